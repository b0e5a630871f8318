"""Tests of hmmtrack.hmm.inference: brute-force enumeration, a numpy log-space reference
implementation and hmmlearn's compiled recursions as oracles."""

import itertools

import numpy as np
import pytest
from hmmlearn import _hmmc
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from hmmtrack.hmm.inference import forward_backward, log_likelihood, viterbi

# --- oracles --------------------------------------------------------------------------------


def bounds(lengths, n_obs):
    lengths = [n_obs] if lengths is None else list(lengths)
    ends = np.cumsum(lengths)
    return list(zip(ends - np.array(lengths), ends, strict=True))


def transition_at(log_transition, t):
    """Log transition matrix from row t to row t+1."""
    return log_transition[t] if log_transition.ndim == 3 else log_transition


def brute_force(log_initial, log_transition, log_lik, lengths=None):
    """Enumerate all K**T state paths of the concatenated tracks."""
    n_obs, n_states = log_lik.shape
    tracks = bounds(lengths, n_obs)
    first_rows = {s for s, _ in tracks}
    paths = np.array(list(itertools.product(range(n_states), repeat=n_obs)))
    log_joint = np.zeros(len(paths))
    for t in range(n_obs):
        if t in first_rows:
            log_joint += log_initial[paths[:, t]]
        else:
            log_joint += transition_at(log_transition, t - 1)[paths[:, t - 1], paths[:, t]]
        log_joint += log_lik[t, paths[:, t]]
    total = logsumexp(log_joint)
    weight = np.exp(log_joint - total)
    posterior = np.zeros((n_obs, n_states))
    xi = np.zeros((n_obs - 1, n_states, n_states))
    for t in range(n_obs):
        np.add.at(posterior[t], paths[:, t], weight)
        if t < n_obs - 1 and t + 1 not in first_rows:
            np.add.at(xi[t], (paths[:, t], paths[:, t + 1]), weight)
    return total, posterior, xi, paths[np.argmax(log_joint)]


def reference_forward_backward(log_initial, log_transition, log_lik, lengths=None):
    """Plain log-space forward-backward, one track at a time: (per_track, posterior, xi)."""
    n_obs, n_states = log_lik.shape
    log_alpha = np.zeros((n_obs, n_states))
    log_beta = np.zeros((n_obs, n_states))
    posterior = np.zeros((n_obs, n_states))
    xi = np.zeros((max(n_obs - 1, 0), n_states, n_states))
    per_track = []
    for s, e in bounds(lengths, n_obs):
        log_alpha[s] = log_initial + log_lik[s]
        for t in range(s + 1, e):
            a = transition_at(log_transition, t - 1)
            log_alpha[t] = logsumexp(log_alpha[t - 1][:, None] + a, axis=0) + log_lik[t]
        for t in range(e - 2, s - 1, -1):
            a = transition_at(log_transition, t)
            log_beta[t] = logsumexp(a + (log_lik[t + 1] + log_beta[t + 1])[None, :], axis=1)
        total = logsumexp(log_alpha[e - 1])
        posterior[s:e] = np.exp(log_alpha[s:e] + log_beta[s:e] - total)
        for t in range(s, e - 1):
            a = transition_at(log_transition, t)
            xi[t] = np.exp(
                log_alpha[t][:, None] + a + (log_lik[t + 1] + log_beta[t + 1])[None, :] - total
            )
        per_track.append(total)
    return np.array(per_track), posterior, xi


def random_problem(rng, n_obs, n_states, time_varying=False, missing=(), forbidden=False):
    """Random log initial, log transition(s) and log-likelihood matrix."""
    log_initial = np.log(rng.dirichlet(np.ones(n_states)))
    shape = (n_obs - 1, n_states, n_states) if time_varying else (n_states, n_states)
    transition = rng.dirichlet(np.ones(n_states), size=shape[:-1])
    if forbidden:  # some impossible transitions
        transition[..., 0, -1] = 0.0
        transition /= transition.sum(axis=-1, keepdims=True)
    with np.errstate(divide="ignore"):
        log_transition = np.log(transition)
    log_lik = rng.normal(scale=2.0, size=(n_obs, n_states))
    log_lik[list(missing)] = 0.0
    return log_initial, log_transition, log_lik


# --- brute force ------------------------------------------------------------------------------

CASES = [
    # (K, T, lengths, time_varying, missing rows, forbidden transitions)
    (2, 6, None, False, (), False),
    (2, 7, [3, 1, 3], False, (1, 4), False),
    (2, 7, [2, 5], True, (0, 6), True),
    (3, 5, None, False, (2,), True),
    (3, 6, [4, 2], True, (3,), False),
    (3, 6, [1, 1, 4], False, (), False),
]


