import warnings

import numba
import numpy as np
import pandas as pd
import pytest
from scipy import special

from hmmtrack.hmm import Gamma, MovementHMM, VonMises
from hmmtrack.tracking import filter as filter_module
from hmmtrack.tracking.acquisition import Acquisition
from hmmtrack.tracking.filter import (
    ESTIMATE_COLUMNS,
    ParticleFilter,
    _weigh,
    _weight_summary,
)
from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement
from hmmtrack.tracking.motion import BaselineMotion, HMMMotion, VelocityMotion
from hmmtrack.tracking.particles import _ARRAY_NAMES, Particles, sqrt_largest_eigenvalue
from hmmtrack.tracking.resampling import (
    RESAMPLERS,
    effective_sample_size,
    log_normalise,
    multinomial,
)

TAG = np.array([30.0, -20.0])
T0 = 1.7e9
BOUNDS = (-500.0, 500.0, -500.0, 500.0)
MEASUREMENT = RangeRateMeasurement.from_std(2.0, 0.1)


def _observe(t, hx, hy, hvx, hvy, receiver, rng):
    dx, dy = hx - TAG[0], hy - TAG[1]
    r = np.hypot(dx, dy)
    return pd.DataFrame(
        {
            "time": T0 + t,
            "receiver": receiver,
            "range": r + rng.normal(0.0, 1.0, t.size),
            "range_rate": (dx * hvx + dy * hvy) / r + rng.normal(0.0, 0.05, t.size),
            "receiver_x": hx,
            "receiver_y": hy,
            "receiver_vx": hvx,
            "receiver_vy": hvy,
        }
    )


def circling_observations(seed=0, duration=900.0, period=8.0, radius=200.0, speed=2.0):
    """A stationary tag at TAG; a ping every period s heard by a receiver circling the
    origin and, every other ping, by one anchored at (-150, 100)."""
    rng = np.random.default_rng(seed)
    t = np.arange(4.0, duration, period) + 0.3
    omega = speed / radius
    circling = _observe(
        t,
        radius * np.cos(omega * t),
        radius * np.sin(omega * t),
        -speed * np.sin(omega * t),
        speed * np.cos(omega * t),
        "auv1",
        rng,
    )
    a = t[::2]
    anchored = _observe(a, np.full(a.size, -150.0), np.full(a.size, 100.0), 0.0, 0.0, "moor", rng)
    return pd.concat([circling, anchored], ignore_index=True).sort_values("time", kind="stable")


def slow_fish_model():
    return MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=np.array([[0.95, 0.05], [0.1, 0.9]]),
        step=Gamma(mean=np.array([0.2, 1.0]), sd=np.array([0.15, 0.5])),
        angle=VonMises(mean=np.zeros(2), concentration=np.array([1.0, 10.0])),
        dt=1.0,
    )


MOTIONS = {
    "baseline": BaselineMotion(sigma=0.5),
    "velocity": VelocityMotion(sigma_speed=0.05, sigma_turn_rate=0.01),
    "hmm": HMMMotion(slow_fish_model(), "paper"),
    "hmm_time_consistent": HMMMotion(slow_fish_model(), "time_consistent"),
}


def make_filter(motion="velocity", n=2000, seed=1, **options):
    return ParticleFilter(MOTIONS[motion], MEASUREMENT, n, BOUNDS, rng=seed, **options)


@pytest.mark.parametrize(
    ("motion", "backend"),
    [(m, "auto") for m in MOTIONS] + [("velocity", "numpy"), ("hmm", "numpy")],
)
def test_stationary_tag_with_a_circling_receiver_converges(motion, backend):
    result = make_filter(motion, backend=backend).run(circling_observations(), start=T0)
    e = result.estimates
    assert list(e.columns) == list(ESTIMATE_COLUMNS)
    assert (
        e["time"].iloc[0] == T0 and e["time"].iloc[-1] == T0 + 893
    )  # pings at +4.3, +12.3, ... +892.3
    assert np.allclose(np.diff(e["time"]), 1.0)
    assert np.isfinite(e.to_numpy()).all()
    error = np.hypot(e["x"] - TAG[0], e["y"] - TAG[1])
    assert e["sqrt_lambda1"].iloc[0] > 200  # uniform start
    converged = e["sqrt_lambda1"] < 10.0
    assert converged.iloc[-300:].all()
    first = int(np.argmax(converged.to_numpy()))
    assert error.iloc[first:].mean() < 10.0
    assert result.events.empty


