"""Tests of hmmtrack.hmm.em_kernels: the fused E-step against forward-backward (and
hmmlearn), the 2-state kernel against the general one, its closed-form M-step against the
general M-step, the dispatch and whole fits."""

import functools

import numpy as np
import pandas as pd
import pytest
from hmmlearn import _hmmc
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack.hmm import Gamma, MovementHMM, VonMises, WrappedCauchy, em_kernels
from hmmtrack.hmm import fit as fitting


def random_case(rng, n_states, lengths, zero_inflated, estimate_mean, missing):
    """Data and parameters: steps (zeros when zero-inflated, NaN when ``missing``), angles."""
    n_obs = int(np.sum(lengths))
    step = rng.gamma(2.0, rng.uniform(0.5, 5.0), n_obs)
    angle = rng.uniform(-np.pi, np.pi, n_obs)
    if zero_inflated:
        step[rng.random(n_obs) < 0.1] = 0.0
    if missing:
        step[rng.random(n_obs) < 0.1] = np.nan
        angle[rng.random(n_obs) < 0.15] = np.nan
    initial = rng.dirichlet(np.ones(n_states))
    transition = rng.dirichlet(np.ones(n_states), size=n_states)
    params = fitting.Parameters(
        initial=initial,
        transition=transition,
        coefficients=None,
        step=Gamma(
            rng.uniform(0.5, 10.0, n_states),
            rng.uniform(0.3, 5.0, n_states),
            rng.uniform(0.01, 0.5, n_states) if zero_inflated else None,
        ),
        angle=VonMises(
            rng.uniform(-np.pi, np.pi, n_states) if estimate_mean else np.zeros(n_states),
            rng.uniform(0.0, 10.0, n_states),
            estimate_mean,
        ),
    )
    return fitting.FitData(step, angle, np.asarray(lengths)), params


def reference_features(data) -> dict:
    """The features of the module docstring, built directly from the raw data."""
    step, angle = data.step, data.angle
    positive = step > 0  # False for NaN
    observed = ~np.isnan(angle)
    return {
        "positive": positive.astype(float),
        "step": np.where(positive, step, 0.0),
        "log_step": np.where(positive, np.log(np.where(positive, step, 1.0)), 0.0),
        "zero": (step == 0).astype(float),
        "observed": observed.astype(float),
        "cos": np.where(observed, np.cos(np.where(observed, angle, 0.0)), 0.0),
        "sin": np.where(observed, np.sin(np.where(observed, angle, 0.0)), 0.0),
    }


STATES = st.sampled_from([2, 3])


@st.composite
def cases(draw, n_states=STATES):
    seed = draw(st.integers(0, 2**32 - 1))
    n_states = draw(n_states)
    lengths = draw(st.lists(st.integers(1, 40), min_size=1, max_size=4))
    options = draw(st.tuples(st.booleans(), st.booleans(), st.booleans()))
    return random_case(np.random.default_rng(seed), n_states, lengths, *options)


@settings(max_examples=60, deadline=None)
@given(cases())
def test_fused_e_step_equals_forward_backward(case):
    data, params = case
    fused = em_kernels.fused_em(params, data)
    assert fused is not None
    statistics = fused.expectation(params)
    post = fitting._posterior(params, data)
    assert statistics.log_likelihood == pytest.approx(post.log_likelihood, rel=1e-10)
    for name, feature in reference_features(data).items():
        expected = feature @ post.posterior
        np.testing.assert_allclose(
            statistics.sums[name], expected, rtol=1e-10, atol=1e-12 * data.n_obs, err_msg=name
        )
    np.testing.assert_allclose(
        statistics.transition_counts, post.transition_counts, rtol=1e-10, atol=1e-12 * data.n_obs
    )
    np.testing.assert_allclose(
        statistics.first, post.posterior[data.starts].sum(axis=0), rtol=1e-10, atol=1e-14
    )
    # the closed-form M-step is the general one, where that one has an answer (on tiny data
    # a state may put all its weight on zero steps, or on one step: zero mass 1, sd 0)
    try:
        general = fitting.m_step(params, data, post)
    except ValueError:
        return
    fast = fused.maximisation(params, statistics)
    np.testing.assert_allclose(fast.initial, general.initial, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.transition, general.transition, rtol=1e-9, atol=1e-12)
    for a, b in ((fast.step, general.step), (fast.angle, general.angle)):
        for key, value in a.to_dict().items():
            if isinstance(value, list):
                # rtol: the gamma shape solves log k - digamma(k) = log(mean) - mean(log x),
                # a difference that cancels for a state on nearly equal steps (sums equal to
                # 1e-10 gave sds equal to 3e-8 on 10 rows); atol: such a state's sd is tiny
                # (6e-5 beside a mean of 8) and known only to ~1e-10 of the steps' scale
                # (1 m when no step is observed: the step parameters stay where they start)
                observed = np.abs(data.step[np.isfinite(data.step)])
                scale = float(observed.max()) if observed.size else 1.0
                np.testing.assert_allclose(
                    value, b.to_dict()[key], rtol=1e-6, atol=1e-9 * scale, err_msg=key
                )
            else:
                assert value == b.to_dict()[key]


