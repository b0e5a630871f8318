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


def test_advance_without_noise_lands_on_the_last_emission():
    model = EmissionClockModel(nominal_period=8.0, period_step_sd=0.0, phase_step_sd=0.0)
    emission = np.array([0.0, 3.0, 7.9, 8.0])
    period = np.array([8.0, 8.0, 2.0, 8.0])
    model.advance(np.random.default_rng(0), emission, period, 100.0)
    # last emission at or before t = 100: 96, 99, 99.9, 96
    np.testing.assert_allclose(emission, [96.0, 99.0, 99.9, 96.0])
    np.testing.assert_allclose(period, [8.0, 8.0, 2.0, 8.0])


def test_period_random_walk_has_the_stated_variance():
    sd = 1e-4
    model = EmissionClockModel(nominal_period=2.0, period_step_sd=sd, phase_step_sd=0.0)
    n = 20_000
    emission = np.zeros(n)
    period = np.full(n, 2.0)
    model.advance(np.random.default_rng(1), emission, period, 50.0)  # 25 pings each
    variance = np.var(period - 2.0)
    # chi-square interval at 1e-6 for the sample variance of 25 * sd^2
    low, high = stats.chi2.ppf([1e-6, 1 - 1e-6], n - 1) / (n - 1)
    assert low * 25 * sd**2 < variance < high * 25 * sd**2
    assert np.all(emission <= 50.0) and np.all(emission + period > 50.0)


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
