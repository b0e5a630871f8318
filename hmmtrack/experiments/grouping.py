"""A fixed-period tag tracked with its pings grouped, against the arrival-time filter, on the
clock-aware cases.

The arrival-time filter (:mod:`hmmtrack.tracking.measurement.clocked`, the clock-aware
study's method, :mod:`hmmtrack.experiments.arrival`) scores a tag's detections one after
the other against a clock carried by every particle. Grouped, the same detections are the
pings of the ``"ping-sequence"`` measurement (:mod:`hmmtrack.tracking.measurement.sequence`)
given the tag's period (a sequence of one interval, with the arrival-time clock model's
random walk): each ping's arrivals are scored jointly, its emission time integrated out
against the particle's clock. :func:`grouping_rows` runs both on the same detections of the
clock-aware cases (:func:`hmmtrack.experiments.arrival.cases`), each with and without the
case's detection curve (unheard pings as information), and scores them as the study does
(:func:`~hmmtrack.experiments.clock_runs.score_run`), with each run's CPU time.
:func:`share_sweep` runs the same pair on the moored array at shorter detection ranges, where
fewer pings reach all three receivers: it sets the share of pings heard by three from which
the command line groups a fixed-period tag's pings
(:data:`~hmmtrack.tracking.measurement.sequence.GROUPING_SHARE`); run at several filter seeds
per dataset, :func:`filter_seed_summary` judges whether grouping is worse beyond the filters'
own scatter. This module runs and scores; it writes nothing.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from hmmtrack.analysis.metrics import truth_at
from hmmtrack.analysis.mirror import mirror_share, mirror_track
from hmmtrack.experiments.arrival import cases
from hmmtrack.experiments.clock_runs import (
    DURATION,
    clock_inputs,
    grouped_config,
    score_run,
    track_arrival,
    without_silences,
)
from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.measurement.sequence import fixed_period_measurement
from hmmtrack.tracking.pipeline import track

#: the clock-aware cases of :func:`grouping_rows` unless told: three moored receivers (most
#: pings heard by all three), two and three moving receivers (mostly one or two)
GROUPING_CASES = (
    "moored array, 3 receivers",
    "shark pursuit, 2 AUVs (circling)",
    "diagnostic: same pursuit, 3 AUVs",
)


#: the pair of receivers whose line a pursuit's mirror track is reflected across
#: (:func:`on_mirror`); the third AUV of the diagnostic case follows the same two
MIRROR_PAIR = ("auv-1", "auv-2")
#: the estimates of :func:`on_mirror` from this many seconds on, as the error after 10 min
MIRROR_FROM = 600.0

#: the methods of :func:`grouping_rows`; "random-interval pings" is the ``"ping"`` measurement
#: told only that the tag's intervals lie within :data:`RANDOM_INTERVAL` of its period (each
#: ping's emission free, no detection curve, its own random-walk motion): whether its outliers
#: let the cloud escape as the grouped ping's uniform one did; ", velocity motion" runs it with
#: the motion of the other rows instead
METHODS = (
    "arrival-time",
    "arrival-time, no detection curve",
    "grouped pings",
    "grouped pings, no detection curve",
    "random-interval pings",
    "random-interval pings, velocity motion",
)
#: the random-interval run's burst interval about the tag's period (s): the moored array's
#: 8 s tag wanders 0.1 s from its schedule
RANDOM_INTERVAL = 1.0
#: a ping's arrivals cannot all be direct paths from a position when their residuals
#: (arrival − range / c) span more than this (s): 5 of the moorings' 2 ms arrival sds
OUTLIER_SPAN = 10e-3


def on_mirror(estimates: pd.DataFrame, scenario) -> float:
    """Share of the estimates from :data:`MIRROR_FROM` s on nearer the tag's mirror across the
    line of :data:`MIRROR_PAIR` than the tag (:func:`hmmtrack.analysis.mirror.mirror_share`),
    where the branches are 50 m apart or more; NaN on a case without those receivers (the
    moorings: three fixed receivers have no mirror)."""
    receivers = scenario.receivers_truth
    if not set(MIRROR_PAIR) <= set(receivers["receiver"]):
        return float("nan")
    late = estimates[estimates["time"] >= estimates["time"].iloc[0] + MIRROR_FROM]
    mirror = mirror_track(scenario.truth, receivers, MIRROR_PAIR)
    return mirror_share(late, scenario.truth, mirror)


def _run(method: str, case, seed: int, detections, options: dict, settings):
    """One run of ``method`` (:data:`METHODS`) on the case's detections."""
    sc = case.scenario
    if method == "arrival-time":
        return track_arrival(detections, sc.receivers, options)
    if method == "arrival-time, no detection curve":
        return track_arrival(detections, sc.receivers, without_silences(options))
    if method == "grouped pings, no detection curve":
        options = without_silences(options)
    if method.startswith("random-interval pings"):
        config = options["config"]
        config = TrackingConfig.from_keys(
            **{
                "measurement": "ping",
                "burst_interval": (sc.period - RANDOM_INTERVAL, sc.period + RANDOM_INTERVAL),
                "bounds": case.search_bounds,
                "n_particles": config.filter.n_particles,
                "start": config.start,
                "end": config.end,
            }
            | dict(settings or {})
        )
        # its own motion, as a user's run, unless told (with the velocity motion it ran off
        # to km here until the acquisition from the first fixes: reports/decisions.md,
        # "Finding a random-interval tag on three moorings")
        own = method == "random-interval pings"
        motion = config.motion_model() if own else options["motion"]
        return track(detections, sc.receivers, config, motion, seed=seed)
    config = grouped_config(options, sc.period, case.search_bounds, settings)
    return track(detections, sc.receivers, config, options["motion"], seed=seed)


