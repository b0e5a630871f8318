"""The velocity model's regimes (``VelocityMotion(regimes=VelocityRegimes(...))``): the switching
chain against its closed forms on the compiled kernel and the NumPy reference, one regime of the
walk as today's model bit for bit, a reverting regime's exact Ornstein-Uhlenbeck law, and the
filter's starts giving every particle a regime."""

import math

import numpy as np
import pytest

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.motion import VelocityMotion, motion_model
from hmmtrack.tracking.motion.regimes import Regime, VelocityRegimes, reverting_step
from hmmtrack.tracking.motion.settings import VelocitySettings
from hmmtrack.tracking.particles import Particles

#: cruise (a turn rate reverting in 5 s), manoeuvre (the paper's walk), still (speed and turn
#: rate reverting to zero); a manoeuvre every 2 min lasting 30 s, a rest every 10 min lasting 2
CRUISE = Regime(0.1, 0.02, turn_reversion=5.0)
MANOEUVRE = Regime(0.1, 0.02)
STILL = Regime(0.02, 0.02, speed_reversion=5.0, turn_reversion=5.0)
RATES = ((0.0, 1 / 120, 1 / 600), (1 / 30, 0.0, 0.0), (1 / 120, 0.0, 0.0))
THREE = VelocityRegimes((CRUISE, MANOEUVRE, STILL), RATES)


def cloud(n, speed=0.0, turn_rate=0.0):
    """``n`` particles at the origin heading east."""
    return Particles.from_state(
        np.zeros(n), np.zeros(n), np.zeros(n), speed=speed, turn_rate=turn_rate
    )


def run(motion, p, n_steps, dt, path, seed=5, each=None):
    """``n_steps`` steps of ``dt`` s on the NumPy or the compiled path, calling ``each(p)``
    after every step; the streams after (None on the NumPy path)."""
    rng = np.random.default_rng(seed)
    streams = rs.new_streams(np.random.default_rng(seed + 1), p.n)
    for _ in range(n_steps):
        if path == "numpy":
            motion.propagate(rng, p, dt)
        else:
            motion.advance(p, streams, 1, dt, p.normalised_weights(), (0.0, 0.0))
        if each is not None:
            each(p)
    return None if path == "numpy" else streams


def test_the_chains_closed_forms_for_two_regimes():
    """Two regimes with rates a (0 -> 1) and b (1 -> 0): stationary (b, a) / (a + b), dwell
    1/a and 1/b, and P_01(dt) = a / (a + b) (1 - exp(-(a + b) dt))."""
    a, b, dt = 1 / 40, 1 / 10, 3.0
    chain = VelocityRegimes((CRUISE, MANOEUVRE), ((0.0, a), (b, 0.0)))
    np.testing.assert_allclose(chain.stationary(), [b / (a + b), a / (a + b)], rtol=1e-12)
    np.testing.assert_allclose(chain.dwell(), [1 / a, 1 / b], rtol=1e-12)
    leave = a / (a + b) * -math.expm1(-(a + b) * dt)
    back = b / (a + b) * -math.expm1(-(a + b) * dt)
    np.testing.assert_allclose(
        chain.transition(dt), [[1 - leave, leave], [back, 1 - back]], rtol=1e-12
    )
    np.testing.assert_allclose(chain.generator().sum(axis=1), 0.0, atol=1e-15)
    # three regimes: the stationary distribution solves pi Q = 0 and is kept by expm(Q dt)
    pi = THREE.stationary()
    np.testing.assert_allclose(pi @ THREE.generator(), 0.0, atol=1e-15)
    np.testing.assert_allclose(pi @ THREE.transition(7.0), pi, rtol=1e-12)
    np.testing.assert_allclose(pi, [0.6896551724137931, 0.1724137931034483, 0.13793103448275862])
    np.testing.assert_allclose(THREE.dwell(), [100.0, 30.0, 120.0])