def test_same_seed_same_answer_whatever_the_threads(monkeypatch):
    obs = circling_observations(duration=300.0)
    a = make_filter("hmm", seed=3, threads=1).run(obs).estimates
    b = make_filter("hmm", seed=3, threads=2).run(obs).estimates
    c = make_filter("hmm", seed=4).run(obs).estimates
    pd.testing.assert_frame_equal(a, b)
    assert not np.allclose(a["x"], c["x"])
    # the corrections and resamplings on two threads too (2,000 particles: two chunks)
    monkeypatch.setattr(filter_module, "PARALLEL_MIN_CORRECTION", 1)
    two = make_filter("hmm", seed=3, threads=2)
    d = two.run(obs).estimates
    assert two.correction_threads() == 2
    pd.testing.assert_frame_equal(a, d)


def test_online_steps_reproduce_the_offline_run():
    obs = circling_observations(duration=200.0)
    offline = make_filter("velocity", seed=6).run(obs, start=T0).estimates.set_index("time")
    online = make_filter("velocity", seed=6)
    online.step(T0)
    for time, rows in obs.groupby(np.rint(obs["time"] - T0)):
        estimate = online.step(T0 + time, rows)
        row = offline.loc[T0 + time]
        assert estimate.x == pytest.approx(row["x"], abs=1e-9)
        assert estimate.sqrt_lambda1 == pytest.approx(row["sqrt_lambda1"], abs=1e-9)
    with pytest.raises(ValueError, match="prediction grid"):
        online.step(T0 + time + 0.5)
    # the acquisition draws from corrections an online filter has not seen yet
    with pytest.raises(ValueError, match="without acquisition"):
        make_filter("velocity", acquisition=Acquisition()).step(T0)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_predicted_estimates_are_the_particles_moments(backend):
    pf = make_filter("hmm", n=3000, backend=backend)
    pf.initialise(T0)
    pf.correct(circling_observations().iloc[:1])
    predicted = pf.predict(5)
    now = pf.estimate()
    assert [e.time for e in predicted] == [T0 + k for k in range(1, 6)]
    for name in ("x", "y", "var_x", "var_y", "cov_xy", "sqrt_lambda1", "n_eff"):
        assert getattr(predicted[-1], name) == pytest.approx(getattr(now, name), rel=1e-9)
    w = pf.particles.normalised_weights()
    cov = np.cov(np.vstack([pf.particles.x, pf.particles.y]), aweights=w, bias=True)
    assert now.var_x == pytest.approx(cov[0, 0], rel=1e-9)
    assert now.cov_xy == pytest.approx(cov[0, 1], rel=1e-9, abs=1e-9)
    assert now.sqrt_lambda1 == pytest.approx(np.sqrt(np.linalg.eigvalsh(cov)[-1]), rel=1e-9)


def test_sqrt_largest_eigenvalue_oracle():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.normal(size=(2, 2))
        cov = a @ a.T
        expected = np.sqrt(np.linalg.eigvalsh(cov)[-1])
        assert sqrt_largest_eigenvalue(cov[0, 0], cov[1, 1], cov[0, 1]) == pytest.approx(expected)


