"""Covariates on the transition probabilities: the multinomial logit of moveHMM's ``formula=~cov``.

For ``K`` states and design row ``z_t`` (the transition formula's standardised design matrix,
:mod:`hmmtrack.hmm.formula`; ``(1, c_1, ..., c_p)`` for plain covariates), the
transition matrix at row ``t`` is

    Gamma_t[i, j] = exp(eta_t[i, j]) / sum_k exp(eta_t[i, k]),   eta_t[i, i] = 0,
    eta_t[i, j] = coefficients[r(i, j)] @ z_t                     (i != j),

where ``r(i, j)`` runs over the off-diagonal entries in row-major order (as moveHMM's
``trMatrix_rcpp``). The transition *into* row ``t`` uses the covariates of row ``t``, so a
sequence of ``T`` rows has ``T - 1`` matrices built from rows ``1 .. T-1``.

This module is for logit transition matrices and the weighted M-step of the coefficients from
expected transition counts. It is not for design matrices (:mod:`hmmtrack.hmm.formula`),
reading covariates from files (see :mod:`hmmtrack.io`) nor for the forward-backward recursions (see
:mod:`hmmtrack.hmm.inference`). Products over the ``T`` rows are written with ``np.einsum``,
not ``@``, to stay on one thread (why: reports/decisions.md, HMM fitting).
"""

from __future__ import annotations

import numpy as np


