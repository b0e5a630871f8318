"""Receiver (hydrophone) positions: reading them from a file and checking the table.

A receiver is moored (one row without time) or mobile (a GPS track of an AUV or boat, a time
on every row); positions are given in metres or in lon/lat, projected by :mod:`hmmtrack.io.geo`.
A moored array's file may also say, per receiver, its depth or height ``z`` (m), the
transmitter moored beside it as a sync tag (``sync_tag``, for clock synchronisation,
:mod:`hmmtrack.sync`) and whether its surveyed position is ``fixed`` (not to be refined).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io.geo import Projection, check_lonlat, check_metres, choose_projection
from hmmtrack.io.tables import handle_missing, numeric, read_csv, rename, require
from hmmtrack.io.times import parse_times
from hmmtrack.tracks import describe_rows


def read_receivers(
    path: str | Path,
    *,
    receiver_col: str = "receiver",
    time_col: str | None = "time",
    x_col: str = "x",
    y_col: str = "y",
    lon_col: str = "lon",
    lat_col: str = "lat",
    z_col: str = "z",
    sync_tag_col: str = "sync_tag",
    fixed_col: str = "fixed",
    tz: str | None = None,
    time_unit: str = "s",
    projection: Projection | str = "utm",
) -> pd.DataFrame:
    """Read receiver (hydrophone) positions: GPS tracks of AUVs / boats, or moorings.

    Parameters
    ----------
    path : str or Path
        CSV with a receiver column, positions either as ``x``/``y`` (m) or as ``lon``/``lat``
        (degrees, WGS 84; used when the x/y columns are absent), and a time column. A moored
        receiver is one row with an empty time (or the file has no time column).
        Optional columns of a moored array: ``z`` (m, depth or height, one sign throughout;
        only differences are used), ``sync_tag`` (the transmitter moored at the receiver as a
        sync tag, full id ``A69-1602-59334`` or ID part ``59334``; empty for none) and
        ``fixed`` (``true``/``false``, ``yes``/``no``, ``1``/``0``; empty = false: a surveyed
        position that clock synchronisation must not refine).
    receiver_col, time_col, x_col, y_col, lon_col, lat_col, z_col, sync_tag_col, fixed_col : str
        Column names in the file.
    tz : str, optional
        Zone of naive times.
    time_unit : {"s", "ms"}
        Unit of numeric times (UTC since the epoch, :func:`hmmtrack.io.times.parse_times`).
    projection : Projection or {"utm", "local"}
        For lon/lat input: the projection to use, or how to choose one from the data.

    Returns
    -------
    DataFrame
        Receiver positions: ``receiver`` (str), ``time`` (s, NaN for a moored receiver),
        ``x``, ``y`` (m), plus ``lon``/``lat`` for lon/lat input (``attrs["crs"]`` set),
        ``z`` (float m), ``sync_tag`` (str, NaN for none) and ``fixed`` (bool) when the file
        has them, and the other columns; rows of a receiver contiguous and in time order;
        index = file line.
    """
    table = read_csv(path)
    has_time = time_col is not None and time_col in table.columns
    if time_col is not None and not has_time and time_col != "time":
        require(table, {"time": time_col}, "read_receivers")
    geographic = x_col not in table.columns and y_col not in table.columns
    coords = {"lon": lon_col, "lat": lat_col} if geographic else {"x": x_col, "y": y_col}
    require(table, {"receiver": receiver_col, **coords}, "read_receivers")
    optional = {"z": z_col, "sync_tag": sync_tag_col, "fixed": fixed_col}
    optional = {role: col for role, col in optional.items() if col in table.columns}
    table = rename(
        table,
        {"receiver": receiver_col, "time": time_col if has_time else None, **coords, **optional},
    )
    empty = np.flatnonzero(table["receiver"].isna().to_numpy())
    if empty.size:
        raise ValueError(f"{describe_rows(table, empty)}: column {receiver_col!r} is empty")
    table["receiver"] = table["receiver"].astype(str).str.strip()
    proj = None
    if geographic:
        table["lon"] = numeric(table, "lon", "degrees")
        table["lat"] = numeric(table, "lat", "degrees")
        handle_missing(table, ["lon", "lat"], "error")
        check_lonlat(table, "lon", "lat")
        proj = choose_projection(table["lon"], table["lat"], projection)
        table["x"], table["y"] = proj.to_xy(table["lon"], table["lat"])
    else:
        table["x"] = numeric(table, "x", "metres")
        table["y"] = numeric(table, "y", "metres")
        handle_missing(table, ["x", "y"], "error")
        check_metres(table, "x", "y")
    if "z" in table.columns:
        table["z"] = numeric(table, "z", "metres")
        handle_missing(table, ["z"], "error")
    if "sync_tag" in table.columns:
        table["sync_tag"] = table["sync_tag"].str.strip().replace("", np.nan)
    if "fixed" in table.columns:
        table["fixed"] = _flags(table, "fixed")
    table["time"] = parse_times(table, "time", tz, time_unit) if has_time else np.nan
    front = ["receiver", "time", "x", "y"]
    table = table[front + [c for c in table.columns if c not in front]]
    table = table.iloc[np.argsort(pd.factorize(table["receiver"])[0], kind="stable")]
    validate_receivers(table)
    if proj is not None:
        table.attrs["crs"] = proj.crs
    return table


_TRUE = {"true", "yes", "1", "t", "y"}
_FALSE = {"false", "no", "0", "f", "n"}


def receivers_from_yaps_hydros(
    path: str | Path,
    *,
    fixed_idx=(),
    receiver_prefix: str = "VR2W-",
    sync_code_space: str = "A69-1602",
) -> pd.DataFrame:
    """The receivers table of a YAPS ``hydros`` CSV (``serial, x, y, z, sync_tag, idx``).

    YAPS names a hydrophone by its serial number and its sync tag by the ID part alone;
    detection logs name them ``VR2W-<serial>`` and ``A69-1602-<id>``.

    Parameters
    ----------
    path : str or Path
        The hydros CSV (``sync_tag`` empty or ``NA`` for a hydrophone without one).
    fixed_idx : iterable of int
        YAPS's ``idx`` of the hydrophones held at their surveyed positions.
    receiver_prefix, sync_code_space : str
        Receiver model prefix and sync-tag code space of the detection log.

    Returns
    -------
    pandas.DataFrame
        ``receiver``, ``x``, ``y``, ``z`` (m), ``sync_tag`` (full transmitter ID, "" for
        none), ``fixed`` (bool): the columns :func:`read_receivers` reads.
    """
    hydros = read_csv(path)
    require(hydros, {c: c for c in ("serial", "x", "y", "z", "sync_tag", "idx")}, "a hydros file")
    sync = [f"{sync_code_space}-{t}" if pd.notna(t) else "" for t in hydros["sync_tag"]]
    return pd.DataFrame(
        {
            "receiver": receiver_prefix + hydros["serial"],
            "x": numeric(hydros, "x", "m"),
            "y": numeric(hydros, "y", "m"),
            "z": numeric(hydros, "z", "m"),
            "sync_tag": sync,
            "fixed": np.isin(numeric(hydros, "idx", "index"), list(fixed_idx)),
        }
    ).reset_index(drop=True)


def _flags(table: pd.DataFrame, column: str) -> np.ndarray:
    """A yes/no column as bool (empty = False); other text raises naming lines and column."""
    text = table[column].fillna("false").astype(str).str.strip().str.lower()
    bad = np.flatnonzero(~text.isin(_TRUE | _FALSE).to_numpy())
    if bad.size:
        raise ValueError(
            f"{describe_rows(table, bad)}: column {column!r} must be true/false (yes/no, 1/0), "
            f"found {table[column].iloc[bad[0]]!r}"
        )
    return text.isin(_TRUE).to_numpy()


def validate_receivers(positions: pd.DataFrame) -> None:
    """Check a receiver-positions table; raise ``ValueError`` naming the rows at fault.

    A receiver is either moored (exactly one row, time NaN) or mobile (every row timed,
    times strictly increasing in row order); coordinates are finite.
    """
    for col in ("receiver", "time", "x", "y"):
        if col not in positions.columns:
            raise ValueError(
                f"receiver positions: missing column {col!r}; found {list(positions.columns)}"
            )
    for col in ("x", "y"):
        bad = np.flatnonzero(~np.isfinite(positions[col].to_numpy(dtype=float)))
        if bad.size:
            raise ValueError(f"{describe_rows(positions, bad)}: column {col!r} is not finite")
    codes = pd.factorize(positions["receiver"])[0]
    time = positions["time"].to_numpy(dtype=float)
    for code in np.unique(codes):
        rows = np.flatnonzero(codes == code)
        name = positions["receiver"].iloc[rows[0]]
        untimed = np.isnan(time[rows])
        if untimed.any() and len(rows) > 1:
            raise ValueError(
                f"{describe_rows(positions, rows[untimed])}: receiver {name!r} has "
                f"{len(rows)} rows but rows without time; a moored receiver is one row "
                "without time, a mobile one has a time on every row"
            )
        steps = np.diff(time[rows])
        bad = np.flatnonzero(~(steps > 0)) if len(rows) > 1 else np.array([], dtype=int)
        if bad.size:
            raise ValueError(
                f"{describe_rows(positions, rows[np.r_[bad, bad + 1]])}: times of receiver "
                f"{name!r} must be strictly increasing (duplicate or unsorted)"
            )
