"""Bad input and faults against every command: nothing lost, nothing invented, no traceback.

Each case runs ``hmmtrack`` in-process on a folder of inputs (a simulated stationary-tag
dataset, a track file, a model and malformed variants of each, plus a "previous" output of
every command) and asserts the exit code (2 bad input, 1 failure, 130 interrupted), a
one-line message naming the file or option at fault, no traceback, and that the folder is
byte for byte as it was: inputs unchanged, previous outputs kept, no new output and no
temporary file left behind. Faults that a test cannot cause for real (a full disk, no
memory, Ctrl-C at a chosen moment) are raised from inside the run by monkeypatching.
Interruption by real signals is in ``test_cli_faults_signals.py``, reader fuzzing in
``test_cli_faults_fuzz.py``.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd
import pytest

from hmmtrack.cli import main
from hmmtrack.experiments.configs import scenario_settings
from hmmtrack.io import outputs
from hmmtrack.scenarios import stationary_tag
from hmmtrack.scenarios.export import write_scenario
from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm

EXAMPLE_TRACKS = Path(__file__).resolve().parents[1] / "data" / "example_tracks.csv"
PREVIOUS = "previous complete output\n"


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> Path:
    """The inputs of every case, their malformed variants and previous outputs."""
    root = tmp_path_factory.mktemp("world")
    scenario = stationary_tag(11)
    write_scenario(scenario, root / "sim", scenario_settings(scenario))
    tracks = pd.read_csv(EXAMPLE_TRACKS)
    tracks[tracks["id"] == tracks["id"].iloc[0]].head(150).to_csv(root / "tracks.csv", index=False)
    # a model fitted at the tracks' 120 s step; tracks at 1 s and 1,200 s for decode to refuse
    replace(load_white_shark_hmm(), dt=120.0).save(root / "model.json")
    for step in (1, 1200):
        other = pd.read_csv(root / "tracks.csv")
        start = pd.Timestamp(other["time"].iloc[0])
        other["time"] = [f"{start + pd.Timedelta(seconds=step * i):%Y-%m-%dT%H:%M:%SZ}"
                         for i in range(len(other))]  # fmt: skip
        other.to_csv(root / f"tracks_{step}s.csv", index=False)
    document = json.loads((root / "model.json").read_text())
    (root / "model_misspelt.json").write_text(
        json.dumps({("trasition" if k == "transition" else k): v for k, v in document.items()})
    )
    (root / "model_aic.json").write_text(json.dumps(document | {"aic": document["aic"] + 5}))
    two = pd.read_csv(root / "sim" / "detections.csv")  # ID part 1234 in two code spaces
    pd.concat([two, two.assign(transmitter="A69-9001-1234")]).to_csv(
        root / "det_two_1234.csv", index=False
    )
    detections = pd.read_csv(root / "sim" / "detections.csv")
    epoch = pd.to_datetime(detections["time"]) - pd.Timestamp("1970-01-01", tz="UTC")
    detections.assign(time=epoch // pd.Timedelta("1ms")).to_csv(root / "det_ms.csv", index=False)
    detections.head(1).to_csv(root / "det_one.csv", index=False)
    naive = pd.to_datetime(detections["time"]).dt.strftime("%Y-%m-%dT%H:%M:%S.%f")
    detections.assign(time=naive).to_csv(root / "det_naive.csv", index=False)
    later = detections[detections["receiver"] == "boat"].head(20)  # the boat, 2 h later
    later = later.assign(time=pd.to_datetime(later["time"]) + pd.Timedelta("2h"))
    later["time"] = later["time"].dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    pd.concat([detections, later]).to_csv(root / "det_gap.csv", index=False)
    receivers = pd.read_csv(root / "sim" / "receivers.csv")  # metres as degrees, as mm
    receivers.assign(x=-118.2 + receivers["x"] * 1e-5, y=33.7 + receivers["y"] * 1e-5).to_csv(
        root / "rec_degrees.csv", index=False
    )
    receivers.assign(x=receivers["x"] * 1e6).to_csv(root / "rec_far.csv", index=False)
    (root / "folder").mkdir()
    (root / "reports").mkdir()
    (root / "reports" / "summary.md").write_text(PREVIOUS)
    for name in ("previous.csv", "previous.json", "previous.png", "plain_file", "c_residuals.csv"):
        (root / name).write_text(PREVIOUS)
    (root / "link.csv").symlink_to(root / "sim" / "detections.csv")
    bad = {
        "empty.csv": b"",
        "blank.csv": b"\n\n",
        "latin1.csv": "time,receiver,transmitter\n2022-06-08T17:00:03Z,bo\xe9t,A\n".encode(
            "latin-1"
        ),
        "ragged.csv": b"time,receiver,transmitter\n2022-06-08T17:00:03Z,a,b,c,d\n",
        "quote.csv": b'time,receiver,transmitter\n2022-06-08T17:00:03Z,"a,b\n',
        "det_header.csv": b"time,receiver,transmitter\n",
        "det_badtime.csv": b"time,receiver,transmitter\nyesterday,a,b\n",
        "rec_header.csv": b"receiver,time,x,y\n",
        "rec_text.csv": b"receiver,time,x,y\nboat,,four,1\n",
        "rec_nocols.csv": b"name,east,north\nboat,1,2\n",
        "tracks_header.csv": b"id,time,x,y\n",
        "tracks_text.csv": b"id,time,x,y\na,2024-01-01T00:00:00Z,one,2\n",
        "tracks_nox.csv": b"id,time,east,y\na,2024-01-01T00:00:00Z,1,2\n",
        "tracks_latin1.csv": "id,time,x,y\nr\xe9,2024-01-01T00:00:00Z,1,2\n".encode("latin-1"),
        "tracks_notime.csv": b"id,x,y\na,0,0\na,1,1\na,2,3\n",
        "movebank_gap.csv": b"individual-local-identifier,timestamp,location-long,location-lat\n"
        b"a,2024-01-01 00:00:00,-114.0,51.0\na,2024-01-01 00:02:00,,\n"
        b"a,2024-01-01 00:04:00,-114.001,51.001\na,2024-01-01 00:06:00,-114.002,51.0005\n",
        "truth_cols.csv": b"time,east,north\n2022-06-08T17:00:00Z,0,0\n",
        "truth_latin1.csv": "time,x,y\n2022-06-08T17:00:00Z,0\xb0,0\n".encode("latin-1"),
        "not_json.json": b"{period: 8}",
        "array.json": b"[8.179]",
        "latin1.json": '{"period": "8\xb0"}'.encode("latin-1"),
        "schema.json": b'{"schema": "something.else", "version": 1}',
        "unknown_key.json": b'{"period": 8.179, "r0": {"boat": 32}, "perod": 8}',
    }
    for name, data in bad.items():
        (root / name).write_bytes(data)
    return root


def snapshot(root: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every file under ``root`` (hidden files included)."""
    return {
        str(path.relative_to(root)): hashlib.sha256(path.read_bytes()).hexdigest()
        if path.is_file()
        else "folder"
        for path in sorted(root.rglob("*"))
    }


