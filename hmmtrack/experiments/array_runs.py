"""Tracking a tag in a simulated moored array against its Cramér–Rao bound, for any measurement.

:func:`array_bound_ratios` runs one measurement (a name of
:data:`hmmtrack.tracking.measurement.MEASUREMENTS`, e.g. ``"arrival-time"`` for a
fixed-period tag, or a measurement for random-interval tags once one is registered) on
:func:`hmmtrack.scenarios.array.tagged_array` datasets the way a user would: the receivers'
clocks fitted from the sync tags (:func:`hmmtrack.sync.fit_clocks`, positions of the
unfixed receivers refined), the tag's detections moved to the time keeper's time base
(:func:`hmmtrack.sync.apply_clocks`), then :func:`hmmtrack.tracking.pipeline.track` with the
measurement's own run defaults (its motion, correction, smoothing; the filter's particle count)
and the fitted sound speed. Each run's RMS position error at the pings (the
estimates interpolated at the emission times, the truth moved to the time keeper's clock)
is set beside the posterior Cramér–Rao bound of the same
pings (:func:`hmmtrack.analysis.crb.tdoa_bound`, emission times unknown per ping or known
up to offset and drift), as a ratio: how far the method is from what any tracker could do
from these pings. This module runs and scores; it writes nothing.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from hmmtrack.analysis.crb import acceleration_psd_from_path, tdoa_bound
from hmmtrack.analysis.metrics import position_error
from hmmtrack.scenarios.array import TaggedArray, tagged_array
from hmmtrack.sync import apply_clocks, fit_clocks
from hmmtrack.tracking.config import TrackingConfig, section_classes
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.measurement.tdoa import per_ping_table
from hmmtrack.tracking.pipeline import track

#: the time keeper of every run (the array's first receiver)
KEEPER = "rx-01"
#: errors and bounds are taken from this many seconds after the tag's first ping (s)
SKIP = 300.0
#: the array of the runs: 3 x 3 receivers 100 m apart, 12 h of sync tags, 1 % echoes
ARRAY = {"rows": 3, "columns": 3, "duration": 43200.0, "echo_fraction": 0.01}
#: a sparser array: 3 x 3 receivers 200 m apart (sync tags heard as in :data:`ARRAY`) and a
#: quieter tag heard to about 170 m, so that a ping is heard by 1-4 receivers (mostly 2-3)
#: and its emission time matters
SPARSE_ARRAY = ARRAY | {
    "spacing": 200.0,
    "tag_detection": LogisticDetection(range_50=170.0, width=20.0),
}
#: the search box's margin around the receivers (m)
MARGIN = 100.0


def array_bound_ratios(
    measurement: str,
    *,
    datasets: Sequence[int] = (1, 2),
    seeds: Sequence[int] = (1, 2),
    burst_interval: tuple[float, float] = (20.0, 40.0),
    tag_duration: float = 1800.0,
    n_particles: int | None = None,
    settings: Mapping | None = None,
    bound_emission: str = "random",
    array: Mapping = ARRAY,
) -> pd.DataFrame:
    """Error and bound of ``measurement`` on simulated moored arrays, per dataset and seed.

    Parameters
    ----------
    measurement : str
        The measurement's name in a configuration.
    datasets : sequence of int
        Scenario seeds of :func:`~hmmtrack.scenarios.array.tagged_array` (with :data:`ARRAY`).
    seeds : sequence of int
        Filter seeds, each run on every dataset.
    burst_interval : (float, float)
        The tag's interval range (s); equal values: a fixed-period tag.
    tag_duration : float
        Length of the tracked window (s).
    n_particles : int, optional
        Default: the filter's.
    settings : mapping, optional
        More settings by key (:meth:`~hmmtrack.tracking.config.TrackingConfig.from_keys`),
        e.g. ``{"period": 30.0}`` for ``"arrival-time"`` or ``{"motion": "velocity"}``; they
        win over the run's own.
    bound_emission : {"random", "sequence"}
        The bound's emission model (:func:`~hmmtrack.analysis.crb.tdoa_bound`).
    array : mapping
        Options of :func:`~hmmtrack.scenarios.array.tagged_array` and
        :func:`~hmmtrack.scenarios.array.moored_sync_array` (default
        :data:`ARRAY`; :data:`SPARSE_ARRAY`: pings heard by 1-4 receivers).

    Returns
    -------
    pandas.DataFrame
        One row per dataset and seed: ``measurement``, ``dataset``, ``seed``, ``pings``,
        ``detections`` (the tag's), ``clock_error_ms`` (largest error of the fitted clocks
        over the tag's window), ``rms_error_m`` (at the pings from :data:`SKIP` s on),
        ``bound_m`` (RMS of the filtering bound over the same pings), ``ratio`` (their
        quotient), and when the
        configuration smooths ``smoothed_rms_error_m``, ``smoother_bound_m`` and
        ``smoothed_ratio``; with a ping measurement (a run with ``pings``) also
        ``per_ping_rms_error_m`` (the position right after each heard ping's correction, at
        its emission), ``per_ping_bound_m`` and ``per_ping_ratio``: the per-second estimate
        at an emission is a prediction made before the ping arrived, so only these compare
        with the filtering bound, and ``heard_per_ping`` (mean receivers per ping heard);
        when it also smooths ``smoothed_per_ping_rms_error_m`` (the smoothed row of each
        such correction, :func:`~hmmtrack.tracking.measurement.tdoa.per_ping_table`),
        ``smoothed_per_ping_bound_m`` and ``smoothed_per_ping_ratio``;
        ``seconds`` (wall time of the filter).
        The bound's efficient estimator on the same draws (:func:`_bound`'s oracle: the exact
        Kalman filter and smoother of the linearised model given the simulated timing
        errors) beside them, as a yardstick of a single run's luck: ``late_pings``
        (pings scored from :data:`SKIP` s on), ``oracle_rms_error_m`` (its filter at
        those pings) and ``oracle_smoothed_rms_error_m`` (its smoother), with
        ``oracle_ratio`` and ``oracle_smoothed_ratio`` against the filtering and smoothing
        bounds; with a ping measurement also ``per_ping_pings`` (pings matched) and
        ``oracle_per_ping_rms_error_m``, ``oracle_per_ping_ratio`` at the same pings; the
        ``direct_oracle_*`` columns likewise for the efficient estimator that knows which
        arrivals came by multipath and leaves them out (the bound counts them as direct: a
        tracker that cannot tell a short delay from jitter does no better than this one),
        against the same bounds.
    """
    rows = []
    for dataset in datasets:
        case = tagged_array(
            dataset, burst_interval=burst_interval, tag_duration=tag_duration, **array
        )
        fit = fit_clocks(
            case.detections, case.array.receivers, time_keeper=KEEPER, refine_positions=3.0
        )
        clocks = fit.clocks
        tag = case.detections[case.detections["transmitter"] == case.transmitter]
        detections = apply_clocks(tag, clocks)
        receivers = pd.DataFrame(
            {
                "receiver": clocks.receivers,
                "time": np.nan,
                "x": clocks.positions[:, 0],
                "y": clocks.positions[:, 1],
            }
        )
        keeper = case.array.clocks[KEEPER]
        truth = case.truth.assign(time=keeper(case.truth["time"].to_numpy()))
        bound = _bound(case, bound_emission)
        direct = _bound(case, bound_emission, direct=True)
        late = (bound["time"] >= case.emission_times[0] + SKIP).to_numpy()
        oracle = {"late_pings": int(late.sum())}
        for prefix, oracle_run in (("", bound), ("direct_", direct)):
            for name, kind in (("", "filter"), ("_smoothed", "smoother")):
                error = _rms(oracle_run.loc[late, f"{kind}_error_m"])
                oracle[f"{prefix}oracle{name}_rms_error_m"] = error
                oracle[f"{prefix}oracle{name}_ratio"] = error / _rms(
                    bound.loc[late, f"{kind}_position_m"]
                )
        pings = keeper(case.emission_times)
        config = _config(measurement, case, clocks, receivers, n_particles, settings or {})
        for seed in seeds:
            began = time.perf_counter()
            result = track(detections, receivers, config, seed=seed)
            seconds = time.perf_counter() - began
            row = {
                "measurement": measurement,
                "dataset": dataset,
                "seed": seed,
                "pings": case.emission_times.size,
                "detections": len(detections),
                "clock_error_ms": 1e3 * _clock_error(case, clocks),
                "rms_error_m": _rms_at(result.estimates, truth, pings[late]),
                "bound_m": _rms(bound.loc[late, "filter_position_m"]),
            }
            row["ratio"] = row["rms_error_m"] / row["bound_m"]
            if getattr(result, "pings", None) is not None and len(result.pings):
                errors, at = _per_ping_rms(result, truth, pings, late)
                row["per_ping_rms_error_m"] = errors["x"]
                row["per_ping_bound_m"] = _rms(bound.loc[at, "filter_position_m"])
                row["per_ping_ratio"] = errors["x"] / row["per_ping_bound_m"]
                row["per_ping_pings"] = at.size
                for prefix, oracle_run in (("", bound), ("direct_", direct)):
                    error = _rms(oracle_run.loc[at, "filter_error_m"])
                    row[f"{prefix}oracle_per_ping_rms_error_m"] = error
                    row[f"{prefix}oracle_per_ping_ratio"] = error / row["per_ping_bound_m"]
                if "smoothed_x" in errors:
                    smoothed = errors["smoothed_x"]
                    row["smoothed_per_ping_rms_error_m"] = smoothed
                    row["smoothed_per_ping_bound_m"] = _rms(bound.loc[at, "smoother_position_m"])
                    row["smoothed_per_ping_ratio"] = smoothed / row["smoothed_per_ping_bound_m"]
                row["heard_per_ping"] = float(result.observations.groupby("ping").size().mean())
            if result.smoothed is not None:
                smoothed = _rms_at(result.smoothed, truth, pings[late])
                row["smoothed_rms_error_m"] = smoothed
                row["smoother_bound_m"] = _rms(bound.loc[late, "smoother_position_m"])
                row["smoothed_ratio"] = smoothed / row["smoother_bound_m"]
            rows.append(row | oracle | {"seconds": seconds})
    return pd.DataFrame(rows)


#: the estimators :func:`pooled_ratios` pools: (name, error, bound, pings) columns of
#: :func:`array_bound_ratios`
POOLED = (
    ("per ping", "per_ping_rms_error_m", "per_ping_bound_m", "per_ping_pings"),
    ("smoothed output", "smoothed_rms_error_m", "smoother_bound_m", "late_pings"),
    ("oracle filter per ping", "oracle_per_ping_rms_error_m", "per_ping_bound_m", "per_ping_pings"),
    ("oracle smoother", "oracle_smoothed_rms_error_m", "smoother_bound_m", "late_pings"),
    (
        "direct oracle per ping",
        "direct_oracle_per_ping_rms_error_m",
        "per_ping_bound_m",
        "per_ping_pings",
    ),
    (
        "direct oracle smoother",
        "direct_oracle_smoothed_rms_error_m",
        "smoother_bound_m",
        "late_pings",
    ),
)


def pooled_ratios(
    runs: pd.DataFrame, *, threshold: float = 1.2, resamples: int = 4000, seed: int = 0
) -> pd.DataFrame:
    """Each estimator's error pooled over runs against its bound pooled the same way.

    A posterior Cramér–Rao bound bounds the mean-square error in expectation over the
    measurement noise (and the path), so an estimator is held to it by its RMS error over
    every scored ping of every run against the root of the mean squared bound over the same
    pings; one run's ratio scatters about that by its draws' luck (the oracle's rows show by
    how much for an efficient estimator).

    Parameters
    ----------
    runs : pandas.DataFrame
        Rows of :func:`array_bound_ratios` (per dataset and seed).
    threshold : float
        Ratio whose runs at or below are counted.
    resamples : int
        Bootstrap resamples of the datasets (each with all its seeds' runs), for the
        pooled ratio's 95 % interval.
    seed : int
        Seed of the bootstrap.

    Returns
    -------
    pandas.DataFrame
        One row per estimator of :data:`POOLED` present in ``runs``: ``estimator``,
        ``pooled_ratio``, ``ci_low``, ``ci_high``, and the per-run ratios' ``median``,
        ``low``, ``high`` and ``runs_within`` (at or below ``threshold``) of ``runs``.
    """
    datasets = runs["dataset"].to_numpy()
    names = np.unique(datasets)
    members = [np.flatnonzero(datasets == d) for d in names]
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, names.size, (resamples, names.size))
    out = []
    for name, error, bound, pings in POOLED:
        if error not in runs:
            continue
        n = runs[pings].to_numpy(dtype=float)
        squares = n * runs[error].to_numpy(dtype=float) ** 2
        bounds = n * runs[bound].to_numpy(dtype=float) ** 2
        per_dataset = np.array([[squares[m].sum(), bounds[m].sum()] for m in members])
        drawn = per_dataset[picks].sum(axis=1)
        ratio = runs[error] / runs[bound]
        out.append(
            {
                "estimator": name,
                "pooled_ratio": float(np.sqrt(squares.sum() / bounds.sum())),
                "ci_low": float(np.sqrt(np.percentile(drawn[:, 0] / drawn[:, 1], 2.5))),
                "ci_high": float(np.sqrt(np.percentile(drawn[:, 0] / drawn[:, 1], 97.5))),
                "median": float(ratio.median()),
                "low": float(ratio.min()),
                "high": float(ratio.max()),
                "runs_within": int((ratio <= threshold).sum()),
                "runs": len(runs),
            }
        )
    return pd.DataFrame(out)


def sequence_versus_random(
    *,
    datasets: Sequence[int] = (1, 2, 3),
    seeds: Sequence[int] = (1, 2),
    burst_interval: tuple[float, float] = (20.0, 40.0),
    n_particles: int = 2000,
    settings: Mapping | None = None,
    array: Mapping = SPARSE_ARRAY,
    tag_duration: float = 1800.0,
) -> pd.DataFrame:
    """The same pings tracked as a random-interval tag (``"ping"``) and with its known
    sequence (``"ping-sequence"``), each beside its own bound.

    Parameters
    ----------
    datasets, seeds, burst_interval, n_particles, array, tag_duration
        As :func:`array_bound_ratios` (the tag's intervals a pseudo-random sequence drawn
        in ``burst_interval``).
    settings : mapping, optional
        Settings of both measurements (e.g. ``arrival_sigma``); both move with the velocity
        model unless these name another.

    Returns
    -------
    pandas.DataFrame
        One row per dataset, seed and model (``"random"``, ``"sequence"``): the columns of
        :func:`array_bound_ratios`, the bound that of the model's emission.
    """
    options = dict(
        datasets=datasets,
        seeds=seeds,
        burst_interval=burst_interval,
        n_particles=n_particles,
        array=array,
        tag_duration=tag_duration,
    )
    shared = {"motion": "velocity"} | dict(settings or {})
    random = array_bound_ratios(
        "ping", settings=shared | {"burst_interval": burst_interval}, **options
    )
    sequence = array_bound_ratios(
        "ping-sequence", settings=shared, bound_emission="sequence", **options
    )
    random.insert(0, "model", "random")
    sequence.insert(0, "model", "sequence")
    return pd.concat([random, sequence], ignore_index=True)


def _config(measurement, case: TaggedArray, clocks, receivers, n_particles, settings):
    """The run's configuration: the tag, its window on the keeper's clock, a box around the
    receivers, the fitted sound speed (when the measurement has one)."""
    keeper = case.array.clocks[KEEPER]
    keys = {
        "measurement": measurement,
        "transmitter": case.transmitter,
        "n_particles": n_particles,
        "start": float(np.floor(keeper(case.emission_times[0]))),
        "end": float(np.floor(keeper(case.truth["time"].iloc[-1]))),
        "bounds": (
            receivers["x"].min() - MARGIN,
            receivers["x"].max() + MARGIN,
            receivers["y"].min() - MARGIN,
            receivers["y"].max() + MARGIN,
        ),
    }
    measurement_keys = section_classes("measurement")[measurement].keys()
    if "sound_speed" in measurement_keys:
        keys["sound_speed"] = float(np.mean(clocks.sound_speed))
    if "burst_sequence" in measurement_keys and "period" not in settings:
        keys["burst_sequence"] = tuple(case.sequence)
    return TrackingConfig.from_keys(**(keys | dict(settings)))


def _bound(case: TaggedArray, emission: str, direct: bool = False) -> pd.DataFrame:
    """The bound of the tag's heard pings (true receivers, sound speed, time), with the
    errors of its efficient estimator given the simulated timing errors of those arrivals
    (each detection's logged time less its receiver's clock at the true arrival, less any
    multipath delay: the Gaussian jitter the bound assumes); ``direct``: of the arrivals
    that came without multipath only."""
    array = case.array
    detected = case.pings[case.pings["detected"]]
    if direct:
        detected = detected[detected["multipath"] == 0]
    heard = detected[["ping", "receiver"]]
    clocks = array.clocks
    jitter = [
        logged - clocks[receiver](arrival)
        for logged, receiver, arrival in zip(
            detected["logged_time"], detected["receiver"], detected["arrival_time"], strict=True
        )
    ]
    receivers = array.receivers_truth.assign(time=np.nan)
    window = float(np.mean(case.burst_interval))
    return tdoa_bound(
        case.truth,
        receivers,
        heard.reset_index(drop=True),
        case.emission_times,
        emission=emission,
        acceleration_psd=acceleration_psd_from_path(case.truth, window),
        sigma=array.listening.timing_sd,
        sound_speed=array.sound_speed,
        noise=np.asarray(jitter) - detected["multipath"].to_numpy(),
    )


def _clock_error(case: TaggedArray, clocks) -> float:
    """Largest error (s) of the fitted clocks over the tag's window."""
    grid = case.truth["time"].to_numpy()[::60]
    keeper = case.array.clocks[KEEPER]
    return max(
        float(np.max(np.abs(clocks.to_common(name, clock(grid)) - keeper(grid))))
        for name, clock in case.array.clocks.items()
    )


def _rms(values: pd.Series) -> float:
    return float(np.sqrt(np.mean(np.square(values.to_numpy(dtype=float)))))


def _per_ping_rms(result, truth: pd.DataFrame, pings: np.ndarray, late: np.ndarray):
    """RMS errors (m) at each heard ping's emission of the filter's position right after the
    ping's correction (key ``"x"``) and, when the run smooths, of the smoothed one at that
    step (``"smoothed_x"``; :func:`~hmmtrack.tracking.measurement.tdoa.per_ping_table`), and
    the indices of the true pings they were matched to (the nearest emission, within 1 s).

    One row per true ping, the one heard by the most receivers: an echo grouped apart
    (0.3-1.5 s after its ping, one receiver) carries an emission estimate near the same
    true ping, but it is not that ping's fix, and the bound counts the ping once.
    """
    table = per_ping_table(result.pings, result.observations, result.smoothed)
    estimated = table["emission_time"].to_numpy(dtype=float)
    nearest = np.abs(estimated[:, None] - pings[None, :]).argmin(axis=1)
    matched = np.flatnonzero((np.abs(pings[nearest] - estimated) < 1.0) & late[nearest])
    heard = table["n_receivers"].to_numpy()[matched]
    matched = matched[np.lexsort((-heard, nearest[matched]))]  # by ping, most heard first
    keep = matched[np.diff(nearest[matched], prepend=-1) != 0]
    errors = {}
    for x in ("x", "smoothed_x"):
        if x in table:
            y = x.replace("x", "y")
            at = pd.DataFrame(
                {
                    "time": pings[nearest[keep]],
                    "x": table[x].to_numpy()[keep],
                    "y": table[y].to_numpy()[keep],
                }
            )
            errors[x] = float(np.sqrt(np.mean(position_error(at, truth) ** 2)))
    return errors, nearest[keep]


def _rms_at(estimates: pd.DataFrame, truth: pd.DataFrame, times: np.ndarray) -> float:
    """RMS error (m) of the estimates interpolated linearly at ``times`` (s), the pings."""
    t = estimates["time"].to_numpy(dtype=float)
    at = pd.DataFrame(
        {"time": times} | {c: np.interp(times, t, estimates[c].to_numpy(dtype=float)) for c in "xy"}
    )
    return float(np.sqrt(np.mean(position_error(at, truth) ** 2)))
