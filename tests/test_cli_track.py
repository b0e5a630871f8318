"""Tests of ``hmmtrack track`` and its configuration (hmmtrack.cli.track, hmmtrack.tracking.config).

End to end on the files ``hmmtrack simulate`` writes for the stationary-tag scenario: the
estimate CSV's columns, one row per second with ISO 8601 UTC times, the printed metrics,
the lon/lat round trip and the plot; on a moored array and on two AUVs with the
``two-moving-receivers`` preset for the arrival-time measurement.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pyproj import Transformer

from hmmtrack import io
from hmmtrack.analysis import metrics
from hmmtrack.cli import build_parser, main
from hmmtrack.cli.track import build_config, register, settings_options
from hmmtrack.experiments.configs import scenario_settings
from hmmtrack.scenarios import stationary_tag
from hmmtrack.scenarios.export import write_scenario
from hmmtrack.scenarios.realistic import moored_array, realistic_shark_pursuit
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import (
    SECTIONS,
    TrackingConfig,
    merge_settings,
    nest,
    read_settings,
    section_classes,
)
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.measurement.range_rate import search_bounds
from hmmtrack.tracking.mixture import ESTIMATE_MODE_COLUMNS
from hmmtrack.tracking.motion import VelocityMotion, bundled_model_path, motion_model

ESTIMATE_COLUMNS = ["time", "x", "y", "var_x", "var_y", "cov_xy", "sqrt_lambda1"]
#: a UTM zone 11N origin off Long Beach, CA (m): scenario metres are shifted by it
ORIGIN = (390_000.0, 3_730_000.0)
UTM_11N = "EPSG:32611"


@pytest.fixture(scope="module")
def scenario_files(tmp_path_factory):
    directory = tmp_path_factory.mktemp("stationary")
    scenario = stationary_tag(11)
    return scenario, write_scenario(scenario, directory, scenario_settings(scenario))


def track_args(paths, output, *extra):
    return [
        "track",
        "--config",
        str(paths["metadata"]),
        "--detections",
        str(paths["detections"]),
        "--receivers",
        str(paths["receivers"]),
        "-o",
        str(output),
        "--particles",
        "1000",
        "--seed",
        "3",
        *extra,
    ]


def arrival_args(scenario, paths, particles, seed):
    """``hmmtrack track`` arguments for the arrival-time fixture: its files, period and
    time window, velocity motion, ``particles`` and ``seed`` (add ``-o`` and options)."""
    window = io.format_times(np.array([scenario.start, scenario.end]))
    return [
        "track", "--detections", str(paths["detections"]), "--receivers",
        str(paths["receivers"]), "--period", str(scenario.period), "--measurement",
        "arrival-time", "--motion", "velocity", "--particles", str(particles), "--seed",
        str(seed), "--start", window[0], "--end", window[1],
    ]  # fmt: skip


def library_estimates(paths, motion_model=None, **settings):
    """What ``tracking.track`` gives on the fixture files with the metadata file's settings,
    1000 particles and ``settings``, seed 3 (the CLI runs are compared with it)."""
    config = TrackingConfig.from_json(paths["metadata"]).override(n_particles=1000, **settings)
    detections = io.read_detections(paths["detections"])
    return tracking.track(
        detections, io.read_receivers(paths["receivers"]), config, motion_model, seed=3
    ).estimates


def assert_written_is(written, expected, other):
    """The CSV ``written`` holds ``expected``'s positions, and the CSV ``other`` (the run
    without the option) differs from it."""
    written = pd.read_csv(written)
    np.testing.assert_allclose(written[["x", "y"]], expected[["x", "y"]], rtol=1e-9)
    assert np.abs(pd.read_csv(other)["x"] - written["x"]).max() > 0.1


def printed_number(text: str, label: str) -> float:
    line = next(line for line in text.splitlines() if line.startswith(label))
    return float(line.split(":")[-1].split()[0])


def test_track_writes_one_row_per_second_and_prints_the_metrics(scenario_files, tmp_path, capsys):
    scenario, paths = scenario_files
    output = tmp_path / "estimate.csv"
    args = track_args(paths, output, "--motion", "velocity", "--truth", str(paths["truth"]))
    assert main(args) == 0
    printed = capsys.readouterr().out
    table = pd.read_csv(output)
    assert list(table.columns[:7]) == ESTIMATE_COLUMNS
    assert len(table) == int(scenario.end - scenario.start) + 1
    assert table["time"].str.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z").all()
    seconds = io.parse_times(table, "time", tz=None)
    np.testing.assert_allclose(np.diff(seconds), 1.0)
    assert seconds[0] == scenario.start
    assert np.isfinite(table[ESTIMATE_COLUMNS[1:]].to_numpy()).all()
    # the printed metrics are those of the written estimates against the truth
    estimates = table.assign(time=seconds)
    scores = metrics.tracking_metrics(estimates, scenario.truth)
    assert printed_number(printed, "time to convergence") == round(scores.time_to_convergence)
    assert printed_number(printed, "mean error after convergence") == pytest.approx(
        scores.mean_error_after_convergence, abs=0.006
    )
    assert printed_number(printed, "root-mean-square error") == pytest.approx(
        scores.rmse_after_convergence, abs=0.006
    )
    assert scores.converged and scores.mean_error_after_convergence < 10.0


def test_track_writes_the_modes_and_acquires_and_monitors(scenario_files, tmp_path):
    """``--modes`` adds the second mode and ``converged`` to the written estimates;
    ``--acquisition --monitor`` run through the command line."""
    _, paths = scenario_files
    output = tmp_path / "modes.csv"
    extra = ("--motion", "velocity", "--modes", "--acquisition", "--monitor")
    assert main(track_args(paths, output, *extra)) == 0
    table = pd.read_csv(output)
    assert list(table.columns[-5:]) == list(ESTIMATE_MODE_COLUMNS)
    converged = table["converged"].to_numpy(dtype=bool)
    assert converged[-1] and (table.loc[converged, "sqrt_lambda1"] < 10.0).all()


def to_lonlat(table: pd.DataFrame) -> pd.DataFrame:
    """Scenario metres, shifted to the UTM origin, as lon/lat columns."""
    transform = Transformer.from_crs(UTM_11N, "EPSG:4326", always_xy=True)
    lon, lat = transform.transform(table["x"] + ORIGIN[0], table["y"] + ORIGIN[1])
    return table.drop(columns=["x", "y"]).assign(lon=lon, lat=lat)


def test_lonlat_inputs_give_lonlat_outputs(scenario_files, tmp_path, capsys):
    scenario, paths = scenario_files
    receivers = to_lonlat(pd.read_csv(paths["receivers"]))
    truth = to_lonlat(pd.read_csv(paths["truth"]))
    lonlat = dict(paths)
    settings = json.loads(paths["metadata"].read_text())
    assert settings.pop("bounds")  # in the scenario's metres: derive them from the receivers
    lonlat["metadata"] = tmp_path / "scenario_lonlat.json"
    lonlat["metadata"].write_text(json.dumps(settings))
    lonlat["receivers"] = tmp_path / "receivers_lonlat.csv"
    receivers.to_csv(lonlat["receivers"], index=False, float_format="%.9f")
    truth_path = tmp_path / "truth_lonlat.csv"
    truth.to_csv(truth_path, index=False, float_format="%.9f")
    output = tmp_path / "estimate.csv"
    args = track_args(lonlat, output, "--motion", "velocity", "--truth", str(truth_path))
    assert main(args) == 0
    printed = capsys.readouterr().out
    table = pd.read_csv(output)
    assert list(table.columns[:5]) == ["time", "x", "y", "lon", "lat"]
    # x, y are in the receivers' projected frame (UTM 11N, chosen from the data) and lon/lat
    # are those same points
    x, y = Transformer.from_crs("EPSG:4326", UTM_11N, always_xy=True).transform(
        table["lon"], table["lat"]
    )
    np.testing.assert_allclose(x, table["x"], atol=1e-3)
    np.testing.assert_allclose(y, table["y"], atol=1e-3)
    # and they land where the tag is: the origin of the shifted scenario
    after = table.iloc[len(table) // 2 :]
    assert np.hypot(after["x"] - ORIGIN[0], after["y"] - ORIGIN[1]).mean() < 10.0
    assert printed_number(printed, "mean error after convergence") < 10.0


def test_plot_is_written(scenario_files, tmp_path):
    _, paths = scenario_files
    picture = tmp_path / "run.png"
    args = track_args(
        paths, tmp_path / "e.csv", "--motion", "velocity", "--truth", str(paths["truth"])
    )
    assert main([*args, "--plot", str(picture)]) == 0
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_hmm_without_model_uses_the_bundled_model(scenario_files, tmp_path):
    _, paths = scenario_files
    output = tmp_path / "hmm.csv"
    assert main(track_args(paths, output, "--motion", "hmm")) == 0
    assert len(pd.read_csv(output)) > 1000


def test_options_without_a_config_file(scenario_files, tmp_path, capsys, caplog):
    scenario, paths = scenario_files
    output = tmp_path / "plain.csv"
    r0 = [f"--r0={name}={metres}" for name, metres in scenario.r0.items()]
    args = [
        "track",
        "--detections",
        str(paths["detections"]),
        "--receivers",
        str(paths["receivers"]),
        "--period",
        str(scenario.period),
        *r0,
        "--motion",
        "baseline",
        "--particles",
        "300",
        "-o",
        str(output),
    ]
    assert main(args) == 0
    assert "seed: " in capsys.readouterr().err  # an unseeded run says how to repeat it
    table = pd.read_csv(output)
    # without start/end the run spans the detections, in whole seconds
    first, last = scenario.detections["time"].min(), scenario.detections["time"].max()
    assert len(table) == int(np.ceil(last) - np.floor(first)) + 1
    # a window in ISO 8601, and a fixed tag's truth as one row without time
    fixed = tmp_path / "tag.csv"
    fixed.write_text("x,y\n0.0,0.0\n")
    window = ["--start", "2022-06-08T17:01:00Z", "--end", "2022-06-08T17:06:00.000Z"]
    caplog.clear()
    assert main([*args, *window, "--seed", "2", "--truth", str(fixed)]) == 0
    printed = capsys.readouterr()
    assert "time to convergence" in printed.out
    # detections outside the window: one log line with the ISO time, not a Python warning
    assert caplog.text.count("observations_outside_window") == 1
    assert "filter event at 2022-06-08T17:01:00.000Z: observations_outside_window" in caplog.text
    table = pd.read_csv(output)
    assert table["time"].iloc[[0, -1]].tolist() == [
        "2022-06-08T17:01:00.000Z",
        "2022-06-08T17:06:00.000Z",
    ]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (["--model", "x.json", "--motion", "baseline"], "--motion hmm only"),
        (
            ["--measurement", "arrival-time", "--r0", "a=1"],
            "--measurement range-rate or range-rate-gps only",
        ),
    ],
)
def test_bad_options_are_clear_errors(scenario_files, tmp_path, capsys, change, message):
    _, paths = scenario_files
    assert main([*track_args(paths, tmp_path / "e.csv"), *change]) == 2
    assert message in capsys.readouterr().err


def test_missing_settings_and_bad_config_files(scenario_files, tmp_path, capsys):
    _, paths = scenario_files
    base = ["track", "--detections", str(paths["detections"]), "--receivers"]
    base += [str(paths["receivers"]), "-o", str(tmp_path / "e.csv")]
    # (a period alone is a fixed-period tag's whose pings choose its measurement)
    assert main([*base, "--period", "8.179", "--measurement", "range-rate"]) == 2
    assert "give --r0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*base, "--period", "8.179", "--r0", "auv:20"])
    bad = tmp_path / "bad.json"
    bad.write_text(
        json.dumps({"measurement": {"period": 8.179, "r0": {"auv": 20}}, "particles": 10})
    )
    assert main([*base, "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "unknown key(s) ['particles']" in err


def test_per_ping_follows_the_measurement_the_pings_choose(
    scenario_files, arrival_files, tmp_path, capsys
):
    """``--period`` alone lets the pings choose the measurement; ``--per-ping`` is then
    checked against the chosen one: written where the moorings' pings are grouped, refused
    (saying the pings chose) where two receivers leave the arrival-time measurement."""
    scenario, paths = arrival_files
    window = io.format_times(np.array([scenario.start, scenario.start + 120.0]))
    pings = tmp_path / "pings.csv"
    args = ["track", "--detections", str(paths["detections"]), "--receivers"]
    args += [str(paths["receivers"]), "--period", str(scenario.period), "--particles", "300"]
    args += ["--seed", "1", "--start", window[0], "--end", window[1]]
    assert main([*args, "-o", str(tmp_path / "e.csv"), "--per-ping", str(pings)]) == 0
    assert "measurement: ping-sequence" in capsys.readouterr().err
    assert len(pd.read_csv(pings)) > 5
    _, two = scenario_files
    args = ["track", "--detections", str(two["detections"]), "--receivers"]
    args += [str(two["receivers"]), "--period", "8.179", "-o", str(tmp_path / "f.csv")]
    assert main([*args, "--per-ping", str(tmp_path / "p2.csv")]) == 2
    err = capsys.readouterr().err
    assert "this run's is arrival-time, chosen by the pings" in err
    assert not (tmp_path / "f.csv").exists() and not (tmp_path / "p2.csv").exists()


@pytest.fixture(scope="module")
def arrival_files(tmp_path_factory):
    """A moored array heard with clock-corrected times (no initial range), as CSV files."""
    case = moored_array(5, duration=300.0)
    scenario = dataclasses.replace(case.scenario, detections=case.corrected_detections())
    return scenario, write_scenario(
        scenario, tmp_path_factory.mktemp("arrival"), scenario_settings(scenario)
    )


def arrival_time_run(paths, scenario, motion, n_particles, seed, smoothing_lag=None, **settings):
    """The library's arrival-time run (:func:`hmmtrack.tracking.pipeline.track`) on the
    files ``paths`` with these settings, over the scenario's span; ``motion`` a name or a
    motion model."""
    config = TrackingConfig.from_keys(
        period=scenario.period,
        measurement="arrival-time",
        n_particles=n_particles,
        start=scenario.start,
        end=scenario.end,
        smoothing_lag=smoothing_lag,
        motion=motion if isinstance(motion, str) else None,
        **settings,
    )
    return tracking.track(
        io.read_detections(paths["detections"]),
        io.read_receivers(paths["receivers"]),
        config,
        None if isinstance(motion, str) else motion,
        seed=seed,
    )


def test_arrival_time_measurement_without_r0_runs_the_clock_aware_tracker(
    arrival_files, tmp_path, capsys
):
    """``--measurement arrival-time`` needs no --r0 and writes what
    :func:`hmmtrack.tracking.pipeline.track` estimates from the same files;
    ``--smooth`` writes the fixed-lag smoothed track instead."""
    scenario, paths = arrival_files
    common = arrival_args(scenario, paths, 500, 4)
    filtered, smoothed = tmp_path / "filtered.csv", tmp_path / "smoothed.csv"
    assert main([*common, "-o", str(filtered)]) == 0
    truth = ["--truth", str(paths["truth"])]
    assert main([*common, "--smooth", "20", "-o", str(smoothed), *truth]) == 0
    printed = capsys.readouterr().out
    assert "mean error after convergence" in printed
    direct = arrival_time_run(paths, scenario, "velocity", 500, 4, smoothing_lag=20)
    for path, expected in ((filtered, direct.estimates), (smoothed, direct.smoothed)):
        table = pd.read_csv(path)
        assert len(table) == int(scenario.end - scenario.start) + 1
        np.testing.assert_allclose(table[["x", "y"]], expected[["x", "y"]], rtol=1e-9)
    assert "n_ancestors" in pd.read_csv(smoothed).columns
    assert "n_ancestors" not in pd.read_csv(filtered).columns


def test_the_papers_configuration_is_reachable_from_the_command_line(scenario_files, tmp_path):
    """--resampling multinomial --hmm-variant paper writes what the library gives for the
    paper's configuration (and differs from the defaults' run with the same seed)."""
    scenario, paths = scenario_files
    paper, default = tmp_path / "paper.csv", tmp_path / "default.csv"
    options = ["--resampling", "multinomial", "--resample-when", "always"]
    assert main([*track_args(paths, paper), *options, "--hmm-variant", "paper"]) == 0
    assert main(track_args(paths, default)) == 0
    expected = library_estimates(
        paths, motion_model("hmm", variant="paper"), resampling="multinomial"
    )
    assert_written_is(paper, expected, default)


def test_no_resting_reaches_the_hmm_motion_model(scenario_files, tmp_path, capsys, monkeypatch):
    """The HMM gets the resting state by default (K + 1 states, the last one resting);
    ``--no-resting`` tracks with the fitted K states; with another motion it is an error."""
    from hmmtrack.hmm import MovementHMM

    _, paths = scenario_files
    fitted = MovementHMM.load(bundled_model_path()).n_states
    used, track = [], tracking.track

    def spy(detections, receivers, config, **options):
        used.append(config.motion.build().model.n_states)
        return track(detections, receivers, config, **options)

    monkeypatch.setattr(tracking, "track", spy)
    assert main([*track_args(paths, tmp_path / "r.csv"), "--motion", "hmm"]) == 0
    assert main([*track_args(paths, tmp_path / "n.csv"), "--motion", "hmm", "--no-resting"]) == 0
    assert used == [fitted + 1, fitted]
    capsys.readouterr()
    assert (
        main([*track_args(paths, tmp_path / "b.csv"), "--motion", "baseline", "--no-resting"]) == 2
    )
    assert "--no-resting is used with --motion hmm only" in capsys.readouterr().err
    assert used == [fitted + 1, fitted]  # the error comes before any tracking


def test_smooth_works_with_the_range_rate_measurement_too(scenario_files, tmp_path, capsys):
    """The smoother is a collector of any run: ``--smooth`` writes the range-rate run's
    smoothed estimates, the library's with that smoothing lag."""
    _, paths = scenario_files
    smoothed = tmp_path / "smoothed.csv"
    options = ["--smooth", "10", "--motion", "velocity"]
    assert main([*track_args(paths, smoothed), *options]) == 0
    config = TrackingConfig.from_json(paths["metadata"])
    config = config.override(n_particles=1000, motion="velocity", smoothing_lag=10)
    detections, receivers = (io.read_detections(paths["detections"]),
                             io.read_receivers(paths["receivers"]))  # fmt: skip
    expected = tracking.track(detections, receivers, config, seed=3).smoothed
    written = pd.read_csv(smoothed)
    assert "n_ancestors" in written.columns
    np.testing.assert_allclose(written[["x", "y"]], expected[["x", "y"]], rtol=1e-9)
    with pytest.raises(SystemExit):
        main([*track_args(paths, tmp_path / "e.csv"), "--smooth", "-1"])
    assert "smoothing_lag must be a whole number >= 0" in capsys.readouterr().err


