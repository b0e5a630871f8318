"""Tests of hmmtrack.hmm.distributions against scipy.stats, closed forms and invariants."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate, optimize, stats

from hmmtrack.hmm import distributions as D
from hmmtrack.hmm.distributions.angles import _AngleFamily
from hmmtrack.hmm.distributions.steps import _StepFamily
from hmmtrack.tracks import wrap_angle

STEP_EXAMPLES = [
    D.Gamma(mean=[0.4, 3.0], sd=[0.3, 1.5]),
    D.Weibull(shape=[0.8, 2.5], scale=[0.5, 4.0]),
    D.LogNormal(location=[-1.0, 1.2], scale=[0.6, 0.3]),
    D.Exponential(rate=[2.5, 0.3]),
]
ANGLE_EXAMPLES = [
    D.VonMises(mean=[0.0, 0.0], concentration=[0.4, 6.0], estimate_mean=False),
    D.VonMises(mean=[-2.5, 1.0], concentration=[0.0, 3.0]),
    D.WrappedCauchy(mean=[0.0, 0.0], concentration=[0.2, 0.85], estimate_mean=False),
    D.WrappedCauchy(mean=[3.0, -0.4], concentration=[0.05, 0.6]),
]


def scipy_step(dist, k):
    """The frozen scipy.stats distribution of state k's positive part."""
    if isinstance(dist, D.Gamma):
        shape = (dist.mean[k] / dist.sd[k]) ** 2
        return stats.gamma(a=shape, scale=dist.mean[k] / shape)
    if isinstance(dist, D.Weibull):
        return stats.weibull_min(c=dist.shape[k], scale=dist.scale[k])
    if isinstance(dist, D.LogNormal):
        return stats.lognorm(s=dist.scale[k], scale=np.exp(dist.location[k]))
    return stats.expon(scale=1 / dist.rate[k])


def scipy_angle(dist, k):
    if isinstance(dist, D.VonMises):
        return stats.vonmises(kappa=dist.concentration[k], loc=dist.mean[k])
    return stats.wrapcauchy(c=dist.concentration[k], loc=dist.mean[k])


def to_scipy_window(dist, k, x):
    """Shift angles to scipy's support: vonmises (loc-pi, loc+pi], wrapcauchy [loc, loc+2pi)."""
    lo = dist.mean[k] - (np.pi if isinstance(dist, D.VonMises) else 0.0)
    return lo + np.mod(x - lo, 2 * np.pi)


def scipy_angle_logpdf(dist, k, x):
    return scipy_angle(dist, k).logpdf(to_scipy_window(dist, k, x))


# --- densities ------------------------------------------------------------------------


@pytest.mark.parametrize("dist", STEP_EXAMPLES, ids=lambda d: d.name)
def test_step_logpdf_matches_scipy(dist):
    x = np.array([1e-4, 0.05, 0.3, 1.0, 2.7, 9.0, np.nan, 30.0])
    out = dist.logpdf(x)
    assert out.shape == (x.size, 2)
    for k in range(2):
        expected = scipy_step(dist, k).logpdf(x)
        np.testing.assert_allclose(out[~np.isnan(x), k], expected[~np.isnan(x)], rtol=1e-10)
    np.testing.assert_array_equal(out[np.isnan(x)], 0.0)


@pytest.mark.parametrize("cls", list(D.STEP_FAMILIES.values()), ids=lambda c: c.name)
def test_zero_inflation_for_every_step_family(cls):
    base = next(d for d in STEP_EXAMPLES if isinstance(d, cls))
    zero_mass = np.array([0.1, 0.3])
    inflated = base._replace(zero_mass=zero_mass)
    x = np.array([0.0, 0.7, np.nan, 0.0, 2.0])
    out = inflated.logpdf(x)
    np.testing.assert_allclose(out[[0, 3]], np.log([zero_mass, zero_mass]))
    np.testing.assert_allclose(out[[1, 4]], np.log1p(-zero_mass) + base.logpdf(x[[1, 4]]))
    np.testing.assert_array_equal(out[2], 0.0)
    # total mass: point mass + scaled density integrates to one
    for k in range(2):
        area, _ = integrate.quad(
            lambda t, k=k: np.exp(inflated.logpdf(np.array([t]))[0, k]), 0, np.inf
        )
        assert area + zero_mass[k] == pytest.approx(1.0, abs=1e-7)


