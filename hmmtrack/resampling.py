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
functions. :func:`effective_sample_size` measures weight degeneracy from log weights.

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
    "log_normalise",
    "multinomial",
    "residual",
    "stratified",
    "systematic",
]


def _checked_weights(weights: np.ndarray) -> np.ndarray:
    """Return ``weights`` as float64 normalised to sum one, refusing unusable input."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        bad = np.flatnonzero(~np.isfinite(w) | (w < 0))
        raise ValueError(
            f"weights must be finite and non-negative; bad entries at indices {bad[:10].tolist()}"
        )
    total = w.sum()
    if total <= 0:
        raise ValueError("weights sum to zero: no particle can be chosen")
    return w / total


@njit(cache=True)
def _merge(cumulative, sorted_points):
    """For ascending points, the first index with ``cumulative > point`` (one linear pass)."""
    out = np.empty(sorted_points.size, dtype=np.int64)
    j = 0
    for k in range(sorted_points.size):
        while cumulative[j] <= sorted_points[k]:
            j += 1
        out[k] = j
    return out


def _inverse_cdf(weights: np.ndarray, sorted_points: np.ndarray) -> np.ndarray:
    """Ancestors for ascending points in ``[0, 1)`` by inverting the weights' cumulative sum.

    Equal to ``np.searchsorted(cumsum(weights), points, side="right")``, in linear time.
    """
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # guard against rounding: every point in [0, 1) finds an index
    return _merge(cumulative, np.ascontiguousarray(sorted_points, dtype=np.float64))


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
    w = _checked_weights(weights)
    spacings = rng.standard_exponential(n + 1)
    points = np.cumsum(spacings[:-1]) / spacings.sum()
    return _inverse_cdf(w, points)


def stratified(rng: np.random.Generator, weights: np.ndarray, n: int) -> np.ndarray:
    """Draw one ancestor in each stratum ``[k/n, (k+1)/n)``, ``k = 0..n-1``.

    Parameters and return value as :func:`multinomial`.
    """
    w = _checked_weights(weights)
    points = (np.arange(n) + rng.random(n)) / n
    return _inverse_cdf(w, points)


def systematic(rng: np.random.Generator, weights: np.ndarray, n: int) -> np.ndarray:
    """Draw ancestors at the evenly spaced points ``(k + u) / n`` with one shared ``u``.

    Index ``i`` appears ``floor(n w_i)`` or ``ceil(n w_i)`` times.
    Parameters and return value as :func:`multinomial`.
    """
    w = _checked_weights(weights)
    points = (np.arange(n) + rng.random()) / n
    return _inverse_cdf(w, points)


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
