"""The resting state added to a fitted movement HMM at tracking time
(``MovementHMM.with_resting_state``, ``motion_model(resting=...)``)."""

import math
import warnings

import numpy as np
import pytest
from scipy import stats

from hmmtrack.experiments import paper_scenarios
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.experiments.trials import _motion
from hmmtrack.hmm import Gamma, MovementHMM, VonMises, Weibull, WrappedCauchy
from hmmtrack.hmm.formula import Design
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.motion import (
    HMM_RESTING,
    HMM_STILL_RESTING,
    HMMMotion,
    RestingState,
    bundled_model_path,
    motion_model,
)
from hmmtrack.tracking.motion.hmm import transition_for_step
from hmmtrack.tracking.particles import Particles


def swimmer_model(dt=60.0, step_cls=Gamma, zero_mass=None):
    """Two swimming states fitted at ``dt`` s (steps in metres)."""
    return MovementHMM(
        initial=np.array([0.7, 0.3]),
        transition=np.array([[0.9, 0.1], [0.25, 0.75]]),
        step=step_cls.from_moments([20.0, 60.0], [10.0, 15.0], zero_mass=zero_mass),
        angle=VonMises(mean=np.array([0.1, 0.0]), concentration=np.array([1.5, 12.0])),
        dt=dt,
    )


def probabilities_per_step(rate_per_hour, dt):
    return 1.0 - math.exp(-rate_per_hour * dt / 3600.0)


# ------------------------------------------------------------------------- the chain


@pytest.mark.parametrize("enter, leave", [(0.5, 2.0), (6.0, 1.0), (0.0, 3.0)])
def test_transition_matrix_structure_and_closed_form_stationary(enter, leave):
    model = swimmer_model()
    rested = model.with_resting_state(enter, leave, resting_step=3.0)
    gamma = rested.transition
    p_enter = probabilities_per_step(enter, model.dt)
    p_leave = probabilities_per_step(leave, model.dt)
    assert gamma.shape == (3, 3)
    assert np.all(gamma >= 0)
    np.testing.assert_allclose(gamma.sum(axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(gamma[:2, :2], (1 - p_enter) * model.transition, rtol=1e-14)
    np.testing.assert_allclose(gamma[:2, 2], p_enter, rtol=1e-14)
    np.testing.assert_allclose(gamma[2, 2], 1 - p_leave, rtol=1e-14)
    # closed form: ((1 - r) pi, r), r = p_enter / (p_enter + p_leave)
    pi = model.stationary()
    r = p_enter / (p_enter + p_leave)
    expected = np.append((1 - r) * pi, r)
    np.testing.assert_allclose(rested.stationary(), expected, atol=1e-12)
    # brute force: the rows of a high power of the matrix
    np.testing.assert_allclose(np.linalg.matrix_power(gamma, 20_000)[1], expected, atol=1e-9)
    # the swimming states keep their relative shares
    swimming = rested.stationary()[:2]
    np.testing.assert_allclose(swimming / swimming.sum(), pi, atol=1e-12)
    np.testing.assert_allclose(rested.initial, np.append((1 - r) * model.initial, r))


def test_resting_share_tends_to_rate_ratio_for_slow_rates():
    rested = swimmer_model(dt=1.0).with_resting_state(0.5, 2.0, resting_step=0.05)
    assert rested.stationary()[-1] == pytest.approx(0.5 / 2.5, rel=1e-3)


def test_resting_state_distributions_and_original_unchanged():
    model = swimmer_model()
    before = model.to_dict()
    rested = model.with_resting_state(0.5, 2.0, resting_step=3.0)
    assert model.to_dict() == before
    assert rested.n_states == 3
    np.testing.assert_array_equal(rested.step.mean, [20.0, 60.0, 3.0])
    np.testing.assert_array_equal(rested.step.sd, [10.0, 15.0, 3.0])
    np.testing.assert_array_equal(rested.angle.concentration, [1.5, 12.0, 0.0])
    assert rested.step.zero_mass is None
    assert math.isnan(rested.log_likelihood) and math.isnan(rested.aic)
    assert rested.dt == model.dt and rested.step_unit == model.step_unit


def test_other_families_and_zero_inflation_keep_their_form():
    model = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=np.array([[0.8, 0.2], [0.3, 0.7]]),
        step=swimmer_model(step_cls=Gamma, zero_mass=[0.01, 0.02]).step,
        angle=WrappedCauchy(mean=np.zeros(2), concentration=np.array([0.3, 0.8])),
        dt=30.0,
    )
    rested = model.with_resting_state(1.0, 2.0, resting_step=1.5)
    np.testing.assert_array_equal(rested.step.zero_mass, [0.01, 0.02, 0.0])
    assert isinstance(rested.angle, WrappedCauchy)
    np.testing.assert_array_equal(rested.angle.concentration, [0.3, 0.8, 0.0])
    weibull = swimmer_model(step_cls=Weibull).with_resting_state(1.0, 2.0, resting_step=1.5)
    np.testing.assert_allclose(weibull.step.expected_value()[-1], 1.5, rtol=1e-6)


def test_augmented_model_round_trips_through_its_file(tmp_path):
    rested = swimmer_model().with_resting_state(0.5, 2.0, resting_step=3.0)
    path = tmp_path / "rested.json"
    rested.save(path)
    loaded = MovementHMM.load(path)
    assert loaded.to_dict() == rested.to_dict()
    np.testing.assert_array_equal(loaded.transition, rested.transition)
    np.testing.assert_array_equal(loaded.stationary(), rested.stationary())


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"enter_per_hour": -1.0, "leave_per_hour": 1.0, "resting_step": 1.0}, "enter_per_hour"),
        ({"enter_per_hour": 1.0, "leave_per_hour": 0.0, "resting_step": 1.0}, "leave_per_hour"),
        ({"enter_per_hour": 1.0, "leave_per_hour": 1.0, "resting_step": 0.0}, "resting_step"),
        ({"enter_per_hour": math.nan, "leave_per_hour": 1.0, "resting_step": 1.0}, "enter"),
    ],
)
def test_bad_rates_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        swimmer_model().with_resting_state(**kwargs)


