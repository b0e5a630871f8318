"""Two AUVs steered on the filter's estimate against the same plan steered on the truth.

``bench_two_auv_plan.py`` measures the ``two-moving-receivers`` preset on the observable
plan (:class:`hmmtrack.scenarios.clocks.RotatingPlan`: stations 27 m from the shark, 135°
apart, one lap per 150 s, led by the shark's recent velocity), whose stations are placed
from the true shark track. Here :func:`hmmtrack.experiments.closed_loop.fly_closed_loop` flies the
same plan twice on each scenario of :func:`hmmtrack.scenarios.clocks.realistic_shark_pursuit`
(``steering="observable"``), with the preset's filter stepped online:

* open loop: stations around the true shark (``steer_on="truth"``), the scenario's own
  AUV paths and detections;
* closed loop: stations around the filter's estimate, 2 s old, carried forward by the
  lead velocity (``steer_on="estimate"``), AUVs capped at 3 m/s.

Both runs use the preset without the detection curve (missed pings carry no information:
the online filter cannot know which pings will still arrive; ``hmmtrack track --preset``
runs it so too) and the same filter seed. Per run the script prints the mean error after
convergence (the paper's metric), its first and last 30 minutes, the time to convergence,
the 60 s fixed-lag smoothed error (an offline rerun on the run's detections, which also
checks that the online filter equals the offline one), and the AUVs' geometry measured
at the true shark from 5 min on: distance (median, 5-95 %) and the angle between the two
(median, 5th percentile), speeds (99th percentile, largest) and the share of 1 s steps at
the speed cap, and the posterior Cramér–Rao bound on the geometry flown (as in
``bench_clock_bound.py``); then a summary (mean, worst run, runs over 10 m) and a figure
of the error over time for the first scenario. Not a test: it measures.

    python benchmarks/bench_closed_loop.py [--seeds 3] [--filter-seeds 1]
        [--report reports/closed_loop.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from bench_arrival import markdown, summarise
from bench_clock_bound import bound_inputs, bound_table, rms_after_skip

from hmmtrack.analysis.metrics import position_error
from hmmtrack.experiments.closed_loop import arrival_time_tracker, fly_closed_loop
from hmmtrack.scenarios.clocks import RotatingPlan, realistic_shark_pursuit
from hmmtrack.tracking.config import TrackingConfig, read_preset
from hmmtrack.tracking.measurement.clock import to_common_time
from hmmtrack.tracking.pipeline import track

#: the plan flown (``steering="observable"``)
PLAN = RotatingPlan()
PRESET = "two-moving-receivers"
DURATION = 7200
SMOOTHING_LAG = 60
#: geometry and errors are measured from this many seconds on
SETTLED = 300
MAX_SPEED = 3.0
#: steer_on of each mode
MODES = {"open loop (truth)": "truth", "closed loop (estimate)": "estimate"}
READING_MARKER = "<!-- reading: kept when the script rewrites this file -->"


def preset_config(case, n_particles: int | None = None) -> TrackingConfig:
    """The preset on ``case`` over the first ``DURATION`` seconds (with ``n_particles``
    instead of the preset's when given)."""
    particles = {} if n_particles is None else {"n_particles": n_particles}
    return case.arrival_config(read_preset(PRESET) | particles, DURATION)


def geometry(run, truth: pd.DataFrame) -> dict:
    """The AUVs' distance and angle at the true shark, and their speeds, from ``SETTLED`` s."""
    shark = truth.iloc[: DURATION + 2][["x", "y"]].to_numpy()
    offset, speed = {}, []
    for name, path in run.receivers_truth.groupby("receiver"):
        xy = path[["x", "y"]].to_numpy()
        offset[name] = (xy[:, 0] - shark[:, 0]) + 1j * (xy[:, 1] - shark[:, 1])
        speed.append(np.hypot(*np.diff(xy, axis=0).T))
    distance = np.abs(np.concatenate([o[SETTLED:] for o in offset.values()]))
    angle = np.degrees(np.abs(np.angle(offset["auv-2"] / offset["auv-1"])))[SETTLED:]
    speed = np.concatenate(speed)
    return {
        "auv_distance_p5_m": np.quantile(distance, 0.05),
        "auv_distance_median_m": np.median(distance),
        "auv_distance_p95_m": np.quantile(distance, 0.95),
        "auv_angle_median_deg": np.median(angle),
        "auv_angle_p5_deg": np.quantile(angle, 0.05),
        "auv_speed_p99_m_s": np.quantile(speed, 0.99),
        "auv_speed_max_m_s": speed.max(),
        "at_speed_cap_share": float(np.mean(speed >= MAX_SPEED - 1e-9)),
    }


def bound_rms(case, run) -> dict:
    """Posterior Cramér–Rao bound (RMS from 10 min on, m) of the filter and the smoother on
    the geometry ``run`` flew and the pings it heard (``bench_clock_bound.py``'s inputs:
    fitted clock, detection curve, 1.5 m GPS)."""
    flown = dataclasses.replace(
        case,
        scenario=dataclasses.replace(
            case.scenario, receivers_truth=run.receivers_truth, pings=run.pings
        ),
    )
    inputs = bound_inputs(flown, 1.5)
    table = bound_table(inputs, inputs.fitted_clock)
    return {
        "bound_filter_rms_m": rms_after_skip(table, inputs, "filter_position_m"),
        "bound_smoother_rms_m": rms_after_skip(table, inputs, "smoother_position_m"),
    }


def smoothed(case, run, config: TrackingConfig, filter_seed: int):
    """The preset's filter and 60 s smoother rerun offline on ``run``'s detections."""
    sc = case.scenario
    end = sc.start + DURATION
    detections = to_common_time(run.detections, case.clock_calibration)
    detections = detections[detections["time"] < end].reset_index(drop=True)
    return track(
        detections,
        run.receivers,
        config,
        config.motion_model(),
        smoothing_lag=SMOOTHING_LAG,
        seed=filter_seed,
    )


def run_rows(seed: int, filter_seeds, latency: float, n_particles) -> tuple[list[dict], dict]:
    """Both modes on scenario ``seed`` with each filter seed; rows and, for the first
    filter seed, the error series of each mode (for the figure)."""
    case = realistic_shark_pursuit(seed, steering="observable")
    truth = case.scenario.truth
    config = preset_config(case, n_particles)
    rows, series = [], {}
    for filter_seed in filter_seeds:
        for mode, steer_on in MODES.items():
            tic = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # recorded in run.events
                run = fly_closed_loop(
                    case,
                    PLAN,
                    arrival_time_tracker(config, filter_seed),
                    steer_on=steer_on,
                    duration=DURATION,
                    max_speed=MAX_SPEED,
                    latency=latency,
                    seed=seed,
                )
            wall = time.perf_counter() - tic
            offline = smoothed(case, run, config, filter_seed)
            paper = summarise(run.estimates, truth, offline.smoothed)
            online_vs_offline = float(
                np.abs(run.estimates[["x", "y"]].to_numpy() - offline.estimates[["x", "y"]])
                .max()
                .max()
            )
            error = position_error(run.estimates, truth)
            if filter_seed == filter_seeds[0]:
                series[mode] = (run.estimates["time"].to_numpy() - case.scenario.start, error)
            rows.append(
                {
                    "mode": mode,
                    "seed": seed,
                    "filter_seed": filter_seed,
                    "filtered_m": paper["error_after_convergence_m"],
                    "smoothed_m": paper["smoothed_after_convergence_m"],
                    "convergence_s": paper["time_to_convergence_s"],
                    "first_30_min_m": paper["first_30_min_m"],
                    "last_30_min_m": paper["last_30_min_m"],
                    "max_error_after_5_min_m": float(error[SETTLED:].max()),
                    **geometry(run, truth),
                    **bound_rms(case, run),
                    "reinitialised": int((run.events["kind"] == "degenerate_weights").sum()),
                    "online_vs_offline_m": online_vs_offline,
                    "loop_s": wall,
                }
            )
            print(
                f"seed {seed} filter {filter_seed} {mode}: {rows[-1]['filtered_m']:.2f} m "
                f"(smoothed {rows[-1]['smoothed_m']:.2f} m), loop {wall:.1f} s",
                flush=True,
            )
    return rows, series


def plot_errors(series: dict, seed: int, path: Path) -> None:
    """Error over time of each mode (1 s and its 60 s running mean)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    for (mode, (elapsed, error)), colour in zip(series.items(), ("C0", "C3"), strict=False):
        minutes = elapsed / 60.0
        mean = pd.Series(error).rolling(60, min_periods=1, center=True).mean()
        ax.plot(minutes, error, color=colour, alpha=0.25, lw=0.5)
        ax.plot(minutes, mean, color=colour, lw=1.5, label=f"{mode}, 60 s mean")
    ax.axhline(10.0, color="k", lw=0.8, ls="--", label="10 m")
    ax.set(
        xlabel="time since start (min)",
        ylabel="filter error (m)",
        ylim=(0, 40),
        title=f"Observable plan, seed {seed}: AUVs steered on the truth vs on the estimate",
    )
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def summary_table(table: pd.DataFrame) -> pd.DataFrame:
    """Mean per mode over the runs, with the worst run and the runs over 10 m."""
    groups = table.groupby("mode", sort=False)
    summary = groups.mean(numeric_only=True).drop(columns=["seed", "filter_seed"])
    summary["runs"] = groups.size()
    summary["worst_run_filtered_m"] = groups["filtered_m"].max()
    summary["runs_over_10_m"] = groups["filtered_m"].apply(lambda e: int((e >= 10.0).sum()))
    summary["auv_speed_max_m_s"] = groups["auv_speed_max_m_s"].max()
    return summary.reset_index()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--filter-seeds", type=int, default=1, help="filter seeds per scenario")
    parser.add_argument("--latency", type=float, default=2.0, help="s (fly_closed_loop's)")
    parser.add_argument("--n-particles", type=int, default=None, help="default: the preset's")
    parser.add_argument("--report", type=Path, default=None, help="write a Markdown report")
    args = parser.parse_args(argv)
    began, load = time.perf_counter(), os.getloadavg()[0]
    filter_seeds = [100 * k for k in range(args.filter_seeds)]
    rows, first_series = [], None
    for seed in range(args.seeds):
        seed_rows, series = run_rows(
            seed, [seed + offset for offset in filter_seeds], args.latency, args.n_particles
        )
        rows += seed_rows
        first_series = first_series or series
    table = pd.DataFrame(rows)
    summary = summary_table(table)
    loop_ratio = (
        table.loc[table["mode"] == "closed loop (estimate)", "loop_s"].mean()
        / table.loc[table["mode"] == "open loop (truth)", "loop_s"].mean()
    )
    took = time.perf_counter() - began
    finished = (
        f"took {took:.0f} s (1-minute load at start {load:.1f}, at end {os.getloadavg()[0]:.1f})"
    )
    pd.set_option("display.width", 250)
    pd.set_option("display.max_columns", 30)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"loop run time, closed / open: {loop_ratio:.2f}; {finished}")
    if args.report is not None:
        figure = args.report.with_suffix(".png")
        plot_errors(first_series, 0, figure)
        reading = ""
        if args.report.exists() and READING_MARKER in args.report.read_text():
            reading = args.report.read_text().split(READING_MARKER, 1)[1]
        args.report.write_text(
            "# Two AUVs steered on the filter's estimate (closed loop)\n\n"
            f"Written by `python benchmarks/bench_closed_loop.py --seeds {args.seeds} "
            f"--filter-seeds {args.filter_seeds} --latency {args.latency:g}"
            + ("" if args.n_particles is None else f" --n-particles {args.n_particles}")
            + f" --report {args.report}`; {finished}. "
            f"`{PRESET}` preset without the detection curve, {DURATION / 3600:.0f} h, "
            "no initial range, the observable plan "
            f"({PLAN.describe()}); open loop: stations around the true shark; closed loop: "
            f"around the filter's online estimate ({args.latency:g} s old, carried forward by "
            f"the lead velocity), AUVs capped at {MAX_SPEED:g} m/s "
            "(`hmmtrack.experiments.closed_loop.fly_closed_loop`). Errors in metres; `filtered_m`: "
            "mean error after convergence; `smoothed_m`: the 60 s fixed-lag smoother rerun "
            f"offline; geometry at the true shark from {SETTLED} s on.\n\n"
            "## Summary\n\n"
            + markdown(summary)
            + f"\n\nLoop run time, closed / open: {loop_ratio:.2f}.\n\n"
            f"![error over time, seed 0]({figure.name})\n\n## Every run\n\n"
            + markdown(table)
            + "\n\n"
            + READING_MARKER
            + reading
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
