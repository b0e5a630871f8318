"""How well could any tracker do? Posterior Cramér–Rao bounds on the clock study's cases.

For each realistic-clock case the clock study runs (:mod:`hmmtrack.experiments.arrival`:
the shark pursuit by two AUVs with "circling", right-angle "formation" and "paper"
steering, the same pursuit with three AUVs, the moored array of three receivers) and
seed, :func:`hmmtrack.analysis.crb.arrival_time_bound` is computed over the first 2 h
(as the filters run) with the realised detections, four ways:

* clock unknown, the clock prior an integrated random walk fitted to the scenario's true
  emission times (:func:`hmmtrack.analysis.crb.emission_clock_from_schedule`, jitter
  65 µs), the prior of this model family closest to the truth's own clock (whose period
  rate is mean-reverting, so the fitted walk is a little looser over long horizons); from
  the arrival times only, and with the scenario's detection curve (hearing or missing each
  ping is information about the range; the arrival-time filter uses that curve too);
* clock unknown, the arrival-time filter's own clock model (:data:`FILTER_CLOCK`), with the
  detection curve;
* clock known (the emission times given), with the detection curve.

The tag's prior is nearly-constant-velocity with ``q`` fitted to the true path
(:func:`hmmtrack.analysis.crb.acceleration_psd_from_path` with 8 s windows, the tag's
period), and each arrival time has noise ``σ = sqrt(jitter² + calibration² + (GPS / c)²)``:
65 µs jitter, 0.1 ms receiver-clock calibration, GPS 1.5 m on the AUVs and 0.5 m on the
moorings (both treated as white noise, which only makes the bound smaller). A bound is
given as its RMS over the pings from 10 minutes on (``sqrt(mean(bound²))``, a lower bound
on the time-averaged RMS error), beside the arrival-time filter's RMS error over the same
window (:func:`filter_errors`); the study adds a sensitivity table (q, clock noise ×3 and
÷3, σ of the filter's 3 ms), a planning sweep of two AUVs circling the shark together
(:func:`hmmtrack.scenarios.realistic.rotating_pair_pursuit`: radius, lap time, angle) with
their speeds, and the particle filter on three of those plans (:data:`FILTER_PLANS`).

:func:`clock_bound_study` returns the tables; ``hmmtrack study clock-bound`` writes them
(``reports/clock_bound.md``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pandas as pd

from hmmtrack.analysis.crb import (
    acceleration_psd_from_path,
    arrival_time_bound,
    emission_clock_from_schedule,
)
from hmmtrack.experiments.clock_runs import (
    DURATION,
    SKIP,
    auv_speeds,
    clock_inputs,
    rms_error_from,
    score_run,
    track_arrival,
)
from hmmtrack.scenarios.clocks import ClockScenario
from hmmtrack.scenarios.realistic import (
    moored_array,
    realistic_shark_pursuit,
    rotating_pair_pursuit,
    three_auv_pursuit,
)
from hmmtrack.tracking.measurement.clock import EmissionClockModel
from hmmtrack.tracking.measurement.detection import LogisticDetection

#: the tag's emission jitter (s), as the scenarios draw it
JITTER = 65e-6
#: the receiver-clock calibration's residual error (s), as the scenarios draw it
CALIBRATION = 100e-6
#: the tag's nominal period (s)
PERIOD = 8.0
#: the arrival-time filter's clock model (``track_arrival_time``'s default)
FILTER_CLOCK = EmissionClockModel(PERIOD)
#: the flyable two-AUV plan drawn beside the cases (radius m, lap time s, separation deg)
PLAN = (30.0, 200.0, 135.0)
#: plans on which the particle filter is run too: PLAN, a slower one, and the geometry of
#: ``steering="formation"`` (70 m, 90°, one turn per 600 s) flown by the sweep's builder
FILTER_PLANS = (PLAN, (40.0, 300.0, 135.0), (70.0, 600.0, 90.0))
#: the planning sweep's grid: radii (m), lap times (s), separations (deg)
SWEEP = (
    (30.0, 40.0, 55.0, 70.0, 100.0, 130.0),
    (200.0, 300.0, 450.0, 600.0, 900.0),
    (90, 135, 180),
)
#: the filter's particles in the study's filter runs
FILTER_PARTICLES = 3000
#: GPS error (m) of the AUVs
AUV_GPS = 1.5

#: name -> (case for a seed, GPS error of its receivers in m)
CASES = {
    "shark pursuit, 2 AUVs (circling)": (lambda s: realistic_shark_pursuit(s), AUV_GPS),
    "shark pursuit, 2 AUVs (right-angle formation)": (
        lambda s: realistic_shark_pursuit(s, steering="formation"),
        AUV_GPS,
    ),
    "shark pursuit, 2 AUVs (paper formation)": (
        lambda s: realistic_shark_pursuit(s, steering="paper"),
        AUV_GPS,
    ),
    "diagnostic: same pursuit, 3 AUVs": (three_auv_pursuit, AUV_GPS),
    "moored array, 3 receivers": (lambda s: moored_array(s), 0.5),
}


@dataclasses.dataclass
class BoundInputs:
    """What the bound needs from one case, cut to the first ``duration`` seconds.

    Attributes
    ----------
    truth, receivers : pandas.DataFrame
        The tag's and the receivers' true paths.
    heard : pandas.DataFrame
        ``ping``, ``receiver`` of every detection.
    emissions : numpy.ndarray, shape (n_pings,)
        True emission times (s).
    sound_speed, start : float
        m/s, s.
    q : float
        Acceleration PSD fitted to the path (m²/s³).
    sigma : float
        Arrival-time noise (s).
    fitted_clock : EmissionClockModel
        The clock prior fitted to the true emissions.
    detection : LogisticDetection
    """

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


def bound_inputs(case: ClockScenario, gps_sd: float, duration: float = DURATION) -> BoundInputs:
    """The bound's inputs for ``case`` whose receivers' positions err by ``gps_sd`` m."""
    sc = case.scenario
    emissions = case.emission_times[case.emission_times < sc.start + duration]
    pings = sc.pings
    heard = pings[pings["detected"] & (pings["ping"] < emissions.size)][["ping", "receiver"]]
    truth = sc.truth[sc.truth["time"] <= sc.start + duration + PERIOD]
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
    """:func:`hmmtrack.analysis.crb.arrival_time_bound` on ``inputs`` with ``clock`` (None:
    known) and, where given, another ``q`` or ``sigma``; ``detection=False`` leaves the
    detection curve out."""
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
    """``sqrt(mean(column²))`` over the pings from :data:`SKIP` s on."""
    late = table.loc[table["time"] >= inputs.start + SKIP, column].to_numpy()
    return float(np.sqrt(np.mean(late**2)))


def filter_errors(
    case: ClockScenario, seed: int, n_particles: int = FILTER_PARTICLES, duration=DURATION
) -> dict:
    """The arrival-time filter as the clock-aware study runs it (velocity motion, 60 s
    smoother): RMS errors (m) of the filter and the smoother from :data:`SKIP` s on, and the
    paper's mean error after convergence (m) with the time to convergence (s)."""
    sc = case.scenario
    detections, _, options = clock_inputs(case, seed, n_particles, "velocity", duration)
    result = track_arrival(detections, sc.receivers, options | {"smoothing_lag": 60})
    paper_metric = score_run(result.estimates, sc.truth, result.smoothed)
    return {
        "pf_after_convergence_m": paper_metric["error_after_convergence_m"],
        "pf_smoothed_after_convergence_m": paper_metric["smoothed_after_convergence_m"],
        "time_to_convergence_s": paper_metric["time_to_convergence_s"],
        "pf_rms_m": rms_error_from(result.estimates, sc.truth, sc.start + SKIP),
        "pf_smoothed_rms_m": rms_error_from(result.smoothed, sc.truth, sc.start + SKIP),
    }


