"""End-to-end tests of ``hmmtrack fit`` and ``hmmtrack decode`` on a small track file."""

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from hmmtrack import io, tracks
from hmmtrack.cli import main
from hmmtrack.hmm import Gamma, MovementHMM, VonMises, crw, imputation

TRUE = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=np.array([[0.9, 0.1], [0.15, 0.85]]),
    step=Gamma(np.array([20.0, 120.0]), np.array([12.0, 40.0])),
    angle=VonMises(np.array([0.0, 0.0]), np.array([0.6, 8.0])),
)


@pytest.fixture
def track_file(tmp_path):
    """Two animals, one fix a minute, positions built from simulated steps and turns."""
    rng = np.random.default_rng(6)
    rows = []
    for animal in ("a", "b"):
        sim = TRUE.simulate(rng, 400)
        heading = np.cumsum(sim["angle"].to_numpy())
        x = np.concatenate([[0.0], np.cumsum(sim["step"] * np.cos(heading))])[:-1]
        y = np.concatenate([[0.0], np.cumsum(sim["step"] * np.sin(heading))])[:-1]
        times = pd.date_range("2024-06-01", periods=400, freq="60s", tz="UTC")
        rows.append(
            pd.DataFrame(
                {"id": animal, "time": times.strftime("%Y-%m-%dT%H:%M:%SZ"), "x": x, "y": y}
            )
        )
    path = tmp_path / "tracks.csv"
    pd.concat(rows).to_csv(path, index=False)
    return path


