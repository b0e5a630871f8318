"""How well could any tracker do? Posterior Cramér–Rao bounds on issue 5's scenarios.

For each realistic-clock scenario the particle filters of ``bench_arrival.py`` run on (the
shark pursuit by two AUVs with "circling", right-angle "formation" and "paper" steering,
the same pursuit with three AUVs, the moored array of three receivers) and seed, it
computes :func:`hmmtrack.analysis.bounds.arrival_time_bound` over the first 2 h (as the filters
run) with the realised detections, four ways:

* clock unknown, the clock prior an integrated random walk fitted to the scenario's true
  emission times (:func:`hmmtrack.analysis.bounds.emission_clock_from_schedule`, jitter 65 µs),
  the prior of this model family closest to the truth's own clock (whose period rate is
  mean-reverting, so the fitted walk is a little looser over long horizons); from the
  arrival times only, and with the
  scenario's detection curve (hearing or missing each ping is information about the
  range; the arrival-time filter uses that curve too): the headline;
* clock unknown, the arrival-time filter's own clock model (period random walk
  0.3 ms per ping, phase steps 0.1 ms, period ± 8 ms), with the detection curve;
* clock known (the emission times given), with the detection curve.

The tag's prior is nearly-constant-velocity with ``q`` fitted to the true path
(:func:`hmmtrack.analysis.bounds.acceleration_psd_from_path` with 8 s windows, the tag's period),
and each arrival time has noise ``σ = sqrt(jitter² + calibration² + (GPS / c)²)``:
65 µs jitter, 0.1 ms receiver-clock calibration, GPS 1.5 m on the AUVs and 0.5 m on the
moorings (both treated as white noise, which only makes the bound smaller). It prints
the bound's RMS over the pings from 10 minutes to 2 h (``sqrt(mean(bound²))``, a lower
bound on the time-averaged RMS error) beside the arrival-time particle filter's RMS error
over the same window (run here as ``bench_arrival.py`` runs it: 3,000 particles, velocity
motion, 60 s smoother lag; ``--no-filter`` skips it) and its mean errors read from
``reports/clock_aware.md``, a sensitivity table (q, clock noise ×3 and ÷3, σ of the
filter's 3 ms), and a planning sweep of two AUVs circling the shark together
(:func:`hmmtrack.scenarios.clocks.rotating_pair`: radius, lap time, angle between them)
with their speeds, and runs the particle filter on three of those plans (``FILTER_PLANS``)
to see how close it comes. With ``--report`` it writes the tables and a figure (bound over
time).

    python benchmarks/bench_clock_bound.py [--seeds 3] [--no-filter]
        [--report reports/clock_bound.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
from bench_arrival import arrival_run, markdown, summarise, three_auv_pursuit
from bench_arrival import inputs as filter_inputs

from hmmtrack.analysis.bounds import (
    acceleration_psd_from_path,
    arrival_time_bound,
    emission_clock_from_schedule,
)
from hmmtrack.analysis.metrics import position_error
from hmmtrack.scenarios.clocks import (
    Multipath,
    WanderingPeriodClock,
    build_clock_scenario,
    moored_array,
    realistic_shark_pursuit,
    rotating_pair,
)
from hmmtrack.scenarios.detection import GpsNoise
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.clock import EmissionClockModel
from hmmtrack.tracking.measurement.detection import LogisticDetection

DURATION = 7200.0
SKIP = 600.0
JITTER = 65e-6
CALIBRATION = 100e-6
PERIOD = 8.0
#: the arrival-time filter's clock model (track_arrival_time's default)
FILTER_CLOCK = EmissionClockModel(PERIOD)
#: the flyable two-AUV plan drawn beside the cases (radius m, lap time s, separation deg)
PLAN = (30.0, 200.0, 135.0)
#: plans on which the particle filter is run too: PLAN, a slower one, and the geometry of
#: ``steering="formation"`` (70 m, 90°, one turn per 600 s) flown by the sweep's builder
FILTER_PLANS = (PLAN, (40.0, 300.0, 135.0), (70.0, 600.0, 90.0))
#: where the marker line starts the hand-written reading kept across reruns
READING_MARKER = "<!-- reading: kept when the script rewrites this file -->"

CASES = {
    "shark pursuit, 2 AUVs (circling)": (lambda s: realistic_shark_pursuit(s), 1.5),
    "shark pursuit, 2 AUVs (right-angle formation)": (
        lambda s: realistic_shark_pursuit(s, steering="formation"),
        1.5,
    ),
    "shark pursuit, 2 AUVs (paper formation)": (
        lambda s: realistic_shark_pursuit(s, steering="paper"),
        1.5,
    ),
    "diagnostic: same pursuit, 3 AUVs": (three_auv_pursuit, 1.5),
    "moored array, 3 receivers": (lambda s: moored_array(s), 0.5),
}


@dataclasses.dataclass
class BoundInputs:
    """What the bound needs from one scenario run, cut to the first ``DURATION`` s."""

    truth: pd.DataFrame
    receivers: pd.DataFrame
    heard: pd.DataFrame
    emissions: np.ndarray
    sound_speed: float
    start: float
    q: float
    sigma: float
    fitted_clock: EmissionClockModel
    detection: LogisticDetection


def bound_inputs(case, gps_sd: float) -> BoundInputs:
    sc = case.scenario
    emissions = case.emission_times[case.emission_times < sc.start + DURATION]
    pings = sc.pings
    heard = pings[pings["detected"] & (pings["ping"] < emissions.size)][["ping", "receiver"]]
    truth = sc.truth[sc.truth["time"] <= sc.start + DURATION + PERIOD]
    sigma = float(np.sqrt(JITTER**2 + CALIBRATION**2 + (gps_sd / sc.sound_speed) ** 2))
    return BoundInputs(
        truth=truth,
        receivers=sc.receivers_truth,
        heard=heard.reset_index(drop=True),
        emissions=emissions,
        sound_speed=sc.sound_speed,
        start=sc.start,
        q=acceleration_psd_from_path(truth, PERIOD),
        sigma=sigma,
        fitted_clock=emission_clock_from_schedule(emissions, JITTER),
        detection=case.detection_probability,
    )


def bound_table(inputs: BoundInputs, clock, *, q=None, sigma=None, detection=True):
    return arrival_time_bound(
        inputs.truth,
        inputs.receivers,
        inputs.heard,
        inputs.emissions,
        clock=clock,
        acceleration_psd=inputs.q if q is None else q,
        sigma=inputs.sigma if sigma is None else sigma,
        sound_speed=inputs.sound_speed,
        detection=inputs.detection if detection else None,
    )


def rms_after_skip(table: pd.DataFrame, inputs: BoundInputs, column: str) -> float:
    """``sqrt(mean(column²))`` over the pings from ``SKIP`` s on."""
    late = table.loc[table["time"] >= inputs.start + SKIP, column].to_numpy()
    return float(np.sqrt(np.mean(late**2)))


def filter_errors_here(case, seed: int) -> dict:
    """The arrival-time filter run as ``bench_arrival.py`` runs it: RMS errors (m) of the
    filter and its 60 s smoother from ``SKIP`` s on, and the paper's mean error after
    convergence (m) with the time to convergence (s)."""
    sc = case.scenario
    detections, _, common = filter_inputs(case, seed, 3000, "velocity", DURATION)
    result = arrival_run(detections, sc.receivers, common, smoothing_lag=60)
    paper_metric = summarise(result.estimates, sc.truth, result.smoothed)
    out = {
        "pf_after_convergence_m": paper_metric["error_after_convergence_m"],
        "pf_smoothed_after_convergence_m": paper_metric["smoothed_after_convergence_m"],
        "time_to_convergence_s": paper_metric["time_to_convergence_s"],
    }
    for label, estimates in (
        ("pf_rms_m", result.estimates),
        ("pf_smoothed_rms_m", result.smoothed),
    ):
        late = estimates[estimates["time"] >= sc.start + SKIP]
        out[label] = float(np.sqrt(np.mean(position_error(late, sc.truth) ** 2)))
    return out


def scaled_clock(clock: EmissionClockModel, factor: float) -> EmissionClockModel:
    """The same clock with every process-noise standard deviation times ``factor``."""
    return dataclasses.replace(
        clock,
        phase_step_sd=clock.phase_step_sd * factor,
        period_step_sd=clock.period_step_sd * factor,
        rate_step_sd=clock.rate_step_sd * factor,
    )


def filter_errors(path: Path) -> pd.DataFrame:
    """Per-run particle-filter errors (m) from bench_arrival's report, by scenario and seed."""
    if not path.exists():
        print(f"note: {path} not found; the particle-filter columns are left out")
        return pd.DataFrame(columns=["scenario", "seed"])
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| scenario | seed |"))
    rows = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split("|")])
    table = pd.DataFrame(rows[2:], columns=rows[0])
    out = []
    for (scenario, seed), group in table.groupby(["scenario", "seed"], sort=False):
        methods = dict(zip(group["method"], group.to_dict("records"), strict=True))
        if scenario.endswith(", true emission schedule given"):
            scenario = scenario.removeprefix("diagnostic: ").split(", true emission")[0]
        row = {"scenario": scenario, "seed": int(seed)}
        for method, record in methods.items():
            if method.startswith("arrival-time (no r0)"):
                row["pf_mean_after_10_min_m"] = float(record["error_after_10_min_m"])
                row["pf_smoothed_mean_after_10_min_m"] = float(record["smoothed_after_10_min_m"])
            elif method == "arrival-time, clock known":
                row["pf_clock_known_mean_after_10_min_m"] = float(record["error_after_10_min_m"])
        out.append(row)
    return pd.DataFrame(out).groupby(["scenario", "seed"], sort=False).first().reset_index()


