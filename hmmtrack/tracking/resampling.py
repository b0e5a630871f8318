"""Resampling schemes for particle filters: normalised weights in, ancestor indices out.

Each scheme is a pure function ``scheme(rng, weights, n) -> ancestors`` that draws ``n``
indices into ``weights`` so that index ``i`` is expected to appear ``n * weights[i]`` times
(all four schemes are unbiased). They differ in how much extra randomness they add:

* :func:`multinomial` -- ``n`` independent draws (the paper's Algorithm 2, lines 14-18);
* :func:`residual` -- ``floor(n w_i)`` deterministic copies, the rest multinomial;
* :func:`stratified` -- one uniform draw in each of ``n`` equal strata of ``[0, 1)``;
* :func:`systematic` -- one uniform shared by all strata; every count is within one of
  ``n w_i`` (floor or ceil), the least noisy of the four.

:data:`RESAMPLERS` maps the names used by :class:`hmmtrack.tracking.filter.ParticleFilter` to the
functions. Multinomial, stratified and systematic draw sorted points in ``[0, 1)`` with
NumPy and invert the cumulative weights in linear compiled passes (:func:`inverse_cdf`);
given a :class:`Scratch` (the particle filter's) they reuse its work arrays from one call to
the next and invert in chunks on its threads, with the same ancestors. Their draws alone
(:data:`POINTS`, an :class:`Inversion` each) let a caller run the chunked inversion itself:
the particle filter merges each chunk's points and gathers its new particles in one pass
(:class:`Prepared`, ``Particles.take``'s ``locate``).
:func:`effective_sample_size` measures weight degeneracy from log weights.

This module does not weigh particles or move them; it only chooses ancestors.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, types
from numba.extending import overload

from hmmtrack.tracking.compiled.chunks import chunk_ancestors, in_chunks, next_chunk

__all__ = [
    "POINTS",
    "RESAMPLERS",
    "Inversion",
    "Prepared",
    "Scratch",
    "Segments",
    "effective_sample_size",
    "first_above",
    "get_resampler",
    "inverse_cdf",
    "invert",
    "log_normalise",
    "merge_chunk",
    "merge_points",
    "merge_segments",
    "multinomial",
    "multinomial_points",
    "prepare_points",
    "residual",
    "stratified",
    "stratified_points",
    "systematic",
    "systematic_points",
]


@njit(cache=True, fastmath={"reassoc"})
def _weights_status(w):
    """0 if ``w`` is usable (finite, non-negative, positive sum), 1 if not, 2 if it sums to 0;
    and the sum. One compiled, branch-free (vectorised) pass instead of four NumPy ones."""
    total = 0.0
    bad = False
    for i in range(w.size):
        bad |= not (w[i] >= 0.0 and w[i] < np.inf)  # also catches NaN
        total += w[i]
    if bad:
        return 1, 0.0
    return (0 if total > 0.0 else 2), total


def _checked_weights(weights: np.ndarray) -> tuple[np.ndarray, float]:
    """``weights`` as float64 and the factor ``1 / sum`` that normalises them, refusing
    unusable input (the weights are scaled on the fly, not copied)."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    status, total = _weights_status(w)
    if status == 1:
        bad = np.flatnonzero(~np.isfinite(w) | (w < 0))
        raise ValueError(
            f"weights must be finite and non-negative; bad entries at indices {bad[:10].tolist()}"
        )
    if status == 2:
        raise ValueError("weights sum to zero: no particle can be chosen")
    return w, 1.0 / total


