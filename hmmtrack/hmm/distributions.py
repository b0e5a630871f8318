"""State-dependent emission distributions of movement HMMs: step lengths and turning angles.

Each family is a small frozen dataclass holding one array of shape ``(K,)`` per parameter
(one entry per behavioural state) and implementing the ``StateDistribution`` protocol of
``docs/interfaces.md``:

* ``logpdf(x) -> (T, K)`` closed-form log-densities on arrays (NaN ``x`` -> a row of 0.0:
  a missing observation contributes a density of 1); ``cdf(x) -> (T, K)`` (for
  pseudo-residuals; NaN ``x`` -> a row of NaN);
* ``fit_weighted(x, w) -> new instance`` weighted maximum likelihood per state (the EM
  M-step; ``w[t, k]`` is the posterior probability of state ``k`` at row ``t``);
* ``sample(rng, states) -> (n,)``; ``expected_value() -> (K,)`` (mean step, or mean direction);
* ``to_dict()`` / ``from_dict()`` for the JSON model file;
* ``to_working()`` / ``from_working()`` an unconstrained parameter vector (moveHMM's
  working scale) for direct likelihood optimisation and Wald intervals;
* ``working_score(x, w) -> (n_working,)`` the gradient of the weighted log-likelihood
  ``sum(w * logpdf(x))`` with respect to ``to_working()``, in closed form (the emission
  part of the likelihood gradient by Fisher's identity);
* ``prepare(x)``: the observations validated once with their transforms (log x; cos x and
  sin x), a :class:`PreparedSteps` / :class:`PreparedAngles` accepted wherever ``x`` is.
  Callers that evaluate the same data many times (EM, numerical derivatives) should pass
  it: at 10^5 rows it saves several milliseconds per call.

Step families (``Gamma`` in moveHMM's mean/sd parametrisation, ``Weibull``, ``LogNormal``,
``Exponential``) share one zero-inflation mechanism: an optional ``zero_mass`` (K,) puts a
point mass at a step of exactly 0 and scales the density for ``x > 0`` by ``1 - zero_mass``.
Angle families (``VonMises``, ``WrappedCauchy``) have a mean that is either estimated or
fixed at 0 (``estimate_mean``).

Not for: hidden-state inference (``hmmtrack.hmm.inference``), transition matrices or EM
bookkeeping (``hmmtrack.hmm.fit``).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np
from scipy import special, stats

_LOG_2PI = float(np.log(2.0 * np.pi))
_MIN_STATE_WEIGHT = 1e-10  # a state with less total weight keeps its current parameters
_TINY = 1e-12  # floor for quantities whose log is taken (degenerate fits, working scale)
_NEWTON_TOL = 1e-12
_NEWTON_MAX_ITER = 100
_MAX_CONCENTRATION = 1e8
_MAX_WRAPPED_CAUCHY_RHO = 1.0 - 1e-9

D = TypeVar("D", bound="_Family")


class StateDistribution(Protocol):
    """The protocol every emission family implements (see module docstring)."""

    name: ClassVar[str]

    @property
    def n_states(self) -> int: ...

    def prepare(self, x: np.ndarray) -> PreparedSteps | PreparedAngles: ...

    def logpdf(self, x: np.ndarray | PreparedSteps | PreparedAngles) -> np.ndarray: ...

    def cdf(self, x: np.ndarray | PreparedSteps | PreparedAngles) -> np.ndarray: ...

    def fit_weighted(
        self, x: np.ndarray | PreparedSteps | PreparedAngles, w: np.ndarray
    ) -> StateDistribution: ...

    def sample(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray: ...

    def expected_value(self) -> np.ndarray: ...

    def to_dict(self) -> dict: ...

    def to_working(self) -> np.ndarray: ...

    def with_working(self, theta: np.ndarray) -> StateDistribution: ...

    def working_score(
        self, x: np.ndarray | PreparedSteps | PreparedAngles, w: np.ndarray
    ) -> np.ndarray: ...


# ----------------------------------------------------------------------------------------
# Small helpers
# ----------------------------------------------------------------------------------------


def wrap_angle(x: np.ndarray) -> np.ndarray:
    """Wrap angles (rad) to the interval (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=float), 2.0 * np.pi)


