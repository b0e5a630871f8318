"""Resampling schemes for particle filters: normalised weights in, ancestor indices out.

Each scheme is a pure function ``scheme(rng, weights, n) -> ancestors`` that draws ``n``
indices into ``weights`` so that index ``i`` is expected to appear ``n * weights[i]`` times
(all four schemes are unbiased). They differ in how much extra randomness they add:

* :func:`multinomial` -- ``n`` independent draws (the paper's Algorithm 2, lines 14-18);
* :func:`residual` -- ``floor(n w_i)`` deterministic copies, the rest multinomial;
* :func:`stratified` -- one uniform draw in each of ``n`` equal strata of ``[0, 1)``;
* :func:`systematic` -- one uniform shared by all strata; every count is within one of
  ``n w_i`` (floor or ceil), the least noisy of the four.

:data:`RESAMPLERS` maps the names used by :class:`hmmtrack.filter.ParticleFilter` to the
functions. Multinomial, stratified and systematic draw sorted points in ``[0, 1)`` with
NumPy and invert the cumulative weights in one compiled pass (:func:`inverse_cdf`).
:func:`effective_sample_size` measures weight degeneracy from log weights.

This module does not weigh particles or move them; it only chooses ancestors.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit

__all__ = [
    "RESAMPLERS",
    "effective_sample_size",
    "get_resampler",
    "inverse_cdf",
    "log_normalise",
    "multinomial",
    "residual",
    "stratified",
    "systematic",
]


@njit(cache=True, fastmath={"reassoc"})
def _weights_status(w):
    """0 if ``w`` is usable (finite, non-negative, positive sum), 1 if not, 2 if it sums to 0;
    and the sum. One compiled, branch-free (vectorised) pass instead of four NumPy ones."""
    total = 0.0
    bad = False
    for i in range(w.size):
        bad |= not (w[i] >= 0.0 and w[i] < np.inf)  # also catches NaN
        total += w[i]
    if bad:
        return 1, 0.0
    return (0 if total > 0.0 else 2), total


def _checked_weights(weights: np.ndarray) -> np.ndarray:
    """Return ``weights`` as float64 normalised to sum one, refusing unusable input."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    status, total = _weights_status(w)
    if status == 1:
        bad = np.flatnonzero(~np.isfinite(w) | (w < 0))
        raise ValueError(
            f"weights must be finite and non-negative; bad entries at indices {bad[:10].tolist()}"
        )
    if status == 2:
        raise ValueError("weights sum to zero: no particle can be chosen")
    return w * (1.0 / total)


@njit(cache=True)
def inverse_cdf(weights, sorted_points):
    """Ancestors for ascending points in ``[0, 1)`` by inverting the weights' cumulative sum.

    Equal to ``np.searchsorted(cumsum(weights), points, side="right")``, clipped to the
    last index of positive weight (so that rounding in the cumulative sum can neither lose
    a point nor pick a weightless particle), in one linear compiled pass.

    Parameters
    ----------
    weights : (M,) float
        Normalised weights (sum one).
    sorted_points : (n,) float
        Ascending points in ``[0, 1)``.

    Returns
    -------
    (n,) int64 indices into ``weights``, ascending.
    """
    out = np.empty(sorted_points.size, dtype=np.int64)
    last = weights.size - 1
    while last > 0 and weights[last] <= 0.0:  # never pick a weightless particle
        last -= 1
    j = 0
    cumulative = weights[0]
    for k in range(sorted_points.size):
        while cumulative <= sorted_points[k] and j < last:
            j += 1
            cumulative += weights[j]
        out[k] = j
    return out


