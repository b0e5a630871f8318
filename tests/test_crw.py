"""Tests of hmmtrack.hmm.crw: exact likelihood oracle, recovery, held-back fixes, draws."""

from fractions import Fraction
from math import factorial

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from hmmtrack import tracks
from hmmtrack.hmm import crw
from hmmtrack.hmm.crw import CorrelatedRandomWalk, fit_crw

TRUE = CorrelatedRandomWalk(sigma=0.05, beta=1 / 600, error_sd=10.0)  # speed sd 0.87 m/s


def brute_force_log_likelihood(time, xy, sigma, beta, error_sd):
    """Density of the fixes after the first given the first, from the whole-track covariance.

    The velocity is stationary, so the position has stationary increments with
    ``V(u) = Var(mu(t + u) - mu(t)) = sigma^2 / beta^3 (beta u - 1 + exp(-beta u))`` and
    ``Cov(mu_i - mu_0, mu_j - mu_0) = (V(t_i) + V(t_j) - V(|t_i - t_j|)) / 2``; the fix
    differences ``y_i - y_0`` add the errors ``eps_i - eps_0``. No Kalman filter involved.
    """
    keep = ~np.isnan(xy).any(axis=1)
    time, xy = time[keep], xy[keep]
    t = time[1:] - time[0]

    def v(u):
        return sigma**2 / beta**3 * (beta * u + np.expm1(-beta * u))

    cov = 0.5 * (v(t)[:, None] + v(t)[None, :] - v(np.abs(t[:, None] - t[None, :])))
    cov += error_sd**2 * (1.0 + np.eye(t.size))
    d = xy[1:] - xy[0]
    normal = stats.multivariate_normal(np.zeros(t.size), cov)
    return normal.logpdf(d[:, 0]) + normal.logpdf(d[:, 1])


@pytest.mark.parametrize(
    ("sigma", "beta", "error_sd"),
    [(0.3, 0.01, 5.0), (0.3, 0.01, 0.0), (0.05, 1 / 600, 10.0), (2.0, 1.0, 1.0)],
)
def test_kalman_log_likelihood_equals_the_whole_track_normal_density(sigma, beta, error_sd):
    rng = np.random.default_rng(1)
    time = np.cumsum(rng.exponential(60.0, 7))
    xy = rng.normal(0.0, 100.0, (7, 2))
    xy[3] = np.nan  # a missing fix
    model = CorrelatedRandomWalk(sigma, beta, error_sd)
    expected = brute_force_log_likelihood(time, xy, sigma, beta, error_sd)
    assert model.log_likelihood_of(time, xy) == pytest.approx(expected, rel=1e-10)


def crw_series(u, terms=80):
    """``u - 2 (1 - e^-u) + (1 - e^-2u) / 2`` by its series in exact fractions."""
    x, total = Fraction(u), Fraction(0)
    for k in range(3, terms):
        total += (-1) ** k * (2 - 2 ** (k - 1)) * x**k / factorial(k)
    return total


def test_transition_noise_is_the_integrated_ornstein_uhlenbeck_covariance():
    # position variance over dt from rest: sigma^2/beta^3 (u - 2(1-e^-u) + (1-e^-2u)/2)
    model = CorrelatedRandomWalk(0.2, 0.5)
    dt = np.array([1e-4, 0.1, 0.39, 0.41, 2.0, 8.0])  # both sides of the series switch
    matrix, covariance = model.transition(dt)
    u = model.beta * dt
    exact = [float(crw_series(x)) for x in u]
    np.testing.assert_allclose(covariance[:, 0, 0] * model.beta**3 / model.sigma**2, exact, 1e-12)
    np.testing.assert_allclose(matrix[:, 1, 1], np.exp(-u))
    np.testing.assert_allclose(covariance[:, 1, 1], model.velocity_variance * (1 - np.exp(-2 * u)))


@pytest.fixture(scope="module")
def irregular():
    """4,000 irregular fixes (exponential gaps, mean 300 s) with 10 m errors; every tenth
    fix held back, the CRW fitted to the other 3,600."""
    rng = np.random.default_rng(5)
    time = np.cumsum(rng.exponential(300.0, 4000))
    position = TRUE.simulate(rng, time)
    fixes = position + rng.normal(0.0, TRUE.error_sd, position.shape)
    held = np.zeros(time.size, dtype=bool)
    held[5::10] = True
    model = fit_crw(time[~held], fixes[~held])
    return time, position, fixes, held, model


def test_parameters_are_recovered_from_a_long_irregular_track(irregular):
    # measured: sigma +1.5 %, beta -1.3 %, error_sd +1.0 % (3,600 fixes)
    *_, model = irregular
    assert model.sigma == pytest.approx(TRUE.sigma, rel=0.05)
    assert model.beta == pytest.approx(TRUE.beta, rel=0.10)
    assert model.error_sd == pytest.approx(TRUE.error_sd, rel=0.10)
    assert model.n_obs == 3600 and np.isfinite(model.log_likelihood)


def test_fit_is_a_maximum(irregular):
    time, _, fixes, held, model = irregular
    best = model.log_likelihood
    assert model.log_likelihood_of(time[~held], fixes[~held]) == pytest.approx(best, abs=1e-6)
    for name in ("sigma", "beta", "error_sd"):
        for factor in (0.98, 1.02):
            moved = CorrelatedRandomWalk(**{**model.to_dict(), name: getattr(model, name) * factor})
            assert moved.log_likelihood_of(time[~held], fixes[~held]) < best


