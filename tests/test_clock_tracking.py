"""Tests of the clock-aware particle filter (arrival times, unknown start, smoothing)."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from hmmtrack.arrival import ArrivalLikelihood, ArrivalTimeMeasurement
from hmmtrack.clock import EmissionClockModel
from hmmtrack.clock_scenarios import moored_array
from hmmtrack.clock_tracking import (
    ClockAwareFilter,
    ambiguity,
    arrival_observations,
    track_arrival_time,
)
from hmmtrack.metrics import position_error
from hmmtrack.motion import BaselineMotion, VelocityMotion
from hmmtrack.receivers import ReceiverTracks

C = 1460.0


def fixed_tag_observations(period=8.003, first=100.37, n_pings=60, jump=None):
    """A tag fixed at (100, 200) heard by three moored receivers (some pings missed).

    Two fixed receivers cannot place a fixed tag of unknown clock: only the difference of
    its ranges is known (a hyperbola); a third makes the position and clock observable.
    """
    pings = first + period * np.arange(n_pings)
    if jump is not None:
        pings[jump:] += 0.5  # the tag's clock jumps by half a second
    receivers = {"r0": (0.0, 0.0), "r1": (300.0, 0.0), "r2": (0.0, 400.0)}
    rows = []
    for k, emission in enumerate(pings):
        for j, (name, (rx, ry)) in enumerate(receivers.items()):
            if (k + j) % 3:
                rows.append((emission + np.hypot(100 - rx, 200 - ry) / C, name, rx, ry))
    obs = pd.DataFrame(rows, columns=["time", "receiver", "receiver_x", "receiver_y"])
    return obs.sort_values("time").reset_index(drop=True), pings


def clock_filter(seed=0, n=500, **kwargs):
    return ClockAwareFilter(
        BaselineMotion(0.01),
        ArrivalTimeMeasurement(ArrivalLikelihood(sigma=1e-3), sound_speed=C),
        EmissionClockModel(8.0, period_step_sd=1e-5, phase_step_sd=1e-5, initial_period_sd=8e-3),
        n,
        (0.0, 300.0, 0.0, 400.0),
        rng=seed,
        **kwargs,
    )


def test_clock_and_position_are_recovered_without_initial_range():
    obs, pings = fixed_tag_observations()
    result = clock_filter().run(obs, 100.0, 600.0)
    last = result.estimates.iloc[-1]
    assert np.hypot(last.x - 100.0, last.y - 200.0) < 3.0
    clock = result.clock.iloc[-1]
    assert clock.period == pytest.approx(8.003, abs=2e-5)
    k = np.searchsorted(pings, clock.time + 0.5) - 1
    assert clock.emission_time == pytest.approx(pings[k], abs=1e-3)
    assert result.events.empty


def test_same_seed_same_answer():
    obs, _ = fixed_tag_observations(n_pings=20)
    a = clock_filter(seed=3).run(obs, 100.0, 260.0)
    b = clock_filter(seed=3).run(obs, 100.0, 260.0)
    pd.testing.assert_frame_equal(a.estimates, b.estimates)
    pd.testing.assert_frame_equal(a.clock, b.clock)


def test_a_clock_jump_is_reacquired_and_recorded():
    obs, _ = fixed_tag_observations(jump=30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = clock_filter().run(obs, 100.0, 600.0)
    assert (result.events["kind"] == "clock_reacquired").sum() >= 1
    last = result.estimates.iloc[-1]
    assert np.hypot(last.x - 100.0, last.y - 200.0) < 5.0


def test_two_fixed_receivers_leave_the_fixed_tag_uncertain_and_say_so():
    obs, _ = fixed_tag_observations()
    obs = obs[obs["receiver"] != "r2"]
    result = clock_filter().run(obs, 100.0, 600.0)
    # the hyperbola of range differences is all the data pin down: a wide cloud, not a point
    assert result.estimates["sqrt_lambda1"].iloc[-1] > 20.0


def test_smoothed_track_uses_the_filter_steps():
    obs, _ = fixed_tag_observations(n_pings=20)
    result = clock_filter(smoothing_lag=10).run(obs, 100.0, 260.0)
    smoothed = result.smoothed
    np.testing.assert_array_equal(smoothed["time"], result.estimates["time"])
    assert (smoothed["n_ancestors"] <= 500).all() and (smoothed["n_ancestors"] >= 1).all()
    # lag 0 reproduces the filter's own estimates
    plain = clock_filter(smoothing_lag=0).run(obs, 100.0, 260.0)
    np.testing.assert_allclose(plain.smoothed["x"], plain.estimates["x"], atol=1e-9)


def test_moored_array_without_initial_range_under_10_m_and_smoothing_helps():
    """Realistic clocks (wandering period, receiver clocks, multipath), no initial range,
    search box 1 km around the receivers: error after convergence under 10 m, and the
    fixed-lag smoothed track's at most 70 % of the filter's (measured: 3.0 m vs 1.0 m)."""
    case = moored_array(5, duration=900.0)
    sc = case.scenario
    result = track_arrival_time(
        case.corrected_detections(),
        sc.receivers,
        motion=VelocityMotion(0.05, 0.02),
        period=sc.period,
        n_particles=2000,
        detection=case.detection_probability,
        smoothing_lag=30,
        start=sc.start,
        end=sc.end,
        seed=1,
    )
    error = position_error(result.estimates, sc.truth)
    converged = np.flatnonzero(result.estimates["sqrt_lambda1"].to_numpy() < 10.0)
    assert converged.size and converged[0] < 120
    after = error[converged[0] :].mean()
    assert after < 10.0
    smoothed = position_error(result.smoothed, sc.truth)[converged[0] :].mean()
    assert smoothed < 0.7 * after


@pytest.mark.parametrize("minor", [0.1, 0.3, 0.5])
def test_ambiguity_finds_two_clusters(minor):
    rng = np.random.default_rng(0)
    n = 4000
    second = rng.random(n) < minor
    x = np.where(second, 150.0, 0.0) + rng.normal(0, 5, n)
    y = np.where(second, 80.0, 0.0) + rng.normal(0, 5, n)
    w = np.full(n, 1.0 / n)
    separation, weight, split = ambiguity(x, y, w)
    assert split
    assert separation == pytest.approx(np.hypot(150, 80), rel=0.05)
    assert weight == pytest.approx(minor, abs=0.03)
    one = ambiguity(rng.normal(0, 5, n), rng.normal(0, 5, n), w)
    assert not one[2]


def test_arrival_observations_name_unknown_receivers():
    receivers = ReceiverTracks.from_frame(
        pd.DataFrame({"receiver": ["a"], "time": [np.nan], "x": [1.0], "y": [2.0]})
    )
    detections = pd.DataFrame({"time": [5.0, 6.0], "receiver": ["a", "b"]})
    with pytest.raises(ValueError, match=r"rows \[1\].*'b'"):
        arrival_observations(detections, receivers)
    obs = arrival_observations(detections.iloc[:1], receivers)
    assert obs[["receiver_x", "receiver_y"]].iloc[0].tolist() == [1.0, 2.0]


def test_arrival_observations_refuse_missing_depths():
    receivers = ReceiverTracks.from_frame(
        pd.DataFrame({"receiver": ["a"], "time": [np.nan], "x": [1.0], "y": [2.0]})
    )
    detections = pd.DataFrame({"time": [5.0, 6.0], "receiver": ["a", "a"], "depth": [3.0, np.nan]})
    with pytest.raises(ValueError, match=r"detections.*'depth'.*rows \[1\]"):
        arrival_observations(detections, receivers)
