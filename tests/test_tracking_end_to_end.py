"""End-to-end tests of hmmtrack.tracking.pipeline: detections → observations → filter → estimates.

The acceptance case of issue 3 is the stationary-tag scenario (a moored tag, an anchored
boat hydrophone and an AUV hydrophone driving away in 50 m steps): every motion model must
converge and keep its mean error after convergence under 10 m. It is checked on every
scenario seed of a stated range (new geometry each), not on one seed; see
``reports/stationary_tag.md`` (``hmmtrack study stationary``) for 100 seeds.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from hmmtrack import io, scenarios
from hmmtrack.analysis import metrics
from hmmtrack.analysis.calibration import expected_measurements
from hmmtrack.analysis.crb import static_tag_fit
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.tracking import filter as filter_module
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import FilterSettings
from hmmtrack.tracking.measurement import ranging
from hmmtrack.tracking.measurement.range_rate import OBSERVATION_COLUMNS, search_bounds
from hmmtrack.tracking.motion import VELOCITY_SIGMA_SPEED, VelocityMotion, motion_model
from hmmtrack.tracking.receivers import ReceiverTracks

PERIOD = 8.179
SOUND = 1460.0
N_PARTICLES = 2000

#: issue 3's acceptance runs on every stationary-tag scenario seed of this range ...
ACCEPTANCE_SEEDS = range(24)
#: ... whose own observations place the tag within this distance (m) of the truth (best
#: fixed-tag fit, :func:`hmmtrack.analysis.crb.static_tag_fit`): no filter can be asked to beat
#: its data by much
DATA_ERROR_LIMIT = 5.0


@pytest.fixture(scope="module")
def stationary():
    return scenarios.stationary_tag(5)


def scenario_config(scenario, **changes) -> TrackingConfig:
    # bounds from r0 (TrackingConfig's rule), not the scenario's box
    return tracking_config(scenario, **({"n_particles": N_PARTICLES, "bounds": None} | changes))


def diving_tag_detections(depth_of_time):
    """A moored receiver at the origin; a tag at depth moving away along x at 0.5 m/s."""
    emissions = 1000.0 + PERIOD * np.array([0, 1, 2, 4, 5, 8, 9, 10, 13, 14])
    horizontal = 40.0 + 0.5 * (emissions - emissions[0])
    depth = depth_of_time(emissions)
    slant = np.hypot(horizontal, depth)
    detections = pd.DataFrame(
        {"time": emissions + slant / SOUND, "receiver": "M", "transmitter": "T", "depth": depth}
    )
    receivers = pd.DataFrame({"receiver": ["M"], "time": [np.nan], "x": [0.0], "y": [0.0]})
    return detections, receivers, horizontal, slant


def test_observations_hold_true_ranges_and_receiver_states(stationary):
    config = scenario_config(stationary)
    observations = tracking.build_observations(stationary.detections, stationary.receivers, config)
    assert list(observations.columns) == list(OBSERVATION_COLUMNS)
    assert len(observations) == len(stationary.detections)  # nothing dropped
    heard = stationary.pings[stationary.pings["detected"]]
    joined = observations.merge(
        heard, left_on=["time", "receiver"], right_on=["logged_time", "receiver"], validate="1:1"
    )
    assert len(joined) == len(observations)
    # 0.1 ms emission jitter: range error s·(ε_k − ε_0) has sd 0.21 m; 1 m is ~5 sd
    assert np.abs(joined["range_x"] - joined["range_y"]).max() < 1.0
    # exactly one anchor (no range-rate) per receiver: its first detection
    anchors = observations[observations["range_rate"].isna()]
    assert sorted(anchors["receiver"]) == sorted(stationary.r0)
    first = observations.groupby("receiver")["time"].min()
    np.testing.assert_array_equal(anchors.set_index("receiver")["time"].sort_index(), first)
    tracks = ReceiverTracks.from_frame(stationary.receivers, velocity_window=20.0)
    auv = observations[observations["receiver"] == "auv"]
    x, y, vx, vy = tracks.state("auv", auv["time"].to_numpy())
    np.testing.assert_allclose(auv[["receiver_x", "receiver_y"]].to_numpy(), np.c_[x, y])
    np.testing.assert_allclose(auv[["receiver_vx", "receiver_vy"]].to_numpy(), np.c_[vx, vy])


@pytest.mark.parametrize("policy", ["constant", "sensor"])
def test_depth_correction_gives_horizontal_ranges(policy):
    if policy == "constant":
        detections, receivers, horizontal, slant = diving_tag_detections(lambda t: 0 * t + 12.0)
        depth = 12.0
    else:
        detections, receivers, horizontal, slant = diving_tag_detections(
            lambda t: 5.0 + 0.1 * (t - t[0])
        )
        depth = "sensor"
    config = TrackingConfig.from_keys(period=PERIOD, r0={"M": slant[0]}, depth=depth)
    observations = tracking.build_observations(detections, receivers, config)
    np.testing.assert_allclose(observations["range"], horizontal, atol=1e-6)
    # range-rates are recomputed from the horizontal ranges
    rates = np.diff(horizontal) / np.diff(detections["time"].to_numpy())
    np.testing.assert_allclose(observations["range_rate"].to_numpy()[1:], rates, atol=1e-6)
    uncorrected = tracking.build_observations(
        detections, receivers, TrackingConfig.from_keys(period=PERIOD, r0={"M": slant[0]})
    )
    np.testing.assert_allclose(uncorrected["range"], slant, atol=1e-6)


def test_depth_policy_errors_name_the_problem():
    detections, receivers, _, slant = diving_tag_detections(lambda t: 0 * t + 12.0)
    with pytest.raises(ValueError, match="needs a 'depth' column"):
        tracking.build_observations(
            detections.drop(columns="depth"),
            receivers,
            TrackingConfig.from_keys(period=PERIOD, r0={"M": slant[0]}, depth="sensor"),
        )
    with pytest.raises(ValueError, match="range shorter than depth"):
        tracking.build_observations(
            detections,
            receivers,
            TrackingConfig.from_keys(period=PERIOD, r0={"M": slant[0]}, depth=45.0),
        )


def test_pipeline_errors_name_what_is_missing(stationary):
    config = scenario_config(stationary)
    two = pd.concat(
        [stationary.detections, stationary.detections.assign(transmitter="A69-1602-99")]
    )
    with pytest.raises(ValueError, match="2 transmitters"):
        tracking.build_observations(
            two, stationary.receivers, dataclasses.replace(config, transmitter=None)
        )
    only_two = tracking.build_observations(two, stationary.receivers, config)
    assert len(only_two) == len(stationary.detections)
    with pytest.raises(ValueError, match=r"no positions for receiver\(s\) \['auv'\]"):
        tracking.build_observations(
            stationary.detections,
            stationary.receivers[stationary.receivers["receiver"] != "auv"],
            config,
        )
    with pytest.raises(ValueError, match=r"no initial range r0 for receiver\(s\) \['boat'\]"):
        tracking.build_observations(
            stationary.detections, stationary.receivers, config.override(r0={"auv": 20.0})
        )


def test_search_bounds_hold_the_tag(stationary):
    config = scenario_config(stationary)
    observations = tracking.build_observations(stationary.detections, stationary.receivers, config)
    r0 = config.measurement.r0
    xmin, xmax, ymin, ymax = search_bounds(observations, r0, margin=0.0)
    start = stationary.truth.iloc[0]
    assert xmin <= start["x"] <= xmax and ymin <= start["y"] <= ymax
    # no bigger than the receivers' reach: the widest is 2 (r0 + GPS error) across
    assert xmax - xmin <= 2 * max(r0.values()) + 10.0


def test_same_seed_same_estimates(stationary):
    config = scenario_config(stationary, n_particles=500)
    runs = [
        tracking.track(
            stationary.detections, stationary.receivers, config.override(motion="velocity"), seed=s
        )
        for s in (7, 7, 8)
    ]
    pd.testing.assert_frame_equal(runs[0].estimates, runs[1].estimates)
    assert not np.allclose(runs[0].estimates["x"], runs[2].estimates["x"])
    events = runs[0].events
    assert (events["kind"] == "anchor_detection").sum() == 2


@pytest.mark.filterwarnings("ignore:.*observations_outside_window:RuntimeWarning")
def test_without_a_motion_the_config_chooses_it(stationary):
    """``track`` with no motion model uses the one the configuration names, with its noise
    (here velocity motion with a turn-rate noise of 0.005): the same estimates as that
    model given explicitly, not those of the "hmm" default."""
    config = scenario_config(
        stationary, n_particles=300, end=stationary.start + 200, motion="velocity",
        sigma_turn_rate=0.005,
    )  # fmt: skip
    data = stationary.detections, stationary.receivers
    implicit = tracking.track(*data, config, seed=3)
    explicit = tracking.track(*data, config, VelocityMotion(VELOCITY_SIGMA_SPEED, 0.005), seed=3)
    by_name = tracking.track(*data, config.override(sigma_turn_rate=0.02), seed=3)
    pd.testing.assert_frame_equal(implicit.estimates, explicit.estimates)
    assert not np.allclose(implicit.estimates["x"], by_name.estimates["x"])
    default = tracking.track(*data, config.override(motion="hmm"), seed=3)
    assert not np.allclose(implicit.estimates["x"], default.estimates["x"])


def data_error(scenario) -> float:
    """Distance (m) from the tag to the best fixed-tag fit to the scenario's observations."""
    config = scenario_config(scenario)
    observations = tracking.build_observations(scenario.detections, scenario.receivers, config)
    scored = observations[observations["range_rate"].notna()]
    position, _ = static_tag_fit(scored, [0.0, 0.0], config.measurement.covariance)
    return float(np.hypot(*position))


