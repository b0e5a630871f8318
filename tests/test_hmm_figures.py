"""Figures of fitted HMMs, covariate effects with bands, and decoded tables aligned to files."""

from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
import pytest
from scipy import special, stats

from hmmtrack import io, tracks
from hmmtrack.hmm import Gamma, MovementHMM, MovementHMMEstimator, VonMises, diagnostics
from hmmtrack.hmm.decoding import decode_table
from hmmtrack.hmm.distributions import Normal
from hmmtrack.hmm.emission import CovariateEmission
from hmmtrack.hmm.formula import design

matplotlib.use("Agg")

from hmmtrack.plots import hmm as plots  # noqa: E402

TRUE = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=np.array([[0.9, 0.1], [0.15, 0.85]]),
    step=Gamma(np.array([20.0, 400.0]), np.array([15.0, 300.0])),
    angle=VonMises(np.array([0.0, 0.0]), np.array([0.6, 8.0])),
)


@pytest.fixture(scope="module")
def covariate_fit():
    """A 2-state fit with one covariate symmetric about 0, so that its grid's middle value
    is its mean (the standardised design's zero)."""
    rng = np.random.default_rng(3)
    n = 1206
    z = np.tile(np.linspace(-1.0, 1.0, 201), 6)
    coefficients = np.array([[-2.0, 1.5], [-1.5, -1.0]])
    model = MovementHMM(
        initial=TRUE.initial,
        transition=None,
        step=TRUE.step,
        angle=TRUE.angle,
        coefficients=coefficients,
        transition_design=design("~ z", pd.DataFrame({"z": z})),
    )
    data = model.simulate(rng, n, {"z": z}).assign(z=z, segment="a")
    fitted = MovementHMMEstimator(2, formula="~ z", n_starts=1, seed=1).fit(data).model_
    return fitted, data


def test_covariate_effects_are_the_model_probabilities_with_delta_method_bands(covariate_fit):
    model, data = covariate_fit
    effects = diagnostics.covariate_effects(model, data, "z", n_points=11, level=0.9)
    assert len(effects) == 11 * (4 + 2)
    grid = diagnostics.covariate_grid(model, data, "z", n_points=11)
    gamma = model.transition_matrix(grid)
    transitions = effects[effects["kind"] == "transition"]
    np.testing.assert_allclose(transitions["estimate"], gamma.reshape(-1), rtol=1e-12)
    stationary = effects[effects["kind"] == "stationary"]
    np.testing.assert_allclose(stationary["estimate"], model.stationary(grid).ravel())
    assert (effects["lower"] < effects["estimate"]).all()
    assert (effects["estimate"] < effects["upper"]).all()
    # at z = its mean the logit of p(1->2) is the intercept: its band is the intercept's
    # Wald interval (same covariance, same delta method), half-width z_0.95 * se
    middle = transitions[(transitions["value"] == 0.0) & (transitions["from_state"] == 1)]
    p12 = middle[middle["to_state"] == 2].iloc[0]
    half = (special.logit(p12["upper"]) - special.logit(p12["lower"])) / 2
    table = diagnostics.confidence_intervals(model, data)
    se = table.query("parameter == 'beta.intercept' and index == '1->2'")["se"].iloc[0]
    assert half == pytest.approx(stats.norm.ppf(0.95) * se, rel=1e-3)
    with pytest.raises(ValueError, match="not a variable"):
        diagnostics.covariate_effects(model, data, "depth")


def test_log_axis_densities_keep_the_stationary_weights():
    data = TRUE.simulate(np.random.default_rng(1), 3000)
    ax = plots.emission_density_plot(TRUE, data["step"], "step", log=True)
    assert ax.get_xscale() == "log"
    areas = [np.trapezoid(line.get_ydata(), np.log10(line.get_xdata())) for line in ax.lines]
    np.testing.assert_allclose(areas[:2], TRUE.stationary(), atol=0.01)
    assert "log" in ax.get_xlabel() and "(m)" in ax.get_xlabel()
    with pytest.raises(ValueError, match="log=True is for steps"):
        plots.emission_density_plot(TRUE, data["angle"], "angle", log=True)
    matplotlib.pyplot.close("all")


def test_steps_in_another_unit_than_the_model_are_refused():
    track = pd.DataFrame({"id": "a", "x": np.arange(20.0) * 100, "y": np.zeros(20)})
    prepared = tracks.prepare(track, scale=1000.0)  # km
    with pytest.raises(ValueError, match="steps are in km .* fitted to steps in m"):
        plots.emission_density_plot(TRUE, prepared["step"], "step")


def test_state_names_label_every_figure_and_must_fit_the_states():
    assert plots.state_labels(2, ["encamped", "exploratory"]) == ["1 encamped", "2 exploratory"]
    assert plots.state_labels(2) == ["state 1", "state 2"]
    for names in (["a"], ["a", "a"], ["a", ""]):
        with pytest.raises(ValueError, match="2 distinct"):
            plots.state_labels(2, names)


