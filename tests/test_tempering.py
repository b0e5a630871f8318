"""The tempered correction's trigger (:class:`hmmtrack.tracking.tempering.Tempered`): a
correction that keeps enough particles in one pass is the plain one, a sharper one is
tempered exactly as without a trigger; its moves within a mixture's components keep two
modes apart."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.mixture import Mixture
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.resampling import effective_sample_size
from hmmtrack.tracking.tempering import (
    Plain,
    Tempered,
    _metropolis,
    regularisation_move,
    regularisation_move_within,
    silverman_bandwidth,
)

N = 500
BOX = (-100.0, 100.0, -100.0, 100.0)


class PointToy:
    """``z = x + N(0, sd²)``: the likelihood's sd against the 200-m box sets the one-pass ESS."""

    def __init__(self, sd: float):
        self.sd = sd

    def loglik(self, particles, obs, time=None):
        z = np.asarray(obs["z"], dtype=float)
        return -0.5 * (((particles.x[:, None] - z) / self.sd) ** 2).sum(axis=1)


class Impossible(PointToy):
    """Every particle impossible (degenerate weights); the recovery weighs the particles by
    the point itself, keeping fewer than 5 % of them."""

    def loglik(self, particles, obs, time=None):
        return np.full(particles.n, -np.inf)

    def recover(self, particles, obs, time, rng):
        particles.log_weight = super().loglik(particles, obs)
        return "weighed by the point"


