"""A moored receiver array with unsynchronised clocks and sync tags: truth for clock fits.

Receivers on a grid, each with its own clock (offset of up to minutes, drift of tens of
ppm, and a slowly changing drift); sync tags moored at some of them ping at random
intervals and are heard by their neighbours with a range-dependent probability, a small
timing jitter, and now and then by a late multipath path instead of the direct one. The
receivers file holds the surveyed positions: exact for receivers marked ``fixed``, off by
a few metres for the others. :func:`hmmtrack.sync.fit_clocks` should recover every clock,
the sound speed and the positions from the detections alone.

Reuses the detection simulation of :mod:`hmmtrack.scenarios.detection` (acoustic paths,
detection probability, receiver clocks).
"""

from __future__ import annotations

from dataclasses import dataclass

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
        plus ``transmitter`` and ``multipath``, the late path's delay in s, 0 for direct).
    start, end : float
        Deployment (true UTC s).
    """

    detections: pd.DataFrame
    receivers: pd.DataFrame
    receivers_truth: pd.DataFrame
    clocks: dict[str, DriftingClock]
    sound_speed: float
    pings: pd.DataFrame
    start: float
    end: float


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
    curves = dict.fromkeys(names, detection)
    frames, detections = [], []
    for home, transmitter in tags.items():
        gaps = rng.uniform(*sync_interval, int(duration / sync_interval[0]) + 2)
        emission = start + rng.uniform(0, sync_interval[0]) + np.cumsum(gaps)
        emission = emission[emission < start + duration]
        pings = simulate_pings(
            rng,
            paths[home],
            paths,
            emission,
            curves,
            sound_speed=sound_speed,
            receiver_clocks=clocks,
        )
        late = rng.random(len(pings)) < multipath_fraction
        delay = np.where(late, rng.exponential(multipath_delay, len(pings)), 0.0)
        jitter = rng.normal(0.0, timing_sd, len(pings))
        pings["logged_time"] = pings["logged_time"] + jitter + delay
        pings["transmitter"] = transmitter
        pings["multipath"] = delay
        frames.append(pings)
        detections.append(detections_from_pings(pings, transmitter))
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
    )
