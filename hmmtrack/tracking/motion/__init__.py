"""Motion models of the tracking filter: how particles move between corrections.

Three models from the paper's section "Motion Models", each with the same two entry points:

``propagate(rng, particles, dt)``
    The reference implementation: one prediction step of ``dt`` seconds for all particles at
    once, written with NumPy arrays and a ``numpy.random.Generator``.
``advance(particles, streams, n_steps, dt, weights, origin, threads=None)``
    The fast path used by :class:`hmmtrack.tracking.filter.ParticleFilter`: ``n_steps`` prediction
    steps fused into one compiled (numba) kernel, run over fixed chunks of particles on
    ``threads`` threads (numba's parallel loop, one serial kernel call per thread, the
    threads claiming chunks as they go), that draws from the per-particle random streams of
    :mod:`hmmtrack.tracking.compiled.streams` and returns the weighted moments
    of the particle positions after every step, so that per-second estimates need no second
    pass over the particles. The kernels implement the same equations as ``propagate``;
    ``tests/test_motion.py`` checks them against each other with the same random draws.
    Inside a kernel each chunk of particles takes each step as a few branch-free passes that
    the compiler vectorises (draw the random numbers, move along the arcs with a polynomial
    arc, sum the moments), each followed by a scalar pass for the rare particles the fast
    path leaves (rejected draws, turns wider than :data:`WIDE_TURN`); the draws are exactly
    those of the scalar samplers of :mod:`hmmtrack.tracking.compiled.streams`.

Models
------
:class:`BaselineMotion`
    Random walk: Gaussian ``dx, dy`` with standard deviation ``sigma * sqrt(dt)``; heading,
    speed and turn rate derived from the step (the paper's equations; the heading change is
    wrapped into ``[-pi, pi)`` before dividing by ``dt``).
:class:`VelocityMotion`
    Gaussian increments of speed and turn rate (standard deviations ``sigma * sqrt(dt)``),
    then the constant-turn-rate arc (the paper's eqs. mm_xc..mm_theta), written in a form
    that tends to the straight line ``v dt (cos theta, sin theta)`` as ``omega -> 0``
    without cancellation (:func:`arc_displacement`).
:class:`HMMMotion`
    Per-particle behavioural state from a fitted :class:`hmmtrack.hmm.MovementHMM`; speed
    ``= step / model.dt`` and turn rate ``= angle / model.dt`` drawn from the state's
    distributions, then the arc. Two variants, see the class docstring:
    ``"time_consistent"`` (the default: the fitted time step respected at any prediction
    step, draw clocks staggered across particles) and ``"paper"`` (new state and new draws
    every prediction step, whatever ``model.dt``); optionally a heading random walk
    (``heading_diffusion``) on top of the fitted model.

The models do not read files, weigh or resample particles.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import warnings
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic
from scipy.linalg import fractional_matrix_power

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.particles import Particles

__all__ = [
    "BaselineMotion",
    "HMMMotion",
    "VelocityMotion",
    "arc_displacement",
    "transition_for_step",
]

logger = logging.getLogger(__name__)

#: below this |omega dt| the NumPy arc uses its Taylor series (first omitted term ~2e-16)
_SERIES_BELOW = 1e-2
#: the compiled kernels split particles into at most this many chunks (one partial sum
#: each), of at least MIN_CHUNK particles; the split depends on N only, so that sums, hence
#: estimates, do not depend on how many threads run them. Per particle-step on one thread,
#: chunks of 512 ran the HMM kernel 4-5 % faster than chunks of 256, and 1024 1-2 % faster
#: still; whole two-thread filter runs at N = 10,000 (10 chunks of 1024 to share) were 1-2 %
#: faster with 1024 than with 512
N_CHUNKS = 64
MIN_CHUNK = 1024
#: the HMM kernel draws with its vectorised passes for all particles of a chunk when more
#: than 1/SPARSE_DRAWS of them are due, else with the scalar samplers for the due ones only
SPARSE_DRAWS = 4
#: moments returned per step: sum w dx, sum w dy, sum w dx^2, sum w dy^2, sum w dx dy
N_MOMENTS = 5


# --------------------------------------------------------------------------- arc equations


def arc_displacement(
    cos_heading: np.ndarray, sin_heading: np.ndarray, arc_length: np.ndarray, turn_angle: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Displacement along a constant-turn-rate arc (NumPy reference).

    With ``phi = omega dt`` and arc length ``s = v dt``, the paper's eqs. mm_xc..mm_y give
    ``dx = (v/omega)(sin(theta + phi) - sin theta)`` and
    ``dy = -(v/omega)(cos(theta + phi) - cos theta)``, rewritten as
    ``dx = s (cos theta sinc(phi) - sin theta cosc(phi))`` and
    ``dy = s (sin theta sinc(phi) + cos theta cosc(phi))`` with
    ``sinc(phi) = sin(phi)/phi`` and ``cosc(phi) = (1 - cos phi)/phi``; both use their
    Taylor series for ``|phi| < 1e-2`` (error about 1e-16 relative), so ``phi = 0`` gives
    the straight line exactly.

    Parameters
    ----------
    cos_heading, sin_heading : (N,) float
        Heading at the start of the step.
    arc_length : (N,) float
        Distance travelled along the arc, ``v dt``, metres.
    turn_angle : (N,) float
        Heading change ``omega dt``, radians.

    Returns
    -------
    dx, dy : (N,) float, metres
    """
    phi = np.asarray(turn_angle, dtype=np.float64)
    phi2 = phi * phi
    small = np.abs(phi) < _SERIES_BELOW
    safe = np.where(small, 1.0, phi)
    sinc = np.where(small, 1.0 - phi2 / 6.0 * (1.0 - phi2 / 20.0), np.sin(safe) / safe)
    cosc = np.where(
        small, phi / 2.0 * (1.0 - phi2 / 12.0 * (1.0 - phi2 / 30.0)), (1.0 - np.cos(safe)) / safe
    )
    dx = arc_length * (cos_heading * sinc - sin_heading * cosc)
    dy = arc_length * (sin_heading * sinc + cos_heading * cosc)
    return dx, dy


