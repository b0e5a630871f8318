"""Scenarios with realistic clocks: drifting tag periods, unsynchronised receivers, multipath.

The paper's simulated tag pings with a constant period plus Gaussian jitter. Real
"fixed-period" tags do not (DESIGN.md, "What real data teaches"): the local period over
400-ping blocks wanders by −700…+360 ppm and the emission schedule drifts up to ~0.8 s
from any constant-period schedule in under two hours; receiver clocks differ by tens of
ppm; a few per cent of detections arrive late by multipath. This module adds those clocks
to the simulation pieces of :mod:`hmmtrack.scenarios` (paths, acoustic arrival times,
detection loss, GPS noise) and builds two test cases:

* :func:`realistic_shark_pursuit` - a shark pursued by two moving hydrophones (2.5 h)
  with a wandering tag period; the AUVs are steered by name (one trails while one
  circles the shark, the paper's fixed formation, or the pair circling the shark
  together, see :data:`STEERINGS`) or by a :class:`RotatingPlan`;
* :func:`moored_array` - a resident shark inside a triangle of three moored receivers.

Each returns a :class:`ClockScenario`: a :class:`hmmtrack.scenarios.scenario.Scenario`
whose detections are logged in the receivers' own clocks, plus the true clocks, the
calibrated clock estimates a tracker is given, the true emission times and a search box
that does not use the true initial ranges.

It does not track or score anything.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios.detection import GpsNoise, detections_from_pings
from hmmtrack.scenarios.paper import shark_pursuit
from hmmtrack.scenarios.scenario import Scenario, assemble_scenario
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.measurement.clock import ReceiverClock, to_common_time
from hmmtrack.tracking.measurement.detection import LogisticDetection


@dataclass(frozen=True)
class WanderingPeriodClock:
    """A "fixed-period" tag whose period is a random walk from ping to ping.

    The period deviations are a Gaussian random walk in time, low-pass filtered with time
    constant ``smoothing_time`` (period changes of a crystal follow temperature, which
    changes over minutes; the 44-83 µs ping jitter seen on real tags leaves no room for
    large ping-to-ping period steps), scaled so that over the first
    ``reference_duration`` seconds the emission schedule's largest distance from its best
    constant-period schedule (:func:`hmmtrack.tracking.measurement.clock.schedule_wander`) is
    exactly
    ``schedule_wander`` before jitter (runs shorter than that are the start of such a
    schedule); each emission then gets independent Gaussian jitter. Implements the
    emission-clock protocol of :mod:`hmmtrack.scenarios.detection`.

    Parameters
    ----------
    period : float
        Mean period (s).
    schedule_wander : float
        Largest drift of the schedule from a constant period over ``reference_duration`` (s).
    jitter_sd : float
        Standard deviation of each emission's independent jitter (s).
    phase : float
        Delay of the first emission after ``start`` (s), in ``[0, period)``.
    reference_duration : float
        Span over which the wander is ``schedule_wander`` (s); 1.8 h as the real trial.
    smoothing_time : float
        Time constant of the low-pass filter on the period's random walk (s); 0 leaves it
        a plain random walk from ping to ping.
    """

    period: float
    schedule_wander: float = 0.8
    jitter_sd: float = 65e-6
    phase: float = 0.0
    reference_duration: float = 6480.0
    smoothing_time: float = 600.0

    def __post_init__(self) -> None:
        if not self.period > 0:
            raise ValueError(f"WanderingPeriodClock: period must be > 0 s, got {self.period}")
        if not (self.schedule_wander >= 0 and self.jitter_sd >= 0):
            raise ValueError("WanderingPeriodClock: schedule_wander and jitter_sd must be >= 0")
        if not 0 <= self.phase < self.period:
            raise ValueError(
                f"WanderingPeriodClock: phase must be in [0, period), got {self.phase}"
            )

    def emission_times(self, rng: np.random.Generator, start: float, end: float) -> np.ndarray:
        """Emission times (UTC s), shape (n,), of the pings nominally in ``[start, end)``."""
        n = int(np.ceil((end - start - self.phase) / self.period))
        if n < 3:
            raise ValueError(f"WanderingPeriodClock: [{start}, {end}) holds fewer than 3 pings")
        n_reference = max(int(np.ceil(self.reference_duration / self.period)), 3)
        n_walk = max(n, n_reference)
        walk = np.cumsum(rng.standard_normal(n_walk - 1))
        if self.smoothing_time > 0:
            keep = np.exp(-self.period / self.smoothing_time)
            walk = lfilter([1.0 - keep], [1.0, -keep], walk - walk[0]) + walk[0]
        walk -= walk[: n_reference - 1].mean()
        drift = np.concatenate([[0.0], np.cumsum(self.period * walk)])
        k = np.arange(n_walk, dtype=float)
        slope, intercept = np.polyfit(k[:n_reference], drift[:n_reference], 1)
        largest = np.max(np.abs(drift - intercept - slope * k)[:n_reference])
        scale = self.schedule_wander / largest if largest > 0 else 0.0
        nominal = start + self.phase + self.period * k[:n] + scale * drift[:n]
        return nominal + self.jitter_sd * rng.standard_normal(n)


@dataclass(frozen=True)
class Multipath:
    """Late arrivals: a share of detections logged after the direct path.

    Parameters
    ----------
    fraction : float
        Probability that a detection is a multipath arrival, in [0, 1).
    mean_delay : float
        Mean extra delay of a multipath arrival (s); delays are exponential.
    """

    fraction: float = 0.03
    mean_delay: float = 20e-3

    def apply(self, rng: np.random.Generator, pings: pd.DataFrame) -> pd.DataFrame:
        """Copy of ``pings`` with ``logged_time`` delayed for multipath arrivals.

        Adds a column ``multipath_delay`` (s, 0 for direct arrivals).
        """
        delay = rng.exponential(self.mean_delay, len(pings))
        delay *= rng.random(len(pings)) < self.fraction
        out = pings.copy()
        out["logged_time"] = out["logged_time"] + delay
        out["multipath_delay"] = delay
        return out


def random_receiver_clocks(
    rng: np.random.Generator,
    names,
    reference_time: float,
    offset_sd: float = 0.5,
    drift_ppm_sd: float = 20.0,
) -> dict[str, ReceiverClock]:
    """Independent receiver clocks: Gaussian offsets (s) and drifts (ppm) at ``reference_time``."""
    return {
        name: ReceiverClock(
            offset=float(offset_sd * rng.standard_normal()),
            drift_ppm=float(drift_ppm_sd * rng.standard_normal()),
            reference_time=reference_time,
        )
        for name in names
    }


def calibrate_clocks(
    rng: np.random.Generator,
    clocks: dict[str, ReceiverClock],
    offset_error_sd: float = 100e-6,
    drift_error_ppm_sd: float = 0.02,
) -> dict[str, ReceiverClock]:
    """Clock estimates with the residual errors of a sync-tag or GPS-PPS calibration."""
    return {
        name: dataclasses.replace(
            clock,
            offset=clock.offset + offset_error_sd * float(rng.standard_normal()),
            drift_ppm=clock.drift_ppm + drift_error_ppm_sd * float(rng.standard_normal()),
        )
        for name, clock in clocks.items()
    }


@dataclass(frozen=True, kw_only=True)
class ClockScenario:
    """A scenario with realistic clocks and everything needed to score trackers on it.

    Attributes
    ----------
    scenario : Scenario
        Detections logged in each receiver's clock; ``scenario.pings`` has the truth per
        ping and receiver (``arrival_time`` true, ``logged_time`` as logged,
        ``multipath_delay``). ``scenario.period`` is the mean period of the emissions (the
        best a constant-period method can be told) and ``scenario.bounds`` uses the true
        initial ranges, as the paper's method assumes.
    emission_times : numpy.ndarray, shape (n_pings,)
        True emission times (s).
    receiver_clocks : dict of str to ReceiverClock
        True receiver clocks.
    clock_calibration : dict of str to ReceiverClock
        The receiver clocks a tracker is given (true clocks plus calibration error).
    detection_probability : LogisticDetection
        The curve that drew which pings were heard (the same for all receivers).
    search_bounds : tuple of float
        ``(xmin, xmax, ymin, ymax)`` (m): a box around the receivers at the start, as wide
        as the detection range - what a tracker without initial ranges may assume.
    """

    scenario: Scenario
    emission_times: np.ndarray
    receiver_clocks: dict[str, ReceiverClock]
    clock_calibration: dict[str, ReceiverClock]
    detection_probability: LogisticDetection
    search_bounds: tuple[float, float, float, float]

    def corrected_detections(self) -> pd.DataFrame:
        """Detections with times mapped to the common time base by ``clock_calibration``."""
        return to_common_time(self.scenario.detections, self.clock_calibration)

    def arrival_config(self, settings=None, duration: float | None = None) -> TrackingConfig:
        """Settings to track this case from arrival times, with no initial range.

        Parameters
        ----------
        settings : mapping, optional
            Keys of :class:`hmmtrack.tracking.config.TrackingConfig` (e.g. a preset's,
            :func:`hmmtrack.tracking.config.read_preset`); the case's own keys below win over them.
        duration : float, optional
            Track the first ``duration`` seconds (s); default: the whole scenario.

        Returns
        -------
        TrackingConfig
            ``measurement="arrival-time"`` unless ``settings`` say otherwise, with the
            case's mean period, :attr:`search_bounds`, time window and sound speed.
        """
        sc = self.scenario
        end = sc.end if duration is None else sc.start + duration
        case = {
            "period": sc.period,
            "bounds": self.search_bounds,
            "start": sc.start,
            "end": end,
            "sound_speed": sc.sound_speed,
        }
        return TrackingConfig.from_dict({"measurement": "arrival-time", **(settings or {}), **case})


def _search_bounds(receivers: dict[str, Trajectory], start: float, reach: float):
    xs, ys = [], []
    for path in receivers.values():
        x, y, _ = path.position(np.array([start]))
        xs.append(x[0])
        ys.append(y[0])
    return (min(xs) - reach, max(xs) + reach, min(ys) - reach, max(ys) + reach)


def build_clock_scenario(
    rng: np.random.Generator,
    *,
    name: str,
    description: str,
    tag: Trajectory,
    receivers: dict[str, Trajectory],
    clock: WanderingPeriodClock,
    detection: LogisticDetection,
    multipath: Multipath,
    gps: GpsNoise,
    start: float,
    end: float,
    receiver_offset_sd: float = 0.5,
    receiver_drift_ppm_sd: float = 20.0,
    sound_speed: float = 1460.0,
) -> ClockScenario:
    """Simulate a scenario with a wandering tag clock, receiver clocks and multipath.

    Parameters
    ----------
    rng : numpy.random.Generator
        Used in this order: emissions, then detection draws and GPS noise (by
        :func:`hmmtrack.scenarios.scenario.assemble_scenario`), receiver clocks, their
        calibration, multipath.
    name, description : str
    tag : Trajectory
        True tag path.
    receivers : dict of str to Trajectory
        True receiver paths (a single vertex: moored).
    clock : WanderingPeriodClock
    detection : LogisticDetection
        Detection probability against range, the same for every receiver.
    multipath : Multipath
    gps : GpsNoise
        Error on logged receiver positions.
    start, end : float
        UTC s.
    receiver_offset_sd, receiver_drift_ppm_sd : float
        Spread of the receivers' clock offsets (s) and drifts (ppm).
    sound_speed : float
        m/s.

    Returns
    -------
    ClockScenario
    """
    emissions = clock.emission_times(rng, start, end)
    base = assemble_scenario(
        rng,
        name=name,
        description=description,
        tag=tag,
        receivers=receivers,
        emission_time=emissions,
        period=float(np.mean(np.diff(emissions))),
        detection_probability={receiver: detection for receiver in receivers},
        gps=gps,
        start=start,
        end=end,
        transmitter="tag",
        sound_speed=sound_speed,
    )
    true_clocks = random_receiver_clocks(
        rng, list(receivers), start, receiver_offset_sd, receiver_drift_ppm_sd
    )
    calibration = calibrate_clocks(rng, true_clocks)
    pings = base.pings.copy()
    for receiver, receiver_clock in true_clocks.items():
        rows = pings["receiver"] == receiver
        pings.loc[rows, "logged_time"] = receiver_clock.to_recorded(
            pings.loc[rows, "arrival_time"].to_numpy(dtype=float)
        )
    pings = multipath.apply(rng, pings)
    scenario = dataclasses.replace(
        base, detections=detections_from_pings(pings, base.transmitter, tag), pings=pings
    )
    reach = detection.range_50 + 2.0 * detection.width
    return ClockScenario(
        scenario=scenario,
        emission_times=emissions,
        receiver_clocks=true_clocks,
        clock_calibration=calibration,
        detection_probability=detection,
        search_bounds=_search_bounds(receivers, start, reach),
    )


#: a white shark staying in its resident (slow, tortuous) behaviour
RESIDENT_SHARK = dataclasses.replace(
    WHITE_SHARK_GROUND_TRUTH,
    initial=np.array([1.0]),
    transition=np.array([[1.0]]),
    step_mean=WHITE_SHARK_GROUND_TRUTH.step_mean[:1],
    step_sd=WHITE_SHARK_GROUND_TRUTH.step_sd[:1],
    angle_concentration=WHITE_SHARK_GROUND_TRUTH.angle_concentration[:1],
    state_names=WHITE_SHARK_GROUND_TRUTH.state_names[:1],
)


def moored_array(
    seed: SeedLike,
    *,
    duration: float = 7200.0,
    period: float = 8.0,
    array_radius: float = 400.0,
    schedule_wander: float = 0.8,
    start: float = 1_600_000_000.0,
) -> ClockScenario:
    """A resident shark inside a triangle of three moored receivers, with realistic clocks.

    The tag follows :data:`RESIDENT_SHARK` (about 0.45 m/s, tortuous). The receivers stand
    at the corners of an equilateral triangle around the shark's home range (the centre
    of its path), each ``array_radius`` from the centre or, if the shark roams further,
    1.2 times its largest distance from the centre, so that it stays inside the array;
    the detection range is logistic with a 50 % range of 1.75 radii (fall-off a quarter
    radius); receiver positions are surveyed to 0.5 m; receiver clocks have offsets of
    ~0.5 s and drifts of ~20 ppm, calibrated to 0.1 ms and 0.02 ppm; 3 % of detections
    are multipath arrivals.

    Parameters
    ----------
    seed : int, SeedSequence or Generator
    duration : float
        Length of the run (s).
    period : float
        Mean tag period (s).
    array_radius : float
        Smallest distance of each receiver from the array centre (m).
    schedule_wander : float
        See :class:`WanderingPeriodClock` (s).
    start : float
        UTC s of the start.
    """
    rng = as_generator(seed)
    n_steps = int(np.ceil(duration / RESIDENT_SHARK.dt))
    tag, _ = RESIDENT_SHARK.simulate_path(rng, n_steps, start_time=start)
    cx, cy = float(np.mean(tag.x)), float(np.mean(tag.y))
    radius = max(array_radius, 1.2 * float(np.max(np.hypot(tag.x - cx, tag.y - cy))))
    angles = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    receivers = {
        f"mooring-{k + 1}": Trajectory.fixed(cx + radius * np.cos(a), cy + radius * np.sin(a))
        for k, a in enumerate(angles)
    }
    return build_clock_scenario(
        rng,
        name="moored-array",
        description=(
            "Synthetic: a resident white shark inside a triangle of three moored receivers, "
            f"tag period {period} s wandering {schedule_wander} s from a constant schedule, "
            "unsynchronised receiver clocks (calibrated), 3 % multipath arrivals."
        ),
        tag=tag,
        receivers=receivers,
        clock=WanderingPeriodClock(period, schedule_wander, phase=float(rng.uniform(0, period))),
        detection=LogisticDetection(range_50=1.75 * radius, width=0.25 * radius),
        multipath=Multipath(),
        gps=GpsNoise(sd=0.5),
        start=start,
        end=start + duration,
    )


def _paths_from_tables(truth: pd.DataFrame, receivers_truth: pd.DataFrame):
    tag = Trajectory(
        truth["time"].to_numpy(),
        truth["x"].to_numpy(),
        truth["y"].to_numpy(),
        truth["depth"].to_numpy() if "depth" in truth else None,
    )
    receivers = {}
    for name, rows in receivers_truth.groupby("receiver", sort=False):
        if rows["time"].isna().all():
            receivers[str(name)] = Trajectory.fixed(rows["x"].iat[0], rows["y"].iat[0])
        else:
            receivers[str(name)] = Trajectory(
                rows["time"].to_numpy(), rows["x"].to_numpy(), rows["y"].to_numpy()
            )
    return tag, receivers


def steered_auv(
    tag: Trajectory,
    radius: float,
    bearing: np.ndarray,
    time_constant: float = 60.0,
    lead_window: float | None = None,
) -> Trajectory:
    """An AUV steered to a station ``radius`` metres from the shark at a given bearing.

    The station is the shark's position plus ``radius · (cos bearing, sin bearing)``; the
    AUV follows it through a first-order low-pass filter of time constant
    ``time_constant`` (a vehicle that homes on a moving set point), as the paper's
    hydrophones follow their fixed offsets. A constant ``bearing`` is the paper's trailing
    vehicle; a bearing that turns makes the vehicle circle the shark. Such a vehicle
    trails a set point moving at a steady velocity ``v`` by ``v · lag`` with
    ``lag = e^(-1/τ) / (1 - e^(-1/τ))`` s (≈ ``time_constant`` − ½ s), so behind a
    travelling shark it flies behind its station; with ``lead_window`` the station is moved
    ahead of the shark by the shark's recent velocity times ``lag``, the velocity being the
    exponential average, with time constant ``lead_window``, of its 1 s displacements up to
    that second (what an operator who follows the track knows), and the vehicle then holds
    its station on a shark that keeps its course. The stations are placed from the true
    shark track, as the paper's simulated hydrophone paths are built from it.

    Parameters
    ----------
    tag : Trajectory
        The shark's path sampled every second (``tag.time`` must be evenly spaced by 1 s).
    radius : float
        Distance of the station from the shark (m).
    bearing : numpy.ndarray, shape (n,)
        Bearing of the station from the shark at each of ``tag.time`` (rad, from +x).
    time_constant : float
        Low-pass time constant (s).
    lead_window : float, optional
        Time constant (s) of the average of the shark's velocity that leads the station;
        ``None`` (default): the station is on the shark's position, without lead.

    Returns
    -------
    Trajectory
        The AUV's true path at ``tag.time``.
    """
    if not np.allclose(np.diff(tag.time), 1.0):
        raise ValueError("steered_auv: the shark's path must be sampled every 1 s")
    keep, lag = homing_memory(time_constant)
    lead = None
    if lead_window is not None:
        lead = (
            lag * recent_velocity(tag.x, lead_window),
            lag * recent_velocity(tag.y, lead_window),
        )
    x, y = station(tag.x, tag.y, radius, bearing, lead)
    # y[k] = keep·y[k-1] + (1 - keep)·target[k], started at the first target
    x = lfilter([1.0 - keep], [1.0, -keep], x - x[0]) + x[0]
    y = lfilter([1.0 - keep], [1.0, -keep], y - y[0]) + y[0]
    return Trajectory(tag.time, x, y)


def homing_memory(time_constant: float) -> tuple[float, float]:
    """The homing low-pass of :func:`steered_auv`: its memory per second and its lag.

    Parameters
    ----------
    time_constant : float
        Low-pass time constant τ (s).

    Returns
    -------
    keep : float
        ``e^(-1/τ)``: the share of last second's position kept each second.
    lag : float
        ``keep / (1 - keep)`` (s): how far in time a vehicle trails a set point moving at
        a steady velocity, the lead that cancels it.
    """
    keep = float(np.exp(-1.0 / time_constant))
    return keep, keep / (1.0 - keep)


def station(shark_x, shark_y, radius: float, bearing, lead=None):
    """A vehicle's station: ``radius`` metres from the shark at ``bearing``, plus a lead.

    Parameters
    ----------
    shark_x, shark_y : float or numpy.ndarray, shape (n,)
        The shark's position (m).
    radius : float
        Distance of the station from the shark (m).
    bearing : float or numpy.ndarray, shape (n,)
        Bearing of the station from the shark (rad, from +x).
    lead : tuple of (float or numpy.ndarray), optional
        ``(x, y)`` offset (m) ahead of the shark (its recent velocity times the homing lag,
        see :func:`steered_auv`); ``None``: no lead.

    Returns
    -------
    x, y : float or numpy.ndarray, shape (n,)
        The station (m).
    """
    x = shark_x + radius * np.cos(bearing)
    y = shark_y + radius * np.sin(bearing)
    if lead is not None:
        x = x + lead[0]
        y = y + lead[1]
    return x, y


def recent_velocity(position: np.ndarray, window: float) -> np.ndarray:
    """Exponential average of the 1 s displacements of one coordinate up to each second.

    Parameters
    ----------
    position : numpy.ndarray, shape (n,)
        One coordinate sampled every second (m).
    window : float
        Time constant of the average (s, > 0).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``v[k] = a·v[k-1] + (1 - a)·(position[k] - position[k-1])`` with ``a = e^(-1/window)``,
        ``v[0] = 0`` (m/s): causal, it uses no later position.
    """
    if not (np.isfinite(window) and window > 0):
        raise ValueError(f"recent_velocity: window must be a positive number of s, got {window!r}")
    keep = np.exp(-1.0 / window)
    step = np.diff(position, prepend=position[0])
    return lfilter([1.0 - keep], [1.0, -keep], step)


def circling_pair(
    tag: Trajectory,
    phi: float,
    *,
    trail_radius: float = 80.0,
    circle_radius: float = 130.0,
    lap_time: float = 1200.0,
) -> dict[str, Trajectory]:
    """Two AUVs steered so that the tag's position and clock are both observable.

    ``auv-1`` trails the shark at ``trail_radius`` on the fixed bearing ``phi``; ``auv-2``
    circles it at ``circle_radius``, one lap every ``lap_time`` seconds, starting a
    quarter turn from ``auv-1``. Two vehicles holding a fixed geometry around the shark
    (the paper's pursuit) leave a common shift of the emission clock nearly
    indistinguishable from a radial shift of the position, and keep the mirror
    intersection of their two range circles; a vehicle whose bearing from the shark turns
    sees the same position shift as a range change that varies around the lap, which a
    smooth path cannot follow, and moves the mirror intersection around. With two
    receivers this reduces the clock-position ambiguity but does not remove it (a common
    clock shift still maps to a position shift along the bisector of the two bearings;
    reports/clock_aware.md measures what is left). The defaults keep the
    circling vehicle's speed relative to the shark at 2π·130/1200 ≈ 0.7 m/s (about 2 m/s
    at most over ground for a shark at ~1 m/s) and both vehicles inside the detection
    range (50 % at 160 m).

    Parameters
    ----------
    tag : Trajectory
        The shark's path sampled every second.
    phi : float
        Bearing of the trailing vehicle from the shark (rad).
    trail_radius, circle_radius : float
        Distances from the shark (m).
    lap_time : float
        Time of one lap of the circling vehicle (s).

    Returns
    -------
    dict of str to Trajectory
        ``auv-1`` (trailing) and ``auv-2`` (circling).
    """
    elapsed = tag.time - tag.time[0]
    return {
        "auv-1": steered_auv(tag, trail_radius, np.full(elapsed.size, phi)),
        "auv-2": steered_auv(
            tag, circle_radius, phi + 0.5 * np.pi + 2.0 * np.pi * elapsed / lap_time
        ),
    }


def rotating_pair(
    tag: Trajectory,
    phi: float,
    *,
    radius: float = 70.0,
    lap_time: float = 600.0,
    separation: float = 0.5 * np.pi,
    time_constant: float = 20.0,
    lead_window: float | None = None,
) -> dict[str, Trajectory]:
    """Two AUVs that keep a right angle at the shark and circle it together.

    Both AUVs hold stations ``radius`` metres from the shark, ``separation`` radians apart
    in bearing, and the pair turns around the shark once every ``lap_time`` seconds. The
    fixed angle keeps the two range circles crossing at a right angle (the tag is never
    near the line through the AUVs, where two ranges fix it poorly and the mirror
    intersection merges with it), and the turning moves the bisector along which a
    common clock shift would move the fix, so that a wrong clock shows as a path the
    shark would have to swim in circles. The vehicles home on their stations more
    tightly than :func:`steered_auv`'s default (20 s), or the pair would lag behind a
    travelling shark instead of circling it; the defaults keep their speeds like
    :func:`circling_pair`'s (about 1 m/s median, 99 % of the time under ~2.2 m/s for a
    shark at ≤ 1.5 m/s). Even at 20 s a pair that turns in minutes falls behind a fast
    shark and closes its angle; ``lead_window`` leads the stations by the shark's
    velocity so that it does not (:class:`RotatingPlan`).

    Parameters
    ----------
    tag : Trajectory
        The shark's path sampled every second.
    phi : float
        Bearing of ``auv-1`` from the shark at the start (rad).
    radius : float
        Distance of both stations from the shark (m).
    lap_time : float
        Time of one turn of the pair (s).
    separation : float
        Angle between the two stations' bearings (rad).
    time_constant : float
        Low-pass time constant of the vehicles' homing (s, see :func:`steered_auv`).
    lead_window : float, optional
        Stations led ahead of the shark by its recent velocity (see :func:`steered_auv`);
        ``None`` (default): no lead.

    Returns
    -------
    dict of str to Trajectory
        ``auv-1`` and ``auv-2``.
    """
    bearings = pair_bearings(tag.time - tag.time[0], phi, lap_time, separation)
    return {
        name: steered_auv(tag, radius, bearing, time_constant, lead_window)
        for name, bearing in bearings.items()
    }


def pair_bearings(elapsed, phi: float, lap_time: float, separation: float) -> dict:
    """Bearings of :func:`rotating_pair`'s two stations from the shark.

    Parameters
    ----------
    elapsed : float or numpy.ndarray, shape (n,)
        Time since the start of the plan (s).
    phi : float
        Bearing of ``auv-1``'s station at the start (rad).
    lap_time : float
        Time of one turn of the pair (s).
    separation : float
        Angle from ``auv-1``'s station to ``auv-2``'s (rad).

    Returns
    -------
    dict of str to (float or numpy.ndarray, shape (n,))
        ``auv-1`` and ``auv-2``: bearing (rad, from +x).
    """
    bearing = phi + 2.0 * np.pi * elapsed / lap_time
    return {"auv-1": bearing, "auv-2": bearing + separation}


@dataclass(frozen=True)
class RotatingPlan:
    """A steering plan for two AUVs that circle the shark together (:func:`rotating_pair`).

    The defaults are the observable plan of ``benchmarks/bench_two_auv_plan.py``: both
    stations 27 m from the shark, 135° apart, the pair turning once every 150 s, each
    station led ahead of the shark by the shark's recent velocity (``lead_window``, see
    :func:`steered_auv`). Homing with a 20 s time constant, the vehicles fly the lap on a
    circle of 27 × 0.77 ≈ 21 m (the low-pass's gain at one turn per 150 s; 5-95 %:
    16-26 m), hold the angle (median 134-135° by seed; 5th percentile 114-122°) and
    fly every lap. Without the lead they fell behind a travelling shark: on the same
    plan at 30 m they were 72-126° apart by seed (median), 6-46 m from the shark, and
    flew 76-97 % of the laps, and on the fastest shark (seed 8, median 0.79 m/s) the
    filter's error reached 10.1 m. On the realistic pursuit (:func:`realistic_shark_pursuit`,
    2 h, 9 seeds) the AUVs' speeds over ground are 2.1-2.5 m/s at the 99th percentile and
    at most 2.4-2.9 m/s (1 s steps), and the arrival-time filter with the
    ``two-moving-receivers`` preset (:mod:`hmmtrack.tracking.config`) reaches a mean error after
    convergence of 5.6 m (worst of 18 runs, 9 scenarios × 2 filter seeds, 6.6 m;
    reports/two_auv_plan.md). The
    stations are placed from the true shark track, as the paper's simulated hydrophone
    paths are built from it; :func:`hmmtrack.experiments.closed_loop.fly_closed_loop` flies the plan
    on the filter's online estimate instead (the preset without the detection curve:
    5.0 m mean, worst 5.4 m over the same 18 runs, against 5.7 and 6.8 m steered on the
    truth; reports/closed_loop.md).

    Parameters
    ----------
    radius, lap_time, separation, time_constant, lead_window
        As :func:`rotating_pair`'s (other defaults).
    """

    radius: float = 27.0
    lap_time: float = 150.0
    separation: float = float(np.radians(135.0))
    time_constant: float = 20.0
    lead_window: float | None = 30.0

    def __post_init__(self) -> None:
        for name in ("radius", "lap_time", "time_constant", "lead_window"):
            value = getattr(self, name)
            if name == "lead_window" and value is None:
                continue
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"RotatingPlan: {name} must be a positive number, got {value!r}")
        if not 0 < self.separation < 2 * np.pi:
            raise ValueError(
                f"RotatingPlan: separation must lie in (0, 2π) rad, got {self.separation!r}"
            )

    def bearings(self, elapsed, phi: float) -> dict:
        """The stations' bearings from the shark (rad) at ``elapsed`` s (:func:`pair_bearings`)."""
        return pair_bearings(elapsed, phi, self.lap_time, self.separation)

    def receivers(self, tag: Trajectory, phi: float) -> dict[str, Trajectory]:
        """The two AUVs' true paths around ``tag`` (see :func:`rotating_pair`)."""
        return rotating_pair(tag, phi, **dataclasses.asdict(self))

    def describe(self) -> str:
        """``"30 m, 135°, lap 150 s, led"`` (``led``: stations led by the shark's velocity)."""
        led = "" if self.lead_window is None else ", led"
        return (
            f"{self.radius:g} m, {np.degrees(self.separation):.0f}°, lap {self.lap_time:g} s{led}"
        )


