import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack.tracking.resampling import (
    RESAMPLERS,
    Scratch,
    effective_sample_size,
    get_resampler,
    inverse_cdf,
    multinomial,
    residual,
    systematic,
)

WEIGHTS = np.array([0.05, 0.4, 0.01, 0.3, 0.24])


def _counts(ancestors, m):
    return np.bincount(ancestors, minlength=m)


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_expected_counts_are_n_times_weights(name):
    """Unbiasedness: over many draws the mean number of copies of i is n * w_i."""
    resample = get_resampler(name)
    rng = np.random.default_rng(3)
    n, reps = 20, 4000
    counts = np.array([_counts(resample(rng, WEIGHTS, n), WEIGHTS.size) for _ in range(reps)])
    assert (counts.sum(axis=1) == n).all()
    expected = n * WEIGHTS
    # multinomial variance bounds every scheme's variance
    standard_error = np.sqrt(n * WEIGHTS * (1 - WEIGHTS) / reps)
    assert np.all(np.abs(counts.mean(axis=0) - expected) < 5 * standard_error + 1e-12)


def test_multinomial_counts_have_multinomial_variance():
    rng = np.random.default_rng(4)
    n, reps = 20, 4000
    counts = np.array([_counts(multinomial(rng, WEIGHTS, n), 5) for _ in range(reps)])
    np.testing.assert_allclose(counts.var(axis=0), n * WEIGHTS * (1 - WEIGHTS), rtol=0.1)


weights_strategy = st.lists(
    st.floats(min_value=0.0, max_value=1.0, allow_nan=False), min_size=1, max_size=30
).filter(lambda w: sum(w) > 1e-6)


@settings(max_examples=200, deadline=None)
@given(weights=weights_strategy, n=st.integers(1, 60), seed=st.integers(0, 2**32 - 1))
def test_systematic_counts_within_floor_and_ceil(weights, n, seed):
    w = np.array(weights) / np.sum(weights)
    counts = _counts(systematic(np.random.default_rng(seed), w, n), w.size)
    expected = n * w
    assert counts.sum() == n
    assert np.all(counts >= np.floor(expected - 1e-9))
    assert np.all(counts <= np.ceil(expected + 1e-9))


@settings(max_examples=200, deadline=None)
@given(weights=weights_strategy, n=st.integers(1, 60), seed=st.integers(0, 2**32 - 1))
def test_residual_keeps_deterministic_copies_and_never_picks_zero_weight(weights, n, seed):
    w = np.array(weights) / np.sum(weights)
    for name, resample in RESAMPLERS.items():
        counts = _counts(resample(np.random.default_rng(seed), w, n), w.size)
        assert counts.sum() == n, name
        assert np.all(counts[w == 0] == 0), name
    counts = _counts(residual(np.random.default_rng(seed), w, n), w.size)
    assert np.all(counts >= np.floor(n * w - 1e-9))


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_same_seed_same_ancestors(name):
    resample = get_resampler(name)
    a = resample(np.random.default_rng(9), WEIGHTS, 50)
    b = resample(np.random.default_rng(9), WEIGHTS, 50)
    assert a.dtype == np.int64 and np.array_equal(a, b)


def test_bad_weights_and_names_are_refused():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="indices \\[1\\]"):
        multinomial(rng, np.array([0.5, np.nan]), 3)
    with pytest.raises(ValueError, match="sum to zero"):
        systematic(rng, np.zeros(3), 3)
    with pytest.raises(ValueError, match="unknown resampling scheme 'nope'"):
        get_resampler("nope")


def test_effective_sample_size_oracles():
    assert effective_sample_size(np.zeros(7)) == pytest.approx(7.0)
    assert effective_sample_size(np.array([0.0, -np.inf, -np.inf])) == pytest.approx(1.0)
    assert effective_sample_size(np.full(4, -np.inf)) == 0.0
    lw = np.random.default_rng(1).normal(size=50) * 3
    w = np.exp(lw) / np.exp(lw).sum()
    assert effective_sample_size(lw) == pytest.approx(1 / np.sum(w**2))
    assert effective_sample_size(lw - 1e4) == pytest.approx(1 / np.sum(w**2))
    with pytest.raises(ValueError, match="NaN"):
        effective_sample_size(np.array([0.0, np.nan]))


