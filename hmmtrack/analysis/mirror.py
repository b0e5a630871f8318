"""The mirror track: where a tag heard by two receivers could equally well be.

Two range circles in the plane meet at the tag and at its reflection across the line
through the two receivers. The reflection keeps both distances at every instant, so the
*mirror track* (the true track reflected, second by second, across the moving line) has
exactly the ranges of the true track and, being the same functions of time, the same
range-rates: no measurement of two receivers tells the two apart. Only the motion prior
does, where the mirror track moves unlike an animal: where the tag crosses the receivers'
line (the mirror bounces off it) or the line turns fast. Between such moments a correct
filter's posterior holds both branches, and a run that reports one of them is right or
wrong by chance.

* :func:`mirror_track` — the mirror of a true track across the line of two receivers, with
  the two branches' separation and the tag's signed distance from the line;
* :func:`mirror_share` — the share of a run's estimates that sit on the mirror branch.

It is not for tracking (nothing here corrects a filter) nor for receivers that are not two.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from hmmtrack.analysis.metrics import finite_columns, truth_at
from hmmtrack.tracking.receivers import ReceiverTracks

__all__ = ["MIRROR_COLUMNS", "mirror_share", "mirror_track"]

#: columns of :func:`mirror_track`'s table
MIRROR_COLUMNS = ("time", "x", "y", "separation", "offset")


def mirror_track(
    truth: pd.DataFrame, receivers: pd.DataFrame, pair: tuple[str, str] | None = None
) -> pd.DataFrame:
    """The true track reflected across the line through two receivers, at the truth's times.

    Parameters
    ----------
    truth : pandas.DataFrame
        ``time`` (s), ``x``, ``y`` (m) of the tag.
    receivers : pandas.DataFrame
        Receiver positions (``receiver``, ``time`` s or NaN for a moored one, ``x``, ``y`` m;
        e.g. a scenario's ``receivers_truth``); positions outside a mobile receiver's track
        are held at its nearest end.
    pair : (str, str), optional
        The two receivers; default: the table's receivers, which must then be two.

    Returns
    -------
    pandas.DataFrame
        :data:`MIRROR_COLUMNS`: ``time`` (s), ``x``, ``y`` (m) of the mirror, ``separation``
        (m) between the tag and its mirror (twice the tag's distance from the line; 0 where
        the two branches meet) and ``offset`` (m), the tag's signed distance from the line
        (positive to the left of the direction from the first receiver to the second; a
        change of sign is a crossing). Where the two receivers coincide the line is
        undefined and the row is NaN.
    """
    tracks = ReceiverTracks.from_frame(receivers, outside="clamp")
    if pair is None:
        if len(tracks.names) != 2:
            raise ValueError(
                f"mirror_track: {len(tracks.names)} receivers {list(tracks.names)}; name the "
                "pair to reflect across"
            )
        pair = tracks.names
    time, tag_x, tag_y = finite_columns(truth, "truth", ("time", "x", "y"))
    ax, ay, _, _ = tracks.state(pair[0], time)
    bx, by, _, _ = tracks.state(pair[1], time)
    length = np.hypot(bx - ax, by - ay)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux = np.where(length > 0, (bx - ax) / length, np.nan)
        uy = np.where(length > 0, (by - ay) / length, np.nan)
    offset = ux * (tag_y - ay) - uy * (tag_x - ax)
    return pd.DataFrame(
        {
            "time": time,
            "x": tag_x + 2.0 * offset * uy,
            "y": tag_y - 2.0 * offset * ux,
            "separation": 2.0 * np.abs(offset),
            "offset": offset,
        }
    )


def mirror_share(
    estimates: pd.DataFrame,
    truth: pd.DataFrame,
    mirror: pd.DataFrame,
    min_separation: float = 50.0,
) -> float:
    """Share of the estimates that are nearer the mirror track than the true track.

    Parameters
    ----------
    estimates : pandas.DataFrame
        ``time`` (s), ``x``, ``y`` (m), inside the truth's span.
    truth : pandas.DataFrame
        ``time``, ``x``, ``y`` of the tag.
    mirror : pandas.DataFrame
        :func:`mirror_track` of ``truth``.
    min_separation : float
        Estimates where the branches are closer than this (m) are not counted: there the
        question of which branch is moot.

    Returns
    -------
    float
        In [0, 1]; NaN when no estimate is counted.
    """
    times, x, y = finite_columns(estimates, "estimates", ("time", "x", "y"))
    tx, ty = truth_at(truth, times)
    valid = np.isfinite(mirror["x"].to_numpy(dtype=float))
    branches = mirror.loc[valid, ["time", "x", "y"]]
    mx, my = truth_at(branches, times)
    separation = np.interp(times, branches["time"], mirror.loc[valid, "separation"])
    counted = separation >= min_separation
    if not counted.any():
        return float("nan")
    nearer = np.hypot(x - mx, y - my) < np.hypot(x - tx, y - ty)
    return float(np.mean(nearer[counted]))