class GatedRangeRate(RangeRateMeasurement):
    """The paper's Gaussian, but impossible beyond a 50 m range gate (a hard constraint);
    recovers as the range-rate measurement does (its ``recover`` hook)."""

    def __init__(self, impossible_at=()):
        super().__init__(MEASUREMENT.covariance)
        object.__setattr__(self, "impossible_at", set(impossible_at))

    def loglik(self, particles, obs, time=None):
        if time in self.impossible_at:
            return np.full(particles.n, -np.inf)
        z = self.as_matrix(obs)  # range, range_rate, receiver_x, receiver_y, ...
        ll = MEASUREMENT.loglik(particles, z)
        r = np.hypot(z[None, :, 2] - particles.x[:, None], z[None, :, 3] - particles.y[:, None])
        outside = (np.abs(r - z[None, :, 0]) > 50).any(axis=1)
        return np.where(outside, -np.inf, ll)


def test_degenerate_weights_recover_on_the_range_ring_without_nan():
    obs = circling_observations(duration=400.0)
    bad_row = 31  # heard by auv1 only
    obs.loc[bad_row, "range"] += 400.0  # no particle can explain it any more
    pf = ParticleFilter(MOTIONS["velocity"], GatedRangeRate(), 2000, BOUNDS, rng=2)
    with pytest.warns(RuntimeWarning, match="degenerate_weights"):
        result = pf.run(obs, snapshot_times=[obs["time"][bad_row]])
    assert np.isfinite(result.estimates.drop(columns="time").to_numpy()).all()
    # the outlier empties the filter; so does the next (good) ping, which is off that ring
    assert set(result.events["kind"]) == {"degenerate_weights"}
    ring = f"{obs['range'][bad_row]:.1f} m range ring of receiver auv1"
    assert ring in result.events["detail"].iloc[0]
    assert result.events["time"].iloc[0] == np.rint(obs["time"][bad_row])
    last = result.estimates.iloc[-1]
    assert np.hypot(last["x"] - TAG[0], last["y"] - TAG[1]) < 10  # and it reconverges
    snapshot = next(iter(result.snapshots.values()))
    distance = np.hypot(
        snapshot["x"] - obs["receiver_x"][bad_row], snapshot["y"] - obs["receiver_y"][bad_row]
    )
    assert np.all(np.abs(distance - obs["range"][bad_row]) < 50)
    assert snapshot["weight"].sum() == pytest.approx(1.0)


def test_degenerate_weights_fall_back_to_uniform_and_record_it():
    obs = circling_observations(duration=200.0)
    impossible = float(np.rint(obs["time"][5]))
    pf = ParticleFilter(MOTIONS["hmm"], GatedRangeRate([impossible]), 1000, BOUNDS, rng=2)
    with pytest.warns(RuntimeWarning):
        result = pf.run(obs)
    assert np.isfinite(result.estimates.drop(columns="time").to_numpy()).all()
    assert result.events["detail"].tolist() == ["reinitialised uniformly in the bounds"]
    row = result.estimates.set_index("time").loc[impossible]
    assert row["sqrt_lambda1"] > 200 and row["n_eff"] == pytest.approx(1000)


def test_ess_resampling_only_when_the_sample_degenerates():
    obs = circling_observations(duration=200.0)
    ticks = {
        name: make_filter("velocity", **options).run(obs).estimates
        for name, options in {
            "always": {},
            "half": {"resample_when": "ess", "ess_threshold": 0.5},
            "never": {"resample_when": "ess", "ess_threshold": 1e-9},
        }.items()
    }
    between = ~np.isin(ticks["always"]["time"], np.rint(obs["time"]))  # prediction-only ticks
    np.testing.assert_allclose(ticks["always"]["n_eff"][between], 2000)
    # resampled whenever the sample fell below half: never below half between corrections
    assert np.all(ticks["half"]["n_eff"][between] >= 0.5 * 2000 - 1e-6)
    assert np.any(ticks["half"]["n_eff"][between] < 2000 - 1e-6)  # and sometimes kept weights
    assert ticks["never"]["n_eff"].iloc[-1] < 0.05 * 2000


