"""The fitted movement HMM: a small frozen dataclass and its versioned JSON file.

:class:`MovementHMM` holds everything a user of a fitted model needs -- the initial
distribution, the transition matrix (or the logit coefficients of covariates on it), the
state-dependent step and angle distributions, the time step of the data it was fitted on, the
transition formula's design (:class:`hmmtrack.hmm.formula.Design`) -- and answers questions
about it: transition matrices, the stationary distribution, state
probabilities and Viterbi paths for data, simulation -- and builds the model with a
resting state added for tracking (:meth:`MovementHMM.with_resting_state`).
:meth:`MovementHMM.save` / :meth:`MovementHMM.load` write and read the JSON schema
``"hmmtrack.movement_hmm"``: version 2, version 3 for a model with emission formulas
(:mod:`hmmtrack.hmm.emission`: a distribution block with a ``formulas`` block) or further
streams, version 4 for a model with state names or fit control (fixed parameters, equality
constraints, a stationary initial distribution: :mod:`hmmtrack.hmm.constraints`); each is
written only when needed, so that older readers keep reading every other model. Version 1
files, whose covariates were plain columns, still load; loading validates every field and refuses
anything it does not understand. There is no pickle.

This module is not for fitting (see :mod:`hmmtrack.hmm.fit`) nor for the recursions (see
:mod:`hmmtrack.hmm.inference`).
"""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack import __version__
from hmmtrack.hmm import covariates as cov
from hmmtrack.hmm import distributions, emission
from hmmtrack.hmm.constraints import FitControl, stationary_distribution, stationary_starts
from hmmtrack.hmm.formula import Design, design_rows, of_columns
from hmmtrack.hmm.inference import forward_backward, viterbi

SCHEMA = "hmmtrack.movement_hmm"
VERSION = 4  # written for models with state names or fit control
_FORMULA_VERSION = 3  # models with emission formulas or further streams
_PLAIN_VERSION = 2
_READABLE_VERSIONS = (1, 2, 3, 4)
# The fields of a model document (see MovementHMM.to_dict), in file order; no others are read.
_FIELDS = (
    "schema", "version", "package_version", "units", "n_states", "dt", "initial", "transition",
    "coefficients", "step", "angle", "streams", "log_likelihood", "n_obs", "aic", "bic",
    "state_names", "control",
)  # fmt: skip
_VERSION_4_FIELDS = ("state_names", "control")  # refused in files of an older version
_UNITS = {"step": "m", "angle": "rad", "dt": "s"}
DT_TOLERANCE = 0.1  # a time step more than 10 % from the reference one is another step
# the fields of the coefficients block, by file version
_COEFFICIENT_FIELDS = {
    1: ("covariates", "scaling", "values", "layout"),
    2: ("formula", "columns", "scaling", "levels", "values", "values_data_scale", "layout"),
}
_COEFFICIENT_FIELDS[3] = _COEFFICIENT_FIELDS[4] = _COEFFICIENT_FIELDS[2]