def outlier_pings(observations: pd.DataFrame, track: pd.DataFrame, sound_speed: float) -> float:
    """Share of the pings heard by three or more receivers, from :data:`MIRROR_FROM` s after
    the first on, whose arrivals cannot all be direct paths from ``track``'s position at the
    ping (their residuals span more than :data:`OUTLIER_SPAN`).

    At the true path this is the multipath's share; a cloud that has escaped along the
    ranges of the receivers it still fits needs an outlier at nearly every ping
    (reports/decisions.md, "The moorings' excursions: diagnosed, not fixed").

    Parameters
    ----------
    observations : pandas.DataFrame
        A ping run's observations (``ping``, ``time`` its first arrival, ``arrival``,
        ``receiver_x``, ``receiver_y``; s, m).
    track : pandas.DataFrame
        Positions (``time`` s, ``x``, ``y`` m): the estimates or the truth, interpolated at
        each ping's first arrival.
    sound_speed : float
        m/s.
    """
    heard = observations.groupby("ping")["ping"].transform("size")
    late = observations["time"] >= observations["time"].iloc[0] + MIRROR_FROM
    obs = observations[(heard >= 3) & late]
    if obs.empty:
        return float("nan")
    x, y = truth_at(track, obs["time"].to_numpy())
    ranges = np.hypot(obs["receiver_x"].to_numpy() - x, obs["receiver_y"].to_numpy() - y)
    residual = pd.Series(obs["arrival"].to_numpy() - ranges / sound_speed, index=obs.index)
    span = residual.groupby(obs["ping"]).agg(lambda r: r.max() - r.min())
    return float(np.mean(span > OUTLIER_SPAN))


def grouping_rows(
    seeds: Sequence[int],
    *,
    names: Sequence[str] = GROUPING_CASES,
    methods: Sequence[str] = METHODS,
    n_particles: int = 2000,
    motion: str = "velocity",
    duration: float = DURATION,
    settings: dict | None = None,
) -> pd.DataFrame:
    """The arrival-time filter and the grouped pings, each with and without the detection
    curve, on the same detections, per case and seed.

    Parameters
    ----------
    seeds : sequence of int
        Scenario seeds; the filters run with the same seed.
    names : sequence of str
        Cases of :func:`hmmtrack.experiments.arrival.cases`.
    methods : sequence of str
        Of :data:`METHODS`.
    n_particles : int
    motion : str
        :func:`hmmtrack.experiments.clock_runs.make_motion` name, for every run.
    duration : float
        Length of each run (s).
    settings : dict, optional
        More settings of the grouped and random-interval runs by key (e.g.
        ``arrival_sigma``).

    Returns
    -------
    pandas.DataFrame
        One row per case, seed and method: ``scenario``, ``seed``, ``method``, the columns of
        :func:`~hmmtrack.experiments.clock_runs.score_run`, ``cpu_s`` (the run's CPU time, s),
        ``on_mirror`` (:func:`on_mirror`), and for the runs on pings ``heard_per_ping``
        (receivers per ping), ``heard_by_3`` (share of pings heard by three or more),
        ``echoes_dropped``, and ``outliers_at_estimate`` and ``outliers_at_truth``
        (:func:`outlier_pings` along the estimates and the true path).
    """
    rows = []
    for seed in seeds:
        by_name = cases(seed, duration)
        for name in names:
            case = by_name[name]
            detections, _, options = clock_inputs(case, seed, n_particles, motion, duration)
            rows += case_rows(name, case, seed, detections, options, methods, settings)
    return pd.DataFrame(rows)


