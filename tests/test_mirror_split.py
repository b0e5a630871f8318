"""The mirror split (hmmtrack.tracking.mirror, hmmtrack.tracking.mixture.split_across) and the
modes joined within ONE_MODE_DISTANCE (hmmtrack.tracking.mixture.join_modes).

Oracles: the side weights are sums NumPy recomputes; the joined moments are the moments of the
union of the particles (component_moments on the joined labels); the reflection across a moving
line keeps both ranges and both range-rates (the measurement's own prediction).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack import scenarios
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.measurement.range_rate import predicted_range_and_rate
from hmmtrack.tracking.mirror import MirrorLine
from hmmtrack.tracking.mixture import (
    ONE_MODE_DISTANCE,
    Mixture,
    Modes,
    component_moments,
    join_modes,
    split_across,
)
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.particles import Particles
from hmmtrack.tracking.receivers import ReceiverTracks

LINE = np.array([0.0, -1.0, 0.0, 1.0])  # the y axis: x < 0 is its left


class FixedLine:
    """A mirror line that does not move (the y axis)."""

    def at(self, time):
        return tuple(LINE)


class Straddle:
    """``z = |x| + N(0, 5²)``: a tag 2 m from the y axis is one cluster across it."""

    columns = ("z",)

    def loglik(self, particles, obs, time=None):
        z = np.asarray(obs["z"], dtype=float)
        return -0.5 * (((np.abs(particles.x)[:, None] - z) / 5.0) ** 2).sum(axis=1)


def cloud(seed, n, centre=(0.0, 0.0), sd=(6.0, 3.0)):
    rng = np.random.default_rng(seed)
    x = rng.normal(centre[0], sd[0], n)
    y = rng.normal(centre[1], sd[1], n)
    weights = rng.random(n)
    return x, y, weights / weights.sum()


def test_a_component_across_the_line_is_split_with_each_sides_weight():
    x, y, weights = cloud(0, 500)
    labels = np.zeros(500, dtype=np.int64)
    new, weight = split_across(x, y, weights, labels, np.array([1.0]), LINE, 4, 0.02, 1e-4)
    left = x < 0
    assert (new[left] == 1).all() and (new[~left] == 0).all()
    np.testing.assert_allclose(weight, [weights[~left].sum(), weights[left].sum()], rtol=1e-12)


def test_no_split_below_the_split_share_or_beyond_max_components():
    x, y, weights = cloud(1, 400, centre=(25.0, 0.0), sd=(12.0, 3.0))
    share = weights[x < 0].sum()
    assert 0 < share < 0.02
    labels = np.zeros(400, dtype=np.int64)
    cw = np.array([1.0])
    new, weight = split_across(x, y, weights, labels, cw, LINE, 4, 0.02, 1e-4)
    assert new is labels and weight is cw
    x, y, weights = cloud(2, 400)
    new, weight = split_across(x, y, weights, labels, cw, LINE, 1, 0.02, 1e-4)
    assert new is labels and weight is cw


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n_components=st.integers(1, 3),
    angle=st.floats(0.0, np.pi),
)
def test_the_split_keeps_every_weight_and_puts_each_new_component_on_one_side(
    seed, n_components, angle
):
    rng = np.random.default_rng(seed)
    n = 300
    labels = rng.integers(0, n_components, n).astype(np.int64)
    labels[:n_components] = np.arange(n_components)
    x, y = rng.normal(0, 20, n), rng.normal(0, 20, n)
    weights = rng.random(n)
    weights /= weights.sum()
    cw = np.bincount(labels, weights, n_components)
    line = np.array([0.0, 0.0, np.cos(angle), np.sin(angle)])
    new, weight = split_across(x, y, weights, labels, cw, line, 4, 0.02, 1e-4)
    assert weight.size == new.max() + 1 <= 4
    np.testing.assert_allclose(np.bincount(new, weights, weight.size), weight, atol=1e-12)
    left = line[2] * y - line[3] * x > 0
    for k in range(n_components, weight.size):  # each new component: one side of a parent
        parent = np.unique(labels[new == k])
        assert parent.size == 1 and left[new == k].all()
        assert not left[new == parent[0]].any()


def test_resampling_keeps_each_sides_weight_only_with_the_mirror_split():
    """While the two intersections overlap (one cluster), the whole component is resampled
    as one and the weight left of the line moves by chance; split along the line, it is the
    exact sum of its particles' weights after the resampling as before."""
    moved = []
    for seed in range(5):
        for mirror in (None, FixedLine()):
            pf = ParticleFilter(
                BaselineMotion(1.0),
                Straddle(),
                400,
                (-20.0, 20.0, -5.0, 5.0),
                rng=seed,
                resampling="multinomial",
                mixture=Mixture(mirror=mirror),
            )
            pf.initialise(0.0)
            pf.correct({"z": [2.0]})
            before = pf.weights()[0][pf.particles.x < 0].sum()
            pf.resample()
            after = pf.weights()[0][pf.particles.x < 0].sum()
            if mirror is None:
                moved.append(abs(after - before))
            else:
                np.testing.assert_allclose(after, before, rtol=1e-9)
    assert np.mean(moved) > 0.005  # resampled as one cluster, the side's weight drifts