def test_fit_then_decode(track_file, tmp_path, capsys):
    model_path = tmp_path / "model.json"
    code = main(
        [
            "fit",
            str(track_file),
            "--states",
            "2",
            "--starts",
            "2",
            "--seed",
            "1",
            "-o",
            str(model_path),
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    for words in ("log-likelihood", "AIC", "transition matrix", "step.mean", "upper"):
        assert words in printed
    document = json.loads(model_path.read_text())
    assert document["schema"] == "hmmtrack.movement_hmm" and document["dt"] == 60.0
    model = MovementHMM.load(model_path)
    np.testing.assert_allclose(model.step.mean, TRUE.step.mean, rtol=0.2)
    np.testing.assert_allclose(model.transition, TRUE.transition, atol=0.08)

    states_path = tmp_path / "states.csv"
    code = main(["decode", str(track_file), "--model", str(model_path), "-o", str(states_path)])
    assert code == 0
    decoded = pd.read_csv(states_path)
    assert len(decoded) == 800
    assert {
        "id",
        "time",
        "x",
        "y",
        "segment",
        "step",
        "angle",
        "state",
        "p_state1",
        "p_state2",
    } <= set(decoded.columns)
    assert decoded["time"].iloc[0] == "2024-06-01T00:00:00.000Z"
    np.testing.assert_allclose(decoded[["p_state1", "p_state2"]].sum(axis=1), 1.0)
    expected = model.viterbi(tracks.prepare(io.read_tracks(track_file))) + 1
    np.testing.assert_array_equal(decoded["state"], expected)


def test_fit_reads_renamed_columns_without_times(track_file, tmp_path, capsys):
    renamed = pd.read_csv(track_file).drop(columns="time")
    renamed.columns = ["animal", "east", "north"]
    path = tmp_path / "no_time.csv"
    renamed.to_csv(path, index=False)
    model_path = tmp_path / "m.json"
    code = main(
        [
            "fit",
            str(path),
            "--id-col",
            "animal",
            "--time-col",
            "none",
            "--x-col",
            "east",
            "--y-col",
            "north",
            "--scale",
            "1000",
            "--starts",
            "1",
            "-o",
            str(model_path),
        ]
    )
    assert code == 0
    model = MovementHMM.load(model_path)
    assert np.isnan(model.dt) and model.step_unit == "km"
    assert model.step.mean[1] == pytest.approx(0.12, rel=0.2)


def test_errors_are_reported_without_traceback(track_file, tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema": "hmmtrack.movement_hmm", "version": 7}')
    code = main(["decode", str(track_file), "--model", str(bad), "-o", str(tmp_path / "s.csv")])
    assert code == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "'version'" in err
    code = main(["fit", str(tmp_path / "absent.csv"), "-o", str(tmp_path / "m.json")])
    assert code == 2
    model_path = tmp_path / "km.json"
    main(["fit", str(track_file), "--scale", "1000", "--starts", "1", "-o", str(model_path)])
    capsys.readouterr()
    code = main(["decode", str(track_file), "--model", str(model_path), "-o", str(bad)])
    assert code == 2
    assert "fitted to steps in km; --scale 1 gives m" in capsys.readouterr().err


def as_movebank(track_file, lon0: float, lat0: float) -> pd.DataFrame:
    """The track file as a Movebank export: metres about (lon0, lat0) turned to degrees."""
    table = pd.read_csv(track_file)
    return pd.DataFrame(
        {
            "timestamp": pd.to_datetime(table["time"]).dt.strftime("%Y-%m-%d %H:%M:%S.000"),
            "location-long": lon0 + table["x"] / (111_320.0 * np.cos(np.radians(lat0))),
            "location-lat": lat0 + table["y"] / 110_574.0,
            "individual-local-identifier": table["id"],
        }
    )


def test_fit_reads_movebank_lon_lat(track_file, tmp_path):
    path = tmp_path / "movebank.csv"
    as_movebank(track_file, -118.2, 33.7).to_csv(path, index=False)
    model_path = tmp_path / "m.json"
    code = main(["fit", str(path), "--format", "movebank", "--starts", "1", "-o", str(model_path)])
    assert code == 0
    model = MovementHMM.load(model_path)
    assert model.dt == 60.0
    np.testing.assert_allclose(model.step.mean, TRUE.step.mean, rtol=0.2)


def test_fit_with_transition_and_emission_formulas(track_file, tmp_path, capsys):
    table = pd.read_csv(track_file)
    hour = pd.to_datetime(table["time"]).dt.hour + pd.to_datetime(table["time"]).dt.minute / 60
    table.assign(cosT=np.cos(2 * np.pi * hour / 24), sinT=np.sin(2 * np.pi * hour / 24)).to_csv(
        track_file, index=False
    )
    model_path = tmp_path / "model.json"
    arguments = ["fit", str(track_file), "--starts", "1", "-o", str(model_path)]
    assert main([*arguments, "--formula", "transition ~ cosT + sinT"]) == 0
    printed = capsys.readouterr().out
    assert "transition coefficients (~ cosT + sinT) on the data's scale" in printed
    block = json.loads(model_path.read_text())["coefficients"]
    assert block["formula"] == "~ cosT + sinT"
    assert block["columns"] == ["Intercept", "cosT", "sinT"]
    assert np.array(block["values_data_scale"]).shape == (2, 3)
    model_path.unlink()
    assert main([*arguments, "--covariates", "cosT", "sinT"]) == 0
    assert json.loads(model_path.read_text())["coefficients"] == block
    model_path.unlink()
    assert main([*arguments, "--formula", "step.mean ~ cosT", "--formula", "~ sinT"]) == 0
    assert "step.mean coefficients (~ cosT, link scale)" in capsys.readouterr().out
    document = json.loads(model_path.read_text())
    assert document["version"] == 3 and document["coefficients"]["formula"] == "~ sinT"
    assert document["step"]["formulas"]["mean"]["columns"] == ["Intercept", "cosT"]
    model_path.unlink()
    assert main([*arguments, "--formula", "step.shape ~ cosT"]) != 0
    assert "the parameters that take a formula are ['mean', 'sd']" in capsys.readouterr().err
    assert main([*arguments, "--stream", "cosT=normal", "--formula", "cosT.mean ~ sinT"]) == 0
    document = json.loads(model_path.read_text())
    assert document["streams"]["cosT"]["family"] == "normal"
    assert document["streams"]["cosT"]["formulas"]["mean"]["formula"] == "~ sinT"
    assert main([*arguments, "--stream", "cosT"]) != 0
    assert "expected COLUMN=FAMILY" in capsys.readouterr().err


def test_decode_refuses_another_time_step_unless_regularised_or_allowed(track_file, tmp_path):
    """A model fitted at 60 s decodes 20 s tracks only after --regularise 60 or with
    --allow-other-step; the regularised track is the 60 s grid (states equal to decoding
    the original 60 s fixes, which the grid interpolates exactly)."""
    model_path = tmp_path / "m.json"
    replace(TRUE, dt=60.0).save(model_path)
    table = pd.read_csv(track_file)
    fine = []
    for _, animal in table.groupby("id", sort=False):
        times = pd.to_datetime(animal["time"])
        grid = pd.date_range(times.iloc[0], times.iloc[-1], freq="20s")
        seconds = (grid - times.iloc[0]).total_seconds()
        given = (times - times.iloc[0]).dt.total_seconds()
        fine.append(
            pd.DataFrame(
                {
                    "id": animal["id"].iloc[0],
                    "time": grid.strftime("%Y-%m-%dT%H:%M:%SZ"),
                    "x": np.interp(seconds, given, animal["x"]),
                    "y": np.interp(seconds, given, animal["y"]),
                }
            )
        )
    fine_path = tmp_path / "fine.csv"
    pd.concat(fine).to_csv(fine_path, index=False)
    decode = ["decode", str(fine_path), "--model", str(model_path), "-o"]
    assert main([*decode, str(tmp_path / "refused.csv")]) == 2
    assert not (tmp_path / "refused.csv").exists()
    assert main([*decode, str(tmp_path / "allowed.csv"), "--allow-other-step"]) == 0
    assert len(pd.read_csv(tmp_path / "allowed.csv")) == 2 * (3 * 399 + 1)
    assert main([*decode, str(tmp_path / "grid.csv"), "--regularise", "60"]) == 0
    direct = ["decode", str(track_file), "--model", str(model_path), "-o"]
    assert main([*direct, str(tmp_path / "direct.csv")]) == 0
    on_grid, original = pd.read_csv(tmp_path / "grid.csv"), pd.read_csv(tmp_path / "direct.csv")
    assert len(on_grid) == len(original) == 800
    np.testing.assert_allclose(on_grid[["x", "y"]], original[["x", "y"]], atol=1e-6)
    np.testing.assert_array_equal(on_grid["state"], original["state"])


def test_library_decoding_checks_the_time_step(track_file):
    model = replace(TRUE, dt=120.0)
    prepared = tracks.prepare(io.read_tracks(track_file))
    for method in (model.viterbi, model.state_probabilities, model.score):
        with pytest.raises(ValueError, match=r"time step 60 s .* model's 120 s"):
            method(prepared)
        method(prepared, allow_other_step=True)
    TRUE.viterbi(prepared)  # a model without a time step checks nothing


def test_movebank_export_with_empty_fixes_crs_and_figures(track_file, tmp_path, capsys):
    """A Movebank export with rows without a fix: refused naming --missing, read with
    --missing drop (the decoded rows then align to the file, empty states at those lines),
    projected by --crs, with the figures from fit --plot and from hmmtrack plot."""
    movebank = as_movebank(track_file, -114.0, 51.0)
    movebank.loc[[10, 500], ["location-long", "location-lat"]] = np.nan
    path = tmp_path / "movebank.csv"
    movebank.to_csv(path, index=False)
    model_path = tmp_path / "m.json"
    fit = ["fit", str(path), "--format", "movebank", "--starts", "1", "-o", str(model_path)]
    assert main(fit) == 2
    err = capsys.readouterr().err
    assert "lines 12, 502" in err and "--missing drop" in err and "--missing keep" in err
    assert main(fit + ["--crs", "EPSG:4326", "--missing", "drop"]) == 2
    assert "not a projected CRS in metres" in capsys.readouterr().err
    figures = tmp_path / "figures"
    names = ["--state-names", "slow,fast"]
    options = ["--missing", "drop", "--crs", "EPSG:32611"]
    assert main(fit + options + names + ["--plot", str(figures)]) == 0
    printed = capsys.readouterr().out
    assert "states: 1 = slow, 2 = fast" in printed
    written = sorted(p.name for p in figures.iterdir())
    assert written == ["densities.png", "residuals.png", "tracks.png"]
    model = MovementHMM.load(model_path)
    np.testing.assert_allclose(model.step.mean, TRUE.step.mean, rtol=0.2)

    states = tmp_path / "states.csv"
    decode = ["decode", str(path), "--format", "movebank", "--model", str(model_path)]
    assert main(decode + options + names + ["-o", str(states)]) == 0
    decoded = pd.read_csv(states)
    assert decoded["line"].tolist() == list(range(2, 802))  # one row per file row, in order
    assert decoded["state"].isna().tolist() == [i in (10, 500) for i in range(800)]
    assert set(decoded["state"].dropna()) == {1, 2}
    assert set(decoded["state_name"].dropna()) == {"slow", "fast"}
    assert decoded["time"].iloc[0] == "2024-06-01T00:00:00.000Z"
    assert "(slow)" in capsys.readouterr().out

    again = tmp_path / "again"
    plot = ["plot", str(model_path), str(path), "--format", "movebank", *options, "-o"]
    assert main(plot + [str(again)]) == 0
    assert sorted(p.name for p in again.iterdir()) == written
    assert main(plot + [str(again), "--state-names", "a,b,c"]) == 2
    assert "--state-names" in capsys.readouterr().err


def test_irregular_fixes_warn_and_the_named_cli_fixes_work(track_file, tmp_path, capsys, caplog):
    """Fixes up to 20 s off a 60 s schedule: fit warns naming the CLI options; the CRW
    regularisation and the multiple imputation that it names run from the CLI."""
    table = pd.read_csv(track_file)
    table = table[table["id"] == "a"].head(200).copy()
    jitter = np.random.default_rng(2).uniform(-20.0, 20.0, len(table))
    times = pd.to_datetime(table["time"]) + pd.to_timedelta(jitter, unit="s")
    table["time"] = times.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    path = tmp_path / "irregular.csv"
    table.to_csv(path, index=False)
    model_path = tmp_path / "m.json"
    fit = ["fit", str(path), "--starts", "1", "-o", str(model_path)]
    assert main(fit) == 0
    warned = " ".join(r.getMessage() for r in caplog.records)
    for option in ("--regularise STEP", "--regularise-method crw", "--impute M"):
        assert option in warned
    caplog.clear()
    assert main([*fit, "--regularise", "60", "--regularise-method", "crw"]) == 0
    assert "time steps vary" not in " ".join(r.getMessage() for r in caplog.records)
    assert MovementHMM.load(model_path).dt == 60.0
    capsys.readouterr()
    assert main([*fit, "--regularise", "60", "--impute", "2"]) == 0
    printed = capsys.readouterr().out
    assert "2 tracks imputed on a 60 s grid" in printed and "fraction_missing" in printed
    pooled = MovementHMM.load(model_path)
    assert np.isnan(pooled.log_likelihood) and pooled.dt == 60.0
    # the library's multiple imputation with the same seed (the CLI adds nothing)
    draws = crw.impute(io.read_tracks(path), 60.0, 2, np.random.default_rng(1))
    imputed = [tracks.prepare(draw) for draw in draws]
    direct = imputation.fit_imputed(imputed, 2, seed=1, n_starts=1).model
    np.testing.assert_allclose(pooled.step.mean, direct.step.mean, rtol=1e-9)
    np.testing.assert_allclose(pooled.transition, direct.transition, rtol=1e-9)
    assert pooled.step.mean[0] < TRUE.step.mean[1] < pooled.step.mean[1] * 1.3


def test_fit_control_check_starts_and_stored_state_names(track_file, tmp_path, capsys):
    """--fix, --equal, --stationary and --state-names reach the model file; --check-starts
    prints each start (starts.png with --plot: starts_figure is tested in test_constraints;
    the standard figures take 10 s); decode takes the stored names."""
    model_path = tmp_path / "m.json"
    argv = ["fit", str(track_file), "--check-starts", "3", "--fix", "step.mean[1]=20"]
    argv += ["--equal", "angle.mean[1]==angle.mean[2]", "--stationary"]
    argv += ["--state-names", "slow,fast", "-o", str(model_path)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "check of starting values: " in printed and "of 3 starts reached the best" in printed
    assert "fixed: step.mean[1]=20" in printed and "states: 1 = slow, 2 = fast" in printed
    model = MovementHMM.load(model_path)
    assert model.step.mean[0] == pytest.approx(20.0) and model.state_names == ("slow", "fast")
    assert model.angle.mean[0] == model.angle.mean[1] and model.control.stationary
    np.testing.assert_allclose(model.initial, model.stationary(), atol=1e-10)
    states = tmp_path / "states.csv"
    assert main(["decode", str(track_file), "--model", str(model_path), "-o", str(states)]) == 0
    assert set(pd.read_csv(states)["state_name"]) == {"slow", "fast"}
    assert "(slow)" in capsys.readouterr().out


def test_fit_with_categorical_and_zero_inflated_count_streams(track_file, tmp_path):
    """--stream COL=categorical (codes 1..C) and COL=zipoisson, saved and read back."""
    table = pd.read_csv(track_file)
    rng = np.random.default_rng(2)
    table["behaviour"] = rng.integers(1, 4, len(table)).astype(float)
    table.loc[::50, "behaviour"] = np.nan
    table["dives"] = np.where(rng.random(len(table)) < 0.3, 0, rng.poisson(4.0, len(table)))
    table.to_csv(track_file, index=False)
    model_path = tmp_path / "model.json"
    arguments = ["fit", str(track_file), "--starts", "1", "-o", str(model_path)]
    streams = ["--stream", "behaviour=categorical", "--stream", "dives=zipoisson"]
    assert main([*arguments, *streams]) == 0
    document = json.loads(model_path.read_text())
    assert document["version"] == 3
    assert document["streams"]["behaviour"]["family"] == "categorical"
    prob = np.array(document["streams"]["behaviour"]["prob"])
    assert prob.shape == (2, 3)
    np.testing.assert_allclose(prob.sum(axis=1), 1.0)
    np.testing.assert_allclose(prob, 1 / 3, atol=0.06)  # the codes were drawn uniformly
    dives = document["streams"]["dives"]
    assert dives["family"] == "zipoisson"
    assert np.all((np.array(dives["zero_mass"]) > 0.15) & (np.array(dives["zero_mass"]) < 0.45))
    assert MovementHMM.load(model_path).to_dict() == document