def main_table(seeds, figure_runs, run_filter: bool) -> tuple[pd.DataFrame, pd.DataFrame]:
    """RMS bounds per scenario and seed (and the filter's RMS errors), the sensitivity rows,
    and the first seed's bound curves in ``figure_runs``."""
    rows, sensitivity = [], []
    for name, (make, gps_sd) in CASES.items():
        for seed in seeds:
            case = make(seed)
            inputs = bound_inputs(case, gps_sd)
            tables = {
                "fitted clock, arrivals only": bound_table(
                    inputs, inputs.fitted_clock, detection=False
                ),
                "fitted clock": bound_table(inputs, inputs.fitted_clock),
                "filter's clock": bound_table(inputs, FILTER_CLOCK),
                "clock known": bound_table(inputs, None),
            }
            if seed == seeds[0]:
                figure_runs[name] = tables
            row = {"scenario": name, "seed": seed, "q_m2_s3": inputs.q}
            row["sigma_ms"] = 1e3 * inputs.sigma
            row["fitted_rate_step_us"] = 1e6 * inputs.fitted_clock.rate_step_sd
            for label, table in tables.items():
                row[f"{label}: filter_m"] = rms_after_skip(table, inputs, "filter_position_m")
                row[f"{label}: smoother_m"] = rms_after_skip(table, inputs, "smoother_position_m")
                if label != "clock known":
                    row[f"{label}: smoother_clock_ms"] = 1e3 * rms_after_skip(
                        table, inputs, "smoother_emission_s"
                    )
            if run_filter:
                row.update(filter_errors_here(case, seed))
            rows.append(row)
            if "2 AUVs" in name and "paper" not in name:
                sensitivity += sensitivity_rows(name, seed, inputs)
    return pd.DataFrame(rows), pd.DataFrame(sensitivity)