def test_gamma_mean_sd_mapping():
    g = D.Gamma(mean=[2.0], sd=[0.5])
    assert g.shape[0] == pytest.approx(16.0)
    assert g.scale[0] == pytest.approx(0.125)
    frozen = stats.gamma(a=g.shape[0], scale=g.scale[0])
    assert frozen.mean() == pytest.approx(2.0) and frozen.std() == pytest.approx(0.5)


@pytest.mark.parametrize("dist", STEP_EXAMPLES, ids=lambda d: d.name)
def test_step_pdf_integrates_to_one(dist):
    for k in range(dist.n_states):
        area, _ = integrate.quad(lambda t, k=k: np.exp(dist.logpdf(np.array([t]))[0, k]), 0, np.inf)
        assert area == pytest.approx(1.0, abs=1e-7)


@pytest.mark.parametrize("dist", ANGLE_EXAMPLES, ids=lambda d: f"{d.name}-{d.estimate_mean}")
def test_angle_logpdf_matches_scipy_and_integrates(dist):
    x = np.array([-np.pi + 1e-9, -2.0, -0.3, 0.0, 0.4, 1.7, np.nan, np.pi])
    out = dist.logpdf(x)
    for k in range(2):
        ok = ~np.isnan(x)
        np.testing.assert_allclose(out[ok, k], scipy_angle_logpdf(dist, k, x[ok]), rtol=1e-10)
        area, _ = integrate.quad(
            lambda t, k=k: np.exp(dist.logpdf(np.array([t]))[0, k]), -np.pi, np.pi
        )
        assert area == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_array_equal(out[np.isnan(x)], 0.0)


@pytest.mark.parametrize("dist", STEP_EXAMPLES, ids=lambda d: d.name)
def test_step_cdf_matches_scipy_and_zero_mass(dist):
    x = np.array([1e-3, 0.2, 1.0, 4.0, np.nan, 25.0])
    out = dist.cdf(x)
    for k in range(2):
        np.testing.assert_allclose(out[:, k], scipy_step(dist, k).cdf(x), rtol=1e-10)
    inflated = dist._replace(zero_mass=np.array([0.2, 0.05]))
    out = inflated.cdf(np.array([0.0, 1.0, np.nan]))
    np.testing.assert_allclose(out[0], [0.2, 0.05])
    np.testing.assert_allclose(
        out[1], [0.2, 0.05] + np.array([0.8, 0.95]) * dist.cdf(np.ones(1))[0]
    )
    assert np.isnan(out[2]).all()


@pytest.mark.parametrize("dist", ANGLE_EXAMPLES, ids=lambda d: f"{d.name}-{d.estimate_mean}")
def test_angle_cdf_integrates_the_density(dist):
    # angles live on (-pi, pi]: -pi itself is the angle pi, with cdf 1
    x = np.array([-np.pi + 1e-9, -2.9, -1.0, 0.0, 0.5, 2.0, 3.1, np.pi, np.nan])
    out = dist.cdf(x)
    for k in range(2):
        for i in range(x.size - 1):
            area, _ = integrate.quad(
                lambda t, k=k: np.exp(dist.logpdf(np.array([t]))[0, k]),
                -np.pi,
                x[i],
                points=[dist.mean[k]] if -np.pi < dist.mean[k] < x[i] else None,
                limit=200,
            )
            assert out[i, k] == pytest.approx(area, abs=1e-8)
    np.testing.assert_allclose(out[0], 0.0, atol=1e-8)
    np.testing.assert_allclose(out[-2], 1.0, atol=1e-12)
    assert np.isnan(out[-1]).all()


