"""Tests of the realistic-clock scenario generators."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from hmmtrack.scenarios.clocks import Multipath, WanderingPeriodClock
from hmmtrack.scenarios.realistic import STEERINGS, moored_array, realistic_shark_pursuit
from hmmtrack.scenarios.steering import (
    ROTATING_PLANS,
    RotatingPlan,
    homing_memory,
    pair_bearings,
    recent_velocity,
    rotating_pair,
    station,
    steered_auv,
)
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.clock import local_period_ppm, schedule_wander


def test_wandering_clock_has_the_stated_wander_and_jitter():
    clean = WanderingPeriodClock(8.0, schedule_wander=0.8, jitter_sd=0.0).emission_times(
        np.random.default_rng(0), 0.0, 7200.0
    )
    jittered = WanderingPeriodClock(8.0, schedule_wander=0.8, jitter_sd=65e-6).emission_times(
        np.random.default_rng(0), 0.0, 7200.0
    )
    assert clean.size == 900
    # exactly the stated wander over the reference 1.8 h (810 pings), at least that over 2 h
    assert schedule_wander(clean[:810]) == pytest.approx(0.8, rel=1e-9)
    assert schedule_wander(clean) >= 0.8 - 1e-9
    short = WanderingPeriodClock(8.0, schedule_wander=0.8, jitter_sd=0.0).emission_times(
        np.random.default_rng(0), 0.0, 1800.0
    )
    np.testing.assert_array_equal(short, clean[: short.size])  # a shorter run is the start
    jitter = jittered - clean
    assert np.std(jitter) == pytest.approx(65e-6, rel=0.1)
    assert np.mean(np.diff(clean)) == pytest.approx(8.0, rel=1e-4)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_local_period_excursions_are_of_the_real_tags_size(seed):
    """Over 800 s blocks (400 pings of the real 2 s tag, 100 of an 8 s tag) the real tag's
    local period ranged over about -700..+360 ppm; ours must span hundreds of ppm, not
    thousands."""
    times = WanderingPeriodClock(8.0, 0.8, 0.0).emission_times(
        np.random.default_rng(seed), 0.0, 7200.0
    )
    ppm = local_period_ppm(times, block=100)
    spread = ppm.max() - ppm.min()
    assert 200 < spread < 3000


def test_moored_array_is_reproducible_and_consistent_with_its_truth():
    a = moored_array(11, duration=1800.0)
    b = moored_array(11, duration=1800.0)
    assert a.scenario.detections.equals(b.scenario.detections)
    sc = a.scenario
    pings = sc.pings
    # logged times are the true arrivals through each receiver's clock, plus multipath
    for name, clock in a.receiver_clocks.items():
        rows = pings["receiver"] == name
        expected = clock.to_recorded(pings.loc[rows, "arrival_time"].to_numpy())
        got = pings.loc[rows, "logged_time"].to_numpy() - pings.loc[rows, "multipath_delay"]
        np.testing.assert_allclose(got, expected, atol=1e-6)  # float64 at 1.6e9 s: 2.4e-7 s
    # arrival - emission = range / sound speed
    np.testing.assert_allclose(
        pings["arrival_time"] - pings["emission_time"], pings["range"] / sc.sound_speed, atol=1e-6
    )
    # corrected detections are within the calibration error of the true arrival (+ multipath)
    detected = pings[pings["detected"]].sort_values("logged_time")
    corrected = a.corrected_detections()
    assert len(corrected) == len(detected)
    direct = detected["multipath_delay"].to_numpy() == 0
    error = np.sort(corrected["time"].to_numpy()) - np.sort(
        (detected["arrival_time"] + detected["multipath_delay"]).to_numpy()
    )
    assert np.max(np.abs(error)) < 1e-3
    assert direct.mean() > 0.9
    # the search box does not depend on the true start position beyond the receivers
    xmin, xmax, ymin, ymax = a.search_bounds
    assert xmin < sc.truth["x"].min() and xmax > sc.truth["x"].max()
    assert ymin < sc.truth["y"].min() and ymax > sc.truth["y"].max()


def test_multipath_delays_a_share_of_pings():
    import pandas as pd

    pings = pd.DataFrame({"logged_time": np.zeros(20_000)})
    out = Multipath(fraction=0.05, mean_delay=0.02).apply(np.random.default_rng(5), pings)
    late = out["multipath_delay"] > 0
    assert late.mean() == pytest.approx(0.05, abs=0.005)
    assert out.loc[late, "multipath_delay"].mean() == pytest.approx(0.02, rel=0.1)
    np.testing.assert_allclose(out["logged_time"], out["multipath_delay"])


def auv_geometry(scenario):
    """Per AUV: 1 s speeds (m/s), unwrapped bearing from the shark (rad) and distance (m)."""
    truth = scenario.truth.set_index("time")
    out = {}
    for name, g in scenario.receivers_truth.groupby("receiver"):
        g = g.set_index("time")
        speed = np.hypot(np.diff(g["x"]), np.diff(g["y"])) / np.diff(g.index)
        dx = g["x"] - truth.loc[g.index, "x"]
        dy = g["y"] - truth.loc[g.index, "y"]
        bearing = np.unwrap(np.arctan2(dy, dx).to_numpy())
        out[name] = (speed, bearing, np.hypot(dx, dy).to_numpy(), g.index[-1] - g.index[0])
    return out


@pytest.mark.parametrize("seed", [0, 1])
def test_circling_pursuit_is_realistic_and_turns_its_geometry(seed):
    """The default pursuit: the AUVs stay at about the stated distances, no faster than an
    AUV can go, and the circling vehicle's bearing from the shark turns one lap per
    20 minutes while the trailing one's stays put (what makes the tag observable)."""
    case = realistic_shark_pursuit(seed)
    sc = case.scenario
    for name, (speed, turned, distances, span) in auv_geometry(sc).items():
        assert np.percentile(speed, 99) < 2.2
        laps = (turned[-1] - turned[0]) / (2 * np.pi)
        distance = np.median(distances)
        if name == "auv-2":
            expected = span / 1200.0
            assert laps == pytest.approx(expected, rel=0.1)
            assert 100 < distance < 140
        else:
            assert abs(laps) < 0.25
            assert 50 < distance < 140
    heard = sc.pings.groupby("receiver")["detected"].mean()
    assert (heard > 0.4).all() and (heard < 0.95).all()
    # the paper's formation is still available, with the same shark
    paper = realistic_shark_pursuit(seed, steering="paper").scenario
    pd.testing.assert_frame_equal(paper.truth, sc.truth)
    assert not paper.receivers_truth.equals(sc.receivers_truth)
    with pytest.raises(ValueError, match="steering"):
        realistic_shark_pursuit(seed, steering="zigzag")