@pytest.mark.parametrize("scheme", ["systematic", "stratified", "residual"])
def test_other_resampling_schemes_converge(scheme):
    e = make_filter("velocity", resampling=scheme).run(circling_observations()).estimates
    assert e["sqrt_lambda1"].iloc[-1] < 10
    assert np.hypot(e["x"].iloc[-1] - TAG[0], e["y"].iloc[-1] - TAG[1]) < 10


def test_snapshots_and_window():
    obs = circling_observations(duration=100.0)
    pf = make_filter("baseline")
    with pytest.warns(RuntimeWarning, match="observations_outside_window"):
        result = pf.run(obs, start=T0 + 20, end=T0 + 60, snapshot_times=[T0 + 20, T0 + 41.2])
    assert result.estimates["time"].tolist() == [T0 + k for k in range(20, 61)]
    assert sorted(result.snapshots) == [T0 + 20, T0 + 41]
    for frame in result.snapshots.values():
        assert len(frame) == 2000 and frame["weight"].sum() == pytest.approx(1.0)
    assert result.events["kind"].tolist() == ["observations_outside_window"]
    with pytest.raises(ValueError, match="outside the run"):
        pf.run(obs, snapshot_times=[T0 - 5])


def test_observations_in_any_row_order_give_the_same_run():
    """The rows are put in time order (stably) only when they are not: a shuffled table gives
    the run of the same rows sorted, and numbers in a column of objects that of the numbers,
    bit for bit."""
    obs = circling_observations(duration=120.0)
    shuffled = obs.sample(frac=1.0, random_state=4)
    as_objects = obs.astype({"range": object, "range_rate": object})
    tables = (shuffled, shuffled.sort_values("time", kind="stable"), obs, as_objects)
    runs = [make_filter(n=500).run(table).estimates for table in tables]
    assert not shuffled["time"].is_monotonic_increasing
    pd.testing.assert_frame_equal(runs[0], runs[1], check_exact=True)
    pd.testing.assert_frame_equal(runs[3], runs[2], check_exact=True)


def test_bad_observations_name_rows_and_columns():
    obs = circling_observations(duration=100.0)
    obs.loc[3, "range_rate"] = np.nan
    with pytest.raises(ValueError, match=r"\['range_rate'\] at row\(s\) \[3\]"):
        make_filter().run(obs)
    with pytest.raises(ValueError, match="lack column"):
        make_filter().run(obs.drop(columns="receiver_vx"))
    # columns of other dtypes are coerced to numbers: text and missing values are named
    for column in (obs["range"].astype(object), obs["range"].astype("Float64")):
        odd = obs.assign(range=column)
        odd.loc[5, "range"] = "far" if column.dtype == object else pd.NA
        with pytest.raises(ValueError, match=r"\['range', 'range_rate'\] at row\(s\) \[3, 5\]"):
            make_filter().run(odd)
    with pytest.raises(ValueError, match="backend"):
        make_filter(backend="cuda")


def test_measurement_returning_nan_is_an_error_not_a_result():
    class Broken:
        def loglik(self, particles, obs, time=None):
            return np.full(particles.n, np.nan)

    pf = ParticleFilter(MOTIONS["baseline"], Broken(), 100, BOUNDS, rng=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="NaN"):
            pf.run(circling_observations(duration=50.0))


def test_weight_summary_matches_numpy_far_from_the_origin():
    """UTM-sized coordinates with a 1 m spread and impossible particles: no cancellation."""
    rng = np.random.default_rng(2)
    x = 5.0e5 + rng.normal(0, 1.0, 1000)
    y = 4.2e6 + rng.normal(0, 2.0, 1000)
    log_weight = rng.normal(0, 3.0, 1000) - 800.0
    log_weight[:10] = -np.inf
    weights, log_total, mean_x, mean_y, var_x, var_y, cov_xy, n_eff = _weight_summary(
        x, y, log_weight
    )
    assert log_total == pytest.approx(special.logsumexp(log_weight), rel=1e-13)
    w = np.exp(log_weight - log_weight.max())
    w /= w.sum()
    np.testing.assert_allclose(weights, w, rtol=1e-12)
    cov = np.cov(np.vstack([x - 5.0e5, y - 4.2e6]), aweights=w, bias=True)
    assert (mean_x, mean_y) == pytest.approx((w @ x, w @ y), rel=1e-13)
    np.testing.assert_allclose([var_x, var_y, cov_xy], [cov[0, 0], cov[1, 1], cov[0, 1]], rtol=1e-9)
    assert n_eff == pytest.approx(effective_sample_size(log_weight), rel=1e-12)