def test_gps_offset_measurement_from_the_command_line(scenario_files, tmp_path):
    """``--measurement range-rate-gps`` and its GPS settings reach the library's run, whose
    estimates differ from the paper's measurement's."""
    _, paths = scenario_files
    gps, paper = tmp_path / "gps.csv", tmp_path / "paper.csv"
    options = ["--measurement", "range-rate-gps", "--gps-correlation-time", "90"]
    assert main([*track_args(paths, gps), "--motion", "velocity", *options]) == 0
    assert main([*track_args(paths, paper), "--motion", "velocity"]) == 0
    expected = library_estimates(
        paths, motion="velocity", measurement="range-rate-gps", gps_correlation_time=90.0
    )
    assert_written_is(gps, expected, paper)


def test_config_file_with_overrides(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(
        json.dumps({"measurement": {"period": 8.179, "r0": {"a": 1.0, "b": 2.0}}, "name": "x"})
    )
    layer = nest({"r0": {"b": 5.0}, "n_particles": 10, "period": None})
    config = TrackingConfig.from_dict(merge_settings(read_settings(path), layer))
    assert config.measurement.r0 == {"a": 1.0, "b": 5.0} and config.filter.n_particles == 10
    assert config.measurement.period == 8.179
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        TrackingConfig.from_json(path)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"r0": {"a": -1}}, "r0 of receiver 'a'"),
        ({"sigma_range": -1}, "sigma_range must be a positive"),
        ({"range_rate_correlation": -1}, r"range_rate_correlation must lie in \(-1, 1\)"),
        ({"bounds": (10, 0, 0, 1)}, "xmin < xmax"),
        ({"n_particles": 2.5}, "positive integer"),
        ({"start": "2022-06-08T17:00:00"}, "UTC offset"),
        ({"start": 10.0, "end": 5.0}, "before end"),
        ({"shallower": "ignore"}, "shallower"),
        ({"velocity_window": -1}, "velocity_window"),
        ({"resampling": "bogus"}, "resampling must be one of"),
        ({"resample_when": "sometimes"}, "resample_when must be one of"),
        ({"ess_threshold": 1.5}, "ess_threshold must lie in"),
    ],
)
def test_config_validation(change, message):
    with pytest.raises(ValueError, match=message):
        TrackingConfig.from_keys(**({"period": 8.179, "r0": {"a": 1.0}} | change))


