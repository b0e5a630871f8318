"""Tests of hmmtrack.io: time parsing, tracks / Movebank / detections / receivers readers,
error messages naming files, lines and columns, and the estimates writer."""

from __future__ import annotations

import logging
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod

from hmmtrack import io, tracks

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
VUE = SHARED / "yaps_ssu1" / "VUE_Export_ssu1.csv"
YAPS_DETECTIONS = SHARED / "yaps_ssu1" / "ssu1_detections.csv"
ELK = SHARED / "elk_data.csv"
FATHOM = Path(__file__).resolve().parent / "data" / "fathom_vr2ar_546310.csv"
UTC = timezone.utc


def epoch(*args, microsecond=0, tz=UTC):
    return datetime(*args, microsecond=microsecond, tzinfo=tz).timestamp()


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------- times


def test_times_with_offsets_z_and_milliseconds(tmp_path):
    path = write(
        tmp_path,
        "t.csv",
        "id,time,x,y\n"
        "a,2022-07-21T16:00:03.125Z,0,0\n"
        "a,2022-07-21T18:00:04.5+02:00,1,0\n"
        "a,2022-07-21 10:00:05.0001-06:00,2,0\n",
    )
    t = io.read_tracks(path)["time"].to_numpy()
    expected = [
        epoch(2022, 7, 21, 16, 0, 3, microsecond=125000),
        epoch(2022, 7, 21, 16, 0, 4, microsecond=500000),
        epoch(2022, 7, 21, 16, 0, 5, microsecond=100),
    ]
    np.testing.assert_allclose(t, expected, rtol=0, atol=1e-6)


def test_naive_times_need_a_time_zone(tmp_path):
    path = write(
        tmp_path, "naive.csv", "id,time,x,y\na,2022-07-21 10:00:00,0,0\na,2022-07-21 10:01:00,1,0\n"
    )
    with pytest.raises(
        ValueError,
        match=r"naive.csv lines 2, 3: column 'time' has times "
        r"without a UTC offset .*tz=",
    ):
        io.read_tracks(path)
    local = io.read_tracks(path, tz="America/Costa_Rica")["time"].to_numpy()
    np.testing.assert_allclose(local, [epoch(2022, 7, 21, 16), epoch(2022, 7, 21, 16, 1)])
    utc = io.read_tracks(path, tz="UTC")["time"].to_numpy()
    np.testing.assert_allclose(local - utc, 6 * 3600.0)


def test_unparseable_time_names_line(tmp_path):
    path = write(
        tmp_path, "bad.csv", "id,time,x,y\na,2022-07-21T10:00:00Z,0,0\na,yesterday noon,1,0\n"
    )
    with pytest.raises(ValueError, match=r"bad.csv line 3: column 'time' is not an ISO 8601"):
        io.read_tracks(path)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 4_102_444_800_000))  # 1970 .. 2100, in ms
def test_format_then_parse_times_round_trip(ms):
    seconds = ms / 1000.0
    text = io.format_times(np.array([seconds]))
    assert text[0].endswith("Z") and len(text[0]) == 24
    table = pd.DataFrame({"time": text}, index=pd.Index([2], name="line"))
    table.attrs["source"] = "memory"
    back = io.parse_times(table, "time", None)
    assert back[0] == pytest.approx(seconds, abs=1e-6)


# ------------------------------------------------------------------------- tracks


