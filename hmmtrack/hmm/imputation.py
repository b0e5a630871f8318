"""Multiple imputation: one movement HMM per imputed track, pooled by Rubin's rules.

An irregular track regularised by a single prediction hides the uncertainty of the positions
between fixes. Multiple imputation (momentuHMM's ``MIfitHMM``) draws ``M`` whole tracks from
their distribution given the fixes (:func:`hmmtrack.hmm.crw.impute`), fits the same HMM to
each, and pools the estimates with Rubin's rules on the working (unconstrained) scale, where
the estimates are closest to normal:

* pooled estimate ``theta_bar = mean_m theta_m``;
* within-imputation covariance ``W = mean_m U_m`` (``U_m`` the inverse observed information
  of fit ``m``, :func:`hmmtrack.hmm.diagnostics.working_covariance`);
* between-imputation covariance ``B = cov_m(theta_m)`` (zero when ``M = 1``);
* total covariance ``W + (1 + 1/M) B``.

States are matched across fits by the fitter's own labelling (increasing mean step).

Not for drawing the imputed tracks (:mod:`hmmtrack.hmm.crw`) or fitting one HMM
(:mod:`hmmtrack.hmm.fit`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.hmm.diagnostics import working_covariance
from hmmtrack.hmm.fit import MovementHMMEstimator
from hmmtrack.hmm.model import MovementHMM


@dataclass(frozen=True)
class RubinPooled:
    """Estimates of ``M`` analyses pooled by Rubin's rules.

    Attributes
    ----------
    estimate : ndarray, shape (p,)
        Mean of the ``M`` estimates.
    covariance : ndarray, shape (p, p)
        Total covariance ``within + (1 + 1/M) between``.
    within : ndarray, shape (p, p)
        Mean of the ``M`` covariances.
    between : ndarray, shape (p, p)
        Sample covariance of the estimates (``ddof = 1``; zeros when ``M = 1``).
    """

    estimate: np.ndarray
    covariance: np.ndarray
    within: np.ndarray
    between: np.ndarray


def rubin(estimates: np.ndarray, covariances: np.ndarray) -> RubinPooled:
    """Pool ``M`` estimates and their covariances by Rubin's rules.

    Parameters
    ----------
    estimates : ndarray, shape (M, p)
    covariances : ndarray, shape (M, p, p)
    """
    estimates = np.asarray(estimates, dtype=float)
    covariances = np.asarray(covariances, dtype=float)
    m, p = estimates.shape
    if covariances.shape != (m, p, p):
        raise ValueError(f"covariances must have shape ({m}, {p}, {p}), got {covariances.shape}")
    within = covariances.mean(axis=0)
    between = np.cov(estimates, rowvar=False, ddof=1).reshape(p, p) if m > 1 else np.zeros((p, p))
    return RubinPooled(
        estimate=estimates.mean(axis=0),
        covariance=within + (1.0 + 1.0 / m) * between,
        within=within,
        between=between,
    )


@dataclass(frozen=True)
class ImputedFit:
    """Movement HMMs fitted to ``M`` imputed tracks, and their pooled model.

    Attributes
    ----------
    model : MovementHMM
        Pooled parameters (the working vectors' mean, mapped back); ``log_likelihood``,
        ``aic`` and ``bic`` are NaN (no single data set has this fit), ``n_obs`` is the
        rows of one imputed track.
    pooled : RubinPooled
        Working-scale estimate and covariances (the layout of
        :class:`hmmtrack.hmm.fit.WorkingLikelihood`).
    models : tuple of MovementHMM
        The ``M`` fits, in the order of the tracks.
    """

    model: MovementHMM
    pooled: RubinPooled
    models: tuple[MovementHMM, ...]


def fit_imputed(tables, n_states: int = 2, *, seed=None, **options) -> ImputedFit:
    """Fit the same movement HMM to each imputed track and pool by Rubin's rules.

    Parameters
    ----------
    tables : sequence of DataFrame
        Prepared tracks (:func:`hmmtrack.tracks.prepare` of each of
        :func:`hmmtrack.hmm.crw.impute`'s tables), with the same rows and covariates.
    n_states : int
    seed : int, SeedSequence or None
        Seed of every fit's starts (each fit uses the same seed).
    **options
        Further :class:`~hmmtrack.hmm.fit.MovementHMMEstimator` options; with ``fixed``,
        ``equal`` or ``stationary`` the pooled vector is the free one (fixed parameters stay
        fixed) and the pooled model keeps the fit control and the state names.

    Returns
    -------
    ImputedFit
    """
    tables = list(tables)
    if not tables:
        raise ValueError("fit_imputed needs at least one imputed track")
    models, estimates, covariances = [], [], []
    for table in tables:
        model = MovementHMMEstimator(n_states=n_states, seed=seed, **options).fit(table).model_
        likelihood, theta, covariance = working_covariance(model, table)
        if models and _standardisation(model) != _standardisation(models[0]):
            raise ValueError(
                "the imputed tracks standardise their covariates differently; pool only fits "
                "whose covariates are the same in every imputed track"
            )
        models.append(model)
        estimates.append(theta)
        covariances.append(covariance)
    pooled = rubin(np.array(estimates), np.array(covariances))
    params = likelihood.unpack(pooled.estimate)
    first = models[0]
    model = MovementHMM(
        initial=params.initial,
        transition=params.transition,
        step=params.step,
        angle=params.angle,
        dt=first.dt,
        coefficients=params.coefficients,
        transition_design=first.transition_design,
        step_unit=first.step_unit,
        n_obs=first.n_obs,
        control=first.control,
        state_names=first.state_names,
    )
    return ImputedFit(model, pooled, tuple(models))


def pooled_table(result: ImputedFit) -> pd.DataFrame:
    """Working-scale estimates with their within, between and total standard errors.

    Returns
    -------
    DataFrame
        One row per working parameter: ``estimate``, ``se_within``, ``se_between``, ``se``
        (total), ``fraction_missing`` (``(1 + 1/M) B / T`` on the diagonal: the share of
        the variance due to the missing positions).
    """
    pooled = result.pooled
    m = len(result.models)
    # a parameter on its boundary (the initial distribution of one track) can get a slightly
    # negative variance from the pseudo-inverse: it is not identified, its se is 0
    total = np.maximum(np.diag(pooled.covariance), 0.0)
    extra = (1.0 + 1.0 / m) * np.diag(pooled.between)
    return pd.DataFrame(
        {
            "estimate": pooled.estimate,
            "se_within": np.sqrt(np.maximum(np.diag(pooled.within), 0.0)),
            "se_between": np.sqrt(np.diag(pooled.between)),
            "se": np.sqrt(total),
            "fraction_missing": np.divide(extra, total, out=np.zeros_like(total), where=total > 0),
        }
    )


def _standardisation(model: MovementHMM):
    """The transition design's columns and scaling (None without covariates)."""
    design = model.transition_design
    return None if design is None else (design.columns, design.scaling)
