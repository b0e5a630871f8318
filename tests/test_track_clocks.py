"""Tracking on unsynchronised receivers with a clock file (the configuration's ``clocks``,
``hmmtrack track --clocks``): the clock file moves every receiver's logged times to the
common time base before the measurement sees them, for both measurements, from the library,
a configuration file and the command line alike; and the clear errors of a clock file that
does not fit the detections, and of its path."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pandas as pd
import pytest

from hmmtrack import io
from hmmtrack.cli import main
from hmmtrack.experiments.configs import scenario_settings
from hmmtrack.scenarios import stationary_tag
from hmmtrack.scenarios.export import write_scenario
from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.sync import ReceiverClocks, apply_clocks, read_clocks, write_clocks
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import TrackingConfig, read_settings

#: each receiver's clock error: offset (s) and drift (ppm) by its place in the receivers file
OFFSETS = (0.0, 0.8, -1.3, 2.1, -0.4, 1.7)
DRIFTS = (0.0, 30.0, -45.0, 20.0, -25.0, 50.0)


def drifting_clocks(receivers, first: float, last: float) -> ReceiverClocks:
    """Clocks of ``receivers`` (names) with the errors :data:`OFFSETS`, :data:`DRIFTS`, one
    segment from ``first`` to ``last`` (s), the first receiver the time keeper."""
    n = len(receivers)
    coefficients = np.zeros((n, 1, 3))
    coefficients[:, 0, 0] = [OFFSETS[i % len(OFFSETS)] for i in range(n)]
    coefficients[:, 0, 1] = [DRIFTS[i % len(DRIFTS)] for i in range(n)]
    return ReceiverClocks(
        time_keeper=receivers[0],
        receivers=tuple(receivers),
        segment_starts=np.array([first]),
        segment_ends=np.array([last]),
        coefficients=coefficients,
        sound_speed=np.array([1460.0]),
        sound_speed_method="fixed",
        positions=np.zeros((n, 3)),
        file_positions=np.zeros((n, 3)),
        fixed=np.ones(n, dtype=bool),
        sync_tags=(None,) * n,
        residual_sd_ms=np.full(n, 0.1),
        detections=np.full(n, 100),
        rejected=np.zeros(n, dtype=int),
    )


def logged(detections: pd.DataFrame, clocks: ReceiverClocks) -> pd.DataFrame:
    """``detections`` (common times) as the receivers' drifting clocks logged them: the
    receiver time ``t`` with ``clocks.to_common(receiver, t)`` the common time."""
    common = detections["time"].to_numpy(dtype=float)
    names = detections["receiver"].to_numpy()
    times = common
    for _ in range(4):  # fixed point: the correction changes by ppm of its own size
        correction = [clocks.correction(name, t) for name, t in zip(names, times, strict=True)]
        times = common + np.array(correction, dtype=float)
    return detections.assign(time=times)


@dataclasses.dataclass(frozen=True)
class Case:
    """A scenario's files with its detections logged on drifting clocks, and the clock file."""

    config: TrackingConfig
    paths: dict
    clocks: ReceiverClocks
    clock_file: object
    common: pd.DataFrame


def make_case(scenario, directory, **settings) -> Case:
    paths = write_scenario(scenario, directory, scenario_settings(scenario))
    common = io.read_detections(paths["detections"])
    names = list(io.read_receivers(paths["receivers"])["receiver"].unique())
    times = common["time"].to_numpy()
    clocks = drifting_clocks(names, float(times.min()) - 5.0, float(times.max()) + 5.0)
    drifted = logged(common, clocks)
    drifted.assign(time=io.format_times(drifted["time"].to_numpy())).to_csv(
        paths["detections"], index=False
    )
    clock_file = directory / "clocks.json"
    write_clocks(clocks, clock_file)
    config = TrackingConfig.from_json(paths["metadata"]).override(**settings)
    return Case(config, paths, clocks, clock_file, common)


@pytest.fixture(scope="module")
def range_rate(tmp_path_factory):
    return make_case(stationary_tag(11), tmp_path_factory.mktemp("range_rate"), n_particles=500)