def assert_refused(world: Path, capsys, argv: list[str], code: int, says: tuple[str, ...]):
    """Run ``argv``; check the exit code, the message, no traceback, the folder untouched."""
    before = snapshot(world)
    try:
        exit_code = main(argv)
    except SystemExit as exit_info:  # an option refused while parsing (argparse's exit)
        exit_code = exit_info.code
    assert exit_code == code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if "error:" in line]
    assert len(lines) == 1, err
    for words in says:
        assert words in lines[0], (words, err)
    assert snapshot(world) == before  # inputs and previous outputs intact, nothing left


@dataclass(frozen=True)
class Case:
    """A command line of ``tests/data/cli_faults.txt`` (see its header for the fields)."""

    name: str
    argv: str
    code: int
    says: tuple[str, ...]


TRACK = (
    "track --config {s}/scenario.json --detections {s}/detections.csv "
    "--receivers {s}/receivers.csv --particles 100 --seed 1 --motion baseline"
)
TRACK_NO_CONFIG = (
    "track --detections {s}/detections.csv --receivers {s}/receivers.csv --period 8.179 "
    "--r0 boat=32 --r0 auv=20 --particles 100 --seed 1 --motion baseline"
)
FIT = "fit {w}/tracks.csv --starts 1"
DECODE = "decode {w}/tracks.csv --model {w}/model.json"
BASES = {
    "track": TRACK,
    "track_no_config": TRACK_NO_CONFIG,
    "track_hmm": TRACK_NO_CONFIG.replace("baseline", "hmm"),
    "fit": FIT,
    "decode": DECODE,
    "plot": "plot {w}/model.json {w}/tracks.csv",
}


