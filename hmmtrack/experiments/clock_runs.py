"""Filter runs on realistic-clock cases, shared by the clock studies, and how they are scored.

The clock studies (:mod:`~hmmtrack.experiments.arrival`,
:mod:`~hmmtrack.experiments.clock_bound`, :mod:`~hmmtrack.experiments.two_auv_plan`,
:mod:`~hmmtrack.experiments.closed_loop_study`) track a
:class:`~hmmtrack.scenarios.clocks.ClockScenario` two ways on the same detections, mapped
to the common time base with the calibration the case provides:

* the paper's range-rate method (:func:`hmmtrack.tracking.pipeline.track`), given the best
  constant period and the true initial ranges (:func:`clock_inputs`' configuration);
* the arrival-time method, given neither: :func:`track_arrival` is the one place that runs
  it, with keyword options built by :func:`clock_inputs` or, from a
  :class:`~hmmtrack.tracking.config.TrackingConfig`, by :func:`config_options`;
  :func:`known_clock_run` is its diagnostic twin told the tag's emission schedule
  (:class:`KnownClock`);
* the same detections grouped into pings (``"ping-sequence"`` given the period,
  :func:`grouped_config`).

:func:`score_run` scores a run the way every clock study reports it. This module runs and
scores; it writes nothing (:mod:`hmmtrack.report`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from hmmtrack.analysis.metrics import position_error, time_to_convergence
from hmmtrack.experiments.trials import PAPER_FILTER
from hmmtrack.scenarios.clocks import ClockScenario
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import FilterResult, FilterSettings
from hmmtrack.tracking.measurement.arrival_time import ArrivalTimeMeasurement
from hmmtrack.tracking.measurement.clock import EmissionClockModel
from hmmtrack.tracking.measurement.clocked import ClockedArrivalTime, ClockState
from hmmtrack.tracking.measurement.detection import SilenceModel
from hmmtrack.tracking.motion import VelocityMotion, motion_model
from hmmtrack.tracking.pipeline import TrackingResult, particle_filter, track
from hmmtrack.tracking.receivers import ReceiverTracks

#: length of a clock study's runs (s): the 2 h of issue 5
DURATION = 7200.0
#: RMS errors and bounds are taken from this many seconds on (s), past the start-up
SKIP = 600.0
#: window of the "first / last 30 minutes after convergence" errors (s)
HALF_HOUR = 1800


def make_motion(name: str):
    """The motion model a clock study runs by ``name``.

    ``velocity``: slow random walks of speed and turn rate (0.05 m/s, 0.02 rad/s per √s,
    suited to a cruising shark); ``hmm`` / ``hmm-tc``: the bundled white-shark HMM, the
    paper's variant or the time-consistent one.
    """
    if name == "velocity":
        return VelocityMotion(sigma_speed=0.05, sigma_turn_rate=0.02)
    return motion_model("hmm", variant="time_consistent" if name == "hmm-tc" else "paper")


def score_run(
    estimates: pd.DataFrame, truth: pd.DataFrame, smoothed: pd.DataFrame | None = None
) -> dict:
    """The errors a clock study reports for one run (m, s).

    Parameters
    ----------
    estimates : pandas.DataFrame
        The filter's estimate every second (``time``, ``x``, ``y``, ``sqrt_lambda1``).
    truth : pandas.DataFrame
        The true path (``time``, ``x``, ``y``).
    smoothed : pandas.DataFrame, optional
        The fixed-lag smoother's estimates at the same times.

    Returns
    -------
    dict
        ``error_after_10_min_m`` (mean from the 600th estimate on, defined whether or not
        the run converged), ``converged``, ``time_to_convergence_s``,
        ``error_after_convergence_m`` (the paper's "RMSE", a mean; NaN when the run never
        converged) and that error over the first 5 and 30 and the last 30 minutes after
        convergence (``first_5_min_m``, ``first_30_min_m``, ``last_30_min_m``); with
        ``smoothed`` also ``smoothed_after_10_min_m`` and ``smoothed_after_convergence_m``.
    """
    errors = position_error(estimates, truth)
    convergence = time_to_convergence(
        estimates["time"].to_numpy(), estimates["sqrt_lambda1"].to_numpy()
    )
    after = errors[convergence.index :] if convergence.converged else errors[:0]
    row = {
        "error_after_10_min_m": float(errors[600:].mean()),
        "converged": convergence.converged,
        "time_to_convergence_s": convergence.time_to_convergence,
        "error_after_convergence_m": float(after.mean()) if after.size else np.nan,
        "first_5_min_m": float(after[:300].mean()) if after.size else np.nan,
        "first_30_min_m": float(after[:HALF_HOUR].mean()) if after.size else np.nan,
        "last_30_min_m": float(after[-HALF_HOUR:].mean()) if after.size else np.nan,
    }
    if smoothed is not None:
        smooth_errors = position_error(smoothed, truth)
        row["smoothed_after_10_min_m"] = float(smooth_errors[600:].mean())
        after = smooth_errors[convergence.index :] if convergence.converged else after
        row["smoothed_after_convergence_m"] = float(after.mean()) if after.size else np.nan
    return row


def rms_error_from(estimates: pd.DataFrame, truth: pd.DataFrame, start: float) -> float:
    """Root-mean-square position error (m) of the estimates from ``start`` (s) on."""
    late = estimates[estimates["time"] >= start]
    return float(np.sqrt(np.mean(position_error(late, truth) ** 2)))


def clock_inputs(case: ClockScenario, seed, n_particles: int, motion: str, duration: float):
    """What both methods get for a run of the first ``duration`` seconds of ``case``.

    Parameters
    ----------
    case : ClockScenario
    seed : int
        The filters' seed.
    n_particles : int
    motion : str
        A name of :func:`make_motion`.
    duration : float
        s; runs shorter than the scenario stop there.

    Returns
    -------
    detections : pandas.DataFrame
        Clock-corrected detections before the end of the run.
    config : TrackingConfig
        The range-rate method's: the paper's filter, mean period, true ``r0``, the run's
        window.
    options : dict
        The arrival-time run of :func:`track_arrival`: ``config`` (mean period, the case's
        search box and detection curve, particles, window), ``motion`` and ``seed``.
    """
    sc = case.scenario
    start, end = sc.start, min(sc.end, sc.start + duration)
    detections = case.corrected_detections()
    detections = detections[detections["time"] < end].reset_index(drop=True)
    config = TrackingConfig.from_keys(
        filter=PAPER_FILTER,  # the paper's method, whatever the library's default filter
        period=sc.period,
        r0=sc.r0,
        sound_speed=sc.sound_speed,
        n_particles=n_particles,
        start=start,
        end=end,
    )
    arrival = TrackingConfig.from_keys(
        period=sc.period,
        measurement="arrival-time",
        bounds=case.search_bounds,
        n_particles=n_particles,
        detection_curve=case.detection_probability,
        start=start,
        end=end,
    )
    return detections, config, {"config": arrival, "motion": make_motion(motion), "seed": seed}


def config_options(config: TrackingConfig) -> dict:
    """The :func:`track_arrival` options an arrival-time ``config`` sets: the configuration
    and its motion model (seed and smoother lag are the caller's)."""
    return {"config": config, "motion": config.motion_model()}


def without_silences(options: dict) -> dict:
    """``options`` with no detection curve: unheard pings tell nothing (as ``hmmtrack track``
    runs without ``--detection-curve``)."""
    config = options["config"]
    measurement = dataclasses.replace(config.measurement, detection_curve=None)
    return options | {"config": dataclasses.replace(config, measurement=measurement)}


def grouped_config(options: dict, period: float, bounds, settings: dict | None = None):
    """The grouped run's configuration: the ``"ping-sequence"`` measurement of a tag of
    ``period`` (s), the arrival-time run's particles, window and detection curve
    (``options`` of :func:`clock_inputs`), the case's search ``bounds``, and more
    ``settings`` by key: the tag's pings grouped and scored jointly
    (:mod:`hmmtrack.tracking.measurement.sequence`)."""
    config = options["config"]
    keys = {
        "measurement": "ping-sequence",
        "period": float(period),
        "bounds": bounds,
        "n_particles": config.filter.n_particles,
        "detection_curve": config.measurement.detection_curve,
        "start": config.start,
        "end": config.end,
    }
    return TrackingConfig.from_keys(**(keys | dict(settings or {})))


def track_arrival(
    detections: pd.DataFrame, receivers: pd.DataFrame, options: dict
) -> TrackingResult:
    """Run the arrival-time filter with ``options`` (:func:`clock_inputs`, :func:`config_options`).

    Parameters
    ----------
    detections : pandas.DataFrame
        ``time`` on the common time base (s), ``receiver``.
    receivers : pandas.DataFrame
        Logged receiver positions.
    options : dict
        ``config`` (arrival-time :class:`~hmmtrack.tracking.config.TrackingConfig`),
        ``motion``, ``seed``; optional ``smoothing_lag`` (s) and ``clock`` (an
        :class:`~hmmtrack.tracking.measurement.clock.EmissionClockModel` replacing the
        configuration's default clock model).

    Returns
    -------
    TrackingResult
    """
    config = options["config"]
    measurement = None
    if options.get("clock") is not None:
        tracks = ReceiverTracks.from_frame(receivers, outside="clamp")
        observations = ClockedArrivalTime.observations(detections, tracks)
        built = ClockedArrivalTime.from_settings(config.measurement, observations, tracks)
        measurement = dataclasses.replace(built, clock=options["clock"])
    return track(
        detections,
        receivers,
        config.override(smoothing_lag=options.get("smoothing_lag")),
        options["motion"],
        seed=options["seed"],
        measurement=measurement,
    )


@dataclasses.dataclass(frozen=True)
class KnownClock(ClockedArrivalTime):
    """Diagnostic: the arrival-time measurement told the tag's emission schedule.

    The schedule is a constant-period line (the detections are moved onto it); the clock
    starts on the true pings and is kept rigid, so what remains is what the receivers'
    geometry and the motion model allow.

    Parameters
    ----------
    first_emission : float
        Emission time (s) of ping 0 of the schedule.
    """

    first_emission: float = 0.0

    def _start_clock(self, p, rows, time, state: ClockState, reacquire: bool = False) -> None:
        super()._start_clock(p, rows, time, state, reacquire)
        period = self.clock.nominal_period
        ping = np.rint((p.emission_time - self.first_emission) / period)
        p.extra["emission_time"] = self.first_emission + ping * period
        p.extra["period"] = np.full(p.n, period)
        state.covariance = np.diag([1e-12, 1e-16, 0.0])


def known_clock_run(
    case: ClockScenario, seed, n_particles: int, motion: str, duration: float
) -> FilterResult:
    """Track ``case`` with the true emission schedule given (:class:`KnownClock`).

    Each heard ping's logged time is mapped to true time by the case's calibration and moved
    by its emission's distance from the best constant-period line through the true emissions;
    the filter runs on the first ``duration`` seconds with the case's detection curve. The
    ambiguity table is ``result.collected["ambiguity"]``.
    """
    sc = case.scenario
    start, end = sc.start, min(sc.end, sc.start + duration)
    emissions = case.emission_times
    k = np.arange(emissions.size)
    period, intercept = np.polyfit(k, emissions, 1)
    heard = sc.pings[sc.pings["detected"]]
    times = heard["logged_time"].to_numpy(dtype=float).copy()
    for receiver, clock in case.clock_calibration.items():
        rows = (heard["receiver"] == receiver).to_numpy()
        times[rows] = clock.to_true(times[rows])
    ping = heard["ping"].to_numpy()
    times -= emissions[ping] - (intercept + period * ping)
    detections = pd.DataFrame({"time": times, "receiver": heard["receiver"].astype(str)})
    detections = detections[detections["time"] < end].sort_values("time")
    tracks = ReceiverTracks.from_frame(sc.receivers, outside="clamp")
    obs = KnownClock.observations(detections, tracks)
    measurement = KnownClock(
        EmissionClockModel(period, 0.0, 0.0, 1e-8),
        ArrivalTimeMeasurement(sound_speed=sc.sound_speed),
        SilenceModel.from_observations(obs, tracks, case.detection_probability),
        first_emission=intercept,
    )
    settings = FilterSettings(n_particles=n_particles)
    pf = particle_filter(settings, measurement, case.search_bounds, make_motion(motion), seed=seed)
    return pf.run(obs, start, end)


def auv_speeds(case: ClockScenario, duration: float = DURATION) -> np.ndarray:
    """Every receiver's speed over ground (m/s) over its 1 s steps in the first ``duration`` s.

    Returns
    -------
    numpy.ndarray, shape (n,)
        The receivers' speeds, one receiver after the other (true paths, no GPS error).
    """
    sc = case.scenario
    paths = sc.receivers_truth[sc.receivers_truth["time"] < sc.start + duration]
    return np.concatenate(
        [
            np.hypot(np.diff(path["x"]), np.diff(path["y"])) / np.diff(path["time"])
            for _, path in paths.groupby("receiver")
        ]
    )
