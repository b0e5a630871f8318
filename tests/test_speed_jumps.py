"""The velocity model's speed jumps (``VelocityMotion(jump_rate=..., jump_sd=...)``): a
compound Poisson process in the speed beside its random walk, in the compiled kernel and
the NumPy reference; and its settings (``VelocitySettings``, the command line)."""

import math

import numpy as np
import pytest
from numba import njit
from scipy import stats
from test_speed_diffusion import run  # horizon of steps by the NumPy or the compiled path

from hmmtrack.cli import build_parser
from hmmtrack.cli.track import build_config
from hmmtrack.experiments.trials import _motion
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.motion import VelocityMotion, motion_model
from hmmtrack.tracking.motion.settings import VelocitySettings
from hmmtrack.tracking.motion.velocity import _jump_count, _speed_jumps
from hmmtrack.tracking.particles import Particles


def cloud(n, speed=1.0):
    """``n`` particles at the origin heading east at ``speed`` m/s."""
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=np.zeros(n))
    p.speed = np.full(n, speed)
    return p


def compound_poisson_cdf(x, mean, sd):
    """CDF at ``x`` of the sum of ``K ~ Poisson(mean)`` jumps ``N(0, sd^2)`` given ``K >= 1``
    (the law of a speed change that is not zero, with no random walk)."""
    ks = np.arange(1, 60)
    pmf = stats.poisson.pmf(ks, mean)
    cdf = stats.norm.cdf(np.asarray(x)[:, None] / (sd * np.sqrt(ks)))
    return (cdf * pmf).sum(axis=1) / -math.expm1(-mean)


@pytest.mark.parametrize(("path", "dt"), [("numpy", 1.0), ("compiled", 1.0), ("compiled", 4.0)])
def test_speed_changes_are_the_compound_poisson_process(path, dt):
    """Jumps only (no random walk): after T s the share of particles whose speed moved is
    1 - exp(-rate T), and the moves follow the sum of Poisson(rate T) jumps N(0, sd^2), given
    at least one, whatever the prediction step and the path (the compiled kernel and the
    NumPy reference agree in law). The jumps move the speed only: paths stay straight."""
    rate, sd, horizon, n = 1 / 30, 0.3, 60.0, 40_000
    mean = rate * horizon  # 2 jumps expected
    motion = VelocityMotion(0.0, 0.0, jump_rate=rate, jump_sd=sd)
    p = cloud(n)
    run(motion, p, horizon, dt, path)
    change = p.speed - 1.0
    moved = change != 0.0
    share = -math.expm1(-mean)
    assert abs(moved.mean() - share) < 4.0 * math.sqrt(share * (1 - share) / n)
    assert stats.kstest(change[moved], lambda x: compound_poisson_cdf(x, mean, sd)).pvalue > 1e-3
    # E[change^2] = mean sd^2 within 4 standard errors (E[change^4] = 3 sd^4 (mean + mean^2))
    second, fourth = mean * sd**2, 3 * sd**4 * (mean + mean**2)
    assert abs(np.mean(change**2) - second) < 4.0 * math.sqrt((fourth - second**2) / n)
    assert np.all(p.y == 0.0) and np.all(p.turn_rate == 0.0)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_jumps_add_to_the_random_walk(path):
    """With a random walk of sigma and jumps, the speed's variance after T s is
    (sigma^2 + rate sd^2) T: the two are independent."""
    sigma, rate, sd, horizon, n = 0.03, 1 / 60, 0.3, 120.0, 40_000
    p = cloud(n)
    run(VelocityMotion(sigma, 0.0, jump_rate=rate, jump_sd=sd), p, horizon, 1.0, path)
    variance = (sigma**2 + rate * sd**2) * horizon
    assert abs(np.mean(p.speed) - 1.0) < 4.0 * math.sqrt(variance / n)
    # the sample variance of a heavy-tailed law: 4 standard errors from its fourth moment
    fourth = 3 * (sigma**2 * horizon) ** 2 + 6 * sigma**2 * horizon * rate * horizon * sd**2
    fourth += 3 * (rate * horizon * sd**2) ** 2 + 3 * rate * horizon * sd**4
    assert abs(np.var(p.speed) - variance) < 4.0 * math.sqrt((fourth - variance**2) / n)


@njit
def _scalar_steps(streams, v, w, sigma_speed, sigma_turn, mean, sd, steps):
    """Per step and particle, as the kernel draws them: the speed's and the turn rate's
    normals, then (if ``mean``) the jump's uniform and, for a jump, its normal."""
    for i in range(streams.size):
        s = streams[i]
        for _ in range(steps):
            z1, s = rs.normal(s)
            z2, s = rs.normal(s)
            v[i] += sigma_speed * z1
            w[i] += sigma_turn * z2
            if mean > 0.0:
                u, s = rs.uniform(s)
                if u <= -math.expm1(-mean):
                    z, s = rs.normal(s)
                    v[i] += math.sqrt(_jump_count(1.0 - u, mean)) * sd * z
        streams[i] = s