def _multinomial_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` independent uniforms on ``[0, 1)``, drawn already sorted (ascending).

    Normalised cumulative sums of ``n + 1`` standard exponentials are the order statistics
    of ``n`` uniforms.
    """
    return _order_statistics(rng.standard_exponential(n + 1))


@njit(cache=True)
def _order_statistics(spacings):
    """Cumulative sums of the first ``n`` of ``n + 1`` spacings over their total (one pass)."""
    scale = 1.0 / spacings.sum()
    out = np.empty(spacings.size - 1)
    running = 0.0
    for k in range(out.size):
        running += spacings[k]
        out[k] = running * scale
    return out


def _stratified_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """One uniform in each stratum ``[k/n, (k+1)/n)``, ``k = 0..n-1`` (ascending)."""
    return (np.arange(n) + rng.random(n)) / n


def _systematic_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """The evenly spaced points ``(k + u) / n`` with one shared uniform ``u`` (ascending)."""
    return (np.arange(n) + rng.random()) / n


def multinomial(rng: np.random.Generator, weights: np.ndarray, n: int) -> np.ndarray:
    """Draw ``n`` ancestors independently with probabilities ``weights``.

    The ``n`` uniforms are drawn already sorted (normalised cumulative sums of ``n + 1``
    standard exponentials are the order statistics of ``n`` uniforms), so inverting the
    cumulative weights takes one linear pass.

    Parameters
    ----------
    rng : numpy.random.Generator
    weights : (M,) array of float
        Non-negative weights; normalised here.
    n : int
        Number of ancestors to draw.

    Returns
    -------
    (n,) int64 array of indices into ``weights``, sorted ascending.
    """
    return inverse_cdf(_checked_weights(weights), _multinomial_points(rng, n))


def stratified(rng: np.random.Generator, weights: np.ndarray, n: int) -> np.ndarray:
    """Draw one ancestor in each stratum ``[k/n, (k+1)/n)``, ``k = 0..n-1``.

    Parameters and return value as :func:`multinomial`.
    """
    return inverse_cdf(_checked_weights(weights), _stratified_points(rng, n))


def systematic(rng: np.random.Generator, weights: np.ndarray, n: int) -> np.ndarray:
    """Draw ancestors at the evenly spaced points ``(k + u) / n`` with one shared ``u``.

    Index ``i`` appears ``floor(n w_i)`` or ``ceil(n w_i)`` times.
    Parameters and return value as :func:`multinomial`.
    """
    return inverse_cdf(_checked_weights(weights), _systematic_points(rng, n))


def residual(rng: np.random.Generator, weights: np.ndarray, n: int) -> np.ndarray:
    """Keep ``floor(n w_i)`` copies of each index, draw the remainder multinomially.

    Parameters and return value as :func:`multinomial`.
    """
    w = _checked_weights(weights)
    expected = n * w
    copies = np.floor(expected).astype(np.int64)
    n_left = n - int(copies.sum())
    if n_left > 0:
        copies += rng.multinomial(n_left, _checked_weights(expected - copies))
    return np.repeat(np.arange(w.size, dtype=np.int64), copies)


Resampler = Callable[[np.random.Generator, np.ndarray, int], np.ndarray]

RESAMPLERS: dict[str, Resampler] = {
    "multinomial": multinomial,
    "residual": residual,
    "stratified": stratified,
    "systematic": systematic,
}


def get_resampler(name: str) -> Resampler:
    """Return the resampling function registered under ``name`` (see :data:`RESAMPLERS`)."""
    try:
        return RESAMPLERS[name]
    except KeyError:
        raise ValueError(
            f"unknown resampling scheme {name!r}; expected one of {sorted(RESAMPLERS)}"
        ) from None


def effective_sample_size(log_weights: np.ndarray) -> float:
    """Kish's effective sample size ``1 / sum(w_i^2)`` of normalised weights.

    Parameters
    ----------
    log_weights : (M,) array of float
        Unnormalised log weights; ``-inf`` marks impossible particles.

    Returns
    -------
    float in ``[1, M]``, or ``0.0`` when every particle is impossible.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    if np.any(np.isnan(lw)) or np.any(lw == np.inf):
        raise ValueError("log weights must be finite or -inf, got NaN or +inf")
    top = lw.max()
    if not np.isfinite(top):
        return 0.0
    w = np.exp(lw - top)
    return float(w.sum() ** 2 / (w @ w))


def log_normalise(log_weights: np.ndarray) -> np.ndarray:
    """Log weights minus their log-sum-exp, so that their exponentials sum to one.

    Parameters
    ----------
    log_weights : (M,) array of float, with a finite maximum

    Returns
    -------
    (M,) float array; ``-inf`` entries stay ``-inf``.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    top = lw.max()
    if not np.isfinite(top):
        raise ValueError(f"cannot normalise log weights whose maximum is {top}")
    return lw - (top + np.log(np.exp(lw - top).sum()))