def test_formation_keeps_a_right_angle_and_turns_around_the_shark():
    sc = realistic_shark_pursuit(0, steering="formation").scenario
    bearings = {}
    for name, (speed, bearing, distances, span) in auv_geometry(sc).items():
        bearings[name] = bearing
        assert np.percentile(speed, 99) < 2.3
        assert 40 < np.median(distances) < 90
        laps = (bearing[-1] - bearing[0]) / (2 * np.pi)
        assert laps == pytest.approx(span / 600.0, rel=0.1)
    angle = bearing_gap_deg(bearings)
    assert np.median(angle) == pytest.approx(90.0, abs=10.0)
    assert np.percentile(np.abs(angle - 90.0), 90) < 30.0
    default = realistic_shark_pursuit(0).scenario
    pd.testing.assert_frame_equal(default.truth, sc.truth)


def test_a_led_station_cancels_the_homing_lag_on_a_steady_shark():
    """A vehicle homing with time constant τ on a set point moving at a constant velocity
    trails it by v·e^(-1/τ)/(1 - e^(-1/τ)) (closed form of the discrete low-pass); with the
    lead it sits on its station once the transients (e^(-t/τ), e^(-t/window)) have died."""
    time = np.arange(0.0, 1201.0)
    velocity = np.array([0.8, -0.6])  # m/s
    shark = Trajectory(time, 5.0 + velocity[0] * time, -3.0 + velocity[1] * time)
    bearing = np.full(time.size, 0.7)
    station = np.column_stack([shark.x + 30 * np.cos(0.7), shark.y + 30 * np.sin(0.7)])
    keep = np.exp(-1.0 / 20.0)
    lagging = steered_auv(shark, 30.0, bearing, time_constant=20.0)
    trail = np.column_stack([lagging.x, lagging.y]) - station
    np.testing.assert_allclose(trail[-200:], np.tile(-velocity * keep / (1 - keep), (200, 1)))
    led = steered_auv(shark, 30.0, bearing, time_constant=20.0, lead_window=30.0)
    np.testing.assert_allclose(np.column_stack([led.x, led.y])[-200:], station[-200:], atol=1e-6)
    # the velocity it leads with is causal: a later turn does not change earlier positions
    turned = Trajectory(time, shark.x, np.where(time > 600, shark.y - (time - 600), shark.y))
    early = steered_auv(turned, 30.0, bearing, time_constant=20.0, lead_window=30.0)
    np.testing.assert_array_equal(early.x[:601], led.x[:601])
    assert recent_velocity(shark.x, 30.0)[-1] == pytest.approx(velocity[0])
    with pytest.raises(ValueError, match="window must be a positive"):
        recent_velocity(shark.x, 0.0)


