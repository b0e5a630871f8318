"""Tests of hmmtrack.hmm.diagnostics: pseudo-residuals, Wald intervals, AIC/BIC."""

from dataclasses import replace

import matplotlib
import matplotlib.pyplot
import numpy as np
import pandas as pd
import pytest
from scipy import stats

from hmmtrack.hmm import diagnostics
from hmmtrack.hmm.distributions import Gamma, VonMises
from hmmtrack.hmm.fit import MovementHMMEstimator
from hmmtrack.hmm.formula import Design
from hmmtrack.hmm.inference import forward_backward
from hmmtrack.hmm.model import MovementHMM

TRUE = MovementHMM(
    initial=np.array([0.4, 0.6]),
    transition=np.array([[0.85, 0.15], [0.1, 0.9]]),
    step=Gamma(np.array([1.0, 5.0]), np.array([0.7, 2.0])),
    angle=VonMises(np.array([3.0, 0.2]), np.array([0.7, 4.0])),
)


def simulate(model, n_tracks, length, seed, n_missing=20):
    rng = np.random.default_rng(seed)
    parts = [model.simulate(rng, length).assign(segment=f"t{i}") for i in range(n_tracks)]
    table = pd.concat(parts, ignore_index=True)
    table.loc[rng.choice(len(table), n_missing, replace=False), ["step", "angle"]] = np.nan
    return table


def test_pseudo_residuals_of_the_true_model_are_standard_normal():
    data = simulate(TRUE, 3, 2000, seed=12)
    residuals = diagnostics.pseudo_residuals(TRUE, data)
    for column in ("step_residual", "angle_residual"):
        r = residuals[column].to_numpy()
        assert np.isnan(r).sum() == data[column.split("_")[0]].isna().sum()
        r = r[np.isfinite(r)]
        assert stats.kstest(r, "norm").pvalue > 0.01
        assert abs(np.mean(r)) < 0.05 and abs(np.std(r) - 1) < 0.05
        assert np.all(np.abs(diagnostics.autocorrelation(residuals[column], 5)[1:]) < 0.05)


def test_pseudo_residuals_reveal_a_wrong_model():
    data = simulate(TRUE, 1, 3000, seed=13)
    one_state = MovementHMMEstimator(1, seed=0).fit(data).model_
    r = diagnostics.pseudo_residuals(one_state, data)["step_residual"]
    # a one-state model ignores the persistence of the states: residuals autocorrelate
    assert diagnostics.autocorrelation(r, 1)[1] > 0.2


def test_pseudo_residuals_match_a_forward_oracle_on_a_short_sequence():
    data = simulate(TRUE, 1, 12, seed=3, n_missing=2).assign(segment="a")
    residuals = diagnostics.pseudo_residuals(TRUE, data)
    log_lik = TRUE.log_likelihood_matrix(TRUE.observations(data))
    log_a = np.log(TRUE.transition)
    for t in range(12):
        if t == 0:
            forecast = TRUE.initial
        else:  # the smoothed probabilities of the last row of the truncated data = filtered
            past = forward_backward(np.log(TRUE.initial), log_a, log_lik[:t]).posterior[-1]
            forecast = past @ TRUE.transition
        step, angle = data["step"].iloc[t], data["angle"].iloc[t]
        step_cdf = stats.gamma.cdf(step, a=TRUE.step.shape, scale=TRUE.step.scale)
        angle_cdf = stats.vonmises.cdf(angle, TRUE.angle.concentration, loc=TRUE.angle.mean)
        angle_cdf -= stats.vonmises.cdf(-np.pi, TRUE.angle.concentration, loc=TRUE.angle.mean)
        for name, cdf in (("step", step_cdf), ("angle", angle_cdf)):
            residual = residuals[f"{name}_residual"].iloc[t]
            if np.isnan(cdf).any():
                assert np.isnan(residual)
            else:
                expected = stats.norm.ppf(np.sum(forecast * cdf))
                np.testing.assert_allclose(residual, expected, rtol=1e-9)


def test_wald_intervals_match_the_spread_of_replicate_fits():
    estimates, ses, covered = [], [], []
    for seed in range(24):
        data = simulate(TRUE, 1, 800, seed=100 + seed)
        model = MovementHMMEstimator(2, seed=seed).fit(data).model_
        table = diagnostics.confidence_intervals(model, data)
        rows = table[table["parameter"].isin(["step.mean", "angle.concentration", "transition"])]
        truth = np.concatenate([TRUE.step.mean, TRUE.angle.concentration, TRUE.transition.ravel()])
        estimates.append(rows["estimate"].to_numpy())
        ses.append(rows["se"].to_numpy())
        covered.append((rows["lower"] <= truth) & (truth <= rows["upper"]))
    estimates, ses, covered = np.array(estimates), np.array(ses), np.array(covered)
    ratio = ses.mean(axis=0) / estimates.std(axis=0, ddof=1)
    assert np.all((ratio > 0.6) & (ratio < 1.6)), ratio
    assert np.all(covered.mean(axis=0) >= 0.75), covered.mean(axis=0)
    assert covered.mean() > 0.88


def test_confidence_interval_table_layout_and_ranges():
    data = simulate(TRUE, 2, 500, seed=5)
    model = MovementHMMEstimator(2, seed=1).fit(data).model_
    table = diagnostics.confidence_intervals(model, data, level=0.9)
    assert list(table.columns) == [
        "parameter", "index", "estimate", "se", "lower", "upper", "fixed"
    ]  # fmt: skip
    assert not table["fixed"].any()  # nothing is fixed without fit control
    probabilities = table[table["parameter"].isin(["transition", "initial"])]
    assert (probabilities["lower"] >= 0).all() and (probabilities["upper"] <= 1).all()
    assert (table["lower"] <= table["estimate"]).all() and (
        table["estimate"] <= table["upper"]
    ).all()
    wider = diagnostics.confidence_intervals(model, data, level=0.99)
    assert np.all(wider["upper"] - wider["lower"] >= table["upper"] - table["lower"])
    text = diagnostics.summary(model, table)
    assert "transition matrix" in text and f"{model.log_likelihood:.4f}" in text


