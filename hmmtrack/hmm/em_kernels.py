"""A fused EM iteration for the common movement HMM: one compiled pass, no posterior arrays.

The general EM of :mod:`hmmtrack.hmm.fit` evaluates the emission log densities into a
``(T, K)`` matrix, runs :func:`~hmmtrack.hmm.inference.forward_backward` (which returns
``(T, K)`` posterior, filtered and predicted arrays) and then each family's weighted M-step
reads the posterior back. For 2 or 3 states with gamma steps and von Mises angles (the
default model, zero-inflation and missing values included) and a constant transition
matrix, every
emission log density is linear in a few per-row features,

    log f_k(row t) = sum_j coefficients[k, j] * features[t, j],

with the features ``[1 if step > 0, step, log step, 1 if step == 0, 1 if angle observed,
cos angle, sin angle]`` (0 where the step or the angle is missing), and the M-step needs only
the posterior-weighted sums of the same features per state (the sufficient statistics:
total weight, sum of w x, w log x, w cos, w sin, the weight on zero steps). So one EM
iteration here is one compiled call: the scaled forward pass computes the densities from the
features as it goes, and the backward pass accumulates the sums and the expected transition
counts instead of storing the posterior. The M-step then works on (K,) sums only
(:meth:`Gamma._fit_positive_sums`, :meth:`VonMises._fit_angle_sums`, the zero-inflation
share): the same estimates, by the same code, as the families' ``fit_weighted``.

:func:`fused_em` decides whether a fit can take this path (:func:`hmmtrack.hmm.fit.run_em`
asks it first); models with other families or covariates use the general one.

Not for: Viterbi, state probabilities or residuals of a fitted model
(:mod:`hmmtrack.hmm.inference`), the working-scale likelihood and its polish
(:mod:`hmmtrack.hmm.fit`).
"""

from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import special

from hmmtrack.hmm.distributions import Gamma, PreparedAngles, PreparedSteps, VonMises
from hmmtrack.hmm.distributions.base import _LOG_2PI

__all__ = [
    "FEATURES",
    "KERNELS",
    "FusedEM",
    "Statistics",
    "features_of",
    "fused_em",
    "load_kernel",
    "takes_fused_path",
]

#: features of the gamma / von Mises model, in column order before identical ones are merged
FEATURES = ("positive", "step", "log_step", "zero", "observed", "cos", "sin")


@dataclass(frozen=True)
class Statistics:
    """What one fused E-step returns: the likelihood and the M-step's sufficient statistics.

    Attributes
    ----------
    log_likelihood : float
        Log-likelihood of all tracks at the parameters of the E-step (nats).
    sums : dict of str to ndarray (K,)
        Posterior-weighted sum of each feature of :data:`FEATURES` per state.
    transition_counts : ndarray, shape (K, K)
        Expected number of transitions i -> j, summed over time and tracks.
    first : ndarray, shape (K,)
        Posterior state probabilities at the first row of each track, summed over tracks.
    """

    log_likelihood: float
    sums: dict
    transition_counts: np.ndarray
    first: np.ndarray


_TINY_NORMALISER = 1e-100  # a forward normaliser this small goes to the log at once
_TINY_PRODUCT = 1e-200  # the running product of normalisers goes to the log below this


@njit(nogil=True, inline="always")
def _add_normaliser(log_likelihood, product, total):
    """``(log_likelihood, product)`` after a forward normaliser ``total`` (<= 1): the
    normalisers are multiplied into ``product``, which goes to the log once it is below
    :data:`_TINY_PRODUCT` (one log per ~100 rows rather than one per row)."""
    if total < _TINY_NORMALISER:
        return log_likelihood + np.log(total), product
    product *= total
    if product < _TINY_PRODUCT:
        return log_likelihood + np.log(product), 1.0
    return log_likelihood, product


