"""The HMM motion's log-speed random walk (``HMMMotion(speed_diffusion=...)``) and the rule
that gives it, with the still resting state, to the ``range-rate-gps`` measurement
(``config.MEASUREMENT_MOTIONS``, ``TrackingConfig.motion_model``, ``trials._motion``)."""

import math

import numpy as np
import pytest
from numba import njit
from scipy import stats

from hmmtrack.cli import build_parser
from hmmtrack.cli.track import build_config
from hmmtrack.experiments.trials import _motion
from hmmtrack.hmm import Gamma, MovementHMM, VonMises
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.config import MEASUREMENT_MOTIONS, TrackingConfig, measurement_motion
from hmmtrack.tracking.motion import (
    HMM_GPS_SPEED_DIFFUSION,
    HMM_RESTING,
    HMM_STILL_RESTING,
    HMMMotion,
    RestingState,
    motion_model,
)
from hmmtrack.tracking.motion.hmm import _speed_walk
from hmmtrack.tracking.motion.settings import HMMSettings, VelocitySettings
from hmmtrack.tracking.particles import Particles

#: a fitted step far longer than the tests' horizons: nobody redraws its held speed
LONG_STEP = 10_000.0


def straight_model(resting=None):
    """Two swimming states that practically never switch (1e-9 per fitted step), with
    speeds 0.5 and 1.5 m/s held exactly (step sd 1e-9 of a fitted step of
    :data:`LONG_STEP` s) and straight arcs; with
    ``resting``, a third (resting) state that is never entered or left within a test."""
    model = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=np.array([[1.0 - 1e-9, 1e-9], [1e-9, 1.0 - 1e-9]]),
        step=Gamma(mean=np.array([0.5, 1.5]) * LONG_STEP, sd=np.array([1e-9, 1e-9]) * LONG_STEP),
        angle=VonMises(mean=np.zeros(2), concentration=np.array([1e12, 1e12])),
        dt=LONG_STEP,
    )
    if resting is None:
        return model
    return model.with_resting_state(0.0, 1e-9, resting_step=resting * LONG_STEP)


def held_cloud(motion, n, seed=3, resting_share=0.0):
    """``n`` particles at the origin with the model's states and speeds, their draw clocks
    at 0 (no draw within :data:`LONG_STEP` s); the last ``resting_share`` of them put in the
    last (resting) state with speed 0.01 m/s."""
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=np.zeros(n))
    motion.initialise(np.random.default_rng(seed), p)
    p.time_since_draw[:] = 0.0
    resting = int(resting_share * n)
    if resting:
        p.state[n - resting :] = motion.model.n_states - 1
        p.speed[n - resting :] = 0.01
    return p


def run(motion, p, horizon, dt, path, seed=8):
    """``horizon`` s of prediction steps of ``dt`` s, by the NumPy or the compiled path."""
    steps = int(round(horizon / dt))
    if path == "numpy":
        rng = np.random.default_rng(seed)
        for _ in range(steps):
            motion.propagate(rng, p, dt)
    else:
        streams = rs.new_streams(np.random.default_rng(seed), p.n)
        motion.advance(p, streams, steps, dt, p.normalised_weights(), (0.0, 0.0))


# ------------------------------------------------------------------------- the random walk


@pytest.mark.parametrize(("path", "dt"), [("numpy", 1.0), ("compiled", 1.0), ("compiled", 4.0)])
def test_log_speed_is_a_random_walk_of_variance_sigma_squared_t(path, dt):
    """Held speeds, no switching: after T s, log v - log v0 is N(0, sigma^2 T) whatever
    the prediction step and the path (the compiled kernel and the NumPy reference agree in
    law); resting particles keep their speed exactly."""
    sigma, horizon, n = 0.05, 120.0, 20_000
    motion = HMMMotion(straight_model(resting=0.01), speed_diffusion=(sigma, sigma, 0.0))
    p = held_cloud(motion, n, resting_share=0.25)
    start = p.speed.copy()
    swimming = p.state < 2
    run(motion, p, horizon, dt, path)
    np.testing.assert_array_equal(p.speed[~swimming], start[~swimming])  # resting: held
    walk = np.log(p.speed[swimming] / start[swimming])
    m = walk.size
    variance = sigma**2 * horizon  # 0.3
    # mean 0 within 4 standard errors; the sample variance within 4 of its (2 var^2 / m)^0.5
    assert abs(walk.mean()) < 4.0 * math.sqrt(variance / m)
    assert abs(walk.var() - variance) < 4.0 * variance * math.sqrt(2.0 / m)
    assert stats.kstest(walk / math.sqrt(variance), "norm").pvalue > 1e-3
    # the walk moves the speed, never the path's shape: straight lines of the length travelled
    assert np.all(np.abs(p.y) < 1e-6 * (1.0 + np.abs(p.x)))


