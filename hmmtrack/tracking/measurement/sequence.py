"""The ping measurement of a tag with a known pseudo-random burst-interval sequence (YAPS's
"pbi"): the sequence aligned to the pings, and every ping scored with its emission time
known up to the tag's clock offset and drift.

**Alignment** (:func:`align_sequence`). The tag waits ``sequence[(phase + k) % L]`` seconds
after its ``k``-th ping. Grouped into pings (:mod:`hmmtrack.tracking.measurement.pings`),
the first arrivals ``g_j`` are emissions plus a travel time of at most the grouping window,
and some pings are never heard. For every phase ``p`` and an anchor ping (one of the first
:data:`ANCHORS`, so that a spurious first group cannot spoil it), the pings are walked in
time order: each is given the number of sequence steps ``n`` whose scheduled time
``g_anchor + a + (1 + b)·c_p(n)`` (``c_p(n)`` the sum of ``n`` intervals from ``p``) is
nearest, and counts as matched when it is within the window and later than the previous
match; ``a`` and the tag's drift ``b`` (relative to the receivers' time base) are refitted
after every match by least squares with a ``N(0, DRIFT_SD²)`` prior on ``b`` (so that two
close pings cannot tilt the schedule), which follows a drifting tag over hours. The phase
with the most matches wins; its schedule gives each matched ping a ``scheduled`` time (the
alignment's estimate of its emission, off by about the travel time to the nearest
receiver). A wrong phase matches a ping only by chance (a window of a few tenths of a second
in intervals of tens of seconds), the right one nearly all; fewer than half the pings matched
is refused as "no alignment". The walk is vectorised over phases, a few milliseconds per ping.
A fixed-period tag (one interval) is walked ping to ping instead (:func:`_period_walk`): its
schedule wanders about any line by more than the window.

**Scoring** (:class:`PingSequence`, the ``"ping-sequence"`` measurement). The emission of a
matched ping is ``scheduled + u + j``: ``u`` the tag's offset from the aligned schedule, which
every particle carries as a Kalman filter conditioned on its path (a Rao-Blackwellised tag
clock), with its drift ``b``: between pings ``Δ`` scheduled seconds apart ``u ← u + b·Δ`` plus
random walks of ``u`` and ``b`` (:data:`PHASE_DENSITY`, :data:`DRIFT_DENSITY`), and ``j`` the
emission's own jitter (:data:`EMISSION_JITTER`, not carried over). Offset and drift are not
integrated out in closed form because the arrivals' residual density is a Gaussian core with
outliers, late ones priced by their delay and a small floor either way (the shape of
:class:`~hmmtrack.tracking.measurement.arrival_time.ArrivalLikelihood`): the ping's likelihood
given a particle's position and clock is

    ℓ(x) = ∫ N(T; û, P_uu + J²) Π_i p(r_i − T) dT,   r_i = t_i − d_i(x)/c − scheduled,

with the particle's predicted emission as prior. It is closed form without outliers; with
them, a sum of truncated Gaussians, one per assignment of the arrivals to the core, the late
tail and the floor, for one or two receivers, and for more the same density integrated by
pieces (closed form where no core counts, Gauss-Legendre where one does) to 1e-9 nats of
that sum at a cost that grows with the ping's clusters, not as ``3^n``
(:func:`sequence_ping_integral`, checked against the sum and a brute-force quadrature).
The clock is then updated by the posterior mean and variance of ``T`` (exact
without outliers; the moment-matched Gaussian with them). Before the first ping the
offset's prior is :data:`OFFSET_SD` (flat at the milliseconds of the arrivals: the first
ping sets each particle's offset from its position, as the arrival-time measurement's clock
starts), so the first ping weighs as in the random-interval model and every later one also by its
emission time: one receiver then places the tag on a range circle, two on a point pair.
Pings the alignment did not match are scored as random-interval pings
(:func:`~hmmtrack.tracking.measurement.tdoa.ping_loglik`), clock untouched.

**A fixed-period tag** (``period`` instead of ``burst_sequence``) is a sequence of one
interval: its pings grouped and scored as above, with the arrival-time measurement's clock
model instead of a crystal's (:func:`period_clock_noise`: a real tag's period wanders) and the
arrival sd widened while the cloud is wide (:func:`broadened_sigma`), so that a ping heard
by three receivers offers the tempered cloud a basin rather than a point. Given a detection
curve it also scores who heard each ping, as the arrival-time measurement does: ``log p`` of
the range of every receiver that heard it (:func:`heard_loglik`) and ``log(1 − p)`` of every
ping the particle's clock says a listening receiver missed
(:func:`~hmmtrack.tracking.measurement.clocked.silence_since`, the same code). Without it, a
ping heard by two receivers leaves the tag and its mirror across their line equally likely,
and a cloud can follow the mirror for minutes. Its arrival sd is its own
(:data:`PERIOD_ARRIVAL_SIGMA`), and it is the default for a fixed-period tag only where three
or more receivers hear its pings (:func:`fixed_period_measurement`): with two it was not
better than the arrival-time measurement.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.io import read_burst_sequence
from hmmtrack.tracking.compiled.chunks import in_chunks, next_chunk
from hmmtrack.tracking.measurement.arrival_time import emission_distance
from hmmtrack.tracking.measurement.base import Score
from hmmtrack.tracking.measurement.clocked import (
    TEMPERING_ESS,
    curve_to_dict,
    default_clock_model,
    detection_curve_setting,
    receiver_tracks,
    silence_since,
)
from hmmtrack.tracking.measurement.detection import LogisticDetection, SilenceModel, softplus
from hmmtrack.tracking.measurement.pings import ping_observations
from hmmtrack.tracking.measurement.tdoa import (
    PingSettings,
    PingTDOA,
    arrival_sigma_setting,
    gaussian_ping_loglik,
    ping_loglik,
    ping_residuals,
    split_pings,
)
from hmmtrack.tracking.settings import positive, setting
from hmmtrack.tracking.tempering import Tempered

__all__ = [
    "ANCHORS",
    "DRIFT_SD",
    "EMISSION_JITTER",
    "EXPANDED_RECEIVERS",
    "GROUPING_RECEIVERS",
    "GROUPING_SHARE",
    "INTEGRAL_TOLERANCE",
    "OFFSET_SD",
    "PERIOD_ARRIVAL_SIGMA",
    "PERIOD_BROADENING",
    "SEQUENCE_ARRIVAL_SIGMA",
    "SEQUENCE_FIELDS",
    "PingSequence",
    "PingSequenceSettings",
    "SequenceAlignment",
    "SequenceState",
    "align_sequence",
    "broadened_sigma",
    "fixed_period_measurement",
    "heard_loglik",
    "period_clock_noise",
    "sequence_observations",
    "sequence_ping_integral",
]

logger = logging.getLogger(__name__)

#: particle fields: the tag's offset from the aligned schedule (s), its drift, and their
#: covariance (s², s, 1)
SEQUENCE_FIELDS = (
    "sequence_offset",
    "sequence_drift",
    "sequence_var_offset",
    "sequence_cov",
    "sequence_var_drift",
)
#: the first pings tried as the alignment's anchor (a spurious first group cannot spoil it)
ANCHORS = 3
#: largest change of a fixed-period tag's schedule per period, relative to the period,
#: allowed between two matched pings (:func:`_period_walk`): the arrival-time clock model's
#: initial period sd (1e-3 of the period)
PERIOD_GAP_SD = 1e-3
#: share of the pings after the anchor the alignment must match
MIN_MATCHED = 0.5
#: prior sd (s) of the tag's offset from the aligned schedule before its first ping: the
#: schedule is fitted to first arrivals, later than the emissions by up to the travel span
OFFSET_SD = 1.0
#: prior sd of the tag's drift relative to the alignment's fit (a crystal's 50 ppm)
DRIFT_SD = 5e-5
#: sd (s) of an emission's own jitter, not carried to the next ping: real tags' 44-83 µs
#: (DESIGN.md, "What real data teaches") rounded up; it also bounds the quadrature's step
EMISSION_JITTER = 1e-4
#: share of pings at which a particle's clock counts as unknown (the offset's prior widened by
#: OFFSET_SD): a clock fitted where the particle was, far from the tag, would otherwise keep
#: it from every particle that moves close to the tag
CLOCK_RESET = 0.01
#: mean delay (s) of a late (multipath) arrival in the emission integral, and the share of the
#: outliers on a floor either way: ArrivalLikelihood's defaults (20 ms; 1e-3 of 0.05)
LATE_MEAN = 20e-3
FLOOR_SHARE = 0.02
#: relative error allowed to each part the emission integral drops (a core beyond its
#: reach, a piece or sub-pieces bounded below it): the integral is exact to ~1e-10
INTEGRAL_TOLERANCE = 1e-11
#: a ping heard by at most this many receivers has its emission integral expanded over the
#: 3^n assignments of its arrivals, by more computed by pieces: the cheaper of the two
#: (reports/decisions.md, "The grouped ping's outlier integral, cheap for many receivers")
EXPANDED_RECEIVERS = 2
#: widest sub-piece of the emission integral's quadrature, in the integrand's narrowest
#: scales, and the Gauss-Legendre rules by a sub-piece's width: (widest, nodes, weights) of
#: the fewest nodes whose error on any such stretch of a Gaussian of that sd is below 1e-13
#: of the Gaussian's mass
_GL_WIDEST = 7.0
_GL_RULES = tuple(
    (widest, *np.polynomial.legendre.leggauss(nodes))
    for widest, nodes in (
        (0.25, 4), (0.75, 6), (1.5, 8), (2.0, 10), (3.0, 12), (5.0, 16), (_GL_WIDEST, 20)
    )
)  # fmt: skip
#: random-walk densities of the offset (s²/s: 55 µs over 30 s) and of the drift (1/s: 3 ppm
#: over 1,000 s, a crystal following the water's temperature)
PHASE_DENSITY = 1e-10
DRIFT_DENSITY = 1e-14
_LOG_2PI = math.log(2.0 * math.pi)
#: share of the cloud's spread added to a fixed-period tag's arrival sd
#: (:func:`broadened_sigma`): 2 % turns a cloud spread over 700 m into a 10 ms (14 m) basin
#: (reasons in reports/decisions.md, "Fixed-period tags with ping grouping"; held-out
#: seeds in "Fixed-period grouping with the detection curve")
PERIOD_BROADENING = 0.02
#: arrival sd (s) of a known burst sequence: the 1 ms it was measured with (its clock puts
#: each emission to a millisecond; the random-interval ping's 2 ms is for its untimed pings)
SEQUENCE_ARRIVAL_SIGMA = 1e-3
#: arrival sd (s) of a fixed-period tag's grouped pings: at 1 ms a cloud left behind by a
#: sharp turn gets no pull back (held-out seeds, reports/decisions.md, "Fixed-period grouping
#: with the detection curve")
PERIOD_ARRIVAL_SIGMA = 2e-3
#: a fixed-period tag whose measurement is not named has its pings grouped
#: (:func:`fixed_period_measurement`) when at least GROUPING_SHARE of them are heard by
#: GROUPING_RECEIVERS or more receivers: with two, grouping was not better than the
#: arrival-time filter (reports/decisions.md, "Fixed-period grouping by default"); below a
#: quarter it pays in median but not in mean, at 8-13x the CPU ("The grouping threshold")
GROUPING_RECEIVERS = 3
GROUPING_SHARE = 0.25


# ---------------------------------------------------------------------------- alignment


@dataclass(frozen=True)
class SequenceAlignment:
    """The sequence's phase that best explains a tag's pings (:func:`align_sequence`).

    Attributes
    ----------
    phase : int
        Index in the sequence of the interval after the anchor ping.
    anchor : int
        Index of the anchor ping.
    steps : numpy.ndarray, shape (G,)
        Sequence steps from the anchor of each ping; -1: not matched.
    scheduled : numpy.ndarray, shape (G,)
        The aligned schedule's time of each ping (s; NaN: not matched).
    drift : float
        Fitted drift of the tag relative to the receivers' time base (dimensionless).
    matched : int
        Pings matched (the anchor included).
    runner_up : int
        Pings matched by the second-best phase (by chance).
    spread : float
        RMS residual (s) of the matched first arrivals about the schedule.
    """

    phase: int
    anchor: int
    steps: np.ndarray
    scheduled: np.ndarray
    drift: float
    matched: int
    runner_up: int
    spread: float


def _cumulative(sequence: np.ndarray, span: float) -> np.ndarray:
    """``C`` with ``C[p + n] − C[p]`` the sum of ``n`` intervals from phase ``p`` (s), long
    enough for every phase over ``span`` seconds."""
    cycles = int(np.ceil(span / sequence.min() / sequence.size)) + 2
    return np.concatenate([[0.0], np.cumsum(np.tile(sequence, cycles))])


def _walk(times: np.ndarray, cumulative: np.ndarray, n_phases: int, tolerance: float):
    """Match ``times`` (s from the anchor, ``times[0] = 0``) to every phase's schedule.

    Returns the steps of every ping per phase ``(L, G)`` (-1 unmatched) and the fitted
    intercept and drift per phase.
    """
    phases = np.arange(n_phases)
    base = cumulative[:n_phases]
    ridge = (tolerance / DRIFT_SD) ** 2  # the drift's prior, in units of a match's variance
    count, sc, scc, sy, scy = (np.zeros(n_phases) for _ in range(5))
    count[:] = 1.0  # the anchor: c = 0, y = 0
    a = np.zeros(n_phases)
    b = np.zeros(n_phases)
    last = np.zeros(n_phases, dtype=np.int64)
    steps = np.full((n_phases, times.size), -1, dtype=np.int64)
    steps[:, 0] = 0
    top = cumulative.size - 1
    for j in range(1, times.size):
        target = base + (times[j] - a) / (1.0 + b)
        idx = np.clip(np.searchsorted(cumulative, target), 1, top)
        idx -= (target - cumulative[idx - 1]) < (cumulative[idx] - target)
        c = cumulative[idx] - base
        residual = times[j] - c - (a + b * c)
        step = idx - phases
        ok = (np.abs(residual) <= tolerance) & (step > last)
        y = times[j] - c
        count += ok
        sc += ok * c
        scc += ok * c * c
        sy += ok * y
        scy += ok * c * y
        fitted_a, fitted_b = _ridge_line(count, sc, scc, sy, scy, ridge)
        b = np.where(ok, fitted_b, b)
        a = np.where(ok, fitted_a, a)
        last = np.where(ok, step, last)
        steps[ok, j] = step[ok]
    return steps, a, b


def _period_walk(times: np.ndarray, cumulative: np.ndarray, tolerance: float):
    """:func:`_walk` of a sequence of one interval (a fixed-period tag), ping to ping.

    A real tag's schedule wanders about any straight line by up to seconds an hour (its
    period walks, DESIGN.md), beyond a grouping window, so one line refitted to every match
    loses the pings. Here a ping is matched by its gap to the last matched ping: ``n``
    periods, the nearest whole number, matched when the gap is within ``tolerance`` plus
    :data:`PERIOD_GAP_SD` per period of ``n·P`` (the schedule moves by well under that per
    ping). A ping that fits the last match but one is matched too, so that one stray
    detection matched by chance cannot lose the rest. The line through the matches is the
    walk's (the drift's prior included, the same sums in the same order).
    """
    period = cumulative[1] - cumulative[0]
    steps = np.full((1, times.size), -1, dtype=np.int64)
    steps[0, 0] = 0
    recent = [0]  # the last two matches
    for j in range(1, times.size):
        for m in reversed(recent):
            gap = times[j] - times[m]
            n = round(gap / period)
            if n >= 1 and abs(gap - n * period) <= tolerance + PERIOD_GAP_SD * n * period:
                steps[0, j] = steps[0, m] + n
                recent = [recent[-1], j]
                break
    ridge = (tolerance / DRIFT_SD) ** 2
    count, sc, scc, sy, scy = 1.0, 0.0, 0.0, 0.0, 0.0  # the anchor: c = 0, y = 0
    for j in np.flatnonzero(steps[0] > 0):
        c = cumulative[steps[0, j]] - cumulative[0]
        y = times[j] - c
        count, sc, scc, sy, scy = count + 1.0, sc + c, scc + c * c, sy + y, scy + c * y
    a, b = _ridge_line(count, sc, scc, sy, scy, ridge)
    return steps, np.array([a]), np.array([b])


def _ridge_line(count, sc, scc, sy, scy, ridge):
    """Intercept and slope of the line ``y = a + b c`` through matched pings from their sums
    (count, Σc, Σc², Σy, Σcy; floats or arrays), the slope shrunk towards 0 by ``ridge``
    (the drift's prior, in units of a match's variance): the fit of :func:`_walk` and
    :func:`_period_walk`."""
    b = (count * scy - sc * sy) / (count * (scc + ridge) - sc * sc)
    return (sy - b * sc) / count, b


def align_sequence(
    first_arrivals, sequence, tolerance: float, source: str = "the burst sequence"
) -> SequenceAlignment:
    """The phase of ``sequence`` that best explains the pings' first arrivals.

    See the module docstring for the method.

    Parameters
    ----------
    first_arrivals : (G,) float array
        Each ping's first arrival (s), increasing.
    sequence : (L,) float array
        The tag's intervals (s), used in a cycle.
    tolerance : float
        Largest distance (s) of a first arrival from its scheduled time: the grouping window
        (the travel span and the clocks' error).
    source : str
        What the sequence is (its file), for the error message.

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_MATCHED` of the pings (or fewer than 3) matched by any phase:
        the message says how many the best phase matched.
    """
    times = np.asarray(first_arrivals, dtype=float)
    sequence = np.asarray(sequence, dtype=float)
    cumulative = _cumulative(sequence, float(times[-1] - times[0]) + sequence.max())
    best = None
    for anchor in range(min(ANCHORS, times.size)):
        shifted = times[anchor:] - times[anchor]
        if sequence.size == 1:
            steps, a, b = _period_walk(shifted, cumulative, tolerance)
        else:
            steps, a, b = _walk(shifted, cumulative, sequence.size, tolerance)
        matched = (steps >= 0).sum(axis=1)
        order = np.argsort(-matched, kind="stable")
        phase = int(order[0])
        runner_up = int(matched[order[1]]) if sequence.size > 1 else 0
        if best is None or matched[phase] > best[0]:
            best = (int(matched[phase]), anchor, phase, steps[phase], a[phase], b[phase], runner_up)
    matched, anchor, phase, steps, a, b, runner_up = best
    wanted = max(3, math.ceil(MIN_MATCHED * (times.size - anchor)))
    if matched < wanted:
        raise ValueError(
            f"no alignment of {source} ({sequence.size} intervals) explains the tag's "
            f"{times.size} pings: the best phase ({phase}) matched {matched} of them within "
            f"±{tolerance:.3g} s, {wanted} needed (is it this tag's sequence, in the order the "
            "tag uses it?)"
        )
    all_steps = np.full(times.size, -1, dtype=np.int64)
    all_steps[anchor:] = steps
    hit = all_steps >= 0
    c = cumulative[phase + all_steps[hit]] - cumulative[phase]
    scheduled = np.full(times.size, np.nan)
    scheduled[hit] = times[anchor] + a + (1.0 + b) * c
    spread = float(np.sqrt(np.mean((times[hit] - scheduled[hit]) ** 2)))
    return SequenceAlignment(
        phase, anchor, all_steps, scheduled, float(b), matched, runner_up, spread
    )


def sequence_observations(obs: pd.DataFrame, sequence, source: str) -> pd.DataFrame:
    """Ping observations with the aligned schedule of ``sequence``.

    Parameters
    ----------
    obs : pandas.DataFrame
        :func:`~hmmtrack.tracking.measurement.pings.ping_observations` (its ``window`` in
        ``attrs`` is the alignment's tolerance).
    sequence : (L,) float array
        The tag's intervals (s).
    source : str
        Where the sequence came from (for messages).

    Returns
    -------
    pandas.DataFrame
        ``obs`` with ``scheduled`` (the aligned emission time of the row's ping, s; its
        first arrival when not matched) and ``sequence_step`` (steps from the anchor ping,
        -1 not matched); ``attrs["alignment"]``: the :class:`SequenceAlignment`.
    """
    first = obs.groupby("ping", sort=True)["time"].first()
    alignment = align_sequence(first.to_numpy(), sequence, obs.attrs["window"], source)
    logger.info(
        "burst sequence aligned: phase %d, %d of %d pings matched (next best phase %d), "
        "drift %.1f ppm, first arrivals %.1f ms about the schedule",
        alignment.phase, alignment.matched, first.size, alignment.runner_up,
        1e6 * alignment.drift, 1e3 * alignment.spread,
    )  # fmt: skip
    ping = obs["ping"].to_numpy()
    scheduled = np.where(np.isnan(alignment.scheduled), first.to_numpy(), alignment.scheduled)
    out = obs.assign(scheduled=scheduled[ping], sequence_step=alignment.steps[ping])
    out.attrs.update(obs.attrs, alignment=alignment)
    return out


# ---------------------------------------------------------------------------- the integral


@njit(cache=True)
def _log_normal_tail(z):
    """``log P(Z > z)`` for a standard normal ``Z``, without underflow far in the tail."""
    if z < 20.0:
        return math.log(0.5 * math.erfc(z / math.sqrt(2.0)))
    # the Mills ratio's continued fraction 1/(z + 1/(z + 2/(z + ...))), converged at z ≥ 20
    fraction = z
    for k in range(40, 0, -1):
        fraction = z + k / fraction
    return -0.5 * z * z - 0.5 * _LOG_2PI - math.log(fraction)


@njit(cache=True)
def _log_normal_mass(alpha, beta):
    """``log P(alpha < Z < beta)`` for a standard normal ``Z`` (``alpha < beta``)."""
    if alpha > 0.0:
        upper = _log_normal_tail(alpha)
        return upper + math.log1p(-math.exp(_log_normal_tail(beta) - upper))
    if beta < 0.0:
        upper = _log_normal_tail(-beta)
        return upper + math.log1p(-math.exp(_log_normal_tail(-alpha) - upper))
    outside = math.exp(_log_normal_tail(beta)) + math.exp(_log_normal_tail(-alpha))
    return math.log1p(-outside)


@njit(cache=True)
def _truncated_moments(alpha, beta, log_mass):
    """Mean and variance of a standard normal truncated to ``[alpha, beta]`` of log mass
    ``log_mass``."""
    pa = math.exp(-0.5 * alpha * alpha - 0.5 * _LOG_2PI - log_mass) if alpha > -1e300 else 0.0
    pb = math.exp(-0.5 * beta * beta - 0.5 * _LOG_2PI - log_mass) if beta < 1e300 else 0.0
    mean = pa - pb
    ta = alpha * pa if pa > 0.0 else 0.0
    tb = beta * pb if pb > 0.0 else 0.0
    return mean, max(1.0 + ta - tb - mean * mean, 0.0)


@njit(cache=True)
def _core_reach(core, late, floor, sigma, rate):
    """``K``: beyond ``Kσ`` of its residual an arrival's core density is below
    :data:`INTEGRAL_TOLERANCE` of its floor (within ``L``) and of its late tail (earlier than
    ``L``), so it is dropped there (:func:`sequence_ping_integral`)."""
    k_floor = math.sqrt(2.0 * max(math.log(core / (INTEGRAL_TOLERANCE * floor)), 0.0))
    # the tail: d²/2σ² − λd ≥ log(core / (tol·late)) for every d ≥ Kσ (increasing there)
    lift = max(math.log(core / (INTEGRAL_TOLERANCE * late)), 0.0)
    skew = rate * sigma
    return max(k_floor, skew + math.sqrt(skew * skew + 2.0 * lift), 1.0)


@njit(cache=True)
def _pooled(mean, variance, new_mean, new_variance, share):
    """Mean and variance of a mixture of a distribution (``mean``, ``variance``) and a new
    one with weight ``share``."""
    shift = new_mean - mean
    mean += share * shift
    variance = (1.0 - share) * variance + share * new_variance + share * (1.0 - share) * shift**2
    return mean, variance


@njit(cache=True)
def _log_mass_bound(a, b, centre, precision):
    """An upper bound of ``log ∫_a^b N(T; centre, 1/precision) dT`` without ``erfc``: 1, the
    peak's density times the width, or the Mills ratio's tail."""
    root = math.sqrt(precision)
    log_width = math.log((b - a) * root) - 0.5 * _LOG_2PI if b - a < math.inf else math.inf
    if a <= centre <= b:
        return min(0.0, log_width)
    z = (a - centre) * root if centre < a else (centre - b) * root
    return -0.5 * z * z - 0.5 * _LOG_2PI + min(log_width + 0.5 * _LOG_2PI, -math.log(z))


@njit(cache=True)
def _log_factors_bound(lo, hi, r, sigma, kind, factor, constant, core):
    """Upper bounds of the log of the arrivals' pointwise factors (``kind`` > 0, as
    :func:`_piece` fills them) on ``[lo, hi]`` within a piece, each core at its residual's
    nearest point (no residual lies inside a piece) and each late tail at the piece's end:
    of the product, and of the part of it with at least one core (the product less the
    cores left out: ``Σ_i c_i Π_{j<i} (B_j + A_j) Π_{j>i} (c_j + B_j + A_j)``)."""
    product = 1.0
    without = 1.0  # the product with the cores so far left out
    excess = 0.0
    for i in range(r.size):
        if kind[i] == 1:
            product *= factor[i] + constant[i]
            excess *= factor[i] + constant[i]
            without *= factor[i] + constant[i]
        elif kind[i] == 2:
            e = max(lo - r[i], r[i] - hi, 0.0) / sigma
            peak = core * math.exp(-0.5 * e * e)
            excess = excess * (peak + factor[i] + constant[i]) + peak * without
            product *= peak + factor[i] + constant[i]
            without *= factor[i] + constant[i]
    return math.log(product), math.log(excess) if excess > 0.0 else -math.inf


@njit(cache=True)
def _piece(
    r, window, lift, a, b, sigma, var, half_width, core, late, floor, rate, kind, factor,
    constant,
):  # fmt: skip
    """Classify the arrivals on the piece ``(a, b)`` between cuts, fill ``kind``, ``factor``
    and ``constant`` (n,), and return the piece's Gaussian, log constant and bound.

    On the piece each arrival is *dead* (``T > r + L``: only its core, a Gaussian factor of
    ``G``), *late-only* (``T < r − L``: ``late·e^{λ(T − r)}``), *floor-only*
    (``r < T < r + L``), *mixed* (``kind`` 1: ``factor`` its late tail at ``b``,
    ``constant`` its floor) or, within its cluster's ``window`` (2, n) and not dead,
    *active* (``kind`` 2: its core, ``factor`` its late tail at ``b`` if ``T < r`` else 0,
    ``constant`` its floor if ``|T − r| < L`` else 0). The integrand is
    ``e^c · G(T) · v^m · Π_{kind>0} (…)`` with ``v = e^{λ(T − b)} ≤ 1``,
    ``G(T) = exp(−P(T − centre)²/2)`` and ``m`` the late-only count. The late tails at ``b``
    are ``late·e^{λ(b − max r)}·lift_i``, ``lift`` (n,) = ``e^{λ(max r − r_i)}`` (empty: each
    its own ``exp``, for residuals too far apart).

    Returns
    -------
    precision, centre : float
        ``P`` (s⁻²) and centre (s) of ``G``: the prior times the dead cores.
    log_c : float
        ``c``: the constants of ``G``, the late-only tails at ``b`` and the floors.
    m, n_active : int
        Late-only and active arrivals.
    log_bound : float
        An upper bound of the log of the piece's integral.
    """
    n = r.size
    t = 0.5 * (a + b) if b - a < math.inf else (b - 1.0 if a == -math.inf else a + 1.0)
    s2 = sigma * sigma
    base = late * math.exp(rate * (b - r.max())) if lift.size and b < math.inf else 0.0
    n_dead = 0
    dead_sum = 0.0
    m = 0
    late_sum = 0.0
    n_floor = 0
    n_active = 0
    for i in range(n):
        d = t - r[i]
        kind[i] = 0
        if d > half_width:
            n_dead += 1
            dead_sum += r[i]
        elif window[0, i] < t < window[1, i]:
            kind[i] = 2
            factor[i] = 0.0
            if d < 0.0:
                factor[i] = base * lift[i] if lift.size else late * math.exp(rate * (b - r[i]))
            constant[i] = floor if abs(d) < half_width else 0.0
            n_active += 1
        elif d < -half_width:
            m += 1
            late_sum += r[i]
        elif d > 0.0:
            n_floor += 1
        else:
            kind[i] = 1
            factor[i] = base * lift[i] if lift.size else late * math.exp(rate * (b - r[i]))
            constant[i] = floor
    precision = 1.0 / var + n_dead / s2
    centre = dead_sum / s2 / precision
    log_c = -0.5 * (_LOG_2PI + math.log(var)) - 0.5 * centre * centre / var
    log_c += n_dead * math.log(core)
    for i in range(n):
        if t - r[i] > half_width:
            log_c -= 0.5 * (r[i] - centre) ** 2 / s2
    log_c += n_floor * math.log(floor)
    if m > 0:
        log_c += m * math.log(late) + rate * (m * b - late_sum)
    log_bound = log_c + 0.5 * (_LOG_2PI - math.log(precision))
    log_bound += _log_mass_bound(a, b, centre, precision)
    log_bound += _log_factors_bound(a, b, r, sigma, kind, factor, constant, core)[0]
    return precision, centre, log_c, m, n_active, log_bound


@njit(cache=True)
def _closed_piece(a, b, end, precision, centre, log_c, m, kind, factor, constant, rate, scratch):
    """Log integral, mean and variance of ``T`` on ``(a, b)`` within a piece ending at
    ``end``, the cores left out: the product ``Π_{kind>0} (B_i + A_i v)`` (``constant``,
    ``factor``; ``v = e^{λ(T − end)}``) expanded in powers of ``v`` (``scratch``, (n + 1,)),
    each times ``v^m G`` integrated in closed form (a truncated Gaussian)."""
    coefficients = scratch
    degree = 0
    coefficients[0] = 1.0
    for i in range(kind.size):
        if kind[i] > 0:
            coefficients[degree + 1] = 0.0
            for j in range(degree + 1, 0, -1):
                coefficients[j] = constant[i] * coefficients[j] + factor[i] * coefficients[j - 1]
            coefficients[0] *= constant[i]
            degree += 1
    sd = 1.0 / math.sqrt(precision)
    log_scale = log_c + 0.5 * (_LOG_2PI - math.log(precision))
    total = -math.inf
    first = spread = 0.0
    for j in range(degree + 1):
        if not coefficients[j] > 0.0:
            continue
        k = (m + j) * rate
        shifted = centre + k / precision
        alpha = (a - shifted) / sd
        beta = (b - shifted) / sd
        log_mass = _log_normal_mass(alpha, beta)
        exponent = 0.0 if k == 0.0 else k * (centre - end) + 0.5 * k * k / precision
        log_term = log_scale + math.log(coefficients[j]) + exponent + log_mass
        if log_term == -math.inf:
            continue
        mean, variance = _truncated_moments(alpha, beta, log_mass)
        grown = np.logaddexp(total, log_term)
        first, spread = _pooled(
            first, spread, shifted + sd * mean, sd * sd * variance, math.exp(log_term - grown)
        )
        total = grown
    return total, first, spread


@njit(cache=True)
def _gauss_legendre(width):
    """The Gauss-Legendre rule (nodes, weights on [-1, 1]) for a sub-piece ``width`` of the
    integrand's scales wide (at most :data:`_GL_WIDEST`): the fewest nodes that integrate a
    Gaussian of that scale to ~1e-15 (:data:`_GL_RULES`)."""
    for k in range(len(_GL_RULES) - 1):
        if width <= _GL_RULES[k][0]:
            return _GL_RULES[k][1], _GL_RULES[k][2]
    return _GL_RULES[-1][1], _GL_RULES[-1][2]


@njit(cache=True)
def _quadrature_piece(
    a, b, r, sigma, precision, centre, log_c, m, n_active, kind, factor, constant, log_total,
    core, rate, scratch, cores, bends, slopes,
):  # fmt: skip
    """Log integral, mean and variance of ``T`` on a piece with active cores.

    Gauss-Legendre on equal sub-pieces of at most :data:`_GL_WIDEST` of the integrand's
    narrowest scales (the sd of ``G`` times the active cores, ``1/√(P + n_active/σ²)``, or
    less where ``G``'s centre is outside the piece; the late tails' ``1/(λ·count)``),
    walked outward from ``G``'s centre. A direction stops where the rest
    of the piece's part with a core is below :data:`INTEGRAL_TOLERANCE` of the integral so
    far (``log_total`` before this piece; bounded by ``G``'s largest value and mass there
    and :func:`_log_factors_bound`); the rest without the cores, unless it is below that
    too, is integrated in closed form (:func:`_closed_piece`).

    The nodes are taken in pairs ``±t`` about each sub-piece's middle, where every factor
    ``exp(quadratic)`` is its value at the middle, a curvature term the piece shares and a
    slope term (its inverse at ``−t``); a core's slope term is its own (``slopes``, once a
    piece) times one the cores share (once a pair).
    """
    n = r.size
    sd = 1.0 / math.sqrt(precision)
    anchor = min(max(centre, a), b)
    scale = min(
        1.0 / math.sqrt(precision + n_active / (sigma * sigma)),
        sd / max(1.0, abs(anchor - centre) / sd),
    )
    lates = m
    for i in range(n):
        if kind[i] > 0 and factor[i] > 0.0:
            lates += 1
    if lates > 0:
        scale = min(scale, 1.0 / (rate * lates))
    pieces = int(math.ceil((b - a) / (_GL_WIDEST * scale)))
    h = (b - a) / pieces
    nodes, weights = _gauss_legendre(h / scale)
    half = 0.5 * h
    pairs = nodes.size // 2  # the rules have an even number of nodes
    for q in range(pairs):
        t = half * nodes[nodes.size - 1 - q]
        bends[0, q] = math.exp(-0.5 * precision * t * t)  # G's curvature at ±t
        bends[1, q] = math.exp(-0.5 * (t / sigma) ** 2)  # a core's
        bends[2, q] = math.exp(rate * t)  # v's slope at +t
    start = min(int((anchor - a) / h), pieces - 1)
    # a core's slope at t is exp((r − mid)·κt) = exp((r − ref)·κt)·exp(−(mid − ref)·κt);
    # the first is the piece's (kept where it cannot overflow: |(r − ref)·κ| < 300)
    kappa = half / (sigma * sigma)
    ref = a + (start + 0.5) * h
    for i in range(n):
        if kind[i] == 2:
            lift = (r[i] - ref) * kappa
            cores[2, i] = abs(lift) < 300.0
            if cores[2, i]:
                for q in range(pairs):
                    slopes[i, q] = math.exp(lift * nodes[nodes.size - 1 - q])
    log_half_mass = math.log(0.5 * sd) + 0.5 * _LOG_2PI  # of G beyond its centre
    log_ref = log_c - 0.5 * precision * (anchor - centre) ** 2
    skip = math.log(INTEGRAL_TOLERANCE)
    total = first = second = 0.0
    rest_log, rest_mean, rest_variance = -math.inf, 0.0, 0.0  # the closed-form rests
    for direction in (-1, 1):
        j = start if direction == -1 else start + 1
        while 0 <= j < pieces:
            lo = a + j * h
            near = lo + h if direction == -1 else lo  # the sub-piece's end nearest the anchor
            if total > 0.0:
                far = b if direction == 1 else a
                z = max(direction * (near - centre), 0.0) / sd
                log_g = log_c - 0.5 * z * z + min(log_half_mass, math.log(abs(far - near)))
                log_all, log_excess = _log_factors_bound(
                    min(near, far), max(near, far), r, sigma, kind, factor, constant, core
                )
                here = np.logaddexp(
                    np.logaddexp(log_total, rest_log), log_ref + math.log(total * half)
                )
                if log_g + log_excess < here + skip:
                    if log_g + log_all >= here + skip:
                        part = _closed_piece(
                            min(near, far), max(near, far), b, precision, centre, log_c, m,
                            kind, factor, constant, rate, scratch,
                        )  # fmt: skip
                        grown = np.logaddexp(rest_log, part[0])
                        if grown > -math.inf:
                            rest_mean, rest_variance = _pooled(
                                rest_mean, rest_variance, part[1], part[2],
                                math.exp(part[0] - grown),
                            )  # fmt: skip
                            rest_log = grown
                    break
            # the nodes in pairs ±t about the middle: each exp(quadratic) factor is its
            # value at the middle, a curvature term shared by the piece and a slope term
            # whose value at −t is the inverse of its value at t
            mid = lo + half
            g_mid = math.exp(
                -0.5 * precision * ((mid - centre) ** 2 - (anchor - centre) ** 2)
                + m * rate * (mid - b)
            )
            g_slope = (m * rate - precision * (mid - centre)) * half
            v_mid = math.exp(rate * (mid - b)) if lates > m else 0.0
            drift = (mid - ref) * kappa
            shared = abs(drift) < 300.0
            for i in range(n):
                if kind[i] == 2:
                    e = (mid - r[i]) / sigma
                    cores[0, i] = core * math.exp(-0.5 * e * e)
                    cores[1, i] = -e / sigma * half
            for q in range(pairs):
                t = nodes[nodes.size - 1 - q]
                slope = math.exp(g_slope * t)
                common = math.exp(-drift * t) if shared else 1.0
                upper = g_mid * bends[0, q] * slope
                lower = g_mid * bends[0, q] / slope
                v_upper = v_mid * bends[2, q]
                v_lower = v_mid / bends[2, q] if v_mid > 0.0 else 0.0
                for i in range(n):
                    if kind[i] == 1:
                        upper *= constant[i] + factor[i] * v_upper
                        lower *= constant[i] + factor[i] * v_lower
                    elif kind[i] == 2:
                        c_mid = cores[0, i] * bends[1, q]
                        if c_mid > 0.0:
                            if shared and cores[2, i]:
                                c_slope = slopes[i, q] * common
                            else:
                                c_slope = math.exp(cores[1, i] * t)
                            upper *= c_mid * c_slope + factor[i] * v_upper + constant[i]
                            lower *= c_mid / c_slope + factor[i] * v_lower + constant[i]
                        else:
                            upper *= factor[i] * v_upper + constant[i]
                            lower *= factor[i] * v_lower + constant[i]
                w = weights[q]
                d_upper = mid + half * t - anchor
                d_lower = mid - half * t - anchor
                total += w * (upper + lower)
                first += w * (upper * d_upper + lower * d_lower)
                second += w * (upper * d_upper * d_upper + lower * d_lower * d_lower)
            j += direction
    if not total > 0.0:
        return rest_log, rest_mean, rest_variance
    mean = first / total
    log_q = log_ref + math.log(total * half)
    grown = np.logaddexp(log_q, rest_log)
    mean, variance = _pooled(
        anchor + mean, max(second / total - mean**2, 0.0), rest_mean, rest_variance,
        math.exp(rest_log - grown),
    )  # fmt: skip
    return grown, mean, variance


@njit(cache=True)
def sequence_ping_integral(residual, mu, var, sigma, outlier_fraction, half_width):
    """``log ∫ N(T; mu, var) Π_i p(r_i − T) dT`` with the arrival residual's physical density
    ``p``, and the posterior mean and variance of ``T``.

    ``p(e) = (1 − ε)·N(e; 0, σ) + ε(1 − φ)·Exp(e; LATE_MEAN) + εφ·U(e; ±L)``: a direct path,
    a late (multipath) arrival priced by its delay (:data:`LATE_MEAN`), and a small floor
    either way (share ``φ`` = :data:`FLOOR_SHARE`), the shape of
    :class:`~hmmtrack.tracking.measurement.arrival_time.ArrivalLikelihood`. A uniform outlier
    on ``±L`` alone would let a confident cloud discard one receiver's arrival at a constant
    price ping after ping and slide away along the other receivers' ranges; the exponential
    gives the likelihood a slope back toward the truth (reports/decisions.md, "The moorings'
    excursions").

    Without outliers it is closed form: the flat integral
    (:func:`~hmmtrack.tracking.measurement.tdoa.gaussian_ping_loglik`) times
    ``N(r̄; mu, var + σ²/n)``. With them, at most :data:`EXPANDED_RECEIVERS` arrivals are
    expanded over the ``3^n`` assignments of the arrivals to core, late tail and floor, each
    a truncated Gaussian (:func:`_expanded_integral`, exact). More are integrated by pieces,
    at a cost about that of the ping's clusters, not ``3^n``: the line is cut at every
    arrival's ``r``, ``r ± L`` and cluster window (``r ± Kσ``, ``K`` from :func:`_core_reach`:
    beyond it a core is below :data:`INTEGRAL_TOLERANCE` of the same arrival's floor or late
    tail, and dropped). On each piece the prior times the cores of the arrivals more than
    ``L`` before ``T`` is one Gaussian ``G``, and every other arrival's factor is
    ``A·e^{λT} + B`` or, in its window, that plus its core. A piece without a core is
    integrated in closed form (the product expanded in powers of ``e^{λT}``, each a
    truncated Gaussian: ``O(n²)``); a piece with cores by Gauss-Legendre
    (:func:`_quadrature_piece`). The pieces are taken largest bound first, and a piece, or
    the rest of a piece's sub-pieces, whose bound is below :data:`INTEGRAL_TOLERANCE` of the
    integral so far is skipped. The log-likelihood is within 1e-9 nats of the expansion's
    (tests: 1-12 arrivals, clusters, outliers 1 s off, priors from 0.1 ms to 1 s).

    Parameters
    ----------
    residual : (n,) float array
        Arrival minus travel time minus the scheduled emission (s), n ≥ 1.
    mu, var : float
        Prior mean (s) and variance (s²) of the emission's offset ``T``.
    sigma, outlier_fraction, half_width : float
        Core sd (s), outlier share ``ε`` and the floor's half-width ``L`` (s), as
        :func:`~hmmtrack.tracking.measurement.tdoa.ping_integral`.

    Returns
    -------
    log_l : float
        Log of the integral (log s^(−n)).
    mean, variance : float
        Posterior mean (s) and variance (s²) of ``T``.
    """
    n = residual.size
    work, counts = _workspace(n if n > EXPANDED_RECEIVERS else 0)
    return _emission_integral(residual, mu, var, sigma, outlier_fraction, half_width, work, counts)


@njit(cache=True)
def _expanded_integral(residual, mu, var, sigma, outlier_fraction, half_width):
    """:func:`sequence_ping_integral` of a ping heard by few receivers, expanded over the
    ``3^n`` assignments of its arrivals to core, late tail and floor: each a Gaussian in
    ``T`` times ``e^{λkT}`` on an interval (``T < r`` for a late arrival, ``|r − T| < L``
    for a floor arrival), so a truncated Gaussian's mass and moments."""
    n = residual.size
    rate = 1.0 / LATE_MEAN
    log_core = math.log1p(-outlier_fraction) - math.log(sigma) - 0.5 * _LOG_2PI
    log_late = math.log(outlier_fraction * (1.0 - FLOOR_SHARE) * rate)
    log_floor = math.log(outlier_fraction * FLOOR_SHARE / (2.0 * half_width))
    log_prior = -0.5 * (_LOG_2PI + math.log(var))
    total = -math.inf
    mean = variance = 0.0  # of T − mu
    for code in range(3**n):
        c = code
        n_core = n_late = 0
        core_sum = late_sum = 0.0
        lo, hi = -math.inf, math.inf
        log_c = log_prior
        for i in range(n):
            kind = c % 3
            c //= 3
            r = residual[i] - mu
            if kind == 0:
                n_core += 1
                core_sum += r
                log_c += log_core
            elif kind == 1:
                n_late += 1
                late_sum += r
                hi = min(hi, r)
                log_c += log_late
            else:
                lo = max(lo, r - half_width)
                hi = min(hi, r + half_width)
                log_c += log_floor
        if not hi > lo:
            continue
        precision = 1.0 / var + n_core / (sigma * sigma)
        centre = (core_sum / (sigma * sigma) + rate * n_late) / precision
        quad = centre * centre / var
        c = code
        for i in range(n):
            if c % 3 == 0:
                quad += (centre - (residual[i] - mu)) ** 2 / (sigma * sigma)
            c //= 3
        sd = 1.0 / math.sqrt(precision)
        alpha = (lo - centre) / sd
        beta = (hi - centre) / sd
        log_mass = _log_normal_mass(alpha, beta)
        log_term = (
            log_c - 0.5 * quad + rate * (n_late * centre - late_sum)
            + 0.5 * (_LOG_2PI - math.log(precision)) + log_mass
        )  # fmt: skip
        grown = np.logaddexp(total, log_term)
        if grown == -math.inf:
            continue
        m, v = _truncated_moments(alpha, beta, log_mass)
        mean, variance = _pooled(
            mean, variance, centre + sd * m, sd * sd * v, math.exp(log_term - grown)
        )
        total = grown
    if total == -math.inf:
        return -math.inf, mu, var
    return total, mu + mean, variance


@njit(cache=True)
def _workspace(n):
    """Scratch arrays (float, int) for :func:`_emission_integral` of ``n`` arrivals, so that
    a kernel scoring many particles allocates them once."""
    pieces = 5 * n + 1
    rule = _GL_RULES[-1][1].size // 2
    return np.empty(23 * n + 2 * pieces * n + 9 * pieces + 3 * rule + 1), np.empty(
        n + pieces * n, dtype=np.int64
    )


@njit(cache=True)
def _emission_integral(residual, mu, var, sigma, outlier_fraction, half_width, work, counts):
    """:func:`sequence_ping_integral` in the scratch of :func:`_workspace`."""
    n = residual.size
    if outlier_fraction == 0.0:
        flat, mean = gaussian_ping_loglik(residual, sigma)
        spread = sigma * sigma / n
        total = var + spread
        log_l = flat - 0.5 * (_LOG_2PI + math.log(total)) - 0.5 * (mean - mu) ** 2 / total
        post = 1.0 / (1.0 / var + 1.0 / spread)
        return log_l, post * (mu / var + mean / spread), post
    if n <= EXPANDED_RECEIVERS:
        return _expanded_integral(residual, mu, var, sigma, outlier_fraction, half_width)
    pieces = 5 * n + 1
    rule = _GL_RULES[-1][1].size // 2
    views = np.cumsum(
        np.array([n, 2 * n, 5 * n, n, pieces * n, pieces * n, 5 * pieces, pieces, pieces])
    )
    r = work[: views[0]]
    window = work[views[0] : views[1]].reshape((2, n))
    cuts = work[views[1] : views[2]]
    lift = work[views[2] : views[3]]
    factor = work[views[3] : views[4]].reshape((pieces, n))
    constant = work[views[4] : views[5]].reshape((pieces, n))
    gauss = work[views[5] : views[6]].reshape((pieces, 5))
    bounds = work[views[6] : views[7]]
    logs = work[views[7] : views[8]]
    rest = views[8]
    means = work[rest : rest + pieces]
    variances = work[rest + pieces : rest + 2 * pieces]
    scratch = work[rest + 2 * pieces : rest + 2 * pieces + n + 1]
    rest += 2 * pieces + n + 1
    cores = work[rest : rest + 3 * n].reshape((3, n))
    bends = work[rest + 3 * n : rest + 3 * n + 3 * rule].reshape((3, rule))
    slopes = work[rest + 3 * n + 3 * rule : rest + 13 * n + 3 * rule].reshape((n, rule))
    order = counts[:n]
    kind = counts[n : n + pieces * n].reshape((pieces, n))
    rate = 1.0 / LATE_MEAN
    core = (1.0 - outlier_fraction) / (sigma * math.sqrt(2.0 * math.pi))
    late = outlier_fraction * (1.0 - FLOOR_SHARE) * rate
    floor = outlier_fraction * FLOOR_SHARE / (2.0 * half_width)
    reach = _core_reach(core, late, floor, sigma, rate) * sigma
    for i in range(n):  # the residuals about the prior, their order by insertion
        r[i] = residual[i] - mu
        j = i
        while j > 0 and r[order[j - 1]] > r[i]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = i
    # each arrival's cluster window: residuals less than 2Kσ apart share one
    n_cuts = 0
    first = 0
    for k in range(n):
        if k < n - 1 and r[order[k + 1]] - r[order[k]] <= 2.0 * reach:
            continue
        lo, hi = r[order[first]] - reach, r[order[k]] + reach
        for j in range(first, k + 1):
            window[0, order[j]], window[1, order[j]] = lo, hi
        cuts[n_cuts], cuts[n_cuts + 1] = lo, hi
        n_cuts += 2
        first = k + 1
    for i in range(n):
        cuts[n_cuts], cuts[n_cuts + 1], cuts[n_cuts + 2] = (
            r[i] - half_width, r[i], r[i] + half_width
        )  # fmt: skip
        n_cuts += 3
    cuts[:n_cuts].sort()
    n_pieces = n_cuts + 1
    # each piece's arrivals, Gaussian (precision, centre, log constant, late-only count,
    # active count) and bound
    top, bottom = r[order[n - 1]], r[order[0]]
    spread_ok = rate * (top - bottom) < 600.0
    for i in range(n):
        lift[i] = math.exp(rate * (top - r[i])) if spread_ok else 0.0
    lifts = lift if spread_ok else lift[:0]
    for k in range(n_pieces):
        a = cuts[k - 1] if k > 0 else -math.inf
        b = cuts[k] if k < n_cuts else math.inf
        bounds[k] = -math.inf
        logs[k] = -math.inf
        if b > a:
            out = _piece(
                r, window, lifts, a, b, sigma, var, half_width, core, late, floor, rate,
                kind[k], factor[k], constant[k],
            )  # fmt: skip
            gauss[k, 0], gauss[k, 1], gauss[k, 2], gauss[k, 3], gauss[k, 4] = out[:5]
            bounds[k] = out[5]
    log_total = -math.inf
    skip = math.log(INTEGRAL_TOLERANCE)
    while True:  # the pieces by bound, largest first, until the rest are negligible
        k = 0
        for j in range(1, n_pieces):
            if bounds[j] > bounds[k]:
                k = j
        if bounds[k] == -math.inf or bounds[k] < log_total + skip:
            break
        bounds[k] = -math.inf
        a = cuts[k - 1] if k > 0 else -math.inf
        b = cuts[k] if k < n_cuts else math.inf
        precision, centre, log_c = gauss[k, 0], gauss[k, 1], gauss[k, 2]
        m, n_active = int(gauss[k, 3]), int(gauss[k, 4])
        if n_active == 0:
            logs[k], means[k], variances[k] = _closed_piece(
                a, b, b, precision, centre, log_c, m, kind[k], factor[k], constant[k], rate,
                scratch,
            )  # fmt: skip
        else:
            logs[k], means[k], variances[k] = _quadrature_piece(
                a, b, r, sigma, precision, centre, log_c, m, n_active, kind[k], factor[k],
                constant[k], log_total, core, rate, scratch, cores, bends, slopes,
            )  # fmt: skip
        log_total = np.logaddexp(log_total, logs[k])
    if log_total == -math.inf:
        return -math.inf, mu, var
    mean = 0.0
    for k in range(n_pieces):
        if logs[k] > -math.inf:
            mean += math.exp(logs[k] - log_total) * means[k]
    variance = 0.0
    for k in range(n_pieces):
        if logs[k] > -math.inf:
            variance += math.exp(logs[k] - log_total) * (variances[k] + (means[k] - mean) ** 2)
    return log_total, mu + mean, variance


@njit(cache=True, nogil=True)
def _sequence_kernel(
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
    scheduled, elapsed, clock, noise, sigma, outlier_fraction, half_width, emission, updated,
    counter, loglik,
):  # fmt: skip
    """:func:`sequence_ping_loglik` for every particle of each chunk not yet claimed
    (:func:`~hmmtrack.tracking.compiled.chunks.next_chunk`)."""
    residual = np.empty(arrival.size)
    work, counts = _workspace(arrival.size)
    jitter = EMISSION_JITTER * EMISSION_JITTER
    parts = np.empty((2, 7))  # per prior: log weight, mean of T, updated clock (5)
    chunk, lo, hi = next_chunk(counter, x.size)
    while chunk >= 0:
        for p in range(lo, hi):
            u = clock[0, p] + clock[1, p] * elapsed  # predicted offset and its covariance
            p_uu = (
                clock[2, p] + 2.0 * elapsed * clock[3, p] + elapsed * elapsed * clock[4, p]
                + noise[0] * elapsed
            )  # fmt: skip
            p_ub = clock[3, p] + elapsed * clock[4, p]
            p_bb = clock[4, p] + noise[1] * elapsed
            ping_residuals(
                p, x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time,
                slowness, residual,
            )  # fmt: skip
            residual -= scheduled
            # two priors of the emission's offset: the particle's clock, and (share
            # CLOCK_RESET) the same widened by OFFSET_SD, a clock set from a wrong position
            for k in range(2):
                wide = OFFSET_SD * OFFSET_SD if k == 1 else 0.0
                share = CLOCK_RESET if k == 1 else 1.0 - CLOCK_RESET
                prior = p_uu + wide + jitter
                log_k, mean, var = _emission_integral(
                    residual, u, prior, sigma, outlier_fraction, half_width, work, counts
                )
                gain_u = (p_uu + wide) / prior
                gain_b = p_ub / prior
                shrink = prior - var
                parts[k, 0] = log_k + math.log(share)
                parts[k, 1] = mean
                parts[k, 2] = u + gain_u * (mean - u)
                parts[k, 3] = clock[1, p] + gain_b * (mean - u)
                parts[k, 4] = p_uu + wide - gain_u * gain_u * shrink
                parts[k, 5] = p_ub - gain_u * gain_b * shrink
                parts[k, 6] = p_bb - gain_b * gain_b * shrink
            top = max(parts[0, 0], parts[1, 0])
            w0 = math.exp(parts[0, 0] - top)
            w1 = math.exp(parts[1, 0] - top)
            log_mix = top + math.log(w0 + w1)
            w0, w1 = w0 / (w0 + w1), w1 / (w0 + w1)
            mean_mix = w0 * parts[0, 1] + w1 * parts[1, 1]
            loglik[p] = log_mix
            emission[p] = scheduled + mean_mix
            # the two posteriors of (offset, drift) moment-matched into one Gaussian
            du = parts[0, 2] - parts[1, 2]
            db = parts[0, 3] - parts[1, 3]
            spread = w0 * w1
            updated[0, p] = w0 * parts[0, 2] + w1 * parts[1, 2]
            updated[1, p] = w0 * parts[0, 3] + w1 * parts[1, 3]
            updated[2, p] = w0 * parts[0, 4] + w1 * parts[1, 4] + spread * du * du
            updated[3, p] = w0 * parts[0, 5] + w1 * parts[1, 5] + spread * du * db
            updated[4, p] = w0 * parts[0, 6] + w1 * parts[1, 6] + spread * db * db
        chunk, lo, hi = next_chunk(counter, x.size)


@njit(cache=True, nogil=True, parallel=True)
def _sequence_parallel(
    threads, x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
    scheduled, elapsed, clock, noise, sigma, outlier_fraction, half_width, emission, updated,
    counter, loglik,
):  # fmt: skip
    """:func:`_sequence_kernel` on ``threads`` threads."""
    for _ in numba.prange(threads):
        _sequence_kernel(
            x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
            scheduled, elapsed, clock, noise, sigma, outlier_fraction, half_width, emission,
            updated, counter, loglik,
        )  # fmt: skip


def sequence_ping_loglik(
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, sound_speed,
    scheduled, elapsed, clock, noise, sigma, outlier_fraction, half_width, loglik, emission,
    updated, threads=None,
):  # fmt: skip
    """One matched ping for every particle: its log-likelihood into ``loglik`` (N,), the
    posterior mean emission time into ``emission`` (N,), and each particle's clock after
    the ping into ``updated`` (5, N).

    The particles are scored in chunks on ``threads`` threads, as
    :func:`~hmmtrack.tracking.measurement.tdoa.ping_loglik`'s (default: the enclosing
    :func:`~hmmtrack.tracking.compiled.chunks.default_threads` block's, the filter's
    correction threads, else numba's thread count); each particle's result is computed
    alone, so it does not depend on the number of threads.

    Parameters
    ----------
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, sound_speed
        As :func:`~hmmtrack.tracking.measurement.tdoa.ping_loglik`.
    scheduled : float
        The ping's aligned emission time (s).
    elapsed : float
        Scheduled seconds since the clocks' last ping (0 before the first).
    clock : (5, N) float array
        Each particle's offset (s), drift, and their variances and covariance
        (:data:`SEQUENCE_FIELDS`), after the last ping.
    noise : (2,) float array
        Random-walk densities of the offset (s²/s) and of the drift (1/s)
        (:attr:`PingSequence.clock_noise`).
    threads : int, optional
    """
    args = (
        x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, float(time),
        1.0 / sound_speed, float(scheduled), float(elapsed), clock, noise, float(sigma),
        float(outlier_fraction), float(half_width), emission, updated,
    )  # fmt: skip
    in_chunks(_sequence_kernel, _sequence_parallel, np.shape(x)[0], threads, args, loglik)


@njit(cache=True)
def heard_loglik(
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, sound_speed,
    range_50, width, loglik,
):  # fmt: skip
    """Add to ``loglik`` (N,) each particle's ``log p(range)`` of being heard by every
    receiver of one ping (logistic curve ``range_50``, ``width``, m; range at emission as
    :func:`~hmmtrack.tracking.measurement.tdoa.ping_residuals` takes it), the term the
    arrival-time measurement adds per detection."""
    slowness = 1.0 / sound_speed
    for p in range(x.size):
        for j in range(arrival.size):
            d = emission_distance(
                x[p], y[p], vx[p], vy[p], depth[p] + row_offset[j], time - arrival[j],
                receiver_x[j], receiver_y[j], slowness,
            )  # fmt: skip
            loglik[p] -= softplus((d - range_50) / width)


# ---------------------------------------------------------------------------- measurement


def _burst_sequence(name: str, value):
    """A file name, or the intervals themselves (a list of positive seconds)."""
    if isinstance(value, str):
        if not value:
            raise ValueError(f"{name} must be a file name or a list of intervals, got ''")
        return value
    try:
        intervals = tuple(value)
    except TypeError:
        raise ValueError(
            f"{name} must be a file name or a list of intervals (s), got {value!r}"
        ) from None
    if not intervals:
        raise ValueError(f"{name} must hold at least one interval (s)")
    return tuple(positive(f"{name}[{k}]", v) for k, v in enumerate(intervals))


@dataclass(frozen=True)
class PingSequenceSettings(PingSettings):
    """The ``measurement`` section of the ``"ping-sequence"`` measurement: the ping
    measurement's settings (:class:`~hmmtrack.tracking.measurement.tdoa.PingSettings`, its
    ``burst_interval`` refused) and the tag's sequence.

    Parameters
    ----------
    burst_sequence : str or tuple of float
        CSV file of the tag's intervals (``interval`` column, s;
        :func:`hmmtrack.io.read_burst_sequence`), or the intervals themselves.
    arrival_sigma : float, str or None
        As :class:`~hmmtrack.tracking.measurement.tdoa.PingSettings`; ``None``: the
        case's own (:meth:`chosen_sigma`).
    period : float or None
        A fixed-period tag's period (s), instead of ``burst_sequence``: a sequence of one
        interval, so that its pings are grouped and scored jointly against the tag's clock
        (``hmmtrack track --measurement ping-sequence --period P``; the arrival-time
        measurement scores the same tag's detections one at a time).
    detection_curve : LogisticDetection or None
        With ``period``: the receivers' probability of hearing a ping against range, as the
        arrival-time measurement's (each receiver that heard a ping scores ``log p``, each
        listening one that did not ``log(1 − p)``); ``None``: who heard a ping tells
        nothing.
    """

    name: ClassVar[str] = "ping-sequence"

    # not an option of this measurement (the command line refuses --burst-interval with it)
    burst_interval: tuple[float, float] | None = None
    arrival_sigma: float | str | None = dataclasses.field(
        default=None,
        metadata=dict(arrival_sigma_setting(None).metadata)
        | {
            "default_text": (
                f"{PERIOD_ARRIVAL_SIGMA:g} with period, {SEQUENCE_ARRIVAL_SIGMA:g} with "
                "burst_sequence"
            )
        },
    )
    burst_sequence: str | tuple[float, ...] | None = setting(
        None,
        help=(
            "CSV of the tag's known pseudo-random burst intervals (column 'interval', s, in "
            "the order the tag uses them, cyclically), aligned to the pings automatically"
        ),
        check=_burst_sequence,
        metavar="FILE",
        data=True,
        default_text="none",
    )
    period: float | None = setting(
        None,
        help="a fixed-period tag's period (s): its pings scored as a sequence of one interval",
        check=positive,
        parse=float,
        metavar="SECONDS",
        data=True,
        default_text="none",
    )

    detection_curve: LogisticDetection | None = detection_curve_setting()

    def validate(self) -> None:
        super().validate()
        if self.detection_curve is not None and self.period is None:
            raise ValueError(
                "detection_curve needs period: unheard pings are scored against a "
                "fixed-period tag's schedule (a burst_sequence tag's are not)"
            )
        if (self.burst_sequence is None) == (self.period is None):
            raise ValueError(
                "the ping-sequence measurement needs burst_sequence (a file) or, for a "
                "fixed-period tag, period (s): one of them"
            )
        if self.burst_interval is not None:
            raise ValueError(
                "burst_sequence gives the tag's intervals: burst_interval is for tags whose "
                "sequence is unknown; give one of them"
            )

    def to_dict(self) -> dict:
        """As :meth:`PingSettings.to_dict`, the detection curve as ``{"range_50", "width"}``."""
        return curve_to_dict(super().to_dict(), self.detection_curve)

    def chosen_sigma(self) -> float | str:
        """:attr:`arrival_sigma`, else :data:`PERIOD_ARRIVAL_SIGMA` for a fixed-period tag and
        :data:`SEQUENCE_ARRIVAL_SIGMA` for a known sequence (each the sd it was chosen at)."""
        if self.arrival_sigma is not None:
            return self.arrival_sigma
        return SEQUENCE_ARRIVAL_SIGMA if self.period is None else PERIOD_ARRIVAL_SIGMA

    def intervals(self) -> tuple[np.ndarray, str]:
        """The sequence (s) and what it is, for messages (its file, ``"the given
        burst_sequence"`` or the period)."""
        if self.period is not None:
            return np.array([self.period]), f"the period {self.period:g} s"
        if isinstance(self.burst_sequence, str):
            return read_burst_sequence(self.burst_sequence), self.burst_sequence
        return np.asarray(self.burst_sequence, dtype=float), "the given burst_sequence"


@dataclass
class SequenceState:
    """The mutable state of one run of :class:`PingSequence`.

    Attributes
    ----------
    dt : float
        The filter's prediction step (s).
    emission : numpy.ndarray or None
        Each particle's posterior mean emission time of the latest ping (s, (N,)).
    scheduled : float or None
        The scheduled time of the ping the clocks last saw (s; ``None`` before the first).
    silence_from : float
        With a silence model, unheard pings count from this time on (s): the last
        correction's cut (:func:`~hmmtrack.tracking.measurement.clocked.silence_since`).
    """

    dt: float = 1.0
    emission: np.ndarray | None = None
    scheduled: float | None = None
    silence_from: float = -np.inf


@dataclass(frozen=True)
class PingSequence(PingTDOA):
    """The ping measurement of a tag with a known burst sequence (module docstring): the
    pings' observations carry the aligned schedule, and every particle the tag's clock.

    Parameters
    ----------
    clock_noise : (float, float, float)
        The tag clock's offset random-walk density (s²/s), drift random-walk density (1/s)
        and drift prior sd: a crystal's (:data:`PHASE_DENSITY`, :data:`DRIFT_DENSITY`,
        :data:`DRIFT_SD`) for a pseudo-random sequence; for a fixed-period tag (``period``
        given) those of the arrival-time measurement's period random walk
        (:func:`period_clock_noise`).
    broadening : float
        Share of the cloud's spread added to the arrival sd while the cloud is wide
        (:func:`broadened_sigma`); 0: none. A fixed-period tag takes
        :data:`PERIOD_BROADENING`.
    silence : SilenceModel or None
        A fixed-period tag's detection curve as information, as the arrival-time
        measurement's (:class:`~hmmtrack.tracking.measurement.clocked.ClockedArrivalTime`):
        each detection adds ``log p(range)``, each ping a particle's clock says a listening
        receiver should have heard and did not ``log(1 − p(range))``
        (:func:`~hmmtrack.tracking.measurement.clocked.silence_since`, its detection times
        the arrivals). ``None``: who heard a ping tells nothing.
    schedule_period : float or None
        The aligned schedule's period (s; the tag's period times one plus the alignment's
        drift), by which a particle's clock steps to the pings the silences look at.
    """

    clock_noise: tuple[float, float, float] = (PHASE_DENSITY, DRIFT_DENSITY, DRIFT_SD)
    broadening: float = 0.0
    silence: SilenceModel | None = None
    schedule_period: float | None = None

    name: ClassVar[str] = "ping-sequence"
    settings: ClassVar[type] = PingSequenceSettings
    columns: ClassVar[tuple[str, ...]] = (*PingTDOA.columns, "scheduled", "sequence_step")
    fields: ClassVar[tuple[str, ...]] = SEQUENCE_FIELDS
    # the run defaults it was measured with, not the random-interval ping's offline ones
    # (reports/decisions.md, "Known burst sequence")
    default_correction: ClassVar[Tempered] = Tempered(TEMPERING_ESS)
    default_motion: ClassVar[dict | None] = None
    default_smoothing_lag: ClassVar[int | None] = None

    @classmethod
    def observations(cls, detections: pd.DataFrame, receivers, settings) -> pd.DataFrame:
        """Pings grouped with the sequence's shortest interval as the longest window, then
        the sequence aligned (:func:`sequence_observations`)."""
        sequence, source = settings.intervals()
        obs = ping_observations(
            detections, receiver_tracks(receivers), sequence.min(), settings.ping_tolerance
        )
        obs = sequence_observations(obs, sequence, source)
        obs.attrs["sound_speed"] = detections.attrs.get("sound_speed")
        return obs

    @classmethod
    def from_settings(cls, settings: PingSequenceSettings, observations: pd.DataFrame, receivers):
        """:meth:`PingTDOA.from_settings`, with the clock noise of a fixed-period tag
        (:func:`period_clock_noise`), its broadening, its schedule's period and, with a
        detection curve, its silence model when ``settings.period`` is given; the arrival sd
        is the settings' :meth:`~PingSequenceSettings.chosen_sigma`."""
        chosen = dataclasses.replace(settings, arrival_sigma=settings.chosen_sigma())
        built = super().from_settings(chosen, observations, receivers)
        if settings.period is None:
            return built
        silence = None
        if settings.detection_curve is not None:
            silence = SilenceModel.from_observations(
                observations.assign(time=observations["arrival"]),
                receiver_tracks(receivers),
                settings.detection_curve,
            )
        drift = observations.attrs["alignment"].drift
        return dataclasses.replace(
            built,
            clock_noise=period_clock_noise(settings.period),
            broadening=PERIOD_BROADENING,
            silence=silence,
            schedule_period=settings.period * (1.0 + drift),
        )

    def start(self, particles, time: float, dt: float = 1.0) -> SequenceState:
        """Every particle's clock at its prior (offset 0 ± :data:`OFFSET_SD`, drift 0 ±
        ``clock_noise[2]``); a fresh run state."""
        prior = _prior_clock(particles.n, self.clock_noise[2])
        particles.extra.update(zip(SEQUENCE_FIELDS, prior, strict=True))
        return SequenceState(dt=float(dt))

    @staticmethod
    def as_matrix(table: pd.DataFrame) -> np.ndarray:
        """:meth:`PingTDOA.as_matrix` with columns 6 and 7 the scheduled time (s) and the
        sequence step (-1: not matched)."""
        return np.column_stack(
            [PingTDOA.as_matrix(table), table["scheduled"], table["sequence_step"]]
        )

    def loglik(self, particles, obs, time: float | None = None) -> np.ndarray:
        """The pings' log-likelihood (N,) given the particles' clocks (their prior without
        the fields), the clocks left as they are."""
        return self._sequence_score(particles, obs, time, None, self.sigma)[0]

    def score(self, particles, rows: np.ndarray, time: float, state: SequenceState, weights):
        """The pings' log-likelihood; the clocks' Kalman step and the emission times of the
        last scoring are committed with the final weights. With :attr:`broadening`, the
        arrival sd is widened by the cloud's spread before the correction
        (:func:`broadened_sigma`). With :attr:`silence`, the pings unheard since the last
        correction count once the clocks have seen a ping (:meth:`_silence`); the first
        such ping starts the silences' window at its earliest emission."""
        latest = []
        sigma = self.sigma
        if self.broadening > 0.0:
            sigma = broadened_sigma(
                particles, weights, self.sigma, self.broadening, self.sound_speed
            )

        def scored(particles, weights):
            loglik, emission, clock, scheduled = self._sequence_score(
                particles, rows, time, state.scheduled, sigma
            )
            cut = state.silence_from
            if self.silence is not None and state.scheduled is not None:
                silence, cut = self._silence(particles, time, state)
                loglik += silence
            latest[:] = [emission, clock, scheduled, cut]
            return loglik

        def commit(particles):
            emission, clock, scheduled, cut = latest
            if self.silence is not None and state.scheduled is None and scheduled is not None:
                cut = float(np.min(emission))  # silences count from the first ping on
            state.emission = emission
            state.scheduled = scheduled
            state.silence_from = cut
            particles.extra.update(zip(SEQUENCE_FIELDS, clock, strict=True))

        return Score(scored(particles, weights), rescore=scored, commit=commit)

    def _silence(self, p, time: float, state: SequenceState) -> tuple[np.ndarray, float]:
        """:func:`~hmmtrack.tracking.measurement.clocked.silence_since` the last correction
        of the particles' clocks: particle ``i`` emits at ``s + u_i + k·P(1 + b_i)``, ``s``
        the scheduled time of the clocks' last ping, ``u_i`` and ``b_i`` its offset and
        drift there, ``P`` :attr:`schedule_period`."""
        offset = np.asarray(p.extra["sequence_offset"], dtype=float)
        drift = np.asarray(p.extra["sequence_drift"], dtype=float)
        period = self.schedule_period
        return silence_since(
            self.silence, state.scheduled + offset, period * (1.0 + drift), p.x, p.y, time,
            state.dt, state.silence_from, period, self.sound_speed,
        )  # fmt: skip

    def _sequence_score(self, p, rows, time, last_scheduled, sigma):
        """Log-likelihood (N,), emission times (N,), clocks (5, N) and the clocks' last
        scheduled time after the pings of ``rows`` in order (arrival sd ``sigma``, s)."""
        rows, n, time, motion, offset_column = self._inputs(p, rows, time)
        extra = getattr(p, "extra", {})
        if all(name in extra for name in SEQUENCE_FIELDS):
            clock = np.array([extra[name] for name in SEQUENCE_FIELDS], dtype=float)
        else:
            clock = _prior_clock(n, self.clock_noise[2])
        total = np.zeros(n)
        loglik = np.empty(n)
        emission = np.empty(n)
        constants = (time, self.sound_speed)
        for part, ping_rows in split_pings(rows, offset_column):
            if part[0, 7] < 0:  # not matched: a random-interval ping
                ping_loglik(
                    *motion, *ping_rows, *constants, sigma, self.outlier_fraction,
                    self.half_width, loglik, emission,
                )  # fmt: skip
            else:
                scheduled = float(part[0, 6])
                elapsed = 0.0 if last_scheduled is None else scheduled - last_scheduled
                updated = np.empty_like(clock)
                sequence_ping_loglik(
                    *motion, *ping_rows, *constants, scheduled, elapsed, clock,
                    np.asarray(self.clock_noise[:2]), sigma, self.outlier_fraction,
                    self.half_width, loglik, emission, updated,
                )  # fmt: skip
                clock, last_scheduled = updated, scheduled
            total += loglik
            if self.silence is not None:
                detection = self.silence.detection
                heard_loglik(
                    *motion, *ping_rows, time, self.sound_speed, detection.range_50,
                    detection.width, total,
                )  # fmt: skip
        return total, emission, clock, last_scheduled


def broadened_sigma(particles, weights, sigma: float, broadening: float, sound_speed: float):
    """The arrival sd (s) of a correction, widened while the cloud is wide.

    ``√(σ² + (k·s/c)²)``, ``s`` the cloud's weighted position spread (m, the root of the
    summed variances of x and y), ``k`` = ``broadening``, ``c`` the speed of sound. A ping
    heard by three receivers scores a particle well only within about ``σ·c`` (a metre or
    two) of one point, and a whole hyperbola when one arrival counts as an outlier; a cloud
    spread over kilometres seldom has a particle near that point, and the tempering's moves
    (a share of the spread) carry its copies away again, so the cloud follows the
    hyperbolas out of the array. Widened, the point is a basin the moves can land in; as
    the cloud shrinks, the sd returns to ``σ``.
    """
    weights = np.asarray(weights, dtype=float)
    x, y = np.asarray(particles.x), np.asarray(particles.y)
    spread = math.sqrt(
        max(float(weights @ (x - weights @ x) ** 2 + weights @ (y - weights @ y) ** 2), 0.0)
    )
    return math.sqrt(sigma * sigma + (broadening * spread / sound_speed) ** 2)


def period_clock_noise(period: float) -> tuple[float, float, float]:
    """:attr:`PingSequence.clock_noise` of a fixed-period tag: the arrival-time measurement's
    clock model (:func:`~hmmtrack.tracking.measurement.clocked.default_clock_model`) in the
    sequence's terms.

    That model's phase step (s per ping) is an offset density ``step²/P``, its period step
    (s per ping) a drift step ``step/P`` per ``P`` seconds, a density ``step²/P³``, and its
    initial period sd a drift sd ``sd/P`` (``P`` the period, s): a real tag's period wanders
    by hundreds of ppm over hours (DESIGN.md), which a crystal's drift walk cannot follow.
    """
    clock = default_clock_model(period)
    return (
        clock.phase_step_sd**2 / period,
        clock.period_step_sd**2 / period**3,
        clock.initial_period_sd / period,
    )


def _prior_clock(n: int, drift_sd: float) -> np.ndarray:
    """(5, N): every particle's clock before the first ping (drift sd ``drift_sd``)."""
    prior = np.zeros((5, n))
    prior[2] = OFFSET_SD**2
    prior[4] = drift_sd**2
    return prior


# ---------------------------------------------------------------------------- the default


def fixed_period_measurement(detections: pd.DataFrame, receivers, period: float):
    """The measurement a fixed-period tag is tracked with when none is named: its pings
    grouped (``"ping-sequence"``) when at least :data:`GROUPING_SHARE` of them are heard by
    :data:`GROUPING_RECEIVERS` or more receivers, else ``"arrival-time"``.

    Parameters
    ----------
    detections : pandas.DataFrame
        The tag's detections on the common time base (``time`` s, ``receiver``;
        :func:`hmmtrack.tracking.pipeline.tracked_detections`).
    receivers : pandas.DataFrame or ReceiverTracks
    period : float
        The tag's period (s): the longest grouping window.

    Returns
    -------
    name : str
        ``"ping-sequence"`` or ``"arrival-time"``.
    share : float
        Share of the pings heard by :data:`GROUPING_RECEIVERS` or more receivers.
    """
    obs = ping_observations(detections, receiver_tracks(receivers), period)
    heard = obs.groupby("ping")["heard"].first().to_numpy()
    share = float(np.mean(heard >= GROUPING_RECEIVERS)) if heard.size else 0.0
    return ("ping-sequence" if share >= GROUPING_SHARE else "arrival-time"), share
