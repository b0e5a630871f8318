"""moveHMM parity on real data: the elk tracks of Morales et al. (2004).

The reference figures are moveHMM 1.12's (see ../shared/data/README.md). The data are read
from the shared folder and never copied into the project; without them the tests skip.
The elk data have no time column: one fix per step.
"""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hmmtrack import tracks
from hmmtrack.hmm import MovementHMMEstimator

ELK = Path(__file__).resolve().parents[2] / "shared" / "data" / "elk_data.csv"


@pytest.fixture(scope="module")
def elk() -> pd.DataFrame:
    if not ELK.exists():
        pytest.skip(f"elk data not found at {ELK}")
    raw = pd.read_csv(ELK).rename(columns={"ID": "id", "Easting": "x", "Northing": "y"})
    return tracks.prepare(raw, scale=1000.0)  # km, as moveHMM's example


def test_preprocessing_matches_movehmm(elk):
    assert elk["step"].isna().sum() == 4
    assert elk["angle"].isna().sum() == 10
    assert elk["step"].sum() == pytest.approx(938.304079059, abs=1e-6)
    water = elk["dist_water"]
    assert water.mean() == pytest.approx(773.6457279, abs=1e-6)
    assert water.std(ddof=1) == pytest.approx(791.1607743, abs=1e-6)


def test_two_states_without_covariate_reach_the_movehmm_optimum(elk):
    estimator = MovementHMMEstimator(2, n_starts=2, seed=1, step_unit="km").fit(elk)
    model = estimator.model_
    assert model.log_likelihood >= -1892.97445 - 1e-3
    assert model.step.zero_mass is not None  # one zero step switches zero-inflation on
    states = model.viterbi(elk)
    np.testing.assert_array_equal(np.bincount(states), [520, 215])
    assert model.step.mean[0] < model.step.mean[1]
    # moveHMM's parameter count: 2x(mean, sd, zero mass) + 2x(angle mean, kappa) + 2 + 1
    assert model.aic == pytest.approx(-2 * model.log_likelihood + 2 * 13)


def test_two_states_with_dist_water_reach_the_movehmm_optimum(elk):
    estimator = MovementHMMEstimator(
        2, covariates=["dist_water"], n_starts=2, seed=1, step_unit="km"
    ).fit(elk)
    model = estimator.model_
    assert model.log_likelihood >= -1884.74664 - 1e-3
    mean, sd = model.transition_design.scaling["dist_water"]
    assert (mean, sd) == pytest.approx((773.6457279, 791.1607743), abs=1e-6)


def test_three_states_with_dist_water_reach_the_movehmm_optimum(elk):
    estimator = MovementHMMEstimator(
        3, covariates=["dist_water"], n_starts=3, seed=1, step_unit="km"
    ).fit(elk)
    assert estimator.model_.log_likelihood >= -1798.87480 - 1e-3
    assert len(estimator.starts_) == 3
    assert estimator.model_.log_likelihood >= max(s.log_likelihood for s in estimator.starts_)


def test_dist_water_formula_is_the_covariate_fit(elk):
    options = {"n_starts": 2, "seed": 1, "step_unit": "km"}
    model = MovementHMMEstimator(2, formula="~ dist_water", **options).fit(elk).model_
    assert model.log_likelihood >= -1884.74664 - 1e-3
    same = MovementHMMEstimator(2, covariates=["dist_water"], **options).fit(elk).model_
    assert model.to_dict() == same.to_dict()
