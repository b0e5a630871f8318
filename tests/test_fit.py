"""Tests of hmmtrack.hmm.fit: parameter recovery, covariates, multi-start, labels, gradients."""

import numpy as np
import pandas as pd
import pytest

from hmmtrack.hmm import fit
from hmmtrack.hmm.distributions import Gamma, VonMises, Weibull, WrappedCauchy
from hmmtrack.hmm.fit import MovementHMMEstimator, fit_movement_hmm
from hmmtrack.hmm.formula import Design
from hmmtrack.hmm.model import MovementHMM, Observations

TRUE = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=np.array([[0.9, 0.1], [0.2, 0.8]]),
    step=Gamma(mean=np.array([2.0, 10.0]), sd=np.array([1.5, 4.0])),
    angle=VonMises(np.array([np.pi, 0.5]), np.array([1.0, 5.0])),
    dt=60.0,
)


@pytest.fixture(scope="module")
def simulated() -> pd.DataFrame:
    """20,000 steps in four tracks of 5,000."""
    rng = np.random.default_rng(2024)
    parts = [TRUE.simulate(rng, 5000).assign(segment=f"animal{i}") for i in range(4)]
    return pd.concat(parts, ignore_index=True)


@pytest.fixture(scope="module")
def fitted(simulated) -> MovementHMMEstimator:
    return MovementHMMEstimator(2, n_starts=3, seed=7).fit(simulated)


def test_parameters_are_recovered_from_20000_steps(fitted):
    model = fitted.model_
    np.testing.assert_allclose(model.step.mean, TRUE.step.mean, rtol=0.05)
    np.testing.assert_allclose(model.step.sd, TRUE.step.sd, rtol=0.05)
    np.testing.assert_allclose(model.angle.concentration, TRUE.angle.concentration, rtol=0.05)
    # angle means: 5 % of the true value (pi and 0.5 rad), compared on the circle
    deviation = np.angle(np.exp(1j * (model.angle.mean - TRUE.angle.mean)))
    assert np.all(np.abs(deviation) <= 0.05 * np.abs(TRUE.angle.mean))
    np.testing.assert_allclose(model.transition, TRUE.transition, atol=0.02)
    assert model.n_obs == 20_000 and model.step.zero_mass is None


def test_fit_is_a_maximum_and_em_is_monotone(fitted, simulated):
    model = fitted.model_
    history = np.array(fitted.monitor_.history)
    assert fitted.monitor_.converged and np.all(np.diff(history) > -1e-6)
    assert model.log_likelihood >= max(s.log_likelihood for s in fitted.starts_) - 1e-9
    assert model.score(simulated) == pytest.approx(model.log_likelihood, abs=1e-6)
    # no better point nearby: moving any working parameter lowers the likelihood
    params = fit.parameters_of(model)
    data = fit.fit_data(Observations.from_frame(simulated))
    likelihood = fit.WorkingLikelihood(params, data)
    theta = likelihood.pack(params)
    for i in range(theta.size - 1):  # the last entry is the initial distribution (flat)
        for shift in (-1e-3, 1e-3):
            moved = theta.copy()
            moved[i] += shift
            assert likelihood.value(moved) < model.log_likelihood + 1e-6
    n_parameters = 4 + 4 + 2 + 1
    assert model.aic == pytest.approx(-2 * model.log_likelihood + 2 * n_parameters)
    assert model.bic == pytest.approx(-2 * model.log_likelihood + np.log(20_000) * n_parameters)


def test_working_gradient_matches_finite_differences():
    rng = np.random.default_rng(8)
    n = 600
    values = {"c": rng.normal(size=n)}
    true = MovementHMM(
        initial=np.array([0.2, 0.3, 0.5]),
        transition=None,
        coefficients=rng.normal(scale=0.7, size=(6, 2)) - np.array([[1.5, 0.0]]),
        transition_design=Design.from_dict(
            {
                "formula": "~ c",
                "columns": ["Intercept", "c"],
                "scaling": {"c": {"centre": 0.0, "sd": 1.0}},
            }
        ),
        step=Gamma(np.array([1.0, 3.0, 8.0]), np.array([1.0, 2.0, 3.0]), np.full(3, 0.05)),
        angle=VonMises(np.array([3.0, 0.3, 0.0]), np.array([0.5, 2.0, 6.0])),
    )
    frame = true.simulate(rng, n, values).assign(c=values["c"], segment=np.arange(n) // 200)
    data = fit.fit_data(Observations.from_frame(frame, true.transition_design))
    params = fit.parameters_of(true)
    likelihood = fit.WorkingLikelihood(params, data)
    theta = likelihood.pack(params)
    value, gradient = likelihood.value_and_gradient(theta)
    assert value == pytest.approx(likelihood.value(theta), abs=1e-9)
    numeric = np.empty_like(theta)
    for i in range(theta.size):
        shift = np.zeros_like(theta)
        shift[i] = 1e-5
        numeric[i] = (likelihood.value(theta + shift) - likelihood.value(theta - shift)) / 2e-5
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-5)
    # pack / unpack round trip
    np.testing.assert_allclose(likelihood.pack(likelihood.unpack(theta)), theta, atol=1e-10)


