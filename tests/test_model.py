"""Tests of hmmtrack.hmm.model (the fitted-model dataclass and its JSON file) and of the
multinomial-logit transition matrices of hmmtrack.hmm.covariates."""

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack.hmm import covariates as cov
from hmmtrack.hmm.distributions import Gamma, VonMises, Weibull, WrappedCauchy
from hmmtrack.hmm.formula import Design
from hmmtrack.hmm.model import MovementHMM, Observations


def two_state_model(**changes):
    fields = dict(
        initial=np.array([0.3, 0.7]),
        transition=np.array([[0.9, 0.1], [0.25, 0.75]]),
        step=Gamma(mean=np.array([2.0, 10.0]), sd=np.array([1.5, 4.0])),
        angle=VonMises(np.array([np.pi, 0.1]), np.array([1.0, 5.0])),
        dt=30.0,
        log_likelihood=-1234.5678901234567,
        n_obs=1000,
        aic=2491.1357802469134,
        bic=2545.121088315717,  # -2 logL + 11 log(1000): AIC implies 11 parameters
    )
    fields.update(changes)
    return MovementHMM(**fields)


def covariate_model():
    return MovementHMM(
        initial=np.array([0.2, 0.5, 0.3]),
        transition=None,
        coefficients=np.arange(18, dtype=float).reshape(6, 3) / 9 - 1,
        transition_design=Design.from_dict(
            {
                "formula": "~ dist_water + temp",
                "columns": ["Intercept", "dist_water", "temp"],
                "scaling": {
                    "dist_water": {"centre": 773.6457279, "sd": 791.1607743},
                    "temp": {"centre": 12.5, "sd": 3.25},
                },
            }
        ),
        step=Weibull(
            shape=np.array([1.1, 2.0, 3.0]),
            scale=np.array([0.3, 1.0, 4.0]),
            zero_mass=np.array([0.01, 0.0, 1e-5]),
        ),
        angle=WrappedCauchy(np.zeros(3), np.array([0.1, 0.5, 0.9]), estimate_mean=False),
    )


def assert_same_model(a: MovementHMM, b: MovementHMM):
    assert a.to_dict() == b.to_dict()
    np.testing.assert_array_equal(a.initial, b.initial)
    for name in ("transition", "coefficients"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None)
        if x is not None:
            np.testing.assert_array_equal(x, y)
    if a.transition_design is not None:
        assert a.transition_design.to_dict() == b.transition_design.to_dict()
    else:
        assert b.transition_design is None
    assert a.step == b.step and a.angle == b.angle


# --- JSON file ---------------------------------------------------------------------------


def test_json_round_trip_is_exact(tmp_path):
    zero_inflated = two_state_model(
        step=Gamma(
            mean=np.array([0.1 + 0.2, 1 / 3]),
            sd=np.array([np.pi / 10, 2.0**0.5]),
            zero_mass=np.array([1e-300, 0.123456789012345678]),
        )
    )
    for model in (two_state_model(), zero_inflated, covariate_model(), two_state_model(dt=np.nan)):
        path = tmp_path / "model.json"
        model.save(path)
        loaded = MovementHMM.load(path)
        assert_same_model(model, loaded)
        assert np.isnan(loaded.dt) if np.isnan(model.dt) else loaded.dt == model.dt
        np.testing.assert_equal(
            (loaded.log_likelihood, loaded.n_obs, loaded.aic, loaded.bic),
            (model.log_likelihood, model.n_obs, model.aic, model.bic),
        )


def test_json_document_names_schema_units_and_version(tmp_path):
    path = tmp_path / "m.json"
    two_state_model().save(path)
    document = json.loads(path.read_text())
    assert document["schema"] == "hmmtrack.movement_hmm"
    assert document["version"] == 2
    assert document["units"] == {"step": "m", "angle": "rad", "dt": "s"}
    assert document["dt"] == 30.0
    assert "package_version" in document


