"""Tests of hmmtrack.hmm.constraints and the constrained fit: fixed parameters, equality
constraints, a stationary initial distribution, the check of starting values, state names in
the model file.

The oracle is a reduced likelihood written here from scipy's densities and a plain forward
recursion, maximised by scipy over the parameters that remain free.
"""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import optimize, special

from hmmtrack import tracks
from hmmtrack.hmm import diagnostics, fit
from hmmtrack.hmm.constraints import Constraints, FitControl
from hmmtrack.hmm.decoding import decode_table
from hmmtrack.hmm.distributions import Gamma, VonMises
from hmmtrack.hmm.fit import MovementHMMEstimator
from hmmtrack.hmm.inference import forward_backward
from hmmtrack.hmm.model import MovementHMM

ELK = Path(__file__).resolve().parents[2] / "shared" / "data" / "elk_data.csv"
TRUE = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=np.array([[0.9, 0.1], [0.2, 0.8]]),
    step=Gamma(mean=np.array([2.0, 10.0]), sd=np.array([1.5, 4.0])),
    angle=VonMises(np.zeros(2), np.array([1.0, 5.0]), estimate_mean=False),
)


@pytest.fixture(scope="module")
def small() -> pd.DataFrame:
    """300 rows of one track (angle means fixed at 0: fewer free parameters)."""
    return TRUE.simulate(np.random.default_rng(11), 300)[["step", "angle"]]


def oracle_log_likelihood(data, mean, sd, kappa, gamma, delta) -> float:
    """Log-likelihood by the scaled forward recursion, with the gamma (mean, sd) and von Mises
    (mean 0) densities written out (scipy's special functions)."""
    step, angle = data["step"].to_numpy()[:, None], data["angle"].to_numpy()[:, None]
    shape, scale = (mean / sd) ** 2, sd**2 / mean
    log_density = (
        (shape - 1) * np.log(step)
        - step / scale
        - special.gammaln(shape)
        - shape * np.log(scale)
        + kappa * np.cos(angle)
        - np.log(2 * np.pi * special.i0(kappa))
    )
    density = np.exp(log_density)
    alpha = delta * density[0]
    total = np.log(alpha.sum())
    alpha /= alpha.sum()
    for row in density[1:]:
        alpha = (alpha @ gamma) * row
        norm = alpha.sum()
        total += np.log(norm)
        alpha /= norm
    return float(total)


def two_state_gamma(off_diagonal) -> np.ndarray:
    p12, p21 = special.expit(off_diagonal)
    return np.array([[1 - p12, p12], [p21, 1 - p21]])


def left_eigenvector(gamma) -> np.ndarray:
    values, vectors = np.linalg.eig(gamma.T)
    vector = np.real(vectors[:, np.argmin(np.abs(values - 1))])
    return vector / vector.sum()


def maximise(negative, start) -> optimize.OptimizeResult:
    return optimize.minimize(negative, start, method="BFGS", options={"gtol": 1e-7})


def fit_small(data, **options) -> MovementHMMEstimator:
    return MovementHMMEstimator(2, estimate_angle_mean=False, seed=3, **options).fit(data)


