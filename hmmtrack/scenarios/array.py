"""A moored receiver array with unsynchronised clocks and sync tags: truth for clock fits.

Receivers on a grid, each with its own clock (offset of up to minutes, drift of tens of
ppm, and a slowly changing drift); sync tags moored at some of them ping at random
intervals and are heard by their neighbours with a range-dependent probability, a small
timing jitter, and now and then by a late multipath path instead of the direct one. The
receivers file holds the surveyed positions: exact for receivers marked ``fixed``, off by
a few metres for the others. :func:`hmmtrack.sync.fit_clocks` should recover every clock,
the sound speed and the positions from the detections alone. Echoes (a second detection of
a ping at one receiver, late by a fraction of a second to seconds) may be added.

:func:`tagged_array` adds a tag moving inside the array on a pseudo-random burst interval
(a known interval sequence, or a random interval to a tracker not told it), heard the same
way: the truth for synchronising and then tracking from every ping.

Reuses the detection simulation of :mod:`hmmtrack.scenarios.detection` (acoustic paths,
detection probability, receiver clocks).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from hmmtrack.scenarios.detection import detections_from_pings, simulate_pings
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.detection import LogisticDetection

DAY = 86400.0
PPM = 1e-6


@dataclass(frozen=True)
class DriftingClock:
    """A receiver clock: ``recorded = true + offset + 1e-6 (drift_ppm u + rate u**2 / 2 day)``.

    ``u = true - reference_time`` (s); ``rate`` is ``drift_rate_ppm_per_day``, the change of
    the drift per day.
    """

    offset: float
    drift_ppm: float
    drift_rate_ppm_per_day: float
    reference_time: float

    def __call__(self, true_time) -> np.ndarray:
        """Recorded times (s) of events at ``true_time`` (s), any shape."""
        true_time = np.asarray(true_time, dtype=float)
        u = true_time - self.reference_time
        return (
            true_time
            + self.offset
            + PPM * (self.drift_ppm * u + 0.5 * self.drift_rate_ppm_per_day * u**2 / DAY)
        )

    def to_true(self, recorded_time) -> np.ndarray:
        """True times (s) of events recorded at ``recorded_time`` (s); fixed-point inverse."""
        recorded_time = np.asarray(recorded_time, dtype=float)
        true_time = recorded_time - self.offset
        for _ in range(4):  # each pass shrinks the error by the drift, ~1e-5
            true_time = true_time - (self(true_time) - recorded_time)
        return true_time


@dataclass(frozen=True)
class Listening:
    """How the array's receivers hear a transmitter: paths, detection curves, clocks, errors.

    Attributes
    ----------
    paths : dict of str to Trajectory
        True receiver positions.
    curves : dict of str to LogisticDetection
        Detection probability by range of each receiver.
    clocks : dict of str to DriftingClock
        Each receiver's clock, in which it logs.
    sound_speed : float
        m/s.
    timing_sd, multipath_fraction, multipath_delay, echo_fraction, echo_delay
        See :func:`moored_sync_array`.
    """

    paths: dict[str, Trajectory]
    curves: dict[str, LogisticDetection]
    clocks: dict[str, DriftingClock]
    sound_speed: float
    timing_sd: float
    multipath_fraction: float
    multipath_delay: float
    echo_fraction: float
    echo_delay: tuple[float, float]

    def hear(
        self, rng: np.random.Generator, source: Trajectory, emission: np.ndarray, transmitter: str
    ) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Every receiver's hearing of the pings emitted at ``emission`` (true s) from ``source``.

        Draws, in order: detections (:func:`~hmmtrack.scenarios.detection.simulate_pings`),
        multipath, jitter, then echoes (only when ``echo_fraction > 0``).

        Returns
        -------
        pings : DataFrame
            As :attr:`SyncArray.pings`, for this transmitter.
        detections : DataFrame
            ``time`` (each receiver's clock, s), ``receiver``, ``transmitter``: the detected
            pings and their echoes, sorted by time.
        """
        pings = simulate_pings(
            rng,
            source,
            self.paths,
            emission,
            self.curves,
            sound_speed=self.sound_speed,
            receiver_clocks=self.clocks,
        )
        n = len(pings)
        late = rng.random(n) < self.multipath_fraction
        delay = np.where(late, rng.exponential(self.multipath_delay, n), 0.0)
        jitter = rng.normal(0.0, self.timing_sd, n)
        pings["logged_time"] = pings["logged_time"] + jitter + delay
        pings["transmitter"] = transmitter
        pings["multipath"] = delay
        pings["echo"] = np.nan
        if self.echo_fraction > 0:
            echoed = pings["detected"].to_numpy() & (rng.random(n) < self.echo_fraction)
            pings.loc[echoed, "echo"] = rng.uniform(*self.echo_delay, int(echoed.sum()))
        detections = detections_from_pings(pings, transmitter)
        echoes = pings[pings["echo"].notna()]
        if len(echoes):
            late_copies = pd.DataFrame(
                {
                    "time": (echoes["logged_time"] + echoes["echo"]).to_numpy(),
                    "receiver": echoes["receiver"].to_numpy(),
                    "transmitter": transmitter,
                }
            )
            detections = pd.concat([detections, late_copies], ignore_index=True)
            detections = detections.sort_values(["time", "receiver"], kind="stable")
        return pings, detections.reset_index(drop=True)