def test_speed_walk_parts_the_copies_of_one_particle():
    """Copies of one particle (as resampling makes them) hold one speed without the walk,
    and as many speeds as copies with it."""
    n = 1000
    for sigma, distinct in ((0.0, 1), (0.03, n)):
        motion = HMMMotion(straight_model(), speed_diffusion=sigma)
        p = held_cloud(motion, n)
        p.speed[:], p.state[:] = 1.0, 1
        run(motion, p, 10.0, 1.0, "compiled")
        assert np.unique(p.speed).size == distinct


@njit
def _scalar_sub_steps(streams, v, scale, n_sub, heading):
    """Per sub-step and particle, as the kernel's passes draw them: with ``heading``, the
    heading's normal and the chain's uniform (one pass before the arc), then the walk's
    normal (if ``scale``); without, the walk's normal, then the chain's uniform."""
    for i in range(streams.size):
        s = streams[i]
        for _ in range(n_sub):
            if heading:
                _, s = rs.normal(s)
                _, s = rs.uniform(s)
            if scale > 0.0:
                z, s = rs.normal(s)
                v[i] *= math.exp(scale * z)
            if not heading:
                _, s = rs.uniform(s)
        streams[i] = s


@pytest.mark.parametrize("heading", [0.0, 0.2])
@pytest.mark.parametrize("sigma", [0.0, 0.04])
def test_the_kernel_draws_the_walk_after_the_chain_and_nothing_without_it(sigma, heading):
    """Without due draws a compiled sub-step takes the walk's normal from each particle's
    stream right after the arc (after the heading's normal and the chain's uniform, which
    the heading diffusion draws before it; before the chain's uniform without it), and at
    sigma = 0 exactly the draws of the kernel without a walk (no normal): the random
    streams of every seeded run without it are unchanged."""
    n, steps = 3000, 5
    motion = HMMMotion(straight_model(), heading_diffusion=heading, speed_diffusion=sigma)
    p = held_cloud(motion, n)
    streams = rs.new_streams(np.random.default_rng(2), n)
    expected_streams, expected_speed = streams.copy(), p.speed.copy()
    _scalar_sub_steps(expected_streams, expected_speed, sigma, steps, heading > 0.0)
    motion.advance(p, streams, steps, 1.0, p.normalised_weights(), (0.0, 0.0))
    np.testing.assert_array_equal(streams, expected_streams)
    np.testing.assert_allclose(p.speed, expected_speed, rtol=1e-14)


def test_speed_walk_pass_takes_the_scalar_samplers_normals():
    """The walk's pass (a branch-free ziggurat try, scalar retries) multiplies each speed by
    exp(scale of its state x the normal :func:`streams.normal` draws), rejected tries
    included; a state of scale 0 draws and keeps its speed."""
    n = 20_000
    rng = np.random.default_rng(4)
    streams = rs.new_streams(rng, n)
    v = rng.uniform(0.5, 2.0, n)
    state = rng.integers(0, 3, n)
    scale = np.array([0.1, 0.3, 0.0])
    expected_streams, z = streams.copy(), np.empty(n)
    for i in range(n):
        z[i], expected_streams[i] = rs.normal(expected_streams[i])
    expected = v * np.exp(scale[state] * z)
    retry = np.zeros(n, dtype=bool)
    _speed_walk(v, state, streams, scale, np.empty(n), retry)
    assert 0 < retry.sum() < n // 20  # some rejected tries took the scalar path
    np.testing.assert_array_equal(streams, expected_streams)
    np.testing.assert_allclose(v, expected, rtol=1e-14)  # (the kernel's exp: last bit)


def test_speed_diffusion_is_checked():
    model = straight_model()
    assert HMMMotion(model, speed_diffusion=[0.1, 0.0]).speed_diffusion == (0.1, 0.0)
    for bad in (-0.1, float("nan"), (0.1, 0.1, 0.1), ((0.1,), (0.1,))):
        with pytest.raises(ValueError, match="speed_diffusion"):
            HMMMotion(model, speed_diffusion=bad)
    with pytest.raises(ValueError, match="hmm' only"):
        motion_model("velocity", speed_diffusion=0.1)


