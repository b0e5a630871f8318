"""Motion models of the tracking filter: how particles move between corrections.

Three models from the paper's section "Motion Models", each with the same two entry points:

``propagate(rng, particles, dt)``
    The reference implementation: one prediction step of ``dt`` seconds for all particles at
    once, written with NumPy arrays and a ``numpy.random.Generator``.
``advance(particles, streams, n_steps, dt, weights, origin)``
    The fast path used by :class:`hmmtrack.filter.ParticleFilter`: ``n_steps`` prediction
    steps fused into one compiled (numba, multi-threaded) kernel that draws from the
    per-particle random streams of :mod:`hmmtrack.streams` and returns the weighted moments
    of the particle positions after every step, so that per-second estimates need no second
    pass over the particles. The kernels implement the same equations as ``propagate``;
    ``tests/test_motion.py`` checks them against each other with the same random draws.

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
import warnings
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange
from scipy.linalg import fractional_matrix_power

from hmmtrack import streams as rs
from hmmtrack.particles import Particles

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
#: the compiled kernels split particles into this many fixed chunks (one partial sum each),
#: so that sums, hence estimates, do not depend on how many threads run them
N_CHUNKS = 64
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


@njit(cache=True, inline="always")
def _arc(x, y, c, s, v, w, dt):
    """Scalar arc step; returns new ``x, y, cos, sin`` (same equations as the NumPy path).

    For ``|omega dt| < 0.25`` (almost every step of a swimming animal) ``sin``, ``1 - cos``
    and their quotients by ``phi`` come from one Taylor polynomial each, exact to rounding
    (first omitted terms below 1e-17 relative), which is both faster than the library calls
    and exact in the straight-line limit.
    """
    phi = w * dt
    length = v * dt
    if abs(phi) < 0.25:
        p2 = phi * phi
        sinc = 1.0 - p2 / 6.0 * (
            1.0
            - p2
            / 20.0
            * (1.0 - p2 / 42.0 * (1.0 - p2 / 72.0 * (1.0 - p2 / 110.0 * (1.0 - p2 / 156.0))))
        )
        half_cosc = 0.5 * (
            1.0
            - p2
            / 12.0
            * (1.0 - p2 / 30.0 * (1.0 - p2 / 56.0 * (1.0 - p2 / 90.0 * (1.0 - p2 / 132.0))))
        )
        sin_phi = phi * sinc
        cosc = phi * half_cosc
        cos_phi = 1.0 - phi * cosc
    else:
        sin_phi = math.sin(phi)
        cos_phi = math.cos(phi)
        sinc = sin_phi / phi
        cosc = (1.0 - cos_phi) / phi
    x += length * (c * sinc - s * cosc)
    y += length * (s * sinc + c * cosc)
    return x, y, c * cos_phi - s * sin_phi, s * cos_phi + c * sin_phi


@njit(cache=True, inline="always")
def _accumulate(acc, weight, dx, dy):
    """Add one particle's weighted first and second moments to the 5-tuple ``acc``."""
    wdx = weight * dx
    wdy = weight * dy
    return (acc[0] + wdx, acc[1] + wdy, acc[2] + wdx * dx, acc[3] + wdy * dy, acc[4] + wdx * dy)


@njit(cache=True, inline="always")
def _chunk_bounds(chunk, n):
    """Particles ``lo:hi`` of chunk ``chunk`` (of ``N_CHUNKS``) when there are ``n``."""
    size = (n + N_CHUNKS - 1) // N_CHUNKS
    return min(n, chunk * size), min(n, (chunk + 1) * size)


@njit(cache=True, inline="always")
def _finish_headings(heading, c, s, lo, hi):
    """Wrap the headings of particles ``lo:hi`` into ``(-pi, pi]`` and pull ``(cos, sin)``
    back onto the unit circle (one Newton step of ``1/sqrt``: rotations drift it by ~1e-16
    per step), without the cost of ``atan2``."""
    for i in range(lo, hi):
        while heading[i] > math.pi:
            heading[i] -= 2.0 * math.pi
        while heading[i] <= -math.pi:
            heading[i] += 2.0 * math.pi
        factor = 1.5 - 0.5 * (c[i] * c[i] + s[i] * s[i])
        c[i] *= factor
        s[i] *= factor


