"""The clock-aware study: the paper's range-rate filter against the arrival-time filter.

For each realistic-clock case (:mod:`hmmtrack.scenarios.realistic`: the shark pursuit by
two AUVs steered to make the tag observable — one trails, one circles the shark — the same
pursuit with the paper's fixed formation and with both AUVs circling the shark at a right
angle, and a moored array of three receivers) and seed, both methods track the same
detections (:mod:`hmmtrack.experiments.clock_runs`):

* range-rate (the paper): ΔTOF ranges with the scenario's mean period — the best constant
  period there is — and the true range at each receiver's first detection (``r0``);
* arrival-time: no initial range, the clock in the state, detection probability as
  information, fixed-lag smoothing;
* grouped pings (fixed period): the same detections grouped into pings, each scored jointly
  against the particle's clock (the ``"ping-sequence"`` measurement given the mean period,
  :func:`~hmmtrack.experiments.clock_runs.grouped_config`), with the same detection curve
  and smoother; beside it the share of pings heard by three or more receivers and the
  measurement ``hmmtrack track --period`` would choose from them
  (:func:`~hmmtrack.tracking.measurement.sequence.fixed_period_measurement`).

Diagnostics beside them: the same pursuit with a third AUV, and the circling and
right-angle pursuits with the true emission schedule given (the clock known: what the
two-AUV geometry allows by itself); and a robustness table (the pursuit with clocks unlike
the default's assumptions, tracked with the default period random walk and with the
integrated random walk
:meth:`hmmtrack.tracking.measurement.clock.EmissionClockModel.temperature_drift`).

:func:`arrival_study` returns the tables; ``hmmtrack study arrival`` writes them
(``reports/clock_aware.md``); the filters' throughput is ``benchmarks/bench_arrival.py``'s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.experiments.clock_runs import (
    DURATION,
    clock_inputs,
    grouped_config,
    known_clock_run,
    score_run,
    track_arrival,
)
from hmmtrack.scenarios.realistic import moored_array, realistic_shark_pursuit, three_auv_pursuit
from hmmtrack.tracking.measurement.clock import (
    EmissionClockModel,
    local_period_ppm,
    schedule_wander,
)
from hmmtrack.tracking.measurement.sequence import fixed_period_measurement
from hmmtrack.tracking.pipeline import track

#: the method name's start of the grouped-pings rows (:func:`run_case`)
GROUPED = "grouped pings"
#: the method name's start of the arrival-time rows the grouped rows are set beside
ARRIVAL = "arrival-time (no r0)"
#: the cases also tracked with their clock known (:func:`known_clock_run`)
KNOWN_CLOCK_CASES = (
    "shark pursuit, 2 AUVs (circling)",
    "shark pursuit, 2 AUVs (right-angle formation)",
)
#: (label, ``realistic_shark_pursuit`` keywords) of the robustness runs; the default first
ROBUSTNESS = (
    ("default: wander 0.8 s, period walk smoothed over 600 s", {}),
    ("wander 0.4 s", {"schedule_wander": 0.4}),
    ("wander 1.2 s", {"schedule_wander": 1.2}),
    ("wander 0.8 s, plain per-ping period walk", {"smoothing_time": 0.0}),
)
#: the clock models of the robustness runs: label -> whether it is the integrated random walk
ROBUSTNESS_CLOCKS = {
    "period random walk (default)": False,
    "integrated random walk (temperature_drift)": True,
}


@dataclass(frozen=True)
class ArrivalStudy:
    """What :func:`arrival_study` returns.

    Attributes
    ----------
    runs : pandas.DataFrame
        One row per case, seed and method (``scenario``, ``seed``, ``method``, the columns
        of :func:`hmmtrack.experiments.clock_runs.score_run`, ``ambiguous_share``; the
        grouped rows also ``heard_by_3`` and ``pings_choose``, see :func:`run_case`).
    summary : pandas.DataFrame
        :func:`summary_table` of ``runs``.
    grouping : pandas.DataFrame
        :func:`grouping_table` of ``runs``.
    robustness : pandas.DataFrame
        One row per tag clock, filter clock model and seed.
    robustness_summary : pandas.DataFrame
        Mean and worst seed per tag clock and filter clock model.
    facts : list of str
        The clocks of each case and seed (:func:`clock_facts`).
    """

    runs: pd.DataFrame
    summary: pd.DataFrame
    grouping: pd.DataFrame
    robustness: pd.DataFrame
    robustness_summary: pd.DataFrame
    facts: list[str]


def cases(seed: int, duration: float) -> dict:
    """The study's cases for one seed: name -> ClockScenario."""
    return {
        "shark pursuit, 2 AUVs (circling)": realistic_shark_pursuit(seed),
        "shark pursuit, 2 AUVs (paper formation)": realistic_shark_pursuit(seed, steering="paper"),
        "shark pursuit, 2 AUVs (right-angle formation)": realistic_shark_pursuit(
            seed, steering="formation"
        ),
        "moored array, 3 receivers": moored_array(seed, duration=duration),
        "diagnostic: same pursuit, 3 AUVs": three_auv_pursuit(seed),
    }