@dataclass(frozen=True)
class Observations:
    """Steps, angles and sequence lengths pulled out of a prepared-track table.

    Attributes
    ----------
    step : ndarray, shape (T,)
        Step lengths (m); NaN where missing.
    angle : ndarray, shape (T,)
        Turning angles (rad); NaN where missing.
    lengths : ndarray, shape (n_sequences,)
        Rows per sequence (track segment), in table order; sums to ``T``.
    design : ndarray, shape (T, p) or None
        The transition formula's standardised design matrix; None without a formula.
    emission : dict
        ``{stream: {parameter: (T, p_j) design matrix}}`` of the emission formulas; empty
        without.
    streams : dict of str to ndarray, shape (T,)
        Further data streams by column name (NaN where missing); empty without.
    """

    step: np.ndarray
    angle: np.ndarray
    lengths: np.ndarray
    design: np.ndarray | None = None
    emission: dict = field(default_factory=dict)
    streams: dict = field(default_factory=dict)

    @classmethod
    def from_frame(
        cls,
        frame: pd.DataFrame,
        design: Design | None = None,
        source: str | None = None,
        emission_designs: dict | None = None,
        streams: tuple[str, ...] = (),
    ):
        """Read ``step``, ``angle``, ``segment`` (and the design) from a prepared-track table.

        Parameters
        ----------
        frame : DataFrame
            Prepared track (see :func:`hmmtrack.tracks.prepare`). Without a ``segment``
            column the table is one sequence. Each segment's rows must be contiguous.
        design : Design, optional
            The transition formula's design, evaluated on ``frame``; its columns must be
            finite in every row.
        source : str, optional
            Name of the table's origin used in error messages; by default the file name that
            :mod:`hmmtrack.io` keeps in ``frame.attrs["source"]``, else ``"table"``.
        emission_designs : dict, optional
            ``{stream: {parameter: Design}}`` of the emission formulas, evaluated on
            ``frame`` like ``design``.
        streams : tuple of str
            Columns of further data streams to read.
        """
        source = source or frame.attrs.get("source", "table")
        missing = [c for c in ("step", "angle", *streams) if c not in frame.columns]
        if missing:
            raise ValueError(
                f"{source}: missing column(s) {missing}; a prepared track needs 'step' (m) and "
                f"'angle' (rad) (and 'segment'), and a column per further stream; columns "
                f"present: {list(frame.columns)}"
            )
        values = {}
        for name in ("step", "angle", *streams):
            try:
                values[name] = np.asarray(frame[name], dtype=float)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{source}: column {name!r} is not numeric ({exc})") from exc
        negative = np.flatnonzero(values["step"] < 0)
        if negative.size:
            raise ValueError(
                f"{source}: column 'step' has negative values at rows {negative[:10].tolist()}"
            )
        if "segment" in frame.columns:
            segment = frame["segment"].to_numpy()
            change = np.flatnonzero(segment[1:] != segment[:-1]) + 1
            starts = np.concatenate([[0], change])
            labels = segment[starts]
            if len(set(labels)) != len(labels):
                seen, repeated = set(), None
                for label in labels:
                    if label in seen:
                        repeated = label
                        break
                    seen.add(label)
                raise ValueError(
                    f"{source}: rows of segment {repeated!r} are not contiguous; sort the "
                    "table by segment and time"
                )
            lengths = np.diff(np.concatenate([starts, [len(frame)]]))
        else:
            lengths = np.array([len(frame)])
        return cls(
            step=values["step"],
            angle=values["angle"],
            lengths=lengths.astype(np.int64),
            design=None if design is None else design_rows(design, frame, source),
            emission={
                stream: {name: design_rows(d, frame, source) for name, d in designs.items()}
                for stream, designs in (emission_designs or {}).items()
            },
            streams={name: values[name] for name in streams},
        )


