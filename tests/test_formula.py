"""Tests of hmmtrack.hmm.formula: design matrices equal hand-built ones; data-scale coefficients."""

import numpy as np
import pandas as pd
import pytest

from hmmtrack.hmm import covariates as cov
from hmmtrack.hmm.formula import design


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    rng = np.random.default_rng(0)
    n = 50
    hour = rng.uniform(0, 24, n)
    return pd.DataFrame(
        {
            "temp": rng.normal(12.0, 3.0, n),
            "depth": rng.gamma(2.0, 20.0, n),
            "season": rng.choice(["autumn", "summer", "winter"], n),
            "hour": hour,
            "cosT": np.cos(2 * np.pi * hour / 24),
            "sinT": np.sin(2 * np.pi * hour / 24),
        }
    )


def standard(x):
    return (x - x.mean()) / x.std(ddof=1)


def test_cosinor_columns(table):
    d = design("~ cosT + sinT", table)
    assert d.columns == ("Intercept", "cosT", "sinT")
    expected = np.column_stack([np.ones(len(table)), standard(table.cosT), standard(table.sinT)])
    np.testing.assert_allclose(d.matrix, expected, rtol=0, atol=1e-12)
    assert d.scaling["cosT"] == pytest.approx((table.cosT.mean(), table.cosT.std(ddof=1)))


def test_factor_gets_treatment_indicators_unscaled(table):
    d = design("~ C(season)", table)
    assert d.columns == ("Intercept", "C(season)[T.summer]", "C(season)[T.winter]")
    expected = np.column_stack(
        [np.ones(len(table)), table.season == "summer", table.season == "winter"]
    ).astype(float)
    np.testing.assert_array_equal(d.matrix, expected)
    assert d.scaling == {}


def test_interaction_columns_are_standardised_products(table):
    d = design("~ temp * depth", table)
    assert d.columns == ("Intercept", "temp", "depth", "temp:depth")
    product = table.temp * table.depth
    expected = np.column_stack(
        [np.ones(len(table)), standard(table.temp), standard(table.depth), standard(product)]
    )
    np.testing.assert_allclose(d.matrix, expected, rtol=0, atol=1e-12)


def test_expression_of_a_column(table):
    d = design("~ cos(2*pi*hour/24)", table)
    assert d.columns == ("Intercept", "cos(2 * pi * hour / 24)")
    np.testing.assert_allclose(d.matrix[:, 1], standard(np.cos(2 * np.pi * table.hour / 24)))
    raw = design("cos(2*pi*hour/24)", table, standardise=False)
    np.testing.assert_allclose(raw.matrix[:, 1], np.cos(2 * np.pi * table.hour / 24))


def test_single_covariate_equals_the_fitters_design(table):
    d = design("~ temp", table)
    scaling = cov.covariate_scaling(table, ["temp"])
    np.testing.assert_array_equal(d.matrix, cov.design_matrix(table, scaling))
    assert d.scaling == scaling


def test_data_scale_coefficients_give_the_same_linear_predictor(table):
    d = design("~ temp * depth + C(season)", table)
    raw = design("~ temp * depth + C(season)", table, standardise=False)
    coefficients = np.random.default_rng(1).normal(size=(2, len(d.columns)))
    eta = coefficients @ d.matrix.T
    np.testing.assert_allclose(d.to_data_scale(coefficients) @ raw.matrix.T, eta, atol=1e-10)
    no_intercept = design("~ 0 + temp", table)
    assert no_intercept.scaling["temp"][0] == 0.0
    np.testing.assert_allclose(no_intercept.matrix[:, 0], table.temp / table.temp.std(ddof=1))


def test_transform_reuses_levels_and_scaling(table):
    d = design("~ temp + C(season)", table)
    new = table.iloc[[3, 7]]
    np.testing.assert_allclose(d.transform(new), d.matrix[[3, 7]])
    grid = pd.DataFrame({"temp": [10.0, 14.0], "season": ["winter", "autumn"]})
    mean, sd = d.scaling["temp"]
    np.testing.assert_allclose(
        d.transform(grid), [[1, (10 - mean) / sd, 0, 1], [1, (14 - mean) / sd, 0, 0]]
    )


def test_errors(table):
    with pytest.raises(ValueError, match="one-sided"):
        design("temp ~ depth", table)
    with pytest.raises(ValueError, match="constant"):
        design("~ flat", table.assign(flat=1.0))


def test_missing_values_stay_in_their_rows(table):
    gappy = table.assign(temp=table.temp.where(table.index % 5 != 0))
    d = design("~ temp", gappy)
    assert d.matrix.shape == (len(table), 2)
    assert np.isnan(d.matrix[::5, 1]).all() and np.isfinite(d.matrix[1::5, 1]).all()
    observed = gappy.temp.dropna()
    assert d.scaling["temp"] == pytest.approx((observed.mean(), observed.std(ddof=1)))