def test_aic_bic_and_model_selection_table():
    data = simulate(TRUE, 1, 3000, seed=8)
    models = {f"{k} states": MovementHMMEstimator(k, seed=1).fit(data).model_ for k in (1, 2, 3)}
    for k, model in enumerate(models.values(), start=1):
        # step mean & sd, angle mean & concentration per state; K(K-1) transitions; K-1 initial
        p = 4 * k + k * (k - 1) + k - 1
        assert model.aic == pytest.approx(-2 * model.log_likelihood + 2 * p)
        assert model.bic == pytest.approx(-2 * model.log_likelihood + p * np.log(3000))
    table = diagnostics.model_selection_table(models)
    assert table["model"].iloc[0] != "1 states"
    assert table["aic"].is_monotonic_increasing
    assert table.set_index("model").loc["3 states", "n_parameters"] == 20


def test_qq_points_and_autocorrelation():
    r = np.array([0.5, np.nan, -1.0, 2.0, 0.1, -0.3])
    theoretical, sample = diagnostics.qq_points(r)
    np.testing.assert_array_equal(sample, np.sort(r[np.isfinite(r)]))
    np.testing.assert_allclose(theoretical, -theoretical[::-1], atol=1e-12)
    x = np.random.default_rng(1).normal(size=200)
    centred = x - x.mean()
    lag1 = np.sum(centred[1:] * centred[:-1]) / np.sum(centred**2)
    assert diagnostics.autocorrelation(x, 3)[1] == pytest.approx(lag1)


def test_plots_draw_the_diagnostics_and_densities():
    matplotlib.use("Agg")
    from matplotlib.collections import LineCollection

    from hmmtrack.plots import hmm as plots

    data = simulate(TRUE, 2, 800, seed=2)
    residuals = diagnostics.pseudo_residuals(TRUE, data)
    ax = plots.residual_qq_plot(residuals["step_residual"], "step")
    x, y = ax.collections[0].get_offsets().T
    theoretical, sample = diagnostics.qq_points(residuals["step_residual"])
    np.testing.assert_allclose(x, theoretical)
    np.testing.assert_allclose(y, sample)
    ax = plots.residual_acf_plot(residuals["angle_residual"], n_lags=10)
    assert ax.collections[0].get_segments()[1][1][1] == pytest.approx(
        diagnostics.autocorrelation(residuals["angle_residual"], 10)[1]
    )
    # state densities weighted by the stationary distribution: areas = stationary weights
    for kind, values in (("step", data["step"]), ("angle", data["angle"])):
        ax = plots.emission_density_plot(TRUE, values, kind)
        areas = [np.trapezoid(line.get_ydata(), line.get_xdata()) for line in ax.lines]
        np.testing.assert_allclose(areas[:2], TRUE.stationary(), atol=0.01)
        assert areas[2] == pytest.approx(1.0, abs=0.01)
    with pytest.raises(ValueError, match="no time step"):
        plots.emission_density_plot(TRUE, data["step"], "step", per_second=True)
    timed = replace(TRUE, dt=30.0)
    ax = plots.emission_density_plot(timed, data["angle"] / 30.0, "angle", per_second=True)
    assert np.trapezoid(ax.lines[2].get_ydata(), ax.lines[2].get_xdata()) == pytest.approx(1.0)
    heading = np.cumsum(np.nan_to_num(data["angle"]))
    track = data.assign(
        x=np.cumsum(data["step"].fillna(0) * np.cos(heading)),
        y=np.cumsum(data["step"].fillna(0) * np.sin(heading)),
    )
    ax = plots.decoded_track_plot(track, data["state"].to_numpy())
    lines = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert sum(len(c.get_segments()) for c in lines) == len(data) - 2
    dots = [c for c in ax.collections if not isinstance(c, LineCollection)]
    assert sum(len(c.get_offsets()) for c in dots) == len(data)  # every fix, short steps too
    assert dots[-1].get_label() == "state 1" and dots[-1].get_zorder() > dots[0].get_zorder()
    matplotlib.pyplot.close("all")


def test_confidence_intervals_of_covariate_coefficients():
    rng = np.random.default_rng(17)
    n = 4000
    values = {"c": rng.normal(size=n)}
    true = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=None,
        coefficients=np.array([[-2.0, 1.0], [-1.5, -0.5]]),
        transition_design=Design.from_dict(
            {
                "formula": "~ c",
                "columns": ["Intercept", "c"],
                "scaling": {"c": {"centre": 0.0, "sd": 1.0}},
            }
        ),
        step=TRUE.step,
        angle=TRUE.angle,
    )
    data = true.simulate(rng, n, values).assign(c=values["c"])
    model = MovementHMMEstimator(2, covariates=["c"], seed=1).fit(data).model_
    table = diagnostics.confidence_intervals(model, data).set_index(["parameter", "index"])
    beta = table.loc["beta.c"]
    assert list(beta.index) == ["1->2", "2->1"]
    # the slope in standardised units: true slope times the sample sd of c
    sd = model.transition_design.scaling["c"][1]
    for index, slope in zip(["1->2", "2->1"], true.coefficients[:, 1] * sd, strict=True):
        lower, upper, se = beta.loc[index, ["lower", "upper", "se"]]
        assert lower < slope < upper and 0.02 < se < 0.3
    assert "beta.intercept" in diagnostics.summary(model, table.reset_index())