@pytest.fixture(scope="module")
def arrival_time(tmp_path_factory):
    case = moored_array(5, duration=300.0)
    scenario = dataclasses.replace(case.scenario, detections=case.corrected_detections())
    return make_case(
        scenario,
        tmp_path_factory.mktemp("arrival"),
        measurement="arrival-time",
        motion="velocity",
        n_particles=500,
        start=scenario.start,
        end=scenario.end,
    )


def run(case: Case, config: TrackingConfig, detections=None) -> tracking.TrackingResult:
    if detections is None:
        detections = io.read_detections(case.paths["detections"])
    return tracking.track(detections, io.read_receivers(case.paths["receivers"]), config, seed=7)


@pytest.mark.parametrize("name", ["range_rate", "arrival_time"])
def test_clocks_map_the_logged_times_before_the_measurement_sees_them(name, request):
    case = request.getfixturevalue(name)
    detections = io.read_detections(case.paths["detections"])
    with_clocks = run(case, case.config.override(clocks=str(case.clock_file)))
    synced = run(case, case.config, apply_clocks(detections, read_clocks(case.clock_file)))
    pd.testing.assert_frame_equal(with_clocks.estimates, synced.estimates, check_exact=True)
    pd.testing.assert_frame_equal(with_clocks.observations, synced.observations)
    # the observations are at the common times the scenario heard (to the CSV's ms), which
    # the logged times are seconds off; tracked from the logged times the estimates differ
    observed = with_clocks.observations.sort_values(["receiver", "time"])
    truth = case.common.sort_values(["receiver", "time"])
    np.testing.assert_allclose(observed["time"], truth["time"], rtol=0, atol=1.5e-3)
    raw = detections.sort_values(["receiver", "time"])
    assert np.abs(raw["time"].to_numpy() - truth["time"].to_numpy()).max() > 0.5
    unsynced = run(case, case.config)
    assert np.abs(unsynced.estimates["x"] - with_clocks.estimates["x"]).max() > 0.1


@pytest.mark.parametrize("name", ["range_rate", "arrival_time"])
def test_clocks_option_and_config_key_run_what_the_library_runs(name, request, tmp_path, capsys):
    case = request.getfixturevalue(name)
    expected = run(case, case.config.override(clocks=str(case.clock_file))).estimates
    # the run's settings in a file, given --clocks; and in a file naming the clock file
    # relative to itself
    settings = case.config.to_dict()
    (tmp_path / "plain.json").write_text(json.dumps(settings))
    folder = tmp_path / "settings"
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps(settings | {"clocks": "../clocks.json"}))
    (tmp_path / "clocks.json").write_bytes(case.clock_file.read_bytes())
    assert read_settings(folder / "config.json")["clocks"] == str(folder / "../clocks.json")
    args = ["track", "--detections", str(case.paths["detections"]), "--receivers"]
    args += [str(case.paths["receivers"]), "--seed", "7"]
    by_option, by_file = tmp_path / "option.csv", tmp_path / "file.csv"
    assert main([*args, "--config", str(tmp_path / "plain.json"), "-o", str(by_option),
                 "--clocks", str(case.clock_file)]) == 0  # fmt: skip
    assert main([*args, "--config", str(folder / "config.json"), "-o", str(by_file)]) == 0
    capsys.readouterr()
    for written in (by_option, by_file):
        table = pd.read_csv(written)
        np.testing.assert_array_equal(
            io.parse_times(table, "time", tz=None), expected["time"].to_numpy()
        )
        np.testing.assert_allclose(table[["x", "y"]], expected[["x", "y"]], rtol=1e-9)


def test_a_receiver_without_a_clock_is_named(range_rate, tmp_path):
    clocks = range_rate.clocks
    keep = list(clocks.receivers[:-1])
    fewer = dataclasses.replace(
        clocks,
        receivers=tuple(keep),
        coefficients=clocks.coefficients[:-1],
        positions=clocks.positions[:-1],
        file_positions=clocks.file_positions[:-1],
        fixed=clocks.fixed[:-1],
        sync_tags=clocks.sync_tags[:-1],
        residual_sd_ms=clocks.residual_sd_ms[:-1],
        detections=clocks.detections[:-1],
        rejected=clocks.rejected[:-1],
    )
    path = tmp_path / "fewer.json"
    write_clocks(fewer, path)
    with pytest.raises(
        ValueError, match=rf"fewer\.json: no clock for receiver\(s\) \['{clocks.receivers[-1]}'\]"
    ):
        run(range_rate, range_rate.config.override(clocks=str(path)))


