"""The velocity model's turn rate that reverts to zero (``VelocityMotion(turn_reversion=tau)``,
an Ornstein-Uhlenbeck process): its exact transition in the compiled kernel and the NumPy
reference, the walk's draws kept, and its settings (``VelocitySettings``, the command line)."""

import math

import numpy as np
import pytest

from hmmtrack.cli import build_parser
from hmmtrack.cli.track import build_config
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.motion import VelocityMotion, motion_model
from hmmtrack.tracking.motion.regimes import Regime, VelocityRegimes
from hmmtrack.tracking.motion.settings import VelocitySettings
from hmmtrack.tracking.particles import Particles


def still_cloud(n, turn_rate):
    """``n`` particles at the origin at speed 0 (so only the turn rate moves) with
    ``turn_rate`` rad/s."""
    return Particles.from_state(np.zeros(n), np.zeros(n), np.zeros(n), turn_rate=turn_rate)


def steps(motion, p, n_steps, dt, path, seed=11):
    """``n_steps`` steps of ``dt`` s by the NumPy or the compiled path; the streams after."""
    if path == "numpy":
        rng = np.random.default_rng(seed)
        for _ in range(n_steps):
            motion.propagate(rng, p, dt)
        return None
    streams = rs.new_streams(np.random.default_rng(seed), p.n)
    motion.advance(p, streams, n_steps, dt, p.normalised_weights(), (0.0, 0.0))
    return streams


@pytest.mark.parametrize(
    ("path", "dt", "n_steps"), [("numpy", 1.0, 30), ("compiled", 1.0, 30), ("compiled", 4.0, 8)]
)
def test_the_turn_rate_has_the_exact_ou_law_whatever_the_step(path, dt, n_steps):
    """From omega_0 = 0.1 rad/s, after t = 30 or 32 s of steps of 1 or 4 s (tau 10 s, sigma
    0.02): mean omega_0 exp(-t/tau) and variance sigma^2 tau (1 - exp(-2t/tau)) / 2, within
    4 standard errors; the transition is exact, so the step does not matter."""
    n, omega0, sigma, tau = 40_000, 0.1, 0.02, 10.0
    motion = VelocityMotion(0.0, sigma, turn_reversion=tau)
    p = still_cloud(n, omega0)
    steps(motion, p, n_steps, dt, path)
    t = n_steps * dt
    mean = omega0 * math.exp(-t / tau)
    variance = sigma**2 * tau * -math.expm1(-2 * t / tau) / 2
    w = p.turn_rate
    assert abs(w.mean() - mean) < 4 * math.sqrt(variance / n)
    assert abs(w.var() - variance) < 4 * variance * math.sqrt(2 / (n - 1))
    # the walk from the same start: mean omega_0, variance sigma^2 t (3 times as wide here)
    walk = still_cloud(n, omega0)
    steps(VelocityMotion(0.0, sigma), walk, n_steps, dt, path)
    assert abs(walk.turn_rate.var() - sigma**2 * t) < 4 * sigma**2 * t * math.sqrt(2 / (n - 1))


def test_the_stationary_spread_is_sigma_root_half_tau():
    """Long after the start (20 tau) the turn rate's spread is sigma sqrt(tau / 2), the
    same from rest and from 0.5 rad/s."""
    n, sigma, tau = 40_000, 0.03, 5.0
    motion = VelocityMotion(0.0, sigma, turn_reversion=tau)
    for omega0 in (0.0, 0.5):
        p = still_cloud(n, omega0)
        steps(motion, p, 100, 1.0, "compiled")
        sd = sigma * math.sqrt(tau / 2)
        assert abs(p.turn_rate.mean()) < 4 * sd / math.sqrt(n)
        assert p.turn_rate.std() == pytest.approx(sd, rel=4 * math.sqrt(1 / (2 * n)))


