"""Tests of the simulated moored array with a pseudo-random-interval tag: the files
``hmmtrack simulate moored-array`` writes, read back by the io readers, synchronised by
``hmmtrack sync`` to the truth; the scenario's tag and echoes."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from hmmtrack import io
from hmmtrack.cli import main
from hmmtrack.experiments.array_runs import array_bound_ratios, pooled_ratios
from hmmtrack.scenarios.array import DriftingClock, tagged_array
from hmmtrack.sync import read_clocks
from hmmtrack.tracking.config import read_preset

KEEPER = "rx-01"


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("array")
    argv = ["simulate", "moored-array", "--seed", "4", "--burst-interval", "20", "40"]
    assert main([*argv, "-o", str(folder / "sim")]) == 0
    return folder


def test_files_read_back_with_the_io_readers(simulated):
    sim = simulated / "sim"
    detections = io.read_detections(sim / "detections.csv")
    receivers = io.read_receivers(sim / "receivers.csv")
    metadata = json.loads((sim / "scenario.json").read_text())
    case = tagged_array(4, burst_interval=(20.0, 40.0), duration=43200.0, echo_fraction=0.01)
    assert len(detections) == len(case.detections)
    # milliseconds, as receivers log them
    np.testing.assert_allclose(
        np.sort(detections["time"].to_numpy()), np.sort(case.detections["time"]), atol=5e-4
    )
    assert receivers["sync_tag"].notna().all() and receivers["fixed"].sum() == 8
    tag = detections[detections["transmitter"] == metadata["transmitter"]]
    assert len(tag) > 10 * 16  # the tag is heard by many receivers at every ping
    sequence = pd.read_csv(sim / "burst_sequence.csv")["interval"].to_numpy()
    emissions = pd.read_csv(sim / "emissions.csv")
    gaps = np.diff(emissions["emission_time"].to_numpy())
    used = sequence[emissions["sequence_index"].to_numpy()[:-1]]
    np.testing.assert_allclose(gaps, used, atol=2e-6)  # written to the microsecond
    assert 20.0 <= gaps.min() and gaps.max() <= 40.0


def test_sync_on_the_written_files_recovers_the_true_clocks(simulated):
    sim = simulated / "sim"
    out = simulated / "clocks.json"
    argv = ["sync", "--detections", str(sim / "detections.csv")]
    argv += ["--receivers", str(sim / "receivers.csv"), "--time-keeper", KEEPER]
    assert main([*argv, "--refine-positions", "3", "-o", str(out)]) == 0
    clocks = read_clocks(out)
    truth = pd.read_csv(sim / "receivers_truth.csv").set_index("receiver")
    true_clocks = {
        name: DriftingClock(
            row.clock_offset_s,
            row.clock_drift_ppm,
            row.clock_drift_rate_ppm_per_day,
            row.clock_reference_time,
        )
        for name, row in truth.iterrows()
    }
    deployment = io.read_detections(sim / "detections.csv")["time"]
    grid = np.linspace(deployment.min() + 100.0, deployment.max() - 100.0, 500)
    keeper = true_clocks[KEEPER]
    errors = {
        name: np.max(np.abs(clocks.to_common(name, clock(grid)) - keeper(grid)))
        for name, clock in true_clocks.items()
    }
    print("largest clock error (ms):", 1e3 * max(errors.values()))
    assert max(errors.values()) <= 0.2e-3
    # in the keeper's time base the sound speed is scaled by its drift (< 20 ppm, 0.03 m/s)
    print("sound speed error (m/s):", np.abs(clocks.sound_speed - 1500.0).max())
    np.testing.assert_allclose(clocks.sound_speed, 1500.0, atol=1.0)
    true_xy = truth.loc[clocks.receivers, ["x", "y"]].to_numpy()
    moved = np.hypot(*(clocks.positions[:, :2] - true_xy).T)
    print("largest position error (m):", moved.max())
    assert moved.max() <= 0.5
    assert clocks.echoes_dropped > 0


def test_error_against_bound_for_the_arrival_time_filter_on_a_fixed_period_tag():
    """The experiment a random-interval measurement will be judged by, run now with the
    arrival-time filter on a fixed-period tag (measured, dataset 2: clocks 0.04 ms, error
    at the pings 1.01 m against a 0.22 m bound, smoothed 1.00 m against 0.22 m)."""
    table = array_bound_ratios(
        "arrival-time",
        datasets=(2,),
        seeds=(1,),
        burst_interval=(20.0, 20.0),
        n_particles=1000,
        settings={"period": 20.0, "smoothing_lag": 30, "motion": "velocity"},
    )
    row = table.iloc[0]
    assert row["pings"] == 90 and row["clock_error_ms"] < 0.2
    assert 0.1 < row["bound_m"] < 0.5  # nine receivers at 0.2 ms each, 0.3 m of range
    assert row["ratio"] == pytest.approx(row["rms_error_m"] / row["bound_m"])
    # the filter's 3 ms arrival sd keeps it a few times above the bound, never below it
    assert 1.0 < row["ratio"] < 10.0 and 1.0 < row["smoothed_ratio"] < 10.0


def test_ping_run_at_its_defaults_against_the_tdoa_bound():
    """What a user gets (simulate, sync, track with the ping measurement's defaults: random
    walk, arrival sd 2 ms, 5,000 particles, the 60 s smoother by backward simulation as
    output) on a 15 min window, dataset 1 seed 1, measured: right after each ping 1.69x the
    filtering bound, the smoothed rows at the pings 1.86x and the smoothed track at the
    emissions 1.64x the smoothing bound (with ancestor tracing 1.98x and 1.80x; the 30 min
    windows of datasets 1-3 x seeds 1-2: 2.1-3.7x; reports/decisions.md, "The arrival sd
    from the pings, and backward simulation for the ping smoother"). Issue 12's 1.2x is not
    met at these defaults; this keeps them from drifting further."""
    table = array_bound_ratios(
        "ping",
        datasets=(1,),
        seeds=(1,),
        tag_duration=900.0,
        settings={"burst_interval": (20.0, 40.0)},
    )
    row = table.iloc[0]
    assert row["pings"] == 29 and 0.15 < row["per_ping_bound_m"] < 0.3
    assert 1.0 < row["per_ping_ratio"] < 1.9
    assert 1.0 < row["smoothed_ratio"] < 1.85 and 1.0 < row["smoothed_per_ping_ratio"] < 2.05


def test_matched_ping_run_reaches_the_tdoa_bound_at_the_pings_and_smoothed():
    """A random-interval tag on constant-velocity legs tracked with the matched settings (the
    ``constant-velocity-tag`` preset: the ping measurement with its arrival sd estimated from
    the pings, 0.2 ms simulated jitter; the velocity motion, the bound's own): the position
    right after each ping's correction is close to the TDOA posterior filtering bound of the
    same pings, and the smoothed track (the output) at the emissions close to the smoothing
    bound (measured, dataset 2 seed 1, 2,000 particles: per ping 0.99x against the bound's
    own estimator's 0.93x on the same draws, smoothed 1.12x, at the pings 1.08x; at 5,000
    particles over datasets 1-10 x seeds 1-3, pooled: per ping 1.05x, smoothed 1.14x;
    reports/decisions.md, "The filter per ping at the emission"),
    while the per-second filter estimate interpolated at the emissions is a prediction
    (ratio ~15). A smoother that lost the fixes (ancestor tracing through the tempered
    pings: 1.8-2.3x) or a bound off by its sd would fail."""
    preset = read_preset("constant-velocity-tag")  # by section; by key below
    settings = {k: v for section in preset.values() for k, v in section.items() if k != "name"}
    settings |= {section: values["name"] for section, values in preset.items()}
    assert settings.pop("measurement") == "ping"
    table = array_bound_ratios(
        "ping",
        datasets=(2,),
        seeds=(1,),
        n_particles=2000,
        settings=settings | {"burst_interval": (20.0, 40.0)},
    )
    row = table.iloc[0]
    # this dataset's draws are lucky: the bound's own estimator on them is below the bound
    assert 0.9 < row["oracle_per_ping_ratio"] < 0.95
    assert 1.0 < row["per_ping_ratio"] / row["oracle_per_ping_ratio"] < 1.15
    assert row["per_ping_ratio"] < 1.2
    assert 1.0 < row["smoothed_ratio"] < 1.4 and 1.0 < row["smoothed_per_ping_ratio"] < 1.4
    assert row["per_ping_ratio"] < row["ratio"] / 5


def test_pooled_ratio_is_the_rms_over_every_ping_against_the_pooled_bound():
    """Two datasets of two runs: the pooled ratio weighs each run by its pings (not the mean
    of the runs' ratios), its bootstrap interval over datasets holds it, and the per-run
    spread beside it counts the runs within the threshold."""
    runs = pd.DataFrame(
        {
            "dataset": [1, 1, 2, 2],
            "per_ping_rms_error_m": [0.2, 0.3, 0.25, 0.22],
            "per_ping_bound_m": [0.2, 0.2, 0.21, 0.2],
            "per_ping_pings": [10, 30, 20, 40],
        }
    )
    table = pooled_ratios(runs, resamples=500).set_index("estimator")
    assert list(table.index) == ["per ping"]
    row = table.loc["per ping"]
    n = runs["per_ping_pings"]
    expected = np.sqrt(
        (n * runs["per_ping_rms_error_m"] ** 2).sum() / (n * runs["per_ping_bound_m"] ** 2).sum()
    )
    assert row["pooled_ratio"] == pytest.approx(expected, rel=1e-12)
    assert row["ci_low"] <= row["pooled_ratio"] <= row["ci_high"]
    assert (row["low"], row["high"]) == pytest.approx((1.0, 1.5))
    assert (row["runs_within"], row["runs"]) == (3, 4)