def case_rows(name, case, seed, detections, options, methods, settings) -> list[dict]:
    """The rows of :func:`grouping_rows` for one case and seed, on its clock-corrected
    ``detections`` and arrival-time ``options``
    (:func:`~hmmtrack.experiments.clock_runs.clock_inputs`)."""
    rows = []
    for method in methods:
        began = time.process_time()
        result = _run(method, case, seed, detections, options, settings)
        row = {"scenario": name, "seed": seed, "method": method}
        row |= score_run(result.estimates, case.scenario.truth)
        row["cpu_s"] = time.process_time() - began
        row["on_mirror"] = on_mirror(result.estimates, case.scenario)
        if "pings" in method:
            obs = result.observations
            heard = obs.groupby("ping").size()
            row["heard_per_ping"] = float(heard.mean())
            row["heard_by_3"] = float(np.mean(heard >= 3))
            row["echoes_dropped"] = int(obs.attrs.get("echoes_dropped", 0))
            speed = case.scenario.sound_speed
            row["outliers_at_estimate"] = outlier_pings(obs, result.estimates, speed)
            row["outliers_at_truth"] = outlier_pings(obs, case.scenario.truth, speed)
        rows.append(row)
    return rows


#: 50 % detection ranges (array radii) of :func:`share_sweep`: from pings mostly heard by
#: one or two moorings (0.8: 2-4 % heard by three) to most heard by all three (1.45: ~50 %;
#: the clock-aware study's 1.75: ~80 %)
SWEEP_RANGES = (0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.45)


def share_sweep(
    seeds: Sequence[int],
    detection_ranges: Sequence[float] = SWEEP_RANGES,
    *,
    methods: Sequence[str] = ("arrival-time", "grouped pings"),
    n_particles: int = 2000,
    motion: str = "velocity",
    duration: float = 3600.0,
    settings: dict | None = None,
    filter_offsets: Sequence[int] = (0,),
) -> pd.DataFrame:
    """The rows of :func:`grouping_rows` on the moored array
    (:func:`hmmtrack.scenarios.realistic.moored_array`) at each 50 % detection range: a
    family whose share of pings heard by three receivers runs from near 0 to about one half,
    to find where grouping starts to pay.

    Parameters
    ----------
    seeds : sequence of int
        Scenario seeds (one dataset per seed and range).
    detection_ranges : sequence of float
        ``moored_array``'s ``detection_range`` (array radii).
    methods, n_particles, motion, duration, settings
        As :func:`grouping_rows`.
    filter_offsets : sequence of int
        Every method runs on each dataset once per offset, with filter seed ``seed + offset``
        (the same detections): ``(0,)`` is one run with the dataset's seed, as
        :func:`grouping_rows`; :data:`FILTER_OFFSETS` gives the filters' own spread that
        :func:`filter_seed_summary` judges by.

    Returns
    -------
    pandas.DataFrame
        :func:`grouping_rows`' columns (``scenario`` names the range, ``seed`` the dataset),
        with ``filter_seed``, ``detection_range``, ``share_by_3`` (the share of pings heard by
        three or more receivers that the command line's choice reads,
        :func:`~hmmtrack.tracking.measurement.sequence.fixed_period_measurement`) and
        ``pings_choose`` (its choice) on every row.
    """
    rows = []
    for seed in seeds:
        for detection_range in detection_ranges:
            case = moored_array(seed, duration=duration, detection_range=detection_range)
            name = f"moored array, 50 % range {detection_range:g} radii"
            detections, _, options = clock_inputs(case, seed, n_particles, motion, duration)
            sc = case.scenario
            choice, share = fixed_period_measurement(detections, sc.receivers, sc.period)
            for offset in filter_offsets:
                fseed = seed + offset
                dataset = {
                    "seed": seed,
                    "filter_seed": fseed,
                    "detection_range": detection_range,
                    "share_by_3": share,
                    "pings_choose": choice,
                }
                seeded = options | {"seed": fseed}
                runs = case_rows(name, case, fseed, detections, seeded, methods, settings)
                rows += [row | dataset for row in runs]
    return pd.DataFrame(rows)