def test_fused_e_step_agrees_with_hmmlearn():
    data, params = random_case(np.random.default_rng(7), 3, [300, 1, 199], True, True, True)
    log_lik = params.log_likelihood_matrix(data)
    totals = []
    for s, e in zip(data.starts, data.starts + data.lengths, strict=True):
        total, _, _ = _hmmc.forward_scaling(
            params.initial, params.transition, np.exp(np.ascontiguousarray(log_lik[s:e]))
        )
        totals.append(total)
    statistics = em_kernels.fused_em(params, data).expectation(params)
    assert statistics.log_likelihood == pytest.approx(sum(totals), rel=1e-10)


@functools.cache
def general_kernel(n_states):
    """The loop kernel of :func:`em_kernels._compile_pass`, which 2 states do not use."""
    return em_kernels._compile_pass(n_states)


@settings(max_examples=40, deadline=None)
@given(cases(st.just(2)), st.sampled_from([(), (0,), (0, 1)]))
def test_two_state_kernel_gives_the_general_kernels_bits(case, impossible_zero):
    data, params = case
    if params.step.zero_mass is not None:  # zero steps impossible in no, one or both states
        zero_mass = params.step.zero_mass.copy()
        zero_mass[list(impossible_zero)] = 0.0
        step = Gamma(params.step.mean, params.step.sd, zero_mass)
        params = fitting.Parameters(params.initial, params.transition, None, step, params.angle)
    fused = em_kernels.fused_em(params, data)
    coefficients = fused.coefficients(params.step, params.angle)
    outputs = [
        kernel(
            fused.features,
            coefficients,
            np.array(params.initial),
            np.array(params.transition),
            fused.starts,
            fused.ends,
            np.empty_like(fused.lik),
            np.empty_like(fused.filtered),
            np.empty_like(fused.scale),
            bool(np.isneginf(coefficients).any()),
        )
        for kernel in (em_kernels.KERNELS[2], general_kernel(2))
    ]
    two, general = outputs
    np.testing.assert_array_equal(two[0], general[0])  # log-likelihood
    for a, b in zip(two[1:4], general[1:4], strict=True):
        np.testing.assert_array_equal(a, b)
    assert two[4:] == general[4:]  # the same bad or impossible row, or none


def test_features_merge_equal_indicators_and_drop_empty_ones():
    rng = np.random.default_rng(1)
    data, params = random_case(rng, 2, [50], False, True, False)
    fused = em_kernels.fused_em(params, data)
    # no zero step and nothing missing: "positive" and "observed" are one column of ones
    assert fused.column["positive"] == fused.column["observed"] == 0
    assert fused.column["zero"] is None
    assert fused.features.shape == (50, 5)
    statistics = fused.expectation(params)
    np.testing.assert_array_equal(statistics.sums["zero"], [0.0, 0.0])
    np.testing.assert_allclose(statistics.sums["positive"].sum(), 50.0, rtol=1e-12)