def test_particles_carry_extra_fields_through_resampling():
    rng = np.random.default_rng(0)
    p = Particles.uniform(rng, 5, BOUNDS)
    assert np.all((p.heading >= -np.pi / 2) & (p.heading <= np.pi / 2))
    assert np.all(p.speed == 0) and np.all(p.turn_rate == 0)
    p.extra["period"] = np.arange(5.0)
    taken = p.take(np.array([4, 4, 0, 1, 2]))
    np.testing.assert_array_equal(taken.period, [4.0, 4.0, 0.0, 1.0, 2.0])
    np.testing.assert_array_equal(taken.x, p.x[[4, 4, 0, 1, 2]])
    taken.period[0] = -1.0
    assert p.period[4] == 4.0  # a copy, not a view
    with pytest.raises(AttributeError, match="no field 'clock'"):
        _ = p.clock
    with pytest.raises(ValueError, match=r"extra\['bad'\] has shape \(3,\)"):
        Particles(**{n: getattr(p, n) for n in _ARRAY_NAMES}, extra={"bad": np.zeros(3)})
    with pytest.raises(ValueError, match="xmin < xmax"):
        Particles.uniform(rng, 5, (1.0, 0.0, 0.0, 1.0))


def test_take_is_numpy_indexing_of_every_field_and_refuses_bad_indices():
    """The compiled gather (and the NumPy fallback for a field replaced by a strided view)
    give exactly ``field[indices]``; indices outside 0..N-1 are an error, not a wrap."""
    rng = np.random.default_rng(1)
    p = Particles.uniform(rng, 1000, BOUNDS)
    p.state = rng.integers(0, 3, 1000)
    p.speed = rng.normal(size=1000)
    indices = np.sort(rng.integers(0, 1000, 1500))
    strided = p.copy()
    strided.turn_rate = rng.normal(size=2000)[::2]  # assigned: not made contiguous
    for particles in (p, strided):
        for equal_weights in (False, True):
            taken = particles.take(indices, equal_weights=equal_weights)
            for name in _ARRAY_NAMES:
                want = getattr(particles, name)[indices]
                if equal_weights and name == "log_weight":
                    want = np.full(indices.size, -np.log(indices.size))
                got = getattr(taken, name)
                assert got.dtype == want.dtype and got.flags.c_contiguous
                np.testing.assert_array_equal(got, want)
    for particles in (p, strided):
        for bad in ([0, 1000], [-1, 3]):
            for equal_weights in (False, True):
                with pytest.raises(ValueError, match=r"indices in 0\.\.999"):
                    particles.take(np.array(bad), equal_weights=equal_weights)


def test_resampling_gathers_into_the_spare_arrays_with_the_fresh_answer():
    """A resampling gathers into the arrays of the particles from before the previous one
    (no fresh arrays) exactly what gathering into new arrays gives, on any threads; the
    equal weights after it are one read-only array."""
    obs = circling_observations(duration=100.0)
    runs = {}
    for threads in (1, 2):
        pf = make_filter("hmm", n=5000, seed=4, threads=threads)
        pf.initialise(T0)
        held, fields = [], []
        for k in range(3):
            pf.predict(8)
            pf.correct(obs.iloc[k : k + 1])
            before = pf.particles
            copy = before.copy()
            pf.resample_if_due()
            for name in _ARRAY_NAMES:
                want = getattr(copy, name)[pf.last_ancestors]
                if name == "log_weight":
                    want = np.full(5000, -np.log(5000))
                np.testing.assert_array_equal(getattr(pf.particles, name), want)
            held.append(before)
            fields.append(pf.particles.x)
        assert pf.particles is held[1] and pf.particles.x is not fields[1]  # two resamplings ago
        weights = pf.weights()[0]
        assert not weights.flags.writeable and np.all(weights == 1 / 5000)
        runs[threads] = pf.particles.copy()
    for name in _ARRAY_NAMES:
        np.testing.assert_array_equal(getattr(runs[1], name), getattr(runs[2], name))