def corrected(correction, sd: float, seed: int = 3, toy=PointToy):
    """The particles and the estimate after one correction of fresh particles."""
    pf = ParticleFilter(BaselineMotion(1.0), toy(sd), N, BOX, rng=seed, correction=correction)
    pf.initialise(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        estimate = pf.correct(pd.DataFrame({"time": [0.0], "z": [20.0]}))
    return pf.particles, estimate


def one_pass_ess(sd: float, seed: int = 3) -> float:
    particles, _ = corrected(Plain(), sd, seed)
    return effective_sample_size(particles.log_weight) / N


def test_trigger_must_lie_in_zero_to_ess():
    with pytest.raises(ValueError, match="trigger"):
        Tempered(0.5, 0.6)
    with pytest.raises(ValueError, match="trigger"):
        Tempered(0.5, 0.0)
    assert Tempered(0.5, 0.5).trigger == 0.5


def test_between_trigger_and_ess_the_correction_is_plain():
    """One-pass ESS between the trigger (5 %) and ``ess`` (50 %): no resampling, no move;
    log weights and estimate equal the plain correction's; without the trigger the same
    correction is tempered (the positions move)."""
    sd = 15.0
    assert 0.05 < one_pass_ess(sd) < 0.5
    plain, plain_estimate = corrected(Plain(), sd)
    triggered, estimate = corrected(Tempered(0.5, 0.05), sd)
    np.testing.assert_array_equal(triggered.x, plain.x)
    np.testing.assert_array_equal(triggered.log_weight, plain.log_weight)
    assert estimate == plain_estimate
    tempered, _ = corrected(Tempered(0.5), sd)
    assert not np.array_equal(tempered.x, plain.x)


def test_below_the_trigger_the_correction_is_tempered_as_without_one():
    """One-pass ESS under the trigger: the same steps, draws and result as ``Tempered(ess)``,
    which keeps at least ``ess`` of the particles (the final weights' ESS)."""
    sd = 1.0
    assert one_pass_ess(sd) < 0.05
    triggered, estimate = corrected(Tempered(0.5, 0.05), sd)
    tempered, want = corrected(Tempered(0.5), sd)
    for name in ("x", "y", "log_weight"):
        np.testing.assert_array_equal(getattr(triggered, name), getattr(tempered, name))
    assert estimate == want
    assert effective_sample_size(triggered.log_weight) >= 0.5 * N * (1 - 1e-3)
    assert estimate.x == pytest.approx(20.0, abs=1.0)


def test_degenerate_weights_are_recovered_as_by_the_plain_correction():
    """The recovery's weights are kept even when they hold fewer than the trigger's share."""
    plain, want = corrected(Plain(), 1.0, toy=Impossible)
    triggered, estimate = corrected(Tempered(0.5, 0.05), 1.0, toy=Impossible)
    for name in ("x", "y", "log_weight"):
        np.testing.assert_array_equal(getattr(triggered, name), getattr(plain, name))
    assert estimate == want
    assert estimate.n_eff < 0.05 * N


def test_a_move_is_kept_with_the_metropolis_probability_of_the_powers_applied():
    """``_metropolis``: a move that gains likelihood is always kept, one that loses 1e9
    nats never, and one that loses ``log(1/0.3) / applied`` nats three times in ten (a
    binomial count within five sds); the log-likelihood returned is that of the kept
    places, and a rejection is reported (the measurement last scored the moved places)."""
    n = 20_000
    before_x, before_y = np.zeros(n), np.zeros(n)
    old = np.zeros(n)
    applied = 0.4
    for change, share in [(1.0, 1.0), (-1e9, 0.0), (np.log(0.3) / applied, 0.3)]:
        p = SimpleNamespace(n=n, x=np.ones(n), y=np.full(n, 2.0))
        pf = SimpleNamespace(particles=p, rng=np.random.default_rng(8))
        moved = np.full(n, change)
        loglik, stale = _metropolis(pf, (before_x, before_y, old), moved, applied)
        kept = p.x == 1.0
        assert np.array_equal(p.y == 2.0, kept)
        assert np.array_equal(loglik, np.where(kept, moved, old))
        assert stale == (share < 1.0)
        assert abs(kept.mean() - share) <= 5 * np.sqrt(share * (1 - share) / n) + 1e-12


def test_accepted_moves_keep_the_tempered_correction_on_the_point():
    """With the Metropolis acceptance the tempered correction still ends on the point and
    keeps at least ``ess`` of the particles."""
    sd = 1.0
    assert one_pass_ess(sd) < 0.05
    particles, estimate = corrected(Tempered(0.5, accept=True), sd)
    assert effective_sample_size(particles.log_weight) >= 0.5 * N * (1 - 1e-3)
    assert estimate.x == pytest.approx(20.0, abs=1.0)


def test_the_move_within_one_component_is_the_whole_clouds():
    rng = np.random.default_rng(5)
    x, y = rng.normal(0.0, 30.0, 400), rng.normal(0.0, 5.0, 400)
    normals = rng.standard_normal((2, 400))
    got = regularisation_move_within(x, y, np.zeros(400, dtype=np.int64), normals)
    want = regularisation_move(x, y, normals, silverman_bandwidth(400))
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def test_each_component_moves_by_its_own_covariance_and_count():
    """Two clusters 1 km apart, labels interleaved: each moves as
    ``bandwidth(N_k) · chol(cov_k) · its own normals`` (numpy's covariance and Cholesky),
    so no particle moves farther than a few of its cluster's sds, where the whole cloud's
    move (its covariance spans the 1 km) throws particles hundreds of metres."""
    rng = np.random.default_rng(7)
    n = 900
    labels = (rng.random(n) < 1 / 3).astype(np.int64)  # about 300 and 600
    x = np.where(labels == 1, 1000.0, 0.0) + rng.normal(0.0, 1.0, n) * np.where(labels, 2, 6)
    y = rng.normal(0.0, 3.0, n) + 0.5 * x * (labels == 0)
    normals = rng.standard_normal((2, n))
    got_x, got_y = regularisation_move_within(x, y, labels, normals)
    for k in (0, 1):
        m = labels == k
        covariance = np.cov(np.vstack([x[m], y[m]])) + 1e-4 * np.eye(2)
        move = silverman_bandwidth(m.sum()) * (np.linalg.cholesky(covariance) @ normals[:, m])
        np.testing.assert_allclose(got_x[m], x[m] + move[0], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(got_y[m], y[m] + move[1], rtol=1e-12, atol=1e-9)
    assert np.max(np.hypot(got_x - x, got_y - y)) < 30.0
    whole_x, _ = regularisation_move(x, y, normals, silverman_bandwidth(n))
    assert np.max(np.abs(whole_x - x)) > 300.0


def test_a_single_particle_component_stays_in_place():
    x, y = np.array([0.0, 1.0, 2.0, 50.0]), np.array([0.0, 1.0, 0.0, 50.0])
    labels = np.array([0, 0, 0, 1])
    got_x, got_y = regularisation_move_within(x, y, labels, np.ones((2, 4)))
    assert (got_x[3], got_y[3]) == (50.0, 50.0)
    assert not np.array_equal(got_x[:3], x[:3])


class Mirror:
    """``z = |x| + N(0, sd²)``: the tag at ``+z`` or its mirror at ``-z``, equally likely."""

    def __init__(self, sd: float):
        self.sd = sd

    def loglik(self, particles, obs, time=None):
        z = np.asarray(obs["z"], dtype=float)
        return -0.5 * (((np.abs(particles.x)[:, None] - z) / self.sd) ** 2).sum(axis=1)


def mirrored(within: bool, seed: int):
    """Weight at ``x > 0``, weight farther than 5 sds from both points, and the components,
    after three tempered corrections of the two-point likelihood (mixture filter, a strip
    200 m long in x)."""
    pf = ParticleFilter(
        BaselineMotion(1.0),
        Mirror(1.0),
        N,
        (-100.0, 100.0, -10.0, 10.0),
        rng=seed,
        correction=Tempered(0.5, within_components=within),
        mixture=Mixture(),
    )
    pf.initialise(0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for step in range(3):
            if step:
                pf.predict(1)
            pf.correct(pd.DataFrame({"time": [float(step)], "z": [40.0]}))
    weights, x = pf.weights()[0], pf.particles.x
    off = np.abs(np.abs(x) - 40.0) > 5.0
    return weights[x > 0].sum(), weights[off].sum(), int(Mixture().labels(pf.particles).max()) + 1


def test_moves_within_components_keep_both_points_and_nothing_between():
    """Oracle: the exact posterior puts half the weight on each point and none 5 sds away.
    Moved within the components, every seed keeps two components, nothing between them and
    each point's weight near one half; moved by the whole cloud (its covariance spans the
    80 m between the points), the moves carry particles between the points, the two never
    part, and a share of the weight stays between them."""
    within = [mirrored(True, seed) for seed in range(10)]
    assert all(components == 2 for _, _, components in within)
    assert max(off for _, off, _ in within) < 1e-3
    assert all(abs(plus - 0.5) < 0.2 for plus, _, _ in within)
    whole = [mirrored(False, seed) for seed in range(10)]
    assert sum(off > 0.1 for _, off, _ in whole) >= 8
