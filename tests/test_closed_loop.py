"""Tests of the closed loop: two AUVs steered on the tracker's online estimate."""

from __future__ import annotations

import warnings
from functools import cache

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from hmmtrack.experiments import closed_loop_study
from hmmtrack.experiments.closed_loop import (
    _Channel,
    arrival_time_tracker,
    fly_closed_loop,
    plan_phase,
)
from hmmtrack.scenarios.realistic import realistic_shark_pursuit
from hmmtrack.scenarios.steering import RotatingPlan
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.pipeline import track

PLAN = RotatingPlan()  # the "observable" plan


@cache
def observable_case(seed: int):
    return realistic_shark_pursuit(seed, steering="observable")


def preset_config(case, duration: float, n_particles: int) -> TrackingConfig:
    """The ``two-moving-receivers`` preset on ``case``'s first ``duration`` s, ``n_particles``,
    with the closed-loop study's filter (no acquisition online)."""
    return closed_loop_study.preset_config(case, n_particles, duration)


def fly(case, duration, n_particles=300, filter_seed=5, **options):
    config = preset_config(case, duration, n_particles)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a re-initialised cloud warns
        tracker = arrival_time_tracker(config, filter_seed)
        return fly_closed_loop(case, PLAN, tracker, duration=duration, **options)


def speeds(receivers_truth: pd.DataFrame) -> np.ndarray:
    """Every AUV's 1 s speeds (m/s)."""
    return np.concatenate(
        [np.hypot(np.diff(p["x"]), np.diff(p["y"])) for _, p in receivers_truth.groupby("receiver")]
    )


def test_steered_on_the_truth_the_loop_flies_the_open_loop_plan_and_runs_its_filter():
    """The oracle that ties the closed loop to the open-loop plan: with the true shark
    substituted for the estimate, the AUVs fly exactly the scenario's paths, hear exactly
    its pings at the same logged times and log the same GPS positions, and the tracker
    stepped online gives the estimates of the offline ``track`` run on the
    scenario's own detections with the same seed."""
    case, duration = observable_case(0), 400
    sc = case.scenario
    run = fly(case, duration, steer_on="truth", seed=1)
    n = duration + 2
    for table, closed in ((sc.receivers_truth, run.receivers_truth), (sc.receivers, run.receivers)):
        for name, rows in closed.groupby("receiver"):
            open_rows = table[table["receiver"] == name].iloc[:n]
            np.testing.assert_array_equal(rows[["x", "y"]], open_rows[["x", "y"]])
    assert set(run.steering["source"]) == {"truth"}
    end = sc.start + duration
    open_pings = sc.pings[sc.pings["emission_time"] < end].reset_index(drop=True)
    pd.testing.assert_frame_equal(run.pings, open_pings[run.pings.columns])
    assert run.pings["detected"].sum() > 0.8 * len(run.pings)
    detections = case.corrected_detections()
    detections = detections[detections["time"] < end].reset_index(drop=True)
    config = preset_config(case, duration, 300)
    assert config.bounds == case.search_bounds and config.end == end
    offline = track(detections, sc.receivers, config, seed=5)
    pd.testing.assert_series_equal(
        run.observations["time"], offline_times(detections), check_names=False
    )
    np.testing.assert_allclose(
        run.estimates[["time", "x", "y", "sqrt_lambda1"]],
        offline.estimates[["time", "x", "y", "sqrt_lambda1"]],
        rtol=0,
        atol=1e-6,
    )


def offline_times(detections: pd.DataFrame) -> pd.Series:
    return detections["time"].sort_values(kind="stable").reset_index(drop=True)


def test_the_coupled_draws_are_uniform_and_reproduce_what_the_open_loop_heard():
    """``u`` below ``p`` exactly for the pings the open loop heard, and ``u`` uniform on
    (0, 1) over all (ping, receiver) pairs: the closed loop hears with the right law."""
    case = observable_case(1)
    channel = _Channel(case, ("auv-1", "auv-2"), np.random.default_rng(3))
    pings = case.scenario.pings
    draws = []
    for name in ("auv-1", "auv-2"):
        rows = pings[pings["receiver"] == name].sort_values("ping")
        u = channel.draw[name]
        np.testing.assert_array_equal(u < rows["probability"].to_numpy(), rows["detected"])
        np.testing.assert_array_equal(channel.delay[name], rows["multipath_delay"])
        draws.append(u)
    assert stats.kstest(np.concatenate(draws), "uniform").pvalue > 0.01


def test_same_seed_same_answer_and_the_coupling_seed_matters():
    case = observable_case(2)
    first = fly(case, 200, seed=7)
    again = fly(case, 200, seed=7)
    for name in ("receivers_truth", "pings", "observations", "estimates", "steering"):
        pd.testing.assert_frame_equal(getattr(first, name), getattr(again, name))
    other = fly(case, 200, seed=8)
    assert not first.pings["detected"].equals(other.pings["detected"])


