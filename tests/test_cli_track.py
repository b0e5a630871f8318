"""Tests of ``hmmtrack track`` and its configuration (hmmtrack.cli.track, hmmtrack.config).

End to end on the files ``hmmtrack simulate`` writes for the stationary-tag scenario: the
estimate CSV's columns, one row per second with ISO 8601 UTC times, the printed metrics,
the lon/lat round trip and the plot; on a moored array and on two AUVs with the
``two-moving-receivers`` preset for the arrival-time measurement.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pyproj import Transformer

from hmmtrack import io, metrics, tracking
from hmmtrack.arrival import ArrivalLikelihood, ArrivalTimeMeasurement
from hmmtrack.cli import build_parser, main
from hmmtrack.cli.track import build_config
from hmmtrack.clock_scenarios import moored_array, realistic_shark_pursuit
from hmmtrack.clock_tracking import track_arrival_time
from hmmtrack.config import TrackingConfig
from hmmtrack.motion import VelocityMotion
from hmmtrack.scenarios import stationary_tag
from hmmtrack.scenarios.export import write_scenario

ESTIMATE_COLUMNS = ["time", "x", "y", "var_x", "var_y", "cov_xy", "sqrt_lambda1"]
#: a UTM zone 11N origin off Long Beach, CA (m): scenario metres are shifted by it
ORIGIN = (390_000.0, 3_730_000.0)
UTM_11N = "EPSG:32611"


@pytest.fixture(scope="module")
def scenario_files(tmp_path_factory):
    directory = tmp_path_factory.mktemp("stationary")
    scenario = stationary_tag(11)
    return scenario, write_scenario(scenario, directory)


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


def test_options_without_a_config_file(scenario_files, tmp_path, capsys):
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
    with pytest.warns(RuntimeWarning, match="outside"):  # detections outside the window
        assert main([*args, *window, "--seed", "2", "--truth", str(fixed)]) == 0
    printed = capsys.readouterr()
    assert "time to convergence" in printed.out
    assert "observations_outside_window" in printed.err
    table = pd.read_csv(output)
    assert table["time"].iloc[[0, -1]].tolist() == [
        "2022-06-08T17:01:00.000Z",
        "2022-06-08T17:06:00.000Z",
    ]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (["--period", "-1"], "period must be a positive"),
        (["--model", "x.json", "--motion", "baseline"], "--motion hmm only"),
        (["--depth", "deep"], "depth must be one of"),
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
    assert main([*base, "--period", "8.179"]) == 2
    assert "give --r0" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*base, "--period", "8.179", "--r0", "auv:20"])
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"period": 8.179, "r0": {"auv": 20}, "particles": 10}))
    assert main([*base, "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "unknown key(s) ['particles']" in err


@pytest.fixture(scope="module")
def arrival_files(tmp_path_factory):
    """A moored array heard with clock-corrected times (no initial range), as CSV files."""
    case = moored_array(5, duration=300.0)
    scenario = dataclasses.replace(case.scenario, detections=case.corrected_detections())
    return scenario, write_scenario(scenario, tmp_path_factory.mktemp("arrival"))


def test_arrival_time_measurement_without_r0_runs_the_clock_aware_tracker(
    arrival_files, tmp_path, capsys
):
    """``--measurement arrival-time`` needs no --r0 and writes what
    :func:`hmmtrack.clock_tracking.track_arrival_time` estimates from the same files;
    ``--smooth`` writes the fixed-lag smoothed track instead."""
    scenario, paths = arrival_files
    window = io.format_times(np.array([scenario.start, scenario.end]))
    common = [
        "track", "--detections", str(paths["detections"]), "--receivers",
        str(paths["receivers"]), "--period", str(scenario.period), "--measurement",
        "arrival-time", "--motion", "velocity", "--particles", "500", "--seed", "4",
        "--start", window[0], "--end", window[1],
    ]  # fmt: skip
    filtered, smoothed = tmp_path / "filtered.csv", tmp_path / "smoothed.csv"
    assert main([*common, "-o", str(filtered)]) == 0
    truth = ["--truth", str(paths["truth"])]
    assert main([*common, "--smooth", "20", "-o", str(smoothed), *truth]) == 0
    printed = capsys.readouterr().out
    assert "mean error after convergence" in printed
    detections = io.read_detections(paths["detections"])
    receivers = io.read_receivers(paths["receivers"])
    direct = track_arrival_time(
        detections, receivers, motion=tracking.motion_model("velocity"),
        period=scenario.period, n_particles=500, smoothing_lag=20,
        start=scenario.start, end=scenario.end, seed=4,
    )  # fmt: skip
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
    config = TrackingConfig.from_json(paths["metadata"], n_particles=1000, resampling="multinomial")
    expected = tracking.track(
        io.read_detections(paths["detections"]),
        io.read_receivers(paths["receivers"]),
        config,
        tracking.motion_model("hmm", variant="paper"),
        seed=3,
    ).estimates
    written = pd.read_csv(paper)
    np.testing.assert_allclose(written[["x", "y"]], expected[["x", "y"]], rtol=1e-9)
    assert not np.allclose(pd.read_csv(default)["x"], written["x"])


def test_no_resting_reaches_the_hmm_motion_model(scenario_files, tmp_path, capsys, monkeypatch):
    """The HMM gets the resting state by default (K + 1 states, the last one resting);
    ``--no-resting`` tracks with the fitted K states; with another motion it is an error."""
    from hmmtrack.hmm import MovementHMM

    _, paths = scenario_files
    fitted = MovementHMM.load(tracking.bundled_model_path()).n_states
    used, track = [], tracking.track

    def spy(detections, receivers, config, motion, **options):
        used.append(motion.model.n_states)
        return track(detections, receivers, config, motion, **options)

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


def test_smooth_needs_the_arrival_time_measurement(scenario_files, tmp_path, capsys):
    _, paths = scenario_files
    assert main([*track_args(paths, tmp_path / "e.csv"), "--smooth", "10"]) == 2
    assert "--smooth needs --measurement arrival-time" in capsys.readouterr().err


def test_config_round_trip_and_validation():
    config = TrackingConfig(
        period=8.179,
        r0={"a": 1.5, "b": 30},
        bounds=(0, 10, -5, 5),
        measurement_covariance=[[9.0, 0.3], [0.3, 0.04]],
        depth="10.7",
        start="2022-06-08T17:00:00Z",
        end=1654708800,
    )
    assert config.depth == 10.7 and config.start == 1654707600.0
    assert TrackingConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config
    assert config.override(n_particles=None, period=5.0).period == 5.0


def test_config_file_with_overrides(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"period": 8.179, "r0": {"a": 1.0, "b": 2.0}, "name": "x"}))
    config = TrackingConfig.from_json(path, r0={"b": 5.0}, n_particles=10, period=None)
    assert config.r0 == {"a": 1.0, "b": 5.0} and config.n_particles == 10
    assert config.period == 8.179
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        TrackingConfig.from_json(path)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"r0": {"a": -1}}, "r0 of receiver 'a'"),
        ({"measurement_covariance": [[1, 2], [2, 1]]}, "positive definite"),
        ({"measurement_covariance": [[1, 0.1], [0, 1]]}, "symmetric"),
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
        TrackingConfig(**({"period": 8.179, "r0": {"a": 1.0}} | change))


REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "yaps_ssu1"


def test_real_vue_export_runs_end_to_end(tmp_path, capsys):
    """A real Innovasea VUE export with 19 moored VR2W receivers (skipped when absent).

    Tag 15266 has a random 20-40 s burst interval, so fixed-period ranging does not apply
    and the positions are not checked: this is the real-format path (receiver and
    transmitter names, millisecond receiver-clock times, several transmitters) and the
    filter's guarantee of finite estimates whatever the ranges.
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
    assert main([*args, "--transmitter", "15266"]) == 0  # the ID part is enough
    table = pd.read_csv(output)
    span = np.ceil(detections["time"].max()) - np.floor(detections["time"].min())
    assert len(table) == int(span) + 1
    assert np.isfinite(table[ESTIMATE_COLUMNS[1:]].to_numpy()).all()


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
    return scenario, write_scenario(scenario, tmp_path_factory.mktemp("observable"))