def test_parts_closer_than_the_one_mode_distance_are_one_mode():
    x, y, weights = cloud(3, 600)
    x[400:] += 300.0  # a far third part
    labels = np.where(x < 0, 0, 1)
    labels[400:] = 2
    moments = component_moments(x, y, weights, labels, 3)
    assert np.hypot(*(moments[0, 1:3] - moments[1, 1:3])) < ONE_MODE_DISTANCE
    modes = join_modes(moments)
    union = component_moments(x, y, weights, np.where(labels == 2, 1, 0), 2)
    heavy = np.argsort(-union[:, 0])
    np.testing.assert_allclose(modes, union[heavy], rtol=1e-9, atol=1e-9)
    far = moments.copy()
    far[1, 1] += 100.0
    assert join_modes(far) is far


def test_a_cloud_cut_by_the_line_is_reported_as_one_mode_and_can_converge():
    pf = ParticleFilter(
        BaselineMotion(1.0),
        Straddle(),
        400,
        (-20.0, 20.0, -5.0, 5.0),
        rng=4,
        mixture=Mixture(mirror=FixedLine()),
        collect=[Modes()],
    )
    pf.initialise(0.0)
    pf.correct({"z": [0.0]})
    pf.resample()
    assert len(pf.component_moments) == 2  # the two sides
    modes = next(c for c in pf.collect if isinstance(c, Modes)).table()
    assert modes["components"].iloc[-1] == 2
    np.testing.assert_allclose(modes["mode1_weight"].iloc[-1], 1.0)
    assert np.isnan(modes["mode2_weight"].iloc[-1])


def _receivers():
    t = np.arange(0.0, 101.0, 10.0)
    moving = pd.DataFrame({"receiver": "auv", "time": t, "x": 2.0 * t, "y": 50.0 + 0 * t})
    moored = pd.DataFrame({"receiver": ["boat", "buoy"], "time": np.nan, "x": [0.0, 500.0]})
    moored["y"] = [0.0, 0.0]
    return pd.concat([moving, moored], ignore_index=True)


def test_the_mirror_line_runs_through_the_two_receivers_heard_last():
    obs = pd.DataFrame(
        {"time": [30.0, 10.0, 50.0, 60.0], "receiver": ["boat", "auv", "auv", "buoy"]}
    )
    line = MirrorLine.from_observations(obs, _receivers())
    assert line.at(5.0) is None  # nothing heard yet
    assert line.at(20.0) is None  # one receiver heard
    np.testing.assert_allclose(line.at(40.0), (0.0, 0.0, 80.0, 50.0))  # boat, then the auv at 40 s
    np.testing.assert_allclose(line.at(55.0), (110.0, 50.0, 0.0, 0.0))  # auv, then the boat
    np.testing.assert_allclose(line.at(70.0), (500.0, 0.0, 140.0, 50.0))  # buoy, then the auv
    np.testing.assert_allclose(line.at(500.0), (500.0, 0.0, 200.0, 50.0))  # track's end held
    tracks = ReceiverTracks.from_frame(_receivers())  # raises outside the track itself
    np.testing.assert_allclose(
        MirrorLine.from_observations(obs, tracks).at(500.0), (500.0, 0.0, 200.0, 50.0)
    )