def _move_along_arc(p: Particles, dt: float) -> None:
    """Move ``p`` in place for ``dt`` s along arcs of its speed and turn rate (NumPy)."""
    phi = p.turn_rate * dt
    dx, dy = arc_displacement(p.cos_heading, p.sin_heading, p.speed * dt, phi)
    p.x += dx
    p.y += dy
    cos_phi, sin_phi = np.cos(phi), np.sin(phi)
    c = p.cos_heading * cos_phi - p.sin_heading * sin_phi
    s = p.sin_heading * cos_phi + p.cos_heading * sin_phi
    p.cos_heading, p.sin_heading = c, s
    p.heading = np.arctan2(s, c)


# Taylor coefficients (-1)^k / (2k + 1)! of sinc(a) = sin(a) / a and (-1)^k / (2k + 2)! of
# (1 - cos a) / a^2, in powers of a^2 (multiplications, not divisions)
_SINC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(7))
_COSC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 2) for k in range(7))
#: half-angle doublings of the compiled arc: the series runs at ``phi / 2**4``
_DOUBLINGS = 4
#: the compiled arc's polynomial path covers ``|omega dt|`` up to this (rad); wider turns
#: (rare: more than 229 degrees in one step) use the library's sine and cosine
WIDE_TURN = 4.0


@njit(cache=True, inline="always")
def _series(c, a2):
    """``c[0] + c[1] a2 + ... + c[6] a2^6`` (Horner)."""
    return c[0] + a2 * (c[1] + a2 * (c[2] + a2 * (c[3] + a2 * (c[4] + a2 * (c[5] + a2 * c[6])))))


@njit(cache=True, inline="always")
def _arc_coefficients(phi):
    """``sinc(phi) = sin(phi)/phi`` and ``cosc(phi) = (1 - cos phi)/phi`` for
    ``|phi| <= WIDE_TURN``, branch-free (so that loops of it vectorise).

    The Taylor series at ``a = phi / 16`` (``|a| <= 0.25``: first omitted term below 1e-20
    relative), then four doublings ``sinc(2a) = sinc(a) (1 - a cosc(a))`` and
    ``cosc(2a) = a sinc(a)^2`` (from ``sin 2a = 2 sin a cos a`` and
    ``1 - cos 2a = 2 sin^2 a``): no cancellation anywhere, about 1e-15 absolute error, and
    ``phi = 0`` gives ``(1, 0)`` exactly (the straight line).
    """
    a = phi * (0.5**_DOUBLINGS)
    a2 = a * a
    sinc = _series(_SINC_SERIES, a2)
    cosc = a * _series(_COSC_SERIES, a2)
    for _ in range(_DOUBLINGS):
        sinc, cosc = sinc * (1.0 - a * cosc), a * sinc * sinc
        a = 2.0 * a
    return sinc, cosc


@njit(cache=True, inline="always")
def _arc_pass(x, y, c, s, heading, v, turn, dt):
    """Move particles in place for ``dt`` s along the arcs of speed ``v`` (m/s) and turn rate
    ``turn`` (rad/s), all arrays (n,) (the NumPy path's equations, :func:`arc_displacement`).

    A branch-free (vectorised) pass for turns up to :data:`WIDE_TURN`, then a scalar pass
    for the wider ones with the library's sine and cosine. ``(cos, sin)`` of the heading are
    rotated by ``phi``; ``heading`` gains ``phi`` (wrapped later, :func:`_finish_headings`).
    """
    for i in range(x.size):
        phi = turn[i] * dt
        length = v[i] * dt
        narrow = abs(phi) <= WIDE_TURN
        phi = phi if narrow else 0.0  # wide turns: no move here, see below
        length = length if narrow else 0.0
        sinc, cosc = _arc_coefficients(phi)
        ci = c[i]
        si = s[i]
        x[i] += length * (ci * sinc - si * cosc)
        y[i] += length * (si * sinc + ci * cosc)
        sin_phi = phi * sinc
        cos_phi = 1.0 - phi * cosc
        c[i] = ci * cos_phi - si * sin_phi
        s[i] = si * cos_phi + ci * sin_phi
        heading[i] += phi
    for i in range(x.size):
        phi = turn[i] * dt
        if abs(phi) > WIDE_TURN:
            length = v[i] * dt
            sin_phi = math.sin(phi)
            cos_phi = math.cos(phi)
            sinc = sin_phi / phi
            cosc = (1.0 - cos_phi) / phi
            ci = c[i]
            si = s[i]
            x[i] += length * (ci * sinc - si * cosc)
            y[i] += length * (si * sinc + ci * cosc)
            c[i] = ci * cos_phi - si * sin_phi
            s[i] = si * cos_phi + ci * sin_phi
            heading[i] += phi


# ``reassoc`` lets LLVM split the sums into vector lanes; the order of operations is still
# fixed by the code, so a chunk's sums do not depend on the number of threads
@njit(cache=True, fastmath={"reassoc"})
def _moments_pass(x, y, weights, ox, oy, sums):
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
def _add_scaled(target, z, scale):
    """``target += scale * z`` (a random-walk increment)."""
    for i in range(target.size):
        target[i] += scale * z[i]


