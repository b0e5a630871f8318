"""Synthetic analogues of the paper's three datasets, each a :class:`Scenario` with ground truth.

The paper's field data (Long Beach, Santa Elena Bay) and its simulated shark pursuit are not
public. These generators rebuild datasets of the same shape from the paper's description
("Datasets" section): durations, periods, geometry, how hydrophones move and how pings are
lost. Positions are local metres (x east, y north) with the tag at the origin at the start;
times are UTC seconds on the paper's dates. They are analogues, not the data: numbers
measured on them can be compared with the paper's only in kind.

* :func:`stationary_tag` — Long Beach: 1,200 s, anchored tag and boat, an AUV driving away
  in 50 m increments, period 8.179 s.
* :func:`swimmer` — Santa Elena Bay: 349 s, a swimmer moving the tag near shore, two
  drifting boats that are each repositioned once, period 8.179 s. Its ``start_region`` is a
  box around the escort boats' fix of the swimmer at the start.
* :func:`shark_pursuit` — the simulated dataset: a 150 min, 115-fix white-shark track,
  two AUVs following it with a constant offset and a low-pass lag, period 8 s, each ping lost
  with a fixed probability per metre of range, tuned so that 645 and 671 of 1,125 pings are
  lost on average; optionally a diving shark with a depth-sensor tag. Its ``start_region`` is
  a box around the team's fix of the shark at launch, for trackers told where the chase began.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios.detection import (
    ExponentialDetection,
    GpsNoise,
    JitteredPeriodClock,
    arrival_times,
    loss_per_metre_for,
)
from hmmtrack.scenarios.historical import ARRAY_SAMPLING
from hmmtrack.scenarios.scenario import Scenario, assemble_scenario
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH, SharkMotionModel
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.detection import LogisticDetection

#: period (s) of the field tag used at Long Beach and Santa Elena Bay
FIELD_TAG_PERIOD = 8.179
#: Gaussian emission jitter (s): real fixed-period tags show 44-83 microseconds
EMISSION_JITTER = 1e-4
#: GPS error of the hydrophones' logged positions: sd 1.5 m per axis, wandering over a minute
HYDROPHONE_GPS = GpsNoise(sd=1.5, correlation_time=60.0)
#: error (m, sd per axis) of the field team's fix of the shark when a pursuit is launched: a
#: boat's estimate of an animal seen or tagged at the surface a few tens of metres away
PURSUIT_START_FIX_ERROR = 30.0
#: half-width (m) of the pursuit's start region around that fix: 3.3 sd, and under half the
#: ~210 m between the tag and its mirror across the two AUVs' line at launch (offsets of
#: 150 m at 90 degrees), so the region holds the tag and not its mirror
PURSUIT_START_HALF_WIDTH = 100.0
#: error (m, sd per axis) of the escort boats' fix of the swimmer when the run starts: the
#: swimmer is in sight, 70 m from each boat
SWIMMER_START_FIX_ERROR = 15.0
#: half-width (m) of the swimmer's start region around that fix: 3 sd, and under half the
#: ~99 m between the swimmer and its mirror across the boats' line at the start (both boats
#: 70 m away at 45 and 135 degrees, on the sea side)
SWIMMER_START_HALF_WIDTH = 45.0


def _utc(stamp: str) -> float:
    return pd.Timestamp(stamp).timestamp()


def auv_station_path(
    start: float,
    end: float,
    *,
    x0: float,
    y0: float,
    heading: float,
    holds: np.ndarray,
    increment: float = 50.0,
    speed: float = 1.5,
) -> Trajectory:
    """An AUV that holds station, drives ``increment`` metres along ``heading``, holds, ...

    Parameters
    ----------
    start, end : float
        UTC s; the path is cut at ``end``.
    x0, y0 : float
        First station (m).
    heading : float
        Direction of travel (rad from +x).
    holds : (k,) float array
        Time (s) spent at each successive station; the path ends at ``end`` or after the last
        hold, whichever comes first.
    increment : float
        Distance (m) between stations.
    speed : float
        Driving speed (m/s) between stations.

    Returns
    -------
    Trajectory
        Vertices at arrivals and departures; consecutive stations are ``increment`` apart.
    """
    times, xs, ys = [start], [x0], [y0]
    ux, uy = np.cos(heading), np.sin(heading)
    for hold in holds:
        times += [times[-1] + hold, times[-1] + hold + increment / speed]
        xs += [xs[-1], xs[-1] + increment * ux]
        ys += [ys[-1], ys[-1] + increment * uy]
        if times[-1] >= end:
            break
    path = Trajectory(np.array(times), np.array(xs), np.array(ys))
    kept = path.time[path.time < end]
    return path.sample(np.append(kept, end))


def _field_scenario(
    rng: np.random.Generator,
    *,
    name: str,
    description: str,
    tag: Trajectory,
    receivers: dict[str, Trajectory],
    curve: LogisticDetection,
    start: float,
    end: float,
) -> Scenario:
    """A field-like dataset: the field tag (period 8.179 s, 0.1 ms jitter, random phase)
    heard by every hydrophone through ``curve``, hydrophone GPS noise, UTC s ``start``-``end``.
    """
    clock = JitteredPeriodClock(FIELD_TAG_PERIOD, EMISSION_JITTER, rng.uniform(0, FIELD_TAG_PERIOD))
    return assemble_scenario(
        rng,
        name=name,
        description=description,
        tag=tag,
        receivers=receivers,
        emission_time=clock.emission_times(rng, start, end),
        period=FIELD_TAG_PERIOD,
        detection_probability=dict.fromkeys(receivers, curve),
        gps=HYDROPHONE_GPS,
        start=start,
        end=end,
        transmitter="A69-1602-1234",
    )


def stationary_tag(seed: SeedLike) -> Scenario:
    """The Long Beach-like dataset: a moored tag, an anchored boat, an AUV stepping away.

    1,200 s from 2022-06-08 17:00 UTC. The tag is at the origin; the boat's hydrophone is
    anchored 32 m away; the AUV starts 20 m from the tag in a random direction and drives
    straight away from it in 50 m increments at 1.5 m/s, holding each station 90-150 s
    (uniform), reaching about 400 m. Period 8.179 s with 0.1 ms jitter; detection falls off
    around 450 m (logistic, at most 95 %); GPS noise 1.5 m on the AUV's 1 Hz positions and on
    the boat's single fix.

    Parameters
    ----------
    seed : int, SeedSequence or Generator

    Returns
    -------
    Scenario
    """
    rng = as_generator(seed)
    start = _utc("2022-06-08T17:00:00Z")
    end = start + 1200.0
    bearing = rng.uniform(-np.pi, np.pi)
    auv = auv_station_path(
        start,
        end,
        x0=20.0 * np.cos(bearing),
        y0=20.0 * np.sin(bearing),
        heading=bearing,
        holds=rng.uniform(90.0, 150.0, size=20),
    )
    boat_bearing = bearing + rng.choice([-1.0, 1.0]) * rng.uniform(0.5 * np.pi, np.pi)
    receivers = {
        "boat": Trajectory.fixed(32.0 * np.cos(boat_bearing), 32.0 * np.sin(boat_bearing)),
        "auv": auv,
    }
    return _field_scenario(
        rng,
        name="stationary-tag",
        description=(
            "Synthetic analogue of the paper's Long Beach dataset: moored tag, anchored "
            "boat hydrophone, AUV hydrophone driving away in 50 m increments, 1200 s."
        ),
        tag=Trajectory.fixed(0.0, 0.0),
        receivers=receivers,
        curve=LogisticDetection(range_50=450.0, width=50.0, max_probability=0.95),
        start=start,
        end=end,
    )


def _swimmer_path(rng: np.random.Generator, time: np.ndarray) -> Trajectory:
    """A swimmer towing the tag along a shore at y = 0: ~0.5 m/s, staying ~50 m out."""
    n = time.size
    x, y, heading, speed = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    y[0], speed[0] = 50.0, 0.5
    shocks = rng.normal(size=(n, 2))
    for k in range(1, n):
        target = np.clip(-0.02 * (y[k - 1] - 50.0), -0.8, 0.8)  # alongshore, back to 50 m
        heading[k] = heading[k - 1] + (target - heading[k - 1]) / 60.0 + 0.08 * shocks[k, 0]
        drift = (0.5 - speed[k - 1]) / 30.0 + 0.03 * shocks[k, 1]  # back to 0.5 m/s
        speed[k] = np.clip(speed[k - 1] + drift, 0.1, 1.0)
        x[k] = x[k - 1] + speed[k] * np.cos(heading[k])
        y[k] = y[k - 1] + speed[k] * np.sin(heading[k])
    return Trajectory(time, x, y)


def _drifting_boat(
    rng: np.random.Generator,
    swimmer: Trajectory,
    time: np.ndarray,
    station: np.ndarray,
    current: np.ndarray,
    reposition_at: float,
    motor_speed: float = 2.0,
) -> Trajectory:
    """A boat drifting with ``current`` plus its own leeway, motoring back to its station once.

    At ``reposition_at`` the boat motors at ``motor_speed`` towards the swimmer's position
    plus ``station`` until it is within 3 m of it, then drifts again.
    """
    sx, sy, _ = swimmer.position(time)
    leeway = rng.normal(0.0, 0.05, 2)
    wander = np.cumsum(rng.normal(0.0, 0.005, (time.size, 2)), axis=0)
    position = np.empty((time.size, 2))
    position[0] = (sx[0], sy[0]) + station
    motoring = False
    for k in range(1, time.size):
        dt = time[k] - time[k - 1]
        if time[k - 1] < reposition_at <= time[k]:
            motoring = True
        if motoring:
            gap = np.array([sx[k], sy[k]]) + station - position[k - 1]
            distance = np.hypot(*gap)
            move = min(motor_speed * dt, distance)
            position[k] = position[k - 1] + gap / max(distance, 1e-12) * move
            motoring = distance - move > 3.0
        else:
            position[k] = position[k - 1] + (current + leeway + wander[k]) * dt
    return Trajectory(time, position[:, 0], position[:, 1])


def swimmer(seed: SeedLike) -> Scenario:
    """The Santa Elena Bay-like dataset: a swimmer moves the tag near shore, two boats drift.

    349 s from 2022-07-21 15:30 UTC. The shore is the line y = 0 (land below). The swimmer
    starts 50 m out and swims alongshore at about 0.5 m/s. Two boats start 70 m from the
    swimmer, 90 degrees apart as seen from it, and drift with a common 0.2 m/s current in a
    random direction plus their own leeway; each is repositioned once (boat-1 at 90-170 s,
    boat-2 at 190-270 s), motoring at 2 m/s back to its station relative to the swimmer.
    Period 8.179 s with 0.1 ms jitter; detection falls off around 250 m (logistic, at most
    90 %, a noisy surf zone); GPS noise 1.5 m on the boats' 1 Hz positions.

    The boats escort a swimmer in sight: ``start_region`` is the square of half-width
    :data:`SWIMMER_START_HALF_WIDTH` around a fix of the swimmer's first position with
    Gaussian error :data:`SWIMMER_START_FIX_ERROR` per axis (drawn from a stream of its own,
    so the rest of the dataset does not depend on it). The paper's filter does not use it.

    Parameters
    ----------
    seed : int, SeedSequence or Generator

    Returns
    -------
    Scenario
    """
    rng = as_generator(seed)
    start = _utc("2022-07-21T15:30:00Z")
    end = start + 349.0
    seconds = start + np.arange(350.0)
    tag = _swimmer_path(rng, seconds)
    direction = rng.uniform(-np.pi, np.pi)
    current = 0.2 * np.array([np.cos(direction), np.sin(direction)])
    receivers = {}
    for name, bearing, window in (
        ("boat-1", 0.75 * np.pi, (90.0, 170.0)),
        ("boat-2", 0.25 * np.pi, (190.0, 270.0)),
    ):
        station = 70.0 * np.array([np.cos(bearing), np.sin(bearing)])
        receivers[name] = _drifting_boat(
            rng, tag, seconds, station, current, start + rng.uniform(*window)
        )
    scenario = _field_scenario(
        rng,
        name="swimmer",
        description=(
            "Synthetic analogue of the paper's Santa Elena Bay dataset: tag moved by a "
            "swimmer near shore, two drifting boat hydrophones repositioned once each, 349 s."
        ),
        tag=tag,
        receivers=receivers,
        curve=LogisticDetection(range_50=250.0, width=40.0, max_probability=0.9),
        start=start,
        end=end,
    )
    return _with_start_region(rng, scenario, tag, SWIMMER_START_FIX_ERROR, SWIMMER_START_HALF_WIDTH)


def pursuit_track(
    rng: np.random.Generator,
    start: float,
    *,
    n_fixes: int = 115,
    duration: float = 9000.0,
    model: SharkMotionModel = WHITE_SHARK_GROUND_TRUTH,
) -> pd.DataFrame:
    """A white-shark track segment like the paper's longest one: 115 fixes over 150 min.

    The shark swims the ground-truth model; it is fixed like a receiver array would
    (:data:`~hmmtrack.scenarios.historical.ARRAY_SAMPLING`: intervals in [60, 180] s,
    Gaussian position error), with the intervals conditioned to add up to ``duration``.

    Returns
    -------
    DataFrame
        ``time`` (UTC s, first ``start``, last ``start + duration``), ``x``, ``y`` (m),
        starting near the origin.
    """
    sampling = ARRAY_SAMPLING
    n_intervals = n_fixes - 1
    slack = duration - n_intervals * sampling.min_interval
    room = sampling.max_interval - sampling.min_interval
    if not 0 < slack < n_intervals * room:
        raise ValueError(
            f"pursuit_track: {n_fixes} fixes cannot span {duration} s with intervals in "
            f"[{sampling.min_interval}, {sampling.max_interval}] s"
        )
    while True:  # intervals = minimum + a uniform split of the slack, none above the maximum
        extra = slack * rng.dirichlet(np.ones(n_intervals))
        if extra.max() < room:
            break
    time = start + np.concatenate([[0.0], np.cumsum(sampling.min_interval + extra)])
    time[-1] = start + duration
    path, _ = model.simulate_path(rng, int(np.ceil(duration / model.dt)), start_time=start)
    x, y, _ = path.position(time)
    error = rng.normal(0.0, sampling.position_error, (2, n_fixes))
    return pd.DataFrame({"time": time, "x": x + error[0], "y": y + error[1]})


def dive_profile(rng: np.random.Generator, time: np.ndarray, max_depth: float = 40.0) -> np.ndarray:
    """A white-shark depth record: near the surface with dives of tens of metres.

    Swims at 1-3 m between dives; dives start at a rate of one per 20 min, last 4-15 min,
    reach 10 m to ``max_depth`` (uniform) with a smooth sin^2 shape; the first dive starts
    within the first third of the record and reaches ``max_depth``.

    Parameters
    ----------
    time : (n,) float array
        UTC s, sorted.
    max_depth : float
        Deepest dive (m).

    Returns
    -------
    (n,) float array
        Depth (m, positive down).
    """
    t = time - time[0]
    span = t[-1]
    depth = 2.0 + np.sin(2 * np.pi * t / 600.0 + rng.uniform(0, 2 * np.pi))
    n_dives = 1 + rng.poisson(span / 1200.0)
    starts = np.concatenate([[rng.uniform(0, span / 3)], rng.uniform(0, span, n_dives - 1)])
    depths = np.concatenate([[max_depth], rng.uniform(10.0, max_depth, n_dives - 1)])
    for begin, bottom, length in zip(starts, depths, rng.uniform(240, 900, n_dives), strict=True):
        inside = (t >= begin) & (t <= begin + length)
        depth[inside] = np.maximum(
            depth[inside], bottom * np.sin(np.pi * (t[inside] - begin) / length) ** 2
        )
    return depth


def _follow(
    track: Trajectory, time: np.ndarray, offset: np.ndarray, time_constant: float
) -> Trajectory:
    """A hydrophone following ``track + offset`` through a first-order low-pass filter."""
    x, y, _ = track.position(time)
    target = np.column_stack([x, y]) + offset
    alpha = 1.0 - np.exp(-np.diff(time) / time_constant)
    path = np.empty_like(target)
    path[0] = target[0]
    for k in range(1, time.size):
        path[k] = path[k - 1] + alpha[k - 1] * (target[k] - path[k - 1])
    return Trajectory(time, path[:, 0], path[:, 1])


def shark_pursuit(
    seed: SeedLike,
    dive: bool = False,
    *,
    track: pd.DataFrame | None = None,
    lost_pings: tuple[float, float] = (645.0, 671.0),
    offset: float = 150.0,
    lag: float = 60.0,
) -> Scenario:
    """The paper's simulated dataset: two AUVs pursue a white shark for 150 minutes.

    The shark's 115 fixes (:func:`pursuit_track`, or ``track``) are linearly interpolated
    to 1 s; that path is the truth. Each hydrophone follows the shark's path shifted by a
    constant offset of ``offset`` metres (bearings ``phi`` and ``phi + 90 deg``, ``phi``
    uniform) and smoothed by a first-order low-pass filter of time constant ``lag``, so it
    lags behind the shark while the two stay roughly 90 degrees apart as seen from it. GPS
    noise 1.5 m. The tag pings every 8 s with 0.1 ms Gaussian jitter (1,125 pings). Each
    ping reaches hydrophone ``j`` with probability ``exp(-lambda_j * range)``; ``lambda_j``
    is solved so that the expected number of lost pings is ``lost_pings[j]`` (the paper's
    645 and 671 of 1,125).

    The AUVs are placed around a shark whose position the team knows: ``start_region`` is
    the square of half-width :data:`PURSUIT_START_HALF_WIDTH` around a fix of the shark's
    first position with Gaussian error :data:`PURSUIT_START_FIX_ERROR` per axis (drawn from
    a stream of its own, so the rest of the dataset does not depend on it). The paper's
    filter does not use it (its particles start anywhere in ``bounds``).

    Parameters
    ----------
    seed : int, SeedSequence or Generator
    dive : bool
        If true, the shark dives (:func:`dive_profile`, up to 40 m), ranges are 3-D and the
        tag reports its depth (``depth`` column in detections and truth).
    track : DataFrame, optional
        ``time``, ``x``, ``y`` of the shark's fixes to use instead of a simulated one (e.g.
        the longest segment of :func:`~hmmtrack.scenarios.historical.white_shark_tracks`).
    lost_pings : (2,) floats
        Expected lost pings at ``auv-1`` and ``auv-2``.
    offset : float
        Distance (m) of each hydrophone's offset from the shark's path.
    lag : float
        Time constant (s) of the hydrophones' low-pass filter.

    Returns
    -------
    Scenario
    """
    rng = as_generator(seed)
    depth_rng = rng.spawn(1)[0]  # the dive has its own stream: same horizontal geometry
    if track is None:
        track = pursuit_track(rng, _utc("2020-07-15T18:00:00Z"))
    fixes = Trajectory(track["time"].to_numpy(), track["x"].to_numpy(), track["y"].to_numpy())
    start, end = fixes.start, fixes.end
    seconds = start + np.arange(int(np.floor(end - start)) + 1, dtype=float)
    tag = fixes.sample(seconds)
    if dive:
        tag = Trajectory(tag.time, tag.x, tag.y, dive_profile(depth_rng, seconds))
    phi = rng.uniform(-np.pi, np.pi)
    receivers = {
        name: _follow(fixes, seconds, offset * np.array([np.cos(a), np.sin(a)]), lag)
        for name, a in (("auv-1", phi), ("auv-2", phi + 0.5 * np.pi))
    }
    period = 8.0
    emissions = JitteredPeriodClock(period, EMISSION_JITTER, rng.uniform(0, period))
    emission_time = emissions.emission_times(rng, start, end)
    detection = {
        name: ExponentialDetection(
            loss_per_metre_for(arrival_times(emission_time, tag, path)[1], expected)
        )
        for (name, path), expected in zip(receivers.items(), lost_pings, strict=True)
    }
    scenario = assemble_scenario(
        rng,
        name="shark-pursuit-dive" if dive else "shark-pursuit",
        description=(
            "Synthetic analogue of the paper's simulated dataset: a 150 min, 115-fix shark "
            "track drawn from the ground-truth white-shark model, two AUV hydrophones "
            "following with a constant offset and a low-pass lag, distance-dependent loss"
            + (", diving shark with a depth-sensor tag." if dive else ".")
        ),
        tag=tag,
        receivers=receivers,
        emission_time=emission_time,
        period=period,
        detection_probability=detection,
        gps=HYDROPHONE_GPS,
        start=start,
        end=end,
        transmitter="A69-9001-2020",
    )
    return _with_start_region(rng, scenario, tag, PURSUIT_START_FIX_ERROR, PURSUIT_START_HALF_WIDTH)


def _with_start_region(
    rng: np.random.Generator,
    scenario: Scenario,
    tag: Trajectory,
    fix_error: float,
    half_width: float,
) -> Scenario:
    """``scenario`` with its ``start_region``: the square of half-width ``half_width`` (m)
    around a fix of the tag's first position with Gaussian error ``fix_error`` (m, per axis),
    drawn from a stream spawned off ``rng`` so the dataset itself does not depend on it."""
    x0, y0, _ = tag.position(np.array([scenario.start]))
    error = rng.spawn(1)[0].normal(0.0, fix_error, 2)
    fx, fy = float(x0[0] + error[0]), float(y0[0] + error[1])
    return replace(
        scenario, start_region=(fx - half_width, fx + half_width, fy - half_width, fy + half_width)
    )
