"""Emission formulas (hmmtrack.hmm.emission): covariates on a stream's distribution.

Oracles: the per-row link derivatives against central differences for every family, the
row densities against the families' own ``logpdf``, the design matrices against hand-built
ones, constant formulas against the plain fit of the elk data (moveHMM's optimum), and the
recovery of a cosinor step mean from 20,000 simulated steps within 2 standard errors.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from hmmtrack import tracks
from hmmtrack.hmm import (
    Exponential,
    Gamma,
    LogNormal,
    MovementHMM,
    MovementHMMEstimator,
    VonMises,
    Weibull,
    WrappedCauchy,
    diagnostics,
    distributions,
    fit,
)
from hmmtrack.hmm.emission import CovariateEmission, split_formulas
from hmmtrack.hmm.formula import design
from hmmtrack.hmm.inference import forward_backward

ELK = Path(__file__).resolve().parents[2] / "shared" / "data" / "elk_data.csv"
N = 20_000
COEFFICIENTS = np.array([[0.0, 0.3, -0.2], [np.log(6.0), 0.4, 0.25]])  # log mean, per state


def cosinor(n: int) -> pd.DataFrame:
    hour = (np.arange(n) * 0.25) % 24
    return pd.DataFrame(
        {"cosT": np.cos(2 * np.pi * hour / 24), "sinT": np.sin(2 * np.pi * hour / 24)}
    )


@pytest.fixture(scope="module")
def simulated():
    """20,000 rows of a 2-state model whose step mean follows the time of day."""
    table = cosinor(N)
    step = CovariateEmission(
        Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0])),
        {"mean": design("~ cosT + sinT", table)},
        {"mean": COEFFICIENTS},
    )
    truth = MovementHMM(
        np.array([0.5, 0.5]),
        np.array([[0.9, 0.1], [0.15, 0.85]]),
        step,
        VonMises(np.array([0.0, 0.0]), np.array([0.5, 4.0])),
    )
    data = truth.simulate(np.random.default_rng(11), N, table).join(table)
    model = MovementHMMEstimator(2, formulas={"step.mean": "~ cosT + sinT"}, seed=1).fit(data)
    return truth, data, model.model_


def test_cosinor_step_mean_recovered_within_two_standard_errors(simulated):
    truth, data, model = simulated
    intervals = diagnostics.confidence_intervals(model, data)
    beta = intervals[intervals.parameter.str.startswith("step.mean.beta.")]
    assert list(beta.parameter.unique()) == [
        "step.mean.beta.intercept",
        "step.mean.beta.cosT",
        "step.mean.beta.sinT",
    ]
    expected = COEFFICIENTS.T.ravel()  # column by column, states within
    np.testing.assert_array_less(np.abs(beta.estimate.to_numpy() - expected), 2 * beta.se)
    assert beta.se.max() < 0.01
    # the constant parameters within 5 %
    np.testing.assert_allclose(model.step.base.sd, truth.step.base.sd, rtol=0.05)
    np.testing.assert_allclose(model.angle.concentration, truth.angle.concentration, rtol=0.05)
    np.testing.assert_allclose(model.transition, truth.transition, rtol=0.05)
    assert model.log_likelihood >= truth.score(data)


def test_design_matrices_equal_hand_built_ones(simulated):
    _, data, model = simulated
    matrices = model.observations(data).emission["step"]
    columns = data[["cosT", "sinT"]].to_numpy()
    hand = np.column_stack(
        [np.ones(N), (columns - columns.mean(axis=0)) / columns.std(axis=0, ddof=1)]
    )
    np.testing.assert_allclose(matrices["mean"], hand, atol=1e-12)
    # the fitted mean of each row is exp(hand @ coefficients)
    row_means = model.step._row_distribution(
        1, fit.fit_data(model.observations(data)).inputs["step"]
    )
    np.testing.assert_allclose(
        row_means.mean, np.exp(hand @ model.step.coefficients["mean"][1]), rtol=1e-12
    )


def test_summary_and_json_round_trip(simulated, tmp_path):
    _, data, model = simulated
    text = diagnostics.summary(model)
    assert "step.mean coefficients (~ cosT + sinT, link scale) on the data's scale" in text
    raw = np.column_stack([np.ones(N), data[["cosT", "sinT"]].to_numpy()])
    on_data = diagnostics.emission_coefficients(model)["step.mean"].to_numpy()
    standardised = model.observations(data).emission["step"]["mean"]
    np.testing.assert_allclose(
        raw @ on_data.T, standardised @ model.step.coefficients["mean"].T, atol=1e-12
    )
    path = tmp_path / "model.json"
    model.save(path)
    document = MovementHMM.load(path).to_dict()
    assert document["version"] == 3 and document == model.to_dict()
    loaded = MovementHMM.load(path)
    part = data.iloc[:500].reset_index(drop=True)
    np.testing.assert_array_equal(loaded.state_probabilities(part), model.state_probabilities(part))
    document["step"]["formulas"]["mean"]["colums"] = ["Intercept"]
    with pytest.raises(ValueError, match="formulas.mean.colums"):
        MovementHMM.from_dict(document)
    plain = MovementHMM(model.initial, model.transition, model.step.base, model.angle)
    assert plain.to_dict()["version"] == 2


def test_formula_keys_are_checked():
    assert split_formulas({"transition": "~ a", "step.mean": "~ b", "angle.mean": "~ c"}) == (
        "~ a",
        {"step": {"mean": "~ b"}, "angle": {"mean": "~ c"}},
    )
    with pytest.raises(ValueError, match="'<stream>.<parameter>'"):
        split_formulas({"depth.mean": "~ b"})
    data = pd.DataFrame({"step": np.arange(1.0, 41.0), "angle": 0.1, "c": np.arange(40.0)})
    with pytest.raises(ValueError, match=r"take a formula are \['mean', 'sd'\]"):
        MovementHMMEstimator(2, formulas={"step.shape": "~ c"}).fit(data)
    with pytest.raises(ValueError, match="not several"):
        MovementHMMEstimator(2, formula="~ c", formulas={"transition": "~ c"}).fit(data)


FAMILIES = [
    (Gamma, 2, {"zero_inflated": True}),
    (Weibull, 2, {"zero_inflated": True}),
    (LogNormal, 2, {"zero_inflated": True}),
    (Exponential, 1, {"zero_inflated": True}),
    (VonMises, 2, {"estimate_mean": True}),
    (VonMises, 1, {"estimate_mean": False}),
    (WrappedCauchy, 2, {"estimate_mean": True}),
    (WrappedCauchy, 1, {"estimate_mean": False}),
]


@pytest.mark.parametrize(("family", "n_links", "structure"), FAMILIES)
def test_row_derivatives_are_those_of_row_densities(family, n_links, structure):
    rng = np.random.default_rng(3)
    size = 9
    if "zero_inflated" in structure:
        x = rng.gamma(2.0, 1.0, size)
        x[[2, 5]] = [0.0, np.nan]
        n_links += 1
    else:
        x = rng.vonmises(0.3, 1.0, size)
        x[4] = np.nan
    eta = rng.normal(0.0, 0.5, (n_links, size))
    if "zero_inflated" in structure:
        eta[-1] -= 2.0  # zero mass about 0.1
    row = family.from_links(eta, **structure)
    score = row.row_score(x)
    value, same_score, second = row.row_derivatives(x)
    np.testing.assert_allclose(value, row.row_logpdf(x), rtol=1e-13)
    np.testing.assert_allclose(same_score, score, rtol=1e-13)
    np.testing.assert_array_equal(second, second.transpose(1, 0, 2))
    for j in range(n_links):
        shift = np.zeros_like(eta)
        shift[j] = 1e-6
        up = family.from_links(eta + shift, **structure).row_logpdf(x)
        down = family.from_links(eta - shift, **structure).row_logpdf(x)
        np.testing.assert_allclose(score[j], (up - down) / 2e-6, atol=1e-7)
        # the second derivatives against central differences of the scores
        up = family.from_links(eta + shift, **structure).row_score(x)
        down = family.from_links(eta - shift, **structure).row_score(x)
        np.testing.assert_allclose(second[:, j], (up - down) / 2e-6, atol=1e-6)
    # row t's density is the density of a one-state member with row t's parameters
    one_state = [
        family.from_links(eta[:, [t]], **structure).logpdf(x[[t]])[0, 0] for t in range(size)
    ]
    np.testing.assert_allclose(row.row_logpdf(x), one_state, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(family.from_links(row.to_links(), **structure).to_links(), eta)


def test_emission_gradient_is_the_likelihood_gradient(simulated):
    """Fisher's identity with emission formulas: the analytic gradient of the working
    likelihood equals central differences of its value."""
    _, data, model = simulated
    part = data.iloc[:800].reset_index(drop=True)
    likelihood = fit.WorkingLikelihood(
        fit.parameters_of(model), fit.fit_data(model.observations(part))
    )
    theta = likelihood.pack(fit.parameters_of(model))
    gradient = likelihood.value_and_gradient(theta)[1]
    # directional derivatives along random directions, by central differences
    directions = np.random.default_rng(0).normal(size=(4, theta.size))
    slopes = [
        (likelihood.value(theta + 1e-5 * d) - likelihood.value(theta - 1e-5 * d)) / 2e-5
        for d in directions
    ]
    np.testing.assert_allclose(directions @ gradient, slopes, rtol=1e-5, atol=1e-4)


def test_constant_formulas_reach_the_movehmm_optimum_on_elk():
    if not ELK.exists():
        pytest.skip(f"elk data not found at {ELK}")
    raw = pd.read_csv(ELK).rename(columns={"ID": "id", "Easting": "x", "Northing": "y"})
    elk = tracks.prepare(raw, scale=1000.0)
    constant = {"step.mean": "~ 1", "step.sd": "~ 1", "angle.concentration": "~ 1"}
    model = (
        MovementHMMEstimator(2, formulas=constant, n_starts=2, seed=1, step_unit="km")
        .fit(elk)
        .model_
    )
    # moveHMM's optimum (the Newton M-step reaches it: -1892.9744502, the plain fit
    # -1892.9744495); the zero mass of state 2 tends to 0 on the logit scale, a direction so
    # flat that 1e-6 of log-likelihood moves the state-2 parameters by 3e-4 relative
    assert model.log_likelihood == pytest.approx(-1892.97445, abs=1e-5)
    assert model.n_obs == len(elk)
    np.testing.assert_allclose(model.step.base.mean, [0.373776, 3.247479], rtol=5e-4)
    np.testing.assert_allclose(model.angle.base.concentration, [0.592387, 0.207992], rtol=1e-3)


CDF_EXAMPLES = [
    Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0]), np.array([0.1, 0.2])),
    Weibull(np.array([0.8, 2.0]), np.array([1.0, 5.0]), np.array([0.1, 0.2])),
    LogNormal(np.array([0.0, 1.5]), np.array([0.7, 0.3]), np.array([0.1, 0.2])),
    Exponential(np.array([1.0, 0.2]), np.array([0.1, 0.2])),
    VonMises(np.array([3.0, 0.2]), np.array([0.7, 4.0])),
    WrappedCauchy(np.array([-2.0, 0.1]), np.array([0.3, 0.8])),
    distributions.Normal(np.array([20.0, 5.0]), np.array([6.0, 2.0])),
    distributions.Beta(np.array([2.0, 5.0]), np.array([6.0, 1.5])),
    distributions.Poisson(np.array([3.0, 0.5])),
    distributions.NegativeBinomial(np.array([3.0, 20.0]), np.array([1.5, 6.0])),
    distributions.Bernoulli(np.array([0.2, 0.85])),
    distributions.ZeroInflatedPoisson(np.array([3.0, 10.0]), np.array([0.3, 0.2])),
    distributions.ZeroInflatedNegativeBinomial(
        np.array([3.0, 20.0]), np.array([4.0, 6.0]), np.array([0.3, 0.2])
    ),
    distributions.ZeroOneInflatedBeta(
        np.array([2.0, 5.0]), np.array([6.0, 1.5]), np.array([0.2, 0.1]), np.array([0.1, 0.3])
    ),
    distributions.Categorical(np.array([[0.6, 0.3, 0.1], [0.1, 0.2, 0.7]])),
]


@pytest.mark.parametrize("dist", CDF_EXAMPLES, ids=lambda d: d.name)
def test_row_cdf_with_every_row_in_one_state_is_that_states_cdf(dist):
    """``row_cdf`` (and ``row_cdf_below``) of a row distribution whose T rows all have
    state k's parameters equals column k of ``cdf`` (``cdf_below``), missing rows NaN."""
    rng = np.random.default_rng(5)
    x = dist.sample(rng, rng.integers(0, 2, 60))
    x[[3, 17]] = np.nan
    if dist.name in ("gamma", "weibull", "lognormal", "exponential"):
        x[[4, 9]] = 0.0
    for k in range(2):
        eta = np.repeat(dist.to_links()[:, [k]], x.size, axis=1)
        row = type(dist).from_links(eta, **dist._structure())
        np.testing.assert_allclose(row.row_cdf(x), dist.cdf(x)[:, k], rtol=1e-12, atol=1e-15)
        if hasattr(dist, "cdf_below"):
            np.testing.assert_allclose(
                row.row_cdf_below(x), dist.cdf_below(x)[:, k], rtol=1e-12, atol=1e-15
            )
        assert np.isnan(row.row_cdf(x)[[3, 17]]).all()


