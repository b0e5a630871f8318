"""The GPS-offset measurement (``"range-rate-gps"``): its per-particle Kalman filters against
the exact Kalman filter of a still tag on a fixed line of sight."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.special import logsumexp

from hmmtrack.tracking.filter import FilterSettings
from hmmtrack.tracking.measurement import gps_offset
from hmmtrack.tracking.measurement.gps_offset import GpsOffsetMeasurement
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.particles import Particles
from hmmtrack.tracking.pipeline import particle_filter
from hmmtrack.tracking.tempering import Tempered

GPS_SD, TAU, WHITE, RATE_SD = 1.5, 60.0, 0.5, 0.5
RECEIVER_X = 1000.0
PRIOR_SD = 3.0


def _pings(seed: int, tau: float):
    """Ping times (s, irregular: missed pings) and observed ranges of a still tag at x = 1.2
    m seen from a still receiver at (1000, 0): range 1000 - x plus an AR(1) offset of
    correlation time ``tau`` (s; ``inf``: constant) and white noise."""
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.choice([8.0, 16.0, 24.0, 90.0], size=25, p=[0.7, 0.15, 0.1, 0.05]))
    offset = np.empty(times.size)
    offset[0] = GPS_SD * rng.standard_normal()
    for k in range(1, times.size):
        rho = np.exp(-(times[k] - times[k - 1]) / tau)
        offset[k] = rho * offset[k - 1] + GPS_SD * np.sqrt(1 - rho**2) * rng.standard_normal()
    ranges = RECEIVER_X - 1.2 + offset + WHITE * rng.standard_normal(times.size)
    return times, ranges


def _exact(times, ranges, tau):
    """Kalman filter of the augmented state (x, offset): mean (2,), covariance (2, 2) and
    the log marginal likelihood of the ranges."""
    mean = np.zeros(2)
    cov = np.diag([PRIOR_SD**2, GPS_SD**2])
    h = np.array([-1.0, 1.0])  # range - 1000 = -x + offset + white
    loglik = 0.0
    for k, (t, r) in enumerate(zip(times, ranges, strict=True)):
        if k:
            rho = np.exp(-(t - times[k - 1]) / tau)
            a = np.diag([1.0, rho])
            mean = a @ mean
            cov = a @ cov @ a.T + np.diag([0.0, (1 - rho**2) * GPS_SD**2])
        s = h @ cov @ h + WHITE**2
        innovation = (r - RECEIVER_X) - h @ mean
        loglik += -0.5 * (np.log(2 * np.pi * s) + innovation**2 / s)
        gain = cov @ h / s
        mean = mean + gain * innovation
        cov = cov - np.outer(gain, h @ cov)
    return mean, cov, loglik


def _particles(x):
    return Particles.from_state(x, np.zeros(x.size), np.zeros(x.size))


def _run(measurement, particles, times, ranges):
    """Every ping scored and committed in turn on fixed particles: the summed log-likelihood
    (N,) and the run state after the last."""
    state = measurement.start(particles, times[0])
    total = np.zeros(particles.n)
    for t, r in zip(times, ranges, strict=True):
        rows = np.array([[r, 0.0, RECEIVER_X, 0.0, 0.0, 0.0, 0.0]])
        score = measurement.score(particles, rows, float(t), state, None)
        total += score.loglik
        score.commit(particles)
    return total, state


@pytest.mark.parametrize("moored", [False, True])
def test_particle_kalman_filters_equal_the_exact_filter_of_a_still_tag(moored):
    # a still tag on a fixed line of sight is linear-Gaussian in (x, offset): the weighted
    # particles on a fine grid of x, each with its offset's Kalman filter, must give the
    # exact filter's marginal likelihood and posterior of both (a moored receiver: the
    # offset constant)
    tau = np.inf if moored else TAU
    measurement = GpsOffsetMeasurement.of(["a"], RATE_SD, GPS_SD, TAU, WHITE, [moored])
    rate_norm = -0.5 * np.log(2 * np.pi * RATE_SD**2)  # the range-rate's (observed 0 = 0)
    for seed in range(3):
        times, ranges = _pings(seed, tau)
        mean, cov, exact_loglik = _exact(times, ranges, tau)
        step = 0.01
        x = np.arange(-8 * PRIOR_SD, 8 * PRIOR_SD, step)
        particles = _particles(x)
        total, state = _run(measurement, particles, times, ranges)
        total -= times.size * rate_norm
        log_prior = -0.5 * (x / PRIOR_SD) ** 2 - 0.5 * np.log(2 * np.pi * PRIOR_SD**2)
        log_post = log_prior + total
        assert np.isclose(logsumexp(log_post) + np.log(step), exact_loglik, atol=1e-9)
        w = np.exp(log_post - logsumexp(log_post))
        offsets = particles.gps_offset_0
        x_mean, b_mean = w @ x, w @ offsets
        np.testing.assert_allclose([x_mean, b_mean], mean, atol=1e-9)
        x_var = w @ (x - x_mean) ** 2
        b_var = state.variance[0] + w @ (offsets - b_mean) ** 2
        xb_cov = w @ ((x - x_mean) * (offsets - b_mean))
        np.testing.assert_allclose([[x_var, xb_cov], [xb_cov, b_var]], cov, atol=1e-9)
        assert state.time[0] == times[-1]


def test_first_ping_of_a_receiver_is_the_stationary_prior_likelihood():
    # before a receiver's first scored ping its offset is N(0, gps_sd^2): the score equals the
    # state-free log-likelihood (the paper's with range variance gps_sd^2 + white^2), for each
    # of two receivers seen at the same step; the second receiver's offset is untouched by
    # the first's ping
    measurement = GpsOffsetMeasurement.of(["a", "b"], RATE_SD, GPS_SD, TAU, WHITE)
    rng = np.random.default_rng(4)
    particles = Particles.from_state(
        rng.uniform(-50, 50, 200), rng.uniform(-50, 50, 200), rng.uniform(-3, 3, 200),
        speed=rng.uniform(0, 1, 200),
    )  # fmt: skip
    state = measurement.start(particles, 0.0)
    rows = np.array(
        [
            [400.0, 0.3, 300.0, 200.0, 1.0, 0.5, 1.0],
            [250.0, -0.2, -200.0, 100.0, 0.0, -1.0, 0.0],
        ]
    )
    score = measurement.score(particles, rows, 8.0, state, None)
    np.testing.assert_allclose(score.loglik, measurement.loglik(particles, rows), rtol=1e-12)
    only_b = measurement.score(particles, rows[:1], 8.0, state, None)
    only_b.commit(particles)
    assert np.all(particles.gps_offset_0 == 0.0)
    assert np.all(particles.gps_offset_1 != 0.0)
    assert np.isnan(state.time[0]) and state.time[1] == 8.0
    assert state.variance[1] == GPS_SD**2 * WHITE**2 / (GPS_SD**2 + WHITE**2)


@pytest.mark.parametrize("moored", [False, True])
def test_translation_terms_are_the_derivatives_of_the_pings_log_likelihood(moored):
    # a particle's pings' log-likelihood as its whole (here still) path is translated: the
    # carried gradient and information are its first and second derivatives and the slope
    # the offset mean's, against central differences of runs at shifted positions
    tau = np.inf if moored else TAU
    measurement = GpsOffsetMeasurement.of(["a"], RATE_SD, GPS_SD, TAU, WHITE, [moored])
    times, ranges = _pings(1, tau)
    h = 1e-3
    particles = _particles(np.array([0.7, 0.7 + h, 0.7 - h]))
    total, _ = _run(measurement, particles, times, ranges)
    gradient = (total[1] - total[2]) / (2 * h)
    curvature = (total[1] - 2 * total[0] + total[2]) / h**2
    np.testing.assert_allclose(particles.gps_gradient_x[0], gradient, rtol=1e-6)
    np.testing.assert_allclose(particles.gps_information_xx[0], -curvature, rtol=1e-5)
    slope = (particles.gps_offset_0[1] - particles.gps_offset_0[2]) / (2 * h)
    np.testing.assert_allclose(particles.gps_slope_0_x[0], slope, rtol=1e-6)
    assert particles.gps_information_yy[0] == 0.0  # the line of sight is along x


@pytest.mark.parametrize("moored", [False, True])
def test_one_translation_from_a_point_draws_the_exact_posterior(moored, monkeypatch):
    # every particle at one point of a still tag's line of sight (flat prior): one
    # translation move must draw x from the exact posterior (a grid of the pings' likelihood)
    # and give each particle the offset mean a run at its new position gives (the longest
    # move lifted, which would truncate a posterior of 1.5 m sd)
    monkeypatch.setattr(gps_offset, "MAX_TRANSLATION", 50.0)
    tau = np.inf if moored else TAU
    measurement = GpsOffsetMeasurement.of(["a"], RATE_SD, GPS_SD, TAU, WHITE, [moored])
    times, ranges = _pings(2, tau)
    grid = np.arange(-10.0, 12.0, 0.001)
    log_post, _ = _run(measurement, _particles(grid), times, ranges)
    w = np.exp(log_post - logsumexp(log_post))
    mean = w @ grid
    sd = np.sqrt(w @ (grid - mean) ** 2)
    n = 20_000
    particles = _particles(np.full(n, mean + 0.5 * sd))
    _run(measurement, particles, times, ranges)
    score = measurement.score(particles, np.empty((0, 7)), times[-1], measurement.start(
        _particles(np.zeros(1)), 0.0), None)  # fmt: skip
    score.move(particles, np.random.default_rng(5))
    assert abs(particles.x.mean() - mean) < 4 * sd / np.sqrt(n)
    assert abs(particles.x.std() / sd - 1) < 4 / np.sqrt(2 * n)
    assert np.all(particles.y == 0.0)
    check = _particles(particles.x[:5].copy())
    _run(measurement, check, times, ranges)
    np.testing.assert_allclose(particles.gps_offset_0[:5], check.gps_offset_0, atol=1e-9)


def test_the_gps_option_moves_within_the_mixtures_components():
    """Its tempered steps move each mixture component by its own covariance, also when the
    configuration sets its own ``tempering_ess`` (``pipeline.particle_filter``)."""
    measurement = SimpleNamespace(
        default_correction=GpsOffsetMeasurement.default_correction, collectors=lambda: []
    )
    assert measurement.default_correction.within_components
    settings = FilterSettings(n_particles=10, tempering_ess=0.5, acquisition=False)
    pf = particle_filter(settings, measurement, (0.0, 1.0, 0.0, 1.0), BaselineMotion(1.0))
    assert pf.correction == Tempered(0.5, within_components=True)
    assert pf.mixture is not None