def test_every_setting_has_its_generated_option_with_its_default():
    """One option per key of every section, named after the key (or the option its field
    names), with the field's help and default in its help text; nothing given, the options
    build the defaults of every section. Fails when a field has no option or when an
    option's default differs from the field's."""
    options = {option.key: option for option in settings_options()}
    keys = set(TrackingConfig.keys()) - set(SECTIONS)
    for section in SECTIONS:
        for cls in section_classes(section).values():
            keys |= set(cls.keys())
    assert set(options) == keys
    subparsers = argparse.ArgumentParser().add_subparsers()
    register(subparsers)
    actions: dict = {}
    for action in subparsers.choices["track"]._actions:
        actions.setdefault(action.dest, action)  # the generated option before --no-smooth
    for key, option in options.items():
        action = actions[key]
        assert option.flag in action.option_strings
        assert action.default is None  # not given: the preset, the file or the field decide
        assert option.field.metadata["help"] in action.help
        if option.default_text is not None:
            assert f"(default: {option.default_text})" in action.help
        default = option.field.default
        if isinstance(default, float):
            assert f"(default: {default:g})" in action.help
    for key, flag in {"n_particles": "--particles", "variant": "--hmm-variant",
                      "smoothing_lag": "--smooth", "model": "--model", "r0": "--r0",
                      "resting": "--no-resting"}.items():  # fmt: skip
        assert flag in actions[key].option_strings
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    parser = build_parser()
    built = build_config(parser.parse_args([*base, "--period", "8", "--r0", "a=1"]))
    assert built == TrackingConfig.from_keys(period=8.0, r0={"a": 1.0})
    arrival = ["--period", "8", "--measurement", "arrival-time", "--motion", "velocity"]
    assert build_config(parser.parse_args([*base, *arrival])) == TrackingConfig.from_keys(
        period=8.0, measurement="arrival-time", motion="velocity"
    )
    ping = [*base, "--burst-interval", "20", "40"]
    assert build_config(parser.parse_args(ping)).smoothing == 60
    assert build_config(parser.parse_args([*ping, "--no-smooth"])).smoothing is None
    assert build_config(parser.parse_args([*ping, "--sigma-position", "3"])).motion == (
        TrackingConfig.from_keys(measurement="ping", sigma_position=3.0).motion
    )
    # the ping measurement's arrival sd may be estimated from the pings; a number overrides
    sigma = {
        word: build_config(parser.parse_args([*ping, "--arrival-sigma", word]))
        for word in ("pings", "0.0004")
    }
    assert sigma["pings"].measurement.arrival_sigma == "pings"
    assert sigma["0.0004"].measurement.arrival_sigma == 0.0004
    with pytest.raises(ValueError, match=r"\(arrival-time\): arrival_sigma must be a number"):
        build_config(parser.parse_args([*base, *arrival, "--arrival-sigma", "pings"]))


REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "yaps_ssu1"


def test_real_vue_export_runs_end_to_end(tmp_path, capsys):
    """A real Innovasea VUE export with 19 moored VR2W receivers (skipped when absent).

    Tag 15266 has a random 20-40 s burst interval, so fixed-period ranging does not apply:
    this is the real-format path (receiver and transmitter names, millisecond
    receiver-clock times, several transmitters) up to the period check, which refuses the
    tag as not of a fixed period instead of writing a track from meaningless ranges.
    """
    if not REAL.is_dir():
        pytest.skip(f"real data not present: {REAL}")
    hydros = pd.read_csv(REAL / "ssu1_hydros.csv")
    receivers = pd.DataFrame(
        {"receiver": "VR2W-" + hydros["serial"].astype(str), "x": hydros["x"], "y": hydros["y"]}
    )
    receivers.to_csv(tmp_path / "receivers.csv", index=False)
    detections = io.read_detections(REAL / "VUE_Export_ssu1.csv", transmitter="15266")
    gps = pd.read_csv(REAL / "ssu1_gps.csv")
    gps_time = io.parse_times(gps, "ts", tz=None)
    first = detections.groupby("receiver")["time"].min()
    position = receivers.set_index("receiver").loc[first.index]
    r0 = np.hypot(
        position["x"] - np.interp(first, gps_time, gps["utm_x"]),
        position["y"] - np.interp(first, gps_time, gps["utm_y"]),
    )
    output = tmp_path / "estimate.csv"
    args = ["track", "--detections", str(REAL / "VUE_Export_ssu1.csv")]
    args += ["--receivers", str(tmp_path / "receivers.csv"), "--period", "30"]
    args += [f"--r0={name}={metres:.1f}" for name, metres in r0.items()]
    args += ["--motion", "velocity", "--particles", "300", "--seed", "1", "-o", str(output)]
    assert main(args) == 2  # nine transmitters in the file: which one?
    assert "choose one" in capsys.readouterr().err
    assert main([*args, "--transmitter", "15266"]) == 2  # the ID part is enough
    err = capsys.readouterr().err
    assert "not those of a fixed-period tag" in err and "random delays" in err
    assert not output.exists()