@dataclass(frozen=True, eq=False)
class MovementHMM:
    """A fitted N-state movement HMM of step lengths and turning angles.

    Attributes
    ----------
    initial : ndarray, shape (K,)
        Probability of each state at the first row of a sequence (with a stationary start
        and transition covariates, of the first sequence: :meth:`log_initial_for`).
    transition : ndarray, shape (K, K) or None
        Row-stochastic transition matrix; ``None`` when ``coefficients`` are given.
    step, angle : StateDistribution
        State-dependent distributions of step length (m) and turning angle (rad).
    streams : dict of str to StateDistribution
        Further data streams (a dive depth, counts) by the name of their column, each with
        its family (:data:`hmmtrack.hmm.distributions.VALUE_FAMILIES`); empty without.
    dt : float
        Time step of the data fitted (s); NaN when the data had no times.
    coefficients : ndarray, shape (K*(K-1), p) or None
        Logit coefficients of the standardised design columns (see
        :mod:`~hmmtrack.hmm.covariates`), one row per off-diagonal entry.
    transition_design : Design or None
        The transition formula (``"~ dist_water"``) with its columns, standardisation and
        factor levels; rebuilds the design of new data. Given exactly with ``coefficients``.
    step_unit : str
        Unit of the steps (``"m"``; ``"km"`` if the user fitted kilometres).
    log_likelihood : float
        Maximised log-likelihood (NaN if unknown).
    n_obs : int
        Number of rows (time points) fitted; positive when ``log_likelihood`` is known.
    aic, bic : float
        ``-2 logL + 2 p`` and ``-2 logL + p log(n_obs)`` for ``p`` free parameters (NaN if
        unknown); the constructor refuses values that do not follow from ``log_likelihood``.
    control : FitControl
        The fixed parameters, equality constraints and stationary initial distribution the
        model was fitted under (:mod:`hmmtrack.hmm.constraints`; empty without); intervals
        and refits hold them.
    state_names : tuple of str or None
        A name per state (``("encamped", "exploratory")``), in state order; None without.

    Raises
    ------
    ValueError
        When constructed with shapes that disagree, an ``initial`` or ``transition`` that is not
        row-stochastic, or a contradictory fit summary.
    """

    initial: np.ndarray
    transition: np.ndarray | None
    step: distributions.StateDistribution
    angle: distributions.StateDistribution
    dt: float = math.nan
    coefficients: np.ndarray | None = None
    transition_design: Design | None = None
    step_unit: str = "m"
    log_likelihood: float = math.nan
    n_obs: int = 0
    aic: float = math.nan
    bic: float = math.nan
    streams: dict = field(default_factory=dict)
    control: FitControl = field(default_factory=FitControl)
    state_names: tuple[str, ...] | None = None

    def __post_init__(self):
        initial = np.asarray(self.initial, dtype=float)
        object.__setattr__(self, "initial", initial)
        if self.state_names is not None:
            names = tuple(str(name).strip() for name in self.state_names)
            check_state_names(initial.shape[0] if initial.ndim == 1 else -1, names)
            object.__setattr__(self, "state_names", names)
        if (self.transition is None) == (self.coefficients is None):
            raise ValueError("give exactly one of 'transition' and 'coefficients'")
        if self.transition is not None:
            if self.transition_design is not None:
                raise ValueError("a 'transition_design' goes with 'coefficients'")
            object.__setattr__(self, "transition", np.asarray(self.transition, dtype=float))
        else:
            coefficients = np.asarray(self.coefficients, dtype=float)
            object.__setattr__(self, "coefficients", coefficients)
            design = self.transition_design
            if design is None or coefficients.shape[1] != len(design.columns):
                raise ValueError(
                    f"coefficients have {coefficients.shape[1]} columns; expected one per "
                    "column of 'transition_design'"
                )
            if not design.has_intercept:
                raise ValueError(f"transition formula {design.formula!r} needs an intercept")
        k = initial.shape[0] if initial.ndim == 1 else -1
        shapes = {
            "initial": (initial.shape, (k,)),
            "step": ((self.step.n_states,), (k,)),
            "angle": ((self.angle.n_states,), (k,)),
            **{name: ((dist.n_states,), (k,)) for name, dist in self.streams.items()},
        }
        if self.transition is not None:
            shapes["transition"] = (self.transition.shape, (k, k))
        else:
            shapes["coefficients"] = (self.coefficients.shape[:1], (k * (k - 1),))
        for name, (shape, expected) in shapes.items():
            if shape != expected:
                raise ValueError(f"{name} has shape {shape}; expected {expected} for K = {k}")
        for name in ("initial", "transition"):
            values = getattr(self, name)
            if values is not None and not _is_stochastic(values):
                raise ValueError(
                    f"{name} must hold finite non-negative numbers with each row summing to 1, "
                    f"got {values.tolist()}"
                )
        _check_fit_summary(self.log_likelihood, self.n_obs, self.aic, self.bic)

    @property
    def n_states(self) -> int:
        """Number of hidden states ``K``."""
        return self.initial.shape[0]

    # -- transition probabilities ------------------------------------------------------------

    def transition_matrix(self, covariates: pd.DataFrame | dict | None = None) -> np.ndarray:
        """Transition matrix, or one per row of covariate values.

        Parameters
        ----------
        covariates : DataFrame or mapping of str to array, optional
            Raw (unstandardised) values of the columns the transition formula names.
            Without it a covariate model is evaluated at its intercept: numeric covariates
            at their means, factors at their reference levels.

        Returns
        -------
        ndarray, shape (K, K) or (T, K, K)
            Entry ``t`` of the 3-d result is the matrix *into* row ``t``.
        """
        if self.coefficients is None:
            if covariates is not None:
                raise ValueError("this model has no covariates")
            return self.transition.copy()
        if covariates is None:
            intercept = self.coefficients[:, [self.transition_design.columns.index("Intercept")]]
            return np.exp(cov.log_transition_matrices(intercept, np.ones((1, 1))))[0]
        design = design_rows(self.transition_design, covariates, "covariates")
        return np.exp(cov.log_transition_matrices(self.coefficients, design))

    def stationary(self, covariates: pd.DataFrame | dict | None = None) -> np.ndarray:
        """Stationary distribution of :meth:`transition_matrix` (``delta = delta Gamma``).

        Returns
        -------
        ndarray, shape (K,) or (T, K)
        """
        return stationary_distribution(self.transition_matrix(covariates))

    def log_initial_for(self, observations: Observations) -> np.ndarray:
        """Log initial distribution for the recursions: ``(K,)``, or ``(n_sequences, K)``
        when the model was fitted with a stationary start and has transition covariates:
        each sequence (animal's track segment) starts in the stationary distribution of its
        transition matrix at its first row."""
        initial = self.initial
        if self.control.stationary and self.coefficients is not None:
            starts = np.cumsum(observations.lengths) - observations.lengths
            initial = stationary_starts(self.coefficients, observations.design[starts])
        with np.errstate(divide="ignore"):
            return np.log(initial)

    def log_transition_for(self, observations: Observations) -> np.ndarray:
        """Log transition argument for the recursions: ``(K, K)`` or ``(T-1, K, K)``.

        ``observations`` are read with this model's ``transition_design``. Entry ``t`` of the
        time-varying form is the transition from row ``t`` to ``t + 1``, built from the
        design row ``t + 1``.
        """
        if self.coefficients is None:
            with np.errstate(divide="ignore"):
                return np.log(self.transition)
        return cov.log_transition_matrices(self.coefficients, observations.design[1:])

    def coefficients_on_data_scale(self) -> np.ndarray | None:
        """The logit coefficients per unit of each design column as the data have it.

        Returns
        -------
        ndarray, shape (K*(K-1), p) or None
            :meth:`hmmtrack.hmm.formula.Design.to_data_scale` of ``coefficients``: slopes
            per raw unit, intercept at raw zero. None without covariates.
        """
        if self.coefficients is None:
            return None
        return self.transition_design.to_data_scale(self.coefficients)

    def with_resting_state(
        self, enter_per_hour: float, leave_per_hour: float, resting_step: float
    ) -> MovementHMM:
        """This model with one more behavioural state, "resting": a tag that stays put.

        A tracked tag can be at rest although the fitted animal always swims: a shed tag,
        a dead animal (what mortality and shed-tag checks look for), an animal resting on
        the bottom. The resting state is appended as state ``K`` (the last). Its steps have
        mean and standard deviation ``resting_step`` (a slow drift in a uniform direction:
        the step family's member of those moments, turning angles uniform, concentration
        0); a strictly motionless state would let a particle filter's copies of one resting
        particle pile up on a single point. Every swimming state enters it with probability
        ``p_enter = 1 - exp(-enter_per_hour * dt / 3600)`` per fitted step ``dt`` (the rest
        of its row scaled by ``1 - p_enter``); the resting state is left with probability
        ``p_leave = 1 - exp(-leave_per_hour * dt / 3600)``, into the swimming states in
        proportion to their stationary distribution ``pi``. The stationary distribution of
        the result is then exactly ``((1 - r) pi, r)`` with resting share
        ``r = p_enter / (p_enter + p_leave)`` (about ``enter / (enter + leave)`` when both
        rates are much slower than ``1 / dt``): the swimming states keep their relative
        shares. ``initial`` becomes ``((1 - r) initial, r)``.

        This is a prior added at tracking time, not a fitted model: the log-likelihood, AIC
        and BIC of the result are unknown (NaN). ``self`` is unchanged. A covariate model
        contributes its matrix at the covariate means (what the tracking filter moves
        particles with, :class:`hmmtrack.tracking.motion.HMMMotion`); the result has no covariates.

        Parameters
        ----------
        enter_per_hour : float
            Rate (per hour, >= 0) at which a swimming animal comes to rest.
        leave_per_hour : float
            Rate (per hour, > 0) at which a resting tag starts swimming again (mean rest
            ``1 / leave_per_hour`` h).
        resting_step : float
            Mean (and standard deviation) of the resting state's steps per ``dt``, in
            ``step_unit`` (> 0).

        Returns
        -------
        MovementHMM
            ``K + 1`` states; saved and loaded like any model.

        Raises
        ------
        ValueError
            For a model without a time step, or rates or a step that are not finite numbers
            in range.
        """
        if self.emission_designs or self.streams:
            raise ValueError(
                "with_resting_state needs a model of steps and angles only, without emission "
                "formulas (one step and angle distribution per state)"
            )
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(
                f"with_resting_state needs the fitted time step (model.dt = {self.dt}) to turn "
                "rates per hour into probabilities per step"
            )
        checks = {
            "enter_per_hour": (enter_per_hour, enter_per_hour >= 0, ">= 0"),
            "leave_per_hour": (leave_per_hour, leave_per_hour > 0, "> 0"),
            "resting_step": (resting_step, resting_step > 0, "> 0"),
        }
        for name, (value, ok, expected) in checks.items():
            if not (math.isfinite(value) and ok):
                raise ValueError(f"{name} must be a finite number {expected}, got {value}")
        k = self.n_states
        p_enter = -math.expm1(-enter_per_hour * self.dt / 3600.0)
        p_leave = -math.expm1(-leave_per_hour * self.dt / 3600.0)
        resting_share = p_enter / (p_enter + p_leave)
        transition = np.zeros((k + 1, k + 1))
        transition[:k, :k] = (1.0 - p_enter) * self.transition_matrix()
        transition[:k, k] = p_enter
        transition[k, :k] = p_leave * self.stationary()
        transition[k, k] = 1.0 - p_leave
        resting = type(self.step).from_moments([resting_step], [resting_step]).to_dict()
        if self.step.zero_mass is not None:
            resting["zero_mass"] = [0.0]
        step = _appended(self.step, resting)
        angle = _appended(self.angle, {"mean": [0.0], "concentration": [0.0]})
        return MovementHMM(
            initial=np.append((1.0 - resting_share) * self.initial, resting_share),
            transition=transition,
            step=distributions.from_dict(step),
            angle=distributions.from_dict(angle),
            dt=self.dt,
            step_unit=self.step_unit,
            n_obs=self.n_obs,
        )

    # -- data ---------------------------------------------------------------------------------

    @property
    def emissions(self) -> dict:
        """Every stream's distribution by name: ``step``, ``angle``, then ``streams``."""
        return {"step": self.step, "angle": self.angle, **self.streams}

    @property
    def emission_designs(self) -> dict:
        """``{stream: {parameter: Design}}`` of the emission formulas; empty without."""
        return {
            stream: dist.designs
            for stream, dist in self.emissions.items()
            if isinstance(dist, emission.CovariateEmission)
        }

    def log_likelihood_matrix(self, observations: Observations) -> np.ndarray:
        """State-dependent log densities of each row, shape ``(T, K)``; missing values add 0.

        ``observations`` are read with this model's formulas (:meth:`observations`): an
        emission formula gives each row its own parameters.
        """
        inputs = self.stream_inputs(observations)
        return sum(dist.logpdf(inputs[name]) for name, dist in self.emissions.items())

    def stream_inputs(self, observations: Observations) -> dict:
        """What each stream's distribution is evaluated on, by stream name: its prepared
        observations, or their :class:`~hmmtrack.hmm.emission.EmissionRows` when the stream
        has emission formulas."""
        prepared = {
            "step": distributions.prepare_steps(observations.step),
            "angle": distributions.prepare_angles(observations.angle),
            **{n: distributions.prepare_values(x) for n, x in observations.streams.items()},
        }
        return {
            name: emission.stream_input(prepared[name], observations.emission.get(name))
            for name in self.emissions
        }

    def observations(self, data: pd.DataFrame) -> Observations:
        """The :class:`Observations` of a prepared track with this model's transition and
        emission formulas evaluated on it."""
        return Observations.from_frame(
            data,
            self.transition_design,
            emission_designs=self.emission_designs,
            streams=tuple(self.streams),
        )

    def check_time_step(self, data: pd.DataFrame) -> None:
        """Refuse a prepared track whose time step is not the model's.

        Steps and turning angles over another duration are other quantities (a 1 s step is not
        a 120 s step), so states decoded from them are meaningless. The track's step is the
        median of its ``dt`` column (s); it must be within ``DT_TOLERANCE`` (10 %) of
        :attr:`dt`. Nothing is checked when the model or the track has no time step.

        Raises
        ------
        ValueError
            Naming both steps and the functions that regularise a track to the model's step.
        """
        dt = time_steps(data)
        if not math.isfinite(self.dt) or dt.size == 0:
            return
        median = float(np.median(dt))
        if abs(median - self.dt) > DT_TOLERANCE * self.dt:
            source = data.attrs.get("source", "the track")
            raise ValueError(
                f"{source}: time step {median:g} s (median of 'dt') is not the model's "
                f"{self.dt:g} s (model.dt); steps and turning angles over another duration are "
                f"other quantities. Regularise the track to {self.dt:g} s first (hmmtrack "
                f"fit/decode --regularise {self.dt:g}; in Python "
                f"hmmtrack.tracks.regularise(tracks, {self.dt:g}) or "
                f"hmmtrack.hmm.crw.regularise(tracks, {self.dt:g})), or accept the difference"
                " (--allow-other-step; allow_other_step=True)"
            )

    def _recursion_inputs(self, data: pd.DataFrame, allow_other_step: bool):
        if not allow_other_step:
            self.check_time_step(data)
        obs = self.observations(data)
        return (
            self.log_initial_for(obs),
            self.log_transition_for(obs),
            self.log_likelihood_matrix(obs),
            obs.lengths,
        )

    def state_probabilities(
        self, data: pd.DataFrame, *, allow_other_step: bool = False
    ) -> np.ndarray:
        """Posterior state probabilities of each row of a prepared track, shape ``(T, K)``.

        A track at another time step than the model's is refused (:meth:`check_time_step`)
        unless ``allow_other_step``; so in :meth:`score` and :meth:`viterbi`.
        """
        return forward_backward(*self._recursion_inputs(data, allow_other_step)).posterior

    def score(self, data: pd.DataFrame, *, allow_other_step: bool = False) -> float:
        """Log-likelihood of a prepared track under this model."""
        inputs = self._recursion_inputs(data, allow_other_step)
        return float(forward_backward(*inputs).log_likelihood)

    def viterbi(self, data: pd.DataFrame, *, allow_other_step: bool = False) -> np.ndarray:
        """Most probable state sequence of a prepared track, shape ``(T,)``, states 0..K-1."""
        return viterbi(*self._recursion_inputs(data, allow_other_step))

    def simulate(
        self, rng: np.random.Generator, n: int, covariates: pd.DataFrame | dict | None = None
    ) -> pd.DataFrame:
        """Simulate one sequence of states, steps and angles.

        Parameters
        ----------
        rng : numpy.random.Generator
        n : int
            Number of rows.
        covariates : DataFrame or mapping, optional
            ``n`` rows of raw covariate values (covariate models only; without them the
            matrix at the covariate means is used). Required by emission formulas.

        Returns
        -------
        DataFrame
            Columns ``state`` (int), ``step`` (``step_unit``), ``angle`` (rad), then one per
            further stream.
        """
        gamma = self.transition_matrix(None if self.coefficients is None else covariates)
        if gamma.ndim == 2:
            gamma = np.broadcast_to(gamma, (n, *gamma.shape))
        elif gamma.shape[0] != n:
            raise ValueError(f"covariates have {gamma.shape[0]} rows; expected n = {n}")
        states = np.empty(n, dtype=np.int64)
        uniforms = rng.random(n)
        cumulative = np.cumsum(gamma, axis=2)
        states[0] = np.searchsorted(np.cumsum(self.initial), uniforms[0] * self.initial.sum())
        for t in range(1, n):
            row = cumulative[t, states[t - 1]]
            states[t] = min(np.searchsorted(row, uniforms[t] * row[-1]), self.n_states - 1)
        draws = {}
        for stream, dist in self.emissions.items():
            if isinstance(dist, emission.CovariateEmission):
                if covariates is None:
                    raise ValueError(f"the {stream} formulas need n rows of covariates")
                draws[stream] = dist.sample(rng, states, dist.matrices(covariates, "covariates"))
            else:
                draws[stream] = dist.sample(rng, states)
        return pd.DataFrame({"state": states, **draws})

    # -- file ---------------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """The JSON document of this model (plain Python types)."""
        if self.state_names is not None or self.control:
            version = VERSION
        elif self.emission_designs or self.streams:
            version = _FORMULA_VERSION
        else:
            version = _PLAIN_VERSION
        return {
            "schema": SCHEMA,
            "version": version,
            "package_version": __version__,
            "units": {"step": self.step_unit, "angle": "rad", "dt": "s"},
            "n_states": self.n_states,
            "dt": None if math.isnan(self.dt) else float(self.dt),
            "initial": self.initial.tolist(),
            "transition": None if self.transition is None else self.transition.tolist(),
            "coefficients": None
            if self.coefficients is None
            else {
                **self.transition_design.to_dict(),
                "values": self.coefficients.tolist(),
                "values_data_scale": self.coefficients_on_data_scale().tolist(),
                "layout": "rows: off-diagonal entries (i, j) row-major; columns: 'columns' of "
                "the formula's design, standardised ('scaling': (raw - centre) / sd) in "
                "'values', raw in 'values_data_scale' (not read back)",
            },
            "step": self.step.to_dict(),
            "angle": self.angle.to_dict(),
            **(
                {"streams": {name: d.to_dict() for name, d in self.streams.items()}}
                if self.streams
                else {}
            ),
            "log_likelihood": _float_or_none(self.log_likelihood),
            "n_obs": int(self.n_obs),
            "aic": _float_or_none(self.aic),
            "bic": _float_or_none(self.bic),
            **({"state_names": list(self.state_names)} if self.state_names is not None else {}),
            **({"control": self.control.to_dict()} if self.control else {}),
        }

    def save(self, path: str | Path) -> None:
        """Write the model as JSON (schema ``hmmtrack.movement_hmm``, version 2; version 3
        when it has emission formulas or further streams, version 4 with state names or fit
        control, which older readers do not know)."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n", encoding="utf-8")

    @classmethod
    def load(cls, path: str | Path) -> MovementHMM:
        """Read and validate a model file written by :meth:`save`.

        Raises
        ------
        ValueError
            Naming the file and the field, for an unknown schema or version, an unknown
            (e.g. misspelt) field, a missing or malformed field, probabilities that are not
            probabilities, or a log-likelihood, ``n_obs``, AIC and BIC that contradict each
            other.
        """
        path = Path(path)
        try:
            document = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not a JSON file ({exc})") from exc
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not a JSON file (not UTF-8 text: {exc.reason})") from exc
        return cls.from_dict(document, source=str(path))

    @classmethod
    def from_dict(cls, document: dict, source: str = "model") -> MovementHMM:
        """Validate a JSON document (see :meth:`to_dict`) and build the model."""
        reader = _Reader(document, source)
        schema = reader.get("schema", str)
        if schema != SCHEMA:
            reader.fail("schema", f"is {schema!r}; expected {SCHEMA!r}")
        version = reader.get("version", int)
        if version not in _READABLE_VERSIONS:
            reader.fail(
                "version", f"is {version}; this hmmtrack reads versions {_READABLE_VERSIONS}"
            )
        valid = [f for f in _FIELDS if version >= VERSION or f not in _VERSION_4_FIELDS]
        reader.known_keys("", document, valid)
        n_states = reader.get("n_states", int)
        if n_states < 1:
            reader.fail("n_states", f"is {n_states}; expected a positive integer")
        units = reader.get("units", dict)
        reader.known_keys("units.", units, _UNITS)
        step_unit = units.get("step")
        if not isinstance(step_unit, str):
            reader.fail("units.step", "missing or not a string")
        for name in ("angle", "dt"):
            if units.get(name, _UNITS[name]) != _UNITS[name]:
                reader.fail(f"units.{name}", f"is {units[name]!r}; expected {_UNITS[name]!r}")
        initial = reader.probabilities("initial", (n_states,))
        step = reader.distribution("step", n_states)
        angle = reader.distribution("angle", n_states)
        streams = {}
        if document.get("streams") is not None:
            block = reader.get("streams", dict)
            streams = {
                str(name): reader.distribution(f"streams.{name}", n_states, block) for name in block
            }
        transition = coefficients = design = None
        if document.get("transition") is not None:
            transition = reader.probabilities("transition", (n_states, n_states))
        else:
            if document.get("coefficients") is None:
                reader.fail("coefficients", "is missing; a model needs 'transition' or it")
            block = reader.get("coefficients", dict)
            reader.known_keys("coefficients.", block, _COEFFICIENT_FIELDS[version])
            try:
                design = Design.from_dict(block if version > 1 else _version_1_design(block))
                coefficients = np.array(block["values"], dtype=float)
            except (KeyError, TypeError, ValueError) as exc:
                reader.fail("coefficients", f"malformed ({exc!r})")
            if not design.has_intercept:
                reader.fail("coefficients.formula", f"{design.formula!r} has no intercept")
            expected = (n_states * (n_states - 1), len(design.columns))
            if coefficients.shape != expected or not np.all(np.isfinite(coefficients)):
                reader.fail(
                    "coefficients.values",
                    f"has shape {coefficients.shape}; expected {expected} finite numbers",
                )
        control = FitControl()
        if "control" in document:
            try:
                control = FitControl.from_dict(document["control"])
            except ValueError as exc:
                reader.fail("control", f"is malformed ({exc})")
        state_names = document.get("state_names")
        if "state_names" in document and not (
            isinstance(state_names, list) and all(isinstance(n, str) for n in state_names)
        ):
            reader.fail("state_names", f"is {state_names!r}; expected a list of names")
        dt = document.get("dt")
        if dt is not None and not (isinstance(dt, int | float) and dt > 0):
            reader.fail("dt", f"is {dt!r}; expected a positive number of seconds or null")
        try:
            return cls(
                initial=initial,
                transition=transition,
                step=step,
                angle=angle,
                dt=math.nan if dt is None else float(dt),
                coefficients=coefficients,
                transition_design=design,
                step_unit=step_unit,
                log_likelihood=reader.number("log_likelihood"),
                n_obs=reader.get("n_obs", int),
                aic=reader.number("aic"),
                bic=reader.number("bic"),
                streams=streams,
                control=control,
                state_names=None if state_names is None else tuple(state_names),
            )
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from exc


def _version_1_design(block: dict) -> dict:
    """The design document of a version 1 coefficients block (plain covariate columns)."""
    names = list(block["covariates"])
    if not all(isinstance(n, str) for n in names):
        raise ValueError("'covariates' must be a list of names")
    scaling = block["scaling"]
    return {
        "formula": of_columns(names),
        "columns": ["Intercept", *names],
        "scaling": {n: {"centre": scaling[n]["mean"], "sd": scaling[n]["sd"]} for n in names},
    }


def check_state_names(n_states: int, state_names: Sequence[str] | None) -> None:
    """Refuse state names that are not one distinct, non-empty name per state."""
    if state_names is None:
        return
    names = [str(n).strip() for n in state_names]
    if len(names) != n_states or len(set(names)) != n_states or not all(names):
        raise ValueError(
            f"state names {list(state_names)} for {n_states} states: give {n_states} distinct "
            "non-empty names, in state order (state 1 first)"
        )


def time_steps(table: pd.DataFrame) -> np.ndarray:
    """The finite entries of a prepared track's ``dt`` column (s); empty without one."""
    if "dt" not in table.columns:
        return np.empty(0)
    dt = np.asarray(table["dt"], dtype=float)
    return dt[np.isfinite(dt)]


