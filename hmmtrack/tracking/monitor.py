"""Monitor: notice when a long silence has passed or the tag is lost, and re-acquire it.

A particle filter that has settled on a wrong point (the mirror intersection of two range
rings, or a tag that swam off while unheard) goes on reporting it with confidence.
:class:`Monitor` holds two rules, each switched on its own:

* **long gap** (``long_gap``): a correction more than ``max_gap`` seconds after the
  previous one. A tag may swim farther in that time than the receivers hear it, so the
  cloud carried across the gap no longer says where on the detections' rings it is (and
  the motion models describe seconds to minutes, not days); the observations across the
  gap are not trusted either (a range derived over a long gap counts pings over days of
  clock drift). The particles are re-placed over a box around the cloud on the grid
  posterior of this correction alone, tempered to stay wide (event ``long_gap``, then
  ``reacquired``). A shorter silence may have been **outswum**: once it is longer than
  :meth:`Monitor.outswim_gap` (the time a tag at ``speed`` needs to swim
  :data:`HEARING_RANGE`, 667 s at 1.5 m/s), the tag may be anywhere within a hearing range
  of where the cloud put it, while a motion model spreads the cloud roughly as a random
  walk (with √time, not time): the ring it is heard on can then lie hundreds of metres
  beyond the cloud, and the correction collapses the cloud onto its particle nearest the
  ring, a confident wrong point. So the correction's predictive likelihood (below) is
  compared with the grid's evidence (:func:`grid_evidence`) for a tag anywhere within
  :data:`HEARING_RANGE` of where it was heard (the cloud's mean after the previous
  correction); when the grid explains the detection better by more than ``margin`` nats,
  or when the ring crossed only the cloud's sparse tail (the correction left fewer than
  :data:`SPREAD_ESS` effective particles, a cloud that states no spread), the cloud was
  outswum (event ``outswum``, then ``reacquired`` from this correction over that box,
  untempered: a range within the measurement's own gap limit is trusted).
  Shorter silences are not asked: within a hearing range, a detection far from the cloud
  is the lost-tag test's question (below), which needs more than one correction to tell a
  lost tag from a mirror. Until a silence passes :meth:`Monitor.outswim_gap` the rule
  only notes the time and the cloud's mean after each correction (the filter's own, kept
  from the correction), and no run of the reproduction has such a silence (its longest is
  488 s, at 95 % loss), so a run without one is the run without the rule, draw for draw:
  the library's default filter carries it (:data:`hmmtrack.tracking.filter.FILTERS`).
* **lost tag** (``loss``): the *predictive likelihood* of a correction, ``p(y_t |
  y_1..t-1) ≈ Σ w_i p(y_t | x_i)`` with the weights before the correction, is the
  probability the particles gave the detections before they were heard. When its log per
  observation falls more than ``drop`` nats below its running median (of the last
  ``reference`` normal corrections) in ``patience`` corrections in a row, the suspicion is
  confirmed if the grid explains these suspicious corrections (those of them within the
  acquisition window of the latest) better than the particles did by more than
  ``margin`` nats in all (event ``tag_lost``, then ``reacquired``: the particles take the
  grid posterior of those corrections,
  :meth:`hmmtrack.tracking.acquisition.Acquisition.reacquire`). Only the suspicious ones:
  the earlier corrections may describe the tag before it moved. Like is compared with like:
  the particles' predictive likelihood is an average over where they put the tag, so the
  grid's is an average too (:func:`grid_evidence`: over the box, a tag that may swim
  ``speed`` m/s between each correction and the latest), not the best of its cells (the
  best of 4,096 cells beats a good filter by chance). Opt-in: on the shark pursuit it
  re-acquires onto the mirror about as often as onto the tag (reports/decisions.md,
  "Monitor: the grid's average, not its best cell").

The grid covers a box of the start box's size centred on the cloud's weighted mean (the
mirror point of an intersection lies within a ring's diameter of the true one); after a
long gap, each half-side at least :data:`HEARING_RANGE` (the tag may have swum anywhere on
the ring it was heard on), and after an outswum silence the same, centred on the cloud's
mean after the previous correction (after this one the cloud sits on its particle nearest
the ring). After a re-acquisition the measurement's run state is started afresh (its
``start`` hook: the arrival-time measurement re-acquires its clock from the next
detection) and a mixture's components are reset. The filter calls :meth:`Monitor.before`
before each correction (``ParticleFilter(monitor=...)``) and :meth:`Monitor.corrected`
after it, with the weights before it when the monitor asked for them (the lost-tag test,
or a silence the tag may have outswum).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from hmmtrack.tracking.acquisition import Acquisition, grid_loglik

__all__ = ["Monitor", "grid_evidence"]

#: corrections before the running median is trusted as the reference
WARM_UP = 10
#: m: how far from a receiver a tag is heard (the paper's scenarios hear half the pings at
#: 250-450 m, a few beyond 1 km): after a long gap the re-acquisition grid reaches at least
#: this far around the cloud, so that it holds the ring the tag was heard on; after a silence
#: in which the tag could swim this far the long-gap rule asks whether it outswam the cloud
HEARING_RANGE = 1000.0
#: s: the long gap. A tag at the monitor's top speed (1.5 m/s) swims 2.7 km in it, more than
#: the diameter of the ring a receiver hears it on (2 x HEARING_RANGE), so the cloud no
#: longer picks a point of the ring
MAX_GAP = 1800.0
#: effective particles below which a weighted cloud states no spread (its √λ₁ is one
#: particle's): after a silence the tag may have outswum, a correction that leaves fewer met
#: the detection's ring only in the cloud's sparse tail
SPREAD_ESS = 2.0


@dataclass
class Monitor:
    """Tests every correction for a long gap and a lost tag (module docstring).

    Parameters
    ----------
    long_gap : bool
        Apply the long-gap rule.
    loss : bool
        Apply the lost-tag test (it needs the weights before each correction).
    max_gap : float
        s: with ``long_gap``, a correction after a longer silence re-acquires from its own
        observations (after a shorter one, longer than :meth:`outswim_gap`, when the grid
        explains them better than the particles by ``margin`` nats or the correction left
        fewer than :data:`SPREAD_ESS` effective particles).
    drop : float
        Nats per observation below the running median of the predictive log-likelihood
        that make a correction suspicious.
    patience : int
        Suspicious corrections in a row before the grid is asked.
    margin : float
        Nats by which the grid must explain the suspicious corrections (or the correction
        after a silence the tag may have outswum) better than the particles did to declare
        the tag lost (:func:`grid_evidence`).
    speed : float
        m/s: how fast the tag may swim in the grid's explanation and over a silence (the
        synthetic shark pursuit's shark swims at 1.0 m/s in the median, 1.7 m/s at the 99th
        percentile).
    reference : int
        Normal corrections in the running median.
    gap_ess : float
        Fraction of the grid's cells effectively weighted after a long gap (the
        observations across it are tempered to that).
    acquisition : Acquisition
        Grid and proposal of the re-acquisitions.
    """

    long_gap: bool = True
    loss: bool = True
    max_gap: float = MAX_GAP
    drop: float = 4.0
    patience: int = 3
    margin: float = 10.0
    speed: float = 1.5
    reference: int = 50
    gap_ess: float = 0.25
    acquisition: Acquisition = field(default_factory=Acquisition)

    def __post_init__(self) -> None:
        if not (self.long_gap or self.loss):
            raise ValueError("a monitor needs long_gap or loss (or both)")
        if not (self.max_gap > 0 and self.drop > 0 and self.margin >= 0 and self.speed >= 0):
            raise ValueError(
                f"max_gap and drop must be positive, margin and speed non-negative; got "
                f"{self.max_gap}, {self.drop}, {self.margin}, {self.speed}"
            )
        for name in ("patience", "reference"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if not 0.0 < self.gap_ess <= 1.0:
            raise ValueError(f"gap_ess must lie in (0, 1], got {self.gap_ess!r}")

    def start(self, pf) -> None:
        """A fresh run: no history."""
        self._last: float | None = None
        self._history: deque = deque(maxlen=self.patience)
        self._normal: deque = deque(maxlen=self.reference)
        self._strikes = 0
        self._heard_at: tuple[float, float] | None = None

    def outswim_gap(self) -> float:
        """s: the silence in which a tag at :attr:`speed` swims :data:`HEARING_RANGE`
        (667 s at 1.5 m/s; never with a still tag); after a longer one (and up to
        :attr:`max_gap`) the long-gap rule asks whether the cloud was outswum."""
        return HEARING_RANGE / self.speed if self.speed > 0 else math.inf

    def before(self, pf) -> np.ndarray | None:
        """Before the correction at ``pf.time``: the normalised weights (N,) when the
        monitor will need them (the lost-tag test, or a silence the tag may have outswum),
        else ``None`` (nothing computed)."""
        if not (self.loss or self._may_be_outswum(pf.time)):
            return None
        return pf.weights()[0]

    def _may_be_outswum(self, time: float) -> bool:
        """Whether the long-gap rule asks the correction at ``time`` if the tag outswam
        the cloud (a silence longer than :meth:`outswim_gap`, not longer than
        :attr:`max_gap`)."""
        if not self.long_gap or self._last is None:
            return False
        return self.outswim_gap() < time - self._last <= self.max_gap

    def corrected(self, pf, loglik: np.ndarray, prior_weights: np.ndarray, rows) -> bool:
        """Test the correction just made at ``pf.time``; whether the particles were
        re-placed.

        Parameters
        ----------
        pf : ParticleFilter
        loglik : numpy.ndarray, shape (N,)
            The correction's log-likelihood of each particle (its first scoring).
        prior_weights : numpy.ndarray, shape (N,), or None
            Normalised weights before the correction, as :meth:`before` returned them.
        rows
            The observations, in the measurement's form.
        """
        time = pf.time
        outswum = self._may_be_outswum(time)
        gap = None if self._last is None else time - self._last
        self._last = time
        if self.long_gap and gap is not None and gap > self.max_gap:
            pf.alarm("long_gap", f"{gap:.0f} s since the previous correction")
            self._reacquire(pf, [(time, rows)], self.gap_ess, self._box(pf, HEARING_RANGE))
            replaced = True
        elif outswum and self._test_outswum(pf, loglik, prior_weights, rows, gap):
            replaced = True
        else:
            replaced = self.loss and self._test_loss(pf, loglik, prior_weights, rows)
        if self.long_gap:  # where the tag was heard: the centre of its reach after a silence
            self._heard_at = pf.weights()[2]
        return replaced

    def _test_outswum(self, pf, loglik: np.ndarray, prior_weights: np.ndarray, rows, gap) -> bool:
        """The long-gap rule's question after a silence of ``gap`` s the tag may have
        outswum: did the correction leave fewer than :data:`SPREAD_ESS` effective
        particles, or does a tag anywhere within :data:`HEARING_RANGE` of the cloud's mean
        after the previous correction explain this correction's observations better than
        the particles did, by more than :attr:`margin` nats? If so, re-acquire from them
        over that box (module docstring)."""
        box = self._box(pf, HEARING_RANGE, self._heard_at)
        corrections = [(pf.time, rows)]
        n_eff = pf.weights()[1]
        if n_eff < SPREAD_ESS:
            pf.alarm(
                "outswum",
                f"after {gap:.0f} s of silence the correction left {n_eff:.2f} effective "
                "particles: the cloud met the detection only in its tail",
            )
            self._reacquire(pf, corrections, None, box)
            return True
        predictive = _log_mean_exp(loglik, prior_weights)
        return self._grid_wins(
            pf,
            corrections,
            predictive,
            box,
            0.0,
            "outswum",
            f"after {gap:.0f} s of silence a tag within {HEARING_RANGE:.0f} m explains the "
            "detection better than the particles by {:.1f} nats",
        )

    def _test_loss(self, pf, loglik: np.ndarray, prior_weights: np.ndarray, rows) -> bool:
        """The lost-tag test of the correction at ``pf.time`` (module docstring)."""
        time = pf.time
        n_rows = max(len(rows), 1)
        predictive = _log_mean_exp(loglik, prior_weights)
        self._history.append((time, rows, predictive))
        per_row = predictive / n_rows
        if len(self._normal) >= WARM_UP and per_row < np.median(self._normal) - self.drop:
            self._strikes += 1
        else:
            self._strikes = 0
            self._normal.append(per_row)
        if self._strikes < self.patience:
            return False
        self._strikes = 0
        window = self.acquisition.window
        recent = [(t, r) for t, r, _ in self._history if time - t <= window]
        particles = sum(lp for t, _, lp in self._history if time - t <= window)
        return self._grid_wins(
            pf,
            recent,
            particles,
            self._box(pf),
            self.speed,
            "tag_lost",
            f"the grid explains the last {len(recent)} correction(s) better than the "
            "particles by {:.1f} nats",
        )

    def _grid_wins(self, pf, corrections, predictive, box, speed, kind, detail) -> bool:
        """Whether the grid's evidence for ``corrections`` over ``box`` (a tag swimming
        ``speed`` m/s, :func:`grid_evidence`) beats the particles' ``predictive``
        log-likelihood of them (nats) by more than :attr:`margin`; if so, record ``kind``
        (``detail`` formatted with the difference) and re-acquire from them over ``box``."""
        evidence = grid_evidence(
            pf.measurement, box, self.acquisition.cells, corrections, speed, pf.dt
        )
        if evidence - predictive <= self.margin:
            return False
        pf.alarm(kind, detail.format(evidence - predictive))
        self._reacquire(pf, corrections, None, box)
        return True

    def _box(self, pf, reach: float = 0.0, centre=None) -> tuple[float, float, float, float]:
        """A box of the start box's size centred on ``centre`` (m; default the cloud's
        weighted mean), each half-side at least ``reach`` (m)."""
        mx, my = pf.weights()[2] if centre is None else centre
        xmin, xmax, ymin, ymax = pf.bounds
        hx, hy = max(0.5 * (xmax - xmin), reach), max(0.5 * (ymax - ymin), reach)
        return (mx - hx, mx + hx, my - hy, my + hy)

    def _reacquire(self, pf, corrections, min_ess, box) -> None:
        detail = self.acquisition.reacquire(pf, corrections, box, min_ess)
        pf.restarted(detail)
        self._history.clear()
        self._strikes = 0


def _log_mean_exp(loglik: np.ndarray, weights: np.ndarray) -> float:
    """``log Σ w_i exp(loglik_i)`` (the predictive log-likelihood), ``-inf`` if none."""
    top = float(np.max(loglik))
    if not math.isfinite(top):
        return -math.inf
    return top + math.log(float(weights @ np.exp(loglik - top)))


def grid_evidence(measurement, bounds, cells: int, corrections, speed: float, dt: float = 1.0):
    """Log-likelihood of ``corrections`` for a tag anywhere in ``bounds`` that may swim.

    The prior puts the tag at the latest correction uniformly over the grid's cells, and at
    each earlier correction ``t`` uniformly within ``speed · (t_latest − t)`` (a square, in
    whole cells) of that place: each correction's likelihood on the grid
    (:func:`hmmtrack.tracking.acquisition.grid_loglik`, its terms) is averaged over that
    square, the logs summed over the corrections, and their exponentials averaged over the
    cells. The average of a likelihood under a prior, as the particles' predictive
    likelihood is; a still tag (``speed`` 0) is the plain average over the cells.

    Parameters
    ----------
    measurement, bounds, cells, dt
        As :func:`hmmtrack.tracking.acquisition.grid_loglik`.
    corrections : sequence of (float, rows)
        Times (s, increasing) and observations.
    speed : float
        m/s.

    Returns
    -------
    float
        Nats.
    """
    _, terms = grid_loglik(measurement, bounds, cells, corrections, dt, each=True)
    xmin, xmax, ymin, ymax = bounds
    cell = min((xmax - xmin) / cells, (ymax - ymin) / cells)
    latest = corrections[-1][0]
    total = np.zeros((cells, cells))
    for (time, _), term in zip(corrections, terms, strict=True):
        reach = int(speed * (latest - time) / cell + 0.5)
        grid = term.reshape(cells, cells)
        if reach > 0:
            top = grid.max()
            spread = ndimage.uniform_filter(np.exp(grid - top), 2 * reach + 1, mode="nearest")
            grid = top + np.log(np.maximum(spread, np.finfo(float).tiny))
        total += grid
    flat = total.ravel()
    return _log_mean_exp(flat, np.full(flat.size, 1.0 / flat.size))