def sensitivity_rows(name, seed, inputs) -> list[dict]:
    variants = {
        "as fitted": {},
        "q ×3": {"q": 3 * inputs.q},
        "q ÷3": {"q": inputs.q / 3},
        "clock noise ×3": {"clock": scaled_clock(inputs.fitted_clock, 3.0)},
        "clock noise ÷3": {"clock": scaled_clock(inputs.fitted_clock, 1 / 3)},
        "σ = 3 ms (the filter's)": {"sigma": 3e-3},
        "q ÷3 and clock noise ÷3": {
            "q": inputs.q / 3,
            "clock": scaled_clock(inputs.fitted_clock, 1 / 3),
        },
    }
    out = []
    for label, change in variants.items():
        clock = change.pop("clock", inputs.fitted_clock)
        table = bound_table(inputs, clock, **change)
        out.append(
            {
                "scenario": name,
                "seed": seed,
                "variant": label,
                "filter_m": rms_after_skip(table, inputs, "filter_position_m"),
                "smoother_m": rms_after_skip(table, inputs, "smoother_position_m"),
            }
        )
    return out


def formation_case(seed: int, radius: float, lap_time: float, separation: float):
    """The realistic pursuit's shark, two AUVs flying :func:`rotating_pair`."""
    truth = realistic_shark_pursuit(seed).scenario.truth
    tag = Trajectory(truth["time"].to_numpy(), truth["x"].to_numpy(), truth["y"].to_numpy())
    rng = np.random.default_rng([seed, 17])
    receivers = rotating_pair(
        tag,
        float(rng.uniform(-np.pi, np.pi)),
        radius=radius,
        lap_time=lap_time,
        separation=separation,
    )
    case = build_clock_scenario(
        rng,
        name="shark-pursuit-planning",
        description="Planning sweep: two AUVs circling the shark together.",
        tag=tag,
        receivers=receivers,
        clock=WanderingPeriodClock(PERIOD, 0.8, phase=float(rng.uniform(0, PERIOD))),
        detection=LogisticDetection(range_50=160.0, width=40.0),
        multipath=Multipath(),
        gps=GpsNoise(sd=1.5, correlation_time=60.0),
        start=float(tag.time[0]),
        end=float(tag.time[-1]),
    )
    window = tag.time < tag.time[0] + DURATION
    speeds = np.concatenate(
        [np.hypot(np.diff(r.x[window]), np.diff(r.y[window])) for r in receivers.values()]
    )
    return case, speeds