def _moments(sums: np.ndarray) -> np.ndarray:
    """Reduce per-chunk partial sums ``(N_CHUNKS, n_steps, 5)`` in a fixed order."""
    return sums.sum(axis=0)


# --------------------------------------------------------------------------- baseline


# The kernels below run particles in N_CHUNKS fixed chunks (one per prange iteration) and,
# inside a chunk, time-major: every particle of the chunk takes step t before any takes step
# t + 1. The chunk stays in cache, and the particles' independent chains of arithmetic
# overlap in the processor (about 20 % faster than finishing one particle at a time).


@njit(cache=True, parallel=True)
def _baseline_kernel(x, y, heading, c, s, v, w, streams, n_steps, dt, sigma, weights, ox, oy):
    sums = np.zeros((N_CHUNKS, n_steps, N_MOMENTS))
    scale = sigma * math.sqrt(dt)
    for chunk in prange(N_CHUNKS):
        lo, hi = _chunk_bounds(chunk, x.size)
        for t in range(n_steps):
            acc = (0.0, 0.0, 0.0, 0.0, 0.0)
            for i in range(lo, hi):
                z1, z2, streams[i] = rs.normal_pair(streams[i])
                dx = scale * z1
                dy = scale * z2
                x[i] += dx
                y[i] += dy
                length = math.sqrt(dx * dx + dy * dy)
                if t == n_steps - 1:
                    heading[i] = math.atan2(s[i], c[i])  # the heading before the last step
                if length > 0.0:
                    c[i] = dx / length
                    s[i] = dy / length
                v[i] = length / dt
                acc = _accumulate(acc, weights[i], x[i] - ox, y[i] - oy)
            for k in range(N_MOMENTS):
                sums[chunk, t, k] = acc[k]
        for i in range(lo, hi):
            previous = heading[i]
            heading[i] = math.atan2(s[i], c[i])
            turn = heading[i] - previous
            w[i] = (turn - 2.0 * math.pi * math.floor((turn + math.pi) / (2.0 * math.pi))) / dt
    return sums


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

    def advance(self, particles, streams, n_steps, dt, weights, origin) -> np.ndarray:
        """As :meth:`VelocityMotion.advance` (compiled steps; weighted moments per step)."""
        p = particles
        return _moments(
            _baseline_kernel(
                p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
                streams, n_steps, float(dt), float(self.sigma), weights, *origin,
            )
        )  # fmt: skip


# --------------------------------------------------------------------------- velocity


