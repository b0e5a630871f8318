"""The arrival-time filter with two AUVs on an observable steering plan (issue 5, first must-show).

Issue 5 asks for an error after convergence under 10 m over 2 h with two moving receivers,
no known initial range and the realistic drifting tag clock. ``bench_clock_bound.py``
showed that no tracker can reach that on the earlier steerings, and that a pair of AUVs
circling the shark together fast enough can. For each plan in :data:`PLANS` this script
runs the arrival-time particle filter twice from the same detections, with
``track_arrival_time``'s defaults (:data:`DEFAULT`) and with the bundled
``two-moving-receivers`` preset (:data:`PRESET`, :func:`hmmtrack.tracking.config.read_preset`),
and the paper's range-rate method once (true initial ranges, best constant period,
velocity motion), and prints per seed the filtered and 60 s-smoothed mean error after
convergence (the paper's metric), the time to convergence, the filtered RMS error from
10 min on beside the posterior Cramér–Rao bound
(:func:`hmmtrack.analysis.bounds.arrival_time_bound`,
fitted clock and detection curve, as in ``bench_clock_bound.py``) and the AUVs' speed
percentiles (1 s steps); then the filters' throughput (particle-steps per second without
the smoother, best of two runs) with the machine's load. Not a test: it measures.

The plans are steerings of :func:`hmmtrack.scenarios.clocks.realistic_shark_pursuit` (the
tag clock wanders 0.8 s from a constant 8 s schedule, 65 µs jitter, multipath, correlated
GPS error): ``steering="observable"`` (stations 27 m from the shark, 135° apart, one lap
per 150 s, led ahead of the shark by its recent velocity so that the vehicles hold that
geometry behind a travelling shark) and, for comparison, the plan as it was before the
lead (30 m, stations on the shark's position; a
:class:`hmmtrack.scenarios.clocks.RotatingPlan`). The stations are placed from the true
shark track (as the paper's simulated hydrophone paths are): the steering assumes the
AUVs know where the shark is to within the filter's error. The tuned settings run with
two filter seeds per scenario (:data:`TUNED_FILTER_SEEDS`); the summary gives the worst
run and the number of runs at or over 10 m.

    python benchmarks/bench_two_auv_plan.py [--seeds 3] [--report reports/two_auv_plan.md]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
from bench_arrival import inputs, make_motion, markdown, summarise
from bench_clock_bound import DURATION, SKIP, bound_inputs, bound_table, rms_after_skip

from hmmtrack.analysis.metrics import position_error
from hmmtrack.scenarios.clocks import ROTATING_PLANS, RotatingPlan, realistic_shark_pursuit
from hmmtrack.tracking.config import TrackingConfig, read_preset
from hmmtrack.tracking.pipeline import track

#: steerings of ``realistic_shark_pursuit``: the recommended plan first (its throughput is
#: measured), then the observable plan as it was without the lead (stations 30 m from the
#: shark's position), whose vehicles fell behind a fast shark and closed their angle
PLANS = ("observable", RotatingPlan(radius=30.0, lead_window=None))
SMOOTHING_LAG = 60
#: filter seeds of the tuned settings' runs, as offsets from the scenario seed: two runs per
#: scenario, so that the table shows the tail over filter seeds as well as scenarios
TUNED_FILTER_SEEDS = (0, 100)
#: the bundled preset this script measures
PRESET = "two-moving-receivers"
#: name of the preset's runs without the detection curve
NO_SILENCES = "tuned, no detection curve"

#: the arrival-time measurement's defaults with ``bench_arrival.py``'s velocity motion
#: (:func:`bench_arrival.make_motion`), as settings of
#: :class:`hmmtrack.tracking.config.TrackingConfig`
DEFAULT = {
    "measurement": "arrival-time",
    "motion": "velocity",
    "sigma_speed": make_motion("velocity").sigma_speed,
    "sigma_turn_rate": make_motion("velocity").sigma_turn_rate,
    "n_particles": 3000,
}
#: the preset (H20's tuning, speed noise raised by H25): the residual's σ near the
#: scenario's ~1 ms arrival-time noise, a turn rate that wanders 7× less (a white shark
#: cruises; the mirror fix across the line through the AUVs has to swim circles to follow
#: the turning pair), a speed that wanders 2× more (0.1 m/s per √s: with 0.05, particles
#: that could not follow a shark speeding up by ~1 m/s gave way to a clock-shifted fix
#: circling 40-90 m off for minutes, 8-13 m over a run), with 4,000 particles and the
#: filter's default tempering (below 30 % of the particles). With σ or turn rate back at
#: its default, a seed went over 10 m on the unled plan (12.2 and 12.6 m; H20's report), as
#: did tempering at 30 % there (28.4 m), so H20 tempered at 60 %; on the led plan 60 % gave
#: 5.30 m mean and 6.02 m worst over the 18 runs against 5.61 and 6.56 m at 30 %, for 1.6×
#: the run time (lead, 11:20 UTC), and the preset keeps 30 %
TUNED = read_preset(PRESET)


def plan_label(plan) -> str:
    """``"observable: 30 m, 135°, lap 150 s"`` or the plan's numbers."""
    if isinstance(plan, RotatingPlan):
        return plan.describe()
    return f"{plan}: {ROTATING_PLANS[plan].describe()}"