def planning_sweep(seeds, radii, lap_times, separations_deg) -> pd.DataFrame:
    rows = []
    for radius in radii:
        for lap_time in lap_times:
            for separation in separations_deg:
                for seed in seeds:
                    case, speeds = formation_case(seed, radius, lap_time, np.radians(separation))
                    inputs = bound_inputs(case, 1.5)
                    alone = bound_table(inputs, inputs.fitted_clock, detection=False)
                    fitted = bound_table(inputs, inputs.fitted_clock)
                    known = bound_table(inputs, None)
                    rows.append(
                        {
                            "radius_m": radius,
                            "lap_time_s": lap_time,
                            "separation_deg": separation,
                            "seed": seed,
                            "auv_speed_p99_m_s": np.quantile(speeds, 0.99),
                            "auv_speed_max_m_s": speeds.max(),
                            "detected_share": len(inputs.heard) / (2 * inputs.emissions.size),
                            "arrivals_only_filter_m": rms_after_skip(
                                alone, inputs, "filter_position_m"
                            ),
                            "arrivals_only_smoother_m": rms_after_skip(
                                alone, inputs, "smoother_position_m"
                            ),
                            "filter_m": rms_after_skip(fitted, inputs, "filter_position_m"),
                            "smoother_m": rms_after_skip(fitted, inputs, "smoother_position_m"),
                            "clock_known_filter_m": rms_after_skip(
                                known, inputs, "filter_position_m"
                            ),
                        }
                    )
    table = pd.DataFrame(rows)
    keys = ["radius_m", "lap_time_s", "separation_deg"]
    summary = table.groupby(keys, sort=False).mean(numeric_only=True).reset_index()
    summary["auv_speed_max_m_s"] = table.groupby(keys, sort=False)["auv_speed_max_m_s"].max().values
    summary["flyable"] = summary["auv_speed_p99_m_s"] <= 2.5
    return summary.drop(columns="seed")


#: the columns of the bound-against-filter table (the rest are in "Every run")
COMPACT = [
    "fitted clock, arrivals only: filter_m",
    "fitted clock, arrivals only: smoother_m",
    "fitted clock: filter_m",
    "fitted clock: smoother_m",
    "fitted clock: smoother_clock_ms",
    "filter's clock: filter_m",
    "clock known: filter_m",
    "pf_rms_m",
    "pf_smoothed_rms_m",
    "pf_mean_after_10_min_m",
    "pf_smoothed_mean_after_10_min_m",
    "pf_clock_known_mean_after_10_min_m",
]


