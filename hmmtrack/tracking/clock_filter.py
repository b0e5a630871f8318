"""Clock-aware tracking: the particle filter with the transmitter's emission clock in its state.

:class:`ClockAwareFilter` is :class:`hmmtrack.tracking.filter.ParticleFilter` with four additions,
each through the parent's own steps (predict, correct, resample):

* every particle carries the emission clock as a Kalman filter conditioned on its path
  (a Rao-Blackwellised clock): extra particle fields ``emission_time`` (mean time of
  the particle's reference emission, s), ``period`` (mean period, s) and ``period_rate``
  (s per ping, 0 unless the clock model has a rate), with one ``(3, 3)`` covariance
  shared by all particles (:class:`hmmtrack.tracking.measurement.clock.EmissionClockModel`). A
  detection is
  scored on its marginal likelihood - the clock integrated out - so particles are not
  lost for lack of the exact clock, and each detection then updates every particle's
  clock (one compiled pass per detection over all particles);
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
(:mod:`hmmtrack.tracking.smoothing`) and counts silences against particles near a receiver
(:mod:`hmmtrack.tracking.measurement.detection`).

:func:`arrival_observations` builds the filter's input from detections and receiver
positions, and :func:`track_arrival_time` runs the whole thing (the entry point for
``hmmtrack track --measurement arrival-time``).

This module does not read files and does not score detections itself
(:mod:`hmmtrack.tracking.measurement.arrival_time`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.filter import FilterResult, ParticleFilter
from hmmtrack.tracking.measurement.arrival_time import (
    ArrivalTimeMeasurement,
    check_arrival_observations,
    emission_distance,
    emission_range,
    mixture_constants,
    mixture_log_densities,
    vertical_parts,
    wrap_arrival,
)
from hmmtrack.tracking.measurement.clock import EmissionClockModel
from hmmtrack.tracking.measurement.detection import (
    HeardTimes,
    LogisticDetection,
    silence_loglik_recent_pings,
    softplus,
)
from hmmtrack.tracking.receivers import ReceiverTracks
from hmmtrack.tracking.smoothing import FixedLagSmoother, smoothed_table

#: columns of :attr:`ClockFilterResult.ambiguity`
AMBIGUITY_COLUMNS = ("time", "separation", "minor_weight", "ambiguous")
_NO_ROWS = pd.DataFrame()

#: particle fields of the emission clock's mean (s, s, s per ping)
CLOCK_FIELDS = ("emission_time", "period", "period_rate")
#: columns of :attr:`ClockFilterResult.clock`
CLOCK_COLUMNS = ("time", "emission_time", "period", "emission_time_sd", "period_sd")


@njit(cache=True)
def _clock_row_kernel(
    residual, ping, distance, weights, emission_time, period, rate, loglik, sigma,
    late_fraction, late_mean, uniform_fraction, gain, range_50, width, total, direct,
):  # fmt: skip
    """Score one detection against every particle's clock and update the clocks in place.

    Adds to ``loglik`` the marginal log density of each residual (innovation standard
    deviation ``sigma``; :func:`hmmtrack.tracking.measurement.arrival_time.mixture_log_densities`,
    into the scratch
    arrays ``total`` and ``direct``, shape (N,)) and, when ``range_50`` is not NaN, the
    logistic ``log p(distance)`` of being heard; moves each clock
    ``(emission_time, period, rate)`` to the matched ping and applies the Kalman gain (3,)
    scaled by the probability that the arrival is direct.

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
    mixture_log_densities(residual, period, constants, total, direct)
    for i in range(residual.size):
        eps = residual[i]
        loglik[i] += total[i]
        if not math.isnan(range_50):  # log p = −softplus((distance − range_50) / width)
            loglik[i] -= softplus((distance[i] - range_50) / width)
        m = ping[i]
        shift = direct[i] * eps
        emission_time[i] += m * period[i] + 0.5 * m * (m - 1.0) * rate[i] + gain[0] * shift
        period[i] += m * rate[i] + gain[1] * shift
        rate[i] += gain[2] * shift
        accepted += weights[i] * direct[i]
        closest = min(closest, abs(eps))
    return accepted, closest


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


