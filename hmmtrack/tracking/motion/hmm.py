"""Motion driven by a fitted movement HMM: each particle carries a behavioural state.

Per particle, speed ``= step / model.dt`` and turn rate ``= angle / model.dt`` are drawn
from the step and angle distributions of its state of a fitted
:class:`hmmtrack.hmm.MovementHMM`; the particle moves along the constant-turn-rate arc
(:mod:`hmmtrack.tracking.motion.arcs`) and its state moves along the behavioural chain. Two
variants (:data:`HMM_VARIANTS`, see :class:`HMMMotion`): ``"time_consistent"`` (the fitted
time step respected at any prediction step, draw clocks staggered across particles) and
``"paper"`` (new state and new draws every prediction step, whatever ``model.dt``);
optionally a heading random walk (``heading_diffusion``) and a random walk of the log of the
held speed (``speed_diffusion``) on top of the fitted model.

The compiled kernel draws with vectorised passes (:func:`_draw_pass`,
:func:`~hmmtrack.tracking.motion.chain.transition_pass`) whose draws are exactly those of the
scalar samplers of :mod:`hmmtrack.tracking.compiled.streams` (gamma steps and von Mises angles
only).
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit
from scipy.linalg import fractional_matrix_power

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.compiled.chunks import moments_pass, next_chunk, run_chunks
from hmmtrack.tracking.compiled.noalias import NoAliasCompiler
from hmmtrack.tracking.motion.arcs import arc_pass, finish_headings, move_along_arc
from hmmtrack.tracking.motion.base import motion_views
from hmmtrack.tracking.motion.chain import draw_states, next_states, step_states, transition_pass
from hmmtrack.tracking.particles import Particles

__all__ = ["HMM_VARIANTS", "STEP_UNITS", "HMMMotion", "step_metres", "transition_for_step"]

logger = logging.getLogger(__name__)

#: the HMM kernel draws with its vectorised passes for all particles of a chunk when more
#: than 1/SPARSE_DRAWS of them are due, else with the scalar samplers for the due ones only
SPARSE_DRAWS = 4
_ZERO = np.uint64(0)


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
    uniforms); the first tries themselves (:func:`_first_tries`, vectorised with the per-state
    table lookups as gathers), kept where due and accepted;
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
    _first_tries(
        v, w, behaviour, streams, retry, speed_factor, fitted_dt, gamma_d, gamma_c, gamma_boost,
        gamma_scale, zero_mass, vonmises_tables, normal, normal_accepted, step_u, angle_bits,
        angle_u, angle_v, advanced,
    )  # fmt: skip
    _redraw(
        v, w, behaviour, streams, speed_factor, fitted_dt, gamma_d, gamma_c, gamma_boost,
        gamma_scale, zero_mass, vonmises_tables, retry,
    )  # fmt: skip


@njit(cache=True, error_model="numpy", pipeline_class=NoAliasCompiler)
def _first_tries(
    v, w, behaviour, streams, retry, speed_factor, fitted_dt, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vonmises_tables, normal, normal_accepted, step_u, angle_bits,
    angle_u, angle_v, advanced,
):  # fmt: skip
    """The samplers' first tries (:func:`streams._gamma_from`, :func:`streams._vonmises_from`)
    from the random numbers :func:`_draw_pass` drew for every particle (arrays (n,)): a due
    particle (``retry``) whose tries both accept, in a state that is neither zero-inflated nor
    boosted, takes speed ``v`` (m/s), turn rate ``w`` (rad/s) and its advanced stream;
    ``retry`` then marks the due particles left to the scalar samplers.

    A vectorised loop, with the per-state tables' lookups as gathers. Three things make it
    one: numba's ``noalias`` flag (:class:`~hmmtrack.tracking.compiled.noalias.NoAliasCompiler`:
    no argument shares memory with ``v``, ``w``, ``streams`` or ``retry``), NumPy's error model
    (no zero-division checks, which are early exits, in the gamma's log series; a lane whose
    series divides by zero is one whose try is not used) and the stream's choice between the
    advanced and the old state as a bit blend (as a select of two loads LLVM makes it a load
    from a selected address, which it does not vectorise). Every value is the one the scalar
    loop gave: the same operations, no contraction.
    """
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
        kept = _ZERO - np.uint64(keep)  # all ones when kept
        streams[i] = (advanced[i] & kept) | (streams[i] & ~kept)
        retry[i] = retry[i] and not accepted


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
def _jitter_and_chain_draws(streams, w, jitter_scale, turn, u, retry):
    """The heading random walk's normal and the chain's uniform of a sub-step, in one pass
    over the streams (n,): ``turn = w + jitter_scale Z`` (rad/s) with ``Z`` drawn as
    :func:`streams.normal` draws it, then ``u`` as :func:`streams.uniform` draws it, the
    draws of :func:`streams.normals_into` followed by those of
    :func:`~hmmtrack.tracking.motion.chain.transition_pass`.

    A branch-free pass of the normal's first try and the uniform after it, then a scalar
    pass for the few whose try was rejected (``retry``, boolean scratch): the whole
    ziggurat, then the uniform, from the unchanged stream.
    """
    for i in range(streams.size):
        old = streams[i]
        z, accepted, middle = rs._normal_try(old)
        u[i], new = rs.uniform(middle)
        turn[i] = w[i] + jitter_scale * z
        retry[i] = not accepted
        streams[i] = new if accepted else old
    for i in range(streams.size):
        if retry[i]:
            z, state = rs._normal_loop(streams[i])
            u[i], streams[i] = rs.uniform(state)
            turn[i] = w[i] + jitter_scale * z


@njit(cache=True)
def _speed_walk(v, behaviour, streams, walk_scale, z, retry):
    """The log-speed random walk of a sub-step: ``v *= exp(walk_scale[state] Z)`` for each
    particle (n,), ``Z`` drawn as :func:`streams.normal` draws it (:func:`streams.normals_into`;
    ``z`` float and ``retry`` boolean scratch). ``walk_scale`` (K,) is each state's
    ``speed_diffusion sqrt(h)``; a particle in a state of scale 0 draws and keeps its speed.
    The kernel runs it right after the arc (its normal follows the heading diffusion's normal
    and the chain's uniform, which that draws before the arc, and precedes the chain's
    uniform without it), and out of line: only when some state's scale is positive, so that
    without it the draws are those of the kernel without a walk."""
    rs.normals_into(streams, z, retry)
    for i in range(v.size):
        v[i] *= math.exp(walk_scale[behaviour[i]] * z[i])


@njit(cache=True, nogil=True)
def _hmm_kernel(
    x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
    draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vonmises_tables, heading_diffusion, walk_scale, weights, ox, oy,
    counter, sums,
):  # fmt: skip
    due = draw_interval * (1.0 - 1e-9)
    speed_walk = walk_scale.max() > 0.0
    jitter_scale = heading_diffusion / math.sqrt(sub_step)  # rad/s of this sub-step
    speed_factor = metres_per_step_unit / fitted_dt
    chunk, lo, hi = next_chunk(counter, x.size)
    while chunk >= 0:
        xs, ys, hs, cs, ss, vs, ws = motion_views(lo, hi, x, y, heading, c, s, v, w)
        ks, clocks, chunk_streams = behaviour[lo:hi], clock[lo:hi], streams[lo:hi]
        scratch = np.empty(hi - lo)
        chain_u = np.empty(hi - lo)
        next_state = np.empty(hi - lo, dtype=np.int64)
        retry = np.empty(hi - lo, dtype=np.bool_)
        walk_z = np.empty(hi - lo if speed_walk else 0)
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
                    _jitter_and_chain_draws(
                        chunk_streams, ws, jitter_scale, scratch, chain_u, retry
                    )
                    arc_pass(xs, ys, cs, ss, hs, vs, scratch, sub_step)
                    if speed_walk:
                        _speed_walk(vs, ks, chunk_streams, walk_scale, walk_z, retry)
                    next_states(ks, cumulative, chain_u, next_state)
                else:
                    arc_pass(xs, ys, cs, ss, hs, vs, ws, sub_step)
                    if speed_walk:
                        _speed_walk(vs, ks, chunk_streams, walk_scale, walk_z, retry)
                    transition_pass(ks, chunk_streams, cumulative, chain_u, next_state)
                for i in range(clocks.size):
                    clocks[i] += sub_step
            moments_pass(xs, ys, weights[lo:hi], ox, oy, sums[chunk, t])
        finish_headings(hs, cs, ss)
        chunk, lo, hi = next_chunk(counter, x.size)


@njit(cache=True, nogil=True, parallel=True)
def _hmm_parallel(
    threads, x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
    draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c, gamma_boost,
    gamma_scale, zero_mass, vm_mean, vm_kappa, vm_width, vm_f_left, vm_f_right, vm_cut,
    vm_alias, heading_diffusion, walk_scale, weights, ox, oy, counter, sums,
):  # fmt: skip
    """:func:`_hmm_kernel` on ``threads`` threads; the von Mises tables (a tuple in the
    kernel) are passed as their seven arrays."""
    for _ in numba.prange(threads):
        _hmm_kernel(
            x, y, heading, c, s, v, w, behaviour, clock, streams, n_steps, n_sub, sub_step,
            draw_interval, metres_per_step_unit, fitted_dt, cumulative, gamma_d, gamma_c,
            gamma_boost, gamma_scale, zero_mass,
            (vm_mean, vm_kappa, vm_width, vm_f_left, vm_f_right, vm_cut, vm_alias),
            heading_diffusion, walk_scale, weights, ox, oy, counter, sums,
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
    along the constant-turn-rate arc (as :class:`~hmmtrack.tracking.motion.VelocityMotion`).

    Each (sub-)step of length ``h`` does, per particle: (1) if a draw is due, draw speed and
    turn rate from the current state; (2) move along the arc for ``h``; (3) with a speed
    diffusion, take the log-speed random walk's step; (4) move the behavioural state one step
    of the chain. Particles start with a state drawn from
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
        clouds of particles drift straight (measured in ``reports/decisions.md``, "Tracking
        defaults").
    heading_diffusion : float
        Standard deviation (rad per √s, ≥ 0) of a heading random walk added to the arcs:
        each sub-step of ``h`` s turns by ``omega h + heading_diffusion sqrt(h) Z`` with
        ``Z ~ N(0, 1)``. It stands for the wiggles of a real path about the fitted step's arc
        and, in a filter, lets copies of one particle made by resampling part before their
        next draw (without it they move identically for up to ``model.dt`` s). The law over
        a horizon does not depend on the prediction step (variances add over time). The
        default 0 is the fitted model alone.
    speed_diffusion : float or sequence of float
        Standard deviation (per √s, ≥ 0) of a random walk of the log of the held speed: each
        sub-step of ``h`` s multiplies a particle's speed by ``exp(speed_diffusion sqrt(h)
        Z)``, ``Z ~ N(0, 1)``, after it has moved. One value for every state, or one per state
        (K,): a state with 0 keeps its speed (a resting state added by
        :meth:`hmmtrack.hmm.MovementHMM.with_resting_state` holds its drift). It lets the
        copies of one particle made by resampling part in speed, as the heading diffusion
        parts them in heading; without it they hold one speed until their next draw, and a
        cloud that resamples often keeps only a few distinct speeds. Like the heading's, its
        law over a horizon does not depend on the prediction step. The default 0 draws
        nothing (the random streams are those of the model without it).
    """

    model: object
    variant: str = "time_consistent"
    heading_diffusion: float = 0.0
    speed_diffusion: float | tuple[float, ...] = 0.0
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
        spread = np.asarray(self.speed_diffusion, dtype=np.float64)
        if not (spread.ndim == 0 or spread.shape == (k,)):
            raise ValueError(
                f"speed_diffusion must be one value or one per state ({k}), got "
                f"{self.speed_diffusion!r}"
            )
        if not (np.all(np.isfinite(spread)) and np.all(spread >= 0)):
            raise ValueError(
                f"speed_diffusion must be >= 0 per sqrt(s), got {self.speed_diffusion!r}"
            )
        if spread.ndim == 1:
            object.__setattr__(self, "speed_diffusion", tuple(float(a) for a in spread))

    @property
    def _speed_diffusion(self) -> np.ndarray:
        """The log-speed random walk's spread of each state (per √s), shape (K,)."""
        k = np.asarray(self.model.initial).size
        return np.broadcast_to(np.asarray(self.speed_diffusion, dtype=np.float64), (k,)).copy()

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
        p.state = draw_states(rng, cumulative / cumulative[-1], p.n)
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
        walk_scale = self._speed_diffusion * np.sqrt(plan.sub_step)  # (K,), per sub-step
        speed_walk = walk_scale.max() > 0
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
                move_along_arc(p, plan.sub_step)
                p.turn_rate = held
            else:
                move_along_arc(p, plan.sub_step)
            if speed_walk:
                p.speed = p.speed * np.exp(walk_scale[p.state] * rng.standard_normal(p.n))
            p.time_since_draw += plan.sub_step
            p.state = step_states(rng, p.state, plan.cumulative)

    def advance(self, particles, streams, n_steps, dt, weights, origin, threads=None) -> np.ndarray:
        """``n_steps`` compiled steps of ``dt`` s, in place; the weighted moments after each,
        ``(n_steps, 5)`` (:meth:`hmmtrack.tracking.motion.base.MotionModel.advance`)."""
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
        return run_chunks(
            _hmm_kernel, _hmm_parallel, p.n, n_steps, threads,
            p.x, p.y, p.heading, p.cos_heading, p.sin_heading, p.speed, p.turn_rate,
            p.state, p.time_since_draw, streams, n_steps, plan.n_sub, plan.sub_step,
            plan.draw_interval, self._metres, float(self.model.dt), plan.cumulative,
            *self._schedules["samplers"], float(self.heading_diffusion),
            self._speed_diffusion * math.sqrt(plan.sub_step), weights, *origin,
        )  # fmt: skip
