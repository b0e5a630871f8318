"""Arrival-time measurement model: score detections on their arrival times, not on ΔTOF ranges.

The paper turns detection times into ranges with a constant, exactly known period and a
known initial range. Real tags drift (hundreds of ppm) and wild animals do not start
beside a hydrophone, so this model keeps the raw arrival time and lets each particle
carry the transmitter's emission clock
(:class:`hmmtrack.tracking.measurement.clock.EmissionClockModel`): particle
``i`` predicts that a ping reaches receiver ``j`` at

    emission_time_i + m·period_i (+ m(m−1)/2·period_rate_i) + range_ij / sound_speed

for some whole number ``m`` of periods (any number of missed pings; the rate term when
the clock model has a period rate); the ``m`` that fits best is chosen
(:func:`wrap_to_ping`, :func:`match_particle`) and the residual is scored with a mixture
(:class:`ArrivalLikelihood`): a Gaussian core for jitter and model error, an
exponentially delayed component for multipath (late) arrivals, and a small uniform floor,
so a few outliers cannot capture the filter. The filter scores thousands of particles per
detection with one likelihood, so its compiled path tabulates the mixture once per
detection and interpolates it (:func:`mixture_table`, :func:`mixture_log_densities`:
within 1e-6 of the exact log density, about 2.5 times cheaper);
:meth:`ArrivalLikelihood.logpdf` and :func:`mixture_log_density` are the exact references.

The range is evaluated where the tag was when it emitted the ping: the particle's
position moved back along its velocity from the filter time to ``arrival − range/c``;
the receiver's position is taken at the arrival time. Ranges are 3-D when a depth is
known (particle field ``depth``, or a ``depth`` column of the detections from a depth
sensor) and receivers may have a ``receiver_depth`` column; otherwise both are at the
surface. Detection times must be on the common (true) time base: map receiver clocks
first with :func:`hmmtrack.tracking.measurement.clock.to_common_time`.

This module only scores; it does not move particles, resample, or build observations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pandas as pd
from numba import njit
from scipy.special import erfcx, log_ndtr

from hmmtrack.tracking.compiled.hermite import hermite_basis, hermite_value
from hmmtrack.tracking.measurement.ranging import SOUND_SPEED

#: columns an arrival-time observation table must have
ARRIVAL_COLUMNS = ("time", "receiver", "receiver_x", "receiver_y")

_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


def wrap_to_ping(implied_emission, emission_time, period) -> tuple[np.ndarray, np.ndarray]:
    """Residual of an implied emission time against the nearest ping of a clock.

    Parameters
    ----------
    implied_emission : array_like
        Arrival time minus time of flight (s).
    emission_time, period : array_like
        The clock: a reference emission time and the period (s); broadcast together.

    Returns
    -------
    residual : numpy.ndarray
        ``implied − (emission_time + m·period)`` (s), in ``[−period/2, period/2]``.
    ping : numpy.ndarray of float
        The whole number of periods ``m`` between the reference emission and the ping that
        fits (negative for earlier pings).
    """
    implied_emission = np.asarray(implied_emission, dtype=float)
    offset = implied_emission - emission_time
    ping = np.rint(offset / period)
    return offset - ping * period, ping


@dataclass(frozen=True)
class ArrivalLikelihood:
    """Density of an arrival-time residual: Gaussian core + late (multipath) tail + uniform floor.

    ``p(ε) = (1 − late_fraction − uniform_fraction)·N(ε; 0, sigma)
    + late_fraction·ExGauss(ε; sigma, late_mean) + uniform_fraction / period``, where the
    late component is an exponential delay of mean ``late_mean`` plus the same Gaussian
    noise (an exponentially modified Gaussian), and the uniform part spreads over one
    period (a detection that belongs to no ping of the particle).

    Parameters
    ----------
    sigma : float
        Standard deviation of the residual of a direct-path arrival (s). It must cover ping
        jitter (~50-80 µs) plus receiver-position and motion errors (1 m ≈ 0.7 ms).
    late_fraction : float
        Share of arrivals delayed by multipath, in [0, 1).
    late_mean : float
        Mean multipath delay (s).
    uniform_fraction : float
        Share of detections unrelated to the clock (false or mis-assigned), in [0, 1).
    """

    sigma: float = 3e-3
    late_fraction: float = 0.05
    late_mean: float = 20e-3
    uniform_fraction: float = 1e-3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"ArrivalLikelihood.sigma must be positive (s), got {self.sigma}")
        if not (np.isfinite(self.late_mean) and self.late_mean > 0):
            raise ValueError(
                f"ArrivalLikelihood.late_mean must be positive (s), got {self.late_mean}"
            )
        for name in ("late_fraction", "uniform_fraction"):
            value = getattr(self, name)
            if not (0 <= value < 1):
                raise ValueError(f"ArrivalLikelihood.{name} must be in [0, 1), got {value}")
        if self.late_fraction + self.uniform_fraction >= 1:
            raise ValueError("late_fraction + uniform_fraction must be below 1")

    def core_logpdf(self, residual) -> np.ndarray:
        """Log of the direct-arrival (Gaussian core) term of the density, with its weight."""
        z = np.asarray(residual, dtype=float) / self.sigma
        return (
            np.log1p(-self.late_fraction - self.uniform_fraction)
            - np.log(self.sigma)
            - _LOG_SQRT_2PI
            - 0.5 * z * z
        )

    def log_densities(self, residual, period) -> tuple[np.ndarray, np.ndarray]:
        """Compiled :meth:`logpdf` and :meth:`core_logpdf` of 1-D ``residual``, together.

        Parameters
        ----------
        residual, period : numpy.ndarray, shape (N,)
            Residuals and the periods they were wrapped with (s).
        """
        residual = np.ascontiguousarray(residual, dtype=float)
        period = np.ascontiguousarray(np.broadcast_to(period, residual.shape), dtype=float)
        total = np.empty(residual.shape)
        core = np.empty(residual.shape)
        _density_kernel(
            residual,
            period,
            self.sigma,
            self.late_fraction,
            self.late_mean,
            self.uniform_fraction,
            total,
            core,
        )
        return total, core

    def logpdf(self, residual, period) -> np.ndarray:
        """Log density (log 1/s) of residuals ``residual`` (s); ``period`` (s) broadcasts.

        The NumPy reference of :meth:`log_densities` (any shape)."""
        eps = np.asarray(residual, dtype=float)
        z = eps / self.sigma
        out = self.core_logpdf(eps)
        if self.late_fraction > 0:
            rate_sigma = self.sigma / self.late_mean
            late = (
                np.log(self.late_fraction / self.late_mean)
                + 0.5 * rate_sigma * rate_sigma
                - eps / self.late_mean
                + log_ndtr(z - rate_sigma)
            )
            out = np.logaddexp(out, late)
        if self.uniform_fraction > 0:
            out = np.logaddexp(out, np.log(self.uniform_fraction) - np.log(period))
        return out


def emission_range(
    x, y, vx, vy, lag, receiver_x, receiver_y, vertical, sound_speed: float
) -> np.ndarray:
    """Range (m) from a receiver to where a moving tag emitted the ping it heard.

    The tag at ``(x, y)`` moving with ``(vx, vy)`` heard ``lag`` seconds ago at the receiver
    emitted ``r/c`` seconds before that, where ``r = |q − v·r/c|`` (with the vertical
    separation), ``q`` the tag's position at the arrival minus the receiver's and ``c`` the
    sound speed: a quadratic in ``r`` whose positive root is
    ``r = (|q|² + dz²) / (b + √(b² + a·(|q|² + dz²)))`` with ``b = q·v/c`` and
    ``a = 1 − |v|²/c²`` (this form has no cancellation).

    Parameters
    ----------
    x, y, vx, vy : numpy.ndarray, shape (N,)
        Tag positions (m) and velocities (m/s) at the filter time.
    lag : float
        Filter time minus arrival time (s), >= 0 in a filter.
    receiver_x, receiver_y : float
        Receiver position at the arrival time (m).
    vertical : float or numpy.ndarray, shape (N,)
        Vertical separation of tag and receiver (m).
    sound_speed : float
        Speed of sound (m/s).

    Returns
    -------
    numpy.ndarray, shape (N,)
    """
    qx = np.asarray(x, dtype=float) - np.multiply(vx, lag) - receiver_x
    qy = np.asarray(y, dtype=float) - np.multiply(vy, lag) - receiver_y
    b = (qx * vx + qy * vy) / sound_speed
    a = 1.0 - (np.square(vx) + np.square(vy)) / sound_speed**2
    squared = qx * qx + qy * qy + np.square(vertical)
    root = b + np.sqrt(b * b + a * squared)
    return np.divide(squared, root, out=np.zeros(np.shape(root)), where=root > 0)


@njit(cache=True)
def _log_ndtr(z: float) -> float:
    """log Φ(z), the standard normal log CDF (erfc form; asymptotic series far left)."""
    if z > 8.3:  # Φ(z) rounds to 1: log Φ(z) ≈ −Φ(−z) < 5e-17
        return -0.5 * math.erfc(z / math.sqrt(2.0))
    if z > -30.0:
        return math.log(0.5 * math.erfc(-z / math.sqrt(2.0)))
    z2 = z * z
    series = -1.0 / z2 + 3.0 / z2**2 - 15.0 / z2**3 + 105.0 / z2**4  # next term < 2e-12
    return -0.5 * z2 - math.log(-z) - _LOG_SQRT_2PI + math.log1p(series)


@njit(cache=True)
def _log_add(a: float, b: float) -> float:
    if a < b:
        a, b = b, a
    if b == -math.inf:
        return a
    return a + math.log1p(math.exp(b - a))


@njit(cache=True)
def emission_distance(x, y, vx, vy, vertical, lag, receiver_x, receiver_y, slowness):
    """Compiled :func:`emission_range` of one particle (``slowness`` = 1 / sound speed, s/m).

    A loop of it over particles compiles to vector code (no branches but a select).
    """
    qx = x - vx * lag - receiver_x
    qy = y - vy * lag - receiver_y
    b = (qx * vx + qy * vy) * slowness
    a = 1.0 - (vx * vx + vy * vy) * (slowness * slowness)
    squared = qx * qx + qy * qy + vertical * vertical
    root = b + math.sqrt(b * b + a * squared)
    return squared / root if root > 0.0 else 0.0


@njit(cache=True)
def wrap_arrival(distance, emission_time, period, rate, arrival, slowness):
    """Compiled :func:`wrap_to_ping` of one arrival heard from ``distance`` (m).

    With a period rate ``R`` (s per ping) ping ``m`` of a clock is emitted at
    ``e + m·P + m(m−1)/2·R``; the ping is rounded once more after that correction (which
    changes nothing when ``R = 0``).

    Returns
    -------
    residual : float
        Arrival-time residual against the matched ping (s).
    ping : float
        Whole periods from ``emission_time`` to the matched ping.
    """
    offset = arrival - distance * slowness - emission_time
    frequency = 1.0 / period
    m = np.rint(offset * frequency)
    m = np.rint((offset - 0.5 * m * (m - 1.0) * rate) * frequency)
    return offset - m * period - 0.5 * m * (m - 1.0) * rate, m


@njit(cache=True)
def match_particle(
    x, y, vx, vy, emission_time, period, rate, vertical, lag, arrival, receiver_x, receiver_y,
    sound_speed,
):  # fmt: skip
    """Compiled :func:`emission_range` + :func:`wrap_to_ping` of one particle and detection
    (:func:`emission_distance`, then :func:`wrap_arrival`).

    Returns
    -------
    residual, ping : float
        As :func:`wrap_arrival`.
    distance : float
        Range at emission (m).
    """
    slowness = 1.0 / sound_speed
    r = emission_distance(x, y, vx, vy, vertical, lag, receiver_x, receiver_y, slowness)
    residual, m = wrap_arrival(r, emission_time, period, rate, arrival, slowness)
    return residual, m, r


@njit(cache=True)
def _match_kernel(
    x, y, vx, vy, emission_time, period, rate, vertical, lag, arrival, receiver_x, receiver_y,
    sound_speed, residual, ping, distance,
):  # fmt: skip
    """:func:`match_particle` of every particle for one detection, into the three outputs."""
    for i in range(x.size):
        residual[i], ping[i], distance[i] = match_particle(
            x[i], y[i], vx[i], vy[i], emission_time[i], period[i], rate[i], vertical[i], lag,
            arrival, receiver_x, receiver_y, sound_speed,
        )  # fmt: skip


@njit(cache=True)
def _share(term: float, top: float) -> float:
    """``exp(term − top)``, skipped (0) more than 40 nats below ``top``."""
    return math.exp(term - top) if term > top - 40.0 else 0.0


@njit(cache=True)
def mixture_constants(sigma, late_fraction, late_mean, uniform_fraction):
    """The per-likelihood constants of :func:`mixture_log_density` (compiled).

    Parameters
    ----------
    sigma, late_fraction, late_mean, uniform_fraction : float
        The :class:`ArrivalLikelihood` parameters.

    Returns
    -------
    tuple of float
        ``(sigma, late_mean, log_core_weight, rate_sigma, log_late_weight,
        log_uniform_weight, late_offset, uniform_ratio)``; a weight of a component that is
        absent is ``-inf``; the last two are the late and uniform weights relative to the
        core's (log, and linear for a period of 1 s).
    """
    log_core_weight = math.log1p(-late_fraction - uniform_fraction) - math.log(sigma)
    log_core_weight -= _LOG_SQRT_2PI
    rate_sigma = sigma / late_mean
    log_late_weight = -math.inf
    if late_fraction > 0:
        log_late_weight = math.log(late_fraction / late_mean) + 0.5 * rate_sigma * rate_sigma
    log_uniform_weight = math.log(uniform_fraction) if uniform_fraction > 0 else -math.inf
    return (
        sigma,
        late_mean,
        log_core_weight,
        rate_sigma,
        log_late_weight,
        log_uniform_weight,
        log_late_weight - log_core_weight,
        math.exp(log_uniform_weight - log_core_weight),
    )


@njit(cache=True)
def mixture_log_density(eps, period, constants):
    """Compiled :meth:`ArrivalLikelihood.logpdf` of one residual, and the direct share.

    Parameters
    ----------
    eps : float
        Residual (s).
    period : float
        The period the residual was wrapped with (s).
    constants : tuple of float
        :func:`mixture_constants` of the likelihood.

    Returns
    -------
    total : float
        Log density of the mixture (log 1/s).
    core : float
        Log of its weighted Gaussian core (:meth:`ArrivalLikelihood.core_logpdf`).
    direct : float
        ``exp(core − total)``: the probability that the arrival is direct.

    Notes
    -----
    Near the core (``|eps| < 30·sigma``, where no term can overflow or vanish) the three
    terms are summed in linear scale relative to the core's weight. Elsewhere they are
    summed relative to the largest, and the multipath term is skipped where an upper
    bound of it (``log Φ(w) ≤ −w²/2`` for ``w ≤ 0``) lies more than 40 nats below the
    others: it could not change their sum in double precision, and far-off particles then
    cost no ``erfc``.
    """
    sigma, late_mean, log_core_weight, rate_sigma, log_late_weight, log_uniform_weight = constants[
        :6
    ]
    z = eps / sigma
    w = z - rate_sigma
    late_exponent = constants[6] - eps / late_mean
    if z * z < 900.0 and w > -25.0 and late_exponent < 500.0:
        core_share = math.exp(-0.5 * z * z)
        late = math.exp(late_exponent) * 0.5 * math.erfc(-w / math.sqrt(2.0))
        scaled = core_share + late + constants[7] / period
        return (
            log_core_weight + math.log(scaled),
            log_core_weight - 0.5 * z * z,
            core_share / scaled,
        )
    core = log_core_weight - 0.5 * z * z
    log_uniform = log_uniform_weight - math.log(period)
    top = max(core, log_uniform)
    log_late = -math.inf
    if log_late_weight > -math.inf:
        log_late = log_late_weight - eps / late_mean
        bound = log_late - 0.5 * w * w if w < 0 else log_late
        log_late = log_late + _log_ndtr(w) if bound > top - 40.0 else -math.inf
        top = max(top, log_late)
    core_share = _share(core, top)
    scaled = core_share + _share(log_uniform, top) + _share(log_late, top)
    return top + math.log(scaled), core, core_share / scaled


#: grid of :func:`mixture_table`: ``w = eps/sigma − sigma/late_mean`` (the standardised
#: residual less the multipath term's shift) from ``TABLE_START`` to ``TABLE_END`` in steps
#: of ``TABLE_STEP``; residuals outside it are scored exactly (:func:`mixture_log_density`)
TABLE_START, TABLE_END, TABLE_STEP = -10.0, 10.0, 1.0 / 40.0
#: largest ``sigma/late_mean`` for which :func:`mixture_table` tabulates (beyond, the
#: multipath term bends too sharply within a grid step and every residual is scored exactly)
TABLE_MAX_RATE_SIGMA = 2.0
#: largest relative difference of a particle's period from the table's reference period
TABLE_MAX_PERIOD_RATIO = 0.1
_TABLE_W = np.linspace(TABLE_START, TABLE_END, round((TABLE_END - TABLE_START) / TABLE_STEP) + 1)
#: ``M(w) = exp(w²/2)·Φ(w)`` on the grid: the multipath term over the Gaussian core, up to
#: a constant (its derivative is ``w·M(w) + 1/√(2π)``)
_MILLS = 0.5 * erfcx(-_TABLE_W / np.sqrt(2.0))


@njit(cache=True)
def mixture_table(constants, reference_period):
    """Tabulate :func:`mixture_log_density` of one likelihood for cubic interpolation.

    With ``z = eps/sigma``, ``w = z − sigma/late_mean`` and the uniform floor at
    ``reference_period``, the density relative to the core's weight is
    ``T(w) = exp(−z²/2)·(1 + B·M(w)) + c`` (``M`` the Mills form :data:`_MILLS`, ``B``
    and ``c`` the late and uniform weights over the core's). On the grid of
    :data:`TABLE_START`, :data:`TABLE_END`, :data:`TABLE_STEP` this stores, with their
    derivatives times the step (closed forms), ``G = log T``, the uniform share ``c/T``
    and the direct share ``exp(−z²/2)/T``; :func:`mixture_log_densities` interpolates them.

    Parameters
    ----------
    constants : tuple of float
        :func:`mixture_constants` of the likelihood.
    reference_period : float
        Period (s) of the uniform floor in the table; particles' own periods enter exactly
        through the uniform share (:func:`mixture_log_densities`).

    Returns
    -------
    numpy.ndarray, shape (K, 6)
        Per node ``(G, step·G', D, step·D', C, step·C')``; no rows (K = 0) when
        ``sigma/late_mean`` exceeds :data:`TABLE_MAX_RATE_SIGMA` (nothing is tabulated).
    """
    rate_sigma = constants[3]
    if not rate_sigma <= TABLE_MAX_RATE_SIGMA:
        return np.empty((0, 6))
    late_ratio = math.exp(constants[6] - 0.5 * rate_sigma * rate_sigma)  # B (0 without)
    uniform_ratio = constants[7] / reference_period  # c
    table = np.empty((_TABLE_W.size, 6))
    inv_sqrt_2pi = 1.0 / math.sqrt(2.0 * math.pi)
    # exp(−z²/2) node by node: exp(−z_{k+1}²/2) = exp(−z_k²/2)·q_k with
    # q_k = exp(−z_k·h − h²/2) and q_{k+1} = q_k·exp(−h²) (relative error ~1e-13)
    z = _TABLE_W[0] + rate_sigma
    core = math.exp(-0.5 * z * z)
    step_ratio = math.exp(-z * TABLE_STEP - 0.5 * TABLE_STEP * TABLE_STEP)
    ratio_ratio = math.exp(-TABLE_STEP * TABLE_STEP)
    for k in range(_TABLE_W.size):
        z = _TABLE_W[k] + rate_sigma
        if k:
            core *= step_ratio
            step_ratio *= ratio_ratio
        total = core * (1.0 + late_ratio * _MILLS[k]) + uniform_ratio
        inverse = 1.0 / total
        # T' = exp(−z²/2)·(−z·(1 + B·M) + B·M') with M' − z·M = 1/√(2π) − rate_sigma·M
        slope = core * (-z + late_ratio * (inv_sqrt_2pi - rate_sigma * _MILLS[k])) * inverse
        uniform = uniform_ratio * inverse
        direct = core * inverse
        table[k, 0] = math.log(total)
        table[k, 1] = TABLE_STEP * slope
        table[k, 2] = uniform
        table[k, 3] = -TABLE_STEP * uniform * slope
        table[k, 4] = direct
        table[k, 5] = TABLE_STEP * direct * (-z - slope)
    return table


@njit(cache=True)
def mixture_log_densities(residual, period, constants, total, direct):
    """:func:`mixture_log_density` of N residuals, interpolated in a :func:`mixture_table`.

    The table is built at the mean period ``P̄``; a particle's own period ``P`` enters
    exactly through the uniform share ``D``: with ``x = (P̄/P − 1)·D`` the log density is
    ``log_core_weight + G + log1p(x)`` and the direct share ``C/(1 + x)`` (``log1p`` by
    four terms of its series, exact to 2e-11 for ``|x| ≤ 0.01``). The interpolating pass
    has no branches (those cost more than the interpolation); a second pass scores exactly
    (:func:`mixture_log_density`) the residuals off the table's grid, periods with
    ``|P̄/P − 1|`` above :data:`TABLE_MAX_PERIOD_RATIO` or ``|x| > 0.01``, and every
    residual of a likelihood that cannot be tabulated. The interpolation error is below
    1e-6 in the log density and in the direct share (tested against the exact function
    over the likelihood parameters' range).

    Parameters
    ----------
    residual, period : numpy.ndarray, shape (N,)
        Residuals and the periods they were wrapped with (s).
    constants : tuple of float
        :func:`mixture_constants` of the likelihood.
    total, direct : numpy.ndarray, shape (N,)
        Filled with the log densities (log 1/s) and the direct shares.
    """
    reference_period = period.mean()
    table = mixture_table(constants, reference_period)
    last = table.shape[0] - 2  # the last interval's first node
    to_grid = 1.0 / (constants[0] * TABLE_STEP)
    grid_shift = (constants[3] + TABLE_START) / TABLE_STEP
    if last >= 0:
        for i in range(residual.size):
            at = residual[i] * to_grid - grid_shift
            ratio = reference_period / period[i] - 1.0
            inside = (at >= 0.0) & (at < last + 1.0)  # False for NaN
            clipped = at if inside else 0.0  # (outside: any node, the value is not kept)
            k = int(clipped)
            h01, h10, h11 = hermite_basis(clipped - k)
            log_total = hermite_value(table, k, 0, h01, h10, h11)
            uniform = hermite_value(table, k, 2, h01, h10, h11)
            share = hermite_value(table, k, 4, h01, h10, h11)
            x = ratio * uniform
            log1p_x = x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - 0.25 * x)))
            tabulated = inside & (abs(ratio) <= TABLE_MAX_PERIOD_RATIO) & (abs(x) <= 0.01)
            total[i] = constants[2] + log_total + log1p_x if tabulated else np.nan
            direct[i] = share / (1.0 + x)
    for i in range(residual.size):  # (NaN: not tabulated)
        if last < 0 or math.isnan(total[i]):
            total[i], _, direct[i] = mixture_log_density(residual[i], period[i], constants)


@njit(cache=True)
def _density_kernel(
    residual, period, sigma, late_fraction, late_mean, uniform_fraction, total, core
):
    """:func:`mixture_log_density` over arrays, into ``total`` and ``core``."""
    constants = mixture_constants(sigma, late_fraction, late_mean, uniform_fraction)
    for i in range(residual.size):
        total[i], core[i], _ = mixture_log_density(residual[i], period[i], constants)


def vertical_parts(particles, obs: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Tag depth minus receiver depth as ``tag_depth[i] + row_offset[j]``.

    Parameters
    ----------
    particles
        Particles, with a ``depth`` field (m) when the state carries depth.
    obs : pandas.DataFrame
        M detections; ``depth`` (the tag's sensor, m) is used when the particles carry no
        depth, ``receiver_depth`` (m) always when present.

    Returns
    -------
    tag_depth : numpy.ndarray, shape (N,)
        The particles' depths (m), zeros without a ``depth`` field.
    row_offset : numpy.ndarray, shape (M,)
        Per detection: sensor depth (without particle depth) minus receiver depth (m).
    """
    offset = np.zeros(len(obs))
    if "receiver_depth" in obs:
        offset -= obs["receiver_depth"].to_numpy(dtype=float)
    if getattr(particles, "depth", None) is None and "depth" in obs:
        offset += obs["depth"].to_numpy(dtype=float)
    return particle_depths(particles), offset


def particle_depths(particles) -> np.ndarray:
    """The particles' depths (m), shape (N,): their ``depth`` field, zeros without one."""
    tag_depth = getattr(particles, "depth", None)
    if tag_depth is None:
        return np.zeros(np.shape(particles.x)[0])
    return np.ascontiguousarray(tag_depth, dtype=float)


def _period_rate(particles, n: int) -> np.ndarray:
    """The particles' period rates (s per ping), (N,); zeros when they carry none."""
    rate = getattr(particles, "period_rate", None)
    if rate is None:
        return np.zeros(n)
    return np.ascontiguousarray(rate, dtype=float)


def check_arrival_observations(obs: pd.DataFrame, where: str = "arrival-time observations") -> None:
    """Raise ``ValueError`` naming rows and columns when ``obs`` cannot be scored."""
    missing = [c for c in ARRIVAL_COLUMNS if c not in obs.columns]
    if missing:
        raise ValueError(
            f"{where}: missing column(s) {missing}; expected at least {list(ARRIVAL_COLUMNS)}"
        )
    for column in ("time", "receiver_x", "receiver_y", "depth", "receiver_depth"):
        if column in obs.columns:
            values = pd.to_numeric(obs[column], errors="coerce").to_numpy(dtype=float)
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise ValueError(
                    f"{where}: column {column!r} must hold finite numbers; "
                    f"rows {bad[:10].tolist()} do not"
                )


@dataclass(frozen=True)
class ArrivalTimeMeasurement:
    """Log-likelihood of detections given particles that carry an emission clock.

    Parameters
    ----------
    likelihood : ArrivalLikelihood
        Density of arrival-time residuals.
    sound_speed : float
        Speed of sound (m/s).

    Notes
    -----
    Particles need fields ``x``, ``y``, ``cos_heading``, ``sin_heading``, ``speed``
    (velocity along the heading), ``emission_time`` and ``period`` (see
    :class:`hmmtrack.tracking.measurement.clock.EmissionClockModel`), and optionally
    ``period_rate`` (s per
    ping; 0 when absent) and ``depth`` (m, positive down). Observations are rows of a table with
    columns ``time`` (arrival time on the common time base, s), ``receiver``, ``receiver_x``,
    ``receiver_y`` (m, at the arrival time) and optionally ``depth`` (the tag's depth from
    its sensor, m) and ``receiver_depth`` (m).
    """

    likelihood: ArrivalLikelihood = field(default_factory=ArrivalLikelihood)
    sound_speed: float = SOUND_SPEED
    columns: ClassVar[tuple[str, ...]] = ("receiver_x", "receiver_y")

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sound_speed) and 1000.0 < self.sound_speed < 2000.0):
            raise ValueError(
                f"sound_speed must be a speed of sound in water (m/s), got {self.sound_speed}"
            )

    def match_one(
        self,
        particles,
        arrival: float,
        receiver_x: float,
        receiver_y: float,
        vertical,
        time: float | None = None,
    ):
        """Residual, matched ping and emission range of every particle for one detection.

        Parameters
        ----------
        particles
            Particles with the fields listed in the class notes, shape (N,) each.
        arrival : float
            Arrival time on the common time base (s).
        receiver_x, receiver_y : float
            Receiver position at the arrival (m).
        vertical : float or numpy.ndarray, shape (N,)
            Tag depth minus receiver depth (m).
        time : float, optional
            Filter time at which the particles are (s); default ``arrival``.

        Returns
        -------
        residual, ping, range : numpy.ndarray, shape (N,)
            Residual (s, see :func:`wrap_to_ping`), whole periods from the particle's
            ``emission_time`` to the matched ping, and range at emission (m).
        """
        n = np.shape(particles.x)[0]
        out = np.empty((3, n))
        _match_kernel(
            particles.x,
            particles.y,
            particles.speed * particles.cos_heading,
            particles.speed * particles.sin_heading,
            np.ascontiguousarray(particles.emission_time, dtype=float),
            np.ascontiguousarray(particles.period, dtype=float),
            _period_rate(particles, n),
            np.ascontiguousarray(np.broadcast_to(np.asarray(vertical, dtype=float), (n,))),
            0.0 if time is None else float(time) - float(arrival),
            float(arrival),
            float(receiver_x),
            float(receiver_y),
            self.sound_speed,
            out[0],
            out[1],
            out[2],
        )
        return out[0], out[1], out[2]

    def rows(self, particles, obs: pd.DataFrame, check: bool = True) -> list[tuple]:
        """``(arrival, receiver_x, receiver_y, vertical)`` of each row of ``obs``.

        ``vertical`` is tag depth minus receiver depth (m), shape (N,) (see
        :func:`vertical_parts`).

        ``check=False`` skips :func:`check_arrival_observations` for tables already
        checked as a whole (the filter checks its input once, up front).
        """
        if check:
            check_arrival_observations(obs)
        arrival = obs["time"].to_numpy(dtype=float).tolist()
        rx = obs["receiver_x"].to_numpy(dtype=float).tolist()
        ry = obs["receiver_y"].to_numpy(dtype=float).tolist()
        tag_depth, offset = vertical_parts(particles, obs)
        vertical = [tag_depth + d for d in offset.tolist()]
        return list(zip(arrival, rx, ry, vertical, strict=True))

    def match(self, particles, obs: pd.DataFrame, time: float | None = None):
        """Each particle's residual and matched ping for every observation.

        Parameters
        ----------
        particles
            Particles with the fields listed in the class notes, shape (N,) each.
        obs : pandas.DataFrame
            M detections (see class notes).
        time : float, optional
            Filter time at which the particles are (s); the default is each detection's
            own arrival time (no motion between arrival and filter time).

        Returns
        -------
        residual : numpy.ndarray, shape (N, M)
            Arrival-time residuals (s), see :func:`wrap_to_ping`.
        ping : numpy.ndarray, shape (N, M)
            Whole periods from the particle's ``emission_time`` to the matched ping.
        """
        rows = self.rows(particles, obs)
        n = np.shape(particles.x)[0]
        residual = np.empty((n, len(rows)))
        ping = np.empty((n, len(rows)))
        for j, row in enumerate(rows):
            residual[:, j], ping[:, j], _ = self.match_one(particles, *row, time=time)
        return residual, ping

    def residuals(self, particles, obs: pd.DataFrame, time: float | None = None) -> np.ndarray:
        """Arrival-time residuals (s), shape (N, M); see :meth:`match`."""
        return self.match(particles, obs, time)[0]

    def loglik(self, particles, obs: pd.DataFrame, time: float | None = None) -> np.ndarray:
        """Sum over detections of the log density of each particle's residual, shape (N,)."""
        if len(obs) == 0:
            return np.zeros(np.shape(particles.x)[0])
        residual = self.residuals(particles, obs, time)
        total = np.zeros(residual.shape[0])
        for j in range(residual.shape[1]):
            total += self.likelihood.log_densities(residual[:, j], particles.period)[0]
        return total
