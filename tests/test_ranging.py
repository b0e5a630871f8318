"""Tests of hmmtrack.tracking.measurement.ranging against detection times built from known
trajectories."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack.tracking.measurement import ranging
from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement, RangeRateSettings

PERIOD = 8.179
SOUND = 1460.0


def arrivals(emissions, range_at):
    """Arrival times of pings emitted at ``emissions`` (s) for a range function (m)."""
    return emissions + range_at(emissions) / SOUND


def receding(emissions):
    """Range of a hydrophone driving away at 1.5 m/s from 120 m."""
    return 120.0 + 1.5 * emissions


def heard(n_pings, missed_runs):
    """Indices of the heard pings: after each heard ping, skip ``missed_runs[i]`` pings."""
    index, kept, i = 0, [], 0
    while index < n_pings:
        kept.append(index)
        index += 1 + missed_runs[i % len(missed_runs)]
        i += 1
    return np.array(kept)


@pytest.mark.parametrize("missed", [0, 1, 2, 3, 4, 5])
def test_exact_ranges_with_missed_pings(missed):
    emissions = 1000.0 + PERIOD * heard(300, [missed])
    times = arrivals(emissions, receding)
    r = ranging.ranges(times, PERIOD, r0=receding(emissions[0]))
    np.testing.assert_allclose(r, receding(emissions), rtol=0, atol=1e-7)
    table = ranging.range_table(
        pd.DataFrame({"time": times, "receiver": "A", "transmitter": "T1"}),
        PERIOD,
        {"A": receding(emissions[0])},
    )
    assert table["missed_pings"].tolist() == [0] + [missed] * (times.size - 1)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 5), min_size=1, max_size=12), st.floats(-4.0, 4.0))
def test_ranges_equal_the_papers_sum_of_delta_tof(missed_runs, speed):
    """Any pattern of 0–5 missed pings: the telescoped form equals the truth and the sum."""
    emissions = PERIOD * heard(200, missed_runs)

    def range_at(t):
        return 800.0 + speed * t + 30.0 * np.sin(t / 90.0)

    times = arrivals(emissions, range_at)
    r = ranging.ranges(times, PERIOD, r0=range_at(emissions[0]))
    np.testing.assert_allclose(r, range_at(emissions), atol=1e-7)
    summed = r[0] + np.concatenate(
        [[0], np.cumsum(SOUND * ranging.delta_tof(np.diff(times), PERIOD))]
    )
    np.testing.assert_allclose(r, summed, atol=1e-6)


def test_period_jitter_gives_bounded_non_accumulating_error():
    """Emission jitter ε (|ε| ≤ 1 ms) gives range error s·(ε_k − ε_0), at most 2·s·1 ms."""
    rng = np.random.default_rng(3)
    jitter = 1e-3
    k = heard(20000, [0, 0, 2, 0, 5, 1])
    epsilon = rng.uniform(-jitter, jitter, k.size)
    emissions = PERIOD * k + epsilon
    times = arrivals(emissions, receding)
    r = ranging.ranges(times, PERIOD, r0=receding(emissions[0]))
    error = r - receding(emissions)
    np.testing.assert_allclose(error, SOUND * (epsilon - epsilon[0]), atol=1e-5)
    assert np.abs(error).max() <= 2 * SOUND * jitter
    # no growth: the last thousand detections are no worse than the first thousand
    assert np.abs(error[-1000:]).max() <= 2 * SOUND * jitter


def test_delta_tof_at_the_wrap_around():
    half = PERIOD / 2
    dt = np.array(
        [
            PERIOD + 0.49 * PERIOD,
            PERIOD + 0.51 * PERIOD,
            3 * PERIOD - 0.49 * PERIOD,
            3 * PERIOD + 0.49 * PERIOD,
        ]
    )
    np.testing.assert_allclose(
        ranging.delta_tof(dt, PERIOD),
        [0.49 * PERIOD, -0.49 * PERIOD, -0.49 * PERIOD, 0.49 * PERIOD],
    )
    # the half-open interval [-T/2, T/2): exactly half a period is read as approaching
    assert ranging.delta_tof(np.array([half]), PERIOD)[0] == pytest.approx(-half)
    assert np.all(np.abs(ranging.delta_tof(np.linspace(0, 40, 1001), PERIOD)) <= half)


@pytest.mark.parametrize("fraction", [0.45, -0.45])
def test_ranges_exact_close_to_the_wrap_around(fraction):
    """Range changes of 0.45·s·T between detections (just inside the limit) stay exact."""
    emissions = PERIOD * heard(50, [1])
    step = fraction * SOUND * PERIOD / (2 * PERIOD)  # range change per second

    def range_at(t):
        return 1e5 + step * t

    times = arrivals(emissions, range_at)
    np.testing.assert_allclose(
        ranging.ranges(times, PERIOD, r0=range_at(emissions[0])), range_at(emissions), atol=1e-6
    )


@pytest.mark.parametrize("speed", [-2.0, 2.0])
def test_range_rate_sign_and_value(speed):
    emissions = PERIOD * heard(100, [0, 3])

    def range_at(t):
        return 900.0 + speed * t

    times = arrivals(emissions, range_at)
    table = ranging.range_table(
        pd.DataFrame({"time": times, "receiver": "A", "transmitter": "T1"}),
        PERIOD,
        {"A": range_at(emissions[0])},
    )
    rate = table["range_rate"].to_numpy()
    assert np.isnan(rate[0])
    # per second of arrival time the range changes by v / (1 + v/s) (the Doppler factor)
    np.testing.assert_allclose(rate[1:], speed / (1 + speed / SOUND), rtol=1e-9)
    assert np.all(np.sign(rate[1:]) == np.sign(speed))


def test_range_table_groups_pairs_and_sorts_rows():
    rng = np.random.default_rng(0)
    frames = []
    truth = {}
    for receiver, start in (("A", 50.0), ("B", 400.0)):
        for transmitter in ("T1", "T2"):
            emissions = PERIOD * heard(60, [0, 1, 4]) + rng.uniform(0, 5)

            def range_at(t, start=start, t0=emissions[0]):
                return start + 0.8 * (t - t0)

            times = arrivals(emissions, range_at)
            truth[receiver, transmitter] = (times, range_at(emissions))
            frames.append(
                pd.DataFrame({"time": times, "receiver": receiver, "transmitter": transmitter})
            )
    detections = pd.concat(frames).sample(frac=1.0, random_state=1)
    table = ranging.range_table(detections, PERIOD, {"A": 50.0, "B": 400.0})
    assert list(table.columns) == list(ranging.RANGE_COLUMNS)
    assert len(table) == len(detections)
    assert np.all(np.diff(table["time"].to_numpy()) >= 0)
    for (receiver, transmitter), (times, expected) in truth.items():
        rows = table[(table["receiver"] == receiver) & (table["transmitter"] == transmitter)]
        np.testing.assert_allclose(rows["time"], times)
        np.testing.assert_allclose(rows["range"], expected, atol=1e-7)


def test_range_table_uses_a_detection_logged_twice_once(caplog):
    """The pipeline's one rule for duplicates (io.drop_duplicate_detections), not an error."""
    once = pd.DataFrame({"time": [0.0, 8.0, 16.5], "receiver": "A", "transmitter": "T"})
    twice = pd.concat([once, once.iloc[[1]]]).sort_values("time", kind="stable")
    with caplog.at_level("WARNING", logger="hmmtrack.io.detections"):
        table = ranging.range_table(twice, PERIOD, {"A": 1.0})
    pd.testing.assert_frame_equal(table, ranging.range_table(once, PERIOD, {"A": 1.0}))
    assert "dropped 1 exact duplicate detection(s)" in caplog.text