@njit(cache=True, inline="always")
def _chunking(n):
    """Number of chunks and particles per chunk for ``n`` particles."""
    size = max(MIN_CHUNK, (n + N_CHUNKS - 1) // N_CHUNKS)
    return (n + size - 1) // size, size


@njit(cache=True, inline="always")
def _motion_views(lo, hi, x, y, heading, c, s, v, w):
    """Views ``[lo:hi]`` of the seven motion arrays (one chunk of particles)."""
    return x[lo:hi], y[lo:hi], heading[lo:hi], c[lo:hi], s[lo:hi], v[lo:hi], w[lo:hi]


@njit(cache=True, inline="always")
def _finish_headings(heading, c, s):
    """Wrap the headings (n,) into ``(-pi, pi]`` and pull ``(cos, sin)``
    back onto the unit circle (one Newton step of ``1/sqrt``: rotations drift it by ~1e-16
    per step), without the cost of ``atan2``."""
    for i in range(heading.size):
        while heading[i] > math.pi:
            heading[i] -= 2.0 * math.pi
        while heading[i] <= -math.pi:
            heading[i] += 2.0 * math.pi
        factor = 1.5 - 0.5 * (c[i] * c[i] + s[i] * s[i])
        c[i] *= factor
        s[i] *= factor


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
def _next_chunk(counter, n):
    """Claim the next chunk of ``n`` particles not yet claimed by any thread:
    ``(chunk, lo, hi)``, the particles ``lo:hi``; ``chunk`` is -1 once all are claimed.
    ``counter`` (int64, 1) holds the chunks claimed, starting at 0."""
    n_chunks, size = _chunking(n)
    chunk = _fetch_add(counter, 0, 1)
    if chunk >= n_chunks:
        return -1, 0, 0
    return chunk, chunk * size, min(n, (chunk + 1) * size)


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


def _run_chunks(kernel, parallel, n: int, n_steps: int, threads: int | None, *args) -> np.ndarray:
    """Run ``kernel(*args, counter, sums)`` over all chunks of ``n`` particles and return
    the weighted moments ``(n_steps, 5)`` (the per-chunk sums reduced in a fixed order).

    With ``threads`` > 1 (``None``: ``numba.get_num_threads()``), ``parallel(threads,
    *args, counter, sums)`` (tuple arguments spread into their items) runs the kernel on
    that many threads of numba's threading layer at once (OpenMP's threads wait awake for
    a while between calls, so a call starts in a few microseconds), each claiming the next
    unclaimed chunk whenever it finishes one (:func:`_next_chunk`): a thread that starts
    late or is slowed by other work on the machine simply runs fewer chunks. Every chunk
    writes its own particles and its own row of ``sums``, so the results do not depend on
    which thread ran it. Under numba's "workqueue" layer only one Python thread at a time
    runs kernels in parallel, the others run them on their own thread; in a process forked
    after this one started OpenMP threads, every call runs on the calling thread.
    """
    global _OPENMP_STARTED
    n_chunks, _ = _chunking(n)
    sums = np.zeros((n_chunks, n_steps, N_MOMENTS))
    counter = np.zeros(1, dtype=np.int64)
    previous = numba.get_num_threads()  # of this thread (numba's default: all); starts the layer
    threads = previous if threads is None else threads
    threads = max(1, min(threads, n_chunks, numba.config.NUMBA_NUM_THREADS))
    if threads > 1 and not _FORKED_AFTER_OPENMP:
        layer = numba.threading_layer()
        exclusive = layer == "workqueue"
        if not exclusive or _WORKQUEUE_LOCK.acquire(blocking=False):
            _OPENMP_STARTED = _OPENMP_STARTED or layer == "omp"
            # tuples of arrays (the von Mises tables) are passed to ``parallel`` as their items
            flat = [item for arg in args for item in (arg if isinstance(arg, tuple) else (arg,))]
            try:
                # Load the serial kernel before its parallel twin: a call with every chunk
                # already claimed does nothing. When the twin was loaded from numba's on-disk
                # cache first, it ran its own copy of the kernel, 20-25 % slower (HMM at 1 s,
                # N = 10,000: 0.97 s against 0.78 s a run); with the kernel loaded first it
                # runs the kernel's (2.7 us)
                kernel(*args, np.array([n_chunks], dtype=np.int64), sums)
                if previous != threads:
                    numba.set_num_threads(threads)
                parallel(threads, *flat, counter, sums)
            finally:
                if previous != threads:
                    numba.set_num_threads(previous)
                if exclusive:
                    _WORKQUEUE_LOCK.release()
            return sums.sum(axis=0)
    kernel(*args, counter, sums)
    return sums.sum(axis=0)


# --------------------------------------------------------------------------- baseline


# The kernels below run the chunks of the particles (_chunking) that they claim
# (_next_chunk), one after the other, each into its row of ``sums``; _run_chunks runs them on
# several threads at once through their parallel twins (the kernels themselves stay serial:
# numba's parallel loops over particles inside a kernel, loaded from the on-disk cache, ran
# at half the speed of freshly compiled ones).
# Inside a chunk, time-major: every particle of the chunk takes step t before any takes step
# t + 1, the chunk staying in cache. Each step is a few passes over the chunk (draw the
# normals, move along the arcs, sum the moments), each a branch-free loop that the compiler
# vectorises, followed by a scalar loop for the rare draws or turns the fast path leaves.


@njit(cache=True, nogil=True)
def _baseline_kernel(
    x, y, heading, c, s, v, w, streams, n_steps, dt, sigma, weights, ox, oy, counter, sums,
):  # fmt: skip
    scale = sigma * math.sqrt(dt)
    chunk, lo, hi = _next_chunk(counter, x.size)
    while chunk >= 0:
        xs, ys, hs, cs, ss, vs, ws = _motion_views(lo, hi, x, y, heading, c, s, v, w)
        chunk_streams = streams[lo:hi]
        z1 = np.empty(hi - lo)
        z2 = np.empty(hi - lo)
        retry = np.empty(hi - lo, dtype=np.bool_)
        for t in range(n_steps):
            rs.normals_into(chunk_streams, z1, retry)  # as normal_pair: dx, then dy
            rs.normals_into(chunk_streams, z2, retry)
            for i in range(xs.size):
                if t == n_steps - 1:
                    hs[i] = math.atan2(ss[i], cs[i])  # the heading before the last step
                dx = scale * z1[i]
                dy = scale * z2[i]
                xs[i] += dx
                ys[i] += dy
                length = math.sqrt(dx * dx + dy * dy)
                if length > 0.0:
                    cs[i] = dx / length
                    ss[i] = dy / length
                vs[i] = length / dt
            _moments_pass(xs, ys, weights[lo:hi], ox, oy, sums[chunk, t])
        for i in range(xs.size):
            previous = hs[i]
            hs[i] = math.atan2(ss[i], cs[i])
            turn = hs[i] - previous
            ws[i] = (turn - 2.0 * math.pi * math.floor((turn + math.pi) / (2.0 * math.pi))) / dt
        chunk, lo, hi = _next_chunk(counter, x.size)


# The parallel twins of the kernels: numba's parallel loop runs one kernel call per thread,
# all claiming chunks from the same counter (the kernels' arguments are listed, not passed as
# a tuple: the parallel loop cannot take tuples holding arrays).
@njit(cache=True, nogil=True, parallel=True)
def _baseline_parallel(
    threads, x, y, heading, c, s, v, w, streams, n_steps, dt, sigma, weights, ox, oy, counter,
    sums,
):  # fmt: skip
    for _ in numba.prange(threads):
        _baseline_kernel(
            x, y, heading, c, s, v, w, streams, n_steps, dt, sigma, weights, ox, oy, counter,
            sums,
        )  # fmt: skip


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped into ``[-pi, pi)``."""
    return angle - 2.0 * np.pi * np.floor((angle + np.pi) / (2.0 * np.pi))


@dataclass(frozen=True)
class BaselineMotion:
    """The paper's baseline random walk.

    Parameters
    ----------
    sigma : float
        Standard deviation of each of ``dx`` and ``dy`` over one second, m; over a step of
        ``dt`` seconds it is ``sigma * sqrt(dt)`` (a Brownian walk, so the displacement
        statistics over a horizon do not depend on the prediction step).
    """

    sigma: float
    compiled = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(
                f"BaselineMotion.sigma must be a positive number (m), got {self.sigma}"
            )

    def initialise(self, rng: np.random.Generator, particles: Particles) -> None:
        """Nothing to set: the random walk carries no state beyond position."""

    def propagate(self, rng: np.random.Generator, particles: Particles, dt: float) -> None:
        """One random-walk step of ``dt`` s for all particles, in place (NumPy reference)."""
        self.apply(particles, dt, rng.standard_normal((2, particles.n)))

    def apply(self, particles: Particles, dt: float, normals: np.ndarray) -> None:
        """The step of :meth:`propagate` with given standard normals ``(2, N)`` (dx, dy)."""
        p = particles
        dx = self.sigma * np.sqrt(dt) * normals[0]
        dy = self.sigma * np.sqrt(dt) * normals[1]
        p.x += dx
        p.y += dy
        length = np.hypot(dx, dy)
        moved = length > 0
        safe = np.where(moved, length, 1.0)
        p.cos_heading = np.where(moved, dx / safe, p.cos_heading)
        p.sin_heading = np.where(moved, dy / safe, p.sin_heading)
        new_heading = np.arctan2(p.sin_heading, p.cos_heading)
        p.turn_rate = _wrap(new_heading - p.heading) / dt
        p.heading = new_heading
        p.speed = length / dt

    def advance(self, particles, streams, n_steps, dt, weights, origin, threads=None) -> np.ndarray:
        """As :meth:`VelocityMotion.advance` (compiled steps; weighted moments per step)."""
        p = particles
        return _run_chunks(
            _baseline_kernel, _baseline_parallel, p.n, n_steps, threads,
            p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
            streams, n_steps, float(dt), float(self.sigma), weights, *origin,
        )  # fmt: skip


# --------------------------------------------------------------------------- velocity


@njit(cache=True, nogil=True)
def _velocity_kernel(
    x, y, heading, c, s, v, w, streams, n_steps, dt, sigma_speed, sigma_turn, weights, ox, oy,
    counter, sums,
):  # fmt: skip
    root_dt = math.sqrt(dt)
    chunk, lo, hi = _next_chunk(counter, x.size)
    while chunk >= 0:
        xs, ys, hs, cs, ss, vs, ws = _motion_views(lo, hi, x, y, heading, c, s, v, w)
        chunk_streams = streams[lo:hi]
        z = np.empty(hi - lo)
        retry = np.empty(hi - lo, dtype=np.bool_)
        for t in range(n_steps):
            rs.normals_into(chunk_streams, z, retry)  # as normal_pair: speed, then turn
            _add_scaled(vs, z, sigma_speed * root_dt)
            rs.normals_into(chunk_streams, z, retry)
            _add_scaled(ws, z, sigma_turn * root_dt)
            _arc_pass(xs, ys, cs, ss, hs, vs, ws, dt)
            _moments_pass(xs, ys, weights[lo:hi], ox, oy, sums[chunk, t])
        _finish_headings(hs, cs, ss)
        chunk, lo, hi = _next_chunk(counter, x.size)


@njit(cache=True, nogil=True, parallel=True)
def _velocity_parallel(
    threads, x, y, heading, c, s, v, w, streams, n_steps, dt, sigma_speed, sigma_turn, weights,
    ox, oy, counter, sums,
):  # fmt: skip
    for _ in numba.prange(threads):
        _velocity_kernel(
            x, y, heading, c, s, v, w, streams, n_steps, dt, sigma_speed, sigma_turn, weights,
            ox, oy, counter, sums,
        )  # fmt: skip


@dataclass(frozen=True)
class VelocityMotion:
    """The paper's velocity motion model (constant turn rate between steps).

    Each step adds ``N(0, sigma_speed^2 dt)`` to the speed and ``N(0, sigma_turn_rate^2 dt)``
    to the turn rate (random walks in speed and turn rate, so their spread over a horizon
    does not depend on the prediction step), then moves along the arc of the new speed and
    turn rate. As in the paper the speed is a signed linear velocity and may become negative
    (motion against the heading).

    Parameters
    ----------
    sigma_speed : float
        Standard deviation of the speed increment over one second, m/s.
    sigma_turn_rate : float
        Standard deviation of the turn-rate increment over one second, rad/s.
    """

    sigma_speed: float
    sigma_turn_rate: float
    compiled = True

    def __post_init__(self) -> None:
        for name in ("sigma_speed", "sigma_turn_rate"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"VelocityMotion.{name} must be a number >= 0, got {value}")

    def initialise(self, rng: np.random.Generator, particles: Particles) -> None:
        """Nothing to set: particles start at rest as in the paper's Algorithm 1."""

    def propagate(self, rng: np.random.Generator, particles: Particles, dt: float) -> None:
        """One step of ``dt`` s for all particles, in place (NumPy reference)."""
        self.apply(particles, dt, rng.standard_normal((2, particles.n)))

    def apply(self, particles: Particles, dt: float, normals: np.ndarray) -> None:
        """The step of :meth:`propagate` with given standard normals ``(2, N)`` (dv, domega)."""
        particles.speed = particles.speed + self.sigma_speed * np.sqrt(dt) * normals[0]
        particles.turn_rate = particles.turn_rate + self.sigma_turn_rate * np.sqrt(dt) * normals[1]
        _move_along_arc(particles, dt)

    def advance(self, particles, streams, n_steps, dt, weights, origin, threads=None) -> np.ndarray:
        """``n_steps`` prediction steps of ``dt`` s in one compiled call, in place.

        Parameters
        ----------
        particles : Particles
            N particles, moved in place.
        streams : (N,) uint64
            Per-particle random streams (:func:`hmmtrack.tracking.compiled.streams.new_streams`),
            advanced.
        n_steps : int
        dt : float
            Prediction step, s.
        weights : (N,) float
            Normalised weights (unchanged by prediction), for the moments.
        origin : (float, float)
            Point (m) the moments are taken about (the weighted mean is a good choice: it
            keeps the second moments free of cancellation).
        threads : int, optional
            Threads to run on (default ``numba.get_num_threads()``); the results do not
            depend on it.

        Returns
        -------
        (n_steps, 5) float
            After each step: ``sum w dx, sum w dy, sum w dx^2, sum w dy^2, sum w dx dy``
            with ``dx, dy`` the positions relative to ``origin``.
        """
        p = particles
        return _run_chunks(
            _velocity_kernel, _velocity_parallel, p.n, n_steps, threads,
            p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
            streams, n_steps, float(dt), float(self.sigma_speed), float(self.sigma_turn_rate),
            weights, *origin,
        )  # fmt: skip


# --------------------------------------------------------------------------- HMM


def transition_for_step(transition: np.ndarray, fraction: float) -> np.ndarray:
    """Transition matrix over ``fraction`` of the fitted time step: ``Gamma ** fraction``.

    Integer fractions use matrix powers. Otherwise the principal fractional power is taken
    (``scipy.linalg.fractional_matrix_power``); it is a valid stochastic matrix when, for
    example, every eigenvalue of ``Gamma`` is real and positive (for two states: when
    ``gamma_12 + gamma_21 < 1``, i.e. states persist). When it is not (complex or negative
    entries: the chain is not embeddable), the documented fallback is the nearest usable
    matrix by the simplest regularisation: real part, negative entries set to 0, rows
    renormalised; a ``UserWarning`` says so.

    Parameters
    ----------
    transition : (K, K) float
        Row-stochastic transition matrix over the fitted step ``model.dt``.
    fraction : float
        Prediction sub-step divided by ``model.dt`` (> 0).

    Returns
    -------
    (K, K) float row-stochastic matrix.
    """
    gamma = np.asarray(transition, dtype=np.float64)
    if fraction <= 0 or not np.isfinite(fraction):
        raise ValueError(f"fraction of the fitted time step must be > 0, got {fraction}")
    if abs(fraction - round(fraction)) < 1e-12:
        return np.linalg.matrix_power(gamma, int(round(fraction)))
    root = np.asarray(fractional_matrix_power(gamma, fraction))
    valid = (
        np.all(np.isfinite(root))
        and np.max(np.abs(root.imag)) < 1e-10
        and np.min(root.real) > -1e-10
        and np.allclose(root.real.sum(axis=1), 1.0, atol=1e-8)
    )
    matrix = np.clip(root.real, 0.0, None)
    if not valid:
        warnings.warn(
            f"the transition matrix has no valid stochastic root for {fraction:.6g} of its "
            "time step (the chain is not embeddable); using the nearest stochastic matrix "
            "(real part, negatives set to 0, rows renormalised)",
            UserWarning,
            stacklevel=2,
        )
    return matrix / matrix.sum(axis=1, keepdims=True)


@dataclass(frozen=True)
class _Schedule:
    """How one prediction step of an HMM motion model is carried out."""

    n_sub: int  # sub-steps per prediction step
    sub_step: float  # s
    draw_interval: float  # s between draws of speed and turn rate
    cumulative: np.ndarray  # (K, K) cumulative rows of the per-sub-step transition matrix


@njit(cache=True, inline="always")
def _draw_pass(
    v, w, behaviour, clock, streams, due, draw_interval, speed_factor, fitted_dt,
    gamma_d, gamma_c, gamma_boost, gamma_scale, zero_mass, vonmises_tables, scratch, retry,
):  # fmt: skip
    """Particles whose draw clock has reached ``due`` draw speed (m/s) and turn rate (rad/s)
    from their state and restart their clock (carrying the excess over); arrays (n,).

    When fewer than ``1 / SPARSE_DRAWS`` of the particles are due (the time-consistent
    variant with a model fitted at a coarser step than the prediction step), only those
    draw, with the scalar samplers (:func:`_redraw`). Otherwise three passes: the random
    numbers of the samplers' first tries for every particle (a
    branch-free, vectorised pass: the gamma's normal and uniform, the von Mises bits and two
    uniforms); the first tries themselves (:func:`streams._gamma_from`,
    :func:`streams._vonmises_from`: per-state table lookups), kept where due and accepted;
    then the scalar samplers (:func:`_redraw`) for the due particles whose tries were
    rejected, or whose state has a zero-inflated or boosted (shape < 1) step distribution.
    Either way a particle's draws are exactly those of the scalar samplers from its stream.
    ``scratch`` is a ``(4, n)`` float, ``(2, n)`` uint64 and ``(n,)`` bool tuple of work
    arrays.
    """
    n_due = 0
    for i in range(v.size):
        is_due = clock[i] >= due
        retry[i] = is_due
        n_due += is_due
        previous = clock[i]
        restarted = previous - draw_interval if previous < 2.0 * draw_interval else 0.0
        clock[i] = restarted if is_due else previous
    if SPARSE_DRAWS * n_due <= v.size:  # few due (a model fitted at a coarse time step)
        _redraw(
            v, w, behaviour, streams, speed_factor, fitted_dt, gamma_d, gamma_c, gamma_boost,
            gamma_scale, zero_mass, vonmises_tables, retry,
        )  # fmt: skip
        return
    uniforms, bits, normal_accepted = scratch
    normal, step_u, angle_u, angle_v = uniforms[0], uniforms[1], uniforms[2], uniforms[3]
    angle_bits, advanced = bits[0], bits[1]
    for i in range(v.size):
        state = streams[i]
        normal[i], normal_accepted[i], state = rs._normal_try(state)
        step_u[i], state = rs.uniform(state)
        angle_bits[i], state = rs._bits(state)
        angle_u[i], state = rs.uniform(state)
        angle_v[i], advanced[i] = rs.uniform(state)
    for i in range(v.size):
        k = behaviour[i]
        step, step_ok = rs._gamma_from(
            gamma_d[k], gamma_c[k], gamma_scale[k], normal[i], normal_accepted[i], step_u[i]
        )
        angle, angle_ok = rs._vonmises_from(
            vonmises_tables, k, angle_bits[i], angle_u[i], angle_v[i]
        )
        accepted = step_ok and angle_ok and zero_mass[k] <= 0.0 and gamma_boost[k] <= 0.0
        keep = retry[i] and accepted  # retry[i]: due
        v[i] = step * speed_factor if keep else v[i]
        w[i] = angle / fitted_dt if keep else w[i]
        streams[i] = advanced[i] if keep else streams[i]
        retry[i] = retry[i] and not accepted
    _redraw(
        v, w, behaviour, streams, speed_factor, fitted_dt, gamma_d, gamma_c, gamma_boost,
        gamma_scale, zero_mass, vonmises_tables, retry,
    )  # fmt: skip


@njit(cache=True)
def _redraw(
    v, w, behaviour, streams, speed_factor, fitted_dt, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vonmises_tables, retry,
):  # fmt: skip
    """Draw speed and turn rate with the scalar samplers for the particles marked in
    ``retry`` (the few that :func:`_draw_pass` leaves to them; a separate function keeps
    that pass's loops small)."""
    for i in range(retry.size):
        if not retry[i]:
            continue
        k = behaviour[i]
        state = streams[i]
        step = 0.0
        u = 1.0
        if zero_mass[k] > 0.0:
            u, state = rs.uniform(state)
        if u > zero_mass[k]:
            step, state = rs.gamma(gamma_d[k], gamma_c[k], gamma_boost[k], gamma_scale[k], state)
        angle, state = rs.vonmises(vonmises_tables, k, state)
        v[i] = step * speed_factor
        w[i] = angle / fitted_dt
        streams[i] = state


@njit(cache=True, inline="always")
def _transition_pass(behaviour, streams, cumulative, u, next_state):
    """One step of the behavioural chain for particles ``(n,)``: the next state is the
    first ``j`` with ``u <= cumulative[state, j]`` (:func:`streams.categorical`), counted as
    the number of ``j < K - 1`` with ``cumulative[state, j] < u`` in branch-free passes.
    ``u`` (float) and ``next_state`` (int) are scratch."""
    for i in range(behaviour.size):
        u[i], streams[i] = rs.uniform(streams[i])
        next_state[i] = 0
    for j in range(cumulative.shape[1] - 1):
        for i in range(behaviour.size):
            next_state[i] += cumulative[behaviour[i], j] < u[i]
    for i in range(behaviour.size):
        behaviour[i] = next_state[i]


@njit(cache=True, nogil=True)
def _hmm_kernel(
    x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
    draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vonmises_tables, heading_diffusion, weights, ox, oy, counter, sums,
):  # fmt: skip
    due = draw_interval * (1.0 - 1e-9)
    jitter_scale = heading_diffusion / math.sqrt(sub_step)  # rad/s of this sub-step
    speed_factor = metres_per_step_unit / fitted_dt
    chunk, lo, hi = _next_chunk(counter, x.size)
    while chunk >= 0:
        xs, ys, hs, cs, ss, vs, ws = _motion_views(lo, hi, x, y, heading, c, s, v, w)
        ks, clocks, chunk_streams = behaviour[lo:hi], clock[lo:hi], streams[lo:hi]
        scratch = np.empty(hi - lo)
        next_state = np.empty(hi - lo, dtype=np.int64)
        retry = np.empty(hi - lo, dtype=np.bool_)
        draws = (
            np.empty((4, hi - lo)),
            np.empty((2, hi - lo), dtype=np.uint64),
            np.empty(hi - lo, dtype=np.bool_),
        )
        for t in range(n_steps):
            for _ in range(n_sub):
                _draw_pass(
                    vs, ws, ks, clocks, chunk_streams, due, draw_interval, speed_factor,
                    fitted_dt, gamma_d, gamma_c, gamma_boost, gamma_scale, zero_mass,
                    vonmises_tables, draws, retry,
                )  # fmt: skip
                if heading_diffusion > 0.0:
                    rs.normals_into(chunk_streams, scratch, retry)
                    for i in range(ws.size):
                        scratch[i] = ws[i] + jitter_scale * scratch[i]
                    _arc_pass(xs, ys, cs, ss, hs, vs, scratch, sub_step)
                else:
                    _arc_pass(xs, ys, cs, ss, hs, vs, ws, sub_step)
                for i in range(clocks.size):
                    clocks[i] += sub_step
                _transition_pass(ks, chunk_streams, cumulative, scratch, next_state)
            _moments_pass(xs, ys, weights[lo:hi], ox, oy, sums[chunk, t])
        _finish_headings(hs, cs, ss)
        chunk, lo, hi = _next_chunk(counter, x.size)


@njit(cache=True, nogil=True, parallel=True)
def _hmm_parallel(
    threads, x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
    draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vm_mean, vm_kappa, vm_width, vm_f_left, vm_f_right, vm_cut,
    vm_alias, heading_diffusion, weights, ox, oy, counter, sums,
):  # fmt: skip
    """:func:`_hmm_kernel` on ``threads`` threads; the von Mises tables (a tuple in the
    kernel) are passed as their seven arrays."""
    for _ in numba.prange(threads):
        _hmm_kernel(
            x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
            draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c,
            gamma_boost, gamma_scale, zero_mass,
            (vm_mean, vm_kappa, vm_width, vm_f_left, vm_f_right, vm_cut, vm_alias),
            heading_diffusion, weights, ox, oy, counter, sums,
        )  # fmt: skip


HMM_VARIANTS = ("paper", "time_consistent")
#: metres per unit of a fitted model's ``step_unit``
STEP_UNITS = {"m": 1.0, "km": 1000.0}


def step_metres(model) -> float:
    """Metres per unit of ``model``'s step lengths (its ``step_unit``, metres if it has none).

    Raises
    ------
    ValueError
        For a unit not in :data:`STEP_UNITS`.
    """
    unit = getattr(model, "step_unit", "m")
    if unit not in STEP_UNITS:
        raise ValueError(
            f"the movement HMM's steps are in {unit!r}; expected one of {sorted(STEP_UNITS)}"
        )
    return STEP_UNITS[unit]


@dataclass(frozen=True)
class HMMMotion:
    """Motion driven by a fitted movement HMM; each particle carries a behavioural state.

    Speed is ``step / model.dt`` (m/s; steps in km are converted) and turn rate
    ``angle / model.dt`` (rad/s), drawn
    from the step and angle distributions of the particle's state; the particle then moves
    along the constant-turn-rate arc (as :class:`VelocityMotion`).

    Each (sub-)step of length ``h`` does, per particle: (1) if a draw is due, draw speed and
    turn rate from the current state; (2) move along the arc for ``h``; (3) move the
    behavioural state one step of the chain. Particles start with a state drawn from
    ``model.initial`` and speed and turn rate drawn from it (:meth:`initialise`); in the
    time-consistent variant their draw clocks start at staggered, uniform phases.

    Variants
    --------
    ``"paper"``
        What the paper does: every prediction step (1 s in the filter) each particle draws
        a new speed and turn rate and then a new state from the transition matrix ``Gamma``
        *as fitted*. When the HMM was fitted at ``model.dt`` != 1 s this runs the
        behavioural chain ``model.dt`` times too fast and replaces speed and turn rate more
        often than the data did, so the displacement statistics depend on the prediction
        step (``tests/test_motion.py`` shows it).
    ``"time_consistent"``
        Respects the fitted time step. The behavioural state moves every sub-step ``h`` with
        ``Gamma ** (h / model.dt)`` (:func:`transition_for_step`, with its documented
        fallback), and speed and turn rate are held between draws: a particle redraws them,
        from its current state, only when ``model.dt`` seconds have passed on its own clock
        (``Particles.time_since_draw``). The states at draw times therefore form a Markov
        chain with matrix ``Gamma`` and each fitted step is one arc with one (speed, turn
        rate) drawn from its state: the fitted HMM itself, integrated along arcs. When the
        prediction step divides ``model.dt``, or is a multiple of it (it is then split into
        sub-steps of ``model.dt``), the law of the trajectory over any horizon does not
        depend on the prediction step, and at ``dt == model.dt`` both variants coincide.
        Otherwise speed and turn rate are redrawn at the first sub-step boundary after
        ``model.dt`` has elapsed, carrying the excess over, so that draws still happen once
        per ``model.dt`` on average.

    Parameters
    ----------
    model : hmmtrack.hmm.MovementHMM
        Uses ``initial`` (K,), ``transition_matrix()`` (K, K), ``dt`` (s), ``step`` and
        ``angle`` (``sample(rng, states)``; gamma steps and von Mises angles also have a
        compiled kernel, other families run the NumPy path only).
    variant : {"time_consistent", "paper"}
        ``"time_consistent"`` by default (the two coincide in law when the prediction step
        equals ``model.dt``); ``"paper"`` reproduces the paper's algorithm. With a model
        fitted at a coarser step than the prediction step, ``"paper"`` divides each fitted
        turning angle by ``model.dt`` and redraws it every second, so the heading changes
        by ``model.dt`` independent small turns whose variance adds up to only
        ``1/model.dt`` of the fitted angle variance: headings are under-dispersed and
        clouds of particles drift straight (see the measurements in
        :mod:`hmmtrack.tracking.pipeline`).
    heading_diffusion : float
        Standard deviation (rad per √s, ≥ 0) of a heading random walk added to the arcs:
        each sub-step of ``h`` s turns by ``omega h + heading_diffusion sqrt(h) Z`` with
        ``Z ~ N(0, 1)``. It stands for the wiggles of a real path about the fitted step's arc
        and, in a filter, lets copies of one particle made by resampling part before their
        next draw (without it they move identically for up to ``model.dt`` s). The law over
        a horizon does not depend on the prediction step (variances add over time). The
        default 0 is the fitted model alone.
    """

    model: object
    variant: str = "time_consistent"
    heading_diffusion: float = 0.0
    # per prediction step: _Schedule; under "samplers": the kernel's sampler constants
    _schedules: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.variant not in HMM_VARIANTS:
            raise ValueError(
                f"HMMMotion.variant must be one of {HMM_VARIANTS}, got {self.variant!r}"
            )
        fitted_dt = float(self.model.dt)
        if not (np.isfinite(fitted_dt) and fitted_dt > 0):
            raise ValueError(
                f"the movement HMM has no usable time step (model.dt = {self.model.dt}); "
                "speed = step / dt needs the fitted data's time step in seconds"
            )
        step_metres(self.model)
        if not (np.isfinite(self.heading_diffusion) and self.heading_diffusion >= 0):
            raise ValueError(
                f"heading_diffusion must be >= 0 rad/sqrt(s), got {self.heading_diffusion}"
            )
        gamma = np.asarray(self.model.transition_matrix(), dtype=np.float64)
        k = np.asarray(self.model.initial).size
        if gamma.shape != (k, k):
            raise ValueError(
                f"HMMMotion needs one (K, K) transition matrix, got shape {gamma.shape}"
            )

    @property
    def _metres(self) -> float:
        """Metres per unit of the model's step lengths."""
        return step_metres(self.model)

    @property
    def compiled(self) -> bool:
        """Whether :meth:`advance` is available (gamma steps and von Mises angles)."""
        return self.model.step.name == "gamma" and self.model.angle.name == "vonmises"

    def schedule(self, dt: float) -> _Schedule:
        """Sub-steps, draw interval and transition matrix for prediction steps of ``dt`` s."""
        if dt not in self._schedules:
            fitted_dt = float(self.model.dt)
            gamma = np.asarray(self.model.transition_matrix(), dtype=np.float64)
            if self.variant == "paper":
                n_sub, interval, matrix = 1, dt, gamma
            else:
                n_sub = max(1, math.ceil(dt / fitted_dt - 1e-9))
                interval = fitted_dt
                ratio = fitted_dt / (dt / n_sub)
                if abs(ratio - round(ratio)) > 1e-9 * ratio:
                    logger.info(
                        "prediction sub-step %.6g s does not divide the fitted time step "
                        "%.6g s; speed and turn rate are redrawn at the first sub-step after "
                        "it has elapsed",
                        dt / n_sub,
                        fitted_dt,
                    )
                matrix = transition_for_step(gamma, dt / n_sub / fitted_dt)
            cumulative = np.cumsum(matrix, axis=1)
            cumulative[:, -1] = 1.0
            self._schedules[dt] = _Schedule(n_sub, dt / n_sub, interval, cumulative)
        return self._schedules[dt]

    def initialise(self, rng: np.random.Generator, particles: Particles) -> None:
        """Draw each particle's state, speed, turn rate and (time-consistent) draw clock.

        The state comes from ``model.initial``; speed (m/s) and turn rate (rad/s) are drawn
        from that state's distributions. In the ``"time_consistent"`` variant each
        particle's clock ``time_since_draw`` is uniform on ``[0, model.dt)`` s: the
        stationary phase of a renewal process that redraws every ``model.dt`` s, so that
        particles redraw at staggered times rather than all together every ``model.dt``
        seconds (resampling copies clocks, so a common phase would never break up). In the
        ``"paper"`` variant the clock is ``inf``: every particle draws at the first step.

        Parameters
        ----------
        rng : numpy.random.Generator
        particles : Particles
            Changed in place: ``state``, ``speed``, ``turn_rate``, ``time_since_draw``.
        """
        p = particles
        cumulative = np.cumsum(np.asarray(self.model.initial, dtype=np.float64))
        p.state = np.minimum(
            np.searchsorted(cumulative / cumulative[-1], rng.random(p.n), side="right"),
            cumulative.size - 1,
        ).astype(np.int64)
        fitted_dt = float(self.model.dt)
        p.speed = self.model.step.sample(rng, p.state) * self._metres / fitted_dt
        p.turn_rate = self.model.angle.sample(rng, p.state) / fitted_dt
        if self.variant == "time_consistent":
            p.time_since_draw = rng.uniform(0.0, fitted_dt, p.n)
        else:
            p.time_since_draw = np.full(p.n, np.inf)

    def propagate(self, rng: np.random.Generator, particles: Particles, dt: float) -> None:
        """One prediction step of ``dt`` s for all particles, in place (NumPy reference)."""
        plan = self.schedule(dt)
        p = particles
        for _ in range(plan.n_sub):
            due = np.flatnonzero(p.time_since_draw >= plan.draw_interval * (1.0 - 1e-9))
            if due.size:
                states = p.state[due]
                p.speed[due] = self.model.step.sample(rng, states) * self._metres / self.model.dt
                p.turn_rate[due] = self.model.angle.sample(rng, states) / self.model.dt
                clock = p.time_since_draw[due]
                p.time_since_draw[due] = np.where(
                    clock < 2.0 * plan.draw_interval, clock - plan.draw_interval, 0.0
                )
            if self.heading_diffusion > 0:
                held = p.turn_rate
                jitter = self.heading_diffusion / np.sqrt(plan.sub_step)
                p.turn_rate = held + jitter * rng.standard_normal(p.n)
                _move_along_arc(p, plan.sub_step)
                p.turn_rate = held
            else:
                _move_along_arc(p, plan.sub_step)
            p.time_since_draw += plan.sub_step
            u = rng.random(p.n)
            p.state = (u[:, None] > plan.cumulative[p.state]).sum(axis=1).astype(np.int64)
            p.state = np.minimum(p.state, plan.cumulative.shape[0] - 1)

    def advance(self, particles, streams, n_steps, dt, weights, origin, threads=None) -> np.ndarray:
        """As :meth:`VelocityMotion.advance` (compiled steps; weighted moments per step)."""
        if not self.compiled:
            raise NotImplementedError(
                f"no compiled kernel for {self.model.step.name} steps and "
                f"{self.model.angle.name} angles; use ParticleFilter(backend='numpy')"
            )
        plan = self.schedule(dt)
        if "samplers" not in self._schedules:
            step, angle = self.model.step, self.model.angle
            d, c, boost = rs.gamma_constants(step.shape)
            zero_mass = np.zeros(d.size) if step.zero_mass is None else step.zero_mass
            self._schedules["samplers"] = (
                d, c, boost, np.asarray(step.scale, dtype=np.float64),
                np.asarray(zero_mass, dtype=np.float64),
                rs.VonMisesTables.build(angle.mean, angle.concentration).as_tuple(),
            )  # fmt: skip
        p = particles
        return _run_chunks(
            _hmm_kernel, _hmm_parallel, p.n, n_steps, threads,
            p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
            p.state, p.time_since_draw, streams, n_steps, plan.n_sub, plan.sub_step,
            plan.draw_interval, self._metres, float(self.model.dt), plan.cumulative,
            *self._schedules["samplers"], float(self.heading_diffusion), weights, *origin,
        )  # fmt: skip
