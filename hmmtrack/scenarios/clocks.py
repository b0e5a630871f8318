"""Realistic clocks for synthetic data: drifting tag periods, unsynchronised receivers, multipath.

The paper's simulated tag pings with a constant period plus Gaussian jitter. Real
"fixed-period" tags do not (DESIGN.md, "What real data teaches"): the local period over
400-ping blocks wanders by −700…+360 ppm and the emission schedule drifts up to ~0.8 s
from any constant-period schedule in under two hours; receiver clocks differ by tens of
ppm; a few per cent of detections arrive late by multipath. This module adds those clocks
to the simulation pieces of :mod:`hmmtrack.scenarios` (paths, acoustic arrival times,
detection loss, GPS noise):

* :class:`WanderingPeriodClock`, :class:`Multipath`, :func:`random_receiver_clocks`,
  :func:`calibrate_clocks` — the clocks and the late arrivals;
* :func:`build_clock_scenario` — a :class:`ClockScenario` from given paths: a
  :class:`hmmtrack.scenarios.scenario.Scenario` whose detections are logged in the
  receivers' own clocks, plus the true clocks, the calibrated clock estimates a tracker is
  given, the true emission times and a search box that does not use the true initial ranges.

The ready-made cases are in :mod:`hmmtrack.scenarios.realistic`, the AUV steering plans in
:mod:`hmmtrack.scenarios.steering`. It does not track or score anything; the tracker's
settings for a case come from :func:`hmmtrack.experiments.configs.arrival_config`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from hmmtrack.scenarios.detection import GpsNoise, detections_from_pings
from hmmtrack.scenarios.scenario import Scenario, assemble_scenario
from hmmtrack.scenarios.trajectory import Trajectory
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
