"""Chunked parallel runs of compiled particle kernels: the plumbing shared by the motion kernels
and the correction (:mod:`hmmtrack.tracking.compiled.weighing`).

A compiled motion kernel (:mod:`hmmtrack.tracking.motion`) moves ``N`` particles ``n_steps``
prediction steps and sums their weighted position moments after every step. This module
splits the particles into fixed chunks (:func:`chunking`: the split depends on ``N`` only),
lets threads claim the chunks one at a time (:func:`next_chunk`, an atomic counter), and
runs a kernel and its parallel twin over them (:func:`in_chunks`; :func:`run_chunks` for the
motion kernels' sums), minding numba's threading layers (the "workqueue" layer's lock,
OpenMP after a fork). Every chunk writes its own particles and its own row of sums, reduced
in a fixed order, so results do not depend on the number of threads.

It knows nothing of motion models or random numbers (:mod:`hmmtrack.tracking.compiled.streams`).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import numba
import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = [
    "GOMP_SPINCOUNT",
    "MIN_CHUNK",
    "N_CHUNKS",
    "N_MOMENTS",
    "chunking",
    "block_threads",
    "chunk_ancestors",
    "default_threads",
    "in_chunks",
    "moments_pass",
    "next_chunk",
    "run_chunks",
]

#: the compiled kernels split particles into at most this many chunks (one partial sum
#: each), of at least MIN_CHUNK particles; the split depends on N only, so that sums, hence
#: estimates, do not depend on how many threads run them (sizes chosen by timing,
#: ``reports/decisions.md``, "Motion models")
N_CHUNKS = 64
MIN_CHUNK = 1024
#: moments returned per step: sum w dx, sum w dy, sum w dx^2, sum w dy^2, sum w dx dy
N_MOMENTS = 5


# ``reassoc`` lets LLVM split the sums into vector lanes; the order of operations is still
# fixed by the code, so a chunk's sums do not depend on the number of threads
@njit(cache=True, fastmath={"reassoc"})
def moments_pass(x, y, weights, ox, oy, sums):
    """``sums[:] = (sum w dx, sum w dy, sum w dx^2, sum w dy^2, sum w dx dy)`` over the
    particles, with ``dx = x - ox``, ``dy = y - oy`` (metres)."""
    s0 = s1 = s2 = s3 = s4 = 0.0
    for i in range(x.size):
        dx = x[i] - ox
        dy = y[i] - oy
        wdx = weights[i] * dx
        wdy = weights[i] * dy
        s0 += wdx
        s1 += wdy
        s2 += wdx * dx
        s3 += wdy * dy
        s4 += wdx * dy
    sums[0] = s0
    sums[1] = s1
    sums[2] = s2
    sums[3] = s3
    sums[4] = s4


@njit(cache=True, inline="always")
def chunking(n):
    """Number of chunks and particles per chunk for ``n`` particles."""
    size = max(MIN_CHUNK, (n + N_CHUNKS - 1) // N_CHUNKS)
    return (n + size - 1) // size, size


@intrinsic
def _fetch_add(typingctx, counter, index, value):
    """``counter[index] += value`` as one atomic operation, ordered with every other memory
    access of the thread (safe between threads); returns the value before the addition.
    ``counter`` is an int64 array; ``value`` 0 reads the counter atomically."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64):
        return None

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        position = context.cast(builder, args[1], signature.args[1], types.intp)
        pointer = cgutils.get_item_pointer(context, builder, array_type, array, [position])
        amount = context.cast(builder, args[2], signature.args[2], types.int64)
        return builder.atomic_rmw("add", pointer, amount, "seq_cst")

    return types.int64(counter, index, value), codegen


@njit(cache=True, inline="always")
def next_chunk(counter, n):
    """Claim the next chunk of ``n`` particles not yet claimed by any thread:
    ``(chunk, lo, hi)``, the particles ``lo:hi``; ``chunk`` is -1 once all are claimed.
    ``counter`` (int64, 1) holds the chunks claimed, starting at 0."""
    n_chunks, size = chunking(n)
    chunk = _fetch_add(counter, 0, 1)
    if chunk >= n_chunks:
        return -1, 0, 0
    return chunk, chunk * size, min(n, (chunk + 1) * size)


def chunk_ancestors(locate, lo, hi, ancestors):
    """``ancestors[lo:hi] =`` the ancestors of the new particles ``lo:hi`` of a resampling,
    found by ``locate`` in the pass that gathers them
    (:meth:`hmmtrack.tracking.particles.Particles.take`).

    Compiled only: a resampling registers its implementation for its own ``NamedTuple``
    class of ``locate`` (``numba.extending.overload(chunk_ancestors)``, returning ``None``
    for other types; :class:`hmmtrack.tracking.resampling.Prepared`, the inverse CDF's
    merge). The ancestors must not depend on the chunks. The gather kernel compiles the
    implementation into itself: after editing it, clear numba's cache.
    """
    raise TypeError("chunk_ancestors runs in compiled kernels only (Particles.take calls it)")


#: how many times an idle OpenMP thread of GNU libgomp (numba's "omp" layer here) polls for
#: work before it sleeps, unless the environment sets it: libgomp's default (300,000, about
#: 3 ms) keeps a thread spinning through every serial stretch of a filter cycle, which on a
#: busy machine takes the core from the thread doing the serial work (two threads ran 4-10x
#: slower than one); a short spin keeps the thread awake between the closely spaced regions
#: of a correction (reports/decisions.md, "Velocity at 10,000: the cycle's budget"). Set
#: here, at import, because libgomp reads it once, when numba first loads it
GOMP_SPINCOUNT = "3000"
os.environ.setdefault("GOMP_SPINCOUNT", GOMP_SPINCOUNT)