@njit(cache=True)
def _correction_kernel(
    x, y, speed, cos_heading, sin_heading, tag_depth, weights, emission_time, period, rate,
    arrival, receiver_x, receiver_y, row_offset, time, sound_speed, covariance, noise,
    measurement_sd, late_fraction, late_mean, uniform_fraction, range_50, width, lock_sigmas,
    loglik,
):  # fmt: skip
    """Score detections one after the other and update every particle's clock in place.

    For each row: match every particle's clock to the ping that fits
    (:func:`hmmtrack.tracking.measurement.arrival_time.match_particle`), move the shared covariance
    to the median
    matched ping, score and update (:func:`_clock_row_kernel`).

    Returns
    -------
    covariance : numpy.ndarray, shape (3, 3)
        Shared clock covariance after the last row.
    lost : bool
        Whether some row fitted no particle within ``lock_sigmas`` innovation sds.
    """
    n = x.size
    vx = speed * cos_heading
    vy = speed * sin_heading
    residual = np.empty(n)
    ping = np.empty(n)
    distance = np.empty(n)
    total = np.empty(n)  # scratch of _clock_row_kernel
    direct = np.empty(n)
    lost = False
    slowness = 1.0 / sound_speed
    for j in range(arrival.size):
        lag = time - arrival[j]
        # match_particle in two loops: the ranges' compiles to vector code
        for i in range(n):
            distance[i] = emission_distance(
                x[i], y[i], vx[i], vy[i], tag_depth[i] + row_offset[j], lag, receiver_x[j],
                receiver_y[j], slowness,
            )  # fmt: skip
        lo, hi, missing = math.inf, -math.inf, False  # range of the matched pings
        for i in range(n):
            residual[i], ping[i] = wrap_arrival(
                distance[i], emission_time[i], period[i], rate[i], arrival[j], slowness
            )
            lo = min(lo, ping[i])
            hi = max(hi, ping[i])
            missing |= math.isnan(ping[i])
        ahead = max(int(np.nan if missing else _median_in_range(ping, lo, hi)), 0)
        predicted = predict_clock_covariance(covariance, ahead, noise)
        innovation_var = predicted[0, 0] + measurement_sd * measurement_sd
        sigma = math.sqrt(innovation_var)
        gain = predicted[:, 0] / innovation_var
        accepted, closest = _clock_row_kernel(
            residual, ping, distance, weights, emission_time, period, rate, loglik, sigma,
            late_fraction, late_mean, uniform_fraction, gain, range_50, width, total, direct,
        )  # fmt: skip
        lost = lost or closest > lock_sigmas * sigma
        covariance = predicted - accepted * innovation_var * np.outer(gain, gain)
    return covariance, lost


@njit(cache=True)
def _median_ping(ping):
    """``np.median`` of whole numbers (N,) held as floats, by counting them (linear in N)
    when they span at most :data:`MEDIAN_COUNT_SPAN` values (the matched pings of a cloud
    mostly agree); by ``np.median`` otherwise."""
    lo = hi = ping[0]
    for value in ping:
        if math.isnan(value):
            return np.nan
        lo = min(lo, value)
        hi = max(hi, value)
    return _median_in_range(ping, lo, hi)


@njit(cache=True)
def _median_in_range(ping, lo, hi):
    """:func:`_median_ping` of pings (no NaN) known to lie in ``[lo, hi]``."""
    if not hi - lo < MEDIAN_COUNT_SPAN:
        return np.median(ping)
    counts = np.zeros(int(hi - lo) + 1, dtype=np.int64)
    for value in ping:
        counts[int(value - lo)] += 1
    n = ping.size
    below = (n - 1) // 2  # the middle order statistics (0-based): below and n // 2
    first = -1
    seen = 0
    for k in range(counts.size):
        seen += counts[k]
        if first < 0 and seen > below:
            first = k
        if seen > n // 2:
            return 0.5 * ((lo + first) + (lo + k))
    return np.nan  # not reached


#: span of matched pings up to which :func:`_median_ping` counts instead of sorting
MEDIAN_COUNT_SPAN = 4096