@pytest.mark.parametrize(
    ("shift", "message"),
    [
        ((30.0, 0.0), r"(\d+) up to 25\.0 s before its start of the (\d+) detections"),
        ((0.0, -12.0), r"(\d+) up to 7\.0 s after its end of the (\d+) detections"),
    ],
)
def test_detections_outside_the_clock_files_span_say_by_how_much(
    arrival_time, tmp_path, shift, message
):
    """The fixture's span is the detections' widened by 5 s; the start moved 30 s later
    leaves detections up to 25 s before it, the end 12 s earlier up to 7 s after it."""
    clocks = arrival_time.clocks
    narrower = dataclasses.replace(
        clocks,
        segment_starts=clocks.segment_starts + shift[0],
        segment_ends=clocks.segment_ends + shift[1],
    )
    path = tmp_path / "narrow.json"
    write_clocks(narrower, path)
    detections = io.read_detections(arrival_time.paths["detections"])
    with pytest.raises(ValueError, match="outside the clock file's time span") as raised:
        run(arrival_time, arrival_time.config.override(clocks=str(path)), detections)
    found = re.search(message, str(raised.value))
    assert found is not None, str(raised.value)
    synced = apply_clocks(detections, narrower)["time"]
    first, last = narrower.segment_starts[0], narrower.segment_ends[-1]
    outside = (synced < first) if shift[0] else (synced > last)
    assert int(found.group(1)) == int(outside.sum()) > 0
    assert int(found.group(2)) == len(detections)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda doc: doc | {"version": 2}, r"field 'version' is 2; this hmmtrack reads version 1"),
        (lambda doc: doc | {"schema": "other"}, r"field 'schema' is 'other'"),
        (lambda doc: doc | {"extra": 1}, r"unknown key\(s\) \['extra'\]"),
    ],
)
def test_an_unknown_clock_file_is_refused_naming_it(range_rate, tmp_path, capsys, edit, message):
    document = edit(json.loads(range_rate.clock_file.read_text()))
    path = tmp_path / "other.json"
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match=message):
        run(range_rate, range_rate.config.override(clocks=str(path)))
    args = ["track", "--config", str(range_rate.paths["metadata"]), "--detections"]
    args += [str(range_rate.paths["detections"]), "--receivers", str(range_rate.paths["receivers"])]
    output = tmp_path / "est.csv"
    assert main([*args, "--clocks", str(path), "-o", str(output), "--seed", "1"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "Traceback" not in err
    assert not output.exists()


def test_clocks_path_checks(range_rate, tmp_path, capsys):
    args = ["track", "--config", str(range_rate.paths["metadata"]), "--detections"]
    args += [str(range_rate.paths["detections"]), "--receivers", str(range_rate.paths["receivers"])]
    missing = tmp_path / "none.json"
    assert main([*args, "--clocks", str(missing), "-o", str(tmp_path / "e.csv")]) == 2
    assert f"--clocks {missing}: no such file" in capsys.readouterr().err
    before = range_rate.clock_file.read_bytes()
    clock_file = str(range_rate.clock_file)
    assert main([*args, "--clocks", clock_file, "-o", clock_file, "--seed", "1"]) == 2
    assert "is the input --clocks" in capsys.readouterr().err
    assert range_rate.clock_file.read_bytes() == before
    assert not (tmp_path / "e.csv").exists()


def test_clocks_describe_data_so_a_preset_may_not_hold_them():
    field = {f.name: f for f in dataclasses.fields(TrackingConfig)}["clocks"]
    assert field.metadata["data"]
    with pytest.raises(ValueError, match="clocks must be a non-empty string"):
        TrackingConfig.from_keys(period=8.0, r0={"a": 1.0}, clocks="")