#: numba's "workqueue" threading layer (its fallback where neither OpenMP nor TBB can be
#: loaded) aborts the process when two threads start parallel work at once: parallel kernel
#: calls then hold this lock, and a call that finds it taken runs on its own thread instead
_WORKQUEUE_LOCK = threading.Lock()
#: whether this process has run kernels on GNU OpenMP threads. OpenMP is not fork-safe:
#: numba ends a forked child that starts OpenMP work its parent had started, so such a
#: child (a ``multiprocessing`` fork) runs every kernel on its own thread
_OPENMP_STARTED = False
_FORKED_AFTER_OPENMP = False


def _note_fork() -> None:
    global _FORKED_AFTER_OPENMP
    _FORKED_AFTER_OPENMP = _FORKED_AFTER_OPENMP or _OPENMP_STARTED


os.register_at_fork(after_in_child=_note_fork)


#: the thread count of :func:`in_chunks` calls that name none, per Python thread, while a
#: :func:`default_threads` block runs (else numba's thread count of the calling thread)
_DEFAULT = threading.local()


@contextmanager
def default_threads(threads: int) -> Iterator[None]:
    """Run the :func:`in_chunks` calls of this block that name no thread count (e.g. a
    measurement's log-likelihood, whose ``loglik`` has no thread argument) on ``threads``
    threads: how :class:`hmmtrack.tracking.filter.ParticleFilter` puts its measurement's
    chunked kernels on the threads of its corrections. Only speed depends on it."""
    outer = getattr(_DEFAULT, "threads", None)
    _DEFAULT.threads = threads
    try:
        yield
    finally:
        _DEFAULT.threads = outer


def block_threads(otherwise: int | None) -> int | None:
    """The thread count of the enclosing :func:`default_threads` block, else ``otherwise``."""
    return getattr(_DEFAULT, "threads", None) or otherwise


def run_chunks(kernel, parallel, n: int, n_steps: int, threads: int | None, *args) -> np.ndarray:
    """Run ``kernel(*args, counter, sums)`` over all chunks of ``n`` particles
    (:func:`in_chunks`) and return the weighted moments ``(n_steps, 5)`` (the per-chunk sums
    reduced in a fixed order)."""
    sums = np.zeros((chunking(n)[0], n_steps, N_MOMENTS))
    in_chunks(kernel, parallel, n, threads, args, sums)
    return sums.sum(axis=0)


def in_chunks(kernel, parallel, n: int, threads: int | None, args: tuple, out) -> None:
    """Run ``kernel(*args, counter, out)`` over all chunks of ``n`` particles.

    With ``threads`` > 1 (``None``: that of the enclosing :func:`default_threads` block, else
    ``numba.get_num_threads()``), ``parallel(threads, *args, counter, out)`` (plain tuple
    arguments spread into their items, named tuples passed whole) runs the kernel on that
    many threads of numba's threading layer at once (OpenMP's threads wait awake for a while
    between calls, so a call starts in a few microseconds), each claiming the next unclaimed
    chunk whenever it finishes one (:func:`next_chunk`): a thread that starts
    late or is slowed by other work on the machine simply runs fewer chunks. Every chunk
    writes its own particles and its own row of ``out``, so the results do not depend on
    which thread ran it. Under numba's "workqueue" layer only one Python thread at a time
    runs kernels in parallel, the others run them on their own thread; in a process forked
    after this one started OpenMP threads, every call runs on the calling thread.
    """
    global _OPENMP_STARTED
    counter = np.zeros(1, dtype=np.int64)
    if threads is None:
        threads = block_threads(None)
    if threads == 1:  # straight to the kernel: asking numba for its threads costs more
        kernel(*args, counter, out)
        return
    n_chunks, _ = chunking(n)
    previous = numba.get_num_threads()  # of this thread (numba's default: all); starts the layer
    threads = previous if threads is None else threads
    threads = max(1, min(threads, n_chunks, numba.config.NUMBA_NUM_THREADS))
    if threads > 1 and not _FORKED_AFTER_OPENMP:
        layer = numba.threading_layer()
        exclusive = layer == "workqueue"
        if not exclusive or _WORKQUEUE_LOCK.acquire(blocking=False):
            _OPENMP_STARTED = _OPENMP_STARTED or layer == "omp"
            # plain tuples of arrays (the von Mises tables) are passed to ``parallel`` as their
            # items; named tuples (a measurement's arguments of weighing.chunk_loglik) whole
            flat = [item for arg in args for item in (arg if type(arg) is tuple else (arg,))]
            try:
                # Load the serial kernel before its parallel twin (a call with every chunk
                # already claimed does nothing): a twin loaded first from numba's on-disk
                # cache runs a slower copy of its own (reports/decisions.md, "Motion models")
                kernel(*args, np.array([n_chunks], dtype=np.int64), out)
                if previous != threads:
                    numba.set_num_threads(threads)
                parallel(threads, *flat, counter, out)
            finally:
                if previous != threads:
                    numba.set_num_threads(previous)
                if exclusive:
                    _WORKQUEUE_LOCK.release()
            return
    kernel(*args, counter, out)