def plan_curves(seed: int) -> dict:
    """Bound tables of the :data:`PLAN` geometry for one seed, as in the main table."""
    radius, lap_time, separation = PLAN
    case, _ = formation_case(seed, radius, lap_time, np.radians(separation))
    inputs = bound_inputs(case, 1.5)
    return {
        "fitted clock, arrivals only": bound_table(inputs, inputs.fitted_clock, detection=False),
        "fitted clock": bound_table(inputs, inputs.fitted_clock),
        "clock known": bound_table(inputs, None),
    }


def filter_on_plans(seeds) -> pd.DataFrame:
    """Bounds and the arrival-time particle filter's errors on :data:`FILTER_PLANS`."""
    rows = []
    for radius, lap_time, separation in FILTER_PLANS:
        for seed in seeds:
            case, _ = formation_case(seed, radius, lap_time, np.radians(separation))
            inputs = bound_inputs(case, 1.5)
            table = bound_table(inputs, inputs.fitted_clock)
            rows.append(
                {
                    "radius_m": radius,
                    "lap_time_s": lap_time,
                    "separation_deg": separation,
                    "seed": seed,
                    "bound_filter_m": rms_after_skip(table, inputs, "filter_position_m"),
                    "bound_smoother_m": rms_after_skip(table, inputs, "smoother_position_m"),
                    **filter_errors_here(case, seed),
                }
            )
    return pd.DataFrame(rows)


def plot_curves(curves: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(curves)
    n_rows = int(np.ceil(len(names) / 3))
    fig, axes = plt.subplots(n_rows, 3, figsize=(13, 3.4 * n_rows), sharey=True, sharex=True)
    axes = axes.ravel()
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    for ax, name in zip(axes, names, strict=False):
        tables = curves[name]
        start = tables["clock known"]["time"].iloc[0]
        for label, style in (
            ("fitted clock, arrivals only", "tab:orange"),
            ("fitted clock", "tab:red"),
            ("clock known", "tab:blue"),
        ):
            table = tables[label]
            minutes = (table["time"] - start) / 60
            ax.plot(minutes, table["filter_position_m"], color=style, lw=0.8, label=f"{label}")
            ax.plot(minutes, table["smoother_position_m"], color=style, lw=0.8, ls="--")
        ax.axhline(10.0, color="k", lw=0.6)
        ax.set_yscale("log")
        ax.set_ylim(0.3, 300)
        ax.set_title(name.replace("shark pursuit, ", "").replace("diagnostic: ", ""), fontsize=9)
        ax.set_xlabel("time since start (min)")
    for ax in axes[::3]:
        ax.set_ylabel("position bound √tr (m)\nsolid: filtering, dashed: smoothing")
    axes[0].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def mean_over_seeds(table: pd.DataFrame, keys) -> pd.DataFrame:
    return table.groupby(keys, sort=False).mean(numeric_only=True).reset_index()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--sweep-seeds", type=int, default=2)
    parser.add_argument(
        "--no-filter", action="store_true", help="skip the particle-filter runs (RMS errors)"
    )
    parser.add_argument("--filter-report", type=Path, default=Path("reports/clock_aware.md"))
    parser.add_argument("--report", type=Path, default=None, help="write Markdown + a PNG")
    args = parser.parse_args(argv)
    began = time.perf_counter()
    load = os.getloadavg()[0]
    seeds = list(range(args.seeds))
    curves: dict = {}
    bounds, sensitivity = main_table(seeds, curves, not args.no_filter)
    radius, lap_time, separation = PLAN
    plan_name = f"plan: 2 AUVs, {radius:.0f} m, {separation:.0f}°, lap {lap_time:.0f} s"
    curves[plan_name] = plan_curves(seeds[0])
    pf = filter_errors(args.filter_report)
    runs = bounds.merge(pf, on=["scenario", "seed"], how="left")
    summary = mean_over_seeds(runs, ["scenario"]).drop(columns="seed")
    compact = summary[["scenario"] + [c for c in COMPACT if c in summary]]
    sensitivity_summary = mean_over_seeds(sensitivity, ["scenario", "variant"]).drop(columns="seed")
    on_plans = pd.DataFrame() if args.no_filter else filter_on_plans(seeds)
    sweep = planning_sweep(
        list(range(args.sweep_seeds)),
        radii=(30.0, 40.0, 55.0, 70.0, 100.0, 130.0),
        lap_times=(200.0, 300.0, 450.0, 600.0, 900.0),
        separations_deg=(90, 135, 180),
    )
    took = time.perf_counter() - began
    pd.set_option("display.width", 250)
    pd.set_option("display.max_columns", 40)
    plans_summary = (
        mean_over_seeds(on_plans, ["radius_m", "lap_time_s", "separation_deg"]).drop(columns="seed")
        if len(on_plans)
        else on_plans
    )
    for table in (compact, sensitivity_summary, sweep, plans_summary):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"took {took:.0f} s (1-minute load at start {load:.1f}, at end {os.getloadavg()[0]:.1f})")
    if args.report:
        figure = args.report.with_suffix(".png")
        plot_curves(curves, figure)
        write_report(
            args.report,
            figure,
            {
                "compact": compact,
                "runs": runs,
                "sensitivity": sensitivity_summary,
                "sweep": sweep,
                "plans": plans_summary,
                "plan_runs": on_plans,
            },
            seeds,
            args,
            took,
        )
    return 0