#: filter seeds ``seed + offset`` of :func:`share_sweep` on the same detections, over which
#: :func:`filter_seed_summary` averages each method: one filter seed's run scatters by up to
#: 1.36x (arrival-time) and 1.72x (grouped) about its dataset's others (reports/decisions.md,
#: "The moorings' excursions")
FILTER_OFFSETS = (0, 1000, 2000)

#: a grouped run counts as worse when its error is this much above the arrival-time run's
WORSE_BY = 0.10


def paired_summary(
    rows: pd.DataFrame,
    method: str = "grouped pings",
    baseline: str = "arrival-time",
    *,
    n_boot: int = 10_000,
    seed: int = 0,
) -> pd.DataFrame:
    """Per case, ``method`` against ``baseline`` on the same detections and filter seed
    (paired rows of :func:`grouping_rows`), on the error from 10 min on.

    Parameters
    ----------
    rows : pandas.DataFrame
        :func:`grouping_rows` with both methods at every case and seed.
    method, baseline : str
        Of :data:`METHODS`.
    n_boot : int
        Bootstrap resamples of the seeds for the median ratio's interval.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    pandas.DataFrame
        One row per case: ``runs``; ``median_ratio`` (median over seeds of the error ratio,
        ``method`` / ``baseline``) and its percentile-bootstrap 95 % interval ``ratio_lo``,
        ``ratio_hi``; ``wilcoxon_p`` (two-sided paired Wilcoxon signed-rank test of the
        errors) and ``p_worse`` (one-sided, ``method`` worse); ``worse_share`` (share of
        seeds whose ratio is above ``1 +`` :data:`WORSE_BY`); the median errors (m) and mean
        on-mirror shares of both (``on_mirror_*``, NaN without a mirror); and the mean
        ``heard_by_3`` share of ``method``'s runs when it has one.
    """
    error = "error_after_10_min_m"
    rng = np.random.default_rng(seed)
    out = []
    for name, case in rows.groupby("scenario", sort=False):
        wide = case.pivot(index="seed", columns="method")
        a = wide[(error, method)].to_numpy(dtype=float)
        b = wide[(error, baseline)].to_numpy(dtype=float)
        ratio = a / b
        lo, hi = _bootstrap_interval(ratio, lambda s: np.median(s, axis=1), n_boot, rng)
        row = {
            "scenario": name,
            "runs": ratio.size,
            "median_ratio": float(np.median(ratio)),
            "ratio_lo": lo,
            "ratio_hi": hi,
            "wilcoxon_p": float(stats.wilcoxon(a, b).pvalue),
            "p_worse": float(stats.wilcoxon(a, b, alternative="greater").pvalue),
            "worse_share": float(np.mean(ratio > 1.0 + WORSE_BY)),
            f"median_{baseline}_m": float(np.median(b)),
            f"median_{method}_m": float(np.median(a)),
            f"on_mirror_{baseline}": float(wide[("on_mirror", baseline)].mean()),
            f"on_mirror_{method}": float(wide[("on_mirror", method)].mean()),
        }
        if ("heard_by_3", method) in wide:
            row["heard_by_3"] = float(wide[("heard_by_3", method)].mean())
        out.append(row)
    return pd.DataFrame(out)


def _bootstrap_interval(values, statistic, n_boot: int, rng) -> tuple[float, float]:
    """Percentile-bootstrap 95 % interval of ``statistic`` over ``values`` (K,): ``n_boot``
    resamples of K drawn with replacement from ``rng``; ``statistic`` maps the resamples
    (n_boot, K) to one value each (n_boot,)."""
    picks = rng.integers(0, values.size, (n_boot, values.size))
    lo, hi = np.percentile(statistic(values[picks]), [2.5, 97.5])
    return float(lo), float(hi)


