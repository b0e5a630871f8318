"""Clock-aware tracking: the particle filter with the transmitter's emission clock in its state.

:class:`ClockAwareFilter` is :class:`hmmtrack.filter.ParticleFilter` with four additions,
each through the parent's own steps (predict, correct, resample):

* every particle carries the emission clock as a Kalman filter conditioned on its path
  (a Rao-Blackwellised clock): extra particle fields ``emission_time`` (mean time of
  the particle's reference emission, s) and ``period`` (mean period, s), with one
  ``(2, 2)`` covariance shared by all particles (:class:`hmmtrack.clock.EmissionClockModel`).
  A detection is scored on its marginal likelihood - the clock integrated out - so
  particles are not lost for lack of the exact clock, and each detection then updates
  every particle's clock;
* no known initial range: the clock phase is unknown (uniform over one period) until the
  first detection, whose arrival time then fixes each particle's emission time given its
  position - the exact posterior of a uniform phase, so the first detection carries no
  weight and geometry plus motion resolve the rest;
* tempered corrections: a detection scored on its arrival time is sharp (a few metres)
  against a particle cloud that may span kilometres, so when it would leave fewer than
  ``tempering_ess · N`` effective particles the likelihood is applied in powers
  ``β₁ + β₂ + … = 1``, each followed by resampling and a small Gaussian move of position
  shaped by the particles' covariance (progressive correction with regularisation);
* what the filter cannot see, it reports: per correction, whether the particle cloud is
  split into two separated clusters (:func:`ambiguity`, the paper's two-intersection
  case), and when detections keep fitting no particle's clock (a clock jump, not
  multipath) the clock is re-acquired from the latest one and the event recorded.

Optionally it also records every step for the fixed-lag smoother
(:mod:`hmmtrack.smoothing`) and counts silences against particles near a receiver
(:mod:`hmmtrack.detection_probability`).

:func:`arrival_observations` builds the filter's input from detections and receiver
positions, and :func:`track_arrival_time` runs the whole thing (the entry point for
``hmmtrack track --measurement arrival-time``).

This module does not read files and does not score detections itself
(:mod:`hmmtrack.arrival`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.arrival import (
    ArrivalTimeMeasurement,
    check_arrival_observations,
    emission_range,
    mixture_constants,
    mixture_log_density,
    wrap_to_ping,
)
from hmmtrack.clock import EmissionClockModel
from hmmtrack.detection_probability import LogisticDetection, silence_loglik_recent_pings
from hmmtrack.filter import FilterResult, ParticleFilter
from hmmtrack.receivers import ReceiverTracks
from hmmtrack.smoothing import FixedLagSmoother, smoothed_table

#: columns of :attr:`ClockFilterResult.ambiguity`
AMBIGUITY_COLUMNS = ("time", "separation", "minor_weight", "ambiguous")
#: columns of :attr:`ClockFilterResult.clock`
CLOCK_COLUMNS = ("time", "emission_time", "period", "emission_time_sd", "period_sd")


@njit(cache=True)
def _clock_row_kernel(
    residual, ping, distance, weights, emission_time, period, loglik, sigma,
    late_fraction, late_mean, uniform_fraction, gain_emission, gain_period, range_50, width,
):  # fmt: skip
    """Score one detection against every particle's clock and update the clocks in place.

    Adds to ``loglik`` the marginal log density of each residual (innovation standard
    deviation ``sigma``) and, when ``range_50`` is not NaN, the logistic
    ``log p(distance)`` of being heard; moves ``emission_time`` to the matched ping and
    applies the Kalman gains scaled by the probability that the arrival is direct.

    Returns
    -------
    accepted : float
        Weighted mean probability that the arrival is direct (scales the covariance update).
    closest : float
        Smallest absolute residual (s).
    """
    accepted = 0.0
    closest = math.inf
    constants = mixture_constants(sigma, late_fraction, late_mean, uniform_fraction)
    for i in range(residual.size):
        eps = residual[i]
        total, _, direct = mixture_log_density(eps, math.log(period[i]), constants)
        loglik[i] += total
        if not math.isnan(range_50):
            x = (distance[i] - range_50) / width  # log expit(-x), stable both ways
            loglik[i] -= x + math.log1p(math.exp(-x)) if x > 0 else math.log1p(math.exp(x))
        emission_time[i] += ping[i] * period[i] + gain_emission * direct * eps
        period[i] += gain_period * direct * eps
        accepted += weights[i] * direct
        closest = min(closest, abs(eps))
    return accepted, closest


class _ClockView:
    """Particles seen with other clock means (for scoring without committing an update)."""

    def __init__(self, particles, emission_time: np.ndarray, period: np.ndarray) -> None:
        self._particles = particles
        self.emission_time = emission_time
        self.period = period

    def __getattr__(self, name: str):
        return getattr(self._particles, name)


def ambiguity(x, y, weights, min_separation: float = 20.0) -> tuple[float, float, bool]:
    """Is a particle cloud two separated clusters? (the paper's two-intersection case)

    The cloud is projected on its principal axis and split in two by weighted 1-D 2-means;
    it is called ambiguous when the smaller cluster holds at least 5 % of the weight and
    the clusters' centres lie more than ``min_separation`` apart and more than three
    times the sum of their standard deviations along the axis.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    weights : numpy.ndarray, shape (N,)
        Normalised weights.
    min_separation : float
        m.

    Returns
    -------
    separation : float
        Distance between the two cluster centres along the axis (m).
    minor_weight : float
        Weight of the smaller cluster.
    ambiguous : bool
    """
    w = np.asarray(weights, dtype=float)
    mx, my = w @ x, w @ y
    dx, dy = x - mx, y - my
    cov = np.array([[w @ (dx * dx), w @ (dx * dy)], [w @ (dx * dy), w @ (dy * dy)]])
    values, vectors = np.linalg.eigh(cov)
    if values[1] < 0.05 * 0.95 * min_separation**2:
        # two clusters this far apart, the smaller with 5 % of the weight, would spread
        # the cloud at least this much along the axis joining them
        return 0.0, 0.0, False
    u = dx * vectors[0, 1] + dy * vectors[1, 1]
    order = np.argsort(u)
    u, w = u[order], w[order]
    # prefix sums make each 2-means iteration a binary search (the split is a threshold)
    cw = np.concatenate([[0.0], np.cumsum(w)])
    cwu = np.concatenate([[0.0], np.cumsum(w * u)])
    cwu2 = np.concatenate([[0.0], np.cumsum(w * u * u)])
    total, total_u, total_u2 = cw[-1], cwu[-1], cwu2[-1]
    lo = u[min(np.searchsorted(cw[1:], 0.25 * total), u.size - 1)]
    hi = u[min(np.searchsorted(cw[1:], 0.75 * total), u.size - 1)]
    k = -1
    for _ in range(50):
        k_new = int(np.searchsorted(u, 0.5 * (lo + hi), side="right"))
        if k_new == k:
            break
        k = k_new
        w_lo, w_hi = cw[k], total - cw[k]
        if w_lo <= 0 or w_hi <= 0:
            return 0.0, 0.0, False
        lo, hi = cwu[k] / w_lo, (total_u - cwu[k]) / w_hi
    sd_lo = np.sqrt(max(cwu2[k] / w_lo - lo * lo, 0.0))
    sd_hi = np.sqrt(max((total_u2 - cwu2[k]) / w_hi - hi * hi, 0.0))
    separation = float(hi - lo)
    minor = float(min(w_lo, w_hi) / total)
    split = minor >= 0.05 and separation > max(min_separation, 3.0 * (sd_lo + sd_hi))
    return separation, minor, bool(split)


@dataclass
class ClockFilterResult(FilterResult):
    """:class:`hmmtrack.filter.FilterResult` plus what the clock-aware filter adds.

    Attributes
    ----------
    smoothed : pandas.DataFrame or None
        Fixed-lag smoothed estimates (:data:`hmmtrack.smoothing.SMOOTHED_COLUMNS`), when a
        lag was given.
    ambiguity : pandas.DataFrame
        One row per correction (:data:`AMBIGUITY_COLUMNS`).
    clock : pandas.DataFrame
        The estimated emission clock after each correction (:data:`CLOCK_COLUMNS`).
    """

    smoothed: pd.DataFrame | None = None
    ambiguity: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=AMBIGUITY_COLUMNS))
    clock: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=CLOCK_COLUMNS))


@dataclass(frozen=True)
class SilenceModel:
    """What an unheard ping tells: receivers, their detection curve and their detections.

    Parameters
    ----------
    receivers : ReceiverTracks
        Where the listening receivers are; a moving receiver listens within its GPS span.
    detection : LogisticDetection
        Detection probability against range (all receivers).
    heard : dict of str to numpy.ndarray
        Sorted detection times per receiver on the common time base (s).
    tolerance : float
        A detection this close (s) to a particle's expected arrival is that ping heard.
    """

    receivers: ReceiverTracks
    detection: LogisticDetection
    heard: dict[str, np.ndarray]
    tolerance: float = 1.0

    def __post_init__(self) -> None:
        self.detection.require_unit_maximum("SilenceModel")

    @classmethod
    def from_observations(
        cls, observations: pd.DataFrame, receivers: ReceiverTracks, detection, tolerance=1.0
    ) -> SilenceModel:
        """Build from the arrival-time observations table the filter runs on."""
        heard = {
            name: np.sort(
                observations.loc[observations["receiver"] == name, "time"].to_numpy(dtype=float)
            )
            for name in receivers.names
        }
        return cls(receivers, detection, heard, tolerance)


class ClockAwareFilter(ParticleFilter):
    """Particle filter whose particles carry the transmitter clock (see the module docstring).

    Parameters
    ----------
    motion
        Motion model (:mod:`hmmtrack.motion`).
    measurement : ArrivalTimeMeasurement
    clock : EmissionClockModel
    n_particles : int
    bounds : (xmin, xmax, ymin, ymax)
        Search box (m); no initial range is needed.
    smoothing_lag : int, optional
        Record every step for a fixed-lag smoother of this many steps (prediction then
        runs one step per call, which is slower).
    silence : SilenceModel, optional
        Detection probability as information: every detection adds ``log p(range)`` and
        every unheard ping ``log(1 − p(range))`` to a particle's log weight.
    tempering_ess : float
        Fraction of ``N`` below which a correction is tempered, in (0, 1).
    lock_sigmas : float
        A detection fits no particle when its residual exceeds this many predicted
        standard deviations for every particle.
    lost_corrections : int
        After this many corrections in a row with a detection that fits no particle (more
        than multipath can explain), the clock is re-acquired from the latest one.
    **kwargs
        Passed to :class:`hmmtrack.filter.ParticleFilter` (``resampling``, ``rng``, ...).
    """

    def __init__(
        self,
        motion,
        measurement: ArrivalTimeMeasurement,
        clock: EmissionClockModel,
        n_particles: int,
        bounds,
        *,
        smoothing_lag: int | None = None,
        silence: SilenceModel | None = None,
        tempering_ess: float = 0.3,
        lock_sigmas: float = 10.0,
        lost_corrections: int = 3,
        **kwargs,
    ) -> None:
        kwargs.setdefault("resampling", "systematic")
        super().__init__(motion, measurement, n_particles, bounds, **kwargs)
        if not 0.0 < tempering_ess < 1.0:
            raise ValueError(f"tempering_ess must be in (0, 1), got {tempering_ess}")
        self.clock = clock
        self.smoothing_lag = smoothing_lag
        self.silence = silence
        self.tempering_ess = float(tempering_ess)
        self.lock_sigmas = float(lock_sigmas)
        self.lost_corrections = int(lost_corrections)
        # Silverman-style bandwidth for the regularisation move in (x, y)
        self._bandwidth = (4.0 / (self.n_particles * 4.0)) ** (1.0 / 6.0)

    # ------------------------------------------------------------------ state

    def initialise(self, time: float):
        """Uniform particles in the bounds, at rest, clock unknown (NaN) until a detection."""
        estimate = super().initialise(time)
        n = self.particles.n
        self.particles.extra.update(emission_time=np.full(n, np.nan), period=np.full(n, np.nan))
        self._clock_started = False
        self._lost_count = 0
        self._clock_covariance = np.full((2, 2), np.nan)
        self._silence_from = -np.inf
        self._parent: np.ndarray | None = None
        self._smoother = (
            None if self.smoothing_lag is None else FixedLagSmoother(self.smoothing_lag)
        )
        self._smoothed_rows: list[tuple] = []
        self._pending = self._smoother is not None
        self._ambiguity_rows: list[tuple] = []
        self._clock_rows: list[tuple] = []
        return estimate

    def _push_pending(self) -> None:
        if self._pending:
            p = self.particles
            row = self._smoother.push(self.time, p.x, p.y, p.log_weight, self._parent)
            self._parent = None
            if row is not None:
                self._smoothed_rows.append(row)
            self._pending = False

    # ------------------------------------------------------------------ predict

    def predict(self, n_steps: int):
        """Move the particles ``n_steps`` steps (the clocks move lazily, ping by ping)."""
        if self._smoother is None or n_steps <= 0:
            return super().predict(n_steps)
        estimates = []
        for _ in range(n_steps):
            self._push_pending()
            estimates += super().predict(1)
            self._pending = True
        return estimates

    # ------------------------------------------------------------------ correct

    def _start_clock(self, obs: pd.DataFrame, reacquire: bool = False) -> None:
        """Set every particle's emission time from the first detection of ``obs``.

        Given a particle's position, a uniform prior on the phase and one arrival time
        leave only the measurement noise on its emission time. A re-acquisition keeps the
        particles' periods.
        """
        p = self.particles
        arrival, receiver_x, receiver_y, vertical = self.measurement.rows(p, obs, check=False)[0]
        r = emission_range(
            p.x,
            p.y,
            p.speed * p.cos_heading,
            p.speed * p.sin_heading,
            self.time - arrival,
            receiver_x,
            receiver_y,
            vertical,
            self.measurement.sound_speed,
        )
        p.extra["emission_time"] = arrival - r / self.measurement.sound_speed
        covariance = self.clock.initial_covariance(self.measurement.likelihood.sigma)
        if reacquire:
            covariance[1, 1] = max(covariance[1, 1], float(np.var(p.period)))
        else:
            p.extra["period"] = np.full(p.n, self.clock.nominal_period)
            # silences count from the first ping on: earlier pings may predate the tag
            self._silence_from = float(np.min(p.emission_time))
        self._clock_covariance = covariance
        self._clock_started = True

    def _clock_update(self, obs: pd.DataFrame):
        """Marginal log-likelihood of ``obs`` per particle and the updated clocks.

        Rows are taken one after the other: each is scored against every particle's
        predicted clock (mean and shared covariance moved to the ping that fits), then the
        clock is updated with it (Kalman gain scaled by the posterior probability that the
        detection is a direct arrival), so simultaneous detections of one ping are scored
        jointly.

        Returns
        -------
        loglik : numpy.ndarray, shape (N,)
            With a silence model, it includes ``log p(range)`` of each detection (heard
            pings came from within detection range).
        emission_time, period : numpy.ndarray, shape (N,)
            Updated clock means.
        covariance : numpy.ndarray, shape (2, 2)
        lost : bool
            Whether some detection fitted no particle's clock within ``lock_sigmas``.
        """
        p = self.particles
        likelihood = self.measurement.likelihood
        emission_time = p.emission_time.copy()
        period = p.period.copy()
        covariance = self._clock_covariance
        loglik = np.zeros(p.n)
        weights = p.normalised_weights()
        lost = False
        detection = None if self.silence is None else self.silence.detection
        for row in self.measurement.rows(p, obs, check=False):
            view = _ClockView(p, emission_time, period)
            residual, ping, r = self.measurement.match_one(view, *row, time=self.time)
            n_ahead = int(max(np.median(ping), 0))
            predicted = self.clock.predict_covariance(covariance, n_ahead)
            innovation_var = predicted[0, 0] + likelihood.sigma**2
            sigma = float(np.sqrt(innovation_var))
            gain = predicted[:, 0] / innovation_var
            accepted, closest = _clock_row_kernel(
                residual,
                ping,
                r,
                weights,
                emission_time,
                period,
                loglik,
                sigma,
                likelihood.late_fraction,
                likelihood.late_mean,
                likelihood.uniform_fraction,
                float(gain[0]),
                float(gain[1]),
                np.nan if detection is None else detection.range_50,
                np.nan if detection is None else detection.width,
            )
            lost |= closest > self.lock_sigmas * sigma
            covariance = predicted - accepted * np.outer(gain, gain) * innovation_var
        return loglik, emission_time, period, covariance, lost

    def _loglik(self, obs: pd.DataFrame):
        loglik, emission_time, period, covariance, lost = self._clock_update(obs)
        if self.silence is not None:
            loglik = loglik + self._silence_loglik()
        if loglik.shape != (self.particles.n,) or not np.all(np.isfinite(loglik)):
            raise ValueError(
                f"arrival-time log-likelihood not finite at time {self.time} for "
                f"observations:\n{obs}"
            )
        return loglik, (emission_time, period, covariance), lost

    def _silence_loglik(self) -> np.ndarray:
        """Unheard pings whose expected arrival fell since the last correction."""
        s = self.silence
        p = self.particles
        cut = self.time + 0.5 * self.dt - s.tolerance  # detections up to time + dt/2 are in
        out = np.zeros(p.n)
        if cut <= self._silence_from:
            return out
        # pings of a particle whose arrival can fall in the window, with one to spare
        n_back = min(int(np.ceil((cut - self._silence_from) / self.clock.nominal_period)) + 1, 8)
        for name in s.receivers.names:
            first, last = s.receivers.span(name)
            if not first <= self.time <= last:
                continue
            rx, ry, _, _ = s.receivers.state(name, self.time)
            out += silence_loglik_recent_pings(
                p.emission_time,
                p.period,
                np.hypot(p.x - rx[0], p.y - ry[0]),
                n_back,
                s.heard[name],
                self._silence_from,
                cut,
                s.detection,
                s.tolerance,
                self.measurement.sound_speed,
            )
        self._silence_from = cut
        return out

    def correct(self, obs: pd.DataFrame):
        """Tempered arrival-time correction (see the module docstring); the weighted estimate."""
        if not self._clock_started:
            self._start_clock(obs)
        silence_from = self._silence_from
        loglik, update, lost = self._loglik(obs)
        self._lost_count = self._lost_count + 1 if lost else 0
        if self._lost_count >= self.lost_corrections:
            self._lost_count = 0
            self._start_clock(obs, reacquire=True)
            self._record("clock_reacquired", f"no particle fitted the {len(obs)} detection(s)")
            self._silence_from = silence_from
            loglik, update, _ = self._loglik(obs)
        remaining = 1.0
        while True:
            p = self.particles
            beta = self._tempering_step(p.log_weight, loglik, remaining)
            log_weight = p.log_weight + beta * loglik
            top = log_weight.max()
            p.log_weight = log_weight - (top + np.log(np.exp(log_weight - top).sum()))
            remaining -= beta
            if remaining <= 1e-12:
                break
            before = (p.emission_time, p.period)
            self._resample_now()
            self._regularise()
            p = self.particles
            p.extra["emission_time"] = before[0][self._ancestors]
            p.extra["period"] = before[1][self._ancestors]
            self._silence_from = silence_from
            loglik, update, _ = self._loglik(obs)
        p = self.particles
        p.extra["emission_time"], p.extra["period"] = update[0], update[1]
        self._clock_covariance = update[2]
        self._record_diagnostics()
        return self.estimate()

    def _tempering_step(self, log_weight, loglik, remaining: float) -> float:
        """Largest power ``β ≤ remaining`` of the likelihood that keeps the ESS target."""
        target = self.tempering_ess * log_weight.size

        def ess(beta: float) -> float:
            lw = log_weight + beta * loglik
            w = np.exp(lw - lw.max())
            return w.sum() ** 2 / (w @ w)

        if ess(remaining) >= target:
            return remaining
        lo, hi = 0.0, remaining
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if ess(mid) >= target else (lo, mid)
        return max(lo, 1e-3 * remaining)

    def _regularise(self) -> None:
        """Gaussian move of (x, y) with the particles' own covariance (after resampling)."""
        p = self.particles
        cov = np.cov(np.vstack([p.x, p.y])) + 1e-4 * np.eye(2)
        move = self._bandwidth * (np.linalg.cholesky(cov) @ self.rng.standard_normal((2, p.n)))
        p.x = p.x + move[0]
        p.y = p.y + move[1]

    def _clock_offsets(self, weights: np.ndarray) -> np.ndarray:
        """Particles' emission times relative to the heaviest particle's clock (s), (N,).

        Particles' reference emissions need not be the same ping, so two nearly equal
        clocks can differ by whole periods; offsets are wrapped to the nearest ping of the
        heaviest particle's clock.
        """
        p = self.particles
        best = int(np.argmax(weights))
        offset, _ = wrap_to_ping(p.emission_time, p.emission_time[best], p.period[best])
        return offset

    def _record_diagnostics(self) -> None:
        p = self.particles
        w = p.normalised_weights()
        self._ambiguity_rows.append((self.time, *ambiguity(p.x, p.y, w)))
        offset = self._clock_offsets(w)
        mean_offset = w @ offset
        mean_period = w @ p.period
        self._clock_rows.append(
            (
                self.time,
                p.emission_time[np.argmax(w)] + mean_offset,
                mean_period,
                float(np.sqrt(w @ (offset - mean_offset) ** 2 + self._clock_covariance[0, 0])),
                float(np.sqrt(w @ (p.period - mean_period) ** 2 + self._clock_covariance[1, 1])),
            )
        )

    # ------------------------------------------------------------------ resample

    def _resample_now(self) -> None:
        p = self.particles
        ancestors = self._resample(self.rng, p.normalised_weights(), p.n)
        self._ancestors = ancestors
        self.particles = p.take(ancestors)
        self.particles.log_weight = np.full(p.n, -np.log(p.n))
        self._parent = ancestors if self._parent is None else self._parent[ancestors]

    def resample_if_due(self) -> bool:
        """Resample per ``resample_when``, keeping the ancestry for the smoother."""
        self._push_pending()  # the smoother records the corrected, not yet resampled, step
        p = self.particles
        if self.resample_when == "ess":
            w = p.normalised_weights()
            if 1.0 / (w @ w) >= self.ess_threshold * p.n:
                return False
        self._resample_now()
        return True

    # ------------------------------------------------------------------ offline

    def run(self, observations, start=None, end=None, snapshot_times=()) -> ClockFilterResult:
        """:meth:`ParticleFilter.run` plus smoothed track, ambiguity and clock tables."""
        base = super().run(observations, start, end, snapshot_times)
        smoothed = None
        if self._smoother is not None:
            self._push_pending()
            smoothed = smoothed_table(self._smoothed_rows + self._smoother.finish())
        return ClockFilterResult(
            estimates=base.estimates,
            snapshots=base.snapshots,
            events=base.events,
            smoothed=smoothed,
            ambiguity=pd.DataFrame(self._ambiguity_rows, columns=list(AMBIGUITY_COLUMNS)),
            clock=pd.DataFrame(self._clock_rows, columns=list(CLOCK_COLUMNS)),
        )


def arrival_observations(detections: pd.DataFrame, receivers: ReceiverTracks) -> pd.DataFrame:
    """The arrival-time filter's input: detections with receiver positions at arrival.

    Parameters
    ----------
    detections : pandas.DataFrame
        ``time`` (common time base, s; see :func:`hmmtrack.clock.to_common_time`),
        ``receiver``; ``depth`` (m) is kept for depth-sensor tags.
    receivers : ReceiverTracks

    Returns
    -------
    pandas.DataFrame
        ``time``, ``receiver``, ``receiver_x``, ``receiver_y`` (m) and ``depth`` when
        given, sorted by time.
    """
    missing = [c for c in ("time", "receiver") if c not in detections.columns]
    if missing:
        raise ValueError(f"detections lack column(s) {missing}; expected time, receiver")
    unknown = sorted(set(detections["receiver"].astype(str)) - set(receivers.names))
    if unknown:
        rows = np.flatnonzero(detections["receiver"].astype(str).isin(unknown).to_numpy())
        raise ValueError(
            f"detections rows {rows[:10].tolist()} name receiver(s) {unknown} that have no "
            f"positions; receivers with positions: {list(receivers.names)}"
        )
    columns = ["time", "receiver"] + (["depth"] if "depth" in detections.columns else [])
    obs = detections[columns].copy()
    check_arrival_observations(obs.assign(receiver_x=0.0, receiver_y=0.0), "detections")
    obs["receiver"] = obs["receiver"].astype(str)
    obs["receiver_x"] = np.nan
    obs["receiver_y"] = np.nan
    for name in receivers.names:
        rows = (obs["receiver"] == name).to_numpy()
        if rows.any():
            x, y, _, _ = receivers.state(name, obs["time"].to_numpy(dtype=float)[rows])
            obs.loc[rows, "receiver_x"] = x
            obs.loc[rows, "receiver_y"] = y
    return obs.sort_values("time", kind="stable").reset_index(drop=True)


def track_arrival_time(
    detections: pd.DataFrame,
    receivers: pd.DataFrame,
    *,
    motion,
    period: float,
    bounds=None,
    search_radius: float = 1000.0,
    measurement: ArrivalTimeMeasurement | None = None,
    clock: EmissionClockModel | None = None,
    n_particles: int = 5000,
    smoothing_lag: int | None = None,
    detection: LogisticDetection | None = None,
    start: float | None = None,
    end: float | None = None,
    seed=None,
) -> ClockFilterResult:
    """Track a fixed-period tag from its arrival times, without a known initial range.

    Parameters
    ----------
    detections : pandas.DataFrame
        ``time`` on the common time base (s), ``receiver``; optional ``depth`` (m).
    receivers : pandas.DataFrame
        Receiver positions table (docs/interfaces.md).
    motion
        Motion model (:mod:`hmmtrack.motion`).
    period : float
        Nominal tag period (s).
    bounds : (xmin, xmax, ymin, ymax), optional
        Search box (m); default: the receivers' positions at ``start`` (or at the first
        detection) widened by ``search_radius`` (no initial range needed).
    search_radius : float
        See ``bounds`` (m): about the receivers' detection range.
    measurement : ArrivalTimeMeasurement, optional
        Default: :class:`ArrivalTimeMeasurement` with its default likelihood.
    clock : EmissionClockModel, optional
        Default: ``EmissionClockModel(period, period_step_sd=3e-4, phase_step_sd=1e-4,
        initial_period_sd=1e-3·period)`` (period random walk of ~40 ppm per ping).
    n_particles : int
    smoothing_lag : int, optional
        Steps (s) of the fixed-lag smoother; None: no smoothing.
    detection : LogisticDetection, optional
        Count unheard pings with this detection curve.
    start, end : float, optional
        Time window (s).
    seed : int, SeedSequence or Generator

    Returns
    -------
    ClockFilterResult
    """
    tracks = ReceiverTracks.from_frame(receivers, outside="clamp")
    obs = arrival_observations(detections, tracks)
    if bounds is None:
        at = float(obs["time"].min()) if start is None else float(start)
        xs, ys = zip(*(tracks.state(name, at)[:2] for name in tracks.names), strict=True)
        xs, ys = np.concatenate(xs), np.concatenate(ys)
        bounds = (
            xs.min() - search_radius,
            xs.max() + search_radius,
            ys.min() - search_radius,
            ys.max() + search_radius,
        )
    measurement = measurement or ArrivalTimeMeasurement()
    clock = clock or EmissionClockModel(period, 3e-4, 1e-4, 1e-3 * period)
    silence = None
    if detection is not None:
        silence = SilenceModel.from_observations(obs, tracks, detection)
    pf = ClockAwareFilter(
        motion,
        measurement,
        clock,
        n_particles,
        bounds,
        smoothing_lag=smoothing_lag,
        silence=silence,
        rng=seed,
    )
    return pf.run(obs, start, end)