def test_angle_density_is_periodic():
    d = D.VonMises(mean=[0.5], concentration=[2.0])
    x = np.array([0.3, -1.0])
    np.testing.assert_allclose(d.logpdf(x + 2 * np.pi), d.logpdf(x), rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    family=st.sampled_from(sorted(D.STEP_FAMILIES)),
    a=st.floats(0.05, 50.0),
    b=st.floats(0.05, 50.0),
    x=st.lists(st.floats(1e-12, 1e5), min_size=1, max_size=20),
)
def test_step_logpdf_is_never_nan(family, a, b, x):
    dist = D.STEP_FAMILIES[family].from_moments([a], [b], zero_mass=[0.1])
    out = dist.logpdf(np.array([*x, 0.0, np.nan]))
    assert not np.isnan(out).any() and (out < np.inf).all()


@settings(max_examples=60, deadline=None)
@given(
    family=st.sampled_from(sorted(D.ANGLE_FAMILIES)),
    mean=st.floats(-np.pi, np.pi),
    conc=st.floats(0.0, 0.999999999),
    x=st.lists(st.floats(-np.pi, np.pi), min_size=1, max_size=20),
)
def test_angle_logpdf_is_never_nan(family, mean, conc, x):
    if family == "vonmises":
        conc = 1e4 * conc
    out = D.ANGLE_FAMILIES[family]([mean], [conc]).logpdf(np.array([*x, mean]))
    assert np.isfinite(out).all()


# --- weighted maximum likelihood ---------------------------------------------------------


def one_state(dist):
    """The first state of ``dist`` as a one-state distribution."""
    d = dist.to_dict()
    return D.from_dict({k: (v[:1] if isinstance(v, list) else v) for k, v in d.items()})


@pytest.mark.parametrize("dist", STEP_EXAMPLES, ids=lambda d: d.name)
def test_unit_weight_fit_equals_scipy_mle(dist):
    rng = np.random.default_rng(1)
    one = one_state(dist)
    x = one.sample(rng, np.zeros(3000, dtype=int))
    fit = one.fit_weighted(x, np.ones((x.size, 1)))
    frozen_fit = scipy_step(fit, 0)
    if isinstance(dist, D.Gamma):
        a, _, scale = stats.gamma.fit(x, floc=0)
        np.testing.assert_allclose(
            [frozen_fit.kwds["a"], frozen_fit.kwds["scale"]], [a, scale], rtol=1e-6
        )
    elif isinstance(dist, D.Weibull):
        c, _, scale = stats.weibull_min.fit(x, floc=0)
        np.testing.assert_allclose([fit.shape[0], fit.scale[0]], [c, scale], rtol=1e-4)
    elif isinstance(dist, D.LogNormal):
        s, _, scale = stats.lognorm.fit(x, floc=0)
        np.testing.assert_allclose([fit.scale[0], np.exp(fit.location[0])], [s, scale], rtol=1e-6)
    else:
        _, scale = stats.expon.fit(x, floc=0)
        assert fit.rate[0] == pytest.approx(1 / scale, rel=1e-10)
    # and it is a maximum: the log-likelihood beats nearby parameters
    best = fit.logpdf(x).sum()
    theta = fit.to_working()
    for i in range(theta.size):
        for h in (-1e-3, 1e-3):
            moved = theta.copy()
            moved[i] += h
            assert fit.with_working(moved).logpdf(x).sum() < best


def test_vonmises_unit_weight_fit_equals_scipy_mle():
    rng = np.random.default_rng(2)
    x = stats.vonmises(kappa=2.0, loc=0.7).rvs(4000, random_state=rng)
    fit = D.VonMises([0.0], [1.0]).fit_weighted(x, np.ones((x.size, 1)))
    kappa, loc, _ = stats.vonmises.fit(x, fscale=1)
    assert fit.mean[0] == pytest.approx(loc, abs=1e-8)
    assert fit.concentration[0] == pytest.approx(kappa, rel=1e-6)