def _write(path, document):
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (lambda d: d.update(version=5), "version", "versions (1, 2, 3, 4)"),
        (lambda d: d.update(schema="other"), "schema", "expected 'hmmtrack.movement_hmm'"),
        (lambda d: d.pop("initial"), "initial", "missing"),
        (lambda d: d.update(initial=[0.5, 0.6]), "initial", "summing to 1"),
        (lambda d: d.update(initial=[1.0]), "initial", "shape"),
        (lambda d: d.update(transition=[[0.9, 0.1], [0.2, "x"]]), "transition", "numbers"),
        (lambda d: d.update(transition=[[1.1, -0.1], [0.2, 0.8]]), "transition", "non-negative"),
        (lambda d: d["step"].update(family="cauchy"), "step", "unknown distribution family"),
        (lambda d: d["step"].update(mean=[1.0, -2.0]), "step", "> 0"),
        (lambda d: d["angle"].pop("concentration"), "angle", "expected keys"),
        (lambda d: d.update(dt=-1), "dt", "positive"),
        (lambda d: d.update(n_obs="many"), "n_obs", "expected int"),
        (lambda d: d.update(transition=None), "coefficients", "missing"),
    ],
)
def test_load_refuses_malformed_files_naming_file_and_field(tmp_path, change, field, words):
    document = two_state_model().to_dict()
    change(document)
    path = _write(tmp_path / "bad.json", document)
    with pytest.raises(ValueError) as info:
        MovementHMM.load(path)
    message = str(info.value)
    assert str(path) in message and f"'{field}'" in message and words in message


def test_load_refuses_non_json_and_wrong_coefficient_shape(tmp_path):
    path = tmp_path / "x.json"
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not a JSON file"):
        MovementHMM.load(path)
    document = covariate_model().to_dict()
    document["coefficients"]["values"] = [[0.0, 1.0]] * 5
    with pytest.raises(ValueError, match=r"'coefficients.values' has shape \(5, 2\)"):
        MovementHMM.load(_write(path, document))


# --- transition matrices and the stationary distribution ---------------------------------


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 5), st.integers(0, 2**32 - 1))
def test_stationary_distribution_is_invariant(n_states, seed):
    rng = np.random.default_rng(seed)
    transition = rng.dirichlet(np.full(n_states, 0.7), size=n_states) + 1e-3
    transition /= transition.sum(axis=1, keepdims=True)
    model = MovementHMM(
        initial=np.full(n_states, 1 / n_states),
        transition=transition,
        step=Gamma(np.ones(n_states), np.ones(n_states)),
        angle=VonMises(np.zeros(n_states), np.ones(n_states)),
    )
    delta = model.stationary()
    np.testing.assert_allclose(delta @ transition, delta, atol=1e-12)
    assert delta.sum() == pytest.approx(1.0) and np.all(delta > 0)
    # oracle: the limit of the matrix powers (2**16 steps: with every entry at least about
    # 1e-3 the second eigenvalue can be 0.998, and 0.998**2000 is still 0.02)
    np.testing.assert_allclose(np.linalg.matrix_power(transition, 2**16)[0], delta, atol=1e-9)


def test_logit_transition_matrices_match_hand_construction():
    model = covariate_model()
    values = {"dist_water": np.array([0.0, 773.6457279, 2000.0]), "temp": np.array([10, 12.5, 20])}
    gamma = model.transition_matrix(values)
    design = np.column_stack(
        [
            np.ones(3),
            (values["dist_water"] - 773.6457279) / 791.1607743,
            (values["temp"] - 12.5) / 3.25,
        ]
    )
    beta = model.coefficients
    for t in range(3):
        expected = np.ones((3, 3))
        r = 0
        for i in range(3):
            for j in range(3):
                if i != j:
                    expected[i, j] = np.exp(beta[r] @ design[t])
                    r += 1
        expected /= expected.sum(axis=1, keepdims=True)
        np.testing.assert_allclose(gamma[t], expected, rtol=1e-12)
    # at the covariate means the matrix is the intercept-only one
    np.testing.assert_allclose(gamma[1], model.transition_matrix(), rtol=1e-12)
    np.testing.assert_allclose(model.stationary(values)[1], model.stationary(), rtol=1e-10)


def test_coefficients_from_matrix_inverts_the_logit():
    rng = np.random.default_rng(3)
    transition = rng.dirichlet(np.ones(4), size=4)
    coefficients = cov.coefficients_from_matrix(transition, n_design=3)
    assert coefficients.shape == (12, 3) and np.all(coefficients[:, 1:] == 0)
    rebuilt = np.exp(cov.log_transition_matrices(coefficients, np.array([[1.0, 5.0, -2.0]])))[0]
    np.testing.assert_allclose(rebuilt, transition, rtol=1e-12)