@pytest.fixture(scope="module")
def acceptance_cases():
    """Scenario seed → (scenario, data error m) for every seed of ACCEPTANCE_SEEDS."""
    cases = {}
    for seed in ACCEPTANCE_SEEDS:
        scenario = scenarios.stationary_tag(seed)
        assert scenario.truth[["x", "y"]].abs().to_numpy().max() == 0.0  # tag at the origin
        cases[seed] = (scenario, data_error(scenario))
    return cases


@pytest.fixture(scope="module")
def chosen_seeds(acceptance_cases):
    """The rule: every seed whose data error is under DATA_ERROR_LIMIT."""
    return [s for s, (_, error) in acceptance_cases.items() if error < DATA_ERROR_LIMIT]


def test_the_acceptance_rule_keeps_most_geometries(acceptance_cases, chosen_seeds):
    """The rule drops only scenarios whose own data miss the tag by 5 m or more (the boat's
    single GPS fix is 1.5 m off per axis; on some geometries that moves the fit 6 m)."""
    assert len(chosen_seeds) >= 0.8 * len(ACCEPTANCE_SEEDS)
    for seed in set(ACCEPTANCE_SEEDS) - set(chosen_seeds):
        assert acceptance_cases[seed][1] >= DATA_ERROR_LIMIT