def _appended(distribution, extra: dict) -> dict:
    """The document of ``distribution`` (K states) with the per-state parameters (lists) of
    the one-state document ``extra`` appended as state ``K``."""
    document = distribution.to_dict()
    for name, values in extra.items():
        if isinstance(values, list):
            document[name] = [*document[name], *values]
    return document


def _float_or_none(value: float) -> float | None:
    return None if value is None or math.isnan(value) else float(value)


def _is_stochastic(values: np.ndarray) -> bool:
    """True for finite non-negative numbers whose last axis sums to 1 (to 1e-6)."""
    return bool(
        np.all(np.isfinite(values))
        and np.all(values >= 0)
        and np.all(np.abs(values.sum(axis=-1) - 1) <= 1e-6)
    )


def _check_fit_summary(log_likelihood: float, n_obs, aic: float, bic: float) -> None:
    """Refuse a fit summary whose numbers contradict each other.

    ``n_obs`` is a non-negative integer, positive once a log-likelihood is known. AIC and BIC
    are what :func:`hmmtrack.hmm.fit.information_criteria` makes of the log-likelihood:
    ``AIC = -2 logL + 2 p`` and ``BIC = -2 logL + p log n_obs`` for one whole number ``p`` of
    free parameters. The file does not store ``p`` (it depends on fitting options such as
    fixed angle means), so ``p`` is recovered from one criterion and the other must agree.
    """
    if isinstance(n_obs, bool) or not isinstance(n_obs, int | np.integer) or n_obs < 0:
        raise ValueError(f"n_obs is {n_obs!r}; expected a non-negative integer (rows fitted)")
    if math.isnan(log_likelihood):
        given = [name for name, value in (("aic", aic), ("bic", bic)) if not math.isnan(value)]
        if given:
            raise ValueError(f"{' and '.join(given)} given without the log-likelihood")
        return
    if n_obs == 0:
        raise ValueError("n_obs is 0 but a log-likelihood is given; expected the rows fitted")
    deviance = -2.0 * log_likelihood
    per_parameter = {"aic": 2.0, "bic": math.log(n_obs)}
    values = {name: value for name, value in (("aic", aic), ("bic", bic)) if not math.isnan(value)}
    first = next(iter(values), None)
    if first is None or per_parameter[first] == 0:  # no criterion, or BIC of a single row
        return
    n_parameters = (values[first] - deviance) / per_parameter[first]
    tolerance = 1e-6 * max(1.0, abs(deviance))
    if n_parameters < 0.5 or abs(n_parameters - round(n_parameters)) * 2.0 > tolerance:
        raise ValueError(
            f"{first} = {values[first]!r} does not follow from log_likelihood = "
            f"{log_likelihood!r}: {first} - (-2 logL) = {values[first] - deviance:.6g} is not "
            f"{per_parameter[first]:.6g} times a positive whole number of parameters"
        )
    n_parameters = round(n_parameters)
    for name, value in values.items():
        expected = deviance + per_parameter[name] * n_parameters
        if abs(value - expected) > tolerance:
            raise ValueError(
                f"{name} = {value!r} contradicts log_likelihood = {log_likelihood!r}, "
                f"n_obs = {n_obs} and the {n_parameters} parameters implied by {first}: "
                f"expected {expected!r}"
            )