def _compile_pass(n_states: int):
    """The fused E-step kernel for ``n_states`` states (a compile-time constant, so that
    LLVM unrolls every loop over the states; 2 states have a faster kernel of their own,
    :func:`_fused_pass_2_states`).

    The kernel ``fused_pass(features, coefficients, initial, transition, starts, ends, lik,
    filtered, scale, careful)`` runs the scaled forward-backward with the emission densities
    computed from the features and accumulates the M-step sums in the backward pass.

    Parameters of the kernel
    ------------------------
    features : ndarray, shape (T, m)
        Per-row features.
    coefficients : ndarray, shape (K, m)
        Emission log density of state k at row t: ``coefficients[k] @ features[t]``.
    initial : ndarray, shape (K,)
    transition : ndarray, shape (K, K)
        Rows = from, columns = to.
    starts, ends : ndarray of int64, shape (n_tracks,)
        First and one-past-last row of each track.
    lik, filtered : ndarray, shape (T, K)
        Workspace, overwritten: emission likelihoods scaled by their row maximum (1 in the
        most likely state, so K - 1 exponentials per row), filtered state probabilities.
    scale : ndarray, shape (T,)
        Workspace, overwritten: the inverse forward normalisers.
    careful : bool
        Some coefficient is -inf (the log of a zero probability): a feature of 0 then adds
        nothing rather than ``-inf * 0 = NaN``.

    Returns of the kernel
    ---------------------
    log_likelihood : float
    sums : ndarray, shape (K, m)
        Posterior-weighted feature sums per state.
    counts : ndarray, shape (K, K)
        Expected transition counts.
    first : ndarray, shape (K,)
        Summed posterior of the first row of each track.
    bad_row : int
        -1, or the first row whose log density is NaN or +inf (nothing else is valid then).
    impossible_row : int
        -1, or the first row with probability 0 under every state path.
    """

    def fused_pass(
        features, coefficients, initial, transition, starts, ends, lik, filtered, scale, careful
    ):
        n_features = features.shape[1]
        sums = np.zeros((n_states, n_features))
        counts = np.zeros((n_states, n_states))
        first = np.zeros(n_states)
        beta = np.empty(n_states)
        weighted = np.empty(n_states)
        posterior = np.empty(n_states)
        log_density = np.empty(n_states)
        log_likelihood = 0.0
        product = 1.0  # normalisers (<= 1) not yet in log_likelihood: one log per ~100 rows
        for track in range(starts.size):
            for t in range(starts[track], ends[track]):
                top, arg = -np.inf, 0
                for k in range(n_states):
                    acc = 0.0
                    for j in range(n_features):
                        f = features[t, j]
                        if not careful or f != 0.0:
                            acc += coefficients[k, j] * f
                    if not acc < np.inf:  # NaN or +inf
                        return log_likelihood, sums, counts, first, t, -1
                    log_density[k] = acc
                    if acc > top:
                        top, arg = acc, k
                if top == -np.inf:
                    return log_likelihood, sums, counts, first, -1, t
                total = 0.0
                for k in range(n_states):
                    if t == starts[track]:
                        predicted = initial[k]
                    else:
                        predicted = 0.0
                        for i in range(n_states):
                            predicted += filtered[t - 1, i] * transition[i, k]
                    lik[t, k] = 1.0 if k == arg else np.exp(log_density[k] - top)
                    filtered[t, k] = predicted * lik[t, k]
                    total += filtered[t, k]
                if not total > 0.0:
                    return log_likelihood, sums, counts, first, -1, t
                inverse = 1.0 / total
                scale[t] = inverse
                for k in range(n_states):
                    filtered[t, k] *= inverse
                log_likelihood += top
                log_likelihood, product = _add_normaliser(log_likelihood, product, total)
        log_likelihood += np.log(product)
        for track in range(starts.size):
            last = ends[track] - 1
            for k in range(n_states):
                beta[k] = 1.0
                posterior[k] = filtered[last, k]
            t = last
            while True:
                for k in range(n_states):
                    for j in range(n_features):
                        sums[k, j] += posterior[k] * features[t, j]
                if t == starts[track]:
                    break
                t -= 1
                inverse = scale[t + 1]
                for j in range(n_states):
                    weighted[j] = lik[t + 1, j] * beta[j] * inverse
                for i in range(n_states):
                    acc = 0.0
                    for j in range(n_states):
                        pair = transition[i, j] * weighted[j]
                        acc += pair
                        counts[i, j] += filtered[t, i] * pair
                    beta[i] = acc
                for k in range(n_states):
                    posterior[k] = filtered[t, k] * beta[k]
            for k in range(n_states):
                first[k] += posterior[k]
        return log_likelihood, sums, counts, first, -1, -1

    # numba names a function's on-disk cache after its qualified name: one name per number
    # of states, so that processes compiling different ones never share (and race on) a file
    fused_pass.__qualname__ = fused_pass.__name__ = f"fused_pass_{n_states}_states"
    return njit(cache=True, nogil=True)(fused_pass)