def scaled_clock(clock: EmissionClockModel, factor: float) -> EmissionClockModel:
    """The same clock with every process-noise standard deviation times ``factor``."""
    return dataclasses.replace(
        clock,
        phase_step_sd=clock.phase_step_sd * factor,
        period_step_sd=clock.period_step_sd * factor,
        rate_step_sd=clock.rate_step_sd * factor,
    )


def case_bounds(inputs: BoundInputs, filter_clock: bool = True) -> dict[str, pd.DataFrame]:
    """The bound tables of a case, label -> :func:`bound_table`: fitted clock without and
    with the detection curve, the filter's clock (unless ``filter_clock`` is False) and the
    clock known."""
    tables = {
        "fitted clock, arrivals only": bound_table(inputs, inputs.fitted_clock, detection=False),
        "fitted clock": bound_table(inputs, inputs.fitted_clock),
    }
    if filter_clock:
        tables["filter's clock"] = bound_table(inputs, FILTER_CLOCK)
    tables["clock known"] = bound_table(inputs, None)
    return tables


def sensitivity_rows(name, seed, inputs: BoundInputs) -> list[dict]:
    """The fitted-clock bound with its priors changed (q, clock noise, σ)."""
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


def case_rows(seeds, run_filter: bool, n_particles: int, duration: float):
    """RMS bounds per case and seed (and the filter's errors), the sensitivity rows, and the
    first seed's bound tables per case (for the figure)."""
    rows, sensitivity, curves = [], [], {}
    for name, (make, gps_sd) in CASES.items():
        for seed in seeds:
            case = make(seed)
            inputs = bound_inputs(case, gps_sd, duration)
            tables = case_bounds(inputs)
            if seed == seeds[0]:
                curves[name] = tables
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
                row.update(filter_errors(case, seed, n_particles, duration))
            rows.append(row)
            if "2 AUVs" in name and "paper" not in name:
                sensitivity += sensitivity_rows(name, seed, inputs)
    return pd.DataFrame(rows), pd.DataFrame(sensitivity), curves