def test_standard_figures_of_a_covariate_fit(covariate_fit):
    model, data = covariate_fit
    sim = data.copy()
    heading = np.cumsum(np.nan_to_num(sim["angle"]))
    sim["x"] = np.cumsum(sim["step"] * np.cos(heading))
    sim["y"] = np.cumsum(sim["step"] * np.sin(heading))
    sim["id"] = np.repeat(["a", "b"], 603)
    sim["segment"] = sim["id"]
    states = model.viterbi(sim)
    figures = plots.hmm_figures(model, sim, states, ["slow", "fast"])
    assert sorted(figures) == [
        "densities.png",
        "residuals.png",
        "stationary_z.png",
        "tracks.png",
        "transition_z.png",
    ]
    tracks_axes = [ax for ax in figures["tracks.png"].axes if ax.get_visible()]
    assert [ax.get_title() for ax in tracks_axes] == ["a", "b"]
    legend = [t.get_text() for t in tracks_axes[0].get_legend().get_texts()]
    assert legend == ["1 slow", "2 fast"]
    titles = [ax.get_title() for ax in figures["transition_z.png"].axes]
    assert titles == ["1 slow → 1 slow", "1 slow → 2 fast", "2 fast → 1 slow", "2 fast → 2 fast"]
    matplotlib.pyplot.close("all")


def test_residual_figure_has_a_row_per_stream_formulas_included():
    """A three-stream model whose third stream (normal depth) has a formula on its mean:
    residuals.png has one row of (series, QQ, ACF) per stream, named."""
    rng = np.random.default_rng(8)
    n = 400
    table = pd.DataFrame({"c": np.sin(np.arange(n) / 20.0)})
    depth = CovariateEmission(
        Normal(np.array([20.0, 5.0]), np.array([6.0, 2.0])),
        {"mean": design("~ c", table)},
        {"mean": np.array([[20.0, 3.0], [5.0, -2.0]])},
    )
    model = MovementHMM(
        TRUE.initial, TRUE.transition, TRUE.step, TRUE.angle, streams={"depth": depth}
    )
    sim = model.simulate(rng, n, table).join(table)
    heading = np.cumsum(sim["angle"])
    sim = sim.assign(
        x=np.cumsum(sim["step"] * np.cos(heading)),
        y=np.cumsum(sim["step"] * np.sin(heading)),
        id="a",
        segment="a",
    )
    figure = plots.hmm_figures(model, sim, model.viterbi(sim))["residuals.png"]
    assert len(figure.axes) == 9
    labels = [ax.get_ylabel() for ax in figure.axes[::3]]
    assert labels == ["step pseudo-residual", "angle pseudo-residual", "depth pseudo-residual"]
    series = figure.axes[6].lines[0].get_ydata()
    expected = diagnostics.pseudo_residuals(model, sim)["depth_residual"].to_numpy()
    np.testing.assert_array_equal(series, expected)
    matplotlib.pyplot.close("all")


def test_decode_table_is_aligned_to_the_file_rows(tmp_path: Path):
    rng = np.random.default_rng(4)
    sim = TRUE.simulate(rng, 60)
    heading = np.cumsum(sim["angle"])
    table = pd.DataFrame(
        {
            "id": "a",
            "time": pd.date_range("2024-06-01", periods=60, freq="60s", tz="UTC").strftime(
                "%Y-%m-%dT%H:%M:%SZ"
            ),
            "x": np.cumsum(sim["step"] * np.cos(heading)),
            "y": np.cumsum(sim["step"] * np.sin(heading)),
        }
    )
    table.loc[[5, 30], ["x", "y"]] = np.nan
    path = tmp_path / "t.csv"
    table.to_csv(path, index=False)
    prepared = tracks.prepare(io.read_tracks(path, missing_coordinates="drop"))
    out = decode_table(TRUE, prepared, state_names=["slow", "fast"])
    assert list(out.index) == list(range(2, 62))  # file lines, header = line 1
    assert out["state"].dtype == "Int64"
    assert out["state"].isna().tolist() == [i in (5, 30) for i in range(60)]
    np.testing.assert_array_equal(out["state"].dropna(), TRUE.viterbi(prepared) + 1)
    assert out.loc[3, "time"] - out.loc[2, "time"] == 60.0 and np.isnan(out.loc[7, "time"])
    named = out["state_name"].dropna().to_numpy()
    np.testing.assert_array_equal(named, np.where(TRUE.viterbi(prepared) == 0, "slow", "fast"))
    with pytest.raises(ValueError, match="2 distinct"):
        decode_table(TRUE, prepared, state_names=["only"])