@pytest.mark.parametrize(("path", "dt"), [("numpy", 1.0), ("compiled", 1.0), ("compiled", 4.0)])
def test_occupancy_and_switching_follow_the_rate_matrix(path, dt):
    """From the stationary start, over 100 steps of 8,000 particles: the share in each regime
    is pi at every step (5 binomial standard errors); given the N_i particle-steps that began
    in regime i, the switches i -> j are Binomial(N_i, P_ij(dt)) with P = expm(Q dt), so the
    exits from i are N_i (1 - P_ii) and the mean time in i between exits dt / (1 - P_ii)
    (5 standard errors; at dt = 1 s within 3 % of the dwell 1 / q_i)."""
    n, n_steps = 8000, 100
    motion = VelocityMotion(0.1, 0.02, regimes=THREE)
    p = cloud(n)
    motion.initialise(np.random.default_rng(3), p)
    pi, matrix = THREE.stationary(), THREE.transition(dt)
    k = pi.size
    counts = np.zeros((k, k))
    occupancy = [np.bincount(p.state, minlength=k)]
    before = [p.state.copy()]

    def record(q):
        np.add.at(counts, (before[0], q.state), 1)
        occupancy.append(np.bincount(q.state, minlength=k))
        before[0] = q.state.copy()

    run(motion, p, n_steps, dt, path, each=record)
    share = np.array(occupancy) / n  # (n_steps + 1, K)
    assert np.all(np.abs(share - pi) < 5 * np.sqrt(pi * (1 - pi) / n))
    began = counts.sum(axis=1, keepdims=True)  # N_i
    expected = began * matrix
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(expected * (1 - matrix)) + 1)
    exits = began[:, 0] - np.diag(counts)
    leave = 1 - np.diag(matrix)
    assert np.all(
        np.abs(exits - began[:, 0] * leave) < 5 * np.sqrt(began[:, 0] * leave * (1 - leave))
    )
    if dt == 1.0:
        np.testing.assert_allclose(dt / leave, THREE.dwell(), rtol=0.03)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
@pytest.mark.parametrize("reversion", [None, 5.0])
def test_one_regime_is_todays_model_bit_for_bit(path, reversion):
    """One regime (nothing switches, nothing extra drawn) of the walk, or of the reverting
    turn rate, moves particles exactly as ``VelocityMotion`` without regimes: positions,
    headings, speeds, turn rates and streams equal to the bit, also with speed jumps."""
    n = 3000
    one = VelocityRegimes((Regime(0.1, 0.02, turn_reversion=reversion),), ((0.0,),))
    results = []
    for motion in (
        VelocityMotion(0.1, 0.02, 1 / 60, 0.4, turn_reversion=reversion),
        VelocityMotion(0.1, 0.02, 1 / 60, 0.4, regimes=one),
    ):
        p = cloud(n, speed=1.0, turn_rate=0.01)
        motion.initialise(np.random.default_rng(1), p)
        streams = run(motion, p, 40, 2.0, path)
        results.append((p, streams))
    (today, today_streams), (regime, regime_streams) = results
    for name in ("x", "y", "heading", "speed", "turn_rate"):
        np.testing.assert_array_equal(getattr(regime, name), getattr(today, name))
    np.testing.assert_array_equal(regime.state, 0)
    if path == "compiled":
        np.testing.assert_array_equal(regime_streams, today_streams)


def test_two_equal_regimes_move_as_one_but_draw_one_uniform_more():
    """Two regimes equal to the walk: the motion's law is the walk's (speed variance
    sigma^2 t), but each step draws the chain's uniform after the normals, so the streams
    (and the draws) differ from today's: the same law, not the same bits."""
    n, n_steps = 20_000, 25
    two = VelocityRegimes((MANOEUVRE, MANOEUVRE), ((0.0, 0.1), (0.1, 0.0)))
    p, q = cloud(n), cloud(n)
    walk_streams = run(VelocityMotion(0.1, 0.02), p, n_steps, 1.0, "compiled")
    two_motion = VelocityMotion(0.1, 0.02, regimes=two)
    two_motion.initialise(np.random.default_rng(2), q)
    two_streams = run(two_motion, q, n_steps, 1.0, "compiled")
    variance = 0.1**2 * n_steps
    for speed in (p.speed, q.speed):
        assert abs(speed.var() - variance) < 4 * variance * math.sqrt(2 / (n - 1))
    assert not np.array_equal(two_streams, walk_streams)
    assert not np.array_equal(q.speed, p.speed)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_a_reverting_regime_has_the_exact_ou_law(path):
    """Two regimes sharing a turn rate reverting in tau = 10 s (sigma 0.02) and a speed
    reverting in 3 s (sigma 0.1) but switching fast: from turn rate 0.1 rad/s and speed 1
    m/s, after 30 s the turn rate's mean and variance are ``turn_reversion``'s closed form,
    omega_0 exp(-t/tau) and sigma^2 tau (1 - exp(-2t/tau)) / 2, and the speed's likewise
    (4 standard errors); regimes or not, the same law."""
    n, n_steps, dt = 40_000, 30, 1.0
    shared = Regime(0.1, 0.02, speed_reversion=3.0, turn_reversion=10.0)
    chain = VelocityRegimes((shared, shared), ((0.0, 0.2), (0.3, 0.0)))
    motion = VelocityMotion(0.1, 0.02, regimes=chain)
    p = cloud(n, speed=1.0, turn_rate=0.1)
    motion.initialise(np.random.default_rng(4), p)
    run(motion, p, n_steps, dt, path)
    t = n_steps * dt
    for values, start, sigma, tau in ((p.turn_rate, 0.1, 0.02, 10.0), (p.speed, 1.0, 0.1, 3.0)):
        mean = start * math.exp(-t / tau)
        variance = sigma**2 * tau * -math.expm1(-2 * t / tau) / 2
        assert abs(values.mean() - mean) < 4 * math.sqrt(variance / n)
        assert abs(values.var() - variance) < 4 * variance * math.sqrt(2 / (n - 1))
    # the one-regime model with turn_reversion: the same turn-rate transition
    assert shared.steps(dt)[2:] == VelocityMotion(0.1, 0.02, turn_reversion=10.0).turn_step(dt)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_each_particle_takes_its_own_regimes_transitions(path):
    """A still regime (speed reverting in 2 s, no noise) and a regime of constant speed and
    turn rate, never left (rates 1e-12/s): particles keep their regimes and only the still
    ones stop (speed 1 -> exp(-20/2)), the others keep 1 m/s exactly."""
    still = Regime(0.0, 0.0, speed_reversion=2.0, turn_reversion=2.0)
    held = Regime(0.0, 0.0)
    regimes = VelocityRegimes((still, held), ((0.0, 1e-12), (1e-12, 0.0)))
    motion = VelocityMotion(0.1, 0.02, regimes=regimes)
    p = cloud(4000, speed=1.0, turn_rate=0.05)
    motion.initialise(np.random.default_rng(6), p)
    start = p.state.copy()
    assert 1500 < np.count_nonzero(start) < 2500  # stationary (1/2, 1/2)
    run(motion, p, 10, 2.0, path)
    np.testing.assert_array_equal(p.state, start)
    np.testing.assert_allclose(p.speed[start == 0], math.exp(-10.0), rtol=1e-12)
    np.testing.assert_array_equal(p.speed[start == 1], 1.0)
    np.testing.assert_array_equal(p.turn_rate[start == 1], 0.05)


