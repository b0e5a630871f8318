"""Mixture tracking (hmmtrack.tracking.mixture): no mode lost by resampling drift.

The oracle of the two-mode test is the exact posterior of a toy model on a grid: a tag
whose distance ``|x|`` from a line is observed every second (so ``x`` and ``−x`` explain
the data equally), with a first observation that favours ``x > 0`` by 0.7 to 0.3.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from numba import njit

from hmmtrack import scenarios
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.mixture import (
    ESTIMATE_MODE_COLUMNS,
    MODE_COLUMNS,
    SCHEME_CODES,
    SPLIT_SAMPLE,
    Mixture,
    Modes,
    allocate,
    component_moments,
    resample_components,
    scheme_draws,
    with_modes,
)
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.particles import Particles
from hmmtrack.tracking.resampling import Scratch, invert

#: the toy model: distance of the modes from the line (m), noise of ``|x|`` and ``y`` (m),
#: the first observation's odds for ``x > 0``, random-walk spread (m per s), seconds
DISTANCE, NOISE, FIRST_ODDS, WALK, SECONDS = 100.0, 5.0, 0.7, 1.0, 600
BOX = (-115.0, 115.0, -10.0, 10.0)


class MirrorToy:
    """``z_t = |x| + N(0, NOISE²)`` and ``0 = y + N(0, NOISE²)``; at ``t = 0`` also
    ``P(x > 0) = FIRST_ODDS``."""

    columns = ("z",)

    def loglik(self, particles, obs, time=None):
        z = np.asarray(obs["z"], dtype=float)
        residual = (np.abs(particles.x)[:, None] - z) / NOISE
        loglik = -0.5 * (residual**2).sum(axis=1) - 0.5 * z.size * (particles.y / NOISE) ** 2
        if time == 0.0:
            loglik += np.log(np.where(particles.x > 0, FIRST_ODDS, 1.0 - FIRST_ODDS))
        return loglik


def toy_observations(seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(1000 + seed)
    z = DISTANCE + NOISE * rng.standard_normal(SECONDS)
    return pd.DataFrame({"time": np.arange(SECONDS, dtype=float), "z": z})


def grid_posterior_positive(obs: pd.DataFrame, step: float = 0.25) -> float:
    """Exact ``P(x > 0 | z_0..z_T)`` of the toy on a grid of ``x`` (the ``y`` part of the
    likelihood is the same on both sides and cancels)."""
    x = np.arange(-160.0, 160.0 + step / 2, step)
    density = ((x >= BOX[0]) & (x <= BOX[1])).astype(float)
    offsets = np.arange(-6 * WALK, 6 * WALK + step / 2, step)
    kernel = np.exp(-0.5 * (offsets / WALK) ** 2)
    kernel /= kernel.sum()
    for k, z in enumerate(obs["z"].to_numpy()):
        if k > 0:
            density = np.convolve(density, kernel, mode="same")
        density *= np.exp(-0.5 * ((np.abs(x) - z) / NOISE) ** 2)
        if k == 0:
            density *= np.where(x > 0, FIRST_ODDS, 1.0 - FIRST_ODDS)
        density /= density.sum()
    return float(density[x > 0].sum())


def positive_weight(seed: int, mixture: Mixture | None, n_particles: int = 400) -> float:
    """The filter's posterior weight of ``x > 0`` at the end of the toy run (the paper's
    multinomial resampling after every correction)."""
    pf = ParticleFilter(
        BaselineMotion(WALK),
        MirrorToy(),
        n_particles,
        BOX,
        rng=seed,
        resampling="multinomial",
        mixture=mixture,
    )
    pf.run(toy_observations(seed))
    weights = pf.weights()[0]
    return float(weights[pf.particles.x > 0].sum())


def test_the_toy_posterior_is_two_modes_with_the_first_odds():
    oracle = [grid_posterior_positive(toy_observations(seed)) for seed in range(3)]
    np.testing.assert_allclose(oracle, FIRST_ODDS, atol=1e-6)  # mirror symmetry


def test_plain_resampling_loses_a_mode_and_the_mixture_keeps_both_with_the_right_weight():
    seeds = range(16)
    oracle = np.array([grid_posterior_positive(toy_observations(seed)) for seed in seeds])
    plain = np.array([positive_weight(seed, None) for seed in seeds])
    mixed = np.array([positive_weight(seed, Mixture()) for seed in seeds])
    lost_plain = (plain < 1e-3) | (plain > 1 - 1e-3)
    lost_mixed = (mixed < 1e-3) | (mixed > 1 - 1e-3)
    assert lost_plain.mean() >= 0.75  # 15 of 16 when written
    assert lost_mixed.mean() <= 0.25  # 2 of 16 when written
    # each weight is a ratio of two particle estimates of a mode's evidence, so single runs
    # scatter about the oracle (logit spread about 1.5 here); their centre is the oracle's
    assert abs(mixed.mean() - oracle.mean()) < 0.1
    assert abs(np.median(mixed) - oracle.mean()) < 0.1


def blobs(seed, sizes, centres, sd):
    """Positions (m) of Gaussian blobs of ``sizes`` particles about ``centres``, in order,
    and equal weights."""
    rng = np.random.default_rng(seed)
    x = np.concatenate([rng.normal(cx, sd, n) for n, (cx, _) in zip(sizes, centres, strict=True)])
    y = np.concatenate([rng.normal(cy, sd, n) for n, (_, cy) in zip(sizes, centres, strict=True)])
    return x, y, np.full(x.size, 1.0 / x.size)


def test_a_component_that_forms_two_separated_clusters_is_split():
    x, y, weights = blobs(0, (300, 100), ((0.0, 0.0), (80.0, 60.0)), 3.0)
    labels = Mixture().recluster(x, y, weights, np.zeros(400, dtype=np.int64))
    assert len(np.unique(labels[:300])) == 1 and len(np.unique(labels[300:])) == 1
    assert labels[0] != labels[-1]


def test_one_gaussian_cluster_is_not_split():
    x, y, weights = blobs(1, (1000,), ((500.0, -200.0),), 30.0)
    labels = Mixture().recluster(x, y, weights, np.zeros(1000, dtype=np.int64))
    assert (labels == 0).all()


def test_a_light_cluster_below_the_split_share_stays_in_its_component():
    x, y, weights = blobs(2, (400,), ((0.0, 0.0),), 3.0)
    x[:4] += 200.0  # 1 % of the weight, below split_share = 2 %
    labels = Mixture().recluster(x, y, weights, np.zeros(400, dtype=np.int64))
    assert (labels == 0).all()


def test_components_whose_means_meet_are_merged_and_far_ones_are_not():
    # the first two met (6 m apart, 5 m spreads)
    x, y, weights = blobs(3, (200, 200, 200), ((0.0, 0.0), (6.0, 0.0), (300.0, 0.0)), 5.0)
    new = Mixture().recluster(x, y, weights, np.repeat(np.arange(3), 200))
    assert (new[:400] == new[0]).all()
    assert (new[400:] != new[0]).all()
    assert new.max() == 1


def test_a_component_whose_sampled_particles_carry_no_weight_is_left_whole():
    # the split test looks at an evenly strided sample of a large component; when the
    # component's weight sits on particles outside it (a sharp likelihood), the sample's
    # weights sum to zero and there is nothing to judge a split by: the component stays
    # whole (this raised ZeroDivisionError in a two-AUV study run)
    x, y, _ = blobs(5, (3000, 3000), ((0.0, 0.0), (300.0, 0.0)), 5.0)
    stride = -(-x.size // SPLIT_SAMPLE)
    weights = np.ones(x.size)
    weights[::stride] = 0.0
    weights /= weights.sum()
    labels = Mixture().recluster(x, y, weights, np.zeros(x.size, dtype=np.int64))
    assert (labels == 0).all()
    # the same clouds with the weight on the sample are split
    weights = np.ones(x.size) / x.size
    assert Mixture().recluster(x, y, weights, np.zeros(x.size, dtype=np.int64)).max() == 1


def test_no_split_beyond_max_components():
    x, y, weights = blobs(4, (150, 150), ((0.0, 0.0), (200.0, 0.0)), 2.0)
    one = Mixture(max_components=1, min_share=0.0)
    assert (one.recluster(x, y, weights, np.zeros(300, dtype=np.int64)) == 0).all()
    assert Mixture().recluster(x, y, weights, np.zeros(300, dtype=np.int64)).max() == 1


def test_allocate_gives_each_live_component_its_floor_and_the_rest_by_weight():
    counts = allocate(np.array([0.7, 0.25, 0.05 - 1e-5, 1e-5]), 1000, 1e-4, 50)
    assert counts.sum() == 1000
    assert counts[3] == 0  # pruned
    assert (counts[:3] >= 50).all()
    np.testing.assert_allclose(counts[:3] - 50, 850 * np.array([0.7, 0.25, 0.05]), atol=1)
    # the heaviest always lives, even below the pruning weight
    np.testing.assert_array_equal(allocate(np.array([1.0]), 10, 2.0, 3), [10])


def test_component_moments_match_numpy():
    rng = np.random.default_rng(5)
    x, y = rng.normal(1e5, 20.0, 500), rng.normal(-3e4, 5.0, 500)
    weights = rng.random(500)
    weights /= weights.sum()
    labels = rng.integers(0, 3, 500)
    moments = component_moments(x, y, weights, labels, 4)
    for k in range(3):
        w = weights[labels == k]
        xy = np.vstack([x[labels == k], y[labels == k]])
        cov = np.cov(xy, aweights=w, bias=True)
        expected = [w.sum(), *np.average(xy, axis=1, weights=w), cov[0, 0], cov[1, 1], cov[0, 1]]
        np.testing.assert_allclose(moments[k], expected, rtol=1e-7, atol=1e-6)
    np.testing.assert_array_equal(moments[3], 0.0)


def test_component_moments_are_the_same_on_one_and_two_threads():
    """Chunk sums combined in chunk order: one answer whatever the number of threads (here
    98 chunks of 1,024 particles), and the weights as NumPy sums them to 1e-12."""
    rng = np.random.default_rng(6)
    n = 100_000
    x, y = rng.normal(1e5, 20.0, n), rng.normal(-3e4, 5.0, n)
    weights = rng.random(n)
    weights /= weights.sum()
    labels = rng.integers(0, 3, n)
    serial = component_moments(x, y, weights, labels, 3, threads=1)
    np.testing.assert_array_equal(component_moments(x, y, weights, labels, 3, threads=2), serial)
    np.testing.assert_allclose(serial[:, 0], np.bincount(labels, weights), rtol=1e-12)


def _moments_in_particle_order(x, y, weights, labels, n_components, chunk=1024):
    """The oracle of component_moments' order: per chunk of 1,024 particles, each
    component's six sums about its first particle, each particle added in turn (plain
    Python floats), the chunks combined in order."""
    first = {}
    for i, k in enumerate(labels.tolist()):
        first.setdefault(k, (x[i], y[i]))
    total = np.zeros((n_components, 6))
    for lo in range(0, x.size, chunk):
        own = [[0.0] * 6 for _ in range(n_components)]
        for i in range(lo, min(x.size, lo + chunk)):
            k = int(labels[i])
            w, dx, dy = float(weights[i]), x[i] - first[k][0], y[i] - first[k][1]
            s = own[k]
            s[0] += w
            s[1] += w * dx
            s[2] += w * dy
            s[3] += w * dx * dx
            s[4] += w * dy * dy
            s[5] += w * dx * dy
        total = total + np.array(own) if lo else np.array(own)
    out = np.zeros((n_components, 6))
    for k, (ox, oy) in first.items():
        s = total[k, 0]
        mx, my = total[k, 1] / s, total[k, 2] / s
        out[k] = [
            s, ox + mx, oy + my, max(total[k, 3] / s - mx * mx, 0.0),
            max(total[k, 4] / s - my * my, 0.0), total[k, 5] / s - mx * my,
        ]  # fmt: skip
    return out


@pytest.mark.parametrize("order", ["grouped", "shuffled", "grouped with a merge"])
def test_component_moments_add_each_components_particles_in_order(order):
    """Runs of one component summed in registers, a particle at a time when a chunk's
    labels are not grouped: the same bits as adding every particle to its component's sums
    in turn (three chunks, components spanning chunk ends), on one and two threads."""
    rng = np.random.default_rng(11)
    n = 3000
    x, y = rng.normal(2e4, 30.0, n), rng.normal(-5e3, 10.0, n)
    weights = rng.random(n) ** 3
    weights /= weights.sum()
    labels = np.repeat(np.arange(3), [700, 1500, 800])
    if order == "shuffled":
        labels = rng.permutation(labels)
    elif order == "grouped with a merge":  # what a merge of components 2 and 0 leaves
        labels = np.where(labels == 2, 0, labels)
    n_components = int(labels.max()) + 1
    expected = _moments_in_particle_order(x, y, weights, labels, n_components)
    for threads in (1, 2):
        moments = component_moments(x, y, weights, labels, n_components, threads=threads)
        np.testing.assert_array_equal(moments, expected)


def test_reclustering_one_component_leaves_the_callers_labels_and_splits_a_copy():
    # one component, no split: the labels come back equal (a new array); two separated
    # clusters: split into the two clusters, the labels given left as they were
    rng = np.random.default_rng(12)
    n = 5000
    weights = np.full(n, 1.0 / n)
    labels = np.zeros(n, dtype=np.int64)
    x, y = rng.normal(0.0, 3.0, n), rng.normal(0.0, 3.0, n)
    new = Mixture().recluster(x, y, weights, labels)
    np.testing.assert_array_equal(new, labels)
    assert not np.may_share_memory(new, labels)
    east = rng.random(n) < 0.3
    x = np.where(east, rng.normal(400.0, 3.0, n), rng.normal(0.0, 3.0, n))
    new = Mixture().recluster(x, y, weights, labels)
    np.testing.assert_array_equal(new, east.astype(np.int64))
    np.testing.assert_array_equal(labels, 0)


def test_a_mixture_run_is_the_same_on_one_and_two_threads():
    """60,000 particles (the correction's and the mixture's passes on the filter's threads
    from 50,000): the same seed gives the same weights and particles on one thread and on
    two."""
    runs = []
    for threads in (1, 2):
        pf = ParticleFilter(
            BaselineMotion(WALK),
            MirrorToy(),
            60_000,
            BOX,
            rng=3,
            mixture=Mixture(),
            threads=threads,
        )
        result = pf.run(toy_observations(3).iloc[:40])
        runs.append((result.estimates, pf.particles.x.copy(), pf.weights()[0].copy()))
    pd.testing.assert_frame_equal(runs[0][0], runs[1][0], check_exact=True)
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_array_equal(runs[0][2], runs[1][2])


def test_mixture_resampling_keeps_component_weights_and_equal_weights_within():
    pf = ParticleFilter(
        BaselineMotion(WALK), MirrorToy(), 400, BOX, rng=7, mixture=Mixture(), collect=[Modes()]
    )
    pf.initialise(0.0)
    pf.correct({"z": [DISTANCE]})
    weights = pf.weights()[0]
    positive = weights[pf.particles.x > 0].sum()
    pf.resample()
    p = pf.particles
    after = pf.weights()[0]
    np.testing.assert_allclose(after.sum(), 1.0)
    np.testing.assert_allclose(after[p.x > 0].sum(), positive, rtol=1e-9)
    for k in np.unique(p.component):
        np.testing.assert_allclose(after[p.component == k], after[p.component == k][0])


def test_mixture_settings_are_checked():
    with pytest.raises(ValueError, match="split_share"):
        Mixture(split_share=0.6)
    with pytest.raises(ValueError, match="min_share"):
        Mixture(max_components=4, min_share=0.3)


def test_track_with_the_mixture_reports_the_modes_and_finds_a_stationary_tag():
    scenario = scenarios.stationary_tag(11)
    config = tracking_config(scenario, n_particles=1000, mixture=True, motion="velocity")
    result = tracking.track(scenario.detections, scenario.receivers, config, seed=0)
    modes = result.modes
    assert list(modes.columns) == list(MODE_COLUMNS)
    assert (modes["components"] >= 1).all()
    np.testing.assert_array_less(modes["mode2_weight"].fillna(0), modes["mode1_weight"] + 1e-12)
    truth = scenario.truth[["x", "y"]].to_numpy()[-1]
    last = result.estimates[["x", "y"]].to_numpy()[-1]
    assert np.hypot(*(last - truth)) < 10.0
    estimates = result.estimates
    assert set(ESTIMATE_MODE_COLUMNS) <= set(estimates.columns)
    converged = estimates["converged"].to_numpy()
    assert converged[-1] and (estimates.loc[converged, "sqrt_lambda1"] < 10.0).all()
    assert (estimates.loc[converged, "mode1_weight"] >= 0.95).all()


def test_modes_without_a_mixture_are_the_clusters_of_the_cloud():
    """The plain filter's cloud after the toy's first observation is two clusters at
    ``x = ±DISTANCE`` weighted 0.7 : 0.3; ``Modes`` reports them, heaviest first."""
    pf = ParticleFilter(BaselineMotion(WALK), MirrorToy(), 4000, BOX, rng=3, collect=[Modes()])
    pf.initialise(0.0)
    pf.correct({"z": [DISTANCE]})
    pf.resample()
    (row,) = pf.collect[0].result()["modes"].itertuples(index=False)
    assert row.components == 2
    assert row.mode1_x == pytest.approx(DISTANCE, abs=3.0)
    assert row.mode2_x == pytest.approx(-DISTANCE, abs=3.0)
    assert row.mode1_weight == pytest.approx(FIRST_ODDS, abs=0.05)
    assert row.mode1_weight + row.mode2_weight == pytest.approx(1.0)


def test_a_streamed_runs_modes_keep_only_the_rows_still_needed():
    """Without ``keep``, the rows before the latest resampling at or before a released time
    are dropped (a 30-day streamed run must not hold ~290,000 rows): each table from a
    released time is the kept table's rows from the same resampling on, and the whole
    run's table is not returned."""
    weights = np.arange(1.0, 4.0)[::-1] / 6.0
    moments = np.column_stack([weights, np.zeros((3, 2)), np.ones((3, 2)), np.zeros(3)])
    kept, streamed = Modes(), Modes(keep=False)
    for modes in (kept, streamed):
        modes.start(None)
    for t in range(5000):
        pf = SimpleNamespace(mixture=True, time=float(t // 2), component_moments=moments)
        for modes in (kept, streamed):
            modes.resampled(pf, None)
        if t % 300 == 299:
            since = t // 2 - 150.5
            whole = kept.table()
            first = max(np.flatnonzero(whole["time"] <= since), default=0)
            expect = whole.iloc[first:].reset_index(drop=True)
            pd.testing.assert_frame_equal(streamed.table(since=since), expect)
            streamed.release(since)
    assert len(streamed.table()) <= 2 * 150 + 300 and len(kept.table()) == 5000
    assert streamed.result() == {} and len(kept.result()["modes"]) == 5000


def test_convergence_is_declared_only_when_one_mode_holds_almost_all_the_weight():
    """Each estimate takes the latest modes at or before it; a narrow cloud split between
    two modes is not converged, nor an estimate before the first modes."""
    estimates = pd.DataFrame(
        {"time": [0.0, 1.0, 2.0, 3.0, 4.0], "sqrt_lambda1": [50.0, 5.0, 5.0, 5.0, 20.0]}
    )
    nan = np.nan
    modes = pd.DataFrame(
        [
            [1.0, 2, 0.6, 0.0, 0.0, 3.0, 0.4, 8.0, 0.0, 3.0],
            [3.0, 1, 1.0, 0.0, 0.0, 3.0, nan, nan, nan, nan],
        ],
        columns=list(MODE_COLUMNS),
    )
    merged = with_modes(estimates, modes)
    assert list(merged.columns) == [*estimates.columns, *ESTIMATE_MODE_COLUMNS]
    assert merged["converged"].tolist() == [False, False, False, True, False]
    np.testing.assert_array_equal(merged["mode2_weight"], [nan, 0.4, 0.4, 0.0, 0.0])
    np.testing.assert_array_equal(merged["mode2_x"], [nan, 8.0, 8.0, nan, nan])


@njit
def _sum(values):
    """``values.sum()`` as compiled code forms it (the normaliser of the spacings)."""
    return values.sum()


@pytest.mark.parametrize("grouped", [True, False])
def test_components_invert_as_each_component_alone_on_any_threads(grouped):
    # ~6,000 new particles (six chunks of the merge), five components, chunks spanning
    # several; the oracle inverts each component on its own (resampling.invert)
    rng = np.random.default_rng(5)
    n = 6000
    labels = np.repeat(np.arange(5), [2500, 40, 1500, 1900, 60])
    if not grouped:
        labels = rng.permutation(labels)
    weights = rng.random(n) ** 4
    weights[rng.random(n) < 0.1] = 0.0
    weights /= weights.sum()
    component_weight = np.bincount(labels, weights)
    counts = np.array([2000, 1100, 0, 1500, 1400])
    x, y = rng.normal(0.0, 50.0, n), rng.normal(0.0, 50.0, n)
    for scheme, code in SCHEME_CODES.items():
        draws = scheme_draws(rng, code, n, 4)
        runs = [
            resample_components(weights, labels, counts, component_weight, code, draws, x, y, s)
            for s in (None, Scratch(threads=1), Scratch(threads=2), Scratch(threads=2))
        ]
        for run in runs[1:]:
            for got, first in zip(run, runs[0], strict=True):
                np.testing.assert_array_equal(got, first)
        # the new particles' labels, their ancestors' renumbered over the live components,
        # and their moments: the very numbers of a pass of component_moments
        relabelled = (np.cumsum(counts > 0) - 1)[labels]
        ancestors = runs[0].ancestors
        np.testing.assert_array_equal(runs[0].labels, relabelled[ancestors])
        np.testing.assert_array_equal(
            runs[0].moments,
            component_moments(
                x[ancestors], y[ancestors], runs[0].weights, relabelled[ancestors], 4
            ),
        )
        if scheme == "residual":
            continue
        expected, d = [], 0
        for k in np.flatnonzero(counts):
            own, c = np.flatnonzero(labels == k), counts[k]
            if scheme == "multinomial":
                values, scale, running = (
                    draws[d : d + c + 1],
                    1.0 / _sum(draws[d : d + c + 1]),
                    True,
                )
                d += c + 1
            else:
                u = draws[d : d + c] if scheme == "stratified" else draws[d]
                values, scale, running = (np.arange(c) + u) / c, 1.0, False
                d += c if scheme == "stratified" else 1
            expected.append(
                own[invert(weights[own], 1 / component_weight[k], values, c, scale, running)]
            )
        np.testing.assert_array_equal(runs[0][0], np.concatenate(expected))


@pytest.mark.parametrize("scheme", sorted(SCHEME_CODES))
def test_each_scheme_resamples_within_components_without_bias(scheme):
    rng = np.random.default_rng(11)
    n = 60
    labels = np.repeat([0, 1, 2], [30, 20, 10])
    weights = rng.random(n) ** 3
    weights /= weights.sum()
    component_weight = np.bincount(labels, weights)
    counts = np.array([25, 0, 35])  # component 1 dropped
    code = SCHEME_CODES[scheme]
    x, y = rng.normal(500.0, 30.0, n), rng.normal(-200.0, 10.0, n)
    copies = np.zeros(n)
    for _ in range(400):
        draws = scheme_draws(rng, code, n, 2)
        ancestors, log_weight, new_weights, summary, _, _ = resample_components(
            weights, labels, counts, component_weight, code, draws, x, y
        )
        np.testing.assert_array_equal(labels[ancestors], np.repeat([0, 2], [25, 35]))
        live = component_weight[[0, 2]].sum()
        np.testing.assert_allclose(
            np.exp(log_weight), np.repeat(component_weight[[0, 2]] / live / [25, 35], [25, 35])
        )
        np.testing.assert_array_equal(new_weights, np.exp(log_weight))
        # ESS and weighted mean of the new particles, as the filter keeps them
        np.testing.assert_allclose(
            summary,
            [
                1.0 / (new_weights @ new_weights),
                new_weights @ x[ancestors],
                new_weights @ y[ancestors],
            ],
            rtol=1e-12,
        )
        copies += np.bincount(ancestors, minlength=n)
    # each particle is copied N_k w_i / π_k times on average
    expected = np.where(labels == 1, 0.0, counts[labels] * weights / component_weight[labels])
    np.testing.assert_allclose(copies / 400, expected, atol=0.25)


@pytest.mark.parametrize("grouped", [True, False])
def test_the_filters_resampling_merges_each_component_inside_the_gather(grouped):
    # Mixture.draw's components merged chunk by chunk in Particles.take's gather (six
    # chunks, components spanning several), on one and two threads: the ancestors of
    # resample_components (checked against each component's own inversion above), every
    # field gathered exactly, and finish's weights, labels and moments equal to its own
    rng = np.random.default_rng(8)
    n = 6000
    west = rng.random(n) < 0.4
    x = np.where(west, rng.normal(-300.0, 20.0, n), rng.normal(300.0, 20.0, n))
    y = rng.normal(0.0, 30.0, n)
    labels = (~west).astype(np.int64)
    order = np.argsort(labels, kind="stable") if grouped else np.arange(n)
    weights = rng.random(n) ** 4
    weights[rng.random(n) < 0.1] = 0.0
    weights /= weights.sum()
    mixture = Mixture()
    for scheme, code in SCHEME_CODES.items():
        for threads in (1, 2):
            p = Particles.uniform(np.random.default_rng(1), n, (-400.0, 400.0, -100.0, 100.0))
            p.x, p.y = x[order], y[order]
            p.speed, p.turn_rate = rng.random(n), rng.normal(0.0, 0.1, n)
            p.state = rng.integers(0, 3, n).astype(p.state.dtype)
            p.extra["component"] = labels[order]
            w = weights[order]
            pf = SimpleNamespace(
                particles=p,
                rng=np.random.default_rng(9),
                resampling=scheme,
                scratch=Scratch(),
                correction_threads=lambda threads=threads: threads,
            )
            drawn = mixture.draw(pf, w)
            new = p.take(drawn.ancestors, True, None, threads, drawn.locate)
            log_weight, new_weights, n_eff, mean, moments = mixture.finish(drawn, new)
            reclustered = mixture.recluster(p.x, p.y, w, labels[order])
            live = np.count_nonzero(drawn.counts)
            expected = resample_components(
                w, reclustered, drawn.counts, drawn.component_weight, code,
                scheme_draws(np.random.default_rng(9), code, n, live), p.x, p.y,
            )  # fmt: skip
            assert live == 2
            np.testing.assert_array_equal(drawn.ancestors, expected.ancestors)
            for name in ("x", "y", "heading", "speed", "turn_rate", "state"):
                np.testing.assert_array_equal(
                    getattr(new, name), getattr(p, name)[expected.ancestors]
                )
            np.testing.assert_array_equal(new.log_weight, np.full(n, -np.log(n)))
            np.testing.assert_array_equal(log_weight, expected.log_weight)
            np.testing.assert_array_equal(new_weights, expected.weights)
            np.testing.assert_array_equal([n_eff, *mean], expected.summary)
            np.testing.assert_array_equal(moments, expected.moments)
            np.testing.assert_array_equal(new.extra["component"], expected.labels)
            assert "component" not in p.extra  # taken out before the gather