def test_plot_functions_draw_what_they_are_given():
    import matplotlib

    matplotlib.use("Agg")
    from hmmtrack.plots.tracking import plot_error_over_time, plot_particles, snapshot_times

    np.testing.assert_array_equal(snapshot_times(100.0, 1300.0), [100.0, 110.0, 209.0, 1300.0])
    convergence = metrics.Convergence(time_to_convergence=20.0, converged=True, index=20)
    ax = plot_error_over_time(np.arange(50.0, 150.0), np.linspace(50, 1, 100), convergence)
    assert ax.get_xlim() == (0.0, 99.0) and len(ax.lines) == 2
    receivers = pd.DataFrame(
        {"receiver": ["a", "b", "b"], "time": [np.nan, 0.0, 10.0], "x": [0, 50, 60], "y": [0, 0, 0]}
    )
    observations = pd.DataFrame({"time": [1.0, 2.0, 4.0], "receiver": ["a", "a", "b"]})
    observations["range"] = [30.0, 31.0, 25.0]
    snapshot = pd.DataFrame({"x": [1.0, 2.0], "y": [3.0, 4.0], "weight": [0.5, 0.5]})
    truth = pd.DataFrame({"time": [np.nan], "x": [20.0], "y": [5.0]})
    ax = plot_particles(snapshot, receivers, truth, time=5.0, observations=observations)
    circles = sorted(patch.radius for patch in ax.patches)
    assert circles == [25.0, 31.0]  # each receiver's latest range at or before 5 s
    estimates = pd.DataFrame(
        {"time": [4.0, 5.0, 6.0], "x": [1.0, 2.0, 3.0], "y": [3.0, 4.0, 5.0]}
    ).assign(mode2_x=[7.0, 8.0, 9.0], mode2_y=[-1.0, -2.0, -3.0], mode2_weight=0.3)
    ax = plot_particles(snapshot, receivers, time=5.0, estimates=estimates)
    (second,) = [line for line in ax.lines if line.get_label().startswith("second mode")]
    assert second.get_label() == "second mode (0.30)"
    np.testing.assert_array_equal(second.get_xydata(), [[8.0, -2.0]])  # the one at 5 s
    matplotlib.pyplot.close("all")


@pytest.fixture(scope="module")
def observable_files(tmp_path_factory):
    """Two AUVs on the observable plan (clock-corrected times), their first 300 s as CSV."""
    case = realistic_shark_pursuit(3, steering="observable")
    detections = case.corrected_detections()
    end = case.scenario.start + 300.0
    scenario = dataclasses.replace(
        case.scenario, detections=detections[detections["time"] <= end], end=end
    )
    return scenario, write_scenario(
        scenario, tmp_path_factory.mktemp("observable"), scenario_settings(scenario)
    )


def test_preset_runs_the_arrival_time_filter_with_its_settings(observable_files, tmp_path):
    """``--preset two-moving-receivers`` needs only the period: it writes what
    ``track`` estimates with the preset's motion, likelihood and tempering
    (the particle count overridden by --particles), unlike the arrival-time defaults."""
    scenario, paths = observable_files
    start, end = scenario.start, scenario.end
    common = [
        "track", "--detections", str(paths["detections"]), "--receivers",
        str(paths["receivers"]), "--period", str(scenario.period), "--particles", "600",
        "--seed", "8", "--start", *io.format_times(np.array([start])), "--end",
        *io.format_times(np.array([end])),
    ]  # fmt: skip
    preset, plain = tmp_path / "preset.csv", tmp_path / "plain.csv"
    assert main([*common, "--preset", "two-moving-receivers", "-o", str(preset)]) == 0
    direct = arrival_time_run(
        paths, scenario, VelocityMotion(0.1, 0.003), 600, 8,
        arrival_sigma=1.2e-3, tempering_ess=0.3, search_radius=240.0,
    )  # fmt: skip
    written = pd.read_csv(preset)
    assert len(written) == 301
    np.testing.assert_allclose(written[["x", "y"]], direct.estimates[["x", "y"]], rtol=1e-9)
    options = ["--measurement", "arrival-time", "--motion", "velocity"]
    assert main([*common, *options, "-o", str(plain)]) == 0
    assert not np.allclose(pd.read_csv(plain)[["x", "y"]], written[["x", "y"]])


