"""How far the velocity model's cloud carries a heading (``VelocityMotion``'s turn-rate walk),
against the walk's exact expectation: under the paper's 0.02 rad/s per √s a cloud circles on
the spot within a receiver's silence (reports/decisions.md, "The velocity model's circling
cloud")."""

import numpy as np
import pytest

from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.motion import VelocityMotion, motion_model
from hmmtrack.tracking.particles import Particles

#: the paper's velocity model (turn-rate walk 0.02 rad/s per √s)
PAPER = motion_model("velocity")
#: the arm measured against it (half the turn-rate walk, a small speed walk with jumps)
HALF_TURN = VelocityMotion(0.03, 0.01, 1 / 60, 0.4)


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


@pytest.mark.parametrize("motion", [PAPER, HALF_TURN], ids=["paper", "half-turn"])
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


def test_the_paper_models_cloud_circles():
    """Within the 160 s of a silent receiver the paper's turn-rate walk carries a 1.5 m/s
    particle about 30 m along its heading, 1/8 of its path, and never more than 33 m; half
    the walk, about 50 m."""
    path = 1.5 * 160
    paper = expected_reach(PAPER.sigma_turn_rate, 1.5, 160)
    half = expected_reach(HALF_TURN.sigma_turn_rate, 1.5, 160)
    assert 0.1 * path < paper < 0.15 * path
    assert 1.5 * paper < half < 0.25 * path
    # the walk's continuous-time limit: v * Gamma(4/3) * (6 / sigma^2)^(1/3) as T -> inf
    limit = 1.5 * 0.8930 * (6 / PAPER.sigma_turn_rate**2) ** (1 / 3)
    assert paper == pytest.approx(limit, rel=0.05)