def test_model_without_time_step_is_refused():
    with pytest.raises(ValueError, match="time step"):
        swimmer_model(dt=math.nan).with_resting_state(1.0, 1.0, 1.0)


def test_covariate_model_contributes_its_matrix_at_the_covariate_means():
    model = swimmer_model()
    covariate_model = MovementHMM(
        initial=model.initial,
        transition=None,
        step=model.step,
        angle=model.angle,
        dt=60.0,
        coefficients=np.array([[-2.0, 0.5], [-1.0, -0.3]]),
        transition_design=Design.from_dict(
            {
                "formula": "~ temperature",
                "columns": ["Intercept", "temperature"],
                "scaling": {"temperature": {"centre": 10.0, "sd": 2.0}},
            }
        ),
    )
    at_means = covariate_model.transition_matrix()
    rested = covariate_model.with_resting_state(1.0, 2.0, 3.0)
    fixed = MovementHMM(
        initial=model.initial, transition=at_means, step=model.step, angle=model.angle, dt=60.0
    ).with_resting_state(1.0, 2.0, 3.0)
    assert rested.transition_design is None and rested.coefficients is None
    np.testing.assert_allclose(rested.transition, fixed.transition, rtol=1e-14)
    np.testing.assert_allclose(
        rested.transition[:2, :2], (1 - probabilities_per_step(1.0, 60.0)) * at_means
    )


def test_transition_for_the_prediction_step_is_a_valid_root():
    rested = motion_model("hmm", resting=HMM_RESTING).model
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback: a true stochastic root
        root = transition_for_step(rested.transition, 1.0 / rested.dt)
    assert np.all(root >= 0)
    np.testing.assert_allclose(root.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(
        np.linalg.matrix_power(root, int(rested.dt)), rested.transition, atol=1e-10
    )
    np.testing.assert_allclose(rested.stationary() @ root, rested.stationary(), atol=1e-12)


def test_long_run_state_frequencies_of_simulation_equal_stationary():
    rested = swimmer_model().with_resting_state(6.0, 12.0, resting_step=3.0)
    states = rested.simulate(np.random.default_rng(3), 200_000)["state"].to_numpy()
    frequencies = np.bincount(states, minlength=3) / states.size
    np.testing.assert_allclose(frequencies, rested.stationary(), atol=0.015)


# ------------------------------------------------------------------------- in the filter


def resting_particles(n, k):
    """``n`` particles at the origin in state ``k`` with a draw due."""
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=np.zeros(n), state=k)
    p.time_since_draw = np.full(n, np.inf)
    return p


