"""Mixture tracking: resampling that cannot lose a mode of the posterior by drift.

Two range circles meet at two points, so a tag heard by few receivers has a posterior with
several modes. A filter that resamples the whole cloud after every correction lets the
random drift of resampling choose between them: the share of particles in each mode is a
random walk that ends, sooner or later, with one mode gone, and the survivor is then
reported as certain. :class:`Mixture` is the mixture particle filter of Vermaak, Doucet &
Pérez (2003, "Maintaining multimodality through mixture tracking", ICCV):

* every particle carries a component label (the particle field ``component``);
* the correction is the plain one: adding the log-likelihood to the log weights is
  exactly the mixture's update (the component weight ``π_k`` is multiplied by its
  particles' mean likelihood and the weights within the component by their own), so any
  correction policy (:mod:`hmmtrack.tracking.tempering`) is used as it is;
* at each resampling the components are reclustered (:meth:`Mixture.recluster`: a
  component whose particles form two separated clusters is split in two, components
  whose means meet are merged, components whose weight fell below ``prune_weight`` are
  dropped) and each component is resampled on its own, to a number of particles set by
  its weight with a floor (:func:`allocate`). The component weights are not resampled:
  they stay the exact sums of the weights, so no mode is lost by chance, and a particle
  of component ``k`` weighs ``π_k / N_k`` afterwards.

The estimate is still the weighted mean and covariance of the whole cloud, so two modes
apart inflate ``sqrt_lambda1``: the paper's convergence (√λ₁ < 10 m) is declared only
when one mode holds almost all of the weight (two modes ``d`` apart with weights ``p`` and
``1 − p`` add ``p (1 − p) d²`` to the variance along the line joining them).
:class:`Modes` is the collector that reports the components (weight, mean, √λ₁ of each)
after each resampling.

This module does not score observations nor move particles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.particles import split_in_two, sqrt_largest_eigenvalue
from hmmtrack.tracking.resampling import get_resampler

__all__ = [
    "CONVERGENCE_THRESHOLD",
    "ESTIMATE_MODE_COLUMNS",
    "MODE_COLUMNS",
    "ONE_MODE_WEIGHT",
    "Mixture",
    "Modes",
    "allocate",
    "component_moments",
    "with_modes",
]

#: the paper's convergence threshold on √λ₁ (m)
CONVERGENCE_THRESHOLD = 10.0
#: weight the heaviest mode must hold for a run to be declared converged ("almost all")
ONE_MODE_WEIGHT = 0.95

#: the particle field that holds each particle's component label
COMPONENT = "component"
#: bins of the projection in the split test (:func:`hmmtrack.tracking.particles.split_in_two`)
SPLIT_BINS = 256
#: modes reported per row by :class:`Modes`
REPORTED_MODES = 2
#: columns of the modes table (:class:`Modes`)
MODE_COLUMNS = (
    "time",
    "components",
    *(
        f"mode{k}_{name}"
        for k in range(1, REPORTED_MODES + 1)
        for name in ("weight", "x", "y", "sqrt_lambda1")
    ),
)
#: columns :func:`with_modes` adds to an estimates table
ESTIMATE_MODE_COLUMNS = ("mode1_weight", "mode2_x", "mode2_y", "mode2_weight", "converged")


@dataclass(frozen=True)
class Mixture:
    """Mixture-tracking resampling (see the module docstring).

    Parameters
    ----------
    max_components : int
        Most components at once (a split waits while there are this many).
    min_separation : float
        m: two clusters closer than this are never split; components whose means come
        within half of it are merged.
    split_share : float
        Weight share of a component's lighter cluster needed to split it, in (0, 0.5).
    min_share : float
        Fraction of the particles every live component keeps at least, in [0, 1 / max_components].
    prune_weight : float
        Component weight below which a component is dropped (its particles are given to
        the others), in [0, 1).
    """

    max_components: int = 4
    min_separation: float = 20.0
    split_share: float = 0.02
    min_share: float = 0.25
    prune_weight: float = 1e-4

    def __post_init__(self) -> None:
        if int(self.max_components) != self.max_components or self.max_components < 1:
            raise ValueError(
                f"max_components must be a positive integer, got {self.max_components!r}"
            )
        if not (math.isfinite(self.min_separation) and self.min_separation > 0):
            raise ValueError(f"min_separation must be positive (m), got {self.min_separation!r}")
        if not 0.0 < self.split_share < 0.5:
            raise ValueError(f"split_share must lie in (0, 0.5), got {self.split_share!r}")
        if not 0.0 <= self.min_share * self.max_components <= 1.0:
            raise ValueError(
                f"min_share must lie in [0, 1 / max_components], got {self.min_share!r}"
            )
        if not 0.0 <= self.prune_weight < 1.0:
            raise ValueError(f"prune_weight must lie in [0, 1), got {self.prune_weight!r}")

    def initialised(self, pf) -> None:
        """One component holds every fresh particle."""
        pf.particles.extra[COMPONENT] = np.zeros(pf.particles.n, dtype=np.int64)

    def resample(self, pf, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Recluster, then resample each component on its own with the filter's scheme.

        Parameters
        ----------
        pf : ParticleFilter
            Its particles, generator (``pf.rng``) and scheme name (``pf.resampling``).
        weights : numpy.ndarray, shape (N,)
            Normalised weights of the particles.

        Returns
        -------
        ancestors : numpy.ndarray, shape (N,), int64
            Ancestor of each new particle, grouped by component.
        log_weight : numpy.ndarray, shape (N,)
            Log weight ``log(π_k / N_k)`` of each new particle (the labels travel with the
            ancestors in the particle field ``component``).
        """
        p = pf.particles
        labels = self.recluster(p.x, p.y, weights, p.extra[COMPONENT])
        p.extra[COMPONENT] = labels
        component_weight = np.bincount(labels, weights)
        counts = allocate(component_weight, p.n, self.prune_weight, math.ceil(self.min_share * p.n))
        scheme = get_resampler(pf.resampling)
        ancestors, log_weight = [], []
        live = component_weight[counts > 0].sum()
        for k in np.flatnonzero(counts).tolist():
            members = np.flatnonzero(labels == k)
            chosen = scheme(pf.rng, weights[members] / component_weight[k], int(counts[k]))
            ancestors.append(members[chosen])
            log_weight.append(np.full(counts[k], math.log(component_weight[k] / live / counts[k])))
        # live components numbered 0..K-1 in order (the labels travel with the ancestors)
        p.extra[COMPONENT] = np.cumsum(counts > 0)[labels] - 1
        return np.concatenate(ancestors), np.concatenate(log_weight)

    def recluster(self, x, y, weights, labels) -> np.ndarray:
        """New component labels (N,): merge components whose means meet, split those that
        form two separated clusters.

        Two components merge when their means lie closer than ``max(min_separation / 2,
        2 (sd_j + sd_k))``, the standard deviations taken along the line joining them; a
        component is split along its principal axis when its two 2-means clusters lie more
        than ``max(min_separation, 3 (sd_lo + sd_hi))`` apart and the lighter holds at
        least ``split_share`` of its weight (the test of
        :func:`hmmtrack.tracking.diagnostics.ambiguity`; the gap between 2 and 3 standard
        deviations keeps a pair from being merged and split again at once).

        Parameters
        ----------
        x, y : numpy.ndarray, shape (N,)
            Positions (m).
        weights : numpy.ndarray, shape (N,)
            Normalised weights.
        labels : numpy.ndarray, shape (N,), int64
            Current labels ``0..K-1``.
        """
        n_components = int(labels.max()) + 1
        moments = component_moments(x, y, weights, labels, n_components)
        target = np.arange(n_components)
        for j in range(n_components):
            for k in range(j + 1, n_components):
                if target[k] == k and self._meet(moments[j], moments[k]):
                    target[k] = target[j]
        _, target = np.unique(target, return_inverse=True)
        labels = target[labels]
        n_components = int(target.max()) + 1
        for k in range(n_components):
            if n_components >= self.max_components:
                break
            members = np.flatnonzero(labels == k)
            share = weights[members]
            if members.size < 2 or share.sum() <= self.prune_weight:
                continue
            separation, minor, sd_lo, sd_hi, mx, my, ax, ay, cut = split_in_two(
                x[members],
                y[members],
                share,
                (0.5 * self.min_separation) ** 2 * self.split_share,
                SPLIT_BINS,
            )
            if minor >= self.split_share and separation > max(
                self.min_separation, 3.0 * (sd_lo + sd_hi)
            ):
                upper = (x[members] - mx) * ax + (y[members] - my) * ay >= cut
                labels[members[upper]] = n_components
                n_components += 1
        return labels

    def _meet(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether two components (rows of :func:`component_moments`) have met."""
        if a[0] <= 0.0 or b[0] <= 0.0:
            return True  # a weightless component joins any other
        dx, dy = b[1] - a[1], b[2] - a[2]
        distance = math.hypot(dx, dy)
        if distance < 0.5 * self.min_separation:
            return True
        ux, uy = dx / distance, dy / distance
        sd_a = math.sqrt(max(a[3] * ux * ux + 2 * a[5] * ux * uy + a[4] * uy * uy, 0.0))
        sd_b = math.sqrt(max(b[3] * ux * ux + 2 * b[5] * ux * uy + b[4] * uy * uy, 0.0))
        return distance < 2.0 * (sd_a + sd_b)


def allocate(component_weight, n: int, prune_weight: float, floor: int) -> np.ndarray:
    """Particles per component: ``floor`` each, the rest in proportion to the weights.

    Components lighter than ``prune_weight`` get none (the heaviest always lives); the rest
    ``n − K·floor`` is split by the largest-remainder method.

    Parameters
    ----------
    component_weight : numpy.ndarray, shape (K,)
        Component weights (sum one).
    n : int
        Particles in all.
    prune_weight : float
    floor : int
        Particles each live component gets at least (reduced when ``K·floor > n``).

    Returns
    -------
    numpy.ndarray, shape (K,), int64
        Sums to ``n``.
    """
    component_weight = np.asarray(component_weight, dtype=np.float64)
    live = component_weight >= prune_weight
    live[np.argmax(component_weight)] = True
    floor = min(floor, n // int(live.sum()))
    share = np.where(live, component_weight, 0.0)
    quota = (n - floor * live.sum()) * share / share.sum()
    counts = np.floor(quota).astype(np.int64)
    left = n - floor * int(live.sum()) - int(counts.sum())
    counts[np.argsort(counts - quota, kind="stable")[:left]] += 1
    return np.where(live, counts + floor, 0)


@njit(cache=True)
def component_moments(x, y, weights, labels, n_components):
    """Weight, weighted mean and covariance of each component.

    Parameters
    ----------
    x, y, weights : numpy.ndarray, shape (N,)
        Positions (m) and normalised weights.
    labels : numpy.ndarray, shape (N,), int64
        Component of each particle, ``0..K-1``.
    n_components : int
        ``K``.

    Returns
    -------
    numpy.ndarray, shape (K, 6)
        Per component: weight, mean x, mean y (m), var x, var y, cov xy (m²); zeros for a
        weightless component. Moments are taken about each component's first particle (no
        cancellation far from the origin).
    """
    sums = np.zeros((n_components, 6))
    origin = np.full((n_components, 2), np.nan)
    for i in range(x.size):
        k = labels[i]
        if origin[k, 0] != origin[k, 0]:
            origin[k, 0], origin[k, 1] = x[i], y[i]
        dx, dy, w = x[i] - origin[k, 0], y[i] - origin[k, 1], weights[i]
        sums[k, 0] += w
        sums[k, 1] += w * dx
        sums[k, 2] += w * dy
        sums[k, 3] += w * dx * dx
        sums[k, 4] += w * dy * dy
        sums[k, 5] += w * dx * dy
    out = np.zeros((n_components, 6))
    for k in range(n_components):
        s = sums[k, 0]
        if s <= 0.0:
            continue
        mx, my = sums[k, 1] / s, sums[k, 2] / s
        out[k, 0] = s
        out[k, 1], out[k, 2] = origin[k, 0] + mx, origin[k, 1] + my
        out[k, 3] = max(sums[k, 3] / s - mx * mx, 0.0)
        out[k, 4] = max(sums[k, 4] / s - my * my, 0.0)
        out[k, 5] = sums[k, 5] / s - mx * my
    return out


class Modes:
    """After each resampling: the modes of the cloud, heaviest first (table ``modes``).

    One row per resampling (:data:`MODE_COLUMNS`): the number of modes and, for the
    :data:`REPORTED_MODES` heaviest, weight, mean position (m) and √λ₁ of the mode's own
    covariance (m); NaN where there are fewer modes. The modes are the mixture's
    components (the particle field ``component``, :class:`Mixture`) or, without a
    mixture, the clusters :meth:`Mixture.recluster` finds in the cloud (its default
    thresholds: clusters at least 20 m and 3 standard deviations apart, the lighter with
    at least 2 % of the weight).
    """

    every_step = False

    def start(self, pf) -> None:
        self._rows: list[tuple] = []

    def corrected(self, pf) -> None:
        """Nothing to record (the components are reclustered at resampling)."""

    def settled(self, pf) -> None:
        """Nothing to record."""

    def resampled(self, pf, ancestors) -> None:
        p = pf.particles
        weights = pf.weights()[0]
        labels = p.extra.get(COMPONENT)
        if labels is None:
            labels = _CLUSTERS.recluster(p.x, p.y, weights, np.zeros(p.n, dtype=np.int64))
        moments = component_moments(p.x, p.y, weights, labels, int(labels.max()) + 1)
        order = np.argsort(-moments[:, 0], kind="stable")[:REPORTED_MODES]
        row = [pf.time, len(moments)]
        for k in range(REPORTED_MODES):
            if k < order.size:
                weight, mx, my, var_x, var_y, cov_xy = moments[order[k]].tolist()
                row += [weight, mx, my, sqrt_largest_eigenvalue(var_x, var_y, cov_xy)]
            else:
                row += [math.nan] * 4
        self._rows.append(tuple(row))

    def result(self) -> dict[str, pd.DataFrame]:
        return {"modes": pd.DataFrame(self._rows, columns=list(MODE_COLUMNS))}


#: the clustering of :class:`Modes` without a mixture
_CLUSTERS = Mixture()


def with_modes(estimates: pd.DataFrame, modes: pd.DataFrame) -> pd.DataFrame:
    """The estimates with the modes beside them (:data:`ESTIMATE_MODE_COLUMNS`).

    Each estimate takes the modes of the latest resampling at or before its time:
    ``mode1_weight`` (the heaviest mode's weight), ``mode2_x``, ``mode2_y`` (m) and
    ``mode2_weight`` of the second (NaN, NaN, 0 when there is one mode; NaN before the
    first resampling), and ``converged``: ``sqrt_lambda1`` under
    :data:`CONVERGENCE_THRESHOLD` *and* the heaviest mode holding at least
    :data:`ONE_MODE_WEIGHT` of the weight (a cloud split between two points is not
    converged however narrow each part is).

    Parameters
    ----------
    estimates : pandas.DataFrame
        ``time`` (s, increasing), ``sqrt_lambda1`` (m), ...
    modes : pandas.DataFrame
        :data:`MODE_COLUMNS`, by time.
    """
    table = modes[["time", "mode1_weight", "mode2_x", "mode2_y", "mode2_weight"]]
    table = table.drop_duplicates("time", keep="last").astype(float)
    merged = pd.merge_asof(estimates, table, on="time", direction="backward")
    single = merged["mode1_weight"].notna() & merged["mode2_weight"].isna()
    merged.loc[single, "mode2_weight"] = 0.0
    merged["converged"] = (merged["sqrt_lambda1"] < CONVERGENCE_THRESHOLD) & (
        merged["mode1_weight"] >= ONE_MODE_WEIGHT
    )
    return merged