def run_scores(scenario, motion, seed, **changes):
    """Default configuration (FilterSettings' particle count) with ``changes``: metrics and
    95 % coverage; ``motion`` a name or a motion model."""
    config = scenario_config(scenario, n_particles=FilterSettings().n_particles, **changes)
    if isinstance(motion, str):
        config, motion = config.override(motion=motion), None
    result = tracking.track(scenario.detections, scenario.receivers, config, motion, seed=seed)
    assert len(result.estimates) == int(scenario.end - scenario.start) + 1
    scores = metrics.tracking_metrics(result.estimates, scenario.truth)
    conv = metrics.time_to_convergence(result.estimates["time"], result.estimates["sqrt_lambda1"])
    nees = metrics.normalised_estimation_error(result.estimates.iloc[conv.index :], scenario.truth)
    return scores, metrics.ellipse_coverage(nees)


@pytest.mark.parametrize("motion", ["baseline", "velocity", "hmm"])
def test_acceptance_on_every_geometry(acceptance_cases, chosen_seeds, motion):
    """Issue 3: on every chosen stationary-tag seed the model converges with a mean error
    after convergence under 10 m (filter seed = scenario seed). The HMM is the bundled
    white-shark model with tracking's default resting state
    (``hmmtrack.tracking.motion.HMM_RESTING``;
    measured: at most 5.7 m, 95 % ellipse coverage at least 0.93)."""
    failures = []
    for seed in chosen_seeds:
        scores, _ = run_scores(acceptance_cases[seed][0], motion, seed)
        if not (scores.converged and scores.mean_error_after_convergence < 10.0):
            failures.append((seed, scores.converged, round(scores.mean_error_after_convergence, 1)))
    assert failures == []