@pytest.mark.parametrize("variant", ["time_consistent", "paper"])
@pytest.mark.parametrize("compiled", [False, True])
def test_resting_particles_move_only_by_the_resting_steps(variant, compiled):
    step = 3.0
    # leaving takes ~1e5 h: every particle rests throughout the minute simulated
    rested = swimmer_model().with_resting_state(0.0, 1e-5, resting_step=step)
    motion = HMMMotion(rested, variant=variant, heading_diffusion=0.2)
    n = 4000
    p = resting_particles(n, 2)
    streams = rs.new_streams(np.random.default_rng(11), n)
    rng = np.random.default_rng(12)
    travelled = np.zeros(n)
    for _ in range(60):
        x, y = p.x.copy(), p.y.copy()
        if compiled:
            motion.advance(p, streams, 1, 1.0, p.normalised_weights(), (0.0, 0.0))
        else:
            motion.propagate(rng, p, 1.0)
        moved = np.hypot(p.x - x, p.y - y)
        assert np.all(moved <= p.speed * 1.0 + 1e-12)  # a chord of the second's arc
        travelled += p.speed
        assert np.all(p.state == 2)
    # the speeds are the resting state's steps over the fitted time step: gamma with mean
    # and sd `step` (exponential); the time-consistent variant drew them once, at t = 0
    ks = stats.kstest(p.speed * rested.dt, stats.expon(scale=step).cdf)
    assert ks.pvalue > 1e-3
    assert np.hypot(p.x, p.y).max() <= travelled.max() + 1e-9
    if variant == "time_consistent":
        np.testing.assert_allclose(travelled, p.speed * 60.0, rtol=1e-12)  # held


def test_particle_state_frequencies_in_the_compiled_filter_equal_stationary():
    rested = swimmer_model().with_resting_state(6.0, 12.0, resting_step=3.0)
    motion = HMMMotion(rested, variant="time_consistent")
    n = 8000
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=np.zeros(n))
    motion.initialise(np.random.default_rng(5), p)
    streams = rs.new_streams(np.random.default_rng(6), n)
    motion.advance(p, streams, 1800, 1.0, p.normalised_weights(), (0.0, 0.0))
    frequencies = np.bincount(p.state, minlength=3) / n
    np.testing.assert_allclose(frequencies, rested.stationary(), atol=0.02)


# ------------------------------------------------------------------------- tracking default


def test_tracking_default_adds_the_resting_state_to_the_time_consistent_hmm():
    bundled = MovementHMM.load(bundled_model_path())
    default = motion_model("hmm")
    resting = HMM_RESTING
    metres = resting.drift_speed * bundled.dt
    expected = bundled.with_resting_state(
        resting.enter_per_hour, resting.leave_per_hour, resting_step=metres
    )
    assert default.model.to_dict() == expected.to_dict()
    assert motion_model("hmm", resting=None).model.to_dict() == bundled.to_dict()
    assert motion_model("hmm", variant="paper").model.n_states == bundled.n_states


def test_tracking_resting_state_converts_kilometre_steps():
    model = swimmer_model()
    in_km = MovementHMM.from_dict(
        model.to_dict()
        | {
            "units": {"step": "km", "angle": "rad", "dt": "s"},
            "step": Gamma.from_moments([0.02, 0.06], [0.01, 0.015]).to_dict(),
        }
    )
    rates = RestingState(enter_per_hour=1.0, leave_per_hour=2.0, drift_speed=0.05)
    motion = motion_model("hmm", in_km, resting=rates)
    assert motion.model.step.mean[-1] == pytest.approx(0.05 * 60.0 / 1000.0)


def test_resting_state_is_refused_for_other_motions():
    with pytest.raises(ValueError, match="hmm"):
        motion_model("velocity", resting=HMM_RESTING)


