"""Further data streams: the families of hmmtrack.hmm.distributions.values and models with a
third stream (and a fourth), fitted, recovered, saved and read back."""

import numpy as np
import pytest
from scipy import stats

from hmmtrack.hmm import Gamma, MovementHMM, MovementHMMEstimator, VonMises, diagnostics
from hmmtrack.hmm.distributions import (
    VALUE_FAMILIES,
    Bernoulli,
    Beta,
    Categorical,
    NegativeBinomial,
    Normal,
    Poisson,
    ZeroInflatedNegativeBinomial,
    ZeroInflatedPoisson,
    ZeroOneInflatedBeta,
)

STEP = Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0]))
ANGLE = VonMises(np.array([0.0, 0.0]), np.array([0.5, 4.0]))
TRANSITION = np.array([[0.9, 0.1], [0.15, 0.85]])
STREAMS = {
    "normal": Normal(np.array([20.0, 5.0]), np.array([6.0, 2.0])),
    "beta": Beta(np.array([2.0, 5.0]), np.array([6.0, 1.5])),
    "poisson": Poisson(np.array([3.0, 0.5])),
    "negativebinomial": NegativeBinomial(np.array([3.0, 20.0]), np.array([1.5, 6.0])),
    "bernoulli": Bernoulli(np.array([0.2, 0.85])),
    "zipoisson": ZeroInflatedPoisson(np.array([3.0, 10.0]), np.array([0.3, 0.2])),
    "zinegativebinomial": ZeroInflatedNegativeBinomial(
        np.array([8.0, 20.0]), np.array([4.0, 6.0]), np.array([0.3, 0.2])
    ),
    "zoibeta": ZeroOneInflatedBeta(
        np.array([2.0, 5.0]), np.array([6.0, 1.5]), np.array([0.2, 0.1]), np.array([0.1, 0.3])
    ),
    "categorical": Categorical(np.array([[0.6, 0.3, 0.1], [0.1, 0.2, 0.7]])),
}


def _inflated(count_logpmf, zero_mass):
    """log P(x) of a count distribution with a structural zero of probability zero_mass."""
    return lambda x: np.log(
        np.where(x == 0, zero_mass, 0.0) + (1 - zero_mass) * np.exp(count_logpmf(x))
    )


def _zoibeta(d, k):
    def logpdf(x):
        beta = np.log1p(-d.zero_mass[k] - d.one_mass[k]) + stats.beta(
            d.shape1[k], d.shape2[k]
        ).logpdf(np.clip(x, 1e-9, 1 - 1e-9))
        return np.where(
            x == 0, np.log(d.zero_mass[k]), np.where(x == 1, np.log(d.one_mass[k]), beta)
        )

    return logpdf


SCIPY = {  # the same members in scipy.stats, for the densities
    "normal": lambda d, k: stats.norm(d.mean[k], d.sd[k]).logpdf,
    "beta": lambda d, k: stats.beta(d.shape1[k], d.shape2[k]).logpdf,
    "poisson": lambda d, k: stats.poisson(d.rate[k]).logpmf,
    "negativebinomial": lambda d, k: (
        stats.nbinom(d.size[k], d.size[k] / (d.size[k] + d.mean[k])).logpmf
    ),
    "bernoulli": lambda d, k: stats.bernoulli(d.prob[k]).logpmf,
    "zipoisson": lambda d, k: _inflated(stats.poisson(d.rate[k]).logpmf, d.zero_mass[k]),
    "zinegativebinomial": lambda d, k: _inflated(
        stats.nbinom(d.size[k], d.size[k] / (d.size[k] + d.mean[k])).logpmf, d.zero_mass[k]
    ),
    "zoibeta": _zoibeta,
    "categorical": lambda d, k: lambda x: np.log(d.prob[k, x.astype(int) - 1]),
}


def test_every_further_family_is_tested():
    assert set(STREAMS) == set(VALUE_FAMILIES)


@pytest.mark.parametrize("name", sorted(STREAMS))
def test_densities_scores_and_missing_values(name):
    dist = STREAMS[name]
    rng = np.random.default_rng(1)
    x = dist.sample(rng, rng.integers(0, 2, 40))
    x[3] = np.nan
    log_pdf = dist.logpdf(x)
    np.testing.assert_array_equal(log_pdf[3], [0.0, 0.0])  # missing: a density of 1
    observed = np.isfinite(x)
    for k in range(2):
        np.testing.assert_allclose(log_pdf[observed, k], SCIPY[name](dist, k)(x[observed]))
    assert np.all(np.isnan(dist.cdf(x)[3]))
    # discrete families: the CDF is the running sum of the probabilities
    if name not in ("normal", "beta", "zoibeta"):
        support = {"categorical": np.arange(1.0, 4.0), "bernoulli": np.arange(2.0)}.get(
            name, np.arange(0.0, 400.0)
        )
        np.testing.assert_allclose(
            np.cumsum(np.exp(dist.logpdf(support)), axis=0), dist.cdf(support), atol=1e-12
        )
        np.testing.assert_allclose(dist.cdf(support)[-1], [1.0, 1.0], atol=1e-12)
    # the per-row link derivatives against central differences
    eta = dist.to_links()[:, rng.integers(0, 2, 40)] + rng.normal(
        0, 0.2, (len(dist.link_names()), 40)
    )
    family = type(dist)
    structure = dist._structure()
    score = family.from_links(eta, **structure).row_score(x)
    for j in range(eta.shape[0]):
        shift = np.zeros_like(eta)
        shift[j] = 1e-6
        numeric = (
            family.from_links(eta + shift, **structure).row_logpdf(x)
            - family.from_links(eta - shift, **structure).row_logpdf(x)
        ) / 2e-6
        np.testing.assert_allclose(score[j], numeric, atol=1e-6)
    np.testing.assert_allclose(
        family.from_links(dist.to_links(), **structure).to_links(), dist.to_links(), atol=1e-12
    )
    assert family.from_dict(dist.to_dict()) == dist
    np.testing.assert_allclose(
        family.from_working(dist.to_working(), 2, **structure).to_working(), dist.to_working()
    )
    with pytest.raises(ValueError, match="observations must be|infinite observations"):
        dist.logpdf(np.array([-0.5 if name != "normal" else np.inf]))


