"""Fixed-lag smoothing of a particle filter: by ancestor tracing, or for a random walk by
backward simulation.

A filter estimate at time ``t`` uses detections up to ``t`` only. Offline (or a little
late online) the estimate at ``t`` can also use what came after: follow the particles
alive at ``t + lag`` back through their resampling ancestry to time ``t`` and take the
positions their ancestors had then, weighted by the weights at ``t + lag``. This is the
fixed-lag smoother of Kitagawa (1996): it costs only bookkeeping of ancestor indices, and
its lag trades smoothing gain against path degeneracy (a long lag leaves few distinct
ancestors, so the smoothed cloud understates its uncertainty; each row reports how many
distinct ancestors remain).

Conventions: the filter pushes, every step, the particle positions and log weights after
the correction (before resampling) and ``parent``: for each particle, the index of the
particle of the previous push it descends from (the resampling indices; ``None`` when no
resampling happened in between).

Under a random-walk motion the steps before a sharp correction (a ping heard by many
receivers) keep only the few ancestors that survived its resamplings, and the traced
estimate there is as noisy as those few. :class:`BackwardSmoother` draws paths back through
the filter's clouds instead (:func:`backward_block`): each step, a path moves to any
particle near where it is, weighted by the filter, so the smoothed mean at every step rests
on hundreds of distinct particles.

:class:`Smoothed` is the smoother as a collector of
:class:`hmmtrack.tracking.filter.ParticleFilter` (``collect=[Smoothed(lag)]``): it pushes
every step the filter settles and traces the ancestry of every resampling.

This module does not run filters; it only consumes what they record.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.compiled.streams import uniform
from hmmtrack.tracking.particles import sqrt_largest_eigenvalue
from hmmtrack.tracking.resampling import first_above

#: rows of each table handed to a sink of smoothed estimates (as the filter's, its
#: ``ESTIMATE_ROWS``: memory per table of a few hundred kB)
SINK_ROWS = 10_000
#: gaps (in bridge gaps) beyond which a tag is taken to be away rather than between two fixes
#: of one path: its rows are passed on unbridged, so that the rows held back stay bounded
BRIDGE_LONGEST = 10
#: paths drawn back through each block by :class:`BackwardSmoother`: the smoothed mean's
#: Monte Carlo sd is the posterior's over √ of this (0.03 of it)
BACKWARD_PATHS = 500
#: Metropolis-Hastings moves per path and step of :func:`backward_block`, each a proposal
#: from the step's filter weights: enough that every path leaves a depleted lineage within a
#: few steps
BACKWARD_MOVES = 2
#: columns of the smoothed estimates table (the filter's estimates plus ``n_ancestors``: the
#: distinct ancestors traced, or the distinct particles the backward paths pass through)
SMOOTHED_COLUMNS = ("time", "x", "y", "var_x", "var_y", "cov_xy", "sqrt_lambda1", "n_ancestors")


def trace_ancestry(parents) -> np.ndarray:
    """Lineages of the final particles through a whole run.

    Parameters
    ----------
    parents : array_like of int, shape (T, N)
        ``parents[t, i]``: index at step ``t − 1`` of the parent of particle ``i`` at step
        ``t`` (row 0 is not used).

    Returns
    -------
    numpy.ndarray of int, shape (T, N)
        ``lineage[t, i]``: index at step ``t`` of the ancestor of final particle ``i``.
    """
    parents = np.asarray(parents)
    if parents.ndim != 2:
        raise ValueError(f"parents must have shape (T, N), got {parents.shape}")
    n_steps, n = parents.shape
    lineage = np.empty((n_steps, n), dtype=np.int64)
    lineage[-1] = np.arange(n)
    for t in range(n_steps - 1, 0, -1):
        lineage[t - 1] = parents[t, lineage[t]]
    return lineage


def weighted_moments(x, y, log_weight) -> tuple[float, float, float, float, float]:
    """Weighted mean and covariance of particle positions.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    log_weight : numpy.ndarray, shape (N,)
        Unnormalised log weights.

    Returns
    -------
    mean_x, mean_y, var_x, var_y, cov_xy : float
        m and m².
    """
    w = np.exp(log_weight - np.max(log_weight))
    w /= w.sum()
    mx = float(w @ x)
    my = float(w @ y)
    dx = x - mx
    dy = y - my
    return mx, my, float(w @ (dx * dx)), float(w @ (dy * dy)), float(w @ (dx * dy))


class FixedLagSmoother:
    """Online fixed-lag smoother: push filter steps in, get smoothed estimates ``lag`` steps late.

    Parameters
    ----------
    lag : int
        Number of filter steps between a time and the step whose particles smooth it
        (with 1 s steps, seconds); 0 reproduces the filter's own estimates.

    Notes
    -----
    Every filter step: ``row = smoother.push(t, x, y, log_weight, parent)``, keeping the
    rows that are not ``None``; at the end ``rows += smoother.finish()``, then
    :func:`smoothed_table`.
    """

    def __init__(self, lag: int) -> None:
        if int(lag) != lag or lag < 0:
            raise ValueError(f"lag must be a whole number of steps >= 0, got {lag!r}")
        self.lag = int(lag)
        self._times: deque[float] = deque()
        self._x: deque[np.ndarray] = deque()
        self._y: deque[np.ndarray] = deque()
        self._lineage: deque[np.ndarray | None] = deque()
        self._log_weight: np.ndarray | None = None

    def push(self, time: float, x, y, log_weight, parent=None) -> tuple | None:
        """Record one filter step; return the smoothed row for ``time − lag`` once available.

        Parameters
        ----------
        time : float
            Filter time of this step (s).
        x, y : numpy.ndarray, shape (N,)
            Particle positions after the correction (m); copied.
        log_weight : numpy.ndarray, shape (N,)
            Log weights after the correction.
        parent : numpy.ndarray of int, shape (N,), optional
            Index in the previous push of each particle's parent; ``None`` = identity.

        Returns
        -------
        tuple or None
            A row of :data:`SMOOTHED_COLUMNS`, or ``None`` while fewer than ``lag + 1``
            steps are buffered.
        """
        x = np.array(x, dtype=float)
        y = np.array(y, dtype=float)
        if self._x and x.shape != self._x[-1].shape:
            raise ValueError(
                f"step at time {time}: {x.shape} particles, the previous step had "
                f"{self._x[-1].shape}"
            )
        if parent is not None:
            parent = np.asarray(parent, dtype=np.int64)
            if parent.shape != x.shape:
                raise ValueError(f"parent has shape {parent.shape}, expected {x.shape}")
            for k, lineage in enumerate(self._lineage):
                self._lineage[k] = parent if lineage is None else lineage[parent]
        self._times.append(float(time))
        self._x.append(x)
        self._y.append(y)
        self._lineage.append(None)
        self._log_weight = np.array(log_weight, dtype=float)
        if len(self._times) <= self.lag:
            return None
        return self._pop()

    def _pop(self) -> tuple:
        time = self._times.popleft()
        x = self._x.popleft()
        y = self._y.popleft()
        lineage = self._lineage.popleft()
        if lineage is not None:
            x = x[lineage]
            y = y[lineage]
            n_ancestors = int(np.unique(lineage).size)
        else:
            n_ancestors = int(x.size)
        return (time, *weighted_moments(x, y, self._log_weight), n_ancestors)

    def finish(self) -> list[tuple]:
        """Smoothed rows of the last buffered steps, traced from the final particles."""
        rows = []
        while self._times:
            rows.append(self._pop())
        return rows


@njit(cache=True)
def backward_block(x, y, log_weight, parent, step_sd, paths, moves, state):
    """Backward simulation of a random walk through a block of filter steps: ``paths``
    trajectories drawn from the last step's weights, then back one step at a time, each
    from ``w_t^i · N(x_{t+1}; x_t^i, step_sd²)`` by ``moves`` independent
    Metropolis-Hastings moves proposed from the weights ``w_t``, started at the
    particle's resampling ancestor (FFBSi with MCMC moves: Bunch & Godsill 2013, Dubarry &
    Douc 2011). With no move accepted a path is its traced ancestry; each accepted move
    leaves a lineage the resamplings depleted for any particle of the filter near the path.

    Parameters
    ----------
    x, y : (T, N) float arrays
        Particle positions after each step's correction (m).
    log_weight : (T, N) float array
        Their log weights.
    parent : (T, N) int array
        ``parent[t, i]``: the index at step ``t − 1`` of particle ``i``'s ancestor (row 0
        not used).
    step_sd : float
        The random walk's sd per axis over one step (m).
    paths : int
        Trajectories drawn.
    moves : int
        Moves per path and step (:data:`BACKWARD_MOVES`).
    state : numpy.uint64
        State of the draws' stream (:func:`hmmtrack.tracking.compiled.streams.uniform`).

    Returns
    -------
    (T, 6) float array
        Per step: the trajectories' mean x, y (m), var x, var y, cov xy (m²) and the number
        of distinct particles they pass through.
    """
    n_steps, n = x.shape
    out = np.empty((n_steps, 6))
    cumulative = np.empty(n)
    index = np.empty(paths, dtype=np.int64)
    seen = np.zeros(n, dtype=np.int64)
    scale = -0.5 / (step_sd * step_sd)
    for t in range(n_steps - 1, -1, -1):
        top = log_weight[t].max()
        total = 0.0
        for i in range(n):
            total += math.exp(log_weight[t, i] - top)
            cumulative[i] = total
        for m in range(paths):
            if t == n_steps - 1:
                u, state = uniform(state)
                index[m] = first_above(cumulative, u * total, 0, n - 1)
                continue
            later = index[m]
            px, py = x[t + 1, later], y[t + 1, later]
            at = parent[t + 1, later]
            d2 = (px - x[t, at]) ** 2 + (py - y[t, at]) ** 2
            for _ in range(moves):
                u, state = uniform(state)
                proposal = first_above(cumulative, u * total, 0, n - 1)
                proposed = (px - x[t, proposal]) ** 2 + (py - y[t, proposal]) ** 2
                u, state = uniform(state)
                if u <= math.exp(scale * (proposed - d2)):
                    at, d2 = proposal, proposed
            index[m] = at
        mx = my = 0.0
        for m in range(paths):
            mx += x[t, index[m]]
            my += y[t, index[m]]
        mx /= paths
        my /= paths
        vx = vy = cxy = 0.0
        distinct = 0
        for m in range(paths):
            dx, dy = x[t, index[m]] - mx, y[t, index[m]] - my
            vx += dx * dx
            vy += dy * dy
            cxy += dx * dy
            if seen[index[m]] != t + 1:
                seen[index[m]] = t + 1
                distinct += 1
        out[t, 0], out[t, 1], out[t, 5] = mx, my, distinct
        out[t, 2], out[t, 3], out[t, 4] = vx / paths, vy / paths, cxy / paths
    return out


class BackwardSmoother:
    """Fixed-lag smoother of a random walk by backward simulation: push filter steps in,
    get smoothed rows at least ``lag`` steps late, in blocks.

    Every ``lag`` steps the last ``2·lag`` are simulated back (:func:`backward_block`) and
    the first ``lag`` of them passed on: each row's smoothing uses between ``lag`` and
    ``2·lag − 1`` later steps. Unlike ancestor tracing, the paths pass through any of the
    filter's particles at every step, not only the ancestors that survived the resamplings
    since: a sharp correction does not leave the steps before it a few lineages.

    Parameters
    ----------
    lag : int
        Steps (≥ 1).
    step_sd : float
        The random walk's sd per axis over one step (m).
    seed : int
        Seed of the backward draws (each block its own, drawn from it).
    paths : int
        Trajectories per block.
    moves : int
        Metropolis-Hastings moves per path and step.
    """

    def __init__(
        self,
        lag: int,
        step_sd: float,
        seed: int,
        paths: int = BACKWARD_PATHS,
        moves: int = BACKWARD_MOVES,
    ):
        self.lag = FixedLagSmoother(lag).lag
        if self.lag < 1:
            raise ValueError(f"backward simulation needs a lag of at least 1 step, got {lag}")
        self.step_sd = float(step_sd)
        self.paths = int(paths)
        self.moves = int(moves)
        self._seeds = np.random.default_rng(seed)
        self._steps: list[tuple] = []

    def push(self, time: float, x, y, log_weight, parent=None) -> list[tuple]:
        """Record one filter step (positions and log weights after its correction, and
        ``parent`` as :meth:`FixedLagSmoother.push`); the smoothed rows
        (:data:`SMOOTHED_COLUMNS` but ``sqrt_lambda1``) that became due."""
        x = np.array(x, dtype=float)
        parent = np.arange(x.size) if parent is None else np.asarray(parent, dtype=np.int64)
        self._steps.append(
            (float(time), x, np.array(y, dtype=float), np.array(log_weight, dtype=float), parent)
        )
        if len(self._steps) < 2 * self.lag:
            return []
        return self._flush(self.lag)

    def finish(self) -> list[tuple]:
        """The rows of every step still held."""
        return self._flush(len(self._steps)) if self._steps else []

    def _flush(self, count: int) -> list[tuple]:
        times, x, y, log_weight, parent = (np.stack(c) for c in zip(*self._steps, strict=True))
        state = np.uint64(self._seeds.integers(2**63))
        moments = backward_block(
            x, y, log_weight, parent, self.step_sd, self.paths, self.moves, state
        )
        self._steps = self._steps[count:]
        return [(times[k], *moments[k, :5].tolist(), int(moments[k, 5])) for k in range(count)]


def smoothed_table(rows) -> pd.DataFrame:
    """Table of smoothed estimates (columns :data:`SMOOTHED_COLUMNS`) from smoother rows."""
    raw = pd.DataFrame(
        list(rows), columns=["time", "x", "y", "var_x", "var_y", "cov_xy", "n_ancestors"]
    )
    raw["sqrt_lambda1"] = sqrt_largest_eigenvalue(raw["var_x"], raw["var_y"], raw["cov_xy"])
    return raw[list(SMOOTHED_COLUMNS)]


class Smoothed:
    """The fixed-lag smoother as a filter collector (table ``smoothed``).

    Every second whose particles are final (``settled``: after the correction, before the
    resampling) is pushed to a :class:`FixedLagSmoother`, with the ancestry of the
    resamplings since the previous push (``resampled``: tempered steps included).

    With a ``bridge``, the seconds strictly between two consecutive fixes more than its gap
    apart (a tag that went unheard) take the straight line between the smoothed positions at
    the two fixes: the mean path of a random walk between two known positions, which the
    few ancestors left across a long gap only approximate (each is one random-walk path, up
    to ~10 m off the line over a minute at 2.5 m/√s). Their spread columns are the traced
    ancestors'.

    With ``pin_fixes`` as well, each fix's row is the filter's own cloud at that step (its
    settled particles) and every gap between two fixes is bridged, however short. This is
    for ancestor tracing behind tempered corrections: a tempered correction moves its
    resampled particles (:func:`hmmtrack.tracking.tempering.regularisation_move`), so a
    particle after a sharp ping is not its ancestor's successor, and the traced rows on
    either side of the ping are not on a path through it (under the velocity model, on the
    simulated array, 1.3-1.4 m off the truth the step before a ping against 0.3 m at it).
    Tracing a fix through the next pings' moves does not sharpen it either; it leaves fewer
    ancestors (reports/decisions.md, "The matched model against the bound").

    Parameters
    ----------
    lag : int
        Steps (s) of the smoother; 0 reproduces the filter's own estimates.
    sink : callable, optional
        Called with tables of the smoothed estimates as they are made
        (:data:`SINK_ROWS` rows, the last one shorter), so that
        a long run's memory is bounded by the particles and the lag, not its span; the
        ``smoothed`` table is then ``None``.
    bridge : (knots, gap), optional
        ``knots`` (K,) sorted float array: times (s) of the corrections that fix the position
        (the filter step nearest each is a fix); ``gap`` (s): fixes farther apart than this are
        bridged by a straight line (see above). ``None``: no bridging.
    backward : float, optional
        The sd (m/√s) of a random-walk motion: smooth by backward simulation
        (:class:`BackwardSmoother`, seeded from the filter's generator without drawing from
        it) instead of ancestor tracing. ``None``: ancestor tracing.
    pin_fixes : bool
        With a ``bridge``: the fixes' rows are the filter's, and every gap between two fixes
        is bridged (see above).
    """

    #: the filter predicts one step at a time, so that every second is pushed
    every_step = True

    def __init__(
        self,
        lag: int,
        sink: Callable[[pd.DataFrame], None] | None = None,
        bridge: tuple[np.ndarray, float] | None = None,
        backward: float | None = None,
        pin_fixes: bool = False,
    ) -> None:
        self.lag = FixedLagSmoother(lag).lag  # (checked there)
        self.sink = sink
        self.bridge = bridge
        self.backward = backward
        self.pin_fixes = bool(pin_fixes) and bridge is not None

    def start(self, pf) -> None:
        if self.backward is None:
            self._smoother = FixedLagSmoother(self.lag)
        else:
            seed = int(pf.rng.spawn(1)[0].integers(2**63))
            step_sd = self.backward * math.sqrt(pf.dt)
            self._smoother = BackwardSmoother(self.lag, step_sd, seed)
        self._parent: np.ndarray | None = None
        self._rows: list[tuple] = []
        self._half_step = 0.5 * pf.dt
        self._fix: tuple | None = None  # the latest fix's row (bridge)
        self._pending: list[tuple] = []  # rows since it
        self._filtered: dict[float, tuple] = {}  # the filter's rows at fixes (pin_fixes)

    def settled(self, pf) -> None:
        p = pf.particles
        if self.pin_fixes and self._at_fix(pf.time):
            moments = weighted_moments(p.x, p.y, p.log_weight)
            self._filtered[pf.time] = (pf.time, *moments, int(np.unique(p.x).size))
        rows = self._smoother.push(pf.time, p.x, p.y, p.log_weight, self._parent)
        self._parent = None
        for row in rows if self.backward is not None else filter(None, [rows]):
            self._bridged(row)

    def _at_fix(self, time: float) -> bool:
        """Whether the step at ``time`` is the nearest to a fix of the bridge."""
        knots = self.bridge[0]
        after = int(np.searchsorted(knots, time))
        nearest = np.abs(knots[max(after - 1, 0) : after + 1] - time)
        return bool(nearest.size and nearest.min() <= self._half_step)

    def _bridged(self, row: tuple) -> None:
        """Pass ``row`` on, held back while it may lie inside a gap between two fixes."""
        if self.bridge is None:
            self._out([row])
            return
        gap = self.bridge[1]
        if not self._at_fix(row[0]):
            if self._fix is not None and row[0] - self._fix[0] > BRIDGE_LONGEST * gap:
                self._out(self._pending)  # the tag is away, not between two fixes
                self._fix, self._pending = None, []
            if self._fix is None:
                self._out([row])
            else:
                self._pending.append(row)
            return
        if self.pin_fixes:
            row = self._filtered.pop(row[0])
        if self._fix is not None and (self.pin_fixes or row[0] - self._fix[0] > gap):
            ends = [self._fix[0], row[0]]
            times = [r[0] for r in self._pending]
            x = np.interp(times, ends, [self._fix[1], row[1]])
            y = np.interp(times, ends, [self._fix[2], row[2]])
            self._pending = [
                (r[0], a, b, *r[3:]) for r, a, b in zip(self._pending, x, y, strict=True)
            ]
        self._out([*self._pending, row])
        self._fix, self._pending = row, []

    def _out(self, rows: list[tuple]) -> None:
        """Keep ``rows``, handing full tables to the sink."""
        self._rows.extend(rows)
        if self.sink is not None and len(self._rows) >= SINK_ROWS:
            self.sink(smoothed_table(self._rows))
            self._rows = []

    def resampled(self, pf, ancestors: np.ndarray) -> None:
        self._parent = ancestors if self._parent is None else self._parent[ancestors]

    def corrected(self, pf) -> None:
        """Nothing to record (the corrected step is pushed once settled)."""

    def result(self) -> dict[str, pd.DataFrame | None]:
        for row in self._smoother.finish():
            self._bridged(row)
        table = smoothed_table(self._rows + self._pending)
        if self.sink is None:
            return {"smoothed": table}
        self.sink(table)
        return {"smoothed": None}
