"""Tests of hmmtrack.tracks: hand-computed steps and angles, moveHMM's elk figures, gaps,
regular grids, validation messages and invariants (hypothesis)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack import tracks

ELK = Path(__file__).resolve().parents[2] / "shared" / "data" / "elk_data.csv"


def make(x, y, time=None, ids=None):
    data = {"id": ids if ids is not None else ["a"] * len(x), "x": x, "y": y}
    if time is not None:
        data["time"] = time
    return pd.DataFrame(data)


def test_prepare_hand_computed_square():
    df = make([0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0], time=[0.0, 10.0, 30.0, 60.0])
    p = tracks.prepare(df)
    np.testing.assert_allclose(p["step"], [1.0, 1.0, 1.0, np.nan])
    np.testing.assert_allclose(p["angle"], [np.nan, np.pi / 2, np.pi / 2, np.nan])
    np.testing.assert_allclose(p["dt"], [10.0, 20.0, 30.0, np.nan])
    np.testing.assert_allclose(p["speed"], [0.1, 0.05, 1 / 30, np.nan])
    np.testing.assert_allclose(p["angular_velocity"], [np.nan, np.pi / 40, np.pi / 60, np.nan])
    assert list(p["segment"]) == ["a"] * 4


def test_prepare_right_turn_is_negative_and_reversal_is_plus_pi():
    p = tracks.prepare(make([0.0, 3.0, 3.0, 3.0], [0.0, 0.0, -4.0, 0.0]))
    np.testing.assert_allclose(p["step"], [3.0, 4.0, 4.0, np.nan])
    np.testing.assert_allclose(p["angle"], [np.nan, -np.pi / 2, np.pi, np.nan])
    assert p["dt"].isna().all() and p["speed"].isna().all()


def test_oblique_reversal_is_plus_pi_despite_rounding():
    # heading difference is pi + 4e-16 here; a naive wrap returns -pi (found by hypothesis)
    p = tracks.prepare(make([-0.25, 2.75, -0.25], [0.0, -1.75, 0.0]))
    assert p["angle"].iloc[1] == np.pi
    assert tracks.wrap_angle(np.pi + 4e-16) == np.pi


def test_angle_next_to_zero_step_is_missing():
    p = tracks.prepare(make([0.0, 1.0, 1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 0.0, 1.0]))
    np.testing.assert_allclose(p["step"], [1.0, 0.0, 1.0, np.sqrt(2.0), np.nan])
    np.testing.assert_allclose(p["angle"], [np.nan, np.nan, np.nan, np.pi / 4, np.nan])


def test_missing_fix_gives_missing_steps_and_angles():
    p = tracks.prepare(make([0.0, 1.0, np.nan, 3.0, 4.0], [0.0] * 5))
    np.testing.assert_allclose(p["step"], [1.0, np.nan, np.nan, 1.0, np.nan])
    np.testing.assert_allclose(p["angle"], [np.nan] * 4 + [np.nan])


def test_segments_do_not_share_steps_and_interleaved_animals_are_grouped():
    df = make(
        [0.0, 10.0, 1.0, 20.0, 2.0],
        [0.0, 0.0, 0.0, 0.0, 0.0],
        time=[0.0, 0.0, 1.0, 1.0, 2.0],
        ids=["a", "b", "a", "b", "a"],
    )
    p = tracks.prepare(df)
    assert list(p["id"]) == ["a", "a", "a", "b", "b"]
    assert list(p.index) == [0, 2, 4, 1, 3]
    np.testing.assert_allclose(p["step"], [1.0, 1.0, np.nan, 10.0, np.nan])
    np.testing.assert_allclose(p["angle"], [np.nan, 0.0, np.nan, np.nan, np.nan])


def test_scale_divides_coordinates_and_steps():
    df = make([0.0, 3000.0, 3000.0], [0.0, 0.0, 4000.0], time=[0.0, 100.0, 300.0])
    p = tracks.prepare(df, scale=1000.0)
    np.testing.assert_allclose(p["step"], [3.0, 4.0, np.nan])
    np.testing.assert_allclose(p["x"], [0.0, 3.0, 3.0])
    np.testing.assert_allclose(p["speed"], [0.03, 0.02, np.nan])
    assert p.attrs["length_unit_m"] == 1000.0


@pytest.mark.skipif(not ELK.exists(), reason="real elk data absent (../shared/data)")
def test_elk_preprocessing_matches_movehmm():
    raw = pd.read_csv(ELK).rename(columns={"ID": "id", "Easting": "x", "Northing": "y"})
    p = tracks.prepare(raw, scale=1000.0)
    assert len(p) == 735
    assert int(p["step"].isna().sum()) == 4
    assert int(p["angle"].isna().sum()) == 10
    assert p["step"].sum() == pytest.approx(938.304079059, abs=1e-6)
    assert int((p["step"] == 0).sum()) == 1
    assert "dist_water" in p.columns


def test_split_at_gaps_labels_and_keeps_rows():
    df = make(
        np.arange(7.0),
        np.zeros(7),
        time=[0.0, 60.0, 120.0, 600.0, 660.0, 2000.0, 0.0],
        ids=["a"] * 6 + ["b"],
    )
    s = tracks.split_at_gaps(df, 180.0)
    assert list(s["segment"]) == ["a#1", "a#1", "a#1", "a#2", "a#2", "a#3", "b"]
    p = tracks.prepare(s)
    np.testing.assert_allclose(p["dt"], [60.0, 60.0, np.nan, 60.0, np.nan, np.nan, np.nan])


def test_split_at_gaps_reports_dropped_short_segments(caplog):
    df = make(np.arange(6.0), np.zeros(6), time=[0.0, 60.0, 120.0, 600.0, 2000.0, 2060.0])
    with caplog.at_level(logging.WARNING, logger="hmmtrack.tracks"):
        s = tracks.split_at_gaps(df, 180.0, min_fixes=2)
    assert list(s["segment"]) == ["a#1", "a#1", "a#1", "a#3", "a#3"]
    assert s.attrs["dropped"] == [
        {
            "rows": [3],
            "reason": "segment 'a#2' has fewer than 2 fixes (split_at_gaps, max_gap=180.0 s)",
        }
    ]
    assert "dropped 1 row(s)" in caplog.text


def test_regularise_interpolates_exactly_and_leaves_gaps_missing():
    # constant velocity (2, -1) m/s with irregular fixes, then a 500 s hole
    t = np.array([0.0, 7.0, 25.0, 31.0, 531.0, 540.0])
    df = make(2.0 * t, -1.0 * t, time=t)
    df["depth"] = 10.0 + t
    df["label"] = ["u", "v", "w", "x", "y", "z"]
    r = tracks.regularise(df, 10.0, max_gap=100.0)
    grid = np.arange(0.0, 541.0, 10.0)
    np.testing.assert_allclose(r["time"], grid)
    inside = grid <= 31.0
    np.testing.assert_allclose(r["x"][inside], 2.0 * grid[inside])
    np.testing.assert_allclose(r["y"][inside], -grid[inside])
    np.testing.assert_allclose(r["depth"][inside], 10.0 + grid[inside])
    hole = (grid > 31.0) & (grid < 531.0)
    assert r["x"][hole].isna().all() and r["depth"][hole].isna().all()
    np.testing.assert_allclose(r["x"][grid == 540.0], [1080.0])
    assert list(r["label"][:4]) == ["u", "v", "v", "w"]
    # without max_gap the long interval is interpolated too
    full = tracks.regularise(df, 10.0)
    np.testing.assert_allclose(full["x"], 2.0 * grid)


def test_regularise_next_to_a_missing_fix_gives_missing_rows():
    df = make([0.0, np.nan, 20.0, 30.0], [0.0, np.nan, 0.0, 0.0], time=[0.0, 10.0, 20.0, 30.0])
    r = tracks.regularise(df, 5.0)
    np.testing.assert_allclose(r["x"], [0, np.nan, np.nan, np.nan, 20, 25, 30])
    np.testing.assert_allclose(r["y"], [0, np.nan, np.nan, np.nan, 0, 0, 0])


@settings(max_examples=40, deadline=None)
@given(
    gaps=st.lists(
        st.lists(st.sampled_from([1.0, 2.5, 4.0, 5.0, 7.25, 10.0, 400.0]), min_size=0, max_size=8),
        min_size=1,
        max_size=4,
    ),
    step=st.sampled_from([2.5, 5.0, 6.0]),
)
def test_regularise_matches_interpolation_segment_by_segment(gaps, step):
    # oracle: np.interp on each animal's own fixes, NaN where the interval is over max_gap
    frames = []
    for i, animal_gaps in enumerate(gaps):
        t = 100.0 * i + np.r_[0.0, np.cumsum(animal_gaps)]
        frames.append(make(np.sin(t), np.cos(3.0 * t), time=t, ids=[f"a{i}"] * len(t)))
    df = pd.concat(frames, ignore_index=True)
    r = tracks.regularise(df, step, max_gap=50.0)
    for i, frame in enumerate(frames):
        t = frame["time"].to_numpy()
        grid = t[0] + step * np.arange(int(np.floor((t[-1] - t[0]) / step + 1e-9)) + 1)
        mine = r[r["id"] == f"a{i}"]
        np.testing.assert_array_equal(mine["time"], grid)
        expected = np.interp(grid, t, frame["x"].to_numpy())
        after = np.clip(np.searchsorted(t, grid, side="right"), 1, len(t) - 1)
        on_fix = np.isin(grid, t)
        expected[(t[after] - t[after - 1] > 50.0) & ~on_fix] = np.nan
        np.testing.assert_allclose(mine["x"], expected, rtol=0, atol=1e-12)


def test_regularise_keeps_segments_apart():
    df = make([0.0, 10.0, 50.0, 70.0], [0.0] * 4, time=[0.0, 10.0, 500.0, 520.0])
    r = tracks.regularise(tracks.split_at_gaps(df, 100.0), 5.0)
    assert list(r["segment"]) == ["a#1"] * 3 + ["a#2"] * 5
    np.testing.assert_allclose(r["time"], [0, 5, 10, 500, 505, 510, 515, 520])
    np.testing.assert_allclose(r["x"], [0, 5, 10, 50, 55, 60, 65, 70])


@pytest.mark.parametrize(
    ("time", "x", "message"),
    [
        ([0.0, 5.0, 5.0], [0.0, 1.0, 2.0], r"rows 1, 2: duplicate times within animal 'a'"),
        ([0.0, 5.0, 4.0], [0.0, 1.0, 2.0], r"rows 1, 2: decreasing times"),
        ([0.0, 5.0, 6.0], [0.0, "east", 2.0], r"row 1: column 'x' must be numeric"),
        ([0.0, 5.0, 6.0], [0.0, np.inf, 2.0], r"row 1: column 'x' is infinite"),
        ([0.0, np.nan, 6.0], [0.0, 1.0, 2.0], r"row 1: column 'time' is missing"),
    ],
)
def test_validation_names_rows_and_columns(time, x, message):
    df = make(x, [0.0, 0.0, 0.0], time=time)
    with pytest.raises(ValueError, match=message):
        tracks.prepare(df)


def test_validation_names_file_lines_and_too_few_fixes():
    df = make([0.0, 1.0, 2.0], [0.0, 0.0, 0.0], time=[0.0, 1.0, 2.0], ids=["a", "a", "b"])
    df.index = pd.Index([2, 3, 5], name="line")
    df.attrs["source"] = "fixes.csv"
    with pytest.raises(ValueError, match=r"fixes.csv line 5: animal\(s\) \['b'\] have fewer"):
        tracks.validate_tracks(df, min_fixes=2)
    with pytest.raises(ValueError, match=r"missing column\(s\) \['y'\]; found \['id', 'x'"):
        tracks.prepare(df.drop(columns="y"))


# quarter-metre grid: exact arithmetic in the oracle, zero-length steps drawn often enough
metres = st.integers(-40_000, 40_000).map(lambda k: k / 4.0)
coordinates = st.lists(
    st.tuples(metres, metres),
    min_size=3,
    max_size=30,
)


def rotate(df, theta, shift):
    c, s = np.cos(theta), np.sin(theta)
    out = df.copy()
    out["x"] = c * df["x"] - s * df["y"] + shift[0]
    out["y"] = s * df["x"] + c * df["y"] + shift[1]
    return out


@settings(max_examples=60, deadline=None)
@given(coordinates, st.floats(-np.pi, np.pi), st.tuples(st.floats(-1e5, 1e5), st.floats(-1e5, 1e5)))
def test_steps_and_angles_properties(points, theta, shift):
    xy = np.array(points)
    df = make(xy[:, 0], xy[:, 1])
    p = tracks.prepare(df)
    angle = p["angle"].to_numpy()
    ok = ~np.isnan(angle)
    assert np.all((angle[ok] > -np.pi) & (angle[ok] <= np.pi))
    assert np.all(p["step"].to_numpy()[:-1] >= 0)
    # oracle: turn = argument of v_t / v_{t-1} with complex numbers
    v = np.diff(xy[:, 0] + 1j * xy[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        oracle = np.angle(v[1:] / v[:-1])
    nonzero = (v[1:] != 0) & (v[:-1] != 0)
    np.testing.assert_array_equal(ok[1:-1], nonzero)
    diff = tracks.wrap_angle(angle[1:-1][nonzero] - oracle[nonzero])
    np.testing.assert_allclose(diff, 0.0, atol=1e-9)
    # rotation + translation invariance (tolerance scaled to the coordinates' size)
    q = tracks.prepare(rotate(df, theta, shift))
    scale = 1.0 + np.abs(xy).max() + np.abs(shift).max()
    np.testing.assert_allclose(q["step"], p["step"], atol=1e-9 * scale)
    long_enough = np.r_[False, np.minimum(p["step"].to_numpy()[1:], p["step"].to_numpy()[:-1])]
    keep = ok & (np.nan_to_num(long_enough) > 1e-3 * scale)
    dq = tracks.wrap_angle(q["angle"].to_numpy()[keep] - angle[keep])
    np.testing.assert_allclose(dq, 0.0, atol=1e-6)


@given(st.floats(-1e6, 1e6, allow_nan=False))
def test_wrap_angle_range_and_equivalence(a):
    w = tracks.wrap_angle(a)
    assert -np.pi < w <= np.pi
    assert np.isclose(np.cos(w), np.cos(a), atol=1e-6) and np.isclose(
        np.sin(w), np.sin(a), atol=1e-6
    )


def load_example_script():
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "data" / "make_example_tracks.py"
    spec = importlib.util.spec_from_file_location("make_example_tracks", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_bundled_example_tracks_match_their_generator_and_split_once():
    from hmmtrack import io

    path = Path(__file__).resolve().parents[1] / "data" / "example_tracks.csv"
    assert path.stat().st_size < 300_000
    df = io.read_tracks(path)
    script = load_example_script()
    again = script.make_tracks(script.SEED)
    assert len(df) == len(again) and list(df["id"]) == list(again["id"])
    np.testing.assert_allclose(df["time"], again["time"], atol=1e-3)
    np.testing.assert_allclose(df[["x", "y"]], again[["x", "y"]], atol=0.05 + 1e-9)
    segments = tracks.split_at_gaps(df, 600.0)["segment"].value_counts()
    assert sorted(segments.index) == ["shark-1", "shark-2#1", "shark-2#2", "shark-3"]
    p = tracks.prepare(df, max_gap=600.0)
    interval = p["dt"].dropna()
    assert interval.between(60, 180).all()
    # the documented speeds per simulated state (gamma means 0.15 and 1.0 m/s)
    speed = p.groupby("true_state")["speed"].mean()
    assert speed[1] == pytest.approx(0.15, rel=0.1) and speed[2] == pytest.approx(1.0, rel=0.05)
