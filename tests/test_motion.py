import dataclasses
import os
import subprocess
import sys

import numpy as np
import pytest
from numba import njit
from scipy import stats

from hmmtrack.hmm import Gamma, MovementHMM, VonMises
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.motion import BaselineMotion, HMMMotion, VelocityMotion
from hmmtrack.tracking.motion.arcs import arc_displacement, finish_headings
from hmmtrack.tracking.motion.chain import transition_pass
from hmmtrack.tracking.motion.hmm import (
    _draw_pass,
    _jitter_and_chain_draws,
    transition_for_step,
)
from hmmtrack.tracking.particles import Particles

TRANSITION = np.array([[0.9, 0.1], [0.2, 0.8]])


def movement_model(dt=10.0, transition=TRANSITION, step_sd=(1.0, 5.0), kappa=(1.0, 20.0)):
    """A two-state model shaped like a shark's: slow tortuous state, fast directed state."""
    return MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=np.asarray(transition, dtype=float),
        step=Gamma(mean=np.array([2.0, 15.0]), sd=np.asarray(step_sd, dtype=float)),
        angle=VonMises(mean=np.zeros(2), concentration=np.asarray(kappa, dtype=float)),
        dt=dt,
    )


def particles_at(n, heading=0.3, speed=1.5, turn_rate=0.0, seed=0):
    rng = np.random.default_rng(seed)
    return Particles.from_state(
        x=rng.uniform(-100, 100, n),
        y=rng.uniform(-100, 100, n),
        heading=np.broadcast_to(heading, (n,)),
        speed=speed,
        turn_rate=turn_rate,
    )


def advance(motion, p, n_steps, dt, seed=1):
    """Compiled steps; returns the per-step weighted moments."""
    streams = rs.new_streams(np.random.default_rng(seed), p.n)
    return motion.advance(p, streams, n_steps, dt, p.normalised_weights(), (0.0, 0.0))


# ----------------------------------------------------------------------------- arc


def paper_arc(x, y, theta, v, omega, dt):
    """The paper's eqs. mm_xc..mm_theta verbatim, in extended precision."""
    x, y, theta, v, omega = (np.longdouble(a) for a in (x, y, theta, v, omega))
    xc = x - v / omega * np.sin(theta)
    yc = y + v / omega * np.cos(theta)
    theta1 = theta + omega * dt
    return xc + v / omega * np.sin(theta1), yc - v / omega * np.cos(theta1), theta1


@pytest.mark.parametrize(
    "omega", [-6.0, -2.0, -0.3, -0.01, 1e-3, 0.02, 0.2, 0.26, 1.0, 3.0, 3.9999, 4.0001, 9.0]
)
@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_arc_matches_the_papers_closed_form(omega, path):
    theta = np.array([-2.5, -0.4, 0.0, 1.1, 3.0])
    v, dt = 1.7, 1.0
    p = Particles.from_state(x=np.full(5, 10.0), y=np.full(5, -4.0), heading=theta, speed=v)
    p.turn_rate[:] = omega
    motion = VelocityMotion(sigma_speed=0.0, sigma_turn_rate=0.0)
    if path == "numpy":
        motion.propagate(np.random.default_rng(0), p, dt)
    else:
        advance(motion, p, 1, dt)
    x1, y1, theta1 = paper_arc(10.0, -4.0, theta, v, omega, dt)
    np.testing.assert_allclose(p.x, x1.astype(float), rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.y, y1.astype(float), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.cos(p.heading), np.cos(theta1.astype(float)), atol=1e-12)
    np.testing.assert_allclose(p.cos_heading, np.cos(p.heading), atol=1e-14)
    np.testing.assert_allclose(p.sin_heading, np.sin(p.heading), atol=1e-14)


