"""Tests of hmmtrack.hmm.formula: design matrices equal hand-built ones; data-scale coefficients."""

import json

import numpy as np
import pandas as pd
import pytest

from hmmtrack.hmm.formula import Design, design, of_columns


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
    np.testing.assert_allclose(d.transform(table), expected, rtol=0, atol=1e-12)
    assert d.scaling["cosT"] == pytest.approx((table.cosT.mean(), table.cosT.std(ddof=1)))


def test_factor_gets_treatment_indicators_unscaled(table):
    d = design("~ C(season)", table)
    assert d.columns == ("Intercept", "C(season)[T.summer]", "C(season)[T.winter]")
    expected = np.column_stack(
        [np.ones(len(table)), table.season == "summer", table.season == "winter"]
    ).astype(float)
    np.testing.assert_array_equal(d.transform(table), expected)
    assert d.scaling == {}


def test_interaction_columns_are_standardised_products(table):
    d = design("~ temp * depth", table)
    assert d.columns == ("Intercept", "temp", "depth", "temp:depth")
    product = table.temp * table.depth
    expected = np.column_stack(
        [np.ones(len(table)), standard(table.temp), standard(table.depth), standard(product)]
    )
    np.testing.assert_allclose(d.transform(table), expected, rtol=0, atol=1e-12)


def test_expression_of_a_column(table):
    d = design("~ cos(2*pi*hour/24)", table)
    assert d.columns == ("Intercept", "cos(2 * pi * hour / 24)")
    np.testing.assert_allclose(
        d.transform(table)[:, 1], standard(np.cos(2 * np.pi * table.hour / 24))
    )
    raw = design("cos(2*pi*hour/24)", table, standardise=False)
    np.testing.assert_allclose(raw.transform(table)[:, 1], np.cos(2 * np.pi * table.hour / 24))


def test_single_covariate_is_intercept_and_standardised_column(table):
    d = design("~ temp", table)
    mean, sd = float(np.mean(table.temp)), float(np.std(table.temp, ddof=1))
    expected = np.column_stack([np.ones(len(table)), (table.temp - mean) / sd])
    np.testing.assert_array_equal(d.transform(table), expected)
    assert d.scaling == {"temp": (mean, sd)}


def test_of_columns_and_dict_round_trip(table):
    assert of_columns(["temp", "dist-water"]) == "~ temp + `dist-water`"
    d = design("~ temp * cosT + C(season)", table)
    back = Design.from_dict(json.loads(json.dumps(d.to_dict())))
    assert (back.formula, back.columns, back.scaling) == (d.formula, d.columns, d.scaling)
    assert back.levels == {"C(season)": ["autumn", "summer", "winter"]}
    grid = table.iloc[[5, 2]].assign(season=["winter", "winter"])
    np.testing.assert_array_equal(back.transform(grid), d.transform(grid))
    with pytest.raises(ValueError, match="formula '~ temp'"):
        design("~ temp", table).transform(table.assign(temp=table.season))
    renamed = Design.from_dict({"formula": "~ temp", "columns": ["Intercept", "t"], "scaling": {}})
    with pytest.raises(ValueError, match="expected"):
        renamed.transform(table)
    with pytest.raises(ValueError, match="formula"):
        d.transform(table.drop(columns="temp"))


def test_data_scale_coefficients_give_the_same_linear_predictor(table):
    d = design("~ temp * depth + C(season)", table)
    raw = design("~ temp * depth + C(season)", table, standardise=False)
    coefficients = np.random.default_rng(1).normal(size=(2, len(d.columns)))
    eta = coefficients @ d.transform(table).T
    np.testing.assert_allclose(
        d.to_data_scale(coefficients) @ raw.transform(table).T, eta, atol=1e-10
    )
    no_intercept = design("~ 0 + temp", table)
    assert no_intercept.scaling["temp"][0] == 0.0
    np.testing.assert_allclose(
        no_intercept.transform(table)[:, 0], table.temp / table.temp.std(ddof=1)
    )


def test_transform_reuses_levels_and_scaling(table):
    d = design("~ temp + C(season)", table)
    new = table.iloc[[3, 7]]
    np.testing.assert_allclose(d.transform(new), d.transform(table)[[3, 7]])
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
    matrix = d.transform(gappy)
    assert matrix.shape == (len(table), 2)
    assert np.isnan(matrix[::5, 1]).all() and np.isfinite(matrix[1::5, 1]).all()
    observed = gappy.temp.dropna()
    assert d.scaling["temp"] == pytest.approx((observed.mean(), observed.std(ddof=1)))
