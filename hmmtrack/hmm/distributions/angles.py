"""Turning-angle families: VonMises and WrappedCauchy.

Both are circular distributions on (-pi, pi] (rad) whose density depends on
``cos(x - mean)`` only; ``_AngleFamily`` holds what they share: the mean direction, either
estimated or fixed at 0 (``estimate_mean``), prepared angles (cos and sin computed once), the
inverse-CDF-free sampling by deviation from the mean, and moveHMM's polar working scale.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy import special, stats

from hmmtrack.hmm.distributions.base import (
    _LOG_2PI,
    _NEWTON_MAX_ITER,
    _NEWTON_TOL,
    _TINY,
    D,
    PreparedAngles,
    _by_state,
    _check_states,
    _check_weights,
    _column_sums,
    _dot,
    _Family,
    _rows_where,
    _split_working,
    _weighted_sums,
    prepare_angles,
)
from hmmtrack.tracks import wrap_angle

_MAX_CONCENTRATION = 1e8
_MAX_WRAPPED_CAUCHY_RHO = 1.0 - 1e-9


class _AngleFamily(_Family):
    """Base of circular families on (-pi, pi] with a mean direction and a concentration.

    Both families' densities depend on ``cos(x - mean)`` only. The mean is estimated, or
    fixed at 0 when ``estimate_mean`` is False. Working scale (moveHMM's): with the mean
    estimated ``(r cos mean, r sin mean)``, otherwise ``log r``, where ``r`` is a family
    specific non-negative transform of the concentration (``_radial``).
    """

    mean: np.ndarray
    concentration: np.ndarray
    estimate_mean: bool

    _parameters: ClassVar[tuple[str, ...]] = ("mean", "concentration")

    def _validate(self) -> None:
        if not isinstance(self.estimate_mean, bool | np.bool_):
            raise ValueError(
                f"{type(self).__name__}.estimate_mean must be True or False, "
                f"got {self.estimate_mean!r}"
            )
        object.__setattr__(self, "estimate_mean", bool(self.estimate_mean))
        if not self.estimate_mean:
            self._require("mean", self.mean == 0, "all 0 when estimate_mean is False")
        mean = wrap_angle(self.mean)
        mean.setflags(write=False)
        object.__setattr__(self, "mean", mean)
        self._validate_concentration()

    # --- to be provided by each family ---------------------------------------------------
    def _validate_concentration(self) -> None:
        raise NotImplementedError

    def _state_logpdf_cos(self, k: int, cos_dev: np.ndarray) -> np.ndarray:
        """Log-density (T,) in state ``k`` given ``cos(x - mean[k])`` (T,)."""
        raise NotImplementedError

    def _fit_angles(self, cos_x: np.ndarray, sin_x: np.ndarray, w: np.ndarray) -> dict:
        """Weighted MLE ``{"mean": (K,), "concentration": (K,)}`` (mean 0 if fixed)."""
        raise NotImplementedError

    def _sample_deviation(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _unwrapped_cdf(self, y: np.ndarray) -> np.ndarray:
        """Cumulative mass from an arbitrary origin, growing by 1 per 2 pi of ``y``,
        elementwise with ``y`` broadcast against the parameters."""
        raise NotImplementedError

    def _polar_score(self, cos_x, sin_x, w) -> tuple[np.ndarray, np.ndarray]:
        """Gradient of ``sum(w * logpdf)`` in polar working coordinates, two (K,) arrays.

        ``(d/dr, (1/r) d/dmean)`` with ``r = _radial(concentration)``; the second is finite
        at ``r = 0``.
        """
        raise NotImplementedError

    @classmethod
    def _radial(cls, concentration: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    @classmethod
    def _radial_inverse(cls, r: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    @classmethod
    def from_mean_resultant(
        cls: type[D], mean: Any, mean_resultant_length: Any, estimate_mean: bool = True
    ) -> D:
        """Family member whose mean resultant length E[cos(x - mean)] is given (K,)."""
        raise NotImplementedError

    # --- shared -------------------------------------------------------------------------
    def prepare(self, x: np.ndarray) -> PreparedAngles:
        """:func:`prepare_angles` (the same object for every angle family)."""
        return prepare_angles(x)

    def logpdf(self, x: np.ndarray | PreparedAngles) -> np.ndarray:
        """Log-density of turning angles ``x`` (T,) rad in every state -> (T, K); NaN -> 0.0.

        ``x`` may be the output of :meth:`prepare` (faster when called repeatedly).
        """
        data = prepare_angles(x)
        cos_mean, sin_mean = np.cos(self.mean), np.sin(self.mean)

        def column(k: int) -> np.ndarray:
            cos_dev = data.cos * cos_mean[k]
            if self.estimate_mean:
                cos_dev += data.sin * sin_mean[k]
            return self._state_logpdf_cos(k, cos_dev)

        out = _by_state(data.n_obs, self.n_states, column)
        out[data.missing] = 0.0
        return out

    def cdf(self, x: np.ndarray | PreparedAngles) -> np.ndarray:
        """P(-pi < angle <= x) in every state -> (T, K), x wrapped to (-pi, pi]; NaN -> NaN."""
        return self._cdf(prepare_angles(x).angle[:, None])

    def row_cdf(self, x: np.ndarray | PreparedAngles) -> np.ndarray:
        """P(-pi < angle <= x_t) (T,) under the parameters of "state" ``t`` (a row
        distribution, K = T); missing rows NaN."""
        data = self._row_deviations(x)[0]
        return self._cdf(data.angle)

    def _cdf(self, angle: np.ndarray) -> np.ndarray:
        """P(-pi < angle <= x) of wrapped angles broadcast against the parameters ((T, 1)
        against (K,), or (T,) against a row distribution's (T,))."""
        return self._unwrapped_cdf(angle) - self._unwrapped_cdf(np.full(1, -np.pi))

    def fit_weighted(self: D, x: np.ndarray | PreparedAngles, w: np.ndarray) -> D:
        """Weighted MLE per state (``w`` (T, K)); NaN rows ignored; mean kept at 0 if fixed.

        A state with (almost) no weight keeps its current parameters. ``x`` may be the
        output of :meth:`prepare`.
        """
        data = prepare_angles(x)
        w = _check_weights(w, data.n_obs, self.n_states, type(self).__name__)
        if data.observed_cos is not data.cos:
            w = _rows_where(~data.missing, w)
        fitted = self._fit_states(self._fit_angles, w, data.observed_cos, data.observed_sin)
        return self._replace(**fitted)

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        """Draw one angle (rad, in (-pi, pi]) per entry of ``states`` (n,) -> (n,)."""
        states = _check_states(states, self.n_states, type(self).__name__)
        return wrap_angle(self.mean[states] + self._sample_deviation(rng, states))

    def expected_value(self) -> np.ndarray:
        """Mean direction per state (K,), rad."""
        return self.mean.copy()

    def _trigonometric_moments(self, total, sum_cos, sum_sin) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean direction (0 if fixed) and E[cos(x - direction)] per state, (K,), from
        the total weight and the weighted sums of cos and sin per state, (K,) each."""
        tiny = np.finfo(float).tiny
        c, s = sum_cos / np.maximum(total, tiny), sum_sin / np.maximum(total, tiny)
        if self.estimate_mean:
            return np.arctan2(s, c), np.hypot(c, s)
        return np.zeros_like(c), c

    def _structure(self) -> dict[str, Any]:
        return {"estimate_mean": self.estimate_mean}

    def working_score(self, x: np.ndarray | PreparedAngles, w: np.ndarray) -> np.ndarray:
        """Gradient of ``sum(w * logpdf(x))`` w.r.t. :meth:`to_working`, shape (n_working,).

        ``x`` (T,) angles (rad) or :meth:`prepare` output, ``w`` (T, K) weights. The family
        gives the polar derivatives (``_polar_score``); this maps them to the Cartesian
        working coordinates ``(r cos mean, r sin mean)``, or to ``log r`` with a fixed mean.
        """
        data = prepare_angles(x)
        w = _check_weights(w, data.n_obs, self.n_states, type(self).__name__)
        if data.observed_cos is not data.cos:
            w = _rows_where(~data.missing, w)
        radial, tangential = self._polar_score(data.observed_cos, data.observed_sin, w)
        if self.estimate_mean:
            c, s = np.cos(self.mean), np.sin(self.mean)
            return np.concatenate([c * radial - s * tangential, s * radial + c * tangential])
        return self._radial(self.concentration) * radial

    def to_working(self) -> np.ndarray:
        """Working vector: ``[r cos mean (K), r sin mean (K)]`` or ``log r`` (K) if fixed."""
        r = self._radial(self.concentration)
        if self.estimate_mean:
            return np.concatenate([r * np.cos(self.mean), r * np.sin(self.mean)])
        return np.log(np.maximum(r, _TINY))

    @classmethod
    def from_working(
        cls: type[D], theta: np.ndarray, n_states: int, estimate_mean: bool = True
    ) -> D:
        """Inverse of :meth:`to_working` for ``n_states`` states."""
        blocks = _split_working(theta, n_states, 2 if estimate_mean else 1, cls.__name__)
        if estimate_mean:
            mean = np.arctan2(blocks[1], blocks[0])
            r = np.hypot(blocks[0], blocks[1])
        else:
            mean, r = np.zeros(n_states), np.exp(blocks[0])
        return cls(mean, cls._radial_inverse(r), estimate_mean)  # type: ignore[attr-defined]

    # --- per-row view (covariate-dependent parameters, hmmtrack.hmm.emission) -------------
    def link_names(self) -> tuple[str, ...]:
        """``("mean", "concentration")``, or ``("concentration",)`` with the mean fixed."""
        return ("mean", "concentration") if self.estimate_mean else ("concentration",)

    def to_links(self) -> np.ndarray:
        """Parameters on their link scale (n_links, K): the mean as it is (rad), the
        concentration through the family's link (:meth:`_concentration_link`)."""
        links = [self._concentration_link(self.concentration)]
        return np.vstack([self.mean, *links] if self.estimate_mean else links)

    @classmethod
    def from_links(cls: type[D], eta: np.ndarray, estimate_mean: bool = True) -> D:
        """The member whose parameters on their link scale are ``eta`` (n_links, n)."""
        eta = np.asarray(eta, dtype=float)
        mean = eta[0] if estimate_mean else np.zeros(eta.shape[1])
        return cls(mean, cls._concentration_from_link(eta[-1]), estimate_mean)  # type: ignore[attr-defined]

    def _row_deviations(self, x: np.ndarray | PreparedAngles):
        data = prepare_angles(x)
        if self.n_states != data.n_obs:
            raise ValueError(
                f"{type(self).__name__}: a row distribution needs one parameter set per row; "
                f"it has {self.n_states} for {data.n_obs} rows"
            )
        cos_mean, sin_mean = np.cos(self.mean), np.sin(self.mean)
        cos_dev = data.cos * cos_mean + data.sin * sin_mean
        sin_dev = data.sin * cos_mean - data.cos * sin_mean
        return data, cos_dev, sin_dev

    def row_logpdf(self, x: np.ndarray | PreparedAngles) -> np.ndarray:
        """Log-density (T,) of angle ``t`` under the parameters of "state" ``t`` (a row
        distribution, K = T); missing rows 0.0."""
        data, cos_dev, _ = self._row_deviations(x)
        out = self._state_logpdf_cos(slice(None), cos_dev)  # type: ignore[arg-type]
        out[data.missing] = 0.0
        return out

    def row_score(self, x: np.ndarray | PreparedAngles) -> np.ndarray:
        """Derivatives (n_links, T) of :meth:`row_logpdf` by each row's link values."""
        data, cos_dev, sin_dev = self._row_deviations(x)
        by_mean, by_concentration = self._row_angle_score(cos_dev, sin_dev)
        blocks = np.vstack(
            [by_mean, by_concentration] if self.estimate_mean else [by_concentration]
        )
        blocks[:, data.missing] = 0.0
        return blocks

    def _row_angle_score(self, cos_dev, sin_dev) -> tuple[np.ndarray, np.ndarray]:
        """Derivatives (T,) of each row's log-density by its mean and its linked
        concentration, given ``cos(x - mean)`` and ``sin(x - mean)`` (T,)."""
        raise NotImplementedError

    @classmethod
    def _concentration_link(cls, concentration: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    @classmethod
    def _concentration_from_link(cls, eta: np.ndarray) -> np.ndarray:
        raise NotImplementedError


def _a1(kappa: np.ndarray) -> np.ndarray:
    """Mean resultant length of a von Mises: I1(kappa) / I0(kappa)."""
    return special.i1e(kappa) / special.i0e(kappa)


def _a1_inverse(r: np.ndarray) -> np.ndarray:
    """Von Mises concentration with mean resultant length ``r`` (K,) in [0, 1).

    Best & Fisher's (1981) approximation refined by Newton on ``A1(kappa) = r`` with
    ``A1'(kappa) = 1 - A1/kappa - A1**2``; ``r <= 0`` gives 0, the result is capped at 1e8.
    """
    r = np.clip(np.asarray(r, dtype=float), 0.0, 1.0 - 1e-15)
    with np.errstate(divide="ignore"):
        kappa = np.where(
            r < 0.53,
            2 * r + r**3 + 5 * r**5 / 6,
            np.where(r < 0.85, -0.4 + 1.39 * r + 0.43 / (1 - r), 1 / (r**3 - 4 * r**2 + 3 * r)),
        )
    kappa = np.clip(kappa, 0.0, _MAX_CONCENTRATION)
    for _ in range(_NEWTON_MAX_ITER):
        a = _a1(kappa)
        safe = np.maximum(kappa, _TINY)
        slope = np.where(kappa > _TINY, 1.0 - a / safe - a**2, 0.5)
        k_new = np.clip(kappa - (a - r) / slope, 0.0, _MAX_CONCENTRATION)
        k_new = np.where(k_new > 0, k_new, kappa / 2.0)
        done = np.all(np.abs(k_new - kappa) <= _NEWTON_TOL * np.maximum(k_new, 1.0))
        kappa = k_new
        if done:
            break
    return np.where(r > 0, kappa, 0.0)


@dataclass(frozen=True, eq=False)
class VonMises(_AngleFamily):
    """Von Mises turning angles, density ``exp(kappa cos(x - mean)) / (2 pi I0(kappa))``.

    Parameters
    ----------
    mean : (K,) float
        Mean direction (rad), wrapped to (-pi, pi]; all 0 when ``estimate_mean`` is False.
    concentration : (K,) float >= 0
        Concentration kappa (dimensionless); 0 is the uniform distribution.
    estimate_mean : bool
        Whether ``fit_weighted`` estimates the mean (True) or keeps it at 0.
    """

    mean: np.ndarray
    concentration: np.ndarray
    estimate_mean: bool = True

    name: ClassVar[str] = "vonmises"

    def _validate_concentration(self) -> None:
        self._require("concentration", self.concentration >= 0, ">= 0")

    @classmethod
    def from_mean_resultant(
        cls, mean: Any, mean_resultant_length: Any, estimate_mean: bool = True
    ) -> VonMises:
        """Von Mises whose mean resultant length A1(kappa) is given (K,)."""
        return cls(mean, _a1_inverse(mean_resultant_length), estimate_mean)

    def _state_logpdf_cos(self, k: int, cos_dev: np.ndarray) -> np.ndarray:
        kappa = self.concentration[k]
        return kappa * cos_dev - (_LOG_2PI + np.log(special.i0e(kappa)) + kappa)

    def _fit_angles(self, cos_x, sin_x, w):
        return self._fit_angle_sums(
            _column_sums(w), _weighted_sums(cos_x, w), _weighted_sums(sin_x, w)
        )

    def _fit_angle_sums(self, total, sum_cos, sum_sin) -> dict:
        """Weighted MLE from the sufficient statistics (K,): total weight of the observed
        angles and the weighted sums of their cos and sin."""
        mean, resultant = self._trigonometric_moments(total, sum_cos, sum_sin)
        return {"mean": mean, "concentration": _a1_inverse(resultant)}

    def _polar_score(self, cos_x, sin_x, w) -> tuple[np.ndarray, np.ndarray]:
        # log f = kappa cos(x - mean) - log I0(kappa) - log 2 pi, r = kappa:
        # d/dkappa = cos(x - mean) - A1(kappa), (1/kappa) d/dmean = sin(x - mean)
        total = _column_sums(w)
        sum_cos, sum_sin = _weighted_sums(cos_x, w), _weighted_sums(sin_x, w)
        c, s = np.cos(self.mean), np.sin(self.mean)
        radial = c * sum_cos + s * sum_sin - total * _a1(self.concentration)
        return radial, c * sum_sin - s * sum_cos

    def _row_angle_score(self, cos_dev, sin_dev) -> tuple[np.ndarray, np.ndarray]:
        # log link: d/d log kappa = kappa (cos(x - mean) - A1(kappa))
        kappa = self.concentration
        return kappa * sin_dev, kappa * (cos_dev - _a1(kappa))

    @classmethod
    def _concentration_link(cls, concentration: np.ndarray) -> np.ndarray:
        """log kappa (kappa floored at 1e-12)."""
        return np.log(np.maximum(concentration, _TINY))

    @classmethod
    def _concentration_from_link(cls, eta: np.ndarray) -> np.ndarray:
        return np.minimum(np.exp(eta), _MAX_CONCENTRATION)

    def _sample_deviation(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return rng.vonmises(0.0, self.concentration[states])

    def _unwrapped_cdf(self, y: np.ndarray) -> np.ndarray:
        return stats.vonmises.cdf(y, self.concentration, loc=self.mean)

    @classmethod
    def _radial(cls, concentration: np.ndarray) -> np.ndarray:
        return concentration

    @classmethod
    def _radial_inverse(cls, r: np.ndarray) -> np.ndarray:
        return r


def _project_to_disc(a: float, b: float, estimate_mean: bool) -> tuple[float, float]:
    """Keep psi = a + ib inside |psi| <= 1 - 1e-9 (and on a >= 0 when the mean is fixed)."""
    if not estimate_mean:
        a = max(a, 0.0)
    rho = float(np.hypot(a, b))
    if rho > _MAX_WRAPPED_CAUCHY_RHO:
        a, b = a * _MAX_WRAPPED_CAUCHY_RHO / rho, b * _MAX_WRAPPED_CAUCHY_RHO / rho
    return a, b


def _wrapped_cauchy_loglik(cos_x, sin_x, w, total, a, b) -> float:
    """Weighted log-likelihood at psi = a + ib, without the -log(2 pi) term."""
    # |z - psi|^2 in a form without cancellation when |psi| is close to 1
    distance2 = (cos_x - a) ** 2 + (sin_x - b) ** 2
    return total * np.log1p(-(a**2 + b**2)) - _dot(w, np.log(distance2))


def _wrapped_cauchy_state_mle(
    cos_x: np.ndarray, sin_x: np.ndarray, w: np.ndarray, estimate_mean: bool
) -> tuple[float, float]:
    """Weighted wrapped Cauchy MLE of one state (weights ``w`` (T,)): (mean, rho).

    Safeguarded Newton on ``psi = a + ib = rho exp(i mean)`` (``z = exp(i x)``) for the
    weighted log-likelihood ``W log(1 - |psi|^2) - sum(w log|z - psi|^2)``: the Newton step
    is taken when the Hessian is negative definite and the step raises the likelihood,
    otherwise Kent & Tyler's (1988) fixed point ``psi = sum(w u z) / sum(w (1 + u))`` with
    ``u = (1 - |psi|^2) / |z - psi|^2`` (an ascent step). Started at the trigonometric
    moments; with a fixed mean psi stays real and >= 0.
    """
    total = w.sum()
    a, b = _project_to_disc(
        _dot(cos_x, w) / total, _dot(sin_x, w) / total if estimate_mean else 0.0, estimate_mean
    )
    for _ in range(_NEWTON_MAX_ITER):
        dc, ds = cos_x - a, sin_x - b
        inverse = 1.0 / (dc**2 + ds**2)
        current = total * np.log1p(-(a**2 + b**2)) + _dot(w, np.log(inverse))
        one_minus = 1.0 - a**2 - b**2
        wi = w * inverse
        wi2 = wi * inverse
        # Kent & Tyler's fixed point
        norm = total + one_minus * wi.sum()
        fixed = _project_to_disc(
            one_minus * _dot(cos_x, wi) / norm,
            one_minus * _dot(sin_x, wi) / norm if estimate_mean else 0.0,
            estimate_mean,
        )
        # Newton: gradient and Hessian of the log-likelihood in (a, b)
        c1, c2 = total / one_minus, total / one_minus**2
        g_a = -2 * a * c1 + 2 * _dot(wi, dc)
        h_aa = -2 * c1 - 4 * a**2 * c2 - 2 * wi.sum() + 4 * _dot(wi2, dc**2)
        if estimate_mean:
            g_b = -2 * b * c1 + 2 * _dot(wi, ds)
            h_bb = -2 * c1 - 4 * b**2 * c2 - 2 * wi.sum() + 4 * _dot(wi2, ds**2)
            h_ab = -4 * a * b * c2 + 4 * _dot(wi2, dc * ds)
            det = h_aa * h_bb - h_ab**2
            concave = h_aa < 0 and det > 0
            step = ((h_bb * g_a - h_ab * g_b) / det, (h_aa * g_b - h_ab * g_a) / det)
        else:
            concave = h_aa < 0
            step = (g_a / h_aa, 0.0)
        new = fixed
        if concave:
            newton = _project_to_disc(a - step[0], b - step[1], estimate_mean)
            if _wrapped_cauchy_loglik(cos_x, sin_x, w, total, *newton) >= current:
                new = newton
        done = np.hypot(new[0] - a, new[1] - b) <= _NEWTON_TOL
        a, b = new
        if done:
            break
    return float(np.arctan2(b, a)), float(np.hypot(a, b))


@dataclass(frozen=True, eq=False)
class WrappedCauchy(_AngleFamily):
    """Wrapped Cauchy turning angles, density ``(1 - r^2) / (2 pi (1 + r^2 - 2 r cos(x - mean)))``.

    Parameters
    ----------
    mean : (K,) float
        Mean direction (rad), wrapped to (-pi, pi]; all 0 when ``estimate_mean`` is False.
    concentration : (K,) float in [0, 1)
        Concentration r (the mean resultant length); 0 is the uniform distribution.
    estimate_mean : bool
        Whether ``fit_weighted`` estimates the mean (True) or keeps it at 0.

    Notes
    -----
    The weighted M-step has no closed form: safeguarded Newton with Kent & Tyler's fixed
    point as the fallback ascent step, see ``_wrapped_cauchy_state_mle``.
    Working scale: ``r = artanh(concentration)`` in the base class' polar mapping.
    """

    mean: np.ndarray
    concentration: np.ndarray
    estimate_mean: bool = True

    name: ClassVar[str] = "wrappedcauchy"

    def _validate_concentration(self) -> None:
        ok = (self.concentration >= 0) & (self.concentration < 1)
        self._require("concentration", ok, "in [0, 1)")

    @classmethod
    def from_mean_resultant(
        cls, mean: Any, mean_resultant_length: Any, estimate_mean: bool = True
    ) -> WrappedCauchy:
        """Wrapped Cauchy with concentration equal to the mean resultant length (K,)."""
        rho = np.clip(np.asarray(mean_resultant_length, dtype=float), 0, _MAX_WRAPPED_CAUCHY_RHO)
        return cls(mean, rho, estimate_mean)

    def _state_logpdf_cos(self, k: int, cos_dev: np.ndarray) -> np.ndarray:
        rho = self.concentration[k]
        # 1 + rho^2 - 2 rho cos = (1 - rho)^2 + 2 rho (1 - cos): no cancellation near rho = 1
        denominator = (1.0 - rho) ** 2 + 2.0 * rho * np.maximum(1.0 - cos_dev, 0.0)
        return (np.log1p(-(rho**2)) - _LOG_2PI) - np.log(denominator)

    def _fit_angles(self, cos_x, sin_x, w):
        fits = [
            _wrapped_cauchy_state_mle(
                cos_x, sin_x, np.ascontiguousarray(w[:, k]), self.estimate_mean
            )
            for k in range(w.shape[1])
        ]
        mean, rho = np.array(fits).T
        return {"mean": mean, "concentration": rho}

    def _polar_score(self, cos_x, sin_x, w) -> tuple[np.ndarray, np.ndarray]:
        # log f = log(1 - rho^2) - log D - log 2 pi, D = 1 + rho^2 - 2 rho cos(x - mean) and
        # rho = tanh(r): d/dr = (1 - rho^2) d/drho = -2 rho + 2 (1 - rho^2) (cos - rho) / D;
        # (1/r) d/dmean = (rho / r) 2 sin(x - mean) / D, rho / r -> 1 at r = 0
        rho, r = self.concentration, self._radial(self.concentration)
        cos_mean, sin_mean = np.cos(self.mean), np.sin(self.mean)
        radial, tangential = np.empty(self.n_states), np.empty(self.n_states)
        for k in range(self.n_states):
            cos_dev = cos_x * cos_mean[k] + sin_x * sin_mean[k]
            sin_dev = sin_x * cos_mean[k] - cos_x * sin_mean[k]
            inverse = 1.0 / ((1.0 - rho[k]) ** 2 + 2.0 * rho[k] * np.maximum(1.0 - cos_dev, 0.0))
            weighted = w[:, k] * inverse
            radial[k] = -2.0 * rho[k] * w[:, k].sum() + 2.0 * (1.0 - rho[k] ** 2) * (
                _dot(weighted, cos_dev) - rho[k] * weighted.sum()
            )
            shrink = rho[k] / r[k] if r[k] > 0 else 1.0
            tangential[k] = 2.0 * shrink * _dot(weighted, sin_dev)
        return radial, tangential

    def _row_angle_score(self, cos_dev, sin_dev) -> tuple[np.ndarray, np.ndarray]:
        # log f = log(1 - rho^2) - log D - log 2 pi, D = 1 + rho^2 - 2 rho cos(x - mean);
        # logit link: d rho / d eta = rho (1 - rho)
        rho = self.concentration
        inverse = 1.0 / ((1.0 - rho) ** 2 + 2.0 * rho * np.maximum(1.0 - cos_dev, 0.0))
        by_rho = -2.0 * rho / (1.0 - rho**2) + 2.0 * (cos_dev - rho) * inverse
        return 2.0 * rho * sin_dev * inverse, rho * (1.0 - rho) * by_rho

    @classmethod
    def _concentration_link(cls, concentration: np.ndarray) -> np.ndarray:
        """logit rho (rho clipped to [1e-12, 1 - 1e-9])."""
        rho = np.clip(concentration, _TINY, _MAX_WRAPPED_CAUCHY_RHO)
        return np.log(rho) - np.log1p(-rho)

    @classmethod
    def _concentration_from_link(cls, eta: np.ndarray) -> np.ndarray:
        return np.minimum(special.expit(eta), _MAX_WRAPPED_CAUCHY_RHO)

    def _sample_deviation(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        rho = self.concentration[states]
        uniform = rho == 0
        spread = -np.log(np.where(uniform, 1.0, rho))  # rho = exp(-Cauchy scale)
        out = spread * rng.standard_cauchy(states.size)
        out[uniform] = rng.uniform(-np.pi, np.pi, uniform.sum())
        return out

    def _unwrapped_cdf(self, y: np.ndarray) -> np.ndarray:
        rho = self.concentration
        deviation = y - self.mean
        turns = np.round(deviation / (2.0 * np.pi))
        half = (deviation - 2.0 * np.pi * turns) / 2.0  # in [-pi/2, pi/2]
        return turns + 0.5 + np.arctan((1.0 + rho) / (1.0 - rho) * np.tan(half)) / np.pi

    @classmethod
    def _radial(cls, concentration: np.ndarray) -> np.ndarray:
        return np.arctanh(np.minimum(concentration, _MAX_WRAPPED_CAUCHY_RHO))

    @classmethod
    def _radial_inverse(cls, r: np.ndarray) -> np.ndarray:
        return np.minimum(np.tanh(r), _MAX_WRAPPED_CAUCHY_RHO)
