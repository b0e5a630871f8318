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
from hmmtrack.scenarios.array import DriftingClock, tagged_array
from hmmtrack.sync import read_clocks

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