@njit(cache=True)
def _temper(log_weight, loglik, remaining, target):
    """The next tempered step: the largest power ``β ≤ remaining`` of the likelihood whose
    weights keep an effective sample size of at least ``target``, and those weights.

    ``β = remaining`` when its weights keep the target (the usual case: one pass). Else
    Newton's method on ``log ESS(β) = log target`` (:func:`_tempered_ess` gives the slope),
    kept within a bracket ``[lo, hi]`` (bisection when a step would leave it), returns the
    bracket's low end once its ESS is within :data:`TEMPER_ESS_TOLERANCE` above the target
    (or the bracket is narrower than ``1e-12·remaining``): about three ESS evaluations
    (at most ten in the two-receiver preset's runs) instead of the 30 of a bisection. At
    least ``1e-3·remaining``.

    Returns
    -------
    beta : float
    log_weight : numpy.ndarray, shape (N,)
        ``log_weight + β·loglik`` normalised (:func:`_tempered`).
    weights : numpy.ndarray, shape (N,)
        Normalised.
    """
    out, weights, ess = _tempered(log_weight, loglik, remaining)
    if ess >= target:
        return remaining, out, weights
    mean = mean_squared = squares = 0.0  # the slope at β = remaining, from its weights
    for i in range(weights.size):
        mean += weights[i] * loglik[i]
        mean_squared += weights[i] * weights[i] * loglik[i]
        squares += weights[i] * weights[i]
    slope = 2.0 * (mean - mean_squared / squares)
    log_target = math.log(target)
    gap = math.log(ess) - log_target
    lo, hi, beta = 0.0, remaining, remaining
    for _ in range(100):
        step = beta - gap / slope if slope < 0.0 else -1.0
        beta = step if lo < step < hi else 0.5 * (lo + hi)
        ess, slope = _tempered_ess(log_weight, loglik, beta)
        gap = math.log(ess) - log_target
        if gap >= 0.0:
            lo = beta
            if gap <= math.log1p(TEMPER_ESS_TOLERANCE):
                break
        else:
            hi = beta
        if hi - lo <= 1e-12 * remaining:
            break
    beta = max(lo, 1e-3 * remaining)
    out, weights, _ = _tempered(log_weight, loglik, beta)
    return beta, out, weights


#: relative ESS above the target at which :func:`_temper` stops refining the power
TEMPER_ESS_TOLERANCE = 1e-3


@njit(cache=True)
def _tempered_ess(log_weight, loglik, beta):
    """Effective sample size of the weights ``exp(log_weight + β·loglik)`` (normalised)
    and its logarithm's derivative in ``β``, ``2·(E_w[loglik] − E_{w²}[loglik])``."""
    top = -math.inf
    for i in range(log_weight.size):
        top = max(top, log_weight[i] + beta * loglik[i])
    total = squares = mean = mean_squared = 0.0
    for i in range(log_weight.size):
        w = math.exp(log_weight[i] + beta * loglik[i] - top)
        total += w
        squares += w * w
        mean += w * loglik[i]
        mean_squared += w * w * loglik[i]
    return total * total / squares, 2.0 * (mean / total - mean_squared / squares)


@njit(cache=True)
def _tempered(log_weight, loglik, beta):
    """``log_weight + β·loglik`` normalised (log-sum-exp 0), the weights (N,) and their
    effective sample size (the same number as :func:`_tempered_ess`)."""
    n = log_weight.size
    out = np.empty(n)
    weights = np.empty(n)
    top = -math.inf
    for i in range(n):
        out[i] = log_weight[i] + beta * loglik[i]
        top = max(top, out[i])
    total = squares = 0.0
    for i in range(n):
        weights[i] = math.exp(out[i] - top)
        total += weights[i]
        squares += weights[i] * weights[i]
    scale = 1.0 / total
    shift = top + math.log(total)
    for i in range(n):
        weights[i] *= scale
        out[i] -= shift
    return out, weights, total * total / squares