@njit(cache=True, parallel=True)
def _velocity_kernel(
    x, y, heading, c, s, v, w, streams, n_steps, dt, sigma_speed, sigma_turn, weights, ox, oy
):
    sums = np.zeros((N_CHUNKS, n_steps, N_MOMENTS))
    root_dt = math.sqrt(dt)
    for chunk in prange(N_CHUNKS):
        lo, hi = _chunk_bounds(chunk, x.size)
        for t in range(n_steps):
            acc = (0.0, 0.0, 0.0, 0.0, 0.0)
            for i in range(lo, hi):
                z1, z2, streams[i] = rs.normal_pair(streams[i])
                v[i] += sigma_speed * root_dt * z1
                w[i] += sigma_turn * root_dt * z2
                x[i], y[i], c[i], s[i] = _arc(x[i], y[i], c[i], s[i], v[i], w[i], dt)
                heading[i] += w[i] * dt
                acc = _accumulate(acc, weights[i], x[i] - ox, y[i] - oy)
            for k in range(N_MOMENTS):
                sums[chunk, t, k] = acc[k]
        _finish_headings(heading, c, s, lo, hi)
    return sums


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

    def advance(self, particles, streams, n_steps, dt, weights, origin) -> np.ndarray:
        """``n_steps`` prediction steps of ``dt`` s in one compiled call, in place.

        Parameters
        ----------
        particles : Particles
            N particles, moved in place.
        streams : (N,) uint64
            Per-particle random streams (:func:`hmmtrack.streams.new_streams`), advanced.
        n_steps : int
        dt : float
            Prediction step, s.
        weights : (N,) float
            Normalised weights (unchanged by prediction), for the moments.
        origin : (float, float)
            Point (m) the moments are taken about (the weighted mean is a good choice: it
            keeps the second moments free of cancellation).

        Returns
        -------
        (n_steps, 5) float
            After each step: ``sum w dx, sum w dy, sum w dx^2, sum w dy^2, sum w dx dy``
            with ``dx, dy`` the positions relative to ``origin``.
        """
        p = particles
        return _moments(
            _velocity_kernel(
                p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
                streams, n_steps, float(dt), float(self.sigma_speed), float(self.sigma_turn_rate),
                weights, *origin,
            )
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


@njit(cache=True, parallel=True)
def _hmm_kernel(
    x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
    draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vonmises_tables, heading_diffusion, weights, ox, oy,
):  # fmt: skip
    sums = np.zeros((N_CHUNKS, n_steps, N_MOMENTS))
    due = draw_interval * (1.0 - 1e-9)
    jitter_scale = heading_diffusion / math.sqrt(sub_step)  # rad/s of this sub-step
    for chunk in prange(N_CHUNKS):
        lo, hi = _chunk_bounds(chunk, x.size)
        for t in range(n_steps):
            acc = (0.0, 0.0, 0.0, 0.0, 0.0)
            for i in range(lo, hi):
                k, state = behaviour[i], streams[i]
                for _ in range(n_sub):
                    if clock[i] >= due:
                        step = 0.0
                        u = 1.0
                        if zero_mass[k] > 0.0:
                            u, state = rs.uniform(state)
                        if u > zero_mass[k]:
                            step, state = rs.gamma(
                                gamma_d[k], gamma_c[k], gamma_boost[k], gamma_scale[k], state
                            )
                        angle, state = rs.vonmises(vonmises_tables, k, state)
                        v[i] = step * metres_per_step_unit / fitted_dt
                        w[i] = angle / fitted_dt
                        previous = clock[i]
                        clock[i] = (
                            previous - draw_interval if previous < 2.0 * draw_interval else 0.0
                        )
                    turn = w[i]
                    if heading_diffusion > 0.0:
                        z, state = rs.normal(state)
                        turn += jitter_scale * z
                    x[i], y[i], c[i], s[i] = _arc(x[i], y[i], c[i], s[i], v[i], turn, sub_step)
                    heading[i] += turn * sub_step
                    clock[i] += sub_step
                    k, state = rs.categorical(cumulative[k], state)
                behaviour[i], streams[i] = k, state
                acc = _accumulate(acc, weights[i], x[i] - ox, y[i] - oy)
            for j in range(N_MOMENTS):
                sums[chunk, t, j] = acc[j]
        _finish_headings(heading, c, s, lo, hi)
    return sums


HMM_VARIANTS = ("paper", "time_consistent")
#: metres per unit of a fitted model's ``step_unit``
STEP_UNITS = {"m": 1.0, "km": 1000.0}


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
        clouds of particles drift straight (see the measurements in :mod:`hmmtrack.tracking`).
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
        unit = getattr(self.model, "step_unit", "m")
        if unit not in STEP_UNITS:
            raise ValueError(
                f"the movement HMM's steps are in {unit!r}; expected one of {sorted(STEP_UNITS)}"
            )
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
        return STEP_UNITS[getattr(self.model, "step_unit", "m")]

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

    def advance(self, particles, streams, n_steps, dt, weights, origin) -> np.ndarray:
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
        return _moments(
            _hmm_kernel(
                p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
                p.state, p.time_since_draw, streams, n_steps, plan.n_sub, plan.sub_step,
                plan.draw_interval, self._metres, float(self.model.dt), plan.cumulative,
                *self._schedules["samplers"], float(self.heading_diffusion), weights, *origin,
            )
        )  # fmt: skip
