"""Closed-loop steering: two AUVs that fly a :class:`RotatingPlan` around the filter's estimate.

:func:`hmmtrack.scenarios.realistic.realistic_shark_pursuit` places the AUVs' stations from the
true shark track, as the paper's simulated hydrophone paths are. A robot only has the
tracker's estimate. :func:`fly_closed_loop` re-flies the AUVs of such a scenario second by
second with the tracker in the loop:

1. the position steered on is the tracker's latest estimate (``steer_on="estimate"``) or,
   for checking, the true shark position (``steer_on="truth"``);
2. the stations are the plan's (:meth:`RotatingPlan.bearings`,
   :func:`hmmtrack.scenarios.steering.station`), led by the exponential average of the
   steered-on position's 1 s displacements (the plan's ``lead_window``, as
   :func:`hmmtrack.scenarios.steering.recent_velocity`), and each vehicle homes on its station
   through the plan's low-pass (:func:`hmmtrack.scenarios.steering.homing_memory`), capped at
   ``max_speed``;
3. the tag's pings (the scenario's emissions) reach the AUVs where they now are; each is
   heard with the scenario's detection curve, logged with the scenario's receiver clocks
   and multipath delays, and its vehicle's position logged with the scenario's GPS errors;
4. the tracker is stepped online (:meth:`hmmtrack.tracking.filter.ParticleFilter.step`) with what
   was heard, on the common time base.

Timing. A detection at common time ``τ`` is corrected at the filter's whole second
``rint(τ)`` (as :meth:`ParticleFilter.iterate` does offline), so the filter can take
second ``k - 1`` once the AUVs' positions at second ``k`` are fixed (arrivals up to ``k``
are then known). The AUVs' positions at ``k`` are set from the estimate at ``k - 2``,
carried forward by the lead velocity over those 2 s (``latency``): a 2 s delay between
hearing and steering, with the filter's own convention. With the truth steered on there
is no delay, and the run flies exactly the open-loop plan.

Start. The AUVs steer on the estimate from its first value (second 2; the first two
seconds circle the start point): the tracker's mean starts at
the centre of its search box, which is the middle of the AUVs' start positions (the
deployment point, about 10 m from the tagged shark on the observable plan), so they circle
where they were put in the water and follow the cloud's mean as the first detections
shrink it. Holding that point until the cloud has shrunk (``hold_until_spread``) was
tried and fails: a pair circling a fixed point while the shark swims off gives the
tracker a poor geometry, the cloud then never shrinks enough, and the AUVs lose the shark
(on 3 trial scenarios of 30 min, seeds 10-12: 2 of 3 held to 10 m and 1 of 3 held to
30 m never let go, ending 160 m to 1.3 km off; steering on the estimate from the start
gave 4.6-5.0 m from 5 min on). The option is kept to show it. After a switch from
holding, the lead velocity restarts at zero, so the jump from the start point to the
estimate is not taken for a fast shark.

Common random numbers. Everything that does not depend on the AUVs' paths is taken from
the open-loop scenario: the shark, the emissions, the receiver clocks and their
calibration, each (ping, receiver)'s multipath delay and the GPS errors. A (ping,
receiver) heard in the open loop with probability ``p`` is heard in the closed loop when
``u < p'`` (``p'`` its new probability), ``u`` drawn uniform on ``(0, p)`` if it was heard
and on ``(p, 1)`` if not: ``u`` is then uniform on ``(0, 1)``, so the closed loop hears
with the right law, and where the geometry is unchanged it hears what the open loop did.

Measured in ``reports/closed_loop.md`` (``hmmtrack study closed-loop``,
:mod:`hmmtrack.experiments.closed_loop_study`).

This module simulates and runs a tracker online. It does no filtering of its own
(:func:`arrival_time_tracker` only assembles the filter that
:func:`hmmtrack.tracking.pipeline.track` runs) and scores nothing
(:mod:`hmmtrack.analysis.metrics`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios.clocks import ClockScenario
from hmmtrack.scenarios.detection import arrival_times, detections_from_pings
from hmmtrack.scenarios.steering import RotatingPlan, homing_memory, station
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import ESTIMATE_COLUMNS, ParticleFilter
from hmmtrack.tracking.measurement.clock import to_common_time
from hmmtrack.tracking.measurement.clocked import ClockedArrivalTime, arrival_observations
from hmmtrack.tracking.pipeline import particle_filter
from hmmtrack.tracking.receivers import ReceiverTracks

#: what the stations are placed around: the tracker's estimate, or the true shark (a check)
STEER_ON = ("estimate", "truth")
#: columns of :attr:`ClosedLoopRun.steering`
STEERING_COLUMNS = ("time", "source", "shark_x", "shark_y", "velocity_x", "velocity_y")
#: an arrival is taken once it lies this far (s) before the last AUV position fixed, so that
#: the path solver never looks past it
_ARRIVAL_MARGIN = 0.01


@dataclass(frozen=True, kw_only=True)
class ClosedLoopRun:
    """What :func:`fly_closed_loop` returns.

    Attributes
    ----------
    receivers_truth : pandas.DataFrame
        The AUVs' true paths: ``receiver``, ``time`` (s, every second), ``x``, ``y`` (m).
    receivers : pandas.DataFrame
        The same with the scenario's GPS errors (what the tracker was given).
    pings : pandas.DataFrame
        Every ping emitted in the run at every AUV, heard or not: the columns of
        :data:`hmmtrack.scenarios.detection.PING_COLUMNS` and ``multipath_delay`` (s),
        sorted by receiver then ping, like the scenario's.
    detections : pandas.DataFrame
        The detection log (logged times): ``time``, ``receiver``, ``transmitter``.
    observations : pandas.DataFrame
        What the tracker was given, on the common time base
        (:func:`hmmtrack.tracking.measurement.clocked.arrival_observations`).
    estimates : pandas.DataFrame
        The tracker's estimate every second (:data:`hmmtrack.tracking.filter.ESTIMATE_COLUMNS`).
    steering : pandas.DataFrame
        Per second (:data:`STEERING_COLUMNS`): ``source`` (``"start"``, ``"estimate"`` or
        ``"truth"``), the shark position the stations were placed around (m) and the lead
        velocity (m/s).
    events : pandas.DataFrame
        The tracker's events (``time``, ``kind``, ``detail``).
    """

    receivers_truth: pd.DataFrame
    receivers: pd.DataFrame
    pings: pd.DataFrame
    detections: pd.DataFrame
    observations: pd.DataFrame
    estimates: pd.DataFrame
    steering: pd.DataFrame
    events: pd.DataFrame


def plan_phase(case: ClockScenario, plan: RotatingPlan) -> float:
    """The bearing ``phi`` (rad) of ``auv-1``'s first station in an open-loop ``case``.

    The plan starts each vehicle on its station with no lead (the velocity average starts
    at zero), so ``auv-1`` starts ``plan.radius`` from the shark at bearing ``phi`` and
    ``auv-2`` at ``phi + plan.separation``.

    Raises
    ------
    ValueError
        When the case's AUVs do not start where ``plan`` would put them (another plan).
    """
    sc = case.scenario
    start = _start_positions(sc)
    shark = sc.truth.iloc[0]
    if set(start) != {"auv-1", "auv-2"}:
        raise ValueError(f"plan_phase: expected receivers auv-1 and auv-2, got {sorted(start)}")
    dx, dy = start["auv-1"][0] - shark["x"], start["auv-1"][1] - shark["y"]
    phi = float(np.arctan2(dy, dx))
    for name, bearing in plan.bearings(0.0, phi).items():
        expected = station(shark["x"], shark["y"], plan.radius, bearing)
        miss = float(np.hypot(*(np.asarray(expected) - start[name])))
        if miss > 1e-6:
            raise ValueError(
                f"plan_phase: {name} starts {miss:.3g} m from where the plan "
                f"{plan.describe()!r} puts it; was the case flown with another plan?"
            )
    return phi


def _start_positions(sc) -> dict[str, np.ndarray]:
    first = sc.receivers_truth[sc.receivers_truth["time"] == sc.start]
    return {str(r): np.array([x, y]) for r, x, y in first[["receiver", "x", "y"]].to_numpy()}


class _Channel:
    """How each (ping, receiver) of the open-loop scenario is heard and logged.

    Holds, per receiver and ping, the coupled uniform draw ``u`` (module docstring) and the
    multipath delay (s), with the scenario's detection curve and true receiver clocks.
    """

    def __init__(self, case: ClockScenario, names, rng: np.random.Generator) -> None:
        pings = case.scenario.pings
        draws = rng.random(len(pings))
        heard = pings["detected"].to_numpy()
        p = pings["probability"].to_numpy(dtype=float)
        u = np.where(heard, p * draws, p + (1.0 - p) * draws)
        receiver = pings["receiver"].to_numpy()
        self.draw, self.delay = {}, {}
        for name in names:
            rows = np.flatnonzero(receiver == name)
            order = rows[np.argsort(pings["ping"].to_numpy()[rows], kind="stable")]
            self.draw[name] = u[order]
            self.delay[name] = pings["multipath_delay"].to_numpy(dtype=float)[order]
        self.detection = case.detection_probability
        self.clocks = case.receiver_clocks
        self.sound_speed = case.scenario.sound_speed

    def hear(self, name: str, ping: np.ndarray, emission, arrival, distance) -> pd.DataFrame:
        """Rows of the pings table for the pings ``ping`` (indices) arriving at ``name``."""
        delay = self.delay[name][ping]
        probability = self.detection(distance)
        return pd.DataFrame(
            {
                "ping": ping,
                "emission_time": emission,
                "receiver": name,
                "arrival_time": arrival,
                "logged_time": self.clocks[name].to_recorded(arrival) + delay,
                "range": distance,
                "probability": probability,
                "detected": self.draw[name][ping] < probability,
                "multipath_delay": delay,
            }
        )


def _per_receiver(table: pd.DataFrame, names) -> dict[str, np.ndarray]:
    """``x`` and ``y`` of a receiver-positions table per receiver in time order: (m, 2)."""
    return {
        name: table.loc[table["receiver"] == name].sort_values("time")[["x", "y"]].to_numpy()
        for name in names
    }


class _Fleet:
    """The two AUVs flying ``plan`` from their start positions, one second at a time.

    Homing works as :func:`hmmtrack.scenarios.steering.steered_auv`'s low-pass, in positions
    relative to the start (``offset``), with each 1 s step capped at ``max_speed`` metres.
    """

    def __init__(self, plan, phi, start: dict, n_seconds: int, max_speed) -> None:
        self.plan, self.phi, self.max_speed = plan, phi, max_speed
        self.keep, self.lag = homing_memory(plan.time_constant)
        self.start = start
        self.offset = {name: np.zeros((n_seconds, 2)) for name in start}
        self.position = {name: np.tile(xy, (n_seconds, 1)) for name, xy in start.items()}

    def fly(self, k: int, elapsed: float, shark: np.ndarray, velocity) -> None:
        """Set every AUV's position at second ``k`` (>= 1) from the shark position steered
        on (m, shape (2,)) and the lead velocity (m/s, shape (2,), or None: no lead)."""
        lead = None if velocity is None else (self.lag * velocity[0], self.lag * velocity[1])
        for name, bearing in self.plan.bearings(elapsed, self.phi).items():
            target = np.array(station(shark[0], shark[1], self.plan.radius, bearing, lead))
            previous = self.offset[name][k - 1]
            moved = (1.0 - self.keep) * (target - self.start[name]) + self.keep * previous
            step = moved - previous
            length = float(np.hypot(step[0], step[1]))
            if self.max_speed is not None and length > self.max_speed:
                moved = previous + step * (self.max_speed / length)
            self.offset[name][k] = moved
            self.position[name][k] = moved + self.start[name]

    def path(self, name: str, time: np.ndarray, lo: int, hi: int) -> Trajectory:
        """``name``'s path over seconds ``lo`` to ``hi`` (inclusive)."""
        xy = self.position[name][lo : hi + 1]
        return Trajectory(time[lo : hi + 1], xy[:, 0], xy[:, 1])


