"""Two AUVs steered on the filter's estimate against the same plan steered on the truth.

The two-AUV study (:mod:`hmmtrack.experiments.two_auv_plan`) measures the
``two-moving-receivers`` preset on the observable plan
(:class:`hmmtrack.scenarios.steering.RotatingPlan`), whose stations are placed from the
true shark track. Here :func:`hmmtrack.experiments.closed_loop.fly_closed_loop` flies the
same plan twice on each scenario of
:func:`hmmtrack.scenarios.realistic.realistic_shark_pursuit` (``steering="observable"``),
with the preset's filter stepped online:

* open loop: stations around the true shark (``steer_on="truth"``), the scenario's own
  AUV paths and detections;
* closed loop: stations around the filter's estimate, ``latency`` s old, carried forward by
  the lead velocity (``steer_on="estimate"``), AUVs capped at :data:`MAX_SPEED`.

Both runs use the preset without the detection curve (missed pings carry no information:
the online filter cannot know which pings will still arrive) and the same filter seed.
Each run is scored by the mean error after convergence (the paper's metric), its first and
last 30 minutes, the time to convergence, the 60 s fixed-lag smoothed error (an offline
rerun on the run's detections, which also checks that the online filter equals the
offline one), the AUVs' geometry at the true shark from :data:`SETTLED` s on, and the
posterior Cramér–Rao bound on the geometry flown.

:func:`closed_loop_study` returns the tables; ``hmmtrack study closed-loop`` writes them
(``reports/closed_loop.md``).
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd

from hmmtrack.analysis.metrics import position_error
from hmmtrack.experiments.clock_bound import AUV_GPS, bound_inputs, bound_table, rms_after_skip
from hmmtrack.experiments.clock_runs import DURATION, config_options, score_run, track_arrival
from hmmtrack.experiments.closed_loop import arrival_time_tracker, fly_closed_loop
from hmmtrack.experiments.configs import arrival_config
from hmmtrack.scenarios.realistic import realistic_shark_pursuit
from hmmtrack.scenarios.steering import RotatingPlan
from hmmtrack.tracking.config import TrackingConfig, merge_settings, nest, read_preset
from hmmtrack.tracking.measurement.clock import to_common_time

#: the plan flown (``steering="observable"``)
PLAN = RotatingPlan()
#: the bundled preset whose filter is stepped online
PRESET = "two-moving-receivers"
#: the named filter stepped online (:data:`hmmtrack.tracking.filter.FILTERS`): the paper's,
#: without acquisition (undefined online) and as closed_loop.md was measured
CLOSED_LOOP_FILTER = "paper"
SMOOTHING_LAG = 60
#: geometry and errors are measured from this many seconds on
SETTLED = 300
#: the AUVs' speed cap (m/s)
MAX_SPEED = 3.0
#: steer_on of each mode
MODES = {"open loop (truth)": "truth", "closed loop (estimate)": "estimate"}


def preset_config(case, n_particles: int | None = None, duration=DURATION) -> TrackingConfig:
    """The preset on ``case`` over the first ``duration`` seconds (with ``n_particles``
    instead of the preset's when given), without the detection curve (module docstring) and
    with the paper's filter: the loop steps its filter online, where the default filter's
    acquisition (from the first corrections) is undefined, and ``closed_loop.md`` was
    measured with it."""
    particles = nest({"n_particles": n_particles, "filter": CLOSED_LOOP_FILTER})
    settings = merge_settings(read_preset(PRESET), particles)
    return arrival_config(case, settings, duration, silences=False)


def geometry(run, truth: pd.DataFrame, duration=DURATION) -> dict:
    """The AUVs' distance (m) and angle (deg) at the true shark, and their speeds (m/s),
    from :data:`SETTLED` s on."""
    shark = truth.iloc[: int(duration) + 2][["x", "y"]].to_numpy()
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


def bound_rms(case, run, duration=DURATION) -> dict:
    """Posterior Cramér–Rao bound (RMS from 10 min on, m) of the filter and the smoother on
    the geometry ``run`` flew and the pings it heard (fitted clock, detection curve, AUV GPS
    error; :mod:`hmmtrack.experiments.clock_bound`)."""
    flown = dataclasses.replace(
        case,
        scenario=dataclasses.replace(
            case.scenario, receivers_truth=run.receivers_truth, pings=run.pings
        ),
    )
    inputs = bound_inputs(flown, AUV_GPS, duration)
    table = bound_table(inputs, inputs.fitted_clock)
    return {
        "bound_filter_rms_m": rms_after_skip(table, inputs, "filter_position_m"),
        "bound_smoother_rms_m": rms_after_skip(table, inputs, "smoother_position_m"),
    }


def offline_rerun(case, run, config: TrackingConfig, filter_seed: int):
    """The preset's filter and 60 s smoother rerun offline on ``run``'s detections."""
    detections = to_common_time(run.detections, case.clock_calibration)
    detections = detections[detections["time"] < config.end].reset_index(drop=True)
    options = config_options(config) | {"smoothing_lag": SMOOTHING_LAG, "seed": filter_seed}
    return track_arrival(detections, run.receivers, options)


def run_rows(seed: int, filter_seeds, latency: float, n_particles, duration=DURATION):
    """Both modes on scenario ``seed`` with each filter seed: the rows, and for the first
    filter seed each mode's error series ``(elapsed s, error m)`` (for the figure)."""
    case = realistic_shark_pursuit(seed, steering="observable")
    truth = case.scenario.truth
    config = preset_config(case, n_particles, duration)
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
                    duration=duration,
                    max_speed=MAX_SPEED,
                    latency=latency,
                    seed=seed,
                )
            wall = time.perf_counter() - tic
            offline = offline_rerun(case, run, config, filter_seed)
            paper = score_run(run.estimates, truth, offline.smoothed)
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
                    **geometry(run, truth, duration),
                    **bound_rms(case, run, duration),
                    "reinitialised": int((run.events["kind"] == "degenerate_weights").sum()),
                    "online_vs_offline_m": online_vs_offline,
                    "loop_s": wall,
                }
            )
    return rows, series


