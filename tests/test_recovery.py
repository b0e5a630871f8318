"""Recovery from 20,000 simulated rows for every step and angle family, and for a
three-stream model with emission formulas (issue 15).

Each family is fitted as the one that differs from a gamma / von Mises 2-state model (the
further-stream families: ``tests/test_data_streams.py``): every parameter within 5 % of the
truth; the coefficients of the formulas within 2 Wald standard errors. Fixed seeds, one
start each.
"""

import numpy as np
import pandas as pd
import pytest

from hmmtrack.hmm import MovementHMM, MovementHMMEstimator, diagnostics, distributions
from hmmtrack.hmm.emission import CovariateEmission
from hmmtrack.hmm.formula import design

N = 20_000
TRANSITION = np.array([[0.9, 0.1], [0.15, 0.85]])
STEP = distributions.Gamma(np.array([1.0, 6.0]), np.array([0.8, 3.0]))
ANGLE = distributions.VonMises(np.array([0.8, -0.3]), np.array([1.0, 4.0]))
ZERO_MASS = np.array([0.2, 0.2])
STEPS = {
    "gamma": distributions.Gamma(STEP.mean, STEP.sd, ZERO_MASS),
    "weibull": distributions.Weibull(np.array([1.5, 3.0]), np.array([1.0, 6.0]), ZERO_MASS),
    "lognormal": distributions.LogNormal(np.array([-0.5, 1.8]), np.array([0.6, 0.4]), ZERO_MASS),
    "exponential": distributions.Exponential(np.array([1.0, 1 / 6]), ZERO_MASS),
}
ANGLES = {
    "vonmises": ANGLE,
    "wrappedcauchy": distributions.WrappedCauchy(np.array([0.8, -0.3]), np.array([0.3, 0.8])),
}


def parameters(dist) -> dict:
    """The per-state parameters of a family's document."""
    return {k: v for k, v in dist.to_dict().items() if isinstance(v, list)}


@pytest.mark.parametrize(
    ("kind", "name"), [("step", name) for name in STEPS] + [("angle", name) for name in ANGLES]
)
def test_every_step_and_angle_family_is_recovered_from_20000_rows(kind, name):
    step, angle = (STEPS[name], ANGLE) if kind == "step" else (STEP, ANGLES[name])
    truth = MovementHMM(np.array([0.5, 0.5]), TRANSITION, step, angle)
    data = truth.simulate(np.random.default_rng(5), N)
    model = MovementHMMEstimator(2, **{kind: name}, seed=1).fit(data).model_
    for fitted, true in ((model.step, step), (model.angle, angle)):
        expected = parameters(true)
        for parameter, values in parameters(fitted).items():
            np.testing.assert_allclose(values, expected[parameter], rtol=0.05, err_msg=parameter)
    np.testing.assert_allclose(model.transition, TRANSITION, rtol=0.05)


def test_three_streams_with_formulas_are_recovered():
    """Steps whose mean follows the time of day, angles, and a categorical behaviour whose
    second category's log odds follow the temperature: the coefficients within 2 SE."""
    rng = np.random.default_rng(9)
    hour = (np.arange(N) * 0.25) % 24
    table = pd.DataFrame(
        {
            "cosT": np.cos(2 * np.pi * hour / 24),
            "sinT": np.sin(2 * np.pi * hour / 24),
            "temperature": rng.normal(10.0, 3.0, N),
        }
    )
    step_coefficients = np.array([[0.0, 0.3, -0.2], [np.log(6.0), 0.2, 0.3]])
    behaviour = distributions.Categorical(np.array([[0.6, 0.3, 0.1], [0.1, 0.2, 0.7]]))
    odds = behaviour.to_links()[0]  # log(p2 / p1) at the mean temperature, per state
    behaviour_coefficients = np.column_stack([odds, [0.5, -0.4]])
    truth = MovementHMM(
        np.array([0.5, 0.5]),
        TRANSITION,
        CovariateEmission(
            STEP, {"mean": design("~ cosT + sinT", table)}, {"mean": step_coefficients}
        ),
        ANGLE,
        streams={
            "behaviour": CovariateEmission(
                behaviour,
                {"prob2": design("~ temperature", table)},
                {"prob2": behaviour_coefficients},
            ),
        },
    )
    data = truth.simulate(rng, N, table).join(table)
    model = (
        MovementHMMEstimator(
            2,
            streams={"behaviour": "categorical"},
            formulas={"step.mean": "~ cosT + sinT", "behaviour.prob2": "~ temperature"},
            seed=1,
        )
        .fit(data)
        .model_
    )
    intervals = diagnostics.confidence_intervals(model, data)
    for prefix, expected in (
        ("step.mean.beta.", step_coefficients),
        ("behaviour.prob2.beta.", behaviour_coefficients),
    ):
        beta = intervals[intervals.parameter.str.startswith(prefix)]
        assert len(beta) == expected.size
        np.testing.assert_array_less(
            np.abs(beta.estimate.to_numpy() - expected.T.ravel()), 2 * beta.se.to_numpy()
        )
    np.testing.assert_allclose(model.streams["behaviour"].base.prob[:, 2], [0.1, 0.7], rtol=0.05)
    np.testing.assert_allclose(model.angle.concentration, ANGLE.concentration, rtol=0.05)
    np.testing.assert_allclose(model.transition, TRANSITION, rtol=0.05)