@dataclass(frozen=True)
class SyncArray:
    """A simulated moored array (see the module docstring).

    Attributes
    ----------
    detections : DataFrame
        ``time`` (each receiver's clock, s), ``receiver``, ``transmitter``.
    receivers : DataFrame
        The receivers file: ``receiver``, ``time`` (NaN), ``x``, ``y``, ``z`` (m, surveyed),
        ``sync_tag``, ``fixed``.
    receivers_truth : DataFrame
        True positions: ``receiver``, ``x``, ``y``, ``z``.
    clocks : dict of str to DriftingClock
        Every receiver's clock.
    sound_speed : float
        m/s.
    pings : DataFrame
        Every sync emission at every receiver (:data:`hmmtrack.scenarios.detection.PING_COLUMNS`
        plus ``transmitter``, ``multipath``, the late path's delay in s, 0 for direct, and
        ``echo``, the delay of the echo logged after it, NaN for none).
    start, end : float
        Deployment (true UTC s).
    listening : Listening
        How the receivers hear any transmitter in the array (for tags added to it).
    """

    detections: pd.DataFrame
    receivers: pd.DataFrame
    receivers_truth: pd.DataFrame
    clocks: dict[str, DriftingClock]
    sound_speed: float
    pings: pd.DataFrame
    start: float
    end: float
    listening: Listening


