"""Tests of the studies behind ``hmmtrack study``: each at a tiny size, its tables and report.

Tiny runs (one seed, 15 minutes, a few hundred particles) cannot check the reports' numbers;
they check that a study runs end to end, that its tables have the report's columns with
finite values, and what must hold at any size: a Cramér–Rao bound that shrinks as
information is added, the online closed-loop filter equal to its offline rerun, the
known-clock diagnostic present.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hmmtrack.cli import build_parser
from hmmtrack.cli.study import _keywords
from hmmtrack.experiments.arrival import ARRIVAL, GROUPED, KNOWN_CLOCK_CASES, arrival_study
from hmmtrack.experiments.clock_bound import CASES, clock_bound_study
from hmmtrack.experiments.closed_loop_study import MODES, closed_loop_study
from hmmtrack.experiments.stationary import GEOMETRY_COLUMNS, settings, stationary_study
from hmmtrack.experiments.two_auv_plan import (
    PLANS,
    TUNED_FILTER_SEEDS,
    arrival_run,
    tuned_settings,
    two_auv_plan_study,
)
from hmmtrack.report.clock_aware import clock_aware_markdown, read_filter_errors
from hmmtrack.report.clock_bound import clock_bound_markdown
from hmmtrack.report.closed_loop import closed_loop_markdown
from hmmtrack.report.stationary import stationary_markdown
from hmmtrack.report.studies import READING_MARKER, kept_reading
from hmmtrack.report.two_auv_plan import two_auv_plan_markdown
from hmmtrack.scenarios.realistic import realistic_shark_pursuit
from hmmtrack.tracking.config import merge_settings, nest

#: a tiny run: 15 minutes (the clock studies score from 10 minutes on)
DURATION = 900.0


@pytest.fixture(autouse=True)
def quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # re-initialised clouds warn
        yield


@pytest.fixture(scope="module")
def arrival():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return arrival_study([0], n_particles=200, duration=DURATION)


def test_stationary_study_scores_every_setting_and_bounds_each_geometry():
    study = stationary_study(1, (200,), moving_trials=1, moving_particles=100)
    trials = study.trials
    assert list(trials["motion"]) == list(settings())
    assert set(GEOMETRY_COLUMNS) <= set(trials.columns)
    assert np.isfinite(trials[["error", "crb_m", "coverage", "mirror_share"]]).all().all()
    # seed 0's geometry is well observed: a bound of a few metres, the data within 10 m
    assert 0 < trials["crb_m"].iloc[0] < 10 and trials["static_fit_error_m"].iloc[0] < 10
    assert (trials["error"] < 200).all()
    assert set(study.moving["scenario"]) == {"swimmer", "shark_pursuit"}
    assert study.summary["trials"].eq(1).all()
    text = stationary_markdown(study, "Written by a test")
    assert text.startswith("# Stationary tag") and "## Per-trial table" in text


def test_arrival_study_tracks_every_case_three_ways(arrival, tmp_path):
    runs = arrival.runs
    assert len(runs) == 3 * 5 + len(KNOWN_CLOCK_CASES)
    assert runs.groupby("scenario")["method"].nunique().max() == 3
    # a grouped row beside each arrival-time row, with the share heard by three and the
    # measurement the command line would choose from it: the moorings group, two AUVs not
    grouped = runs[runs["method"].str.startswith(GROUPED)].set_index("scenario")
    assert len(grouped) == 5 and np.isfinite(grouped["smoothed_after_10_min_m"]).all()
    assert grouped.loc["moored array, 3 receivers", "heard_by_3"] > 0.5
    assert grouped.loc["moored array, 3 receivers", "pings_choose"] == "ping-sequence"
    assert grouped.loc["shark pursuit, 2 AUVs (circling)", "heard_by_3"] == 0
    assert grouped.loc["shark pursuit, 2 AUVs (circling)", "pings_choose"] == "arrival-time"
    table = arrival.grouping.set_index("scenario")
    assert list(table.index) == list(grouped.index)
    ratio = (
        grouped["error_after_10_min_m"]
        / runs[runs["method"].str.startswith(ARRIVAL)].set_index("scenario")["error_after_10_min_m"]
    )
    assert np.allclose(table["median_ratio"], ratio[table.index])
    assert table.loc["moored array, 3 receivers", "pings_choose"] == "ping-sequence (1 of 1)"
    scored = runs[["error_after_10_min_m", "time_to_convergence_s"]]
    assert np.isfinite(scored).all().all()
    moored = runs[(runs["scenario"] == "moored array, 3 receivers")]
    arrival_time = moored[moored["method"].str.startswith("arrival-time")]
    assert arrival_time["error_after_10_min_m"].iloc[0] < 100  # three moorings fix the tag
    assert len(arrival.robustness) == 4 * 2 and len(arrival.facts) == 5
    # the report's per-run table reads back as the bound study's filter errors
    path = tmp_path / "clock_aware.md"
    text = clock_aware_markdown(arrival, "Written by a test")
    assert "## Grouped pings (fixed period) against arrival-time" in text
    path.write_text(text)
    errors = read_filter_errors(path)
    assert set(errors["scenario"]) >= set(KNOWN_CLOCK_CASES)
    assert errors["pf_mean_after_10_min_m"].notna().all()


def test_clock_bound_study_orders_the_bounds(arrival, tmp_path):
    path = tmp_path / "clock_aware.md"
    path.write_text(clock_aware_markdown(arrival, "Written by a test"))
    study = clock_bound_study(
        [0],
        sweep_seeds=[0],
        sweep=((30.0,), (200.0,), (135,)),
        run_filter=False,
        filter_runs=read_filter_errors(path),
        duration=DURATION,
    )
    runs = study.runs.set_index("scenario")
    assert list(runs.index) == list(CASES)
    alone = runs["fitted clock, arrivals only: filter_m"]
    fitted = runs["fitted clock: filter_m"]
    known = runs["clock known: filter_m"]
    # more information, a smaller bound: the detection curve, then the clock itself
    assert (known <= fitted * (1 + 1e-9)).all() and (fitted <= alone * (1 + 1e-9)).all()
    assert (runs["fitted clock: smoother_m"] <= fitted * (1 + 1e-9)).all()
    assert np.isfinite(runs["pf_mean_after_10_min_m"]).all()  # merged from the report
    assert len(study.sweep) == 1 and bool(study.sweep["flyable"].iloc[0])
    assert study.plans.empty
    text = clock_bound_markdown(study, "Written by a test", "clock_bound.png", str(path), 1)
    assert "## Planning sweep" in text and "## Every run" in text


def test_two_auv_plan_study_runs_every_setting_on_every_plan():
    study = two_auv_plan_study([0], n_particles=150, duration=DURATION)
    runs = study.runs
    assert len(runs) == len(PLANS) * (1 + 2 * len(TUNED_FILTER_SEEDS))
    assert np.isfinite(runs[["filtered_rms_m", "bound_filter_rms_m", "range_rate_m"]]).all().all()
    assert (runs["bound_filter_rms_m"] > 0).all() and (runs["auv_speed_p99_m_s"] < 3).all()
    assert set(study.summary["runs"]) == {1, 2}
    assert "## Every run" in two_auv_plan_markdown(study, "Written by a test", 1)


def test_two_auv_plan_arrival_run_scores_missed_pings_only_with_the_curve():
    """Runs with and without the case's detection curve differ (same detections and filter
    seed): the curve reaches the filter, whose weights then count the missed pings."""
    case = realistic_shark_pursuit(0, steering="observable")
    settings = merge_settings(tuned_settings(), nest({"n_particles": 150}))
    heard = arrival_run(case, settings, None, 0, silences=True, duration=300.0)
    deaf = arrival_run(case, settings, None, 0, silences=False, duration=300.0)
    shift = np.hypot(*(heard.estimates[["x", "y"]] - deaf.estimates[["x", "y"]]).to_numpy().T)
    assert shift.max() > 1.0  # metres: the silences moved the estimate


def test_closed_loop_study_online_filter_equals_its_offline_rerun():
    study = closed_loop_study([0], n_particles=150, duration=DURATION)
    runs = study.runs
    assert list(runs["mode"]) == list(MODES)
    assert (runs["online_vs_offline_m"] < 1e-6).all()
    assert np.isfinite(runs[["filtered_m", "bound_filter_rms_m", "auv_speed_max_m_s"]]).all().all()
    assert (runs["auv_speed_max_m_s"] <= 3.0 + 1e-9).all()
    assert set(study.series) == set(MODES) and study.loop_ratio > 0
    text = closed_loop_markdown(study, "Written by a test", 2.0, DURATION, "closed_loop.png")
    assert text.startswith("# Two AUVs steered")


def test_a_rewritten_report_keeps_its_reading(tmp_path):
    path = tmp_path / "report.md"
    assert kept_reading(path) == ""
    path.write_text(f"# tables\n\n{READING_MARKER}\nwhat the tables mean\n")
    assert kept_reading(path) == f"{READING_MARKER}\nwhat the tables mean\n"


@pytest.mark.parametrize(
    "argv, expected",
    [
        (
            ["study", "stationary", "--seeds", "3", "--particles", "100", "200"],
            {"seeds": 3, "particles": (100, 200), "moving_trials": 100, "moving_particles": 1000},
        ),
        (
            ["study", "clock-bound", "--seeds", "1", "--sweep-seeds", "0", "--no-filter"],
            {
                "seeds": 1,
                "duration": 7200.0,
                "particles": 3000,
                "sweep_seeds": 0,
                "run_filter": False,
                "filter_report": None,
            },
        ),
        (
            ["study", "closed-loop", "--duration", "900", "--particles", "300"],
            {
                "seeds": 3,
                "duration": 900.0,
                "particles": 300,
                "filter_seeds": 1,
                "latency": 2.0,
            },
        ),
    ],
)
def test_study_command_passes_its_options_to_the_writer(argv, expected):
    assert _keywords(build_parser().parse_args(argv)) == expected
