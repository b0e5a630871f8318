"""Fixed parameters, equality constraints and a stationary initial distribution of a fit.

momentuHMM's ``fixPar``, simple equality constraints and ``stationary=TRUE``. A user names
parameters as they see them, states numbered from 1:

* ``"step.mean[1]"``, ``"angle.concentration[2]"``, ``"depth.sd[1]"``, ``"step.zero_mass[1]"``:
  a parameter of a stream's distribution in one state, in the data's units;
* ``"transition[1,2]"``: the probability of moving from state 1 to state 2 (a model without
  transition covariates; with 3 or more states every off-diagonal entry of the row is fixed
  together, since one probability of a row is not one coefficient of the logit);
* ``"transition.<column>[1,2]"``: a logit coefficient of the transition formula's standardised
  design column (``"Intercept"``, ``"dist_water"``), as the summary prints them;
* ``"initial[1]"``: the initial distribution (all of it fixed together, like a row).

:class:`FitControl` holds what the user asked for (``fixed``, ``equal``, ``stationary``), and is
what the model file stores. :class:`Constraints` resolves it against a model's structure into
a vector of *free* parameters ``phi``: every parameter of the model on its link scale (the
families' ``to_links``: log for positive parameters, logit for probabilities, identity for
locations and angle means; a parameter with an emission formula is its coefficient vector)
forms a vector ``z``; fixed entries of ``z`` are constants, tied entries share one entry of
``phi``. Ties are within one parameter of one stream (the same parameter in several states);
with a formula the coefficient vectors are tied. Equality on the link scale is equality of the
parameters, since each link is one-to-one.

With ``stationary`` the initial distribution is not a parameter: it is the stationary
distribution of the transition matrix (with covariates, of each sequence's -- each animal's
track segment's -- matrix at its first row: :func:`stationary_starts`).

Not for the likelihood or the EM (:mod:`hmmtrack.hmm.fit` uses this mapping).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize

from hmmtrack.hmm import covariates as cov
from hmmtrack.hmm import emission

_TINY = 1e-12  # floor of a fixed probability whose log is a coefficient (0 -> 1e-12)
_SUM_TOLERANCE = 1e-9  # fixed probabilities of a row may sum to 1 within this
_JACOBIAN_STEP = 1e-6  # central-difference step of the link -> working Jacobian
_EMISSION_KEY = re.compile(r"^(\w+)\.(\w+)\[(\d+)\]$")
_TRANSITION_KEY = re.compile(r"^transition\[(\d+),\s*(\d+)\]$")
_COEFFICIENT_KEY = re.compile(r"^transition\.(.+)\[(\d+),\s*(\d+)\]$")
_INITIAL_KEY = re.compile(r"^initial\[(\d+)\]$")
_FORMS = (
    "'<stream>.<parameter>[state]' (step.mean[1]), 'transition[i,j]', "
    "'transition.<column>[i,j]' or 'initial[state]', states from 1"
)


@dataclass(frozen=True)
class FitControl:
    """What a user fixes, ties and asks of the initial distribution.

    Attributes
    ----------
    fixed : dict of str to float
        ``{"step.mean[1]": 50.0, "transition[1,2]": 0.1}``: values in the data's units
        (probabilities for ``transition`` and ``initial``, the link scale for coefficients).
    equal : tuple of str
        ``("angle.concentration[1]==angle.concentration[2]",)``: parameters held equal.
    stationary : bool
        The initial distribution is the stationary distribution of the transition matrix.
    """

    fixed: dict = field(default_factory=dict)
    equal: tuple = ()
    stationary: bool = False

    def __post_init__(self) -> None:
        fixed = {}
        for key, value in dict(self.fixed or {}).items():
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = float("nan")
            if not np.isfinite(number):
                raise ValueError(f"fixed {key!r}: expected a finite number, got {value!r}")
            fixed[str(key).replace(" ", "")] = number
        object.__setattr__(self, "fixed", fixed)
        if isinstance(self.equal, str):
            raise ValueError(f"equal must be a list of 'a==b' strings, got {self.equal!r}")
        object.__setattr__(self, "equal", tuple(str(e).replace(" ", "") for e in self.equal))
        for tie in self.equal:
            if tie.count("==") != 1:
                raise ValueError(f"equality {tie!r}: expected 'a==b' (step.mean[1]==step.mean[2])")
        object.__setattr__(self, "stationary", bool(self.stationary))

    def __bool__(self) -> bool:
        return bool(self.fixed or self.equal or self.stationary)

    @property
    def labels_states(self) -> bool:
        """True when the control names states (fixed or tied per state): the fit then keeps
        the states as numbered rather than ordering them by mean step."""
        return bool(self.fixed or self.equal)

    def fixed_names(self, n_states: int) -> set[tuple[str, str]]:
        """The natural parameters held fixed, as :func:`hmmtrack.hmm.diagnostics.
        natural_parameters` names them (``("step.mean", "1")``, ``("transition", "1->2")``,
        ``("beta.x", "1->2")``): the fixed ones, whole transition rows and initial
        distributions, and parameters tied to a fixed one."""
        names: set[tuple[str, str]] = set()
        for key in self.fixed:
            if match := _TRANSITION_KEY.match(key):
                i = match.group(1)
                names |= {("transition", f"{i}->{j}") for j in range(1, n_states + 1)}
            elif match := _COEFFICIENT_KEY.match(key):
                column = "intercept" if match.group(1) == "Intercept" else match.group(1)
                names.add((f"beta.{column}", f"{match.group(2)}->{match.group(3)}"))
            elif _INITIAL_KEY.match(key):
                names |= {("initial", str(k)) for k in range(1, n_states + 1)}
            elif match := _EMISSION_KEY.match(key):
                names.add((f"{match.group(1)}.{match.group(2)}", match.group(3)))
        pairs = []
        for tie in self.equal:
            matches = [_EMISSION_KEY.match(side) for side in tie.split("==")]
            if all(matches):
                pairs.append([(f"{m.group(1)}.{m.group(2)}", m.group(3)) for m in matches])
        for _ in pairs:  # each pass carries fixedness one tie further
            for a, b in pairs:
                if a in names or b in names:
                    names |= {a, b}
        return names

    def to_dict(self) -> dict:
        """``{"fixed": {...}, "equal": [...], "stationary": bool}`` (the model file's block)."""
        return {"fixed": dict(self.fixed), "equal": list(self.equal), "stationary": self.stationary}

    @classmethod
    def from_dict(cls, document: dict) -> FitControl:
        """Rebuild from :meth:`to_dict` output; ``ValueError`` on unknown or malformed fields."""
        if not isinstance(document, dict):
            raise ValueError(f"expected an object, got {document!r}")
        unknown = sorted(set(document) - {"fixed", "equal", "stationary"})
        if unknown:
            raise ValueError(f"unknown field(s) {unknown}; valid: ['fixed', 'equal', 'stationary']")
        fixed, equal = document.get("fixed", {}), document.get("equal", [])
        stationary = document.get("stationary", False)
        if not isinstance(fixed, dict) or not isinstance(equal, list):
            raise ValueError("'fixed' must be an object and 'equal' a list")
        if not isinstance(stationary, bool):
            raise ValueError(f"'stationary' must be true or false, got {stationary!r}")
        return cls(fixed, tuple(equal), stationary)


def stationary_starts(coefficients: np.ndarray, design: np.ndarray) -> np.ndarray:
    """Stationary initial distributions at design rows: that of the transition matrix of
    ``coefficients`` (K*(K-1), p) at each row of ``design`` (n, p) (each sequence's first),
    clipped to >= 0 and normalised, shape (n, K)."""
    gamma = np.exp(cov.log_transition_matrices(coefficients, design))
    delta = np.maximum(stationary_distribution(gamma), 0.0)
    return delta / delta.sum(axis=-1, keepdims=True)


def stationary_distribution(gamma: np.ndarray) -> np.ndarray:
    """Stationary distribution ``delta = delta Gamma`` of transition matrices.

    Parameters
    ----------
    gamma : ndarray, shape (..., K, K)
        Row-stochastic matrices.

    Returns
    -------
    ndarray, shape (..., K)
        Solves ``delta (I - Gamma + 1) = 1`` (Zucchini et al.'s linear system).
    """
    k = gamma.shape[-1]
    system = np.swapaxes(np.eye(k) - gamma + 1.0, -1, -2)
    return np.linalg.solve(system, np.ones(gamma.shape[:-1])[..., None])[..., 0]


# ---------------------------------------------------------------------------------------------
# Each stream's parameters on the link scale
# ---------------------------------------------------------------------------------------------


def link_vector(dist) -> np.ndarray:
    """A stream distribution's parameters on their link scale, flat: ``to_links()`` row by
    row (parameter-major, K per parameter), or a formula distribution's working vector
    (state by state: per parameter, the constant or the coefficients)."""
    if isinstance(dist, emission.CovariateEmission):
        return dist.to_working()
    return dist.to_links().ravel()


def from_link_vector(dist, z: np.ndarray):
    """The distribution of ``dist``'s structure whose :func:`link_vector` is ``z``."""
    if isinstance(dist, emission.CovariateEmission):
        return dist.with_working(z)
    eta = np.asarray(z, dtype=float).reshape(len(dist.link_names()), dist.n_states)
    return dist.from_links(eta, **dist._structure())


def link_jacobian(dist, z: np.ndarray) -> np.ndarray:
    """``d to_working / d z`` at the link vector ``z``, shape (n_working, n_z).

    The identity for a formula distribution; central differences otherwise (the angle
    families' working scale is ``(r cos mean, r sin mean)``, not their links). The map is on
    a few numbers per state, so the differences cost nothing beside a likelihood.
    """
    if isinstance(dist, emission.CovariateEmission):
        return np.eye(z.size)
    columns = []
    for i in range(z.size):
        shift = np.zeros(z.size)
        shift[i] = _JACOBIAN_STEP * max(1.0, abs(z[i]))
        up = from_link_vector(dist, z + shift).to_working()
        down = from_link_vector(dist, z - shift).to_working()
        columns.append((up - down) / (2 * shift[i]))
    return np.stack(columns, axis=1)


def _layout(dist) -> dict[str, list[np.ndarray]]:
    """Where each parameter of each state sits in :func:`link_vector`:
    ``{parameter: [indices of state 0, state 1, ...]}``."""
    k = dist.n_states
    if not isinstance(dist, emission.CovariateEmission):
        names = dist.link_names()
        return {name: [np.array([j * k + s]) for s in range(k)] for j, name in enumerate(names)}
    names = dist.base.link_names()
    sizes = [len(dist.designs[n].columns) if n in dist.designs else 1 for n in names]
    block = sum(sizes)
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    return {
        name: [s * block + o + np.arange(size) for s in range(k)]
        for name, o, size in zip(names, offsets, sizes, strict=True)
    }


def _link_value(dist, parameter: str, state: int, value: float, key: str) -> float:
    """The link value of ``parameter`` of ``state`` set to ``value`` (natural units)."""
    base = dist.base if isinstance(dist, emission.CovariateEmission) else dist
    document = base.to_dict()
    document[parameter] = list(document[parameter])
    document[parameter][state] = value
    try:
        member = type(base).from_dict(document)
    except ValueError as exc:
        raise ValueError(f"fixed {key}={value:g}: not a valid value ({exc})") from exc
    return float(member.to_links()[base.link_names().index(parameter), state])


# ---------------------------------------------------------------------------------------------
# The free parameters of a constrained model
# ---------------------------------------------------------------------------------------------


class Constraints:
    """A :class:`FitControl` resolved against a model's structure: the map between the free
    vector ``phi`` and the parameters.

    Parameters
    ----------
    control : FitControl
    template : Parameters
        The fit's structure (:class:`hmmtrack.hmm.fit.Parameters`: streams, families,
        formulas, states, transition covariates).
    transition_columns : tuple of str
        Names of the transition design's columns (``("Intercept",)`` without covariates).
    start_design : ndarray, shape (n_sequences, p) or None
        The transition design's row at the start of each sequence: a stationary initial
        distribution with covariates is that of each sequence's matrix there. None without
        covariates.

    Raises
    ------
    ValueError
        Naming the parameter and what was expected: an unknown stream, parameter, state or
        column, a value outside the parameter's range, a fixed parameter with a formula, a
        partly fixed transition row or initial distribution, ties across parameters.
    """

    def __init__(self, control: FitControl, template, transition_columns, start_design=None):
        self.control = control
        self.template = replace(template, stationary=control.stationary)
        self.start_design = start_design
        self.columns = tuple(transition_columns)
        k = template.n_states
        self.n_states = k
        self.blocks, start = {}, 0
        for name, dist in template.emissions.items():
            size = link_vector(dist).size
            self.blocks[name] = slice(start, start + size)
            start += size
        n_coefficients = k * (k - 1) * len(self.columns)
        self.blocks["transition"] = slice(start, start + n_coefficients)
        start += n_coefficients
        self.blocks["initial"] = slice(start, start if control.stationary else start + k - 1)
        self.size_z = self.blocks["initial"].stop
        self.fixed_z = np.full(self.size_z, np.nan)
        self._fix(control.fixed)
        self._resolve_classes(control.equal)

    # -- resolving the user's names ------------------------------------------------------------

    def _state(self, text: str, key: str) -> int:
        state = int(text)
        if not 1 <= state <= self.n_states:
            raise ValueError(f"{key}: state {state}; the model has states 1..{self.n_states}")
        return state - 1

    def _emission_indices(self, key: str, allow_formula: bool) -> np.ndarray:
        match = _EMISSION_KEY.match(key)
        emissions = self.template.emissions
        if match is None or match.group(1) not in emissions:
            raise ValueError(
                f"{key!r}: not a parameter of this model; expected {_FORMS} with a stream in "
                f"{list(emissions)}"
            )
        stream, parameter = match.group(1), match.group(2)
        dist = emissions[stream]
        layout = _layout(dist)
        if parameter not in layout:
            raise ValueError(
                f"{key!r}: the {dist.name} {stream} has parameters {list(layout)}"
                + (" (the angle mean is not estimated)" if parameter == "mean" else "")
            )
        designs = getattr(dist, "designs", {})
        if parameter in designs and not allow_formula:
            raise ValueError(
                f"{key!r}: {stream}.{parameter} has a formula ({designs[parameter].formula}); "
                "a parameter with a formula can be tied but not fixed"
            )
        state = self._state(match.group(3), key)
        return self.blocks[stream].start + layout[parameter][state]

    def _coefficient_index(self, key: str, column: str, i: str, j: str) -> int:
        if column not in self.columns:
            raise ValueError(
                f"{key!r}: no transition design column {column!r}; columns {list(self.columns)}"
            )
        origin, target = self._state(i, key), self._state(j, key)
        if origin == target:
            raise ValueError(f"{key!r}: a diagonal entry has no coefficient (its logit is 0)")
        rows, cols = cov.off_diagonal_index(self.n_states)
        r = int(np.flatnonzero((rows == origin) & (cols == target))[0])
        return self.blocks["transition"].start + r * len(self.columns) + self.columns.index(column)

    def _fix(self, fixed: dict) -> None:
        rows: dict[int, dict[int, float]] = {}
        initial: dict[int, float] = {}
        for key, value in fixed.items():
            if match := _TRANSITION_KEY.match(key):
                if self.start_design is not None:
                    raise ValueError(
                        f"{key!r}: with transition covariates fix coefficients instead: "
                        f"'transition.<column>[i,j]' with a column in {list(self.columns)}"
                    )
                i, j = self._state(match.group(1), key), self._state(match.group(2), key)
                if i == j or not 0 <= value <= 1:
                    raise ValueError(
                        f"{key}={value:g}: expected an off-diagonal entry (i != j) and a "
                        "probability in [0, 1]; the diagonal is what the row leaves"
                    )
                rows.setdefault(i, {})[j] = value
            elif match := _COEFFICIENT_KEY.match(key):
                index = self._coefficient_index(key, *match.groups())
                self.fixed_z[index] = value
            elif match := _INITIAL_KEY.match(key):
                if self.control.stationary:
                    raise ValueError(f"{key!r}: the initial distribution is stationary, not fixed")
                if not 0 <= value <= 1:
                    raise ValueError(f"{key}={value:g}: expected a probability in [0, 1]")
                initial[self._state(match.group(1), key)] = value
            else:
                index = self._emission_indices(key, allow_formula=False)
                stream, parameter, state = _EMISSION_KEY.match(key).groups()
                dist = self.template.emissions[stream]
                self.fixed_z[index] = _link_value(dist, parameter, int(state) - 1, value, key)
        for i, entries in rows.items():
            full = self._full_row(entries, i, "transition", f"transition[{i + 1},j]")
            for j in range(self.n_states):
                if j != i:
                    key = f"transition[{i + 1},{j + 1}]"
                    index = self._coefficient_index(key, "Intercept", str(i + 1), str(j + 1))
                    self.fixed_z[index] = np.log(max(full[j], _TINY)) - np.log(max(full[i], _TINY))
        if initial:
            full = self._full_row(initial, None, "initial", "initial[k]")
            block = self.blocks["initial"]
            self.fixed_z[block] = np.log(np.maximum(full[1:], _TINY)) - np.log(max(full[0], _TINY))

    def _full_row(self, entries: dict, diagonal: int | None, name: str, form: str) -> np.ndarray:
        """A whole probability row from the fixed ``entries`` ``{column: p}``: all but one
        entry (the diagonal of a transition row, or any one of ``initial``) may be given."""
        k = self.n_states
        free = [j for j in range(k) if j not in entries]
        expected = [diagonal] if diagonal is not None else free[:1]
        total = sum(entries.values())
        if len(free) > 1 or (diagonal is not None and free != expected):
            given = ", ".join(
                f"{name}[{'' if diagonal is None else f'{diagonal + 1},'}{j + 1}]"
                for j in sorted(entries)
            )
            raise ValueError(
                f"{given}: fix the whole row {form} ({k - 1} of its {k} probabilities, the "
                "last is what remains): one probability of a row is not one parameter"
            )
        if total > 1 + _SUM_TOLERANCE or (not free and abs(total - 1) > _SUM_TOLERANCE):
            raise ValueError(f"{form}: the fixed probabilities sum to {total:g}; expected 1")
        full = np.zeros(k)
        for j, value in entries.items():
            full[j] = value
        if free:
            full[free[0]] = max(1.0 - total, 0.0)
        return full

    def _resolve_classes(self, equal: tuple) -> None:
        parent = np.arange(self.size_z)

        def root(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        for tie in equal:
            left, right = tie.split("==")
            sides = [self._tie_side(left, tie), self._tie_side(right, tie)]
            (a, name_a), (b, name_b) = sides
            if name_a != name_b or a.size != b.size:
                raise ValueError(
                    f"equality {tie!r}: both sides must be the same parameter of the same "
                    f"stream in different states ({name_a} and {name_b} given)"
                )
            for i, j in zip(a, b, strict=True):
                ri, rj = root(i), root(j)
                fixed_i, fixed_j = self.fixed_z[ri], self.fixed_z[rj]
                if np.isfinite(fixed_i) and np.isfinite(fixed_j) and fixed_i != fixed_j:
                    raise ValueError(f"equality {tie!r}: both sides are fixed at other values")
                parent[rj] = ri
                if np.isnan(fixed_i):
                    self.fixed_z[ri] = fixed_j
        roots = np.array([root(i) for i in range(self.size_z)], dtype=np.int64)
        self.fixed_z = self.fixed_z[roots]
        free = np.isnan(self.fixed_z)
        _, first, classes = np.unique(roots[free], return_index=True, return_inverse=True)
        # number the classes in order of their first position
        order = np.argsort(np.argsort(first))
        self.free = free
        self.classes = order[classes]
        self.size = int(first.size)
        self.counts = np.bincount(self.classes, minlength=self.size).astype(float)

    def _tie_side(self, key: str, tie: str) -> tuple[np.ndarray, str]:
        if match := _COEFFICIENT_KEY.match(key):
            return np.array([self._coefficient_index(key, *match.groups())]), "transition"
        if _EMISSION_KEY.match(key) is None:
            raise ValueError(
                f"equality {tie!r}: {key!r} is not a stream parameter "
                "('<stream>.<parameter>[state]') or a transition coefficient "
                "('transition.<column>[i,j]')"
            )
        stream, parameter, _ = _EMISSION_KEY.match(key).groups()
        return self._emission_indices(key, allow_formula=True), f"{stream}.{parameter}"

    # -- between the free vector, the link vector and the parameters ---------------------------

    def z_of(self, params) -> np.ndarray:
        """The link vector ``z`` of ``params``, shape (size_z,)."""
        if params.coefficients is None:
            coefficients = cov.coefficients_from_matrix(np.maximum(params.transition, _TINY))
        else:
            coefficients = params.coefficients
        initial = np.maximum(params.initial, _TINY)
        parts = [link_vector(d) for d in params.emissions.values()]
        parts.append(coefficients.ravel())
        if not self.control.stationary:
            parts.append(np.log(initial[1:]) - np.log(initial[0]))
        return np.concatenate(parts)

    def expand(self, phi: np.ndarray) -> np.ndarray:
        """The link vector of the free vector ``phi``: fixed entries, tied entries shared."""
        z = self.fixed_z.copy()
        z[self.free] = np.asarray(phi, dtype=float)[self.classes]
        return z

    def reduce(self, z: np.ndarray) -> np.ndarray:
        """The free vector nearest ``z``: each class's mean (a projection onto the constraints)."""
        return np.bincount(self.classes, weights=z[self.free], minlength=self.size) / self.counts

    def reduce_gradient(self, gradient_z: np.ndarray) -> np.ndarray:
        """Gradient by ``phi`` from the gradient by ``z``: tied entries' gradients summed."""
        return np.bincount(self.classes, weights=gradient_z[self.free], minlength=self.size)

    def parameters(self, z: np.ndarray):
        """The parameters of the link vector ``z`` (the template's structure)."""
        template = self.template
        emissions = {
            name: from_link_vector(dist, z[self.blocks[name]])
            for name, dist in template.emissions.items()
        }
        k = self.n_states
        coefficients = z[self.blocks["transition"]].reshape(k * (k - 1), len(self.columns))
        transition = None
        if self.start_design is None:
            transition = np.exp(cov.log_transition_matrices(coefficients, np.ones((1, 1))))[0]
        if self.control.stationary:  # the first sequence's (each has its own: log_initial)
            initial = self.stationary_initial(coefficients)[0]
        else:
            log_initial = np.concatenate([[0.0], z[self.blocks["initial"]]])
            initial = np.exp(log_initial - np.logaddexp.reduce(log_initial))
        return replace(
            template,
            initial=initial,
            transition=transition,
            coefficients=None if transition is not None else coefficients,
        ).with_emissions(emissions)

    def stationary_initial(self, coefficients: np.ndarray) -> np.ndarray:
        """:func:`stationary_starts` of ``coefficients`` (K*(K-1), p): (n_sequences, K) with
        covariates, (1, K) without."""
        design = np.ones((1, 1)) if self.start_design is None else self.start_design
        return stationary_starts(coefficients, design)

    def stationary_jacobian(self, coefficients: np.ndarray) -> np.ndarray:
        """``d delta / d coefficients`` of :meth:`stationary_initial` flattened, by central
        differences, shape (n * K, K*(K-1)*p) (n sequences, 1 without covariates)."""
        flat = coefficients.ravel()
        columns = []
        for i in range(flat.size):
            shift = np.zeros(flat.size)
            shift[i] = _JACOBIAN_STEP * max(1.0, abs(flat[i]))
            up = self.stationary_initial((flat + shift).reshape(coefficients.shape))
            down = self.stationary_initial((flat - shift).reshape(coefficients.shape))
            columns.append((up - down).ravel() / (2 * shift[i]))
        return np.stack(columns, axis=1)

    def pack(self, params) -> np.ndarray:
        """The free vector of ``params`` (projected onto the constraints)."""
        return self.reduce(self.z_of(params))

    def unpack(self, phi: np.ndarray):
        """The parameters of the free vector ``phi``."""
        return self.parameters(self.expand(phi))

    def project(self, params):
        """``params`` moved onto the constraints: fixed values set, tied values averaged on
        the link scale, a stationary initial distribution."""
        return self.unpack(self.pack(params))

    def touches(self, block: str) -> bool:
        """True when a fixed or tied entry lies in ``block`` (a stream, ``"transition"``)."""
        part = self.blocks[block]
        tied = self.counts[self._classes_in(block)] > 1
        return bool(not self.free[part].all() or tied.any())

    def _classes_in(self, block: str) -> np.ndarray:
        """The classes of the free entries of ``block``."""
        part = self.blocks[block]
        before = int(self.free[: part.start].sum())
        return self.classes[before : before + int(self.free[part].sum())]

    def maximise_block(self, block: str, z: np.ndarray, objective, start_z: np.ndarray):
        """Maximise ``objective(z_block) -> (value, gradient by z_block)`` over the free
        entries of ``block``, the rest of ``z`` held; BFGS from ``start_z``'s block projected
        onto the constraints. Returns the new ``z``, or ``z`` when that is not better.

        This is the constrained M-step of one stream or of the transition coefficients: the
        expected complete-data log-likelihood of tied states is the sum of theirs, so the
        optimum pools their weighted data (their sufficient statistics) exactly.
        """
        part = self.blocks[block]
        classes = np.unique(self._classes_in(block))
        if classes.size == 0:
            return z
        phi_all = self.reduce(z)

        def expanded(values):
            phi = phi_all.copy()
            phi[classes] = values
            return self.expand(phi)[part]

        def negative(values):
            try:
                value, gradient = objective(expanded(values))
            except (ValueError, FloatingPointError):
                return np.inf, np.zeros_like(values)
            if not np.isfinite(value):
                return np.inf, np.zeros_like(values)
            full = np.zeros(self.size_z)
            full[part] = gradient
            return -value, -self.reduce_gradient(full)[classes]

        current = negative(phi_all[classes])[0]
        start = self.reduce(np.concatenate([z[: part.start], start_z[part], z[part.stop :]]))
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            result = minimize(negative, start[classes], jac=True, method="BFGS")
        if not (np.isfinite(result.fun) and result.fun <= current):
            return z
        out = z.copy()
        out[part] = expanded(result.x)
        return out