def read_cases(path: Path) -> list[Case]:
    cases = []
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, code, says, argv = (field.strip() for field in line.split(" | "))
            argv = argv.replace("{w}", "{{w}}").replace("{s}", "{{s}}").format(**BASES)
            cases.append(Case(name, argv, int(code), tuple(says.split(";"))))
    return cases


CASES = read_cases(Path(__file__).parent / "data" / "cli_faults.txt")


def expand(case: Case, world: Path) -> list[str]:
    return case.argv.format(w=world, s=world / "sim").split()


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_bad_input_is_refused_and_nothing_is_written(world, capsys, case):
    assert_refused(world, capsys, expand(case, world), case.code, case.says)


def test_a_long_gap_breaks_the_range_chain_with_a_warning(world, tmp_path, capsys, caplog):
    """Detections 2 h after the rest (longer than --max-gap, 1 h) are not used and the break
    is said once; with --max-gap above the gap they are used (and the track is longer)."""
    argv = TRACK_NO_CONFIG.replace("{s}/detections.csv", "{w}/det_gap.csv")
    argv = argv.format(w=world, s=world / "sim").split()
    with caplog.at_level("WARNING"):
        assert main([*argv, "-o", str(tmp_path / "e.csv")]) == 0
    assert "Traceback" not in capsys.readouterr().err
    broken = [r.getMessage() for r in caplog.records if "range_chain_broken" in r.getMessage()]
    assert len(broken) == 1, caplog.text
    assert "receiver boat: its 20 detection(s)" in broken[0]
    assert "--max-gap" in broken[0]
    caplog.clear()
    with caplog.at_level("WARNING"):
        assert main([*argv, "--max-gap", "9000", "-o", str(tmp_path / "f.csv")]) == 0
    assert "range_chain_broken" not in caplog.text


def test_naive_times_with_tz_track_as_their_utc_twins(world, tmp_path):
    """``--tz UTC`` on detections written without an offset gives the estimates of the same
    detections written with ``Z``."""
    base = TRACK.format(w=world, s=world / "sim").split()
    assert main([*base, "-o", str(tmp_path / "utc.csv")]) == 0
    naive = [str(world / "det_naive.csv") if a.endswith("detections.csv") else a for a in base]
    assert main([*naive, "--tz", "UTC", "-o", str(tmp_path / "naive.csv")]) == 0
    assert (tmp_path / "naive.csv").read_text() == (tmp_path / "utc.csv").read_text()


def test_a_dead_dask_scheduler_is_one_line_and_exit_1(world, capsys):
    """Nothing listens at the address: a one-line failure after --dask-timeout, no hang."""
    pytest.importorskip("distributed")
    address = "tcp://127.0.0.1:1"
    argv = f"reproduce --quick --out {world}/r --dask-scheduler {address} --dask-timeout 2"
    assert_refused(world, capsys, argv.split(), 1, ("--dask-scheduler", address, "2 s"))


def test_a_folder_output_may_hold_its_own_previous_files(world, tmp_path, capsys):
    """``simulate -o`` into the folder of an earlier simulation replaces its files (the
    one case above that is not refused): the dataset is rewritten, nothing else."""
    folder = tmp_path / "sim"
    shutil.copytree(world / "sim", folder)
    (folder / "notes.txt").write_text("mine\n")
    assert main(["simulate", "stationary-tag", "--seed", "11", "-o", str(folder)]) == 0
    assert snapshot(folder) == snapshot(world / "sim") | {
        "notes.txt": snapshot(folder)["notes.txt"]
    }
    assert (folder / "notes.txt").read_text() == "mine\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no stage, no lock


def test_argparse_errors_exit_2_without_traceback(world, capsys):
    for argv in (
        ["track"],
        ["fit", "x.csv", "--states", "two", "-o", "m.json"],
        ["study", "stationary", "--seeds", "0"],
        ["track", "--particles", "1e9", "--detections", "d", "--receivers", "r", "-o", "e"],
    ):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 2
        assert "Traceback" not in capsys.readouterr().err