def test_accelerated_em_reaches_plain_em_optimum_in_fewer_iterations(monkeypatch):
    """A crawling EM (3 states fitted to 5 behaviours) switches to SQUAREM after
    ACCELERATE_AFTER iterations: a monotone history, the optimum of plain EM (which the
    polish also finds) in fewer E-steps."""
    five = MovementHMM(
        initial=np.full(5, 0.2),
        transition=np.full((5, 5), 0.025) + 0.875 * np.eye(5),
        step=Gamma(np.array([1.0, 3.0, 6.0, 10.0, 15.0]), np.array([0.7, 1.5, 2.5, 3.5, 5.0])),
        angle=VonMises(np.array([np.pi, np.pi, 0, 0, 0]), np.array([0.5, 1, 3, 8, 20.0])),
    )
    frame = five.simulate(np.random.default_rng(3), 20_000).assign(segment=0)
    data = fit.fit_data(Observations.from_frame(frame))
    spec = fit.FitSpec(3, "gamma", "vonmises", True, False, max_iter=1000, tol=1e-9)
    start = fit.initial_parameters(None, data, spec)
    fast, fast_value, fast_monitor = fit.run_em(start, data, 1000, 1e-9)
    monkeypatch.setattr(fit, "ACCELERATE_AFTER", 1000)
    plain, plain_value, plain_monitor = fit.run_em(start, data, 1000, 1e-9)
    assert fast_monitor.converged and plain_monitor.converged
    assert plain_monitor.n_iter > 40 and fast_monitor.n_iter < 0.7 * plain_monitor.n_iter
    assert np.all(np.diff(fast_monitor.history) > -1e-6)
    assert fast_value >= plain_value - 1e-3
    # both stop within EM's tolerance of the optimum the polish reaches
    polished, polished_value = fit.polish(plain, data)
    assert polished_value - fast_value < 1e-3
    for em in (fast, plain):
        np.testing.assert_allclose(em.step.mean, polished.step.mean, rtol=1e-3)
        np.testing.assert_allclose(em.transition, polished.transition, atol=1e-3)


def test_covariate_effects_are_recovered():
    rng = np.random.default_rng(21)
    n = 20_000
    water = rng.gamma(2.0, 400.0, size=n)
    true = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=None,
        coefficients=np.array([[-2.0, 0.8], [-1.5, -0.6]]),
        transition_design=Design.from_dict(
            {
                "formula": "~ water",
                "columns": ["Intercept", "water"],
                "scaling": {"water": {"centre": 800.0, "sd": 560.0}},
            }
        ),
        step=Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0])),
        angle=VonMises(np.array([0.0, 0.0]), np.array([0.5, 4.0])),
    )
    frame = true.simulate(rng, n, {"water": water}).assign(water=water)
    estimator = MovementHMMEstimator(2, covariates=["water"], seed=1).fit(frame)
    model = estimator.model_
    # compare on the data's own standardisation
    mean, sd = model.transition_design.scaling["water"]
    beta = model.coefficients.copy()
    slope_true = true.coefficients[:, 1] / 560.0 * sd
    intercept_true = true.coefficients[:, 0] + true.coefficients[:, 1] * (mean - 800.0) / 560.0
    np.testing.assert_allclose(beta[:, 1], slope_true, atol=0.1)
    np.testing.assert_allclose(beta[:, 0], intercept_true, atol=0.1)
    # transition probabilities within 0.02 over the central 90 % of the covariate
    grid = {"water": np.quantile(water, np.linspace(0.05, 0.95, 19))}
    np.testing.assert_allclose(
        model.transition_matrix(grid), true.transition_matrix(grid), atol=0.02
    )


@pytest.mark.parametrize("angle", ["vonmises", "wrappedcauchy"])  # threads, processes
def test_serial_and_parallel_multistart_agree_bit_for_bit(simulated, angle):
    data = simulated.iloc[:3000]
    options = {"n_starts": 4, "seed": 99, "polish": False, "angle": angle}
    serial = MovementHMMEstimator(2, n_jobs=1, **options).fit(data)
    parallel = MovementHMMEstimator(2, n_jobs=2, **options).fit(data)
    assert serial.model_.to_dict() == parallel.model_.to_dict()
    for a, b in zip(serial.starts_, parallel.starts_, strict=True):
        assert a.log_likelihood == b.log_likelihood and a.monitor.history == b.monitor.history
    # different seeds give different random starts
    other = MovementHMMEstimator(2, n_starts=4, seed=100, polish=False).fit(data)
    assert other.starts_[1].monitor.history[0] != serial.starts_[1].monitor.history[0]