@njit(cache=True)
def _clock_summary(emission_time, period, weights, var_emission, var_period):
    """The estimated clock: a row of :data:`CLOCK_COLUMNS` after ``time``.

    Particles' reference emissions need not be the same ping, so two nearly equal clocks
    can differ by whole periods: emission times are taken relative to the heaviest
    particle's clock, wrapped to its nearest ping
    (:func:`hmmtrack.tracking.measurement.arrival_time.wrap_to_ping`).

    Parameters
    ----------
    emission_time, period, weights : numpy.ndarray, shape (N,)
        Particles' clock means (s) and normalised weights.
    var_emission, var_period : float
        Shared clock variances (s²) added to the spread of the means.

    Returns
    -------
    emission_time, period, emission_time_sd, period_sd : float
        Seconds.
    """
    best = np.argmax(weights)
    reference, step = emission_time[best], period[best]
    offset = np.empty(weights.size)
    mean_offset = mean_period = 0.0
    for i in range(weights.size):
        offset[i] = emission_time[i] - reference
        offset[i] -= np.rint(offset[i] / step) * step
        mean_offset += weights[i] * offset[i]
        mean_period += weights[i] * period[i]
    spread_offset = spread_period = 0.0
    for i in range(weights.size):
        spread_offset += weights[i] * (offset[i] - mean_offset) ** 2
        spread_period += weights[i] * (period[i] - mean_period) ** 2
    return (
        reference + mean_offset,
        mean_period,
        math.sqrt(spread_offset + var_emission),
        math.sqrt(spread_period + var_period),
    )


@njit(cache=True)
def _regularisation_move(x, y, normals, bandwidth):
    """Move positions by ``bandwidth·L·normals``, ``L`` the Cholesky factor of their sample
    covariance (``np.cov``, N − 1 in the denominator) plus 1e-4 m² on the diagonal.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    normals : numpy.ndarray, shape (2, N)
        Standard normal draws.
    bandwidth : float

    Returns
    -------
    x, y : numpy.ndarray, shape (N,)
        New arrays (m).
    """
    n = x.size
    mean_x, mean_y = x.mean(), y.mean()
    sxx = sxy = syy = 0.0
    for i in range(n):
        dx, dy = x[i] - mean_x, y[i] - mean_y
        sxx += dx * dx
        sxy += dx * dy
        syy += dy * dy
    sxx = sxx / (n - 1) + 1e-4
    sxy = sxy / (n - 1)
    syy = syy / (n - 1) + 1e-4
    l11 = math.sqrt(sxx)  # 2 x 2 Cholesky factor [[l11, 0], [l21, l22]]
    l21 = sxy / l11
    l22 = math.sqrt(syy - l21 * l21)
    moved_x = np.empty(n)
    moved_y = np.empty(n)
    for i in range(n):
        moved_x[i] = x[i] + bandwidth * l11 * normals[0, i]
        moved_y[i] = y[i] + bandwidth * (l21 * normals[0, i] + l22 * normals[1, i])
    return moved_x, moved_y


