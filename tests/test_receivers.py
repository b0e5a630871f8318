"""Tests of hmmtrack.tracking.receivers.ReceiverTracks: exact interpolation, exact velocities of
straight-line motion, moored receivers, errors and GPS-noise smoothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack.io import read_receivers
from hmmtrack.tracking.receivers import ReceiverTracks

GPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "yaps_ssu1" / "ssu1_gps.csv"


def positions(rows):
    return pd.DataFrame(rows, columns=["receiver", "time", "x", "y"])


# an L-shaped path: east at 2 m/s for 10 s, then north at 0.5 m/s for 40 s
PATH = positions(
    [
        ("auv", 100.0, 0.0, 0.0),
        ("auv", 110.0, 20.0, 0.0),
        ("auv", 150.0, 20.0, 20.0),
        ("buoy", np.nan, -50.0, 30.0),
    ]
)


def test_exact_interpolation_on_a_known_path():
    rt = ReceiverTracks.from_frame(PATH)
    assert rt.names == ("auv", "buoy")
    x, y, vx, vy = rt.state("auv", np.array([100.0, 105.0, 110.0, 130.0, 150.0]))
    np.testing.assert_allclose(x, [0.0, 10.0, 20.0, 20.0, 20.0])
    np.testing.assert_allclose(y, [0.0, 0.0, 0.0, 10.0, 20.0])
    # segment slopes; a fix time belongs to the segment that starts there (last: the one ending)
    np.testing.assert_allclose(vx, [2.0, 2.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(vy, [0.0, 0.0, 0.5, 0.5, 0.5])


def test_windowed_velocity_is_the_chord_slope():
    rt = ReceiverTracks.from_frame(PATH, velocity_window=10.0)
    _, _, vx, vy = rt.state("auv", np.array([110.0, 100.0, 130.0]))
    # at 110: chord from (10, 0) at 105 to (20, 2.5) at 115
    np.testing.assert_allclose(vx, [1.0, 2.0, 0.0])
    np.testing.assert_allclose(vy, [0.25, 0.0, 0.5])


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-5.0, 5.0),
    st.floats(-5.0, 5.0),
    st.floats(0.0, 30.0),
    st.lists(st.floats(0.2, 20.0), min_size=2, max_size=30),
)
def test_straight_line_velocity_is_exact_for_any_window(vx0, vy0, window, gaps):
    time = 1.6e9 + np.cumsum(np.r_[0.0, gaps])
    df = positions(
        [("boat", t, 3.0 + vx0 * (t - time[0]), -7.0 + vy0 * (t - time[0])) for t in time]
    )
    rt = ReceiverTracks.from_frame(df, velocity_window=window)
    t = np.linspace(time[0], time[-1], 57)
    x, y, vx, vy = rt.state("boat", t)
    np.testing.assert_allclose(x, 3.0 + vx0 * (t - time[0]), atol=1e-6)
    np.testing.assert_allclose(y, -7.0 + vy0 * (t - time[0]), atol=1e-6)
    np.testing.assert_allclose(vx, vx0, atol=1e-6)
    np.testing.assert_allclose(vy, vy0, atol=1e-6)


def test_moored_receiver_is_fixed_at_any_time():
    rt = ReceiverTracks.from_frame(PATH)
    assert rt.is_moored("buoy") and not rt.is_moored("auv")
    x, y, vx, vy = rt.state("buoy", np.array([-1e9, 0.0, 2e9]))
    np.testing.assert_array_equal(x, -50.0)
    np.testing.assert_array_equal(y, 30.0)
    np.testing.assert_array_equal(vx, 0.0)
    np.testing.assert_array_equal(vy, 0.0)
    assert rt.span("buoy") == (-np.inf, np.inf) and rt.span("auv") == (100.0, 150.0)


def test_unknown_receiver_and_times_outside_the_track():
    rt = ReceiverTracks.from_frame(PATH)
    with pytest.raises(KeyError, match=r"unknown receiver 'glider'.*\['auv', 'buoy'\]"):
        rt.state("glider", 120.0)
    with pytest.raises(ValueError, match=r"'auv': 2 time\(s\) outside its GPS track"):
        rt.state("auv", np.array([99.0, 120.0, 151.0]))
    clamped = ReceiverTracks.from_frame(PATH, outside="clamp")
    x, y, vx, vy = clamped.state("auv", np.array([99.0, 151.0]))
    np.testing.assert_allclose(np.c_[x, y, vx, vy], [[0, 0, 0, 0], [20, 20, 0, 0]])


def test_window_smooths_gps_noise():
    rng = np.random.default_rng(7)
    time = np.arange(0.0, 600.0, 1.0)  # 1 Hz GPS, 1 m noise, 1.5 m/s east
    df = positions(
        [
            ("boat", t, 1.5 * t + e, n)
            for t, e, n in zip(
                time, rng.normal(0, 1, time.size), rng.normal(0, 1, time.size), strict=True
            )
        ]
    )
    t = np.linspace(20.0, 580.0, 300)
    raw = ReceiverTracks.from_frame(df).state("boat", t)[2]
    smooth = ReceiverTracks.from_frame(df, velocity_window=20.0).state("boat", t)[2]
    assert np.std(raw - 1.5) > 1.0  # segment slopes scatter by ~sqrt(2) m/s
    assert np.std(smooth - 1.5) < 0.15  # a 20 s chord: ~sqrt(2)/20 m/s
    assert abs(np.mean(smooth) - 1.5) < 0.05


@pytest.mark.skipif(not GPS.exists(), reason="real yaps GPS track absent (../shared/data)")
def test_real_boat_gps_track_through_read_receivers(tmp_path):
    """The towing boat's real GPS (irregular 1-35 s fixes): the reader and the interpolation
    reproduce every fix, and velocities integrate back to the displacement."""
    gps = pd.read_csv(GPS)
    path = tmp_path / "gps.csv"  # the real file has no receiver column; add one in a temp copy
    gps.assign(receiver="boat").to_csv(path, index=False)
    table = read_receivers(path, time_col="ts", x_col="utm_x", y_col="utm_y")
    assert len(table) == 450 and (table["receiver"] == "boat").all()
    rt = ReceiverTracks.from_frame(table)
    t = table["time"].to_numpy()
    x, y, vx, vy = rt.state("boat", t)
    np.testing.assert_array_equal(x, gps["utm_x"])
    np.testing.assert_array_equal(y, gps["utm_y"])
    # segment velocities integrate exactly to the displacement between any two fixes
    grid = np.linspace(t[0], t[-1], 200_001)
    _, _, gvx, _ = rt.state("boat", grid)
    assert np.trapezoid(gvx, grid) == pytest.approx(x[-1] - x[0], abs=2.0)
    assert 0.2 < np.median(np.hypot(vx, vy)) < 1.5  # a boat towing a tag slowly


HYDROS = GPS.parent / "ssu1_hydros.csv"
VUE = GPS.parent / "VUE_Export_ssu1.csv"


@pytest.mark.skipif(not (HYDROS.exists() and VUE.exists()), reason="real yaps data absent")
def test_real_moored_array_serves_every_vue_detection():
    """The Florida Bay array: a file of moored hydrophones (no time column) read as moored
    receivers; every receiver serial of the real VUE export has a fixed position there."""
    from hmmtrack.io import read_detections

    table = read_receivers(HYDROS, receiver_col="serial")
    hydros = pd.read_csv(HYDROS)
    assert len(table) == len(hydros) and table["time"].isna().all()
    rt = ReceiverTracks.from_frame(table)
    det = read_detections(VUE)
    serials = sorted(det["receiver_serial"].unique())
    assert set(serials) <= set(rt.names)
    for serial in serials[:3]:
        t = det.loc[det["receiver_serial"] == serial, "time"].to_numpy()
        x, y, vx, vy = rt.state(serial, t)
        row = hydros.loc[hydros["serial"].astype(str) == serial].iloc[0]
        np.testing.assert_array_equal(x, row["x"])
        np.testing.assert_array_equal(y, row["y"])
        assert not vx.any() and not vy.any()