def run_case(name, case, seed, n_particles, motion, lag, duration) -> list[dict]:
    """The three methods on one case: the range-rate row, the smoothed arrival-time row (with
    the unsmoothed filter's error after convergence from a run without the smoother) and the
    smoothed grouped-pings row, whose ``heard_by_3`` is the share of the pings heard by three
    or more receivers and ``pings_choose`` the measurement the command line would choose from
    them (:func:`~hmmtrack.tracking.measurement.sequence.fixed_period_measurement`)."""
    sc = case.scenario
    detections, config, options = clock_inputs(case, seed, n_particles, motion, duration)
    paper = track(detections, sc.receivers, config, options["motion"], seed=seed)
    plain = track_arrival(detections, sc.receivers, options)
    smoothed = track_arrival(detections, sc.receivers, options | {"smoothing_lag": lag})
    grouped = track(
        detections,
        sc.receivers,
        grouped_config(options, sc.period, case.search_bounds, {"smoothing_lag": lag}),
        options["motion"],
        seed=seed,
    )
    choice, share = fixed_period_measurement(detections, sc.receivers, sc.period)
    return [
        {
            "scenario": name,
            "seed": seed,
            "method": "range-rate (paper, known r0)",
            **score_run(paper.estimates, sc.truth),
            "ambiguous_share": np.nan,
        },
        {
            "scenario": name,
            "seed": seed,
            "method": f"{ARRIVAL}, smoothed lag {lag} s",
            **score_run(smoothed.estimates, sc.truth, smoothed.smoothed),
            "ambiguous_share": float(smoothed.ambiguity["ambiguous"].mean()),
            "unsmoothed_error_after_convergence_m": score_run(plain.estimates, sc.truth)[
                "error_after_convergence_m"
            ],
        },
        {
            "scenario": name,
            "seed": seed,
            "method": f"{GROUPED} (fixed period), smoothed lag {lag} s",
            **score_run(grouped.estimates, sc.truth, grouped.smoothed),
            "ambiguous_share": np.nan,
            "heard_by_3": share,
            "pings_choose": choice,
        },
    ]


def known_clock_row(name, case, seed, n_particles, motion, duration) -> dict:
    """The arrival-time filter on ``case`` with the true emission schedule given."""
    result = known_clock_run(case, seed, n_particles, motion, duration)
    return {
        "scenario": f"diagnostic: {name}, true emission schedule given",
        "seed": seed,
        "method": "arrival-time, clock known",
        **score_run(result.estimates, case.scenario.truth),
        "ambiguous_share": float(result.collected["ambiguity"]["ambiguous"].mean()),
    }


def robustness_rows(seeds, n_particles, motion, duration) -> list[dict]:
    """The circling pursuit with other tag clocks (:data:`ROBUSTNESS`), tracked with the
    clock models of :data:`ROBUSTNESS_CLOCKS`."""
    rows = []
    for label, keywords in ROBUSTNESS:
        for seed in seeds:
            case = realistic_shark_pursuit(seed, **keywords)
            sc = case.scenario
            detections, _, options = clock_inputs(case, seed, n_particles, motion, duration)
            for model, drift in ROBUSTNESS_CLOCKS.items():
                clock = EmissionClockModel.temperature_drift(sc.period) if drift else None
                result = track_arrival(detections, sc.receivers, options | {"clock": clock})
                scores = score_run(result.estimates, sc.truth)
                rows.append(
                    {
                        "tag clock": label,
                        "filter clock model": model,
                        "seed": seed,
                        "error_after_10_min_m": scores["error_after_10_min_m"],
                        "error_after_convergence_m": scores["error_after_convergence_m"],
                    }
                )
    return rows


def summary_table(table: pd.DataFrame) -> pd.DataFrame:
    """Mean over seeds per case and method, runs converged, and the smoother's gain (%) on
    the error from 10 minutes on and on the error after convergence."""
    columns = [
        "error_after_10_min_m",
        "error_after_convergence_m",
        "first_5_min_m",
        "first_30_min_m",
        "last_30_min_m",
        "smoothed_after_10_min_m",
        "smoothed_after_convergence_m",
        "ambiguous_share",
    ]
    groups = table.groupby(["scenario", "method"], sort=False)
    summary = groups[columns].mean().reset_index()
    summary.insert(2, "runs_converged", groups["converged"].sum().to_numpy())
    summary["smoothing_gain_pct"] = 100 * (
        1 - summary["smoothed_after_10_min_m"] / summary["error_after_10_min_m"]
    )
    summary["smoothing_gain_after_convergence_pct"] = 100 * (
        1 - summary["smoothed_after_convergence_m"] / summary["error_after_convergence_m"]
    )
    return summary