def test_states_are_ordered_by_mean_step(simulated):
    swapped = MovementHMM(
        initial=TRUE.initial[::-1],
        transition=TRUE.transition[::-1, ::-1],
        step=Gamma(TRUE.step.mean[::-1], TRUE.step.sd[::-1]),
        angle=VonMises(TRUE.angle.mean[::-1], TRUE.angle.concentration[::-1]),
    )
    sample = swapped.simulate(np.random.default_rng(3), 5000)
    model = fit_movement_hmm(sample, 2, seed=1)
    assert model.step.mean[0] < model.step.mean[1]
    np.testing.assert_allclose(model.transition, TRUE.transition, atol=0.03)
    states = model.viterbi(sample)
    assert np.mean(states == 1 - sample["state"].to_numpy()) > 0.9

    order = np.array([1, 0])
    params = fit.parameters_of(swapped).permuted(order)
    np.testing.assert_array_equal(params.transition, TRUE.transition)
    np.testing.assert_array_equal(params.step.mean, TRUE.step.mean)


def test_zero_inflation_switches_on_for_zero_steps_and_arrays_match_tables():
    rng = np.random.default_rng(4)
    sample = TRUE.simulate(rng, 4000)
    sample.loc[rng.choice(4000, 40, replace=False), "step"] = 0.0
    sample.loc[sample["step"] == 0, "angle"] = np.nan
    sample.loc[::500, "step"] = np.nan
    table = sample.assign(segment=np.repeat(["a", "b"], 2000))
    by_table = MovementHMMEstimator(2, seed=5).fit(table)
    by_array = MovementHMMEstimator(2, seed=5).fit(
        sample[["step", "angle"]].to_numpy(), lengths=[2000, 2000]
    )
    assert by_table.model_.to_dict() == by_array.model_.to_dict()
    zero_mass = by_table.model_.step.zero_mass
    # zeros were put at random rows: 1 % of the steps in either state
    assert zero_mass is not None
    np.testing.assert_allclose(zero_mass, 0.01, atol=0.005)
    np.testing.assert_array_equal(
        by_table.predict(table),
        by_array.predict(sample[["step", "angle"]].to_numpy(), [2000, 2000]),
    )
    proba = by_table.predict_proba(table)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0)
    with pytest.raises(ValueError, match="zero_inflation must be on"):
        MovementHMMEstimator(2, zero_inflation=False).fit(table)


def test_bad_options_and_inputs_are_refused(simulated):
    with pytest.raises(ValueError, match="step family 'gama' unknown"):
        MovementHMMEstimator(step="gama").fit(simulated)
    with pytest.raises(ValueError, match="not fitted"):
        MovementHMMEstimator().predict(simulated)
    with pytest.raises(ValueError, match="lengths sum to 5"):
        MovementHMMEstimator().fit(np.ones((6, 2)), lengths=[2, 3])
    with pytest.raises(
        ValueError,
        match=r"formula '~ water' have missing or non-finite values at rows \[0, 1\]",
    ):
        water = np.where(np.arange(len(simulated)) < 2, np.nan, np.arange(len(simulated)))
        MovementHMMEstimator(covariates=["water"]).fit(simulated.assign(water=water))


def test_sample_uses_the_seed(fitted):
    a = fitted.sample(100, seed=3)
    pd.testing.assert_frame_equal(a, fitted.sample(100, seed=3))
    assert list(a.columns) == ["state", "step", "angle"]


def test_other_families_with_fixed_angle_mean_are_recovered():
    true = MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=np.array([[0.8, 0.2], [0.1, 0.9]]),
        step=Weibull(np.array([1.2, 3.0]), np.array([1.0, 8.0])),
        angle=WrappedCauchy(np.zeros(2), np.array([0.2, 0.8]), estimate_mean=False),
    )
    sample = true.simulate(np.random.default_rng(31), 8000)
    model = fit_movement_hmm(
        sample, 2, seed=2, step="weibull", angle="wrappedcauchy", estimate_angle_mean=False
    )
    assert isinstance(model.step, Weibull) and isinstance(model.angle, WrappedCauchy)
    assert not model.angle.estimate_mean and np.all(model.angle.mean == 0)
    np.testing.assert_allclose(model.step.shape, true.step.shape, rtol=0.06)
    np.testing.assert_allclose(model.step.scale, true.step.scale, rtol=0.05)
    np.testing.assert_allclose(model.angle.concentration, true.angle.concentration, atol=0.03)
    np.testing.assert_allclose(model.transition, true.transition, atol=0.02)
    # 2 x (shape, scale) + 2 concentrations + 2 transitions + 1 initial
    assert model.aic == pytest.approx(-2 * model.log_likelihood + 2 * 9)


