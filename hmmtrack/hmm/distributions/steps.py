"""Step-length families: Gamma, Weibull, LogNormal, Exponential, with zero inflation.

Each family implements the density of strictly positive steps, its weighted maximum
likelihood and its working scale; ``_StepFamily`` adds what they share: missing values and
the optional point mass ``zero_mass`` (K,) at a step of exactly 0, which scales the density
for ``x > 0`` by ``1 - zero_mass`` (moveHMM's zero inflation). Steps are in the units of the
data (m, or km for the elk example), >= 0, NaN when missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import njit
from scipy import special

from hmmtrack.hmm.distributions.base import (
    _LOG_2PI,
    _MIN_STATE_WEIGHT,
    _NEWTON_MAX_ITER,
    _NEWTON_TOL,
    _TINY,
    D,
    PreparedSteps,
    _by_state,
    _check_states,
    _check_weights,
    _column_sums,
    _dot,
    _Family,
    _logit,
    _rows,
    _rows_where,
    _split_working,
    _weighted_means,
    _weighted_sums,
    prepare_steps,
)


class _StepFamily(_Family):
    """Base of step-length families (x >= 0, units of the data, e.g. m or km).

    Subclasses implement the density of strictly positive steps (``_state_logpdf``),
    its weighted MLE (``_fit_positive``), sampling and mean; this class adds missing
    values and the optional point mass ``zero_mass`` at exactly 0.
    """

    zero_mass: np.ndarray | None

    def _array_fields(self) -> tuple[str, ...]:
        return (*self._parameters, "zero_mass")

    def _validate(self) -> None:
        self._validate_positive_part()
        if self.zero_mass is not None:
            self._require("zero_mass", (self.zero_mass >= 0) & (self.zero_mass < 1), "in [0, 1)")

    def _validate_positive_part(self) -> None:
        for field in self._parameters:
            self._require(field, getattr(self, field) > 0, "> 0")

    # --- to be provided by each family ---------------------------------------------------
    def _state_logpdf(self, k: int, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        """Log-density (T,) of positive steps ``x`` in state ``k``."""
        raise NotImplementedError

    def _fit_positive(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> dict:
        raise NotImplementedError

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        """P(X <= x) of the positive part, elementwise: ``x`` and ``log_x`` broadcast against
        the parameters ((T, 1) against (K,), or (T,) against a row distribution's (T,))."""
        raise NotImplementedError

    def _sample_positive(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _expected_positive(self) -> np.ndarray:
        raise NotImplementedError

    @classmethod
    def from_moments(cls: type[D], mean: Any, sd: Any, zero_mass: Any = None) -> D:
        """Family member whose positive part has the given mean and sd (K,) (same units)."""
        raise NotImplementedError

    # --- shared -------------------------------------------------------------------------
    @property
    def zero_inflated(self) -> bool:
        """True when the distribution has a point mass at step 0."""
        return self.zero_mass is not None

    def prepare(self, x: np.ndarray) -> PreparedSteps:
        """:func:`prepare_steps` (the same object for every step family)."""
        return prepare_steps(x)

    def _prepared(self, x: np.ndarray | PreparedSteps) -> PreparedSteps:
        data = prepare_steps(x)
        if self.zero_mass is None and data.zero.any():
            raise ValueError(
                f"{type(self).__name__}: steps of exactly 0 at rows {_rows(data.zero)} need "
                "zero-inflation; construct the distribution with zero_mass=... (K,) to switch "
                "it on"
            )
        return data

    def logpdf(self, x: np.ndarray | PreparedSteps) -> np.ndarray:
        """Log-density of steps ``x`` (T,) in every state -> (T, K); NaN -> 0.0 row.

        With ``zero_mass`` z: ``log z`` at x == 0 and ``log(1 - z) + log f(x)`` for x > 0.
        ``x`` may be the output of :meth:`prepare` (faster when called repeatedly).
        """
        data = self._prepared(x)
        safe, log_safe = data.safe, data.log_safe
        if self.zero_mass is None:
            out = _by_state(
                data.n_obs, self.n_states, lambda k: self._state_logpdf(k, safe, log_safe)
            )
        else:
            positive_share = np.log1p(-self.zero_mass)
            out = _by_state(
                data.n_obs,
                self.n_states,
                lambda k: self._state_logpdf(k, safe, log_safe) + positive_share[k],
            )
            with np.errstate(divide="ignore"):
                out[data.zero] = np.log(self.zero_mass)
        out[data.missing] = 0.0
        return out

    def cdf(self, x: np.ndarray | PreparedSteps) -> np.ndarray:
        """P(step <= x) in every state -> (T, K), including the zero mass; NaN -> NaN row."""
        return self._cdf(self._prepared(x), (-1, 1))

    def row_cdf(self, x: np.ndarray | PreparedSteps) -> np.ndarray:
        """P(step <= x_t) (T,) under the parameters of "state" ``t`` (a row distribution,
        K = T), including the zero mass; missing rows NaN."""
        data = self._prepared(x)
        self._check_rows(data)
        return self._cdf(data, (-1,))

    def _cdf(self, data: PreparedSteps, shape: tuple[int, ...]) -> np.ndarray:
        """P(step <= x) with the steps reshaped to ``shape``: (T, 1) against the K states'
        parameters gives (T, K), (T,) against a row distribution's gives (T,)."""
        out = self._cdf_positive(data.safe.reshape(shape), data.log_safe.reshape(shape))
        if self.zero_mass is not None:
            z = self.zero_mass
            out = np.where(data.zero.reshape(shape), z, z + (1.0 - z) * out)
        return np.where(data.missing.reshape(shape), np.nan, out)

    def fit_weighted(self: D, x: np.ndarray | PreparedSteps, w: np.ndarray) -> D:
        """Weighted MLE per state: ``w[t, k]`` is the weight of row t for state k.

        NaN rows are ignored. ``zero_mass`` (if present) becomes the weighted share of
        exact zeros. A state with (almost) no weight on positive steps keeps its current
        parameters for the positive part. ``x`` may be the output of :meth:`prepare`.
        """
        data = self._prepared(x)
        w = _check_weights(w, data.n_obs, self.n_states, type(self).__name__)
        changes: dict[str, Any] = {}
        if self.zero_mass is not None:
            changes["zero_mass"] = self._zero_mass_of_sums(
                _weighted_sums((~data.missing).astype(float), w),
                _weighted_sums(data.zero.astype(float), w),
            )
        wp = w if data.positive_x is data.safe else _rows_where(data.positive, w)
        changes.update(
            self._fit_states(self._fit_positive, wp, data.positive_x, data.positive_log_x)
        )
        return self._replace(**changes)

    def _zero_mass_of_sums(self, total: np.ndarray, zeros: np.ndarray) -> np.ndarray:
        """Weighted share of exact zeros per state from the weights of the observed rows
        ``total`` and of the zero rows ``zeros`` (K,); a state without weight keeps its own."""
        share = zeros / np.maximum(total, np.finfo(float).tiny)
        return np.where(total > _MIN_STATE_WEIGHT, share, self.zero_mass)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one step per entry of ``states`` (n,) ints in [0, K) -> (n,)."""
        states = _check_states(states, self.n_states, type(self).__name__)
        out = self._sample_positive(rng, states)
        if self.zero_mass is not None:
            out[rng.random(states.size) < self.zero_mass[states]] = 0.0
        return out

    def expected_value(self) -> np.ndarray:
        """Expected step per state (K,), including the zero mass."""
        m = self._expected_positive()
        return m if self.zero_mass is None else (1.0 - self.zero_mass) * m

    def _structure(self) -> dict[str, Any]:
        return {"zero_inflated": self.zero_mass is not None}

    def to_working(self) -> np.ndarray:
        """Working vector: log of each positive parameter, then logit(zero_mass) if present.

        Laid out parameter-major: ``[p1_state1..p1_stateK, p2_state1.., (logit z)..]``.
        ``zero_mass`` is clipped to [1e-12, 1 - 1e-12] before the logit.
        """
        blocks = [self._positive_to_working()]
        if self.zero_mass is not None:
            blocks.append(_logit(self.zero_mass))
        return np.concatenate(blocks)

    def _positive_to_working(self) -> np.ndarray:
        return np.log(np.concatenate([getattr(self, f) for f in self._parameters]))

    def working_score(self, x: np.ndarray | PreparedSteps, w: np.ndarray) -> np.ndarray:
        """Gradient of ``sum(w * logpdf(x))`` w.r.t. :meth:`to_working`, shape (n_working,).

        ``x`` (T,) steps or :meth:`prepare` output, ``w`` (T, K) weights (posterior state
        probabilities). Closed form: per-state weighted sums of the positive steps' features
        for the positive part; for ``logit(zero_mass)`` ``(1 - z) W_zero - z W_positive``.
        """
        data = self._prepared(x)
        w = _check_weights(w, data.n_obs, self.n_states, type(self).__name__)
        wp = w if data.positive_x is data.safe else _rows_where(data.positive, w)
        blocks = [self._positive_score(data.positive_x, data.positive_log_x, wp)]
        if self.zero_mass is not None:
            zeros = _weighted_sums(data.zero.astype(float), w)
            blocks.append((1.0 - self.zero_mass) * zeros - self.zero_mass * _column_sums(wp))
        return np.concatenate(blocks)

    def _positive_score(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Working-scale gradient (n_parameters * K,) of ``sum(w * log f(x))``, x > 0."""
        raise NotImplementedError

    @classmethod
    def from_working(
        cls: type[D], theta: np.ndarray, n_states: int, zero_inflated: bool = False
    ) -> D:
        """Inverse of :meth:`to_working` for ``n_states`` states."""
        n_blocks = len(cls._parameters) + int(zero_inflated)  # type: ignore[attr-defined]
        blocks = _split_working(theta, n_states, n_blocks, cls.__name__)
        params = cls._positive_from_working(blocks[: len(cls._parameters)])  # type: ignore[attr-defined]
        zero_mass = special.expit(blocks[-1]) if zero_inflated else None
        return cls(**params, zero_mass=zero_mass)

    @classmethod
    def _positive_from_working(cls, blocks: np.ndarray) -> dict:
        return {f: np.exp(b) for f, b in zip(cls._parameters, blocks, strict=True)}  # type: ignore[attr-defined]

    # --- per-row view (covariate-dependent parameters, hmmtrack.hmm.emission) -------------
    def link_names(self) -> tuple[str, ...]:
        """The parameters in link order: the family's, then ``zero_mass`` if present."""
        return (*self._parameters, *(("zero_mass",) if self.zero_mass is not None else ()))

    def to_links(self) -> np.ndarray:
        """Each parameter on its link scale, shape (n_links, K): the working blocks (log of
        positive parameters, identity for the log-normal location, logit of ``zero_mass``)."""
        return self.to_working().reshape(-1, self.n_states)

    @classmethod
    def from_links(cls: type[D], eta: np.ndarray, zero_inflated: bool = False) -> D:
        """The member whose parameters on their link scale are ``eta`` (n_links, n)."""
        eta = np.asarray(eta, dtype=float)
        return cls.from_working(eta.ravel(), eta.shape[1], zero_inflated=zero_inflated)  # type: ignore[attr-defined]

    def _check_rows(self, data: PreparedSteps) -> None:
        if self.n_states != data.n_obs:
            raise ValueError(
                f"{type(self).__name__}: a row distribution needs one parameter set per row; "
                f"it has {self.n_states} for {data.n_obs} rows"
            )

    def row_logpdf(self, x: np.ndarray | PreparedSteps) -> np.ndarray:
        """Log-density (T,) of step ``t`` under the parameters of "state" ``t`` (a row
        distribution, K = T); missing rows 0.0, zero steps ``log zero_mass``."""
        data = self._prepared(x)
        self._check_rows(data)
        positive = self._state_logpdf(slice(None), data.safe, data.log_safe)  # type: ignore[arg-type]
        return self._row_value(data, positive)

    def _row_value(self, data: PreparedSteps, out: np.ndarray) -> np.ndarray:
        """Row log-densities from those of the positive part ``out`` (T, overwritten): the
        zero mass added, missing rows 0."""
        if self.zero_mass is not None:
            out += np.log1p(-self.zero_mass)
            with np.errstate(divide="ignore"):
                out[data.zero] = np.log(self.zero_mass[data.zero])
        out[data.missing] = 0.0
        return out

    def row_score(self, x: np.ndarray | PreparedSteps) -> np.ndarray:
        """Derivatives (n_links, T) of :meth:`row_logpdf` by each row's link values.

        The positive part's derivatives vanish on zero and missing rows; the zero mass's is
        ``1 - z`` at a zero step and ``-z`` at a positive one (logit link).
        """
        return self.row_derivatives(x)[1]

    def row_derivatives(
        self, x: np.ndarray | PreparedSteps
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`row_logpdf`, :meth:`row_score` and the second derivatives (n_links, n_links,
        T) of each row's log-density by its link values, all in closed form.

        The zero mass's second derivative is ``-z (1 - z)`` on every observed row; it has
        no cross term with the positive part's parameters.
        """
        data = self._prepared(x)
        self._check_rows(data)
        value, score, hessian = self._row_positive_derivatives(data.safe, data.log_safe)
        score[:, ~data.positive] = 0.0
        hessian[:, :, ~data.positive] = 0.0
        if self.zero_mass is not None:
            z = self.zero_mass
            by_zero = np.where(data.zero, 1.0 - z, -z)
            by_zero[data.missing] = 0.0
            score = np.vstack([score, by_zero])
            n = hessian.shape[0]
            padded = np.zeros((n + 1, n + 1, data.n_obs))
            padded[:n, :n] = hessian
            padded[n, n] = np.where(data.missing, 0.0, -z * (1.0 - z))
            hessian = padded
        return self._row_value(data, value), score, hessian

    def _row_positive_derivatives(
        self, x: np.ndarray, log_x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each row's ``log f(x_t)`` (T,) for x > 0 and its first (n_parameters, T) and
        second (n_parameters, n_parameters, T) derivatives by the row's link values."""
        raise NotImplementedError


@njit(cache=True, nogil=True)
def _digamma_trigamma(a: float) -> tuple[float, float]:
    """digamma(a) and trigamma(a) for a > 0, to about 1e-15 relative: the recurrences
    ``psi(a) = psi(a + 1) - 1/a``, ``psi'(a) = psi'(a + 1) + 1/a**2`` up to a >= 10, then
    the asymptotic series (their next terms are below 1e-16 there)."""
    psi, tri = 0.0, 0.0
    while a < 10.0:
        psi -= 1.0 / a
        tri += 1.0 / (a * a)
        a += 1.0
    inverse = 1.0 / a
    square = inverse * inverse
    psi += (
        math.log(a)
        - 0.5 * inverse
        - square
        * (1 / 12 - square * (1 / 120 - square * (1 / 252 - square * (1 / 240 - square / 132))))
    )
    tri += (
        inverse
        + 0.5 * square
        + inverse
        * square
        * (1 / 6 - square * (1 / 30 - square * (1 / 42 - square * (1 / 30 - square * 5 / 66))))
    )
    return psi, tri


@njit(cache=True, nogil=True)
def _gamma_row_derivatives(x, log_x, mean, sd):
    """Of gamma rows with their own ``mean`` and ``sd`` (T,) at steps ``x`` > 0 (T,): the
    log-density (T,), its derivatives by (log mean, log sd) (2, T) and its second
    derivatives (2, 2, T), in one compiled pass.

    Compiled because scipy's trigamma is far slower than the rest of a Newton step
    (reports/decisions.md, emission M-step).

    With shape a = (mean / sd)**2 and rate b = mean / sd**2: d a / d log mean = 2a,
    d b / d log mean = b, and d / d log sd = -2 d / d log mean for both; S = d log f / d a =
    log x + log b - digamma(a), so dS / d log mean = 1 - 2a trigamma(a).
    """
    n = x.size
    value = np.empty(n)
    score = np.empty((2, n))
    hessian = np.empty((2, 2, n))
    for t in range(n):
        ratio = mean[t] / sd[t]
        a = ratio * ratio
        b = ratio / sd[t]
        log_b = math.log(b)
        psi, tri = _digamma_trigamma(a)
        bx = b * x[t]
        value[t] = (a - 1.0) * log_x[t] - bx + a * log_b - math.lgamma(a)
        by_shape = 2.0 * a * (log_x[t] + log_b - psi)  # 2a S
        by_rate = a - bx
        score[0, t] = by_shape + by_rate
        score[1, t] = -by_shape - 2.0 * by_rate
        common = 2.0 * by_shape + 4.0 * a - 4.0 * a * a * tri
        hessian[0, 0, t] = common - bx
        hessian[0, 1, t] = hessian[1, 0, t] = -common - 2.0 * a + 2.0 * bx
        hessian[1, 1, t] = common + 4.0 * a - 4.0 * bx
    return value, score, hessian


def _gamma_shape_mle(s: np.ndarray) -> np.ndarray:
    """Solve ``log k - digamma(k) = s`` for the gamma shape k, (K,), by Newton from Minka's start.

    ``s = log(weighted mean of x) - weighted mean of log x`` (> 0 by Jensen; floored at 1e-12
    for degenerate data, which gives a very large but finite shape).
    """
    s = np.maximum(s, _TINY)
    k = (3.0 - s + np.sqrt((s - 3.0) ** 2 + 24.0 * s)) / (12.0 * s)
    for _ in range(_NEWTON_MAX_ITER):
        f = np.log(k) - special.digamma(k) - s
        fprime = 1.0 / k - special.zeta(2.0, k)  # trigamma: polygamma(1, k) without its wrapper
        k_new = k - f / fprime
        k_new = np.where(k_new > 0, k_new, k / 2.0)
        done = np.all(np.abs(k_new - k) <= _NEWTON_TOL * k_new)
        k = k_new
        if done:
            break
    return k


@dataclass(frozen=True, eq=False)
class Gamma(_StepFamily):
    """Gamma step lengths in moveHMM's mean/sd parametrisation.

    Parameters
    ----------
    mean, sd : (K,) float > 0
        Mean and standard deviation of the positive part, in the units of the steps.
        Shape ``(mean / sd)**2``, scale ``sd**2 / mean``.
    zero_mass : (K,) float in [0, 1) or None
        Probability of a step of exactly 0 (zero-inflation); None switches it off.
    """

    mean: np.ndarray
    sd: np.ndarray
    zero_mass: np.ndarray | None = None

    name: ClassVar[str] = "gamma"
    _parameters: ClassVar[tuple[str, ...]] = ("mean", "sd")

    @property
    def shape(self) -> np.ndarray:
        """Gamma shape k = (mean / sd)**2, (K,)."""
        return (self.mean / self.sd) ** 2

    @property
    def scale(self) -> np.ndarray:
        """Gamma scale theta = sd**2 / mean, (K,), units of the steps."""
        return self.sd**2 / self.mean

    @classmethod
    def from_moments(cls, mean: Any, sd: Any, zero_mass: Any = None) -> Gamma:
        """Gamma with the given mean and sd (K,) of its positive part."""
        return cls(mean=mean, sd=sd, zero_mass=zero_mass)

    def _state_logpdf(self, k: int, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        shape = self.shape[k]
        rate = self.mean[k] / self.sd[k] ** 2
        return (shape - 1.0) * log_x - rate * x + (shape * np.log(rate) - special.gammaln(shape))

    def _fit_positive(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> dict:
        return self._fit_positive_sums(
            _column_sums(w), _weighted_sums(x, w), _weighted_sums(log_x, w)
        )

    @staticmethod
    def _fit_positive_sums(total: np.ndarray, sum_x: np.ndarray, sum_log_x: np.ndarray) -> dict:
        """Weighted MLE from the sufficient statistics (K,): total weight, sum of w x and of
        w log x over the positive steps."""
        tiny = np.finfo(float).tiny
        mean = sum_x / np.maximum(total, tiny)
        mean_log = sum_log_x / np.maximum(total, tiny)
        k = _gamma_shape_mle(np.log(mean) - mean_log)
        return {"mean": mean, "sd": mean / np.sqrt(k)}

    def _positive_score(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> np.ndarray:
        # log f = (a - 1) log x - b x + a log b - gammaln(a), shape a = exp(2u - 2v), rate
        # b = exp(u - 2v) with u = log mean, v = log sd: da/du = 2a, db/du = b, d./dv = -2 d./du
        # for a and b alike; d log f / da = log x + log b - digamma(a), d log f / db = a/b - x
        a, b = self.shape, self.mean / self.sd**2
        total = _column_sums(w)
        by_shape = 2.0 * a * (_weighted_sums(log_x, w) + total * (np.log(b) - special.digamma(a)))
        by_rate = a * total - b * _weighted_sums(x, w)
        return np.concatenate([by_shape + by_rate, -by_shape - 2.0 * by_rate])

    def _row_positive_derivatives(self, x, log_x):
        return _gamma_row_derivatives(x, log_x, self.mean, self.sd)

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return special.gammainc(self.shape, x / self.scale)

    def _sample_positive(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return rng.gamma(self.shape[states], self.scale[states])

    def _expected_positive(self) -> np.ndarray:
        return self.mean.copy()


def _weibull_state_mle(y: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """Weighted Weibull MLE of one state from ``y = log x - c`` (T,): (shape, log scale - c).

    Newton on the profile equation ``1/k + mean_w(y) - sum(w y e^{ky}) / sum(w e^{ky}) = 0``
    (decreasing in k), started from the log-Weibull variance ``pi^2 / (6 k^2)``; then
    ``log scale = log(sum(w e^{ky}) / sum(w)) / k``.
    """
    total = w.sum()
    mean_y = _dot(y, w) / total
    var_y = max(_dot(y**2, w) / total - mean_y**2, _TINY)
    k = np.pi / np.sqrt(6.0 * var_y)
    y2 = y**2
    for _ in range(_NEWTON_MAX_ITER):
        e = np.exp(k * y) * w
        b = e.sum()
        a, c = _dot(y, e) / b, _dot(y2, e) / b
        k_new = k - (1.0 / k + mean_y - a) / (-1.0 / k**2 - (c - a**2))
        k_new = k_new if k_new > 0 else k / 2.0
        done = abs(k_new - k) <= _NEWTON_TOL * k_new
        k = k_new
        if done:
            break
    return float(k), float(np.log(_dot(np.exp(k * y), w) / total) / k)


@dataclass(frozen=True, eq=False)
class Weibull(_StepFamily):
    """Weibull step lengths, density ``(k/l) (x/l)**(k-1) exp(-(x/l)**k)``.

    Parameters
    ----------
    shape : (K,) float > 0
        Shape k (dimensionless).
    scale : (K,) float > 0
        Scale l, in the units of the steps.
    zero_mass : (K,) float in [0, 1) or None
        Probability of a step of exactly 0; None switches zero-inflation off.
    """

    shape: np.ndarray
    scale: np.ndarray
    zero_mass: np.ndarray | None = None

    name: ClassVar[str] = "weibull"
    _parameters: ClassVar[tuple[str, ...]] = ("shape", "scale")

    @classmethod
    def from_moments(cls, mean: Any, sd: Any, zero_mass: Any = None) -> Weibull:
        """Weibull with approximately the given mean and sd (K,) (Justus' shape formula).

        Shape ``k = (sd / mean) ** -1.086`` clipped to [0.1, 50], then scale
        ``mean / Gamma(1 + 1/k)`` so the mean is exact; meant for starting values.
        """
        mean, sd = np.asarray(mean, dtype=float), np.asarray(sd, dtype=float)
        shape = np.clip((sd / mean) ** -1.086, 0.1, 50.0)
        return cls(shape=shape, scale=mean / special.gamma(1.0 + 1.0 / shape), zero_mass=zero_mass)

    def _state_logpdf(self, k: int, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        shape = self.shape[k]
        z = shape * (log_x - np.log(self.scale[k]))  # log (x / l)^k
        return z - np.exp(z) - log_x + np.log(shape)

    def _fit_positive(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> dict:
        shift = log_x.max()
        y = log_x - shift  # <= 0: scale invariance keeps exp(k y) from overflowing
        fits = [_weibull_state_mle(y, np.ascontiguousarray(w[:, k])) for k in range(w.shape[1])]
        shape, log_scale = np.array(fits).T
        return {"shape": shape, "scale": np.exp(shift + log_scale)}

    def _positive_score(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> np.ndarray:
        # log f = z - exp(z) - log x + log k with z = k (log x - log l):
        # d/d log k = 1 + z (1 - e^z), d/d log l = k (e^z - 1)
        n_states = self.n_states
        by_shape, by_scale = np.empty(n_states), np.empty(n_states)
        for k in range(n_states):
            z = self.shape[k] * (log_x - np.log(self.scale[k]))
            excess = np.expm1(z)  # e^z - 1
            by_shape[k] = w[:, k].sum() - _dot(z * excess, w[:, k])
            by_scale[k] = self.shape[k] * _dot(excess, w[:, k])
        return np.concatenate([by_shape, by_scale])

    def _row_positive_derivatives(self, x, log_x):
        # z depends on log k as z and on log l as -k
        k = self.shape
        z = k * (log_x - np.log(self.scale))
        excess = np.expm1(z)  # e^z - 1
        growth = excess + z * (excess + 1.0)  # e^z - 1 + z e^z
        hessian = np.empty((2, 2, x.size))
        hessian[0, 0] = -z * growth
        hessian[0, 1] = hessian[1, 0] = k * growth
        hessian[1, 1] = -(k**2) * (excess + 1.0)
        value = self._state_logpdf(slice(None), x, log_x)  # type: ignore[arg-type]
        return value, np.vstack([1.0 - z * excess, k * excess]), hessian

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        z = log_x * self.shape - self.shape * np.log(self.scale)
        return -np.expm1(-np.exp(z))

    def _sample_positive(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return self.scale[states] * rng.weibull(self.shape[states])

    def _expected_positive(self) -> np.ndarray:
        return self.scale * special.gamma(1.0 + 1.0 / self.shape)


@dataclass(frozen=True, eq=False)
class LogNormal(_StepFamily):
    """Log-normal step lengths: ``log x ~ Normal(location, scale**2)``.

    Parameters
    ----------
    location : (K,) float
        Mean of log step (log of the units of the steps).
    scale : (K,) float > 0
        Standard deviation of log step.
    zero_mass : (K,) float in [0, 1) or None
        Probability of a step of exactly 0; None switches zero-inflation off.
    """

    location: np.ndarray
    scale: np.ndarray
    zero_mass: np.ndarray | None = None

    name: ClassVar[str] = "lognormal"
    _parameters: ClassVar[tuple[str, ...]] = ("location", "scale")

    def _validate_positive_part(self) -> None:
        self._require("scale", self.scale > 0, "> 0")

    def _positive_to_working(self) -> np.ndarray:
        return np.concatenate([self.location, np.log(self.scale)])

    @classmethod
    def _positive_from_working(cls, blocks: np.ndarray) -> dict:
        return {"location": blocks[0].copy(), "scale": np.exp(blocks[1])}

    @classmethod
    def from_moments(cls, mean: Any, sd: Any, zero_mass: Any = None) -> LogNormal:
        """Log-normal with exactly the given mean and sd (K,) of the steps."""
        mean, sd = np.asarray(mean, dtype=float), np.asarray(sd, dtype=float)
        var_log = np.log1p((sd / mean) ** 2)
        return cls(location=np.log(mean) - var_log / 2, scale=np.sqrt(var_log), zero_mass=zero_mass)

    def _state_logpdf(self, k: int, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        z = (log_x - self.location[k]) / self.scale[k]
        return -0.5 * z**2 - log_x - (np.log(self.scale[k]) + 0.5 * _LOG_2PI)

    def _fit_positive(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> dict:
        total = _column_sums(w)
        location = _weighted_means(log_x, w, total)
        var = _weighted_means(log_x**2, w, total) - location**2
        return {"location": location, "scale": np.sqrt(np.maximum(var, _TINY))}

    def _positive_score(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> np.ndarray:
        # z = (log x - location) / scale: d/d location = z / scale, d/d log scale = z^2 - 1
        total, sum_log = _column_sums(w), _weighted_sums(log_x, w)
        first = sum_log - self.location * total  # sum w (log x - location)
        second = (  # sum w (log x - location)^2
            _weighted_sums(log_x**2, w) - 2.0 * self.location * sum_log + self.location**2 * total
        )
        variance = self.scale**2
        return np.concatenate([first / variance, second / variance - total])

    def _row_positive_derivatives(self, x, log_x):
        z = (log_x - self.location) / self.scale
        hessian = np.empty((2, 2, x.size))
        hessian[0, 0] = -1.0 / self.scale**2
        hessian[0, 1] = hessian[1, 0] = -2.0 * z / self.scale
        hessian[1, 1] = -2.0 * z**2
        value = self._state_logpdf(slice(None), x, log_x)  # type: ignore[arg-type]
        return value, np.vstack([z / self.scale, z**2 - 1.0]), hessian

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return special.ndtr((log_x - self.location) / self.scale)

    def _sample_positive(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return rng.lognormal(self.location[states], self.scale[states])

    def _expected_positive(self) -> np.ndarray:
        return np.exp(self.location + self.scale**2 / 2)


@dataclass(frozen=True, eq=False)
class Exponential(_StepFamily):
    """Exponential step lengths, density ``rate * exp(-rate * x)``.

    Parameters
    ----------
    rate : (K,) float > 0
        Rate, in 1 / (units of the steps).
    zero_mass : (K,) float in [0, 1) or None
        Probability of a step of exactly 0; None switches zero-inflation off.
    """

    rate: np.ndarray
    zero_mass: np.ndarray | None = None

    name: ClassVar[str] = "exponential"
    _parameters: ClassVar[tuple[str, ...]] = ("rate",)

    @classmethod
    def from_moments(cls, mean: Any, sd: Any = None, zero_mass: Any = None) -> Exponential:
        """Exponential with the given mean (K,); ``sd`` is ignored (it equals the mean)."""
        return cls(rate=1.0 / np.asarray(mean, dtype=float), zero_mass=zero_mass)

    def _state_logpdf(self, k: int, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return np.log(self.rate[k]) - self.rate[k] * x

    def _fit_positive(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> dict:
        return {"rate": 1.0 / _weighted_means(x, w, _column_sums(w))}

    def _positive_score(self, x: np.ndarray, log_x: np.ndarray, w: np.ndarray) -> np.ndarray:
        # d/d log rate of (log rate - rate x) = 1 - rate x
        return _column_sums(w) - self.rate * _weighted_sums(x, w)

    def _row_positive_derivatives(self, x, log_x):
        rx = self.rate * x
        return np.log(self.rate) - rx, (1.0 - rx)[None, :], -rx[None, None, :]

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return -np.expm1(x * -self.rate)

    def _sample_positive(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return rng.exponential(1.0 / self.rate[states])

    def _expected_positive(self) -> np.ndarray:
        return 1.0 / self.rate
