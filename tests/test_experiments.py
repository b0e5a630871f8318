"""Experiments: seeding, tables, loss bands, thinning, and executor-independence of real trials."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from hmmtrack import experiments as ex


def _table(rows):
    """A trials table from (loss_fraction, converged, time_to_convergence, error) tuples."""
    return pd.DataFrame(
        {
            "scenario": "s",
            "motion": "hmm",
            "trial": range(len(rows)),
            "loss_fraction": [r[0] for r in rows],
            "depth_correction": False,
            "n_particles": 10,
            "converged": [r[1] for r in rows],
            "time_to_convergence": [r[2] for r in rows],
            "mean_error_after_convergence": [r[3] for r in rows],
            "rmse_after_convergence": [r[3] * 1.5 for r in rows],
            "runtime": 0.0,
        }
    )


def test_child_seeds_equal_spawned_children_and_do_not_depend_on_call_order():
    root = np.random.SeedSequence(123)
    spawned = np.random.SeedSequence(123).spawn(4)
    later = ex._child(root, 3)
    earlier = ex._child(root, 0)
    for got, want in ((earlier, spawned[0]), (later, spawned[3])):
        np.testing.assert_array_equal(got.generate_state(4), want.generate_state(4))
    grand = np.random.SeedSequence(123).spawn(3)[2].spawn(2)[1]
    np.testing.assert_array_equal(ex._child(root, 2, 1).generate_state(4), grand.generate_state(4))


def test_experiment_seed_refuses_a_generator():
    with pytest.raises(TypeError, match="Generator"):
        ex.experiment_seed(np.random.default_rng(0))
    ss = np.random.SeedSequence(7)
    assert ex.experiment_seed(ss) is ss


def test_loss_bands_on_hand_data():
    table = _table([
        (0.0, True, 10.0, 5.0),
        (0.1, True, 30.0, 7.0),
        (0.15, False, 0.0, 900.0),   # never converged: counted, not averaged
        (0.2, True, 50.0, 20.0),     # an edge belongs to the middle band
        (0.5, True, 70.0, 40.0),
        (0.8, True, 90.0, 60.0),
        (0.85, True, 1000.0, 300.0),
        (1.0, False, 0.0, 5000.0),
    ])
    bands = ex.loss_bands(table)
    assert list(bands.index) == list(ex.LOSS_BANDS)
    assert bands["n_trials"].tolist() == [3, 3, 2]
    assert bands["n_converged"].tolist() == [2, 3, 1]
    np.testing.assert_allclose(bands["convergence_mean"], [20.0, 70.0, 1000.0])
    np.testing.assert_allclose(bands["convergence_max"], [30.0, 90.0, 1000.0])
    np.testing.assert_allclose(bands["error_mean"], [6.0, 40.0, 300.0])
    np.testing.assert_allclose(bands["error_max"], [7.0, 60.0, 300.0])


def test_loss_bands_reject_fractions_outside_unit_interval():
    with pytest.raises(ValueError, match=r"row\(s\) \[1\]"):
        ex.loss_bands(_table([(0.0, True, 1.0, 1.0), (1.2, True, 1.0, 1.0)]))


def test_summarise_trials_means_over_trials_and_converged_times():
    table = pd.concat([_table([(0.0, True, 10.0, 4.0), (0.0, False, 0.0, 8.0)]),
                       _table([(0.0, True, 30.0, 1.0)]).assign(motion="baseline")])
    summary = ex.summarise_trials(table).set_index("motion")
    assert summary.loc["hmm", "n_trials"] == 2 and summary.loc["hmm", "n_converged"] == 1
    assert summary.loc["hmm", "mean_error_after_convergence"] == pytest.approx(6.0)
    assert summary.loc["hmm", "rmse_after_convergence"] == pytest.approx(9.0)
    assert summary.loc["hmm", "time_to_convergence"] == pytest.approx(10.0)
    assert summary.loc["baseline", "time_to_convergence"] == pytest.approx(30.0)


def test_trials_table_order_does_not_depend_on_finishing_order():
    def result(motion, trial):
        return ex.TrialResult("s", motion, trial, 0.0, False, 10, 1.0, True, 2.0, 3.0, 0.1,
                              np.zeros(1), np.zeros(1))

    results = [result(m, k) for m in ("hmm", "baseline", "velocity") for k in (1, 0)]
    table = ex.trials_table(results)
    assert table["motion"].tolist() == ["baseline"] * 2 + ["velocity"] * 2 + ["hmm"] * 2
    assert table["trial"].tolist() == [0, 1] * 3
    pd.testing.assert_frame_equal(table, ex.trials_table(results[::-1]))


def test_depth_percent_error_curve_matches_paper_points():
    analysis = ex.depth_analysis(n_trials=0)
    curve = dict(zip(analysis.ranges, analysis.percent_error, strict=True))
    assert curve[20.0] == pytest.approx(18.4, abs=0.05)
    assert curve[50.0] == pytest.approx(2.4, abs=0.05)
    assert curve[100.0] == pytest.approx(0.6, abs=0.05)
    assert np.all(np.diff(analysis.percent_error) < 0)
