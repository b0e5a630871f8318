"""What a motion model is to the particle filter: the :class:`MotionModel` protocol.

A motion model moves particles between corrections; it never weighs or resamples them. The
filter (:class:`hmmtrack.tracking.filter.ParticleFilter`) uses it through two paths:

``propagate(rng, particles, dt)``
    The reference path: one prediction step of ``dt`` seconds for all particles at once,
    NumPy arrays and a ``numpy.random.Generator`` (``backend="numpy"``, and every model
    without a compiled kernel).
``advance(particles, streams, n_steps, dt, weights, origin, threads=None)``
    The fast path when ``compiled`` is true: ``n_steps`` prediction steps fused into one
    compiled (numba) kernel that draws from per-particle random streams
    (:mod:`hmmtrack.tracking.compiled.streams`), runs over fixed chunks of particles on
    ``threads`` threads (:func:`hmmtrack.tracking.compiled.chunks.run_chunks`), and returns
    the weighted moments of the positions after every step, so that per-second estimates
    need no second pass over the particles. It implements the equations of ``propagate``.

This module also holds :func:`motion_views`, the chunk slicing every motion kernel shares.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numba import njit

from hmmtrack.tracking.particles import Particles

__all__ = ["MotionModel", "motion_views"]


@runtime_checkable
class MotionModel(Protocol):
    """A motion model of the particle filter.

    Attributes
    ----------
    compiled : bool
        Whether :meth:`advance` is available (else the filter runs :meth:`propagate`).
    """

    compiled: bool

    def initialise(self, rng: np.random.Generator, particles: Particles) -> None:
        """Set the particles' motion fields (speed, turn rate, state, ...) at the start, in
        place; positions are the filter's (uniform in the search box)."""

    def propagate(self, rng: np.random.Generator, particles: Particles, dt: float) -> None:
        """One prediction step of ``dt`` s for all particles, in place (NumPy reference)."""

    def advance(
        self,
        particles: Particles,
        streams: np.ndarray,
        n_steps: int,
        dt: float,
        weights: np.ndarray,
        origin: tuple[float, float],
        threads: int | None = None,
    ) -> np.ndarray:
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


# The motion kernels run the chunks of the particles (chunks.chunking) that they claim
# (chunks.next_chunk), one after the other, each into its row of ``sums``; chunks.run_chunks
# runs them on several threads at once through their parallel twins (the kernels themselves
# stay serial: numba's parallel loops over particles inside a kernel, loaded from the on-disk
# cache, ran at half the speed of freshly compiled ones). The parallel twins list the
# kernels' arguments rather than pass a tuple: numba's parallel loop cannot take tuples
# holding arrays.
# Inside a chunk, time-major: every particle of the chunk takes step t before any takes step
# t + 1, the chunk staying in cache. Each step is a few passes over the chunk (draw the
# random numbers, move along the arcs, sum the moments), each a branch-free loop that the
# compiler vectorises, followed by a scalar loop for the rare draws or turns the fast path
# leaves; the draws are exactly those of the scalar samplers of
# :mod:`hmmtrack.tracking.compiled.streams`.


@njit(cache=True, inline="always")
def motion_views(lo, hi, x, y, heading, c, s, v, w):
    """Views ``[lo:hi]`` of the seven motion arrays (one chunk of particles)."""
    return x[lo:hi], y[lo:hi], heading[lo:hi], c[lo:hi], s[lo:hi], v[lo:hi], w[lo:hi]