def test_read_tracks_plain_keeps_covariates_and_line_numbers(tmp_path):
    path = write(
        tmp_path,
        "fixes.csv",
        "animal,t,east,north,temp\n"
        "b,2022-01-01T00:00:00Z,10,20,4.5\n"
        "a,2022-01-01T00:00:00Z,0,0,3.0\n"
        "\n"
        "a,2022-01-01T00:01:00Z,3,4,3.5\n"
        "b,2022-01-01T00:02:00Z,13,24,5.0\n",
    )
    df = io.read_tracks(path, id_col="animal", time_col="t", x_col="east", y_col="north")
    assert list(df.columns) == ["id", "time", "x", "y", "temp"]
    assert list(df["id"]) == ["b", "b", "a", "a"]
    assert list(df.index) == [2, 6, 3, 5]
    assert df.index.name == "line" and df.attrs["source"] == str(path)
    np.testing.assert_allclose(df["temp"], [4.5, 5.0, 3.0, 3.5])
    p = tracks.prepare(df)
    np.testing.assert_allclose(p["step"], [5.0, np.nan, 5.0, np.nan])
    np.testing.assert_allclose(p["speed"], [5.0 / 120.0, np.nan, 5.0 / 60.0, np.nan])


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            "a,2022-01-01T00:00:00Z,0,0\na,2022-01-01T00:00:00Z,1,0\n",
            r"f.csv lines 2, 3: duplicate times within animal 'a'",
        ),
        (
            "a,2022-01-01T00:05:00Z,0,0\na,2022-01-01T00:00:00Z,1,0\n",
            r"f.csv lines 2, 3: decreasing times",
        ),
        (
            "a,2022-01-01T00:00:00Z,0,0\na,2022-01-01T00:01:00Z,1O,0\n",
            r"f.csv line 3: column 'x' must be numeric \(metres\), found '1O'",
        ),
        (
            "a,2022-01-01T00:00:00Z,0,0\nb,2022-01-01T00:01:00Z,1,0\nb,2022-01-01T00:02:00Z,1,1\n",
            r"f.csv line 2: animal\(s\) \['a'\] have fewer than 2 fixes",
        ),
        (
            "a,2022-01-01T00:00:00Z,0,0\na,2022-01-01T00:01:00Z,,0\n",
            r"f.csv line 3: empty coordinates in column\(s\) \['x', 'y'\]",
        ),
        (
            "a,2022-01-01T00:00:00Z,0,0\n,2022-01-01T00:01:00Z,1,0\n",
            r"f.csv line 3: the animal id is empty",
        ),
    ],
)
def test_read_tracks_errors_name_file_lines_and_columns(tmp_path, body, message):
    path = write(tmp_path, "f.csv", "id,time,x,y\n" + body)
    with pytest.raises(ValueError, match=message):
        io.read_tracks(path)


def test_read_tracks_missing_columns_lists_what_was_found(tmp_path):
    path = write(tmp_path, "f.csv", "id,when,x,y\na,0,0,0\n")
    with pytest.raises(
        ValueError,
        match=r"needs column\(s\) 'time' \(time\); the file has "
        r"\['id', 'when', 'x', 'y'\]",
    ):
        io.read_tracks(path)


def test_dropped_rows_are_reported(tmp_path, caplog):
    path = write(tmp_path, "f.csv", "id,time,x,y\na,0,0,0\na,60,,\na,120,1,1\na,180,2,2\n")
    with caplog.at_level(logging.WARNING, logger="hmmtrack.io"):
        df = io.read_tracks(path, missing_coordinates="drop")
    assert list(df.index) == [2, 4, 5]
    assert df.attrs["dropped"] == [{"rows": [3], "reason": "empty coordinates in ['x', 'y']"}]
    assert "dropped 1 row(s)" in caplog.text
    kept = io.read_tracks(path, missing_coordinates="keep")
    assert len(kept) == 4 and np.isnan(kept["x"].iloc[1])


@pytest.mark.skipif(not ELK.exists(), reason="real elk data absent (../shared/data)")
def test_read_elk_without_times():
    df = io.read_tracks(ELK, id_col="ID", time_col=None, x_col="Easting", y_col="Northing")
    assert "time" not in df.columns and len(df) == 735
    assert df["id"].value_counts().to_dict() == {
        "elk-115": 194,
        "elk-163": 159,
        "elk-287": 164,
        "elk-363": 218,
    }
    p = tracks.prepare(df, scale=1000.0)
    assert int(p["step"].isna().sum()) == 4 and int(p["angle"].isna().sum()) == 10
    assert p["step"].sum() == pytest.approx(938.304079059, abs=1e-6)
    assert p["dt"].isna().all()


# ------------------------------------------------------------------------- Movebank


def movebank_file(tmp_path, lons, lats):
    lines = ["event-id,timestamp,location-long,location-lat,individual-local-identifier"]
    for i, (lon, lat) in enumerate(zip(lons, lats, strict=True)):
        lines.append(f"{i},2020-05-01 12:{i:02d}:00.000,{lon},{lat},shark-1")
    return write(tmp_path, "movebank.csv", "\n".join(lines) + "\n")


