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
  of component ``k`` weighs ``π_k / N_k`` afterwards;
* the mirror split: with a :class:`~hmmtrack.tracking.mirror.MirrorLine` (``mirror``), a
  component that straddles the line through the two receivers heard last, with at least
  ``split_share`` of its weight on each side, is split along that line after the
  reclustering (:func:`split_across`). Those two receivers' ranges and range-rates are the
  same from a track and from its reflection across the line, so only the motion model
  tells the sides apart; while the two intersections of the rings overlap they form one
  cluster, which the 2-means split cannot cut and whose resampling would let drift choose
  the side (reports/decisions.md, "The mirror split").

The estimate is still the weighted mean and covariance of the whole cloud, so two modes
apart inflate ``sqrt_lambda1``: the paper's convergence (√λ₁ < 10 m) is declared only
when one mode holds almost all of the weight (two modes ``d`` apart with weights ``p`` and
``1 − p`` add ``p (1 − p) d²`` to the variance along the line joining them).
:class:`Modes` is the collector that reports the modes (weight, mean, √λ₁ of each) after
each resampling: the components; with the mirror split, those whose means lie within
:data:`ONE_MODE_DISTANCE` of a heavier one's joined to it (:func:`join_modes`: the two
halves of a cloud cut by the split are one place).

The mirror split is opt-in (``FilterSettings.mirror_split``, in no named filter): on fresh
synthetic shark pursuits it kept the HMM's runs on the tag's side where resampling had let
the mirror win, but the velocity model's losses, where its motion prior favours the
mirror's track, did not fall (reports/decisions.md, "The mirror split").

This module does not score observations nor move particles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.compiled.chunks import chunking, in_chunks, next_chunk
from hmmtrack.tracking.compiled.weighing import add_weighted
from hmmtrack.tracking.mirror import MirrorLine
from hmmtrack.tracking.particles import split_in_two, sqrt_largest_eigenvalue
from hmmtrack.tracking.resampling import (
    Scratch,
    Segments,
    invert,
    merge_segments,
    prepare_points,
)

__all__ = [
    "CONVERGENCE_THRESHOLD",
    "Components",
    "Drawn",
    "ESTIMATE_MODE_COLUMNS",
    "MODE_COLUMNS",
    "ONE_MODE_DISTANCE",
    "ONE_MODE_WEIGHT",
    "Mixture",
    "Modes",
    "SCHEME_CODES",
    "allocate",
    "component_moments",
    "join_modes",
    "resample_components",
    "scheme_draws",
    "split_across",
    "with_modes",
]

#: the paper's convergence threshold on √λ₁ (m)
CONVERGENCE_THRESHOLD = 10.0
#: weight the heaviest mode must hold for a run to be declared converged ("almost all")
ONE_MODE_WEIGHT = 0.95
#: m: components whose means lie closer than this are one mode (:func:`join_modes`): twice
#: the convergence threshold, so two such parts of any weights add at most (10 m)² to the
#: variance along the line joining them
ONE_MODE_DISTANCE = 2 * CONVERGENCE_THRESHOLD