def test_straight_line_limit_is_exact_and_continuous():
    theta = np.linspace(-np.pi, np.pi, 9)
    c, s = np.cos(theta), np.sin(theta)
    dx0, dy0 = arc_displacement(c, s, 2.0, np.zeros(9))
    np.testing.assert_array_equal(dx0, 2.0 * c)
    np.testing.assert_array_equal(dy0, 2.0 * s)
    # tiny turns: the third-order expansion of the arc (error O(phi^4) < 1e-20)
    for phi in (1e-14, 1e-9, 1e-5):
        dx, dy = arc_displacement(c, s, 2.0, np.full(9, phi))
        sinc, cosc = 1 - phi**2 / 6, phi / 2 - phi**3 / 24
        np.testing.assert_allclose(dx, 2.0 * (c * sinc - s * cosc), rtol=0, atol=1e-15)
        np.testing.assert_allclose(dy, 2.0 * (s * sinc + c * cosc), rtol=0, atol=1e-15)
    # around the numpy path's series threshold (|phi| = 0.01): the closed form
    for phi in (0.00999, 0.01, 0.01001):
        dx, dy = arc_displacement(c, s, 2.0, np.full(9, phi))
        x1, y1, _ = paper_arc(0.0, 0.0, theta, 2.0, phi, 1.0)
        np.testing.assert_allclose(dx, x1.astype(float), rtol=0, atol=1e-13)
        np.testing.assert_allclose(dy, y1.astype(float), rtol=0, atol=1e-13)
    # the compiled kernel runs its series on phi / 16 up to |phi| = 4 (WIDE_TURN), the
    # library's sine and cosine beyond: continuous across it
    for omega in (0.0, 1e-12, 0.2499999, 0.25, 0.2500001, 3.9999999, 4.0, 4.0000001):
        p = particles_at(9, heading=theta)
        p.turn_rate[:] = omega
        x1, y1, _ = paper_arc(p.x, p.y, theta, 1.5, omega if omega else 1e-300, 1.0)
        advance(VelocityMotion(0.0, 0.0), p, 1, 1.0)
        if omega:
            np.testing.assert_allclose(p.x, x1.astype(float), atol=1e-12)
            np.testing.assert_allclose(p.y, y1.astype(float), atol=1e-12)
        else:
            start = particles_at(9, heading=theta)
            np.testing.assert_allclose(p.x - start.x, 1.5 * c, rtol=0, atol=1e-13)
            np.testing.assert_allclose(p.y - start.y, 1.5 * s, rtol=0, atol=1e-13)


def test_finish_headings_wraps_any_number_of_turns_as_the_loop_does():
    """The branch-free pass, and its loop for headings more than a turn outside, give the
    bits of subtracting 2 pi while above pi, then adding it while at or below -pi; (cos,
    sin) take one Newton step back to the unit circle."""
    pi = np.pi

    def loop(heading):
        out = heading.copy()
        for i in range(out.size):
            while out[i] > pi:
                out[i] -= 2.0 * pi
            while out[i] <= -pi:
                out[i] += 2.0 * pi
        return out

    within_a_turn = [0.0, pi, -pi, np.nextafter(pi, 4.0), np.nextafter(-pi, -4.0), 3.5, -3.5,
                     2 * pi, -2 * pi, 3 * pi, np.nan]  # fmt: skip
    turns_outside = [7.0, -7.0, 3 * pi + 1e-9, -3 * pi - 1e-9, 40.0, -33.0, 1e3, -1e3]
    for values in (within_a_turn, within_a_turn + turns_outside):
        heading = np.array(values)
        angle = np.arange(heading.size) * 0.4
        c, s = 1.001 * np.cos(angle), 0.999 * np.sin(angle)  # off the unit circle
        got, got_c, got_s = heading.copy(), c.copy(), s.copy()
        finish_headings(got, got_c, got_s)
        np.testing.assert_array_equal(got, loop(heading))
        finite = np.isfinite(got)
        assert np.all((got[finite] > -pi) & (got[finite] <= pi))
        factor = 1.5 - 0.5 * (c * c + s * s)
        np.testing.assert_array_equal(got_c, c * factor)
        np.testing.assert_array_equal(got_s, s * factor)
        np.testing.assert_allclose(np.hypot(got_c, got_s), 1.0, atol=1e-5)


# ----------------------------------------------------------------------------- kernels == numpy