class _Pilot:
    """Each second, the shark position the stations are placed around and the lead velocity.

    The lead velocity is :func:`hmmtrack.scenarios.steering.recent_velocity`'s average of
    the steered-on position's 1 s displacements, restarted at zero when the source of
    that position changes (start point to estimate).
    """

    def __init__(self, steer_on, centre, lead_window, latency, hold_until_spread) -> None:
        self.steer_on, self.centre, self.latency = steer_on, centre, latency
        self.memory = None if lead_window is None else np.exp(-1.0 / lead_window)
        self.hold_until_spread = hold_until_spread
        self.holding = hold_until_spread is not None
        self.velocity, self.previous, self.source = np.zeros(2), None, None
        self.rows: list[tuple] = []

    def steer(self, time: float, shark: np.ndarray, estimate) -> tuple[np.ndarray, object]:
        """The position (m, shape (2,)) to place the stations around at ``time`` and the
        lead velocity (m/s, shape (2,), or None without lead), from the true ``shark``
        position or the latest ``estimate`` (None before the first)."""
        if self.steer_on == "truth":
            source, seen = "truth", shark
        elif self.holding or estimate is None:
            source, seen = "start", self.centre
        else:
            source, seen = "estimate", np.array([estimate.x, estimate.y])
        if source == self.source and self.memory is not None:
            self.velocity = (1.0 - self.memory) * (
                seen - self.previous
            ) + self.memory * self.velocity
        else:  # the first second, a switch of source, or no lead
            self.velocity = np.zeros(2)
        steered = seen + self.latency * self.velocity if source == "estimate" else seen
        self.rows.append((time, source, *steered, *self.velocity))
        self.previous, self.source = seen, source
        return steered, None if self.memory is None else self.velocity

    def saw(self, estimate) -> None:
        """Stop holding once ``estimate``'s spread is down to ``hold_until_spread``."""
        self.holding = self.holding and not estimate.sqrt_lambda1 <= self.hold_until_spread

    def table(self) -> pd.DataFrame:
        """The steering table (:data:`STEERING_COLUMNS`)."""
        return pd.DataFrame(self.rows, columns=list(STEERING_COLUMNS))


