"""The names users call from hmmtrack.io, hmmtrack.hmm and hmmtrack.tracks (README.md,
docs/interfaces.md, notebooks) import from the package faces and are the intended objects."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np
import pandas as pd
import pytest

import hmmtrack.hmm.distributions.angles
import hmmtrack.hmm.distributions.families
import hmmtrack.hmm.distributions.steps
import hmmtrack.io.detections
import hmmtrack.io.estimates
import hmmtrack.io.geo
import hmmtrack.io.receivers
import hmmtrack.io.sequence
import hmmtrack.io.times
import hmmtrack.io.tracks
from hmmtrack import hmm, io, tracks
from hmmtrack.hmm import distributions

IO_FACE = {
    "read_tracks": hmmtrack.io.tracks,
    "read_movebank": hmmtrack.io.tracks,
    "read_detections": hmmtrack.io.detections,
    "detect_format": hmmtrack.io.detections,
    "VUE_COLUMNS": hmmtrack.io.detections,
    "read_receivers": hmmtrack.io.receivers,
    "validate_receivers": hmmtrack.io.receivers,
    "read_burst_sequence": hmmtrack.io.sequence,
    "write_estimates": hmmtrack.io.estimates,
    "read_truth": hmmtrack.io.estimates,
    "parse_times": hmmtrack.io.times,
    "format_times": hmmtrack.io.times,
    "Projection": hmmtrack.io.geo,
    "choose_projection": hmmtrack.io.geo,
    "bounds_in_metres": hmmtrack.io.geo,
}

DISTRIBUTIONS_FACE = {
    "Gamma": hmmtrack.hmm.distributions.steps,
    "Weibull": hmmtrack.hmm.distributions.steps,
    "LogNormal": hmmtrack.hmm.distributions.steps,
    "Exponential": hmmtrack.hmm.distributions.steps,
    "VonMises": hmmtrack.hmm.distributions.angles,
    "WrappedCauchy": hmmtrack.hmm.distributions.angles,
    "STEP_FAMILIES": hmmtrack.hmm.distributions.families,
    "ANGLE_FAMILIES": hmmtrack.hmm.distributions.families,
    "from_dict": hmmtrack.hmm.distributions.families,
    "initial_guess": hmmtrack.hmm.distributions.families,
}


@pytest.mark.parametrize(("name", "module"), IO_FACE.items())
def test_io_face_names_are_their_modules_objects(name, module):
    assert name in io.__all__
    assert getattr(io, name) is getattr(module, name)


@pytest.mark.parametrize(("name", "module"), DISTRIBUTIONS_FACE.items())
def test_distributions_face_names_are_their_modules_objects(name, module):
    assert name in distributions.__all__
    assert getattr(distributions, name) is getattr(module, name)


def test_hmm_face():
    """README's workflow names and the families, from hmmtrack.hmm."""
    from hmmtrack.hmm import fit, inference, model

    assert hmm.fit_movement_hmm is fit.fit_movement_hmm
    assert hmm.MovementHMMEstimator is fit.MovementHMMEstimator
    assert hmm.MovementHMM is model.MovementHMM
    assert hmm.forward_backward is inference.forward_backward
    assert hmm.viterbi is inference.viterbi
    for name in ("Gamma", "Weibull", "LogNormal", "Exponential", "VonMises", "WrappedCauchy"):
        assert getattr(hmm, name) is getattr(distributions, name)
    assert distributions.STEP_FAMILIES == {
        "gamma": hmm.Gamma,
        "weibull": hmm.Weibull,
        "lognormal": hmm.LogNormal,
        "exponential": hmm.Exponential,
    }
    assert distributions.ANGLE_FAMILIES == {
        "vonmises": hmm.VonMises,
        "wrappedcauchy": hmm.WrappedCauchy,
    }
    gamma = hmm.Gamma(mean=[1.0, 5.0], sd=[0.5, 2.0])
    assert distributions.from_dict(gamma.to_dict()) == gamma