@pytest.mark.parametrize(
    "motion", [BaselineMotion(sigma=0.8), VelocityMotion(sigma_speed=0.2, sigma_turn_rate=0.1)]
)
def test_compiled_kernel_equals_numpy_with_the_same_draws(motion):
    n, n_steps, dt = 500, 3, 2.0
    reference = particles_at(n, heading=np.random.default_rng(5).uniform(-3, 3, n), turn_rate=0.05)
    compiled = reference.copy()
    streams = rs.new_streams(np.random.default_rng(7), n)
    draws = streams.copy()
    weights = np.random.default_rng(8).dirichlet(np.ones(n))
    moments = motion.advance(compiled, streams, n_steps, dt, weights, (3.0, -2.0))
    for k in range(n_steps):
        motion.apply(reference, dt, rs.draw_normal_pairs(draws))
        dx, dy = reference.x - 3.0, reference.y + 2.0
        expected = [
            weights @ dx,
            weights @ dy,
            weights @ dx**2,
            weights @ dy**2,
            weights @ (dx * dy),
        ]
        np.testing.assert_allclose(moments[k], expected, rtol=1e-10)
    assert np.array_equal(draws, streams)  # the kernel used exactly these draws
    for name in ("x", "y", "speed", "turn_rate", "cos_heading", "sin_heading", "heading"):
        np.testing.assert_allclose(getattr(compiled, name), getattr(reference, name), atol=1e-9)


@pytest.mark.parametrize(
    "motion",
    [
        BaselineMotion(sigma=0.8),
        VelocityMotion(sigma_speed=0.2, sigma_turn_rate=0.1),
        HMMMotion(movement_model(dt=3.0), heading_diffusion=0.05),
    ],
)
def test_kernels_give_the_same_particles_on_any_number_of_threads(motion):
    """Threads claim chunks as they go but never change them: identical results on one
    thread, two, more threads than cores, and numba's thread count (the default)."""
    results = []
    for threads in (1, 2, 5, None):
        p = particles_at(6000, heading=np.linspace(-3, 3, 6000), turn_rate=0.05)  # 6 chunks
        motion.initialise(np.random.default_rng(3), p)
        streams = rs.new_streams(np.random.default_rng(4), p.n)
        weights = p.normalised_weights()
        moments = motion.advance(p, streams, 6, 1.0, weights, (0.0, 0.0), threads=threads)
        results.append((moments, p, streams))
    m1, p1, s1 = results[0]
    for m2, p2, s2 in results[1:]:
        np.testing.assert_array_equal(m1, m2)
        np.testing.assert_array_equal(s1, s2)
        for name in ("x", "y", "heading", "speed", "turn_rate", "state", "time_since_draw"):
            np.testing.assert_array_equal(getattr(p1, name), getattr(p2, name))


# Python threads that each advance their own particles with two kernel threads, at once;
# every result must equal a one-thread run. Run in this process (numba's OpenMP layer here)
# and in a child process forced onto numba's "workqueue" layer, which aborts the process on
# concurrent parallel calls unless hmmtrack.tracking.compiled.chunks serialises them.
CONCURRENT_ADVANCES = """
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.hmm import Gamma, MovementHMM, VonMises
from hmmtrack.tracking.motion import HMMMotion
from hmmtrack.tracking.particles import Particles

model = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=np.array([[0.9, 0.1], [0.2, 0.8]]),
    step=Gamma(mean=np.array([2.0, 15.0]), sd=np.array([1.0, 5.0])),
    angle=VonMises(mean=np.zeros(2), concentration=np.array([1.0, 20.0])),
    dt=1.0,
)
motion = HMMMotion(model, "paper")


def run(seed, threads):
    rng = np.random.default_rng(seed)
    p = Particles.uniform(rng, 5000, (-100.0, 100.0, -100.0, 100.0))
    motion.initialise(rng, p)
    streams = rs.new_streams(rng, p.n)
    moments = [
        motion.advance(p, streams, 4, 1.0, p.normalised_weights(), (0.0, 0.0), threads=threads)
        for _ in range(20)
    ]
    return np.concatenate([np.ravel(moments), p.x, p.y, p.state])


with ThreadPoolExecutor(4) as pool:
    together = list(pool.map(lambda seed: run(seed, 2), range(8)))
for seed, result in enumerate(together):
    assert np.array_equal(result, run(seed, 1)), seed
print("same")
"""