def test_formula_stream_residuals_equal_a_per_row_scipy_forecast():
    """Pseudo-residuals of a step mean and a further stream's (normal) mean with formulas:
    per row, ``Phi^-1`` of the forecast mixture of scipy CDFs at the row's parameters (the
    normal stream continuous: its randomised residual has P(X < x) = P(X <= x))."""
    n = 30
    table = cosinor(n).assign(segment="a")
    step = CovariateEmission(
        Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0])),
        {"mean": design("~ cosT + sinT", table)},
        {"mean": COEFFICIENTS},
    )
    depth = CovariateEmission(
        distributions.Normal(np.array([20.0, 5.0]), np.array([6.0, 2.0])),
        {"mean": design("~ cosT", table)},
        {"mean": np.array([[20.0, 3.0], [5.0, -2.0]])},
    )
    model = MovementHMM(
        np.array([0.4, 0.6]),
        np.array([[0.85, 0.15], [0.1, 0.9]]),
        step,
        VonMises(np.array([3.0, 0.2]), np.array([0.7, 4.0])),
        streams={"depth": depth},
    )
    data = model.simulate(np.random.default_rng(2), n, table).join(table)
    data.loc[[5, 11], "depth"] = np.nan
    residuals = diagnostics.pseudo_residuals(model, data)
    observations = model.observations(data)
    log_lik = model.log_likelihood_matrix(observations)
    step_matrix = observations.emission["step"]["mean"]
    depth_matrix = observations.emission["depth"]["mean"]
    for t in range(n):
        forecast = model.initial
        if t > 0:
            past = forward_backward(
                np.log(model.initial), np.log(model.transition), log_lik[:t]
            ).posterior[-1]
            forecast = past @ model.transition
        mean = np.exp(step_matrix[t] @ COEFFICIENTS.T)
        sd = step.base.sd
        step_cdf = stats.gamma.cdf(data.step[t], a=(mean / sd) ** 2, scale=sd**2 / mean)
        depth_mean = depth_matrix[t] @ depth.coefficients["mean"].T
        depth_cdf = stats.norm.cdf(data.depth[t], depth_mean, depth.base.sd)
        for name, cdf in (("step", step_cdf), ("depth", depth_cdf)):
            residual = residuals[f"{name}_residual"][t]
            if np.isnan(data[name][t]):
                assert np.isnan(residual)
            else:
                expected = stats.norm.ppf(forecast @ cdf)
                np.testing.assert_allclose(residual, expected, rtol=1e-9, atol=1e-12)


def test_residuals_of_a_fitted_formula_model_are_standard_normal(simulated):
    """On 20,000 rows simulated with a cosinor step mean, the fitted formula model's step
    residuals pass a KS test against N(0, 1); the same model without the cosinor (its
    slopes set to 0) is rejected."""
    truth, data, model = simulated
    residuals = diagnostics.pseudo_residuals(model, data)
    for column in ("step_residual", "angle_residual"):
        assert stats.kstest(residuals[column].dropna(), "norm").pvalue > 0.01
    flat = CovariateEmission(
        model.step.base,
        model.step.designs,
        {"mean": model.step.coefficients["mean"] * np.array([1.0, 0.0, 0.0])},
    )
    wrong = diagnostics.pseudo_residuals(replace(model, step=flat), data)["step_residual"]
    assert stats.kstest(wrong.dropna(), "norm").pvalue < 1e-6
