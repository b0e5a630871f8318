"""Readers of animal tracks: plain CSV in metres, and Movebank CSV in lon/lat.

Both return the *tracks* table of ``docs/interfaces.md`` (``id``, ``time`` in UTC seconds,
``x``, ``y`` in projected metres, other columns kept), rows of an animal contiguous, index =
file line; the track maths is :mod:`hmmtrack.tracks`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io.geo import Projection, check_lonlat, check_metres, choose_projection
from hmmtrack.io.tables import handle_missing, numeric, numeric_columns, read_csv, rename, require
from hmmtrack.io.times import parse_times
from hmmtrack.tracks import describe_rows, validate_tracks

#: what a user of a track reader can do about empty coordinates (library and CLI spelling)
_MISSING_REMEDY = (
    "remove these rows (they are reported) with missing_coordinates='drop' (hmmtrack "
    "fit/decode/plot --missing drop), or keep them as missing fixes with 'keep' (--missing keep)"
)


def read_tracks(
    path: str | Path,
    *,
    id_col: str | None = "id",
    time_col: str | None = "time",
    x_col: str = "x",
    y_col: str = "y",
    tz: str | None = None,
    missing_coordinates: str = "error",
    min_fixes: int = 2,
) -> pd.DataFrame:
    """Read animal fixes in projected metres from a plain CSV.

    Parameters
    ----------
    path : str or Path
        CSV file with a header line.
    id_col : str or None
        Column of animal identifiers; ``None`` when the file holds one animal (its id is the
        file stem).
    time_col : str or None
        Column of times (ISO 8601, or numbers = UTC epoch seconds); ``None`` when the data
        have no times (e.g. moveHMM's elk example): the table then has no ``time`` column
        and :func:`hmmtrack.tracks.prepare` leaves ``dt``, ``speed`` and
        ``angular_velocity`` missing.
    x_col, y_col : str
        Columns of east and north coordinates (m).
    tz : str, optional
        Time zone of times written without a UTC offset (required for those).
    missing_coordinates : {"error", "drop", "keep"}
        What to do with rows whose coordinates are empty: raise naming the lines, remove them
        (reported in ``attrs["dropped"]`` and logged), or keep them as missing fixes (NaN).
    min_fixes : int
        Fewest fixes an animal may have.

    Returns
    -------
    DataFrame
        Tracks table: ``id`` (str), ``time`` (s, when there are times), ``x``, ``y`` (m), then
        every other column of the file (numeric text converted to numbers), rows of an
        animal contiguous, index = file line.
    """
    table = read_csv(path)
    require(
        table,
        {"id": id_col, "time": time_col, "x": x_col, "y": y_col},
        "read_tracks (time_col=None for data without times)",
    )
    table = rename(table, {"id": id_col, "time": time_col, "x": x_col, "y": y_col})
    if id_col is None:
        if "id" in table.columns:
            raise ValueError(f"{path}: id_col=None but the file has an 'id' column")
        table.insert(0, "id", Path(path).stem)
    return _finish_tracks(table, time_col is not None, tz, missing_coordinates, min_fixes)


def _finish_tracks(
    table: pd.DataFrame, has_time: bool, tz: str | None, missing: str, min_fixes: int
) -> pd.DataFrame:
    table["x"] = numeric(table, "x", "metres")
    table["y"] = numeric(table, "y", "metres")
    table = handle_missing(table, ["x", "y"], missing, _MISSING_REMEDY)
    check_metres(table, "x", "y")
    if has_time:
        table["time"] = parse_times(table, "time", tz)
    numeric_columns(table, skip=("id", "time", "x", "y"))
    empty = np.flatnonzero(table["id"].isna().to_numpy())
    if empty.size:
        raise ValueError(f"{describe_rows(table, empty)}: the animal id is empty")
    table["id"] = table["id"].astype(str)
    front = [c for c in ("id", "time", "x", "y") if c in table.columns]
    table = table[front + [c for c in table.columns if c not in front]]
    order = np.argsort(pd.factorize(table["id"])[0], kind="stable")
    table = table.iloc[order]
    validate_tracks(table, min_fixes=min_fixes)
    return table


def read_movebank(
    path: str | Path,
    *,
    id_col: str = "individual-local-identifier",
    time_col: str = "timestamp",
    lon_col: str = "location-long",
    lat_col: str = "location-lat",
    tz: str | None = "UTC",
    projection: Projection | str | int = "utm",
    missing_coordinates: str = "error",
    min_fixes: int = 2,
) -> pd.DataFrame:
    """Read a Movebank CSV and project lon/lat to local metres.

    Parameters
    ----------
    path : str or Path
        Movebank CSV export.
    id_col, time_col, lon_col, lat_col : str
        Columns of animal id, time, longitude and latitude (degrees, WGS 84).
    tz : str or None
        Zone of naive times; Movebank timestamps are UTC, hence the default.
    projection : Projection, {"utm", "local"} or EPSG code
        A projection to use (e.g. shared with receivers), how to choose one from the data's
        centre (its UTM zone, or an azimuthal equidistant projection about it), or the EPSG
        code of a projected CRS in metres (``"EPSG:32611"``); see
        :func:`hmmtrack.io.geo.choose_projection`.
    missing_coordinates : {"error", "drop", "keep"}
        As in :func:`read_tracks` (Movebank files often hold rows without a fix).
    min_fixes : int
        Fewest fixes an animal may have.

    Returns
    -------
    DataFrame
        Tracks table (``id``, ``time``, ``x``, ``y``) plus ``lon``, ``lat`` and the file's
        other columns; ``attrs["crs"]`` holds the projection's WKT
        (:meth:`Projection.from_frame` gives it back).
    """
    table = read_csv(path)
    require(
        table, {"id": id_col, "time": time_col, "lon": lon_col, "lat": lat_col}, "read_movebank"
    )
    table = rename(table, {"id": id_col, "time": time_col, "lon": lon_col, "lat": lat_col})
    table["lon"] = numeric(table, "lon", "degrees")
    table["lat"] = numeric(table, "lat", "degrees")
    table = handle_missing(table, ["lon", "lat"], missing_coordinates, _MISSING_REMEDY)
    check_lonlat(table, "lon", "lat")
    proj = choose_projection(table["lon"], table["lat"], projection)
    x, y = proj.to_xy(table["lon"], table["lat"])
    table.insert(0, "x", x)
    table.insert(1, "y", y)
    out = _finish_tracks(table, True, tz, "keep", min_fixes)
    out.attrs["crs"] = proj.crs
    return out