@njit(cache=True, nogil=True)
def _fused_pass_2_states(
    features, coefficients, initial, transition, starts, ends, lik, filtered, scale, careful
):
    """The fused E-step of :func:`_compile_pass` for 2 states, with the same arguments and
    returns and the same arithmetic in the same order (bit-identical results).

    The general kernel keeps per-state values in small arrays, which LLVM cannot hold in
    registers: each row's recursion then goes through memory. Here they are scalars (the
    filtered probabilities, backward variables and transition counts), and the most likely
    state is chosen without a branch; about 30 % less time per row.
    """
    n_features = features.shape[1]
    sums = np.zeros((2, n_features))
    counts = np.zeros((2, 2))
    first = np.zeros(2)
    a00, a01, a10, a11 = transition[0, 0], transition[0, 1], transition[1, 0], transition[1, 1]
    log_likelihood = 0.0
    product = 1.0  # normalisers (<= 1) not yet in log_likelihood
    for track in range(starts.size):
        f0, f1 = 0.0, 0.0
        for t in range(starts[track], ends[track]):
            d0, d1 = 0.0, 0.0
            for j in range(n_features):
                f = features[t, j]
                if not careful or f != 0.0:
                    d0 += coefficients[0, j] * f
                    d1 += coefficients[1, j] * f
            if not (d0 < np.inf and d1 < np.inf):  # NaN or +inf
                return log_likelihood, sums, counts, first, t, -1
            up = d1 > d0
            top = d1 if up else d0
            if top == -np.inf:
                return log_likelihood, sums, counts, first, -1, t
            scaled = np.exp(-abs(d1 - d0))  # the other state's likelihood over the top one's
            l0 = scaled if up else 1.0
            l1 = 1.0 if up else scaled
            if t == starts[track]:
                p0, p1 = initial[0], initial[1]
            else:
                p0 = f0 * a00 + f1 * a10
                p1 = f0 * a01 + f1 * a11
            lik[t, 0], lik[t, 1] = l0, l1
            v0, v1 = p0 * l0, p1 * l1
            total = v0 + v1
            if not total > 0.0:
                return log_likelihood, sums, counts, first, -1, t
            inverse = 1.0 / total
            scale[t] = inverse
            f0, f1 = v0 * inverse, v1 * inverse
            filtered[t, 0], filtered[t, 1] = f0, f1
            log_likelihood += top
            log_likelihood, product = _add_normaliser(log_likelihood, product, total)
    log_likelihood += np.log(product)
    c00 = c01 = c10 = c11 = 0.0
    for track in range(starts.size):
        t = ends[track] - 1
        b0, b1 = 1.0, 1.0
        q0, q1 = filtered[t, 0], filtered[t, 1]  # posterior
        while True:
            for j in range(n_features):
                f = features[t, j]
                sums[0, j] += q0 * f
                sums[1, j] += q1 * f
            if t == starts[track]:
                break
            t -= 1
            inverse = scale[t + 1]
            w0 = lik[t + 1, 0] * b0 * inverse
            w1 = lik[t + 1, 1] * b1 * inverse
            g0, g1 = filtered[t, 0], filtered[t, 1]
            pair00, pair01, pair10, pair11 = a00 * w0, a01 * w1, a10 * w0, a11 * w1
            b0, b1 = pair00 + pair01, pair10 + pair11
            c00 += g0 * pair00
            c01 += g0 * pair01
            c10 += g1 * pair10
            c11 += g1 * pair11
            q0, q1 = g0 * b0, g1 * b1
        first[0] += q0
        first[1] += q1
    counts[0, 0], counts[0, 1], counts[1, 0], counts[1, 1] = c00, c01, c10, c11
    return log_likelihood, sums, counts, first, -1, -1


#: the fused E-step kernel of each number of states the fused path takes
KERNELS = {2: _fused_pass_2_states, 3: _compile_pass(3)}