def test_preset_then_config_file_then_options(tmp_path, capsys):
    """Each source overrides the one before; an unknown preset lists the available ones."""
    settings = tmp_path / "settings.json"
    settings.write_text(
        json.dumps(nest({"period": 8.0, "n_particles": 2000, "tempering_ess": 0.5}))
    )
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    preset = ["--preset", "two-moving-receivers"]

    def config_of(*extra):
        return build_config(build_parser().parse_args([*base, *extra]))

    def summary(config):
        return (
            config.filter.n_particles,
            config.filter.tempering_ess,
            config.measurement.arrival_sigma,
        )

    alone = config_of(*preset, "--period", "8.0")
    assert summary(alone) == (4000, 0.3, 1.2e-3)
    filed = config_of(*preset, "--config", str(settings))
    assert summary(filed) == (2000, 0.5, 1.2e-3)
    flagged = config_of(*preset, "--config", str(settings), "--particles", "1000")
    assert summary(flagged)[:2] == (1000, 0.5)
    assert flagged.motion.build() == VelocityMotion(0.1, 0.003)
    assert main([*base, "--preset", "two-auvs", "--period", "8"]) == 2
    assert (
        "unknown preset 'two-auvs'; available presets: constant-velocity-tag, two-moving-receivers"
        in (capsys.readouterr().err)
    )
    paper = ["--period", "8", "--r0", "auv-1=10", "--measurement", "range-rate"]
    assert main([*base, *preset, *paper]) == 2
    assert "(range-rate): unknown key(s) ['arrival_sigma', 'search_radius']" in (
        capsys.readouterr().err
    )


@pytest.fixture
def starting_particles(monkeypatch):
    """``main(args)`` that must succeed and returns the positions (x, y), shape (N, 2), of
    the particles its filter started from (Algorithm 1, recorded from ``Particles.uniform``;
    a later re-initialisation is not the start)."""
    from hmmtrack.tracking.particles import Particles

    uniform, runs = Particles.uniform, []

    def spy(cls, rng, n, bounds):
        particles = uniform(rng, n, bounds)
        runs.append(np.column_stack([particles.x, particles.y]))
        return particles

    monkeypatch.setattr(Particles, "uniform", classmethod(spy))

    def run(args):
        runs.clear()
        assert main(args) == 0
        return runs[0]

    return run


def inside(points: np.ndarray, box) -> np.ndarray:
    xmin, xmax, ymin, ymax = box
    x, y = points[:, 0], points[:, 1]
    return (xmin <= x) & (x <= xmax) & (ymin <= y) & (y <= ymax)


def test_bounds_option_is_the_starting_particles_box(scenario_files, tmp_path, starting_particles):
    """--bounds (metres for x/y receivers) is the box the particles start in, here a box
    around the tag that holds neither receiver; it overrides the --config file's (wider)
    box; without either, --bounds-margin widens the box derived from r0."""
    scenario, paths = scenario_files
    box = (-12.0, 18.0, -9.0, 11.0)
    first = scenario.receivers.groupby("receiver")[["x", "y"]].first().to_numpy()
    assert not inside(first, box).any()
    given = starting_particles([*track_args(paths, tmp_path / "b.csv"), "--bounds", *map(str, box)])
    filed = starting_particles(track_args(paths, tmp_path / "file.csv"))
    plain = ["--config", str(paths["metadata"]), "--bounds-margin", "0"]
    without_file = [a for a in track_args(paths, tmp_path / "d.csv") if a not in plain]
    r0 = [f"--r0={name}={metres}" for name, metres in scenario.r0.items()]
    derived = [*without_file, "--period", str(scenario.period), *r0]
    tight = starting_particles([*derived, "--bounds-margin", "0"])
    wide = starting_particles([*derived, "--bounds-margin", "50"])
    assert inside(given, box).all() and len(given) == 1000
    file_box = json.loads(paths["metadata"].read_text())["bounds"]
    assert inside(filed, file_box).all() and not inside(filed, box).all()
    # derived: each receiver's first position ± (r0 + margin)
    observations = tracking.build_observations(
        scenario.detections,
        scenario.receivers,
        TrackingConfig.from_keys(period=scenario.period, r0=scenario.r0),
    )
    for run, margin in ((tight, 0.0), (wide, 50.0)):
        expected = search_bounds(observations, scenario.r0, margin)
        assert inside(run, expected).all()
        assert run[:, 0].min() < expected[0] + 5 and run[:, 0].max() > expected[1] - 5
    assert np.ptp(wide[:, 0]) > np.ptp(tight[:, 0]) + 80