def test_range_table_errors_name_what_is_wrong():
    detections = pd.DataFrame({"time": [0.0, 8.0, 8.0], "receiver": "A", "transmitter": "T"})
    with pytest.raises(ValueError, match=r"receiver\(s\) \['A'\]"):
        ranging.range_table(detections, PERIOD, {"B": 1.0})
    with pytest.raises(ValueError, match="lacks column"):
        ranging.range_table(detections.drop(columns="transmitter"), PERIOD, {"A": 1.0})
    with pytest.raises(ValueError, match="period"):
        ranging.ranges([0.0, 8.0], -1.0, 0.0)


@pytest.mark.parametrize("guess", [None, 8.1])
def test_estimate_period_recovers_the_period_with_missed_pings(guess):
    rng = np.random.default_rng(7)
    k = heard(600, [0, 2, 0, 1, 5, 0, 0, 3])
    times = 50.0 + 0.2 + PERIOD * k + rng.normal(0, 1e-4, k.size)
    assert ranging.estimate_period(times, period_guess=guess) == pytest.approx(PERIOD, abs=1e-6)


def test_estimate_measurement_covariance_recovers_a_known_covariance():
    rng = np.random.default_rng(11)
    sigma = np.array([[16.0, 1.2], [1.2, 0.25]])
    n = 40000
    truth = np.column_stack([rng.uniform(0, 500, n), rng.uniform(-2, 2, n)])
    measured = truth + rng.multivariate_normal([0, 0], sigma, n)
    estimate = ranging.estimate_measurement_covariance(measured, truth)
    # standard error of a sample covariance entry: sqrt((S_ii S_jj + S_ij²) / n)
    se = np.sqrt((np.outer(np.diag(sigma), np.diag(sigma)) + sigma**2) / n)
    assert np.all(np.abs(estimate - sigma) < 4 * se)
    assert np.allclose(estimate, estimate.T)
    measured[5, 1] = np.nan
    with pytest.raises(ValueError, match=r"row\(s\) \[5\]"):
        ranging.estimate_measurement_covariance(measured, truth)


