"""Regimes of the velocity motion model: a jump-Markov switch between kinds of movement.

An animal alternates between kinds of movement -- cruising straight, manoeuvring, holding
still -- whose speed and turn rate change in different ways. :class:`VelocityRegimes` gives
the velocity model (:class:`hmmtrack.tracking.motion.VelocityMotion`) one
:class:`Regime` per kind and a continuous-time Markov chain between them, with switching
rates per second. Each particle carries its regime (``Particles.state``); over a step of
``dt`` s the regime moves by the chain's exact transition matrix ``expm(Q dt)`` and the speed
and turn rate then take the new regime's exact transition over ``dt``: a random walk, or an
Ornstein-Uhlenbeck process that reverts to zero (:func:`reverting_step`).

This module holds the regimes' parameters and the matrices computed from them once per step
length; the draws are the velocity model's (:mod:`hmmtrack.tracking.motion.velocity`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

__all__ = ["Regime", "VelocityRegimes", "reverting_step"]


def reverting_step(sigma: float, reversion: float | None, dt: float) -> tuple[float, float]:
    """A step of ``dt`` s of a random walk or an Ornstein-Uhlenbeck process, exactly:
    ``x' = decay x + scale z`` with ``z ~ N(0, 1)``.

    Parameters
    ----------
    sigma : float
        Spread of the increments over one second (units of ``x`` per √s).
    reversion : float or None
        Reversion time tau to zero, s (> 0); ``None``: no reversion, the random walk.
    dt : float
        Step, s.

    Returns
    -------
    decay : float
        ``exp(-dt / tau)``; exactly 1 for the random walk.
    scale : float
        ``sigma sqrt(dt)`` for the walk, ``sigma sqrt(tau (1 - exp(-2 dt / tau)) / 2)`` with
        reversion (whose stationary spread is ``sigma sqrt(tau / 2)``).
    """
    if reversion is None:
        return 1.0, sigma * np.sqrt(dt)
    variance = -reversion * math.expm1(-2.0 * dt / reversion) / 2.0
    return math.exp(-dt / reversion), sigma * math.sqrt(variance)


@dataclass(frozen=True)
class Regime:
    """How speed and turn rate change in one regime of the velocity model.

    Parameters
    ----------
    sigma_speed : float
        Spread of the speed increments, m/s per √s.
    sigma_turn_rate : float
        Spread of the turn-rate increments, rad/s per √s.
    speed_reversion : float or None
        Reversion time of the speed to zero, s (a regime that comes to rest); ``None``: the
        speed's random walk.
    turn_reversion : float or None
        Reversion time of the turn rate to zero, s (a regime that swims straight);
        ``None``: the turn rate's random walk (the paper's, which circles).
    """

    sigma_speed: float
    sigma_turn_rate: float
    speed_reversion: float | None = None
    turn_reversion: float | None = None

    def __post_init__(self) -> None:
        for name in ("sigma_speed", "sigma_turn_rate"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Regime.{name} must be a number >= 0, got {value}")
        for name in ("speed_reversion", "turn_reversion"):
            tau = getattr(self, name)
            if tau is not None and not (np.isfinite(tau) and tau > 0):
                raise ValueError(f"Regime.{name} must be a number > 0 or None, got {tau}")

    def steps(self, dt: float) -> tuple[float, float, float, float]:
        """The regime's transitions over ``dt`` s (:func:`reverting_step`): speed decay,
        speed scale (m/s), turn-rate decay, turn-rate scale (rad/s)."""
        return (
            *reverting_step(self.sigma_speed, self.speed_reversion, dt),
            *reverting_step(self.sigma_turn_rate, self.turn_reversion, dt),
        )


@dataclass(frozen=True)
class VelocityRegimes:
    """The velocity model's regimes and the Markov chain that switches between them.

    Parameters
    ----------
    regimes : tuple of Regime
        K regimes; a particle's ``state`` is its regime's index.
    rates : (K, K) nested tuple of float
        Switching rates per second: ``rates[i][j]`` (i != j) is the rate of leaving regime
        ``i`` for ``j``, 1/s (>= 0). The diagonal is ignored (the generator's diagonal is
        minus the row's sum), so the expected dwell in ``i`` is ``1 / sum_j rates[i][j]``.

    Notes
    -----
    The chain must have one stationary distribution (irreducible); particles start in it.
    One regime (K = 1) is a velocity model without switching: nothing is drawn for the chain.
    """

    regimes: tuple[Regime, ...]
    rates: tuple[tuple[float, ...], ...]

    def __post_init__(self) -> None:
        k = len(self.regimes)
        rates = np.asarray(self.rates, dtype=np.float64)
        if k < 1 or rates.shape != (k, k):
            raise ValueError(
                f"VelocityRegimes needs K >= 1 regimes and (K, K) rates, got {k} and {rates.shape}"
            )
        off = rates[~np.eye(k, dtype=bool)]
        if not (np.all(np.isfinite(off)) and np.all(off >= 0)):
            raise ValueError("VelocityRegimes.rates must be finite and >= 0 off the diagonal")
        stationary = self.stationary()
        if not (np.all(np.isfinite(stationary)) and np.all(stationary > 1e-12)):
            raise ValueError(
                "VelocityRegimes.rates must connect every regime (one stationary distribution)"
            )

    @property
    def n_regimes(self) -> int:
        """K, the number of regimes."""
        return len(self.regimes)

    def generator(self) -> np.ndarray:
        """The chain's generator ``Q`` (K, K), 1/s: the rates off the diagonal, minus each
        row's sum on it (rows sum to 0)."""
        q = np.asarray(self.rates, dtype=np.float64).copy()
        np.fill_diagonal(q, 0.0)
        np.fill_diagonal(q, -q.sum(axis=1))
        return q

    def stationary(self) -> np.ndarray:
        """The stationary distribution ``pi`` (K,): ``pi Q = 0``, ``sum(pi) = 1`` (least
        squares on the stacked system; exact for an irreducible chain)."""
        q = self.generator()
        k = q.shape[0]
        system = np.vstack([q.T, np.ones((1, k))])
        target = np.zeros(k + 1)
        target[-1] = 1.0
        pi = np.linalg.lstsq(system, target, rcond=None)[0]
        return pi if np.allclose(system @ pi, target, atol=1e-10) else np.full(k, np.nan)

    def dwell(self) -> np.ndarray:
        """Expected dwell in each regime (K,), s: ``1 / -Q_ii`` (``inf`` for a regime never
        left)."""
        with np.errstate(divide="ignore"):
            return 1.0 / -np.diag(self.generator())

    def transition(self, dt: float) -> np.ndarray:
        """The chain's exact transition matrix over ``dt`` s, ``expm(Q dt)`` (K, K), rows
        summing to 1."""
        matrix = np.clip(expm(self.generator() * dt), 0.0, None)
        return matrix / matrix.sum(axis=1, keepdims=True)

    def cumulative(self, dt: float) -> np.ndarray:
        """Cumulative rows of :meth:`transition` (K, K), the last column exactly 1: a
        particle in regime ``i`` with uniform ``u`` moves to the first ``j`` with
        ``u <= cumulative[i, j]``."""
        cumulative = np.cumsum(self.transition(dt), axis=1)
        cumulative[:, -1] = 1.0
        return cumulative

    def steps(self, dt: float) -> np.ndarray:
        """Every regime's :meth:`Regime.steps` over ``dt`` s, (4, K): speed decay, speed
        scale, turn-rate decay, turn-rate scale."""
        return np.array([regime.steps(dt) for regime in self.regimes], dtype=np.float64).T.copy()