@pytest.mark.parametrize(
    ("n_states", "n_obs", "lengths", "time_varying", "missing", "forbid"), CASES
)
def test_equals_brute_force_enumeration(n_states, n_obs, lengths, time_varying, missing, forbid):
    rng = np.random.default_rng(n_states * 100 + n_obs)
    problem = random_problem(rng, n_obs, n_states, time_varying, missing, forbid)
    if forbid:  # an observation with -inf in one state
        problem[2][n_obs // 2, 0] = -np.inf
    lengths = None if lengths is None else np.array(lengths)
    total, posterior, xi, best = brute_force(*problem, lengths)
    result = forward_backward(*problem, lengths, return_xi=True)
    assert result.log_likelihood == pytest.approx(total, rel=1e-12)
    np.testing.assert_allclose(result.per_track.sum(), total, rtol=1e-12)
    np.testing.assert_allclose(result.posterior, posterior, atol=1e-12)
    np.testing.assert_allclose(result.xi, xi, atol=1e-12)
    np.testing.assert_allclose(result.transition_counts, xi.sum(axis=0), atol=1e-12)
    np.testing.assert_array_equal(viterbi(*problem, lengths), best)
    assert log_likelihood(*problem, lengths) == pytest.approx(total, rel=1e-12)


def test_per_track_log_likelihoods_are_independent_tracks():
    rng = np.random.default_rng(1)
    log_initial, log_transition, log_lik = random_problem(rng, 7, 3)
    result = forward_backward(log_initial, log_transition, log_lik, np.array([3, 4]))
    for value, rows in zip(result.per_track, (slice(0, 3), slice(3, 7)), strict=True):
        alone = brute_force(log_initial, log_transition, log_lik[rows])[0]
        assert value == pytest.approx(alone, rel=1e-12)


def test_missing_rows_propagate_the_prior():
    """A track with every row missing: likelihood 1 and posteriors = the Markov chain's law."""
    rng = np.random.default_rng(2)
    log_initial, log_transition, _ = random_problem(rng, 5, 3)
    result = forward_backward(log_initial, log_transition, np.zeros((5, 3)))
    assert result.log_likelihood == pytest.approx(0.0, abs=1e-14)
    law = np.exp(log_initial)
    for t in range(5):
        np.testing.assert_allclose(result.posterior[t], law, atol=1e-14)
        np.testing.assert_allclose(result.predicted[t], law, atol=1e-14)
        law = law @ np.exp(log_transition)


def test_filtered_and_predicted_probabilities():
    rng = np.random.default_rng(3)
    log_initial, log_transition, log_lik = random_problem(rng, 6, 2)
    result = forward_backward(log_initial, log_transition, log_lik, np.array([2, 4]))
    for t_end in (1, 4, 5):  # filtered at t = smoothed on the data up to t (same track)
        s = 0 if t_end < 2 else 2
        smoothed_prefix = brute_force(log_initial, log_transition, log_lik[s : t_end + 1])[1]
        np.testing.assert_allclose(result.filtered[t_end], smoothed_prefix[-1], atol=1e-12)
    a = np.exp(log_transition)
    np.testing.assert_allclose(result.predicted[3], result.filtered[2] @ a, atol=1e-14)
    np.testing.assert_allclose(result.predicted[2], np.exp(log_initial), atol=1e-14)


# --- hmmlearn ---------------------------------------------------------------------------------


def test_agrees_with_hmmlearn():
    rng = np.random.default_rng(4)
    n_states, lengths = 3, np.array([300, 1, 199])
    log_initial, log_transition, log_lik = random_problem(rng, lengths.sum(), n_states)
    log_lik[[5, 400]] = 0.0
    startprob, transmat = np.exp(log_initial), np.exp(log_transition)
    result = forward_backward(log_initial, log_transition, log_lik, lengths)
    path = viterbi(log_initial, log_transition, log_lik, lengths)
    totals, xi_sum = [], np.zeros((n_states, n_states))
    for s, e in bounds(lengths, lengths.sum()):
        frame = np.ascontiguousarray(log_lik[s:e])
        total, fwd = _hmmc.forward_log(startprob, transmat, frame)
        bwd = _hmmc.backward_log(startprob, transmat, frame)
        totals.append(total)
        np.testing.assert_allclose(result.posterior[s:e], np.exp(fwd + bwd - total), atol=1e-10)
        if e - s > 1:
            xi_sum += np.exp(_hmmc.compute_log_xi_sum(fwd, transmat, bwd, frame))
        best, best_path = _hmmc.viterbi(startprob, transmat, frame)
        np.testing.assert_array_equal(path[s:e], best_path)
        # the scaled implementation of hmmlearn gives the same total
        scaled_total, _, _ = _hmmc.forward_scaling(startprob, transmat, np.exp(frame))
        assert scaled_total == pytest.approx(total, rel=1e-10)
    np.testing.assert_allclose(result.per_track, totals, rtol=1e-10)
    np.testing.assert_allclose(result.transition_counts, xi_sum, rtol=1e-9)


# --- numba kernels vs the numpy reference -----------------------------------------------------


@st.composite
def problems(draw):
    n_states = draw(st.integers(1, 4))
    lengths = np.array(draw(st.lists(st.integers(1, 12), min_size=1, max_size=4)))
    n_obs = int(lengths.sum())
    time_varying = draw(st.booleans()) and n_obs > 1
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    missing = rng.choice(n_obs, size=draw(st.integers(0, n_obs // 2)), replace=False)
    problem = random_problem(rng, n_obs, n_states, time_varying, missing, n_states > 1)
    problem[2][:] *= draw(st.sampled_from([1.0, 30.0]))  # also very peaked likelihoods
    return (*problem, lengths)


@settings(max_examples=60, deadline=None)
@given(problems())
def test_kernels_match_numpy_reference(problem):
    per_track, posterior, xi = reference_forward_backward(*problem)
    result = forward_backward(*problem, return_xi=True)
    np.testing.assert_allclose(result.per_track, per_track, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(result.posterior, posterior, atol=1e-10)
    np.testing.assert_allclose(result.xi, xi, atol=1e-10)
    np.testing.assert_allclose(result.posterior.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(result.filtered.sum(axis=1), 1.0, atol=1e-12)
    # pair probabilities marginalise to the posteriors within a track
    lengths = problem[3]
    inside = np.ones(max(len(posterior) - 1, 0), dtype=bool)
    inside[np.cumsum(lengths)[:-1] - 1] = False
    np.testing.assert_allclose(result.xi[inside].sum(axis=2), posterior[:-1][inside], atol=1e-10)
    np.testing.assert_allclose(result.xi[inside].sum(axis=1), posterior[1:][inside], atol=1e-10)
    assert np.all(result.xi[~inside] == 0)


@settings(max_examples=40, deadline=None)
@given(problems())
def test_viterbi_path_is_optimal(problem):
    """The path's joint log-probability is the maximum found by a log-space max-product."""
    log_initial, log_transition, log_lik, lengths = problem
    path = viterbi(*problem)
    for s, e in bounds(lengths, len(log_lik)):
        delta = log_initial + log_lik[s]
        for t in range(s + 1, e):
            delta = (delta[:, None] + transition_at(log_transition, t - 1)).max(0) + log_lik[t]
        score = log_initial[path[s]] + log_lik[s, path[s]]
        for t in range(s + 1, e):
            score += transition_at(log_transition, t - 1)[path[t - 1], path[t]]
            score += log_lik[t, path[t]]
        assert score == pytest.approx(delta.max(), rel=1e-12, abs=1e-12)


def test_long_sequence_accuracy():
    """10^5 rows with extreme log-likelihoods: scaled recursions agree with log space."""
    rng = np.random.default_rng(5)
    log_initial, log_transition, log_lik = random_problem(rng, 100_000, 2)
    log_lik *= 100.0
    total, fwd = _hmmc.forward_log(np.exp(log_initial), np.exp(log_transition), log_lik)
    result = forward_backward(log_initial, log_transition, log_lik)
    assert result.log_likelihood == pytest.approx(total, rel=1e-11)
    assert np.isfinite(result.posterior).all()


# --- impossible and malformed input ----------------------------------------------------------


def test_impossible_observation_is_explicit():
    log_initial = np.log([0.5, 0.5])
    log_transition = np.array([[0.0, -np.inf], [-np.inf, 0.0]])  # states never change
    log_lik = np.array([[0.0, -np.inf], [-np.inf, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match=r"rows \[1\] have probability 0"):
        forward_backward(log_initial, log_transition, log_lik)
    assert log_likelihood(log_initial, log_transition, log_lik) == -np.inf
    with pytest.raises(ValueError, match="no state path"):
        viterbi(log_initial, log_transition, log_lik)
    all_impossible = np.array([[0.0, 0.0], [-np.inf, -np.inf]])
    assert log_likelihood(log_initial, log_transition, all_impossible) == -np.inf
    with pytest.raises(ValueError, match=r"rows \[1\] have probability 0"):
        forward_backward(log_initial, log_transition, all_impossible)


def test_malformed_input_raises():
    log_initial, log_transition, log_lik = random_problem(np.random.default_rng(6), 5, 2)
    with pytest.raises(ValueError, match="lengths sum to 4 but log_lik has 5 rows"):
        forward_backward(log_initial, log_transition, log_lik, np.array([2, 2]))
    with pytest.raises(ValueError, match=r"tracks \[1\]"):
        forward_backward(log_initial, log_transition, log_lik, np.array([5, 0]))
    with pytest.raises(ValueError, match=r"\(4, 2, 2\)"):
        forward_backward(log_initial, np.zeros((5, 2, 2)) - 1, log_lik)
    bad = log_lik.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"NaN or \+inf at rows \[3\]"):
        viterbi(log_initial, log_transition, bad)
    with pytest.raises(ValueError, match="log-probabilities"):
        forward_backward(log_initial, -log_transition, log_lik)
    varying = np.log(np.full((4, 2, 2), 0.5))
    varying[2, 1] = np.log([0.5, 0.6])
    with pytest.raises(ValueError, match=r"log_transition must sum to 1 .* not at \[\[2, 1\]\]"):
        forward_backward(log_initial, varying, log_lik)
    with pytest.raises(ValueError, match="log_initial must sum to 1"):
        viterbi(np.log([0.2, 0.2]), log_transition, log_lik)