def test_kernels_on_several_python_threads_at_once_give_the_one_thread_answer():
    exec(CONCURRENT_ADVANCES, {})


def test_concurrent_parallel_kernels_are_safe_under_numbas_workqueue_layer(tmp_path):
    environment = {**os.environ, "NUMBA_THREADING_LAYER": "workqueue"}
    script = CONCURRENT_ADVANCES + "\nimport numba; print(numba.threading_layer())"
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True, text=True, env=environment, cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["same", "workqueue"]


FORK_AFTER_OPENMP = (
    CONCURRENT_ADVANCES.split("with ThreadPoolExecutor")[0]
    + """
import multiprocessing

if __name__ == "__main__":
    parent = run(0, 2)  # starts numba's OpenMP threads in this process
    with multiprocessing.get_context("fork").Pool(2) as pool:
        children = pool.starmap(run, [(0, 2), (1, 2)])
    assert np.array_equal(children[0], parent)
    assert np.array_equal(children[1], run(1, 1))
    print("same")
"""
)


@pytest.mark.skipif(os.name != "posix", reason="fork exists on POSIX systems only")
def test_a_process_forked_after_openmp_started_still_runs_kernels(tmp_path):
    """numba ends a forked child that starts GNU OpenMP work its parent had started; the
    kernels must notice the fork and run on the child's own thread, same answers."""
    script = tmp_path / "fork_after_openmp.py"
    script.write_text(FORK_AFTER_OPENMP)
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600
    )  # without the guard the pool waits for ever on its ended workers
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["same"]


def test_hmm_kernel_equals_numpy_on_a_nearly_deterministic_model():
    """Identity transitions, tiny step sd, huge concentration: both paths give one path."""
    model = movement_model(dt=4.0, transition=np.eye(2), step_sd=(1e-7, 1e-7), kappa=(1e12, 1e12))
    model = MovementHMM(
        initial=model.initial,
        transition=model.transition,
        step=model.step,
        angle=VonMises(mean=np.array([0.3, -0.1]), concentration=np.array([1e12, 1e12])),
        dt=4.0,
    )
    for variant in ("paper", "time_consistent"):
        motion = HMMMotion(model, variant)
        compiled = particles_at(200, heading=np.linspace(-3, 3, 200))
        motion.initialise(np.random.default_rng(1), compiled)
        reference = compiled.copy()
        advance(motion, compiled, 7, 1.0)
        for _ in range(7):
            motion.propagate(np.random.default_rng(2), reference, 1.0)
        assert np.array_equal(compiled.state, reference.state)
        for name in ("x", "y", "speed", "turn_rate", "cos_heading", "sin_heading"):
            np.testing.assert_allclose(getattr(compiled, name), getattr(reference, name), atol=1e-4)
        np.testing.assert_allclose(compiled.time_since_draw, reference.time_since_draw)


@njit
def _scalar_draws(due, state, streams, v, w, d, c, boost, scale, zero_mass, tables):
    """The scalar samplers, one due particle after the other (speed factor 2/4, dt 4)."""
    for i in due:
        k, s = state[i], streams[i]
        step, u = 0.0, 1.0
        if zero_mass[k] > 0:
            u, s = rs.uniform(s)
        if u > zero_mass[k]:
            step, s = rs.gamma(d[k], c[k], boost[k], scale[k], s)
        angle, s = rs.vonmises(tables, k, s)
        v[i], w[i], streams[i] = step * 2.0 / 4.0, angle / 4.0, s


@njit
def _scalar_transitions(state, streams, cumulative):
    for i in range(state.size):
        state[i], streams[i] = rs.categorical(cumulative[state[i]], streams[i])


