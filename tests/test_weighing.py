import math

import numpy as np
import pytest

from hmmtrack.tracking.compiled.weighing import moment_sums, weigh


@pytest.mark.parametrize("n", [1, 1000, 5000, 70_001])
def test_weigh_is_the_numpy_arithmetic_and_the_same_bits_on_any_number_of_threads(n):
    """One chunk or many, one thread or several: the log weights plus the log-likelihood,
    ``np.argmax``, ``np.exp``, one pass of sums, the weights divided by their sum and the
    log weights minus their log-sum-exp. The same bits on every number of threads; the
    NumPy composition to the last bits (the compiled ``exp`` is the C library's, NumPy's
    its own SIMD one: they may differ by an ulp, as they do on an AVX-512 Xeon with NumPy
    2.4)."""
    rng = np.random.default_rng(n)
    x, y = rng.normal(5e5, 50.0, n), rng.normal(4.2e6, 80.0, n)
    log_weight, loglik = rng.normal(-5.0, 3.0, n), rng.normal(-40.0, 10.0, n)
    loglik[1::7] = -np.inf
    updated = log_weight + loglik
    k = int(np.argmax(updated))
    w = np.exp(updated - updated[k])
    s, *summary = moment_sums(w, x, y, k)
    log_total = updated[k] + math.log(s)
    first = None
    for threads in (1, 2, 3):
        for scores in (loglik, None):
            start = log_weight if scores is not None else updated
            status, out, weights, total, got = weigh(start, scores, x, y, threads)
            assert status == 0
            bits = (out.copy(), weights.copy(), total, tuple(got))
            first = first or bits
            for a, b in zip(bits[:2], first[:2], strict=True):
                np.testing.assert_array_equal(a, b)
            assert bits[2:] == first[2:]
    out, weights, total, got = first
    assert total == pytest.approx(log_total, rel=1e-15)
    assert got == pytest.approx(summary, rel=1e-14, abs=1e-12)
    np.testing.assert_allclose(weights, w / s, rtol=1e-15, atol=0)
    np.testing.assert_allclose(out, updated - log_total, rtol=1e-15, atol=0)
    assert summary[:2] == pytest.approx([w @ x / s, w @ y / s], rel=1e-12)
    assert summary[-1] == pytest.approx(s * s / (w @ w), rel=1e-12)


def test_weigh_reports_bad_loglik_and_impossible_particles_in_any_chunk():
    n = 5000
    rng = np.random.default_rng(1)
    x, y, log_weight = rng.normal(size=n), rng.normal(size=n), np.zeros(n)
    for threads in (1, 2):
        for bad in (np.nan, np.inf):
            loglik = np.zeros(n)
            loglik[4321] = bad
            assert weigh(log_weight, loglik, x, y, threads)[0] == 1
        assert weigh(log_weight, np.full(n, -np.inf), x, y, threads)[0] == 2
        first = np.full(n, -np.inf)
        first[[3000, 4000]] = 2.0  # ties: the first index, as np.argmax
        status, out, weights, _, summary = weigh(first, None, x, y, threads)
        assert status == 0 and weights[3000] == weights[4000] == 0.5
        assert summary[0] == pytest.approx(0.5 * (x[3000] + x[4000]), rel=1e-12, abs=1e-12)


def test_a_measurement_scored_inside_weigh_gives_the_bits_of_scoring_first():
    """The range-rate log-likelihood computed chunk by chunk in weigh's first pass
    (``scored``) is the one ``loglik`` returns, and weigh's results are those of adding it
    afterwards, on any number of threads."""
    from hmmtrack.tracking.compiled.chunks import default_threads
    from hmmtrack.tracking.compiled.weighing import loglik_chunks
    from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement
    from hmmtrack.tracking.particles import Particles

    n = 70_001
    rng = np.random.default_rng(5)
    p = Particles.from_state(
        rng.uniform(-500, 500, n), rng.uniform(-500, 500, n), rng.uniform(-3, 3, n),
        speed=rng.uniform(0, 2, n),
    )  # fmt: skip
    p.log_weight = rng.normal(-5.0, 3.0, n)
    model = RangeRateMeasurement.from_std(3.0, 0.2)
    rows = np.array([[300.0, 0.4, 100.0, -50.0, 0.9, 0.0], [450.0, -0.1, -200.0, 80.0, 0, 0]])
    expected = model.loglik(p, rows)
    assert np.isfinite(expected).all() and expected.std() > 1.0
    want = weigh(p.log_weight, expected, p.x, p.y, 1)
    for threads in (1, 2, 3):
        with default_threads(threads):
            np.testing.assert_array_equal(loglik_chunks(model.loglik_terms(p, rows), n), expected)
        scores = np.full(n, np.nan)
        got = weigh(p.log_weight, scores, p.x, p.y, threads, scored=model.loglik_terms(p, rows))
        np.testing.assert_array_equal(scores, expected)
        assert got[0] == 0 and got[3:] == want[3:]
        np.testing.assert_array_equal(got[1], want[1])
        np.testing.assert_array_equal(got[2], want[2])
