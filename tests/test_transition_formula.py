"""Transition formulas end to end: a factor and cosinor terms fitted and recovered, the
formula kept through the JSON file, ``covariates=`` as the formula of its columns."""

import numpy as np
import pandas as pd
import pytest

from hmmtrack.hmm import Gamma, MovementHMM, MovementHMMEstimator, VonMises, diagnostics
from hmmtrack.hmm.formula import design

FORMULA = "~ C(season) + cos(2*pi*hour/24) + sin(2*pi*hour/24)"


def covariate_table(rng, n):
    return pd.DataFrame(
        {
            "season": np.where(np.arange(n) < n // 2, "dry", "wet"),
            "hour": (np.arange(n) * 0.5) % 24,
        }
    )


@pytest.fixture(scope="module")
def simulated():
    """4,000 rows of a 2-state model whose switching depends on season and time of day."""
    rng = np.random.default_rng(5)
    table = covariate_table(rng, 4000)
    truth = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=None,
        coefficients=np.array([[-2.0, 0.8, 0.6, -0.4], [-1.5, -0.5, -0.3, 0.7]]),
        transition_design=design(FORMULA, table),
        step=Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0])),
        angle=VonMises(np.array([0.0, 0.0]), np.array([0.5, 4.0])),
    )
    data = truth.simulate(rng, len(table), table).join(table)
    estimator = MovementHMMEstimator(2, formula=FORMULA, seed=1).fit(data)
    return truth, data, estimator.model_


def test_factor_and_cosinor_coefficients_recovered_within_two_se(simulated):
    truth, data, model = simulated
    assert model.transition_design.columns == (
        "Intercept",
        "C(season)[T.wet]",
        "cos(2 * pi * hour / 24)",
        "sin(2 * pi * hour / 24)",
    )
    assert model.transition_design.levels == {"C(season)": ["dry", "wet"]}
    intervals = diagnostics.confidence_intervals(model, data)
    beta = intervals[intervals.parameter.str.startswith("beta.")]
    assert len(beta) == 8
    # same rows as the truth's (the fit saw the same table, so the same standardisation)
    expected = truth.coefficients.T.ravel()  # natural_parameters: column-major over transitions
    np.testing.assert_array_less(np.abs(beta.estimate.to_numpy() - expected), 2 * beta.se)
    assert beta.se.max() < 0.3


def test_summary_prints_data_scale_coefficients(simulated):
    _, _, model = simulated
    text = diagnostics.summary(model)
    assert "on the data's scale" in text and "C(season)[T.wet]" in text
    table = diagnostics.data_scale_coefficients(model)
    assert list(table.index) == ["1->2", "2->1"]
    # the data-scale coefficients applied to raw columns give the fitted linear predictor
    grid = pd.DataFrame({"season": ["dry", "wet", "wet"], "hour": [3.0, 9.0, 20.0]})
    raw_columns = np.column_stack(
        [
            np.ones(3),
            grid.season == "wet",
            np.cos(2 * np.pi * grid.hour / 24),
            np.sin(2 * np.pi * grid.hour / 24),
        ]
    )
    standardised = model.transition_design.transform(grid)
    np.testing.assert_allclose(
        table.to_numpy() @ raw_columns.T, model.coefficients @ standardised.T, atol=1e-12
    )


def test_json_round_trip_reproduces_transition_matrices_on_new_data(simulated, tmp_path):
    _, data, model = simulated
    path = tmp_path / "model.json"
    model.save(path)
    loaded = MovementHMM.load(path)
    grid = pd.DataFrame({"season": ["wet", "dry", "wet"], "hour": [0.25, 7.5, 13.0]})
    np.testing.assert_array_equal(loaded.transition_matrix(grid), model.transition_matrix(grid))
    part = data.iloc[100:400].reset_index(drop=True)
    np.testing.assert_array_equal(loaded.state_probabilities(part), model.state_probabilities(part))
    assert loaded.score(data) == model.score(data)
    np.testing.assert_array_equal(
        loaded.coefficients_on_data_scale(), model.coefficients_on_data_scale()
    )


def test_covariates_are_the_formula_of_their_columns():
    rng = np.random.default_rng(2)
    n = 600
    data = pd.DataFrame(
        {"step": rng.gamma(2.0, 1.0, n), "angle": rng.vonmises(0, 1, n), "c": rng.normal(size=n)}
    )
    by_name = MovementHMMEstimator(2, covariates=("c",), seed=3).fit(data).model_
    by_formula = MovementHMMEstimator(2, formula="~ c", seed=3).fit(data).model_
    assert by_name.to_dict() == by_formula.to_dict()
    with pytest.raises(ValueError, match="either"):
        MovementHMMEstimator(2, covariates=("c",), formula="~ c").fit(data)
    with pytest.raises(ValueError, match="intercept"):
        MovementHMMEstimator(2, formula="~ 0 + c").fit(data)


def test_version_1_covariate_files_still_load():
    rng = np.random.default_rng(4)
    table = pd.DataFrame({"c": rng.normal(3.0, 2.0, 50)})
    model = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=None,
        coefficients=np.array([[-2.0, 0.8], [-1.5, -0.5]]),
        transition_design=design("~ c", table),
        step=Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0])),
        angle=VonMises(np.array([0.0, 0.0]), np.array([0.5, 4.0])),
    )
    document = model.to_dict()
    centre, sd = model.transition_design.scaling["c"]
    document["version"] = 1
    document["coefficients"] = {
        "covariates": ["c"],
        "scaling": {"c": {"mean": centre, "sd": sd}},
        "values": document["coefficients"]["values"],
    }
    old = MovementHMM.from_dict(document)
    assert old.transition_design.formula == "~ c"
    np.testing.assert_array_equal(old.transition_matrix(table), model.transition_matrix(table))