def test_a_fixed_parameter_keeps_its_value_and_the_rest_is_the_reduced_optimum(small):
    estimator = fit_small(small, fixed={"step.mean[1]": 2.5, "initial[1]": 0.5})
    model = estimator.model_
    assert model.step.mean[0] == pytest.approx(2.5, rel=1e-12)
    np.testing.assert_allclose(model.initial, [0.5, 0.5], rtol=1e-12)
    assert estimator.n_parameters_ == 7  # 8 working parameters of TRUE's form, 1 fixed

    def negative(theta):
        mean = np.array([2.5, np.exp(theta[0])])
        sd, kappa = np.exp(theta[1:3]), np.exp(theta[3:5])
        gamma = two_state_gamma(theta[5:7])
        return -oracle_log_likelihood(small, mean, sd, kappa, gamma, np.array([0.5, 0.5]))

    start = np.array([np.log(10), np.log(1.5), np.log(4), 0.0, np.log(5), -2.0, -1.5])
    oracle = maximise(negative, start)
    assert model.log_likelihood == pytest.approx(-oracle.fun, abs=1e-5)
    assert model.log_likelihood >= -oracle.fun - 1e-6
    np.testing.assert_allclose(model.step.mean[1], np.exp(oracle.x[0]), rtol=1e-3)
    np.testing.assert_allclose(model.step.sd, np.exp(oracle.x[1:3]), rtol=1e-3)
    np.testing.assert_allclose(model.angle.concentration, np.exp(oracle.x[3:5]), rtol=1e-3)
    np.testing.assert_allclose(model.transition, two_state_gamma(oracle.x[5:7]), atol=1e-4)
    # the fixed parameters have no standard error (the angle means' is 0: not estimated)
    intervals = diagnostics.confidence_intervals(model, small)
    fixed = intervals[intervals["fixed"]]
    assert set(zip(fixed["parameter"], fixed["index"], strict=True)) == {
        ("step.mean", "1"),
        ("initial", "1"),
        ("initial", "2"),
    }
    estimated = intervals[~intervals["fixed"] & (intervals["parameter"] != "angle.mean")]
    assert fixed["se"].isna().all() and estimated["se"].gt(0).all()
    text = diagnostics.summary(model, intervals)
    assert "fixed: step.mean[1]=2.5, initial[1]=0.5" in text
    assert any(line.split()[:4] == ["step.mean", "1", "2.5", "fixed"] for line in text.split("\n"))


def test_an_equality_gives_the_optimum_of_the_hand_reduced_likelihood(small):
    tie = "angle.concentration[1]==angle.concentration[2]"
    estimator = fit_small(small, equal=[tie], fixed={"initial[1]": 0.5})
    model = estimator.model_
    kappa = model.angle.concentration
    assert kappa[0] == kappa[1]
    assert estimator.n_parameters_ == 7

    def negative(theta):
        mean, sd = np.exp(theta[0:2]), np.exp(theta[2:4])
        gamma = two_state_gamma(theta[5:7])
        return -oracle_log_likelihood(
            small, mean, sd, np.full(2, np.exp(theta[4])), gamma, np.array([0.5, 0.5])
        )

    start = np.array([np.log(2), np.log(10), np.log(1.5), np.log(4), np.log(2), -2.0, -1.5])
    oracle = maximise(negative, start)
    assert model.log_likelihood == pytest.approx(-oracle.fun, abs=1e-5)
    np.testing.assert_allclose(kappa[0], np.exp(oracle.x[4]), rtol=1e-3)
    np.testing.assert_allclose(model.step.mean, np.exp(oracle.x[0:2]), rtol=1e-3)
    intervals = diagnostics.confidence_intervals(model, small)
    se = intervals.loc[intervals["parameter"] == "angle.concentration", "se"].to_numpy()
    assert se[0] == pytest.approx(se[1], rel=1e-9) and se[0] > 0


def test_the_stationary_initial_distribution_is_the_eigenvector_at_the_optimum(small):
    estimator = fit_small(small, stationary=True)
    model = estimator.model_
    np.testing.assert_allclose(model.initial, left_eigenvector(model.transition), atol=1e-10)
    assert estimator.n_parameters_ == 8  # 4 step, 2 angle, 2 transition; delta follows

    def negative(theta):
        gamma = two_state_gamma(theta[6:8])
        delta = left_eigenvector(gamma)
        mean, sd, kappa = np.exp(theta[0:2]), np.exp(theta[2:4]), np.exp(theta[4:6])
        return -oracle_log_likelihood(small, mean, sd, kappa, gamma, delta)

    start = np.array([np.log(2), np.log(10), np.log(1.5), np.log(4), 0.0, np.log(5), -2.0, -1.5])
    oracle = maximise(negative, start)
    assert model.log_likelihood == pytest.approx(-oracle.fun, abs=1e-5)
    np.testing.assert_allclose(model.transition, two_state_gamma(oracle.x[6:8]), atol=1e-4)


