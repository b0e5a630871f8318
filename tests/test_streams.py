import numpy as np
import pytest
from scipy import stats

from hmmtrack.tracking.compiled import streams as rs

N = 200_000


@pytest.fixture
def streams():
    return rs.new_streams(np.random.default_rng(11), N)


def test_uniforms_are_uniform_and_in_open_closed_interval(streams):
    u = rs.draw_uniforms(streams, 2)
    assert u.min() > 0.0 and u.max() <= 1.0
    assert stats.kstest(u[0], "uniform").pvalue > 1e-3
    assert abs(np.corrcoef(u[0], u[1])[0, 1]) < 0.01  # successive draws of one stream


def test_streams_are_deterministic_and_advance(streams):
    a = rs.draw_normal_pairs(streams.copy())
    b = rs.draw_normal_pairs(streams.copy())
    assert np.array_equal(a, b)
    before = streams.copy()
    rs.draw_normal_pairs(streams)
    assert not np.array_equal(before, streams)
    assert not np.array_equal(rs.draw_normal_pairs(streams.copy()), a)


def test_ziggurat_normals_match_scipy_in_body_and_tails():
    z = rs.draw_normal_pairs(rs.new_streams(np.random.default_rng(2), 1_000_000))
    assert stats.kstest(z[0], "norm").pvalue > 1e-3
    assert stats.kstest(z[1], "norm").pvalue > 1e-3
    assert abs(np.corrcoef(z)[0, 1]) < 0.005
    magnitude = np.abs(z.ravel())
    for cut in (2.0, 3.0, rs._ZIG_R):  # the base layer's tail starts at r ~ 3.654
        tail = magnitude[magnitude > cut]
        expected = 2 * stats.norm.sf(cut) * magnitude.size
        assert abs(tail.size - expected) < 5 * np.sqrt(expected)
        conditional = stats.kstest(tail, lambda x, c=cut: 1 - stats.norm.sf(x) / stats.norm.sf(c))
        assert conditional.pvalue > 1e-3


def test_vectorised_normals_are_the_scalar_draws(streams):
    """normals_into (branch-free first tries, scalar retries) draws exactly what normal()
    draws from each stream, rejected first tries included."""
    expected = rs.draw_normal_pairs(streams.copy())  # normal() twice per stream
    after = streams.copy()
    rs.draw_normal_pairs(after)
    out = np.empty((2, N))
    retry = np.zeros(N, dtype=bool)
    retried = 0
    for row in out:
        rs.normals_into(streams, row, retry)
        retried += retry.sum()
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(streams, after)
    assert 0.005 * 2 * N < retried < 0.03 * 2 * N  # the retries ran (about 1 % of draws)


def test_vectorised_normal_pairs_are_the_scalar_pairs(streams):
    """normal_pairs_into (two branch-free tries per stream, scalar redraws of both) draws
    exactly what normal_pair() draws from each stream, rejected tries included."""
    expected = rs.draw_normal_pairs(streams.copy())
    after = streams.copy()
    rs.draw_normal_pairs(after)
    out = np.empty((2, N))
    retry = np.zeros(N, dtype=bool)
    rs.normal_pairs_into(streams, out[0], out[1], retry)
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(streams, after)
    assert 0.01 * N < retry.sum() < 0.05 * N  # the redraws ran (about 2 % of pairs)


def test_ziggurat_layers_have_equal_area():
    x, f = rs._ZIG_X, rs._ZIG_F
    v = x[1] * f[1] + np.sqrt(np.pi / 2) * stats.norm.sf(x[1]) * 2
    areas = x[1:-1] * (f[2:] - f[1:-1])  # layers 1..255 are rectangles of width x[i]
    np.testing.assert_allclose(areas, v, rtol=1e-9)
    assert x[0] * f[1] == pytest.approx(v)


@pytest.mark.parametrize("shape", [0.3, 1.0, 2.5, 40.0])
def test_gamma_matches_scipy(streams, shape):
    g = rs.draw_gamma(streams, shape, 2.0)
    assert stats.kstest(g, "gamma", args=(shape, 0, 2.0)).pvalue > 1e-3


@pytest.mark.parametrize("concentration", [0.0, 1e-6, 0.5, 3.0, 50.0, 5000.0])
def test_vonmises_matches_scipy(streams, concentration):
    v = rs.draw_vonmises(streams, 0.0, concentration)
    assert v.min() > -np.pi and v.max() <= np.pi
    cdf = stats.vonmises(max(concentration, 1e-12)).cdf
    assert stats.kstest(v, cdf).pvalue > 1e-3


def test_vonmises_mean_and_tight_limit(streams):
    shifted = rs.draw_vonmises(streams, 3.0, 20.0)
    assert shifted.min() > -np.pi and shifted.max() <= np.pi  # wrapped across +-pi
    assert np.angle(np.exp(1j * shifted).mean()) == pytest.approx(3.0, abs=0.01)
    tight = rs.draw_vonmises(streams, 0.3, 1e8)
    assert tight.mean() == pytest.approx(0.3, abs=1e-5)
    assert tight.std() == pytest.approx(1e-4, rel=0.02)
    assert stats.kstest((tight - 0.3) * 1e4, "norm").pvalue > 1e-3


def test_alias_table_reproduces_its_weights():
    weights = np.random.default_rng(0).random(37) ** 3
    cut, alias = rs.alias_table(weights)
    probability = cut / weights.size
    np.add.at(probability, alias, (1 - cut) / weights.size)
    np.testing.assert_allclose(probability, weights / weights.sum(), rtol=1e-12, atol=1e-15)


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="gamma shapes"):
        rs.gamma_constants(np.array([1.0, -1.0]))
    with pytest.raises(ValueError, match="concentrations"):
        rs.VonMisesTables.build([0.0], [np.nan])