def grouping_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Per case, the grouped pings against the arrival-time filter on the same detections and
    seeds (the rows of :func:`run_case`).

    Returns
    -------
    pandas.DataFrame
        ``scenario``, ``seeds``, the mean error from 10 min on (m) of each
        (``arrival_time_m``, ``grouped_m``) and of their smoothers
        (``arrival_time_smoothed_m``, ``grouped_smoothed_m``), the median and range over seeds
        of the ratio grouped / arrival-time of that error (``median_ratio``,
        ``ratio_min``, ``ratio_max``), the mean and range of the share of pings heard by three
        or more receivers (``heard_by_3``, ``heard_by_3_min``, ``heard_by_3_max``), and
        ``pings_choose``: the measurement the command line chose from the pings, with how
        many seeds chose it.
    """
    out = []
    for name, case in runs.groupby("scenario", sort=False):
        arrival = case[case["method"].str.startswith(ARRIVAL)].set_index("seed")
        grouped = case[case["method"].str.startswith(GROUPED)].set_index("seed")
        if grouped.empty:
            continue
        ratio = grouped["error_after_10_min_m"] / arrival["error_after_10_min_m"]
        choices = grouped["pings_choose"].value_counts()
        out.append(
            {
                "scenario": name,
                "seeds": len(grouped),
                "arrival_time_m": arrival["error_after_10_min_m"].mean(),
                "grouped_m": grouped["error_after_10_min_m"].mean(),
                "arrival_time_smoothed_m": arrival["smoothed_after_10_min_m"].mean(),
                "grouped_smoothed_m": grouped["smoothed_after_10_min_m"].mean(),
                "median_ratio": ratio.median(),
                "ratio_min": ratio.min(),
                "ratio_max": ratio.max(),
                "heard_by_3": grouped["heard_by_3"].mean(),
                "heard_by_3_min": grouped["heard_by_3"].min(),
                "heard_by_3_max": grouped["heard_by_3"].max(),
                "pings_choose": ", ".join(
                    f"{choice} ({count} of {len(grouped)})" for choice, count in choices.items()
                ),
            }
        )
    return pd.DataFrame(out)


def robustness_summary(robustness: pd.DataFrame) -> pd.DataFrame:
    """Mean errors and the worst seed's error after convergence per tag clock and model."""
    return (
        robustness.groupby(["tag clock", "filter clock model"], sort=False)
        .agg(
            error_after_10_min_m=("error_after_10_min_m", "mean"),
            error_after_convergence_m=("error_after_convergence_m", "mean"),
            worst_seed_after_convergence_m=("error_after_convergence_m", "max"),
        )
        .reset_index()
    )


def clock_facts(case, duration: float) -> str:
    """The tag clock of a case in words: schedule wander (s), local period range (ppm over
    800 s blocks) and the multipath arrivals of the whole scenario."""
    emissions = case.emission_times
    emissions = emissions[emissions < case.scenario.start + duration]
    per_block = local_period_ppm(emissions, block=100)
    return (
        f"schedule wander {schedule_wander(emissions):.2f} s over the run, local period "
        f"over 800 s blocks {per_block.min():+.0f}…{per_block.max():+.0f} ppm, "
        f"{int((case.scenario.pings['multipath_delay'] > 0).sum())} multipath arrivals in "
        "the whole scenario"
    )


def arrival_study(
    seeds: Sequence[int],
    *,
    n_particles: int = 3000,
    motion: str = "velocity",
    lag: int = 60,
    duration: float = DURATION,
) -> ArrivalStudy:
    """Every case of :func:`cases` for each seed (range-rate, arrival-time and grouped pings),
    the known-clock diagnostics and the robustness runs.

    Parameters
    ----------
    seeds : sequence of int
        Scenario seeds; each case's filters run with the same seed.
    n_particles : int
    motion : {"velocity", "hmm", "hmm-tc"}
        :func:`hmmtrack.experiments.clock_runs.make_motion`.
    lag : int
        Smoother lag (s).
    duration : float
        Length of each run (s).

    Returns
    -------
    ArrivalStudy
    """
    rows, facts = [], []
    for seed in seeds:
        by_name = cases(seed, duration)
        for name, case in by_name.items():
            facts.append(f"- {name}, seed {seed}: {clock_facts(case, duration)}")
            rows += run_case(name, case, seed, n_particles, motion, lag, duration)
        for name in KNOWN_CLOCK_CASES:
            rows.append(known_clock_row(name, by_name[name], seed, n_particles, motion, duration))
    runs = pd.DataFrame(rows)
    robustness = pd.DataFrame(robustness_rows(seeds, n_particles, motion, duration))
    return ArrivalStudy(
        runs=runs,
        summary=summary_table(runs),
        grouping=grouping_table(runs),
        robustness=robustness,
        robustness_summary=robustness_summary(robustness),
        facts=facts,
    )
