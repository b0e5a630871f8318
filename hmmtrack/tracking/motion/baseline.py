"""The paper's baseline motion model: a Gaussian random walk in position.

Each step adds ``N(0, sigma^2 dt)`` to ``x`` and to ``y``; heading, speed and turn rate
are derived from the step (the paper's equations; the heading change is wrapped into
``[-pi, pi)`` before dividing by ``dt``). :class:`BaselineMotion` has the NumPy reference
(``propagate``) and the compiled path (``advance``, :mod:`hmmtrack.tracking.motion.base`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.compiled.chunks import moments_pass, next_chunk, run_chunks
from hmmtrack.tracking.motion.base import motion_views
from hmmtrack.tracking.particles import Particles

__all__ = ["BaselineMotion"]


@njit(cache=True, nogil=True)
def _baseline_kernel(
    x, y, heading, c, s, v, w, streams, n_steps, dt, sigma, weights, ox, oy, counter, sums,
):  # fmt: skip
    scale = sigma * math.sqrt(dt)
    chunk, lo, hi = next_chunk(counter, x.size)
    while chunk >= 0:
        xs, ys, hs, cs, ss, vs, ws = motion_views(lo, hi, x, y, heading, c, s, v, w)
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
            moments_pass(xs, ys, weights[lo:hi], ox, oy, sums[chunk, t])
        for i in range(xs.size):
            previous = hs[i]
            hs[i] = math.atan2(ss[i], cs[i])
            turn = hs[i] - previous
            ws[i] = (turn - 2.0 * math.pi * math.floor((turn + math.pi) / (2.0 * math.pi))) / dt
        chunk, lo, hi = next_chunk(counter, x.size)


# The parallel twins of the kernels: numba's parallel loop runs one kernel call per thread,
# all claiming chunks from the same counter (the kernels' arguments are listed, not passed as


# the parallel twin: one kernel call per thread, all claiming chunks from one counter
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
        """``n_steps`` compiled steps of ``dt`` s, in place; the weighted moments after each,
        ``(n_steps, 5)`` (:meth:`hmmtrack.tracking.motion.base.MotionModel.advance`)."""
        p = particles
        return run_chunks(
            _baseline_kernel, _baseline_parallel, p.n, n_steps, threads,
            p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
            streams, n_steps, float(dt), float(self.sigma), weights, *origin,
        )  # fmt: skip
