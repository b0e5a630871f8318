"""How far the velocity model's cloud carries a heading (``VelocityMotion``'s turn-rate walk,
or its turn rate that reverts to zero), against the exact expectation: under the paper's
0.02 rad/s per √s walk a cloud circles on the spot within a receiver's silence
(reports/decisions.md, "The velocity model's circling cloud"); a reverting turn rate carries
the heading."""

import numpy as np
import pytest

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.motion import VelocityMotion, motion_model
from hmmtrack.tracking.particles import Particles

#: the paper's velocity model (turn-rate walk 0.02 rad/s per √s)
PAPER = motion_model("velocity")
#: the arm measured against it (half the turn-rate walk, a small speed walk with jumps)
HALF_TURN = VelocityMotion(0.03, 0.01, 1 / 60, 0.4)
#: the paper's turn-rate sd with a turn rate that reverts to zero in 10 s (Ornstein-Uhlenbeck)
REVERTING = VelocityMotion(0.1, 0.02, turn_reversion=10.0)


def turn_covariance(motion, steps):
    """The covariance ``(steps, steps)`` of the turn rates ``w_1..w_steps`` over 1-s steps
    from turn rate 0: ``w_k = a w_{k-1} + c Z_k`` (``(a, c) = motion.turn_step(1)``), so
    ``Cov(w_i, w_l) = c^2 a^{|i-l|} sum_{j < min(i, l)} a^{2j}``; for the walk (``a = 1``)
    ``c^2 min(i, l)``."""
    decay, scale = motion.turn_step(1.0)
    i = np.arange(1, steps + 1)
    common = np.minimum.outer(i, i)
    geometric = np.cumsum(decay ** (2.0 * np.arange(steps)))  # sum_{j < m} a^{2j}, m = 1..
    return scale**2 * decay ** np.abs(np.subtract.outer(i, i)) * geometric[common - 1]


def expected_reach(motion, speed, steps):
    """The exact expected displacement (m) along the initial heading after ``steps`` 1-s
    steps of a particle that starts at ``speed`` with turn rate 0.

    Step ``k`` (1..n) moves along the arc of turn rate ``w_k`` from heading
    ``h_{k-1} = w_1 + ... + w_{k-1}``, at a speed of mean ``speed`` independent of the
    headings (the speed's walk and jumps have mean 0). At the arc's fraction ``s`` the
    heading is Gaussian with mean 0 and variance ``A_k + 2 s B_k + s^2 C_kk`` (``C`` of
    :func:`turn_covariance`, ``A_k`` the sum of ``C`` over ``i, l < k``, ``B_k`` of ``C_ik``
    over ``i < k``; for the walk ``sigma^2 (A_k + 2 s B_k + s^2 k)`` with
    ``A_k = sum_{i,l<k} min(i, l)``, ``B_k = sum_{i<k} i``), and ``E cos = exp(-variance / 2)``;
    the arc's integral over ``s`` is taken by Gauss-Legendre quadrature."""
    nodes, weights = np.polynomial.legendre.leggauss(16)
    s, ws = (nodes + 1) / 2, weights / 2
    c = turn_covariance(motion, steps)
    reach = 0.0
    for k in range(1, steps + 1):
        a = float(c[: k - 1, : k - 1].sum())
        b = float(c[: k - 1, k - 1].sum())
        variance = a + 2 * s * b + s**2 * c[k - 1, k - 1]
        reach += speed * float(ws @ np.exp(-variance / 2))
    return reach


@pytest.mark.parametrize(
    "motion", [PAPER, HALF_TURN, REVERTING], ids=["paper", "half-turn", "reverting"]
)
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
    exact = expected_reach(motion, speed, steps)
    for got, want in ((p.x, exact), (p.y, 0.0)):
        assert abs(got.mean() - want) < 4 * got.std() / np.sqrt(n)


def test_the_paper_models_cloud_circles():
    """Within the 160 s of a silent receiver the paper's turn-rate walk carries a 1.5 m/s
    particle about 30 m along its heading, 1/8 of its path, and never more than 33 m; half
    the walk, about 50 m."""
    path = 1.5 * 160
    paper = expected_reach(PAPER, 1.5, 160)
    half = expected_reach(HALF_TURN, 1.5, 160)
    assert 0.1 * path < paper < 0.15 * path
    assert 1.5 * paper < half < 0.25 * path
    # the walk's continuous-time limit: v * Gamma(4/3) * (6 / sigma^2)^(1/3) as T -> inf
    limit = 1.5 * 0.8930 * (6 / PAPER.sigma_turn_rate**2) ** (1 / 3)
    assert paper == pytest.approx(limit, rel=0.05)


def test_a_reverting_turn_rate_carries_the_heading():
    """With the turn rate reverting to zero the heading diffuses (variance
    ``sigma^2 tau^2 (t - 2 tau (1 - e^{-t/tau}) + tau (1 - e^{-2t/tau}) / 2)``, ``t^3``-like
    only for ``t << tau``), so the reach grows with the path: within 160 s at 1.5 m/s, about
    92 m at tau = 10 s and 171 m at tau = 5 s against the walk's 32 m; the discrete steps'
    reach is the continuous one's within 5 %, and tau -> infinity is the walk."""
    sigma, speed, horizon = PAPER.sigma_turn_rate, 1.5, 160

    def continuous(tau):
        t = np.linspace(0.0, horizon, 16_001)
        e1, e2 = -np.expm1(-t / tau), -np.expm1(-2 * t / tau)
        variance = sigma**2 * tau**2 * (t - 2 * tau * e1 + tau * e2 / 2)
        return np.trapezoid(speed * np.exp(-variance / 2), t)

    walk = expected_reach(PAPER, speed, horizon)
    for tau, near in ((10.0, 92.0), (5.0, 171.0)):
        reach = expected_reach(VelocityMotion(0.1, sigma, turn_reversion=tau), speed, horizon)
        assert reach == pytest.approx(continuous(tau), rel=0.05)
        assert reach == pytest.approx(near, rel=0.05)
        assert reach > 2.5 * walk
    assert expected_reach(VelocityMotion(0.1, sigma, turn_reversion=1e7), speed, horizon) == (
        pytest.approx(walk, rel=1e-4)
    )