@pytest.mark.parametrize("n_states", [3, 4, 6])
@pytest.mark.parametrize("latest_clock", [2.0, 1.1])
def test_vectorised_hmm_passes_make_the_scalar_samplers_draws(latest_clock, n_states):
    """The HMM kernel's draw pass (branch-free first tries, scalar retries; or, when few
    particles are due, the scalar samplers for those only) and transition pass give,
    particle by particle, exactly what the scalar samplers draw from the same streams: gamma
    and von Mises for due particles (also for a zero-inflated state and a boosted shape < 1
    state, which always take the scalar path) and categorical states, for models of three
    to six states."""
    n = 50_000
    rng = np.random.default_rng(12)
    shape = np.array([1.8, 0.6, 5.0, 2.5, 1.2, 9.0])[:n_states]
    scale = np.array([0.3, 2.0, 0.1, 0.7, 1.1, 0.05])[:n_states]
    zero_mass = np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0])[:n_states]
    tables = rs.VonMisesTables.build(
        [0.0, 1.0, -2.9, 0.5, 3.0, -1.0][:n_states], [2.0, 0.3, 40.0, 8.0, 1.0, 15.0][:n_states]
    ).as_tuple()
    d, c, boost = rs.gamma_constants(shape)
    state = rng.integers(0, n_states, n)
    clock = rng.uniform(0.0, latest_clock, n)  # due when >= 1: half, or one in eleven
    streams = rs.new_streams(rng, n)
    v, w = np.full(n, -1.0), np.full(n, -2.0)
    retry = np.zeros(n, dtype=bool)
    expected_streams = streams.copy()
    due = clock >= 1.0
    expected_v, expected_w = v.copy(), w.copy()
    _scalar_draws(
        np.flatnonzero(due), state, expected_streams, expected_v, expected_w, d, c, boost,
        scale, zero_mass, tables,
    )  # fmt: skip
    expected_clock = np.where(due, np.where(clock < 2.0, clock - 1.0, 0.0), clock)
    _draw_pass(
        v, w, state, clock, streams, 1.0, 1.0, 2.0 / 4.0, 4.0, d, c, boost, scale, zero_mass,
        tables, (np.empty((4, n)), np.empty((2, n), dtype=np.uint64), np.empty(n, bool)), retry,
    )  # fmt: skip
    np.testing.assert_array_equal(v, expected_v)
    np.testing.assert_array_equal(w, expected_w)
    np.testing.assert_array_equal(streams, expected_streams)
    np.testing.assert_array_equal(clock, expected_clock)
    if latest_clock == 2.0:  # the vectorised path: rejected tries and scalar-only states
        plain = (state == 0) | (state > 2)
        assert retry[plain].any() and not retry[plain].all() and retry[~plain & due].all()

    transition = rng.dirichlet(np.ones(n_states), n_states)
    transition[0, 2] = 0.0  # a tie in the cumulative row
    cumulative = np.cumsum(transition / transition.sum(axis=1, keepdims=True), axis=1)
    cumulative[:, -1] = 1.0
    expected_state = state.copy()
    _scalar_transitions(expected_state, expected_streams, cumulative)
    transition_pass(state, streams, cumulative, np.empty(n), np.empty(n, dtype=np.int64))
    np.testing.assert_array_equal(state, expected_state)
    np.testing.assert_array_equal(streams, expected_streams)


@njit
def _scalar_jitter_and_uniforms(streams, w, jitter_scale, turn, u):
    for i in range(streams.size):
        z, s = rs.normal(streams[i])
        u[i], streams[i] = rs.uniform(s)
        turn[i] = w[i] + jitter_scale * z


def test_jitter_and_chain_draws_are_a_normal_then_a_uniform():
    """The heading diffusion's normal and the chain's uniform drawn in one pass over the
    streams are exactly :func:`streams.normal` then :func:`streams.uniform` from each
    stream, for the particles whose ziggurat try is rejected too."""
    n = 20_000
    rng = np.random.default_rng(4)
    streams = rs.new_streams(rng, n)
    w = rng.normal(0.0, 0.1, n)
    turn, u, retry = np.empty(n), np.empty(n), np.zeros(n, dtype=bool)
    expected_streams, expected_turn, expected_u = streams.copy(), np.empty(n), np.empty(n)
    _scalar_jitter_and_uniforms(expected_streams, w, 0.3, expected_turn, expected_u)
    _jitter_and_chain_draws(streams, w, 0.3, turn, u, retry)
    assert 0 < retry.sum() < n // 20  # some rejected tries took the scalar path
    np.testing.assert_array_equal(streams, expected_streams)
    np.testing.assert_array_equal(turn, expected_turn)
    np.testing.assert_array_equal(u, expected_u)


