"""The velocity model under the ``range-rate-gps`` measurement (``motion.VELOCITY_GPS``,
``config.MEASUREMENT_MOTIONS``, ``VelocitySettings``): how far its cloud carries a heading,
against the exact expectation of the turn-rate walk, and the rule that gives it."""

import numpy as np
import pytest

from hmmtrack.cli import build_parser
from hmmtrack.cli.track import build_config
from hmmtrack.experiments.trials import _motion
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.config import MEASUREMENT_MOTIONS, TrackingConfig, measurement_motion
from hmmtrack.tracking.motion import (
    VELOCITY_GPS,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
    VelocityMotion,
    motion_model,
)
from hmmtrack.tracking.motion.settings import VelocitySettings
from hmmtrack.tracking.particles import Particles

PAPER = VelocityMotion(VELOCITY_SIGMA_SPEED, VELOCITY_SIGMA_TURN_RATE)


def expected_reach(sigma_turn_rate, speed, steps):
    """The exact expected displacement (m) along the initial heading after ``steps`` 1-s
    steps of a particle that starts at ``speed`` with turn rate 0.

    Step ``k`` (1..n) moves along the arc of turn rate ``w_k = sigma W_k`` (``W_k`` the sum
    of ``k`` standard normals) from heading ``h_{k-1} = sigma (W_1 + ... + W_{k-1})``, at a
    speed of mean ``speed`` independent of the headings (the speed's walk and jumps have mean
    0). At the arc's fraction ``s`` the heading is Gaussian with mean 0 and variance
    ``sigma^2 (A_k + 2 s B_k + s^2 k)``, ``A_k = sum_{i,l<k} min(i, l)``,
    ``B_k = sum_{i<k} i``, and ``E cos = exp(-variance / 2)``; the arc's integral over ``s``
    is taken by Gauss-Legendre quadrature."""
    nodes, weights = np.polynomial.legendre.leggauss(16)
    s, ws = (nodes + 1) / 2, weights / 2
    i = np.arange(1, steps + 1)
    reach = 0.0
    for k in range(1, steps + 1):
        before = i[: k - 1]
        a = float(np.minimum.outer(before, before).sum())
        b = float(before.sum())
        variance = sigma_turn_rate**2 * (a + 2 * s * b + s**2 * k)
        reach += speed * float(ws @ np.exp(-variance / 2))
    return reach


@pytest.mark.parametrize("motion", [PAPER, VELOCITY_GPS], ids=["paper", "gps"])
@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_the_clouds_reach_along_its_heading_is_the_turn_rate_walks(motion, path):
    """Particles that start together at 1.5 m/s, heading east, with turn rate 0: their mean
    position after 160 s (the shark pursuit's silences) is the exact expectation within
    4 SE, and north of it by 0 within 4 SE."""
    n, steps, speed = 20_000, 160, 1.5
    p = Particles.from_state(np.zeros(n), np.zeros(n), np.zeros(n), speed=speed)
    if path == "numpy":
        rng = np.random.default_rng(5)
        for _ in range(steps):
            motion.propagate(rng, p, 1.0)
    else:
        streams = rs.new_streams(np.random.default_rng(5), n)
        motion.advance(p, streams, steps, 1.0, p.normalised_weights(), (0.0, 0.0))
    exact = expected_reach(motion.sigma_turn_rate, speed, steps)
    for got, want in ((p.x, exact), (p.y, 0.0)):
        assert abs(got.mean() - want) < 4 * got.std() / np.sqrt(n)


def test_the_paper_models_cloud_circles_and_the_gps_models_carries_on():
    """Why the rule (reports/decisions.md, "The velocity model's circling cloud"): within
    the 160 s of a silent receiver the paper's turn-rate walk carries a 1.5 m/s particle
    about 30 m along its heading, 1/8 of its path; :data:`VELOCITY_GPS`'s about 50 m."""
    path = 1.5 * 160
    paper = expected_reach(PAPER.sigma_turn_rate, 1.5, 160)
    gps = expected_reach(VELOCITY_GPS.sigma_turn_rate, 1.5, 160)
    assert 0.1 * path < paper < 0.15 * path
    assert 1.5 * paper < gps < 0.25 * path
    # the walk's continuous-time limit: v * Gamma(4/3) * (6 / sigma^2)^(1/3) as T -> inf
    limit = 1.5 * 0.8930 * (6 / PAPER.sigma_turn_rate**2) ** (1 / 3)
    assert paper == pytest.approx(limit, rel=0.05)


def gps_config(**motion):
    """A range-rate-gps configuration with the velocity model and the ``motion`` keys."""
    return TrackingConfig.from_dict(
        {
            "measurement": {"name": "range-rate-gps", "period": 8.0},
            "motion": {"name": "velocity", **motion},
        }
    )


def test_the_gps_measurement_gives_the_velocity_model_its_settings():
    assert gps_config().motion_model() == VELOCITY_GPS
    assert _motion("velocity", "range-rate-gps") == VELOCITY_GPS
    assert measurement_motion(VelocitySettings(), "range-rate-gps") == VELOCITY_GPS
    assert MEASUREMENT_MOTIONS["range-rate-gps"]["velocity"] == {
        "sigma_speed": 0.03,
        "sigma_turn_rate": 0.01,
        "jump_rate": 1 / 60,
        "jump_sd": 0.4,
    }
    assert VELOCITY_GPS == VelocityMotion(0.03, 0.01, 1 / 60, 0.4)


def test_other_measurements_keep_the_papers_velocity_model():
    config = TrackingConfig.from_dict(
        {"measurement": {"period": 8.0}, "motion": {"name": "velocity"}}
    )
    for motion in (
        config.motion_model(),
        _motion("velocity", "range-rate"),
        _motion("velocity"),
        VelocitySettings().build(),
        motion_model("velocity"),
    ):
        assert motion == PAPER


def test_a_velocity_setting_given_explicitly_wins_over_the_measurements():
    given = gps_config(sigma_turn_rate=0.02, jump_rate=0.0).motion_model()
    assert given == VelocityMotion(0.03, 0.02, 0.0, 0.4)
    assert TrackingConfig.from_dict(gps_config(sigma_speed=0.1).to_dict()).motion_model() == (
        VelocityMotion(0.1, 0.01, 1 / 60, 0.4)
    )
    assert VelocitySettings(sigma_turn_rate=0.005).build() == VelocityMotion(0.1, 0.005)
    with pytest.raises(ValueError, match="sigma_turn_rate must be a non-negative"):
        VelocitySettings(sigma_turn_rate=-1.0)


def test_the_command_line_gets_the_velocity_models_gps_settings():
    parser = build_parser()
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    fix = ["--period", "8", "--r0", "a=1", "--motion", "velocity"]
    gps = [*base, *fix, "--measurement", "range-rate-gps"]
    assert build_config(parser.parse_args(gps)).motion_model() == VELOCITY_GPS
    turned = build_config(parser.parse_args([*gps, "--sigma-turn-rate", "0.02"])).motion_model()
    assert turned == VelocityMotion(0.03, 0.02, 1 / 60, 0.4)
    assert build_config(parser.parse_args([*base, *fix])).motion_model() == PAPER
    track = next(a for a in parser._actions if a.dest == "command").choices["track"]
    helps = {a.dest: a.help for a in track._actions}
    assert "0.01 for range-rate-gps, else 0.02" in helps["sigma_turn_rate"]
    assert "0.03 for range-rate-gps, else 0.1" in helps["sigma_speed"]
