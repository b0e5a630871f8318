"""The ping measurement: every ping scored on the time differences of its arrivals, with its
emission time integrated out, for tags with a random burst interval.

A ping emitted at an unknown time ``T`` from the tag's position ``x`` arrives at receiver
``i`` at ``t_i = T + d_i(x)/c + e_i``. With the residual ``r_i = t_i − d_i(x)/c`` every
receiver says ``r_i = T + e_i``, so the ping's likelihood of a particle is

    ℓ(x) = ∫ Π_i p(r_i − T) dT

with a flat prior on ``T`` (density 1 per second: a random burst interval of 20–40 s is flat
at the milliseconds where the integrand lives, and the prior's constant is the same for all
particles of a ping). Only the spread of the residuals matters, not their level: the time
differences between receivers (TDOA) inform the position, and no emission clock is carried.
A ping heard by one receiver is uninformative (``ℓ`` is the same for every particle).

Residual density (:func:`ping_loglik`): a Gaussian core of sd ``σ`` (direct arrivals) mixed
with a broad outlier (multipath, a mistimed detection) of weight ``ε``, uniform over
``|e| ≤ L``:

    p(e) = (1 − ε) N(e; 0, σ²) + ε / (2L) · 1{|e| ≤ L}.

Without outliers (``ε = 0``) the integral is closed form, with ``n`` receivers, ``r̄`` their
mean residual and ``S = Σ (r_i − r̄)²``::

    log ℓ = −(n − 1)/2 · log(2πσ²) − ½ log n − S / (2σ²)

(the ``−½ log n`` and the ``n − 1`` are the same for every particle of a ping: harmless to
the filter, but part of the exact value). With outliers it is not closed form (the product
of mixtures is a sum of ``2^n`` Gaussian integrals), and it is computed exactly to double
precision by a cheap 1-D quadrature (:func:`ping_integral`): with ``β = ε/(2L)`` the
integrand is ``β^n Π_i (1 + a_i(T)/β)`` on ``[max r − L, min r + L]`` (``a_i`` the core
term); residuals more than ``2Kσ`` apart (``K`` = :data:`CLUSTER_SIGMAS`) never share a
``T`` where both cores count (``a/β < 1e-17`` beyond ``Kσ``), so the integral is the
interval's length (every arrival an outlier) plus, for each cluster of close residuals, the
integral of ``Π_cluster(1 + a_i/β) − 1`` over the cluster's ``±Kσ`` span (a lone residual:
``(1 − ε)/β`` exactly). That integrand is a sum of Gaussians in ``T`` of sd at least
``σ/√m`` (``m`` the cluster's size) that vanish at the span's ends, so the trapezoidal rule
with step ``σ/(2√m)`` is exact to ~1e-12 relative (tested against ``scipy.integrate.quad``).
The support ``L`` is taken larger than any particle's residual spread (the grouping window
plus the array's travel span), so it never cuts a ping.

The particles are where the tag is at the filter's correction time (the ping's first
arrival, on the 1 s grid); each range is taken from where the particle was at emission
(:func:`hmmtrack.tracking.measurement.arrival_time.emission_distance`, its velocity).

The core sd ``σ`` is a setting, or with :data:`FROM_PINGS` the robust sd of the pings' own
least-squares fixes (:func:`arrival_sigma`,
:func:`hmmtrack.tracking.measurement.pings.arrival_spread`): a property of the data (0.2 ms
on the simulated array, 0.62 ms on YAPS's ssu1), reported in the run's summary.

:class:`PingTDOA` is the ``"ping"`` measurement of
:data:`hmmtrack.tracking.measurement.MEASUREMENTS` (detections grouped into pings by
:mod:`hmmtrack.tracking.measurement.pings`); its :class:`PingTrace` collector reports each
ping's estimated emission time and position. Corrections are tempered
(:class:`hmmtrack.tracking.tempering.Tempered`): a ping heard by many receivers places the
tag to a metre.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.sync.pings import largest_travel_time
from hmmtrack.tracking.acquisition import Acquisition
from hmmtrack.tracking.compiled.chunks import in_chunks, next_chunk
from hmmtrack.tracking.measurement.arrival_time import emission_distance, vertical_parts
from hmmtrack.tracking.measurement.base import Score, no_events
from hmmtrack.tracking.measurement.clocked import (
    SEARCH_RADIUS,
    ClockedArrivalTime,
    receiver_tracks,
    search_box,
    search_radius_setting,
)
from hmmtrack.tracking.measurement.pings import (
    PING_TOLERANCE,
    SPREAD_RECEIVERS,
    arrival_spread,
    ping_observations,
)
from hmmtrack.tracking.measurement.ranging import SOUND_SPEED
from hmmtrack.tracking.settings import Settings, fraction, positive, setting
from hmmtrack.tracking.tempering import Tempered

__all__ = [
    "CLUSTER_SIGMAS",
    "STEPS_PER_SD",
    "PING_TRACE_COLUMNS",
    "ARRIVAL_SIGMA",
    "FROM_PINGS",
    "OUTLIER_FRACTION",
    "FIX_RECEIVERS",
    "MISSED_PING_SLACK",
    "PING_MOTION",
    "PING_SMOOTHING_LAG",
    "PING_TEMPERING_ESS",
    "PingSettings",
    "PingState",
    "PingTDOA",
    "PingTrace",
    "cluster_excess",
    "gaussian_ping_loglik",
    "arrival_sigma",
    "arrival_sigma_setting",
    "ping_integral",
    "per_ping_table",
    "ping_loglik",
    "ping_residuals",
    "split_pings",
]

#: residuals farther apart than twice this many core sds never count as direct arrivals
#: at one emission time (the core term over the outlier's is below 1e-17 there)
CLUSTER_SIGMAS = 10.0
#: trapezoid steps per core sd of a cluster's product bump (``σ/√m``)
STEPS_PER_SD = 2.0
#: columns of the per-ping table (:class:`PingTrace`)
PING_TRACE_COLUMNS = (
    "ping", "time", "emission_time", "x", "y", "x_sd", "y_sd", "n_receivers", "receivers",
)  # fmt: skip
#: default sd (s) of a direct arrival's residual: 2 ms, chosen on YAPS's ssu1, kept over the
#: pings' own sd (:data:`FROM_PINGS`, 0.62 ms there), which misses YAPS's 3.0 m median
#: (reports/decisions.md, "Ping measurement", "Defaults of the ping measurement", "The
#: arrival sd from the pings")
ARRIVAL_SIGMA = 2e-3
#: the ``arrival_sigma`` that has it estimated from the pings before filtering
#: (:func:`~hmmtrack.tracking.measurement.pings.arrival_spread`)
FROM_PINGS = "pings"
#: default share of outliers: multipath and mistimed arrivals must be allowed for
OUTLIER_FRACTION = 0.05
#: tempering of a ping's correction: a ping heard by many receivers places the tag to a
#: metre, and the tempering's moves keep the smoother's ancestors distinct through it
PING_TEMPERING_ESS = 0.6
#: the motion a ping run takes unless told: a random walk of the speed scale of a towed or
#: swimming tag over a 20-40 s interval (the velocity model overshoots the turns)
PING_MOTION = {"name": "baseline", "sigma_position": 2.5}
#: smoothing lag (s) of a ping run unless told: random-interval array data is processed
#: offline (as YAPS does), and the lag spans two to three pings
PING_SMOOTHING_LAG = 60
#: receivers that must hear a ping for it to fix the tag's position (two time differences)
FIX_RECEIVERS = 3
#: the acquisition of a ping run (:class:`hmmtrack.tracking.acquisition.Acquisition`): from
#: the first fixes (pings heard by :data:`FIX_RECEIVERS`, :meth:`PingTDOA.informative`)
#: within five minutes of the first, three of them so that one multipath arrival does not
#: place the start; on a grid of 256 x 256 (9 m cells over the moorings' 2.4 km box): at 64 x
#: 64 (37 m) too few particles fall within the metres of a fix for the tempered correction
#: to find it, and a still tag with exact arrivals was lost (reports/decisions.md, "Finding
#: a random-interval tag on three moorings")
PING_ACQUISITION = Acquisition(corrections=3, window=300.0, cells=256)
#: slack (s) beyond the burst interval's maximum before two fixes are taken to have a missed
#: ping between them: the corrections' rounding to the 1 s grid and the travel times
MISSED_PING_SLACK = 5.0
_LOG_2PI = math.log(2.0 * math.pi)
_NO_ROWS = pd.DataFrame()


@njit(cache=True)
def gaussian_ping_loglik(residual, sigma):
    """Closed-form ``log ∫ Π N(r_i; T, σ²) dT`` (flat prior on ``T``) and the mean of ``T``.

    Parameters
    ----------
    residual : (n,) float array
        Arrival minus travel time of each receiver (s), n ≥ 1.
    sigma : float
        Residual sd (s).
    """
    n = residual.size
    mean = 0.0
    for value in residual:
        mean += value
    mean /= n
    spread = 0.0
    for value in residual:
        spread += (value - mean) ** 2
    log_l = -0.5 * (n - 1) * (_LOG_2PI + 2.0 * math.log(sigma)) - 0.5 * math.log(n)
    return log_l - 0.5 * spread / (sigma * sigma), mean


@njit(cache=True)
def _log_add(a, b):
    if a == -math.inf:
        return b
    if b == -math.inf:
        return a
    top = max(a, b)
    return top + math.log(math.exp(a - top) + math.exp(b - top))


@njit(cache=True)
def cluster_excess(s, a, h, steps, sigma, log_peak):
    """``e^(−m·c) (Π_i (1 + q_i(T_k)) − 1)`` on the nodes ``T_k = a + k·h`` (k = 0..steps),
    with ``q_i = exp(log_peak − (s_i − T)²/(2σ²))`` over the ``m`` residuals ``s``: a
    cluster's excess over every arrival being an outlier, scaled.

    Each ``q_i`` is stepped along the grid by two multiplications (a Gaussian's ratio
    between neighbouring nodes is itself geometric), started by ``exp`` where it first
    exceeds ``e^-40`` (below that ``1 + q_i`` is 1 in double precision); the scaling by
    ``e^-c`` (``c ≥ log(1 + q)``) keeps the product from overflowing for any number of
    receivers.

    Returns
    -------
    excess : (steps + 1,) float array
        The scaled excess at each node.
    c : float
        The scale's exponent per factor (``c ≥ log 2``).
    """
    m = s.size
    delta = h / sigma
    c = max(log_peak, 0.0) + math.log(2.0)
    scale = math.exp(-c)
    reach = math.sqrt(2.0 * (max(log_peak, 0.0) + 40.0))  # |z| beyond: 1 + q == 1
    product = np.ones(steps + 1)
    active = np.zeros(steps + 1, dtype=np.int64)
    ratio_step = math.exp(-delta * delta)
    for i in range(m):
        z0 = (s[i] - a) / sigma  # z at node k is z0 − k·delta
        k_lo = max(0, int(math.ceil((z0 - reach) / delta)))
        k_hi = min(steps, int(math.floor((z0 + reach) / delta)))
        if k_hi < k_lo:
            continue
        z = z0 - k_lo * delta
        q = math.exp(log_peak - 0.5 * z * z)
        ratio = math.exp(z * delta - 0.5 * delta * delta)
        for k in range(k_lo, k_hi + 1):
            product[k] *= (1.0 + q) * scale
            active[k] += 1
            q *= ratio
            ratio *= ratio_step
    powers = np.empty(m + 1)  # e^(-c·j)
    powers[0] = 1.0
    for j in range(m):
        powers[j + 1] = powers[j] * scale
    return product * powers[m - active] - powers[m], c


@njit(cache=True)
def _cluster_integral(s, a, b, sigma, log_peak):
    """``log ∫_a^b (Π_i (1 + q_i(T)) − 1) dT`` and the mean of ``T`` under it, where
    ``q_i = exp(log_peak − (s_i − T)²/(2σ²))``: one cluster's excess over every arrival
    being an outlier (:func:`ping_integral`).

    Trapezoidal rule with :data:`STEPS_PER_SD` steps per ``σ/√m`` over
    :func:`cluster_excess`.
    """
    m = s.size
    steps = int(math.ceil((b - a) / (sigma / (STEPS_PER_SD * math.sqrt(m))))) + 1
    h = (b - a) / steps
    excess, c = cluster_excess(s, a, h, steps, sigma, log_peak)
    total = 0.0
    weighted = 0.0
    for k in range(steps + 1):
        value = excess[k]
        if k == 0 or k == steps:
            value *= 0.5
        total += value
        weighted += value * (a + k * h)
    if not total > 0.0:
        return -math.inf, 0.5 * (a + b)
    return m * c + math.log(total * h), weighted / total


@njit(cache=True)
def ping_integral(residual, sigma, outlier_fraction, half_width):
    """``log ∫ Π_i p(r_i − T) dT`` of the core-plus-outlier density, and the mean of ``T``.

    See the module docstring for the method (clusters of residuals, trapezoid over each).

    Parameters
    ----------
    residual : (n,) float array
        Arrival minus travel time of each receiver (s), n ≥ 1 (not modified).
    sigma : float
        Core sd (s).
    outlier_fraction : float
        ``ε`` in [0, 1); 0 gives :func:`gaussian_ping_loglik`.
    half_width : float
        ``L`` (s): the outlier density is ``ε/(2L)`` for ``|e| ≤ L``.

    Returns
    -------
    log_l : float
        Log of the integral (log s^(1−n)).
    mean : float
        Posterior mean of ``T`` (s).
    """
    if outlier_fraction == 0.0:
        return gaussian_ping_loglik(residual, sigma)
    n = residual.size
    origin = residual.min()
    s = np.sort(residual) - origin  # (relative to the smallest: epoch seconds lose digits)
    beta = outlier_fraction / (2.0 * half_width)
    log_peak = math.log((1.0 - outlier_fraction) / (sigma * math.sqrt(2.0 * math.pi)) / beta)
    lo = s[n - 1] - half_width
    hi = s[0] + half_width
    width = max(hi - lo, 0.0)
    log_width = math.log(width) if width > 0.0 else -math.inf
    reach = CLUSTER_SIGMAS * sigma
    first = 0
    # each cluster adds J = ∫(Π(1 + a_i/β) − 1) dT and ∫T(...) dT, summed as log J and J·T̄
    terms_log = np.empty(n)
    terms_mean = np.empty(n)
    n_terms = 0
    for last in range(n):
        if last < n - 1 and s[last + 1] - s[last] <= 2.0 * reach:
            continue
        m = last - first + 1
        a = max(s[first] - reach, lo)
        b = min(s[last] + reach, hi)
        if m == 1 and a == s[first] - reach and b == s[last] + reach:
            terms_log[n_terms] = log_peak + math.log(sigma * math.sqrt(2.0 * math.pi))
            terms_mean[n_terms] = s[first]
            n_terms += 1
        elif b > a:
            terms_log[n_terms], terms_mean[n_terms] = _cluster_integral(
                s[first : last + 1], a, b, sigma, log_peak
            )
            n_terms += 1
        first = last + 1
    log_total = log_width
    for j in range(n_terms):
        log_total = _log_add(log_total, terms_log[j])
    mean = math.exp(log_width - log_total) * 0.5 * (lo + hi)  # every arrival an outlier
    for j in range(n_terms):
        mean += math.exp(terms_log[j] - log_total) * terms_mean[j]
    return n * math.log(beta) + log_total, origin + mean


@njit(cache=True, inline="always")
def ping_residuals(
    p, x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
    residual,
):  # fmt: skip
    """Into ``residual`` (n,): each receiver's arrival time minus particle ``p``'s travel
    time to it (s), the ping's emission time if the particle were the tag (arguments as
    :func:`ping_loglik`, ``slowness`` = 1 / sound speed)."""
    for j in range(arrival.size):
        d = emission_distance(
            x[p], y[p], vx[p], vy[p], depth[p] + row_offset[j], time - arrival[j],
            receiver_x[j], receiver_y[j], slowness,
        )  # fmt: skip
        residual[j] = arrival[j] - d * slowness


@njit(cache=True, nogil=True)
def _ping_kernel(
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness, sigma,
    outlier_fraction, half_width, emission, counter, loglik,
):  # fmt: skip
    """:func:`ping_integral` for every particle of each chunk not yet claimed
    (:func:`~hmmtrack.tracking.compiled.chunks.next_chunk`)."""
    residual = np.empty(arrival.size)
    chunk, lo, hi = next_chunk(counter, x.size)
    while chunk >= 0:
        for p in range(lo, hi):
            ping_residuals(
                p, x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time,
                slowness, residual,
            )  # fmt: skip
            loglik[p], emission[p] = ping_integral(residual, sigma, outlier_fraction, half_width)
        chunk, lo, hi = next_chunk(counter, x.size)


@njit(cache=True, nogil=True, parallel=True)
def _ping_parallel(
    threads, x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
    sigma, outlier_fraction, half_width, emission, counter, loglik,
):  # fmt: skip
    """:func:`_ping_kernel` on ``threads`` threads."""
    for _ in numba.prange(threads):
        _ping_kernel(
            x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
            sigma, outlier_fraction, half_width, emission, counter, loglik,
        )  # fmt: skip


def ping_loglik(
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, sound_speed,
    sigma, outlier_fraction, half_width, loglik, emission, threads=None,
):  # fmt: skip
    """:func:`ping_integral` of one ping for every particle, into ``loglik`` and
    ``emission`` (N,): its log-likelihood and the posterior mean emission time (s).

    The particles are scored in chunks on ``threads`` threads (default: numba's thread
    count of the calling thread, one in the worker processes of
    :mod:`hmmtrack.experiments.executors`); each particle's result is computed alone, so it
    does not depend on the number of threads.

    Parameters
    ----------
    x, y, vx, vy, depth : (N,) float arrays
        Particle positions (m) at ``time``, velocities (m/s) and depths (m).
    arrival, receiver_x, receiver_y, row_offset : (n,) float arrays
        The ping's arrival times (s), receiver positions (m) and vertical offsets (m,
        :func:`hmmtrack.tracking.measurement.arrival_time.vertical_parts`).
    time : float
        Filter time of the particles (s).
    threads : int, optional
    """
    args = (
        x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, float(time),
        1.0 / sound_speed, float(sigma), float(outlier_fraction), float(half_width), emission,
    )  # fmt: skip
    in_chunks(_ping_kernel, _ping_parallel, np.shape(x)[0], threads, args, loglik)


def split_pings(rows: np.ndarray, offset_column: int):
    """Per ping of ``rows`` (:meth:`PingTDOA.as_matrix`; column 5 the ping number), in
    order: its rows and its contiguous (arrival, receiver x, receiver y, vertical offset)
    columns, as the compiled ping kernels take them."""
    for ping in np.unique(rows[:, 5]):
        part = rows[rows[:, 5] == ping]
        yield part, tuple(np.ascontiguousarray(part[:, k]) for k in (0, 1, 2, offset_column))


def arrival_sigma(setting: float | str, observations: pd.DataFrame, sound_speed: float) -> float:
    """The arrival sd (s) a run uses: ``setting``, or with :data:`FROM_PINGS` the robust sd
    of the pings' own fixes (:func:`~hmmtrack.tracking.measurement.pings.arrival_spread`),
    :data:`ARRIVAL_SIGMA` when no ping was heard by enough receivers to show one. The
    value chosen and how are recorded in ``observations.attrs["arrival_sigma"]`` (s) and
    ``["arrival_sigma_source"]`` (what a run's summary reports)."""
    if setting != FROM_PINGS:
        chosen, source = float(setting), "as configured"
    else:
        spread = arrival_spread(observations, sound_speed)
        if np.isfinite(spread.sigma):
            chosen = spread.sigma
            source = (
                f"estimated from {spread.pings} pings heard by {SPREAD_RECEIVERS} or more "
                f"receivers, {100 * spread.outlier_fraction:.1f} % of their arrivals outliers"
            )
        else:
            chosen = ARRIVAL_SIGMA
            source = f"no ping heard by {SPREAD_RECEIVERS} or more receivers: the default"
    observations.attrs.update(arrival_sigma=chosen, arrival_sigma_source=source)
    return chosen


def _burst_interval(name: str, value) -> tuple[float, float]:
    low, high = (positive(f"{name} {end}", v) for end, v in zip(("MIN", "MAX"), value, strict=True))
    if not low <= high:
        raise ValueError(f"{name} must be MIN MAX with MIN <= MAX (s), got {low:g} {high:g}")
    return low, high


def _arrival_sigma(name: str, value) -> float | str:
    return value if value == FROM_PINGS else positive(name, value)


def _parse_arrival_sigma(text: str) -> float | str:
    return text if text == FROM_PINGS else float(text)


def arrival_sigma_setting(default: float | str):
    """The ``arrival_sigma`` key of a ping measurement's section (s, or :data:`FROM_PINGS`:
    estimated from the pings), with its default."""
    return setting(
        default,
        help=(
            f"standard deviation of a direct arrival's residual (s), or '{FROM_PINGS}': "
            f"estimated from fixes of the pings heard by {SPREAD_RECEIVERS} or more receivers"
        ),
        check=_arrival_sigma,
        parse=_parse_arrival_sigma,
        metavar="SECONDS",
    )


@dataclass(frozen=True)
class PingSettings(Settings):
    """The ``measurement`` section of the ``"ping"`` measurement.

    Parameters
    ----------
    burst_interval : (float, float) or None
        The tag's random interval between emissions, ``(MIN, MAX)`` s; its minimum bounds
        the grouping window (:func:`hmmtrack.tracking.measurement.pings.ping_window`).
        ``None``: unknown, pings grouped on the array's travel span only.
    sound_speed : float or None
        Speed of sound (m/s); ``None``: the one the clock file's fit estimated when the
        detections were synchronised (``attrs["sound_speed"]``), else
        :data:`~hmmtrack.tracking.measurement.ranging.SOUND_SPEED`.
    arrival_sigma : float or str
        Sd (s) of a direct arrival's residual: receiver clocks' error after
        synchronisation, timing jitter and the tag's motion within the filter's step;
        :data:`FROM_PINGS`: estimated from the pings
        (:func:`~hmmtrack.tracking.measurement.pings.arrival_spread`).
    outlier_fraction : float
        Share ``ε`` of arrivals that are outliers (multipath, mistimed).
    ping_tolerance : float
        Clock error allowed for when grouping detections into pings (s).
    search_radius : float
        Without given bounds, the search box is the receivers' positions at the start
        widened by this many metres.
    """

    name: ClassVar[str] = "ping"

    burst_interval: tuple[float, float] | None = setting(
        None,
        help="random interval between the tag's emissions, MIN MAX (s), e.g. 20 40",
        check=_burst_interval,
        parse=float,
        metavar=("MIN", "MAX"),
        nargs=2,
        data=True,
        default_text="unknown",
    )
    sound_speed: float | None = setting(
        None,
        help="speed of sound (m/s)",
        check=positive,
        parse=float,
        metavar="M_PER_S",
        default_text=f"the clock file's, else {SOUND_SPEED:g}",
    )
    arrival_sigma: float | str = arrival_sigma_setting(ARRIVAL_SIGMA)
    outlier_fraction: float = setting(
        OUTLIER_FRACTION,
        help="share of arrivals that are outliers (multipath, mistimed)",
        check=fraction,
        parse=float,
        metavar="FRACTION",
    )
    ping_tolerance: float = setting(
        PING_TOLERANCE,
        help="clock error allowed for when grouping detections into pings (s)",
        check=positive,
        parse=float,
        metavar="SECONDS",
    )
    search_radius: float = search_radius_setting()

    def validate(self) -> None:
        if not self.outlier_fraction < 1.0:
            raise ValueError(f"outlier_fraction must be below 1, got {self.outlier_fraction}")

    def to_dict(self) -> dict:
        """As :meth:`Settings.to_dict`, the burst interval as a list."""
        out = super().to_dict()
        if self.burst_interval is not None:
            out["burst_interval"] = list(self.burst_interval)
        return out


@dataclass
class PingState:
    """The mutable state of one run of :class:`PingTDOA`: each particle's posterior mean
    emission time (s, (N,)) of the latest ping, committed with its weights."""

    emission: np.ndarray | None = None


@dataclass(frozen=True)
class PingTDOA:
    """Ping measurement: each ping's arrivals scored jointly, the emission time integrated
    out (module docstring).

    Parameters
    ----------
    sound_speed : float
        m/s.
    sigma : float
        Core sd of an arrival's residual (s).
    outlier_fraction : float
        ``ε`` of the residual density.
    half_width : float
        ``L`` (s), the outlier's support: the grouping window plus the array's travel span.
    search_radius : float
        Without bounds, the search box is the receivers' positions widened by this (m).
    max_interval : float or None
        Longest time between two emissions (s), the burst interval's maximum; ``None``:
        unknown (the smoother bridges no gap, :meth:`bridge`).
    """

    sound_speed: float
    sigma: float = ARRIVAL_SIGMA
    outlier_fraction: float = OUTLIER_FRACTION
    half_width: float = 1.0
    search_radius: float = SEARCH_RADIUS
    max_interval: float | None = None
    name: ClassVar[str] = "ping"
    settings: ClassVar[type] = PingSettings
    columns: ClassVar[tuple[str, ...]] = ("arrival", "ping", "receiver_x", "receiver_y")
    fields: ClassVar[tuple[str, ...]] = ()
    default_correction: ClassVar[Tempered] = Tempered(PING_TEMPERING_ESS)
    default_motion: ClassVar[dict] = PING_MOTION
    default_smoothing_lag: ClassVar[int] = PING_SMOOTHING_LAG
    default_acquisition: ClassVar[Acquisition] = PING_ACQUISITION
    #: smoothed by backward simulation under a random walk
    #: (:class:`hmmtrack.tracking.smoothing.BackwardSmoother`): a sharp ping leaves the
    #: steps before it few traced ancestors
    backward: ClassVar[bool] = True

    @classmethod
    def observations(cls, detections: pd.DataFrame, receivers, settings) -> pd.DataFrame:
        """:func:`hmmtrack.tracking.measurement.pings.ping_observations` with the burst
        interval's minimum and the grouping tolerance of ``settings``."""
        interval = settings.burst_interval
        obs = ping_observations(
            detections,
            receiver_tracks(receivers),
            None if interval is None else interval[0],
            settings.ping_tolerance,
        )
        obs.attrs["sound_speed"] = detections.attrs.get("sound_speed")
        return obs

    @classmethod
    def from_settings(cls, settings: PingSettings, observations: pd.DataFrame, receivers):
        """The measurement of ``settings``; the outlier's support is the observations'
        grouping window plus the receivers' largest travel time (any particle's residual
        spread fits in it); the sound speed is the settings', else the clock file's (the
        observations' ``attrs``), else the default; the arrival sd is the settings', or
        with :data:`FROM_PINGS` the pings' own (:func:`arrival_sigma`)."""
        positions = observations[["receiver_x", "receiver_y"]].to_numpy()
        window = observations.attrs.get("window", settings.ping_tolerance)
        sound_speed = settings.sound_speed or observations.attrs.get("sound_speed")
        sound_speed = SOUND_SPEED if sound_speed is None else float(sound_speed)
        return cls(
            sound_speed,
            arrival_sigma(settings.arrival_sigma, observations, sound_speed),
            settings.outlier_fraction,
            window + largest_travel_time(np.unique(positions.round(), axis=0)),
            settings.search_radius,
            None if settings.burst_interval is None else settings.burst_interval[1],
        )

    def bridge(self, observations: pd.DataFrame) -> tuple[np.ndarray, float] | None:
        """The smoother's bridge (:class:`hmmtrack.tracking.smoothing.Smoothed`): the first
        arrivals (s, sorted) of the pings heard by :data:`FIX_RECEIVERS` or more receivers,
        and the gap between two of them that a missed ping leaves (the burst interval's
        maximum plus :data:`MISSED_PING_SLACK`); ``None`` when the maximum is unknown."""
        if self.max_interval is None:
            return None
        fixes = observations.loc[observations["heard"] >= FIX_RECEIVERS, "time"]
        return np.unique(fixes.to_numpy(dtype=float)), self.max_interval + MISSED_PING_SLACK

    def start_box(self, observations, receivers, settings=None, bounds=None, start=None):
        """``bounds``, else the receivers' positions at ``start`` widened by
        :attr:`search_radius` (as the arrival-time measurement)."""
        return search_box(observations, receivers, self.search_radius, bounds, start)

    def split(self, observations: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Every detection is scored (a ping's rows share its first arrival as ``time``)."""
        return observations, no_events()

    def collectors(self) -> tuple:
        """A fresh :class:`PingTrace`."""
        return (PingTrace(),)

    @staticmethod
    def informative(rows: np.ndarray) -> bool:
        """Whether ``rows`` (:meth:`as_matrix`) can fix the tag, so that an acquisition
        (:meth:`hmmtrack.tracking.acquisition.Acquisition.first`) starts from them: one of
        their pings heard by :data:`FIX_RECEIVERS` or more receivers. A ping heard by one
        receiver says nothing of the position, and one heard by two a hyperbola that the
        tag's motion until the next fix smears along."""
        _, heard = np.unique(rows[:, 5], return_counts=True)
        return bool(heard.max(initial=0) >= FIX_RECEIVERS)

    def on_grid(self, cell: float) -> PingTDOA:
        """This measurement as a grid of ``cell``-metre cells scores it
        (:func:`hmmtrack.tracking.acquisition.grid_loglik`): a ping's hyperbolae are a few
        metres wide (``σ`` times the sound speed), so a grid point a few metres off them
        would miss a cell that holds the tag. Each arrival's residual is widened by its
        spread over a cell -- a uniform point in a square of side ``cell`` projects on any
        direction with sd ``cell / √12``, so the travel time spreads by that over the sound
        speed -- and the core sd becomes ``√(σ² + (cell / (c √12))²)``."""
        spread = cell / (self.sound_speed * math.sqrt(12.0))
        return dataclasses.replace(self, sigma=math.hypot(self.sigma, spread))

    def start(self, particles, time: float, dt: float = 1.0) -> PingState:
        """A fresh run state (no particle fields)."""
        return PingState()

    @staticmethod
    def as_matrix(table: pd.DataFrame) -> np.ndarray:
        """Rows as an (M, 6) matrix: arrival (s), receiver x, y (m), vertical offsets without
        and with a particle depth field (m, as the arrival-time measurement's), ping index."""
        return np.column_stack(
            [ClockedArrivalTime.as_matrix(table.assign(time=table["arrival"])), table["ping"]]
        )

    def loglik(self, particles, obs, time: float | None = None) -> np.ndarray:
        """Sum over the pings of ``obs`` (table or :meth:`as_matrix` rows) of
        :func:`ping_loglik`, shape (N,)."""
        return self._score(particles, obs, time)[0]

    def _inputs(self, p, rows, time):
        """What the compiled ping kernels take, shared by every ping of ``rows``: the rows as
        a matrix (:meth:`as_matrix`), the number of particles, the scoring time (default:
        the first arrival), the particles' ``(x, y, vx, vy, depth)`` arrays and the rows'
        column of vertical offsets (with or without the particles' depths)."""
        if isinstance(rows, pd.DataFrame):
            rows = self.as_matrix(rows)
        n = p.n if hasattr(p, "n") else np.shape(p.x)[0]
        if time is None:
            time = float(rows[:, 0].min())
        speed = np.asarray(p.speed, dtype=float)
        motion = (
            np.ascontiguousarray(p.x, dtype=float),
            np.ascontiguousarray(p.y, dtype=float),
            speed * np.asarray(p.cos_heading),
            speed * np.asarray(p.sin_heading),
            vertical_parts(p, _NO_ROWS)[0],  # the particles' depths
        )
        offset_column = 4 if getattr(p, "depth", None) is not None else 3
        return rows, n, float(time), motion, offset_column

    def _score(self, p, rows, time):
        rows, n, time, motion, offset_column = self._inputs(p, rows, time)
        total = np.zeros(n)
        loglik = np.empty(n)
        emission = np.empty(n)
        for _, ping_rows in split_pings(rows, offset_column):
            ping_loglik(
                *motion, *ping_rows, time, self.sound_speed, self.sigma, self.outlier_fraction,
                self.half_width, loglik, emission,
            )  # fmt: skip
            total += loglik
        return total, emission

    def score(self, particles, rows: np.ndarray, time: float, state: PingState, weights):
        """The pings' log-likelihood; each particle's posterior mean emission time of the
        last ping is committed to the run state with the final weights."""
        latest = []

        def scored(particles, weights):
            loglik, emission = self._score(particles, rows, time)
            latest[:] = [emission]
            return loglik

        def commit(particles):
            state.emission = latest[0]

        return Score(scored(particles, weights), rescore=scored, commit=commit)


class PingTrace:
    """Per ping: the estimated emission time and position (table ``pings``,
    :data:`PING_TRACE_COLUMNS`).

    After each correction: the weighted mean of the particles' posterior mean emission
    times (``pf.measurement_state.emission``), the weighted mean position at the emission and
    its sds, the receivers that heard the ping (``;``-separated, as observed) and their
    number.

    The position is each particle's at its own emission time, taken back from the filter's
    step (the ping's first arrival rounded to the 1 s grid, up to half a second away) along
    its velocity, as the measurement scores it
    (:func:`hmmtrack.tracking.measurement.arrival_time.emission_distance`): the ping fixes
    that point, while the particles' position at the step also carries their velocity's
    spread over the lag (reports/decisions.md, "The filter per ping at the emission").
    """

    every_step = False

    def start(self, pf) -> None:
        self._rows: list[tuple] = []

    def corrected(self, pf) -> None:
        p = pf.particles
        weights = pf.weights()[0]
        emissions = pf.measurement_state.emission
        lag = pf.time - emissions
        speed = np.asarray(p.speed, dtype=float)
        at_x = p.x - speed * np.asarray(p.cos_heading) * lag
        at_y = p.y - speed * np.asarray(p.sin_heading) * lag
        x, y = float(weights @ at_x), float(weights @ at_y)
        x_sd = math.sqrt(max(float(weights @ (at_x - x) ** 2), 0.0))
        y_sd = math.sqrt(max(float(weights @ (at_y - y) ** 2), 0.0))
        emission = float(weights @ emissions)
        self._rows.append((pf.time, emission, x, y, x_sd, y_sd))

    def settled(self, pf) -> None:
        """Nothing to record."""

    def resampled(self, pf, ancestors) -> None:
        """Nothing to record."""

    def result(self) -> dict[str, pd.DataFrame]:
        return {"pings": pd.DataFrame(self._rows, columns=list(PING_TRACE_COLUMNS[1:7]))}


def per_ping_table(
    pings: pd.DataFrame, observations: pd.DataFrame, smoothed: pd.DataFrame | None = None
) -> pd.DataFrame:
    """One row per ping heard: the :class:`PingTrace` of its correction, with the receivers.

    Parameters
    ----------
    pings : pandas.DataFrame
        A run's ``pings`` table (:class:`PingTrace`; one row per correction).
    observations : pandas.DataFrame
        The run's observations (:func:`hmmtrack.tracking.measurement.pings.ping_observations`).
    smoothed : pandas.DataFrame, optional
        The run's smoothed estimates (one per second): their row at each ping's correction
        time as ``smoothed_x``, ``smoothed_y`` (m), the step of ``x`` and ``y``: the
        smoothed position at the emission, up to half a step plus the travel time away.
        The track interpolated at the emission time is worse: it mixes in the row of a
        neighbouring step, and under the random walk the smoothed rows before a sharp ping
        rest on the few particles its tempered resamplings left (reports/decisions.md,
        "The ping runs against the bound").

    Returns
    -------
    pandas.DataFrame
        ``time`` (the estimated emission time, s) and :data:`PING_TRACE_COLUMNS` (``time``
        as ``correction_time``, s; ``emission_time`` s;
        ``x``, ``y`` and their sds m; ``n_receivers``; ``receivers`` ``;``-separated) and the
        smoothed columns; a correction that scored two pings describes both by its state.
    """
    heard = observations.groupby("ping", sort=True).agg(
        first=("time", "first"),
        n_receivers=("receiver", "size"),
        receivers=("receiver", lambda names: ";".join(names)),
    )
    heard = heard.reset_index().sort_values("first", kind="stable")
    table = pd.merge_asof(
        heard, pings.sort_values("time"), left_on="first", right_on="time", direction="nearest"
    )
    table = table[list(PING_TRACE_COLUMNS)].rename(columns={"time": "correction_time"})
    table.insert(0, "time", table["emission_time"])
    if smoothed is not None and len(smoothed):
        for axis in ("x", "y"):
            table[f"smoothed_{axis}"] = np.interp(
                table["correction_time"], smoothed["time"], smoothed[axis]
            )
    return table