def test_movebank_projects_to_utm_with_true_distances(tmp_path):
    lons = np.array([-119.70, -119.69, -119.675, -119.66])
    lats = np.array([34.40, 34.405, 34.401, 34.39])
    df = io.read_movebank(movebank_file(tmp_path, lons, lats))
    proj = io.Projection.from_frame(df)
    assert "UTM zone 11N" in df.attrs["crs"]
    np.testing.assert_allclose(df["time"].iloc[1] - df["time"].iloc[0], 60.0)
    _, _, geodesic = Geod(ellps="WGS84").inv(lons[:-1], lats[:-1], lons[1:], lats[1:])
    step = np.hypot(np.diff(df["x"]), np.diff(df["y"]))
    np.testing.assert_allclose(step, geodesic, rtol=1e-3)  # UTM scale error < 0.1 %
    lon, lat = proj.to_lonlat(df["x"], df["y"])
    np.testing.assert_allclose(lon, lons, atol=1e-9)
    np.testing.assert_allclose(lat, lats, atol=1e-9)


def test_local_projection_keeps_distances_from_centre_exact(tmp_path):
    lons = np.array([179.8, -179.9, 179.95])  # across the antimeridian
    lats = np.array([-16.0, -16.1, -16.05])
    df = io.read_movebank(movebank_file(tmp_path, lons, lats), projection="local")
    assert "Azimuthal Equidistant" in df.attrs["crs"] or "aeqd" in df.attrs["crs"]
    proj = io.Projection.from_frame(df)
    lon0, lat0 = proj.to_lonlat(np.array([0.0]), np.array([0.0]))
    assert abs(lon0[0]) > 179.0
    _, _, distance = Geod(ellps="WGS84").inv(np.full(3, lon0[0]), np.full(3, lat0[0]), lons, lats)
    np.testing.assert_allclose(np.hypot(df["x"], df["y"]), distance, rtol=1e-9)


@pytest.mark.parametrize(
    ("lon", "lat", "message"),
    [
        (-119.7, 95.0, r"line 3: latitude out of \[-90, 90\]"),
        (-219.7, 34.0, r"line 3: longitude out of \[-180, 180\]"),
    ],
)
def test_movebank_rejects_out_of_range_coordinates(tmp_path, lon, lat, message):
    path = movebank_file(tmp_path, [-119.7, lon], [34.4, lat])
    with pytest.raises(ValueError, match=message):
        io.read_movebank(path)


# ------------------------------------------------------------------------- detections


@pytest.mark.skipif(not VUE.exists(), reason="real VUE export absent (../shared/data)")
def test_real_vue_export_loads_with_millisecond_times():
    det = io.read_detections(VUE)
    assert det.attrs["format"] == "vue" and len(det) == 15373
    first = det.loc[2]
    assert first["time"] == pytest.approx(
        epoch(2019, 9, 9, 16, 4, 11, microsecond=193000), abs=1e-6
    )
    assert (first["receiver"], first["receiver_model"], first["receiver_serial"]) == (
        "VR2W-128355",
        "VR2W",
        "128355",
    )
    assert (first["transmitter"], first["code_space"], first["transmitter_id"]) == (
        "A69-1602-59335",
        "A69-1602",
        "59335",
    )
    assert first["station"] == "CESI10"
    ms = det["time"].to_numpy() * 1000.0
    np.testing.assert_allclose(ms, np.round(ms), atol=1e-3)  # whole milliseconds ...
    assert np.mean(np.round(ms) % 1000 != 0) > 0.9  # ... and not rounded to seconds
    assert np.all(np.diff(det["time"].to_numpy()) >= 0)
    tag = io.read_detections(VUE, transmitter="15266")
    assert set(tag["transmitter"]) == {"A69-1602-15266"}
    assert len(tag) + tag.attrs["other_transmitters"] == 15373


@pytest.mark.skipif(not (VUE.exists() and YAPS_DETECTIONS.exists()), reason="yaps data absent")
def test_real_vue_times_equal_yaps_epoch_plus_fraction():
    """yaps's own table of these detections (epo + frac, by receiver serial and tag) is an
    independent reading of the same export: every one of its rows must be found, to 1 us."""
    det = io.read_detections(VUE)
    yaps = pd.read_csv(YAPS_DETECTIONS)
    det = det.assign(
        serial=det["receiver_serial"].astype(int), tag=det["transmitter_id"].astype(int)
    )
    merged = yaps.assign(t=yaps["epo"] + yaps["frac"]).merge(det, on=["serial", "tag"])
    matched = merged[np.abs(merged["t"] - merged["time"]) < 1e-6]
    assert len(yaps) == 9476
    assert matched[["serial", "tag", "t"]].drop_duplicates().shape[0] == len(yaps)