def test_corrections_reuse_two_pairs_of_arrays_and_keep_the_previous_weights():
    """A correction writes its log weights and weights into reused arrays (two pairs): the
    particles' log weights and the weights of the previous correction stay intact through
    it (with and without a resampling in between), and a run gives the same estimates as
    corrections into fresh arrays (the weighing with no arrays given)."""
    obs = circling_observations(duration=120.0)
    for options in ({}, {"resample_when": "ess", "ess_threshold": 1e-9}):
        pf = make_filter("velocity", n=3000, seed=2, **options)
        pf.initialise(T0)
        arrays = set()
        for k in range(6):
            pf.predict(8)
            before_log, before_weights = pf.particles.log_weight, pf.weights()[0]
            copies = before_log.copy(), before_weights.copy()
            pf.correct(obs.iloc[k : k + 1])
            np.testing.assert_array_equal(before_log, copies[0])
            np.testing.assert_array_equal(before_weights, copies[1])
            arrays |= {id(pf.particles.log_weight), id(pf.weights()[0])}
            pf.resample_if_due()
        assert len(arrays) == 4 if options else len(arrays) <= 3
    fresh = make_filter("velocity", n=3000, seed=2)
    fresh._buffers = lambda p: None  # every correction into new arrays
    pd.testing.assert_frame_equal(
        fresh.run(obs).estimates, make_filter("velocity", n=3000, seed=2).run(obs).estimates
    )


def test_weigh_matches_log_normalise_and_the_weight_summary():
    rng = np.random.default_rng(5)
    x, y = rng.normal(0, 50, 500), rng.normal(0, 80, 500)
    log_weight = log_normalise(rng.normal(0, 2.0, 500))
    loglik = rng.normal(-40, 10.0, 500)
    loglik[:7] = -np.inf
    status, updated, weights, *moments, n_eff = _weigh(log_weight, loglik, x, y)
    assert status == 0
    np.testing.assert_allclose(updated, log_normalise(log_weight + loglik), rtol=1e-12)
    summary = _weight_summary(x, y, log_weight + loglik)
    np.testing.assert_allclose(weights, summary[0], rtol=1e-12)
    np.testing.assert_allclose([*moments, n_eff], [*summary[2:]], rtol=1e-12)
    assert _weigh(log_weight, np.full(500, -np.inf), x, y)[0] == 2
    equal = _weight_summary(x, y, np.full(500, -np.inf))  # no NaN: all equally impossible
    np.testing.assert_allclose(equal[0], 1 / 500)
    assert equal[2] == pytest.approx(x.mean())
    for bad in (np.nan, np.inf):
        loglik[3] = bad
        assert _weigh(log_weight, loglik, x, y)[0] == 1


def test_matrix_fast_path_equals_the_generic_correction():
    """iterate() scores with the measurement's matrix form; a measurement without one
    (scored on table slices) must give the same run."""

    class TableOnly:
        columns = MEASUREMENT.columns

        def loglik(self, particles, obs, time=None):
            assert isinstance(obs, pd.DataFrame)
            return MEASUREMENT.loglik(particles, obs, time)

    obs = circling_observations(duration=200.0)
    fast = make_filter("velocity", seed=8).run(obs).estimates
    generic = ParticleFilter(MOTIONS["velocity"], TableOnly(), 2000, BOUNDS, rng=8)
    pd.testing.assert_frame_equal(fast, generic.run(obs).estimates, rtol=1e-12)