@njit(cache=True, inline="always")
def first_above(cumulative, point, lo, hi):
    """Smallest ``j`` in ``lo..hi`` with ``cumulative[j] > point`` (binary search; ``hi``
    when none below it is: the inversion of a point in the cumulative weights)."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if cumulative[mid] <= point:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, inline="always")
def _merge_step(cumulative, points, out, j, k):
    """One branch-free step of the merge: either point ``k`` gets ancestor ``j`` and the
    next point is taken, or ``j`` moves on; returns the new ``(j, k)``."""
    up = cumulative[j] <= points[k]
    out[k] = j
    return j + up, k + 1 - up


@njit(cache=True, inline="always")
def prepare_points(weights, weight_scale, values, n, value_scale, running, cumulative, points):
    """Fill ``cumulative[:last + 1]`` with the cumulative sum of ``weights * weight_scale``
    (``inf`` at ``last``, the last index of positive weight, so that rounding can neither
    lose a point nor pick a weightless particle) and ``points[:n]`` with ``values[k] *
    value_scale`` (``running`` False) or ``(values[0] + ... + values[k]) * value_scale``
    (``running`` True: the order statistics from spacings); returns ``last``. One loop,
    two independent chains of additions in flight."""
    last = weights.size - 1
    while last > 0 and weights[last] <= 0.0:  # never pick a weightless particle
        last -= 1
    running_weight = total = 0.0
    both = min(last + 1, n)
    for j in range(both):
        running_weight += weights[j] * weight_scale
        cumulative[j] = running_weight
        total += values[j]
        points[j] = (total if running else values[j]) * value_scale
    for j in range(both, last + 1):
        running_weight += weights[j] * weight_scale
        cumulative[j] = running_weight
    for k in range(both, n):
        total += values[k]
        points[k] = (total if running else values[k]) * value_scale
    cumulative[last] = np.inf  # every point left ends at ``last``
    return last


@njit(cache=True, inline="always")
def merge_points(cumulative, points, out, lo, hi, first, last):
    """``out[k]`` = the first ``j`` from ``first`` on with ``cumulative[j] > points[k]`` for
    ``k`` in ``lo..hi-1`` (ascending points; ``cumulative[last]`` is ``inf``).

    The points are split in four runs, each started by a binary search and merged with the
    cumulative weights by :func:`_merge_step`, the four in lockstep. A plain merge of random
    data mispredicts a branch at about every other step; this one has no such branch and
    keeps four independent chains in flight (44 against 108 us for 10,000 particles). Any
    split of ``0..n-1`` into ranges gives the same ancestors."""
    m = hi - lo
    size = (m + 3) // 4
    e0, e1, e2 = lo + min(size, m), lo + min(2 * size, m), lo + min(3 * size, m)
    k0, k1, k2, k3 = lo, e0, e1, e2
    j0 = first_above(cumulative, points[k0], first, last) if k0 < e0 else last
    j1 = first_above(cumulative, points[k1], j0, last) if k1 < e1 else last
    j2 = first_above(cumulative, points[k2], j1, last) if k2 < e2 else last
    j3 = first_above(cumulative, points[k3], j2, last) if k3 < hi else last
    while k0 < e0 and k1 < e1 and k2 < e2 and k3 < hi:
        j0, k0 = _merge_step(cumulative, points, out, j0, k0)
        j1, k1 = _merge_step(cumulative, points, out, j1, k1)
        j2, k2 = _merge_step(cumulative, points, out, j2, k2)
        j3, k3 = _merge_step(cumulative, points, out, j3, k3)
    for j, k, end in ((j0, k0, e0), (j1, k1, e1), (j2, k2, e2), (j3, k3, hi)):
        while k < end:
            j, k = _merge_step(cumulative, points, out, j, k)


@njit(cache=True)
def invert(weights, weight_scale, values, n, value_scale, running):
    """Ancestors (n,) of the ascending points ``values[k] * value_scale`` (``running``
    False) or ``(values[0] + ... + values[k]) * value_scale`` (``running`` True: the order
    statistics from spacings), against the cumulative sum of ``weights * weight_scale``;
    clipped to the last index of positive weight (so that rounding in the cumulative sum
    can neither lose a point nor pick a weightless particle).

    :func:`prepare_points` forms the cumulative weights and the points, :func:`merge_points` inverts
    them; :class:`Scratch` does the same into reused arrays, in chunks on threads.
    """
    out = np.empty(n, dtype=np.int64)
    cumulative = np.empty(weights.size)
    points = np.empty(n)
    last = prepare_points(
        weights, weight_scale, values, n, value_scale, running, cumulative, points
    )
    merge_points(cumulative, points, out, 0, n, 0, last)
    return out


@njit(cache=True)
def _prepare_into(weights, weight_scale, values, n, value_scale, running, cumulative, points):
    """:func:`prepare_points` as a call of its own (before the chunked merge)."""
    return prepare_points(
        weights, weight_scale, values, n, value_scale, running, cumulative, points
    )


@njit(cache=True, inline="always")
def merge_chunk(cumulative, points, start, at, last, members, lo, hi, out):
    """``out[lo:hi]`` = the ancestors of the points ``lo:hi`` of several independent
    inversions (segments, :func:`merge_segments`): :func:`merge_points` piece by piece where
    the range spans several segments, each searching its own segment of ``cumulative``, so
    that it finds ``start[k] + j`` for the index ``j`` within the segment (made
    ``members[start[k] + j]`` when ``members`` is not empty). Any split of the points into
    ranges gives the same ancestors."""
    k = 0
    while at[k + 1] <= lo:
        k += 1
    while k < last.size and at[k] < hi:
        a, b = at[k], at[k + 1]
        first, end = max(lo, a), min(hi, b)
        if first < end:
            own = out[a:b]
            merge_points(
                cumulative, points[a:b], own, first - a, end - a, start[k], start[k] + last[k]
            )
            if members.size > 0:
                for j in range(first - a, end - a):
                    own[j] = members[own[j]]
        k += 1


@njit(cache=True, nogil=True)
def _merge_kernel(cumulative, points, start, at, last, members, counter, out):
    """:func:`merge_chunk` of every chunk of ``out`` not yet claimed (:func:`next_chunk`)."""
    chunk, lo, hi = next_chunk(counter, out.size)
    while chunk >= 0:
        merge_chunk(cumulative, points, start, at, last, members, lo, hi, out)
        chunk, lo, hi = next_chunk(counter, out.size)


@njit(cache=True, nogil=True, parallel=True)
def _merge_parallel(threads, cumulative, points, start, at, last, members, counter, out):
    """:func:`_merge_kernel` on ``threads`` threads."""
    for _ in numba.prange(threads):
        _merge_kernel(cumulative, points, start, at, last, members, counter, out)


def merge_segments(cumulative, points, start, at, last, members, threads: int, out) -> None:
    """:func:`merge_points` of several independent inversions at once, in the chunks of
    :mod:`hmmtrack.tracking.compiled.chunks` on ``threads`` threads (:func:`merge_chunk`).

    Segment ``k`` has the cumulative weights ``cumulative[start[k]:start[k + 1]]`` (its
    last index of positive weight ``last[k]``) and the ascending points
    ``points[at[k]:at[k + 1]]``; ``out[at[k]:at[k + 1]]`` receives their ancestors: the
    index ``j`` found within the segment made ``start[k] + j``, or ``members[start[k] + j]``
    when ``members`` is not empty (segment ``k``'s weights were those of the particles
    ``members[start[k]:start[k + 1]]``). One segment is the whole cloud's inversion
    (:class:`Scratch`); the mixture filter's components are several
    (:func:`hmmtrack.tracking.mixture.resample_components`; :class:`Segments` does the same
    chunk by chunk in the pass that gathers the new particles). Any split of the points
    into chunks gives the same ancestors, so they do not depend on ``threads``.

    Parameters
    ----------
    cumulative, points : numpy.ndarray
        From :func:`prepare_points`, segment after segment.
    start : numpy.ndarray, shape (K + 1,) int64
    at : numpy.ndarray, shape (K + 1,) int64
    last : numpy.ndarray, shape (K,) int64
    members : numpy.ndarray, shape (start[K],) or (0,), int64
    threads : int
    out : numpy.ndarray, shape (at[K],) int64
    """
    args = (cumulative, points, start, at, last, members)
    in_chunks(_merge_kernel, _merge_parallel, out.size, threads, args, out)


#: the work arrays' usual dtype (comparing with a dtype is faster than with ``np.float64``)
_FLOAT64 = np.dtype(np.float64)


class Scratch:
    """Work arrays of the inverse-CDF schemes (multinomial, stratified, systematic), reused
    from one resampling to the next, and the threads they run on.

    A filter resamples its N particles hundreds of times with the same scheme; fresh work
    arrays each time (the points, the cumulative weights, the random numbers) are paged in
    afresh once they are large (at N = 100,000, about 2 ms a resampling on this machine's
    VM). With a ``Scratch`` only the ancestors are a new array. The inversion runs in the
    chunks of :mod:`hmmtrack.tracking.compiled.chunks` on ``threads`` threads; the
    ancestors do not depend on it.
    """

    def __init__(self, threads: int = 1) -> None:
        self.threads = threads
        self._arrays: dict[str, np.ndarray] = {}
        self._turns: dict[str, int] = {}

    def array(self, name: str, size: int) -> np.ndarray:
        """The float work array ``name`` with ``size`` entries (its contents undefined)."""
        return self._kept(name, size, _FLOAT64)

    def alternate(self, name: str, size: int, dtype: np.dtype = _FLOAT64) -> np.ndarray:
        """Of two work arrays ``name`` with ``size`` entries, the one the previous call did
        not return (its contents undefined): for results that must outlive the next
        resampling but not the one after it (the mixture's new log weights, weights and
        labels, :meth:`hmmtrack.tracking.mixture.Mixture.finish`), so that none is a fresh
        array to fault in."""
        turn = self._turns.get(name, 0)
        self._turns[name] = 1 - turn
        return self._kept(f"{name} {turn}", size, dtype)

    def _kept(self, key: str, size: int, dtype) -> np.ndarray:
        """The work array ``key``, made anew when it has not ``size`` entries of ``dtype``."""
        array = self._arrays.get(key)
        if array is None or array.size != size or array.dtype != dtype:
            array = self._arrays[key] = np.empty(size, dtype=dtype)
        return array

    def steps(self, n: int) -> np.ndarray:
        """``0., 1., ..., n - 1.`` (n,) (read-only: the strata of the evenly spaced
        schemes)."""
        array = self._arrays.get("steps")
        if array is None or array.size != n:
            array = self._arrays["steps"] = np.arange(n, dtype=np.float64)
            array.flags.writeable = False
        return array

    def exponentials(self, rng: np.random.Generator, size: int) -> np.ndarray:
        """``rng.standard_exponential(size)`` into a work array."""
        return rng.standard_exponential(size, out=self.array("values", size))

    def prepare(self, inversion: Inversion) -> Prepared:
        """``inversion``'s cumulative weights and points (:func:`prepare_points`, into work
        arrays), ready to be merged chunk by chunk."""
        cumulative = self.array("cumulative", inversion.weights.size)
        points = self.array("points", inversion.n)
        return Prepared(cumulative, points, _prepare_into(*inversion, cumulative, points))


class Inversion(NamedTuple):
    """An inverse-CDF scheme's draw: the ascending points ``values[k] * value_scale``
    (``running`` False) or ``(values[0] + ... + values[k]) * value_scale`` (``running``
    True: the order statistics from spacings), ``n`` of them, to be inverted against the
    cumulative sum of ``weights * weight_scale`` (:func:`invert`)."""

    weights: np.ndarray
    weight_scale: float
    values: np.ndarray
    n: int
    value_scale: float
    running: bool


class Prepared(NamedTuple):
    """An inversion ready to merge (:meth:`Scratch.prepare`): the cumulative weights (M,)
    (``inf`` at ``last``), the ascending points (n,) and the last index of positive weight.
    As the ``locate`` of :meth:`hmmtrack.tracking.particles.Particles.take`, each chunk of
    the new particles finds its ancestors by :func:`merge_points` in the pass that gathers
    it (:func:`_merge_chunk`)."""

    cumulative: np.ndarray
    points: np.ndarray
    last: int


@overload(chunk_ancestors)
def _merge_chunk(locate, lo, hi, ancestors):
    """:func:`~hmmtrack.tracking.compiled.chunks.chunk_ancestors` of :class:`Prepared`: the
    points ``lo:hi`` merged with the cumulative weights (the same ancestors as one merge of
    all of them)."""
    if not (isinstance(locate, types.BaseNamedTuple) and locate.instance_class is Prepared):
        return None

    def merge(locate, lo, hi, ancestors):
        merge_points(locate.cumulative, locate.points, ancestors, lo, hi, 0, locate.last)

    return merge


class Segments(NamedTuple):
    """Several inversions ready to merge (:func:`merge_segments`' arguments): as the
    ``locate`` of :meth:`hmmtrack.tracking.particles.Particles.take`, each chunk of the new
    particles finds its ancestors by :func:`merge_chunk` in the pass that gathers it (the
    mixture filter's components, :meth:`hmmtrack.tracking.mixture.Mixture.draw`)."""

    cumulative: np.ndarray
    points: np.ndarray
    start: np.ndarray
    at: np.ndarray
    last: np.ndarray
    members: np.ndarray


@overload(chunk_ancestors)
def _merge_segments_chunk(locate, lo, hi, ancestors):
    """:func:`~hmmtrack.tracking.compiled.chunks.chunk_ancestors` of :class:`Segments`."""
    if not (isinstance(locate, types.BaseNamedTuple) and locate.instance_class is Segments):
        return None

    def merge(locate, lo, hi, ancestors):
        merge_chunk(
            locate.cumulative, locate.points, locate.start, locate.at, locate.last,
            locate.members, lo, hi, ancestors,
        )  # fmt: skip

    return merge


#: "the segments' indices are the particles'" (:func:`merge_segments`' ``members``)
_NO_MEMBERS = np.zeros(0, dtype=np.int64)


def _invert_with(scratch, weights, weight_scale, values, n, value_scale, running):
    """:func:`invert` into ``scratch``'s arrays (``None``: :func:`invert` itself), its merge
    on ``scratch.threads`` threads."""
    if scratch is None:
        return invert(weights, weight_scale, values, n, value_scale, running)
    cumulative, points, last = scratch.prepare(
        Inversion(weights, weight_scale, values, n, value_scale, running)
    )
    out = np.empty(n, dtype=np.int64)
    whole = np.array([0, weights.size], dtype=np.int64), np.array([0, n], dtype=np.int64)
    merge_segments(cumulative, points, *whole, np.array([last]), _NO_MEMBERS, scratch.threads, out)
    return out


def inverse_cdf(weights: np.ndarray, sorted_points: np.ndarray) -> np.ndarray:
    """Ancestors for ascending points in ``[0, 1)`` by inverting the weights' cumulative sum.

    Equal to ``np.searchsorted(cumsum(weights), points, side="right")``, clipped to the
    last index of positive weight (so that rounding in the cumulative sum can neither lose
    a point nor pick a weightless particle), in linear time (compiled).

    Parameters
    ----------
    weights : (M,) float
        Normalised weights (sum one).
    sorted_points : (n,) float
        Ascending points in ``[0, 1)``.

    Returns
    -------
    (n,) int64 indices into ``weights``, ascending.
    """
    points = np.asarray(sorted_points, dtype=np.float64)
    return invert(np.asarray(weights, dtype=np.float64), 1.0, points, points.size, 1.0, False)


def _evenly_spaced(
    rng: np.random.Generator, n: int, scratch: Scratch | None, shared: bool
) -> np.ndarray:
    """The points ``(k + u_k) / n``, ``k = 0..n-1`` (ascending): one uniform ``u_k`` per
    stratum, or one shared by all (``shared``)."""
    if scratch is None:
        return (np.arange(n) + (rng.random() if shared else rng.random(n))) / n
    points = scratch.array("values", n)
    if shared:
        np.add(scratch.steps(n), rng.random(), out=points)
    else:
        np.add(rng.random(n, out=points), scratch.steps(n), out=points)
    points /= n
    return points


def multinomial(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> np.ndarray:
    """Draw ``n`` ancestors independently with probabilities ``weights``.

    The ``n`` uniforms are drawn already sorted (normalised cumulative sums of ``n + 1``
    standard exponentials are the order statistics of ``n`` uniforms), so inverting the
    cumulative weights takes one linear pass, which also forms the sums.

    Parameters
    ----------
    rng : numpy.random.Generator
    weights : (M,) array of float
        Non-negative weights; normalised here.
    n : int
        Number of ancestors to draw.
    scratch : Scratch, optional
        Work arrays and threads to use (a filter's); the
        ancestors do not depend on it.

    Returns
    -------
    (n,) int64 array of indices into ``weights``, sorted ascending.
    """
    return _invert_with(scratch, *multinomial_points(rng, weights, n, scratch))


def multinomial_points(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> Inversion:
    """:func:`multinomial`'s draw before its inversion (the same parameters)."""
    w, weight_scale = _checked_weights(weights)
    spacings = (
        rng.standard_exponential(n + 1) if scratch is None else scratch.exponentials(rng, n + 1)
    )
    return Inversion(w, weight_scale, spacings, n, 1.0 / spacings.sum(), True)


def stratified(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> np.ndarray:
    """Draw one ancestor in each stratum ``[k/n, (k+1)/n)``, ``k = 0..n-1``.

    Parameters and return value as :func:`multinomial`.
    """
    return _invert_with(scratch, *stratified_points(rng, weights, n, scratch))


def stratified_points(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> Inversion:
    """:func:`stratified`'s draw before its inversion (the same parameters)."""
    w, weight_scale = _checked_weights(weights)
    return Inversion(w, weight_scale, _evenly_spaced(rng, n, scratch, shared=False), n, 1.0, False)


def systematic(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> np.ndarray:
    """Draw ancestors at the evenly spaced points ``(k + u) / n`` with one shared ``u``.

    Index ``i`` appears ``floor(n w_i)`` or ``ceil(n w_i)`` times.
    Parameters and return value as :func:`multinomial`.
    """
    return _invert_with(scratch, *systematic_points(rng, weights, n, scratch))


def systematic_points(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> Inversion:
    """:func:`systematic`'s draw before its inversion (the same parameters)."""
    w, weight_scale = _checked_weights(weights)
    return Inversion(w, weight_scale, _evenly_spaced(rng, n, scratch, shared=True), n, 1.0, False)


def residual(
    rng: np.random.Generator, weights: np.ndarray, n: int, scratch: Scratch | None = None
) -> np.ndarray:
    """Keep ``floor(n w_i)`` copies of each index, draw the remainder multinomially.

    Parameters and return value as :func:`multinomial` (``scratch`` is not used).
    """
    w, weight_scale = _checked_weights(weights)
    expected = n * (w * weight_scale)
    copies = np.floor(expected).astype(np.int64)
    n_left = n - int(copies.sum())
    if n_left > 0:
        left, left_scale = _checked_weights(expected - copies)
        copies += rng.multinomial(n_left, left * left_scale)
    return np.repeat(np.arange(w.size, dtype=np.int64), copies)


Resampler = Callable[..., np.ndarray]

RESAMPLERS: dict[str, Resampler] = {
    "multinomial": multinomial,
    "residual": residual,
    "stratified": stratified,
    "systematic": systematic,
}


#: the inverse-CDF schemes' draws before their inversion, by name: a caller that merges the
#: points itself (the particle filter, in the pass that gathers the new particles) runs
#: ``Scratch.prepare`` and hands the :class:`Prepared` to ``Particles.take``
POINTS: dict[str, Callable[..., Inversion]] = {
    "multinomial": multinomial_points,
    "stratified": stratified_points,
    "systematic": systematic_points,
}


def get_resampler(name: str) -> Resampler:
    """Return the resampling function registered under ``name`` (see :data:`RESAMPLERS`)."""
    try:
        return RESAMPLERS[name]
    except KeyError:
        raise ValueError(
            f"unknown resampling scheme {name!r}; expected one of {sorted(RESAMPLERS)}"
        ) from None


def effective_sample_size(log_weights: np.ndarray) -> float:
    """Kish's effective sample size ``1 / sum(w_i^2)`` of normalised weights.

    Parameters
    ----------
    log_weights : (M,) array of float
        Unnormalised log weights; ``-inf`` marks impossible particles.

    Returns
    -------
    float in ``[1, M]``, or ``0.0`` when every particle is impossible.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    if np.any(np.isnan(lw)) or np.any(lw == np.inf):
        raise ValueError("log weights must be finite or -inf, got NaN or +inf")
    top = lw.max()
    if not np.isfinite(top):
        return 0.0
    w = np.exp(lw - top)
    return float(w.sum() ** 2 / (w @ w))


def log_normalise(log_weights: np.ndarray) -> np.ndarray:
    """Log weights minus their log-sum-exp, so that their exponentials sum to one.

    Parameters
    ----------
    log_weights : (M,) array of float, with a finite maximum

    Returns
    -------
    (M,) float array; ``-inf`` entries stay ``-inf``.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    top = lw.max()
    if not np.isfinite(top):
        raise ValueError(f"cannot normalise log weights whose maximum is {top}")
    return lw - (top + np.log(np.exp(lw - top).sum()))
