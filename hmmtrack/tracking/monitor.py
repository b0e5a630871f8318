"""Monitor: notice when the tag is lost or a long silence has passed, and re-acquire it.

A particle filter that has settled on a wrong point (the mirror intersection of two range
rings, or a tag that swam off while unheard) goes on reporting it with confidence. Its own
numbers say so: the *predictive likelihood* of a correction, ``p(y_t | y_1..t-1) ≈ Σ w_i
p(y_t | x_i)`` with the weights before the correction, is the probability the particles
gave the detections before they were heard. :class:`Monitor` tests it at every correction:

* **long gap**: a correction more than ``max_gap`` seconds after the previous one. The
  prior has diffused (or the model's motion does not describe so long a time) and the
  observations across the gap are not trusted (a range derived over a long gap counts
  pings over days of clock drift), so the particles are re-placed over a box around the
  cloud on the grid posterior of this correction alone, tempered to stay wide (event
  ``long_gap``, then ``reacquired``);
* **lost tag**: the predictive log-likelihood per observation falls more than ``drop``
  nats below its running median (of the last ``reference`` normal corrections) in
  ``patience`` corrections in a row. The suspicion is confirmed when a point of the grid
  explains these suspicious corrections (those of them within the acquisition window of
  the latest) better than the particles did by more than ``margin`` nats in all (event
  ``tag_lost``, then ``reacquired``: the particles take the grid posterior of those
  corrections, :meth:`hmmtrack.tracking.acquisition.Acquisition.reacquire`). Only the
  suspicious ones: the earlier corrections may describe the tag before it moved.

The grid covers a box of the start box's size centred on the cloud's weighted mean (the
mirror point of an intersection lies within a ring's diameter of the true one). After a
re-acquisition the measurement's run state is started afresh (its ``start`` hook: the
arrival-time measurement re-acquires its clock from the next detection) and a mixture's
components are reset. The filter calls :meth:`Monitor.corrected` after each correction
(``ParticleFilter(monitor=...)``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from hmmtrack.tracking.acquisition import Acquisition, grid_loglik

__all__ = ["Monitor"]

#: corrections before the running median is trusted as the reference
WARM_UP = 10


@dataclass
class Monitor:
    """Tests the predictive likelihood at every correction (module docstring).

    Parameters
    ----------
    max_gap : float
        s: a correction after a longer silence re-acquires from its own observations.
    drop : float
        Nats per observation below the running median of the predictive log-likelihood
        that make a correction suspicious.
    patience : int
        Suspicious corrections in a row before the grid is asked.
    margin : float
        Nats by which the grid's best point must explain the suspicious corrections
        better than the particles did to declare the tag lost.
    reference : int
        Normal corrections in the running median.
    gap_ess : float
        Fraction of the grid's cells effectively weighted after a long gap (the
        observations across it are tempered to that).
    acquisition : Acquisition
        Grid and proposal of the re-acquisitions.
    """

    max_gap: float = 1800.0
    drop: float = 4.0
    patience: int = 3
    margin: float = 10.0
    reference: int = 50
    gap_ess: float = 0.25
    acquisition: Acquisition = field(default_factory=Acquisition)

    def __post_init__(self) -> None:
        if not (self.max_gap > 0 and self.drop > 0 and self.margin >= 0):
            raise ValueError(
                f"max_gap and drop must be positive, margin non-negative; got {self.max_gap}, "
                f"{self.drop}, {self.margin}"
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

    def corrected(self, pf, loglik: np.ndarray, prior_weights: np.ndarray, rows) -> bool:
        """Test the correction just made at ``pf.time``; whether the particles were
        re-placed.

        Parameters
        ----------
        pf : ParticleFilter
        loglik : numpy.ndarray, shape (N,)
            The correction's log-likelihood of each particle (its first scoring).
        prior_weights : numpy.ndarray, shape (N,)
            Normalised weights before the correction.
        rows
            The observations, in the measurement's form.
        """
        time = pf.time
        gap = None if self._last is None else time - self._last
        self._last = time
        if gap is not None and gap > self.max_gap:
            pf.alarm("long_gap", f"{gap:.0f} s since the previous correction")
            self._reacquire(pf, [(time, rows)], self.gap_ess)
            return True
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
        box = self._box(pf)
        _, grid = grid_loglik(pf.measurement, box, self.acquisition.cells, recent, pf.dt)
        if grid.max() - particles > self.margin:
            pf.alarm(
                "tag_lost",
                f"a point of the grid explains the last {len(recent)} correction(s) better "
                f"than the particles by {grid.max() - particles:.1f} nats",
            )
            self._reacquire(pf, recent, None, box)
            return True
        return False

    def _box(self, pf) -> tuple[float, float, float, float]:
        """A box of the start box's size centred on the cloud's weighted mean (m)."""
        _, _, (mx, my) = pf.weights()
        xmin, xmax, ymin, ymax = pf.bounds
        hx, hy = 0.5 * (xmax - xmin), 0.5 * (ymax - ymin)
        return (mx - hx, mx + hx, my - hy, my + hy)

    def _reacquire(self, pf, corrections, min_ess, box=None) -> None:
        detail = self.acquisition.reacquire(
            pf, corrections, self._box(pf) if box is None else box, min_ess
        )
        pf.restarted(detail)
        self._history.clear()
        self._strikes = 0


def _log_mean_exp(loglik: np.ndarray, weights: np.ndarray) -> float:
    """``log Σ w_i exp(loglik_i)`` (the predictive log-likelihood), ``-inf`` if none."""
    top = float(np.max(loglik))
    if not math.isfinite(top):
        return -math.inf
    return top + math.log(float(weights @ np.exp(loglik - top)))