def plan_case(seed: int, plan) -> ClockScenario:
    """:func:`rotating_pair_pursuit` for a ``(radius m, lap time s, separation deg)`` plan."""
    radius, lap_time, separation = plan
    return rotating_pair_pursuit(seed, radius, lap_time, np.radians(separation))


def planning_sweep(seeds, radii, lap_times, separations_deg, duration=DURATION) -> pd.DataFrame:
    """Bounds and AUV speeds of every plan of the grid, mean over ``seeds``; ``flyable``:
    99 % of the AUVs' 1 s speeds at most 2.5 m/s."""
    rows = []
    for radius in radii:
        for lap_time in lap_times:
            for separation in separations_deg:
                for seed in seeds:
                    case = plan_case(seed, (radius, lap_time, separation))
                    speeds = auv_speeds(case, duration)
                    inputs = bound_inputs(case, AUV_GPS, duration)
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
    summary = mean_over_seeds(table, keys)
    summary["auv_speed_max_m_s"] = table.groupby(keys, sort=False)["auv_speed_max_m_s"].max().values
    summary["flyable"] = summary["auv_speed_p99_m_s"] <= 2.5
    return summary


def plan_curves(seed: int, duration: float = DURATION) -> dict[str, pd.DataFrame]:
    """Bound tables of the :data:`PLAN` geometry for one seed, as in the case tables."""
    return case_bounds(bound_inputs(plan_case(seed, PLAN), AUV_GPS, duration), filter_clock=False)


def filter_on_plans(seeds, n_particles: int, duration: float) -> pd.DataFrame:
    """Bounds and the arrival-time filter's errors on :data:`FILTER_PLANS`, per seed."""
    rows = []
    for plan in FILTER_PLANS:
        radius, lap_time, separation = plan
        for seed in seeds:
            case = plan_case(seed, plan)
            inputs = bound_inputs(case, AUV_GPS, duration)
            table = bound_table(inputs, inputs.fitted_clock)
            rows.append(
                {
                    "radius_m": radius,
                    "lap_time_s": lap_time,
                    "separation_deg": separation,
                    "seed": seed,
                    "bound_filter_m": rms_after_skip(table, inputs, "filter_position_m"),
                    "bound_smoother_m": rms_after_skip(table, inputs, "smoother_position_m"),
                    **filter_errors(case, seed, n_particles, duration),
                }
            )
    return pd.DataFrame(rows)