def test_read_detections_reads_a_small_vue_export(tmp_path):
    header = ",".join(io.VUE_COLUMNS)
    path = tmp_path / "vue.csv"
    path.write_text(
        f"{header}\n"
        "2019-09-09 16:04:11.193,VR2W-128355,A69-1602-15266,,,,,,,\n"
        "2019-09-09 16:04:03.5,VR2AR-546310,A69-1602-15266,,,21.5,m,North,,\n"
    )
    table = io.read_detections(path)
    assert table.attrs["format"] == "vue"
    assert table.index.name == "line"
    assert table.index.tolist() == [3, 2]  # sorted by time, file lines kept
    expected = [
        datetime(2019, 9, 9, 16, 4, 3, 500000, tzinfo=timezone.utc).timestamp(),
        datetime(2019, 9, 9, 16, 4, 11, 193000, tzinfo=timezone.utc).timestamp(),
    ]
    np.testing.assert_allclose(table["time"], expected, rtol=0, atol=1e-6)
    assert table["receiver"].tolist() == ["VR2AR-546310", "VR2W-128355"]
    assert table["receiver_model"].tolist() == ["VR2AR", "VR2W"]
    assert table["receiver_serial"].tolist() == ["546310", "128355"]
    assert table["code_space"].tolist() == ["A69-1602", "A69-1602"]
    assert table["transmitter_id"].tolist() == ["15266", "15266"]
    assert table["sensor_value"].iloc[0] == 21.5
    assert table["station"].iloc[0] == "North"


def test_read_tracks_then_prepare(tmp_path):
    """README's first two calls: steps and angles of a right-angle turn."""
    path = tmp_path / "tracks.csv"
    path.write_text("id,time,x,y\na,0,0,0\na,10,30,0\na,20,30,40\n")
    prepared = tracks.prepare(io.read_tracks(path))
    np.testing.assert_allclose(prepared["step"], [30.0, 40.0, np.nan])
    np.testing.assert_allclose(prepared["angle"], [np.nan, np.pi / 2, np.nan])
    np.testing.assert_allclose(prepared["speed"], [3.0, 4.0, np.nan])
    assert tracks.describe_rows(prepared, [1]) == f"{path} line 3"


def test_times_round_trip_through_the_face():
    seconds = np.array([1568045051.193, 0.0])
    text = io.format_times(seconds)
    assert text.tolist() == ["2019-09-09T16:04:11.193Z", "1970-01-01T00:00:00.000Z"]
    table = pd.DataFrame({"time": text})
    np.testing.assert_allclose(io.parse_times(table, "time", tz=None), seconds, atol=1e-6)


def test_io_raises_value_errors_not_cli_errors(tmp_path):
    """io is below the CLI: bad input is a ValueError, which the CLI prints in one line."""
    projection = io.Projection.local(np.array([-118.0]), np.array([34.0]))
    with pytest.raises(ValueError, match="LON_MIN LON_MAX LAT_MIN LAT_MAX in degrees"):
        io.bounds_in_metres((389988.0, 390018.0, 3729991.0, 3730011.0), projection)
    xmin, xmax, ymin, ymax = io.bounds_in_metres((-118.001, -117.999, 33.999, 34.001), projection)
    assert xmin < 0 < xmax and ymin < 0 < ymax  # a box about the projection's centre
    assert xmax - xmin == pytest.approx(2 * 0.001 * 111_320 * np.cos(np.deg2rad(34)), rel=2e-3)
    truth = tmp_path / "truth.csv"
    truth.write_text("time,lon,lat\n0,-118,34\n1,-118,34\n")
    with pytest.raises(ValueError, match="needs receivers in lon/lat"):
        io.read_truth(truth, None)
    fixed = tmp_path / "fixed.csv"
    fixed.write_text("x,y\n5,-2\n")
    got = io.read_truth(fixed, None)
    assert got["time"].isna().all() and got[["x", "y"]].to_numpy().tolist() == [[5.0, -2.0]]


def test_tracks_face():
    """The track maths docs/interfaces.md names, with one value each."""
    assert tracks.wrap_angle(1.5 * np.pi) == pytest.approx(-0.5 * np.pi)
    table = pd.DataFrame({"id": "a", "time": [0.0, 10.0, 20.0, 500.0, 510.0], "x": 0.0, "y": 0.0})
    split = tracks.split_at_gaps(table, max_gap=100.0)
    assert split["segment"].tolist() == ["a#1", "a#1", "a#1", "a#2", "a#2"]
    with pytest.raises(ValueError, match="fewer than|at least|fixes"):
        tracks.validate_tracks(table.iloc[:1], min_fixes=2)
    assert callable(tracks.regularise)