def summary_table(table: pd.DataFrame) -> pd.DataFrame:
    """Mean per mode over the runs, with the worst run and the runs over 10 m."""
    groups = table.groupby("mode", sort=False)
    summary = groups.mean(numeric_only=True).drop(columns=["seed", "filter_seed"])
    summary["runs"] = groups.size()
    summary["worst_run_filtered_m"] = groups["filtered_m"].max()
    summary["runs_over_10_m"] = groups["filtered_m"].apply(lambda e: int((e >= 10.0).sum()))
    summary["auv_speed_max_m_s"] = groups["auv_speed_max_m_s"].max()
    return summary.reset_index()


@dataclasses.dataclass(frozen=True)
class ClosedLoopStudy:
    """What :func:`closed_loop_study` returns.

    Attributes
    ----------
    runs : pandas.DataFrame
        One row per scenario seed, filter seed and mode.
    summary : pandas.DataFrame
        :func:`summary_table`.
    series : dict of str to (numpy.ndarray, numpy.ndarray)
        The first scenario's error over time per mode: elapsed (s), error (m).
    loop_ratio : float
        Mean loop run time, closed over open.
    """

    runs: pd.DataFrame
    summary: pd.DataFrame
    series: dict
    loop_ratio: float


def closed_loop_study(
    seeds: Sequence[int],
    *,
    filter_seeds: int = 1,
    latency: float = 2.0,
    n_particles: int | None = None,
    duration: float = DURATION,
) -> ClosedLoopStudy:
    """Both modes on every scenario seed, with ``filter_seeds`` filter seeds each.

    Parameters
    ----------
    seeds : sequence of int
        Scenario seeds.
    filter_seeds : int
        Filter seeds per scenario: ``seed``, ``seed + 100``, ...
    latency : float
        s (:func:`~hmmtrack.experiments.closed_loop.fly_closed_loop`'s).
    n_particles : int, optional
        Default: the preset's.
    duration : float
        Length of each run (s).
    """
    offsets = [100 * k for k in range(filter_seeds)]
    rows, first_series = [], None
    for seed in seeds:
        seed_rows, series = run_rows(
            seed, [seed + offset for offset in offsets], latency, n_particles, duration
        )
        rows += seed_rows
        first_series = first_series or series
    table = pd.DataFrame(rows)
    loop = table.groupby("mode")["loop_s"].mean()
    return ClosedLoopStudy(
        runs=table,
        summary=summary_table(table),
        series=first_series,
        loop_ratio=float(loop["closed loop (estimate)"] / loop["open loop (truth)"]),
    )