class _Reader:
    """Field access on a model document with errors naming the source and field."""

    def __init__(self, document, source: str):
        if not isinstance(document, dict):
            raise ValueError(f"{source}: expected a JSON object at the top level")
        self.document = document
        self.source = source

    def fail(self, name: str, message: str):
        raise ValueError(f"{self.source}: field {name!r} {message}")

    def known_keys(self, prefix: str, block: dict, valid) -> None:
        """Refuse keys of ``block`` outside ``valid``, naming them, a likely intended key and
        the valid ones (a misspelt field would otherwise be silently ignored)."""
        unknown = sorted(set(block) - set(valid))
        if unknown:
            guesses = {u: difflib.get_close_matches(u, list(valid), n=1) for u in unknown}
            hints = "".join(f" ({u!r}: did you mean {g[0]!r}?)" for u, g in guesses.items() if g)
            raise ValueError(
                f"{self.source}: unknown field(s) {[prefix + u for u in unknown]}{hints}; "
                f"valid fields: {[prefix + v for v in valid]}"
            )

    def get(self, name: str, kind: type):
        if name not in self.document:
            self.fail(name, "is missing")
        value = self.document[name]
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            self.fail(name, f"is {value!r}; expected {kind.__name__}")
        return value

    def number(self, name: str) -> float:
        value = self.document.get(name)
        if value is None:
            return math.nan
        if not isinstance(value, int | float) or isinstance(value, bool):
            self.fail(name, f"is {value!r}; expected a number or null")
        return float(value)

    def probabilities(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        values = self.get(name, list)
        try:
            values = np.array(values, dtype=float)
        except (TypeError, ValueError):
            self.fail(name, "is not an array of numbers")
        if values.shape != shape:
            self.fail(name, f"has shape {values.shape}; expected {shape}")
        if not _is_stochastic(values):
            self.fail(name, "must hold non-negative numbers with each row summing to 1")
        return values

    def distribution(self, name: str, n_states: int, within: dict | None = None):
        """The distribution of field ``name`` (of the block ``within``: a further stream)."""
        if within is None:
            block = self.get(name, dict)
        else:
            block = within[name.split(".", 1)[1]]
            if not isinstance(block, dict):
                self.fail(name, f"is {block!r}; expected dict")
        try:
            dist = emission.from_dict(block)
        except (KeyError, TypeError, ValueError) as exc:
            self.fail(name, f"is not a valid distribution ({exc})")
        if dist.n_states != n_states:
            self.fail(name, f"has {dist.n_states} states; expected {n_states}")
        return dist