def _rows(mask: np.ndarray, limit: int = 10) -> str:
    idx = np.flatnonzero(mask)
    shown = ", ".join(str(i) for i in idx[:limit])
    return f"[{shown}{', ...' if idx.size > limit else ''}] ({idx.size} rows)"


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(p, _TINY, 1.0 - _TINY)
    return np.log(p) - np.log1p(-p)


def _check_observations(x: np.ndarray, who: str) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"{who}: observations must have shape (T,), got {x.shape}")
    if np.isinf(x).any():
        raise ValueError(f"{who}: infinite observations at rows {_rows(np.isinf(x))}")
    return x


def _check_weights(w: np.ndarray, n_obs: int, n_states: int, who: str) -> np.ndarray:
    w = np.asarray(w, dtype=float)
    if w.shape != (n_obs, n_states):
        raise ValueError(f"{who}: weights must have shape ({n_obs}, {n_states}), got {w.shape}")
    bad = ~np.isfinite(w) | (w < 0)
    if bad.any():
        raise ValueError(
            f"{who}: weights must be finite and >= 0; bad weights at rows {_rows(bad.any(1))}"
        )
    return w


def _by_state(n_obs: int, n_states: int, column) -> np.ndarray:
    """(T, K) array whose column k is ``column(k)`` (T,).

    A loop over the few states with long vectorised operations inside: several times faster
    than broadcasting (T, 1) against (K,), whose inner loops are only K long.
    """
    out = np.empty((n_obs, n_states))
    for k in range(n_states):
        out[:, k] = column(k)
    return out