def test_held_back_fixes_fall_inside_their_95_percent_intervals(irregular):
    # measured: 94.4 % of the 800 held-back coordinates (x and y of 400 fixes) inside the
    # intervals of a new fix (position variance + error_sd^2); 94.5 % of the true
    # coordinates inside the position intervals
    time, position, fixes, held, model = irregular
    prediction = model.predict(time[~held], fixes[~held], time[held])
    z = (fixes[held] - prediction.mean) / np.sqrt(prediction.variance + model.error_sd**2)
    coverage = np.mean(np.abs(z) < stats.norm.ppf(0.975))
    assert 0.90 <= coverage <= 0.98
    z_true = (position[held] - prediction.mean) / np.sqrt(prediction.variance)
    assert 0.90 <= np.mean(np.abs(z_true) < stats.norm.ppf(0.975)) <= 0.98


def test_draws_have_the_smoothers_mean_and_variance():
    rng = np.random.default_rng(7)
    time = np.cumsum(rng.exponential(300.0, 15))
    fixes = TRUE.simulate(rng, time) + rng.normal(0.0, TRUE.error_sd, (15, 2))
    fixes[4] = np.nan
    at = np.array([time[0], time[0] + 10.0, time[4], 0.5 * (time[7] + time[8]), time[-1]])
    prediction = TRUE.predict(time, fixes, at)
    n = 4000
    draws = TRUE.sample_paths(np.random.default_rng(3), time, fixes, at, n)
    assert draws.shape == (n, 5, 2)
    z = (draws.mean(axis=0) - prediction.mean) / np.sqrt(prediction.variance / n)
    assert np.all(np.abs(z) < 4)
    ratio = draws.var(axis=0) / prediction.variance
    assert np.all(np.abs(ratio - 1) < 4 * np.sqrt(2 / n))
    again = TRUE.sample_paths(np.random.default_rng(3), time, fixes, at, 2)
    np.testing.assert_array_equal(again, draws[:2])


def test_exact_fixes_are_reproduced_with_zero_variance():
    rng = np.random.default_rng(2)
    time = np.arange(20) * 60.0
    fixes = TRUE.simulate(rng, time)
    exact = CorrelatedRandomWalk(TRUE.sigma, TRUE.beta, error_sd=0.0)
    prediction = exact.predict(time, fixes, time)
    np.testing.assert_allclose(prediction.mean, fixes, atol=1e-6)
    np.testing.assert_allclose(prediction.variance, 0.0, atol=1e-6)
    between = exact.predict(time, fixes, time[:-1] + 30.0)
    assert np.all(between.variance > 1.0)


def test_first_fix_must_be_observed_and_times_increase():
    time = np.arange(5) * 60.0
    xy = np.zeros((5, 2))
    xy[0] = np.nan
    with pytest.raises(ValueError, match="first fix"):
        TRUE.log_likelihood_of(time, xy)
    with pytest.raises(ValueError, match="strictly increasing"):
        TRUE.log_likelihood_of(time[::-1], np.zeros((5, 2)))
    with pytest.raises(ValueError, match="sigma > 0"):
        CorrelatedRandomWalk(sigma=0.0, beta=1.0)


@pytest.fixture(scope="module")
def table():
    """Two animals, 300 irregular fixes each, one missing fix, a covariate column."""
    rng = np.random.default_rng(11)
    parts = []
    for name in ("a", "b"):
        time = 1e9 + np.cumsum(rng.uniform(100.0, 500.0, 300))
        xy = TRUE.simulate(rng, time) + rng.normal(0.0, TRUE.error_sd, (300, 2))
        parts.append(
            pd.DataFrame({"id": name, "time": time, "x": xy[:, 0], "y": xy[:, 1], "temp": 1.0})
        )
    out = pd.concat(parts, ignore_index=True)
    out.loc[7, ["x", "y"]] = np.nan
    return out


def test_regularise_predicts_on_the_linear_grid(table):
    models = crw.fit_tracks(table, error_sd=TRUE.error_sd)
    grid = crw.regularise(table, 300.0, models=models)
    linear = tracks.regularise(table, 300.0)
    pd.testing.assert_series_equal(grid["time"], linear["time"])
    pd.testing.assert_series_equal(grid["temp"], linear["temp"])
    assert set(grid.attrs["crw"]) == {"a", "b"} and grid.attrs["crw"]["a"]["error_sd"] == 10.0
    assert np.isfinite(grid[["x", "y", "sd_x", "sd_y"]].to_numpy()).all()
    # the prediction follows the fixes: within a few sd of the linear interpolation
    gap = np.abs(grid["x"] - linear["x"]) / np.hypot(grid["sd_x"], TRUE.error_sd)
    assert np.nanmedian(gap) < 1.0
    draws = crw.impute(table, 300.0, 3, np.random.default_rng(0), models=models)
    assert len(draws) == 3 and all(len(d) == len(grid) for d in draws)
    assert not np.allclose(draws[0]["x"], draws[1]["x"])
    spread = np.abs(np.mean([d["x"] for d in draws], axis=0) - grid["x"]) / grid["sd_x"]
    assert np.median(spread) < 2.0