def test_reverting_step_is_the_walk_without_reversion():
    assert reverting_step(0.1, None, 4.0) == (1.0, 0.1 * np.sqrt(4.0))
    decay, scale = reverting_step(0.1, 5.0, 4.0)
    assert decay == math.exp(-0.8)
    assert scale == pytest.approx(0.1 * math.sqrt(5.0 * (1 - math.exp(-1.6)) / 2), rel=1e-15)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Regime(-0.1, 0.02), "sigma_speed"),
        (lambda: Regime(0.1, 0.02, speed_reversion=0.0), "speed_reversion"),
        (lambda: VelocityRegimes((CRUISE, STILL), ((0.0, 0.1),)), "rates"),
        (lambda: VelocityRegimes((CRUISE, STILL), ((0.0, -0.1), (0.1, 0.0))), "rates"),
        (lambda: VelocityRegimes((CRUISE, STILL), ((0.0, 0.0), (0.1, 0.0))), "connect"),
        (lambda: VelocityMotion(0.1, 0.02, turn_reversion=5.0, regimes=THREE), "turn_reversion"),
    ],
)
def test_invalid_regimes_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_no_default_path_has_regimes():
    """Off by default: no regimes, and ``initialise`` leaves the particles' state alone."""
    for motion in (motion_model("velocity"), VelocitySettings().build()):
        assert motion.regimes is None
        p = cloud(10)
        p.state = np.full(10, 7, dtype=np.int64)
        motion.initialise(np.random.default_rng(0), p)
        np.testing.assert_array_equal(p.state, 7)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_the_filter_gives_every_particle_a_regime(backend):
    """A filter run with regimes: after ``initialise`` and after degenerate weights (the
    uniform re-initialisation keeps the state field), every particle's state is a regime."""
    motion = VelocityMotion(0.1, 0.02, regimes=THREE)

    class Flat:
        def loglik(self, particles, obs, time=None):
            return np.zeros(particles.n)

    pf = ParticleFilter(motion, Flat(), 500, (0, 100, 0, 100), rng=3, backend=backend)
    pf.initialise(0.0)
    assert set(np.unique(pf.particles.state)) == {0, 1, 2}
    started = pf.particles.state.copy()
    with pytest.warns(RuntimeWarning, match="degenerate_weights"):
        pf._recover(None)
    np.testing.assert_array_equal(pf.particles.state, started)
    pf.predict(30)
    pf.resample()
    assert set(np.unique(pf.particles.state)) <= {0, 1, 2}
    pf.predict(30)
    assert set(np.unique(pf.particles.state)) == {0, 1, 2}