def test_expected_log_likelihood_gradient_matches_finite_differences():
    rng = np.random.default_rng(4)
    xi = rng.random((50, 3, 3))
    design = np.column_stack([np.ones(50), rng.normal(size=(50, 2))])
    beta = rng.normal(size=(6, 3))
    _, gradient = cov.expected_log_likelihood(beta, xi, design)
    numeric = np.empty_like(beta)
    for index in np.ndindex(beta.shape):
        shift = np.zeros_like(beta)
        shift[index] = 1e-6
        up = cov.expected_log_likelihood(beta + shift, xi, design)[0]
        down = cov.expected_log_likelihood(beta - shift, xi, design)[0]
        numeric[index] = (up - down) / 2e-6
    np.testing.assert_allclose(gradient, numeric, rtol=1e-6, atol=1e-6)
    # the Newton M-step reaches a stationary point of the same objective
    fitted = cov.fit_coefficients(xi, design, np.zeros_like(beta))
    assert np.abs(cov.expected_log_likelihood(fitted, xi, design)[1]).max() < 1e-6


def test_covariate_rows_must_be_finite_and_present():
    model = covariate_model()
    grid = {"dist_water": [100.0, np.nan], "temp": [10.0, 11.0]}
    with pytest.raises(ValueError, match=r"missing or non-finite values at rows \[1\]"):
        model.transition_matrix(grid)
    with pytest.raises(ValueError, match="temp"):
        model.transition_matrix({"dist_water": [100.0]})


# --- simulation and data -----------------------------------------------------------------


def test_simulate_reproduces_transition_and_emission_statistics():
    model = two_state_model()
    sim = model.simulate(np.random.default_rng(11), 40_000)
    again = model.simulate(np.random.default_rng(11), 40_000)
    pd.testing.assert_frame_equal(sim, again)
    states = sim["state"].to_numpy()
    counts = np.zeros((2, 2))
    np.add.at(counts, (states[:-1], states[1:]), 1)
    np.testing.assert_allclose(counts / counts.sum(1, keepdims=True), model.transition, atol=0.01)
    np.testing.assert_allclose(np.bincount(states) / states.size, model.stationary(), atol=0.02)
    for k in range(2):
        steps = sim.loc[states == k, "step"]
        assert steps.mean() == pytest.approx(model.step.mean[k], rel=0.03)
        assert steps.std() == pytest.approx(model.step.sd[k], rel=0.05)
    assert sim["angle"].between(-np.pi, np.pi).all()


