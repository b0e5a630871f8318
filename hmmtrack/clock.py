"""Clocks of transmitters and receivers: the time bases behind every detection time.

A fixed-period acoustic tag is only nominally fixed: its period wanders by hundreds of
ppm, so its emission schedule drifts by up to a second from any constant-period schedule
over a couple of hours (see "What real data teaches" in DESIGN.md). Receivers log arrival
times in their own clocks, which differ from true time by an offset and a drift of tens
of ppm. This module holds the three small models the arrival-time filter needs:

* :class:`ReceiverClock` - the map between true time and a receiver's recorded time
  (offset + linear drift), used to put detections on the common time base;
* :class:`EmissionClockModel` - the particle-filter process model of the transmitter's clock:
  each particle carries ``emission_time`` (true time of its last emission, s) and
  ``period`` (s), the period a random walk from ping to ping (as YAPS treats "stable"
  burst intervals);
* :func:`local_period_ppm` and :func:`schedule_wander` - the two summaries by which a
  simulated or estimated emission schedule is compared with real tags.

It is not for scoring detections (:mod:`hmmtrack.arrival`) nor for simulating them
(:mod:`hmmtrack.clock_scenarios`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PPM = 1e-6


@dataclass(frozen=True)
class ReceiverClock:
    """Clock of one receiver: ``recorded = true + offset + drift_ppm·1e-6·(true − reference_time)``.

    Parameters
    ----------
    offset : float
        Recorded minus true time at ``reference_time`` (s).
    drift_ppm : float
        Rate error of the receiver clock (ppm, parts per million of elapsed time);
        positive means the receiver clock runs fast.
    reference_time : float
        True time at which ``offset`` holds (UTC s).
    """

    offset: float = 0.0
    drift_ppm: float = 0.0
    reference_time: float = 0.0

    def __post_init__(self) -> None:
        for name in ("offset", "drift_ppm", "reference_time"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"ReceiverClock.{name} must be finite, got {getattr(self, name)}")
        if abs(self.drift_ppm) >= 1e5:
            raise ValueError(f"ReceiverClock.drift_ppm={self.drift_ppm} is not a clock drift")

    def to_recorded(self, true_time) -> np.ndarray:
        """Recorded times (s) of events at ``true_time`` (s), any shape."""
        true_time = np.asarray(true_time, dtype=float)
        return true_time + self.offset + self.drift_ppm * PPM * (true_time - self.reference_time)

    def to_true(self, recorded_time) -> np.ndarray:
        """True times (s) of events recorded at ``recorded_time`` (s); exact inverse."""
        recorded_time = np.asarray(recorded_time, dtype=float)
        rate = 1.0 + self.drift_ppm * PPM
        return self.reference_time + (recorded_time - self.offset - self.reference_time) / rate


@dataclass(frozen=True)
class EmissionClockModel:
    """Process model of the transmitter's emission clock carried by each particle.

    A particle's clock is ``(emission_time, period)``: the true time of the last emission
    at or before the filter time and the current period. When the filter time passes
    ``emission_time + period`` the next ping is emitted: ``emission_time += period``, then
    the period takes a random-walk step ``N(0, period_step_sd²)`` and the emission time a
    phase step ``N(0, phase_step_sd²)`` (roughening that keeps clock diversity after
    resampling).

    Parameters
    ----------
    nominal_period : float
        The tag's nominal period (s); initial periods are drawn around it.
    period_step_sd : float
        Standard deviation of the period's change from one ping to the next (s).
    phase_step_sd : float
        Standard deviation of the extra emission-time step per ping (s).
    initial_period_sd : float
        Standard deviation of the initial period about ``nominal_period`` (s).
    """

    nominal_period: float
    period_step_sd: float = 20e-6
    phase_step_sd: float = 50e-6
    initial_period_sd: float = 2e-3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.nominal_period) and self.nominal_period > 0):
            raise ValueError(f"nominal_period must be positive (s), got {self.nominal_period}")
        for name in ("period_step_sd", "phase_step_sd", "initial_period_sd"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"EmissionClock.{name} must be >= 0 (s), got {value}")
        if self.initial_period_sd > 0.1 * self.nominal_period:
            raise ValueError(
                f"initial_period_sd={self.initial_period_sd} s is not small against the "
                f"nominal period {self.nominal_period} s; the ping wrapping needs it to be"
            )

    def initial_periods(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw ``n`` initial periods (s), shape (n,)."""
        return self.nominal_period + self.initial_period_sd * rng.standard_normal(n)

    def advance(
        self, rng: np.random.Generator, emission_time: np.ndarray, period: np.ndarray, t: float
    ) -> None:
        """Emit every ping due by time ``t`` (s): update ``emission_time`` and ``period`` in place.

        Parameters
        ----------
        rng : numpy.random.Generator
        emission_time, period : numpy.ndarray, shape (N,)
            Particles' last emission times and periods (s); modified in place.
        t : float
            Filter time to advance to (s).
        """
        due = np.flatnonzero(emission_time + period <= t)
        while due.size:
            emission_time[due] += period[due]
            if self.phase_step_sd > 0:
                emission_time[due] += self.phase_step_sd * rng.standard_normal(due.size)
            if self.period_step_sd > 0:
                period[due] += self.period_step_sd * rng.standard_normal(due.size)
            due = due[emission_time[due] + period[due] <= t]


def _as_schedule(emission_times) -> np.ndarray:
    emission_times = np.asarray(emission_times, dtype=float)
    if emission_times.ndim != 1 or emission_times.size < 3:
        raise ValueError(
            f"emission_times must be a 1-D array of at least 3 times, got shape "
            f"{emission_times.shape}"
        )
    if np.any(~np.isfinite(emission_times)) or np.any(np.diff(emission_times) <= 0):
        raise ValueError("emission_times must be finite and strictly increasing")
    return emission_times


def schedule_wander(emission_times) -> float:
    """Largest distance (s) of an emission schedule from its best constant-period schedule.

    The best constant-period schedule is the least-squares line ``t_k ≈ a + k·T`` through
    consecutive emissions; the wander is ``max_k |t_k − a − k·T|``.

    Parameters
    ----------
    emission_times : array_like, shape (n,)
        Times of consecutive emissions (no missing pings), s.
    """
    times = _as_schedule(emission_times)
    k = np.arange(times.size, dtype=float)
    slope, intercept = np.polyfit(k, times - times[0], 1)
    return float(np.max(np.abs(times - times[0] - intercept - slope * k)))


def local_period_ppm(emission_times, block: int = 400) -> np.ndarray:
    """Mean period of consecutive blocks of pings relative to the overall mean (ppm).

    Parameters
    ----------
    emission_times : array_like, shape (n,)
        Times of consecutive emissions (no missing pings), s.
    block : int
        Pings per block; a final partial block of fewer than ``block // 2`` pings is left
        out of the summary (its mean period is too noisy to compare).

    Returns
    -------
    numpy.ndarray, shape (n_blocks,)
        ``(mean period of block / overall mean period − 1)·1e6``.
    """
    times = _as_schedule(emission_times)
    if block < 2:
        raise ValueError(f"block must be at least 2 pings, got {block}")
    periods = np.diff(times)
    mean_period = periods.mean()
    starts = np.arange(0, periods.size, block)
    sizes = np.minimum(block, periods.size - starts)
    keep = sizes >= max(block // 2, 1)
    sums = np.add.reduceat(periods, starts)
    return (sums[keep] / sizes[keep] / mean_period - 1.0) / PPM
