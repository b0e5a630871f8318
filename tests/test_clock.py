"""Tests of receiver clocks, the particles' emission-clock process and schedule summaries."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from hmmtrack.tracking.measurement.clock import (
    EmissionClockModel,
    ReceiverClock,
    local_period_ppm,
    predict_clock_covariance,
    schedule_wander,
    to_common_time,
)


@settings(max_examples=100, deadline=None)
@given(
    offset=st.floats(-100, 100),
    drift=st.floats(-500, 500),
    reference=st.floats(0, 2e9),
    elapsed=st.floats(-1e5, 1e5),
)
def test_receiver_clock_round_trip(offset, drift, reference, elapsed):
    clock = ReceiverClock(offset=offset, drift_ppm=drift, reference_time=reference)
    true_time = reference + elapsed
    assert clock.to_true(clock.to_recorded(true_time)) == pytest.approx(true_time, abs=1e-5)


def test_receiver_clock_drift_accumulates_linearly():
    clock = ReceiverClock(offset=0.25, drift_ppm=20.0, reference_time=1000.0)
    # 20 ppm over one hour is 72 ms
    assert clock.to_recorded(4600.0) - 4600.0 == pytest.approx(0.25 + 0.072, abs=1e-12)
    with pytest.raises(ValueError, match="offset"):
        ReceiverClock(offset=np.nan)


def test_predicted_clock_covariance_matches_simulated_clocks():
    """Oracle: simulate the ping-to-ping recursion of many clocks and compare covariances."""
    model = EmissionClockModel(
        nominal_period=8.0, period_step_sd=2e-4, phase_step_sd=5e-4, rate_step_sd=5e-5
    )
    start = np.array([[1e-6, 2e-7, 0.0], [2e-7, 4e-6, 1e-8], [0.0, 1e-8, 1e-8]])
    rng = np.random.default_rng(1)
    n = 200_000
    clock = rng.multivariate_normal([0.0, 8.0, 0.0], start, size=n)
    for _ in range(6):
        clock[:, 0] += clock[:, 1] + 5e-4 * rng.standard_normal(n)
        clock[:, 1] += clock[:, 2] + 2e-4 * rng.standard_normal(n)
        clock[:, 2] += 5e-5 * rng.standard_normal(n)
    want = np.cov(clock.T)
    got = model.predict_covariance(start, 6)
    np.testing.assert_allclose(np.diag(got), np.diag(want), rtol=0.02)
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    np.testing.assert_allclose(got / scale, want / scale, atol=0.01)  # correlations
    np.testing.assert_array_equal(model.predict_covariance(start, 0), start)
    with pytest.raises(ValueError, match="n_pings"):
        model.predict_covariance(start, -1)


def test_compiled_covariance_prediction_equals_the_model():
    model = EmissionClockModel(8.0, period_step_sd=3e-5, phase_step_sd=1e-5, rate_step_sd=4e-6)
    start = model.initial_covariance(2e-3) + 1e-9
    noise = np.array([1e-5, 3e-5, 4e-6]) ** 2
    for n_pings in (0, 1, 7, 300):
        np.testing.assert_allclose(
            predict_clock_covariance(start, n_pings, noise),
            model.predict_covariance(start, n_pings),
            rtol=1e-12,
        )


def test_without_a_rate_the_period_is_a_plain_random_walk():
    """With rate_step_sd = initial_rate_sd = 0 the (e, P) block is the two-state model."""
    model = EmissionClockModel(8.0, period_step_sd=2e-4, phase_step_sd=5e-4)
    got = model.predict_covariance(model.initial_covariance(1e-3), 5)
    cov = np.diag([1e-6, model.initial_period_sd**2])
    for _ in range(5):
        cov = np.array([[1.0, 1.0], [0.0, 1.0]]) @ cov @ np.array([[1.0, 0.0], [1.0, 1.0]])
        cov += np.diag([5e-4**2, 2e-4**2])
    np.testing.assert_allclose(got[:2, :2], cov, rtol=1e-12)
    assert np.all(got[2] == 0) and np.all(got[:, 2] == 0)


@pytest.mark.parametrize("period", [2.0, 8.0])
def test_temperature_drift_rate_wanders_by_the_stated_rate_over_the_time_scale(period):
    """From a known rate, the walk's sd of the fractional period rate after
    ``time_scale`` seconds equals the stated typical rate (its own derivation)."""
    model = EmissionClockModel.temperature_drift(period, rate_ppm_per_s=1.25, time_scale=800.0)
    n_pings = round(800.0 / period)
    cov = model.predict_covariance(np.zeros((3, 3)), n_pings)
    fractional_rate_sd = np.sqrt(cov[2, 2]) / period**2  # R = P² · (dP/dt) / P
    assert fractional_rate_sd == pytest.approx(1.25e-6, rel=0.01)
    assert model.initial_rate_sd / period**2 == pytest.approx(1.25e-6)


def test_emission_clock_model_refuses_bad_settings():
    with pytest.raises(ValueError, match="nominal_period"):
        EmissionClockModel(nominal_period=0.0)
    with pytest.raises(ValueError, match="initial_period_sd"):
        EmissionClockModel(nominal_period=1.0, initial_period_sd=0.5)
    with pytest.raises(ValueError, match="rate_step_sd"):
        EmissionClockModel(nominal_period=1.0, rate_step_sd=-1e-6)


def test_schedule_wander_matches_least_squares_residuals():
    rng = np.random.default_rng(2)
    k = np.arange(500)
    times = 100.0 + 2.01 * k + np.cumsum(rng.normal(0, 1e-3, k.size))
    fit = stats.linregress(k, times)
    want = np.max(np.abs(times - fit.intercept - fit.slope * k))
    assert schedule_wander(times) == pytest.approx(want, rel=1e-6)
    assert schedule_wander(100.0 + 2.01 * k) < 1e-9


def test_local_period_ppm_of_two_known_blocks():
    periods = np.concatenate([np.full(400, 2.0 * (1 + 100e-6)), np.full(400, 2.0 * (1 - 100e-6))])
    times = np.concatenate([[0.0], np.cumsum(periods)])
    np.testing.assert_allclose(local_period_ppm(times, block=400), [100.0, -100.0], atol=1e-6)
    with pytest.raises(ValueError, match="increasing"):
        local_period_ppm(times[::-1])


def test_to_common_time_maps_each_receiver_and_keeps_the_rest():
    clocks = {"a": ReceiverClock(offset=1.0, drift_ppm=0.0), "b": ReceiverClock(offset=-0.5)}
    detections = pd.DataFrame(
        {"time": [10.0, 10.2, 10.4], "receiver": ["a", "b", "c"], "depth": [1.0, 2.0, 3.0]}
    )
    out = to_common_time(detections, clocks)
    assert out["receiver"].tolist() == ["a", "c", "b"]
    np.testing.assert_allclose(out["time"], [9.0, 10.4, 10.7])
    np.testing.assert_allclose(out["depth"], [1.0, 3.0, 2.0])
    assert detections["time"].tolist() == [10.0, 10.2, 10.4]