#: the pooled ratio of :func:`filter_seed_summary` is "not worse" when its upper 95 % bound is
#: below this: worse by more than 5 % excluded
NOT_WORSE_BY = 1.05


def filter_seed_summary(
    rows: pd.DataFrame,
    method: str = "grouped pings",
    baseline: str = "arrival-time",
    *,
    n_boot: int = 10_000,
    seed: int = 0,
) -> tuple[pd.DataFrame, dict]:
    """``method`` against ``baseline`` per dataset, each averaged over its filter seeds, and
    pooled over datasets: the criterion "grouping is not worse" judged beyond one filter
    seed's luck (reports/decisions.md, "Never worse, judged over three filter seeds").

    Parameters
    ----------
    rows : pandas.DataFrame
        :func:`share_sweep` rows (``scenario``, ``seed``, ``filter_seed``, ``method``,
        ``error_after_10_min_m``), several filter seeds per dataset (:data:`FILTER_OFFSETS`).
    method, baseline : str
        The ``method`` labels compared; a dataset counts when both ran on the same filter
        seeds, and only those seeds are used.
    n_boot : int
        Bootstrap resamples of the datasets for the pooled ratio's interval.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    per_dataset : pandas.DataFrame
        One row per dataset (``scenario``, ``seed``): ``filter_seeds`` (how many),
        ``<baseline>_m`` and ``<method>_m`` (mean error from 10 min on over the filter
        seeds, m), ``<baseline>_max_m`` (the baseline's worst filter seed), each method's
        ``*_spread`` (max ÷ min over filter seeds), ``ratio`` (the means' ratio, method ÷
        baseline) and ``within_noise`` (the method's mean no higher than the baseline's
        worst filter seed).
    pooled : dict
        ``datasets``; ``geometric_ratio`` (the geometric mean of the datasets' ratios: the
        errors' scales differ fourfold between detection ranges) with its percentile
        bootstrap 95 % interval ``ratio_lo``, ``ratio_hi``; ``not_worse`` (``ratio_hi`` below
        :data:`NOT_WORSE_BY`); ``mean_ratio`` (the datasets' mean ratio); the pooled mean
        errors ``<baseline>_m`` and ``<method>_m`` (m); ``within_noise`` (datasets within
        their noise).
    """
    error = "error_after_10_min_m"
    compared = rows[rows["method"].isin((method, baseline))]
    wide = compared.pivot_table(
        index=["scenario", "seed", "filter_seed"], columns="method", values=error
    ).dropna()
    out = []
    for (name, data_seed), dataset in wide.groupby(level=["scenario", "seed"], sort=False):
        a = dataset[method].to_numpy(dtype=float)
        b = dataset[baseline].to_numpy(dtype=float)
        out.append(
            {
                "scenario": name,
                "seed": data_seed,
                "filter_seeds": a.size,
                f"{baseline}_m": b.mean(),
                f"{method}_m": a.mean(),
                f"{baseline}_max_m": b.max(),
                f"{baseline}_spread": b.max() / b.min(),
                f"{method}_spread": a.max() / a.min(),
                "ratio": a.mean() / b.mean(),
                "within_noise": bool(a.mean() <= b.max()),
            }
        )
    per_dataset = pd.DataFrame(out)
    log_ratio = np.log(per_dataset["ratio"].to_numpy())
    rng = np.random.default_rng(seed)
    lo, hi = _bootstrap_interval(log_ratio, lambda s: np.exp(s.mean(axis=1)), n_boot, rng)
    pooled = {
        "datasets": log_ratio.size,
        "geometric_ratio": float(np.exp(log_ratio.mean())),
        "ratio_lo": lo,
        "ratio_hi": hi,
        "not_worse": bool(hi < NOT_WORSE_BY),
        "mean_ratio": float(per_dataset["ratio"].mean()),
        f"{baseline}_m": float(per_dataset[f"{baseline}_m"].mean()),
        f"{method}_m": float(per_dataset[f"{method}_m"].mean()),
        "within_noise": int(per_dataset["within_noise"].sum()),
    }
    return per_dataset, pooled