# ----------------------------------------------------------------------------- baseline


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_baseline_moments(path):
    n, sigma, dt = 100_000, 0.7, 4.0
    p = particles_at(n)
    x0, y0 = p.x.copy(), p.y.copy()
    heading0 = p.heading.copy()
    motion = BaselineMotion(sigma)
    if path == "numpy":
        motion.propagate(np.random.default_rng(3), p, dt)
    else:
        advance(motion, p, 1, dt)
    dx, dy = p.x - x0, p.y - y0
    sd = sigma * np.sqrt(dt)
    assert stats.kstest(dx / sd, "norm").pvalue > 1e-3
    assert stats.kstest(dy / sd, "norm").pvalue > 1e-3
    np.testing.assert_allclose(p.speed * dt, np.hypot(dx, dy), rtol=1e-12)
    np.testing.assert_allclose(p.heading, np.arctan2(dy, dx), atol=1e-12)
    turn = (p.heading - heading0 + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(p.turn_rate * dt, turn, atol=1e-9)
    assert p.speed.mean() == pytest.approx(sd * np.sqrt(np.pi / 2) / dt, rel=0.01)


def test_baseline_and_velocity_spread_does_not_depend_on_step():
    """sigma is per sqrt(second): 12 steps of 1 s spread like 3 steps of 4 s."""
    spread = {}
    for dt in (1.0, 4.0):
        p = particles_at(40_000)
        x0 = p.x.copy()
        advance(BaselineMotion(0.5), p, int(12 / dt), dt, seed=int(dt))
        spread[dt] = np.var(p.x - x0)
    assert spread[1.0] == pytest.approx(0.25 * 12, rel=0.03)
    assert spread[4.0] == pytest.approx(0.25 * 12, rel=0.03)


def test_velocity_increments_have_the_given_spread():
    p = particles_at(100_000, speed=1.0, turn_rate=0.01)
    advance(VelocityMotion(sigma_speed=0.3, sigma_turn_rate=0.02), p, 4, 1.0)
    assert np.std(p.speed) == pytest.approx(0.3 * 2, rel=0.02)
    assert np.mean(p.speed) == pytest.approx(1.0, abs=0.01)
    assert np.std(p.turn_rate) == pytest.approx(0.02 * 2, rel=0.02)


# ----------------------------------------------------------------------------- HMM


@pytest.mark.parametrize("variant", ["paper", "time_consistent"])
@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_hmm_long_run_state_frequencies_are_stationary(variant, path):
    model = movement_model(dt=3.0)
    motion = HMMMotion(model, variant)
    n = 20_000
    p = particles_at(n)
    rng = np.random.default_rng(4)
    motion.initialise(rng, p)
    p.state[:] = 0  # start far from the stationary distribution
    if path == "numpy":
        for _ in range(60):
            motion.propagate(rng, p, 1.0)
    else:
        advance(motion, p, 60, 1.0)
    stationary = model.stationary()
    frequencies = np.bincount(p.state, minlength=2) / n
    standard_error = np.sqrt(stationary * (1 - stationary) / n)
    assert np.all(np.abs(frequencies - stationary) < 4 * standard_error)


def test_hmm_speed_and_turn_rate_come_from_the_state_distributions():
    model = movement_model(dt=5.0, transition=np.eye(2))
    motion = HMMMotion(model, "paper")
    p = particles_at(40_000)
    motion.initialise(np.random.default_rng(1), p)
    advance(motion, p, 1, 1.0)
    for k in range(2):
        in_state = p.state == k
        step = p.speed[in_state] * model.dt
        angle = p.turn_rate[in_state] * model.dt
        assert (
            stats.kstest(step, "gamma", args=(model.step.shape[k], 0, model.step.scale[k])).pvalue
            > 1e-3
        )
        assert stats.kstest(angle, stats.vonmises(model.angle.concentration[k]).cdf).pvalue > 1e-3


def _displacements(variant, dt, horizon=60.0, n=20_000, seed=0, fitted_dt=10.0, synchronised=False):
    """Positions after ``horizon`` s from the origin; ``synchronised``: every particle draws
    speed and turn rate at the first step (draw clocks at ``inf``, as the paper's variant)."""
    motion = HMMMotion(movement_model(dt=fitted_dt), variant)
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=np.zeros(n))
    motion.initialise(np.random.default_rng(seed), p)
    if synchronised:
        p.time_since_draw[:] = np.inf
    advance(motion, p, int(round(horizon / dt)), dt, seed=seed + 1)
    return p.x, p.y


