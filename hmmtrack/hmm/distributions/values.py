"""Families of further data streams: Normal, Beta, Poisson, NegativeBinomial, Bernoulli.

A movement HMM's steps and turning angles can be joined by other observations per row, each
with its own family: a dive depth (normal), a proportion of time at the surface (beta),
activity counts (Poisson, negative binomial), a dive or no dive (Bernoulli). Each family
follows the emission protocol of :mod:`.base` on :class:`PreparedValues` (validated once,
missing rows NaN); ``_ValueFamily`` holds what they share. A family gives the log-density
and the derivatives of its parameters' link values for a state index or for every row at
once (``_state_logpdf(k, x)`` and ``_link_score(k, x)`` with ``k`` an int or
``slice(None)``), from which the weighted score, the row view and the working scale follow.
Links: log for positive parameters, identity for the normal mean, logit for the Bernoulli
probability.

Not for step lengths or turning angles (:mod:`.steps`, :mod:`.angles`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy import optimize, special, stats

from hmmtrack.hmm.distributions.base import (
    _LOG_2PI,
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

    _links: ClassVar[tuple[str, ...]]  # per parameter: "log", "identity" or "logit"
    _support: ClassVar[str]  # what the observations must be, for error messages
    _start: ClassVar[dict[str, float]]  # parameter values before a first weighted fit

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
        data = self.prepare(x)
        out = self._cdf_values(data.safe)
        out[data.missing] = np.nan
        return out

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
        blocks = np.empty((len(self._parameters), self.n_states))
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
        for field, link, block in zip(cls._parameters, cls._links, eta, strict=True):  # type: ignore[attr-defined]
            if link == "log":
                values[field] = np.exp(block)
            elif link == "logit":
                values[field] = special.expit(block)
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
        return special.ndtr(np.subtract.outer(x, self.mean) / self.sd)

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
    _support: ClassVar[str] = "in (0, 1)"
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
        return special.betainc(self.shape1, self.shape2, x[:, None])

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
        return stats.poisson.cdf(x[:, None], self.rate)

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
        Poisson limit, size 1e8)."""
        total = _column_sums(w)
        mean = np.maximum(_weighted_means(x, w, total), _TINY)
        variance = _weighted_means(x**2, w, total) - mean**2
        size = np.full_like(mean, _MAX_SIZE)
        for k in range(w.shape[1]):
            if variance[k] <= mean[k] * (1.0 + 1e-9):
                continue
            weights = w[:, k]

            def profile(log_r, k=k, weights=weights):  # the size score at the mean's MLE
                r = np.exp(log_r)
                digammas = special.digamma(x + r) - special.digamma(r)
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
        return stats.nbinom.cdf(x[:, None], self.size, self.size / (self.size + self.mean))

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
        return np.where(x[:, None] >= 1, 1.0, 1.0 - self.prob)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one 0 / 1 per entry of ``states`` (n,) -> (n,) float."""
        states = _check_states(states, self.n_states, type(self).__name__)
        return (rng.random(states.size) < self.prob[states]).astype(float)

    def expected_value(self) -> np.ndarray:
        """Probability of a 1 per state (K,)."""
        return self.prob.copy()