def test_hmm_without_resting_state_is_wide_but_honest(acceptance_cases, chosen_seeds):
    """Without the resting state (``resting=None``) the HMM does NOT meet issue 3's 10 m on
    every geometry: the white-shark prior always swims (0.4-1 m/s), so the cloud stays
    10-25 m wide and, when the boat is 125-160° from the AUV's line, reaches the second
    intersection of the two range circles, which the detections after the AUV has left
    barely tell apart; about half of these seeds end above 10 m, and on a few the spread
    √λ₁ never falls below 10 m (seed 10 here; ``reports/stationary_tag.md``). What holds on
    every seed: the mean error stays within 35 m (measured: at most 30 m) and the filter's
    own 95 % ellipse holds the truth after convergence at least 60 % of the time on each
    seed and 95 % on average (measured: 74 % at worst, 98 % on average): wide, not
    overconfident. Most seeds converge.
    """
    motion = motion_model("hmm", resting=None)
    converged, coverages = [], []
    for seed in chosen_seeds:
        scores, coverage = run_scores(acceptance_cases[seed][0], motion, seed)
        converged.append(scores.converged)
        coverages.append(coverage)
        assert scores.mean_error_after_convergence < 35.0, seed
        assert coverage >= 0.6, seed
    assert np.mean(coverages) >= 0.95
    assert np.mean(converged) >= 0.8


def test_hmm_without_resting_state_meets_the_acceptance_with_more_heading_diffusion(
    acceptance_cases, chosen_seeds
):
    """Without the resting state but with heading diffusion 0.5 rad/√s (a less ballistic
    cloud; it loses the shark pursuit, see hmmtrack.tracking.motion.HMM_HEADING_DIFFUSION) the
    HMM converges on every chosen seed and is under 10 m on at least 90 % of them (measured:
    95 % at three filter seeds; 97 % over 100 scenario seeds) and under 12 m on all, with the
    paper's filter, which these measurements are of. (On seed 14 the default filter keeps a
    second mode 33-40 m off, 5-8 % of the weight from 600 s to the end, so it never declares
    convergence there, at 3.8 m mean error: reports/decisions.md, "The library's default
    filter".)"""
    motion = motion_model("hmm", heading_diffusion=0.5, resting=None)
    errors = []
    for seed in chosen_seeds:
        scores, _ = run_scores(acceptance_cases[seed][0], motion, seed, filter="paper")
        assert scores.converged, seed
        errors.append(scores.mean_error_after_convergence)
    assert np.mean(np.array(errors) < 10.0) >= 0.9
    assert max(errors) < 12.0


@pytest.mark.filterwarnings("ignore:.*observations_outside_window:RuntimeWarning")
def test_resampling_settings_reach_the_filter(stationary):
    """Resampling after every correction leaves equal weights (n_eff = N) between
    corrections; ESS-triggered resampling with a low threshold leaves them unequal. (Before
    the first correction the default filter's particles carry the acquisition's importance
    weights: no resampling has happened yet.)"""
    n = 300
    config = scenario_config(
        stationary, n_particles=n, end=stationary.start + 120, motion="velocity"
    )
    always = tracking.track(stationary.detections, stationary.receivers, config, seed=2)
    lazy = tracking.track(
        stationary.detections,
        stationary.receivers,
        config.override(resample_when="ess", ess_threshold=0.05),
        seed=2,
    )
    corrected = set(always.observations["time"].round())
    scored = always.observations.loc[always.observations["range_rate"].notna(), "time"]
    times = always.estimates["time"]
    between = ~times.isin(corrected).to_numpy() & (times > scored.min()).to_numpy()
    np.testing.assert_allclose(always.estimates["n_eff"].to_numpy()[between], n)
    assert (lazy.estimates["n_eff"].to_numpy()[between] < 0.9 * n).mean() > 0.3


def test_range_rate_tracking_needs_r0_for_every_receiver(stationary):
    config = TrackingConfig.from_keys(period=stationary.period, transmitter=stationary.transmitter)
    assert config.measurement.r0 == {}  # given, as arrival-time tracking needs none
    with pytest.raises(ValueError, match=r"no initial range r0 for receiver\(s\)"):
        tracking.build_observations(stationary.detections, stationary.receivers, config)


