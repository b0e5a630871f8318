"""Clocks of transmitters and receivers: the time bases behind every detection time.

A fixed-period acoustic tag is only nominally fixed: its period wanders by hundreds of
ppm, so its emission schedule drifts by up to a second from any constant-period schedule
over a couple of hours (see "What real data teaches" in DESIGN.md). Receivers log arrival
times in their own clocks, which differ from true time by an offset and a drift of tens
of ppm. This module holds the three small models the arrival-time filter needs:

* :class:`ReceiverClock` - the map between true time and a receiver's recorded time
  (offset + linear drift), and :func:`to_common_time`, which puts detections on the
  common time base;
* :class:`EmissionClockModel` - the linear-Gaussian model of the transmitter's clock that
  the filter carries per particle: a reference emission time, the period (s) and the
  period's rate of change, the period a random walk or an integrated random walk;
  (:func:`predict_clock_covariance` is its covariance prediction, compiled);
* :func:`local_period_ppm` and :func:`schedule_wander` - the two summaries by which a
  simulated or estimated emission schedule is compared with real tags.

It is not for scoring detections (:mod:`hmmtrack.tracking.measurement.arrival_time`) nor for
simulating them
(:mod:`hmmtrack.scenarios.clocks`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numba import njit

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


def to_common_time(detections: pd.DataFrame, clocks: Mapping[str, ReceiverClock]) -> pd.DataFrame:
    """Detections with ``time`` mapped from each receiver's clock to true time.

    Parameters
    ----------
    detections : pandas.DataFrame
        Columns ``time`` (as logged, s) and ``receiver``; other columns are kept.
    clocks : mapping of str to ReceiverClock
        Clocks of the receivers that are not synchronised; others are left as they are.

    Returns
    -------
    pandas.DataFrame
        A copy sorted by the corrected time (stable), with a fresh index.
    """
    out = detections.copy()
    times = out["time"].to_numpy(dtype=float).copy()
    receivers = out["receiver"].astype(str).to_numpy()
    for name, clock in clocks.items():
        rows = receivers == name
        times[rows] = clock.to_true(times[rows])
    out["time"] = times
    return out.sort_values(["time", "receiver"], kind="stable").reset_index(drop=True)


@dataclass(frozen=True)
class EmissionClockModel:
    """Linear-Gaussian model of the transmitter's emission clock, ping to ping.

    The clock is ``(e, P, R)``: the true time ``e`` of a reference emission, the period
    ``P`` (s) and the period's rate of change ``R`` (s per ping). From one ping to the
    next ``e ← e + P + N(0, phase_step_sd²)``, ``P ← P + R + N(0, period_step_sd²)`` and
    ``R ← R + N(0, rate_step_sd²)``. With ``rate_step_sd = initial_rate_sd = 0`` the rate
    stays 0 and the period is a plain random walk (as YAPS treats "stable" burst
    intervals); a positive ``rate_step_sd`` makes it an integrated random walk, a period
    that keeps drifting the same way for minutes, as a crystal follows the water's
    temperature. The phase step is timing noise that persists (the schedule moves);
    ping jitter that does not persist belongs in the arrival-time likelihood's ``sigma``.
    The clock-aware filter keeps, per particle, the mean of ``(e, P, R)`` and one
    covariance shared by all particles (a Rao-Blackwellised clock: a Kalman filter
    conditioned on the particle's path).

    Parameters
    ----------
    nominal_period : float
        The tag's nominal period (s): the prior mean of ``P``.
    period_step_sd : float
        Standard deviation of the period's own change from one ping to the next (s).
    phase_step_sd : float
        Standard deviation of the persistent emission-time step per ping (s).
    initial_period_sd : float
        Prior standard deviation of ``P`` about ``nominal_period`` (s).
    rate_step_sd : float
        Standard deviation of the change of ``R`` from one ping to the next (s per ping).
    initial_rate_sd : float
        Prior standard deviation of ``R`` about 0 (s per ping).
    """

    nominal_period: float
    period_step_sd: float = 3e-4
    phase_step_sd: float = 1e-4
    initial_period_sd: float = 8e-3
    rate_step_sd: float = 0.0
    initial_rate_sd: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.nominal_period) and self.nominal_period > 0):
            raise ValueError(f"nominal_period must be positive (s), got {self.nominal_period}")
        for name in (
            "period_step_sd",
            "phase_step_sd",
            "initial_period_sd",
            "rate_step_sd",
            "initial_rate_sd",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"EmissionClockModel.{name} must be >= 0 (s), got {value}")
        if self.initial_period_sd > 0.1 * self.nominal_period:
            raise ValueError(
                f"initial_period_sd={self.initial_period_sd} s is not small against the "
                f"nominal period {self.nominal_period} s; the ping wrapping needs it to be"
            )

    @classmethod
    def temperature_drift(
        cls, nominal_period: float, rate_ppm_per_s: float = 1.25, time_scale: float = 800.0
    ) -> EmissionClockModel:
        """An integrated random walk of the period sized from the real-tag facts.

        On the real towed-tag trial (DESIGN.md, "What real data teaches") the local period
        moved over ~1,000 ppm (−697…+364) between 400-ping blocks of ~800 s: a fractional
        period rate of about ``rate_ppm_per_s`` ppm per second that itself changes over
        ``time_scale`` seconds. As an integrated random walk in time this is a white
        change of the fractional rate with density ``q = (rate·1e-6)² / time_scale``
        (s⁻³); per ping of period ``P`` the period rate ``R = P²·(fractional rate)``
        (s per ping) then steps by ``sqrt(q·P)·P²``, and ``R`` starts within
        ``P²·rate·1e-6``. The period and phase keep small white steps
        (``rate·1e-6·P`` and 10 µs) for what the walk does not describe; the 44-83 µs
        jitter of each ping does not persist and belongs in the likelihood's ``sigma``.
        For ``P = 8 s``: rate step 8 µs per ping, initial rate 80 µs per ping.

        Parameters
        ----------
        nominal_period : float
            s.
        rate_ppm_per_s : float
            Typical fractional period rate (ppm per second).
        time_scale : float
            Time over which that rate changes (s).
        """
        rate = rate_ppm_per_s * PPM
        p = float(nominal_period)
        return cls(
            p,
            period_step_sd=rate * p,
            phase_step_sd=1e-5,
            initial_period_sd=1e-3 * p,
            rate_step_sd=float(np.sqrt(rate**2 / time_scale * p) * p**2),
            initial_rate_sd=rate * p**2,
        )

    def initial_covariance(self, emission_sd: float) -> np.ndarray:
        """Covariance (3, 3) of ``(e, P, R)`` after ``e`` is fixed to ``emission_sd`` seconds."""
        return np.diag([emission_sd**2, self.initial_period_sd**2, self.initial_rate_sd**2])

    def predict_covariance(self, covariance: np.ndarray, n_pings: int) -> np.ndarray:
        """Covariance (3, 3) of ``(e, P, R)`` moved ``n_pings`` pings ahead (0: unchanged).

        Parameters
        ----------
        covariance : numpy.ndarray, shape (3, 3)
            Covariance of the clock at the reference emission (s², s²/ping, ...).
        n_pings : int
            Pings between the reference emission and the new one, >= 0.
        """
        if n_pings < 0:
            raise ValueError(f"n_pings must be >= 0, got {n_pings}")
        transition = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
        noise = np.diag([self.phase_step_sd**2, self.period_step_sd**2, self.rate_step_sd**2])
        out = np.array(covariance, dtype=float)
        for _ in range(int(n_pings)):
            out = transition @ out @ transition.T + noise
        return out


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


@njit(cache=True)
def predict_clock_covariance(covariance, n_pings, noise):
    """Compiled :meth:`hmmtrack.tracking.measurement.clock.EmissionClockModel.predict_covariance`.

    Parameters
    ----------
    covariance : numpy.ndarray, shape (3, 3)
        Covariance of ``(e, P, R)`` at the reference emission.
    n_pings : int
        Pings ahead, >= 0.
    noise : numpy.ndarray, shape (3,)
        Per-ping variances of the phase, period and rate steps.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
    """
    out = covariance.copy()
    left = np.empty((3, 3))
    for _ in range(n_pings):
        for j in range(3):  # left = F·out, F = [[1, 1, 0], [0, 1, 1], [0, 0, 1]]
            left[0, j] = out[0, j] + out[1, j]
            left[1, j] = out[1, j] + out[2, j]
            left[2, j] = out[2, j]
        for i in range(3):  # out = left·Fᵀ + noise
            out[i, 0] = left[i, 0] + left[i, 1]
            out[i, 1] = left[i, 1] + left[i, 2]
            out[i, 2] = left[i, 2]
            out[i, i] += noise[i]
    return out
