"""Conformance of every registered motion model to :class:`hmmtrack.tracking.motion.MotionModel`.

Each case is a model as :func:`hmmtrack.tracking.motion.motion_model` makes it (the bundled
white-shark HMM in both variants, with and without its resting state). Exact agreement of
the compiled path with the NumPy path, draw by draw, is established in ``test_motion.py``
for the baseline and velocity models; here it is checked again on the registered models,
and in distribution for the HMM (whose two paths draw differently).
"""

import dataclasses

import numpy as np
import pytest
from scipy import stats

from hmmtrack.hmm import MovementHMM
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.motion import (
    HMM_RESTING,
    MOTIONS,
    BaselineMotion,
    HMMMotion,
    MotionModel,
    VelocityMotion,
    bundled_model_path,
    motion_model,
)
from hmmtrack.tracking.motion.arcs import arc_displacement
from hmmtrack.tracking.particles import Particles

BOUNDS = (-500.0, 500.0, -300.0, 300.0)
FIELDS = ("x", "y", "heading", "cos_heading", "sin_heading", "speed", "turn_rate", "state")

CASES = {
    "baseline": ("baseline", {}),
    "velocity": ("velocity", {}),
    "hmm time_consistent, resting": ("hmm", {}),
    "hmm time_consistent": ("hmm", {"resting": None}),
    "hmm paper": ("hmm", {"variant": "paper"}),
    "hmm paper, resting": ("hmm", {"variant": "paper", "resting": HMM_RESTING}),
}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    name, options = CASES[request.param]
    return request.param, motion_model(name, **options)


def started(motion, n=2000, seed=0):
    """``n`` particles uniform in the box with the model's motion fields set."""
    rng = np.random.default_rng(seed)
    p = Particles.uniform(rng, n, BOUNDS)
    motion.initialise(rng, p)
    return p


def advance(motion, p, n_steps, dt, seed=1, origin=(0.0, 0.0), threads=None):
    streams = rs.new_streams(np.random.default_rng(seed), p.n)
    moments = motion.advance(p, streams, n_steps, dt, p.normalised_weights(), origin, threads)
    return moments, streams