def moored_sync_array(
    seed: int,
    *,
    rows: int = 4,
    columns: int = 4,
    spacing: float = 100.0,
    sync_every: int = 1,
    duration: float = DAY,
    sync_interval: tuple[float, float] = (400.0, 700.0),
    max_offset: float = 100.0,
    max_drift_ppm: float = 20.0,
    max_drift_rate: float = 2.0,
    position_error: float = 2.0,
    timing_sd: float = 2e-4,
    multipath_fraction: float = 0.02,
    multipath_delay: float = 0.02,
    echo_fraction: float = 0.0,
    echo_delay: tuple[float, float] = (0.3, 1.5),
    sound_speed: float = 1500.0,
    detection: LogisticDetection | None = None,
    start: float = 1.6e9,
) -> SyncArray:
    """Simulate a moored array with unsynchronised clocks and sync tags.

    Parameters
    ----------
    seed : int
        Random seed.
    rows, columns, spacing : int, int, float
        The grid of receivers (spacing in m); depths 1-3 m.
    sync_every : int
        A sync tag at every ``sync_every``-th receiver (1: every receiver).
    duration : float
        Deployment (s).
    sync_interval : (float, float)
        Sync tags' random interval between pings, uniform (s).
    max_offset, max_drift_ppm, max_drift_rate : float
        Clock errors drawn uniform in ``±`` these: offset (s), drift (ppm), drift change
        (ppm per day).
    position_error : float
        Sd (m) of the surveyed x, y of receivers not marked fixed (every other one is).
    timing_sd : float
        Sd (s) of the detection-time jitter.
    multipath_fraction, multipath_delay : float
        Share of detections logged from a late path instead, late by an exponential delay
        of this mean (s).
    echo_fraction, echo_delay : float, (float, float)
        Share of detections followed by an echo, a second detection of the same ping at
        the same receiver late by a uniform delay in ``echo_delay`` (s): a reflection
        decoded after the receiver's blanking interval.
    sound_speed : float
        m/s.
    detection : LogisticDetection, optional
        Detection probability by range; default 50 % at 350 m.
    start : float
        Deployment start (UTC s).

    Returns
    -------
    SyncArray
    """
    rng = np.random.default_rng(seed)
    detection = detection or LogisticDetection(range_50=350.0, width=40.0)
    gx, gy = np.meshgrid(np.arange(columns) * spacing, np.arange(rows) * spacing)
    n = rows * columns
    names = [f"rx-{i + 1:02d}" for i in range(n)]
    truth = pd.DataFrame(
        {
            "receiver": names,
            "x": gx.ravel() + rng.normal(0, 5.0, n),
            "y": gy.ravel() + rng.normal(0, 5.0, n),
            "z": rng.uniform(1.0, 3.0, n),
        }
    )
    fixed = np.arange(n) % 2 == 0
    surveyed = truth.copy()
    moved = ~fixed
    surveyed.loc[moved, "x"] += rng.normal(0, position_error, moved.sum())
    surveyed.loc[moved, "y"] += rng.normal(0, position_error, moved.sum())
    tags = {name: f"A69-1602-{60000 + i}" for i, name in enumerate(names) if i % sync_every == 0}
    surveyed.insert(1, "time", np.nan)
    surveyed["sync_tag"] = [tags.get(name) for name in names]
    surveyed["fixed"] = fixed
    clocks = {
        name: DriftingClock(
            offset=rng.uniform(-max_offset, max_offset),
            drift_ppm=rng.uniform(-max_drift_ppm, max_drift_ppm),
            drift_rate_ppm_per_day=rng.uniform(-max_drift_rate, max_drift_rate),
            reference_time=start,
        )
        for name in names
    }
    paths = {
        row.receiver: Trajectory(
            np.array([start]), np.array([row.x]), np.array([row.y]), np.array([row.z])
        )
        for row in truth.itertuples()
    }
    listening = Listening(
        paths=paths,
        curves=dict.fromkeys(names, detection),
        clocks=clocks,
        sound_speed=sound_speed,
        timing_sd=timing_sd,
        multipath_fraction=multipath_fraction,
        multipath_delay=multipath_delay,
        echo_fraction=echo_fraction,
        echo_delay=echo_delay,
    )
    frames, detections = [], []
    for home, transmitter in tags.items():
        gaps = rng.uniform(*sync_interval, int(duration / sync_interval[0]) + 2)
        emission = start + rng.uniform(0, sync_interval[0]) + np.cumsum(gaps)
        emission = emission[emission < start + duration]
        pings, heard = listening.hear(rng, paths[home], emission, transmitter)
        frames.append(pings)
        detections.append(heard)
    table = pd.concat(detections, ignore_index=True)
    table = table.sort_values(["time", "receiver"], kind="stable").reset_index(drop=True)
    return SyncArray(
        detections=table,
        receivers=surveyed,
        receivers_truth=truth,
        clocks=clocks,
        sound_speed=sound_speed,
        pings=pd.concat(frames, ignore_index=True),
        start=start,
        end=start + duration,
        listening=listening,
    )


@dataclass(frozen=True)
class TaggedArray:
    """A moored sync array with a moving tag on a pseudo-random burst interval.

    Attributes
    ----------
    array : SyncArray
        The array, its clocks and its sync tags (its ``detections`` are the sync tags' only).
    detections : DataFrame
        Everything the receivers logged, sync tags and the tag: ``time`` (each receiver's
        clock, s), ``receiver``, ``transmitter``.
    transmitter : str
        The tag's id.
    truth : DataFrame
        The tag's true path every second: ``time`` (true UTC s), ``x``, ``y`` (m).
    emission_times : numpy.ndarray, shape (n_pings,)
        True emission times (s).
    sequence : numpy.ndarray, shape (L,)
        The tag's interval sequence (s), used in a cycle: the interval after ping ``k`` is
        ``sequence[(first_index + k) % L]``.
    first_index : int
        Index in ``sequence`` of the interval after the first ping.
    burst_interval : (float, float)
        Smallest and largest interval (s) the sequence was drawn from.
    pings : DataFrame
        Every tag emission at every receiver (as :attr:`SyncArray.pings`).
    """

    array: SyncArray
    detections: pd.DataFrame
    transmitter: str
    truth: pd.DataFrame
    emission_times: np.ndarray
    sequence: np.ndarray
    first_index: int
    burst_interval: tuple[float, float]
    pings: pd.DataFrame


