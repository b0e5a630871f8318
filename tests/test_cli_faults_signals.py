"""SIGINT and SIGTERM in the write phase of ``track``, ``decode`` and ``reproduce``.

Each run is a real ``python -m hmmtrack`` process. The write phase is made observable with
the writers' test hook (:data:`hmmtrack.io.outputs.PAUSE_VARIABLE`): once every temporary
file of the outputs is written, the process creates a marker file and waits; the test then
sends the signal. The previous complete output must be left byte for byte (or, with none
before, no output at all), with no temporary file, no staging folder and no lock, and the
process must exit 130 (SIGINT) or 143 (SIGTERM) with a one-line message, no traceback.
Timeouts are generous: the machine may be busy.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from hmmtrack.experiments.configs import scenario_settings
from hmmtrack.io.outputs import PAUSE_VARIABLE
from hmmtrack.scenarios import stationary_tag
from hmmtrack.scenarios.export import write_scenario
from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm

ROOT = Path(__file__).resolve().parents[1]
PREVIOUS = "previous complete output\n"
#: seconds a run may take to reach its write phase, or to end after the signal (busy machine)
STARTUP_TIMEOUT = 600
EXIT_TIMEOUT = 120


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("inputs")
    scenario = stationary_tag(11)
    write_scenario(scenario, root / "sim", scenario_settings(scenario))
    replace(load_white_shark_hmm(), dt=120.0).save(root / "model.json")  # the tracks' step
    return root


def commands(inputs: Path, out: Path) -> dict[str, tuple[list[str], Path]]:
    """Command -> (arguments, the output it writes) with outputs in ``out``."""
    sim = inputs / "sim"
    return {
        "track": (
            ["track", "--config", str(sim / "scenario.json"), "--detections",
             str(sim / "detections.csv"), "--receivers", str(sim / "receivers.csv"),
             "--particles", "100", "--seed", "1", "--motion", "baseline", "--end",
             "2022-06-08T17:03:00Z", "-o", str(out / "estimates.csv")],
            out / "estimates.csv",
        ),
        "decode": (
            ["decode", str(ROOT / "data" / "example_tracks.csv"), "--model",
             str(inputs / "model.json"), "-o", str(out / "states.csv")],
            out / "states.csv",
        ),
        "reproduce": (
            ["reproduce", "--quick", "--trials", "1", "--particles", "20", "--workers", "1",
             "--no-progress", "--out", str(out / "reports")],
            out / "reports",
        ),
    }  # fmt: skip


def listing(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): p.read_text(errors="replace") if p.is_file() else "folder"
        for p in sorted(folder.rglob("*"))
    }


def run_until_write_phase(argv: list[str], marker: Path) -> subprocess.Popen:
    environment = os.environ | {PAUSE_VARIABLE: str(marker), "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen(
        [sys.executable, "-m", "hmmtrack", *argv],
        env=environment,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while not marker.exists():
        if process.poll() is not None:
            raise AssertionError(f"ended before its write phase: {process.communicate()}")
        if time.monotonic() > deadline:
            process.kill()
            raise AssertionError("did not reach its write phase in time")
        time.sleep(0.05)
    return process


#: (command, signal, previous output present); reproduce (about a minute a run) twice only
RUNS = [
    *[
        (command, signum, previous)
        for command in ("track", "decode")
        for signum in (signal.SIGINT, signal.SIGTERM)
        for previous in (True, False)
    ],
    ("reproduce", signal.SIGINT, True),
    ("reproduce", signal.SIGTERM, False),
]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "signum", "previous"),
    RUNS,
    ids=[f"{c}-{signal.Signals(s).name}-{'previous' if p else 'none'}" for c, s, p in RUNS],
)
def test_a_signal_in_the_write_phase_leaves_the_previous_output_or_none(
    inputs, tmp_path, command, signum, previous
):
    out = tmp_path / "out"
    out.mkdir()
    argv, output = commands(inputs, out)[command]
    if previous:
        if command == "reproduce":
            output.mkdir()
            (output / "summary.md").write_text(PREVIOUS)
            (output / "motion_model_trials.csv").write_text(PREVIOUS)
        else:
            output.write_text(PREVIOUS)
    before = listing(out)
    marker = tmp_path / "in-write-phase"
    process = run_until_write_phase(argv, marker)
    process.send_signal(signum)
    _, err = process.communicate(timeout=EXIT_TIMEOUT)
    assert process.returncode == 128 + signum
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == (
        f"hmmtrack {command}: error: interrupted ({signal.Signals(signum).name})"
    )
    assert listing(out) == before  # the previous output, or none; nothing half-written