def write_report(path, figure, tables: dict, seeds, args, took) -> None:
    reading = ""
    if path.exists():
        text = path.read_text()
        if READING_MARKER in text:
            reading = text[text.index(READING_MARKER) :]
    parts = [
        "# How well could any tracker do? Posterior Cramér–Rao bounds for issue 5",
        "",
        f"Written by `python benchmarks/bench_clock_bound.py --seeds {len(seeds)} "
        f"--report {path}` ({took:.0f} s). Bounds are the square root of the trace of the "
        "position block (m) at each ping, given as its RMS over the pings from 10 min to 2 h "
        "(a lower bound on the RMS position error over that window); `*_clock_ms` is the "
        "same for the emission time (ms). `pf_rms_m` and `pf_smoothed_rms_m` are the "
        "arrival-time particle filter's and its 60 s smoother's RMS errors over the same "
        "window, run by this script; `pf_*mean*` are mean Euclidean errors over the same "
        f"window read from `{args.filter_report}` (the paper's metric). "
        "How q, σ and the clock prior are chosen: see the script's docstring and the "
        "reading below.",
        "",
        "## Bounds beside the particle filter (mean over seeds)",
        "",
        "`fitted clock`: clock unknown, prior fitted to the true schedule, with the "
        "detection curve; `arrivals only`: the same without the detection curve; "
        "`filter's clock`: the arrival-time filter's clock model, with the detection curve; "
        "`clock known`: with the detection curve. All columns per seed, with q, σ and the "
        'fitted clock, are under "Every run". `nan` in a `pf_*` column: no such run in '
        f"`{args.filter_report}` (it has clock-known runs for two geometries only).",
        "",
        markdown(tables["compact"]),
        "",
        "## Sensitivity of the bound to its priors (two-AUV cases, fitted clock and detection "
        "curve, mean over seeds)",
        "",
        markdown(tables["sensitivity"]),
        "",
        f"## Planning sweep: two AUVs circling the shark together (mean over "
        f"{args.sweep_seeds} seeds, fitted clock)",
        "",
        "`filter_m`, `smoother_m`: with the detection curve; `arrivals_only_*`: without; "
        "`clock_known_filter_m`: emission times given, with the detection curve.",
        "",
        "`flyable`: 99 % of the AUVs' 1 s speeds ≤ 2.5 m/s.",
        "",
        markdown(tables["sweep"]),
        "",
        f"![bound over time, seed {seeds[0]}]({figure.name})",
        "",
    ]
    if len(tables["plans"]):
        parts += [
            "## The particle filter on planned geometries (mean over seeds)",
            "",
            "Bounds (fitted clock, detection curve) beside the arrival-time filter run on "
            "the same plans (3,000 particles, velocity motion, 60 s smoother lag); "
            "`pf_*after_convergence_m` is the paper's metric (mean error after "
            'convergence). 70 m, 90°, 600 s is the geometry of `steering="formation"`.',
            "",
            markdown(tables["plans"]),
            "",
        ]
    parts += ["## Every run", "", markdown(tables["runs"]), ""]
    if len(tables["plans"]):
        parts += ["### Planned geometries, every run", "", markdown(tables["plan_runs"]), ""]
    path.write_text("\n".join(parts) + ("\n" + reading if reading else ""))


if __name__ == "__main__":
    raise SystemExit(main())