def test_simulate_with_covariates_follows_the_time_varying_matrix():
    model = covariate_model()
    n = 30_000
    rng = np.random.default_rng(5)
    values = {"dist_water": np.where(np.arange(n) < n // 2, 0.0, 3000.0), "temp": np.full(n, 12.5)}
    states = model.simulate(rng, n, values)["state"].to_numpy()
    gamma = model.transition_matrix(values)
    for half, rows in (("low", slice(1, n // 2)), ("high", slice(n // 2 + 1, n))):
        prev, cur = states[:-1][rows.start - 1 : rows.stop - 1], states[rows]
        counts = np.zeros((3, 3))
        np.add.at(counts, (prev, cur), 1)
        empirical = counts / counts.sum(1, keepdims=True)
        np.testing.assert_allclose(empirical, gamma[rows.start], atol=0.03, err_msg=half)


def test_observations_from_frame_lengths_and_errors():
    frame = pd.DataFrame(
        {"segment": ["a", "a", "b", "b", "b"], "step": [1, 2, np.nan, 3, 4], "angle": 0.0}
    )
    obs = Observations.from_frame(frame)
    np.testing.assert_array_equal(obs.lengths, [2, 3])
    with pytest.raises(ValueError, match="tracks.csv: rows of segment 'a' are not contiguous"):
        Observations.from_frame(frame.iloc[[0, 2, 1, 3, 4]], source="tracks.csv")
    with pytest.raises(ValueError, match=r"missing column\(s\) \['angle'\]"):
        Observations.from_frame(frame.drop(columns="angle"))
    with pytest.raises(ValueError, match=r"negative values at rows \[1\]"):
        Observations.from_frame(frame.assign(step=[1, -2, 0, 3, 4]))


def test_constructor_checks_shapes():
    with pytest.raises(ValueError, match=r"transition has shape \(3, 3\); expected \(2, 2\)"):
        two_state_model(transition=np.full((3, 3), 1 / 3))
    with pytest.raises(ValueError, match=r"angle has shape \(3,\); expected \(2,\)"):
        two_state_model(angle=VonMises(np.zeros(3), np.ones(3)))
    with pytest.raises(ValueError, match="exactly one of 'transition' and 'coefficients'"):
        two_state_model(coefficients=np.zeros((2, 1)))


# --- strict loading and plausibility of a model -------------------------------------------


@pytest.mark.parametrize(
    ("change", "words"),
    [
        (lambda d: d.update(trasition=d.pop("transition")), ["'trasition'", "'transition'"]),
        (lambda d: d.update(extra=1), ["unknown field(s) ['extra']", "valid fields", "'n_obs'"]),
        (lambda d: d["units"].update(time="s"), ["'units.time'", "'units.step'"]),
    ],
)
def test_load_refuses_unknown_or_misspelt_fields_naming_the_valid_ones(tmp_path, change, words):
    document = two_state_model().to_dict()
    change(document)
    with pytest.raises(ValueError) as info:
        MovementHMM.load(_write(tmp_path / "bad.json", document))
    assert str(tmp_path / "bad.json") in str(info.value)
    for word in words:
        assert word in str(info.value)


def test_load_refuses_unknown_coefficient_fields_and_units(tmp_path):
    document = covariate_model().to_dict()
    document["coefficients"]["scale"] = document["coefficients"].pop("scaling")
    with pytest.raises(ValueError, match=r"'coefficients.scale'.*did you mean 'scaling'"):
        MovementHMM.load(_write(tmp_path / "c.json", document))
    document = two_state_model().to_dict()
    document["units"]["angle"] = "deg"
    with pytest.raises(ValueError, match=r"'units.angle' is 'deg'; expected 'rad'"):
        MovementHMM.load(_write(tmp_path / "u.json", document))


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        ({"n_obs": -5}, "n_obs is -5"),
        ({"n_obs": 0}, "n_obs is 0 but a log-likelihood"),
        ({"log_likelihood": -1200.0}, "is not 2 times a positive whole number"),
        ({"aic": 2491.6}, "does not follow from log_likelihood"),
        ({"bic": 2545.2}, "bic = 2545.2 contradicts log_likelihood"),
        ({"n_obs": 2000}, "the 11 parameters implied by aic"),
        ({"log_likelihood": np.nan}, "aic and bic given without the log-likelihood"),
    ],
)
def test_contradictory_fit_summary_is_refused_on_load_and_construction(tmp_path, fields, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(")):
        two_state_model(**fields)
    document = two_state_model().to_dict()
    document.update({k: None if v is np.nan else v for k, v in fields.items()})
    with pytest.raises(ValueError) as info:
        MovementHMM.load(_write(tmp_path / "bad.json", document))
    assert str(tmp_path / "bad.json") in str(info.value) and words in str(info.value)


def test_fit_summary_rules_accept_consistent_and_partial_summaries():
    """AIC alone, BIC alone, neither, and a one-row fit (BIC says nothing about p)."""
    two_state_model(bic=np.nan)
    two_state_model(aic=np.nan)
    two_state_model(aic=np.nan, bic=np.nan, log_likelihood=np.nan, n_obs=0)
    two_state_model(n_obs=1, bic=2469.1357802469134)
    with pytest.raises(ValueError, match="bic = 2470.0 contradicts"):
        two_state_model(n_obs=1, bic=2470.0)


def test_constructor_refuses_a_transition_matrix_that_is_not_stochastic():
    for bad in ([[0.9, 0.2], [0.25, 0.75]], [[1.1, -0.1], [0.25, 0.75]], [[np.nan, 1], [0, 1]]):
        with pytest.raises(ValueError, match="transition must hold finite non-negative"):
            two_state_model(transition=np.array(bad))
    with pytest.raises(ValueError, match="initial must hold"):
        two_state_model(initial=np.array([0.5, 0.6]))


def test_bundled_models_load():
    from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm

    model = load_white_shark_hmm()
    assert model.n_obs == 162976 and model.n_states == 2