@pytest.mark.parametrize("name", sorted(STREAMS))
def test_a_third_stream_is_recovered_from_20000_rows(name):
    truth = MovementHMM(np.array([0.5, 0.5]), TRANSITION, STEP, ANGLE, streams={"z": STREAMS[name]})
    data = truth.simulate(np.random.default_rng(7), 20_000)
    data.loc[::40, "z"] = np.nan
    model = MovementHMMEstimator(2, streams={"z": name}, seed=1).fit(data).model_
    fitted, true = model.streams["z"].to_dict(), STREAMS[name].to_dict()
    assert fitted.keys() == true.keys()
    for parameter in set(true) - {"family"}:
        np.testing.assert_allclose(fitted[parameter], true[parameter], rtol=0.05)
    np.testing.assert_allclose(model.step.mean, STEP.mean, rtol=0.05)
    np.testing.assert_allclose(model.transition, TRANSITION, rtol=0.05)


def test_two_further_streams_with_a_formula_saved_and_read_back(tmp_path):
    rng = np.random.default_rng(3)
    n = 20_000
    truth = MovementHMM(
        np.array([0.5, 0.5]),
        TRANSITION,
        STEP,
        ANGLE,
        streams={"depth": STREAMS["normal"], "dives": STREAMS["poisson"]},
    )
    data = truth.simulate(rng, n)
    temperature = rng.normal(10.0, 3.0, n)
    data = data.assign(temperature=temperature, depth=data.depth + 0.5 * (temperature - 10.0))
    estimator = MovementHMMEstimator(
        2,
        streams={"depth": "normal", "dives": "poisson"},
        formulas={"depth.mean": "~ temperature"},
        seed=1,
    ).fit(data)
    model = estimator.model_
    coefficients = model.streams["depth"].coefficients["mean"]
    slope_per_degree = coefficients[:, 1] / temperature.std(ddof=1)
    np.testing.assert_allclose(slope_per_degree, [0.5, 0.5], atol=0.05)
    np.testing.assert_allclose(model.streams["dives"].rate, [3.0, 0.5], rtol=0.05)
    path = tmp_path / "model.json"
    model.save(path)
    loaded = MovementHMM.load(path)
    assert loaded.to_dict() == model.to_dict() and loaded.to_dict()["version"] == 3
    part = data.iloc[:300].reset_index(drop=True)
    assert loaded.score(part) == model.score(part)
    document = model.to_dict()
    document["streams"]["dives"]["family"] = "binomial"
    with pytest.raises(ValueError, match="streams.dives"):
        MovementHMM.from_dict(document)
    with pytest.raises(ValueError, match="missing column"):
        model.score(part.drop(columns="dives"))
    with pytest.raises(ValueError, match="cannot be named"):
        MovementHMMEstimator(2, streams={"step": "normal"}).fit(data)
    with pytest.raises(ValueError, match="family 'gaussian' unknown"):
        MovementHMMEstimator(2, streams={"depth": "gaussian"}).fit(data)
    simulated = loaded.simulate(rng, 5, data.iloc[:5])
    assert list(simulated.columns) == ["state", "step", "angle", "depth", "dives"]


@pytest.mark.parametrize("name", sorted(STREAMS))
def test_pseudo_residuals_of_every_further_family_are_standard_normal(name):
    """Forecast pseudo-residuals under the true model (randomised where the family has
    point masses) are N(0, 1); NaN where the value is missing."""
    truth = MovementHMM(np.array([0.5, 0.5]), TRANSITION, STEP, ANGLE, streams={"z": STREAMS[name]})
    data = truth.simulate(np.random.default_rng(7), 5000)
    data.loc[::40, "z"] = np.nan
    residuals = diagnostics.pseudo_residuals(truth, data)["z_residual"]
    assert residuals.isna().sum() == 125
    assert stats.kstest(residuals.dropna(), "norm").pvalue > 1e-3
    if name == "zipoisson":  # a Poisson without the structural zeros is rejected
        plain = MovementHMM(
            truth.initial, TRANSITION, STEP, ANGLE, streams={"z": Poisson(STREAMS[name].rate)}
        )
        wrong = diagnostics.pseudo_residuals(plain, data)["z_residual"]
        assert stats.kstest(wrong.dropna(), "norm").pvalue < 1e-10
