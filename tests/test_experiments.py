"""Experiments: seeding, tables, loss bands, thinning, and executor-independence of real trials."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from hmmtrack import experiments as ex
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.motion import motion_model


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
    later = ex.child_seed(root, 3)
    earlier = ex.child_seed(root, 0)
    for got, want in ((earlier, spawned[0]), (later, spawned[3])):
        np.testing.assert_array_equal(got.generate_state(4), want.generate_state(4))
    grand = np.random.SeedSequence(123).spawn(3)[2].spawn(2)[1]
    np.testing.assert_array_equal(
        ex.child_seed(root, 2, 1).generate_state(4), grand.generate_state(4)
    )


def test_experiment_seed_refuses_a_generator():
    with pytest.raises(TypeError, match="Generator"):
        ex.experiment_seed(np.random.default_rng(0))
    ss = np.random.SeedSequence(7)
    assert ex.experiment_seed(ss) is ss


def test_loss_bands_on_hand_data():
    table = _table(
        [
            (0.0, True, 10.0, 5.0),
            (0.1, True, 30.0, 7.0),
            (0.15, False, 0.0, 900.0),  # never converged: counted, not averaged
            (0.2, True, 50.0, 20.0),  # an edge belongs to the middle band
            (0.5, True, 70.0, 40.0),
            (0.8, True, 90.0, 60.0),
            (0.85, True, 1000.0, 300.0),
            (1.0, False, 0.0, 5000.0),
        ]
    )
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
    table = pd.concat(
        [
            _table([(0.0, True, 10.0, 4.0), (0.0, False, 0.0, 8.0)]),
            _table([(0.0, True, 30.0, 1.0)]).assign(motion="baseline"),
        ]
    )
    summary = ex.summarise_trials(table).set_index("motion")
    assert summary.loc["hmm", "n_trials"] == 2 and summary.loc["hmm", "n_converged"] == 1
    assert summary.loc["hmm", "mean_error_after_convergence"] == pytest.approx(6.0)
    assert summary.loc["hmm", "rmse_after_convergence"] == pytest.approx(9.0)
    assert summary.loc["hmm", "time_to_convergence"] == pytest.approx(10.0)
    assert summary.loc["baseline", "time_to_convergence"] == pytest.approx(30.0)
    # the region's scale is a median: one lost trial (scale 300) does not swamp it
    scaled = ex.summarise_trials(
        _table([(0.0, True, 10.0, 4.0)] * 3).assign(region_scale=[0.5, 0.6, 300.0])
    )
    assert scaled["region_scale"].tolist() == [0.6]


def test_trials_table_order_does_not_depend_on_finishing_order():
    def result(motion, trial):
        return ex.TrialResult(
            "s", motion, trial, 0.0, False, 10, 1.0, True, 2.0, 3.0, 0.1, np.zeros(1), np.zeros(1)
        )

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


# ------------------------------------------------------------------ real filter trials

N_PARTICLES = 100


@pytest.fixture(scope="module")
def small_scenarios():
    """The swimmer (349 s) and the first 10 minutes of the shark pursuit."""
    built = ex.paper_scenarios(11, names=("swimmer", "shark_pursuit"))
    return [built["swimmer"], ex.truncate(built["shark_pursuit"], 600.0)]


def _without_runtime(table: pd.DataFrame) -> pd.DataFrame:
    return table.drop(columns="runtime")


def test_same_seed_same_table_serial_equals_processes(small_scenarios):
    serial = ex.compare_motion_models(small_scenarios, n_trials=2, seed=5, n_particles=N_PARTICLES)
    parallel = ex.compare_motion_models(
        small_scenarios, n_trials=2, seed=5, **ex.run_options(2, N_PARTICLES, progress=False)
    )
    pd.testing.assert_frame_equal(_without_runtime(serial), _without_runtime(parallel))
    assert len(serial) == 2 * 3 * 2
    assert serial["scenario"].tolist()[:6] == ["swimmer"] * 6
    # trials differ from each other, and another seed gives other numbers
    assert serial["mean_error_after_convergence"].nunique() == len(serial)
    other = ex.compare_motion_models(
        small_scenarios[:1], motions=("hmm",), n_trials=1, seed=6, n_particles=N_PARTICLES
    )
    first = serial[(serial["motion"] == "hmm") & (serial["trial"] == 0)].iloc[0]
    assert other["mean_error_after_convergence"].iloc[0] != first["mean_error_after_convergence"]


def test_paper_datasets_extend_paper_scenarios_with_other_draws():
    datasets = ex.paper_datasets(11, 3, names=("swimmer",))["swimmer"]
    first = ex.paper_scenarios(11, names=("swimmer",))["swimmer"]
    pd.testing.assert_frame_equal(datasets[0].detections, first.detections)
    truths = [d.truth[["x", "y"]].to_numpy() for d in datasets]
    assert not np.array_equal(truths[0][:50], truths[1][:50])
    assert not np.array_equal(truths[1][:50], truths[2][:50])
    again = ex.paper_datasets(11, 3, names=("swimmer",))["swimmer"][2]
    pd.testing.assert_frame_equal(again.truth, datasets[2].truth)
    with pytest.raises(ValueError, match="n_datasets"):
        ex.paper_datasets(11, 0)


def test_several_datasets_keep_dataset_zero_trials_and_add_their_own(small_scenarios):
    swimmer = small_scenarios[0]
    other = ex.paper_datasets(11, 2, names=("swimmer",))["swimmer"][1]
    options = {"motions": ("velocity",), "n_trials": 2, "seed": 3, "n_particles": N_PARTICLES}
    alone = ex.compare_motion_models([swimmer], **options)
    both = ex.compare_motion_models([[swimmer, other]], **options)
    assert both["dataset"].tolist() == [0, 0, 1, 1]
    pd.testing.assert_frame_equal(
        _without_runtime(alone), _without_runtime(both[both["dataset"] == 0])
    )
    # the other dataset's trials are their own draws, not dataset 0's again
    errors = both["mean_error_after_convergence"].to_numpy()
    assert len(set(errors)) == 4


def test_dataset_spread_separates_datasets_from_runs():
    table = pd.DataFrame(
        {
            "scenario": ["s"] * 6,
            "motion": ["hmm"] * 6,
            "dataset": [0, 0, 0, 1, 1, 1],
            "mean_error_after_convergence": [1.0, 2.0, 3.0, 10.0, 12.0, 200.0],
        }
    )
    row = ex.dataset_spread(table).iloc[0]
    means = np.array([2.0, 74.0])
    within = np.array([np.var([1.0, 2.0, 3.0], ddof=1), np.var([10.0, 12.0, 200.0], ddof=1)])
    assert row["n_datasets"] == 2 and row["runs_per_dataset"] == 3
    assert row["mean"] == pytest.approx(38.0)
    assert row["between_datasets"] == pytest.approx(np.std(means, ddof=1))
    assert row["between_runs"] == pytest.approx(np.sqrt(within.mean()))
    assert row["worst_dataset"] == pytest.approx(74.0)
    assert row["share_above_100m"] == pytest.approx(1 / 6)


def test_calibration_spread_counts_the_datasets_a_cells_share_rests_on():
    # three datasets of two runs: one all inside, one half inside on average, one that is
    # all inside in one run only; a second cell to show the grouping
    table = pd.DataFrame(
        {
            "scenario": ["s"] * 6 + ["t"] * 2,
            "motion": ["hmm"] * 6 + ["velocity"] * 2,
            "dataset": [0, 0, 1, 1, 2, 2, 0, 1],
            "calibration": [1.0, 1.0, 0.4, 0.6, 1.0, 0.9, 0.95, 0.7],
        }
    )
    cells = ex.calibration_spread(table).set_index(["scenario", "motion"])
    hmm = cells.loc[("s", "hmm")]
    assert hmm["n_datasets"] == 3
    assert hmm["share"] == pytest.approx(np.mean([1.0, 1.0, 0.4, 0.6, 1.0, 0.9]))
    assert hmm["between_datasets"] == pytest.approx(np.std([1.0, 0.5, 0.95], ddof=1))
    assert hmm["all_inside"] == 1 and hmm["mostly_outside"] == 1
    velocity = cells.loc[("t", "velocity")]
    assert velocity["all_inside"] == 0 and velocity["mostly_outside"] == 1
    assert velocity["share"] == pytest.approx(0.825)
    assert ex.MOSTLY_OUTSIDE == 0.8


def test_run_options_run_one_worker_serially_and_more_in_processes():
    assert ex.run_options(1, 50) == {
        "executor": "serial",
        "max_workers": 1,
        "n_particles": 50,
        "progress": True,
    }
    assert ex.run_options(3, progress=False) == {
        "executor": "processes",
        "max_workers": 3,
        "n_particles": ex.DEFAULT_PARTICLES,
        "progress": False,
    }


def test_more_trials_only_append_rows(small_scenarios):
    swimmer = small_scenarios[:1]
    two = ex.compare_motion_models(
        swimmer, motions=("velocity",), n_trials=2, seed=3, n_particles=N_PARTICLES
    )
    three = ex.compare_motion_models(
        swimmer, motions=("velocity",), n_trials=3, seed=3, n_particles=N_PARTICLES
    )
    pd.testing.assert_frame_equal(_without_runtime(two), _without_runtime(three.iloc[:2]))


def test_start_prior_starts_the_particles_in_the_start_region(small_scenarios):
    swimmer, pursuit = small_scenarios
    # no start region recorded: the run starts in the search box, as without the option
    unknown = replace(swimmer, start_region=None)
    pd.testing.assert_frame_equal(
        ex.track_scenario(unknown, "velocity", 1, N_PARTICLES, start_prior=True).estimates,
        ex.track_scenario(unknown, "velocity", 1, N_PARTICLES).estimates,
    )
    assert not ex.run_trial(unknown, "velocity", 1, N_PARTICLES, start_prior=True).start_prior
    # a known start replaces the named filter's acquisition: the same run as the mixture alone
    keeping = ex.track_scenario(
        pursuit, "velocity", 1, N_PARTICLES, start_prior=True, filter="mode-keeping"
    )
    mixture_only = tracking.track(
        pursuit.detections,
        pursuit.receivers,
        tracking_config(
            pursuit,
            n_particles=N_PARTICLES,
            depth="none",
            shallower="clip",
            bounds=pursuit.start_region,
            filter="mode-keeping",
            acquisition=False,
        ),
        motion_model("velocity"),
        seed=1,
    )
    pd.testing.assert_frame_equal(keeping.estimates, mixture_only.estimates)
    run = ex.track_scenario(
        pursuit, "velocity", 1, N_PARTICLES, start_prior=True, snapshot_times=[pursuit.start]
    )
    first = run.snapshots[pursuit.start]
    xmin, xmax, ymin, ymax = pursuit.start_region
    assert first["x"].between(xmin, xmax).all() and first["y"].between(ymin, ymax).all()
    assert (first["x"].max() - first["x"].min()) > 0.9 * (xmax - xmin)
    result = ex.run_trial(pursuit, "velocity", 1, N_PARTICLES, start_prior=True)
    assert result.start_prior and result.row()["start_prior"]
    assert not ex.run_trial(pursuit, "velocity", 1, N_PARTICLES).start_prior


def test_a_motion_model_given_is_tracked_with_as_it_is(small_scenarios):
    swimmer = small_scenarios[0]
    # the named model's own object: the same run as by name
    pd.testing.assert_frame_equal(
        ex.track_scenario(
            swimmer, "velocity", 2, N_PARTICLES, motion=ex.trials._motion("velocity")
        ).estimates,
        ex.track_scenario(swimmer, "velocity", 2, N_PARTICLES).estimates,
    )
    # another model under the same name: that model's run, not the name's
    given = ex.track_scenario(swimmer, "velocity", 2, N_PARTICLES, motion=motion_model("baseline"))
    by_name = ex.track_scenario(swimmer, "baseline", 2, N_PARTICLES)
    pd.testing.assert_frame_equal(given.estimates, by_name.estimates)
    assert not given.estimates.equals(
        ex.track_scenario(swimmer, "velocity", 2, N_PARTICLES).estimates
    )
    # a trial passes it on, and keeps the name it is given
    trial = ex.run_trial(swimmer, "velocity", 2, N_PARTICLES, motion=motion_model("baseline"))
    baseline = ex.run_trial(swimmer, "baseline", 2, N_PARTICLES)
    assert trial.motion == "velocity"
    assert trial.mean_error_after_convergence == baseline.mean_error_after_convergence
    np.testing.assert_array_equal(trial.error, baseline.error)


def test_trial_scores_and_error_curve_match_metrics(small_scenarios):
    from hmmtrack.analysis import metrics

    swimmer = small_scenarios[0]
    result = ex.run_trial(swimmer, "hmm", 9, N_PARTICLES)
    run = ex.track_scenario(swimmer, "hmm", 9, N_PARTICLES)
    scores = metrics.tracking_metrics(run.estimates, swimmer.truth)
    assert result.mean_error_after_convergence == scores.mean_error_after_convergence
    assert result.rmse_after_convergence == scores.rmse_after_convergence
    assert result.time_to_convergence == scores.time_to_convergence
    honesty = metrics.uncertainty_metrics(run.estimates, swimmer.truth)
    assert result.false_converged == honesty.false_converged
    np.testing.assert_equal(result.calibration, honesty.calibration)
    np.testing.assert_equal(result.region_scale, honesty.region_scale)
    # the mirror share is taken over the seconds after convergence, on the logged receivers
    from hmmtrack.analysis.mirror import mirror_share, mirror_track

    elapsed = run.estimates["time"] - run.estimates["time"].iloc[0]
    after = run.estimates[elapsed >= scores.time_to_convergence]
    mirror = mirror_track(swimmer.truth, swimmer.receivers)
    assert scores.converged
    assert result.mirror_share == mirror_share(after, swimmer.truth, mirror)
    assert 0.0 <= result.mirror_share <= 1.0
    errors = metrics.position_error(run.estimates, swimmer.truth)
    np.testing.assert_array_equal(result.error, errors[:: int(ex.ERROR_CURVE_SPACING)])
    np.testing.assert_array_equal(np.diff(result.error_time), ex.ERROR_CURVE_SPACING)


def test_loss_sweep_thins_detections_evenly(small_scenarios):
    from dataclasses import replace

    from hmmtrack.scenarios import thin_evenly

    shark = small_scenarios[1]
    sweep = ex.loss_sweep(
        shark, fractions=(0.0, 0.5, 1.0), n_trials=1, seed=2, n_particles=N_PARTICLES
    )
    assert sweep["loss_fraction"].tolist() == [0.0, 0.5, 1.0]
    # the half-loss trial is the trial of a scenario whose detections were thinned by hand
    thinned = replace(shark, detections=thin_evenly(shark.detections, 0.5))
    seed = ex.child_seed(ex.experiment_seed(2), 1, 1, 0)
    by_hand = ex.run_trial(thinned, "hmm", seed, N_PARTICLES)
    half = sweep.iloc[1]
    assert half["mean_error_after_convergence"] == by_hand.mean_error_after_convergence
    assert half["time_to_convergence"] == by_hand.time_to_convergence
    # and differs from the full-data trial; with every detection gone it cannot converge
    assert sweep.iloc[0]["mean_error_after_convergence"] != by_hand.mean_error_after_convergence
    assert not sweep.iloc[2]["converged"]


def test_truncate_keeps_the_first_seconds(small_scenarios):
    shark = small_scenarios[1]
    assert shark.end - shark.start == 600.0
    assert shark.detections["time"].max() <= shark.end
    assert shark.truth["time"].iloc[-1] == shark.end
    with pytest.raises(ValueError, match="duration"):
        ex.truncate(shark, 0.0)


def test_unknown_names_are_refused(small_scenarios):
    with pytest.raises(ValueError, match="unknown motion"):
        ex.compare_motion_models(small_scenarios, motions=("kalman",), n_trials=1)
    with pytest.raises(ValueError, match="unknown scenario"):
        ex.paper_scenarios(0, names=("long_beach",))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        ex.loss_sweep(small_scenarios[1], fractions=(1.5,), n_trials=1)


def test_depth_correction_reaches_the_ranges_and_both_variants_are_tracked():
    diving = ex.paper_scenarios(5, dive=True, duration=600.0)["shark_pursuit"]
    plain = ex.track_scenario(diving, "hmm", 1, N_PARTICLES).observations
    corrected = ex.track_scenario(diving, "hmm", 1, N_PARTICLES, depth_correction=True)
    corrected = corrected.observations
    depth = np.interp(plain["time"], diving.truth["time"], diving.truth["depth"])
    # r_2D = sqrt(r^2 - d^2) with the tag's reported depth (reported = true depth here)
    expected = np.sqrt(np.maximum(plain["range"] ** 2 - depth**2, 0.0))
    np.testing.assert_allclose(corrected["range"], expected, atol=0.5)
    assert (corrected["range"] < plain["range"]).mean() > 0.9
    analysis = ex.depth_analysis(n_trials=1, seed=5, n_particles=N_PARTICLES, duration=600.0)
    assert analysis.trials["depth_correction"].tolist() == [False, True]
    assert analysis.max_depth == pytest.approx(diving.truth["depth"].max())


def test_the_named_filter_reaches_every_trial(small_scenarios):
    """``filter="mode-keeping"`` runs acquisition and the mixture (an ``acquired`` event, the
    modes reported); the default is the paper's filter, named."""
    swimmer = small_scenarios[0]
    paper = ex.track_scenario(swimmer, "velocity", 9, N_PARTICLES)
    keeping = ex.track_scenario(swimmer, "velocity", 9, N_PARTICLES, filter="mode-keeping")
    assert paper.modes is None and "acquired" not in set(paper.events["kind"])
    assert keeping.modes is not None and "acquired" in set(keeping.events["kind"])
    tables = {
        name: ex.compare_motion_models(
            [swimmer], ("velocity",), n_trials=1, seed=5, n_particles=N_PARTICLES, filter=name
        )
        for name in ("paper", "mode-keeping")
    }
    assert (
        not tables["paper"]
        .drop(columns="runtime")
        .equals(tables["mode-keeping"].drop(columns="runtime"))
    )
