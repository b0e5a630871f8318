"""Ready-made realistic-clock cases: a shark pursued by AUVs, a resident shark in a moored array.

* :func:`realistic_shark_pursuit` — a shark pursued by two moving hydrophones (2.5 h) with a
  wandering tag period; the AUVs are steered by name (one trails while one circles the
  shark, the paper's fixed formation, or the pair circling the shark together, see
  :data:`STEERINGS`) or by a :class:`RotatingPlan` (:mod:`hmmtrack.scenarios.steering`);
* :func:`moored_array` — a resident shark inside a triangle of three moored receivers;
* :func:`three_auv_pursuit` (the same shark followed by three AUVs, a diagnostic) and
  :func:`rotating_pair_pursuit` (two AUVs on any rotating plan, for planning sweeps).

Each returns a :class:`~hmmtrack.scenarios.clocks.ClockScenario`. It does not track or
score anything.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios.clocks import (
    ClockScenario,
    Multipath,
    WanderingPeriodClock,
    build_clock_scenario,
)
from hmmtrack.scenarios.detection import GpsNoise
from hmmtrack.scenarios.paper import shark_pursuit
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH
from hmmtrack.scenarios.steering import (
    ROTATING_PLANS,
    RotatingPlan,
    circling_pair,
    rotating_pair,
    steered_auv,
)
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.detection import LogisticDetection

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
    detection_range: float = 1.75,
    start: float = 1_600_000_000.0,
) -> ClockScenario:
    """A resident shark inside a triangle of three moored receivers, with realistic clocks.

    The tag follows :data:`RESIDENT_SHARK` (about 0.45 m/s, tortuous). The receivers stand
    at the corners of an equilateral triangle around the shark's home range (the centre
    of its path), each ``array_radius`` from the centre or, if the shark roams further,
    1.2 times its largest distance from the centre, so that it stays inside the array;
    the detection range is logistic with a 50 % range of ``detection_range`` radii (fall-off a
    quarter radius); receiver positions are surveyed to 0.5 m; receiver clocks have offsets of
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
    detection_range : float
        50 % detection range in array radii: at 1.75 most pings reach all three receivers,
        nearer 1 the far receiver hears fewer of them (fewer pings heard by three).
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
        detection=LogisticDetection(range_50=detection_range * radius, width=0.25 * radius),
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


def three_auv_pursuit(seed: int) -> ClockScenario:
    """A diagnostic case: :func:`realistic_shark_pursuit`'s shark followed by three AUVs.

    Each AUV trails the shark 100 m away on a fixed bearing, 120° apart; clocks, multipath,
    GPS and detection are as in the two-AUV pursuit. With a third range the clock's common
    mode is observable at every ping, so this case separates what a tracker can do from
    what two receivers leave undetermined.

    Parameters
    ----------
    seed : int
        The shark is that of ``realistic_shark_pursuit(seed)``; the rest is drawn from
        ``default_rng([seed, 3])``.
    """
    tag = _pursuit_tag(seed)
    rng = np.random.default_rng([seed, 3])
    phi = rng.uniform(-np.pi, np.pi)
    receivers = {
        f"auv-{k + 1}": steered_auv(tag, 100.0, np.full(tag.time.size, phi + 2 * np.pi * k / 3))
        for k in range(3)
    }
    return _pursuit_case(
        rng,
        tag,
        receivers,
        name="shark-pursuit-three-auvs",
        description="Diagnostic: the realistic-clock pursuit with a third AUV.",
    )


def rotating_pair_pursuit(
    seed: int, radius: float, lap_time: float, separation: float
) -> ClockScenario:
    """A planning case: :func:`realistic_shark_pursuit`'s shark, two AUVs on :func:`rotating_pair`.

    The pair circles the shark together (no lead, 20 s homing) at ``radius`` m,
    ``separation`` rad apart, one turn per ``lap_time`` s; the tag clock wanders 0.8 s from
    a constant 8 s schedule; detection, multipath and GPS as in the two-AUV pursuit. Used to
    sweep plans before anyone goes to sea.

    Parameters
    ----------
    seed : int
        The shark is that of ``realistic_shark_pursuit(seed)``; the rest is drawn from
        ``default_rng([seed, 17])``.
    radius, lap_time, separation : float
        m, s, rad (see :func:`rotating_pair`).
    """
    tag = _pursuit_tag(seed)
    rng = np.random.default_rng([seed, 17])
    receivers = rotating_pair(
        tag,
        float(rng.uniform(-np.pi, np.pi)),
        radius=radius,
        lap_time=lap_time,
        separation=separation,
    )
    return _pursuit_case(
        rng,
        tag,
        receivers,
        name="shark-pursuit-planning",
        description="Planning sweep: two AUVs circling the shark together.",
    )


def _pursuit_tag(seed: int) -> Trajectory:
    """The shark of ``realistic_shark_pursuit(seed)`` as a 1 Hz path (no depth)."""
    truth = realistic_shark_pursuit(seed).scenario.truth
    return Trajectory(truth["time"].to_numpy(), truth["x"].to_numpy(), truth["y"].to_numpy())


def _pursuit_case(rng, tag: Trajectory, receivers: dict, *, name: str, description: str):
    """The pursuit's clocks, detection, multipath and GPS for other receivers; ``rng`` draws
    the tag clock's phase first, then :func:`build_clock_scenario`'s draws."""
    return build_clock_scenario(
        rng,
        name=name,
        description=description,
        tag=tag,
        receivers=receivers,
        clock=WanderingPeriodClock(8.0, 0.8, phase=float(rng.uniform(0, 8.0))),
        detection=LogisticDetection(range_50=160.0, width=40.0),
        multipath=Multipath(),
        gps=GpsNoise(sd=1.5, correlation_time=60.0),
        start=float(tag.time[0]),
        end=float(tag.time[-1]),
    )