def test_turn_step_is_the_walks_without_reversion_and_its_limit():
    """No reversion: decay exactly 1 and scale sigma sqrt(dt) (the walk's draws, bit for
    bit); a long reversion time tends to it, a short one to the stationary spread."""
    walk = VelocityMotion(0.1, 0.02)
    assert walk.turn_step(4.0) == (1.0, 0.02 * np.sqrt(4.0))
    decay, scale = VelocityMotion(0.1, 0.02, turn_reversion=1e9).turn_step(4.0)
    assert decay == pytest.approx(1.0, abs=1e-8)
    assert scale == pytest.approx(0.04, rel=1e-8)
    decay, scale = VelocityMotion(0.1, 0.02, turn_reversion=0.01).turn_step(4.0)
    assert decay < 1e-100
    assert scale == pytest.approx(0.02 * math.sqrt(0.01 / 2), rel=1e-12)


def test_without_reversion_the_numpy_step_is_the_walk_bit_for_bit():
    """``turn_reversion=None`` adds ``sigma sqrt(dt) z`` to the turn rate exactly as the
    walk did, and the positions follow."""
    n, dt = 1000, 2.0
    motion = VelocityMotion(0.1, 0.02)
    p = Particles.from_state(np.zeros(n), np.zeros(n), np.zeros(n), speed=1.0, turn_rate=0.01)
    normals = np.random.default_rng(2).standard_normal((2, n))
    motion.apply(p, dt, normals)
    np.testing.assert_array_equal(p.turn_rate, 0.01 + 0.02 * np.sqrt(dt) * normals[1])
    np.testing.assert_array_equal(p.speed, 1.0 + 0.1 * np.sqrt(dt) * normals[0])


def test_reversion_draws_what_the_walk_draws():
    """The same streams and normals as the walk: after the same steps the streams are equal,
    the speeds equal bit for bit, and the turn rates are the walk's normals under the OU
    transition (tau = 1e9 s: within 1e-6 of the walk's, whose relative difference is t / tau)."""
    n = 5000
    runs = {}
    for tau in (None, 1e9, 20.0):
        p = Particles.from_state(np.zeros(n), np.zeros(n), np.zeros(n), speed=1.0)
        streams = steps(VelocityMotion(0.1, 0.02, turn_reversion=tau), p, 50, 1.0, "compiled")
        runs[tau] = (p, streams)
    walk, walk_streams = runs[None]
    for tau in (1e9, 20.0):
        p, streams = runs[tau]
        np.testing.assert_array_equal(streams, walk_streams)
        np.testing.assert_array_equal(p.speed, walk.speed)
    np.testing.assert_allclose(runs[1e9][0].turn_rate, walk.turn_rate, rtol=0, atol=1e-6)
    assert np.abs(runs[20.0][0].turn_rate - walk.turn_rate).max() > 0.01


@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, np.inf])
def test_the_reversion_time_must_be_a_positive_number(value):
    with pytest.raises(ValueError, match="turn_reversion"):
        VelocityMotion(0.1, 0.02, turn_reversion=value)


def test_no_default_path_reverts():
    """The paper's walk everywhere by default."""
    for motion in (motion_model("velocity"), VelocitySettings().build()):
        assert motion.turn_reversion is None


def test_the_reversion_is_given_in_a_configuration_or_on_the_command_line():
    config = TrackingConfig.from_dict(
        {
            "measurement": {"name": "range-rate-gps", "period": 8.0},
            "motion": {"name": "velocity", "turn_reversion": 10.0},
        }
    )
    # range-rate-gps's velocity model (VELOCITY_GPS) has a still regime, so the reversion
    # is its moving regime's
    still = Regime(0.005, 0.005, speed_reversion=0.5, turn_reversion=2.0)
    moving = Regime(0.05, 0.02, turn_reversion=10.0)
    regimes = VelocityRegimes((moving, still), ((0.0, 1 / 7200), (1 / 1800, 0.0)))
    assert config.motion_model() == VelocityMotion(
        0.05, 0.02, jump_rate=1 / 60, jump_sd=0.4, regimes=regimes
    )
    assert TrackingConfig.from_dict(config.to_dict()) == config
    parser = build_parser()
    args = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    args += ["--period", "8", "--r0", "a=1", "--motion", "velocity"]
    given = build_config(parser.parse_args([*args, "--turn-reversion", "5"]))
    assert given.motion_model() == VelocityMotion(0.1, 0.02, turn_reversion=5.0)
    assert build_config(parser.parse_args(args)).motion_model().turn_reversion is None
    with pytest.raises(ValueError, match="turn_reversion"):
        VelocitySettings(turn_reversion=0.0)