def test_recalibrate_drift_removes_a_constant_period_error():
    emissions = PERIOD * heard(2000, [0, 1, 0, 3])

    def range_at(t):
        return 300.0 + 200.0 * np.sin(t / 700.0)

    times = arrivals(emissions, range_at)
    wrong_period = PERIOD * (1 + 20e-6)  # a 20 ppm period error
    drifted = ranging.ranges(times, wrong_period, r0=range_at(emissions[0]))
    truth = range_at(emissions)
    assert np.abs(drifted - truth).max() > 400.0  # 20 ppm over 2000 periods (4.5 h): ~480 m
    corrected = ranging.recalibrate_drift(times, drifted, final_range=truth[-1])
    # residual: the error is linear in the period count, the correction linear in time;
    # they differ by at most the relative TOF change, here well under 0.1 m
    assert np.abs(corrected - truth).max() < 0.1


def test_depth_correction_reproduces_the_papers_figures():
    errors = ranging.depth_percent_error(np.array([20.0, 50.0, 100.0]), 10.7)
    np.testing.assert_array_equal(np.round(errors, 1), [18.4, 2.4, 0.6])
    np.testing.assert_allclose(
        ranging.depth_correction(np.array([5.0, 13.0]), 12.0, "clip"), [0, 5]
    )
    np.testing.assert_allclose(
        ranging.depth_correction(np.array([5.0, 13.0]), np.array([3.0, 5.0])), [4.0, 12.0]
    )
    with pytest.raises(ValueError, match=r"position\(s\) \[0\]"):
        ranging.depth_correction(np.array([5.0, 13.0]), 12.0)


def test_a_gap_longer_than_max_gap_breaks_the_range_chain():
    """Ranges counted across a long gap are not trusted: NaN from the detection after it,
    and the measurement reports the break as an event instead of scoring those rows."""
    times = np.r_[np.arange(5) * PERIOD, 5000.0 + np.arange(3) * PERIOD]
    detections = pd.DataFrame({"time": times, "receiver": "A", "transmitter": "T"})
    whole = ranging.range_table(detections, PERIOD, {"A": 30.0})
    assert np.isfinite(whole["range"]).all()
    table = ranging.range_table(detections, PERIOD, {"A": 30.0}, max_gap=3600.0)
    np.testing.assert_array_equal(table["range"][:5], whole["range"][:5])
    assert table["range"][5:].isna().all() and table["range_rate"][5:].isna().all()
    observations = table.assign(receiver_x=0.0, receiver_y=0.0, receiver_vx=0.0, receiver_vy=0.0)
    measurement = RangeRateMeasurement.from_settings(RangeRateSettings(period=PERIOD))
    scored, events = measurement.split(observations)
    np.testing.assert_array_equal(scored["time"], times[1:5])
    assert events["kind"].tolist() == ["anchor_detection", "range_chain_broken"]
    assert events["time"].iloc[1] == 5000.0
    assert "receiver A: its 3 detection(s)" in events["detail"].iloc[1]
    assert "4967 s gap" in events["detail"].iloc[1]
