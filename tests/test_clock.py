"""Tests of receiver clocks, the particles' emission-clock process and schedule summaries."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from hmmtrack.clock import (
    EmissionClockModel,
    ReceiverClock,
    local_period_ppm,
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
    model = EmissionClockModel(nominal_period=8.0, period_step_sd=2e-4, phase_step_sd=5e-4)
    start = np.array([[1e-6, 2e-7], [2e-7, 4e-6]])
    rng = np.random.default_rng(1)
    n = 200_000
    clock = rng.multivariate_normal([0.0, 8.0], start, size=n)
    for _ in range(6):
        clock[:, 0] += clock[:, 1] + 5e-4 * rng.standard_normal(n)
        clock[:, 1] += 2e-4 * rng.standard_normal(n)
    want = np.cov(clock.T)
    got = model.predict_covariance(start, 6)
    np.testing.assert_allclose(got, want, rtol=0.02)
    np.testing.assert_array_equal(model.predict_covariance(start, 0), start)
    with pytest.raises(ValueError, match="n_pings"):
        model.predict_covariance(start, -1)


def test_emission_clock_model_refuses_bad_settings():
    with pytest.raises(ValueError, match="nominal_period"):
        EmissionClockModel(nominal_period=0.0)
    with pytest.raises(ValueError, match="initial_period_sd"):
        EmissionClockModel(nominal_period=1.0, initial_period_sd=0.5)


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