def test_constrained_gradient_matches_finite_differences(small):
    """Fixed, tied and stationary at once, with a transition covariate: the free vector's
    gradient (link Jacobians, tie sums, the stationary term) against central differences."""
    data = small.assign(x=np.sin(np.arange(len(small)) / 25.0))
    estimator = MovementHMMEstimator(
        2,
        covariates=["x"],
        fixed={"step.sd[2]": 4.0, "transition.x[1,2]": 0.3},
        equal=["angle.concentration[1]==angle.concentration[2]"],
        stationary=True,
        n_starts=1,
        seed=1,
        max_iter=5,
        polish=False,
    ).fit(data)
    likelihood = fit.model_likelihood(estimator.model_, data)
    assert isinstance(likelihood, fit.ConstrainedLikelihood)
    theta = likelihood.pack(fit.parameters_of(estimator.model_)) + 0.05
    value, gradient = likelihood.value_and_gradient(theta)
    assert value == pytest.approx(likelihood.value(theta), abs=1e-9)
    shifts = np.eye(theta.size) * 1e-5
    numeric = [(likelihood.value(theta + h) - likelihood.value(theta - h)) / 2e-5 for h in shifts]
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-4)
    model = estimator.model_
    assert model.step.sd[1] == pytest.approx(4.0)
    assert model.coefficients[0, model.transition_design.columns.index("x")] == 0.3


@pytest.mark.parametrize(
    ("control", "words"),
    [
        ({"fixed": {"step.mean[3]": 1.0}}, "state 3; the model has states 1..2"),
        ({"fixed": {"step.mena[1]": 1.0}}, "has parameters ['mean', 'sd']"),
        ({"fixed": {"depth.mean[1]": 1.0}}, "with a stream in ['step', 'angle']"),
        ({"fixed": {"step.mean[1]": -1.0}}, "Gamma.mean must be > 0"),
        ({"fixed": {"angle.mean[1]": 0.1}}, "the angle mean is not estimated"),
        ({"fixed": {"transition[1,1]": 0.1}}, "off-diagonal entry"),
        ({"fixed": {"transition.x[1,2]": 0.1}}, "no transition design column 'x'"),
        ({"fixed": {"initial[1]": 0.5}, "stationary": True}, "stationary, not fixed"),
        ({"equal": ["step.mean[1]==step.sd[2]"]}, "the same parameter of the same stream"),
        (
            {
                "fixed": {"step.mean[1]": 1.0, "step.mean[2]": 2.0},
                "equal": ["step.mean[1]==step.mean[2]"],
            },
            "both sides are fixed at other values",
        ),
        ({"equal": ["step.mean[1]"]}, "expected 'a==b'"),
    ],
)
def test_constraints_refuse_what_they_cannot_mean_naming_it(control, words):
    template = fit.parameters_of(TRUE)
    with pytest.raises(ValueError, match=None) as info:
        Constraints(FitControl(**control), template, ("Intercept",))
    assert words in str(info.value)


def test_three_state_rows_are_fixed_whole_and_formula_parameters_only_tied():
    three = fit.Parameters(
        np.full(3, 1 / 3),
        np.full((3, 3), 1 / 3),
        None,
        Gamma(np.array([1.0, 2.0, 3.0]), np.ones(3)),
        VonMises(np.zeros(3), np.ones(3)),
    )
    with pytest.raises(ValueError, match=r"fix the whole row transition\[1,j\]"):
        Constraints(FitControl({"transition[1,2]": 0.1}), three, ("Intercept",))
    row = Constraints(
        FitControl({"transition[1,2]": 0.1, "transition[1,3]": 0.3}), three, ("Intercept",)
    )
    params = row.project(three)
    np.testing.assert_allclose(params.transition[0], [0.6, 0.1, 0.3], rtol=1e-12)
    np.testing.assert_allclose(params.transition[1], [1 / 3] * 3, rtol=1e-12)


def test_formula_parameters_tie_their_coefficients():
    rng = np.random.default_rng(4)
    table = TRUE.simulate(rng, 300).assign(x=rng.normal(size=300))
    with pytest.raises(ValueError, match="can be tied but not fixed"):
        fit_small(table, formulas={"step.mean": "~ x"}, fixed={"step.mean[1]": 2.0})
    model = fit_small(
        table, formulas={"step.mean": "~ x"}, equal=["step.mean[1]==step.mean[2]"]
    ).model_
    coefficients = model.step.coefficients["mean"]
    np.testing.assert_array_equal(coefficients[0], coefficients[1])


