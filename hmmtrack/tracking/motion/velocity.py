"""The paper's velocity motion model: random walks in speed and turn rate, moves along arcs.

Each step adds Gaussian increments to speed and turn rate (standard deviations
``sigma * sqrt(dt)``; optionally a turn rate that reverts to zero, an Ornstein-Uhlenbeck
process, instead of its walk), optionally speed jumps (a compound Poisson process beside the
speed's random walk), then moves along the constant-turn-rate arc of the new speed and turn rate
(:mod:`hmmtrack.tracking.motion.arcs`). Optionally regimes
(:mod:`~hmmtrack.tracking.motion.regimes`): each particle switches between kinds of movement,
each with its own speed and turn-rate transitions. :class:`VelocityMotion` has the NumPy
reference (``propagate``) and the compiled path (``advance``,
:mod:`hmmtrack.tracking.motion.base`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.compiled.chunks import moments_pass, next_chunk, run_chunks
from hmmtrack.tracking.motion.arcs import arc_pass, finish_headings, move_along_arc
from hmmtrack.tracking.motion.base import motion_views
from hmmtrack.tracking.motion.chain import draw_states, step_states, transition_pass
from hmmtrack.tracking.motion.regimes import Regime, VelocityRegimes, reverting_step
from hmmtrack.tracking.particles import Particles

__all__ = ["VelocityMotion"]

#: the kernel's regimes when nothing switches: every particle takes regime 0's transitions
_NO_REGIMES = np.zeros(0, dtype=np.int64)


@njit(cache=True, inline="always")
def _revert_and_add(target, z, decay, scale, regime):
    """``target = decay * target + scale * z`` (n,): an Ornstein-Uhlenbeck step, or with
    ``decay = 1`` a random walk's increment (``1 * target`` is ``target`` exactly).
    ``decay`` and ``scale`` (K,) are per regime, looked up by each particle's ``regime``
    (n,); an empty ``regime``: every particle takes regime 0's (one regime)."""
    if regime.size == 0:
        d, s = decay[0], scale[0]
        for i in range(target.size):
            target[i] = d * target[i] + s * z[i]
    else:
        for i in range(target.size):
            k = regime[i]
            target[i] = decay[k] * target[i] + scale[k] * z[i]


@njit(cache=True, inline="always")
def _jump_count(w, mean):
    """The number of jumps in a step whose expected number is ``mean``, by inversion of the
    Poisson distribution at ``w`` in ``[0, 1)``: the smallest ``k`` with ``w < P(K <= k)``."""
    pmf = math.exp(-mean)
    cdf = pmf
    k = 0
    while w >= cdf and pmf > 0.0:
        k += 1
        pmf *= mean / k
        cdf += pmf
    return k


@njit(cache=True)
def _speed_jumps(v, streams, mean, jump_sd, u):
    """The speed jumps of a step, in place: each particle's ``v`` (n,) gains
    ``N(0, k jump_sd^2)``, the sum of its ``k ~ Poisson(mean)`` jumps (``mean`` = jump rate
    x step). Each stream draws one uniform ``u`` in ``(0, 1]`` (a vectorised pass; ``u`` is
    float scratch (n,)); a particle jumps when ``u <= 1 - exp(-mean)`` (rare), and only then
    takes ``k`` from ``1 - u`` (:func:`_jump_count`) and draws one normal
    (:func:`streams.normal`). The velocity kernel runs it after the random walks' normals,
    and out of line: only when the jump rate is positive, so that without jumps the draws
    are those of the kernel without them."""
    for i in range(streams.size):
        u[i], streams[i] = rs.uniform(streams[i])
    jump = -math.expm1(-mean)
    for i in range(streams.size):
        if u[i] <= jump:
            z, streams[i] = rs.normal(streams[i])
            v[i] += math.sqrt(_jump_count(1.0 - u[i], mean)) * jump_sd * z


@njit(cache=True, nogil=True)
def _velocity_kernel(
    x, y, heading, c, s, v, w, regime, streams, n_steps, dt, steps, cumulative,
    jump_rate, jump_sd, weights, ox, oy, counter, sums,
):  # fmt: skip
    jumps = jump_rate > 0.0
    switching = regime.size > 0
    chunk, lo, hi = next_chunk(counter, x.size)
    while chunk >= 0:
        xs, ys, hs, cs, ss, vs, ws = motion_views(lo, hi, x, y, heading, c, s, v, w)
        chunk_streams = streams[lo:hi]
        chunk_regime = regime[lo:hi] if switching else regime
        z_speed = np.empty(hi - lo)
        z_turn = np.empty(hi - lo)
        retry = np.empty(hi - lo, dtype=np.bool_)
        jump_u = np.empty(hi - lo if jumps else 0)
        switch_u = np.empty(hi - lo if switching else 0)
        next_regime = np.empty(hi - lo if switching else 0, dtype=np.int64)
        for t in range(n_steps):
            rs.normal_pairs_into(chunk_streams, z_speed, z_turn, retry)  # speed, then turn
            if switching:  # the regime's step, then the new regime's transitions
                transition_pass(chunk_regime, chunk_streams, cumulative, switch_u, next_regime)
            _revert_and_add(vs, z_speed, steps[0], steps[1], chunk_regime)
            _revert_and_add(ws, z_turn, steps[2], steps[3], chunk_regime)
            if jumps:
                _speed_jumps(vs, chunk_streams, jump_rate * dt, jump_sd, jump_u)
            arc_pass(xs, ys, cs, ss, hs, vs, ws, dt)
            moments_pass(xs, ys, weights[lo:hi], ox, oy, sums[chunk, t])
        finish_headings(hs, cs, ss)
        chunk, lo, hi = next_chunk(counter, x.size)