def test_fixed_mean_vonmises_fit_is_the_constrained_maximum():
    rng = np.random.default_rng(3)
    x = D.VonMises([0.3], [1.5]).sample(rng, np.zeros(3000, dtype=int))
    fit = D.VonMises([0.0], [1.0], estimate_mean=False).fit_weighted(x, np.ones((x.size, 1)))
    assert fit.mean[0] == 0.0
    result = optimize.minimize_scalar(
        lambda k: -stats.vonmises(kappa=k).logpdf(x).sum(),
        bounds=(1e-6, 50),
        method="bounded",
        options={"xatol": 1e-10},
    )
    assert fit.concentration[0] == pytest.approx(result.x, rel=1e-5)


@pytest.mark.parametrize("estimate_mean", [True, False])
def test_wrapped_cauchy_fit_is_the_maximum(estimate_mean):
    rng = np.random.default_rng(4)
    start = D.WrappedCauchy([0.8 if estimate_mean else 0.0], [0.5], estimate_mean)
    x = start.sample(rng, np.zeros(3000, dtype=int))
    fit = start.fit_weighted(x, np.ones((x.size, 1)))

    def negloglik(p):
        mean = p[1] if estimate_mean else 0.0
        return -scipy_angle_logpdf(D.WrappedCauchy([mean], [p[0]]), 0, x).sum()

    p0 = [0.3, 0.0] if estimate_mean else [0.3]
    ref = optimize.minimize(
        negloglik,
        p0,
        method="Nelder-Mead",
        bounds=[(1e-6, 0.999)] + ([(-10, 10)] if estimate_mean else []),
        options={"xatol": 1e-9, "fatol": 1e-12},
    )
    assert fit.concentration[0] == pytest.approx(ref.x[0], abs=1e-5)
    if estimate_mean:
        assert fit.mean[0] == pytest.approx(ref.x[1], abs=1e-5)


def test_zero_mass_is_the_weighted_share_of_zeros():
    x = np.array([0.0, 1.0, 2.0, 0.0, np.nan, 3.0])
    w = np.array([[1, 0], [1, 0], [1, 0], [0.5, 0.5], [1, 0], [0, 1.0]])
    fit = D.Gamma([1.0, 1.0], [1.0, 1.0], zero_mass=[0.5, 0.5]).fit_weighted(x, w)
    np.testing.assert_allclose(fit.zero_mass, [1.5 / 3.5, 0.5 / 1.5])


@pytest.mark.parametrize("dist", STEP_EXAMPLES + ANGLE_EXAMPLES, ids=lambda d: d.name)
def test_parameter_recovery_from_weighted_mixture(dist):
    """Soft weights (the true posterior of a 2-state mixture) recover both states."""
    rng = np.random.default_rng(5)
    states = rng.integers(0, 2, 20000)
    x = dist.sample(rng, states)
    log_density = dist.logpdf(x)
    w = np.exp(log_density - np.logaddexp(log_density[:, :1], log_density[:, 1:]))
    assert 0.05 < np.mean((w > 0.01) & (w < 0.99))  # the weights really are soft
    start = dist.with_working(dist.to_working() + 0.3)  # the fit does not start at the truth
    fit = start.fit_weighted(x, w)
    for name in dist._parameters:
        truth, got = getattr(dist, name), getattr(fit, name)
        if name == "mean" and isinstance(dist, _AngleFamily):
            defined = dist.concentration > 0.1  # the mean of a (near) uniform is not identified
            np.testing.assert_allclose(wrap_angle(got - truth)[defined], 0, atol=0.06)
        elif name == "location":
            np.testing.assert_allclose(got, truth, atol=0.02)
        elif name == "concentration":
            np.testing.assert_allclose(got, truth, atol=0.05, rtol=0.05)
        else:
            np.testing.assert_allclose(got, truth, rtol=0.05)


@pytest.mark.parametrize("dist", STEP_EXAMPLES + ANGLE_EXAMPLES, ids=lambda d: d.name)
def test_state_without_weight_keeps_its_parameters(dist):
    rng = np.random.default_rng(6)
    x = dist.sample(rng, np.zeros(200, dtype=int))
    w = np.column_stack([np.ones(200), np.zeros(200)])
    fit = dist.fit_weighted(x, w)
    for name in dist._parameters:
        assert getattr(fit, name)[1] == getattr(dist, name)[1]
        assert np.isfinite(getattr(fit, name)).all()