def test_lonlat_bounds_are_degrees_converted_like_the_receivers(
    scenario_files, tmp_path, starting_particles, capsys
):
    """With lon/lat receivers --bounds are LON_MIN LON_MAX LAT_MIN LAT_MAX in degrees; the
    particles start in the smallest box of the receivers' projection (UTM 11N) holding that
    lon/lat box (pyproj's transform_bounds as oracle), i.e. around the tag; metres are
    refused with a message that says degrees."""
    _, paths = scenario_files
    lonlat = dict(paths)
    settings = json.loads(paths["metadata"].read_text())
    del settings["bounds"]
    lonlat["metadata"] = tmp_path / "scenario_lonlat.json"
    lonlat["metadata"].write_text(json.dumps(settings))
    lonlat["receivers"] = tmp_path / "receivers_lonlat.csv"
    to_lonlat(pd.read_csv(paths["receivers"])).to_csv(
        lonlat["receivers"], index=False, float_format="%.9f"
    )
    corners = to_lonlat(pd.DataFrame({"x": [-12.0, 18.0], "y": [-9.0, 11.0]}))
    box = (corners["lon"][0], corners["lon"][1], corners["lat"][0], corners["lat"][1])
    degrees = [f"{b:.9f}" for b in box]
    particles = starting_particles([*track_args(lonlat, tmp_path / "e.csv"), "--bounds", *degrees])
    expected = Transformer.from_crs("EPSG:4326", UTM_11N, always_xy=True).transform_bounds(
        *(float(d) for d in np.array(degrees)[[0, 2, 1, 3]]), densify_pts=201
    )
    xmin, ymin, xmax, ymax = expected
    assert inside(particles, (xmin - 1e-6, xmax + 1e-6, ymin - 1e-6, ymax + 1e-6)).all()
    shifted = particles - np.array(ORIGIN)
    assert inside(shifted, (-12.5, 18.5, -9.5, 11.5)).all()  # the metres box, to 0.5 m
    assert shifted[:, 0].min() < -11.0 and shifted[:, 0].max() > 17.0
    derived = starting_particles(track_args(lonlat, tmp_path / "d.csv")) - np.array(ORIGIN)
    assert not inside(derived, (-12.5, 18.5, -9.5, 11.5)).all()  # without --bounds: wider
    metres = ["389988", "390018", "3729991", "3730011"]
    assert main([*track_args(lonlat, tmp_path / "m.csv"), "--bounds", *metres]) == 2
    assert "LON_MIN LON_MAX LAT_MIN LAT_MAX in degrees" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (["--bounds", "10", "0", "0", "1"], "XMIN < XMAX and YMIN < YMAX (metres for x/y"),
        (["--bounds", "0", "10", "5", "5"], "LON_MIN LON_MAX LAT_MIN LAT_MAX degrees for"),
        (["--bounds", "5000", "5010", "0", "1"], "are the bounds in the receivers' frame?"),
        (["--measurement", "arrival-time", "--bounds-margin", "5"], "--bounds-margin is used"),
        (["--measurement", "arrival-time", "--sigma-range", "5"], "--sigma-range is used with"),
        (["--sigma-range-rate", "0.1", "--measurement", "arrival-time"], "--measurement range"),
        (["--arrival-sigma", "0.001"], "--arrival-sigma is used with --measurement arrival-time"),
        (["--detection-curve", "500", "50"], "--detection-curve is used with --measurement arr"),
        # the file's range-rate keys are not the arrival-time measurement's
        (["--measurement", "arrival-time"], "(arrival-time): unknown key(s) ['r0']; valid keys"),
        (["--search-radius", "100"], "--search-radius is used with --measurement arrival-time"),
        (["--heading-diffusion", "0.1", "--motion", "velocity"], "--motion hmm only"),
        (["--sigma-speed", "0.1"], "--sigma-speed is used with --motion velocity only (this"),
        (["--motion", "baseline", "--sigma-turn-rate", "0"], "run's motion is baseline)"),
        (["--ess-threshold", "0.5"], "--ess-threshold is used with --resample-when ess only"),
    ],
)
def test_bad_settings_options_are_clear_errors(scenario_files, tmp_path, capsys, change, message):
    _, paths = scenario_files
    assert main([*track_args(paths, tmp_path / "e.csv"), *change]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (["--bounds", "0", "nan", "0", "1"], "argument --bounds: expected a finite number"),
        (["--bounds", "0", "1", "west", "1"], "argument --bounds: expected a number, got 'west'"),
        (["--bounds", "0", "1", "0"], "argument --bounds: expected 4 arguments"),
        (["--bounds-margin", "-1"], "argument --bounds-margin: bounds_margin must be a non-neg"),
        (["--sigma-range", "0"], "argument --sigma-range: sigma_range must be a positive"),
        (
            ["--sigma-range-rate", "inf"],
            "argument --sigma-range-rate: sigma_range_rate must be a f",
        ),
        (["--arrival-sigma", "-0.001"], "argument --arrival-sigma: arrival_sigma must be a posit"),
        (["--detection-curve", "500"], "argument --detection-curve: expected 2 arguments"),
        (["--search-radius", "0"], "argument --search-radius: search_radius must be a positive"),
        (["--sigma-speed", "-0.1"], "argument --sigma-speed: sigma_speed must be a non-negative"),
        (["--sound-speed", "nan"], "argument --sound-speed: sound_speed must be a finite number"),
        (["--tempering-ess", "1.5"], "argument --tempering-ess: tempering_ess must lie in (0, 1)"),
        (["--ess-threshold", "2"], "argument --ess-threshold: ess_threshold must lie in (0, 1]"),
        (["--period", "-1"], "argument --period: period must be a positive"),
        (["--depth", "deep"], "argument --depth: depth must be one of"),
        (["--particles", "0"], "argument --particles: n_particles must be a positive integer"),
    ],
)
def test_settings_options_that_do_not_parse(scenario_files, tmp_path, capsys, change, message):
    _, paths = scenario_files
    with pytest.raises(SystemExit) as exit_:
        main([*track_args(paths, tmp_path / "e.csv"), *change])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err


def test_sigma_options_reach_the_range_rate_likelihood(scenario_files, tmp_path):
    """--sigma-range / --sigma-range-rate set Σ_z's diagonal: the run equals the library's
    with that Σ_z and differs from the default run of the same seed."""
    _, paths = scenario_files
    tight, default = tmp_path / "tight.csv", tmp_path / "default.csv"
    sigmas = ["--sigma-range", "2", "--sigma-range-rate", "0.3", "--motion", "velocity"]
    assert main([*track_args(paths, tight), *sigmas]) == 0
    assert main([*track_args(paths, default), "--motion", "velocity"]) == 0
    expected = library_estimates(paths, sigma_range=2.0, sigma_range_rate=0.3, motion="velocity")
    assert_written_is(tight, expected, default)
    config = build_config(build_parser().parse_args([*track_args(paths, tight), *sigmas]))
    np.testing.assert_allclose(config.measurement.covariance, [[4.0, 0.0], [0.0, 0.09]])


def test_detection_curve_reaches_the_arrival_time_filter(arrival_files, tmp_path):
    """--detection-curve RANGE_50 WIDTH: the run equals the library's with that
    LogisticDetection (the scenario's own curve) and differs from the run without it."""
    scenario, paths = arrival_files
    common = arrival_args(scenario, paths, 400, 6)
    curve, plain = tmp_path / "curve.csv", tmp_path / "plain.csv"
    assert main([*common, "--detection-curve", "700", "100", "-o", str(curve)]) == 0
    assert main([*common, "-o", str(plain)]) == 0
    direct = arrival_time_run(
        paths, scenario, "velocity", 400, 6, detection_curve=LogisticDetection(700.0, 100.0)
    )
    assert_written_is(curve, direct.estimates, plain)


def test_arrival_time_settings_by_options_and_bounds_outside_the_array(
    arrival_files, tmp_path, starting_particles
):
    """--arrival-sigma and --bounds reach the arrival-time run: a box around the tag's start
    that holds no mooring is where the particles start."""
    scenario, paths = arrival_files
    box = (-60.0, 60.0, -50.0, 70.0)
    assert not inside(scenario.receivers[["x", "y"]].to_numpy(), box).any()
    args = [
        *arrival_args(scenario, paths, 400, 6),
        "--arrival-sigma", "0.002", "--bounds",
        *map(str, box), "-o", str(tmp_path / "e.csv"),
    ]  # fmt: skip
    assert inside(starting_particles(args), box).all()
    direct = arrival_time_run(paths, scenario, "velocity", 400, 6, arrival_sigma=0.002, bounds=box)
    written = pd.read_csv(tmp_path / "e.csv")
    np.testing.assert_allclose(written[["x", "y"]], direct.estimates[["x", "y"]], rtol=1e-9)


