"""The particle filter's correction arithmetic, compiled, in chunks that run on several threads.

A correction adds a log-likelihood (N,) to the particles' log weights, normalises them by
their log-sum-exp and summarises the weights: the weighted mean and covariance of the
positions and the effective sample size (ESS). :func:`weigh` does it in four passes over the
particles, three of them in the chunks of :mod:`hmmtrack.tracking.compiled.chunks` on as many
threads as asked (:func:`~hmmtrack.tracking.compiled.chunks.in_chunks`), all in one compiled
call:

1. per chunk: the measurement's log-likelihood when it is computed here (below), the updated
   log weights, whether the log-likelihood has NaN or ``+inf`` entries, and the chunk's
   largest log weight (its first index);
2. per chunk: the weights ``exp(log weight - largest)``;
3. on one thread: the sums of the weights, of their position moments about the heaviest
   particle and of their squares (:func:`moment_sums`). These sums feed back into the filter
   (normalisation, resampling, every later estimate); summed per chunk and combined they
   would differ in their last bits from the one vectorised order of this pass, which is
   the order the filter has always used (its stored golden runs);
4. per chunk: the weights divided by their sum (a division, not a multiplication by its
   reciprocal: the filter's order since its moments pass let LLVM turn one into the other)
   and the log weights minus their log-sum-exp.

Every chunk writes only its own particles and its own row of results, combined in chunk order,
so the results do not depend on the number of threads; they are bit for bit those of the
NumPy composition (``log_weight + loglik``, ``np.argmax``, ``np.exp``, one pass of sums).

A measurement whose log-likelihood is a compiled loop over particles can have it computed in
the first pass, chunk by chunk, instead of in a pass (and a parallel region) of its own: it
registers an implementation of :func:`chunk_loglik` for a ``NamedTuple`` class of its own
holding the particle arrays and constants the loop reads (numba's ``overload``, chosen by that
class), and hands :func:`weigh` an instance as ``scored``. :func:`loglik_chunks` runs the same
implementation alone (for the grid of an acquisition, a recovery, tests). A function passed
as an argument would do the same, but numba does not cache a kernel compiled for a function
argument (it recompiles in every process).

It knows nothing of particular measurements or of resampling schemes.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit

from hmmtrack.tracking.compiled.chunks import block_threads, chunking, in_chunks, next_chunk

__all__ = ["add_weighted", "chunk_loglik", "loglik_chunks", "moment_sums", "weigh"]

#: the passes of :func:`_weigh_kernel`
_UPDATE, _EXPONENTIALS, _NORMALISE = 0, 1, 2


def chunk_loglik(scored, lo, hi, out):
    """``out[:] =`` a measurement's log-likelihood (one correction's observations) of the
    particles ``lo:hi``; ``out`` has ``hi - lo`` entries.

    Compiled only: each measurement that offers it registers its implementation for its
    own ``NamedTuple`` class of ``scored`` (``numba.extending.overload(chunk_loglik)``,
    returning ``None`` for other types), which holds the particle arrays (N,) and the
    constants it reads. Each particle's value must be computed alone, so that it does not
    depend on the chunks. The kernels here compile the implementation into themselves:
    after editing it, clear numba's cache (their cached copies are not refreshed).
    """
    raise TypeError("chunk_loglik runs in compiled kernels only (weighing.loglik_chunks calls it)")


@njit(cache=True, nogil=True)
def _weigh_kernel(
    phase, log_weight, loglik, add, scored, updated, weights, top, total, shift, counter, found
):  # fmt: skip
    """One pass over every chunk not yet claimed (:func:`next_chunk`).

    ``_UPDATE``: ``loglik`` of the chunk from ``scored`` (:func:`chunk_loglik`, unless
    ``None``), ``updated = log_weight + loglik`` (``add``; else a copy of ``log_weight``),
    ``found[chunk] = (whether loglik has NaN or +inf, index of the chunk's first largest
    updated log weight, that log weight)``. ``_EXPONENTIALS``: ``weights = exp(updated -
    top)``. ``_NORMALISE``: ``weights /= total``, ``updated -= shift``.
    """
    n = updated.size
    chunk, lo, hi = next_chunk(counter, n)
    while chunk >= 0:
        # loops over views of the chunk, not over lo:hi of the whole arrays: 2-3x faster
        # (reports/decisions.md, "Resampling and correction passes")
        chunk_updated = updated[lo:hi]
        if phase == _UPDATE:
            bad = False
            chunk_log_weight = log_weight[lo:hi]
            if add:
                chunk_scores = loglik[lo:hi]
                if scored is not None:  # pruned when compiled for None
                    chunk_loglik(scored, lo, hi, chunk_scores)
                for i in range(chunk_updated.size):
                    li = chunk_scores[i]
                    bad |= not li < np.inf
                    chunk_updated[i] = chunk_log_weight[i] + li
            else:
                chunk_updated[:] = chunk_log_weight
            k = 0
            largest = chunk_updated[0]
            for i in range(1, chunk_updated.size):
                if chunk_updated[i] > largest:
                    largest = chunk_updated[i]
                    k = i
            found[chunk, 0] = bad
            found[chunk, 1] = lo + k
            found[chunk, 2] = largest
        elif phase == _EXPONENTIALS:
            chunk_weights = weights[lo:hi]
            for i in range(chunk_updated.size):
                chunk_weights[i] = math.exp(chunk_updated[i] - top)
        else:
            chunk_weights = weights[lo:hi]
            for i in range(chunk_updated.size):
                chunk_weights[i] /= total
                chunk_updated[i] -= shift
        chunk, lo, hi = next_chunk(counter, n)


@njit(cache=True, nogil=True, inline="always")
def add_weighted(s, sx, sy, sxx, syy, sxy, w, dx, dy):
    """The sums ``s, sx, sy, sxx, syy, sxy`` of weights and weighted moments, plus a point of
    weight ``w`` at ``(dx, dy)`` from their origin: ``s + w, sx + w dx, sy + w dy,
    sxx + w dx², syy + w dy², sxy + w dx dy`` (inlined: each caller's loop keeps the sums
    in registers, in its own order of additions)."""
    return (
        s + w,
        sx + w * dx,
        sy + w * dy,
        sxx + w * dx * dx,
        syy + w * dy * dy,
        sxy + w * dx * dy,
    )


# ``reassoc`` lets LLVM split the sums into vector lanes (4-5x faster than one serial chain
# of additions); the result is still one fixed order of operations for a given input
@njit(cache=True, fastmath={"reassoc"})
def moment_sums(w, x, y, k):
    """The sum ``s`` of the weights ``w`` (N,), the weighted mean, variances and covariance
    of ``(x, y)`` (N,) (m, m^2) and the ESS ``s^2 / sum w^2``.

    The moments are taken about particle ``k`` (the heaviest: inside the cloud, so no
    cancellation far from the origin)."""
    x0 = x[k]
    y0 = y[k]
    s = sx = sy = sxx = syy = sxy = sww = 0.0
    for i in range(w.size):
        wi = w[i]
        s, sx, sy, sxx, syy, sxy = add_weighted(s, sx, sy, sxx, syy, sxy, wi, x[i] - x0, y[i] - y0)
        sww += wi * wi
    mx, my = sx / s, sy / s
    var_x = max(sxx / s - mx * mx, 0.0)
    var_y = max(syy / s - my * my, 0.0)
    return s, x0 + mx, y0 + my, var_x, var_y, sxy / s - mx * my, s * s / sww


@njit(cache=True, nogil=True)
def _largest(add, found):
    """``(status, k, top)`` from the chunks' rows of ``found`` (:func:`_weigh_kernel`):
    status 1 when a chunk found NaN or ``+inf`` in the log-likelihood, 2 when the largest
    log weight ``top`` is ``-inf``, else 0; ``k`` its first index (``np.argmax``'s)."""
    if add and found[:, 0].any():
        return 1, 0, 0.0
    best = np.argmax(found[:, 2])  # the first chunk with the largest
    k, top = int(found[best, 1]), found[best, 2]
    return (2 if top == -np.inf else 0), k, top


@njit(cache=True, nogil=True)
def _weigh_serial(
    log_weight, loglik, add, scored, x, y, updated, weights, result, counter, found
):  # fmt: skip
    """:func:`weigh`'s passes on the calling thread; ``result[:] = (status, log_total, mean
    x, mean y, var x, var y, cov xy, ESS)``. Does nothing when ``counter`` says every chunk
    was claimed (how :func:`~hmmtrack.tracking.compiled.chunks.in_chunks` loads it)."""
    if counter[0] > 0:
        return
    args = (log_weight, loglik, add, scored, updated, weights)
    _weigh_kernel(_UPDATE, *args, 0.0, 0.0, 0.0, counter, found)
    status, k, top = _largest(add, found)
    result[0] = status
    if status:
        return
    counter[0] = 0
    _weigh_kernel(_EXPONENTIALS, *args, top, 0.0, 0.0, counter, found)
    summary = moment_sums(weights, x, y, k)
    log_total = top + math.log(summary[0])
    counter[0] = 0
    _weigh_kernel(_NORMALISE, *args, top, summary[0], log_total, counter, found)
    result[1] = log_total
    result[2:] = np.array(summary[1:])


@njit(cache=True, nogil=True, parallel=True)
def _weigh_parallel(
    threads, log_weight, loglik, add, scored, x, y, updated, weights, result, counter, found
):  # fmt: skip
    """:func:`_weigh_serial` with the chunked passes on ``threads`` threads."""
    for _ in numba.prange(threads):
        _weigh_kernel(
            _UPDATE, log_weight, loglik, add, scored, updated, weights, 0.0, 0.0, 0.0,
            counter, found,
        )  # fmt: skip
    status, k, top = _largest(add, found)
    result[0] = status
    if status == 0:
        counter[0] = 0
        for _ in numba.prange(threads):
            _weigh_kernel(
                _EXPONENTIALS, log_weight, loglik, add, scored, updated, weights, top, 0.0,
                0.0, counter, found,
            )  # fmt: skip
        summary = moment_sums(weights, x, y, k)
        log_total = top + math.log(summary[0])
        counter[0] = 0
        for _ in numba.prange(threads):
            _weigh_kernel(
                _NORMALISE, log_weight, loglik, add, scored, updated, weights, top,
                summary[0], log_total, counter, found,
            )  # fmt: skip
        result[1] = log_total
        result[2:] = np.array(summary[1:])


def weigh(log_weight, loglik, x, y, threads: int = 1, out=None, scored=None):
    """Log weights plus a log-likelihood, normalised, with their weights' summary.

    Parameters
    ----------
    log_weight : numpy.ndarray, shape (N,)
        Log weights (finite or ``-inf``).
    loglik : numpy.ndarray, shape (N,), or None
        Log-likelihood to add; ``None``: summarise ``log_weight`` itself. With ``scored``,
        the float64 array that receives the log-likelihood computed here.
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    threads : int
        Threads for the chunked passes (results do not depend on it).
    out : (numpy.ndarray, numpy.ndarray), optional
        Two float64 arrays (N,), neither of them ``log_weight``, that receive the log weights
        and the weights (reused arrays: a fresh array of 100,000 entries costs more to page
        in than this whole call); default: new arrays.

    Returns
    -------
    status : int
        0 (done), 1 (``loglik`` has NaN or ``+inf`` entries) or 2 (every updated log weight
        is ``-inf``: every particle impossible); the rest is ``None`` unless 0.
    log_weight : numpy.ndarray, shape (N,)
        The updated log weights minus their log-sum-exp (``out[0]`` when given).
    weights : numpy.ndarray, shape (N,)
        Their exponentials, summing to one (``out[1]`` when given).
    log_total : float
        The log-sum-exp of the updated log weights.
    summary : list of float
        Weighted mean x, y (m), variances of x and y and their covariance (m^2), ESS.
    """
    n = log_weight.size
    add = loglik is not None
    updated, weights = (np.empty(n), np.empty(n)) if out is None else out
    result = np.empty(8)
    args = (log_weight, loglik if add else log_weight, add, scored, x, y, updated, weights, result)
    in_chunks(_weigh_serial, _weigh_parallel, n, threads, args, np.empty((chunking(n)[0], 3)))
    status = int(result[0])
    if status:
        return status, None, None, None, None
    return 0, updated, weights, float(result[1]), result[2:].tolist()


@njit(cache=True, nogil=True)
def _loglik_kernel(scored, counter, out):
    """:func:`chunk_loglik` of every chunk of ``out`` (N,) not yet claimed (:func:`next_chunk`)."""
    chunk, lo, hi = next_chunk(counter, out.size)
    while chunk >= 0:
        chunk_loglik(scored, lo, hi, out[lo:hi])
        chunk, lo, hi = next_chunk(counter, out.size)


@njit(cache=True, nogil=True, parallel=True)
def _loglik_parallel(threads, scored, counter, out):
    """:func:`_loglik_kernel` on ``threads`` threads."""
    for _ in numba.prange(threads):
        _loglik_kernel(scored, counter, out)


def loglik_chunks(scored, n: int) -> np.ndarray:
    """A measurement's log-likelihood (N,) of ``n`` particles from its :func:`chunk_loglik`
    arguments ``scored``, in chunks on the threads of the enclosing
    :func:`~hmmtrack.tracking.compiled.chunks.default_threads` block, else on one (the same
    values on any number)."""
    out = np.empty(n)
    in_chunks(_loglik_kernel, _loglik_parallel, n, block_threads(1), (scored,), out)
    return out
