"""The emission-family protocol and what every family shares.

:class:`StateDistribution` is the protocol of ``docs/interfaces.md`` that the fitting code
(:mod:`hmmtrack.hmm.fit`, :mod:`hmmtrack.hmm.model`) relies on. This module also holds the
prepared observations (:class:`PreparedSteps`, :class:`PreparedAngles`: data validated once,
with the transforms every family of a kind needs), ``_Family`` (parameter storage and
validation, ``to_dict`` / ``from_dict``, the working-scale round trip, the per-state M-step
driver) and the small weighted-sum helpers of the M-steps.

Not for: a family's density or fit (:mod:`.steps`, :mod:`.angles`).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np

from hmmtrack.tracks import wrap_angle

_LOG_2PI = float(np.log(2.0 * np.pi))
_MIN_STATE_WEIGHT = 1e-10  # a state with less total weight keeps its current parameters
_TINY = 1e-12  # floor for quantities whose log is taken (degenerate fits, working scale)
_NEWTON_TOL = 1e-12
_NEWTON_MAX_ITER = 100
_HESSIAN_STEP = 1e-5  # link-scale step of the central differences of row scores

D = TypeVar("D", bound="_Family")


class StateDistribution(Protocol):
    """The protocol every emission family implements.

    A family is a small frozen dataclass holding one array of shape ``(K,)`` per parameter
    (one entry per behavioural state):

    * ``logpdf(x) -> (T, K)`` closed-form log-densities on arrays (NaN ``x`` -> a row of 0.0:
      a missing observation contributes a density of 1); ``cdf(x) -> (T, K)`` (for
      pseudo-residuals; NaN ``x`` -> a row of NaN);
    * ``fit_weighted(x, w) -> new instance`` weighted maximum likelihood per state (the EM
      M-step; ``w[t, k]`` is the posterior probability of state ``k`` at row ``t``);
    * ``sample(rng, states) -> (n,)``; ``expected_value() -> (K,)`` (mean step, or mean
      direction);
    * ``to_dict()`` / ``from_dict()`` for the JSON model file;
    * ``to_working()`` / ``from_working()`` an unconstrained parameter vector (moveHMM's
      working scale) for direct likelihood optimisation and Wald intervals;
    * ``working_score(x, w) -> (n_working,)`` the gradient of the weighted log-likelihood
      ``sum(w * logpdf(x))`` with respect to ``to_working()``, in closed form (the emission
      part of the likelihood gradient by Fisher's identity);
    * ``permuted(order)`` the same distribution with its states reordered;
    * ``link_names()``, ``to_links() -> (n_links, K)``, ``from_links(eta, **structure)``,
      ``row_logpdf(x) -> (T,)``, ``row_score(x) -> (n_links, T)`` and ``row_cdf(x) ->
      (T,)`` (the value families also ``row_cdf_below``): the per-row view
      that covariate-dependent parameters (:mod:`hmmtrack.hmm.emission`) build on. A *row
      distribution* is a member whose K "states" are the T rows of the data (row ``t`` has
      its own parameters); ``eta`` holds each parameter on its link scale (log for positive
      parameters, logit for probabilities, identity for locations and angle means), and
      ``row_score`` is the derivative of each row's log-density by its link values;
      ``row_derivatives(x)`` gives the log-density, that score and the second derivatives
      ``(n_links, n_links, T)`` at once (the Newton M-step of emission formulas);
    * ``prepare(x)``: the observations validated once with their transforms (log x; cos x
      and sin x), a :class:`PreparedSteps` / :class:`PreparedAngles` accepted wherever ``x``
      is. Callers that evaluate the same data many times (EM, numerical derivatives) should
      pass it: validation and transforms are then paid once, not on every call.
    """

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

    def permuted(self, order: np.ndarray) -> StateDistribution: ...

    def with_working(self, theta: np.ndarray) -> StateDistribution: ...

    def working_score(
        self, x: np.ndarray | PreparedSteps | PreparedAngles, w: np.ndarray
    ) -> np.ndarray: ...


# ----------------------------------------------------------------------------------------
# Small helpers
# ----------------------------------------------------------------------------------------


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

    A loop over the few states with long vectorised operations inside, because broadcasting
    (T, 1) against (K,) runs inner loops only K long (timing in reports/decisions.md).
    """
    out = np.empty((n_obs, n_states))
    for k in range(n_states):
        out[:, k] = column(k)
    return out


def _rows_where(mask: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``a[mask]`` for a (T, K) array (``np.compress``: faster than boolean indexing)."""
    return np.compress(mask, a, axis=0)


# Long dot products go through einsum rather than ``@``, which stays on one thread: OpenBLAS's
# threads made M-steps randomly slow on a shared machine (reports/decisions.md, HMM fitting).


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """sum(a * b) of two (T,) arrays, single-threaded."""
    return float(np.einsum("t,t->", a, b))


def _weighted_sums(values: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-state sums of ``values`` (T,) weighted by ``w`` (T, K) -> (K,)."""
    return np.array([_dot(values, w[:, k]) for k in range(w.shape[1])])


def _column_sums(w: np.ndarray) -> np.ndarray:
    """Sums over the rows of a (T, K) array -> (K,), column by column (numpy's axis-0
    reduction of a narrow (T, 2) array is slow)."""
    return np.array([w[:, k].sum() for k in range(w.shape[1])])


def _weighted_means(values: np.ndarray, w: np.ndarray, total: np.ndarray) -> np.ndarray:
    """Per-state weighted means of ``values`` (T,) with weights ``w`` (T, K); total (K,)."""
    return _weighted_sums(values, w) / np.maximum(total, np.finfo(float).tiny)


def _check_states(states: np.ndarray, n_states: int, who: str) -> np.ndarray:
    states = np.asarray(states)
    if states.ndim != 1 or not np.issubdtype(states.dtype, np.integer):
        raise ValueError(f"{who}.sample: states must be a (n,) integer array, got {states.dtype}")
    bad = (states < 0) | (states >= n_states)
    if bad.any():
        raise ValueError(f"{who}.sample: states must be in [0, {n_states}); bad at {_rows(bad)}")
    return states


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
        order = np.argsort(values)  # numpy's SIMD quicksort: much faster than a stable sort
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
        return self._fill_states(usable, fit(*data, w if usable.all() else w[:, usable]))

    def _fit_sums(self, fit, total: np.ndarray, *sums: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`_fit_states` from per-state weighted sums instead of rows and weights.

        ``fit(total, *sums)`` takes the usable states' total weights and sums (each
        ``(K_usable,)``) and returns ``{parameter: (K_usable,) array}``; the fused EM of
        :mod:`hmmtrack.hmm.em_kernels` accumulates those sums without a ``(T, K)`` array.
        """
        usable = total > _MIN_STATE_WEIGHT
        if not usable.any():
            return {}
        return self._fill_states(usable, fit(total[usable], *(s[usable] for s in sums)))

    def _fill_states(self, usable: np.ndarray, fitted: dict) -> dict[str, np.ndarray]:
        """Full ``(K,)`` parameters: ``fitted`` on the ``usable`` states, current elsewhere."""
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

    def permuted(self: D, order: np.ndarray) -> D:
        """The same distribution with state ``k`` of the result being state ``order[k]``."""
        document = self.to_dict()
        for key, value in document.items():
            if isinstance(value, list) and len(value) == self.n_states:
                document[key] = [value[i] for i in order]
        return type(self).from_dict(document)

    def with_working(self: D, theta: np.ndarray) -> D:
        """Return a distribution of the same structure from working parameters ``theta``."""
        return type(self).from_working(theta, self.n_states, **self._structure())

    def _structure(self) -> dict[str, Any]:
        raise NotImplementedError

    @classmethod
    def from_working(cls: type[D], theta: np.ndarray, n_states: int, **structure: Any) -> D:
        raise NotImplementedError

    def row_derivatives(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Of a row distribution (K = T): each row's log-density (T,), its derivatives by the
        row's link values (n_links, T) and its second derivatives (n_links, n_links, T).

        Here the second derivatives are central differences (step 1e-5 on the link scale)
        of the closed-form ``row_score``; families with closed-form second derivatives
        override this. Missing rows have 0 everywhere.
        """
        eta, structure = self.to_links(), self._structure()
        hessian = np.empty((eta.shape[0], *eta.shape))
        for j in range(eta.shape[0]):
            shift = np.zeros_like(eta)
            shift[j] = _HESSIAN_STEP
            up = self.from_links(eta + shift, **structure).row_score(x)  # type: ignore[attr-defined]
            down = self.from_links(eta - shift, **structure).row_score(x)  # type: ignore[attr-defined]
            hessian[:, j] = (up - down) / (2.0 * _HESSIAN_STEP)
        hessian = (hessian + hessian.transpose(1, 0, 2)) / 2.0
        return self.row_logpdf(x), self.row_score(x), hessian  # type: ignore[attr-defined]


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