@pytest.mark.parametrize(
    "name, bounds",
    [("stationary_tag", (0.8, 1.0)), ("swimmer", (0.0, 0.05))],
)
def test_filter_posterior_rests_on_a_fixed_tag_and_swims_on_a_moving_one(name, bounds):
    """Posterior weight of the resting state at the end of a run with tracking's default
    HMM (measured: 0.97 on the moored tag, 0.0015 on the swimmer; 0.20 under the prior)."""
    scenario = paper_scenarios(0, [name])[name]
    config = tracking_config(scenario, n_particles=2000, shallower="clip", motion="hmm")
    run = tracking.track(
        scenario.detections, scenario.receivers, config, seed=1, snapshot_times=[scenario.end]
    )
    cloud = run.snapshots[scenario.end]
    resting = cloud.loc[cloud["state"] == 2, "weight"].sum() / cloud["weight"].sum()
    assert bounds[0] <= resting <= bounds[1]


# ------------------------------------------------------------------------- a tag that holds still


def rested_bundled(resting):
    """The bundled model with ``resting``, as tracking adds it."""
    bundled = MovementHMM.load(bundled_model_path())
    metres = resting.drift_speed * bundled.dt
    return bundled.with_resting_state(
        resting.enter_per_hour, resting.leave_per_hour, resting_step=metres
    )


def test_trials_hold_the_resting_tag_still_under_the_gps_measurement_only():
    gps = _motion("hmm", "range-rate-gps")
    assert gps.model.to_dict() == rested_bundled(HMM_STILL_RESTING).to_dict()
    assert gps.variant == "time_consistent"
    assert _motion("hmm", "range-rate").model.to_dict() == motion_model("hmm").model.to_dict()
    assert _motion("hmm").model.to_dict() == rested_bundled(HMM_RESTING).to_dict()
    assert _motion("velocity", "range-rate") == motion_model("velocity")
    assert (HMM_STILL_RESTING.enter_per_hour, HMM_STILL_RESTING.leave_per_hour) == (
        HMM_RESTING.enter_per_hour,
        HMM_RESTING.leave_per_hour,
    )


def resting_cloud_after(resting, seconds, n=4000):
    """Positions (2, n) and held speeds (n,) of ``n`` particles resting at the origin after
    ``seconds`` (at most the fitted step) of the compiled time-consistent HMM with
    ``resting``, from fixed streams."""
    still = RestingState(0.0, 1e-5, resting.drift_speed)  # nobody leaves within the test
    model = rested_bundled(still)
    motion = HMMMotion(model, variant="time_consistent", heading_diffusion=0.2)
    p = resting_particles(n, model.n_states - 1)
    streams = rs.new_streams(np.random.default_rng(21), n)
    motion.advance(p, streams, int(seconds), 1.0, p.normalised_weights(), (0.0, 0.0))
    assert np.all(p.state == model.n_states - 1)
    return np.stack([p.x, p.y]), p.speed


@pytest.mark.parametrize("seconds", [8, 60])
def test_a_still_resting_cloud_stops_widening(seconds):
    """A resting particle's speed is held over the fitted step (exponential, mean the
    drift), so its distance from where it rested is at most speed x time, and the cloud's
    mean squared spread at most E[speed^2] t^2 = 2 drift^2 t^2: under the still resting
    state 0.02 m over a ping interval and 0.17 m over a minute, against the gps
    measurement's white sd of 1 m. The default's drift spreads 25 times as far, from the
    same draws (the steps scale with the drift)."""
    still, speed = resting_cloud_after(HMM_STILL_RESTING, seconds)
    default, _ = resting_cloud_after(HMM_RESTING, seconds)
    distance = np.hypot(*still)
    assert np.all(distance <= speed * seconds + 1e-12)
    bound = math.sqrt(2.0) * HMM_STILL_RESTING.drift_speed * seconds
    spread = math.sqrt(np.mean(distance**2))
    # 4,000 exponential speeds: E[speed^2] within 7 % (one sd), so the root within 4 %
    assert 0.25 * bound <= spread <= 1.15 * bound  # it drifts (turning), slowly
    ratio = HMM_STILL_RESTING.drift_speed / HMM_RESTING.drift_speed
    np.testing.assert_allclose(still, ratio * default, rtol=1e-9, atol=1e-12)