def fly_closed_loop(
    case: ClockScenario,
    plan: RotatingPlan,
    tracker,
    *,
    steer_on: str = "estimate",
    duration: int | None = None,
    max_speed: float | None = 3.0,
    hold_until_spread: float | None = None,
    latency: float = 2.0,
    seed: SeedLike = None,
) -> ClosedLoopRun:
    """Re-fly ``case``'s AUVs on ``plan`` around ``tracker``'s online estimate.

    See the module docstring for the loop, its timing, its start and what is reused from
    ``case``.

    Parameters
    ----------
    case : ClockScenario
        An open-loop :func:`hmmtrack.scenarios.realistic.realistic_shark_pursuit` flown with
        ``plan`` (``steering=plan`` or the named plan it is); without a diving tag.
    plan : RotatingPlan
        The plan (its start bearing is recovered by :func:`plan_phase`).
    tracker : hmmtrack.tracking.filter.ParticleFilter
        Not yet started; stepped once a second with ``step(time, observations)`` on the
        observations of :func:`hmmtrack.tracking.measurement.clocked.arrival_observations` (e.g. a
        filter of :func:`arrival_time_tracker` whose search box is
        ``case.search_bounds``). It must not use future detections (no silence model).
    steer_on : {"estimate", "truth"}
        Place the stations around the tracker's estimate, or around the true shark, which
        flies ``case``'s AUV paths exactly (up to ``max_speed``) and hears its pings.
    duration : int, optional
        Seconds tracked (the tracker's last step is at ``start + duration``); the AUVs fly
        one second longer. Default: the scenario's length less 1 s.
    max_speed : float or None
        Top speed of the AUVs (m/s; 1 s steps). The default 3 m/s is above every speed
        of the open-loop plan (at most 2.9 m/s over 9 seeds), so it only binds when the
        estimate jumps. ``None``: no cap.
    hold_until_spread : float, optional
        Circle the start point (no lead) until the tracker's √λ₁ first falls to this
        spread (m), then steer on the estimate; ``None`` (default): steer on the
        estimate from the start (see the module docstring for why).
    latency : float
        Seconds (2, see the module docstring) by which the estimate is carried forward
        with the lead velocity; not used with ``steer_on="truth"``.
    seed : int, SeedSequence or Generator
        For the coupled draws of which pings are heard.

    Returns
    -------
    ClosedLoopRun
    """
    if steer_on not in STEER_ON:
        raise ValueError(f"steer_on must be one of {STEER_ON}, got {steer_on!r}")
    if getattr(tracker, "particles", None) is not None:
        raise ValueError("fly_closed_loop: the tracker has already started; pass a new one")
    if max_speed is not None and not (np.isfinite(max_speed) and max_speed > 0):
        raise ValueError(f"max_speed must be a positive number of m/s or None, got {max_speed!r}")
    if not (np.isfinite(latency) and latency >= 0):
        raise ValueError(f"latency must be a number of s >= 0, got {latency!r}")
    if hold_until_spread is not None and not hold_until_spread > 0:
        raise ValueError(
            f"hold_until_spread must be a positive number of m or None, got {hold_until_spread!r}"
        )
    sc = case.scenario
    if "depth" in sc.truth:
        raise ValueError(
            "fly_closed_loop: a diving tag is not supported (its depth is not simulated)"
        )
    names = ("auv-1", "auv-2")
    truth_xy = sc.truth[["x", "y"]].to_numpy()
    time = sc.truth["time"].to_numpy(dtype=float)
    logged, exact = _per_receiver(sc.receivers, names), _per_receiver(sc.receivers_truth, names)
    n_grid = min(time.size, *(len(v) for v in exact.values()))
    duration = n_grid - 2 if duration is None else duration
    if int(duration) != duration or not 1 <= duration <= n_grid - 2:
        raise ValueError(
            f"duration must be a whole number of seconds in [1, {n_grid - 2}] for scenario "
            f"{sc.name!r}, got {duration!r}"
        )
    n_seconds = int(duration) + 2  # AUV positions at seconds 0 .. duration + 1
    gps_error = {name: logged[name][:n_seconds] - exact[name][:n_seconds] for name in names}
    fleet = _Fleet(plan, plan_phase(case, plan), _start_positions(sc), n_seconds, max_speed)
    channel = _Channel(case, names, as_generator(seed))
    shark = Trajectory(time, truth_xy[:, 0], truth_xy[:, 1])
    window_end = time[0] + duration
    emission = case.emission_times
    n_pings = int(np.searchsorted(emission, window_end))
    next_ping = dict.fromkeys(names, 0)
    centre = np.mean([fleet.start[name] for name in names], axis=0)
    pilot = _Pilot(steer_on, centre, plan.lead_window, latency, hold_until_spread)
    pings, heard, ready, observed, estimates = [], [], [], [], []
    for k in range(n_seconds):
        steered, velocity = pilot.steer(time[k], truth_xy[k], estimates[-1] if estimates else None)
        if k > 0:
            fleet.fly(k, time[k] - time[0], steered, velocity)
        for name in names:
            first, last = next_ping[name], int(np.searchsorted(emission[:n_pings], time[k]))
            if last > first:
                rows = _arrived(channel, fleet, shark, name, emission[first:last], first, time, k)
                next_ping[name] += len(rows)
                pings.append(rows)
                heard.append(_common_time(rows, case, window_end))
        # observations need the AUVs' positions at their (corrected) times: up to second k
        heard, known = _split(heard, time[k])
        if len(known):
            observed.append(_observations(known, fleet, gps_error, time, k))
            ready.append(observed[-1])
        if k == 0:
            continue
        ready, due = _split(ready, k - 1, origin=time[0])
        if len(due) and np.rint(due["time"].min() - time[0]) < k - 1:
            raise RuntimeError(f"fly_closed_loop: an observation came after its second {k - 1}")
        estimate = tracker.step(time[k - 1], due if len(due) else None)
        estimates.append(estimate)
        pilot.saw(estimate)
    unresolved = {name: n_pings - next_ping[name] for name in names if next_ping[name] < n_pings}
    if unresolved:
        raise RuntimeError(
            f"fly_closed_loop: pings of the run not yet arrived at the end {unresolved}: "
            "ranges over ~1.4 km (flight over 1 s) are not supported"
        )
    pings = pd.concat(pings, ignore_index=True).sort_values(["receiver", "ping"], kind="stable")
    pings = pings.reset_index(drop=True)
    exact = pd.concat(
        [
            pd.DataFrame({"receiver": name, "time": time[:n_seconds], "x": xy[:, 0], "y": xy[:, 1]})
            for name, xy in fleet.position.items()
        ],
        ignore_index=True,
    )
    errors = np.concatenate([gps_error[name] for name in fleet.position])
    return ClosedLoopRun(
        receivers_truth=exact,
        receivers=exact.assign(x=exact["x"] + errors[:, 0], y=exact["y"] + errors[:, 1]),
        pings=pings,
        detections=detections_from_pings(pings, sc.transmitter),
        observations=pd.concat(observed, ignore_index=True),
        estimates=pd.DataFrame(estimates, columns=list(ESTIMATE_COLUMNS)),
        steering=pilot.table(),
        events=pd.DataFrame(tracker.events, columns=["time", "kind", "detail"]),
    )


