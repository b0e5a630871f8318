"""Tests of the arrival-time measurement model against brute force and the paper's ranging."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from hmmtrack.tracking.measurement.arrival_time import (
    TABLE_END,
    TABLE_START,
    TABLE_STEP,
    ArrivalLikelihood,
    ArrivalTimeMeasurement,
    emission_range,
    mixture_constants,
    mixture_log_densities,
    mixture_log_density,
    mixture_table,
    wrap_to_ping,
)
from hmmtrack.tracking.measurement.ranging import ranges

C = 1460.0


def particles(x, y, heading=0.0, speed=0.0, emission_time=0.0, period=8.0, depth=None):
    n = np.size(x)
    out = SimpleNamespace(
        x=np.asarray(x, dtype=float),
        y=np.asarray(y, dtype=float),
        heading=np.broadcast_to(np.asarray(heading, dtype=float), (n,)).copy(),
        speed=np.broadcast_to(np.asarray(speed, dtype=float), (n,)).copy(),
        emission_time=np.broadcast_to(np.asarray(emission_time, dtype=float), (n,)).copy(),
        period=np.broadcast_to(np.asarray(period, dtype=float), (n,)).copy(),
    )
    out.cos_heading = np.cos(out.heading)
    out.sin_heading = np.sin(out.heading)
    if depth is not None:
        out.depth = np.broadcast_to(np.asarray(depth, dtype=float), (n,)).copy()
    return out


def brute_force_loglik(p, obs, time, likelihood, tag_depth_column=True):
    """Scalar loops: exact emission range by iteration, nearest ping by search, scipy densities."""
    total = np.zeros(p.x.size)
    for i in range(p.x.size):
        vx = p.speed[i] * math.cos(p.heading[i])
        vy = p.speed[i] * math.sin(p.heading[i])
        for _, row in obs.iterrows():
            arrival = row["time"]
            depth = row["depth"] if tag_depth_column and "depth" in obs else 0.0
            r = 0.0
            for _ in range(50):  # emitted at arrival - r/C, the tag then at x - v * (time - that)
                back = time - arrival + r / C
                r = math.sqrt(
                    (p.x[i] - vx * back - row["receiver_x"]) ** 2
                    + (p.y[i] - vy * back - row["receiver_y"]) ** 2
                    + depth**2
                )
            implied = arrival - r / C
            candidates = p.emission_time[i] + p.period[i] * np.arange(-2000, 2001)
            residual = implied - candidates[np.argmin(np.abs(implied - candidates))]
            s = likelihood.sigma
            density = (
                (1 - likelihood.late_fraction - likelihood.uniform_fraction)
                * stats.norm.pdf(residual, 0, s)
                + likelihood.late_fraction
                * stats.exponnorm.pdf(residual, likelihood.late_mean / s, loc=0, scale=s)
                + likelihood.uniform_fraction / p.period[i]
            )
            total[i] += math.log(density)
    return total


def test_loglik_equals_brute_force_for_a_few_particles():
    rng = np.random.default_rng(1)
    n = 6
    p = particles(
        x=rng.uniform(-300, 300, n),
        y=rng.uniform(-300, 300, n),
        heading=rng.uniform(-np.pi, np.pi, n),
        speed=rng.uniform(0, 2, n),
        emission_time=1000.0 + rng.normal(0, 0.01, n),
        period=8.0 + rng.normal(0, 1e-3, n),
    )
    obs = pd.DataFrame(
        {
            "time": [1100.31, 1100.52, 1108.2],  # several pings after the reference emission
            "receiver": ["a", "b", "a"],
            "receiver_x": [120.0, -200.0, 130.0],
            "receiver_y": [50.0, 10.0, 55.0],
            "depth": [12.0, 12.0, 14.0],
        }
    )
    likelihood = ArrivalLikelihood(sigma=4e-3, late_fraction=0.05, late_mean=0.02)
    model = ArrivalTimeMeasurement(likelihood, sound_speed=C)
    got = model.loglik(p, obs, time=1109.0)
    want = brute_force_loglik(p, obs, 1109.0, likelihood)
    np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-7)


def test_particle_depth_takes_precedence_over_the_depth_column():
    p = particles(x=[100.0, 30.0], y=[0.0, 40.0], depth=[0.0, 0.0])
    obs = pd.DataFrame({"time": [0.2], "receiver": ["a"], "receiver_x": [0.0], "receiver_y": [0.0]})
    model = ArrivalTimeMeasurement(ArrivalLikelihood(late_fraction=0.0, uniform_fraction=0.0))
    obs["time"] = 0.06
    flat = model.loglik(p, obs.assign(depth=[50.0]))
    want = brute_force_loglik(p, obs, 0.06, model.likelihood, tag_depth_column=False)
    np.testing.assert_allclose(flat, want, rtol=1e-9)


def test_constant_period_and_known_start_agree_with_the_paper_ranges():
    # a tag swimming past a moving receiver; emissions exactly every T from a known e0
    period, e0 = 8.179, 5000.0
    k = np.arange(200)
    emission = e0 + k * period
    tag_x, tag_y = 300 + 0.8 * (emission - e0), 100 - 0.3 * (emission - e0)
    arrival = emission.copy()
    for _ in range(6):  # receiver moves at 1.5 m/s along x; solve the arrival exactly
        rx, ry = 1.5 * (arrival - e0), 0.0 * arrival
        r = np.hypot(tag_x - rx, tag_y - ry)
        arrival = emission + r / C
    heard = np.random.default_rng(2).random(k.size) < 0.5  # about half the pings missed
    heard[0] = True
    times = arrival[heard]
    paper = ranges(times, period, r0=r[heard][0], sound_speed=C)
    residual, ping = wrap_to_ping(times, e0, period)
    np.testing.assert_allclose(C * residual, paper, atol=1e-6)
    np.testing.assert_array_equal(ping, k[heard])

    # and the likelihood of a range is the paper's Gaussian in range, up to a constant
    sigma = 3e-3
    model = ArrivalTimeMeasurement(
        ArrivalLikelihood(sigma=sigma, late_fraction=0.0, uniform_fraction=0.0), sound_speed=C
    )
    j = np.flatnonzero(heard)[40]
    rng = np.random.default_rng(3)
    px = tag_x[j] + rng.normal(0, 8, 50)
    py = tag_y[j] + rng.normal(0, 8, 50)
    obs = pd.DataFrame(
        {
            "time": [arrival[j]],
            "receiver": ["auv"],
            "receiver_x": [1.5 * (arrival[j] - e0)],
            "receiver_y": [0.0],
        }
    )
    got = model.loglik(particles(px, py, emission_time=e0, period=period), obs)
    predicted = np.hypot(px - obs["receiver_x"][0], py)
    paper_range = ranges(times, period, r0=r[heard][0], sound_speed=C)[40]
    gaussian = stats.norm.logpdf(predicted, paper_range, C * sigma)
    np.testing.assert_allclose(got - gaussian, np.log(C), atol=1e-8)


@settings(max_examples=200, deadline=None)
@given(
    ping=st.integers(-5000, 5000),
    fraction=st.floats(-0.49, 0.49),
    period=st.floats(0.5, 120.0),
    reference=st.floats(-1e6, 1e6),
)
def test_wrapping_picks_the_right_ping_after_many_missed_pings(ping, fraction, period, reference):
    residual = fraction * period
    implied = reference + ping * period + residual
    got_residual, got_ping = wrap_to_ping(implied, reference, period)
    assert got_ping == ping
    assert got_residual == pytest.approx(residual, abs=1e-6)


def test_wrapping_in_the_likelihood_after_500_missed_pings():
    # the particle's reference emission lies 500 pings before the detection
    period = 8.0
    p = particles(x=[0.0, 0.0, 0.0], y=[300.0, 303.0, 330.0], emission_time=0.0, period=period)
    obs = pd.DataFrame(
        {
            "time": [500 * period + 300.0 / C],
            "receiver": ["a"],
            "receiver_x": [0.0],
            "receiver_y": [0.0],
        }
    )
    model = ArrivalTimeMeasurement(ArrivalLikelihood(sigma=2e-3), sound_speed=C)
    residual = model.residuals(p, obs)[:, 0]
    np.testing.assert_allclose(residual, [0.0, -3.0 / C, -30.0 / C], atol=1e-9)
    ll = model.loglik(p, obs)
    assert ll[0] > ll[1] > ll[2]


def _grid_posterior_mean(model, obs, half_width=15.0, step=0.25):
    g = np.arange(-half_width, half_width + step / 2, step)
    gx, gy = np.meshgrid(g, g)
    p = particles(gx.ravel(), gy.ravel(), emission_time=0.0, period=8.0)
    ll = model.loglik(p, obs)
    w = np.exp(ll - ll.max())
    w /= w.sum()
    return np.array([w @ p.x, w @ p.y])


def test_five_percent_multipath_outliers_move_the_estimate_less_than_a_quarter_metre():
    """Stated bound: with 5 % late arrivals (mean delay 20 ms = 29 m), the posterior mean
    of a fixed tag seen by a receiver driving a quarter circle around it moves by less than
    0.25 m; a plain Gaussian likelihood on the same data moves by more than 1 m."""
    rng = np.random.default_rng(4)
    n, period = 240, 8.0
    angle = np.linspace(0, np.pi / 2, n)
    rx, ry = 250 * np.cos(angle), 250 * np.sin(angle)
    emission = period * np.arange(1, n + 1)
    clean = emission + np.hypot(rx, ry) / C + rng.normal(0, 1e-3, n)
    late = rng.random(n) < 0.05
    noisy = clean + late * rng.exponential(0.02, n)
    assert 6 <= late.sum() <= 20

    def obs(times):
        return pd.DataFrame({"time": times, "receiver": "auv", "receiver_x": rx, "receiver_y": ry})

    robust = ArrivalTimeMeasurement(ArrivalLikelihood(sigma=1e-3, late_fraction=0.05), C)
    gaussian = ArrivalTimeMeasurement(
        ArrivalLikelihood(sigma=1e-3, late_fraction=0.0, uniform_fraction=0.0), C
    )
    shift_robust = np.linalg.norm(
        _grid_posterior_mean(robust, obs(noisy)) - _grid_posterior_mean(robust, obs(clean))
    )
    shift_gaussian = np.linalg.norm(
        _grid_posterior_mean(gaussian, obs(noisy)) - _grid_posterior_mean(gaussian, obs(clean))
    )
    assert shift_robust < 0.25
    assert shift_gaussian > 1.0


def test_emission_range_solves_the_light_time_equation():
    rng = np.random.default_rng(5)
    x, y = rng.uniform(-900, 900, 20), rng.uniform(-900, 900, 20)
    vx, vy = rng.normal(0, 2, 20), rng.normal(0, 2, 20)
    r = emission_range(x, y, vx, vy, 0.4, 10.0, -20.0, 5.0, C)
    back = 0.4 + r / C
    exact = np.sqrt((x - vx * back - 10.0) ** 2 + (y - vy * back + 20.0) ** 2 + 25.0)
    np.testing.assert_allclose(r, exact, atol=1e-6)


def test_likelihood_integrates_to_one_over_a_period():
    likelihood = ArrivalLikelihood(sigma=2e-3, late_fraction=0.1, late_mean=0.03)
    grid = np.linspace(-4.0, 4.0, 2_000_001)
    density = np.exp(likelihood.logpdf(grid, 8.0))
    assert np.trapezoid(density, grid) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(
    "column, value, message",
    [
        ("receiver_x", np.nan, "receiver_x"),
        ("time", np.inf, "'time'"),
    ],
)
def test_bad_observations_name_the_column_and_rows(column, value, message):
    obs = pd.DataFrame(
        {"time": [1.0, 2.0], "receiver": ["a", "a"], "receiver_x": [0.0, 0.0], "receiver_y": [0, 0]}
    )
    obs.loc[1, column] = value
    model = ArrivalTimeMeasurement()
    with pytest.raises(ValueError, match=rf"{message}.*rows \[1\]"):
        model.loglik(particles([1.0], [1.0]), obs)


def test_missing_columns_and_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="receiver_y"):
        ArrivalTimeMeasurement().loglik(
            particles([1.0], [1.0]),
            pd.DataFrame({"time": [1.0], "receiver": ["a"], "receiver_x": [0.0]}),
        )
    with pytest.raises(ValueError, match="sound_speed"):
        ArrivalTimeMeasurement(sound_speed=343.0)
    with pytest.raises(ValueError, match="sigma"):
        ArrivalLikelihood(sigma=0.0)
    with pytest.raises(ValueError, match="below 1"):
        ArrivalLikelihood(late_fraction=0.6, uniform_fraction=0.5)


@settings(max_examples=30, deadline=None)
@given(
    sigma=st.floats(1e-4, 1e-2),
    late=st.floats(0.0, 0.3),
    uniform=st.floats(0.0, 0.05),
    late_mean=st.floats(1e-3, 0.1),
)
def test_compiled_densities_equal_the_numpy_reference(sigma, late, uniform, late_mean):
    likelihood = ArrivalLikelihood(sigma, late, late_mean, uniform)
    residual = np.concatenate([np.linspace(-4.0, 4.0, 401), np.linspace(-0.2, 0.2, 401)])
    period = np.full(residual.size, 8.0)
    total, core = likelihood.log_densities(residual, period)
    want_total = likelihood.logpdf(residual, period)
    want_core = likelihood.core_logpdf(residual)
    np.testing.assert_allclose(total, want_total, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(core, want_core, rtol=1e-12, atol=1e-9)
    # the scalar kernel's direct-arrival share, used by the clock update
    # (where both logs are below 1e4 in size: beyond, exp(core - total) of the reference
    # loses digits to cancellation)
    near = np.flatnonzero(np.abs(want_core) < 1e4)
    assert near.size >= 20
    constants = mixture_constants(sigma, late, late_mean, uniform)
    direct = [mixture_log_density(residual[i], 8.0, constants)[2] for i in near]
    np.testing.assert_allclose(direct, np.exp(want_core - want_total)[near], rtol=1e-9, atol=1e-12)


def test_compiled_match_equals_emission_range_and_wrapping():
    rng = np.random.default_rng(6)
    n = 50
    p = particles(
        x=rng.uniform(-900, 900, n),
        y=rng.uniform(-900, 900, n),
        heading=rng.uniform(-np.pi, np.pi, n),
        speed=rng.uniform(0, 2, n),
        emission_time=rng.uniform(0, 8, n),
        period=8.0 + rng.normal(0, 1e-3, n),
    )
    model = ArrivalTimeMeasurement(sound_speed=C)
    residual, ping, r = model.match_one(p, 1234.5, 10.0, -20.0, 4.0, time=1235.1)
    vx, vy = p.speed * np.cos(p.heading), p.speed * np.sin(p.heading)
    want_r = emission_range(p.x, p.y, vx, vy, 0.6, 10.0, -20.0, 4.0, C)
    want_residual, want_ping = wrap_to_ping(1234.5 - want_r / C, p.emission_time, p.period)
    np.testing.assert_allclose(r, want_r, rtol=1e-12)
    np.testing.assert_allclose(residual, want_residual, atol=1e-9)
    np.testing.assert_array_equal(ping, want_ping)


def exact_densities(likelihood, residual, period):
    """The NumPy reference: log density and direct share of each residual."""
    total = likelihood.logpdf(residual, period)
    return total, np.exp(likelihood.core_logpdf(residual) - total)


@settings(max_examples=40, deadline=None)
@given(
    sigma=st.floats(1e-4, 0.1),
    late=st.sampled_from([0.0, 0.01, 0.05, 0.3, 0.5]),
    late_mean=st.floats(3e-4, 0.3),
    uniform=st.sampled_from([0.0, 1e-9, 1e-6, 1e-3, 0.05]),
    period=st.floats(1.0, 300.0),
)
def test_tabulated_mixture_is_within_1e_6_of_the_exact_density(
    sigma, late, late_mean, uniform, period
):
    """The filter's interpolated mixture against the NumPy reference over the whole line:
    the table's grid (densely), its ends, far tails, the wrap boundaries ±period/2, and
    particles' periods within and beyond 10 % of the mean (those are scored exactly)."""
    likelihood = ArrivalLikelihood(sigma, late, late_mean, uniform)
    rng = np.random.default_rng(0)
    z = np.concatenate(
        [
            np.linspace(-15.0, 15.0, 12001),
            TABLE_START + sigma / late_mean + np.array([-1e-9, 0.0, 1e-9]),
            TABLE_END + sigma / late_mean + np.array([-1e-9, 0.0, 1e-9]),
            [-1e4, -300.0, -40.0, 40.0, 300.0, 1e4],
        ]
    )
    residual = np.concatenate([z * sigma, [-0.5 * period, 0.5 * period]])
    residual = residual[np.abs(residual) <= 0.5 * period]
    periods = period * (1.0 + rng.uniform(-0.12, 0.12, residual.size))
    total, direct = np.empty(residual.size), np.empty(residual.size)
    mixture_log_densities(
        residual, periods, mixture_constants(sigma, late, late_mean, uniform), total, direct
    )
    want_total, want_direct = exact_densities(likelihood, residual, periods)
    near = np.abs(want_total) < 1e4  # beyond, the reference's exp(core − total) loses digits
    np.testing.assert_allclose(total, want_total, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(direct[near], want_direct[near], rtol=0, atol=1e-6)


def test_mixture_table_holds_the_exact_density_and_its_slopes_at_the_nodes():
    """Each node of the table against the NumPy reference: the log density (less the
    core's log weight), the uniform and direct shares, and their slopes against central
    differences of the reference; likelihoods too sharp to tabulate get an empty table."""
    sigma, late, late_mean, uniform, period = 3e-3, 0.05, 0.02, 1e-3, 8.0
    likelihood = ArrivalLikelihood(sigma, late, late_mean, uniform)
    constants = mixture_constants(sigma, late, late_mean, uniform)
    table = mixture_table(constants, period)
    w = np.linspace(TABLE_START, TABLE_END, table.shape[0])
    assert np.allclose(np.diff(w), TABLE_STEP)
    eps = (w + sigma / late_mean) * sigma

    def parts(e):
        total, direct = exact_densities(likelihood, e, period)
        uniform_share = np.exp(np.log(uniform / period) - total)
        return total - constants[2], uniform_share, direct

    h = 1e-5  # in w
    for column, (value, upper, lower) in enumerate(
        zip(parts(eps), parts(eps + h * sigma), parts(eps - h * sigma), strict=True)
    ):
        np.testing.assert_allclose(table[:, 2 * column], value, rtol=1e-11, atol=1e-10)
        slope = TABLE_STEP * (upper - lower) / (2 * h)
        np.testing.assert_allclose(table[:, 2 * column + 1], slope, rtol=1e-5, atol=1e-9)
    too_sharp = mixture_constants(0.1, late, 0.01, uniform)  # sigma/late_mean = 10
    assert mixture_table(too_sharp, period).shape == (0, 6)