def test_failed_starts_are_kept_and_reported(simulated, monkeypatch, caplog):
    data = simulated.iloc[:2000]
    real_run_em = fit.run_em
    calls = []

    def flaky(params, *args):
        calls.append(1)
        if len(calls) == 2:
            raise FloatingPointError("overflow in a test")
        return real_run_em(params, *args)

    monkeypatch.setattr(fit, "run_em", flaky)
    estimator = MovementHMMEstimator(2, n_starts=3, seed=4).fit(data)
    errors = [s.error for s in estimator.starts_]
    assert errors[0] is None and "overflow in a test" in errors[1] and errors[2] is None
    assert estimator.starts_[1].log_likelihood == -np.inf
    assert "EM start 1 failed" in caplog.text
    assert np.isfinite(estimator.model_.log_likelihood)

    def broken(params, *args):
        raise ValueError("always")

    monkeypatch.setattr(fit, "run_em", broken)
    with pytest.raises(ValueError, match="every EM start failed .start 0: ValueError: always"):
        MovementHMMEstimator(2, n_starts=2, seed=4).fit(data)


def test_estimator_contract_get_params_set_params():
    estimator = MovementHMMEstimator(3, step="weibull", covariates=("temp",), seed=4)
    params = estimator.get_params()
    assert params["n_states"] == 3 and params["step"] == "weibull" and params["seed"] == 4
    assert set(params) == set(MovementHMMEstimator().get_params(deep=False))
    twin = MovementHMMEstimator(**params)
    assert twin.get_params() == params
    assert estimator.set_params(n_states=2, polish=False) is estimator
    assert estimator.n_states == 2 and estimator.polish is False
    with pytest.raises(ValueError, match="invalid parameter 'states'"):
        estimator.set_params(states=2)


def test_sklearn_clone_copies_hyper_parameters_not_the_fit(fitted):
    base = pytest.importorskip("sklearn.base")
    copy = base.clone(fitted)
    assert type(copy) is MovementHMMEstimator and copy is not fitted
    assert copy.get_params() == fitted.get_params()
    assert not hasattr(copy, "model_")


def test_package_ships_py_typed():
    from importlib import resources

    assert resources.files("hmmtrack").joinpath("py.typed").is_file()


def test_user_starting_values_are_the_first_start(simulated):
    """Without EM iterations and polish, the fit returns the given starting values."""
    estimator = MovementHMMEstimator(2, start=TRUE, max_iter=0, polish=False, n_starts=2, seed=3)
    model = estimator.fit(simulated).model_
    np.testing.assert_array_equal(model.step.mean, TRUE.step.mean)
    np.testing.assert_array_equal(model.transition, TRUE.transition)
    assert model.log_likelihood == pytest.approx(TRUE.score(simulated), rel=1e-12)
    assert estimator.starts_[1].parameters.step != TRUE.step  # the other starts stay random
    weibull = MovementHMM(
        TRUE.initial, TRUE.transition, Weibull([1.0, 2.0], [2.0, 9.0]), TRUE.angle
    )
    with pytest.raises(ValueError, match=r"start: the model's \['step'\] differ"):
        MovementHMMEstimator(2, start=weibull).fit(simulated)


def test_known_states_everywhere_give_the_complete_data_estimates(simulated):
    """With every state known the likelihood is the complete-data one: its maximum is the
    weighted fit with one-hot weights and the counted transitions."""
    data = simulated.assign(known=simulated.state + 1.0)
    model = MovementHMMEstimator(2, known_states="known", seed=1).fit(data).model_
    one_hot = np.eye(2)[simulated.state.to_numpy()]
    expected = TRUE.step.fit_weighted(simulated.step.to_numpy(), one_hot)
    np.testing.assert_allclose(model.step.mean, expected.mean, rtol=1e-6)
    np.testing.assert_allclose(model.step.sd, expected.sd, rtol=1e-6)
    states = simulated.state.to_numpy()
    same_track = simulated.segment.to_numpy()[1:] == simulated.segment.to_numpy()[:-1]
    counts = np.zeros((2, 2))
    np.add.at(counts, (states[:-1][same_track], states[1:][same_track]), 1)
    np.testing.assert_allclose(
        model.transition, counts / counts.sum(axis=1, keepdims=True), rtol=1e-6
    )
    with pytest.raises(ValueError, match="known states must be 1..2"):
        MovementHMMEstimator(2, known_states="known").fit(data.assign(known=3.0))