def _arrived(channel, fleet, shark, name, emission, first, time, k) -> pd.DataFrame:
    """Pings table rows of the pings ``first``, ``first + 1``, ... (emitted at
    ``emission``, s) that have reached ``name`` by second ``k`` (a leading run of them:
    the rest wait for the next second)."""
    lo = max(int(np.floor(emission[0] - time[0])) - 1, 0)
    path = fleet.path(name, time, lo, k)
    arrival, distance = arrival_times(emission, shark, path, channel.sound_speed)
    ready = arrival <= time[k] - _ARRIVAL_MARGIN
    done = ready.size if ready.all() else int(np.argmin(ready))
    ping = np.arange(first, first + done)
    return channel.hear(name, ping, emission[:done], arrival[:done], distance[:done])


def _common_time(rows: pd.DataFrame, case: ClockScenario, window_end: float) -> pd.DataFrame:
    """The heard pings of ``rows`` as detections on the common time base, before ``window_end``."""
    detections = detections_from_pings(rows, case.scenario.transmitter)
    common = to_common_time(detections, case.clock_calibration)
    return common[common["time"] < window_end]


def _split(frames: list, limit: float, origin: float | None = None) -> tuple[list, pd.DataFrame]:
    """Split the rows of ``frames`` at ``limit``: by their time (s), or with ``origin`` by
    their filter second ``rint(time - origin)``.

    Returns
    -------
    later : list of pandas.DataFrame
        The rows over ``limit``.
    table : pandas.DataFrame
        The others, sorted by time then receiver.
    """
    if not frames:
        return [], pd.DataFrame()
    table = pd.concat(frames, ignore_index=True)
    value = table["time"].to_numpy()
    passed = (value if origin is None else np.rint(value - origin)) <= limit
    later = [table[~passed]] if (~passed).any() else []
    out = table[passed].sort_values(["time", "receiver"], kind="stable").reset_index(drop=True)
    return later, out