# --- faults raised inside a run: disk full, permission, memory, Ctrl-C, bugs ---


def _failing(exception: BaseException):
    def fail(*args, **kwargs):
        raise exception

    return fail


FAULTS = [
    ("disk-full", OSError(errno.ENOSPC, "No space left on device", "e.csv"), 1, "No space left"),
    ("permission", PermissionError(errno.EACCES, "Permission denied", "e.csv"), 1, "Permission"),
    ("memory", MemoryError(), 1, "out of memory"),
    ("interrupt", KeyboardInterrupt(), 130, "interrupted"),
]


#: commands whose main output and figures are one set
WITH_FIGURES = {
    "track": TRACK + " -o {w}/previous.csv --plot {w}/previous.png",
    "fit": FIT + " -o {w}/previous.json --plot {w}/figs",
}


@pytest.mark.parametrize("command", sorted(WITH_FIGURES))
@pytest.mark.parametrize(("name", "exception", "code", "says"), FAULTS, ids=[f[0] for f in FAULTS])
def test_fault_while_drawing_keeps_the_previous_output(
    world, capsys, monkeypatch, command, name, exception, code, says
):
    """The output (estimates, model) and its figures are one set: a fault writing a figure
    leaves neither."""
    import matplotlib.figure

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", _failing(exception))
    argv = expand(Case("", WITH_FIGURES[command], 0, ()), world)
    assert_refused(world, capsys, argv, code, (says,))


@pytest.mark.parametrize(("name", "exception", "code", "says"), FAULTS, ids=[f[0] for f in FAULTS])
def test_fit_fault_while_saving_keeps_the_previous_model(
    world, capsys, monkeypatch, name, exception, code, says
):
    from hmmtrack.hmm import MovementHMM

    monkeypatch.setattr(MovementHMM, "save", _failing(exception))
    argv = expand(Case("", FIT + " -o {w}/previous.json", 0, ()), world)
    assert_refused(world, capsys, argv, code, (says,))


@pytest.mark.parametrize(("name", "exception", "code", "says"), FAULTS, ids=[f[0] for f in FAULTS])
def test_decode_fault_while_writing_keeps_the_previous_output(
    world, capsys, monkeypatch, name, exception, code, says
):
    monkeypatch.setattr(pd.DataFrame, "to_csv", _failing(exception))
    argv = expand(Case("", DECODE + " -o {w}/previous.csv", 0, ()), world)
    assert_refused(world, capsys, argv, code, (says,))


@pytest.mark.parametrize(("name", "exception", "code", "says"), FAULTS, ids=[f[0] for f in FAULTS])
def test_simulate_fault_while_writing_keeps_the_previous_folder(
    world, capsys, monkeypatch, name, exception, code, says
):
    monkeypatch.setattr("hmmtrack.cli.simulate.write_scenario", _failing(exception))
    argv = expand(Case("", "simulate stationary-tag --seed 2 -o {s}", 0, ()), world)
    assert_refused(world, capsys, argv, code, (says,))


REPRODUCE_FAULTS = [
    ("write_summary", *FAULTS[0]),  # at the end, with the run's tables and figures staged
    ("compare_motion_models", *FAULTS[2]),
    ("compare_motion_models", *FAULTS[3]),
]


@pytest.mark.parametrize(
    ("where", "name", "exception", "code", "says"),
    REPRODUCE_FAULTS,
    ids=[f"{f[0]}-{f[1]}" for f in REPRODUCE_FAULTS],
)
def test_reproduce_fault_keeps_the_previous_folder(
    world, capsys, monkeypatch, where, name, exception, code, says
):
    """A fault in the run leaves the previous reports as they were: no trial table of the
    new run beside the old summary, no staging folder, no lock."""
    monkeypatch.setattr(f"hmmtrack.report.pipeline.{where}", _failing(exception))
    argv = expand(Case("", "reproduce --quick --trials 1 --particles 20 --workers 1 "
                  "--no-progress --out {w}/reports", 0, ()), world)  # fmt: skip
    assert_refused(world, capsys, argv, code, (says,))


def test_a_bug_still_shows_its_traceback(world, capsys, monkeypatch):
    """Only expected failures become one-line messages; a programming error is reported."""
    monkeypatch.setattr("hmmtrack.cli.fit.read_prepared", _failing(TypeError("a bug")))
    with pytest.raises(TypeError, match="a bug"):
        main(expand(Case("", FIT + " -o {w}/m.json", 0, ()), world))


