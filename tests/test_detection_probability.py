"""Tests of the logistic detection curve, its fit, and the information in a silence."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.tracking.measurement.detection import (
    SOFTPLUS_END,
    SOFTPLUS_STEP,
    HeardTimes,
    LogisticDetection,
    SilenceModel,
    expected_pings,
    fit_detection_probability,
    silence_loglik,
    silence_loglik_recent_pings,
    softplus,
)
from hmmtrack.tracking.receivers import ReceiverTracks


@given(r=st.floats(-1e4, 1e5), r50=st.floats(10, 5000), width=st.floats(1, 1000))
def test_probabilities_of_hearing_and_missing_add_to_one(r, r50, width):
    curve = LogisticDetection(r50, width)
    total = np.exp(curve.log_probability(r)) + np.exp(curve.log_miss_probability(r))
    assert total == pytest.approx(1.0, abs=1e-12)
    assert curve(r) == pytest.approx(np.exp(curve.log_probability(r)), rel=1e-9, abs=1e-300)


@given(
    r=st.floats(-1e4, 1e5),
    r50=st.floats(10, 5000),
    width=st.floats(1, 1000),
    ceiling=st.floats(0.05, 1.0),
)
def test_a_ceiling_scales_the_curve_and_keeps_the_logs_consistent(r, r50, width, ceiling):
    full, capped = LogisticDetection(r50, width), LogisticDetection(r50, width, ceiling)
    oracle = ceiling * np.exp(-np.logaddexp(0.0, (r - r50) / width))
    assert capped(r) == pytest.approx(oracle, rel=1e-12, abs=1e-300)
    assert capped(r) == pytest.approx(ceiling * full(r), rel=1e-12)
    total = np.exp(capped.log_probability(r)) + np.exp(capped.log_miss_probability(r))
    assert total == pytest.approx(1.0, abs=1e-12)


def test_a_curve_refuses_a_bad_ceiling_and_compiled_scores_refuse_any_ceiling():
    for bad in (0.0, 1.2, np.nan):
        with pytest.raises(ValueError, match="max_probability in \\(0, 1\\]"):
            LogisticDetection(300.0, 40.0, bad)
    one = np.ones(1)
    with pytest.raises(ValueError, match="silence_loglik_recent_pings .* got 0.9"):
        silence_loglik_recent_pings(
            one, one * 8.0, one, one, (0.0, 0.0), 1, one, 0.0, 1.0,
            LogisticDetection(300.0, 40.0, 0.9), 0.1, 1500.0,
        )  # fmt: skip


def test_fit_recovers_the_curve():
    rng = np.random.default_rng(0)
    truth = LogisticDetection(range_50=650.0, width=90.0)
    r = rng.uniform(0, 1500, 20_000)
    heard = rng.random(r.size) < truth.probability(r)
    fit = fit_detection_probability(r, heard)
    # standard errors here are about 2 m and 1.5 m; allow 5 of them
    assert fit.range_50 == pytest.approx(650.0, abs=10.0)
    assert fit.width == pytest.approx(90.0, abs=7.5)


def test_fit_refuses_data_without_information():
    with pytest.raises(ValueError, match="both heard and missed"):
        fit_detection_probability([1.0, 2.0], [True, True])
    with pytest.raises(ValueError, match="rows \\[1\\]"):
        fit_detection_probability([1.0, np.nan], [True, False])
    r = np.linspace(0, 1000, 200)
    with pytest.raises(ValueError, match="do not fall off"):
        fit_detection_probability(r, r > 500)  # heard only far away


def test_expected_pings_reproduce_the_simulated_detections():
    case = moored_array(3, duration=1800.0)
    sc = case.scenario
    truth_x = np.interp(case.emission_times, sc.truth["time"], sc.truth["x"])
    truth_y = np.interp(case.emission_times, sc.truth["time"], sc.truth["y"])
    receivers = ReceiverTracks.from_frame(sc.receivers_truth)
    table = expected_pings(
        case.emission_times,
        truth_x,
        truth_y,
        receivers,
        case.corrected_detections(),
        sc.sound_speed,
        tolerance=0.5,
    )
    pings = sc.pings.sort_values(["receiver", "ping"])
    merged = table.sort_values(["receiver", "emission_time"])
    np.testing.assert_array_equal(merged["heard"].to_numpy(), pings["detected"].to_numpy())
    np.testing.assert_allclose(merged["range"].to_numpy(), pings["range"].to_numpy(), atol=0.5)


def test_silence_counts_only_due_and_unheard_pings():
    curve = LogisticDetection(range_50=500.0, width=50.0)
    expected = np.array([10.2, 10.7, 11.5, 10.9])
    r = np.array([100.0, 100.0, 100.0, 900.0])
    heard = np.array([10.21, 20.0])
    got = silence_loglik(expected, r, heard, 10.0, 11.0, curve, tolerance=0.05)
    want = np.array([0.0, np.log1p(-curve(100.0)), 0.0, np.log1p(-curve(900.0))])
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert pd.isna(got).sum() == 0


def test_compiled_recent_pings_equal_silence_loglik_ping_by_ping():
    """The compiled sum over each particle's last pings equals :func:`silence_loglik`
    applied to each of those pings in turn (the NumPy reference)."""
    rng = np.random.default_rng(12)
    n, n_back, c = 400, 4, 1500.0
    curve = LogisticDetection(range_50=300.0, width=60.0)
    emission = rng.uniform(0.0, 8.0, n)
    period = 8.0 + rng.normal(0.0, 2e-3, n)
    receiver = np.array([120.0, -40.0])
    bearing = rng.uniform(-np.pi, np.pi, n)
    radius = rng.uniform(10.0, 900.0, n)
    x, y = receiver[0] + radius * np.cos(bearing), receiver[1] + radius * np.sin(bearing)
    r = np.hypot(x - receiver[0], y - receiver[1])
    start, end, tolerance = 30.0, 45.0, 0.05  # at most two pings due per particle
    # detections exactly at some particles' expected arrivals, and noise elsewhere
    travel = r / c
    last = np.floor((end - travel - emission) / period)
    due = [emission + (last - back) * period + travel for back in (0, 1)]
    heard = np.sort(np.concatenate([due[0][::20], due[1][::20], rng.uniform(0.0, 60.0, 10)]))
    nothing_heard = silence_loglik_recent_pings(
        emission, period, x, y, receiver, n_back, np.empty(0), start, end, curve, tolerance, c
    )
    # many detections in the window (searched) and a few (scanned)
    for times in (heard, np.sort(due[0][::100])):
        got = silence_loglik_recent_pings(
            emission, period, x, y, receiver, n_back, times, start, end, curve, tolerance, c
        )
        want = sum(
            silence_loglik(
                emission + (last - back) * period + travel, r, times, start, end, curve, tolerance
            )
            for back in range(n_back)
        )
        # (the compiled log(1 − p) is interpolated to within 3e-9 per ping, see softplus)
        np.testing.assert_allclose(got, want, rtol=0, atol=n_back * 3e-9)
        assert (got < 0).sum() > n // 2  # unheard pings count, heard ones do not:
        assert (got > nothing_heard).sum() >= min(times.size, n // 20)
    assert (nothing_heard < 0).all()  # every particle has a ping due in the window


def test_compiled_softplus_is_within_3e_9_of_the_exact_function():
    """The table's bound (step⁴/3072 for a fourth derivative of at most 1/8) over the
    table, its ends and beyond, where it is max(x, 0); NaN stays NaN."""
    x = np.concatenate(
        [
            np.linspace(-SOFTPLUS_END - 5.0, SOFTPLUS_END + 5.0, 400_001),
            [-SOFTPLUS_END, SOFTPLUS_END, -1e300, 1e300, -np.inf, np.inf],
        ]
    )
    got = np.array([softplus(v) for v in x])
    np.testing.assert_allclose(got, np.logaddexp(0.0, x), rtol=1e-15, atol=3e-9)
    assert SOFTPLUS_STEP**4 / 3072 < 3e-9
    assert np.isnan(softplus(np.nan))


def test_recent_pings_of_several_receivers_are_the_sum_of_each():
    rng = np.random.default_rng(13)
    n, c = 300, 1500.0
    curve = LogisticDetection(range_50=300.0, width=60.0)
    emission = rng.uniform(0.0, 8.0, n)
    period = 8.0 + rng.normal(0.0, 2e-3, n)
    x, y = rng.uniform(-600.0, 600.0, (2, n))
    receivers = rng.uniform(-100.0, 100.0, (3, 2))
    heard = [np.sort(rng.uniform(0.0, 60.0, k)) for k in (0, 5, 40)]
    args = (30.0, 60.0, curve, 0.05, c)
    got = silence_loglik_recent_pings(emission, period, x, y, receivers, 5, heard, *args)
    want = sum(
        silence_loglik_recent_pings(emission, period, x, y, xy, 5, h, *args)
        for xy, h in zip(receivers, heard, strict=True)
    )
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert np.all(got < 0)
    # the same from the concatenated form, with receivers picked out of order
    everyone = HeardTimes.of(heard[::-1])
    picked = silence_loglik_recent_pings(
        emission, period, x, y, receivers[[2, 0]], 5, everyone.select(np.array([0, 2])), *args
    )
    np.testing.assert_allclose(
        picked,
        silence_loglik_recent_pings(
            emission, period, x, y, receivers[[2, 0]], 5, heard[::2][::-1], *args
        ),
        rtol=0,
    )
    with pytest.raises(ValueError, match="3 receiver"):
        silence_loglik_recent_pings(emission, period, x, y, receivers[:2], 5, heard, *args)


def test_a_silence_window_ends_at_the_correction_cut_and_lists_the_listening_receivers():
    # r1 listens (has positions) from t = 100 s only; ping period 8 s, tolerance 1 s
    receivers = ReceiverTracks.from_frame(
        pd.DataFrame(
            {
                "receiver": ["r0", "r1", "r1"],
                "time": [np.nan, 100.0, 200.0],
                "x": [0.0, 50.0, 150.0],
                "y": [0.0, 10.0, 10.0],
            }
        )
    )
    heard = {"r0": np.array([5.0, 60.0, 150.0]), "r1": np.array([120.0, 130.0])}
    silence = SilenceModel(receivers, LogisticDetection(300.0, 50.0), heard, tolerance=1.0)
    # empty: the cut (time + dt/2 - tolerance) is not after the last one
    assert silence.window(50.0, 1.0, 49.5, 8.0)[:2] == (49.5, 0)
    cut, n_back, xy, times = silence.window(50.0, 1.0, 20.0, 8.0)
    assert (cut, n_back) == (49.5, 5)  # ceil(29.5 / 8) + 1 pings per particle
    np.testing.assert_array_equal(xy, [[0.0, 0.0]])  # r1 does not listen yet
    np.testing.assert_array_equal(times.times[times.first[0] : times.stop[0]], heard["r0"])
    cut, n_back, xy, times = silence.window(150.0, 1.0, 0.0, 8.0)
    assert (cut, n_back) == (149.5, 8)  # at most 8
    np.testing.assert_allclose(xy, [[0.0, 0.0], [100.0, 10.0]])
    np.testing.assert_array_equal(times.times[times.first[1] : times.stop[1]], heard["r1"])


def test_curve_fitted_from_a_tracking_run_is_close_to_the_truth():
    """Two passes: track without detection probability, then fit p(range) from the track
    from its convergence on (before it, the track is not where the tag is), its clock and
    the detections. On a moored array the fitted 50 % range is within 10 % of the simulated
    one (measured, filter seeds 0-2, the default and the paper's filter: 713-762 m for
    700 m, widths 110-130 m for 100 m; from the track's start instead, 731-980 m)."""
    import warnings

    from hmmtrack.analysis.metrics import convergence_flags, first_convergence
    from hmmtrack.tracking.config import TrackingConfig
    from hmmtrack.tracking.measurement.detection import fit_detection_probability_from_track
    from hmmtrack.tracking.motion import VelocityMotion
    from hmmtrack.tracking.pipeline import track

    case = moored_array(2, duration=1800.0)
    sc = case.scenario
    detections = case.corrected_detections()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        config = TrackingConfig.from_keys(
            period=sc.period,
            measurement="arrival-time",
            n_particles=1500,
            start=sc.start,
            end=sc.end,
        )
        result = track(detections, sc.receivers, config, VelocityMotion(0.05, 0.02), seed=0)
    estimates = result.estimates
    convergence = first_convergence(estimates["time"], convergence_flags(estimates))
    fitted = fit_detection_probability_from_track(
        estimates.iloc[convergence.index :],
        result.clock,
        ReceiverTracks.from_frame(sc.receivers),
        detections,
        sc.sound_speed,
    )
    truth = case.detection_probability
    assert fitted.range_50 == pytest.approx(truth.range_50, rel=0.1)
    assert fitted.width == pytest.approx(truth.width, rel=0.5)