def test_time_consistent_displacement_statistics_do_not_depend_on_the_prediction_step():
    reference = _displacements("time_consistent", 1.0, seed=10)
    msd_reference = np.mean(reference[0] ** 2 + reference[1] ** 2)
    for i, dt in enumerate((2.0, 5.0, 20.0)):
        x, y = _displacements("time_consistent", dt, seed=20 + i)
        msd = np.mean(x**2 + y**2)
        assert msd == pytest.approx(msd_reference, rel=0.03), dt
        assert np.mean(x) == pytest.approx(np.mean(reference[0]), rel=0.03), dt
        assert stats.ks_2samp(np.hypot(x, y), np.hypot(*reference)).pvalue > 1e-3, dt


def test_time_consistent_steps_that_do_not_divide_the_fitted_step_stay_close():
    """Fitted at 2.5 s: 0.5 s steps are exact; 1, 2 and 3 s steps redraw at the first step
    boundary after 2.5 s (carrying the excess), which keeps the spread within a few %."""
    x, y = _displacements("time_consistent", 0.5, seed=40, fitted_dt=2.5)
    reference = np.mean(x**2 + y**2)
    for i, dt in enumerate((1.0, 2.0, 3.0)):
        x, y = _displacements("time_consistent", dt, seed=41 + i, fitted_dt=2.5)
        assert np.mean(x**2 + y**2) == pytest.approx(reference, rel=0.03), dt


def test_paper_variant_is_the_fitted_model_only_at_the_fitted_step():
    """At the fitted step both variants are one process (same draws, same paths); at 1 s the
    paper's variant moves differently -- the contrast that motivates the time-consistent one."""
    paper = _displacements("paper", 10.0, seed=30)
    consistent = _displacements("time_consistent", 10.0, seed=30, synchronised=True)
    np.testing.assert_array_equal(paper[0], consistent[0])
    np.testing.assert_array_equal(paper[1], consistent[1])
    x1, y1 = _displacements("paper", 1.0, seed=31)
    # many times the 3 % tolerance of the time-consistent test above
    assert np.mean(paper[0] ** 2 + paper[1] ** 2) > 1.4 * np.mean(x1**2 + y1**2)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_time_consistent_draw_clocks_start_staggered_and_stay_staggered(path):
    """The draw clocks start uniform on [0, model.dt) (the renewal process's stationary
    phase) with speed and turn rate already drawn, so about N dt / model.dt particles redraw
    at every step, never all at once (all at the first step, then in lock-step, without)."""
    model = movement_model(dt=10.0, transition=np.eye(2))
    motion = HMMMotion(model, "time_consistent")
    n = 20_000
    p = particles_at(n)
    rng = np.random.default_rng(5)
    motion.initialise(rng, p)
    assert stats.kstest(p.time_since_draw / model.dt, "uniform").pvalue > 1e-3
    for k in range(2):
        step = p.speed[p.state == k] * model.dt
        law = stats.gamma(model.step.shape[k], scale=model.step.scale[k])
        assert stats.kstest(step, law.cdf).pvalue > 1e-3
    streams = rs.new_streams(np.random.default_rng(6), n)
    redraws = []
    for _ in range(25):
        before = p.time_since_draw.copy()
        if path == "numpy":
            motion.propagate(rng, p, 1.0)
        else:
            motion.advance(p, streams, 1, 1.0, p.normalised_weights(), (0.0, 0.0))
        redraws.append(np.count_nonzero(p.time_since_draw < before))
    # a draw falls due at the end of a step and is made at the start of the next one, so
    # none at the first step, then binomial(n, 1/10) per step: mean 2000, sd 42
    assert redraws[0] == 0
    assert np.all(np.abs(np.array(redraws[1:]) - n / 10) < 6 * np.sqrt(n * 0.09)), redraws
    paper = particles_at(100)
    HMMMotion(model, "paper").initialise(rng, paper)
    assert np.all(np.isinf(paper.time_since_draw))