def test_new_settings_keep_preset_then_config_then_options(tmp_path):
    """Bounds, Σ_z's standard deviations, arrival σ and the detection curve: the options
    override a --config file, which overrides the preset; a --sigma option keeps the
    file's other standard deviation and its range/range-rate correlation."""
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    preset = ["--preset", "two-moving-receivers"]
    arrival = tmp_path / "arrival.json"
    arrival.write_text(
        json.dumps(
            {"bounds": [0, 10, 0, 10],
             "measurement": {"period": 8.0, "arrival_sigma": 0.003,
                             "detection_curve": {"range_50": 300, "width": 30}}}
        )
    )  # fmt: skip
    paper = tmp_path / "paper.json"
    paper.write_text(
        json.dumps(
            {"measurement": {"period": 8.0, "r0": {"a": 5.0}, "bounds_margin": 20,
                             "sigma_range": 3.0, "sigma_range_rate": 0.2,
                             "range_rate_correlation": 0.5}}
        )
    )  # fmt: skip

    def config_of(*extra):
        return build_config(build_parser().parse_args([*base, *extra]))

    def summary(config):
        return config.bounds, config.measurement.arrival_sigma, config.measurement.detection_curve

    alone = config_of(*preset, "--period", "8")
    assert summary(alone) == (None, 1.2e-3, None)
    filed = config_of(*preset, "--config", str(arrival))
    assert summary(filed) == ((0.0, 10.0, 0.0, 10.0), 0.003, LogisticDetection(300.0, 30.0))
    options = ["--bounds", "-5", "5", "-6", "6", "--arrival-sigma", "0.001"]
    flagged = config_of(
        *preset, "--config", str(arrival), *options, "--detection-curve", "200", "20"
    )
    assert summary(flagged) == ((-5.0, 5.0, -6.0, 6.0), 0.001, LogisticDetection(200.0, 20.0))
    ranged = config_of("--config", str(paper)).measurement
    assert ranged.bounds_margin == 20.0
    np.testing.assert_allclose(ranged.covariance[0], (9.0, 0.3))
    ranged = config_of("--config", str(paper), "--sigma-range", "6", "--bounds-margin", "0")
    assert ranged.measurement.bounds_margin == 0.0
    # the file's correlation 0.5 kept: 0.5 * 6 * 0.2 = 0.6
    np.testing.assert_allclose(ranged.measurement.covariance, [[36.0, 0.6], [0.6, 0.04]])
    plain = config_of("--period", "8", "--r0", "a=5", "--sigma-range-rate", "0.1")
    np.testing.assert_allclose(plain.measurement.covariance, [[25.0, 0.0], [0.0, 0.01]])


def test_search_and_motion_settings_by_options(arrival_files, tmp_path, starting_particles):
    """--search-radius, --tempering-ess, --sigma-speed and --sigma-turn-rate reach
    the arrival-time run: the particles start within the receivers ± the radius, and the run
    equals the library's with those settings."""
    scenario, paths = arrival_files
    args = [
        *arrival_args(scenario, paths, 400, 5),
        "--search-radius", "150",
        "--tempering-ess", "0.6", "--sigma-speed", "0.08", "--sigma-turn-rate", "0.004",
        "-o", str(tmp_path / "e.csv"),
    ]  # fmt: skip
    particles = starting_particles(args)
    x, y = scenario.receivers["x"], scenario.receivers["y"]
    box = (x.min() - 150, x.max() + 150, y.min() - 150, y.max() + 150)
    assert inside(particles, box).all()
    assert particles[:, 0].min() < box[0] + 20 and particles[:, 0].max() > box[1] - 20
    direct = arrival_time_run(
        paths, scenario, VelocityMotion(0.08, 0.004), 400, 5,
        search_radius=150.0, tempering_ess=0.6,
    )  # fmt: skip
    written = pd.read_csv(tmp_path / "e.csv")
    np.testing.assert_allclose(written[["x", "y"]], direct.estimates[["x", "y"]], rtol=1e-9)


def test_ess_threshold_reaches_the_range_rate_filter(scenario_files, tmp_path):
    """--resample-when ess --ess-threshold F equals the library's run with that threshold,
    and a different threshold gives a different run."""
    _, paths = scenario_files
    ess = ["--motion", "velocity", "--resample-when", "ess"]
    low, high = tmp_path / "low.csv", tmp_path / "high.csv"
    assert main([*track_args(paths, low), *ess, "--ess-threshold", "0.1"]) == 0
    assert main([*track_args(paths, high), *ess, "--ess-threshold", "0.9"]) == 0
    expected = library_estimates(paths, motion="velocity", resample_when="ess", ess_threshold=0.1)
    assert_written_is(low, expected, high)


def test_sigma_options_name_a_bad_covariance_of_the_config_file(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"measurement": {"period": 8.0, "range_rate_correlation": 2}}))
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    assert main([*base, "--config", str(bad), "--r0", "a=1", "--sigma-range", "3"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}, command line, section 'measurement' (range-rate): range_rate_correlation" in err
    assert "must lie in (-1, 1), got 2" in err


def test_filter_names_the_filter_and_the_switches_override_it():
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    base += ["--period", "8", "--r0", "a=1"]

    def switches(*extra):
        built = build_config(build_parser().parse_args([*base, *extra])).filter
        return built.acquisition, built.mixture, built.long_gap, built.monitor

    assert switches("--filter", "paper") == (False, False, False, False)
    assert switches("--filter", "mode-keeping") == (True, True, True, False)
    assert switches() == (True, True, True, False)  # the default: the long-gap rule, no loss test
    assert switches("--monitor") == (True, True, True, True)  # --monitor adds the loss test
    assert switches("--filter", "paper", "--long-gap") == (False, False, True, False)
    assert switches("--filter", "mode-keeping", "--no-mixture", "--monitor") == (
        True,
        False,
        True,
        True,
    )
    assert switches("--no-long-gap", "--monitor") == (True, True, False, True)