def test_the_registry_leaves_the_resting_state_out_of_the_walk():
    assert motion_model("hmm").speed_diffusion == 0.0
    assert motion_model("hmm", speed_diffusion=0.02).speed_diffusion == (0.02, 0.02, 0.0)
    assert motion_model("hmm", resting=None, speed_diffusion=0.02).speed_diffusion == 0.02


# ------------------------------------------------------------------------- the measurement's rule


def gps_config(**motion):
    """A range-rate-gps configuration with the ``motion`` section's keys."""
    return TrackingConfig.from_dict(
        {
            "measurement": {"name": "range-rate-gps", "period": 8.0},
            "motion": {"name": "hmm", **motion},
        }
    )


def test_the_gps_measurement_gives_the_hmm_a_still_resting_tag_and_the_speed_walk():
    motion = gps_config().motion_model()
    still = motion_model("hmm", resting=HMM_STILL_RESTING)
    assert motion.model.to_dict() == still.model.to_dict()
    sigma = HMM_GPS_SPEED_DIFFUSION
    assert motion.speed_diffusion == (sigma, sigma, 0.0)
    assert (motion.variant, motion.heading_diffusion) == (still.variant, still.heading_diffusion)
    # the reproduction asks the same rule
    trial = _motion("hmm", "range-rate-gps")
    assert trial.model.to_dict() == motion.model.to_dict()
    assert trial.speed_diffusion == motion.speed_diffusion
    assert MEASUREMENT_MOTIONS["range-rate-gps"]["hmm"] == {
        "resting_drift": HMM_STILL_RESTING.drift_speed,
        "speed_diffusion": sigma,
    }


def test_other_measurements_and_models_keep_their_defaults():
    config = TrackingConfig.from_dict({"measurement": {"period": 8.0}})
    default = motion_model("hmm")
    for motion in (config.motion_model(), _motion("hmm", "range-rate"), _motion("hmm")):
        assert motion.model.to_dict() == default.model.to_dict()
        assert motion.speed_diffusion == 0.0
    assert _motion("velocity", "range-rate") == motion_model("velocity")
    assert measurement_motion(VelocitySettings(), "range-rate") == motion_model("velocity")


def test_a_setting_given_explicitly_wins_over_the_measurements():
    motion = gps_config(speed_diffusion=0.0, resting_drift=HMM_RESTING.drift_speed).motion_model()
    assert motion.model.to_dict() == motion_model("hmm").model.to_dict()
    assert motion.speed_diffusion == 0.0
    assert gps_config(speed_diffusion=0.01).motion_model().speed_diffusion == (0.01, 0.01, 0.0)
    plain = gps_config(resting=False).motion_model()
    assert plain.model.n_states == 2 and plain.speed_diffusion == HMM_GPS_SPEED_DIFFUSION
    drift = RestingState(HMM_RESTING.enter_per_hour, HMM_RESTING.leave_per_hour, 0.01)
    settings = HMMSettings(resting_drift=0.01)
    assert settings.build().model.to_dict() == motion_model("hmm", resting=drift).model.to_dict()
    # the range-rate measurement's settings carry over as given
    changed = TrackingConfig.from_dict({"measurement": {"period": 8.0}}).override(
        measurement="range-rate-gps"
    )
    assert changed.motion_model().speed_diffusion == (
        HMM_GPS_SPEED_DIFFUSION,
        HMM_GPS_SPEED_DIFFUSION,
        0.0,
    )


def test_the_command_line_gets_the_measurements_motion_settings():
    """``hmmtrack track --measurement range-rate-gps`` builds the HMM with the rule's
    settings, its options override them, and the help says so."""
    parser = build_parser()
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    fix = ["--period", "8", "--r0", "a=1"]
    gps = [*base, *fix, "--measurement", "range-rate-gps", "--motion", "hmm"]
    sigma = HMM_GPS_SPEED_DIFFUSION
    built = build_config(parser.parse_args(gps)).motion_model()
    assert built.speed_diffusion == (sigma, sigma, 0.0)
    assert built.model.to_dict() == motion_model("hmm", resting=HMM_STILL_RESTING).model.to_dict()
    given = build_config(parser.parse_args([*gps, "--speed-diffusion", "0"])).motion_model()
    assert given.speed_diffusion == 0.0
    plain = build_config(parser.parse_args([*base, *fix])).motion_model()
    assert plain.speed_diffusion == 0.0
    track = next(a for a in parser._actions if a.dest == "command").choices["track"]
    helps = {a.dest: a.help for a in track._actions}
    assert f"{sigma:g} for range-rate-gps, else 0" in helps["speed_diffusion"]
    assert f"{HMM_STILL_RESTING.drift_speed:g} for range-rate-gps" in helps["resting_drift"]
