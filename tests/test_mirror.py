"""The mirror track of two receivers (hmmtrack.analysis.mirror)."""

import numpy as np
import pandas as pd
import pytest

from hmmtrack.analysis.mirror import MIRROR_COLUMNS, mirror_share, mirror_track


def _receivers(time, a, b):
    rows = []
    for name, (x, y) in (("a", a), ("b", b)):
        rows.append(pd.DataFrame({"receiver": name, "time": time, "x": x, "y": y}))
    return pd.concat(rows, ignore_index=True)


def test_reflection_across_a_fixed_line():
    truth = pd.DataFrame({"time": [0.0, 1.0], "x": [30.0, 50.0], "y": [40.0, -10.0]})
    moored = pd.DataFrame(
        {"receiver": ["a", "b"], "time": [np.nan, np.nan], "x": [0.0, 100.0], "y": [0.0, 0.0]}
    )
    mirror = mirror_track(truth, moored)
    assert tuple(mirror.columns) == MIRROR_COLUMNS
    np.testing.assert_allclose(mirror["x"], [30.0, 50.0])
    np.testing.assert_allclose(mirror["y"], [-40.0, 10.0])
    np.testing.assert_allclose(mirror["separation"], [80.0, 20.0])
    np.testing.assert_allclose(mirror["offset"], [40.0, -10.0])  # left of a -> b is +y


def test_moving_receivers_see_the_same_ranges_from_the_mirror():
    rng = np.random.default_rng(3)
    time = np.arange(200.0)
    a = (np.cumsum(rng.normal(0, 1, 200)), np.cumsum(rng.normal(0, 1, 200)))
    b = (150.0 + np.cumsum(rng.normal(0, 1, 200)), 60.0 + np.cumsum(rng.normal(0, 1, 200)))
    truth = pd.DataFrame(
        {"time": time, "x": 40.0 + np.cumsum(rng.normal(0, 1, 200)), "y": 90.0 + 0.5 * time}
    )
    mirror = mirror_track(truth, _receivers(time, a, b))
    for rx, ry in (a, b):
        np.testing.assert_allclose(
            np.hypot(mirror["x"] - rx, mirror["y"] - ry),
            np.hypot(truth["x"] - rx, truth["y"] - ry),
            rtol=0,
            atol=1e-9,
        )
    # the tag starts above the line and crosses it once the line has moved past it
    side = np.sign(mirror["offset"].to_numpy())
    assert side[0] == 1.0
    np.testing.assert_allclose(
        mirror["separation"], np.hypot(mirror["x"] - truth["x"], mirror["y"] - truth["y"])
    )


def test_pair_must_be_named_for_more_than_two_receivers():
    truth = pd.DataFrame({"time": [0.0], "x": [1.0], "y": [1.0]})
    three = pd.DataFrame(
        {"receiver": ["a", "b", "c"], "time": [np.nan] * 3, "x": [0.0, 9.0, 5.0], "y": [0.0] * 3}
    )
    with pytest.raises(ValueError, match="3 receivers"):
        mirror_track(truth, three)
    np.testing.assert_allclose(mirror_track(truth, three, pair=("a", "b"))["y"], [-1.0])


def test_mirror_share_counts_estimates_on_the_mirror_branch():
    time = np.arange(10.0)
    truth = pd.DataFrame({"time": time, "x": time, "y": np.where(time < 5, 100.0, 10.0)})
    moored = pd.DataFrame(
        {"receiver": ["a", "b"], "time": [np.nan] * 2, "x": [0.0, 50.0], "y": [0.0, 0.0]}
    )
    mirror = mirror_track(truth, moored)
    assert mirror_share(truth, truth, mirror) == 0.0
    assert mirror_share(mirror, truth, mirror) == 1.0
    # half on each branch while they are 200 m apart; the last 5 s (20 m apart) not counted
    halves = pd.concat([mirror.iloc[:3], truth.iloc[3:]])[["time", "x", "y"]]
    assert mirror_share(halves, truth, mirror) == pytest.approx(3 / 5)
    assert np.isnan(mirror_share(truth, truth, mirror, min_separation=500.0))