def test_control_and_state_names_round_trip_and_old_files_still_load(small, tmp_path):
    model = fit_small(
        small,
        fixed={"step.mean[1]": 2.5},
        equal=["angle.concentration[1]==angle.concentration[2]"],
        stationary=True,
        state_names=["slow", "fast"],
    ).model_
    path = tmp_path / "model.json"
    model.save(path)
    document = json.loads(path.read_text())
    assert document["version"] == 4 and document["state_names"] == ["slow", "fast"]
    assert document["control"] == {
        "fixed": {"step.mean[1]": 2.5},
        "equal": ["angle.concentration[1]==angle.concentration[2]"],
        "stationary": True,
    }
    again = MovementHMM.load(path)
    assert again.to_dict() == model.to_dict()
    assert again.control == model.control and again.state_names == ("slow", "fast")
    assert set(decode_table(again, small)["state_name"]) <= {"slow", "fast"}
    # without names or control the file stays version 2 and loads with neither
    plain = fit_small(small).model_
    assert plain.to_dict()["version"] == 2 and "control" not in plain.to_dict()
    assert MovementHMM.from_dict(plain.to_dict()).state_names is None
    # the new fields are refused in older versions; names must fit the states
    older = dict(document, version=3)
    with pytest.raises(ValueError, match="unknown field"):
        MovementHMM.from_dict(older)
    with pytest.raises(ValueError, match="state names"):
        MovementHMM.from_dict(dict(document, state_names=["one"]))
    with pytest.raises(ValueError, match="control"):
        MovementHMM.from_dict(dict(document, control={"fixed": {}, "free": []}))


def test_check_starts_on_elk_finds_the_movehmm_optimum():
    if not ELK.exists():
        pytest.skip(f"elk data not found at {ELK}")
    raw = pd.read_csv(ELK).rename(columns={"ID": "id", "Easting": "x", "Northing": "y"})
    elk = tracks.prepare(raw, scale=1000.0)
    table = diagnostics.check_starts(elk, 2, n_starts=4, rng=1, step_unit="km")
    assert list(table["start"]) == [1, 2, 3, 4]
    best = table.loc[table["best"], "log_likelihood"]
    assert best.max() == pytest.approx(-1892.97445, abs=1e-3)
    assert (table["log_likelihood"] <= best.max()).all()
    at_best = table[table["best"]]
    np.testing.assert_allclose(at_best["step.mean[1]"], 0.3738, atol=2e-3)
    assert {"step.mean[2]", "angle.concentration[1]", "transition[1,2]"} <= set(table)

    import matplotlib

    matplotlib.use("Agg")
    from hmmtrack.plots.hmm import starts_figure

    figure = starts_figure(table)
    assert f"of 4 starts at the best {best.max():.5f}" in figure.axes[0].get_title()


def test_each_animal_starts_in_the_stationary_distribution_at_its_first_row(small):
    """Two animals whose first rows have opposite covariates: with ``stationary`` each
    track starts in the stationary distribution of its own first row's transition matrix.
    The fitted log-likelihood is the sum of per-animal forward recursions with those
    starts, and the free vector's gradient (the per-animal stationary terms) matches
    central differences."""
    data = small.assign(
        x=np.cos(np.pi * np.arange(len(small)) / 150.0), segment=np.repeat(["a", "b"], 150)
    )
    estimator = MovementHMMEstimator(
        2, covariates=["x"], stationary=True, n_starts=1, seed=1, max_iter=20
    ).fit(data)
    model = estimator.model_
    total, starts = 0.0, []
    for _, animal in data.groupby("segment"):
        observations = model.observations(animal)
        delta = model.stationary(animal.iloc[:1])[0]
        starts.append(delta)
        total += forward_backward(
            np.log(delta),
            model.log_transition_for(observations),
            model.log_likelihood_matrix(observations),
        ).log_likelihood
    assert np.abs(starts[0] - starts[1]).max() > 0.05
    np.testing.assert_allclose(np.exp(model.log_initial_for(model.observations(data))), starts)
    assert model.log_likelihood == pytest.approx(total, abs=1e-8)
    assert model.score(data) == pytest.approx(total, abs=1e-8)
    likelihood = fit.model_likelihood(model, data)
    theta = likelihood.pack(fit.parameters_of(model)) + 0.05
    gradient = likelihood.value_and_gradient(theta)[1]
    shifts = np.eye(theta.size) * 1e-5
    numeric = [(likelihood.value(theta + h) - likelihood.value(theta - h)) / 2e-5 for h in shifts]
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-4)