#: the particle field that holds each particle's component label
COMPONENT = "component"
#: bins of the projection in the split test (:func:`hmmtrack.tracking.particles.split_in_two`)
SPLIT_BINS = 256
#: most particles of a component the split test looks at (an evenly strided sample): its
#: clusters, each with at least ``split_share`` (2 %) of the weight, hold 40 of them or more,
#: and the test's cost stops growing with N
SPLIT_SAMPLE = 2000
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
    mirror : MirrorLine or None
        The run's mirror line (:class:`hmmtrack.tracking.mirror.MirrorLine`): components
        that straddle it are split along it at each resampling (:func:`split_across`);
        ``None``: no mirror split.
    """

    max_components: int = 4
    min_separation: float = 20.0
    split_share: float = 0.02
    min_share: float = 0.25
    prune_weight: float = 1e-4
    mirror: MirrorLine | None = field(default=None, compare=False, repr=False)

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

    def labels(self, particles) -> np.ndarray:
        """Each particle's component, ``0..K-1``, shape (N,), int64 (the particle field
        ``component``; e.g. for a move within components,
        :func:`hmmtrack.tracking.tempering.regularisation_move_within`)."""
        return particles.extra[COMPONENT]

    def draw(self, pf, weights: np.ndarray) -> Drawn:
        """Recluster, then draw each component's new particles with the filter's scheme,
        to be gathered by ``Particles.take(drawn.ancestors, ..., locate=drawn.locate)`` and
        finished by :meth:`finish`.

        One compiled call before the scheme's draws: the components' moments, the
        reclustering and the allocation (:func:`_recluster_and_allocate`; the moments on
        the correction's threads first when it has more than one); one after them: every
        component's cumulative weights and points in the filter's work arrays
        (:func:`_prepare_components`). The merge of the points with the cumulative weights
        runs chunk by chunk in the pass that gathers the new particles
        (:class:`hmmtrack.tracking.resampling.Segments`), on the correction's threads;
        residual's ancestors are found here. The particles' component labels are taken out
        of ``pf.particles.extra`` (:meth:`finish` gives the new particles theirs without a
        gather).

        Parameters
        ----------
        pf : ParticleFilter
            Its particles, generator (``pf.rng``) and scheme name (``pf.resampling``).
        weights : numpy.ndarray, shape (N,)
            Normalised weights of the particles.
        """
        p = pf.particles
        labels = p.extra.pop(COMPONENT)
        threads = pf.correction_threads()
        moments = (
            _NO_MOMENTS
            if threads == 1
            else component_moments(p.x, p.y, weights, labels, int(labels.max()) + 1, threads)
        )
        floor = math.ceil(self.min_share * p.n)
        labels, component_weight, counts, live = _recluster_and_allocate(
            p.x,
            p.y,
            weights,
            labels,
            moments,
            int(self.max_components),
            float(self.min_separation),
            float(self.split_share),
            float(self.prune_weight),
            floor,
        )
        line = None if self.mirror is None else self.mirror.at(pf.time)
        if line is not None:
            labels, component_weight, counts, live = _split_and_allocate(
                p.x,
                p.y,
                weights,
                labels,
                component_weight,
                counts,
                np.array(line),
                int(self.max_components),
                float(self.split_share),
                float(self.prune_weight),
                floor,
            )
        code = SCHEME_CODES[pf.resampling]
        scratch = pf.scratch  # the filter's work arrays, unused by its own scheme here
        draws = scheme_draws(pf.rng, code, p.n, live, scratch)
        ancestors, segments = _segments(
            weights, labels, counts, component_weight, code, draws, scratch
        )
        locate = None if code == SCHEME_CODES["residual"] else segments
        return Drawn(ancestors, locate, counts, component_weight)

    def finish(self, drawn: Drawn, particles, scratch: Scratch | None = None) -> tuple:
        """The weights of the particles gathered from :meth:`draw`'s ancestors, and their
        component labels (the particle field ``component``, live components numbered
        ``0..K-1`` in order).

        Parameters
        ----------
        drawn : Drawn
            :meth:`draw`'s result, its ancestors gathered.
        particles : Particles
            The new particles (``particles.extra`` receives the labels).
        scratch : Scratch, optional
            The filter's work arrays: the log weights, weights and labels are written into
            two sets of its arrays in turn (:meth:`Scratch.alternate`: each stays valid
            until the resampling after the next); by default new arrays.

        Returns
        -------
        log_weight : numpy.ndarray, shape (N,)
            Log weight ``log(π_k / N_k)`` of each new particle.
        weights : numpy.ndarray, shape (N,)
            Their normalised weights.
        n_eff : float
            Their effective sample size ``1 / Σ w²``.
        mean : (float, float)
            Their weighted mean position (m).
        moments : numpy.ndarray, shape (K, 6)
            The new particles' :func:`component_moments` (the same numbers), ``K`` the live
            components (what :class:`Modes` reports).
        """
        n = particles.n
        if scratch is None:
            into = np.empty(n), np.empty(n), np.empty(n, dtype=np.int64)
        else:
            into = (
                scratch.alternate("mixture log weight", n),
                scratch.alternate("mixture weights", n),
                scratch.alternate("mixture labels", n, _INT64),
            )
        summary, moments = _finish_components(
            drawn.counts, drawn.component_weight, particles.x, particles.y, *into
        )
        log_weight, weights, labels = into
        particles.extra[COMPONENT] = labels
        n_eff, mean_x, mean_y = summary.tolist()
        return log_weight, weights, n_eff, (mean_x, mean_y), moments

    def recluster(self, x, y, weights, labels) -> np.ndarray:
        """New component labels (N,): merge components whose means meet, split those that
        form two separated clusters.

        Two components merge when their means lie closer than ``max(min_separation / 2,
        2 (sd_j + sd_k))``, the standard deviations taken along the line joining them; a
        component is split along its principal axis when its two 2-means clusters lie more
        than ``max(min_separation, 3 (sd_lo + sd_hi))`` apart and the lighter holds at
        least ``split_share`` of its weight (the test of
        :func:`hmmtrack.tracking.diagnostics.ambiguity`; the gap between 2 and 3 standard
        deviations keeps a pair from being merged and split again at once). The split test
        looks at an evenly strided sample of at most :data:`SPLIT_SAMPLE` of a component's
        particles and is skipped for a component too narrow to hold two such clusters.

        Parameters
        ----------
        x, y : numpy.ndarray, shape (N,)
            Positions (m).
        weights : numpy.ndarray, shape (N,)
            Normalised weights.
        labels : numpy.ndarray, shape (N,), int64
            Current labels ``0..K-1`` (not changed; never the array returned).
        """
        new = _recluster(
            x,
            y,
            weights,
            labels,
            _component_moments(x, y, weights, labels, int(labels.max()) + 1),
            int(self.max_components),
            float(self.min_separation),
            float(self.split_share),
            float(self.prune_weight),
        )[0]
        return new.copy() if np.may_share_memory(new, labels) else new  # labels stay unchanged


#: codes of the resampling schemes in :func:`resample_components`
SCHEME_CODES = {"multinomial": 0, "residual": 1, "stratified": 2, "systematic": 3}
#: the labels' dtype (for :meth:`~hmmtrack.tracking.resampling.Scratch.alternate`)
_INT64 = np.dtype(np.int64)
#: "no moments given": :func:`_recluster_and_allocate` sums them itself
_NO_MOMENTS = np.zeros((0, 6))
#: "every particle": :func:`_recluster`'s members of the only component (no list built)
_EVERYONE = np.zeros(0, dtype=np.int64)


def scheme_draws(
    rng: np.random.Generator, code: int, n: int, live: int, scratch: Scratch | None = None
) -> np.ndarray:
    """The random numbers :func:`resample_components` consumes for ``n`` particles in
    ``live`` components: standard exponentials (multinomial and residual: the spacings of
    each component's sorted uniforms, ``N_k + 1`` each), one uniform per particle
    (stratified) or per component (systematic). The same stream as the whole-cloud scheme
    run on each component in turn (:mod:`hmmtrack.tracking.resampling`; residual aside).
    With ``scratch`` (the filter's), the exponentials go into its work array
    (:meth:`~hmmtrack.tracking.resampling.Scratch.exponentials`)."""
    if code <= SCHEME_CODES["residual"]:
        if scratch is None:
            return rng.standard_exponential(n + live)
        return scratch.exponentials(rng, n + live)
    return rng.random(n if code == SCHEME_CODES["stratified"] else live)


@njit(cache=True)
def _recluster_and_allocate(
    x, y, weights, labels, moments, max_components, min_separation, split_share, prune_weight,
    floor,
):  # fmt: skip
    """The compiled part of :meth:`Mixture.draw` before the draws, from the components'
    moments (:func:`component_moments`; summed here, on this thread, when ``moments`` has
    no rows): the new labels (N,), the component weights (K,), the particles each gets
    (K,), :func:`allocate`, and the number of components that get any."""
    if moments.shape[0] == 0:
        moments = _component_moments(x, y, weights, labels, labels.max() + 1)
    labels, component_weight = _recluster(
        x, y, weights, labels, moments, max_components, min_separation, split_share, prune_weight
    )
    counts = allocate(component_weight, labels.size, prune_weight, floor)
    return labels, component_weight, counts, np.count_nonzero(counts)


class Drawn(NamedTuple):
    """What :meth:`Mixture.draw` returns.

    Attributes
    ----------
    ancestors : numpy.ndarray, shape (N,), int64
        The new particles' ancestors, grouped by component in component order: filled by
        the gather's ``locate`` when it is given, else already.
    locate : Segments or None
        Every live component's inversion, merged chunk by chunk in the pass that gathers
        the new particles (``Particles.take``'s ``locate``); ``None`` (residual) when the
        ancestors are given.
    counts : numpy.ndarray, shape (K,), int64
        New particles per component (:func:`allocate`).
    component_weight : numpy.ndarray, shape (K,)
        Sum of the old weights of each component.
    """

    ancestors: np.ndarray
    locate: Segments | None
    counts: np.ndarray
    component_weight: np.ndarray


class Components(NamedTuple):
    """What :func:`resample_components` returns.

    Attributes
    ----------
    ancestors : numpy.ndarray, shape (M,), int64
        Grouped by component, in component order (``M = sum(counts)``).
    log_weight : numpy.ndarray, shape (M,)
        ``log(π_k / N_k)`` with ``π_k`` the component's share of the live components'
        weight.
    weights : numpy.ndarray, shape (M,)
        ``exp(log_weight)``.
    summary : numpy.ndarray, shape (3,)
        The new particles' ESS ``1 / Σ w²`` and weighted mean x, y (m): what the filter
        keeps beside the weights (:meth:`hmmtrack.tracking.filter.ParticleFilter.weights`),
        summed here, one component at a time, rather than by NumPy's dot products (which
        hand arrays over 10,000 to OpenBLAS threads: a millisecond or more per call on a
        busy machine).
    labels : numpy.ndarray, shape (M,), int64
        The new particles' components, numbered ``0..K'-1`` over the live components (those
        with ``counts > 0``) in order.
    moments : numpy.ndarray, shape (K', 6)
        :func:`component_moments` of the new particles (positions of the ancestors, the
        new weights and labels): the same sums in the same order, taken in the pass that
        forms the ESS and mean instead of a pass of their own.
    """

    ancestors: np.ndarray
    log_weight: np.ndarray
    weights: np.ndarray
    summary: np.ndarray
    labels: np.ndarray
    moments: np.ndarray


def resample_components(
    weights, labels, counts, component_weight, code, draws, x, y, scratch: Scratch | None = None
) -> Components:  # fmt: skip
    """Resample each component on its own (compiled; the scheme by its code).

    Component ``k`` gets ``counts[k]`` ancestors among its particles, drawn by the scheme of
    :data:`SCHEME_CODES` from its weights normalised by ``component_weight[k]``, by the
    inversion of :mod:`hmmtrack.tracking.resampling` (multinomial, stratified, systematic:
    every component's cumulative weights and points formed in one pass, then merged in the
    chunks of all components' points on ``scratch.threads`` threads; the ancestors do not
    depend on the threads); residual keeps ``floor(N_k w)`` copies and draws the rest
    multinomially. (The particle filter runs the same steps with the merge inside its
    gather: :meth:`Mixture.draw`.)

    Parameters
    ----------
    weights : numpy.ndarray, shape (N,)
        Normalised weights.
    labels : numpy.ndarray, shape (N,), int64
        Component of each particle, ``0..K-1``.
    counts : numpy.ndarray, shape (K,), int64
        New particles per component (:func:`allocate`); components with none are dropped.
    component_weight : numpy.ndarray, shape (K,)
        Sum of the weights of each component.
    code : int
        :data:`SCHEME_CODES`.
    draws : numpy.ndarray
        The scheme's random numbers for the live components in order (:func:`scheme_draws`).
    x, y : numpy.ndarray, shape (N,)
        Positions (m), for the new particles' weighted mean and moments.
    scratch : Scratch, optional
        Work arrays reused from one call to the next and the threads of the merge (the
        filter's, :class:`hmmtrack.tracking.resampling.Scratch`); by default fresh arrays
        and one thread.
    """
    scratch = Scratch() if scratch is None else scratch
    ancestors, segments = _segments(weights, labels, counts, component_weight, code, draws, scratch)
    if code != SCHEME_CODES["residual"]:
        merge_segments(*segments, scratch.threads, ancestors)
    log_weight, weights, labels = (
        np.empty(ancestors.size),
        np.empty(ancestors.size),
        np.empty(ancestors.size, dtype=np.int64),
    )
    summary, moments = _finish_components(
        counts, component_weight, x[ancestors], y[ancestors], log_weight, weights, labels
    )
    return Components(ancestors, log_weight, weights, summary, labels, moments)


def _segments(weights, labels, counts, component_weight, code, draws, scratch: Scratch):
    """The ancestors' array (filled for residual) and the components' :class:`Segments`
    in ``scratch``'s work arrays (:func:`_prepare_components`)."""
    cumulative = scratch.array("cumulative", labels.size)
    points = scratch.array("points", int(counts.sum()))
    gathered = scratch.array("gathered", labels.size)
    ancestors = np.empty(points.size, dtype=np.int64)
    prepared = _prepare_components(
        weights, labels, counts, component_weight, code, draws, cumulative, points, gathered,
        ancestors,
    )  # fmt: skip
    return ancestors, Segments(cumulative, points, *prepared)


@njit(cache=True)
def _prepare_components(
    weights, labels, counts, component_weight, code, draws, cumulative, points, gathered,
    ancestors,
):  # fmt: skip
    """The serial part of :func:`resample_components` before the merge.

    Component ``k``'s particles are ``start[k]:start[k + 1]`` in label order (themselves
    when the labels are grouped, as a resampling leaves them, else ``members`` of that
    slice; ``members`` is empty when grouped) and its new particles ``at[k]:at[k + 1]``;
    fills ``cumulative[start[k]:start[k + 1]]`` and ``points[at[k]:at[k + 1]]`` by
    :func:`hmmtrack.tracking.resampling.prepare_points` (``last[k]`` its last index of
    positive weight), taking ``gathered`` for the weights of ungrouped labels; residual
    writes its ancestors (particle indices) at once. Returns ``start, at, last, members``
    (:class:`~hmmtrack.tracking.resampling.Segments`' last four)."""
    n_components = counts.size
    start = np.zeros(n_components + 1, dtype=np.int64)
    # labels in component order (as a resampling leaves them): each component's particles
    # are a slice, so no index list is built and no weights are gathered
    grouped = _ascending(labels, 0, labels.size)
    if grouped:  # a run of each label: its length
        i = 0
        while i < labels.size:
            end = _run_end(labels, i, labels.size)
            start[labels[i] + 1] = end - i
            i = end
    else:
        for i in range(labels.size):
            start[labels[i] + 1] += 1
    for k in range(n_components):
        start[k + 1] += start[k]
    members = np.empty(0 if grouped else labels.size, dtype=np.int64)
    if not grouped:
        fill = start[:-1].copy()
        for i in range(labels.size):
            members[fill[labels[i]]] = i
            gathered[fill[labels[i]]] = weights[i]
            fill[labels[i]] += 1
    at = np.zeros(n_components + 1, dtype=np.int64)
    last = np.zeros(n_components, dtype=np.int64)
    d = 0
    for k in range(n_components):
        c = counts[k]
        at[k + 1] = at[k] + c
        if c == 0:
            continue
        lo, hi, a = start[k], start[k + 1], at[k]
        w = weights[lo:hi] if grouped else gathered[lo:hi]
        scale = 1.0 / component_weight[k]
        cum, own_points = cumulative[lo:hi], points[a : a + c]
        if code == 0:  # multinomial
            spacings = draws[d : d + c + 1]
            last[k] = prepare_points(
                w, scale, spacings, c, 1.0 / spacings.sum(), True, cum, own_points
            )
            d += c + 1
        elif code == 1:  # residual
            expected = c * scale * w
            copies = np.floor(expected).astype(np.int64)
            kept = 0
            for i in range(hi - lo):
                for _ in range(copies[i]):
                    if kept < c:
                        ancestors[a + kept] = lo + i if grouped else members[lo + i]
                        kept += 1
            left = c - kept
            if left > 0:
                rest = expected - copies
                spacings = draws[d : d + left + 1]
                drawn = invert(rest, 1.0 / rest.sum(), spacings, left, 1.0 / spacings.sum(), True)
                for j in range(left):
                    i = drawn[j]
                    ancestors[a + kept + j] = lo + i if grouped else members[lo + i]
            d += c + 1
        else:  # stratified (a uniform per point) or systematic (one for the component)
            for j in range(c):
                own_points[j] = (j + draws[d + j if code == 2 else d]) / c
            last[k] = prepare_points(w, scale, own_points, c, 1.0, False, cum, own_points)
            d += c if code == 2 else 1
    return start, at, last, members


@njit(cache=True)
def _finish_components(counts, component_weight, x, y, log_weight, new_weights, labels):
    """The serial part of :func:`resample_components` after the merge, from the new
    particles' positions ``x, y`` (M,) (grouped by component): their log weights, weights
    and labels into the arrays (M,) given, and their summary and component moments, one
    component at a time (the moments' sums in the chunks of
    :func:`hmmtrack.tracking.compiled.chunks.chunking` over the new particles, about each
    component's first new particle, as :func:`component_moments` sums them)."""
    total = x.size
    sum_squares = mean_x = mean_y = 0.0
    live = 0.0
    n_live = 0
    for k in range(counts.size):
        if counts[k] > 0:
            live += component_weight[k]
            n_live += 1
    origin = np.empty((n_live, 2))
    n_chunks, size = chunking(total)
    sums = np.zeros((n_chunks, n_live, 6))
    r = 0  # the live rank of component k
    a = 0  # its first new particle
    for k in range(counts.size):
        c = counts[k]
        if c == 0:
            continue
        log_w = math.log(component_weight[k] / live / c)
        w_k = math.exp(log_w)
        log_weight[a : a + c] = log_w
        new_weights[a : a + c] = w_k
        labels[a : a + c] = r
        ox, oy = x[a], y[a]
        origin[r, 0], origin[r, 1] = ox, oy
        sx = sy = 0.0
        j = a
        while j < a + c:  # the component's particles in each chunk
            chunk = j // size
            end = min(a + c, (chunk + 1) * size)
            sx, sy = _add_run(sums[chunk], r, new_weights, x, y, j, end, ox, oy, sx, sy)
            j = end
        sum_squares += c * w_k * w_k
        mean_x += w_k * sx
        mean_y += w_k * sy
        r += 1
        a += c
    summary = np.array([1.0 / sum_squares, mean_x, mean_y])
    return summary, _moments_of_sums(sums, origin)


@njit(cache=True)
def _meet(a, b, min_separation):
    """Whether two components (rows of :func:`component_moments`) have met."""
    if a[0] <= 0.0 or b[0] <= 0.0:
        return True  # a weightless component joins any other
    dx, dy = b[1] - a[1], b[2] - a[2]
    distance = math.hypot(dx, dy)
    if distance < 0.5 * min_separation:
        return True
    ux, uy = dx / distance, dy / distance
    sd_a = math.sqrt(max(a[3] * ux * ux + 2 * a[5] * ux * uy + a[4] * uy * uy, 0.0))
    sd_b = math.sqrt(max(b[3] * ux * ux + 2 * b[5] * ux * uy + b[4] * uy * uy, 0.0))
    return distance < 2.0 * (sd_a + sd_b)


@njit(cache=True)
def _recluster(
    x, y, weights, labels, moments, max_components, min_separation, split_share, prune_weight
):  # fmt: skip
    """:meth:`Mixture.recluster`, compiled (its settings as arguments), from the current
    components' moments (:func:`component_moments`); also the new components' weights
    (K,). The new labels are ``labels`` itself when no merge or split changed them."""
    n_components = labels.max() + 1
    target = np.arange(n_components)
    for j in range(n_components):
        for k in range(j + 1, n_components):
            if target[k] == k and _meet(moments[j], moments[k], min_separation):
                target[k] = target[j]
    present = np.zeros(n_components, dtype=np.int64)
    for k in range(n_components):
        present[target[k]] = 1
    rank = np.cumsum(present) - 1
    merged = rank[-1] + 1
    # the labels themselves until a merge or a split changes them
    new = labels
    copied = merged < n_components
    if copied:
        new = np.empty(labels.size, dtype=np.int64)
        for i in range(labels.size):
            new[i] = rank[target[labels[i]]]
        moments = _component_moments(x, y, weights, new, merged)
    n_components = merged
    min_variance = (0.5 * min_separation) ** 2 * split_share
    for k in range(merged):
        if n_components >= max_components:
            break
        # too light, or too narrow to hold two clusters: no pass over its particles
        var_x, var_y, cov_xy = moments[k, 3], moments[k, 4], moments[k, 5]
        half = 0.5 * (var_x - var_y)
        largest = 0.5 * (var_x + var_y) + math.sqrt(half * half + cov_xy * cov_xy)
        if moments[k, 0] <= prune_weight or largest < min_variance:
            continue
        # one component: every particle is a member (no list of them is built)
        everyone = merged == 1
        members = _EVERYONE if everyone else np.flatnonzero(new == k)
        size = new.size if everyone else members.size
        if size < 2:
            continue
        # the test on an evenly strided sample of at most SPLIT_SAMPLE particles
        stride = -(-size // SPLIT_SAMPLE)
        sample = np.arange(0, size, stride) if everyone else members[::stride]
        separation, minor, sd_lo, sd_hi, mx, my, ax, ay, cut = split_in_two(
            x[sample], y[sample], weights[sample], min_variance, SPLIT_BINS
        )
        if minor >= split_share and separation > max(min_separation, 3.0 * (sd_lo + sd_hi)):
            if not copied:
                new, copied = labels.copy(), True
            for j in range(size):
                i = j if everyone else members[j]
                if (x[i] - mx) * ax + (y[i] - my) * ay >= cut:
                    new[i] = n_components
            n_components += 1
    if n_components == merged:  # no split: the moments' weights, summed in the same order
        return new, moments[:, 0].copy()
    component_weight = np.zeros(n_components)
    for i in range(new.size):
        component_weight[new[i]] += weights[i]
    return new, component_weight


@njit(cache=True)
def allocate(component_weight, n, prune_weight, floor):
    """Particles per component: ``floor`` each, the rest in proportion to the weights.

    Components lighter than ``prune_weight`` get none (the heaviest always lives); the rest
    ``n − K·floor`` is split by the largest-remainder method (compiled).

    Parameters
    ----------
    component_weight : numpy.ndarray, shape (K,), float
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
    live = component_weight >= prune_weight
    live[np.argmax(component_weight)] = True
    n_live = live.sum()
    floor = min(floor, n // n_live)
    share = np.where(live, component_weight, 0.0)
    quota = (n - floor * n_live) * share / share.sum()
    counts = np.floor(quota).astype(np.int64)
    left = n - floor * n_live - counts.sum()
    for k in np.argsort(counts - quota, kind="mergesort")[:left]:
        counts[k] += 1
    return np.where(live, counts + floor, 0)


@njit(cache=True)
def split_across(
    x, y, weights, labels, component_weight, line, max_components, split_share, prune_weight
):
    """The mirror split: each component that straddles ``line`` split along it.

    Components are taken in order; one whose weight is at least ``prune_weight`` and whose
    particles left of the line (``(b − a) × (p − a) > 0``) hold a share of its weight in
    ``[split_share, 1 − split_share]`` gives those particles to a new component, numbered
    after the others, while there are fewer than ``max_components``. Each side's weight is
    the sum of its particles' weights.

    Parameters
    ----------
    x, y, weights, labels
        Positions (m), normalised weights and components ``0..K-1`` (N,), as
        :meth:`Mixture.recluster` takes them (``labels`` not changed).
    component_weight : numpy.ndarray, shape (K,)
        The components' weights.
    line : numpy.ndarray, shape (4,)
        ``ax, ay, bx, by`` (m): two points of the line (:meth:`MirrorLine.at`).
    max_components : int
    split_share, prune_weight : float
        As :class:`Mixture`'s.

    Returns
    -------
    labels : numpy.ndarray, shape (N,), int64
        ``labels`` itself when nothing is split, else a new array.
    component_weight : numpy.ndarray, shape (K',)
        ``component_weight`` itself when nothing is split, else the new weights.
    """
    ax, ay, ux, uy = line[0], line[1], line[2] - line[0], line[3] - line[1]
    n_components = component_weight.size
    left = np.zeros(n_components)
    total = np.zeros(n_components)
    for i in range(x.size):
        total[labels[i]] += weights[i]
        if ux * (y[i] - ay) - uy * (x[i] - ax) > 0.0:
            left[labels[i]] += weights[i]
    twin = np.full(n_components, -1, dtype=np.int64)
    k = n_components
    for c in range(n_components):
        if k >= max_components or component_weight[c] < prune_weight or total[c] <= 0.0:
            continue
        share = left[c] / total[c]
        if split_share <= share <= 1.0 - split_share:
            twin[c] = k
            k += 1
    if k == n_components:
        return labels, component_weight
    new_labels = labels.copy()
    for i in range(x.size):
        c = labels[i]
        if twin[c] >= 0 and ux * (y[i] - ay) - uy * (x[i] - ax) > 0.0:
            new_labels[i] = twin[c]
    new_weight = np.empty(k)
    new_weight[:n_components] = component_weight
    for c in range(n_components):
        if twin[c] >= 0:
            new_weight[c] = total[c] - left[c]
            new_weight[twin[c]] = left[c]
    return new_labels, new_weight


@njit(cache=True)
def _split_and_allocate(
    x, y, weights, labels, component_weight, counts, line, max_components, split_share,
    prune_weight, floor,
):  # fmt: skip
    """:func:`split_across`, then the particles each component gets (:func:`allocate`) and
    the number that get any, when it split one (else ``counts`` as they were)."""
    new_labels, new_weight = split_across(
        x, y, weights, labels, component_weight, line, max_components, split_share, prune_weight
    )
    if new_weight.size > component_weight.size:
        counts = allocate(new_weight, labels.size, prune_weight, floor)
    return new_labels, new_weight, counts, np.count_nonzero(counts)


def join_modes(moments: np.ndarray, distance: float = ONE_MODE_DISTANCE) -> np.ndarray:
    """The modes of a cloud's components: each component joined to the heaviest one before
    it (by weight) whose mean lies within ``distance`` of its own, the joined moments those
    of the union (weight, weighted mean, covariance about that mean).

    Parameters
    ----------
    moments : numpy.ndarray, shape (K, 6)
        :func:`component_moments` (weight, mean x, y, var x, var y, cov xy).
    distance : float
        m.

    Returns
    -------
    numpy.ndarray, shape (K', 6)
        The modes, heaviest component's first; ``moments`` itself when no two join.
    """
    order = np.argsort(-moments[:, 0], kind="mergesort")
    heads: list[int] = []  # for each mode, its heaviest component
    members: list[list[int]] = []
    for k in order:
        for m, head in enumerate(heads):
            if math.hypot(*(moments[k, 1:3] - moments[head, 1:3])) < distance:
                members[m].append(int(k))
                break
        else:
            heads.append(int(k))
            members.append([int(k)])
    if len(heads) == len(moments):
        return moments
    modes = np.zeros((len(heads), 6))
    for m, group in enumerate(members):
        part = moments[group]
        weight = part[:, 0].sum()
        if weight <= 0.0:
            modes[m] = part[0]
            continue
        share = part[:, 0] / weight
        mean = share @ part[:, 1:3]
        dx, dy = part[:, 1] - mean[0], part[:, 2] - mean[1]
        modes[m] = (
            weight,
            mean[0],
            mean[1],
            share @ (part[:, 3] + dx * dx),
            share @ (part[:, 4] + dy * dy),
            share @ (part[:, 5] + dx * dy),
        )
    return modes


@njit(cache=True, nogil=True)
def _first_members(x, y, labels, n_components):
    """Position of each component's first particle (K, 2) (NaN for an empty component): the
    origin of its moments (no cancellation far from the origin of the frame)."""
    origin = np.full((n_components, 2), np.nan)
    found = 0
    for i in range(labels.size):
        k = labels[i]
        if origin[k, 0] != origin[k, 0]:
            origin[k, 0], origin[k, 1] = x[i], y[i]
            found += 1
            if found == n_components:
                break
    return origin


@njit(cache=True, nogil=True)
def _moment_chunks(x, y, weights, labels, origin, counter, sums):
    """Per chunk of particles (:func:`hmmtrack.tracking.compiled.chunks.next_chunk`), each
    component's sums of ``w``, ``w dx``, ``w dy``, ``w dx²``, ``w dy²``, ``w dx dy`` about its
    origin into ``sums[chunk]`` (chunks not yet claimed only): a run of equal labels at a
    time (:func:`_add_run`) when the chunk's labels are grouped, else a particle at a time
    (the same additions in the same order either way)."""
    chunk, lo, hi = next_chunk(counter, x.size)
    while chunk >= 0:
        own = sums[chunk]
        if _ascending(labels, lo, hi):
            i = lo
            while i < hi:
                k = labels[i]
                end = _run_end(labels, i, hi)
                _add_run(own, k, weights, x, y, i, end, origin[k, 0], origin[k, 1], 0.0, 0.0)
                i = end
        else:  # runs may be short: a particle at a time, straight into its component's sums
            for i in range(lo, hi):
                k = labels[i]
                s = own[k]
                s[0], s[1], s[2], s[3], s[4], s[5] = add_weighted(
                    s[0], s[1], s[2], s[3], s[4], s[5],
                    weights[i], x[i] - origin[k, 0], y[i] - origin[k, 1],
                )  # fmt: skip
        chunk, lo, hi = next_chunk(counter, x.size)


@njit(cache=True, nogil=True, inline="always")
def _ascending(labels, lo, hi):
    """Whether ``labels[lo:hi]`` never decreases (grouped by component, in order)."""
    ascending = True
    for i in range(lo + 1, hi):
        ascending &= labels[i - 1] <= labels[i]
    return ascending


@njit(cache=True, nogil=True, inline="always")
def _run_end(labels, i, hi):
    """The end of the run of labels equal to ``labels[i]`` that starts at ``i`` (at most
    ``hi``)."""
    end = i + 1
    while end < hi and labels[end] == labels[i]:
        end += 1
    return end


@njit(cache=True, nogil=True, inline="always")
def _add_run(own, k, weights, x, y, lo, hi, ox, oy, sx, sy):
    """Add the particles ``lo:hi``, all of component ``k``, to the component's sums
    ``own[k]``: ``w``, ``w dx``, ``w dy``, ``w dx²``, ``w dy²``, ``w dx dy`` with ``(dx, dy)``
    their offsets from ``(ox, oy)``; return ``sx, sy`` plus their ``x`` and ``y``. Each sum
    is one chain of additions in particle order (the same numbers as adding each particle
    to ``own[k]`` in turn), carried in registers through the run."""
    s0, s1, s2 = own[k, 0], own[k, 1], own[k, 2]
    s3, s4, s5 = own[k, 3], own[k, 4], own[k, 5]
    for i in range(lo, hi):
        xi, yi = x[i], y[i]
        sx += xi
        sy += yi
        s0, s1, s2, s3, s4, s5 = add_weighted(s0, s1, s2, s3, s4, s5, weights[i], xi - ox, yi - oy)
    own[k, 0], own[k, 1], own[k, 2] = s0, s1, s2
    own[k, 3], own[k, 4], own[k, 5] = s3, s4, s5
    return sx, sy


@njit(cache=True, nogil=True, parallel=True)
def _moment_chunks_parallel(threads, x, y, weights, labels, origin, counter, sums):
    """:func:`_moment_chunks` on ``threads`` threads."""
    for _ in numba.prange(threads):
        _moment_chunks(x, y, weights, labels, origin, counter, sums)


@njit(cache=True, nogil=True)
def _moments_of_sums(sums, origin):
    """The chunks' sums combined in chunk order, as :func:`component_moments` returns them."""
    n_components = origin.shape[0]
    total = sums[0].copy()
    for chunk in range(1, sums.shape[0]):
        total += sums[chunk]
    out = np.zeros((n_components, 6))
    for k in range(n_components):
        s = total[k, 0]
        if s <= 0.0:
            continue
        mx, my = total[k, 1] / s, total[k, 2] / s
        out[k, 0] = s
        out[k, 1], out[k, 2] = origin[k, 0] + mx, origin[k, 1] + my
        out[k, 3] = max(total[k, 3] / s - mx * mx, 0.0)
        out[k, 4] = max(total[k, 4] / s - my * my, 0.0)
        out[k, 5] = total[k, 5] / s - mx * my
    return out


@njit(cache=True, nogil=True)
def _component_moments(x, y, weights, labels, n_components):
    """:func:`component_moments` on the calling thread (for compiled callers)."""
    origin = _first_members(x, y, labels, n_components)
    sums = np.zeros((chunking(x.size)[0], n_components, 6))
    _moment_chunks(x, y, weights, labels, origin, np.zeros(1, dtype=np.int64), sums)
    return _moments_of_sums(sums, origin)


def component_moments(x, y, weights, labels, n_components: int, threads: int = 1) -> np.ndarray:
    """Weight, weighted mean and covariance of each component.

    The sums run in the chunks of :mod:`hmmtrack.tracking.compiled.chunks` (on ``threads``
    threads) and are combined in chunk order, so the result does not depend on the number
    of threads; up to 1,024 particles (one chunk) they are one running sum in particle
    order.

    Parameters
    ----------
    x, y, weights : numpy.ndarray, shape (N,)
        Positions (m) and normalised weights.
    labels : numpy.ndarray, shape (N,), int64
        Component of each particle, ``0..K-1``.
    n_components : int
        ``K``.
    threads : int
        Threads for the sums (the filter's :meth:`~hmmtrack.tracking.filter.ParticleFilter
        .correction_threads`).

    Returns
    -------
    numpy.ndarray, shape (K, 6)
        Per component: weight, mean x, mean y (m), var x, var y, cov xy (m²); zeros for a
        weightless component. Moments are taken about each component's first particle (no
        cancellation far from the origin).
    """
    origin = _first_members(x, y, labels, n_components)
    sums = np.zeros((chunking(x.size)[0], n_components, 6))
    args = (x, y, weights, labels, origin)
    in_chunks(_moment_chunks, _moment_chunks_parallel, x.size, threads, args, sums)
    return _moments_of_sums(sums, origin)


class Modes:
    """After each resampling: the modes of the cloud, heaviest first (table ``modes``).

    One row per resampling (:data:`MODE_COLUMNS`): the number of components and, for the
    :data:`REPORTED_MODES` heaviest modes, weight, mean position (m) and √λ₁ of the mode's
    own covariance (m); NaN where there are fewer modes. The components are the
    mixture's (the particle field ``component``, :class:`Mixture`) or, without a
    mixture, the clusters :meth:`Mixture.recluster` finds in the cloud (its default
    thresholds: clusters at least 20 m and 3 standard deviations apart, the lighter with
    at least 2 % of the weight); the modes are the components, with the mirror split
    those closer than :data:`ONE_MODE_DISTANCE` joined (:func:`join_modes`).
    """

    every_step = False

    def __init__(self, keep: bool = True):
        #: whether the whole run's table is kept (:meth:`result`); a streamed run's modes
        #: leave with its estimates (:meth:`release`), so only the rows still needed are
        self.keep = keep

    def start(self, pf) -> None:
        # one row per resampling: time, number of modes, then the REPORTED_MODES heaviest
        # modes' six moments; grown by doubling (a 30-day run resamples ~300,000 times:
        # 34 MB of rows, up to twice that with the doubling's slack, when kept)
        self._table = np.empty((1024, 2 + 6 * REPORTED_MODES))
        self._n = 0
        self._needed = 0  # rows before this one are released (not kept)

    def corrected(self, pf) -> None:
        """Nothing to record (the components are reclustered at resampling)."""

    def settled(self, pf) -> None:
        """Nothing to record."""

    def resampled(self, pf, ancestors) -> None:
        """The modes of the resampled cloud: the mixture's components (their moments as the
        mixture's resampling summed them, :attr:`~hmmtrack.tracking.filter.ParticleFilter
        .component_moments`), else the clusters of the cloud."""
        if pf.mixture is not None:
            moments = pf.component_moments
        else:
            p = pf.particles
            weights = pf.weights()[0]
            labels = _CLUSTERS.recluster(p.x, p.y, weights, np.zeros(p.n, dtype=np.int64))
            moments = component_moments(
                p.x, p.y, weights, labels, int(labels.max()) + 1, pf.correction_threads()
            )
        if self._n == len(self._table):
            self._make_room()
        self._table[self._n, :2] = pf.time, len(moments)
        if getattr(pf.mixture, "mirror", None) is not None:
            moments = join_modes(moments)  # the parts of a cloud the mirror split cut
        self._table[self._n, 2:] = _heaviest(moments).ravel()
        self._n += 1

    def _make_room(self) -> None:
        """Room for one more row: the released rows dropped when they are at least half the
        table (a streamed run's table stays a few tables of estimates long), else the
        table doubled."""
        if not self.keep and 2 * self._needed >= len(self._table):
            kept = self._n - self._needed
            self._table[:kept] = self._table[self._needed : self._n]
            self._n, self._needed = kept, 0
        else:
            self._table = np.concatenate([self._table, np.empty_like(self._table)])

    def table(self, since: float | None = None) -> pd.DataFrame:
        """The modes table (:data:`MODE_COLUMNS`): every row recorded (and not released),
        or from the latest resampling at or before ``since`` (s) on, the first row a table
        of estimates after ``since`` needs (:func:`with_modes`); √λ₁ of the modes computed
        once for all its rows."""
        rows = self._table[self._needed if since is None else self._latest(since) : self._n]
        top = rows[:, 2:].reshape(len(rows), REPORTED_MODES, 6)
        spread = sqrt_largest_eigenvalue(top[..., 3], top[..., 4], top[..., 5])
        modes = np.concatenate([top[..., :3], spread[..., None]], axis=2).reshape(
            len(rows), 4 * REPORTED_MODES
        )
        columns = {
            "time": rows[:, 0].copy(),
            "components": rows[:, 1].astype(np.int64),
            **dict(zip(MODE_COLUMNS[2:], modes.T, strict=True)),
        }
        return pd.DataFrame(columns)

    def _latest(self, time: float) -> int:
        """Row of the latest resampling at or before ``time`` (the first row kept when
        there is none)."""
        times = self._table[self._needed : self._n, 0]
        return self._needed + max(int(np.searchsorted(times, time, side="right")) - 1, 0)

    def release(self, time: float) -> None:
        """Estimates up to ``time`` (s) have taken their modes: without :attr:`keep`, the
        rows before the latest resampling at or before ``time`` may be dropped."""
        if not self.keep:
            self._needed = self._latest(time)

    def result(self) -> dict[str, pd.DataFrame]:
        """The whole run's table, when kept."""
        return {"modes": self.table()} if self.keep else {}


#: the clustering of :class:`Modes` without a mixture
_CLUSTERS = Mixture()


@njit(cache=True)
def _heaviest(moments):
    """The :data:`REPORTED_MODES` rows of ``moments`` (K, 6) of largest weight, heaviest
    first (ties in row order), NaN rows where ``K`` is smaller."""
    top = np.full((REPORTED_MODES, 6), np.nan)
    order = np.argsort(-moments[:, 0], kind="mergesort")
    for r in range(min(REPORTED_MODES, order.size)):
        top[r] = moments[order[r]]
    return top


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
    times = estimates["time"].to_numpy(dtype=float)
    # the latest resampling at or before each time (the last of several at one time)
    latest = np.searchsorted(modes["time"].to_numpy(dtype=float), times, side="right") - 1
    before = latest < 0
    columns = {}
    for name in ("mode1_weight", "mode2_x", "mode2_y", "mode2_weight"):
        values = np.append(modes[name].to_numpy(dtype=float), np.nan)
        columns[name] = values[np.where(before, -1, latest)]
    single = ~np.isnan(columns["mode1_weight"]) & np.isnan(columns["mode2_weight"])
    columns["mode2_weight"][single] = 0.0
    columns["converged"] = (estimates["sqrt_lambda1"].to_numpy() < CONVERGENCE_THRESHOLD) & (
        columns["mode1_weight"] >= ONE_MODE_WEIGHT
    )
    # one concatenation, not an insertion per column (assign: half a millisecond a run)
    return pd.concat([estimates, pd.DataFrame(columns, index=estimates.index)], axis=1)