def bearing_gap_deg(bearings) -> np.ndarray:
    """Angle (deg, in (-180, 180]) from auv-1's bearing to auv-2's, per second."""
    return np.degrees(np.angle(np.exp(1j * (bearings["auv-2"] - bearings["auv-1"]))))


def test_observable_plan_flies_its_stated_geometry_at_auv_speeds():
    """``steering="observable"``: stations 27 m from the shark, 135° apart, the pair turning
    once per 150 s, led by the shark's recent velocity. The vehicles then hold the angle
    and fly every lap behind a travelling shark, on the circle that the homing low-pass
    passes (radius × |H(e^(iω))| at the lap's frequency ω), at speeds an AUV can hold
    (99 % under 2.5 m/s); without the lead the same pair falls behind the shark, closes
    its angle and skips laps."""
    plan = RotatingPlan()
    assert (plan.radius, plan.lap_time, np.degrees(plan.separation)) == pytest.approx(
        (27.0, 150.0, 135.0)
    )
    keep, omega = np.exp(-1.0 / plan.time_constant), 2 * np.pi / plan.lap_time
    flown = plan.radius * (1 - keep) / abs(1 - keep * np.exp(-1j * omega))
    sc = realistic_shark_pursuit(1, steering="observable").scenario
    bearings = {}
    for name, (speed, bearing, distances, span) in auv_geometry(sc).items():
        bearings[name] = bearing
        assert np.percentile(speed, 99) < 2.5
        assert np.median(distances) == pytest.approx(flown, abs=0.5)
        assert np.percentile(np.abs(distances - flown), 95) < 6.0  # the shark turns, speeds up
        laps = (bearing[-1] - bearing[0]) / (2 * np.pi)
        assert laps == pytest.approx(span / 150.0, rel=0.01)
    gap = np.abs(bearing_gap_deg(bearings))
    assert np.median(gap) == pytest.approx(135.0, abs=2.0)
    assert np.percentile(gap, 5) > 110.0
    unled = RotatingPlan(lead_window=None)
    lagging = auv_geometry(realistic_shark_pursuit(1, steering=unled).scenario)
    assert np.median(np.abs(bearing_gap_deg({n: g[1] for n, g in lagging.items()}))) < 125.0
    assert np.percentile(lagging["auv-1"][2], 5) < 15.0
    pd.testing.assert_frame_equal(realistic_shark_pursuit(1).scenario.truth, sc.truth)
    assert "observable" in sc.description