def test_fathom_det_records():
    assert io.detect_format(FATHOM) == "fathom"
    det = io.read_detections(FATHOM)
    assert list(det.index) == [11, 12, 13, 15, 16]  # DIAG/TEMP/config lines ignored
    expected = [
        epoch(2022, 7, 21, 16, 0, 3, microsecond=125000),
        epoch(2022, 7, 21, 16, 0, 11, microsecond=304700),
        epoch(2022, 7, 21, 16, 0, 19, microsecond=483900),
        epoch(2022, 7, 21, 16, 0, 25, microsecond=2100),
        epoch(2022, 7, 21, 16, 0, 35, microsecond=841100) + 0.0123,  # time correction added
    ]
    np.testing.assert_allclose(det["time"], expected, rtol=0, atol=1e-6)
    assert set(det["receiver"]) == {"VR2AR-546310"}
    assert list(det["transmitter_id"]) == ["15266", "15266", "15266", "60774", "15266"]
    np.testing.assert_allclose(det["signal_strength"], [-38.2, -40.9, -43.5, -22.1, -47.0])
    one = io.read_detections(FATHOM, transmitter="A69-1602-15266")
    assert len(one) == 4 and one.attrs["other_transmitters"] == 1


def test_fathom_without_det_desc_is_refused(tmp_path):
    path = write(
        tmp_path,
        "f.csv",
        "VEMCO DATA LOG,2.0.0,x\nRECORD TYPE,FIELD\nDET,2022-07-21 16:00:03.1250\n",
    )
    with pytest.raises(ValueError, match="no DET_DESC line"):
        io.read_detections(path)


def test_plain_detections_sorted_with_extra_columns(tmp_path):
    path = write(
        tmp_path,
        "det.csv",
        "time,receiver,transmitter,depth\n"
        "2022-07-21T16:00:11.304Z,auv2,A69-1602-15266,10.5\n"
        "2022-07-21T16:00:03.125Z,auv1,A69-1602-15266,10.7\n",
    )
    det = io.read_detections(path)
    assert det.attrs["format"] == "plain"
    assert list(det.index) == [3, 2] and list(det["receiver"]) == ["auv1", "auv2"]
    np.testing.assert_allclose(det["depth"], [10.7, 10.5])
    numeric = write(tmp_path, "num.csv", "time,receiver,transmitter\n1658419203.125,r,t\n")
    assert io.read_detections(numeric)["time"].iloc[0] == 1658419203.125
    empty = write(tmp_path, "e.csv", "time,receiver,transmitter\n1.0,,t\n")
    with pytest.raises(ValueError, match=r"e.csv line 2: column 'receiver' is empty"):
        io.read_detections(empty)


# ------------------------------------------------------------------------- receivers


def test_read_receivers_lonlat_gps_and_moored(tmp_path):
    path = write(
        tmp_path,
        "rx.csv",
        "receiver,time,lon,lat\n"
        "boat,2022-07-21T16:00:00Z,-85.80,10.90\n"
        "buoy,,-85.79,10.91\n"
        "boat,2022-07-21T16:00:10Z,-85.801,10.9005\n",
    )
    rx = io.read_receivers(path)
    assert list(rx["receiver"]) == ["boat", "boat", "buoy"]
    assert np.isnan(rx["time"].iloc[2]) and rx["time"].iloc[1] - rx["time"].iloc[0] == 10.0
    proj = io.Projection.from_frame(rx)
    lon, lat = proj.to_lonlat(rx["x"], rx["y"])
    np.testing.assert_allclose(lon, [-85.80, -85.801, -85.79], atol=1e-9)
    np.testing.assert_allclose(lat, [10.90, 10.9005, 10.91], atol=1e-9)


