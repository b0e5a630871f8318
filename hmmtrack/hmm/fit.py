"""Fitting movement HMMs: EM (Baum-Welch) with multi-start, then a direct-likelihood polish.

:class:`MovementHMMEstimator` is the scikit-learn-shaped estimator (hyper-parameters in
``__init__``, read and set with ``get_params`` / ``set_params`` so that
``sklearn.base.clone`` works; ``fit`` returns ``self``; learned attributes ``model_``,
``starts_``, ``monitor_``; ``predict``, ``predict_proba``, ``score``, ``sample``) and
:func:`fit_movement_hmm` the one-call convenience. One fit is:

1. for each of ``n_starts`` starts (seeds from ``SeedSequence.spawn``, run serially or on
   ``n_jobs`` threads or processes with identical results): random initial values, then EM --
   the E-step is :func:`hmmtrack.hmm.inference.forward_backward`, the M-step the weighted
   maximum-likelihood fits of the emission families, the initial distribution and the
   transition matrix (closed form) or its logit coefficients (:mod:`~hmmtrack.hmm.covariates`);
   2-3 state gamma / von Mises models without covariates take one fused compiled pass per
   iteration instead (:mod:`~hmmtrack.hmm.em_kernels`, the same estimates);
   an EM still crawling after :data:`ACCELERATE_AFTER` iterations continues with SQUAREM;
2. the best start is *polished* when its EM stopped at ``max_iter`` before converging
   (``polish="auto"``; ``True`` always polishes): BFGS on the full log-likelihood over the working
   parameters (the scale moveHMM's ``nlm`` maximises on), with the gradient from Fisher's
   identity (one forward-backward pass plus the emission scores), so that the optimum is
   the same one moveHMM reaches;
3. states are reordered by increasing mean step so labels are stable.

Fixed parameters, equality constraints and a stationary initial distribution
(:mod:`~hmmtrack.hmm.constraints`) hold in every start, in EM (a constrained M-step,
:func:`_constrained_m_step`) and in the polish (BFGS over the free parameters,
:class:`ConstrainedLikelihood`). With a stationary initial distribution EM is not exact (its
initial distribution follows the transition matrix instead of maximising its own term), so
every start is polished: the direct maximisation gives the optimum.

The working-scale log-likelihood and its gradient (:class:`WorkingLikelihood`) are also what
:mod:`hmmtrack.hmm.diagnostics` differentiates for Wald intervals.

This module is not for the recursions themselves, the emission maths, the JSON file or
diagnostics; those live in the sibling modules.
"""

from __future__ import annotations

import concurrent.futures
import inspect
import logging
import multiprocessing
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from scipy.optimize import minimize

from hmmtrack.hmm import constraints as con
from hmmtrack.hmm import covariates as cov
from hmmtrack.hmm import distributions, em_kernels, emission
from hmmtrack.hmm import formula as formulas
from hmmtrack.hmm.inference import forward_backward, load_kernels, log_likelihood
from hmmtrack.hmm.model import DT_TOLERANCE, MovementHMM, Observations, time_steps
from hmmtrack.random import as_generator, spawn

logger = logging.getLogger(__name__)

_TINY = 1e-12  # floor of probabilities whose log is a working parameter
_POLISH_GTOL = 1e-6  # polish stops when no gradient entry of the per-row log-lik exceeds this
#: EM iterations before run_em accelerates (SQUAREM); common fits have converged by then
ACCELERATE_AFTER = 20


# ---------------------------------------------------------------------------------------------
# Data and parameters
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FitData:
    """Arrays a fit runs on.

    Attributes
    ----------
    step, angle : ndarray, shape (T,)
        Step lengths and turning angles (NaN = missing).
    lengths : ndarray, shape (n_sequences,)
    design : ndarray, shape (T, p) or None
        Standardised design matrix of the transition formula (None without covariates).
    emission : dict
        ``{stream: {parameter: (T, p_j) design matrix}}`` of the emission formulas
        (:mod:`~hmmtrack.hmm.emission`); empty without.
    streams : dict of str to ndarray, shape (T,)
        Further data streams by name (a dive depth, counts; NaN = missing); empty without.
    known : ndarray, shape (T, K) or None
        Known states as log-likelihood terms: 0 where the state is possible, -inf for the
        other states of a row whose state is known (:func:`known_state_terms`); None
        without.
    prepared : dict
        Each stream's observations validated once with their transforms (log step, cos and
        sin of the angle), by stream; every density evaluation, M-step and score of the fit
        uses these.
    inputs : dict
        What each stream's distribution is evaluated on, by stream (``"step"``,
        ``"angle"``, then ``streams``): its prepared observations, with the design matrices
        of the stream's emission formulas when it has some.
    """

    step: np.ndarray
    angle: np.ndarray
    lengths: np.ndarray
    design: np.ndarray | None = None
    emission: dict = field(default_factory=dict)
    streams: dict = field(default_factory=dict)
    known: np.ndarray | None = None
    prepared: dict = field(init=False, repr=False)
    inputs: dict = field(init=False, repr=False)

    def __post_init__(self) -> None:
        prepared = {
            "step": distributions.prepare_steps(self.step),
            "angle": distributions.prepare_angles(self.angle),
            **{name: distributions.prepare_values(x) for name, x in self.streams.items()},
        }
        inputs = {
            name: emission.stream_input(values, self.emission.get(name))
            for name, values in prepared.items()
        }
        object.__setattr__(self, "prepared", prepared)
        object.__setattr__(self, "inputs", inputs)

    @property
    def starts(self) -> np.ndarray:
        """Row index of the first row of each sequence, shape (n_sequences,)."""
        return np.concatenate([[0], np.cumsum(self.lengths)[:-1]]).astype(np.int64)

    @property
    def n_obs(self) -> int:
        """Number of rows ``T``."""
        return int(self.step.shape[0])


