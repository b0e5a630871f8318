"""Tests of hmmtrack.analysis.metrics: hand-computed values, eigenvalue oracle, mean ≤ RMS."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hmmtrack.analysis import metrics
from hmmtrack.tracking.particles import sqrt_largest_eigenvalue


def estimates_table(times, x, y, spread):
    return pd.DataFrame({"time": times, "x": x, "y": y, "sqrt_lambda1": spread})


def test_position_error_interpolates_the_truth():
    truth = pd.DataFrame({"time": [0.0, 10.0], "x": [0.0, 100.0], "y": [0.0, 0.0]})
    estimates = estimates_table([0.0, 2.5, 10.0], [3.0, 25.0, 100.0], [4.0, 6.0, -1.0], 1.0)
    # truth at 2.5 s is (25, 0)
    np.testing.assert_allclose(metrics.position_error(estimates, truth), [5.0, 6.0, 1.0])


def test_single_row_truth_is_a_stationary_tag():
    truth = pd.DataFrame({"time": [123.0], "x": [10.0], "y": [20.0]})
    estimates = estimates_table([0.0, 500.0], [13.0, 10.0], [24.0, 20.0], 1.0)
    np.testing.assert_allclose(metrics.position_error(estimates, truth), [5.0, 0.0])


def test_estimates_outside_the_truth_span_are_an_error():
    truth = pd.DataFrame({"time": [0.0, 10.0], "x": [0.0, 1.0], "y": [0.0, 1.0]})
    with pytest.raises(ValueError, match="outside the truth's span"):
        metrics.position_error(estimates_table([5.0, 11.0], [0, 0], [0, 0], 1.0), truth)
    with pytest.raises(ValueError, match=r"non-finite 'x' in row\(s\) \[1\]"):
        metrics.position_error(estimates_table([5.0, 6.0], [0, np.nan], [0, 0], 1.0), truth)


def test_time_to_convergence_hand_values():
    times = np.array([100.0, 101.0, 102.0, 103.0, 104.0])
    conv = metrics.time_to_convergence(times, [50.0, 12.0, 9.9, 30.0, 5.0])
    assert conv == metrics.Convergence(time_to_convergence=2.0, converged=True, index=2)
    # at the threshold is not below it
    assert metrics.time_to_convergence(times, [10.0] * 5).converged is False


def test_never_converged_is_zero_as_in_the_paper_but_flagged():
    conv = metrics.time_to_convergence([0.0, 1.0, 2.0], [20.0, 15.0, 11.0])
    assert conv == metrics.Convergence(time_to_convergence=0.0, converged=False, index=0)
    # converging at the first estimate also gives 0 s, but is told apart
    first = metrics.time_to_convergence([0.0, 1.0], [3.0, 3.0])
    assert first.time_to_convergence == 0.0 and first.converged


def test_errors_after_convergence_hand_values():
    conv = metrics.Convergence(time_to_convergence=2.0, converged=True, index=2)
    errors = [100.0, 50.0, 3.0, 4.0, 5.0, 0.0]
    assert metrics.mean_error_after_convergence(errors, conv) == pytest.approx(3.0)
    assert metrics.rmse_after_convergence(errors, conv) == pytest.approx(np.sqrt(12.5))


def test_tracking_metrics_of_a_run():
    times = np.arange(6.0)
    truth = pd.DataFrame({"time": [0.0], "x": [0.0], "y": [0.0]})
    estimates = estimates_table(
        times, [80, 40, 3, 0, 0, 6], [60, 30, 4, 0, 8, 8], [90, 40, 9, 5, 5, 5]
    )
    result = metrics.tracking_metrics(estimates, truth)
    assert result.time_to_convergence == 2.0 and result.converged
    assert result.n_estimates_after_convergence == 4
    assert result.mean_error_after_convergence == pytest.approx((5 + 0 + 8 + 10) / 4)
    assert result.rmse_after_convergence == pytest.approx(np.sqrt((25 + 0 + 64 + 100) / 4))


@settings(max_examples=60, deadline=None)
@given(
    arrays(float, st.integers(1, 50), elements=st.just(0.0) | st.floats(1e-6, 1e4)),
    st.integers(0, 49),
)
def test_mean_error_never_exceeds_rmse(errors, index):
    conv = metrics.Convergence(0.0, True, min(index, errors.size - 1))
    mean = metrics.mean_error_after_convergence(errors, conv)
    rms = metrics.rmse_after_convergence(errors, conv)
    assert mean <= rms * (1 + 1e-12)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(0.0, 1e6),
    st.floats(0.0, 1e6),
    st.floats(-1.0, 1.0),
)
def test_sqrt_largest_eigenvalue_matches_eigvalsh(var_x, var_y, correlation):
    cov = correlation * np.sqrt(var_x * var_y)
    expected = np.sqrt(np.linalg.eigvalsh([[var_x, cov], [cov, var_y]])[-1].clip(0))
    got = sqrt_largest_eigenvalue(var_x, var_y, cov)
    assert got == pytest.approx(expected, rel=1e-7, abs=1e-6)


# --------------------------------------------------------------------------- filter honesty


def covariance_table(times, x, y, var_x, var_y, cov_xy):
    return pd.DataFrame(
        {"time": times, "x": x, "y": y, "var_x": var_x, "var_y": var_y, "cov_xy": cov_xy}
    )


def test_ellipse_scale_is_the_chi2_quantile():
    from scipy.stats import chi2

    for level in (0.5, 0.9, 0.95, 0.99):
        assert metrics.ellipse_scale(level) == pytest.approx(chi2.ppf(level, 2), rel=1e-12)
    with pytest.raises(ValueError, match=r"level must lie in \(0, 1\)"):
        metrics.ellipse_scale(1.0)


def test_nees_of_a_rotated_covariance_closed_form():
    """P = R diag(a², b²) Rᵀ and e = R (a u, b v) give NEES = u² + v²."""
    a, b, angle = 6.0, 1.5, 0.7
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    cov = rotation @ np.diag([a**2, b**2]) @ rotation.T
    uv = np.array([[1.0, 0.0], [0.0, 2.0], [1.5, -1.0]])
    errors = (rotation @ (uv * [a, b]).T).T
    truth = pd.DataFrame({"time": [0.0, 10.0], "x": [0.0, 10.0], "y": [5.0, 5.0]})
    times = np.array([0.0, 5.0, 10.0])
    estimates = covariance_table(
        times, times + errors[:, 0], 5.0 + errors[:, 1], cov[0, 0], cov[1, 1], cov[0, 1]
    )
    np.testing.assert_allclose(
        metrics.normalised_estimation_error(estimates, truth), (uv**2).sum(axis=1)
    )


def test_nees_refuses_a_covariance_that_is_not_positive_definite():
    truth = pd.DataFrame({"time": [0.0], "x": [0.0], "y": [0.0]})
    estimates = covariance_table([0.0, 1.0, 2.0], 1.0, 1.0, [1.0, 1.0, 0.0], 1.0, [0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match=r"not positive definite in row\(s\) \[1, 2\]"):
        metrics.normalised_estimation_error(estimates, truth)


def test_ellipse_coverage_hand_values_and_a_consistent_gaussian():
    assert metrics.ellipse_coverage([0.1, 5.9, 6.0, 100.0]) == 0.5
    # errors drawn from the filter's own covariance: NEES ~ chi2(2), coverage ~ 95 %
    rng = np.random.default_rng(11)
    n = 4000
    cov = np.array([[30.0, 12.0], [12.0, 9.0]])
    errors = rng.multivariate_normal([0.0, 0.0], cov, size=n)
    estimates = covariance_table(
        np.arange(n, dtype=float), errors[:, 0], errors[:, 1], cov[0, 0], cov[1, 1], cov[0, 1]
    )
    truth = pd.DataFrame({"time": [np.nan], "x": [0.0], "y": [0.0]})
    nees = metrics.normalised_estimation_error(estimates, truth)
    assert nees.mean() == pytest.approx(2.0, abs=4 * 2.0 / np.sqrt(n))  # chi2(2): sd 2
    binomial_sd = np.sqrt(0.95 * 0.05 / n)
    assert metrics.ellipse_coverage(nees) == pytest.approx(0.95, abs=4 * binomial_sd)
    # an overconfident filter (covariance 4 times too small) covers far less
    shrunk = estimates.assign(var_x=cov[0, 0] / 4, var_y=cov[1, 1] / 4, cov_xy=cov[0, 1] / 4)
    low = metrics.ellipse_coverage(metrics.normalised_estimation_error(shrunk, truth))
    assert low == pytest.approx(1 - np.exp(-5.991 / 8), abs=4 * binomial_sd)  # P(chi2 < 1.5)


def test_convergence_is_judged_by_the_converged_column_when_present():
    truth = pd.DataFrame({"time": [0.0, 10.0], "x": [0.0, 0.0], "y": [0.0, 0.0]})
    estimates = estimates_table([0.0, 1.0, 2.0, 3.0], [90.0, 60.0, 3.0, 1.0], 0.0, 5.0)
    by_spread = metrics.tracking_metrics(estimates, truth)
    assert by_spread.time_to_convergence == 0.0 and by_spread.converged
    assert by_spread.mean_error_after_convergence == pytest.approx(154 / 4)
    # two modes until 2 s: not converged however narrow the cloud
    estimates["converged"] = [False, False, True, True]
    by_modes = metrics.tracking_metrics(estimates, truth)
    assert by_modes.time_to_convergence == 2.0
    assert by_modes.mean_error_after_convergence == pytest.approx(2.0)


def test_uncertainty_metrics_calibration_and_false_convergence():
    rng = np.random.default_rng(3)
    n = 4000
    times = np.arange(n, dtype=float)
    truth = pd.DataFrame({"time": times, "x": 0.0, "y": 0.0})
    # a consistent filter: errors drawn from the stated covariance diag(4, 9) m²
    estimates = estimates_table(times, rng.normal(0, 2, n), rng.normal(0, 3, n), 3.0)
    estimates["var_x"], estimates["var_y"], estimates["cov_xy"] = 4.0, 9.0, 0.0
    estimates["converged"] = times >= 1000
    estimates.loc[:999, "x"] += 200.0  # wrong and not converged: neither counted
    honest = metrics.uncertainty_metrics(estimates, truth)
    assert honest.seconds_after_convergence == 3000
    assert honest.calibration == pytest.approx(0.95, abs=0.015)
    assert honest.false_converged == 0.0
    # an overconfident run: 60 m off for 400 converged seconds
    estimates.loc[2000:2399, "x"] += 60.0
    wrong = metrics.uncertainty_metrics(estimates, truth)
    assert wrong.false_converged == pytest.approx(400 / n)
    assert wrong.calibration == pytest.approx(honest.calibration - 400 / 3000, abs=0.01)
    # never converged: no calibration, by √λ₁ without the column
    never = metrics.uncertainty_metrics(
        estimates.drop(columns="converged").assign(sqrt_lambda1=20.0), truth
    )
    assert np.isnan(never.calibration) and never.seconds_after_convergence == 0
    assert np.isnan(never.region_scale)
    # the consistent filter needs no scaling; regions twice as wide need halving
    assert honest.region_scale == pytest.approx(1.0, abs=0.05)
    wide = estimates.assign(var_x=16.0, var_y=36.0)
    wide["x"] -= np.where((times >= 2000) & (times < 2400), 60.0, 0.0)
    assert metrics.uncertainty_metrics(wide, truth).region_scale == pytest.approx(0.5, abs=0.03)


def test_region_scale_hand_values_and_chi2_oracle():
    # the 95 % quantile of twenty values is the 19th smallest (inverted CDF)
    nees = np.arange(1.0, 21.0)
    assert metrics.region_scale(nees) == pytest.approx(np.sqrt(19.0 / 5.991464547107979))
    assert metrics.region_scale([5.991464547107979] * 3) == pytest.approx(1.0)
    # two degenerate covariances in twenty: more than 5 %, no scale helps
    assert metrics.region_scale([1.0] * 18 + [np.inf] * 2) == np.inf
    # NEES of errors drawn from covariance P against a stated covariance 9 P: chi2(2) / 9
    rng = np.random.default_rng(5)
    chi2 = (rng.standard_normal((20000, 2)) ** 2).sum(axis=1)
    assert metrics.region_scale(chi2) == pytest.approx(1.0, abs=0.03)
    assert metrics.region_scale(chi2 / 9.0) == pytest.approx(1 / 3, abs=0.01)
    assert metrics.region_scale(chi2, level=0.5) == pytest.approx(1.0, abs=0.03)
    with pytest.raises(ValueError, match="non-empty 1-D array without NaN"):
        metrics.region_scale([1.0, np.nan])


def test_a_collapsed_cloud_holds_no_truth():
    truth = pd.DataFrame({"time": [0.0, 3.0], "x": [0.0, 0.0], "y": [0.0, 0.0]})
    estimates = estimates_table([0.0, 1.0, 2.0, 3.0], [1.0, 1.0, 1.0, 1.0], 0.0, 1.0)
    estimates["var_x"], estimates["var_y"], estimates["cov_xy"] = [1.0, 0.0, 1.0, 1.0], 1.0, 0.0
    with pytest.raises(ValueError, match="not positive definite"):
        metrics.normalised_estimation_error(estimates, truth)
    nees = metrics.normalised_estimation_error(estimates, truth, degenerate="inf")
    np.testing.assert_array_equal(nees, [1.0, np.inf, 1.0, 1.0])
    assert metrics.uncertainty_metrics(estimates, truth).calibration == 0.75
