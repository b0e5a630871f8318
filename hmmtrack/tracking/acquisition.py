"""Acquisition: start the particles where the first detections put the tag, every mode of it.

The paper starts the particles uniformly in a search box. Two range circles (or two
hyperbolae) meet at two points, and the few particles that happen to fall near the wrong
one -- or near neither -- decide the run: a mode that no particle starts in is never found.
:class:`Acquisition` draws the initial particles from the likelihood of the first
corrections instead, evaluated on a coarse grid over the box:

1. a grid of ``cells x cells`` points over the box, at rest, is scored by the
   measurement itself with the observations of the first ``corrections`` corrections
   (within ``window`` seconds of the first), the tag taken as still over that span
   (:func:`grid_loglik`: the measurement's ``score`` hook with a fresh ``start`` state when
   it has them -- the arrival-time measurement starts each grid point's clock on the first
   detection, so the rest score the time differences, the hyperbolae -- else its
   ``loglik``; nothing measurement-specific here);
2. that log-likelihood is tempered (multiplied by ``beta <= 1``) until at least
   ``grid_ess`` of the cells carry weight: the tag moves during the window and the grid
   is coarse, so the proposal must be wider than the likelihood;
3. particles are drawn from it (a cell by its tempered weight, a point uniform in the
   cell), a share ``uniform_share`` uniformly in the box (the proposal never excludes a
   place the prior allows), and given the importance weight ``prior / proposal``
   (:func:`propose`): the filter then scores the same observations as always, so its
   posterior is the paper's, only better sampled -- both intersections start populated.

A measurement may say which corrections inform it (an ``informative(rows)`` hook: a ping
heard by one receiver says nothing of the position); then the first informative ones are
scored, and when others come before them the filter starts its particles at the first
informative one (:meth:`hmmtrack.tracking.filter.ParticleFilter.iterate`), not at the start.
A measurement sharper than a cell (a ping's hyperbolae) widens itself for the grid (an
``on_grid(cell)`` hook, :func:`grid_loglik`).

The same grid re-places the particles when the tag is lost
(:class:`hmmtrack.tracking.monitor.Monitor`): there the recent corrections are scored and
the particles take the grid posterior's weights.

This module moves no particle in time and reads no file.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from hmmtrack.tracking.particles import Particles, as_bounds

__all__ = ["Acquisition", "grid_loglik", "propose", "temper"]


@dataclass(frozen=True)
class Acquisition:
    """Initial particles drawn from the first corrections' likelihood (module docstring).

    Parameters
    ----------
    corrections : int
        Corrections whose observations are scored on the grid (the first ones).
    window : float
        s: only corrections within this time of the first are scored (the tag is taken as
        still over it).
    cells : int
        The grid has ``cells x cells`` points over the box.
    grid_ess : float
        Fraction in (0, 1]: the grid log-likelihood is tempered until this share of cells
        is effectively weighted.
    uniform_share : float
        Fraction in (0, 1) of the proposal that is uniform in the box.
    """

    corrections: int = 4
    window: float = 120.0
    cells: int = 64
    grid_ess: float = 0.02
    uniform_share: float = 0.1

    def __post_init__(self) -> None:
        if int(self.corrections) != self.corrections or self.corrections < 1:
            raise ValueError(f"corrections must be a positive integer, got {self.corrections!r}")
        if not (math.isfinite(self.window) and self.window >= 0):
            raise ValueError(f"window must be a non-negative number of seconds, got {self.window}")
        if int(self.cells) != self.cells or self.cells < 2:
            raise ValueError(f"cells must be an integer >= 2, got {self.cells!r}")
        if not 0.0 < self.grid_ess <= 1.0:
            raise ValueError(f"grid_ess must lie in (0, 1], got {self.grid_ess!r}")
        if not 0.0 < self.uniform_share < 1.0:
            raise ValueError(f"uniform_share must lie in (0, 1), got {self.uniform_share!r}")

    def first(self, corrections, measurement=None):
        """The corrections to score: the first :attr:`corrections` of ``corrections`` (an
        iterable of ``(time, rows)``, by time, read no further than needed) within
        :attr:`window` of the first; of those that inform ``measurement`` when it says which
        do (its ``informative(rows)`` hook: a ping heard by one receiver says nothing of
        where the tag is)."""
        informative = getattr(measurement, "informative", None)
        if informative is not None:
            corrections = (c for c in corrections if informative(c[1]))
        chosen = list(itertools.islice(corrections, self.corrections))
        return [c for c in chosen if c[0] - chosen[0][0] <= self.window] if chosen else []

    def place(self, pf, chosen) -> str:
        """Re-place the filter's fresh particles from the likelihood of the ``chosen``
        corrections.

        Parameters
        ----------
        pf : ParticleFilter
            Just started: its particles, bounds, generator, measurement and ``dt``.
        chosen : sequence of (float, rows)
            The corrections to score (:meth:`first`): time (s) and the observations in the
            measurement's form (what the filter scores).

        Returns
        -------
        str
            What was done (for the filter's ``acquired`` event).
        """
        _, loglik = grid_loglik(pf.measurement, pf.bounds, self.cells, chosen, pf.dt)
        beta = temper(loglik, self.grid_ess)
        p = pf.particles
        p.x, p.y, log_q = propose(
            pf.rng, pf.bounds, self.cells, beta * loglik, p.n, self.uniform_share
        )
        log_weight = -log_q
        p.log_weight = log_weight - _log_sum_exp(log_weight)
        return (
            f"particles drawn from the likelihood of {len(chosen)} correction(s) "
            f"({chosen[0][0]:.0f}-{chosen[-1][0]:.0f} s) on a {self.cells}x{self.cells} grid, "
            f"tempered by {beta:.3g}"
        )

    def reacquire(self, pf, corrections, bounds, min_ess: float | None = None) -> str:
        """Re-place the particles on the grid posterior of recent ``corrections`` (already
        scored by the filter) over ``bounds``: positions drawn as in :meth:`place`, log
        weights the grid's tempered log-likelihood minus the proposal's, so the cloud is
        that posterior under a uniform prior over the box. ``min_ess`` (default
        :attr:`grid_ess`) tempers the likelihood itself: observations that are not trusted
        (after a long gap) get a larger one and so a wider cloud."""
        _, loglik = grid_loglik(pf.measurement, bounds, self.cells, corrections, pf.dt)
        proposal_beta = temper(loglik, self.grid_ess)
        beta = proposal_beta if min_ess is None else min(proposal_beta, temper(loglik, min_ess))
        p = pf.particles
        x, y, log_q = propose(
            pf.rng, bounds, self.cells, proposal_beta * loglik, p.n, self.uniform_share
        )
        log_weight = beta * loglik[_cell_of(bounds, self.cells, x, y)] - log_q
        p.x, p.y = x, y
        p.log_weight = log_weight - _log_sum_exp(log_weight)
        return (
            f"particles re-placed on the grid posterior of {len(corrections)} correction(s) "
            f"({corrections[0][0]:.0f}-{corrections[-1][0]:.0f} s) over "
            f"{bounds[1] - bounds[0]:.0f} x {bounds[3] - bounds[2]:.0f} m, tempered by {beta:.3g}"
        )


def grid_loglik(measurement, bounds, cells: int, corrections, dt: float = 1.0, each: bool = False):
    """The summed log-likelihood of ``corrections`` at the points of a grid over ``bounds``.

    Parameters
    ----------
    measurement
        A :class:`hmmtrack.tracking.measurement.base.Measurement`: scored by its ``score``
        hook (with a fresh ``start`` state, the clock of the arrival-time measurement) when
        it has one, else by ``loglik``; when it has an ``on_grid(cell)`` hook, as that
        returns it for the grid's cell (m): a likelihood sharper than a cell (a ping's
        hyperbolae, metres wide) widened so that the cell centres do not miss it.
    bounds : (xmin, xmax, ymin, ymax)
        m.
    cells : int
        Grid points per axis; the points are the cell centres.
    corrections : sequence of (float, rows)
        Times (s) and observations in the measurement's form.
    dt : float
        The filter's step (s), for the measurement's ``start`` hook.
    each : bool
        Return each correction's terms instead of their sum: ``p(y_k | y_1..k-1)`` at each
        still point (its own log-likelihood for a measurement without a run state).

    Returns
    -------
    grid : Particles
        ``cells**2`` particles at rest at the cell centres (row-major: y, then x).
    loglik : numpy.ndarray, shape (cells**2,), or (len(corrections), cells**2) with ``each``
        Sum over the corrections (or each term); finite (``-inf`` replaced by the lowest
        finite value minus 50 nats, a cell that no observation allows).
    """
    xmin, xmax, ymin, ymax = as_bounds(bounds)
    on_grid = getattr(measurement, "on_grid", None)
    if on_grid is not None:
        measurement = on_grid(max(xmax - xmin, ymax - ymin) / cells)
    cx = xmin + (np.arange(cells) + 0.5) * (xmax - xmin) / cells
    cy = ymin + (np.arange(cells) + 0.5) * (ymax - ymin) / cells
    gx, gy = np.meshgrid(cx, cy)
    grid = Particles.from_state(gx.ravel(), gy.ravel(), np.zeros(cells * cells))
    start = getattr(measurement, "start", None)
    score = getattr(measurement, "score", None)
    state = None if start is None else start(grid, float(corrections[0][0]), dt)
    weights = np.full(grid.n, 1.0 / grid.n)
    terms = np.zeros((len(corrections) if each else 1, grid.n))
    for k, (time, rows) in enumerate(corrections):
        if score is None:
            terms[k if each else 0] += measurement.loglik(grid, rows, time=time)
        else:
            scored = score(grid, rows, time, state, weights)
            terms[k if each else 0] += scored.loglik
            if scored.commit is not None:
                scored.commit(grid)
    for term in terms:
        finite = np.isfinite(term)
        term[~finite] = term[finite].min() - 50.0 if finite.any() else 0.0
    return grid, terms if each else terms[0]


def temper(loglik: np.ndarray, min_ess: float) -> float:
    """The largest ``beta`` in (0, 1] with an effective sample size of ``exp(beta loglik)``
    of at least ``min_ess`` times the number of cells (bisection on ``log beta``)."""
    n = loglik.size
    centred = loglik - loglik.max()

    def ess(beta: float) -> float:
        w = np.exp(beta * centred)
        return w.sum() ** 2 / (w @ w) / n

    if ess(1.0) >= min_ess:
        return 1.0
    lo, hi = -30.0, 0.0  # log beta
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if ess(math.exp(mid)) >= min_ess:
            lo = mid
        else:
            hi = mid
    return math.exp(lo)


def propose(rng, bounds, cells: int, log_weight: np.ndarray, n: int, uniform_share: float):
    """``n`` points from the grid's cells by ``exp(log_weight)`` (uniform within a cell),
    a share ``uniform_share`` of them uniform over the box instead.

    Returns
    -------
    x, y : numpy.ndarray, shape (n,)
        m.
    log_q : numpy.ndarray, shape (n,)
        Log of the proposal density at each point times the box's area (0 for a uniform
        proposal).
    """
    xmin, xmax, ymin, ymax = as_bounds(bounds)
    w = np.exp(log_weight - log_weight.max())
    w /= w.sum()
    from_grid = rng.uniform(size=n) >= uniform_share
    cell = rng.choice(w.size, size=n, p=w)
    u, v = rng.uniform(size=n), rng.uniform(size=n)
    col, row = cell % cells, cell // cells
    width, height = (xmax - xmin) / cells, (ymax - ymin) / cells
    x = np.where(from_grid, xmin + (col + u) * width, xmin + u * (xmax - xmin))
    y = np.where(from_grid, ymin + (row + v) * height, ymin + v * (ymax - ymin))
    log_q = np.log(
        uniform_share + (1.0 - uniform_share) * w.size * w[_cell_of(bounds, cells, x, y)]
    )
    return x, y, log_q


def _cell_of(bounds, cells: int, x, y) -> np.ndarray:
    """Grid cell index of each point (row-major), points on the edge in the edge cells."""
    xmin, xmax, ymin, ymax = as_bounds(bounds)
    col = np.clip(((x - xmin) / (xmax - xmin) * cells).astype(np.int64), 0, cells - 1)
    row = np.clip(((y - ymin) / (ymax - ymin) * cells).astype(np.int64), 0, cells - 1)
    return row * cells + col


def _log_sum_exp(values: np.ndarray) -> float:
    top = float(values.max())
    return top + math.log(float(np.exp(values - top).sum()))