@pytest.mark.parametrize("rate", [0.0, 0.05])
def test_the_kernel_draws_the_jumps_after_the_walks_and_nothing_without_them(rate):
    """A compiled step takes the jump's uniform after the random walks' two normals, and a
    normal only for a particle that jumps; at rate 0 exactly the draws of the kernel without
    jumps: the random streams of every seeded run without them are unchanged."""
    n, steps = 3000, 6
    motion = VelocityMotion(0.1, 0.02, jump_rate=rate, jump_sd=0.4)
    p = cloud(n)
    streams = rs.new_streams(np.random.default_rng(2), n)
    expected_streams, v, w = streams.copy(), p.speed.copy(), p.turn_rate.copy()
    _scalar_steps(expected_streams, v, w, 0.1, 0.02, rate, 0.4, steps)
    motion.advance(p, streams, steps, 1.0, p.normalised_weights(), (0.0, 0.0))
    np.testing.assert_array_equal(streams, expected_streams)
    np.testing.assert_allclose(p.speed, v, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(p.turn_rate, w, rtol=1e-13, atol=1e-15)


def test_the_numpy_path_draws_nothing_for_jumps_at_rate_zero():
    """At rate 0 the reference draws what it drew before jumps existed: the walks' normals."""
    p, q = cloud(500), cloud(500)
    VelocityMotion(0.1, 0.02).propagate(np.random.default_rng(4), p, 1.0)
    rng = np.random.default_rng(4)
    normals = rng.standard_normal((2, 500))
    VelocityMotion(0.1, 0.02).apply(q, 1.0, normals)
    np.testing.assert_array_equal(p.speed, q.speed)
    np.testing.assert_array_equal(p.x, q.x)


def test_jump_count_inverts_the_poisson_distribution():
    """The count at ``w`` is the Poisson(mean) quantile, at the CDF's steps as between."""
    for mean in (0.01, 0.5, 3.0):
        w = np.random.default_rng(1).random(2000)
        counts = [_jump_count(x, mean) for x in w]
        np.testing.assert_array_equal(counts, stats.poisson.ppf(w, mean))
    assert _jump_count(math.exp(-0.5) * (1 - 1e-12), 0.5) == 0
    assert _jump_count(math.exp(-0.5) * (1 + 1e-12), 0.5) == 1


def test_the_jump_pass_jumps_at_the_poisson_rate():
    """One pass of the jump step over many streams: the share that jumped is
    1 - exp(-mean), and a stream advances by two draws when it jumps, one when not."""
    n, mean = 200_000, 0.02
    streams = rs.new_streams(np.random.default_rng(6), n)
    v, before = np.zeros(n), streams.copy()
    _speed_jumps(v, streams, mean, 1.0, np.empty(n))
    jumped = v != 0.0
    share = -math.expm1(-mean)
    assert abs(jumped.mean() - share) < 4.0 * math.sqrt(share * (1 - share) / n)
    one = np.array([rs.uniform(s)[1] for s in before[:2000]])
    np.testing.assert_array_equal(streams[:2000][~jumped[:2000]], one[~jumped[:2000]])
    assert np.all(streams[:2000][jumped[:2000]] != one[jumped[:2000]])


@pytest.mark.parametrize("name", ["jump_rate", "jump_sd"])
@pytest.mark.parametrize("value", [-0.1, np.nan, np.inf])
def test_jump_settings_must_be_numbers_at_least_zero(name, value):
    with pytest.raises(ValueError, match=name):
        VelocityMotion(0.1, 0.02, **{name: value})


# ------------------------------------------------------------------------------- settings


def test_only_the_gps_measurement_jumps_by_default():
    """The paper's velocity model by default, and under the paper's measurement; under
    range-rate-gps the speed jumps 1/60 times per second by 0.4 m/s (reports/decisions.md,
    "A sticky still regime for the velocity model")."""
    for motion in (
        motion_model("velocity"),
        VelocitySettings().build(),
        _motion("velocity", "range-rate"),
    ):
        assert (motion.jump_rate, motion.jump_sd) == (0.0, 0.0)
    gps = _motion("velocity", "range-rate-gps")
    assert (gps.jump_rate, gps.jump_sd) == (1 / 60, 0.4)


def test_jumps_are_given_in_a_configuration_or_on_the_command_line():
    config = TrackingConfig.from_dict(
        {
            "measurement": {"name": "range-rate-gps", "period": 8.0},
            "motion": {
                "name": "velocity",
                "sigma_speed": 0.03,
                "jump_rate": 0.02,
                "jump_sd": 0.4,
                "still_rate": 0.0,  # no still regime (the measurement's would add one)
            },
        }
    )
    assert config.motion_model() == VelocityMotion(0.03, 0.02, jump_rate=0.02, jump_sd=0.4)
    assert TrackingConfig.from_dict(config.to_dict()) == config
    parser = build_parser()
    args = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    args += ["--period", "8", "--r0", "a=1", "--motion", "velocity"]
    given = build_config(parser.parse_args([*args, "--jump-rate", "0.05", "--jump-sd", "0.3"]))
    assert given.motion_model() == VelocityMotion(0.1, 0.02, jump_rate=0.05, jump_sd=0.3)
    with pytest.raises(ValueError, match="jump_rate must be a non-negative"):
        VelocitySettings(jump_rate=-1.0)