def arrival_run(case, settings: dict, smoothing_lag, seed, silences: bool = True):
    """:func:`hmmtrack.tracking.pipeline.track` with ``settings`` (keys of
    :class:`hmmtrack.tracking.config.TrackingConfig`) on ``case``'s clock-corrected detections
    (default clock model; the scenario's detection curve, so that missed pings count,
    unless ``silences`` is False, as ``hmmtrack track`` runs without ``--detection-curve``)."""
    sc = case.scenario
    detections, _, common = inputs(case, seed, settings["n_particles"], "velocity", DURATION)
    arrival = common["config"]
    window = {key: getattr(arrival, key) for key in ("period", "bounds", "start", "end")}
    curve = arrival.detection_curve if silences else None
    config = TrackingConfig.from_dict(
        settings | window | {"sound_speed": sc.sound_speed, "detection_curve": curve}
    )
    return track(
        detections,
        sc.receivers,
        config,
        config.motion_model(),
        seed=common["seed"],
        smoothing_lag=smoothing_lag,
    )


def errors(case, settings: dict, seed: int, silences: bool = True) -> dict:
    """Mean errors after convergence (m) of the filter and its smoother (for the filter also
    over the first and last 30 minutes after convergence), time to convergence (s) and the
    filter's RMS error from ``SKIP`` s on (m)."""
    result = arrival_run(case, settings, SMOOTHING_LAG, seed, silences)
    truth = case.scenario.truth
    paper = summarise(result.estimates, truth, result.smoothed)
    late = result.estimates[result.estimates["time"] >= case.scenario.start + SKIP]
    return {
        "filtered_m": paper["error_after_convergence_m"],
        "smoothed_m": paper["smoothed_after_convergence_m"],
        "convergence_s": paper["time_to_convergence_s"],
        "filtered_first_30_min_m": paper["first_30_min_m"],
        "filtered_last_30_min_m": paper["last_30_min_m"],
        "filtered_rms_m": float(np.sqrt(np.mean(position_error(late, truth) ** 2))),
    }


def range_rate_errors(case, seed: int) -> dict:
    """The paper's method on the same detections: ΔTOF ranges from the best constant period
    and the true range at each receiver's first detection, velocity motion, as
    ``bench_arrival.py`` runs it; mean error after convergence overall and in the first and
    last 30 minutes after convergence (m)."""
    sc = case.scenario
    detections, config, _ = inputs(case, seed, TUNED["n_particles"], "velocity", DURATION)
    result = track(detections, sc.receivers, config, make_motion("velocity"), seed=seed)
    paper = summarise(result.estimates, sc.truth)
    return {
        "range_rate_m": paper["error_after_convergence_m"],
        "range_rate_first_30_min_m": paper["first_30_min_m"],
        "range_rate_last_30_min_m": paper["last_30_min_m"],
    }


def throughput(case, settings: dict, seed: int, silences: bool = True, repeats: int = 2) -> float:
    """Particle-steps per second of the filter alone (no smoother), best of ``repeats``."""
    best = np.inf
    for _ in range(repeats):
        tic = time.perf_counter()
        arrival_run(case, settings, None, seed, silences)
        best = min(best, time.perf_counter() - tic)
    return settings["n_particles"] * DURATION / best


def auv_speeds(case) -> np.ndarray:
    """Both AUVs' speeds over ground (m/s) over 1 s steps of the first ``DURATION`` s."""
    sc = case.scenario
    paths = sc.receivers_truth[sc.receivers_truth["time"] < sc.start + DURATION]
    return np.concatenate(
        [
            np.hypot(np.diff(path["x"]), np.diff(path["y"])) / np.diff(path["time"])
            for _, path in paths.groupby("receiver")
        ]
    )