def test_debug_prints_the_traceback(world, capsys):
    argv = expand(Case("", "--debug " + FIT + " -o {w}/tracks.csv", 0, ()), world)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err
    assert err.strip().splitlines()[-1].startswith("hmmtrack fit: error: -o")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder_is_refused(world, tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        argv = expand(Case("", FIT + f" -o {locked}/m.json", 0, ()), world)
        assert_refused(world, capsys, argv, 1, ("not writable",))
    finally:
        locked.chmod(0o755)


# --- concurrent runs into one folder ---


def test_a_live_lock_refuses_a_concurrent_run(world, capsys):
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    lock = world / ".reports.lock"
    try:
        lock.write_text(f"{holder.pid}\n")
        argv = expand(Case("", "reproduce --quick --out {w}/reports", 0, ()), world)
        assert_refused(world, capsys, argv, 1, ("another hmmtrack run", str(holder.pid)))
    finally:
        holder.kill()
        holder.wait(timeout=60)
        lock.unlink()


def test_a_stale_lock_is_taken_over(world, tmp_path, capsys):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait(timeout=60)
    (tmp_path / ".sim.lock").write_text(f"{dead.pid}\n")
    assert main(["simulate", "swimmer", "--seed", "1", "-o", str(tmp_path / "sim")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sim"]


# --- the writers themselves ---


def test_atomic_files_commit_a_whole_set_or_nothing(tmp_path):
    first, second = tmp_path / "a.csv", tmp_path / "b.png"
    first.write_text("old\n")
    with pytest.raises(RuntimeError), outputs.atomic_files(first, second) as (a, b):
        a.write_text("new\n")
        raise RuntimeError("fails before b is written")
    assert first.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv"]
    with outputs.atomic_files(first, second) as (a, b):
        a.write_text("new\n")
        b.write_bytes(b"png")
        assert first.read_text() == "old\n"  # nothing in place before the block ends
    assert (first.read_text(), second.read_bytes()) == ("new\n", b"png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.png"]
    mask = os.umask(0)
    os.umask(mask)
    assert second.stat().st_mode & 0o777 == 0o666 & ~mask  # not mkstemp's private 0o600


def test_staged_folder_replaces_its_set_and_keeps_other_files(tmp_path):
    folder = tmp_path / "reports"
    with outputs.staged_folder(folder, last="summary.md") as stage:
        (stage / "table.csv").write_text("1\n")
        (stage / "summary.md").write_text("first\n")
        assert not folder.exists()
    (folder / "other_study.md").write_text("kept\n")
    with pytest.raises(KeyboardInterrupt), outputs.staged_folder(folder, "summary.md") as stage:
        (stage / "table.csv").write_text("2\n")
        raise KeyboardInterrupt
    assert {p.name: p.read_text() for p in folder.iterdir()} == {
        "table.csv": "1\n",
        "summary.md": "first\n",
        "other_study.md": "kept\n",
    }
    with outputs.staged_folder(folder, last="summary.md") as stage:
        (stage / "table.csv").write_text("2\n")
        (stage / "summary.md").write_text("second\n")
    assert {p.name: p.read_text() for p in folder.iterdir()} == {
        "table.csv": "2\n",
        "summary.md": "second\n",
        "other_study.md": "kept\n",
    }
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_check_paths_compares_files_not_spellings(tmp_path):
    data = tmp_path / "data.csv"
    data.write_text("x\n")
    (tmp_path / "alias.csv").symlink_to(data)
    outputs.check_paths({"in": data}, outputs={"-o": tmp_path / "out.csv"})
    for spelling in (tmp_path / "alias.csv", tmp_path / "." / "data.csv"):
        with pytest.raises(ValueError, match="is the input"):
            outputs.check_paths({"in": data}, outputs={"-o": spelling})
    os.link(data, tmp_path / "hard.csv")
    with pytest.raises(ValueError, match="is the input"):
        outputs.check_paths({"in": data}, outputs={"-o": tmp_path / "hard.csv"})
    with pytest.raises(ValueError, match="holds the input"):
        outputs.check_paths({"in": data}, folders={"--out": tmp_path})