def load_kernel(n_states: int) -> None:
    """Load the fused kernel of ``n_states`` states (if there is one) into this process now.

    As :func:`hmmtrack.hmm.inference.load_kernels`: a process about to fork workers calls it
    so that they inherit the loaded kernel. The arguments have the types of a fit's call
    (read-only features), so that no other specialisation is compiled.
    """
    if n_states not in KERNELS:
        return
    features = np.zeros((1, 1))
    features.setflags(write=False)
    uniform = np.full((n_states, n_states), 1.0 / n_states)
    KERNELS[n_states](
        features,
        np.zeros((n_states, 1)),
        uniform[0].copy(),
        uniform,
        np.zeros(1, dtype=np.int64),
        np.ones(1, dtype=np.int64),
        np.empty((1, n_states)),
        np.empty((1, n_states)),
        np.empty(1),
        False,
    )


#: the features of prepared steps, built once for all the starts of a fit: steps -> (angles,
#: features, column); entries go with the prepared steps
_FEATURE_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def features_of(steps: PreparedSteps, angles: PreparedAngles) -> tuple[np.ndarray, dict]:
    """The ``(T, m)`` features of :data:`FEATURES` and the column of each name.

    Indicator features that are equal (no missing value and no zero step: "positive" and
    "observed" are both all ones) share one column; an indicator that is 0 on every row has
    none (column None: its sums are 0). Built once per pair of prepared observations (every
    start of a multi-start fit shares them; read-only).
    """
    cached = _FEATURE_CACHE.get(steps)
    if cached is not None and cached[0] is angles:
        return cached[1], cached[2]
    columns = {
        "positive": steps.positive.astype(float),
        "step": np.where(steps.positive, steps.safe, 0.0),
        "log_step": np.where(steps.positive, steps.log_safe, 0.0),
        "zero": steps.zero.astype(float),
        "observed": (~angles.missing).astype(float),
        "cos": angles.cos,
        "sin": angles.sin,
    }
    kept: list[np.ndarray] = []
    column: dict[str, int | None] = {}
    for name in FEATURES:
        same = [i for i, c in enumerate(kept) if np.array_equal(c, columns[name])]
        if name in ("positive", "zero", "observed") and not columns[name].any():
            column[name] = None
        elif name in ("positive", "zero", "observed") and same:
            column[name] = same[0]
        else:
            column[name] = len(kept)
            kept.append(columns[name])
    features = np.ascontiguousarray(np.column_stack(kept))
    features.setflags(write=False)
    _FEATURE_CACHE[steps] = (angles, features, column)
    return features, column