def _rows_where(mask: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``a[mask]`` for a (T, K) array; ``np.compress`` is ~5x faster than boolean indexing."""
    return np.compress(mask, a, axis=0)


# Long dot products go through einsum rather than ``@``: OpenBLAS runs them on several
# threads, and on a machine shared with other work the threads' wake-ups and spinning were
# measured to make an M-step 10-1000x slower at random; einsum stays on one thread.


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """sum(a * b) of two (T,) arrays, single-threaded."""
    return float(np.einsum("t,t->", a, b))


def _weighted_sums(values: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-state sums of ``values`` (T,) weighted by ``w`` (T, K) -> (K,)."""
    return np.array([_dot(values, w[:, k]) for k in range(w.shape[1])])


def _column_sums(w: np.ndarray) -> np.ndarray:
    """Sums over the rows of a (T, K) array -> (K,) (column by column: numpy's axis-0
    reduction of a narrow (T, 2) array is an order of magnitude slower)."""
    return np.array([w[:, k].sum() for k in range(w.shape[1])])


def _weighted_means(values: np.ndarray, w: np.ndarray, total: np.ndarray) -> np.ndarray:
    """Per-state weighted means of ``values`` (T,) with weights ``w`` (T, K); total (K,)."""
    return _weighted_sums(values, w) / np.maximum(total, np.finfo(float).tiny)


# ----------------------------------------------------------------------------------------
# Prepared observations: validated once, transforms (log x, cos x, sin x) computed once
# ----------------------------------------------------------------------------------------


def _frozen(*arrays: np.ndarray) -> None:
    for arr in arrays:
        arr.setflags(write=False)


@dataclass(frozen=True, eq=False)
class PreparedSteps:
    """Step lengths validated once, with what every step family needs; from :func:`prepare_steps`.

    Pass it instead of the raw array to ``logpdf``, ``cdf`` and ``fit_weighted`` of any step
    family to skip validation and the logarithm on every call (EM iterations, numerical
    derivatives). All arrays are read-only.

    Attributes
    ----------
    missing, zero, positive : (T,) bool
        NaN rows, steps of exactly 0, steps > 0.
    safe, log_safe : (T,) float
        Steps with missing and zero rows replaced by 1, and their logarithm.
    positive_x, positive_log_x : (n_positive,) float
        The positive steps and their logarithm.
    """

    missing: np.ndarray
    zero: np.ndarray
    positive: np.ndarray
    safe: np.ndarray
    log_safe: np.ndarray
    positive_x: np.ndarray
    positive_log_x: np.ndarray

    @property
    def n_obs(self) -> int:
        """Number of rows T."""
        return self.missing.size

    @functools.cached_property
    def positive_order(self) -> np.ndarray:
        """Rows of the positive steps by increasing step (stable), (n_positive,) int.

        Sorted on first use only (starting values of every start of a multi-start fit).
        """
        rows = np.flatnonzero(self.positive)
        values = self.safe[rows]
        order = np.argsort(values)  # numpy's SIMD quicksort, ~10x faster than a stable sort
        ordered = values[order]
        if np.any(ordered[1:] == ordered[:-1]):  # only ties make the result sort-dependent
            order = np.argsort(values, kind="stable")
        order = rows[order]
        order.setflags(write=False)
        return order


def prepare_steps(x: np.ndarray) -> PreparedSteps:
    """Validate step lengths ``x`` (T,) (>= 0 or NaN) and precompute their transforms."""
    if isinstance(x, PreparedSteps):
        return x
    x = _check_observations(x, "steps")
    missing = np.isnan(x)
    negative = x < 0
    if negative.any():
        raise ValueError(f"step lengths must be >= 0; negative at rows {_rows(negative)}")
    zero = x == 0
    positive = ~(missing | zero)
    safe = np.where(positive, x, 1.0)
    log_safe = np.log(safe)
    all_positive = bool(positive.all())
    positive_x = safe if all_positive else safe[positive]
    positive_log_x = log_safe if all_positive else log_safe[positive]
    _frozen(missing, zero, positive, safe, log_safe, positive_x, positive_log_x)
    return PreparedSteps(missing, zero, positive, safe, log_safe, positive_x, positive_log_x)


@dataclass(frozen=True, eq=False)
class PreparedAngles:
    """Turning angles validated once, with their cosines and sines; from :func:`prepare_angles`.

    Pass it instead of the raw array to ``logpdf``, ``cdf`` and ``fit_weighted`` of any angle
    family. All arrays are read-only.

    Attributes
    ----------
    angle : (T,) float
        Angles wrapped to (-pi, pi], NaN where missing.
    missing : (T,) bool
    cos, sin : (T,) float
        cos and sin of the angles, 0 where missing.
    observed_cos, observed_sin : (n_observed,) float
        The same on the non-missing rows only.
    """

    angle: np.ndarray
    missing: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    observed_cos: np.ndarray
    observed_sin: np.ndarray

    @property
    def n_obs(self) -> int:
        """Number of rows T."""
        return self.missing.size


def prepare_angles(x: np.ndarray) -> PreparedAngles:
    """Validate turning angles ``x`` (T,) (rad, NaN missing) and precompute cos and sin."""
    if isinstance(x, PreparedAngles):
        return x
    angle = wrap_angle(_check_observations(x, "angles"))
    missing = np.isnan(angle)
    safe = np.where(missing, 0.0, angle)
    cos, sin = np.cos(safe), np.sin(safe)
    cos[missing] = 0.0
    sin[missing] = 0.0
    observed = ~missing
    all_observed = bool(observed.all())
    observed_cos = cos if all_observed else cos[observed]
    observed_sin = sin if all_observed else sin[observed]
    _frozen(angle, missing, cos, sin, observed_cos, observed_sin)
    return PreparedAngles(angle, missing, cos, sin, observed_cos, observed_sin)


# ----------------------------------------------------------------------------------------
# Common base: parameter storage, validation, dict and working-scale round trips
# ----------------------------------------------------------------------------------------


class _Family:
    """Shared machinery of all families; subclasses are frozen dataclasses."""

    name: ClassVar[str]
    _parameters: ClassVar[tuple[str, ...]]  # per-state array fields, in working order

    def __post_init__(self) -> None:
        n = None
        for field in self._array_fields():
            value = getattr(self, field)
            if value is None:
                continue
            try:
                arr = np.atleast_1d(np.asarray(value, dtype=float)).copy()
            except (TypeError, ValueError) as error:
                raise ValueError(
                    f"{type(self).__name__}.{field} must be an array of numbers, got {value!r}"
                ) from error
            if arr.ndim != 1 or arr.size == 0:
                raise ValueError(f"{type(self).__name__}.{field} must have shape (K,), K >= 1")
            if n is not None and arr.size != n:
                raise ValueError(
                    f"{type(self).__name__}: all parameters need the same number of states; "
                    f"{field} has {arr.size}, expected {n}"
                )
            n = arr.size
            if not np.isfinite(arr).all():
                raise ValueError(f"{type(self).__name__}.{field} must be finite, got {arr}")
            arr.setflags(write=False)
            object.__setattr__(self, field, arr)
        self._validate()

    def _array_fields(self) -> tuple[str, ...]:
        return self._parameters

    def _validate(self) -> None:
        raise NotImplementedError

    def _require(self, field: str, ok: np.ndarray, expected: str) -> None:
        if not np.all(ok):
            value = getattr(self, field)
            raise ValueError(f"{type(self).__name__}.{field} must be {expected}, got {value}")

    @property
    def n_states(self) -> int:
        """Number of states K."""
        return int(getattr(self, self._parameters[0]).size)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    def _replace(self: D, **changes: Any) -> D:
        return dataclasses.replace(self, **changes)

    def _fit_states(self, fit, w: np.ndarray, *data: np.ndarray) -> dict[str, np.ndarray]:
        """Run ``fit(*data, w)`` on the states with weight; the others keep their values.

        ``fit`` returns ``{parameter: (K_usable,) array}``; a state is usable when its total
        weight exceeds 1e-10.
        """
        usable = _column_sums(w) > _MIN_STATE_WEIGHT
        if not usable.any():
            return {}
        fitted = fit(*data, w if usable.all() else w[:, usable])
        out = {}
        for field, value in fitted.items():
            full = np.array(getattr(self, field), dtype=float)
            full[usable] = value
            out[field] = full
        return out

    def to_dict(self) -> dict:
        """Return a JSON-ready dict ``{"family": name, <parameter>: [K floats], ...}``."""
        out: dict[str, Any] = {"family": self.name}
        for field in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, field.name)
            out[field.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out

    @classmethod
    def from_dict(cls: type[D], d: dict) -> D:
        """Rebuild from :meth:`to_dict` output; raises ``ValueError`` on malformed input."""
        if not isinstance(d, dict):
            raise ValueError(f"{cls.__name__}.from_dict expects a dict, got {type(d).__name__}")
        if d.get("family") != cls.name:
            raise ValueError(f"{cls.__name__}.from_dict: family must be {cls.name!r}, got {d}")
        names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        required = {f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING}  # type: ignore[arg-type]
        keys = set(d) - {"family"}
        if not required <= keys or not keys <= names:
            raise ValueError(
                f"{cls.__name__}.from_dict: expected keys {sorted(required)} "
                f"(optional {sorted(names - required)}), got {sorted(keys)}"
            )
        return cls(**{k: d[k] for k in keys})

    def with_working(self: D, theta: np.ndarray) -> D:
        """Return a distribution of the same structure from working parameters ``theta``."""
        return type(self).from_working(theta, self.n_states, **self._structure())

    def _structure(self) -> dict[str, Any]:
        raise NotImplementedError

    @classmethod
    def from_working(cls: type[D], theta: np.ndarray, n_states: int, **structure: Any) -> D:
        raise NotImplementedError


def _split_working(theta: np.ndarray, n_states: int, n_blocks: int, who: str) -> np.ndarray:
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (n_blocks * n_states,):
        raise ValueError(
            f"{who}.from_working: expected {n_blocks * n_states} working parameters "
            f"({n_blocks} per state x {n_states} states), got shape {theta.shape}"
        )
    if not np.isfinite(theta).all():
        raise ValueError(f"{who}.from_working: working parameters must be finite, got {theta}")
    return theta.reshape(n_blocks, n_states)


# ----------------------------------------------------------------------------------------
# Step lengths: positive part per family + one shared zero-inflation mechanism
# ----------------------------------------------------------------------------------------


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
        data = self._prepared(x)
        out = self._cdf_positive(data.safe, data.log_safe)
        if self.zero_mass is not None:
            out = self.zero_mass + (1.0 - self.zero_mass) * out
            out[data.zero] = self.zero_mass
        out[data.missing] = np.nan
        return out

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
            total = _weighted_sums((~data.missing).astype(float), w)
            zeros = _weighted_sums(data.zero.astype(float), w)
            share = zeros / np.maximum(total, np.finfo(float).tiny)
            changes["zero_mass"] = np.where(total > _MIN_STATE_WEIGHT, share, self.zero_mass)
        wp = w if data.positive_x is data.safe else _rows_where(data.positive, w)
        changes.update(
            self._fit_states(self._fit_positive, wp, data.positive_x, data.positive_log_x)
        )
        return self._replace(**changes)

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


def _check_states(states: np.ndarray, n_states: int, who: str) -> np.ndarray:
    states = np.asarray(states)
    if states.ndim != 1 or not np.issubdtype(states.dtype, np.integer):
        raise ValueError(f"{who}.sample: states must be a (n,) integer array, got {states.dtype}")
    bad = (states < 0) | (states >= n_states)
    if bad.any():
        raise ValueError(f"{who}.sample: states must be in [0, {n_states}); bad at {_rows(bad)}")
    return states


def _gamma_shape_mle(s: np.ndarray) -> np.ndarray:
    """Solve ``log k - digamma(k) = s`` for the gamma shape k, (K,), by Newton from Minka's start.

    ``s = log(weighted mean of x) - weighted mean of log x`` (> 0 by Jensen; floored at 1e-12
    for degenerate data, which gives a very large but finite shape).
    """
    s = np.maximum(s, _TINY)
    k = (3.0 - s + np.sqrt((s - 3.0) ** 2 + 24.0 * s)) / (12.0 * s)
    for _ in range(_NEWTON_MAX_ITER):
        f = np.log(k) - special.digamma(k) - s
        fprime = 1.0 / k - special.polygamma(1, k)
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
        total = _column_sums(w)
        mean = _weighted_means(x, w, total)
        mean_log = _weighted_means(log_x, w, total)
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

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return special.gammainc(self.shape, np.divide.outer(x, self.scale))

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

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        z = np.multiply.outer(log_x, self.shape) - self.shape * np.log(self.scale)
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

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return special.ndtr(np.subtract.outer(log_x, self.location) / self.scale)

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

    def _cdf_positive(self, x: np.ndarray, log_x: np.ndarray) -> np.ndarray:
        return -np.expm1(np.multiply.outer(x, -self.rate))

    def _sample_positive(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return rng.exponential(1.0 / self.rate[states])

    def _expected_positive(self) -> np.ndarray:
        return 1.0 / self.rate


# ----------------------------------------------------------------------------------------
# Turning angles
# ----------------------------------------------------------------------------------------


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
        """Cumulative mass (T, K) from an arbitrary origin, growing by 1 per 2 pi of ``y``."""
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
        angle = prepare_angles(x).angle
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

    def _trigonometric_moments(self, cos_x, sin_x, w) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean direction (0 if fixed) and E[cos(x - direction)] per state, (K,)."""
        total = _column_sums(w)
        c, s = _weighted_means(cos_x, w, total), _weighted_means(sin_x, w, total)
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
        mean, resultant = self._trigonometric_moments(cos_x, sin_x, w)
        return {"mean": mean, "concentration": _a1_inverse(resultant)}

    def _polar_score(self, cos_x, sin_x, w) -> tuple[np.ndarray, np.ndarray]:
        # log f = kappa cos(x - mean) - log I0(kappa) - log 2 pi, r = kappa:
        # d/dkappa = cos(x - mean) - A1(kappa), (1/kappa) d/dmean = sin(x - mean)
        total = _column_sums(w)
        sum_cos, sum_sin = _weighted_sums(cos_x, w), _weighted_sums(sin_x, w)
        c, s = np.cos(self.mean), np.sin(self.mean)
        radial = c * sum_cos + s * sum_sin - total * _a1(self.concentration)
        return radial, c * sum_sin - s * sum_cos

    def _sample_deviation(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        return rng.vonmises(0.0, self.concentration[states])

    def _unwrapped_cdf(self, y: np.ndarray) -> np.ndarray:
        return stats.vonmises.cdf(y[:, None], self.concentration, loc=self.mean)

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

    def _sample_deviation(self, rng: np.random.Generator, states: np.ndarray) -> np.ndarray:
        rho = self.concentration[states]
        uniform = rho == 0
        spread = -np.log(np.where(uniform, 1.0, rho))  # rho = exp(-Cauchy scale)
        out = spread * rng.standard_cauchy(states.size)
        out[uniform] = rng.uniform(-np.pi, np.pi, uniform.sum())
        return out

    def _unwrapped_cdf(self, y: np.ndarray) -> np.ndarray:
        rho = self.concentration
        deviation = np.subtract.outer(y, self.mean)
        turns = np.round(deviation / (2.0 * np.pi))
        half = (deviation - 2.0 * np.pi * turns) / 2.0  # in [-pi/2, pi/2]
        return turns + 0.5 + np.arctan((1.0 + rho) / (1.0 - rho) * np.tan(half)) / np.pi

    @classmethod
    def _radial(cls, concentration: np.ndarray) -> np.ndarray:
        return np.arctanh(np.minimum(concentration, _MAX_WRAPPED_CAUCHY_RHO))

    @classmethod
    def _radial_inverse(cls, r: np.ndarray) -> np.ndarray:
        return np.minimum(np.tanh(r), _MAX_WRAPPED_CAUCHY_RHO)


# ----------------------------------------------------------------------------------------
# Registries and starting values
# ----------------------------------------------------------------------------------------

STEP_FAMILIES: dict[str, type[_StepFamily]] = {
    cls.name: cls for cls in (Gamma, Weibull, LogNormal, Exponential)
}
ANGLE_FAMILIES: dict[str, type[_AngleFamily]] = {cls.name: cls for cls in (VonMises, WrappedCauchy)}


def from_dict(d: dict) -> _StepFamily | _AngleFamily:
    """Rebuild any family from its ``to_dict`` output, dispatching on ``d["family"]``."""
    if not isinstance(d, dict) or "family" not in d:
        raise ValueError(f"a distribution needs a dict with a 'family' key, got {d!r}")
    families = {**STEP_FAMILIES, **ANGLE_FAMILIES}
    if d["family"] not in families:
        raise ValueError(f"unknown distribution family {d['family']!r}; known: {sorted(families)}")
    return families[d["family"]].from_dict(d)


def _family(name_or_class: str | type, registry: dict[str, type], kind: str) -> type:
    if isinstance(name_or_class, str):
        if name_or_class not in registry:
            raise ValueError(f"unknown {kind} family {name_or_class!r}; known: {sorted(registry)}")
        return registry[name_or_class]
    if name_or_class not in registry.values():
        raise ValueError(f"{name_or_class!r} is not a {kind} family; known: {sorted(registry)}")
    return name_or_class


def initial_guess(
    steps: np.ndarray | PreparedSteps,
    angles: np.ndarray,
    n_states: int,
    step_family: str | type = "gamma",
    angle_family: str | type = "vonmises",
    *,
    estimate_angle_mean: bool = True,
    zero_inflated: bool | None = None,
    rng: np.random.Generator | None = None,
) -> tuple[_StepFamily, _AngleFamily]:
    """Starting values for an EM fit from the data, states ordered by mean step.

    The positive steps are sorted and cut into ``n_states`` groups of equal size (with
    ``rng``: group sizes drawn from a flat Dirichlet, for multi-start). Each group's mean
    and sd give the step distribution (``from_moments``); the turning angles of the rows in
    each group give the mean direction and mean resultant length of the angle distribution.

    Parameters
    ----------
    steps : (T,) float or PreparedSteps
        Step lengths (>= 0, NaN missing), units of the data; prepared steps (see
        :func:`prepare_steps`) are sorted once for all the calls that share them.
    angles : (T,) float
        Turning angles (rad, NaN missing), same rows as ``steps``.
    n_states : int
        Number of states K >= 1.
    step_family, angle_family : str or class
        Names in ``STEP_FAMILIES`` / ``ANGLE_FAMILIES`` or the classes themselves.
    estimate_angle_mean : bool
        False fixes the angle means at 0.
    zero_inflated : bool or None
        Zero-inflation of steps; None switches it on when a step is exactly 0 (moveHMM).
    rng : numpy.random.Generator or None
        None gives the deterministic equal-count split.

    Returns
    -------
    (step distribution, angle distribution)
    """
    step_cls = _family(step_family, STEP_FAMILIES, "step")
    angle_cls = _family(angle_family, ANGLE_FAMILIES, "angle")
    prepared = prepare_steps(steps)
    steps = prepared.safe  # the steps on positive rows, which are the only ones used
    angles = _check_observations(angles, "initial_guess(angles)")
    if steps.shape != angles.shape:
        raise ValueError(f"initial_guess: steps {steps.shape} and angles {angles.shape} differ")
    if n_states < 1:
        raise ValueError(f"initial_guess: n_states must be >= 1, got {n_states}")
    order = prepared.positive_order
    if order.size < 2 * n_states:
        raise ValueError(
            f"initial_guess: {order.size} positive steps are too few for {n_states} states"
        )
    zero = prepared.zero
    if zero_inflated is None:
        zero_inflated = bool(zero.any())
    shares = np.full(n_states, 1.0 / n_states) if rng is None else rng.dirichlet(np.ones(n_states))
    # at least two rows per group so that every sd is defined
    sizes = 2 + np.floor(shares * (order.size - 2 * n_states)).astype(int)
    sizes[-1] = order.size - sizes[:-1].sum()
    groups = np.split(order, np.cumsum(sizes)[:-1])

    means = np.array([steps[g].mean() for g in groups])
    sds = np.array([max(steps[g].std(), 1e-3 * steps[g].mean()) for g in groups])
    zero_mass = None
    if zero_inflated:
        share = zero.sum() / max((~prepared.missing).sum(), 1)
        zero_mass = np.full(n_states, min(max(share, 1e-3), 0.5))
    step_dist = step_cls.from_moments(means, sds, zero_mass=zero_mass)

    direction, resultant = np.zeros(n_states), np.zeros(n_states)
    for k, g in enumerate(groups):
        a = angles[g]
        a = a[~np.isnan(a)]
        if a.size == 0:
            continue
        c, s = np.cos(a).mean(), np.sin(a).mean()
        direction[k] = np.arctan2(s, c) if estimate_angle_mean else 0.0
        resultant[k] = np.hypot(c, s) if estimate_angle_mean else max(c, 0.0)
    resultant = np.clip(resultant, 0.01, 0.95)
    angle_dist = angle_cls.from_mean_resultant(direction, resultant, estimate_angle_mean)
    return step_dist, angle_dist