def mean_over_seeds(table: pd.DataFrame, keys) -> pd.DataFrame:
    """Numeric columns averaged per ``keys``, without the ``seed`` column."""
    means = table.groupby(keys, sort=False).mean(numeric_only=True).reset_index()
    return means.drop(columns="seed")


def plan_name() -> str:
    """The figure's name of :data:`PLAN`."""
    radius, lap_time, separation = PLAN
    return f"plan: 2 AUVs, {radius:.0f} m, {separation:.0f}°, lap {lap_time:.0f} s"


@dataclasses.dataclass(frozen=True)
class ClockBoundStudy:
    """What :func:`clock_bound_study` returns.

    Attributes
    ----------
    runs : pandas.DataFrame
        Per case and seed: q, σ, the fitted clock, every bound's RMS (m; clock in ms) and,
        when the filter ran, its errors.
    summary : pandas.DataFrame
        ``runs`` averaged per case.
    sensitivity : pandas.DataFrame
        The fitted-clock bound with changed priors, mean per two-AUV case and variant.
    sweep : pandas.DataFrame
        :func:`planning_sweep` (empty without sweep seeds).
    plans, plan_runs : pandas.DataFrame
        :func:`filter_on_plans`, mean per plan and every run (empty without the filter).
    curves : dict of str to dict of str to DataFrame
        The first seed's bound tables per case and for :data:`PLAN` (the figure).
    """

    runs: pd.DataFrame
    summary: pd.DataFrame
    sensitivity: pd.DataFrame
    sweep: pd.DataFrame
    plans: pd.DataFrame
    plan_runs: pd.DataFrame
    curves: dict


def clock_bound_study(
    seeds: Sequence[int],
    *,
    sweep_seeds: Sequence[int] = (0, 1),
    sweep: tuple = SWEEP,
    run_filter: bool = True,
    filter_runs: pd.DataFrame | None = None,
    n_particles: int = FILTER_PARTICLES,
    duration: float = DURATION,
) -> ClockBoundStudy:
    """Bounds on every case of :data:`CASES`, their sensitivity, the planning sweep and the
    filter on :data:`FILTER_PLANS`.

    Parameters
    ----------
    seeds : sequence of int
        Scenario seeds of the cases (and of the filter's plans).
    sweep_seeds : sequence of int
        Scenario seeds of the planning sweep; empty: no sweep.
    sweep : (radii, lap times, separations in degrees)
        The planning sweep's grid.
    run_filter : bool
        Run the arrival-time filter on the cases and on :data:`FILTER_PLANS`.
    filter_runs : pandas.DataFrame, optional
        Other filter errors per ``scenario`` and ``seed`` (e.g. read from the clock-aware
        study's report) merged into :attr:`ClockBoundStudy.runs`.
    n_particles : int
        The filter's particles.
    duration : float
        Length of each run (s).

    Returns
    -------
    ClockBoundStudy
    """
    seeds = list(seeds)
    runs, sensitivity, curves = case_rows(seeds, run_filter, n_particles, duration)
    curves[plan_name()] = plan_curves(seeds[0], duration)
    if filter_runs is not None and len(filter_runs):
        runs = runs.merge(filter_runs, on=["scenario", "seed"], how="left")
    plan_runs = filter_on_plans(seeds, n_particles, duration) if run_filter else pd.DataFrame()
    plan_keys = ["radius_m", "lap_time_s", "separation_deg"]
    return ClockBoundStudy(
        runs=runs,
        summary=mean_over_seeds(runs, ["scenario"]),
        sensitivity=mean_over_seeds(sensitivity, ["scenario", "variant"]),
        sweep=planning_sweep(list(sweep_seeds), *sweep, duration)
        if sweep_seeds
        else pd.DataFrame(),
        plans=mean_over_seeds(plan_runs, plan_keys) if len(plan_runs) else plan_runs,
        plan_runs=plan_runs,
        curves=curves,
    )
