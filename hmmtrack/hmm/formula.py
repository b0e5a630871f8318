"""Formula design matrices (``formulaic``) over a prepared track, standardised and reported.

A formula such as ``"~ cosT + sinT"``, ``"~ C(season)"``, ``"~ temp * depth"`` or
``"~ cos(2*pi*hour/24)"`` names what a parameter (a transition probability's logit, a step
mean's log) depends on. :func:`design` turns it into the design matrix of a table, one row
per table row, with its column names, and standardises the numeric columns the way
:mod:`hmmtrack.hmm.covariates` standardises covariates (mean and sample sd, ``ddof=1``), so
that the optimiser sees columns of unit scale. The standardisation is reported
(:attr:`Design.scaling`) and undone for printing (:meth:`Design.to_data_scale`): a
coefficient per unit of the column as the data have it, and an intercept at zero.

Formula syntax is formulaic's (Wilkinson-Rogers, as R's): ``+`` adds terms, ``a * b`` is
``a + b + a:b``, ``C(x)`` makes ``x`` a factor (treatment coding, first level the reference),
``0 +`` drops the intercept, and any Python expression of the columns is a term; ``pi``,
``cos``, ``sin``, ``exp``, ``log``, ``sqrt`` and ``np`` (numpy) are available in it.

Which columns are standardised: every column of a term with a numeric factor (``temp``,
``temp:depth``, ``cos(...)``, ``temp:C(season)``); not the intercept and not the indicator
columns of a term made of factors only (``C(season)[T.w]``), which keep their 0/1 meaning.
Without an intercept the columns are scaled but not centred (centring would change the
model). Missing values (NaN) stay in their rows and are left out of the means and sds.

Not for fitting (:mod:`hmmtrack.hmm.fit`) or the logit transition maths
(:mod:`hmmtrack.hmm.covariates`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from formulaic import model_matrix
from formulaic.errors import FormulaicError
from formulaic.model_spec import ModelSpec
from formulaic.parser.types import Factor

_CONTEXT = {
    "np": np,
    "pi": np.pi,
    "cos": np.cos,
    "sin": np.sin,
    "exp": np.exp,
    "log": np.log,
    "sqrt": np.sqrt,
}
_INTERCEPT = "Intercept"


@dataclass(frozen=True)
class Design:
    """A formula's design: how to build its standardised design matrix for any table.

    Built from a table by :func:`design` (which learns the factor levels and the
    standardisation from it); :meth:`transform` gives the matrix of that or any other table.
    :meth:`to_dict` / :meth:`from_dict` write and read it as plain JSON types (what a saved
    model keeps of its formula).

    Attributes
    ----------
    formula : str
        The right-hand side as given (``"~ temp * depth"``).
    columns : tuple of str
        Column names (formulaic's: ``"Intercept"``, ``"temp"``, ``"temp:depth"``,
        ``"C(season)[T.w]"``, ``"cos(2 * pi * hour / 24)"``).
    scaling : dict
        ``{column: (centre, sd)}`` of each standardised column: ``matrix[:, j] =
        (raw_j - centre) / sd`` (centre 0 without an intercept). Columns not listed are raw.
    spec : formulaic ModelSpec
        Rebuilds the raw columns for new data (:meth:`transform`).
    """

    formula: str
    columns: tuple[str, ...]
    scaling: dict[str, tuple[float, float]]
    spec: ModelSpec = field(repr=False)

    @property
    def has_intercept(self) -> bool:
        return _INTERCEPT in self.columns

    @property
    def levels(self) -> dict[str, list]:
        """``{factor: levels}`` of each categorical factor (``"C(season)"``), reference first."""
        return {
            str(name): list(state[1]["categories"])
            for name, state in self.spec.encoder_state.items()
            if state[0].value == "categorical"
        }

    def transform(self, table: pd.DataFrame) -> np.ndarray:
        """Standardised design matrix of a table: the one fitted to, or new rows (a grid).

        Factor levels and standardisation are those of the table :func:`design` saw.

        Returns
        -------
        ndarray, shape (len(table), p)
            NaN in the rows of missing values.

        Raises
        ------
        ValueError
            When the formula cannot be evaluated on ``table`` (a missing column, an unknown
            factor level) or gives other columns than :attr:`columns`.
        """
        try:
            raw = self.spec.get_model_matrix(table, context=_CONTEXT, na_action="ignore")
        except FormulaicError as exc:
            raise ValueError(f"formula {self.formula!r}: {exc}") from exc
        columns = tuple(str(c) for c in raw.columns)
        if columns != self.columns:
            raise ValueError(
                f"formula {self.formula!r} gives columns {list(columns)} on this table; "
                f"expected {list(self.columns)}"
            )
        return _standardised(raw, self.scaling)

    def to_dict(self) -> dict:
        """The design as JSON types: formula, columns, scaling and factor levels.

        Raises
        ------
        ValueError
            For a formula with a stateful transform (``center(x)``, ``poly(x)``), whose state
            is not written.
        """
        if self.spec.transform_state:
            raise ValueError(
                f"formula {self.formula!r} uses a stateful transform; it cannot be saved"
            )
        return {
            "formula": self.formula,
            "columns": list(self.columns),
            "scaling": {name: {"centre": c, "sd": s} for name, (c, s) in self.scaling.items()},
            "levels": {name: [_plain(v) for v in levels] for name, levels in self.levels.items()},
        }

    @classmethod
    def from_dict(cls, document: dict) -> Design:
        """The design of a :meth:`to_dict` document.

        Raises
        ------
        KeyError, TypeError, ValueError
            For a malformed document.
        """
        formula = _one_sided(str(document["formula"]))
        encoder_state = {
            str(name): (Factor.Kind.CATEGORICAL, {"categories": list(levels)})
            for name, levels in dict(document.get("levels", {})).items()
        }
        spec = ModelSpec(formula=formula, encoder_state=encoder_state, na_action="ignore")
        scaling = {
            str(name): (float(value["centre"]), float(value["sd"]))
            for name, value in dict(document["scaling"]).items()
        }
        columns = tuple(str(c) for c in document["columns"])
        unknown = set(scaling) - set(columns)
        if unknown:
            raise ValueError(f"scaling of unknown columns {sorted(unknown)}")
        return cls(formula, columns, scaling, spec)

    def to_data_scale(self, coefficients: np.ndarray) -> np.ndarray:
        """Coefficients of the standardised columns as coefficients of the raw columns.

        With ``eta = sum_j b_j (raw_j - centre_j) / sd_j``, the raw coefficient of column
        ``j`` is ``b_j / sd_j`` and the intercept absorbs ``-sum_j b_j centre_j / sd_j``.

        Parameters
        ----------
        coefficients : ndarray, shape (..., p)
            On the standardised columns (e.g. ``MovementHMM.coefficients``, one row per
            off-diagonal transition).

        Returns
        -------
        ndarray, shape (..., p)
            The same linear predictor written on the data's scale.
        """
        coefficients = np.asarray(coefficients, dtype=float)
        out = coefficients.copy()
        for j, name in enumerate(self.columns):
            if name in self.scaling:
                centre, sd = self.scaling[name]
                out[..., j] = coefficients[..., j] / sd
                if self.has_intercept:
                    out[..., self.columns.index(_INTERCEPT)] -= coefficients[..., j] * centre / sd
        return out


def design(formula: str, table: pd.DataFrame, *, standardise: bool = True) -> Design:
    """Build the design matrix of ``formula`` over ``table``.

    Parameters
    ----------
    formula : str
        A one-sided formula, ``"~ terms"`` (the ``~`` may be left out).
    table : DataFrame
        Typically a prepared track; every column the formula names must be in it.
    standardise : bool
        Standardise the numeric columns (see the module docstring); False keeps them raw
        (``scaling`` is then empty).

    Returns
    -------
    Design
        Its :meth:`~Design.transform` of ``table`` is the design matrix, shape (T, p).
    """
    rhs = _one_sided(formula)
    try:
        raw = model_matrix(rhs, table, context=_CONTEXT, na_action="ignore")
    except FormulaicError as exc:
        raise ValueError(f"formula {rhs!r}: {exc}") from exc
    spec = raw.model_spec
    columns = tuple(str(c) for c in raw.columns)
    scaling = _scaling(raw, spec, columns) if standardise else {}
    return Design(rhs, columns, scaling, spec)


def design_rows(design: Design, table: pd.DataFrame | dict, source: str = "table") -> np.ndarray:
    """``design.transform(table)``, refusing rows with missing or non-finite values.

    Returns
    -------
    ndarray, shape (len(table), p)
    """
    table = table if isinstance(table, pd.DataFrame) else pd.DataFrame(table)
    try:
        matrix = design.transform(table)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from exc
    bad = np.flatnonzero(~np.all(np.isfinite(matrix), axis=1))
    if bad.size:
        raise ValueError(
            f"{source}: the covariates of formula {design.formula!r} have missing or non-finite "
            f"values at rows {bad[:10].tolist()}{' ...' if bad.size > 10 else ''}; fill or "
            "drop them first"
        )
    return matrix


def of_columns(names) -> str:
    """The formula ``"~ a + b"`` of plain columns (quoted with backticks where not a name)."""
    terms = [n if str(n).isidentifier() else f"`{n}`" for n in names]
    return "~ " + " + ".join(terms)


def _one_sided(formula: str) -> str:
    rhs = formula.strip()
    if not rhs.startswith("~"):
        rhs = "~ " + rhs
    if "~" in rhs[1:]:
        raise ValueError(f"design takes a one-sided formula '~ terms', got {formula!r}")
    return rhs


def _plain(value):
    """A factor level as a JSON type (numpy scalars to Python ones)."""
    return value.item() if isinstance(value, np.generic) else value


def _scaling(raw: pd.DataFrame, spec: ModelSpec, columns: tuple[str, ...]) -> dict:
    """``{column: (centre, sd)}`` of the columns of terms with a numeric factor."""
    kinds = {str(name): state[0].value for name, state in spec.encoder_state.items()}
    centre = _INTERCEPT in columns
    scaling = {}
    for term, indices in spec.term_indices.items():
        factors = [str(f) for f in term.factors if str(f) in kinds]
        if not factors or all(kinds[f] == "categorical" for f in factors):
            continue  # the intercept, or indicators of factor levels
        for j in indices:
            values = np.asarray(raw.iloc[:, j], dtype=float)
            sd = float(np.nanstd(values, ddof=1))
            if not sd > 0:
                raise ValueError(
                    f"design column {columns[j]!r} is constant (sd = {sd}); it cannot be "
                    "standardised"
                )
            scaling[columns[j]] = (float(np.nanmean(values)) if centre else 0.0, sd)
    return scaling


def _standardised(raw: pd.DataFrame, scaling: dict) -> np.ndarray:
    matrix = np.asarray(raw, dtype=float).copy()
    for j, name in enumerate(str(c) for c in raw.columns):
        if name in scaling:
            centre, sd = scaling[name]
            matrix[:, j] = (matrix[:, j] - centre) / sd
    return matrix
