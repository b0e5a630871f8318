"""Checking a fitted movement HMM: pseudo-residuals, QQ / ACF, Wald intervals, AIC/BIC tables.

* :func:`pseudo_residuals` -- moveHMM's forecast pseudo-residuals: for row ``t`` of a
  sequence, ``Phi^-1(sum_k P(S_t = k | rows before t) F_k(x_t))`` with ``F_k`` the
  state-dependent CDF of each stream (steps with their zero mass, angles from -pi, further
  streams randomised between P(X < x) and P(X <= x)), the emission families' ``cdf``, with
  row ``t``'s parameters where the stream has emission formulas. Under a correct model each
  series is independent standard normal.
* :func:`qq_points`, :func:`autocorrelation` -- their QQ coordinates and ACF (statsmodels).
* :func:`confidence_intervals` -- Wald intervals: the Hessian of the log-likelihood on the
  working scale by central differences of its gradient, standard errors on the natural scale
  by the delta method, limits on the logit / log scale for probabilities / positive
  parameters so that they stay in range.
* :func:`model_selection_table` -- log-likelihood, parameters, AIC and BIC of several models.
* :func:`covariate_effects` -- transition and stationary probabilities against a covariate
  of the transition formula, with delta-method bands (on :func:`covariate_grid`).
* :func:`check_starts`, :func:`starts_table` -- fits from many random starting values: the
  log-likelihood and parameters each reached, and which reached the best optimum (what
  moveHMM users do by hand to trust a fit).

Not for fitting (:mod:`hmmtrack.hmm.fit`) or drawing (:mod:`hmmtrack.plots.hmm`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
from scipy import special, stats
from statsmodels.graphics.gofplots import ProbPlot
from statsmodels.tsa.stattools import acf

from hmmtrack.hmm import emission, fit
from hmmtrack.hmm.inference import forward_backward
from hmmtrack.hmm.model import MovementHMM

# ---------------------------------------------------------------------------------------------
# Pseudo-residuals
# ---------------------------------------------------------------------------------------------


def pseudo_residuals(model: MovementHMM, data: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """Forecast pseudo-residuals of steps, angles and further streams (moveHMM's
    ``pseudoRes``).

    A further stream's residuals are randomised quantile residuals (Dunn & Smyth 1996)
    where its family has point masses (counts, categories, 0 / 1 of a proportion): ``u``
    is drawn uniformly between the forecast P(X < x) and P(X <= x), so that the residuals
    of a correct model are standard normal for discrete data too. A stream with emission
    formulas has each row's CDF under that row's parameters (the families' ``row_cdf``).

    Parameters
    ----------
    model : MovementHMM
    data : DataFrame
        Prepared track (``step``, ``angle``, ``segment``, covariates, further streams).
    seed : int
        Seed of the uniform draws of the randomised residuals.

    Returns
    -------
    DataFrame
        Columns ``step_residual``, ``angle_residual`` and ``<stream>_residual`` per further
        stream, one row per data row; NaN where the observation is missing.
    """
    observations = model.observations(data)
    log_lik = model.log_likelihood_matrix(observations)
    forecast = forward_backward(
        model.log_initial_for(observations),
        model.log_transition_for(observations),
        log_lik,
        observations.lengths,
    ).predicted
    inputs = model.stream_inputs(observations)
    rng = np.random.default_rng(seed)
    out = {}
    for name, dist in model.emissions.items():
        x = inputs[name]
        upper = np.sum(forecast * dist.cdf(x), axis=1)
        u = upper
        if name not in emission.STREAMS:
            lower = np.sum(forecast * dist.cdf_below(x), axis=1)
            u = lower + rng.random(upper.size) * (upper - lower)
        out[f"{name}_residual"] = stats.norm.ppf(np.clip(u, 1e-300, 1 - 1e-16))
    return pd.DataFrame(out, index=data.index)


def qq_points(residuals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Theoretical and sample quantiles of the non-missing residuals against N(0, 1)."""
    residuals = np.asarray(residuals, dtype=float)
    plot = ProbPlot(residuals[np.isfinite(residuals)], dist=stats.norm)
    return plot.theoretical_quantiles, plot.sample_quantiles


def autocorrelation(residuals: np.ndarray, n_lags: int = 40) -> np.ndarray:
    """Sample autocorrelation of the residuals at lags 0..n_lags (missing values skipped)."""
    return acf(np.asarray(residuals, dtype=float), nlags=n_lags, missing="conservative")


# ---------------------------------------------------------------------------------------------
# Wald intervals
# ---------------------------------------------------------------------------------------------


def working_hessian(likelihood: fit.WorkingLikelihood, theta: np.ndarray, step: float = 1e-4):
    """Hessian of the log-likelihood on the working scale, central differences of the gradient.

    Returns
    -------
    ndarray, shape (n_parameters, n_parameters)
        Symmetrised.
    """
    n = theta.size
    hessian = np.empty((n, n))
    for i in range(n):
        shift = np.zeros(n)
        shift[i] = step
        up = likelihood.value_and_gradient(theta + shift)[1]
        down = likelihood.value_and_gradient(theta - shift)[1]
        hessian[i] = (up - down) / (2 * step)
    return 0.5 * (hessian + hessian.T)


def working_covariance(model: MovementHMM, data: pd.DataFrame):
    """Working-scale estimate of a fitted model and its covariance (inverse observed information).

    ``model`` and ``data`` as in :func:`confidence_intervals` (a fit and its prepared track).

    Returns
    -------
    likelihood : WorkingLikelihood
        Of ``data``, with the model's structure (its ``unpack`` maps working vectors back;
        the free vector of a model fitted with fixed or tied parameters:
        :func:`~hmmtrack.hmm.fit.model_likelihood`).
    theta : ndarray, shape (n_parameters,)
        The model's working vector.
    covariance : ndarray, shape (n_parameters, n_parameters)
        Pseudo-inverse of minus the Hessian of the log-likelihood at ``theta``.
    """
    likelihood = fit.model_likelihood(model, data)
    theta = likelihood.pack(fit.parameters_of(model))
    return likelihood, theta, np.linalg.pinv(-working_hessian(likelihood, theta))


def natural_parameters(
    params: fit.Parameters, covariate_names=()
) -> tuple[list[tuple], np.ndarray]:
    """Names and values of the natural parameters.

    Parameters
    ----------
    params : Parameters
    covariate_names : sequence of str
        Names of the coefficients' columns (:func:`coefficient_names`).

    Returns
    -------
    names : list of (parameter, index) tuples
        ``("step.mean", "1")``, ``("transition", "1->2")``, ``("beta.intercept", "1->2")``,
        ``("beta.dist_water", "1->2")``...; states numbered from 1 as moveHMM prints them;
        a categorical stream's probabilities per category (``("behaviour.prob2", "1")``).
        A parameter with an emission formula has its value at the intercept
        (``("step.mean", "1")``) and its coefficients on the link scale
        (``("step.mean.beta.cosT", "1")``, ``"intercept"`` for formulaic's ``"Intercept"``).
    values : ndarray, shape (n,)
    """
    names, values = [], []
    for prefix, dist in params.emissions.items():
        for key, value in dist.to_dict().items():
            if isinstance(value, list):
                for k, v in enumerate(value):
                    # a categorical's probabilities: one entry per category c, "prob<c>"
                    entries = enumerate(v, 1) if isinstance(v, list) else [("", v)]
                    for c, entry in entries:
                        names.append((f"{prefix}.{key}{c}", str(k + 1)))
                        values.append(entry)
        if isinstance(dist, emission.CovariateEmission):
            for key, design in dist.designs.items():
                for c, column in enumerate(_column_names(design.columns)):
                    for k in range(dist.n_states):
                        names.append((f"{prefix}.{key}.beta.{column}", str(k + 1)))
                        values.append(dist.coefficients[key][k, c])
    k = params.n_states
    if params.transition is not None:
        for i in range(k):
            for j in range(k):
                names.append(("transition", f"{i + 1}->{j + 1}"))
                values.append(params.transition[i, j])
    else:
        rows, cols = np.nonzero(~np.eye(k, dtype=bool))
        for c, covariate in enumerate(covariate_names):
            for r, (i, j) in enumerate(zip(rows, cols, strict=True)):
                names.append((f"beta.{covariate}", f"{i + 1}->{j + 1}"))
                values.append(params.coefficients[r, c])
    for i in range(k):
        names.append(("initial", str(i + 1)))
        values.append(params.initial[i])
    return names, np.asarray(values, dtype=float)


def coefficient_names(model: MovementHMM) -> tuple[str, ...]:
    """Names of the transition coefficients' columns: the formula's design columns, with
    ``"intercept"`` for formulaic's ``"Intercept"``; empty without covariates."""
    if model.transition_design is None:
        return ()
    return _column_names(model.transition_design.columns)


def _column_names(columns) -> tuple[str, ...]:
    """Design columns as printed: ``"intercept"`` for formulaic's ``"Intercept"``."""
    return tuple("intercept" if c == "Intercept" else c for c in columns)


def confidence_intervals(model: MovementHMM, data: pd.DataFrame, level: float = 0.95):
    """Wald confidence intervals of every natural parameter (delta method).

    Parameters
    ----------
    model : MovementHMM
        A fitted model (at the maximum of the likelihood of ``data``).
    data : DataFrame
        The prepared track it was fitted to.
    level : float
        Coverage probability.

    Returns
    -------
    DataFrame
        Columns ``parameter``, ``index``, ``estimate``, ``se``, ``lower``, ``upper``,
        ``fixed``. Coefficient rows are named ``beta.intercept`` and ``beta.<covariate>``. A
        parameter on the boundary (e.g. a zero mass of 0) gets a degenerate interval. A
        parameter the model's fit control holds fixed (it does not depend on any free
        parameter: a fixed value, a fixed transition row or initial distribution) has
        ``fixed`` True and no standard error or interval (NaN); tied parameters share theirs.
        A formula parameter's value at the intercept is not marked (its coefficients are).
    """
    params = fit.parameters_of(model)
    likelihood, theta, covariance = working_covariance(model, data)
    columns = coefficient_names(model)
    names, values = natural_parameters(params, columns)
    se = _delta_method_se(
        lambda t: natural_parameters(likelihood.unpack(t), columns)[1], theta, covariance
    )
    lower, upper = _interval(names, values, se, stats.norm.ppf(0.5 + level / 2))
    held = model.control.fixed_names(model.n_states)
    fixed = np.array([name in held for name in names], dtype=bool)
    se, lower, upper = (np.where(fixed, np.nan, a) for a in (se, lower, upper))
    return pd.DataFrame(
        {
            "parameter": [n for n, _ in names],
            "index": [i for _, i in names],
            "estimate": values,
            "se": se,
            "lower": lower,
            "upper": upper,
            "fixed": fixed,
        }
    )


def _delta_method_se(function, theta: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """Standard errors of ``function(theta)`` (shape (n,)) by the delta method: its Jacobian
    by central differences (step 1e-6) through the working covariance, shape (n,)."""
    columns = []
    for i in range(theta.size):
        shift = np.zeros(theta.size)
        shift[i] = 1e-6
        columns.append((function(theta + shift) - function(theta - shift)) / 2e-6)
    jacobian = np.stack(columns, axis=-1)
    return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", jacobian, covariance, jacobian), 0.0))


def _interval(names, values, se, z):
    """Wald limits on a scale that respects each parameter's range, mapped back.

    Probabilities (transition, initial, zero mass): logit scale; positive parameters (step
    parameters, concentrations): log scale; real ones (angle means, log-normal location,
    transition and emission coefficients): as they are. The standard error on the
    transformed scale is the delta method's ``se / |d transform^-1|``.
    """
    lower, upper = np.empty_like(values), np.empty_like(values)
    for i, ((name, _), value, s) in enumerate(zip(names, values, se, strict=True)):
        if name in ("transition", "initial", "step.zero_mass") and 0 < value < 1:
            centre, spread = np.log(value / (1 - value)), z * s / (value * (1 - value))
            lower[i], upper[i] = special.expit(centre - spread), special.expit(centre + spread)
        elif (
            name.startswith(("angle.mean", "step.location", "beta."))
            or ".beta." in name
            or not value > 0
        ):
            lower[i], upper[i] = value - z * s, value + z * s
        else:
            lower[i], upper[i] = value * np.exp(-z * s / value), value * np.exp(z * s / value)
    return lower, upper


def model_selection_table(models: dict[str, MovementHMM]) -> pd.DataFrame:
    """Log-likelihood, number of parameters, AIC and BIC of fitted models, best AIC first."""
    rows = []
    for name, model in models.items():
        n_parameters = round((model.aic + 2 * model.log_likelihood) / 2)
        rows.append(
            {
                "model": name,
                "log_likelihood": model.log_likelihood,
                "n_parameters": n_parameters,
                "n_obs": model.n_obs,
                "aic": model.aic,
                "bic": model.bic,
            }
        )
    return pd.DataFrame(rows).sort_values("aic", ignore_index=True)


def data_scale_coefficients(model: MovementHMM) -> pd.DataFrame:
    """Transition coefficients on the data's scale, one row per transition ``"i->j"``
    (states from 1), one column per design column
    (:meth:`~hmmtrack.hmm.model.MovementHMM.coefficients_on_data_scale`)."""
    rows, cols = np.nonzero(~np.eye(model.n_states, dtype=bool))
    return pd.DataFrame(
        model.coefficients_on_data_scale(),
        index=[f"{i + 1}->{j + 1}" for i, j in zip(rows, cols, strict=True)],
        columns=list(coefficient_names(model)),
    )


def emission_coefficients(model: MovementHMM) -> dict[str, pd.DataFrame]:
    """The emission formulas' coefficients on the data's scale, by parameter
    (``"step.mean"``): one row per state (from 1), one column per design column, on the
    parameter's link scale (per unit of each column as the data have it; the intercept at
    zero)."""
    out = {}
    for stream, designs in model.emission_designs.items():
        dist = model.emissions[stream]
        for name, design in designs.items():
            out[f"{stream}.{name}"] = pd.DataFrame(
                design.to_data_scale(dist.coefficients[name]),
                index=[f"state {k + 1}" for k in range(model.n_states)],
                columns=list(_column_names(design.columns)),
            )
    return out


def summary(model: MovementHMM, intervals: pd.DataFrame | None = None) -> str:
    """Readable text: parameters (with intervals), transition matrix, log-likelihood, AIC/BIC.

    Parameters
    ----------
    model : MovementHMM
    intervals : DataFrame, optional
        Output of :func:`confidence_intervals`; without it only estimates are shown. Fixed
        parameters show "fixed" instead of a standard error.
    """
    lines = [
        f"{model.n_states}-state movement HMM: step {model.step.name} ({model.step_unit}), "
        f"angle {model.angle.name} (rad); "
        + (f"time step {model.dt:g} s" if np.isfinite(model.dt) else "no time step (no times)"),
        f"log-likelihood {model.log_likelihood:.4f}   AIC {model.aic:.4f}   BIC {model.bic:.4f}"
        f"   rows {model.n_obs}",
        *_control_lines(model),
        "",
    ]
    if intervals is None:
        names, values = natural_parameters(fit.parameters_of(model), coefficient_names(model))
        intervals = pd.DataFrame(
            {"parameter": [n for n, _ in names], "index": [i for _, i in names], "estimate": values}
        )
    shown = intervals
    if "fixed" in intervals.columns:
        shown = intervals.drop(columns="fixed")
        if intervals["fixed"].any() and "se" in shown.columns:
            shown = shown.astype({"se": object})
            shown.loc[intervals["fixed"].to_numpy(), "se"] = "fixed"
    lines.append(shown.to_string(index=False, float_format=lambda v: f"{v:.6g}"))
    lines.append("")
    if model.transition_design is not None:
        lines.append("")
        lines.append(
            f"transition coefficients ({model.transition_design.formula}) on the data's scale "
            "(per unit of each column; the intercept at zero)"
        )
        lines.append(data_scale_coefficients(model).to_string(float_format=lambda v: f"{v:.6g}"))
        lines.append("")
    for name, table in emission_coefficients(model).items():
        stream, parameter = name.split(".", 1)
        design = model.emission_designs[stream][parameter]
        lines.append(
            f"{name} coefficients ({design.formula}, link scale) on the data's scale (per "
            "unit of each column; the intercept at zero)"
        )
        lines.append(table.to_string(float_format=lambda v: f"{v:.6g}"))
        lines.append("")
    lines.append(
        "transition matrix"
        + (
            " at the covariate means (factors at their reference levels)"
            if model.transition_design is not None
            else ""
        )
    )
    gamma = model.transition_matrix()
    labels = [f"state {k + 1}" for k in range(model.n_states)]
    if model.state_names is not None:
        labels = [f"{k + 1} {name}" for k, name in enumerate(model.state_names)]
    lines.append(pd.DataFrame(gamma, index=labels, columns=labels).to_string(float_format="%.4f"))
    stationary = "  ".join(f"{p:.4f}" for p in model.stationary())
    lines.append(f"stationary distribution: {stationary}")
    return "\n".join(lines)


def starts_table(starts, tolerance: float = 1e-3, columns=()) -> pd.DataFrame:
    """Where each start of a multi-start fit ended.

    Parameters
    ----------
    starts : list of StartResult
        A fit's ``starts_`` (:class:`hmmtrack.hmm.fit.MovementHMMEstimator`): each start's EM
        result, states ordered by mean step (unless the fit control names states).
    tolerance : float
        A start reached the best optimum when its log-likelihood is within this of the best
        start's (nats; EM converged to ``tol`` per row stops within ~1e-5 of its optimum).
    columns : sequence of str
        Names of the transition design's columns (:func:`coefficient_names`); empty
        without transition covariates.

    Returns
    -------
    DataFrame
        One row per start: ``start`` (from 1), ``log_likelihood`` (NaN for a start that
        failed), ``n_iter``, ``converged``, ``best`` (reached the best optimum), ``error``,
        then one column per natural parameter named as ``--fix`` names them
        (``step.mean[1]``, ``transition[1,2]``, ``initial[1]``; coefficients
        ``beta.<column>[1,2]``); rows in start order.
    """
    ok = [s for s in starts if s.error is None]
    best = max((s.log_likelihood for s in ok), default=np.nan)
    rows = []
    for s in starts:
        row = {
            "start": s.index + 1,
            "log_likelihood": s.log_likelihood if s.error is None else np.nan,
            "n_iter": s.monitor.n_iter,
            "converged": s.monitor.converged,
            "best": s.error is None and bool(s.log_likelihood >= best - tolerance),
            "error": s.error or "",
        }
        names, values = natural_parameters(s.parameters, columns)
        for (name, index), value in zip(names, values, strict=True):
            row[f"{name}[{index.replace('->', ',')}]"] = value if s.error is None else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def check_starts(
    data: pd.DataFrame,
    n_states: int = 2,
    *,
    n_starts: int = 20,
    rng=None,
    tolerance=1e-3,
    **options,
) -> pd.DataFrame:
    """Fit from ``n_starts`` random starting values and tabulate where each start ended.

    The first start uses the deterministic starting values, the others random ones
    (:func:`hmmtrack.hmm.fit.initial_parameters`) from seeds spawned from ``rng``. A fit
    whose starts mostly reach the best log-likelihood with the same parameters is
    trustworthy; a spread of optima says the likelihood is multimodal (or the model is
    poorly identified) and more starts are needed.

    Parameters
    ----------
    data : DataFrame
        A prepared track (as :meth:`~hmmtrack.hmm.fit.MovementHMMEstimator.fit` takes).
    n_states : int
    n_starts : int
    rng : int, SeedSequence or None
        Seed of the starts.
    tolerance : float
        See :func:`starts_table`.
    **options
        Further options of :class:`~hmmtrack.hmm.fit.MovementHMMEstimator` (families,
        formulas, ``fixed``...).

    Returns
    -------
    DataFrame
        :func:`starts_table` of the fit's starts (EM results before any polish).
    """
    estimator = fit.MovementHMMEstimator(n_states, n_starts=n_starts, seed=rng, **options)
    model = estimator.fit(data).model_
    return starts_table(estimator.starts_, tolerance, coefficient_names(model))


def _control_lines(model: MovementHMM) -> list[str]:
    """The summary's lines on state names and the fit control (none without)."""
    lines = []
    if model.state_names is not None:
        names = ", ".join(f"{k + 1} = {n}" for k, n in enumerate(model.state_names))
        lines.append(f"states: {names}")
    control = model.control
    if control.fixed:
        lines.append("fixed: " + ", ".join(f"{k}={v:g}" for k, v in control.fixed.items()))
    if control.equal:
        lines.append("equal: " + ", ".join(control.equal))
    if control.stationary:
        lines.append("initial distribution: stationary (of the transition matrix)")
    return lines


# ---------------------------------------------------------------------------------------------
# Transition and stationary probabilities against a covariate
# ---------------------------------------------------------------------------------------------


def covariate_grid(
    model: MovementHMM, data: pd.DataFrame, variable: str, n_points: int = 101
) -> pd.DataFrame:
    """Rows of raw covariate values along one variable of the transition formula.

    ``variable`` runs over its range in ``data`` (``n_points`` evenly spaced values) or over
    its levels (a text column); every other variable of the formula is held at its mean in
    ``data`` (text columns: at the first level in sorted order, the formula's reference).

    Returns
    -------
    DataFrame
        One column per variable of the formula, ``n_points`` (or the number of levels) rows.
    """
    if model.transition_design is None:
        raise ValueError("the model has no transition formula; nothing depends on a covariate")
    variables = sorted(model.transition_design.spec.required_variables)
    if variable not in variables:
        raise ValueError(
            f"{variable!r} is not a variable of the transition formula "
            f"{model.transition_design.formula!r}; its variables: {variables}"
        )
    missing = [v for v in variables if v not in data.columns]
    if missing:
        raise ValueError(f"the data lack the formula's column(s) {missing}")

    def numeric(name):
        return pd.api.types.is_numeric_dtype(data[name]) and not pd.api.types.is_bool_dtype(
            data[name]
        )

    column = data[variable].dropna()
    if numeric(variable):
        values = np.linspace(column.min(), column.max(), n_points)
    else:
        values = np.array(sorted(column.unique()), dtype=object)
    grid = {variable: values}
    for name in variables:
        if name != variable:
            value = data[name].mean() if numeric(name) else sorted(data[name].dropna().unique())[0]
            grid[name] = np.full(len(values), value, dtype=object if not numeric(name) else float)
    return pd.DataFrame(grid)


def covariate_effects(
    model: MovementHMM,
    data: pd.DataFrame,
    variable: str,
    *,
    n_points: int = 101,
    level: float = 0.95,
) -> pd.DataFrame:
    """Transition and stationary probabilities against one covariate, with Wald bands.

    The probabilities are evaluated on :func:`covariate_grid`; their confidence bands come
    from the working-scale covariance of the fit (:func:`working_covariance`, inverse
    observed information) by the delta method on the logit scale, mapped back, so that they
    stay inside (0, 1) -- momentuHMM's ``plot(..., plotCI=TRUE)``.

    Parameters
    ----------
    model : MovementHMM
        A fit with a transition formula, at the maximum of the likelihood of ``data``.
    data : DataFrame
        The prepared track it was fitted to.
    variable : str
        A variable (column) the transition formula names.
    n_points : int
        Grid size of a numeric variable.
    level : float
        Coverage of the bands.

    Returns
    -------
    DataFrame
        Long table: ``value`` (the variable), ``kind`` (``"transition"`` or
        ``"stationary"``), ``from_state`` (1-based; 0 for stationary rows), ``to_state``
        (1-based), ``estimate``, ``lower``, ``upper``; one row per grid value and
        probability (``K * K`` transitions and ``K`` stationary ones per value).
    """
    grid = covariate_grid(model, data, variable, n_points)
    likelihood, theta, covariance = working_covariance(model, data)
    k = model.n_states

    def probabilities(working: np.ndarray) -> np.ndarray:
        coefficients = likelihood.unpack(working).coefficients
        candidate = replace(model, coefficients=coefficients)
        gamma = candidate.transition_matrix(grid).reshape(len(grid), k * k)
        return np.concatenate([gamma, candidate.stationary(grid)], axis=1).ravel()

    def logit(working: np.ndarray) -> np.ndarray:
        return special.logit(np.clip(probabilities(working), 1e-12, 1 - 1e-12))

    centre = logit(theta)
    spread = stats.norm.ppf(0.5 + level / 2) * _delta_method_se(logit, theta, covariance)
    rows, cols = np.divmod(np.arange(k * k), k)
    per_value = pd.DataFrame(
        {
            "kind": ["transition"] * (k * k) + ["stationary"] * k,
            "from_state": np.r_[rows + 1, np.zeros(k, dtype=int)],
            "to_state": np.r_[cols + 1, np.arange(1, k + 1)],
        }
    )
    out = pd.concat([per_value] * len(grid), ignore_index=True)
    out.insert(0, "value", np.repeat(grid[variable].to_numpy(), len(per_value)))
    out["estimate"] = special.expit(centre)
    out["lower"] = special.expit(centre - spread)
    out["upper"] = special.expit(centre + spread)
    return out