def test_last_ancestors_are_the_resampling_draw():
    pf = make_filter("velocity", n=500, seed=2)
    assert pf.last_ancestors is None
    pf.initialise(T0)
    pf.predict(4)
    obs = circling_observations().iloc[:1]
    pf.correct(obs)
    before = pf.particles.copy()
    weights = before.normalised_weights()
    state = pf.rng.bit_generator.state
    pf.resample_if_due()
    replay = np.random.default_rng()
    replay.bit_generator.state = state
    np.testing.assert_array_equal(pf.last_ancestors, multinomial(replay, weights, 500))
    np.testing.assert_array_equal(pf.particles.x, before.x[pf.last_ancestors])
    np.testing.assert_array_equal(pf.particles.speed, before.speed[pf.last_ancestors])


@pytest.mark.parametrize("scheme", ["multinomial", "stratified", "systematic", "residual"])
def test_resampling_in_one_pass_is_the_schemes_draw_and_the_gather(scheme, monkeypatch):
    """The inverse-CDF schemes' points are merged and the new particles gathered chunk by
    chunk in one pass (the residual scheme: drawn, then gathered): the ancestors are the
    scheme's own draw and the particles exactly ``field[ancestors]``, on one thread and on
    two, and with a field of another layout (merged, then taken)."""
    monkeypatch.setattr(filter_module, "PARALLEL_MIN_CORRECTION", 1)
    obs = circling_observations().iloc[:1]
    for threads in (1, 2):
        for strided in (False, True):
            pf = make_filter("hmm", n=3000, seed=2, threads=threads, resampling=scheme)
            pf.initialise(T0)
            pf.predict(4)
            pf.correct(obs)
            if strided:
                pf.particles.speed = np.random.default_rng(0).normal(size=6000)[::2]
            before = pf.particles.copy()
            weights = pf.weights()[0].copy()
            state = pf.rng.bit_generator.state
            pf.resample_if_due()
            replay = np.random.default_rng()
            replay.bit_generator.state = state
            want = RESAMPLERS[scheme](replay, weights, 3000)
            np.testing.assert_array_equal(pf.last_ancestors, want)
            for name in _ARRAY_NAMES:
                taken = getattr(before, name)[want]
                if name == "log_weight":
                    taken = np.full(3000, -np.log(3000))
                np.testing.assert_array_equal(getattr(pf.particles, name), taken)
            assert pf.particles.speed.flags.c_contiguous


def test_automatic_threads_respect_numbas_thread_count(monkeypatch):
    """Under ``numba.set_num_threads(1)`` (the executors' worker processes) a filter with
    ``threads=None`` runs every compiled call on one thread."""
    obs = circling_observations(duration=120.0)
    seen = []
    advance = VelocityMotion.advance
    monkeypatch.setattr(
        VelocityMotion,
        "advance",
        lambda self, *args, threads=None: (
            seen.append(threads) or advance(self, *args, threads=threads)
        ),
    )
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        pf = make_filter("velocity", n=5000, seed=3)
        pf.run(obs)
    finally:
        numba.set_num_threads(previous)
    assert pf._thread_choice.options == (1,)
    assert seen and set(seen) == {1}
    if previous > 1:  # and with numba's default count both are tried
        seen.clear()
        make_filter("velocity", n=5000, seed=3).run(obs)
        assert set(seen) == {1, previous}


def test_automatic_threads_measure_both_and_give_the_threads_1_answer():
    obs = circling_observations(duration=300.0)
    auto = make_filter("velocity", n=5000, seed=3)
    a = auto.run(obs).estimates
    b = make_filter("velocity", n=5000, seed=3, threads=1).run(obs).estimates
    pd.testing.assert_frame_equal(a, b)
    assert all(cost is not None for cost in auto._thread_choice.cost.values())