def test_a_zero_probability_counts_only_where_its_feature_is_not_zero():
    rng = np.random.default_rng(2)
    data, params = random_case(rng, 2, [60], True, True, True)
    step = Gamma(params.step.mean, params.step.sd, np.array([0.0, 0.2]))
    params = fitting.Parameters(params.initial, params.transition, None, step, params.angle)
    statistics = em_kernels.fused_em(params, data).expectation(params)
    post = fitting._posterior(params, data)
    assert statistics.log_likelihood == pytest.approx(post.log_likelihood, rel=1e-10)
    assert statistics.sums["zero"][0] == 0.0  # state 0 cannot emit a zero step


def test_impossible_observations_raise_like_forward_backward():
    rng = np.random.default_rng(3)
    data, params = random_case(rng, 2, [30], True, True, False)
    step = Gamma(params.step.mean, params.step.sd, np.zeros(2))
    params = fitting.Parameters(params.initial, params.transition, None, step, params.angle)
    with pytest.raises(ValueError, match="probability 0 under every state"):
        fitting._posterior(params, data)
    with pytest.raises(ValueError, match="probability 0 under every state"):
        em_kernels.fused_em(params, data).expectation(params)


def test_dispatch_takes_only_the_models_it_computes():
    rng = np.random.default_rng(4)
    data, params = random_case(rng, 2, [40], False, True, False)
    assert isinstance(em_kernels.fused_em(params, data), em_kernels.FusedEM)
    five = random_case(rng, 5, [40], False, True, False)
    assert em_kernels.fused_em(five[1], five[0]) is None
    cauchy = fitting.Parameters(
        params.initial,
        params.transition,
        None,
        params.step,
        WrappedCauchy(params.angle.mean, np.array([0.3, 0.6])),
    )
    assert em_kernels.fused_em(cauchy, data) is None
    with_design = fitting.FitData(data.step, data.angle, data.lengths, np.ones((40, 1)))
    assert em_kernels.fused_em(params, with_design) is None
    zeros = fitting.FitData(np.where(data.step < 1, 0.0, data.step), data.angle, data.lengths)
    assert em_kernels.fused_em(params, zeros) is None  # zero steps need zero-inflation


def simulated(n_states: int, zero_inflated: bool, seed: int):
    """Two tracks (400 and 250 rows) from a model with well separated states, a few values
    missing; exact zero steps when zero-inflated."""
    model = MovementHMM(
        initial=np.full(n_states, 1.0 / n_states),
        transition=np.where(np.eye(n_states, dtype=bool), 0.9, 0.1 / (n_states - 1)),
        step=Gamma(np.array([1.0, 5.0, 15.0][:n_states]), np.array([0.7, 2.0, 4.0][:n_states])),
        angle=VonMises(
            np.array([np.pi, 0.0, 0.0][:n_states]), np.array([0.5, 3.0, 10.0][:n_states])
        ),
    )
    rng = np.random.default_rng(seed)
    table = pd.concat([model.simulate(rng, 400), model.simulate(rng, 250)], ignore_index=True)
    step, angle = table["step"].to_numpy(copy=True), table["angle"].to_numpy(copy=True)
    if zero_inflated:
        step[rng.random(step.size) < 0.03] = 0.0
    step[rng.random(step.size) < 0.02] = np.nan
    angle[rng.random(step.size) < 0.02] = np.nan
    return fitting.FitData(step, angle, np.array([400, 250]))


@pytest.mark.parametrize(("n_states", "zero_inflated"), [(2, False), (2, True), (3, True)])
def test_em_reaches_the_general_paths_optimum(monkeypatch, n_states, zero_inflated):
    data = simulated(n_states, zero_inflated, seed=5)
    spec = fitting.FitSpec(n_states, "gamma", "vonmises", True, zero_inflated, 500, 1e-10)
    start = fitting.initial_parameters(None, data, spec)
    fused = fitting.run_em(start, data, spec.max_iter, spec.tol)
    monkeypatch.setattr(em_kernels, "fused_em", lambda params, data: None)
    general = fitting.run_em(start, data, spec.max_iter, spec.tol)
    assert fused[2].converged and general[2].converged
    assert fused[1] == pytest.approx(general[1], rel=1e-9)
    np.testing.assert_allclose(fused[2].history[:5], general[2].history[:5], rtol=1e-10)
    np.testing.assert_allclose(fused[0].transition, general[0].transition, atol=1e-4)
    np.testing.assert_allclose(fused[0].step.mean, general[0].step.mean, rtol=1e-4)