@pytest.mark.parametrize(("path", "dt"), [("numpy", 1.0), ("compiled", 1.0), ("compiled", 5.0)])
def test_heading_diffusion_adds_a_heading_random_walk(path, dt):
    """A straight, fixed-speed model: the heading after T s is N(0, sigma^2 T) whatever the
    prediction step, and positions stay on the model's path length."""
    model = movement_model(dt=10.0, transition=np.eye(2), step_sd=(1e-9, 1e-9), kappa=(1e12, 1e12))
    sigma, horizon, n = 0.05, 60.0, 20_000
    motion = HMMMotion(model, "time_consistent", heading_diffusion=sigma)
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=np.zeros(n))
    rng = np.random.default_rng(7)
    motion.initialise(rng, p)
    steps = int(horizon / dt)
    if path == "numpy":
        for _ in range(steps):
            motion.propagate(rng, p, dt)
    else:
        advance(motion, p, steps, dt, seed=8)
    assert np.var(p.heading) == pytest.approx(sigma**2 * horizon, rel=0.04)
    assert stats.kstest(p.heading / (sigma * np.sqrt(horizon)), "norm").pvalue > 1e-3
    # a curved path is shorter end to end than its length, never longer
    assert np.all(np.hypot(p.x, p.y) <= p.speed * horizon * (1 + 1e-9))
    with pytest.raises(ValueError, match="heading_diffusion"):
        HMMMotion(model, heading_diffusion=-0.1)


def test_matrix_root_and_its_fallback():
    root = transition_for_step(TRANSITION, 0.2)
    np.testing.assert_allclose(np.linalg.matrix_power(root, 5), TRANSITION, atol=1e-12)
    assert np.all(root >= 0)
    np.testing.assert_allclose(root.sum(axis=1), 1.0)
    np.testing.assert_array_equal(transition_for_step(TRANSITION, 2.0), TRANSITION @ TRANSITION)
    flip = np.array([[0.1, 0.9], [0.9, 0.1]])  # eigenvalue -0.8: no real stochastic root
    with pytest.warns(UserWarning, match="not embeddable"):
        fallback = transition_for_step(flip, 0.5)
    assert np.all(fallback >= 0)
    np.testing.assert_allclose(fallback.sum(axis=1), 1.0)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_steps_fitted_in_kilometres_become_metres_per_second(path):
    metres = movement_model(dt=5.0, transition=np.eye(2))
    kilometres = dataclasses.replace(
        metres,
        step=Gamma(mean=metres.step.mean / 1000, sd=metres.step.sd / 1000),
        step_unit="km",
    )
    speeds = []
    for model in (metres, kilometres):
        motion = HMMMotion(model)
        p = particles_at(2000)
        motion.initialise(np.random.default_rng(1), p)
        if path == "numpy":
            motion.propagate(np.random.default_rng(2), p, 1.0)
        else:
            advance(motion, p, 1, 1.0)
        speeds.append(p.speed)
    np.testing.assert_allclose(speeds[1], speeds[0], rtol=1e-9)


def test_bad_models_are_refused():
    with pytest.raises(ValueError, match="variant"):
        HMMMotion(movement_model(), "fast")
    with pytest.raises(ValueError, match="time step"):
        HMMMotion(movement_model(dt=float("nan")))
    with pytest.raises(ValueError, match="sigma"):
        BaselineMotion(sigma=-1.0)
    with pytest.raises(ValueError, match="'miles'"):
        HMMMotion(dataclasses.replace(movement_model(), step_unit="miles"))