def _observations(known: pd.DataFrame, fleet: _Fleet, gps_error, time, k: int) -> pd.DataFrame:
    """The tracker's input rows for detections ``known`` (common time at or before second
    ``k``): the AUVs' logged positions at their times, interpolated as
    :func:`hmmtrack.tracking.measurement.clocked.arrival_observations` does offline."""
    lo = max(int(np.floor(known["time"].min() - time[0])) - 1, 0)
    positions = pd.concat(
        [
            pd.DataFrame(
                {
                    "receiver": name,
                    "time": time[lo : k + 1],
                    "x": xy[lo : k + 1, 0] + gps_error[name][lo : k + 1, 0],
                    "y": xy[lo : k + 1, 1] + gps_error[name][lo : k + 1, 1],
                }
            )
            for name, xy in fleet.position.items()
        ],
        ignore_index=True,
    )
    return arrival_observations(known, ReceiverTracks.from_frame(positions, outside="clamp"))


def arrival_time_tracker(config: TrackingConfig, seed: SeedLike = None) -> ParticleFilter:
    """The arrival-time filter that :func:`hmmtrack.tracking.pipeline.track` runs for
    ``config``, not yet started, without silence model or smoother.

    Parameters
    ----------
    config : TrackingConfig
        ``measurement="arrival-time"`` with ``period`` and ``bounds`` (m) set (e.g. the
        ``two-moving-receivers`` preset with ``case.search_bounds``), without acquisition
        (an online filter has not heard the corrections it would draw from).
    seed : int, SeedSequence or Generator

    Returns
    -------
    ParticleFilter
        With :class:`hmmtrack.tracking.measurement.clocked.ClockedArrivalTime` of the
        configuration (its default clock model: a period random walk of 0.3 ms per ping,
        phase steps of 0.1 ms, the period known to 0.1 %).
    """
    if config.measurement.name != "arrival-time" or config.bounds is None:
        raise ValueError(
            "arrival_time_tracker: the configuration needs measurement 'arrival-time' and bounds"
        )
    if config.measurement.detection_curve is not None:
        raise ValueError(
            "arrival_time_tracker: the closed loop runs without a detection curve (the "
            "silence model is built from the whole detection table, future pings included); "
            "remove detection_curve from the configuration"
        )
    if config.filter.acquisition:
        raise ValueError(
            "arrival_time_tracker: the closed loop steps its filter online, which cannot draw "
            "its first particles from detections not yet heard; set acquisition to False "
            "(e.g. filter='paper')"
        )
    measurement = ClockedArrivalTime.from_settings(
        config.measurement, observations=None, receivers=None
    )
    return particle_filter(
        config.filter, measurement, config.bounds, config.motion_model(), seed=seed
    )
