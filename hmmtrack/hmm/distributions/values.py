"""Families of further data streams: Normal, Beta, Poisson, NegativeBinomial, Bernoulli,
Categorical, and the inflated ZeroInflatedPoisson, ZeroInflatedNegativeBinomial and
ZeroOneInflatedBeta.

A movement HMM's steps and turning angles can be joined by other observations per row, each
with its own family: a dive depth (normal), a proportion of time at the surface (beta, or
zero/one-inflated beta with exact 0s and 1s), activity counts (Poisson, negative binomial,
either zero-inflated), a dive or no dive (Bernoulli), a behaviour class (categorical). Each family
follows the emission protocol of :mod:`.base` on :class:`PreparedValues` (validated once,
missing rows NaN); ``_ValueFamily`` holds what they share. A family gives the log-density
and the derivatives of its parameters' link values for a state index or for every row at
once (``_state_logpdf(k, x)`` and ``_link_score(k, x)`` with ``k`` an int or
``slice(None)``), from which the weighted score, the row view and the working scale follow.
Links: log for positive parameters, identity for the normal mean, logit for the Bernoulli
probability and a zero mass, a multinomial logit for the beta's zero and one masses and the
categories.

Not for step lengths or turning angles (:mod:`.steps`, :mod:`.angles`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy import optimize, special, stats

from hmmtrack.hmm.distributions.base import (
    _LOG_2PI,
    _MIN_STATE_WEIGHT,
    _NEWTON_MAX_ITER,
    _NEWTON_TOL,
    _TINY,
    D,
    _by_state,
    _check_observations,
    _check_states,
    _check_weights,
    _column_sums,
    _Family,
    _frozen,
    _logit,
    _rows,
    _rows_where,
    _split_working,
    _weighted_means,
    _weighted_sums,
)

_MAX_SIZE = 1e8  # negative binomial size without overdispersion (the Poisson limit)


@dataclass(frozen=True, eq=False)
class PreparedValues:
    """Observations of a further stream validated once; from :func:`prepare_values`.

    Attributes
    ----------
    missing : (T,) bool
        NaN rows.
    safe : (T,) float
        The values with missing rows replaced by a value in every family's support (0.5).
    observed : (n_observed,) float
        The non-missing values.
    """

    missing: np.ndarray
    safe: np.ndarray
    observed: np.ndarray

    @property
    def n_obs(self) -> int:
        """Number of rows T."""
        return self.missing.size


def prepare_values(x: np.ndarray) -> PreparedValues:
    """Validate the observations ``x`` (T,) of a further stream (finite or NaN)."""
    if isinstance(x, PreparedValues):
        return x
    x = _check_observations(x, "values")
    missing = np.isnan(x)
    safe = np.where(missing, 0.5, x)
    observed = safe if not missing.any() else safe[~missing]
    _frozen(missing, safe, observed)
    return PreparedValues(missing, safe, observed)


class _ValueFamily(_Family):
    """Base of the families of further streams (parameters in link order: ``_parameters``)."""

    # per parameter: "log", "identity", "logit", or "mlogit" (point masses sharing one
    # multinomial logit against the rest of the distribution: log(p / (1 - sum of them)))
    _links: ClassVar[tuple[str, ...]]
    _support: ClassVar[str]  # what the observations must be, for error messages
    _start: ClassVar[dict[str, float]]  # parameter values before a first weighted fit
    # the smallest value of a discrete family (counts 0, categories 1); None when continuous
    _lowest: ClassVar[float | None] = None

    # --- to be provided by each family ---------------------------------------------------
    def _in_support(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _state_logpdf(self, k: int | slice, x: np.ndarray) -> np.ndarray:
        """Log-density (T,) of ``x`` (T,) in state ``k`` (or row by row for ``slice(None)``)."""
        raise NotImplementedError

    def _link_score(self, k: int | slice, x: np.ndarray) -> np.ndarray:
        """Derivatives (n_parameters, T) of :meth:`_state_logpdf` by the link values."""
        raise NotImplementedError

    def _fit_observed(self, x: np.ndarray, w: np.ndarray) -> dict:
        """Weighted MLE ``{parameter: (K,)}`` of observed values ``x`` (n,), weights (n, K)."""
        raise NotImplementedError

    def _cdf_values(self, x: np.ndarray) -> np.ndarray:
        """P(X <= x) elementwise: ``x`` broadcast against the parameters ((T, 1) against
        (K,) gives (T, K); (T,) against a row distribution's (T,) gives (T,))."""
        raise NotImplementedError

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def expected_value(self) -> np.ndarray:
        raise NotImplementedError

    # --- shared -------------------------------------------------------------------------
    def _validate(self) -> None:
        for field, link in zip(self._parameters, self._links, strict=True):
            value = getattr(self, field)
            if link == "log":
                self._require(field, value > 0, "> 0")
            elif link == "logit":
                self._require(field, (value >= 0) & (value <= 1), "in [0, 1]")
            elif link == "mlogit":
                self._require(field, (value >= 0) & (self._masses() < 1), "in [0, 1), summing < 1")

    def _masses(self) -> np.ndarray:
        """Total probability (K,) of the point masses with the "mlogit" link."""
        fields = [
            f for f, link in zip(self._parameters, self._links, strict=True) if link == "mlogit"
        ]
        return sum((getattr(self, f) for f in fields), np.zeros(self.n_states))

    def prepare(self, x: np.ndarray) -> PreparedValues:
        """:func:`prepare_values` with the family's support checked."""
        data = prepare_values(x)
        bad = ~data.missing & ~self._in_support(data.safe)
        if bad.any():
            raise ValueError(
                f"{type(self).__name__}: observations must be {self._support}; not at rows "
                f"{_rows(bad)}"
            )
        return data

    def _observed_weights(self, data: PreparedValues, w: np.ndarray) -> np.ndarray:
        w = _check_weights(w, data.n_obs, self.n_states, type(self).__name__)
        return w if data.observed is data.safe else _rows_where(~data.missing, w)

    def logpdf(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """Log-density (log-probability for counts) of ``x`` (T,) in every state -> (T, K);
        NaN -> 0.0 row."""
        data = self.prepare(x)
        out = _by_state(data.n_obs, self.n_states, lambda k: self._state_logpdf(k, data.safe))
        out[data.missing] = 0.0
        return out

    def cdf(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """P(X <= x) in every state -> (T, K); NaN -> NaN row."""
        return self._cdf(self._cdf_values, self.prepare(x), (-1, 1))

    def cdf_below(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """P(X < x) in every state -> (T, K); NaN -> NaN row. It differs from :meth:`cdf`
        at the point masses (every value of a discrete family), where the randomised
        quantile residuals of :func:`hmmtrack.hmm.diagnostics.pseudo_residuals` draw
        between the two."""
        return self._cdf(self._cdf_below_values, self.prepare(x), (-1, 1))

    def row_cdf(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """P(X <= x_t) (T,) under the parameters of "state" ``t`` (a row distribution,
        K = T); missing rows NaN."""
        return self._cdf(self._cdf_values, self._row_data(x), (-1,))

    def row_cdf_below(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """P(X < x_t) (T,) under the parameters of "state" ``t``; missing rows NaN."""
        return self._cdf(self._cdf_below_values, self._row_data(x), (-1,))

    def _row_data(self, x: np.ndarray | PreparedValues) -> PreparedValues:
        data = self.prepare(x)
        self._check_rows(data)
        return data

    @staticmethod
    def _cdf(values, data: PreparedValues, shape: tuple[int, ...]) -> np.ndarray:
        """``values`` (:meth:`_cdf_values` or :meth:`_cdf_below_values`) of the observations
        reshaped to ``shape`` ((T, 1) for every state, (T,) for a row distribution), NaN
        where missing."""
        return np.where(data.missing.reshape(shape), np.nan, values(data.safe.reshape(shape)))

    def _cdf_below_values(self, x: np.ndarray) -> np.ndarray:
        """P(X < x) elementwise, broadcast as :meth:`_cdf_values`."""
        if self._lowest is None:
            return self._cdf_values(x)
        above = x > self._lowest
        below = self._cdf_values(np.where(above, x - 1.0, self._lowest))
        return np.where(above, below, 0.0)

    def fit_weighted(self: D, x: np.ndarray | PreparedValues, w: np.ndarray) -> D:
        """Weighted MLE per state (``w`` (T, K)); NaN rows ignored; a state with (almost) no
        weight keeps its parameters."""
        data = self.prepare(x)
        w = self._observed_weights(data, w)
        return self._replace(**self._fit_states(self._fit_observed, w, data.observed))

    @classmethod
    def initial(cls: type[D], x: np.ndarray | PreparedValues, w: np.ndarray) -> D:
        """Starting values: the weighted fit of ``x`` (T,) with weights ``w`` (T, K)."""
        start = cls(**{f: np.full(w.shape[1], cls._start[f]) for f in cls._parameters})  # type: ignore[arg-type]
        return start.fit_weighted(x, w)

    def working_score(self, x: np.ndarray | PreparedValues, w: np.ndarray) -> np.ndarray:
        """Gradient of ``sum(w * logpdf(x))`` w.r.t. :meth:`to_working`, (n_working,)."""
        data = self.prepare(x)
        w = self._observed_weights(data, w)
        blocks = np.empty((len(self.link_names()), self.n_states))
        for k in range(self.n_states):
            blocks[:, k] = self._link_score(k, data.observed) @ w[:, k]
        return blocks.ravel()

    def to_working(self) -> np.ndarray:
        """Working vector: each parameter on its link scale, parameter-major (K per block)."""
        return self.to_links().ravel()

    def to_links(self) -> np.ndarray:
        """Parameters on their link scale, (n_links, K)."""
        blocks = []
        for field, link in zip(self._parameters, self._links, strict=True):
            value = getattr(self, field)
            if link == "log":
                blocks.append(np.log(np.maximum(value, _TINY)))
            elif link == "logit":
                blocks.append(_logit(value))
            elif link == "mlogit":
                rest = np.maximum(1.0 - self._masses(), _TINY)
                blocks.append(np.log(np.maximum(value, _TINY)) - np.log(rest))
            else:
                blocks.append(np.array(value, dtype=float))
        return np.vstack(blocks)

    @classmethod
    def from_working(cls: type[D], theta: np.ndarray, n_states: int) -> D:
        """Inverse of :meth:`to_working` for ``n_states`` states."""
        blocks = _split_working(theta, n_states, len(cls._parameters), cls.__name__)  # type: ignore[attr-defined]
        return cls.from_links(blocks)

    @classmethod
    def from_links(cls: type[D], eta: np.ndarray) -> D:
        """The member whose parameters on their link scale are ``eta`` (n_links, n)."""
        values = {}
        masses = [b for link, b in zip(cls._links, eta, strict=True) if link == "mlogit"]  # type: ignore[attr-defined]
        if masses:  # softmax against the rest (link 0), shifted so that no exp overflows
            top = np.maximum(np.max(masses, axis=0), 0.0)
            denominator = np.exp(-top) + np.sum(np.exp(np.array(masses) - top), axis=0)
        for field, link, block in zip(cls._parameters, cls._links, eta, strict=True):  # type: ignore[attr-defined]
            if link == "log":
                values[field] = np.exp(block)
            elif link == "logit":
                values[field] = special.expit(block)
            elif link == "mlogit":
                values[field] = np.exp(block - top) / denominator
            else:
                values[field] = np.array(block, dtype=float)
        return cls(**values)

    def link_names(self) -> tuple[str, ...]:
        """The parameters in link order."""
        return self._parameters

    def _structure(self) -> dict[str, Any]:
        return {}

    def _check_rows(self, data: PreparedValues) -> None:
        if self.n_states != data.n_obs:
            raise ValueError(
                f"{type(self).__name__}: a row distribution needs one parameter set per row; "
                f"it has {self.n_states} for {data.n_obs} rows"
            )

    def row_logpdf(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """Log-density (T,) of value ``t`` under the parameters of "state" ``t``; NaN -> 0."""
        data = self.prepare(x)
        self._check_rows(data)
        out = self._state_logpdf(slice(None), data.safe)
        out[data.missing] = 0.0
        return out

    def row_score(self, x: np.ndarray | PreparedValues) -> np.ndarray:
        """Derivatives (n_links, T) of :meth:`row_logpdf` by each row's link values."""
        data = self.prepare(x)
        self._check_rows(data)
        out = self._link_score(slice(None), data.safe)
        out[:, data.missing] = 0.0
        return out


@dataclass(frozen=True, eq=False)
class Normal(_ValueFamily):
    """Normal observations (a dive depth, a temperature).

    Parameters
    ----------
    mean : (K,) float
        Mean, in the units of the observations (identity link).
    sd : (K,) float > 0
        Standard deviation, same units (log link).
    """

    mean: np.ndarray
    sd: np.ndarray

    name: ClassVar[str] = "normal"
    _parameters: ClassVar[tuple[str, ...]] = ("mean", "sd")
    _links: ClassVar[tuple[str, ...]] = ("identity", "log")
    _support: ClassVar[str] = "finite numbers"
    _start: ClassVar[dict[str, float]] = {"mean": 0.0, "sd": 1.0}

    def _in_support(self, x: np.ndarray) -> np.ndarray:
        return np.isfinite(x)

    def _state_logpdf(self, k, x):
        z = (x - self.mean[k]) / self.sd[k]
        return -0.5 * z**2 - (np.log(self.sd[k]) + 0.5 * _LOG_2PI)

    def _link_score(self, k, x):
        z = (x - self.mean[k]) / self.sd[k]
        return np.vstack([z / self.sd[k], z**2 - 1.0])

    def _fit_observed(self, x, w):
        total = _column_sums(w)
        mean = _weighted_means(x, w, total)
        variance = _weighted_means(x**2, w, total) - mean**2
        return {"mean": mean, "sd": np.sqrt(np.maximum(variance, _TINY))}

    def _cdf_values(self, x):
        return special.ndtr((x - self.mean) / self.sd)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one value per entry of ``states`` (n,) -> (n,)."""
        states = _check_states(states, self.n_states, type(self).__name__)
        return rng.normal(self.mean[states], self.sd[states])

    def expected_value(self) -> np.ndarray:
        """Mean per state (K,)."""
        return self.mean.copy()


def _beta_state_mle(mean_log: float, mean_log1m: float, start: tuple[float, float]):
    """Beta shapes (a, b) with ``psi(a) - psi(a+b) = mean_log`` and ``psi(b) - psi(a+b) =
    mean_log1m``: Newton on (a, b), where the log-likelihood is concave (an exponential
    family in them), steps halved to keep both shapes positive."""
    shapes = np.array(start, dtype=float)
    for _ in range(_NEWTON_MAX_ITER):
        a, b = shapes
        both = special.digamma(a + b)
        gradient = np.array(
            [mean_log - special.digamma(a) + both, mean_log1m - special.digamma(b) + both]
        )
        total = special.polygamma(1, a + b)
        hessian = np.array(
            [[total - special.polygamma(1, a), total], [total, total - special.polygamma(1, b)]]
        )
        step = np.linalg.solve(hessian, -gradient)
        while np.any(shapes + step <= 0):
            step /= 2.0
        shapes = shapes + step
        if np.max(np.abs(step) / shapes) <= _NEWTON_TOL:
            break
    return float(shapes[0]), float(shapes[1])


@dataclass(frozen=True, eq=False)
class Beta(_ValueFamily):
    """Beta observations in (0, 1) (a proportion of time at the surface).

    Parameters
    ----------
    shape1, shape2 : (K,) float > 0
        The shapes ``a`` and ``b``: density ``x**(a-1) (1-x)**(b-1) / B(a, b)`` (log links).
    """

    shape1: np.ndarray
    shape2: np.ndarray

    name: ClassVar[str] = "beta"
    _parameters: ClassVar[tuple[str, ...]] = ("shape1", "shape2")
    _links: ClassVar[tuple[str, ...]] = ("log", "log")
    _support: ClassVar[str] = "in (0, 1) (with exact 0s or 1s: the family 'zoibeta')"
    _start: ClassVar[dict[str, float]] = {"shape1": 1.0, "shape2": 1.0}

    def _in_support(self, x):
        return (x > 0) & (x < 1)

    def _state_logpdf(self, k, x):
        a, b = self.shape1[k], self.shape2[k]
        return (a - 1.0) * np.log(x) + (b - 1.0) * np.log1p(-x) - special.betaln(a, b)

    def _link_score(self, k, x):
        a, b = self.shape1[k], self.shape2[k]
        both = special.digamma(a + b)
        return np.vstack(
            [
                a * (np.log(x) - special.digamma(a) + both),
                b * (np.log1p(-x) - special.digamma(b) + both),
            ]
        )

    def _fit_observed(self, x, w):
        total = _column_sums(w)
        mean = _weighted_means(x, w, total)
        variance = np.maximum(_weighted_means(x**2, w, total) - mean**2, _TINY)
        common = np.maximum(mean * (1 - mean) / variance - 1.0, 1e-3)  # moments' a + b
        mean_log = _weighted_means(np.log(x), w, total)
        mean_log1m = _weighted_means(np.log1p(-x), w, total)
        fits = [
            _beta_state_mle(
                mean_log[k], mean_log1m[k], (mean[k] * common[k], (1 - mean[k]) * common[k])
            )
            for k in range(w.shape[1])
        ]
        shape1, shape2 = np.array(fits).T
        return {"shape1": shape1, "shape2": shape2}

    def _cdf_values(self, x):
        return special.betainc(self.shape1, self.shape2, x)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one value per entry of ``states`` (n,) -> (n,)."""
        states = _check_states(states, self.n_states, type(self).__name__)
        return rng.beta(self.shape1[states], self.shape2[states])

    def expected_value(self) -> np.ndarray:
        """Mean per state (K,)."""
        return self.shape1 / (self.shape1 + self.shape2)


def _is_count(x: np.ndarray) -> np.ndarray:
    return (x >= 0) & (x == np.floor(x))


@dataclass(frozen=True, eq=False)
class Poisson(_ValueFamily):
    """Poisson counts (activity counts per step).

    Parameters
    ----------
    rate : (K,) float > 0
        Mean count per row (log link).
    """

    rate: np.ndarray

    name: ClassVar[str] = "poisson"
    _parameters: ClassVar[tuple[str, ...]] = ("rate",)
    _links: ClassVar[tuple[str, ...]] = ("log",)
    _support: ClassVar[str] = "non-negative whole numbers"
    _start: ClassVar[dict[str, float]] = {"rate": 1.0}
    _lowest: ClassVar[float | None] = 0.0

    def _in_support(self, x):
        return _is_count(x)

    def _state_logpdf(self, k, x):
        rate = self.rate[k]
        return x * np.log(rate) - rate - special.gammaln(x + 1.0)

    def _link_score(self, k, x):
        return (x - self.rate[k])[None, :]

    def _fit_observed(self, x, w):
        return {"rate": np.maximum(_weighted_means(x, w, _column_sums(w)), _TINY)}

    def _cdf_values(self, x):
        return stats.poisson.cdf(x, self.rate)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one count per entry of ``states`` (n,) -> (n,) float."""
        states = _check_states(states, self.n_states, type(self).__name__)
        return rng.poisson(self.rate[states]).astype(float)

    def expected_value(self) -> np.ndarray:
        """Mean count per state (K,)."""
        return self.rate.copy()


@dataclass(frozen=True, eq=False)
class NegativeBinomial(_ValueFamily):
    """Negative binomial counts (overdispersed activity counts), momentuHMM's mean/size.

    Parameters
    ----------
    mean : (K,) float > 0
        Mean count ``mu`` (log link).
    size : (K,) float > 0
        Dispersion ``r``: variance ``mu + mu**2 / r`` (log link); the Poisson as ``r -> inf``
        (capped at 1e8).
    """

    mean: np.ndarray
    size: np.ndarray

    name: ClassVar[str] = "negativebinomial"
    _parameters: ClassVar[tuple[str, ...]] = ("mean", "size")
    _links: ClassVar[tuple[str, ...]] = ("log", "log")
    _support: ClassVar[str] = "non-negative whole numbers"
    _start: ClassVar[dict[str, float]] = {"mean": 1.0, "size": 1.0}
    _lowest: ClassVar[float | None] = 0.0

    def _in_support(self, x):
        return _is_count(x)

    def _state_logpdf(self, k, x):
        mu, r = self.mean[k], self.size[k]
        log_total = np.log(r + mu)
        return (
            special.gammaln(x + r)
            - special.gammaln(r)
            - special.gammaln(x + 1.0)
            + r * (np.log(r) - log_total)
            + x * (np.log(mu) - log_total)
        )

    def _link_score(self, k, x):
        mu, r = self.mean[k], self.size[k]
        total = r + mu
        by_mean = r * (x - mu) / total
        by_size = r * (
            special.digamma(x + r)
            - special.digamma(r)
            + np.log(r)
            - np.log(total)
            + (mu - x) / total
        )
        return np.vstack([by_mean, by_size])

    def _fit_observed(self, x, w):
        """The mean's MLE is the weighted mean; the size solves its profile score, bracketed
        around the moment estimate ``mean**2 / (variance - mean)`` (no overdispersion: the
        Poisson limit, size 1e8). The score sums over the distinct counts with their total
        weights (a few dozen digammas per evaluation instead of one per row)."""
        total = _column_sums(w)
        mean = np.maximum(_weighted_means(x, w, total), _TINY)
        variance = _weighted_means(x**2, w, total) - mean**2
        size = np.full_like(mean, _MAX_SIZE)
        distinct, index = np.unique(x, return_inverse=True)
        for k in range(w.shape[1]):
            if variance[k] <= mean[k] * (1.0 + 1e-9):
                continue
            weights = np.bincount(index, weights=w[:, k], minlength=distinct.size)

            def profile(log_r, k=k, weights=weights):  # the size score at the mean's MLE
                r = np.exp(log_r)
                digammas = special.digamma(distinct + r) - special.digamma(r)
                return float(weights @ digammas) + total[k] * (np.log(r) - np.log(r + mean[k]))

            guess = np.log(mean[k] ** 2 / (variance[k] - mean[k]))
            lower, upper = guess - 2.0, guess + 2.0
            while profile(lower) <= 0 and lower > -40:
                lower -= 4.0
            while profile(upper) >= 0 and upper < np.log(_MAX_SIZE):
                upper += 4.0
            if profile(upper) < 0 < profile(lower):
                size[k] = np.exp(optimize.brentq(profile, lower, upper, xtol=1e-12))
        return {"mean": mean, "size": np.minimum(size, _MAX_SIZE)}

    def _cdf_values(self, x):
        return stats.nbinom.cdf(x, self.size, self.size / (self.size + self.mean))

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one count per entry of ``states`` (n,) -> (n,) float."""
        states = _check_states(states, self.n_states, type(self).__name__)
        r = self.size[states]
        return rng.negative_binomial(r, r / (r + self.mean[states])).astype(float)

    def expected_value(self) -> np.ndarray:
        """Mean count per state (K,)."""
        return self.mean.copy()


@dataclass(frozen=True, eq=False)
class Bernoulli(_ValueFamily):
    """Binary observations, 0 or 1 (a dive or not in the step).

    Parameters
    ----------
    prob : (K,) float in [0, 1]
        Probability of a 1 (logit link; clipped to [1e-12, 1 - 1e-12] on it).
    """

    prob: np.ndarray

    name: ClassVar[str] = "bernoulli"
    _parameters: ClassVar[tuple[str, ...]] = ("prob",)
    _links: ClassVar[tuple[str, ...]] = ("logit",)
    _support: ClassVar[str] = "0 or 1"
    _start: ClassVar[dict[str, float]] = {"prob": 0.5}
    _lowest: ClassVar[float | None] = 0.0

    def _in_support(self, x):
        return (x == 0) | (x == 1)

    def _state_logpdf(self, k, x):
        p = np.clip(self.prob[k], _TINY, 1.0 - _TINY)
        return np.where(x == 1, np.log(p), np.log1p(-p))

    def _link_score(self, k, x):
        return (x - np.clip(self.prob[k], _TINY, 1.0 - _TINY))[None, :]

    def _fit_observed(self, x, w):
        return {"prob": _weighted_means(x, w, _column_sums(w))}

    def _cdf_values(self, x):
        return np.where(x >= 1, 1.0, 1.0 - self.prob)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one 0 / 1 per entry of ``states`` (n,) -> (n,) float."""
        states = _check_states(states, self.n_states, type(self).__name__)
        return (rng.random(states.size) < self.prob[states]).astype(float)

    def expected_value(self) -> np.ndarray:
        """Probability of a 1 per state (K,)."""
        return self.prob.copy()


class _ZeroInflatedCounts:
    """Zero inflation of a count family (mixed in before it): a structural zero with
    probability ``zero_mass`` z, else a count of the family, so ``P(0) = z + (1 - z) f(0)``
    and ``P(x) = (1 - z) f(x)`` for x > 0. The zero mass has a logit link.

    Its weighted MLE is an EM inside the M-step: a zero is structural with probability
    ``r = z / P(0)`` (the same for every zero row of a state); z is then the weighted share
    of zeros times r, and the count family is fitted with the zero rows' weights times
    ``1 - r``.
    """

    zero_mass: np.ndarray

    def _parts(self, k, x):
        """log (1 - z) f(x) (T,) and the share of a row's probability that is the count
        family's (T,): ``(1 - z) f(0) / P(0)`` at zero, 1 elsewhere."""
        z = self.zero_mass[k]
        with np.errstate(divide="ignore"):
            counts = np.log1p(-z) + super()._state_logpdf(k, x)  # type: ignore[misc]
            at_zero = np.logaddexp(np.log(z), counts)
        zero = x == 0
        return np.where(zero, at_zero, counts), np.where(zero, np.exp(counts - at_zero), 1.0)

    def _state_logpdf(self, k, x):
        return self._parts(k, x)[0]

    def _link_score(self, k, x):
        share = self._parts(k, x)[1]
        counts = super()._link_score(k, x) * share  # type: ignore[misc]
        return np.vstack([counts, (1.0 - share) - self.zero_mass[k]])

    def fit_weighted(self, x, w):
        """One step (``w`` (T, K)) of the inner EM of the class docstring from the current
        values: it raises the weighted log-likelihood (a generalised EM M-step), at the cost
        of one fit of the count family (iterating it to convergence in every M-step is far
        slower: reports/decisions.md, emission M-step)."""
        data = self.prepare(x)  # type: ignore[attr-defined]
        w = self._observed_weights(data, w)  # type: ignore[attr-defined]
        zero = data.observed == 0
        total = _column_sums(w)
        z = self.zero_mass
        count_family = super()
        f0 = np.exp([count_family._state_logpdf(k, np.zeros(1))[0] for k in range(self.n_states)])  # type: ignore[attr-defined]
        structural = z / np.maximum(z + (1.0 - z) * f0, np.finfo(float).tiny)
        counts = np.where(zero[:, None], w * (1.0 - structural), w)
        fitted = self._fit_states(count_family._fit_observed, counts, data.observed)  # type: ignore[attr-defined]
        share = _weighted_sums(zero.astype(float), w) * structural
        fitted["zero_mass"] = np.where(
            total > _MIN_STATE_WEIGHT, share / np.maximum(total, np.finfo(float).tiny), z
        )
        return self._replace(**fitted)  # type: ignore[attr-defined]

    @classmethod
    def initial(cls, x, w: np.ndarray):
        """Starting values: 20 steps of the inner EM from ``_start`` with weights ``w``."""
        member = super().initial(x, w)  # type: ignore[misc]
        for _ in range(19):
            member = member.fit_weighted(x, w)
        return member

    def _cdf_values(self, x):
        z = self.zero_mass
        return z + (1.0 - z) * super()._cdf_values(x)  # type: ignore[misc]

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one count per entry of ``states`` (n,) -> (n,) float."""
        out = super().sample(rng, states)  # type: ignore[misc]
        out[rng.random(out.size) < self.zero_mass[states]] = 0.0
        return out

    def expected_value(self) -> np.ndarray:
        """Mean count per state (K,), structural zeros included."""
        return (1.0 - self.zero_mass) * super().expected_value()  # type: ignore[misc]


@dataclass(frozen=True, eq=False)
class ZeroInflatedPoisson(_ZeroInflatedCounts, Poisson):
    """Zero-inflated Poisson counts (activity counts with a resting state of exact zeros).

    Parameters
    ----------
    rate : (K,) float > 0
        Mean of the Poisson part (log link).
    zero_mass : (K,) float in [0, 1]
        Probability of a structural zero (logit link).
    """

    zero_mass: np.ndarray

    name: ClassVar[str] = "zipoisson"
    _parameters: ClassVar[tuple[str, ...]] = ("rate", "zero_mass")
    _links: ClassVar[tuple[str, ...]] = ("log", "logit")
    _start: ClassVar[dict[str, float]] = {"rate": 1.0, "zero_mass": 0.2}


@dataclass(frozen=True, eq=False)
class ZeroInflatedNegativeBinomial(_ZeroInflatedCounts, NegativeBinomial):
    """Zero-inflated negative binomial counts (momentuHMM's mean/size and a zero mass).

    Parameters
    ----------
    mean, size : (K,) float > 0
        Of the negative binomial part (log links), as :class:`NegativeBinomial`.
    zero_mass : (K,) float in [0, 1]
        Probability of a structural zero (logit link).
    """

    zero_mass: np.ndarray

    name: ClassVar[str] = "zinegativebinomial"
    _parameters: ClassVar[tuple[str, ...]] = ("mean", "size", "zero_mass")
    _links: ClassVar[tuple[str, ...]] = ("log", "log", "logit")
    _start: ClassVar[dict[str, float]] = {"mean": 1.0, "size": 1.0, "zero_mass": 0.2}


@dataclass(frozen=True, eq=False)
class ZeroOneInflatedBeta(Beta):
    """Beta proportions with exact 0s and 1s (momentuHMM's zero and one inflation).

    ``P(x = 0) = zero_mass``, ``P(x = 1) = one_mass`` and the beta density times
    ``1 - zero_mass - one_mass`` in between. The two masses share a multinomial logit
    against the beta part (link ``log(mass / (1 - zero_mass - one_mass))``), so that every
    working vector is a valid member; a mass of a value the data never take tends to 0.

    Parameters
    ----------
    shape1, shape2 : (K,) float > 0
        The beta part's shapes (log links), as :class:`Beta`.
    zero_mass, one_mass : (K,) float >= 0, summing < 1
    """

    zero_mass: np.ndarray
    one_mass: np.ndarray

    name: ClassVar[str] = "zoibeta"
    _parameters: ClassVar[tuple[str, ...]] = ("shape1", "shape2", "zero_mass", "one_mass")
    _links: ClassVar[tuple[str, ...]] = ("log", "log", "mlogit", "mlogit")
    _support: ClassVar[str] = "in [0, 1]"
    _start: ClassVar[dict[str, float]] = {
        "shape1": 1.0,
        "shape2": 1.0,
        "zero_mass": 0.1,
        "one_mass": 0.1,
    }

    def _in_support(self, x):
        return (x >= 0) & (x <= 1)

    def _state_logpdf(self, k, x):
        zero, one = x == 0, x == 1
        inside = np.where(zero | one, 0.5, x)
        with np.errstate(divide="ignore"):
            log_masses = np.log(self.zero_mass[k]), np.log(self.one_mass[k])
            beta = np.log1p(-self._masses()[k]) + super()._state_logpdf(k, inside)
        return np.where(zero, log_masses[0], np.where(one, log_masses[1], beta))

    def _link_score(self, k, x):
        zero, one = x == 0, x == 1
        shapes = super()._link_score(k, np.where(zero | one, 0.5, x))
        shapes[:, zero | one] = 0.0
        return np.vstack([shapes, zero - self.zero_mass[k], one - self.one_mass[k]])

    def _fit_observed(self, x, w):
        total = _column_sums(w)
        inside = (x > 0) & (x < 1)
        masses = {
            "zero_mass": _weighted_means((x == 0).astype(float), w, total),
            "one_mass": _weighted_means((x == 1).astype(float), w, total),
        }
        # the beta part from the interior values; a state without any gets shapes 1
        usable = _column_sums(w[inside]) > _MIN_STATE_WEIGHT
        shapes = {"shape1": np.ones(w.shape[1]), "shape2": np.ones(w.shape[1])}
        if usable.any():
            fitted = super()._fit_observed(x[inside], w[inside][:, usable])
            for name, value in fitted.items():
                shapes[name][usable] = value
        return {**shapes, **masses}

    def _cdf_values(self, x):
        beta = super()._cdf_values(np.clip(x, 0.0, 1.0))
        out = self.zero_mass + (1.0 - self._masses()) * beta
        return np.where(x >= 1, 1.0, out)

    def _cdf_below_values(self, x):
        out = np.where(x == 0, 0.0, self._cdf_values(x))
        return np.where(x == 1, 1.0 - self.one_mass, out)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one value per entry of ``states`` (n,) -> (n,)."""
        out = super().sample(rng, states)
        u = rng.random(out.size)
        zero = u < self.zero_mass[states]
        one = ~zero & (u < self.zero_mass[states] + self.one_mass[states])
        out[zero], out[one] = 0.0, 1.0
        return out

    def expected_value(self) -> np.ndarray:
        """Mean per state (K,), the masses included."""
        return self.one_mass + (1.0 - self._masses()) * super().expected_value()


@dataclass(frozen=True, eq=False)
class Categorical(_ValueFamily):
    """Categorical observations: one of C categories per row, coded 1..C (a behaviour
    scored by an observer, a habitat class).

    Parameters
    ----------
    prob : (K, C) float
        Per state (row), the probability of each category; rows sum to 1. Links: the log
        ratio of categories 2..C to category 1 (multinomial logit, ``prob2`` ..
        ``probC``), so a formula such as ``"behaviour.prob2 ~ x"`` is a multinomial
        logistic regression of that category against the first.
    """

    prob: np.ndarray

    name: ClassVar[str] = "categorical"
    _parameters: ClassVar[tuple[str, ...]] = ("prob",)
    _support: ClassVar[str] = "whole numbers 1..C (the categories)"
    _lowest: ClassVar[float | None] = 1.0

    def __post_init__(self) -> None:
        try:
            prob = np.array(self.prob, dtype=float)
        except (TypeError, ValueError) as error:
            raise ValueError(
                f"Categorical.prob must be a (K, C) array, got {self.prob!r}"
            ) from error
        if prob.ndim != 2 or prob.shape[0] < 1 or prob.shape[1] < 2:
            raise ValueError(f"Categorical.prob must have shape (K, C), C >= 2, got {prob.shape}")
        if not np.isfinite(prob).all() or (prob < 0).any():
            raise ValueError(f"Categorical.prob must be finite and >= 0, got {prob}")
        if np.max(np.abs(prob.sum(axis=1) - 1.0)) > 1e-9:
            raise ValueError(f"Categorical.prob rows must sum to 1, got {prob.sum(axis=1)}")
        prob.setflags(write=False)
        object.__setattr__(self, "prob", prob)

    @property
    def n_states(self) -> int:
        """Number of states K."""
        return self.prob.shape[0]

    @property
    def n_categories(self) -> int:
        """Number of categories C."""
        return self.prob.shape[1]

    @classmethod
    def initial(cls, x, w: np.ndarray) -> Categorical:
        """Starting values: the weighted fit of ``x`` (T,) with weights ``w`` (T, K), with as
        many categories as the largest code in ``x``."""
        values = prepare_values(x)
        n_categories = max(int(np.max(values.observed, initial=2)), 2)
        start = cls(np.full((w.shape[1], n_categories), 1.0 / n_categories))
        return start.fit_weighted(values, w)

    def _in_support(self, x):
        return (x >= 1) & (x <= self.n_categories) & (x == np.floor(x))

    def _index(self, x: np.ndarray) -> np.ndarray:
        return np.clip(x.astype(int) - 1, 0, self.n_categories - 1)

    def _state_logpdf(self, k, x):
        chosen = (
            self.prob[k, self._index(x)]
            if isinstance(k, int)
            else (self.prob[np.arange(x.size), self._index(x)])
        )
        with np.errstate(divide="ignore"):
            return np.log(chosen)

    def _link_score(self, k, x):
        onehot = self._index(x)[None, :] == np.arange(1, self.n_categories)[:, None]
        prob = self.prob[k, 1:]
        return onehot - (prob[:, None] if isinstance(k, int) else prob.T)

    def _fit_observed(self, x, w):
        total = np.maximum(_column_sums(w), np.finfo(float).tiny)
        index = self._index(x)
        prob = np.column_stack(
            [
                _weighted_means((index == c).astype(float), w, total)
                for c in range(self.n_categories)
            ]
        )
        return {"prob": prob / prob.sum(axis=1, keepdims=True)}

    def _cdf_values(self, x):
        # state (or row) k's cumulative probability at category x[t, k]
        return np.cumsum(self.prob, axis=1)[np.arange(self.n_states), self._index(x)]

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one category (1..C) per entry of ``states`` (n,) -> (n,) float."""
        states = _check_states(states, self.n_states, type(self).__name__)
        cumulative = np.cumsum(self.prob[states], axis=1)
        below = rng.random(states.size)[:, None] >= cumulative[:, :-1]
        return 1.0 + below.sum(axis=1)

    def expected_value(self) -> np.ndarray:
        """Mean category code per state (K,): ``sum_c c * prob[k, c]``."""
        return self.prob @ np.arange(1.0, self.n_categories + 1)

    def link_names(self) -> tuple[str, ...]:
        """``prob2`` .. ``probC``: the log ratio of each category to the first."""
        return tuple(f"prob{c}" for c in range(2, self.n_categories + 1))

    def to_links(self) -> np.ndarray:
        """Log ratios of categories 2..C to category 1, (C - 1, K)."""
        log_prob = np.log(np.maximum(self.prob, _TINY))
        return (log_prob[:, 1:] - log_prob[:, :1]).T

    @classmethod
    def from_links(cls, eta: np.ndarray, n_categories: int | None = None) -> Categorical:
        """The member whose log ratios to category 1 are ``eta`` (C - 1, n); C is read from
        ``eta`` (``n_categories``, the structure of :meth:`with_working`, must agree)."""
        if n_categories is not None and n_categories != np.shape(eta)[0] + 1:
            raise ValueError(f"Categorical: {np.shape(eta)[0]} links for {n_categories} categories")
        eta = np.asarray(eta, dtype=float)
        logits = np.vstack([np.zeros((1, eta.shape[1])), eta]).T
        logits -= logits.max(axis=1, keepdims=True)
        prob = np.exp(logits)
        return cls(prob / prob.sum(axis=1, keepdims=True))

    @classmethod
    def from_working(cls, theta: np.ndarray, n_states: int, n_categories: int = 2) -> Categorical:
        """Inverse of :meth:`to_working` for ``n_states`` states and C categories."""
        blocks = _split_working(theta, n_states, n_categories - 1, cls.__name__)
        return cls.from_links(blocks)

    def _structure(self) -> dict[str, Any]:
        return {"n_categories": self.n_categories}
