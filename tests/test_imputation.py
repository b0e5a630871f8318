"""Tests of hmmtrack.hmm.imputation: Rubin's rules, and MI fits against a direct fit."""

import warnings

import numpy as np
import pandas as pd
import pytest

from hmmtrack import tracks
from hmmtrack.hmm import crw, imputation
from hmmtrack.hmm.diagnostics import working_covariance
from hmmtrack.hmm.distributions import Gamma, VonMises
from hmmtrack.hmm.fit import MovementHMMEstimator, fit_movement_hmm
from hmmtrack.hmm.model import MovementHMM

TRUE = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=np.array([[0.9, 0.1], [0.2, 0.8]]),
    step=Gamma(mean=np.array([20.0, 200.0]), sd=np.array([15.0, 80.0])),
    angle=VonMises(np.array([np.pi, 0.0]), np.array([1.0, 5.0])),
    dt=60.0,
)


def hmm_track(rng, n, dt=60.0, name="a") -> pd.DataFrame:
    """Fixes every ``dt`` s of an animal moving by TRUE's steps and turns (m)."""
    sim = TRUE.simulate(rng, n)
    heading = np.cumsum(np.r_[0.0, sim["angle"].to_numpy()[1:]])
    x = np.r_[0.0, np.cumsum(sim["step"].to_numpy() * np.cos(heading))]
    y = np.r_[0.0, np.cumsum(sim["step"].to_numpy() * np.sin(heading))]
    return pd.DataFrame({"id": name, "time": 1e9 + dt * np.arange(n + 1), "x": x, "y": y})


def test_rubin_rules_on_hand_numbers():
    estimates = np.array([[1.0, 10.0], [3.0, 14.0]])
    covariances = np.array([np.diag([0.5, 2.0]), np.diag([1.5, 4.0])])
    pooled = imputation.rubin(estimates, covariances)
    np.testing.assert_allclose(pooled.estimate, [2.0, 12.0])
    np.testing.assert_allclose(pooled.within, np.diag([1.0, 3.0]))
    np.testing.assert_allclose(pooled.between, [[2.0, 4.0], [4.0, 8.0]])
    np.testing.assert_allclose(pooled.covariance, np.diag([1.0, 3.0]) + 1.5 * pooled.between)
    single = imputation.rubin(estimates[:1], covariances[:1])
    np.testing.assert_array_equal(single.covariance, covariances[0])


def test_one_imputation_of_a_regular_track_equals_the_direct_fit():
    raw = hmm_track(np.random.default_rng(3), 600)
    direct = fit_movement_hmm(tracks.prepare(raw), 2, seed=1)
    exact = {"a": crw.fit_crw(raw["time"], raw[["x", "y"]], error_sd=0.0)}
    (drawn,) = crw.impute(raw, 60.0, 1, np.random.default_rng(0), models=exact)
    np.testing.assert_allclose(drawn[["x", "y"]], raw[["x", "y"]], atol=1e-6)
    result = imputation.fit_imputed([tracks.prepare(drawn)], 2, seed=1)
    pooled = result.model
    np.testing.assert_allclose(pooled.step.mean, direct.step.mean, rtol=1e-6)
    np.testing.assert_allclose(pooled.step.sd, direct.step.sd, rtol=1e-6)
    np.testing.assert_allclose(pooled.angle.concentration, direct.angle.concentration, rtol=1e-6)
    np.testing.assert_allclose(pooled.angle.mean, direct.angle.mean, atol=1e-6)
    np.testing.assert_allclose(pooled.transition, direct.transition, atol=1e-6)
    np.testing.assert_array_equal(result.pooled.between, 0.0)
    table = imputation.pooled_table(result)
    assert (table["fraction_missing"] == 0).all() and (table["se"].iloc[:-1] > 0).all()


def test_imputations_of_an_irregular_track_pool_their_spread():
    rng = np.random.default_rng(8)
    raw = hmm_track(rng, 1500, dt=20.0)
    kept = raw.iloc[np.sort(rng.choice(len(raw), 500, replace=False))]
    kept = pd.concat([raw.iloc[:1], kept]).drop_duplicates("time")
    with pytest.warns(UserWarning, match="time steps vary.*crw.regularise"):
        MovementHMMEstimator(2, seed=1).fit(tracks.prepare(kept))
    imputed = crw.impute(kept, 60.0, 4, np.random.default_rng(1), error_sd=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # regular grids: no time-step warning
        result = imputation.fit_imputed([tracks.prepare(t) for t in imputed], 2, seed=1)
    thetas = [
        working_covariance(model, tracks.prepare(table))[1]
        for model, table in zip(result.models, imputed, strict=True)
    ]
    np.testing.assert_allclose(result.pooled.estimate, np.mean(thetas, axis=0))
    total = np.diag(result.pooled.covariance)
    assert np.all(total >= np.diag(result.pooled.within)) and np.any(
        np.diag(result.pooled.between) > 0
    )
    # two movement modes are still told apart at the 60 s grid
    assert result.model.step.mean[1] > 3 * result.model.step.mean[0]