def test_a_short_closed_loop_converges_and_holds_the_plan_geometry():
    """Steered on its own estimate (600 particles, 15 min), the tracker converges, stays
    within 10 m from 5 min on, and the AUVs keep near the open-loop geometry: ~21 m from
    the true shark (27 m stations through the homing low-pass), about 135° apart, at AUV
    speeds."""
    case, duration = observable_case(3), 900
    sc = case.scenario
    run = fly(case, duration, n_particles=600, seed=3)
    truth = sc.truth.iloc[: len(run.estimates)]
    error = np.hypot(
        run.estimates["x"].to_numpy() - truth["x"].to_numpy(),
        run.estimates["y"].to_numpy() - truth["y"].to_numpy(),
    )
    assert error[300:].mean() < 10.0
    assert run.estimates["sqrt_lambda1"].iloc[300:].median() < 15.0
    assert list(run.steering["source"].iloc[:2]) == ["start", "start"]
    assert set(run.steering["source"].iloc[2:]) == {"estimate"}
    paths = {n: p for n, p in run.receivers_truth.groupby("receiver")}
    shark = sc.truth.iloc[: duration + 2][["x", "y"]].to_numpy()
    offsets = {n: p[["x", "y"]].to_numpy() - shark for n, p in paths.items()}
    distance = {n: np.hypot(*o.T)[300:] for n, o in offsets.items()}
    for d in distance.values():
        assert 15.0 < np.median(d) < 27.0
    angle = np.angle(
        (offsets["auv-2"][:, 0] + 1j * offsets["auv-2"][:, 1])
        / (offsets["auv-1"][:, 0] + 1j * offsets["auv-1"][:, 1])
    )
    assert np.degrees(np.median(np.abs(angle[300:]))) == pytest.approx(135.0, abs=15.0)
    assert speeds(run.receivers_truth).max() <= 3.0 + 1e-9


def test_the_speed_cap_binds_and_holding_waits_for_the_cloud():
    case = observable_case(0)
    capped = fly(case, 150, max_speed=1.2, seed=1)
    assert speeds(capped.receivers_truth).max() == pytest.approx(1.2)
    held = fly(case, 300, hold_until_spread=60.0, seed=1)
    source = held.steering["source"].to_numpy()
    switch = int(np.argmax(source == "estimate"))
    assert switch > 0 and set(source[:switch]) == {"start"}
    assert set(source[switch:]) == {"estimate"}
    # it let go one second after the first estimate at or under 60 m
    spread = held.estimates["sqrt_lambda1"].to_numpy()
    assert switch == int(np.argmax(spread <= 60.0)) + 2
    assert held.steering[["velocity_x", "velocity_y"]].iloc[switch].abs().max() == 0.0
    start = held.steering[["shark_x", "shark_y"]].iloc[:switch].to_numpy()
    np.testing.assert_array_equal(start, np.tile(start[0], (switch, 1)))


def test_bad_inputs_are_clear_errors():
    case = observable_case(0)
    config = preset_config(case, 100, 100)
    with pytest.raises(ValueError, match="another plan"):
        plan_phase(realistic_shark_pursuit(0, steering="formation"), PLAN)
    assert plan_phase(case, PLAN) == pytest.approx(
        np.arctan2(*(case_start(case, "auv-1") - case.scenario.truth[["x", "y"]].iloc[0])[::-1])
    )
    with pytest.raises(ValueError, match="steer_on"):
        fly_closed_loop(case, PLAN, arrival_time_tracker(config, 0), steer_on="oracle")
    with pytest.raises(ValueError, match="duration must be"):
        fly_closed_loop(case, PLAN, arrival_time_tracker(config, 0), duration=10**6)
    started = arrival_time_tracker(config, 0)
    started.initialise(case.scenario.start)
    with pytest.raises(ValueError, match="already started"):
        fly_closed_loop(case, PLAN, started)
    with pytest.raises(ValueError, match="max_speed"):
        fly_closed_loop(case, PLAN, arrival_time_tracker(config, 0), max_speed=0.0)
    with pytest.raises(ValueError, match="without a detection curve"):
        arrival_time_tracker(config.override(detection_curve={"range_50": 160, "width": 40}), 0)
    with pytest.raises(ValueError, match="set acquisition to False"):
        arrival_time_tracker(config.override(filter="mode-keeping"), 0)


def case_start(case, name: str) -> np.ndarray:
    rows = case.scenario.receivers_truth
    return rows.loc[rows["receiver"] == name, ["x", "y"]].iloc[0].to_numpy()