def well_spread(rows):
    """No value carries half of the total count (else the wrapped Cauchy MLE degenerates)."""
    totals = {}
    for value, count in rows:
        totals[value] = totals.get(value, 0) + count
    return sum(totals.values()) >= 3 and 2 * max(totals.values()) < sum(totals.values())


@settings(max_examples=25, deadline=None)
@given(
    family=st.sampled_from(
        ["gamma", "weibull", "lognormal", "exponential", "vonmises", "wrappedcauchy"]
    ),
    data=st.lists(
        st.tuples(st.floats(0.05, 3.0), st.integers(0, 4)), min_size=3, max_size=25
    ).filter(well_spread),
)
def test_integer_weights_equal_repeated_data(family, data):
    values = np.array([v for v, _ in data])
    counts = np.array([c for _, c in data])
    if family in D.ANGLE_FAMILIES:
        values = values - 1.5  # angles in (-1.45, 1.5)
        start = D.ANGLE_FAMILIES[family]([0.0], [0.5])
    else:
        start = D.STEP_FAMILIES[family].from_moments([1.0], [0.7])
    weighted = start.fit_weighted(values, counts[:, None].astype(float))
    repeated = np.repeat(values, counts)
    plain = start.fit_weighted(repeated, np.ones((repeated.size, 1)))
    for a, b in zip(weighted.to_working(), plain.to_working(), strict=True):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-6)


# --- sampling ---------------------------------------------------------------------------


@pytest.mark.parametrize("dist", STEP_EXAMPLES + ANGLE_EXAMPLES, ids=lambda d: d.name)
def test_samples_follow_the_density(dist):
    """Kolmogorov-Smirnov against scipy's cdf, per state (seeded, n = 4000)."""
    rng = np.random.default_rng(7)
    for k in range(2):
        x = dist.sample(rng, np.full(4000, k))
        if isinstance(dist, _StepFamily):
            cdf = scipy_step(dist, k).cdf
        else:
            assert np.all((x > -np.pi) & (x <= np.pi))
            x = to_scipy_window(dist, k, x)
            cdf = scipy_angle(dist, k).cdf
        assert stats.kstest(x, cdf).pvalue > 1e-3


def test_sample_moments_and_expected_value():
    rng = np.random.default_rng(8)
    for dist in STEP_EXAMPLES:
        inflated = dist._replace(zero_mass=np.array([0.2, 0.05]))
        for k in range(2):
            x = inflated.sample(rng, np.full(40000, k))
            assert np.mean(x == 0) == pytest.approx(inflated.zero_mass[k], abs=0.01)
            se = x.std() / np.sqrt(x.size)
            assert abs(x.mean() - inflated.expected_value()[k]) < 5 * se
    angles = D.VonMises([1.0, -2.0], [3.0, 1.0]).sample(rng, np.repeat([0, 1], 20000))
    assert np.all((angles > -np.pi) & (angles <= np.pi))
    assert np.angle(np.exp(1j * angles[:20000]).mean()) == pytest.approx(1.0, abs=0.02)


def test_same_seed_same_samples():
    dist = D.WrappedCauchy([0.0, 1.0], [0.3, 0.9])
    states = np.array([0, 1, 1, 0, 1])
    a = dist.sample(np.random.default_rng(9), states)
    b = dist.sample(np.random.default_rng(9), states)
    np.testing.assert_array_equal(a, b)


# --- round trips --------------------------------------------------------------------------


ALL = [
    *STEP_EXAMPLES,
    D.Gamma([1.0, 2.0], [0.5, 1.0], zero_mass=[0.01, 0.2]),
    D.LogNormal([-0.5], [0.2], zero_mass=[0.3]),
    *ANGLE_EXAMPLES,
]


@pytest.mark.parametrize("dist", ALL, ids=lambda d: d.name)
def test_dict_round_trip_through_json(dist):
    back = D.from_dict(json.loads(json.dumps(dist.to_dict())))
    assert type(back) is type(dist) and back == dist