@dataclass(frozen=True)
class Parameters:
    """Parameters of one EM iterate.

    Attributes
    ----------
    initial : ndarray, shape (K,)
        With ``stationary`` and covariates, the first sequence's (:meth:`log_initial`).
    transition : ndarray, shape (K, K) or None
        Used when there are no covariates.
    coefficients : ndarray, shape (K*(K-1), 1 + p) or None
        Logit coefficients, used with covariates.
    step, angle : StateDistribution
    streams : dict of str to StateDistribution
        The distributions of further data streams, by name; empty without.
    stationary : bool
        Each sequence starts in the stationary distribution of its transition matrix at its
        first row (a fit control's ``stationary``).
    """

    initial: np.ndarray
    transition: np.ndarray | None
    coefficients: np.ndarray | None
    step: distributions.StateDistribution
    angle: distributions.StateDistribution
    streams: dict = field(default_factory=dict)
    stationary: bool = False

    @property
    def n_states(self) -> int:
        return self.initial.shape[0]

    @property
    def emissions(self) -> dict:
        """Every stream's distribution by name: ``step``, ``angle``, then ``streams``."""
        return {"step": self.step, "angle": self.angle, **self.streams}

    def with_emissions(self, emissions: dict) -> Parameters:
        """These parameters with the stream distributions ``emissions`` (same names)."""
        emissions = dict(emissions)
        step, angle = emissions.pop("step"), emissions.pop("angle")
        return replace(self, step=step, angle=angle, streams=emissions)

    def log_initial(self, data: FitData) -> np.ndarray:
        """Log initial distribution: ``(K,)``, or ``(n_sequences, K)`` for a stationary start
        with covariates (each sequence's, at its first row's covariates)."""
        initial = self.initial
        if self.stationary and self.coefficients is not None:
            initial = con.stationary_starts(self.coefficients, data.design[data.starts])
        with np.errstate(divide="ignore"):
            return np.log(initial)

    def log_transition(self, data: FitData) -> np.ndarray:
        """``(K, K)`` or, with covariates, ``(T-1, K, K)`` (entry t: row t -> t+1)."""
        if self.coefficients is None:
            with np.errstate(divide="ignore"):
                return np.log(self.transition)
        return cov.log_transition_matrices(self.coefficients, data.design[1:])

    def log_likelihood_matrix(self, data: FitData) -> np.ndarray:
        """Emission log densities, shape (T, K), with ``data.known``'s -inf where a row's
        state is known to be another."""
        log_lik = self.step.logpdf(data.inputs["step"])
        for name, dist in self.emissions.items():
            if name != "step":
                log_lik += dist.logpdf(data.inputs[name])  # in place: no third (T, K) array
        if data.known is not None:
            log_lik += data.known
        return log_lik

    def permuted(self, order: np.ndarray) -> Parameters:
        """The same model with state ``k`` of the result being state ``order[k]`` of this one."""
        order = np.asarray(order)
        rows, cols = cov.off_diagonal_index(self.n_states)
        position = {(i, j): r for r, (i, j) in enumerate(zip(rows, cols, strict=True))}
        return Parameters(
            initial=self.initial[order],
            transition=None if self.transition is None else self.transition[np.ix_(order, order)],
            coefficients=None
            if self.coefficients is None
            else self.coefficients[
                [position[order[i], order[j]] for i, j in zip(rows, cols, strict=True)]
            ],
            step=self.step.permuted(order),
            angle=self.angle.permuted(order),
            streams={name: dist.permuted(order) for name, dist in self.streams.items()},
            stationary=self.stationary,
        )


# ---------------------------------------------------------------------------------------------
# The working scale: unconstrained vector <-> parameters, likelihood and its gradient
# ---------------------------------------------------------------------------------------------


