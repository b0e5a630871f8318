"""Hidden-state inference for HMMs: forward-backward, log-likelihood and Viterbi.

Pure functions on a log-likelihood matrix ``log_lik`` (T, K) (``log_lik[t, k]`` = log
density of observation t in state k; a row of zeros is a missing observation), emission
agnostic. Inputs are in log space:

* ``log_initial`` (K,): log initial distribution, shared by every track, or (n_tracks, K):
  one per track (a stationary start at each track's first-row covariates);
* ``log_transition`` (K, K), or (T-1, K, K) for time-varying transitions, where entry t is
  the transition from row t to row t+1 (entries that cross a track boundary are ignored);
* ``lengths``: several tracks concatenated in ``log_lik`` (None = one track); there is no
  transition across track boundaries.

The recursions are scaled (not log-sum-exp): each row of ``log_lik`` is shifted by its
maximum and exponentiated, the forward probabilities are normalised at every step and the
log normalisers accumulated. They are compiled with numba (``cache=True``); the tests
check them against a plain numpy log-space implementation and brute-force enumeration.

Not for: emission densities (``hmmtrack.hmm.distributions``), parameter estimation
(``hmmtrack.hmm.fit``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["Posterior", "forward_backward", "load_kernels", "log_likelihood", "viterbi"]


@dataclass(frozen=True)
class Posterior:
    """Result of :func:`forward_backward`.

    Attributes
    ----------
    log_likelihood : float
        Total log-likelihood of all tracks (nats).
    per_track : (n_tracks,) float
        Log-likelihood of each track.
    posterior : (T, K) float
        Smoothed state probabilities P(S_t = k | all observations of the track).
    filtered : (T, K) float
        Filtered state probabilities P(S_t = k | observations up to t).
    predicted : (T, K) float
        One-step predictions P(S_t = k | observations before t) (the initial distribution
        at the first row of a track); with the emission cdfs they give pseudo-residuals.
    transition_counts : (K, K) float
        Expected number of transitions i -> j, summed over time and tracks.
    xi : (T-1, K, K) float or None
        Expected transitions per step: ``xi[t, i, j] = P(S_t = i, S_{t+1} = j | data)``,
        zero where rows t and t+1 are in different tracks. Present when the transitions are
        time-varying or ``return_xi=True``.
    """

    log_likelihood: float
    per_track: np.ndarray
    posterior: np.ndarray
    filtered: np.ndarray
    predicted: np.ndarray
    transition_counts: np.ndarray
    xi: np.ndarray | None = None

    @property
    def pair_counts(self) -> np.ndarray:
        """What a transition M-step needs: ``xi`` (T-1, K, K) if present, else (K, K) counts."""
        return self.transition_counts if self.xi is None else self.xi


# ----------------------------------------------------------------------------------------
# Input checks and preparation
# ----------------------------------------------------------------------------------------


def _track_bounds(lengths, n_obs: int) -> tuple[np.ndarray, np.ndarray]:
    if lengths is None:
        lengths = np.array([n_obs])
    lengths = np.asarray(lengths)
    if lengths.ndim != 1 or lengths.size == 0 or not np.issubdtype(lengths.dtype, np.integer):
        raise ValueError(f"lengths must be a non-empty 1-D integer array, got {lengths!r}")
    if np.any(lengths < 1):
        bad = np.flatnonzero(lengths < 1)
        raise ValueError(f"lengths must all be >= 1; tracks {bad.tolist()} have {lengths[bad]}")
    if lengths.sum() != n_obs:
        raise ValueError(f"lengths sum to {lengths.sum()} but log_lik has {n_obs} rows")
    ends = np.cumsum(lengths).astype(np.int64)
    return ends - lengths.astype(np.int64), ends


def _prepare(log_initial, log_transition, log_lik, lengths):
    """Validate the shapes and log-probabilities; return arrays ready for the kernels."""
    log_lik = np.ascontiguousarray(log_lik, dtype=float)
    if log_lik.ndim != 2 or log_lik.shape[0] == 0:
        raise ValueError(f"log_lik must have shape (T, K) with T >= 1, got {log_lik.shape}")
    n_obs, n_states = log_lik.shape
    log_initial = np.asarray(log_initial, dtype=float)
    starts, ends = _track_bounds(lengths, n_obs)
    if log_initial.shape not in ((n_states,), (starts.size, n_states)):
        raise ValueError(
            f"log_initial must have shape ({n_states},) or ({starts.size}, {n_states}) (one "
            f"per track), got {log_initial.shape}"
        )
    log_transition = np.asarray(log_transition, dtype=float)
    time_varying = log_transition.ndim == 3
    expected = (n_obs - 1, n_states, n_states) if time_varying else (n_states, n_states)
    if log_transition.shape != expected:
        raise ValueError(
            f"log_transition must have shape ({n_states}, {n_states}) or "
            f"({n_obs - 1}, {n_states}, {n_states}), got {log_transition.shape}"
        )
    for name, arr in (("log_initial", log_initial), ("log_transition", log_transition)):
        if np.isnan(arr).any() or (arr > 1e-9).any():
            raise ValueError(f"{name} must hold log-probabilities (<= 0, no NaN)")
        off = np.abs(np.exp(arr).sum(axis=-1) - 1.0) > 1e-6  # as the model-file loader
        if off.any():
            where = np.argwhere(np.atleast_1d(off))[:5].tolist()
            raise ValueError(f"{name} must sum to 1 over its last axis; not at {where}")
    log_initial = np.ascontiguousarray(np.broadcast_to(log_initial, (starts.size, n_states)))
    if not time_varying:
        log_transition = log_transition[None]
    return log_initial, log_transition, time_varying, log_lik, starts, ends


def _check_rows(flagged: np.ndarray) -> None:
    """Raise on rows flagged (bool (T,)) as holding NaN or +inf."""
    bad = np.flatnonzero(flagged)
    if bad.size:
        raise ValueError(f"log_lik has NaN or +inf at rows {bad[:10].tolist()} (of {bad.size})")


# ----------------------------------------------------------------------------------------
# Compiled kernels (scaled recursions)
# ----------------------------------------------------------------------------------------


@njit(cache=True)
def _shift_kernel(log_lik):
    """Row maxima ``shift`` (T,) and ``log_lik - shift`` (T,K) (exponentiated by numpy).

    ``bad`` (T,) bool flags rows holding NaN or +inf. A row that is -inf in every state
    keeps shift -inf and differences -inf (likelihood 0).
    """
    n_obs, n_states = log_lik.shape
    shifted = np.empty((n_obs, n_states))
    shift = np.empty(n_obs)
    bad = np.zeros(n_obs, dtype=np.bool_)
    for t in range(n_obs):
        m = -np.inf
        for j in range(n_states):
            v = log_lik[t, j]
            if not v < np.inf:  # NaN or +inf
                bad[t] = True
            m = max(m, v)
        shift[t] = m
        if m == -np.inf:
            for j in range(n_states):
                shifted[t, j] = -np.inf
        else:
            for j in range(n_states):
                shifted[t, j] = log_lik[t, j] - m
    return shifted, shift, bad


@njit(cache=True)
def _forward_kernel(initial, transition, time_varying, lik, starts, ends):
    """Scaled forward pass on likelihoods ``lik`` (T,K) (each row scaled by its maximum).

    Returns ``filtered`` and ``predicted`` (T,K) and the normalisers ``scale`` (T,), so that
    the log-likelihood is sum(log scale + shift). A row with probability 0 under every path
    gets scale 0, and the rest of its track is left at 0.
    """
    n_obs, n_states = lik.shape
    filtered = np.empty((n_obs, n_states))
    predicted = np.empty((n_obs, n_states))
    scale = np.empty(n_obs)
    for track in range(starts.size):
        for t in range(starts[track], ends[track]):
            if t == starts[track]:
                for j in range(n_states):
                    predicted[t, j] = initial[track, j]
            else:
                k = t - 1 if time_varying else 0
                for j in range(n_states):
                    acc = 0.0
                    for i in range(n_states):
                        acc += filtered[t - 1, i] * transition[k, i, j]
                    predicted[t, j] = acc
            total = 0.0
            for j in range(n_states):
                filtered[t, j] = predicted[t, j] * lik[t, j]
                total += filtered[t, j]
            if not total > 0.0:
                filtered[t : ends[track]] = 0.0
                predicted[t + 1 : ends[track]] = 0.0
                scale[t : ends[track]] = 0.0
                break
            scale[t] = total
            inverse = 1.0 / total
            for j in range(n_states):
                filtered[t, j] *= inverse
    return filtered, predicted, scale


@njit(cache=True)
def _backward_kernel(transition, time_varying, lik, scale, filtered, starts, ends, want_xi):
    """Scaled backward pass; returns posterior (T,K), transition counts (K,K), xi."""
    n_obs, n_states = lik.shape
    posterior = np.empty((n_obs, n_states))
    counts = np.zeros((n_states, n_states))
    xi = np.zeros((n_obs - 1 if want_xi else 0, n_states, n_states))
    beta = np.ones(n_states)
    weighted = np.empty(n_states)
    for track in range(starts.size):
        last = ends[track] - 1
        for j in range(n_states):
            beta[j] = 1.0
            posterior[last, j] = filtered[last, j]
        for t in range(last - 1, starts[track] - 1, -1):
            k = t if time_varying else 0
            inverse = 1.0 / scale[t + 1]
            for j in range(n_states):
                weighted[j] = lik[t + 1, j] * beta[j] * inverse
            for i in range(n_states):
                acc = 0.0
                for j in range(n_states):
                    pair = transition[k, i, j] * weighted[j]
                    acc += pair
                    joint = filtered[t, i] * pair
                    counts[i, j] += joint
                    if want_xi:
                        xi[t, i, j] = joint
                beta[i] = acc
            for i in range(n_states):
                posterior[t, i] = filtered[t, i] * beta[i]
    return posterior, counts, xi


@njit(cache=True)
def _viterbi_kernel(log_initial, log_transition, time_varying, log_lik, starts, ends):
    """Log-space max-product per track; returns (path, first failed track or -1)."""
    n_obs, n_states = log_lik.shape
    path = np.empty(n_obs, dtype=np.int64)
    backpointer = np.zeros((n_obs, n_states), dtype=np.int64)
    delta = np.empty(n_states)
    previous = np.empty(n_states)
    for track in range(starts.size):
        s, e = starts[track], ends[track]
        for j in range(n_states):
            delta[j] = log_initial[track, j] + log_lik[s, j]
        for t in range(s + 1, e):
            k = t - 1 if time_varying else 0
            for j in range(n_states):
                previous[j] = delta[j]
            for j in range(n_states):
                best, arg = -np.inf, 0
                for i in range(n_states):
                    v = previous[i] + log_transition[k, i, j]
                    if v > best:
                        best, arg = v, i
                delta[j] = best + log_lik[t, j]
                backpointer[t, j] = arg
        best, arg = -np.inf, 0
        for j in range(n_states):
            if delta[j] > best:
                best, arg = delta[j], j
        if best == -np.inf:
            return path, track
        path[e - 1] = arg
        for t in range(e - 1, s, -1):
            path[t - 1] = backpointer[t, path[t]]
    return path, -1


def _forward(log_initial, log_transition, log_lik, lengths):
    """Validate, scale and exponentiate the likelihoods, run the forward kernel.

    Returns (transition, time_varying, starts, ends, lik, shift, filtered, predicted, scale);
    raises on NaN / +inf rows.
    """
    log_initial, log_transition, time_varying, log_lik, starts, ends = _prepare(
        log_initial, log_transition, log_lik, lengths
    )
    lik, shift, bad = _shift_kernel(log_lik)
    _check_rows(bad)
    np.exp(lik, out=lik)  # numpy's vectorised exp: faster than a numba loop
    transition = np.exp(log_transition)
    filtered, predicted, scale = _forward_kernel(
        np.exp(log_initial), transition, time_varying, lik, starts, ends
    )
    return transition, time_varying, starts, ends, lik, shift, filtered, predicted, scale


def _impossible_rows(scale: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """First row of each track whose normaliser is 0 (probability 0 under every path)."""
    if scale.all():
        return np.empty(0, dtype=np.int64)
    rows = []
    for s, e in zip(starts, ends, strict=True):
        zero = np.flatnonzero(scale[s:e] == 0)
        if zero.size:
            rows.append(s + zero[0])
    return np.array(rows, dtype=np.int64)


def _per_track(scale, shift, starts) -> np.ndarray:
    return np.add.reduceat(np.log(scale) + shift, starts)


# ----------------------------------------------------------------------------------------
# Public functions
# ----------------------------------------------------------------------------------------


def forward_backward(
    log_initial: np.ndarray,
    log_transition: np.ndarray,
    log_lik: np.ndarray,
    lengths: np.ndarray | None = None,
    *,
    return_xi: bool = False,
) -> Posterior:
    """Smoothed state probabilities and expected transitions (scaled forward-backward).

    Parameters
    ----------
    log_initial : (K,) or (n_tracks, K) float
        Log initial state distribution, shared by all tracks or one per track.
    log_transition : (K, K) or (T-1, K, K) float
        Log transition matrix, rows = from, columns = to; time-varying: entry t is the
        transition from row t to row t+1.
    log_lik : (T, K) float
        Log emission densities; a row of zeros is a missing observation, -inf allowed.
    lengths : (n_tracks,) int, optional
        Lengths of the concatenated tracks (sum T); None is one track.
    return_xi : bool
        Also return per-step expected transitions ``xi`` (always done when time-varying).

    Returns
    -------
    Posterior

    Raises
    ------
    ValueError
        On malformed input, or when some observation has probability 0 under every state
        path (the posterior is then undefined); :func:`log_likelihood` returns -inf instead.
    """
    transition, time_varying, starts, ends, lik, shift, filtered, predicted, scale = _forward(
        log_initial, log_transition, log_lik, lengths
    )
    rows = _impossible_rows(scale, starts, ends)
    if rows.size:
        raise ValueError(
            f"observations at rows {rows[:10].tolist()} have probability 0 under every state "
            "path (log-likelihood -inf); the posterior is undefined"
        )
    want_xi = bool(return_xi or time_varying)
    posterior, counts, xi = _backward_kernel(
        transition, time_varying, lik, scale, filtered, starts, ends, want_xi
    )
    per_track = _per_track(scale, shift, starts)
    return Posterior(
        log_likelihood=float(per_track.sum()),
        per_track=per_track,
        posterior=posterior,
        filtered=filtered,
        predicted=predicted,
        transition_counts=counts,
        xi=xi if want_xi else None,
    )


def log_likelihood(
    log_initial: np.ndarray,
    log_transition: np.ndarray,
    log_lik: np.ndarray,
    lengths: np.ndarray | None = None,
) -> float:
    """Total log-likelihood by the forward pass only (same arguments as ``forward_backward``).

    Returns -inf (explicitly, never NaN) when some observation is impossible under every
    state path.
    """
    *_, starts, ends, _, shift, _, _, scale = _forward(
        log_initial, log_transition, log_lik, lengths
    )
    if _impossible_rows(scale, starts, ends).size:
        return -np.inf
    return float(_per_track(scale, shift, starts).sum())


def viterbi(
    log_initial: np.ndarray,
    log_transition: np.ndarray,
    log_lik: np.ndarray,
    lengths: np.ndarray | None = None,
) -> np.ndarray:
    """Most probable state path of each track, concatenated: (T,) int in [0, K).

    Same arguments as :func:`forward_backward`. Ties go to the lowest state index.

    Raises
    ------
    ValueError
        When a track has no path of positive probability.
    """
    log_initial, log_transition, time_varying, log_lik, starts, ends = _prepare(
        log_initial, log_transition, log_lik, lengths
    )
    _check_rows(~(log_lik < np.inf).all(axis=1))
    path, failed = _viterbi_kernel(log_initial, log_transition, time_varying, log_lik, starts, ends)
    if failed >= 0:
        raise ValueError(
            f"track {failed} (rows {starts[failed]}..{ends[failed] - 1}) has no state path "
            "of positive probability"
        )
    return path


def load_kernels() -> None:
    """Load the compiled forward-backward kernels into this process now.

    The first call of a numba function in a process pays numba's set-up even when the machine
    code comes from the on-disk cache. A process about to fork workers
    calls this first, so that the workers inherit loaded kernels instead of each paying it.
    """
    forward_backward(np.zeros(1), np.zeros((1, 1)), np.zeros((2, 1)))