def test_read_receivers_xy_without_time_column_and_errors(tmp_path):
    moored = io.read_receivers(write(tmp_path, "m.csv", "receiver,x,y\nA,0,0\nB,100,5\n"))
    assert moored["time"].isna().all() and "crs" not in moored.attrs
    bad = write(tmp_path, "b.csv", "receiver,time,x,y\nA,,0,0\nA,,1,1\n")
    with pytest.raises(ValueError, match=r"b.csv lines 2, 3: receiver 'A' has 2 rows"):
        io.read_receivers(bad)
    unsorted = write(tmp_path, "u.csv", "receiver,time,x,y\nA,10,0,0\nA,5,1,1\n")
    with pytest.raises(ValueError, match=r"u.csv lines 2, 3: times of receiver 'A' must be"):
        io.read_receivers(unsorted)


# ------------------------------------------------------------------------- writing


def test_write_estimates_round_trip(tmp_path):
    proj = io.Projection.utm(np.array([-85.8]), np.array([10.9]))
    x0, y0 = proj.to_xy(np.array([-85.8]), np.array([10.9]))
    t0 = epoch(2022, 7, 21, 16, 0, 3, microsecond=125000)
    est = pd.DataFrame(
        {
            "time": t0 + np.arange(3.0),
            "x": x0[0] + np.array([0.0, 10, 20]),
            "y": y0[0] + np.zeros(3),
            "sqrt_lambda1": [50.0, 20.0, 8.0],
        }
    )
    out = tmp_path / "est.csv"
    io.write_estimates(est, out, projection=proj)
    back = pd.read_csv(out)
    assert list(back.columns) == ["time", "x", "y", "lon", "lat", "sqrt_lambda1"]
    assert back["time"].iloc[0] == "2022-07-21T16:00:03.125Z"
    again = io.read_tracks(out, id_col=None, missing_coordinates="error")
    np.testing.assert_allclose(again["time"], est["time"], atol=1e-6)
    np.testing.assert_allclose(again["x"], est["x"], rtol=1e-9)
    assert back["lon"].iloc[0] == pytest.approx(-85.8, abs=1e-8)
    forward = (
        (datetime.fromtimestamp(t0, UTC) + timedelta(seconds=2))
        .isoformat(timespec="milliseconds")
        .replace("+00:00", "Z")
    )
    assert back["time"].iloc[2] == forward


def test_other_epoch_times_are_written_to_the_microsecond(tmp_path):
    """A ping's ``emission_time`` (epoch s) keeps its microseconds; 12 significant digits
    would round 1658419203.123456 to 1658419203.12."""
    emission = np.array([1658419203.123456, np.nan])
    est = pd.DataFrame(
        {
            "time": [1658419203.0, 1658419204.0],
            "x": [1.0, 2.0],
            "y": [3.0, 4.0],
            "emission_time": emission,
        }
    )
    out = tmp_path / "pings.csv"
    io.write_estimates(est, out)
    back = pd.read_csv(out)
    assert back["emission_time"].iloc[0] == pytest.approx(1658419203.123456, abs=5e-7)
    assert np.isnan(back["emission_time"].iloc[1])
    assert out.read_text().splitlines()[1].endswith(",1658419203.123456")


def test_an_id_part_shared_by_two_code_spaces_is_refused(tmp_path):
    """``42`` names two tags here; merging them would track two animals as one."""
    from hmmtrack.tracking.pipeline import select_transmitter

    path = tmp_path / "d.csv"
    path.write_text(
        "time,receiver,transmitter\n"
        "2024-01-01T00:00:00Z,a,A69-1602-42\n"
        "2024-01-01T00:00:05Z,a,A69-9001-42\n"
        "2024-01-01T00:00:09Z,b,A69-1602-42\n"
        "2024-01-01T00:00:12Z,b,A69-1602-7\n"
    )
    with pytest.raises(ValueError, match=r"'42' is ambiguous.*\['A69-1602-42', 'A69-9001-42'\]"):
        io.read_detections(path, transmitter="42")
    table = io.read_detections(path)
    with pytest.raises(ValueError, match=r"d.csv.*full ID, e.g. --transmitter A69-1602-42"):
        io.read_detections(path, transmitter=["7", "42"])
    with pytest.raises(ValueError, match="ambiguous.*A69-9001-42"):
        select_transmitter(table, "42")
    assert select_transmitter(table, "A69-9001-42")["receiver"].tolist() == ["a"]
    assert select_transmitter(table, "7")["transmitter"].tolist() == ["A69-1602-7"]
    assert len(io.read_detections(path, transmitter="A69-1602-42")) == 2
