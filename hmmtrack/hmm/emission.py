"""Covariates on the state-dependent distributions: emission formulas (momentuHMM's ``DM``).

A formula such as ``"step.mean ~ cosT + sinT"`` makes one parameter of a stream's family
depend on covariates, state by state, through the parameter's link (log for positive
parameters, logit for probabilities, identity for locations and angle means; the families'
``to_links``)::

    link(theta[t, k]) = X[t] @ beta[k],        X = the formula's standardised design matrix

:class:`CovariateEmission` is such a distribution. It follows the emission protocol of
:mod:`hmmtrack.hmm.distributions` (``logpdf``, ``fit_weighted``, ``working_score``, the
working scale, ``to_dict``...) with one difference: its observations are
:class:`EmissionRows`, the prepared observations together with the design matrices of its
formulas, because each row has its own parameters. The parameters without a formula stay
one value per state. The M-step is a weighted maximum likelihood per state over that
state's coefficients and constant parameters (Newton's method with the closed-form
gradient ``X^T (w * d log f / d eta)`` and Hessian ``X^T diag(w * d2 log f / d eta2) X``
from the families' ``row_derivatives``; the E-step's posteriors are the weights),
warm-started at the current values.

The design matrices are standardised (:mod:`hmmtrack.hmm.formula`): the intercept is the
parameter at the covariate means (factors at their reference levels), which is what
:attr:`CovariateEmission.base` holds and what orders the states; the coefficients are saved
on that scale and on the data's (``values_data_scale``).

Not for the families' maths (:mod:`hmmtrack.hmm.distributions`), design matrices
(:mod:`hmmtrack.hmm.formula`) or EM bookkeeping (:mod:`hmmtrack.hmm.fit`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.hmm import distributions
from hmmtrack.hmm.distributions import PreparedAngles, PreparedSteps
from hmmtrack.hmm.formula import Design, design_rows

STREAMS = ("step", "angle")  # the streams of every movement HMM
_INTERCEPT = "Intercept"
_MIN_STATE_WEIGHT = 1e-10  # a state with less total weight keeps its parameters
_NEWTON_MAX_ITER = 50  # Newton iterations per state and M-step (warm-started: 1 to 3 used)
# the M-step stops when the Newton step would gain less than this per unit weight (the
# log-likelihood per row): below 1e-8 in total for 1e6 rows
_NEWTON_GAIN = 1e-14
_NEWTON_HALVINGS = 30  # step halvings before a state's M-step gives up
_REMEMBERED = 8  # row derivatives kept per stream: the last few Newton points of each state
_BLOCK_FIELDS = ("formula", "columns", "scaling", "levels", "values", "values_data_scale", "layout")
_LAYOUT = (
    "rows: states; columns: 'columns' of the formula's design; on the parameter's link scale "
    "(log for positive parameters, logit for probabilities, identity for locations and angle "
    "means), standardised columns ('scaling': (raw - centre) / sd) in 'values', raw in "
    "'values_data_scale' (not read back); the parameter's list holds its value at the intercept"
)


@dataclass(frozen=True, eq=False)
class EmissionRows:
    """Observations of one stream with the design matrices of its emission formulas.

    Attributes
    ----------
    observations : PreparedSteps or PreparedAngles
        The stream's observations, T rows.
    matrices : dict of str to ndarray, shape (T, p_j)
        Standardised design matrix of each parameter with a formula, by parameter name.
    """

    observations: PreparedSteps | PreparedAngles
    matrices: dict[str, np.ndarray]

    @property
    def n_obs(self) -> int:
        """Number of rows T."""
        return self.observations.n_obs

    @functools.cached_property
    def columns(self) -> dict[str, np.ndarray]:
        """Each design matrix transposed, (p_j, T) C-contiguous: the M-step's sums over the
        rows run along contiguous memory, several times faster than on (T, p_j)."""
        return {name: np.ascontiguousarray(m.T) for name, m in self.matrices.items()}

    @functools.cached_property
    def _products(self) -> dict:
        return {}

    @functools.cached_property
    def _memory(self) -> dict:
        return {}

    def remembered(self, key: tuple):
        """What :meth:`remember` kept under ``key``, or None."""
        return self._memory.get(key)

    def remember(self, key: tuple, arrays: tuple) -> tuple:
        """Keep ``arrays`` (made read-only) under ``key``, the last 8 only: the row
        densities and derivatives of a state's row distribution (key: the distribution's
        structure and working block), which the next M-step and E-step ask for again."""
        for array in arrays:
            array.setflags(write=False)
        self._memory[key] = arrays
        while len(self._memory) > _REMEMBERED:
            self._memory.pop(next(iter(self._memory)))
        return arrays

    def products(self, left: str, right: str) -> np.ndarray:
        """Row-wise products of the columns of two designs, (p_left * p_right, T): the
        Hessian blocks ``X_l^T diag(v) X_r`` are then one sum over rows per entry. Built on
        first use and kept (the data of a fit do not change)."""
        key = (left, right)
        if key not in self._products:
            a, b = self.columns[left], self.columns[right]
            self._products[key] = (a[:, None, :] * b[None, :, :]).reshape(-1, self.n_obs)
        return self._products[key]


@dataclass(frozen=True, eq=False)
class CovariateEmission:
    """A state-dependent distribution some of whose parameters depend on covariates.

    Parameters
    ----------
    base : family instance (K states)
        The family (class, zero inflation, estimated or fixed angle mean) with the values of
        the parameters without a formula; its other parameters are overwritten by their
        values at the intercept (covariates at their means) when constructed.
    designs : dict of str to Design
        The formula of each parameter that has one (``{"mean": design("~ cosT + sinT")}``);
        each keeps its intercept.
    coefficients : dict of str to ndarray, shape (K, p_j)
        Per state, the coefficients of the parameter's standardised design columns on its
        link scale.
    """

    base: distributions.StateDistribution
    designs: dict[str, Design]
    coefficients: dict[str, np.ndarray]

    def __post_init__(self) -> None:
        links = self.base.link_names()
        unknown = sorted(set(self.designs) - set(links))
        if unknown or not self.designs:
            raise ValueError(
                f"{self.base.name}: formulas of {unknown or 'no parameter'}; the parameters "
                f"that take a formula are {list(links)}"
            )
        if set(self.coefficients) != set(self.designs):
            raise ValueError("give coefficients for exactly the parameters with a formula")
        eta = self.base.to_links()
        coefficients = {}
        for name in links:
            if name not in self.designs:
                continue
            design = self.designs[name]
            if not design.has_intercept:
                raise ValueError(
                    f"{self.base.name}.{name} formula {design.formula!r} needs an intercept"
                )
            values = np.array(self.coefficients[name], dtype=float)
            expected = (self.base.n_states, len(design.columns))
            if values.shape != expected or not np.all(np.isfinite(values)):
                raise ValueError(
                    f"{self.base.name}.{name} coefficients have shape {values.shape}; expected "
                    f"{expected} finite numbers (states x columns {list(design.columns)})"
                )
            values.setflags(write=False)
            coefficients[name] = values
            eta[links.index(name)] = values[:, design.columns.index(_INTERCEPT)]
        object.__setattr__(self, "coefficients", coefficients)
        object.__setattr__(
            self, "designs", {n: self.designs[n] for n in links if n in self.designs}
        )
        object.__setattr__(self, "base", self.base.from_links(eta, **self.base._structure()))

    @classmethod
    def from_constant(cls, base, designs: dict[str, Design]) -> CovariateEmission:
        """The distribution whose parameters equal ``base``'s at every row: each formula's
        intercept is the parameter's link value, its slopes 0 (EM starting values)."""
        eta, links = base.to_links(), base.link_names()
        coefficients = {}
        for name, design in designs.items():
            if name not in links:
                raise ValueError(
                    f"{base.name}: no parameter {name!r}; the parameters that take a formula "
                    f"are {list(links)}"
                )
            values = np.zeros((base.n_states, len(design.columns)))
            if design.has_intercept:
                values[:, design.columns.index(_INTERCEPT)] = eta[links.index(name)]
            coefficients[name] = values
        return cls(base, designs, coefficients)

    # -- what every distribution answers -------------------------------------------------------

    @property
    def name(self) -> str:
        """The family's name (``"gamma"``)."""
        return self.base.name

    @property
    def n_states(self) -> int:
        """Number of states K."""
        return self.base.n_states

    def expected_value(self) -> np.ndarray:
        """Expected value per state (K,) at the intercept (covariates at their means)."""
        return self.base.expected_value()

    def matrices(self, table: pd.DataFrame | dict, source: str = "table") -> dict:
        """The design matrices ``{parameter: (T, p_j)}`` of ``table``'s T rows.

        Raises
        ------
        ValueError
            When a formula cannot be evaluated on ``table`` or its covariates are missing or
            not finite in some row.
        """
        return {name: design_rows(design, table, source) for name, design in self.designs.items()}

    def _row_distribution(self, k: int, rows: EmissionRows, theta: np.ndarray | None = None):
        """The row distribution of state ``k``: its parameters at every row, from the state's
        working block ``theta`` (default: the current one)."""
        eta = self._row_links(self._state_blocks(k, theta), rows.columns, rows.n_obs)
        return self.base.from_links(eta, **self.base._structure())

    def _state_blocks(self, k: int, theta: np.ndarray | None) -> list[np.ndarray]:
        """Per link, state ``k``'s constant (shape (1,)) or coefficients (shape (p_j,))."""
        if theta is None:
            theta = self._state_working(k)
        blocks, start = [], 0
        for name in self.base.link_names():
            size = len(self.designs[name].columns) if name in self.designs else 1
            blocks.append(theta[start : start + size])
            start += size
        return blocks

    def _state_working(self, k: int) -> np.ndarray:
        """State ``k``'s working block: per link, the constant or the coefficients."""
        eta = self.base.to_links()
        return np.concatenate(
            [
                self.coefficients[name][k] if name in self.designs else eta[j, k : k + 1]
                for j, name in enumerate(self.base.link_names())
            ]
        )

    def _row_links(self, blocks: list[np.ndarray], columns: dict, n_obs: int) -> np.ndarray:
        """Link values (n_links, T) of the working blocks at the rows of the transposed
        design matrices ``columns`` ({parameter: (p_j, T)})."""
        eta = np.empty((len(blocks), n_obs))
        for j, (name, block) in enumerate(zip(self.base.link_names(), blocks, strict=True)):
            if name in self.designs:
                eta[j] = np.einsum("pt,p->t", columns[name], block)
            else:
                eta[j] = block[0]
        return eta

    def _state_score(self, k: int, rows: EmissionRows, w: np.ndarray):
        """Gradient (p,) of state ``k``'s weighted log-likelihood by its working block."""
        weighted = self._row_distribution(k, rows).row_score(rows.observations) * w
        return np.concatenate(
            [_cross(rows, name, weighted[j], None)[:, 0] for j, name in self._formula_names()]
        )

    def _state_derivatives(self, k: int, rows: EmissionRows, w: np.ndarray, theta: np.ndarray):
        """Weighted log-likelihood of state ``k`` at its working block ``theta`` (p,), with
        its gradient (p,) and Hessian (p, p): ``X_j^T (w d log f / d eta_j)`` and
        ``X_j^T diag(w d2 log f / d eta_j d eta_l) X_l`` over the links j, l."""
        value, score, second = self._row_derivatives(k, rows, theta)
        names = [name for _, name in self._formula_names()]
        gradient = np.concatenate(
            [_cross(rows, name, w * score[j], None)[:, 0] for j, name in enumerate(names)]
        )
        hessian = np.block(
            [
                [_cross(rows, left, w * second[j, i], right) for i, right in enumerate(names)]
                for j, left in enumerate(names)
            ]
        )
        return float(np.einsum("t,t->", w, value)), gradient, hessian

    def _row_derivatives(self, k: int, rows: EmissionRows, theta: np.ndarray):
        """``row_derivatives`` of state ``k``'s row distribution at working block ``theta``,
        kept on ``rows`` (:meth:`EmissionRows.remembered`): an M-step starts where the last
        one ended, and the E-step between them needs the same row densities."""
        key = (self._key(), theta.tobytes())
        found = rows.remembered(key)
        if found is None:
            row = self._row_distribution(k, rows, theta)
            found = rows.remember(key, row.row_derivatives(rows.observations))
        return found

    def _key(self) -> tuple:
        """What fixes the row distribution besides the working block: family, structure and
        the parameters that have formulas."""
        return (type(self.base), tuple(sorted(self.base._structure().items())), tuple(self.designs))

    def _formula_names(self) -> list[tuple[int, str | None]]:
        """Per link in order: (index, the parameter's name if it has a formula, else None)."""
        return [
            (j, name if name in self.designs else None)
            for j, name in enumerate(self.base.link_names())
        ]

    def logpdf(self, rows: EmissionRows) -> np.ndarray:
        """Log-density of every row in every state, shape (T, K); missing rows 0.0."""
        out = np.empty((rows.n_obs, self.n_states))
        for k in range(self.n_states):
            theta = self._state_working(k)
            found = rows.remembered((self._key(), theta.tobytes()))
            if found is None:
                out[:, k] = self._row_distribution(k, rows, theta).row_logpdf(rows.observations)
            else:
                out[:, k] = found[0]
        return out

    def cdf(self, rows: EmissionRows) -> np.ndarray:
        """P(X_t <= x_t) of every row in every state with the row's parameters, (T, K);
        missing rows NaN (each state's row distribution's ``row_cdf``)."""
        return self._by_state_rows(rows, "row_cdf")

    def cdf_below(self, rows: EmissionRows) -> np.ndarray:
        """P(X_t < x_t) of every row in every state, (T, K); missing rows NaN. Only for
        families with point masses (the value families' ``row_cdf_below``)."""
        return self._by_state_rows(rows, "row_cdf_below")

    def _by_state_rows(self, rows: EmissionRows, method: str) -> np.ndarray:
        """The row distribution's ``method`` (T,) of each state, as columns (T, K)."""
        out = np.empty((rows.n_obs, self.n_states))
        for k in range(self.n_states):
            out[:, k] = getattr(self._row_distribution(k, rows), method)(rows.observations)
        return out

    def sample(self, rng: np.random.Generator, states: np.ndarray, matrices: dict) -> np.ndarray:
        """One draw per row (n,) of state ``states[t]`` with row ``t``'s parameters, the
        design matrices of the n rows being ``matrices`` (:meth:`matrices`)."""
        states = np.asarray(states)
        eta = np.empty((len(self.base.link_names()), states.size))
        for k in range(self.n_states):
            here = states == k
            if here.any():
                columns = {name: m.T for name, m in matrices.items()}
                links = self._row_links(self._state_blocks(k, None), columns, states.size)
                eta[:, here] = links[:, here]
        row = self.base.from_links(eta, **self.base._structure())
        return row.sample(rng, np.arange(states.size))

    def fit_weighted(self, rows: EmissionRows, w: np.ndarray) -> CovariateEmission:
        """Weighted maximum likelihood per state (``w`` (T, K)): the EM M-step.

        Each state's working block (constants and coefficients) is maximised by Newton's
        method from its current value, with the closed-form gradient and Hessian (each
        family's ``row_derivatives``): quadratic convergence needs few evaluations per
        state (reports/decisions.md, emission M-step). Where the Hessian is not negative
        definite, the step uses its eigenvalues' absolute values (still an ascent
        direction); a step that lowers the value is halved. A state with (almost) no weight
        keeps its values.
        """
        theta = self.to_working_by_state()
        for k in range(self.n_states):
            weights = np.ascontiguousarray(w[:, k])
            total = weights.sum()
            if total > _MIN_STATE_WEIGHT:
                theta[k] = self._newton(k, rows, weights / total, theta[k])
        return self._from_state_working(theta)

    def _newton(self, k: int, rows: EmissionRows, w: np.ndarray, theta: np.ndarray):
        """State ``k``'s working block maximising its log-likelihood with weights ``w`` (T,)
        summing to 1, by Newton's method from ``theta``."""

        def evaluate(block):
            try:
                with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                    value, gradient, hessian = self._state_derivatives(k, rows, w, block)
            except (ValueError, FloatingPointError):
                return -np.inf, None, None
            if np.isfinite(value) and np.isfinite(gradient).all() and np.isfinite(hessian).all():
                return value, gradient, hessian
            return -np.inf, None, None

        value, gradient, hessian = evaluate(theta)
        for _ in range(_NEWTON_MAX_ITER if np.isfinite(value) else 0):
            step = _ascent_direction(gradient, hessian)
            if gradient @ step <= _NEWTON_GAIN:
                break
            for _ in range(_NEWTON_HALVINGS):
                trial = evaluate(theta + step)
                if trial[0] >= value:
                    break
                step = step / 2.0
            else:
                break
            theta = theta + step
            value, gradient, hessian = trial
        return theta

    # -- working scale ------------------------------------------------------------------------

    def to_working_by_state(self) -> list[np.ndarray]:
        """Each state's working block (constants then coefficients, in link order)."""
        return [self._state_working(k) for k in range(self.n_states)]

    def _from_state_working(self, theta: list[np.ndarray]) -> CovariateEmission:
        links = self.base.link_names()
        blocks = [self._state_blocks(k, theta[k]) for k in range(self.n_states)]
        eta = self.base.to_links()
        coefficients = {}
        for j, name in enumerate(links):
            if name in self.designs:
                coefficients[name] = np.array([b[j] for b in blocks])
            else:
                eta[j] = [b[j][0] for b in blocks]
        base = self.base.from_links(eta, **self.base._structure())
        return CovariateEmission(base, self.designs, coefficients)

    def to_working(self) -> np.ndarray:
        """Working vector: the states' working blocks one after the other."""
        return np.concatenate(self.to_working_by_state())

    def with_working(self, theta: np.ndarray) -> CovariateEmission:
        """The distribution of the same structure at the working vector ``theta``."""
        size = theta.size // self.n_states
        return self._from_state_working(
            [theta[k * size : (k + 1) * size] for k in range(self.n_states)]
        )

    def working_score(self, rows: EmissionRows, w: np.ndarray) -> np.ndarray:
        """Gradient of ``sum(w * logpdf(rows))`` by :meth:`to_working`, (n_working,)."""
        return np.concatenate(
            [
                self._state_score(k, rows, np.ascontiguousarray(w[:, k]))
                for k in range(self.n_states)
            ]
        )

    def permuted(self, order: np.ndarray) -> CovariateEmission:
        """The same distribution with state ``k`` of the result being state ``order[k]``."""
        order = np.asarray(order)
        return CovariateEmission(
            self.base.permuted(order),
            self.designs,
            {name: values[order] for name, values in self.coefficients.items()},
        )

    # -- file ---------------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """The base family's document (values at the intercept) with a ``formulas`` block:
        per parameter, its design (:meth:`Design.to_dict`) and coefficients."""
        return {
            **self.base.to_dict(),
            "formulas": {
                name: {
                    **design.to_dict(),
                    "values": self.coefficients[name].tolist(),
                    "values_data_scale": design.to_data_scale(self.coefficients[name]).tolist(),
                    "layout": _LAYOUT,
                }
                for name, design in self.designs.items()
            },
        }

    @classmethod
    def from_dict(cls, document: dict) -> CovariateEmission:
        """Rebuild from :meth:`to_dict` output.

        Raises
        ------
        ValueError
            For an unknown field of a formula block or a malformed block.
        """
        document = dict(document)
        blocks = document.pop("formulas")
        if not isinstance(blocks, dict):
            raise ValueError(f"'formulas' must be an object, got {blocks!r}")
        base = distributions.from_dict(document)
        designs, coefficients = {}, {}
        for name, block in blocks.items():
            if not isinstance(block, dict):
                raise ValueError(f"formulas.{name} must be an object, got {block!r}")
            unknown = sorted(set(block) - set(_BLOCK_FIELDS))
            if unknown:
                raise ValueError(
                    f"unknown field(s) {[f'formulas.{name}.{u}' for u in unknown]}; valid: "
                    f"{list(_BLOCK_FIELDS)}"
                )
            try:
                designs[name] = Design.from_dict(block)
                coefficients[name] = np.array(block["values"], dtype=float)
            except (KeyError, TypeError, ValueError) as exc:
                raise ValueError(f"formulas.{name} malformed ({exc!r})") from exc
        return cls(base, designs, coefficients)


def _cross(rows: EmissionRows, left: str | None, weights: np.ndarray, right: str | None):
    """``X_left^T diag(weights) X_right`` (p, q) of the design matrices of two parameters
    (by name; None stands for a column of ones, a parameter without a formula)."""
    if left is None and right is None:
        return np.array([[weights.sum()]])
    if left is None:
        return np.einsum("qt,t->q", rows.columns[right], weights)[None, :]
    if right is None:
        return np.einsum("pt,t->p", rows.columns[left], weights)[:, None]
    product = np.einsum("kt,t->k", rows.products(left, right), weights)
    return product.reshape(rows.columns[left].shape[0], -1)


def _ascent_direction(gradient: np.ndarray, hessian: np.ndarray) -> np.ndarray:
    """Newton's step ``-H^-1 g`` with the eigenvalues of ``-H`` replaced by their absolute
    values (floored at 1e-10 of the largest), an ascent direction even where the log-
    likelihood is not concave."""
    values, vectors = np.linalg.eigh(-(hessian + hessian.T) / 2.0)
    values = np.maximum(np.abs(values), 1e-10 * max(np.abs(values).max(), np.finfo(float).tiny))
    return vectors @ ((vectors.T @ gradient) / values)


def from_dict(document: dict):
    """Any emission distribution from its document: a :class:`CovariateEmission` when the
    document has ``formulas``, else the plain family (:func:`distributions.from_dict`)."""
    if isinstance(document, dict) and "formulas" in document:
        return CovariateEmission.from_dict(document)
    return distributions.from_dict(document)


def stream_input(prepared: PreparedSteps | PreparedAngles, matrices: dict | None):
    """What a stream's distribution is evaluated on: the prepared observations, or their
    :class:`EmissionRows` when the stream has emission formulas (``matrices`` not empty)."""
    return EmissionRows(prepared, matrices) if matrices else prepared


def split_formulas(
    formulas: dict[str, str] | None, streams=STREAMS
) -> tuple[str | None, dict[str, dict[str, str]]]:
    """The transition formula and the emission formulas by stream and parameter.

    Parameters
    ----------
    formulas : dict of str to str, or None
        ``{"transition": "~ x", "step.mean": "~ cosT + sinT", "angle.concentration": "~ z"}``.
    streams : sequence of str
        The streams of the model (``"step"``, ``"angle"`` and any further ones).

    Returns
    -------
    transition : str or None
    emission : dict
        ``{"step": {"mean": "~ cosT + sinT"}, "angle": {"concentration": "~ z"}}``.
    """
    transition, emission = None, {}
    for key, rhs in (formulas or {}).items():
        if key == "transition":
            transition = rhs
            continue
        stream, _, parameter = str(key).partition(".")
        if stream not in streams or not parameter:
            raise ValueError(
                f"formula of {key!r}: expected 'transition' or '<stream>.<parameter>' with a "
                f"stream in {list(streams)} ('step.mean', 'angle.concentration')"
            )
        emission.setdefault(stream, {})[parameter] = rhs
    return transition, emission
