"""The clock-aware study: the paper's range-rate filter against the arrival-time filter.

For each realistic-clock case (:mod:`hmmtrack.scenarios.realistic`: the shark pursuit by
two AUVs steered to make the tag observable — one trails, one circles the shark — the same
pursuit with the paper's fixed formation and with both AUVs circling the shark at a right
angle, and a moored array of three receivers) and seed, both methods track the same
detections (:mod:`hmmtrack.experiments.clock_runs`):

* range-rate (the paper): ΔTOF ranges with the scenario's mean period — the best constant
  period there is — and the true range at each receiver's first detection (``r0``);
* arrival-time: no initial range, the clock in the state, detection probability as
  information, fixed-lag smoothing.

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
from hmmtrack.tracking.pipeline import track

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
        of :func:`hmmtrack.experiments.clock_runs.score_run`, ``ambiguous_share``).
    summary : pandas.DataFrame
        :func:`summary_table` of ``runs``.
    robustness : pandas.DataFrame
        One row per tag clock, filter clock model and seed.
    robustness_summary : pandas.DataFrame
        Mean and worst seed per tag clock and filter clock model.
    facts : list of str
        The clocks of each case and seed (:func:`clock_facts`).
    """

    runs: pd.DataFrame
    summary: pd.DataFrame
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
    """Both methods on one case: the range-rate row and the smoothed arrival-time row (with
    the unsmoothed filter's error after convergence from a run without the smoother)."""
    sc = case.scenario
    detections, config, options = clock_inputs(case, seed, n_particles, motion, duration)
    paper = track(detections, sc.receivers, config, options["motion"], seed=seed)
    plain = track_arrival(detections, sc.receivers, options)
    smoothed = track_arrival(detections, sc.receivers, options | {"smoothing_lag": lag})
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
            "method": f"arrival-time (no r0), smoothed lag {lag} s",
            **score_run(smoothed.estimates, sc.truth, smoothed.smoothed),
            "ambiguous_share": float(smoothed.ambiguity["ambiguous"].mean()),
            "unsmoothed_error_after_convergence_m": score_run(plain.estimates, sc.truth)[
                "error_after_convergence_m"
            ],
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
    """Every case of :func:`cases` for each seed, the known-clock diagnostics and the
    robustness runs.

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
        robustness=robustness,
        robustness_summary=robustness_summary(robustness),
        facts=facts,
    )