def test_preset_runs_the_arrival_time_filter_with_its_settings(observable_files, tmp_path):
    """``--preset two-moving-receivers`` needs only the period: it writes what
    ``track_arrival_time`` estimates with the preset's motion, likelihood and tempering
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
    direct = track_arrival_time(
        io.read_detections(paths["detections"]), io.read_receivers(paths["receivers"]),
        motion=VelocityMotion(0.1, 0.003),
        measurement=ArrivalTimeMeasurement(ArrivalLikelihood(sigma=1.2e-3)),
        tempering_ess=0.3, search_radius=240.0, period=scenario.period, n_particles=600,
        start=start, end=end, seed=8,
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
    settings.write_text(json.dumps({"period": 8.0, "n_particles": 2000, "tempering_ess": 0.5}))
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    preset = ["--preset", "two-moving-receivers"]

    def config_of(*extra):
        return build_config(build_parser().parse_args([*base, *extra]))

    alone = config_of(*preset, "--period", "8.0")
    assert (alone.n_particles, alone.tempering_ess, alone.arrival_sigma) == (4000, 0.3, 1.2e-3)
    filed = config_of(*preset, "--config", str(settings))
    assert (filed.n_particles, filed.tempering_ess, filed.arrival_sigma) == (2000, 0.5, 1.2e-3)
    flagged = config_of(*preset, "--config", str(settings), "--particles", "1000")
    assert (flagged.n_particles, flagged.tempering_ess) == (1000, 0.5)
    assert flagged.motion_model() == VelocityMotion(0.1, 0.003)
    assert main([*base, "--preset", "two-auvs", "--period", "8"]) == 2
    assert "unknown preset 'two-auvs'; available presets: two-moving-receivers" in (
        capsys.readouterr().err
    )
    paper = ["--period", "8", "--r0", "auv-1=10", "--measurement", "range-rate"]
    assert main([*base, *preset, *paper]) == 2
    assert "is a setting of measurement 'arrival-time'" in capsys.readouterr().err
