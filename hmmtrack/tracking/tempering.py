"""Correction policies: how a particle filter applies one correction's log-likelihood.

:class:`ParticleFilter <hmmtrack.tracking.filter.ParticleFilter>` adds a correction's
log-likelihood to the log weights through a policy object with two methods,
``initialised(filter)`` (after the particles were drawn) and
``correct(filter, score, table) -> Estimate``:

* :class:`Plain` (the default, the paper's): add it in one go (:meth:`ParticleFilter.weigh`,
  which also recovers from degenerate weights);
* :class:`Tempered`: progressive correction. A sharp likelihood (an arrival time scores a
  particle to a few metres) against a cloud that spans kilometres would leave a handful of
  particles, so when one pass would leave fewer than ``ess · N`` effective particles the
  likelihood is applied in powers ``β₁ + β₂ + … = 1`` (:func:`temper`), each followed by
  resampling and a small Gaussian move of the positions shaped by the particles' own
  covariance (:func:`regularisation_move`), and the measurement rescores the moved particles
  (``score.rescore``). With a ``trigger`` below ``ess``, only a correction that would leave
  fewer than ``trigger · N`` in one pass is tempered (the cloud far wider than the
  likelihood); the others are plain. With ``within_components`` and a mixture filter, each
  component is moved by its own covariance (:func:`regularisation_move_within`): the whole
  cloud's covariance spans the distance between two modes, and a move shaped by it carries
  particles from one mode to the other, stage after stage, until the components meet and
  are merged. Usable with any measurement.

This module does not score observations (:mod:`hmmtrack.tracking.measurement`) nor hold the
filter's weights (the filter keeps them: :meth:`ParticleFilter.keep_weights`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


class Plain:
    """Add the log-likelihood to the log weights in one pass (the paper's correction)."""

    def initialised(self, pf) -> None:
        """Nothing to prepare."""

    def correct(self, pf, score, table):
        """:meth:`ParticleFilter.weigh` of ``score.loglik``; ``table()`` gives the
        observations for messages and recovery."""
        return pf.weigh(score.loglik, table)


@dataclass(frozen=True)
class Tempered:
    """Progressive correction with regularisation (see the module docstring).

    Parameters
    ----------
    ess : float
        Fraction of ``N`` in (0, 1): a correction that would leave fewer effective
        particles is tempered, in steps that each keep this many.
    trigger : float or None
        Fraction of ``N`` in (0, ``ess``]: temper only a correction that would leave fewer
        effective particles than this in one pass (the cloud much wider than the
        likelihood: before convergence, after a gap), and then in steps that keep ``ess``;
        a correction between the two is applied in one pass. ``None``: ``ess``.
    accept : bool
        Keep each particle's move only with the Metropolis probability of the likelihood
        applied so far, ``min(1, exp(β (ℓ(moved) − ℓ(before))))`` (β the powers applied),
        else put it back: the move is shaped by the whole cloud's covariance, so while
        stray particles far away hold weight it throws the particles off a mode a few
        metres wide (a ping's fix); ``False``: every move is kept (the regularisation alone).
    within_components : bool
        With a mixture filter (``ParticleFilter(mixture=...)``), move each component's
        particles by that component's covariance and the bandwidth of its particle count
        (:func:`regularisation_move_within`), so that no move carries a particle from one
        mode to another; ``False``, or without a mixture, or with one component: the
        whole cloud's (:func:`regularisation_move`).

    Notes
    -----
    The filter's weights are kept (:meth:`ParticleFilter.keep_weights`) wherever this policy
    replaces the log weights: after the particles are drawn and after each tempered step.
    The regularisation bandwidth is Silverman's for two dimensions,
    ``(4 / (4 N))^(1/6)`` (:func:`silverman_bandwidth`).
    """

    ess: float = 0.3
    trigger: float | None = None
    accept: bool = False
    within_components: bool = False

    def __post_init__(self) -> None:
        if not 0.0 < self.ess < 1.0:
            raise ValueError(f"tempering_ess must be in (0, 1), got {self.ess}")
        object.__setattr__(self, "ess", float(self.ess))
        if self.trigger is not None:
            if not 0.0 < self.trigger <= self.ess:
                raise ValueError(f"trigger must be in (0, ess = {self.ess}], got {self.trigger}")
            object.__setattr__(self, "trigger", float(self.trigger))

    def initialised(self, pf) -> None:
        """Keep the equal weights of fresh particles in the filter's cache."""
        pf.keep_weights(pf.particles.normalised_weights())

    def correct(self, pf, score, table):
        """Apply ``score.loglik`` in tempered steps; the weighted estimate after them.

        With a ``trigger``, first in one pass (:meth:`ParticleFilter.weigh`), kept when its
        ESS reaches ``trigger · N`` or the weights were degenerate (recovered as by
        :class:`Plain`), else undone (the log weights restored) and tempered.
        Between steps the particles are resampled (:meth:`ParticleFilter.resample`), moved
        (:func:`regularisation_move`, or :func:`regularisation_move_within` the mixture's
        components with ``within_components``; one ``(2, N)`` draw of standard normals from
        the filter's generator either way) and rescored (``score.rescore(particles,
        weights)``).
        """
        loglik = score.loglik
        if self.trigger is not None:
            before = pf.particles.log_weight  # ParticleFilter.weigh leaves this array intact
            events = len(pf.events)
            estimate = pf.weigh(loglik, table)
            recovered = len(pf.events) > events  # degenerate weights: re-placed, as Plain
            if recovered or estimate.n_eff >= self.trigger * pf.n_particles:
                return estimate
            pf.particles.log_weight = before
        bandwidth = silverman_bandwidth(pf.n_particles)
        mixture = pf.mixture if self.within_components else None
        remaining = 1.0
        stale = False
        while True:
            p = pf.particles
            beta, p.log_weight, weights = temper(p.log_weight, loglik, remaining, self.ess * p.n)
            pf.keep_weights(weights)
            remaining -= beta
            if remaining <= 1e-12:
                break
            pf.resample()
            p = pf.particles
            before = (p.x, p.y, loglik[pf.last_ancestors])
            normals = pf.rng.standard_normal((2, p.n))
            if mixture is None:
                p.x, p.y = regularisation_move(p.x, p.y, normals, bandwidth)
            else:
                p.x, p.y = regularisation_move_within(p.x, p.y, mixture.labels(p), normals)
            loglik = score.rescore(p, pf.weights()[0])
            if self.accept:
                loglik, stale = _metropolis(pf, before, loglik, 1.0 - remaining)
        if stale:
            score.rescore(p, pf.weights()[0])  # the measurement's run state at the kept places
        return pf.estimate()


def _metropolis(pf, before, loglik, applied: float):
    """Keep each moved particle with probability ``min(1, exp(applied · Δℓ))``, else put
    it back (``before``: positions (m) and log-likelihood before the move, (N,) each); the
    log-likelihood at the kept places, and whether any was put back (the measurement last
    scored the moved places). One ``(N,)`` uniform draw from the filter's generator."""
    p = pf.particles
    x, y, old = before
    kept = np.log(pf.rng.uniform(size=p.n)) < applied * (loglik - old)
    p.x, p.y = np.where(kept, p.x, x), np.where(kept, p.y, y)
    return np.where(kept, loglik, old), not kept.all()


@njit(cache=True)
def temper(log_weight, loglik, remaining, target):
    """The next tempered step: the largest power ``β ≤ remaining`` of the likelihood whose
    weights keep an effective sample size of at least ``target``, and those weights.

    ``β = remaining`` when its weights keep the target (the usual case: one pass). Else
    Newton's method on ``log ESS(β) = log target`` (:func:`tempered_ess` gives the slope),
    kept within a bracket ``[lo, hi]`` (bisection when a step would leave it), returns the
    bracket's low end once its ESS is within :data:`TEMPER_ESS_TOLERANCE` above the target
    (or the bracket is narrower than ``1e-12·remaining``): about three ESS evaluations
    (at most ten in the two-receiver preset's runs) instead of the 30 of a bisection. At
    least ``1e-3·remaining``.

    Returns
    -------
    beta : float
    log_weight : numpy.ndarray, shape (N,)
        ``log_weight + β·loglik`` normalised (:func:`tempered`).
    weights : numpy.ndarray, shape (N,)
        Normalised.
    """
    out, weights, ess = tempered(log_weight, loglik, remaining)
    if ess >= target:
        return remaining, out, weights
    mean = mean_squared = squares = 0.0  # the slope at β = remaining, from its weights
    for i in range(weights.size):
        mean += weights[i] * loglik[i]
        mean_squared += weights[i] * weights[i] * loglik[i]
        squares += weights[i] * weights[i]
    slope = 2.0 * (mean - mean_squared / squares)
    log_target = math.log(target)
    gap = math.log(ess) - log_target
    lo, hi, beta = 0.0, remaining, remaining
    for _ in range(100):
        step = beta - gap / slope if slope < 0.0 else -1.0
        beta = step if lo < step < hi else 0.5 * (lo + hi)
        ess, slope = tempered_ess(log_weight, loglik, beta)
        gap = math.log(ess) - log_target
        if gap >= 0.0:
            lo = beta
            if gap <= math.log1p(TEMPER_ESS_TOLERANCE):
                break
        else:
            hi = beta
        if hi - lo <= 1e-12 * remaining:
            break
    beta = max(lo, 1e-3 * remaining)
    out, weights, _ = tempered(log_weight, loglik, beta)
    return beta, out, weights


#: relative ESS above the target at which :func:`temper` stops refining the power
TEMPER_ESS_TOLERANCE = 1e-3


@njit(cache=True)
def tempered_ess(log_weight, loglik, beta):
    """Effective sample size of the weights ``exp(log_weight + β·loglik)`` (normalised)
    and its logarithm's derivative in ``β``, ``2·(E_w[loglik] − E_{w²}[loglik])``."""
    top = -math.inf
    for i in range(log_weight.size):
        top = max(top, log_weight[i] + beta * loglik[i])
    total = squares = mean = mean_squared = 0.0
    for i in range(log_weight.size):
        w = math.exp(log_weight[i] + beta * loglik[i] - top)
        total += w
        squares += w * w
        mean += w * loglik[i]
        mean_squared += w * w * loglik[i]
    return total * total / squares, 2.0 * (mean / total - mean_squared / squares)


@njit(cache=True)
def tempered(log_weight, loglik, beta):
    """``log_weight + β·loglik`` normalised (log-sum-exp 0), the weights (N,) and their
    effective sample size (the same number as :func:`tempered_ess`)."""
    n = log_weight.size
    out = np.empty(n)
    weights = np.empty(n)
    top = -math.inf
    for i in range(n):
        out[i] = log_weight[i] + beta * loglik[i]
        top = max(top, out[i])
    total = squares = 0.0
    for i in range(n):
        weights[i] = math.exp(out[i] - top)
        total += weights[i]
        squares += weights[i] * weights[i]
    scale = 1.0 / total
    shift = top + math.log(total)
    for i in range(n):
        weights[i] *= scale
        out[i] -= shift
    return out, weights, total * total / squares


def silverman_bandwidth(n: int) -> float:
    """Silverman's rule for a two-dimensional Gaussian kernel over ``n`` points,
    ``(4 / (4 n))^(1/6)`` (a multiple of the points' standard deviation)."""
    return (4.0 / (n * 4.0)) ** (1.0 / 6.0)


def regularisation_move_within(x, y, labels, normals):
    """:func:`regularisation_move` of each component on its own: the positions labelled
    ``k`` move by their own covariance and Silverman's bandwidth for their count
    (:func:`silverman_bandwidth`), with their own columns of ``normals``.

    With one component this is :func:`regularisation_move` with the bandwidth of all the
    points (the same numbers). A component of one particle stays in place (it has no
    covariance).

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    labels : numpy.ndarray, shape (N,), int
        Component of each position, ``0..K-1``.
    normals : numpy.ndarray, shape (2, N)
        Standard normal draws.

    Returns
    -------
    x, y : numpy.ndarray, shape (N,)
        New arrays (m).
    """
    components = int(labels.max()) + 1
    if components == 1:
        return regularisation_move(x, y, normals, silverman_bandwidth(x.size))
    moved_x, moved_y = x.copy(), y.copy()
    for k in range(components):
        members = np.flatnonzero(labels == k)
        if members.size < 2:
            continue
        moved_x[members], moved_y[members] = regularisation_move(
            x[members],
            y[members],
            np.ascontiguousarray(normals[:, members]),
            silverman_bandwidth(members.size),
        )
    return moved_x, moved_y


@njit(cache=True)
def regularisation_move(x, y, normals, bandwidth):
    """Move positions by ``bandwidth·L·normals``, ``L`` the Cholesky factor of their sample
    covariance (``np.cov``, N − 1 in the denominator) plus 1e-4 m² on the diagonal.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    normals : numpy.ndarray, shape (2, N)
        Standard normal draws.
    bandwidth : float

    Returns
    -------
    x, y : numpy.ndarray, shape (N,)
        New arrays (m).
    """
    n = x.size
    mean_x, mean_y = x.mean(), y.mean()
    sxx = sxy = syy = 0.0
    for i in range(n):
        dx, dy = x[i] - mean_x, y[i] - mean_y
        sxx += dx * dx
        sxy += dx * dy
        syy += dy * dy
    sxx = sxx / (n - 1) + 1e-4
    sxy = sxy / (n - 1)
    syy = syy / (n - 1) + 1e-4
    l11 = math.sqrt(sxx)  # 2 x 2 Cholesky factor [[l11, 0], [l21, l22]]
    l21 = sxy / l11
    l22 = math.sqrt(syy - l21 * l21)
    moved_x = np.empty(n)
    moved_y = np.empty(n)
    for i in range(n):
        moved_x[i] = x[i] + bandwidth * l11 * normals[0, i]
        moved_y[i] = y[i] + bandwidth * (l21 * normals[0, i] + l22 * normals[1, i])
    return moved_x, moved_y