#: named plans of :func:`rotating_pair` for ``realistic_shark_pursuit(steering=...)``:
#: ``formation`` keeps a right angle (70 m, one turn per 10 min, no lead); ``observable``
#: is the plan on which two AUVs track the shark to under 10 m in every run measured
#: (:class:`RotatingPlan`'s defaults)
ROTATING_PLANS = {
    "formation": RotatingPlan(
        radius=70.0, lap_time=600.0, separation=0.5 * np.pi, lead_window=None
    ),
    "observable": RotatingPlan(),
}
#: names of ``realistic_shark_pursuit``'s steerings
STEERINGS = ("circling", "paper", *ROTATING_PLANS)


def realistic_shark_pursuit(
    seed: SeedLike,
    *,
    dive: bool = False,
    schedule_wander: float = 0.8,
    detection: LogisticDetection | None = None,
    steering: str | RotatingPlan = "circling",
    smoothing_time: float = 600.0,
) -> ClockScenario:
    """A shark pursuit by two AUVs (150 min) with realistic clocks.

    The shark's path is that of :func:`hmmtrack.scenarios.paper.shark_pursuit` for the same
    seed (1 Hz samples, linearly interpolated); the steering changes only the AUVs. With
    ``steering="circling"`` (default) one AUV trails the shark at 80 m and the other
    circles it at 130 m, one lap per 20 min (:func:`circling_pair`): an operator who must
    localise a tag whose clock is unknown does not hold a fixed formation, because with
    the paper's formation a common clock shift and a radial position shift explain the
    arrival times almost equally (the paper itself cites optimal AUV positioning). With
    ``steering="paper"`` the AUVs are the paper's (fixed offsets 90° apart, lagging), kept
    to show that limit. With ``steering="formation"`` both AUVs circle the shark together
    at a right angle (:func:`rotating_pair`: 70 m, one turn per 10 min). With
    ``steering="observable"`` they circle it on stations 27 m away, 135° apart, one turn
    per 150 s, led by the shark's recent velocity (:class:`RotatingPlan`'s defaults, where
    its geometry, speeds and errors are given): the plan on which the arrival-time filter
    with the ``two-moving-receivers`` preset stays under 10 m; a :class:`RotatingPlan`
    flies any other such plan. The tag's period (8 s)
    wanders ``schedule_wander`` seconds from a constant schedule over 1.8 h, with 65 µs
    jitter; the AUVs' clocks have offsets of ~0.5 s and drifts of ~20 ppm, calibrated (GPS
    time) to 0.1 ms and 0.02 ppm; 3 % of detections are multipath arrivals; GPS noise
    1.5 m; pings are heard with a logistic range curve (default 50 % at 160 m, 40 m
    fall-off).

    Parameters
    ----------
    seed : int, SeedSequence or Generator
    dive : bool
        A diving, depth-reporting tag (see ``shark_pursuit``).
    schedule_wander : float
        See :class:`WanderingPeriodClock` (s).
    detection : LogisticDetection, optional
        Detection curve of both AUVs.
    steering : {"circling", "paper", "formation", "observable"} or RotatingPlan
        How the AUVs move (see above).
    smoothing_time : float
        Time constant of the period's random walk (s, see :class:`WanderingPeriodClock`;
        0: a plain random walk from ping to ping).
    """
    if isinstance(steering, RotatingPlan):
        plan, label = steering, f"rotating pair {steering.describe()}"
    elif steering in STEERINGS:
        plan, label = ROTATING_PLANS.get(steering), steering
    else:
        raise ValueError(f"steering must be one of {STEERINGS} or a RotatingPlan, got {steering!r}")
    rng = as_generator(seed)
    base = shark_pursuit(rng, dive=dive)
    tag, receivers = _paths_from_tables(base.truth, base.receivers_truth)
    if steering != "paper":
        phi = float(rng.uniform(-np.pi, np.pi))
        receivers = circling_pair(tag, phi) if plan is None else plan.receivers(tag, phi)
    period = 8.0
    return build_clock_scenario(
        rng,
        name="shark-pursuit-realistic-clock",
        description=(
            f"Synthetic: a shark pursuit by two AUVs ({label} steering) with a tag whose "
            f"8 s period wanders {schedule_wander} s from a constant schedule over 1.8 h, "
            "receiver clocks with offsets and drifts (calibrated), 3 % multipath arrivals."
        ),
        tag=tag,
        receivers=receivers,
        clock=WanderingPeriodClock(
            period,
            schedule_wander,
            phase=float(rng.uniform(0, period)),
            smoothing_time=smoothing_time,
        ),
        detection=detection or LogisticDetection(range_50=160.0, width=40.0),
        multipath=Multipath(),
        gps=GpsNoise(sd=1.5, correlation_time=60.0),
        start=base.start,
        end=base.end,
    )