def assert_same_particles(a, b):
    for name in (*FIELDS, "time_since_draw"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_the_cases_cover_every_registered_model():
    assert {name for name, _ in CASES.values()} == set(MOTIONS)
    for name, factory in MOTIONS.items():
        assert isinstance(factory(), MotionModel), name


def test_satisfies_the_protocol(case):
    label, motion = case
    assert isinstance(motion, MotionModel)
    assert motion.compiled is True  # gamma steps and von Mises angles for the HMM
    expected = {"baseline": BaselineMotion, "velocity": VelocityMotion}.get(label, HMMMotion)
    assert type(motion) is expected
    if label.startswith("hmm"):
        bundled = MovementHMM.load(bundled_model_path()).n_states
        resting = "resting" in label
        assert motion.model.n_states == bundled + resting
        assert motion.variant == ("paper" if "paper" in label else "time_consistent")


def test_initialise_sets_finite_fields_of_shape_n(case):
    label, motion = case
    p = started(motion, n=3000)
    for name in FIELDS:
        value = getattr(p, name)
        assert value.shape == (3000,), name
        assert np.all(np.isfinite(value)), name
    np.testing.assert_allclose(p.cos_heading**2 + p.sin_heading**2, 1.0, atol=1e-12)
    # the draw clock: finite in [0, model.dt) in the time-consistent variant, +inf (draw at
    # the first step) in the paper's; unused by the others
    assert not np.any(np.isnan(p.time_since_draw)) and np.all(p.time_since_draw >= 0)
    if label.startswith("hmm"):
        assert np.all((p.state >= 0) & (p.state < motion.model.n_states))
        assert np.all(p.speed >= 0)
        if "paper" in label:
            assert np.all(np.isinf(p.time_since_draw))
        else:
            assert np.all(p.time_since_draw < motion.model.dt)
        if "resting" in label:  # some particles start in the resting state (20 % prior)
            share = np.mean(p.state == motion.model.n_states - 1)
            assert 0.15 < share < 0.25
    else:  # at rest, as in the paper's Algorithm 1
        assert np.all(p.speed == 0) and np.all(p.turn_rate == 0)


def test_propagate_keeps_shapes_and_finiteness(case):
    _, motion = case
    p = started(motion)
    rng = np.random.default_rng(2)
    for dt in (1.0, 1.0, 5.0, 0.5):
        motion.propagate(rng, p, dt)
    for name in FIELDS:
        value = getattr(p, name)
        assert value.shape == (p.n,), name
        assert np.all(np.isfinite(value)), name
    assert -np.pi <= p.heading.min() and p.heading.max() <= np.pi
    np.testing.assert_allclose(p.cos_heading, np.cos(p.heading), atol=1e-9)
    np.testing.assert_allclose(p.sin_heading, np.sin(p.heading), atol=1e-9)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_moves_are_those_of_the_model(case, path):
    """Baseline: Gaussian steps of spread ``sigma sqrt(dt)``. Velocity and HMM: a move along
    an arc of the speed and turn rate the step leaves (its chord never longer than the arc);
    without heading diffusion exactly the arc of :func:`arc_displacement`."""
    label, motion = case
    dt = 4.0
    p = started(motion, n=20_000)
    before = p.copy()
    if path == "numpy":
        motion.propagate(np.random.default_rng(3), p, dt)
    else:
        advance(motion, p, 1, dt)
    dx, dy = p.x - before.x, p.y - before.y
    if label == "baseline":
        spread = motion.sigma * np.sqrt(dt)
        assert np.std(dx) == pytest.approx(spread, rel=0.03)
        assert np.std(dy) == pytest.approx(spread, rel=0.03)
        assert np.mean(dx) == pytest.approx(0.0, abs=4 * spread / np.sqrt(p.n))
        np.testing.assert_allclose(p.speed * dt, np.hypot(dx, dy), rtol=0, atol=1e-12)
        return
    chord = np.hypot(dx, dy)
    assert np.all(chord <= np.abs(p.speed) * dt * (1 + 1e-9) + 1e-9)
    if label == "velocity":
        assert np.std(p.speed - before.speed) == pytest.approx(
            motion.sigma_speed * np.sqrt(dt), rel=0.03
        )
        assert np.std(p.turn_rate - before.turn_rate) == pytest.approx(
            motion.sigma_turn_rate * np.sqrt(dt), rel=0.03
        )
    if label == "velocity" or "paper" in label:  # one arc of the speed and turn rate left
        arc_x, arc_y = arc_displacement(
            before.cos_heading, before.sin_heading, p.speed * dt, p.turn_rate * dt
        )
        np.testing.assert_allclose(dx, arc_x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(dy, arc_y, rtol=0, atol=1e-9)


@pytest.mark.parametrize("path", ["numpy", "compiled"])
def test_velocity_without_noise_moves_v_dt_along_the_heading(path):
    motion = dataclasses.replace(motion_model("velocity"), sigma_speed=0.0, sigma_turn_rate=0.0)
    heading = np.linspace(-3.0, 3.0, 50)
    p = Particles.from_state(x=np.full(50, 7.0), y=np.full(50, -2.0), heading=heading, speed=1.3)
    if path == "numpy":
        motion.propagate(np.random.default_rng(0), p, 2.5)
    else:
        advance(motion, p, 1, 2.5)
    np.testing.assert_allclose(p.x, 7.0 + 1.3 * 2.5 * np.cos(heading), rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.y, -2.0 + 1.3 * 2.5 * np.sin(heading), rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.heading, heading, rtol=0, atol=1e-12)


def test_advance_returns_the_weighted_moments_after_every_step(case):
    _, motion = case
    p = started(motion)
    weights = np.random.default_rng(4).dirichlet(np.ones(p.n))
    origin = (12.0, -30.0)
    streams = rs.new_streams(np.random.default_rng(5), p.n)
    rows = []
    for _ in range(3):  # step by step: the moments of each call's last step
        rows.append(motion.advance(p, streams, 1, 1.0, weights, origin)[-1])
        dx, dy = p.x - origin[0], p.y - origin[1]
        expected = weights @ np.column_stack([dx, dy, dx**2, dy**2, dx * dy])
        np.testing.assert_allclose(rows[-1], expected, rtol=1e-10)
    fused = started(motion)
    moments = motion.advance(
        fused, rs.new_streams(np.random.default_rng(5), p.n), 3, 1.0, weights, origin
    )
    assert moments.shape == (3, 5)
    # one call of three steps = three calls of one (up to the headings' renormalisation at
    # the end of each call)
    np.testing.assert_allclose(moments, np.array(rows), rtol=1e-9)
    np.testing.assert_array_equal(fused.state, p.state)
    np.testing.assert_allclose(fused.x, p.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fused.y, p.y, rtol=0, atol=1e-9)


def test_compiled_advance_agrees_with_numpy_propagate(case):
    """Baseline and velocity: the same particles from the same draws. HMM: the same law of
    the displacements and states after 90 s (different draws)."""
    label, motion = case
    if label in ("baseline", "velocity"):
        compiled = started(motion, n=500)
        reference = compiled.copy()
        streams = rs.new_streams(np.random.default_rng(6), compiled.n)
        draws = streams.copy()
        motion.advance(compiled, streams, 4, 2.0, compiled.normalised_weights(), (0.0, 0.0))
        for _ in range(4):
            motion.apply(reference, 2.0, rs.draw_normal_pairs(draws))
        np.testing.assert_array_equal(streams, draws)
        for name in ("x", "y", "speed", "turn_rate", "cos_heading", "sin_heading", "heading"):
            np.testing.assert_allclose(getattr(compiled, name), getattr(reference, name), atol=1e-9)
        return
    n, horizon = 8000, 90
    compiled = started(motion, n=n, seed=7)
    reference = started(motion, n=n, seed=8)
    start_c, start_r = (
        (compiled.x.copy(), compiled.y.copy()),
        (reference.x.copy(), reference.y.copy()),
    )
    advance(motion, compiled, horizon, 1.0, seed=9)
    rng = np.random.default_rng(10)
    for _ in range(horizon):
        motion.propagate(rng, reference, 1.0)
    distance_c = np.hypot(compiled.x - start_c[0], compiled.y - start_c[1])
    distance_r = np.hypot(reference.x - start_r[0], reference.y - start_r[1])
    assert stats.ks_2samp(distance_c, distance_r).pvalue > 1e-3
    assert stats.ks_2samp(compiled.speed, reference.speed).pvalue > 1e-3
    k = motion.model.n_states
    counts = np.array(
        [np.bincount(compiled.state, minlength=k), np.bincount(reference.state, minlength=k)]
    )
    assert stats.chi2_contingency(counts).pvalue > 1e-3


def test_same_seed_same_answer(case):
    _, motion = case
    runs = []
    for threads in (1, 2):
        numpy_path = started(motion)
        rng = np.random.default_rng(11)
        for _ in range(3):
            motion.propagate(rng, numpy_path, 1.0)
        compiled = started(motion, n=5000)  # 5 chunks: threads share them
        moments, streams = advance(motion, compiled, 5, 1.0, seed=12, threads=threads)
        runs.append((numpy_path, compiled, moments, streams))
    (numpy_1, compiled_1, moments_1, streams_1), (numpy_2, compiled_2, moments_2, streams_2) = runs
    assert_same_particles(numpy_1, numpy_2)
    assert_same_particles(compiled_1, compiled_2)
    np.testing.assert_array_equal(moments_1, moments_2)
    np.testing.assert_array_equal(streams_1, streams_2)