@pytest.mark.parametrize("dist", ALL, ids=lambda d: d.name)
def test_working_round_trip(dist):
    theta = dist.to_working()
    assert np.isfinite(theta).all()
    back = dist.with_working(theta)
    for name in dist._parameters:
        got, expected = getattr(back, name), getattr(dist, name)
        if (
            isinstance(dist, _AngleFamily) and name == "mean"
        ):  # a uniform angle distribution (concentration 0) has no mean
            got, expected = got[dist.concentration > 0], expected[dist.concentration > 0]
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    if isinstance(dist, _StepFamily) and dist.zero_inflated:
        np.testing.assert_allclose(back.zero_mass, dist.zero_mass, rtol=1e-9)
    # and the other direction: any finite working vector maps to a valid distribution
    rng = np.random.default_rng(10)
    theta2 = rng.normal(size=theta.size)
    np.testing.assert_allclose(
        dist.with_working(theta2).to_working(), theta2, rtol=1e-8, atol=1e-10
    )


@pytest.mark.parametrize("dist", ALL, ids=lambda d: d.name)
def test_working_score_is_the_gradient_of_the_weighted_log_likelihood(dist):
    rng = np.random.default_rng(13)
    states = rng.integers(0, dist.n_states, 400)
    x = dist.sample(rng, states)
    x[[2, 30]] = np.nan
    w = rng.dirichlet(np.ones(dist.n_states), size=x.size)
    theta = dist.to_working()

    def weighted_log_likelihood(t):
        return np.sum(w * dist.with_working(t).logpdf(x))

    numeric = np.array(
        [
            (weighted_log_likelihood(theta + h) - weighted_log_likelihood(theta - h)) / 2e-6
            for h in np.eye(theta.size) * 1e-6
        ]
    )
    score = dist.working_score(x, w)
    assert score.shape == theta.shape
    np.testing.assert_allclose(score, numeric, rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(dist.working_score(dist.prepare(x), w), score)


@given(
    mean=st.floats(-np.pi + 1e-6, np.pi),
    conc=st.floats(1e-3, 0.99),
    family=st.sampled_from(["vonmises", "wrappedcauchy"]),
)
def test_angle_working_round_trip_property(mean, conc, family):
    dist = D.ANGLE_FAMILIES[family]([mean], [conc])
    back = dist.with_working(dist.to_working())
    assert wrap_angle(back.mean[0] - mean) == pytest.approx(0, abs=1e-9)
    assert back.concentration[0] == pytest.approx(conc, rel=1e-8)


# --- prepared observations ----------------------------------------------------------------


def test_prepared_observations_give_the_same_results():
    rng = np.random.default_rng(12)
    states = rng.integers(0, 2, 500)
    w = rng.dirichlet([1.0, 1.0], size=500)
    steps = STEP_EXAMPLES[0].sample(rng, states)
    steps[[3, 40]] = np.nan
    steps[[7, 8]] = 0.0
    angles = ANGLE_EXAMPLES[1].sample(rng, states)
    angles[[5, 99]] = np.nan
    prepared_steps = D.prepare_steps(steps)
    prepared_angles = D.VonMises([0.0], [1.0]).prepare(angles + 2 * np.pi)  # wrapped on the way
    for dist in STEP_EXAMPLES:  # one preparation serves every step family
        inflated = dist._replace(zero_mass=np.array([0.1, 0.2]))
        np.testing.assert_array_equal(inflated.logpdf(prepared_steps), inflated.logpdf(steps))
        np.testing.assert_array_equal(inflated.cdf(prepared_steps), inflated.cdf(steps))
        assert inflated.fit_weighted(prepared_steps, w) == inflated.fit_weighted(steps, w)
        with pytest.raises(ValueError, match="need zero-inflation"):
            dist.logpdf(prepared_steps)
    for dist in ANGLE_EXAMPLES:
        np.testing.assert_allclose(dist.logpdf(prepared_angles), dist.logpdf(angles), atol=1e-12)
        np.testing.assert_allclose(dist.cdf(prepared_angles), dist.cdf(angles), atol=1e-12)
        a, b = dist.fit_weighted(prepared_angles, w), dist.fit_weighted(angles, w)
        np.testing.assert_allclose(a.to_working(), b.to_working(), rtol=1e-9, atol=1e-12)
    assert D.prepare_steps(prepared_steps) is prepared_steps
    with pytest.raises(ValueError, match="read-only"):
        prepared_steps.log_safe[0] = 0.0


# --- starting values ------------------------------------------------------------------------


def test_initial_guess_orders_states_and_switches_zero_inflation_on():
    rng = np.random.default_rng(11)
    truth = D.Gamma([0.2, 2.0], [0.1, 1.0])
    states = rng.integers(0, 2, 4000)
    steps = truth.sample(rng, states)
    steps[:5] = 0.0
    angles = D.VonMises([0.0, 0.0], [0.5, 8.0], estimate_mean=False).sample(rng, states)
    step, angle = D.initial_guess(steps, angles, 2, estimate_angle_mean=False)
    assert step.zero_inflated and isinstance(step, D.Gamma)
    assert step.mean[0] < step.mean[1]
    assert angle.concentration[0] < angle.concentration[1] and not angle.estimate_mean
    a = D.initial_guess(steps, angles, 3, "weibull", "wrappedcauchy", rng=np.random.default_rng(1))
    b = D.initial_guess(steps, angles, 3, "weibull", "wrappedcauchy", rng=np.random.default_rng(1))
    assert a == b and a[0].n_states == 3
    # prepared steps sort once (stable, as a sort of the raw steps) and give the same guesses
    prepared = D.prepare_steps(steps)
    positive = np.flatnonzero(steps > 0)
    np.testing.assert_array_equal(
        prepared.positive_order, positive[np.argsort(steps[positive], kind="stable")]
    )
    for seed in range(3):
        guesses = [
            D.initial_guess(s, angles, 3, "gamma", "wrappedcauchy", rng=np.random.default_rng(seed))
            for s in (steps, prepared)
        ]
        assert guesses[0] == guesses[1]
    # the guess is usable: finite log-likelihood on the data
    assert np.isfinite(a[0].logpdf(steps) + a[1].logpdf(angles)).all()


# --- bad input ----------------------------------------------------------------------------


def test_bad_input_raises_clear_errors():
    g = D.Gamma([1.0], [1.0])
    with pytest.raises(ValueError, match=r"negative at rows \[1\]"):
        g.logpdf(np.array([1.0, -0.5]))
    with pytest.raises(ValueError, match=r"rows \[0\].*need zero-inflation"):
        g.logpdf(np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match=r"shape \(2, 1\)"):
        g.fit_weighted(np.array([1.0, 2.0]), np.ones((2, 2)))
    with pytest.raises(ValueError, match="weights must be finite"):
        g.fit_weighted(np.array([1.0, 2.0]), np.array([[1.0], [np.nan]]))
    with pytest.raises(ValueError, match="sd must be > 0"):
        D.Gamma([1.0], [-1.0])
    with pytest.raises(ValueError, match="same number of states"):
        D.Gamma([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="all 0 when estimate_mean is False"):
        D.VonMises([0.5], [1.0], estimate_mean=False)
    with pytest.raises(ValueError, match="estimate_mean must be True or False"):
        D.from_dict(
            {"family": "vonmises", "mean": [0.0], "concentration": [1.0], "estimate_mean": 1}
        )
    with pytest.raises(ValueError, match="Gamma.sd must be an array of numbers"):
        D.from_dict({"family": "gamma", "mean": [1.0], "sd": ["wide"]})
    with pytest.raises(ValueError, match=r"in \[0, 1\)"):
        D.WrappedCauchy([0.0], [1.0])
    with pytest.raises(ValueError, match="unknown distribution family 'cauchy'"):
        D.from_dict({"family": "cauchy"})
    with pytest.raises(ValueError, match="expected keys"):
        D.from_dict({"family": "gamma", "mean": [1.0]})
    with pytest.raises(ValueError, match="states must be in"):
        g.sample(np.random.default_rng(0), np.array([0, 1]))
    with pytest.raises(ValueError, match="expected 2 working parameters"):
        D.Gamma.from_working(np.zeros(3), 1)