def test_no_mirror_line_without_two_receivers():
    one = pd.DataFrame({"time": [1.0, 2.0], "receiver": ["boat", "boat"]})
    assert MirrorLine.from_observations(one, _receivers()) is None
    assert MirrorLine.from_observations(pd.DataFrame({"time": [1.0]}), _receivers()) is None


@pytest.mark.parametrize("seed", range(5))
def test_the_reflection_across_the_moving_line_keeps_both_ranges_and_range_rates(seed):
    """Why the sides need the split: receivers ``a(t)``, ``b(t)`` moving anyhow, a tag at
    ``p`` moving at ``v``; its reflection across the line through ``a`` and ``b``, moving
    at the reflection's time derivative, has the same predicted ranges and range-rates."""
    rng = np.random.default_rng(seed)
    a, b, p = rng.normal(0, 100, 2), rng.normal(0, 100, 2), rng.normal(0, 100, 2)
    va, vb, v = rng.normal(0, 2, 2), rng.normal(0, 2, 2), rng.normal(0, 2, 2)
    d = b - a
    u = d / np.hypot(*d)
    reflect = 2 * np.outer(u, u) - np.eye(2)
    du = ((vb - va) - u * (u @ (vb - va))) / np.hypot(*d)  # d/dt of the unit vector
    dreflect = 2 * (np.outer(du, u) + np.outer(u, du))
    q = a + reflect @ (p - a)
    vq = va + dreflect @ (p - a) + reflect @ (v - va)
    two = Particles.from_state(
        x=[p[0], q[0]],
        y=[p[1], q[1]],
        heading=np.arctan2([v[1], vq[1]], [v[0], vq[0]]),
        speed=np.hypot([v[0], vq[0]], [v[1], vq[1]]),
    )
    r, rate = predicted_range_and_rate(
        two, [a[0], b[0]], [a[1], b[1]], [va[0], vb[0]], [va[1], vb[1]]
    )
    np.testing.assert_allclose(r[1], r[0], rtol=1e-12)
    np.testing.assert_allclose(rate[1], rate[0], rtol=1e-9, atol=1e-12)


def test_track_splits_along_the_mirror_line_only_with_its_switch():
    """Off in every named filter (the default run is the mixture without it); with
    ``mirror_split`` the stationary tag near the boat-AUV line is still found, and the
    cloud's two sides are reported as one mode when they meet."""
    scenario = scenarios.stationary_tag(11)
    config = tracking_config(scenario, n_particles=1000, motion="velocity")
    assert config.filter.mixture and not config.filter.mirror_split
    default = tracking.track(scenario.detections, scenario.receivers, config, seed=0)
    plain = tracking.track(
        scenario.detections,
        scenario.receivers,
        config.override(mirror_split=False),
        seed=0,
    )
    pd.testing.assert_frame_equal(default.estimates, plain.estimates)
    split = tracking.track(
        scenario.detections, scenario.receivers, config.override(mirror_split=True), seed=0
    )
    assert (split.modes["components"] > default.modes["components"].max()).any()
    truth = scenario.truth[["x", "y"]].to_numpy()[-1]
    last = split.estimates[["x", "y"]].to_numpy()[-1]
    assert np.hypot(*(last - truth)) < 10.0
    assert split.estimates["converged"].to_numpy()[-1]


def test_the_other_receiver_is_the_latest_heard_by_another_one():
    """Brute force: for each observation, the receiver of the latest earlier observation by
    another receiver than its own."""
    rng = np.random.default_rng(0)
    receivers = pd.DataFrame(
        {"receiver": [f"r{k}" for k in range(4)], "time": np.nan, "x": np.arange(4.0), "y": 0.0}
    )
    for _ in range(100):
        heard = rng.integers(0, 4, rng.integers(2, 40))
        if np.unique(heard).size < 2:
            continue
        obs = pd.DataFrame(
            {"time": np.arange(heard.size, dtype=float), "receiver": [f"r{k}" for k in heard]}
        )
        line = MirrorLine.from_observations(obs, receivers)
        for j in range(heard.size):
            earlier = [i for i in range(j) if line.last[i] != line.last[j]]
            assert line.other[j] == (line.last[earlier[-1]] if earlier else -1)