def test_a_rotating_plan_is_a_steering_and_the_named_plans_are_rotating_plans():
    """A :class:`RotatingPlan` with the formation's numbers gives exactly the "formation"
    scenario; other numbers change only the AUVs; bad plans and names are clear errors."""
    assert set(ROTATING_PLANS) < set(STEERINGS)
    formation = RotatingPlan(radius=70.0, lap_time=600.0, separation=0.5 * np.pi, lead_window=None)
    named = realistic_shark_pursuit(2, steering="formation").scenario
    planned = realistic_shark_pursuit(2, steering=formation).scenario
    pd.testing.assert_frame_equal(named.detections, planned.detections)
    pd.testing.assert_frame_equal(named.receivers_truth, planned.receivers_truth)
    slow = realistic_shark_pursuit(2, steering=RotatingPlan(lap_time=300.0)).scenario
    bearings = {n: g[1] for n, g in auv_geometry(slow).items()}
    span = auv_geometry(slow)["auv-1"][3]
    laps = (bearings["auv-1"][-1] - bearings["auv-1"][0]) / (2 * np.pi)
    assert laps == pytest.approx(span / 300.0, rel=0.05)
    assert "lap 300 s" in slow.description
    with pytest.raises(ValueError, match="lap_time must be a positive"):
        RotatingPlan(lap_time=0.0)
    with pytest.raises(ValueError, match="separation must lie in"):
        RotatingPlan(separation=7.0)
    with pytest.raises(ValueError, match="lead_window must be a positive"):
        RotatingPlan(lead_window=-1.0)
    with pytest.raises(ValueError, match="observable"):
        realistic_shark_pursuit(2, steering="observed")


def test_the_plan_geometry_pieces_in_closed_form():
    """``homing_memory``: ``keep = e^(-1/τ)`` and the lag ``keep / (1 - keep)`` is the time a
    vehicle homing on a set point moving at constant speed trails it (1 s steps, the
    geometric series); ``station``: ``radius`` from the shark at ``bearing``, shifted by the
    lead; ``pair_bearings``: ``separation`` apart, turning ``2π`` per ``lap_time``; and
    :func:`rotating_pair` is :func:`steered_auv` flown on those bearings."""
    keep, lag = homing_memory(20.0)
    assert keep == pytest.approx(np.exp(-0.05))
    assert lag == pytest.approx(sum(k * (1 - keep) * keep**k for k in range(2000)))
    x, y = station(3.0, -4.0, 27.0, np.pi / 3)
    assert (x, y) == pytest.approx((3.0 + 13.5, -4.0 + 27.0 * np.sqrt(3) / 2))
    assert station(3.0, -4.0, 27.0, np.pi / 3, (1.0, 2.0)) == pytest.approx((x + 1.0, y + 2.0))
    bearings = pair_bearings(np.array([0.0, 75.0]), 0.2, 150.0, 2.0)
    np.testing.assert_allclose(bearings["auv-1"], [0.2, 0.2 + np.pi])
    np.testing.assert_allclose(bearings["auv-2"] - bearings["auv-1"], [2.0, 2.0])
    time = np.arange(0.0, 301.0)
    shark = Trajectory(time, 0.5 * time, np.sin(time / 50.0))
    pair = rotating_pair(shark, 0.2, radius=27.0, lap_time=150.0, separation=2.0, lead_window=30.0)
    for name, bearing in pair_bearings(time, 0.2, 150.0, 2.0).items():
        alone = steered_auv(shark, 27.0, bearing, 20.0, 30.0)
        np.testing.assert_array_equal(pair[name].x, alone.x)
