"""The tracker's files: writing its estimates, and reading a truth track to score them.

Estimates get ISO 8601 UTC times and, with a projection, lon/lat beside the metres; a truth
is read in the same frame as the receivers it is compared with.
"""

from __future__ import annotations

from pathlib import Path
from typing import TextIO

import numpy as np
import pandas as pd

from hmmtrack.io.geo import Projection
from hmmtrack.io.tables import unreadable_as_value_error
from hmmtrack.io.times import format_times, parse_times


def write_estimates(
    estimates: pd.DataFrame, path: str | Path, projection: Projection | None = None
) -> None:
    """Write estimates as CSV: ``time`` as ISO 8601 UTC with milliseconds, then ``x``, ``y``
    (m), ``lon``, ``lat`` (degrees, when ``projection`` is given) and the other columns
    (12 significant digits; other epoch times, ``*_time``, to the microsecond).

    Parameters
    ----------
    estimates : DataFrame
        Estimates table (``time`` in UTC epoch s, ``x``, ``y`` in m, others as they are).
    path : str or Path
        Output CSV.
    projection : Projection, optional
        Projection of ``x``/``y``; adds ``lon``/``lat`` columns.
    """
    with open(path, "w", newline="") as file:
        EstimatesWriter(file, projection)(estimates)


class EstimatesWriter:
    """Estimates appended to an open CSV table by table, as :func:`write_estimates` writes
    them whole (the same text): the sink of a streamed run
    (:func:`hmmtrack.tracking.pipeline.track`'s ``estimates_to``).

    Parameters
    ----------
    file : text file
        Open for writing (``newline=""``); the header goes with the first table.
    projection : Projection, optional
        Projection of ``x``/``y``; adds ``lon``/``lat`` columns.

    Attributes
    ----------
    rows : int
        Estimates written so far.
    """

    def __init__(self, file: TextIO, projection: Projection | None = None):
        self.file, self.projection, self.rows = file, projection, 0
        self._header = True

    def __call__(self, estimates: pd.DataFrame) -> None:
        """Append ``estimates`` (a table of :func:`write_estimates`'s form)."""
        for col in ("time", "x", "y"):
            if col not in estimates.columns:
                raise ValueError(
                    f"estimates: missing column {col!r}; found {list(estimates.columns)}"
                )
        out = estimates.copy()
        out["time"] = format_times(out["time"].to_numpy(dtype=float))
        front = ["time", "x", "y"]
        if self.projection is not None:
            out["lon"], out["lat"] = self.projection.to_lonlat(out["x"], out["y"])
            front += ["lon", "lat"]
        out = out[front + [c for c in out.columns if c not in front]]
        for col in out.columns:
            if col.endswith("_time") and pd.api.types.is_float_dtype(out[col]):
                out[col] = _microseconds(out[col].to_numpy())
        out.to_csv(self.file, index=False, header=self._header, float_format="%.12g")
        self._header = False
        self.rows += len(out)


def _microseconds(seconds: np.ndarray) -> np.ndarray:
    """Epoch seconds (n,) as text to the microsecond ("" where NaN): 12 significant digits
    would keep only 10 ms of an epoch time such as a ping's emission."""
    text = np.char.mod("%.6f", seconds).astype(object)
    text[np.isnan(seconds)] = ""
    return text


def read_truth(
    path: str | Path, projection: Projection | None, time_unit: str = "s", tz: str | None = None
) -> pd.DataFrame:
    """Read a truth track (the tag's true positions) to score estimates against.

    Parameters
    ----------
    path : str or Path
        CSV of ``time`` (ISO 8601 with a UTC offset, or UTC epoch seconds) and ``x``, ``y``
        (m) or ``lon``, ``lat`` (degrees). A single row with ``time`` empty or absent is a
        fixed tag.
    projection : Projection or None
        The receivers' projection; needed (and used) for lon/lat truth.
    time_unit : {"s", "ms"}
        Unit of numeric times (:func:`hmmtrack.io.times.parse_times`).
    tz : str, optional
        Time zone of ISO times written without a UTC offset (refused without it).

    Returns
    -------
    DataFrame
        ``time`` (s, NaN for a fixed tag), ``x``, ``y`` (m).
    """
    with unreadable_as_value_error(path):
        table = pd.read_csv(path)
    table.attrs["source"] = str(path)
    if "time" not in table.columns:
        if len(table) != 1:
            raise ValueError(f"{path}: truth needs a 'time' column; found {list(table.columns)}")
        table["time"] = np.nan  # one row without time: a fixed tag
    if {"x", "y"} <= set(table.columns):
        x, y = table["x"].to_numpy(dtype=float), table["y"].to_numpy(dtype=float)
    elif {"lon", "lat"} <= set(table.columns):
        if projection is None:
            raise ValueError(f"{path}: truth in lon/lat needs receivers in lon/lat too")
        x, y = projection.to_xy(table["lon"], table["lat"])
    else:
        raise ValueError(
            f"{path}: truth needs x, y or lon, lat columns; found {list(table.columns)}"
        )
    time = parse_times(table, "time", tz, time_unit)
    if len(table) > 1 and not np.isfinite(time).all():
        raise ValueError(f"{path}: empty time in a truth with several rows")
    return pd.DataFrame({"time": time, "x": x, "y": y})