def plan_rows(plan, seeds) -> list[dict]:
    """Bound, AUV speeds and both settings' errors on ``plan`` (a steering) for each seed."""
    rows = []
    for seed in seeds:
        case = realistic_shark_pursuit(seed, steering=plan)
        speeds = auv_speeds(case)
        inputs = bound_inputs(case, 1.5)
        bound = bound_table(inputs, inputs.fitted_clock)
        common = {
            "plan": plan_label(plan),
            "seed": seed,
            "auv_speed_p50_m_s": np.quantile(speeds, 0.5),
            "auv_speed_p99_m_s": np.quantile(speeds, 0.99),
            "auv_speed_max_m_s": speeds.max(),
            "bound_filter_rms_m": rms_after_skip(bound, inputs, "filter_position_m"),
            "bound_smoother_rms_m": rms_after_skip(bound, inputs, "smoother_position_m"),
        }
        paper = range_rate_errors(case, seed)
        runs = [("default", DEFAULT, seed, True)]
        runs += [("tuned", TUNED, seed + offset, True) for offset in TUNED_FILTER_SEEDS]
        runs += [(NO_SILENCES, TUNED, seed + offset, False) for offset in TUNED_FILTER_SEEDS]
        for name, settings, filter_seed, silences in runs:
            errors_ = errors(case, settings, filter_seed, silences)
            rows.append(
                {**common, "settings": name, "filter_seed": filter_seed, **errors_, **paper}
            )
    return rows


def settings_lines() -> str:
    """The two settings compared, as Markdown list items."""
    return (
        f"- default (`track_arrival_time`'s, velocity motion): {DEFAULT}\n"
        f"- tuned (`--preset {PRESET}`, hmmtrack/data/presets/{PRESET}.json): {TUNED}\n"
        f"- {NO_SILENCES}: the same without the detection curve (missed pings carry no "
        "information), as `hmmtrack track --preset` runs without `--detection-curve 160 40`"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--report", type=Path, default=None, help="write a Markdown table")
    args = parser.parse_args(argv)
    began = time.perf_counter()
    load = os.getloadavg()[0]
    seeds = list(range(args.seeds))
    table = pd.DataFrame([row for plan in PLANS for row in plan_rows(plan, seeds)])
    case = realistic_shark_pursuit(0, steering=PLANS[0])
    speed = {
        "default": throughput(case, DEFAULT, 0),
        "tuned": throughput(case, TUNED, 0),
        NO_SILENCES: throughput(case, TUNED, 0, silences=False),
    }
    took = time.perf_counter() - began
    pd.set_option("display.width", 250)
    pd.set_option("display.max_columns", 20)
    print(f"two AUVs circling the shark together; {DURATION / 3600:.0f} h, no initial range")
    print(settings_lines())
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    groups = table.groupby(["plan", "settings"], sort=False)
    summary = groups.mean(numeric_only=True).drop(columns=["seed", "filter_seed"])
    summary["auv_speed_max_m_s"] = groups["auv_speed_max_m_s"].max()  # over all seeds
    summary["worst_seed_auv_speed_p99_m_s"] = groups["auv_speed_p99_m_s"].max()
    summary["runs"] = groups.size()
    summary["worst_run_filtered_m"] = groups["filtered_m"].max()
    summary["runs_over_10_m"] = groups["filtered_m"].apply(lambda e: int((e >= 10.0).sum()))
    print(f"\nmean over {len(seeds)} seeds and the runs' filter seeds (worst run last)")
    print(summary.to_string(float_format=lambda v: f"{v:.3g}"))
    run_time_ratio = (TUNED["n_particles"] / speed["tuned"]) / (
        DEFAULT["n_particles"] / speed["default"]
    )
    print(
        f"\nthroughput, filter alone, {plan_label(PLANS[0])}, seed 0 (particle-steps/s): "
        + ", ".join(f"{k} {v / 1e6:.2f} M" for k, v in speed.items())
        + f"; tuned / default {speed['tuned'] / speed['default']:.2f}; "
        f"run time tuned / default {run_time_ratio:.2f}"
    )
    finished = (
        f"took {took:.0f} s (1-minute load at start {load:.1f}, at end {os.getloadavg()[0]:.1f})"
    )
    print(finished)
    if args.report is not None:
        args.report.write_text(
            "# Two AUVs on an observable plan: arrival-time filter against the paper's method\n\n"
            f"Written by `python benchmarks/bench_two_auv_plan.py --seeds {args.seeds} "
            f"--report {args.report}`; {finished}. Errors in metres, 2 h runs, no initial range "
            "for the arrival-time filter; the paper's range-rate method gets the true initial "
            "ranges and the best constant period, on the same detections. `filtered_m` / "
            "`smoothed_m`: mean error after convergence of the filter and of its 60 s "
            "fixed-lag smoother; `bound_*`: posterior Cramér–Rao bound (RMS from 10 min on).\n\n"
            + settings_lines()
            + f"\n\n## Mean over {len(seeds)} seeds (tuned: {len(TUNED_FILTER_SEEDS)} filter "
            "seeds each)\n\n"
            + markdown(summary.reset_index())
            + "\n\n## Every run\n\n"
            + markdown(table)
            + "\n\nThroughput of the filter alone (particle-steps/s), "
            + ", ".join(f"{k} {v / 1e6:.2f} M" for k, v in speed.items())
            + f"; run time tuned / default {run_time_ratio:.2f}.\n"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