class FusedEM:
    """The fused E-step and closed-form M-step of one fit (gamma steps, von Mises angles).

    Parameters
    ----------
    steps : PreparedSteps
    angles : PreparedAngles
        The fit's observations (same rows).
    lengths : ndarray of int, shape (n_tracks,)
        Rows per track.
    n_states : int

    Notes
    -----
    Holds the ``(T, m)`` features and a ``(T, K)`` workspace reused by every iteration, so
    an EM run allocates no per-iteration arrays of the data's length. Indicator features
    that are equal (no missing value and no zero step: "positive" and "observed" are both
    all ones) share one column.
    """

    def __init__(self, steps: PreparedSteps, angles: PreparedAngles, lengths, n_states: int):
        self.features, self.column = features_of(steps, angles)
        lengths = np.asarray(lengths, dtype=np.int64)
        self.ends = np.cumsum(lengths)
        self.starts = self.ends - lengths
        n_obs = self.features.shape[0]
        self.lik = np.empty((n_obs, n_states))
        self.filtered = np.empty((n_obs, n_states))
        self.scale = np.empty(n_obs)

    def coefficients(self, step: Gamma, angle: VonMises) -> np.ndarray:
        """Emission log density coefficients (K, m) of the features (see the module)."""
        shape, rate = step.shape, step.mean / step.sd**2
        kappa = angle.concentration
        positive = shape * np.log(rate) - special.gammaln(shape)
        by_name = {
            "positive": positive,
            "step": -rate,
            "log_step": shape - 1.0,
            "observed": -(_LOG_2PI + np.log(special.i0e(kappa)) + kappa),
            "cos": kappa * np.cos(angle.mean),
            "sin": kappa * np.sin(angle.mean),
        }
        if step.zero_mass is not None:
            by_name["positive"] = positive + np.log1p(-step.zero_mass)
            with np.errstate(divide="ignore"):
                by_name["zero"] = np.log(step.zero_mass)
        out = np.zeros((step.n_states, self.features.shape[1]))
        for name, value in by_name.items():
            if self.column[name] is not None:
                out[:, self.column[name]] += value
        return out

    def expectation(self, params) -> Statistics:
        """The fused E-step at ``params`` (a :class:`hmmtrack.hmm.fit.Parameters`).

        Raises
        ------
        ValueError
            When a log density is NaN or +inf, or some observation has probability 0 under
            every state path (as :func:`~hmmtrack.hmm.inference.forward_backward`).
        """
        coefficients = self.coefficients(params.step, params.angle)
        log_likelihood, sums, counts, first, bad_row, impossible_row = KERNELS[params.n_states](
            self.features,
            coefficients,
            np.array(params.initial, dtype=float),  # writable C copies: one specialisation
            np.array(params.transition, dtype=float),
            self.starts,
            self.ends,
            self.lik,
            self.filtered,
            self.scale,
            bool(np.isneginf(coefficients).any()),
        )
        if bad_row >= 0:
            raise ValueError(f"the emission log density is NaN or +inf at row {bad_row}")
        if impossible_row >= 0:
            raise ValueError(
                f"the observation at row {impossible_row} has probability 0 under every state "
                "path (log-likelihood -inf)"
            )
        none = np.zeros(sums.shape[0])
        by_name = {
            name: none if index is None else sums[:, index] for name, index in self.column.items()
        }
        return Statistics(float(log_likelihood), by_name, counts, first)

    def maximisation(self, params, statistics: Statistics):
        """Parameters maximising the expected complete-data log-likelihood (closed form).

        The same estimates as :func:`hmmtrack.hmm.fit.m_step` without covariates: initial
        distribution and transition rows from the expected counts (a row with no expected
        departures keeps its values), the families' weighted MLE from the sums.
        """
        sums = statistics.sums
        first = statistics.first
        counts = statistics.transition_counts
        leaving = counts.sum(axis=1, keepdims=True)
        transition = np.where(
            leaving > 0, counts / np.where(leaving > 0, leaving, 1.0), params.transition
        )
        step, angle = params.step, params.angle
        changes = {}
        if step.zero_mass is not None:
            changes["zero_mass"] = step._zero_mass_of_sums(
                sums["positive"] + sums["zero"], sums["zero"]
            )
        changes.update(
            step._fit_sums(
                step._fit_positive_sums, sums["positive"], sums["step"], sums["log_step"]
            )
        )
        return dataclasses.replace(
            params,
            initial=first / first.sum(),
            transition=transition,
            step=step._replace(**changes),
            angle=angle._replace(
                **angle._fit_sums(angle._fit_angle_sums, sums["observed"], sums["cos"], sums["sin"])
            ),
        )


def takes_fused_path(params, data) -> bool:
    """Whether a fit starting at ``params`` on ``data`` takes the fused EM.

    Parameters
    ----------
    params : hmmtrack.hmm.fit.Parameters
    data : hmmtrack.hmm.fit.FitData

    The fused path needs 2 or 3 states (:data:`KERNELS`), a constant transition matrix (no
    covariates) and exactly the families :class:`Gamma` (zero-inflated or not) and
    :class:`VonMises` (mean estimated or fixed at 0), no further streams (emission formulas
    have other types) and no known states.
    """
    if params.n_states not in KERNELS or params.coefficients is not None:
        return False
    if data.design is not None:
        return False
    if type(params.step) is not Gamma or type(params.angle) is not VonMises:
        return False
    if params.streams or data.known is not None:
        return False
    # the general path refuses zero steps without zero-inflation
    return params.step.zero_mass is not None or not data.prepared["step"].zero.any()


def fused_em(params, data) -> FusedEM | None:
    """The fused EM of a fit starting at ``params`` on ``data``, or None for the general path
    (see :func:`takes_fused_path`)."""
    if not takes_fused_path(params, data):
        return None
    return FusedEM(data.prepared["step"], data.prepared["angle"], data.lengths, params.n_states)