class WorkingLikelihood:
    """Log-likelihood of the data as a function of the working parameter vector.

    The vector is ``[step.to_working(), angle.to_working(), the further streams'
    to_working(), logit coefficients (row-major, intercepts = log(Gamma_ij / Gamma_ii)
    without covariates), log(delta_k / delta_0) for k = 1..K-1]``, moveHMM's layout up to
    ordering.

    Parameters
    ----------
    template : Parameters
        Fixes the structure (families, zero-inflation, fixed angle means, covariates).
    data : FitData
    """

    def __init__(self, template: Parameters, data: FitData):
        self.template = template
        self.data = data
        sizes = [dist.to_working().size for dist in template.emissions.values()]
        #: where each stream's block ends in the vector, by name
        self.ends = dict(zip(template.emissions, np.cumsum(sizes), strict=True))
        self.n_emission = int(np.sum(sizes))
        n_design = 1 if data.design is None else data.design.shape[1]
        k = template.n_states
        self.coefficient_shape = (k * (k - 1), n_design)
        self.size = self.n_emission + k * (k - 1) * n_design + k - 1

    def pack(self, params: Parameters) -> np.ndarray:
        """Working vector of ``params``, shape (n_parameters,)."""
        if params.coefficients is None:
            coefficients = cov.coefficients_from_matrix(np.maximum(params.transition, _TINY))
        else:
            coefficients = params.coefficients
        initial = np.maximum(params.initial, _TINY)
        return np.concatenate(
            [
                *(dist.to_working() for dist in params.emissions.values()),
                coefficients.ravel(),
                np.log(initial[1:]) - np.log(initial[0]),
            ]
        )

    def _blocks(self):
        """``(name, start, end)`` of each stream's block of the vector."""
        start = 0
        for name, end in self.ends.items():
            yield name, start, end
            start = end

    def unpack(self, theta: np.ndarray) -> Parameters:
        """Parameters of a working vector (inverse of :meth:`pack`)."""
        b = self.n_emission
        c = b + int(np.prod(self.coefficient_shape))
        coefficients = theta[b:c].reshape(self.coefficient_shape)
        log_initial = np.concatenate([[0.0], theta[c:]])
        initial = np.exp(log_initial - np.logaddexp.reduce(log_initial))
        if self.data.design is None:
            transition = np.exp(cov.log_transition_matrices(coefficients, np.ones((1, 1))))[0]
            coefficients = None
        else:
            transition = None
        emissions = self.template.emissions
        return replace(
            self.template, initial=initial, transition=transition, coefficients=coefficients
        ).with_emissions(
            {name: emissions[name].with_working(theta[i:j]) for name, i, j in self._blocks()}
        )

    def value(self, theta: np.ndarray) -> float:
        """Log-likelihood at ``theta``."""
        params = self.unpack(theta)
        data = self.data
        return log_likelihood(
            params.log_initial(data),
            params.log_transition(data),
            params.log_likelihood_matrix(data),
            data.lengths,
        )

    def value_and_gradient(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """Log-likelihood and its gradient at ``theta`` (Fisher's identity).

        The gradient of the log-likelihood equals the expected gradient of the complete-data
        log-likelihood under the posterior at ``theta``, all in closed form: the emission
        families' ``working_score`` of the posterior-weighted log densities, and the
        initial and transition parts (:func:`_scores`).
        """
        params = self.unpack(theta)
        post = _posterior(params, self.data)
        b = self.n_emission
        c = b + int(np.prod(self.coefficient_shape))
        coefficients = theta[b:c].reshape(self.coefficient_shape)
        emission_scores, coefficient_score, first = _scores(params, self.data, post, coefficients)
        gradient = np.empty_like(theta)
        for name, i, j in self._blocks():
            gradient[i:j] = emission_scores[name]
        gradient[b:c] = coefficient_score.ravel()
        gradient[c:] = first[1:] - first.sum() * params.initial[1:]
        return post.log_likelihood, gradient


class ConstrainedLikelihood(WorkingLikelihood):
    """Log-likelihood as a function of the free parameters of a constrained fit.

    The vector is :class:`~hmmtrack.hmm.constraints.Constraints`' ``phi``: the parameters on
    their link scale with the fixed ones left out and the tied ones once. The gradient is
    Fisher's identity as in :class:`WorkingLikelihood`, taken to the link scale through
    each stream's ``d working / d link`` Jacobian, to ``phi`` by summing tied entries; a
    stationary initial distribution adds ``sum_k (first_k / delta_k) d delta_k / d beta`` to
    the transition coefficients (``first``: posterior at the first rows).

    Parameters
    ----------
    template : Parameters
    data : FitData
    constraints : Constraints
    """

    def __init__(self, template: Parameters, data: FitData, constraints: con.Constraints):
        super().__init__(template, data)
        self.constraints = constraints
        self.size = constraints.size

    def pack(self, params: Parameters) -> np.ndarray:
        """Free vector of ``params`` (projected onto the constraints)."""
        return self.constraints.pack(params)

    def unpack(self, theta: np.ndarray) -> Parameters:
        """Parameters of a free vector."""
        return self.constraints.unpack(theta)

    def value_and_gradient(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """Log-likelihood and its gradient by the free vector ``theta``."""
        constraints = self.constraints
        z = constraints.expand(theta)
        params = constraints.parameters(z)
        post = _posterior(params, self.data)
        coefficients = z[constraints.blocks["transition"]].reshape(self.coefficient_shape)
        emission_scores, coefficient_score, first = _scores(params, self.data, post, coefficients)
        gradient = np.zeros(constraints.size_z)
        for name, dist in params.emissions.items():
            block = constraints.blocks[name]
            gradient[block] = con.link_jacobian(dist, z[block]).T @ emission_scores[name]
        coefficient_score = coefficient_score.ravel()
        if constraints.control.stationary:  # sum over sequences of first / delta d delta
            delta = constraints.stationary_initial(coefficients)
            starts = post.posterior[self.data.starts]  # (n_sequences, K)
            if delta.shape[0] == 1:  # one distribution shared by every sequence
                starts = starts.sum(axis=0, keepdims=True)
            jacobian = constraints.stationary_jacobian(coefficients)
            coefficient_score = (
                coefficient_score + jacobian.T @ (starts / np.maximum(delta, _TINY)).ravel()
            )
        else:
            gradient[constraints.blocks["initial"]] = first[1:] - first.sum() * params.initial[1:]
        gradient[constraints.blocks["transition"]] = coefficient_score
        return post.log_likelihood, constraints.reduce_gradient(gradient)


def working_likelihood(
    template: Parameters, data: FitData, constraints: con.Constraints | None = None
) -> WorkingLikelihood:
    """The likelihood on the working scale, or on the free vector of ``constraints``."""
    if constraints is None:
        return WorkingLikelihood(template, data)
    return ConstrainedLikelihood(template, data, constraints)


def _scores(params: Parameters, data: FitData, post, coefficients: np.ndarray):
    """The parts of the likelihood gradient by Fisher's identity at ``params``.

    Returns
    -------
    emission : dict of str to ndarray
        Each stream's ``working_score`` of the posterior-weighted log densities.
    coefficients : ndarray, shape (K*(K-1), p)
        Gradient by the transition coefficients ``coefficients`` (those of ``params``).
    first : ndarray, shape (K,)
        Posterior state probabilities at the first rows of the sequences, summed.
    """
    weights = post.posterior
    emission_scores = {
        name: dist.working_score(data.inputs[name], weights)
        for name, dist in params.emissions.items()
    }
    if data.design is None:
        xi, design = post.pair_counts[None], np.ones((1, 1))
    else:
        xi, design = post.pair_counts, data.design[1:]
    coefficient_score = cov.expected_log_likelihood(coefficients, xi, design)[1]
    return emission_scores, coefficient_score, weights[data.starts].sum(axis=0)


def _posterior(params: Parameters, data: FitData):
    """Forward-backward of ``data`` under ``params`` (a :class:`~.inference.Posterior`)."""
    return forward_backward(
        params.log_initial(data),
        params.log_transition(data),
        params.log_likelihood_matrix(data),
        data.lengths,
    )


# ---------------------------------------------------------------------------------------------
# EM
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ConvergenceMonitor:
    """History of one EM run.

    Attributes
    ----------
    history : tuple of float
        Log-likelihood before each M-step (the E-step's value), one per iteration.
    n_iter : int
    converged : bool
        True when the gain of an iteration fell below ``tol * n_obs`` before ``max_iter``.
    tol : float
        Tolerance on the log-likelihood gain per observation.
    """

    history: tuple[float, ...]
    n_iter: int
    converged: bool
    tol: float


@dataclass(frozen=True)
class StartResult:
    """What one start produced.

    Attributes
    ----------
    index : int
        Position of the start (its seed is child ``index`` of the fit's seed).
    parameters : Parameters
        After EM (and after the polish, for the chosen start), states in ascending mean step.
    log_likelihood : float
        ``-inf`` for a start that failed.
    monitor : ConvergenceMonitor
    polished : bool
    error : str or None
        Why the start failed (its ``parameters`` are then its starting values).
    """

    index: int
    parameters: Parameters
    log_likelihood: float
    monitor: ConvergenceMonitor
    polished: bool = False
    error: str | None = None


def m_step(
    params: Parameters, data: FitData, post, constraints: con.Constraints | None = None
) -> Parameters:
    """One weighted maximum-likelihood M-step from a forward-backward result (under
    ``constraints``: :func:`_constrained_m_step`)."""
    weights = post.posterior
    first = weights[data.starts].sum(axis=0)
    initial = first / first.sum()
    transition = coefficients = None
    if params.coefficients is None:
        counts = post.pair_counts
        leaving = counts.sum(axis=1, keepdims=True)
        transition = np.where(
            leaving > 0, counts / np.where(leaving > 0, leaving, 1.0), params.transition
        )
    else:
        coefficients = cov.fit_coefficients(post.pair_counts, data.design[1:], params.coefficients)
    free = replace(
        params, initial=initial, transition=transition, coefficients=coefficients
    ).with_emissions(
        {
            name: dist.fit_weighted(data.inputs[name], weights)
            for name, dist in params.emissions.items()
        }
    )
    if constraints is None:
        return free
    return _constrained_m_step(params, free, data, post, constraints)


def _constrained_m_step(
    params: Parameters, free: Parameters, data: FitData, post, constraints: con.Constraints
) -> Parameters:
    """The M-step under fixed parameters, ties and a stationary initial distribution.

    Streams and transition coefficients without a fixed or tied entry take the free M-step's
    values ``free``. Each other block maximises its expected complete-data log-likelihood
    (``sum(w * logpdf)``, or the transitions' :func:`~.covariates.expected_log_likelihood`)
    over its free entries with BFGS from ``free`` projected onto the constraints, and keeps
    ``params``' values unless that is better (so the EM stays monotone): tied states share
    one parameter whose score is the sum of theirs, which pools the tied states' weighted
    observations -- their sufficient statistics (weighted sums of x and log x for gamma
    steps, of cos and sin for angles, counts for Poisson...) -- for every family alike; a
    formula parameter ties its coefficients. A fixed initial distribution stays; a stationary
    one follows the new transition matrix, which is not the exact M-step of the
    initial-distribution term (each start is polished on the full likelihood afterwards).
    """
    weights = post.posterior
    z = constraints.z_of(params)
    start = constraints.z_of(free)
    for name, dist in params.emissions.items():
        block = constraints.blocks[name]
        if not constraints.touches(name):
            z[block] = start[block]
            continue
        x = data.inputs[name]

        def objective(values, dist=dist, x=x):
            member = con.from_link_vector(dist, values)
            value = float(np.sum(weights * member.logpdf(x)))
            return value, con.link_jacobian(member, values).T @ member.working_score(x, weights)

        z = constraints.maximise_block(name, z, objective, start)
    block = constraints.blocks["transition"]
    if constraints.touches("transition"):
        if data.design is None:
            xi, design = post.pair_counts[None], np.ones((1, 1))
        else:
            xi, design = post.pair_counts, data.design[1:]
        shape = (params.n_states * (params.n_states - 1), -1)

        def transitions(values):
            value, gradient = cov.expected_log_likelihood(values.reshape(shape), xi, design)
            return value, gradient.ravel()

        z = constraints.maximise_block("transition", z, transitions, start)
    else:
        z[block] = start[block]
    initial = constraints.blocks["initial"]
    if not constraints.touches("initial"):
        z[initial] = start[initial]
    return constraints.parameters(z)


def _em_steps(params: Parameters, data: FitData, constraints: con.Constraints | None = None):
    """The E-step ``params -> result with .log_likelihood`` and M-step ``(params, result) ->
    params`` of a fit: the fused kernel of :mod:`~hmmtrack.hmm.em_kernels` when the model
    allows it (gamma / von Mises, no covariates, no constraints), else forward-backward and
    :func:`m_step`."""
    fused = None if constraints is not None else em_kernels.fused_em(params, data)
    if fused is not None:
        return fused.expectation, fused.maximisation

    def expectation(params):
        return _posterior(params, data)

    def maximisation(params, post):
        return m_step(params, data, post, constraints)

    return expectation, maximisation


def run_em(
    params: Parameters,
    data: FitData,
    max_iter: int,
    tol: float,
    constraints: con.Constraints | None = None,
):
    """Baum-Welch from ``params`` until the gain per observation is below ``tol``.

    Plain EM for the first :data:`ACCELERATE_AFTER` iterations (most fits converge within
    them); an EM that is still crawling then continues with SQUAREM (Varadhan & Roland 2008,
    scheme S3) on the working parameters (:class:`WorkingLikelihood`): two EM steps ``r``
    and ``v`` give the extrapolation ``theta0 - 2 alpha r + alpha^2 v``, kept only when its
    log-likelihood is at least that of the second EM step, so that every value in the
    history is at least the one before. Each E-step counts as one iteration. The E- and
    M-steps are the fused kernel's where the model allows (see :func:`_em_steps`). Under
    ``constraints`` the M-step is constrained and SQUAREM extrapolates the free vector.

    Returns
    -------
    params : Parameters
        The parameters of the last E-step.
    log_likelihood : float
        Log-likelihood of the returned parameters.
    monitor : ConvergenceMonitor
    """
    history = []
    expectation, maximisation = _em_steps(params, data, constraints)
    post = expectation(params)

    def step(params, post):
        """EM step; ``None`` for a gain below ``tol`` or the end of ``max_iter``."""
        history.append(post.log_likelihood)
        params = maximisation(params, post)
        post = expectation(params)
        done = post.log_likelihood - history[-1] < tol * data.n_obs
        return params, post, done or len(history) >= max_iter

    done = max_iter < 1
    while not done and len(history) < ACCELERATE_AFTER:
        params, post, done = step(params, post)
    working = working_likelihood(params, data, constraints)
    step_max = 1.0
    while not done:
        start = working.pack(params)
        first, first_post, done = step(params, post)
        if done:
            params, post = first, first_post
            break
        second, second_post, done = step(first, first_post)
        params, post = second, second_post
        if done:
            break
        r = working.pack(first) - start
        v = working.pack(second) - start - 2.0 * r
        if not (np.all(np.isfinite(v)) and np.any(v)):
            continue
        alpha = min(-1.0, max(-step_max, -np.sqrt(r @ r / (v @ v))))
        if alpha == -step_max:
            step_max *= 4.0
        if alpha == -1.0:  # the extrapolation is the second EM step itself
            continue
        try:
            candidate = working.unpack(start - 2.0 * alpha * r + alpha * alpha * v)
            candidate_post = expectation(candidate)
        except ValueError:  # parameters out of range, or an observation impossible throughout
            continue
        if candidate_post.log_likelihood >= second_post.log_likelihood:
            history.append(second_post.log_likelihood)
            params, post = candidate, candidate_post
            done = len(history) >= max_iter
    converged = bool(history) and post.log_likelihood - history[-1] < tol * data.n_obs
    monitor = ConvergenceMonitor(tuple(history), len(history), converged, tol)
    return params, float(post.log_likelihood), monitor


def polish(
    params: Parameters,
    data: FitData,
    max_iter: int = 500,
    constraints: con.Constraints | None = None,
):
    """Maximise the full log-likelihood over the working parameters with BFGS (over the free
    vector of ``constraints`` when given: :class:`ConstrainedLikelihood`).

    BFGS rather than L-BFGS: a transition probability that tends to 0 with a covariate sends
    a coefficient off towards -inf, along which L-BFGS crawls for hundreds of iterations.
    Returns the polished parameters and log-likelihood, or the inputs if BFGS did not
    improve on them.
    """
    likelihood = working_likelihood(params, data, constraints)
    start = likelihood.pack(params)
    scale = 1.0 / data.n_obs  # per-row log-likelihood: one gradient tolerance for any size

    def objective(theta):
        try:
            value, gradient = likelihood.value_and_gradient(theta)
        except ValueError:  # some observation impossible under every state path
            return np.inf, np.zeros_like(theta)
        if not np.isfinite(value):
            return np.inf, np.zeros_like(theta)
        return -scale * value, -scale * gradient

    at_start = objective(start)  # BFGS asks for it first: one recursion less than value()
    start_value = -at_start[0] / scale

    def objective_from_start(theta):
        return at_start if np.array_equal(theta, start) else objective(theta)

    result = minimize(
        objective_from_start,
        start,
        jac=True,
        method="BFGS",
        options={"maxiter": max_iter, "gtol": _POLISH_GTOL},
    )
    result.fun /= scale
    if np.isfinite(result.fun) and -result.fun > start_value:
        return likelihood.unpack(result.x), float(-result.fun)
    return params, float(start_value)


def order_by_mean_step(params: Parameters) -> Parameters:
    """Relabel states so that the mean step increases with the state index."""
    return params.permuted(np.argsort(params.step.expected_value(), kind="stable"))


# ---------------------------------------------------------------------------------------------
# Starting values
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FitSpec:
    """Structure and controls of a fit (everything a start needs besides data and seed)."""

    n_states: int
    step_family: str
    angle_family: str
    estimate_angle_mean: bool
    zero_inflated: bool
    max_iter: int
    tol: float
    emission_designs: dict = field(default_factory=dict)  # {stream: {parameter: Design}}
    stream_families: dict = field(default_factory=dict)  # {further stream: family name}
    #: starting values of start 0 (the user's, or the deterministic ones a fit builds first)
    start: Parameters | None = None
    constraints: con.Constraints | None = None  # fixed, tied, stationary (None: none)

    @property
    def keeps_labels(self) -> bool:
        """True when the constraints name states, which the fit then keeps as numbered
        instead of ordering them by mean step."""
        return self.constraints is not None and self.constraints.control.labels_states


def initial_parameters(rng: np.random.Generator | None, data: FitData, spec: FitSpec) -> Parameters:
    """Starting values for one start.

    Emission distributions come from :func:`hmmtrack.hmm.distributions.initial_guess` (steps
    cut into groups at quantiles; random group sizes with ``rng``, equal sizes without). The
    transition matrix has diagonal entries 0.9 (without ``rng``) or uniform in (0.5, 0.95),
    the rest of each row spread evenly; covariate slopes start at 0 (transition and emission
    formulas alike); the initial distribution is uniform. A further stream starts at its
    weighted fit with each row's state probabilities under the starting step distribution
    alone (equal prior), so that its states follow the steps'. Under ``spec.constraints``
    the values are projected onto them (fixed values set, ties averaged).
    """
    k = spec.n_states
    step, angle = distributions.initial_guess(
        data.prepared["step"],
        data.angle,
        k,
        spec.step_family,
        spec.angle_family,
        estimate_angle_mean=spec.estimate_angle_mean,
        zero_inflated=spec.zero_inflated,
        rng=rng,
    )
    emissions = {"step": step, "angle": angle}
    if spec.stream_families:
        log_lik = step.logpdf(data.prepared["step"])
        weights = np.exp(log_lik - np.logaddexp.reduce(log_lik, axis=1, keepdims=True))
        for name, family in spec.stream_families.items():
            cls = distributions.VALUE_FAMILIES[family]
            emissions[name] = cls.initial(data.prepared[name], weights)
    for name, designs in spec.emission_designs.items():
        emissions[name] = emission.CovariateEmission.from_constant(emissions[name], designs)
    step, angle = emissions.pop("step"), emissions.pop("angle")
    diagonal = np.full(k, 0.9) if rng is None else rng.uniform(0.5, 0.95, k)
    if k == 1:
        diagonal = np.ones(1)
    off = (1 - diagonal[:, None]) / max(k - 1, 1)
    transition = np.where(np.eye(k, dtype=bool), diagonal[:, None], off)
    coefficients = None
    if data.design is not None:
        coefficients = cov.coefficients_from_matrix(transition, data.design.shape[1])
        transition = None
    params = Parameters(np.full(k, 1.0 / k), transition, coefficients, step, angle, emissions)
    return params if spec.constraints is None else spec.constraints.project(params)


def run_start(index: int, seed: np.random.SeedSequence, data: FitData, spec: FitSpec):
    """One start, then EM; states ordered by mean step.

    Start 0 uses ``spec.start`` (the user's starting values or the deterministic equal-count
    ones a fit has built already; projected onto the constraints) or, without it, the
    deterministic ones; the others random ones drawn with a generator from ``seed``. States
    keep their numbers when the constraints name them. With a stationary initial
    distribution every start is polished (EM alone does not reach the optimum then).
    """
    if index == 0 and spec.start is not None:
        start = spec.start
        if spec.constraints is not None:
            start = spec.constraints.project(start)
    else:
        start = initial_parameters(None if index == 0 else as_generator(seed), data, spec)
    try:
        params, log_likelihood, monitor = run_em(
            start, data, spec.max_iter, spec.tol, spec.constraints
        )
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
        monitor = ConvergenceMonitor((), 0, False, spec.tol)
        return StartResult(index, start, -np.inf, monitor, error=f"{type(exc).__name__}: {exc}")
    if not np.isfinite(log_likelihood):
        return StartResult(index, params, -np.inf, monitor, error="log-likelihood not finite")
    polished = spec.constraints is not None and spec.constraints.control.stationary
    if polished:  # EM is not exact with a stationary initial distribution: maximise directly
        params, log_likelihood = polish(params, data, constraints=spec.constraints)
    if not spec.keeps_labels:
        params = order_by_mean_step(params)
    return StartResult(index, params, log_likelihood, monitor, polished)


_worker_data: FitData | None = None  # the data of a worker process, set once when it starts


def _set_worker_data(data: FitData) -> None:
    global _worker_data
    _worker_data = data


def _run_start_in_worker(task) -> StartResult:
    index, seed, spec = task
    return run_start(index, seed, _worker_data, spec)


def run_starts(data: FitData, spec: FitSpec, n_starts: int, seed, n_jobs: int = 1):
    """All starts, serially or on ``n_jobs`` workers; the same list either way.

    Fits that take the fused EM (no constraints and
    :func:`~hmmtrack.hmm.em_kernels.takes_fused_path`, as in :func:`_em_steps`) run their
    starts on threads: the fused kernel, most of an iteration's time, releases the GIL, and
    threads start in microseconds where a process pool takes tens of milliseconds to fork
    and to return its results. Other fits use worker processes, forked where the platform
    allows (no re-import, no copy of the data: they inherit it, and the compiled kernels,
    loaded first), which receive the data once, through the pool's initializer, rather than
    with every start.
    """
    seeds = spawn(seed, n_starts)
    if n_jobs == 1 or n_starts == 1:
        return [run_start(i, s, data, spec) for i, s in enumerate(seeds)]
    workers = min(n_jobs, n_starts)
    template = spec.start if spec.start is not None else initial_parameters(None, data, spec)
    if spec.constraints is None and em_kernels.takes_fused_path(template, data):
        em_kernels.load_kernel(spec.n_states)
        em_kernels.features_of(data.prepared["step"], data.prepared["angle"])  # shared, once
        with concurrent.futures.ThreadPoolExecutor(workers) as pool:
            return list(pool.map(lambda i, s: run_start(i, s, data, spec), range(n_starts), seeds))
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("fork" if "fork" in methods else None)
    load_kernels()
    em_kernels.load_kernel(spec.n_states)
    with concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=context, initializer=_set_worker_data, initargs=(data,)
    ) as pool:
        return list(pool.map(_run_start_in_worker, [(i, s, spec) for i, s in enumerate(seeds)]))


# ---------------------------------------------------------------------------------------------
# Between tables, arrays and models
# ---------------------------------------------------------------------------------------------


def fit_data(observations: Observations, known: np.ndarray | None = None) -> FitData:
    """:class:`FitData` of a table's observations (``known``: see :class:`FitData`)."""
    return FitData(
        observations.step,
        observations.angle,
        observations.lengths,
        observations.design,
        observations.emission,
        observations.streams,
        known,
    )


def known_state_terms(states, n_states: int) -> np.ndarray:
    """Log-likelihood terms (T, K) of known states: 0 for the possible states of a row, -inf
    for the others.

    Parameters
    ----------
    states : array of float, shape (T,)
        The state of each row, numbered from 1 as users see them; NaN where unknown.
    n_states : int

    Raises
    ------
    ValueError
        For a state that is not a whole number in 1..K.
    """
    states = np.asarray(states, dtype=float)
    known = np.isfinite(states)
    bad = known & ~np.isin(states, np.arange(1, n_states + 1))
    if bad.any() or np.isinf(states).any():
        rows = np.flatnonzero(bad | np.isinf(states))[:10].tolist()
        raise ValueError(f"known states must be 1..{n_states} or NaN; not at rows {rows}")
    terms = np.zeros((states.size, n_states))
    rows = np.flatnonzero(known)
    terms[rows] = -np.inf
    terms[rows, states[rows].astype(np.int64) - 1] = 0.0
    return terms


def model_likelihood(model: MovementHMM, data: pd.DataFrame) -> WorkingLikelihood:
    """The likelihood of ``data`` (a prepared-track table) with ``model``'s structure, on the
    working scale or, for a model fitted under :attr:`~MovementHMM.control`, on the free
    vector of its constraints (fixed parameters held, ties shared)."""
    params = parameters_of(model)
    data = fit_data(model.observations(data))
    constraints = None
    if model.control:
        design = model.transition_design
        columns = ("Intercept",) if design is None else design.columns
        start_design = None if data.design is None else data.design[data.starts]
        constraints = con.Constraints(model.control, params, columns, start_design)
    return working_likelihood(params, data, constraints)


def parameters_of(model: MovementHMM) -> Parameters:
    """The :class:`Parameters` of a fitted model."""
    return Parameters(
        model.initial,
        model.transition,
        model.coefficients,
        model.step,
        model.angle,
        model.streams,
        model.control.stationary,
    )


def as_table(X, lengths=None, covariate_names=()) -> pd.DataFrame:
    """A prepared-track table from a table, or from an array ``(T, 2 + p)`` and ``lengths``.

    Array columns are step, angle, then the covariates in ``covariate_names`` order;
    ``lengths`` (rows per sequence) becomes a ``segment`` column.
    """
    if isinstance(X, pd.DataFrame):
        if lengths is not None:
            raise ValueError("give 'lengths' with an array only; a table has a 'segment' column")
        return X
    X = np.asarray(X, dtype=float)
    columns = ["step", "angle", *covariate_names]
    if X.ndim != 2 or X.shape[1] != len(columns):
        raise ValueError(f"X must have shape (T, {len(columns)}) with columns {columns}")
    table = pd.DataFrame(X, columns=columns)
    if lengths is not None:
        lengths = np.asarray(lengths, dtype=np.int64)
        if lengths.sum() != len(table) or np.any(lengths < 1):
            raise ValueError(f"lengths sum to {lengths.sum()}; expected {len(table)} rows")
        table["segment"] = np.repeat(np.arange(lengths.size), lengths)
    return table


def warn_if_irregular(table: pd.DataFrame) -> None:
    """Warn when the table's time steps (``dt``, s) are not one step: steps and turning
    angles over different durations are different quantities, which a movement HMM cannot
    tell apart.

    The warning counts the rows whose ``dt`` differs from the median by more than
    ``DT_TOLERANCE`` (10 %) of it and names the functions that regularise a track.
    """
    dt = time_steps(table)
    if dt.size == 0:
        return
    median = float(np.median(dt))
    irregular = np.abs(dt - median) > DT_TOLERANCE * median
    if irregular.any():
        warnings.warn(
            f"time steps vary: {int(irregular.sum())} of {dt.size} differ from the median "
            f"{median:g} s by more than {DT_TOLERANCE:.0%}; regularise the track before "
            "preparing it: hmmtrack.hmm.crw.regularise(tracks, step) (continuous-time "
            "correlated random walk; hmmtrack fit --regularise STEP --regularise-method crw), "
            "crw.impute with imputation.fit_imputed for multiple imputation (--impute M) or "
            "hmmtrack.tracks.regularise(tracks, step) (linear interpolation; --regularise STEP)",
            UserWarning,
            stacklevel=3,
        )


def information_criteria(log_likelihood: float, n_parameters: int, n_obs: int):
    """AIC ``= -2 logL + 2 p`` and BIC ``= -2 logL + p log n`` (n = rows fitted)."""
    return (
        -2.0 * log_likelihood + 2.0 * n_parameters,
        -2.0 * log_likelihood + n_parameters * np.log(n_obs),
    )


def _matching_start(given: Parameters, template: Parameters) -> Parameters:
    """``given`` if it has the structure of ``template`` (the fit's), else a ``ValueError``
    naming the difference."""

    def structure(params: Parameters) -> dict:
        return {
            "states": params.n_states,
            "transition covariates": params.coefficients is not None and params.coefficients.shape,
            **{
                name: (dist.name, dist.link_names(), tuple(getattr(dist, "designs", {})))
                for name, dist in params.emissions.items()
            },
        }

    want, have = structure(template), structure(given)
    different = [key for key in {**want, **have} if want.get(key) != have.get(key)]
    if different:
        raise ValueError(
            f"start: the model's {different} differ from the fit's: "
            + "; ".join(f"{k}: {have.get(k)} given, {want.get(k)} fitted" for k in different)
        )
    return given


# ---------------------------------------------------------------------------------------------
# Estimator
# ---------------------------------------------------------------------------------------------


class MovementHMMEstimator:
    """Fit an N-state step-length / turning-angle HMM (scikit-learn-shaped).

    Parameters
    ----------
    n_states : int
    step : {"gamma", "weibull", "lognormal", "exponential"}
    angle : {"vonmises", "wrpcauchy"}
    estimate_angle_mean : bool
        False fixes the angle means at 0.
    covariates : sequence of str
        Columns of the data on the transition probabilities: short for the formula
        ``"~ a + b"`` (give this or ``formula``). Also the names of an array ``X``'s
        columns after step and angle.
    formula : str or None
        Transition formula (``"~ dist_water"``, ``"~ C(season) + cos(2*pi*hour/24)"``; see
        :mod:`hmmtrack.hmm.formula`): its design matrix, standardised, is the multinomial
        logit's (:mod:`~hmmtrack.hmm.covariates`). It must keep the intercept.
    formulas : dict of str to str, or None
        Formulas by parameter: ``"transition"`` (as ``formula``) and any parameter of a
        stream's distribution, ``"<stream>.<parameter>"`` (``{"step.mean": "~ cosT + sinT",
        "angle.concentration": "~ x", "depth.mean": "~ x"}``): the parameter depends on the
        covariates through its link, state by state (:mod:`hmmtrack.hmm.emission`). Each
        keeps its intercept.
    streams : dict of str to str, or None
        Further data streams: a column of the table and its family in ``VALUE_FAMILIES``
        (``{"depth": "normal", "dives": "poisson"}``); NaN = missing.
    start : MovementHMM or None
        Starting values of the first start (the others stay random): a model of the same
        structure as the fit (families, zero inflation, formulas, streams, states).
    known_states : str or None
        A column of the table with the state of each row where it is known (1..K, as users
        number states; NaN where unknown): the fit allows only that state there. The
        fitted model does not keep it (decoding and intervals see the data alone).
    fixed : dict of str to float, or None
        Parameters held at a value during EM and the polish, by name, states from 1
        (``{"step.mean[1]": 50, "transition[1,2]": 0.05, "initial[1]": 1}``; the names of
        :mod:`hmmtrack.hmm.constraints`). They are not counted as free parameters, have no
        standard error, and are saved in the model file.
    equal : sequence of str
        Parameters held equal: ``["angle.concentration[1]==angle.concentration[2]"]`` (the
        same parameter of one stream in several states; coefficients of a formula parameter
        are tied together).
    stationary : bool
        The initial distribution is the stationary distribution of the transition matrix (at
        the first row's covariates with a transition formula) rather than a parameter; each
        start then ends with a polish on the full likelihood.
    state_names : sequence of str or None
        Names of the states (``["encamped", "exploratory"]``), saved in the model file;
        with names the states are in the order fitted (ascending mean step unless ``fixed``
        or ``equal`` name states, which then keep their numbers).
    zero_inflation : "auto" or bool
        "auto" switches zero-inflated steps on when a step is exactly 0.
    n_starts : int
        EM runs from random starting values; the best is kept.
    seed : int, SeedSequence or None
        Seed of the starts (children by ``SeedSequence.spawn``).
    n_jobs : int
        Workers for the starts (threads when the fit takes the fused EM, else processes;
        :func:`run_starts`); results do not depend on it.
    max_iter : int
        EM iterations per start.
    tol : float
        EM stops when an iteration gains less than ``tol`` log-likelihood per row.
    polish : "auto" or bool
        Maximise the full likelihood with BFGS from the best EM result: "auto" when that EM
        stopped at ``max_iter`` before converging (a converged EM is within a few 1e-6 nats of
        the optimum; reports/decisions.md, HMM fitting), True always, False never. With
        ``stationary`` every start is polished whatever this says.
    dt : float or None
        Time step of the data (s); None takes the median of the table's ``dt`` column (NaN
        if it has none).
    step_unit : str
        Unit of the steps, written to the model file.

    Attributes
    ----------
    model_ : MovementHMM
        The fitted model (best start, polished, states ordered by mean step).
    starts_ : list of StartResult
        Every start's EM result, in seed order.
    monitor_ : ConvergenceMonitor
        EM history of the chosen start.
    best_start_ : int
    n_parameters_ : int
        Free parameters (the working vector's length).
    """

    def __init__(
        self,
        n_states: int = 2,
        step: str = "gamma",
        angle: str = "vonmises",
        estimate_angle_mean: bool = True,
        covariates=(),
        formula: str | None = None,
        formulas: dict | None = None,
        streams: dict | None = None,
        start=None,
        known_states: str | None = None,
        fixed: dict | None = None,
        equal=(),
        stationary: bool = False,
        state_names=None,
        zero_inflation="auto",
        n_starts: int = 1,
        seed=None,
        n_jobs: int = 1,
        max_iter: int = 1000,
        tol: float = 1e-9,
        polish="auto",
        dt: float | None = None,
        step_unit: str = "m",
    ):
        self.n_states = n_states
        self.step = step
        self.angle = angle
        self.estimate_angle_mean = estimate_angle_mean
        self.covariates = covariates
        self.formula = formula
        self.formulas = formulas
        self.streams = streams
        self.start = start
        self.known_states = known_states
        self.fixed = fixed
        self.equal = equal
        self.stationary = stationary
        self.state_names = state_names
        self.zero_inflation = zero_inflation
        self.n_starts = n_starts
        self.seed = seed
        self.n_jobs = n_jobs
        self.max_iter = max_iter
        self.tol = tol
        self.polish = polish
        self.dt = dt
        self.step_unit = step_unit

    @classmethod
    def _parameter_names(cls) -> list[str]:
        """Names of the hyper-parameters: the arguments of ``__init__``."""
        signature = inspect.signature(cls.__init__)
        return [name for name in signature.parameters if name != "self"]

    def get_params(self, deep: bool = True) -> dict:
        """Hyper-parameters by name (scikit-learn's estimator contract).

        Parameters
        ----------
        deep : bool
            Accepted for scikit-learn; no hyper-parameter is itself an estimator.
        """
        return {name: getattr(self, name) for name in self._parameter_names()}

    def set_params(self, **params) -> MovementHMMEstimator:
        """Set hyper-parameters by name and return ``self`` (scikit-learn's contract)."""
        valid = self._parameter_names()
        for name, value in params.items():
            if name not in valid:
                raise ValueError(
                    f"invalid parameter {name!r} for {type(self).__name__}; valid: {valid}"
                )
            setattr(self, name, value)
        return self

    def _spec(self, data: FitData, emission_designs: dict) -> FitSpec:
        for kind, name, known in (
            ("step", self.step, distributions.STEP_FAMILIES),
            ("angle", self.angle, distributions.ANGLE_FAMILIES),
            *((name, f, distributions.VALUE_FAMILIES) for name, f in self._streams().items()),
        ):
            if name not in known:
                raise ValueError(f"{kind} family {name!r} unknown; choose from {list(known)}")
        if not (self.polish is True or self.polish is False or self.polish == "auto"):
            raise ValueError(f"polish must be 'auto', True or False, got {self.polish!r}")
        if int(self.n_states) < 1 or int(self.n_starts) < 1 or int(self.n_jobs) < 1:
            raise ValueError("n_states, n_starts and n_jobs must be positive integers")
        has_zero = bool(np.any(data.step == 0))
        if self.zero_inflation == "auto":
            zero_inflated = has_zero
        elif has_zero and not self.zero_inflation:
            raise ValueError("the data have steps of exactly 0; zero_inflation must be on")
        else:
            zero_inflated = bool(self.zero_inflation)
        return FitSpec(
            n_states=int(self.n_states),
            step_family=self.step,
            angle_family=self.angle,
            estimate_angle_mean=bool(self.estimate_angle_mean),
            zero_inflated=zero_inflated,
            max_iter=int(self.max_iter),
            tol=float(self.tol),
            emission_designs=emission_designs,
            stream_families=self._streams(),
        )

    def _streams(self) -> dict:
        """The further streams ``{column: family}``, their names checked."""
        streams = dict(self.streams or {})
        reserved = {"step", "angle", "transition", "segment"} & set(streams)
        if reserved:
            raise ValueError(f"streams cannot be named {sorted(reserved)}")
        return streams

    def _formulas(self) -> tuple[str | None, dict]:
        """The transition formula (``formula``, ``formulas["transition"]`` or that of
        ``covariates``, or None) and the emission formulas ``{stream: {parameter: rhs}}``."""
        streams = ("step", "angle", *self._streams())
        transition, emission_formulas = emission.split_formulas(self.formulas, streams)
        names = tuple(self.covariates)
        given = [self.formula is not None, transition is not None, bool(names)]
        if sum(given) > 1:
            raise ValueError(
                "give the transition covariates either as 'covariates', in 'formula' or as "
                "formulas['transition'], not several"
            )
        if self.formula is not None:
            transition = self.formula
        elif names:
            transition = formulas.of_columns(names)
        return transition, emission_formulas

    def fit(self, X, lengths=None) -> MovementHMMEstimator:
        """Fit to a prepared-track table or to an array ``(T, 2 + p)`` with ``lengths``.

        Parameters
        ----------
        X : DataFrame or ndarray
            Table with ``step`` (``step_unit``), ``angle`` (rad), ``segment`` and the
            columns the transition formula names; or an array with columns step, angle,
            ``covariates``.
        lengths : array of int, optional
            Rows per sequence, for an array ``X``.
        """
        rhs, emission_formulas = self._formulas()
        table = as_table(X, lengths, tuple(self.covariates))
        warn_if_irregular(table)
        design = None
        if rhs is not None:
            design = formulas.design(rhs, table)
            if not design.has_intercept:
                raise ValueError(f"transition formula {rhs!r} needs an intercept")
        emission_designs = {
            stream: {name: formulas.design(f, table) for name, f in by_name.items()}
            for stream, by_name in emission_formulas.items()
        }
        observations = Observations.from_frame(
            table, design, emission_designs=emission_designs, streams=tuple(self._streams())
        )
        known = None
        if self.known_states is not None:
            if self.known_states not in table.columns:
                raise ValueError(f"known_states: no column {self.known_states!r} in the data")
            known = known_state_terms(table[self.known_states], int(self.n_states))
        data = fit_data(observations, known)
        if np.all(np.isnan(data.step)):
            raise ValueError("no observed step in the data")
        spec = self._spec(data, emission_designs)
        template = initial_parameters(None, data, spec)  # refuses unknown parameters early
        control = con.FitControl(self.fixed or {}, tuple(self.equal or ()), self.stationary)
        if control:
            columns = ("Intercept",) if design is None else design.columns
            start_design = None if data.design is None else data.design[data.starts]
            spec = replace(
                spec, constraints=con.Constraints(control, template, columns, start_design)
            )
        if self.start is not None:
            template = _matching_start(parameters_of(self.start), template)
        spec = replace(spec, start=template)
        starts = run_starts(data, spec, int(self.n_starts), self.seed, int(self.n_jobs))
        failed = [s for s in starts if s.error is not None]
        if len(failed) == len(starts):
            errors = "; ".join(f"start {s.index}: {s.error}" for s in failed)
            raise ValueError(f"every EM start failed ({errors})")
        for s in failed:
            logger.warning("EM start %d failed and is left out: %s", s.index, s.error)
        best = max(starts, key=lambda s: (s.log_likelihood, -s.index))
        params, log_likelihood = best.parameters, best.log_likelihood
        unconverged = not best.monitor.converged and not best.polished
        if self.polish is True or (self.polish == "auto" and unconverged):
            params, log_likelihood = polish(params, data, constraints=spec.constraints)
            if not spec.keeps_labels:
                params = order_by_mean_step(params)
            best = replace(best, parameters=params, log_likelihood=log_likelihood, polished=True)
        n_parameters = working_likelihood(params, data, spec.constraints).size
        aic, bic = information_criteria(log_likelihood, n_parameters, data.n_obs)
        self.model_ = MovementHMM(
            initial=params.initial,
            transition=params.transition,
            step=params.step,
            angle=params.angle,
            streams=params.streams,
            dt=self._time_step(table),
            coefficients=params.coefficients,
            transition_design=design,
            step_unit=self.step_unit,
            log_likelihood=log_likelihood,
            n_obs=data.n_obs,
            aic=aic,
            bic=bic,
            control=control,
            state_names=None if self.state_names is None else tuple(self.state_names),
        )
        self.starts_ = starts
        self.best_start_ = best.index
        self.monitor_ = best.monitor
        self.n_parameters_ = n_parameters
        return self

    def _time_step(self, table: pd.DataFrame) -> float:
        if self.dt is not None:
            return float(self.dt)
        if "dt" in table.columns:
            dt = np.asarray(table["dt"], dtype=float)
            if np.any(np.isfinite(dt)):
                return float(np.nanmedian(dt))
        return float("nan")

    def _table(self, X, lengths):
        if not hasattr(self, "model_"):
            raise ValueError("this estimator is not fitted yet; call fit first")
        return as_table(X, lengths, tuple(self.covariates))

    def predict(self, X, lengths=None) -> np.ndarray:
        """Viterbi states (T,) of ``X`` (same forms as :meth:`fit`)."""
        table = self._table(X, lengths)
        return self.model_.viterbi(table)

    def predict_proba(self, X, lengths=None) -> np.ndarray:
        """Posterior state probabilities (T, K) of ``X``."""
        table = self._table(X, lengths)
        return self.model_.state_probabilities(table)

    def score(self, X, lengths=None) -> float:
        """Log-likelihood of ``X`` under the fitted model."""
        table = self._table(X, lengths)
        return self.model_.score(table)

    def sample(self, n: int, seed=None) -> pd.DataFrame:
        """Simulate ``n`` rows (state, step, angle) from the fitted model."""
        if not hasattr(self, "model_"):
            raise ValueError("this estimator is not fitted yet; call fit first")
        return self.model_.simulate(as_generator(seed), n)


def fit_movement_hmm(X, n_states: int = 2, *, lengths=None, seed=None, **options) -> MovementHMM:
    """Fit a movement HMM and return the model (see :class:`MovementHMMEstimator`).

    Examples
    --------
    >>> from hmmtrack import io, tracks                                   # doctest: +SKIP
    >>> prepared = tracks.prepare(io.read_tracks("data/example_tracks.csv"))  # doctest: +SKIP
    >>> model = fit_movement_hmm(prepared, 2, n_starts=5, seed=1)          # doctest: +SKIP
    >>> model.save("model.json")                                          # doctest: +SKIP
    """
    estimator = MovementHMMEstimator(n_states=n_states, seed=seed, **options)
    return estimator.fit(X, lengths).model_