@settings(max_examples=200, deadline=None)
@given(weights=weights_strategy, n=st.integers(1, 60), seed=st.integers(0, 2**32 - 1))
def test_inverse_cdf_is_searchsorted_of_the_cumulative_weights(weights, n, seed):
    """Oracle: NumPy's binary search on the cumulative sum (clipped to the last index)."""
    w = np.array(weights) / np.sum(weights)
    points = np.sort(np.random.default_rng(seed).random(n))
    expected = np.searchsorted(np.cumsum(w), points, side="right")
    last_positive = np.flatnonzero(w > 0)[-1]
    np.testing.assert_array_equal(inverse_cdf(w, points), np.minimum(expected, last_positive))


def test_inverse_cdf_never_picks_trailing_weightless_particles():
    """Cumulative sums that round below one must not send the last points to a zero weight."""
    w = np.array([0.3, 0.7 - 1e-15, 0.0, 0.0])
    points = np.array([0.1, 0.5, 0.9999999999999999])
    assert np.cumsum(w)[-1] < points[-1]
    assert inverse_cdf(w, points).tolist() == [0, 1, 1]


@settings(max_examples=150, deadline=None)
@given(
    m=st.integers(1, 400),
    n=st.integers(1, 400),
    power=st.integers(1, 30),
    zero_share=st.floats(0.0, 0.9),
    seed=st.integers(0, 2**32 - 1),
)
def test_resampled_ancestors_bracket_their_points(m, n, power, zero_share, seed):
    """Oracle for the four-run merge: each scheme's k-th ancestor ``j`` has its point in
    ``[C[j-1], C[j])`` of the cumulative weights ``C`` (points redrawn from the same seed),
    never a weightless particle, for weights from flat to very peaked."""
    g = np.random.default_rng(seed)
    w = g.random(m) ** power
    w[g.random(m) < zero_share] = 0.0
    w[g.integers(m)] += 1e-3
    cumulative = np.cumsum(w / w.sum())
    for name, points in (
        ("multinomial", None),
        ("systematic", lambda r: (np.arange(n) + r.random()) / n),
        ("stratified", lambda r: (np.arange(n) + r.random(n)) / n),
    ):
        ancestors = get_resampler(name)(np.random.default_rng(seed + 1), w, n)
        if name == "multinomial":
            e = np.random.default_rng(seed + 1).standard_exponential(n + 1)
            p = np.cumsum(e)[:n] / e.sum()
        else:
            p = points(np.random.default_rng(seed + 1))
        assert ancestors.shape == (n,) and np.all(np.diff(ancestors) >= 0)
        assert np.all(w[ancestors] > 0)
        below = np.where(ancestors > 0, cumulative[ancestors - 1], 0.0)
        assert np.all(below <= p + 1e-12)
        last = np.flatnonzero(w > 0)[-1]
        assert np.all((cumulative[ancestors] > p - 1e-12) | (ancestors == last))


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_scratch_and_threads_leave_the_ancestors_unchanged(name):
    """A filter's reused work arrays (:class:`Scratch`), on one thread or two, give the
    ancestors of the plain call from the same seed, over several chunks and twice in a row
    (the second time into the same arrays), for flat and peaked weights."""
    g = np.random.default_rng(11)
    resample = get_resampler(name)
    scratches = (Scratch(1), Scratch(2))
    for n, power in ((5000, 1), (5000, 25), (4321, 3)):
        w = g.random(5000) ** power
        w[g.random(5000) < 0.3] = 0.0
        expected = resample(np.random.default_rng(n + power), w, n)
        for scratch in scratches:
            for _ in range(2):
                got = resample(np.random.default_rng(n + power), w, n, scratch)
                np.testing.assert_array_equal(got, expected)


def test_scratch_alternates_between_two_arrays_of_each_name():
    scratch = Scratch()
    first = scratch.alternate("w", 5)
    second = scratch.alternate("w", 5)
    assert first is not second and not np.shares_memory(first, second)
    assert scratch.alternate("w", 5) is first and scratch.alternate("w", 5) is second
    labels = scratch.alternate("labels", 5, np.dtype(np.int64))
    assert labels.dtype == np.int64 and labels.shape == (5,)
    assert first.dtype == np.float64 and scratch.alternate("w", 5) is first  # own turns
    resized = scratch.alternate("w", 7)
    assert resized.shape == (7,) and resized is not second
    assert scratch.array("w", 5) is not first  # the plain work arrays are apart