@njit(cache=True, nogil=True, parallel=True)
def _velocity_parallel(
    threads, x, y, heading, c, s, v, w, regime, streams, n_steps, dt, steps, cumulative,
    jump_rate, jump_sd, weights, ox, oy, counter, sums,
):  # fmt: skip
    for _ in numba.prange(threads):
        _velocity_kernel(
            x, y, heading, c, s, v, w, regime, streams, n_steps, dt, steps, cumulative,
            jump_rate, jump_sd, weights, ox, oy, counter, sums,
        )  # fmt: skip


@dataclass(frozen=True)
class VelocityMotion:
    """The paper's velocity motion model (constant turn rate between steps).

    Each step adds ``N(0, sigma_speed^2 dt)`` to the speed and ``N(0, sigma_turn_rate^2 dt)``
    to the turn rate (random walks in speed and turn rate, so their spread over a horizon
    does not depend on the prediction step), then moves along the arc of the new speed and
    turn rate. As in the paper the speed is a signed linear velocity and may become negative
    (motion against the heading).

    The speed may also jump: at ``jump_rate`` jumps per second (a Poisson process), each
    adding ``N(0, jump_sd^2)`` m/s. That is the form of an animal whose speed holds between
    changes of behaviour and then changes at once, beside the small random walk of one whose
    speed drifts (reports/decisions.md, "Speed jumps for the velocity model").

    The turn rate may revert to zero instead (an Ornstein-Uhlenbeck process of reversion time
    ``turn_reversion`` tau): each step of ``dt`` draws its exact transition,
    ``omega' = omega exp(-dt/tau) + sigma_turn_rate sqrt(tau (1 - exp(-2 dt/tau)) / 2) z``, with
    the walk's normal ``z``. Its stationary spread is ``sigma_turn_rate sqrt(tau / 2)``, and
    the heading then diffuses (variance about ``sigma_turn_rate^2 tau^2 t`` for ``t >> tau``),
    where under the walk it spreads as ``t^3`` and a cloud circles on the spot
    (reports/decisions.md, "The velocity model's circling cloud"). tau -> infinity is the walk.

    With ``regimes`` (:class:`~hmmtrack.tracking.motion.regimes.VelocityRegimes`) each
    particle carries a regime in ``Particles.state``, drawn at the start from the regimes'
    stationary distribution. Each step the regime first moves along the switching chain
    (its exact transition over ``dt``; one uniform per particle, drawn only with two
    regimes or more), then speed and turn rate take that regime's exact transitions (a walk
    or a reversion to zero, each with the step's own normals); the jumps and the arc follow
    as without regimes. The regimes replace ``sigma_speed``, ``sigma_turn_rate`` and
    ``turn_reversion`` (which must then be None); one regime of the walk is today's model
    bit for bit.

    Parameters
    ----------
    sigma_speed : float
        Standard deviation of the speed increment over one second, m/s.
    sigma_turn_rate : float
        Standard deviation of the turn-rate increment over one second, rad/s.
    jump_rate : float
        Expected number of speed jumps per second, 1/s. 0 (default): no jumps, and nothing
        is drawn for them.
    jump_sd : float
        Standard deviation of one speed jump, m/s.
    turn_reversion : float or None
        Reversion time tau of the turn rate to zero, s (> 0). None (default): no reversion,
        the paper's random walk.
    regimes : VelocityRegimes or None
        The regimes and their switching chain; None (default): none, one kind of movement.
    """

    sigma_speed: float
    sigma_turn_rate: float
    jump_rate: float = 0.0
    jump_sd: float = 0.0
    turn_reversion: float | None = None
    regimes: VelocityRegimes | None = None
    compiled = True
    _tables: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("sigma_speed", "sigma_turn_rate", "jump_rate", "jump_sd"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"VelocityMotion.{name} must be a number >= 0, got {value}")
        tau = self.turn_reversion
        if tau is not None and not (np.isfinite(tau) and tau > 0):
            raise ValueError(f"VelocityMotion.turn_reversion must be a number > 0, got {tau}")
        if self.regimes is not None and tau is not None:
            raise ValueError("VelocityMotion: give turn_reversion in the regimes, not beside them")

    def turn_step(self, dt: float) -> tuple[float, float]:
        """The turn rate's transition over ``dt`` s: ``omega' = decay omega + scale z``.

        Returns
        -------
        decay : float
            ``exp(-dt / tau)``; exactly 1 for the random walk (no reversion).
        scale : float
            The spread of the step's noise, rad/s: ``sigma sqrt(dt)`` for the walk,
            ``sigma sqrt(tau (1 - exp(-2 dt / tau)) / 2)`` with reversion.
        """
        return reverting_step(self.sigma_turn_rate, self.turn_reversion, dt)

    def step_table(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The transitions over ``dt`` s by regime, computed once per ``dt``.

        Returns
        -------
        steps : (4, K) float
            Speed decay, speed scale (m/s), turn-rate decay, turn-rate scale (rad/s) of each
            regime (K = 1 without regimes: the speed's walk and :meth:`turn_step`).
        cumulative : (K, K) float
            Cumulative rows of the switching chain's transition over ``dt``
            (:meth:`VelocityRegimes.cumulative`); ``[[1.0]]`` for one regime.
        """
        if dt not in self._tables:
            regimes = self.regimes
            if regimes is None:  # one regime of the model's own walks (or turn reversion)
                tau = self.turn_reversion
                own = Regime(self.sigma_speed, self.sigma_turn_rate, turn_reversion=tau)
                regimes = VelocityRegimes((own,), ((0.0,),))
            self._tables[dt] = (regimes.steps(dt), regimes.cumulative(dt))
        return self._tables[dt]

    @property
    def switching(self) -> bool:
        """Whether particles switch regimes (two regimes or more)."""
        return self.regimes is not None and self.regimes.n_regimes > 1

    def initialise(self, rng: np.random.Generator, particles: Particles) -> None:
        """Particles start at rest as in the paper's Algorithm 1 (nothing to set); with
        regimes, each particle's regime (``state``) is drawn from the switching chain's
        stationary distribution (one uniform per particle, only with two regimes or more)."""
        if self.regimes is None:
            return
        if not self.switching:
            particles.state = np.zeros(particles.n, dtype=np.int64)
            return
        particles.state = draw_states(rng, np.cumsum(self.regimes.stationary()), particles.n)

    def propagate(self, rng: np.random.Generator, particles: Particles, dt: float) -> None:
        """One step of ``dt`` s for all particles, in place (NumPy reference): the random
        walks' normals ``(2, N)``, then, with jumps, each particle's number of jumps
        (``Poisson(jump_rate dt)``) and a normal for each particle that jumps; with two
        regimes or more, a uniform per particle for the regime's step of the chain."""
        normals = rng.standard_normal((2, particles.n))
        if self.jump_rate > 0.0:
            count = rng.poisson(self.jump_rate * dt, particles.n)
            jumped = np.flatnonzero(count)
            jumps = np.sqrt(count[jumped]) * self.jump_sd * rng.standard_normal(jumped.size)
            speed = particles.speed.copy()
            speed[jumped] += jumps
            particles.speed = speed
        if self.switching:
            particles.state = step_states(rng, particles.state, self.step_table(dt)[1])
        self.apply(particles, dt, normals)

    def apply(self, particles: Particles, dt: float, normals: np.ndarray) -> None:
        """The step of :meth:`propagate` with given standard normals ``(2, N)`` (dv, domega),
        each particle taking its regime's transitions (:meth:`step_table`)."""
        steps = self.step_table(dt)[0]
        by_particle = steps[:, particles.state] if self.switching else steps[:, 0]
        speed_decay, speed_scale, turn_decay, turn_scale = by_particle
        particles.speed = speed_decay * particles.speed + speed_scale * normals[0]
        particles.turn_rate = turn_decay * particles.turn_rate + turn_scale * normals[1]
        move_along_arc(particles, dt)

    def advance(self, particles, streams, n_steps, dt, weights, origin, threads=None) -> np.ndarray:
        """``n_steps`` compiled steps of ``dt`` s, in place; the weighted moments after each,
        ``(n_steps, 5)`` (:meth:`hmmtrack.tracking.motion.base.MotionModel.advance`)."""
        p = particles
        steps, cumulative = self.step_table(dt)
        regime = p.state if self.switching else _NO_REGIMES
        return run_chunks(
            _velocity_kernel, _velocity_parallel, p.n, n_steps, threads,
            p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate, regime,
            streams, n_steps, float(dt), steps, cumulative,
            float(self.jump_rate), float(self.jump_sd), weights, *origin,
        )  # fmt: skip