def ambiguity(x, y, weights, min_separation: float = 20.0) -> tuple[float, float, bool]:
    """Is a particle cloud two separated clusters? (the paper's two-intersection case)

    The cloud is projected on its principal axis and split in two by weighted 1-D 2-means
    (on :data:`AMBIGUITY_BINS` bins of the projection, so in time linear in N); it is
    called ambiguous when the smaller cluster holds at least 5 % of the weight and the
    clusters' centres lie more than ``min_separation`` apart and more than three times
    the sum of their standard deviations along the axis.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Particle positions (m).
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
    separation, minor, split = _ambiguity_kernel(
        np.ascontiguousarray(x, dtype=float),
        np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(weights, dtype=float),
        float(min_separation),
        AMBIGUITY_BINS,
    )
    return float(separation), float(minor), bool(split)


#: bins of the projected cloud in :func:`ambiguity` (cluster centres to 1/1024 of its span)
AMBIGUITY_BINS = 1024


@njit(cache=True)
def _ambiguity_kernel(x, y, w, min_separation, n_bins):
    """:func:`ambiguity` (compiled): weighted moments, principal axis, binned 2-means."""
    total = mx = my = 0.0
    for i in range(x.size):
        total += w[i]
        mx += w[i] * x[i]
        my += w[i] * y[i]
    mx, my = mx / total, my / total
    sxx = sxy = syy = 0.0
    for i in range(x.size):
        dx, dy = x[i] - mx, y[i] - my
        sxx += w[i] * dx * dx
        sxy += w[i] * dx * dy
        syy += w[i] * dy * dy
    sxx, sxy, syy = sxx / total, sxy / total, syy / total
    half = 0.5 * (sxx - syy)
    largest = 0.5 * (sxx + syy) + math.sqrt(half * half + sxy * sxy)
    if largest < 0.05 * 0.95 * min_separation**2:
        # two clusters this far apart, the smaller with 5 % of the weight, would spread
        # the cloud at least this much along the axis joining them
        return 0.0, 0.0, False
    ax, ay = (
        (sxy, largest - sxx)
        if abs(sxy) > 1e-12 * largest
        else ((1.0, 0.0) if sxx >= syy else (0.0, 1.0))
    )
    norm = math.hypot(ax, ay)
    ax, ay = ax / norm, ay / norm
    u = np.empty(x.size)
    low, high = math.inf, -math.inf
    for i in range(x.size):
        u[i] = (x[i] - mx) * ax + (y[i] - my) * ay
        low = min(low, u[i])
        high = max(high, u[i])
    width = (high - low) / n_bins
    bin_w = np.zeros(n_bins)
    bin_wu = np.zeros(n_bins)
    bin_wu2 = np.zeros(n_bins)
    for i in range(u.size):
        k = min(int((u[i] - low) / width), n_bins - 1)
        bin_w[k] += w[i]
        bin_wu[k] += w[i] * u[i]
        bin_wu2[k] += w[i] * u[i] * u[i]
    cw, cwu, cwu2 = np.cumsum(bin_w), np.cumsum(bin_wu), np.cumsum(bin_wu2)
    total_u, total_u2 = cwu[-1], cwu2[-1]
    # start from the weighted quartiles; each iteration splits at the midpoint of the means
    lo = low + width * (np.searchsorted(cw, 0.25 * total) + 0.5)
    hi = low + width * (np.searchsorted(cw, 0.75 * total) + 0.5)
    k = -1
    w_lo = w_hi = 0.0
    for _ in range(50):
        k_new = min(max(int((0.5 * (lo + hi) - low) / width), 0), n_bins - 1)
        if k_new == k:
            break
        k = k_new
        w_lo, w_hi = cw[k], total - cw[k]
        if w_lo <= 0 or w_hi <= 0:
            return 0.0, 0.0, False
        lo, hi = cwu[k] / w_lo, (total_u - cwu[k]) / w_hi
    sd_lo = math.sqrt(max(cwu2[k] / w_lo - lo * lo, 0.0))
    sd_hi = math.sqrt(max((total_u2 - cwu2[k]) / w_hi - hi * hi, 0.0))
    separation = hi - lo
    minor = min(w_lo, w_hi) / total
    split = minor >= 0.05 and separation > max(min_separation, 3.0 * (sd_lo + sd_hi))
    return separation, minor, split


@dataclass
class ClockFilterResult(FilterResult):
    """:class:`hmmtrack.tracking.filter.FilterResult` plus what the clock-aware filter adds.

    Attributes
    ----------
    smoothed : pandas.DataFrame or None
        Fixed-lag smoothed estimates (:data:`hmmtrack.tracking.smoothing.SMOOTHED_COLUMNS`), when a
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
    _grid: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _heard_all: list = field(default_factory=list, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.detection.require_unit_maximum("SilenceModel")

    def heard_times(self, names) -> HeardTimes:
        """Detection times of the receivers ``names`` in the compiled kernel's form."""
        if not self._heard_all:  # once: every receiver's times, and their positions there
            self._heard_all.append(HeardTimes.of(list(self.heard.values())))
            self._heard_all.append({name: k for k, name in enumerate(self.heard)})
        everyone, position = self._heard_all
        return everyone.select(np.array([position[n] for n in names], dtype=np.int64))

    def listening(self, time: float, step: float = 1.0, chunk: int = 1024):
        """Receivers listening at ``time`` (within their GPS span) and their positions.

        Positions are looked up on a grid of ``step`` seconds computed ``chunk`` steps
        at a time (a filter asks once per correction, on its prediction grid).

        Returns
        -------
        names : list of str
        xy : numpy.ndarray, shape (K, 2)
            Positions (m) at ``time``.
        """
        grid = self._grid
        k = round((time - grid.get("start", np.inf)) / step) if grid else -1
        if not (0 <= k < chunk and abs(grid["start"] + k * step - time) < 1e-6 * step):
            times = time + step * np.arange(chunk)
            span = {n: self.receivers.span(n) for n in self.receivers.names}
            # (clipped to each span: positions outside it are never used)
            xy = {n: np.array(self.receivers.state(n, np.clip(times, *span[n]))[:2]) for n in span}
            grid.update(start=float(time), xy=xy, span=span)
            k = 0
        names = [n for n, (a, b) in grid["span"].items() if a <= time <= b]
        return names, np.array([grid["xy"][n][:, k] for n in names]).reshape(len(names), 2)

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
        Motion model (:mod:`hmmtrack.tracking.motion`).
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
        Passed to :class:`hmmtrack.tracking.filter.ParticleFilter` (``resampling``, ``rng``, ...).
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
        self._table = self._table_rows = None  # set during run (see _rows)
        self._clock_noise = np.array(
            [clock.phase_step_sd**2, clock.period_step_sd**2, clock.rate_step_sd**2]
        )
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
        self.particles.extra.update(
            emission_time=np.full(n, np.nan),
            period=np.full(n, np.nan),
            period_rate=np.zeros(n),
        )
        self._clock_started = False
        self._keep_weights(self.particles.normalised_weights())
        self._lost_count = 0
        self._clock_covariance = np.full((3, 3), np.nan)
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

    # ------------------------------------------------------------------ weights

    def _keep_weights(self, weights: np.ndarray) -> None:
        """Keep ``weights`` (N,), the normalised weights of the particles' current log
        weights, in :class:`ParticleFilter`'s cache (``_weighed``, read through
        :meth:`ParticleFilter._weights` by prediction, correction, resampling and the
        diagnostics) with their effective sample size ``1 / Σ w²`` and weighted mean
        position (m).

        Called wherever this filter replaces the log weights (initialisation, each
        tempered step, resampling), so the cache is never missed; moving the particles
        (prediction, regularisation) leaves the weights valid and the mean a point inside
        the cloud.
        """
        p = self.particles
        self._weighed = (
            p.log_weight,
            weights,
            1.0 / (weights @ weights),
            (float(weights @ p.x), float(weights @ p.y)),
        )

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
            covariance[2, 2] = max(covariance[2, 2], float(np.var(p.period_rate)))
        else:
            p.extra["period"] = np.full(p.n, self.clock.nominal_period)
            p.extra["period_rate"] = np.zeros(p.n)
            # silences count from the first ping on: earlier pings may predate the tag
            self._silence_from = float(np.min(p.emission_time))
        self._clock_covariance = covariance
        self._clock_started = True

    def _clock_update(self, obs: pd.DataFrame, rows=None):
        """Marginal log-likelihood of ``obs`` per particle and the updated clocks.

        Rows are taken one after the other: each is scored against every particle's
        predicted clock (mean and shared covariance moved to the ping that fits), then the
        clock is updated with it (Kalman gain scaled by the posterior probability that the
        detection is a direct arrival), so simultaneous detections of one ping are scored
        jointly. ``rows``: :meth:`_rows` of ``obs``, when already taken.

        Returns
        -------
        loglik : numpy.ndarray, shape (N,)
            With a silence model, it includes ``log p(range)`` of each detection (heard
            pings came from within detection range).
        clocks : tuple of numpy.ndarray, shape (N,) each
            Updated clock means: emission time, period, period rate.
        covariance : numpy.ndarray, shape (3, 3)
        lost : bool
            Whether some detection fitted no particle's clock within ``lock_sigmas``.
        """
        p = self.particles
        likelihood = self.measurement.likelihood
        clocks = tuple(np.array(p.extra[name], dtype=float) for name in CLOCK_FIELDS)
        loglik = np.zeros(p.n)
        detection = None if self.silence is None else self.silence.detection
        arrival, receiver_x, receiver_y, row_offset = self._rows(obs) if rows is None else rows
        covariance, lost = _correction_kernel(
            p.x,
            p.y,
            p.speed,
            p.cos_heading,
            p.sin_heading,
            vertical_parts(p, _NO_ROWS)[0],  # the particles' depths
            self._weights()[0],
            *clocks,
            arrival,
            receiver_x,
            receiver_y,
            row_offset,
            float(self.time),
            self.measurement.sound_speed,
            self._clock_covariance,
            self._clock_noise,
            likelihood.sigma,
            likelihood.late_fraction,
            likelihood.late_mean,
            likelihood.uniform_fraction,
            np.nan if detection is None else detection.range_50,
            np.nan if detection is None else detection.width,
            self.lock_sigmas,
            loglik,
        )
        return loglik, clocks, covariance, lost

    def _rows(self, obs: pd.DataFrame):
        """The rows of ``obs`` as arrays (M,): arrival time, receiver x and y, and depth
        offset (:func:`hmmtrack.tracking.measurement.arrival_time.vertical_parts`).

        During :meth:`run`, ``obs`` is a slice of the run's table (its index labels are
        row positions), whose columns were converted once.
        """
        table = obs if self._table is None else self._table
        if self._table is None or self._table_rows is None:
            offset = vertical_parts(self.particles, table)[1]
            columns = [table[c].to_numpy(dtype=float) for c in ("time", "receiver_x", "receiver_y")]
            if self._table is None:
                return *columns, offset
            self._table_rows = (*columns, offset)
        at = obs.index.to_numpy()
        return tuple(column[at] for column in self._table_rows)

    def _loglik(self, obs: pd.DataFrame, rows=None):
        loglik, clocks, covariance, lost = self._clock_update(obs, rows)
        if self.silence is not None:
            loglik = loglik + self._silence_loglik()
        # (the sum of finite log-likelihoods of this size is finite)
        if loglik.shape != (self.particles.n,) or not math.isfinite(loglik.sum()):
            raise ValueError(
                f"arrival-time log-likelihood not finite at time {self.time} for "
                f"observations:\n{obs}"
            )
        return loglik, (clocks, covariance), lost

    def _silence_loglik(self) -> np.ndarray:
        """Unheard pings whose expected arrival fell since the last correction.

        Each particle's pings are stepped by its period; a period rate is left out (over
        the at most 8 pings looked at it moves an arrival by well under ``tolerance``).
        """
        s = self.silence
        p = self.particles
        cut = self.time + 0.5 * self.dt - s.tolerance  # detections up to time + dt/2 are in
        if cut <= self._silence_from:
            return np.zeros(p.n)
        # pings of a particle whose arrival can fall in the window, with one to spare
        n_back = min(int(np.ceil((cut - self._silence_from) / self.clock.nominal_period)) + 1, 8)
        listening, at = s.listening(self.time, self.dt)
        self._silence_from, window_start = cut, self._silence_from
        if not listening:
            return np.zeros(p.n)
        return silence_loglik_recent_pings(
            p.emission_time,
            p.period,
            p.x,
            p.y,
            at,
            n_back,
            s.heard_times(listening),
            window_start,
            cut,
            s.detection,
            s.tolerance,
            self.measurement.sound_speed,
        )

    def correct(self, obs: pd.DataFrame):
        """Tempered arrival-time correction (see the module docstring); the weighted estimate."""
        if not self._clock_started:
            self._start_clock(obs)
        silence_from = self._silence_from
        rows = self._rows(obs)  # (the same for every tempered step)
        loglik, update, lost = self._loglik(obs, rows)
        self._lost_count = self._lost_count + 1 if lost else 0
        if self._lost_count >= self.lost_corrections:
            self._lost_count = 0
            self._start_clock(obs, reacquire=True)
            self._record("clock_reacquired", f"no particle fitted the {len(obs)} detection(s)")
            self._silence_from = silence_from
            loglik, update, _ = self._loglik(obs, rows)
        remaining = 1.0
        while True:
            p = self.particles
            beta, p.log_weight, weights = _temper(
                p.log_weight, loglik, remaining, self.tempering_ess * p.n
            )
            self._keep_weights(weights)
            remaining -= beta
            if remaining <= 1e-12:
                break
            self._resample_now()
            self._regularise()
            self._silence_from = silence_from
            loglik, update, _ = self._loglik(obs, rows)
        p = self.particles
        clocks, self._clock_covariance = update
        p.extra.update(zip(CLOCK_FIELDS, clocks, strict=True))
        self._record_diagnostics()
        return self.estimate()

    def _regularise(self) -> None:
        """Gaussian move of (x, y) with the particles' own covariance (after resampling)."""
        p = self.particles
        p.x, p.y = _regularisation_move(
            p.x, p.y, self.rng.standard_normal((2, p.n)), self._bandwidth
        )

    def _record_diagnostics(self) -> None:
        p = self.particles
        w = self._weights()[0]
        self._ambiguity_rows.append((self.time, *ambiguity(p.x, p.y, w)))
        self._clock_rows.append(
            (
                self.time,
                *_clock_summary(
                    p.emission_time,
                    p.period,
                    w,
                    self._clock_covariance[0, 0],
                    self._clock_covariance[1, 1],
                ),
            )
        )

    # ------------------------------------------------------------------ resample

    def _resample_now(self) -> None:
        """The base filter's resampling, keeping the ancestry for the smoother."""
        super()._resample_now()
        if self._smoother is not None:  # (ancestry is only kept for the smoother)
            ancestors = self.last_ancestors
            self._parent = ancestors if self._parent is None else self._parent[ancestors]

    def resample_if_due(self) -> bool:
        """Resample per ``resample_when``, after the smoother has recorded the corrected,
        not yet resampled, step."""
        self._push_pending()
        return super().resample_if_due()

    # ------------------------------------------------------------------ offline

    def run(self, observations, start=None, end=None, snapshot_times=()) -> ClockFilterResult:
        """:meth:`ParticleFilter.run` plus smoothed track, ambiguity and clock tables."""
        # the run's corrections get slices of this table; their rows are read from arrays
        # converted once (see _rows), not column by column from each slice
        self._table = observations.reset_index(drop=True)
        self._table_rows = None
        try:
            base = super().run(self._table, start, end, snapshot_times)
        finally:
            self._table = self._table_rows = None
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
        ``time`` (common time base, s; see
        :func:`hmmtrack.tracking.measurement.clock.to_common_time`),
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


def default_clock_model(period: float) -> EmissionClockModel:
    """The tag clock model of :func:`track_arrival_time` when none is given.

    ``EmissionClockModel(period, period_step_sd=3e-4, phase_step_sd=1e-4,
    initial_period_sd=1e-3·period)``: a period random walk of 0.3 ms per ping (~40 ppm of an
    8 s period), which over 100-400 pings spreads the period by 375-750 ppm, the size of a
    real tag's block-to-block changes (DESIGN.md), and stays bounded when the tag's clock
    wanders otherwise (robustness table of reports/clock_aware.md).

    Parameters
    ----------
    period : float
        Nominal transmitter period (s).
    """
    return EmissionClockModel(period, 3e-4, 1e-4, 1e-3 * period)


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
    tempering_ess: float = 0.3,
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
        Motion model (:mod:`hmmtrack.tracking.motion`).
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
        Default: :func:`default_clock_model` of ``period``.
        :meth:`EmissionClockModel.temperature_drift` is the alternative for tags known to
        drift smoothly.
    n_particles : int
    smoothing_lag : int, optional
        Steps (s) of the fixed-lag smoother; None: no smoothing.
    detection : LogisticDetection, optional
        Count unheard pings with this detection curve.
    start, end : float, optional
        Time window (s).
    tempering_ess : float
        See :class:`ClockAwareFilter`; two receivers on a fast-turning plan need 0.6
        (benchmarks/bench_two_auv_plan.py).
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
    clock = clock or default_clock_model(period)
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
        tempering_ess=tempering_ess,
        rng=seed,
    )
    return pf.run(obs, start, end)