def off_diagonal_index(n_states: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the off-diagonal entries, row-major, each ``(K*(K-1),)``."""
    rows, cols = np.nonzero(~np.eye(n_states, dtype=bool))
    return rows, cols


def log_transition_matrices(coefficients: np.ndarray, design: np.ndarray) -> np.ndarray:
    """Log transition matrices of the multinomial logit, one per design row.

    Parameters
    ----------
    coefficients : ndarray, shape (K*(K-1), 1 + p)
        One row per off-diagonal entry (row-major), one column per design column.
    design : ndarray, shape (T, 1 + p)

    Returns
    -------
    ndarray, shape (T, K, K)
        ``log Gamma_t``; each row of each matrix exponentiates and sums to one.
    """
    coefficients = np.asarray(coefficients, dtype=float)
    n_states = _n_states(coefficients.shape[0])
    rows, cols = off_diagonal_index(n_states)
    eta = np.zeros((design.shape[0], n_states, n_states))
    eta[:, rows, cols] = np.einsum("td,rd->tr", design, coefficients)
    # log-sum-exp over the destination axis one column at a time (K is small, T long): faster
    # than scipy's logsumexp on the (T, K, K) array
    columns = [eta[:, :, j] for j in range(n_states)]
    top = np.maximum.reduce(columns)
    log_norm = top + np.log(sum(np.exp(column - top) for column in columns))
    return eta - log_norm[:, :, None]


def coefficients_from_matrix(transition: np.ndarray, n_design: int = 1) -> np.ndarray:
    """Coefficients whose intercepts reproduce ``transition`` and whose slopes are zero.

    Parameters
    ----------
    transition : ndarray, shape (K, K)
        Row-stochastic with positive entries.
    n_design : int
        Number of design columns ``1 + p``.

    Returns
    -------
    ndarray, shape (K*(K-1), n_design)
    """
    transition = np.asarray(transition, dtype=float)
    rows, cols = off_diagonal_index(transition.shape[0])
    coefficients = np.zeros((rows.size, n_design))
    coefficients[:, 0] = np.log(transition[rows, cols]) - np.log(transition[rows, rows])
    return coefficients


def expected_log_likelihood(coefficients: np.ndarray, xi: np.ndarray, design: np.ndarray):
    """Value and gradient of ``sum_t sum_ij xi_t[i, j] log Gamma_t[i, j]``.

    Parameters
    ----------
    coefficients : ndarray, shape (K*(K-1), 1 + p)
    xi : ndarray, shape (T, K, K)
        Expected transition counts per step (zero rows for steps that cross a track boundary).
    design : ndarray, shape (T, 1 + p)
        Design row of the step's destination row.

    Returns
    -------
    value : float
    gradient : ndarray, shape (K*(K-1), 1 + p)
    """
    log_gamma = log_transition_matrices(coefficients, design)
    value = float(np.sum(xi * log_gamma))
    n_states = xi.shape[1]
    rows, cols = off_diagonal_index(n_states)
    leaving = xi.sum(axis=2, keepdims=True)  # (T, K, 1)
    residual = xi - leaving * np.exp(log_gamma)  # (T, K, K)
    gradient = np.einsum("tr,td->rd", residual[:, rows, cols], design)
    return value, gradient


def fit_coefficients(
    xi: np.ndarray,
    design: np.ndarray,
    start: np.ndarray,
    max_iter: int = 50,
    tol: float = 1e-10,
    max_abs: float = 30.0,
) -> np.ndarray:
    """Weighted maximum-likelihood coefficients of the logit (the EM M-step).

    Maximises :func:`expected_log_likelihood`, which separates into one weighted multinomial
    logistic regression per origin state ``i`` (outcomes: the destination ``j``, reference
    ``j = i``). Each is solved by Newton's method with its analytic gradient and Hessian and
    step halving, so the objective never decreases.

    Parameters
    ----------
    xi : ndarray, shape (T, K, K)
        Expected transition counts per step.
    design : ndarray, shape (T, 1 + p)
    start : ndarray, shape (K*(K-1), 1 + p)
        Starting coefficients (the previous iteration's).
    max_iter : int
        Newton iterations per origin state.
    tol : float
        Stop when a Newton step gains less than ``tol`` (in log-likelihood units).
    max_abs : float
        Bound on each coefficient's absolute value, keeping a nearly absorbing state finite.

    Returns
    -------
    ndarray, shape (K*(K-1), 1 + p)
    """
    n_states = xi.shape[1]
    rows, _ = off_diagonal_index(n_states)
    out = np.array(start, dtype=float)
    for i in range(n_states):
        others = np.flatnonzero(np.arange(n_states) != i)
        counts = xi[:, i, others]  # (T, K-1)
        out[rows == i] = _newton_logit(
            counts, xi[:, i, i], design, out[rows == i], max_iter, tol, max_abs
        )
    return out


def _logit_objective(beta, counts, total, design, outer):
    """Value, gradient and Hessian of one origin state's weighted multinomial logit.

    ``counts`` (T, J) are the expected moves to the J other states, ``total`` (T,) all moves
    out of the origin (staying included), ``outer`` (T, D*D) the design rows' outer products.
    """
    eta = np.einsum("td,jd->tj", design, beta)  # (T, J)
    columns = [eta[:, j] for j in range(eta.shape[1])]  # J is small, T long: column loops
    top = np.maximum(np.maximum.reduce(columns), 0.0)  # the reference outcome has eta = 0
    log_norm = top + np.log(np.exp(-top) + sum(np.exp(column - top) for column in columns))
    value = float(np.einsum("tj,tj->", counts, eta) - np.einsum("t,t->", total, log_norm))
    prob = np.exp(eta - log_norm[:, None])  # (T, J)
    weighted = total[:, None] * prob
    gradient = np.einsum("tj,td->jd", counts - weighted, design)  # (J, D)
    n_out, n_design = beta.shape
    pairs = (weighted[:, :, None] * prob[:, None, :]).reshape(-1, n_out * n_out)
    hessian = np.einsum("tp,tq->pq", pairs, outer).reshape(n_out, n_out, n_design, n_design)
    diagonal = np.einsum("tj,tq->jq", weighted, outer).reshape(n_out, n_design, n_design)
    hessian[np.arange(n_out), np.arange(n_out)] -= diagonal
    return value, gradient, hessian.transpose(0, 2, 1, 3).reshape(n_out * n_design, -1)


def _newton_logit(counts, stay, design, beta, max_iter, tol, max_abs):
    total = counts.sum(axis=1) + stay
    n_design = design.shape[1]
    outer = (design[:, :, None] * design[:, None, :]).reshape(-1, n_design * n_design)
    beta = np.clip(beta, -max_abs, max_abs)
    value, gradient, hessian = _logit_objective(beta, counts, total, design, outer)
    size = beta.size
    for _ in range(max_iter):
        # the objective is concave; a small ridge keeps flat directions solvable
        direction = np.linalg.solve(
            hessian - 1e-9 * np.eye(size) * (1 + np.abs(np.diag(hessian)).max()),
            -gradient.ravel(),
        ).reshape(beta.shape)
        step = 1.0
        while step > 1e-8:
            trial = np.clip(beta + step * direction, -max_abs, max_abs)
            trial_value, trial_gradient, trial_hessian = _logit_objective(
                trial, counts, total, design, outer
            )
            if trial_value >= value:
                break
            step /= 2
        else:
            return beta
        gain = trial_value - value
        beta, value, gradient, hessian = trial, trial_value, trial_gradient, trial_hessian
        if gain < tol:
            break
    return beta


def _n_states(n_off_diagonal: int) -> int:
    n_states = int(round((1 + np.sqrt(1 + 4 * n_off_diagonal)) / 2))
    if n_states * (n_states - 1) != n_off_diagonal:
        raise ValueError(
            f"coefficients have {n_off_diagonal} rows; expected K*(K-1) for some K >= 2"
        )
    return n_states