def test_bounds_in_another_frame_are_refused(stationary):
    config = scenario_config(stationary, bounds=(1e5, 1e5 + 300, 0.0, 300.0), motion="baseline")
    with pytest.raises(ValueError, match="are the bounds in the receivers' frame"):
        tracking.track(stationary.detections, stationary.receivers, config, seed=0)


def test_expected_measurements_hand_values():
    observations = pd.DataFrame(
        {
            "time": [0.0, 10.0],
            "receiver_x": [0.0, 0.0],
            "receiver_y": [0.0, 0.0],
            "receiver_vx": [1.0, 0.0],
            "receiver_vy": [0.0, 0.0],
        }
    )
    fixed = pd.DataFrame({"time": [np.nan], "x": [3.0], "y": [4.0]})
    # r = 5; r_dot = ((0 - 3)(1 - 0) + (0 - 4)(0 - 0)) / 5 = -0.6
    np.testing.assert_allclose(
        expected_measurements(observations, fixed), [[5.0, -0.6], [5.0, 0.0]]
    )
    # a tag moving at (0, 0.5) m/s from (3, 4): at 10 s it is at (3, 9), moving away
    moving = pd.DataFrame({"time": [0.0, 20.0], "x": [3.0, 3.0], "y": [4.0, 14.0]})
    expected = [[5.0, (-3 * 1 + -4 * -0.5) / 5], [np.hypot(3, 9), (-9 * -0.5) / np.hypot(3, 9)]]
    np.testing.assert_allclose(expected_measurements(observations, moving), expected)


def test_measurement_covariance_from_a_simulation(stationary):
    """Σ_z from the scenario's truth: range error of the logged boat fix, small rate error."""
    observations = tracking.build_observations(
        stationary.detections, stationary.receivers, scenario_config(stationary)
    )
    rated = observations[observations["range_rate"].notna()]
    sigma = ranging.estimate_measurement_covariance(
        rated[["range", "range_rate"]], expected_measurements(rated, stationary.truth)
    )
    # the hydrophones' logged positions carry 1.5 m GPS noise and the tag 0.1 ms jitter, so
    # range errors of a few metres and range-rate errors of a few tenths of a m/s; the
    # default Σ_z (5 m, 0.5 m/s) covers them
    assert 0.1 < np.sqrt(sigma[0, 0]) < 5.0
    assert 0.01 < np.sqrt(sigma[1, 1]) < 0.5


@pytest.mark.filterwarnings("ignore:.*observations_outside_window:RuntimeWarning")
def test_streamed_estimates_are_the_kept_ones_written(stationary, tmp_path, monkeypatch):
    """With a sink (``estimates_to``) the estimates leave as tables of at most
    ``ESTIMATE_ROWS`` rows, none is kept, and an ``io.EstimatesWriter`` sink writes the very
    file ``io.write_estimates`` writes from the kept estimates (the CLI's streamed output),
    the mode columns of the default (mode-keeping) filter included: each table takes the
    modes recorded so far."""
    monkeypatch.setattr(filter_module, "ESTIMATE_ROWS", 70)
    config = scenario_config(stationary, n_particles=200, end=stationary.start + 200)
    data = stationary.detections, stationary.receivers
    kept = tracking.track(*data, config, seed=3)
    io.write_estimates(kept.estimates, tmp_path / "kept.csv")
    tables = []
    with open(tmp_path / "streamed.csv", "w", newline="") as file:
        writer = io.EstimatesWriter(file)

        def sink(table: pd.DataFrame) -> None:
            tables.append(len(table))
            writer(table)

        streamed = tracking.track(*data, config, seed=3, estimates_to=sink)
    assert streamed.estimates is None
    assert tables == [70, 70, 61] and writer.rows == len(kept.estimates) == 201
    assert {"mode2_x", "converged"} <= set(kept.estimates.columns)
    assert streamed.modes is None and len(kept.modes) > 0  # (they left with the estimates)
    assert (tmp_path / "streamed.csv").read_text() == (tmp_path / "kept.csv").read_text()
    pd.testing.assert_frame_equal(streamed.events, kept.events)