def tagged_array(
    seed: int,
    *,
    burst_interval: tuple[float, float] = (20.0, 40.0),
    sequence_length: int = 256,
    tag_duration: float = 7200.0,
    tag_speed: float = 0.5,
    transmitter: str = "A69-1602-1000",
    tag_detection: LogisticDetection | None = None,
    **array_options,
) -> TaggedArray:
    """A tag moving inside a simulated moored array, heard as the sync tags are.

    The array is ``moored_sync_array(seed, **array_options)`` (the same for the same seed
    and options); the tag is drawn from a second stream of the seed. It travels at
    ``tag_speed`` between waypoints drawn uniformly inside the receiver grid (a tag towed
    or a fish cruising about the array) for ``tag_duration`` seconds from the middle of the
    deployment minus half that duration. Its burst intervals follow a pseudo-random
    sequence drawn uniformly in ``burst_interval`` and used in a cycle, entered at a random
    index, as a tag with a known interval sequence (YAPS's "pbi"); tracked without the
    sequence the same pings are a random-interval tag, whose intervals look independent
    and uniform in ``burst_interval`` whenever the track is shorter than a cycle. Equal
    bounds give a fixed-period tag. Heard by every receiver with the array's detection
    curve, timing jitter, multipath and echoes (:meth:`Listening.hear`).

    Parameters
    ----------
    seed : int
    burst_interval : (float, float)
        Smallest and largest interval between pings (s).
    sequence_length : int
        Intervals in the sequence.
    tag_duration : float
        How long the tag is tracked (s), within the deployment.
    tag_speed : float
        m/s.
    transmitter : str
    tag_detection : LogisticDetection, optional
        Detection probability of the tag by range, when it is heard less far than the sync
        tags (a smaller, quieter tag); default the array's.
    **array_options
        Of :func:`moored_sync_array`.

    Returns
    -------
    TaggedArray
    """
    low, high = burst_interval
    if not 0 < low <= high:
        raise ValueError(f"burst_interval must be 0 < MIN <= MAX (s), got {burst_interval}")
    array = moored_sync_array(seed, **array_options)
    if not 0 < tag_duration <= array.end - array.start:
        raise ValueError(f"tag_duration must be in (0, {array.end - array.start}] s")
    rng = np.random.default_rng([seed, 1])
    start = 0.5 * (array.start + array.end - tag_duration)
    path = _waypoint_path(rng, array.receivers_truth, tag_speed, start, start + tag_duration)
    sequence = rng.uniform(low, high, sequence_length)
    first = int(rng.integers(sequence_length))
    n = int(tag_duration / low) + 2
    gaps = sequence[(first + np.arange(n)) % sequence_length]
    emission = start + rng.uniform(0.0, high) + np.concatenate([[0.0], np.cumsum(gaps)])
    emission = emission[emission < start + tag_duration]
    listening = array.listening
    if tag_detection is not None:
        listening = replace(listening, curves=dict.fromkeys(listening.curves, tag_detection))
    pings, heard = listening.hear(rng, path, emission, transmitter)
    detections = pd.concat([array.detections, heard], ignore_index=True)
    detections = detections.sort_values(["time", "receiver"], kind="stable")
    seconds = start + np.arange(int(tag_duration) + 1, dtype=float)
    x, y, _ = path.position(seconds)
    return TaggedArray(
        array=array,
        detections=detections.reset_index(drop=True),
        transmitter=transmitter,
        truth=pd.DataFrame({"time": seconds, "x": x, "y": y}),
        emission_times=emission,
        sequence=sequence,
        first_index=first,
        burst_interval=(float(low), float(high)),
        pings=pings,
    )


def _waypoint_path(
    rng: np.random.Generator, receivers: pd.DataFrame, speed: float, start: float, end: float
) -> Trajectory:
    """Straight legs at ``speed`` (m/s) between waypoints uniform in the receivers' box,
    inset by a tenth of its size, from ``start`` to at least ``end`` (s)."""
    low = receivers[["x", "y"]].min().to_numpy(dtype=float)
    high = receivers[["x", "y"]].max().to_numpy(dtype=float)
    inset = 0.1 * (high - low)
    points, times = [rng.uniform(low + inset, high - inset)], [start]
    while times[-1] < end:
        points.append(rng.uniform(low + inset, high - inset))
        times.append(times[-1] + max(np.hypot(*(points[-1] - points[-2])), 1.0) / speed)
    xy = np.array(points)
    return Trajectory(np.array(times), xy[:, 0], xy[:, 1])
