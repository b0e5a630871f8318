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

with the particle's predicted emission as prior. It is exact: closed form without outliers,
otherwise a sum of truncated Gaussians, one per assignment of the arrivals to the core, the
late tail and the floor (:func:`sequence_ping_integral`, checked against a brute-force
quadrature). The clock is then updated by the posterior mean and variance of ``T`` (exact
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
    "GROUPING_RECEIVERS",
    "GROUPING_SHARE",
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
    ``N(r̄; mu, var + σ²/n)``. With them it is exact too: the product expands into one term
    per assignment of each arrival to a component (``3^n``), each a Gaussian in ``T`` times
    ``exp(λ k T)`` on an interval (``T < r_i`` for a late arrival, ``|r_i − T| < L`` for a
    floor arrival), so a truncated Gaussian's mass and moments.

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
    if outlier_fraction == 0.0:
        flat, mean = gaussian_ping_loglik(residual, sigma)
        spread = sigma * sigma / n
        total = var + spread
        log_l = flat - 0.5 * (_LOG_2PI + math.log(total)) - 0.5 * (mean - mu) ** 2 / total
        post = 1.0 / (1.0 / var + 1.0 / spread)
        return log_l, post * (mu / var + mean / spread), post
    rate = 1.0 / LATE_MEAN
    log_core = math.log1p(-outlier_fraction) - math.log(sigma) - 0.5 * _LOG_2PI
    log_late = math.log(outlier_fraction * (1.0 - FLOOR_SHARE) * rate)
    log_floor = math.log(outlier_fraction * FLOOR_SHARE / (2.0 * half_width))
    log_prior = -0.5 * (_LOG_2PI + math.log(var))
    n_terms = 3**n
    logs = np.full(n_terms, -math.inf)
    means = np.zeros(n_terms)  # of T − mu
    seconds = np.zeros(n_terms)
    for code in range(n_terms):
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
        for i in range(n):
            if (code // 3**i) % 3 == 0:
                quad += (centre - (residual[i] - mu)) ** 2 / (sigma * sigma)
        sd = 1.0 / math.sqrt(precision)
        alpha = (lo - centre) / sd
        beta = (hi - centre) / sd
        log_mass = _log_normal_mass(alpha, beta)
        logs[code] = (
            log_c - 0.5 * quad + rate * (n_late * centre - late_sum)
            + 0.5 * (_LOG_2PI - math.log(precision)) + log_mass
        )  # fmt: skip
        m, v = _truncated_moments(alpha, beta, log_mass)
        means[code] = centre + sd * m
        seconds[code] = sd * sd * v + means[code] ** 2
    top = logs.max()
    if top == -math.inf:
        return -math.inf, mu, var
    weight = np.exp(logs - top)
    total = weight.sum()
    mean = (weight * means).sum() / total
    moment = (weight * seconds).sum() / total
    return top + math.log(total), mu + mean, max(moment - mean * mean, 0.0)


@njit(cache=True, nogil=True)
def _sequence_kernel(
    x, y, vx, vy, depth, arrival, receiver_x, receiver_y, row_offset, time, slowness,
    scheduled, elapsed, clock, noise, sigma, outlier_fraction, half_width, emission, updated,
    counter, loglik,
):  # fmt: skip
    """:func:`sequence_ping_loglik` for every particle of each chunk not yet claimed
    (:func:`~hmmtrack.tracking.compiled.chunks.next_chunk`)."""
    residual = np.empty(arrival.size)
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
                log_k, mean, var = sequence_ping_integral(
                    residual, u, prior, sigma, outlier_fraction, half_width
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
