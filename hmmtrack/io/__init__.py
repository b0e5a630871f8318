"""File formats in and out: tracks, detection logs, receiver (hydrophone) tracks, estimates.

This is the only module that parses or prints calendar times and the only one that knows map
projections. Everything it returns follows ``docs/interfaces.md``: times are UTC seconds
since the Unix epoch (``float64``, millisecond and finer precision kept) and positions are
projected metres (``x`` east, ``y`` north), with the CRS kept as WKT in ``attrs["crs"]``.

Readers
-------
* :func:`read_tracks` -- plain CSV of animal fixes (id, time, x, y in metres).
* :func:`read_movebank` -- Movebank CSV (``timestamp``, ``location-long``, ``location-lat``,
  ``individual-local-identifier``), projected with :class:`Projection`.
* :func:`read_detections` -- Innovasea VUE export, Innovasea Fathom CSV, or plain CSV.
* :func:`read_receivers` -- GPS tracks of mobile receivers, or one row per moored receiver.
* :func:`write_estimates` -- the filter's estimates with ISO 8601 UTC times (and lon/lat).

Row bookkeeping
---------------
Tables read from a file carry an index named ``"line"`` holding each row's 1-based line in
the file (header = line 1) and ``attrs["source"]`` (the file name), so that later errors
(:func:`hmmtrack.tracks.describe_rows`) still name file lines. Blank lines carry no data and
are skipped. Rows removed on request (``missing_coordinates="drop"``) are listed in
``attrs["dropped"]`` (``[{"rows": [line, ...], "reason": str}]``) and logged as a warning;
nothing else is ever removed.

Times
-----
Time strings are ISO 8601 (``2019-09-09 16:04:11.193``, ``2019-09-09T16:04:11.193Z``,
``...+02:00``). Strings with an offset are converted to UTC. Naive strings (no offset) need
an explicit ``tz`` (an IANA name such as ``"UTC"`` or ``"America/Los_Angeles"``); without one
the reader raises an error naming the column, because guessing a zone silently shifts a
track by hours. Formats that define their zone (VUE ``Date and Time (UTC)``, Fathom
``Device Time (UTC)``, Movebank ``timestamp``) are read as UTC. Numeric time columns are taken
as UTC seconds since the epoch.

Not for: track maths (:mod:`hmmtrack.tracks`), ranging
(:mod:`hmmtrack.tracking.measurement.ranging`).
"""

from __future__ import annotations

import csv
import logging
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from pyproj import CRS, Transformer
from pyproj.aoi import AreaOfInterest
from pyproj.database import query_utm_crs_info

from hmmtrack.tracks import describe_rows, validate_tracks

logger = logging.getLogger(__name__)

#: VUE export header (Innovasea VUE, "Export detections to CSV")
VUE_COLUMNS = (
    "Date and Time (UTC)",
    "Receiver",
    "Transmitter",
    "Transmitter Name",
    "Transmitter Serial",
    "Sensor Value",
    "Sensor Unit",
    "Station Name",
    "Latitude",
    "Longitude",
)

_OFFSET = re.compile(r"\d:\d{2}(?::\d{2}(?:\.\d*)?)?\s*(?:Z|[+-]\d{2}(?::?\d{2})?)$", re.I)
_MISSING_CHOICES = ("error", "drop", "keep")


# --------------------------------------------------------------------------- projection


@dataclass(frozen=True)
class Projection:
    """A map projection between WGS 84 lon/lat (degrees) and local metres.

    Parameters
    ----------
    crs : str
        The projected CRS as WKT (what ``attrs["crs"]`` stores).

    Use :meth:`utm` or :meth:`local` to choose one for data, :meth:`from_frame` to recover the
    one a table was projected with.
    """

    crs: str

    @classmethod
    def utm(cls, lon: np.ndarray, lat: np.ndarray) -> Projection:
        """The WGS 84 UTM zone that contains the centre of the points (degrees)."""
        lon0, lat0 = _centre(lon, lat)
        found = query_utm_crs_info(
            datum_name="WGS 84",
            area_of_interest=AreaOfInterest(lon0, lat0, lon0, lat0),
        )
        if not found:
            raise ValueError(f"no UTM zone found for lon {lon0}, lat {lat0}")
        return cls(CRS.from_epsg(int(found[0].code)).to_wkt())

    @classmethod
    def local(cls, lon: np.ndarray, lat: np.ndarray) -> Projection:
        """An azimuthal equidistant projection centred on the points (distances from the
        centre exact; good for small study areas anywhere, including across UTM zones)."""
        lon0, lat0 = _centre(lon, lat)
        return cls(
            CRS.from_proj4(
                f"+proj=aeqd +lat_0={lat0} +lon_0={lon0} +datum=WGS84 +units=m +no_defs"
            ).to_wkt()
        )

    @classmethod
    def from_frame(cls, table: pd.DataFrame) -> Projection | None:
        """The projection stored in ``table.attrs["crs"]``, or ``None``."""
        crs = table.attrs.get("crs")
        return cls(crs) if crs else None

    def _transformer(self, inverse: bool) -> Transformer:
        src, dst = "EPSG:4326", CRS.from_user_input(self.crs)
        if inverse:
            src, dst = dst, src
        return Transformer.from_crs(src, dst, always_xy=True)

    def to_xy(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project lon/lat (degrees, shape (n,)) to x, y (m, shape (n,))."""
        x, y = self._transformer(False).transform(np.asarray(lon, float), np.asarray(lat, float))
        return np.asarray(x, float), np.asarray(y, float)

    def to_lonlat(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unproject x, y (m, shape (n,)) to lon/lat (degrees, shape (n,))."""
        lon, lat = self._transformer(True).transform(np.asarray(x, float), np.asarray(y, float))
        return np.asarray(lon, float), np.asarray(lat, float)


def _centre(lon: np.ndarray, lat: np.ndarray) -> tuple[float, float]:
    lon = np.asarray(lon, float)
    lat = np.asarray(lat, float)
    ok = np.isfinite(lon) & np.isfinite(lat)
    if not ok.any():
        raise ValueError("cannot choose a projection: no finite lon/lat")
    # circular mean of longitudes so that data across the antimeridian centre correctly
    rad = np.deg2rad(lon[ok])
    lon0 = float(np.rad2deg(np.arctan2(np.sin(rad).mean(), np.cos(rad).mean())))
    return lon0, float(np.mean(lat[ok]))


def choose_projection(lon: np.ndarray, lat: np.ndarray, kind: str = "utm") -> Projection:
    """Projection for lon/lat data: ``kind="utm"`` (UTM zone of the centre) or ``"local"``
    (azimuthal equidistant about the centre)."""
    if kind == "utm":
        return Projection.utm(lon, lat)
    if kind == "local":
        return Projection.local(lon, lat)
    raise ValueError(f"projection must be 'utm' or 'local', got {kind!r}")


# --------------------------------------------------------------------------- CSV helpers


def _read_csv(path: str | Path, **kwargs) -> pd.DataFrame:
    """Read a CSV as strings, index = 1-based file line (header = 1), blank lines skipped."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    table = pd.read_csv(
        path,
        dtype=str,
        keep_default_na=False,
        na_values=["", "NA", "NaN", "nan"],  # empty cells and R's NA are missing
        skip_blank_lines=False,
        encoding="utf-8-sig",
        **kwargs,
    )
    table.index = pd.RangeIndex(2, 2 + len(table), name="line")
    table = table.loc[table.notna().any(axis=1)].copy()
    table.attrs["source"] = str(path)
    return table


def _require(table: pd.DataFrame, columns: dict[str, str | None], what: str) -> None:
    """Raise if a required column is absent; ``columns`` maps role -> file column name."""
    missing = {role: col for role, col in columns.items() if col and col not in table.columns}
    if missing:
        wanted = ", ".join(f"{col!r} ({role})" for role, col in missing.items())
        raise ValueError(
            f"{table.attrs['source']}: {what} needs column(s) {wanted}; the file has "
            f"{list(table.columns)} (column names can be set with the *_col arguments)"
        )


def _numeric(table: pd.DataFrame, column: str, unit: str) -> np.ndarray:
    """Column as float; non-numeric text raises naming lines and column (empty -> NaN)."""
    raw = table[column]
    values = pd.to_numeric(raw, errors="coerce")
    bad = np.flatnonzero(values.isna() & raw.notna())
    if bad.size:
        raise ValueError(
            f"{describe_rows(table, bad)}: column {column!r} must be numeric ({unit}), found "
            f"{raw.iloc[bad[0]]!r}"
        )
    return values.to_numpy(dtype=float)


def parse_times(table: pd.DataFrame, column: str, tz: str | None) -> np.ndarray:
    """Parse a time column of ``table`` to UTC seconds since the epoch.

    Parameters
    ----------
    table : DataFrame
        Table read by this module (index = file lines) holding ``column``.
    column : str
        Column of ISO 8601 strings, or of numbers (taken as UTC epoch seconds).
    tz : str or None
        Zone of strings without an offset; ``None`` makes such strings an error.

    Returns
    -------
    ndarray, shape (n,)
        ``float64`` seconds; NaN where the cell is empty.
    """
    raw = table[column]
    pos = np.flatnonzero(raw.notna().to_numpy())
    text = raw.iloc[pos].astype(str).str.strip()
    numeric = pd.to_numeric(text, errors="coerce")
    out = np.full(len(raw), np.nan)
    if len(text) and numeric.notna().all():
        out[pos] = numeric.to_numpy(dtype=float)
        return out
    aware = text.str.contains(_OFFSET).to_numpy()
    for mask in (aware, ~aware):
        if not mask.any():
            continue
        part = text[mask]
        parsed = pd.to_datetime(part, format="ISO8601", errors="coerce", utc=mask is aware)
        bad = np.flatnonzero(parsed.isna().to_numpy())
        if bad.size:
            raise ValueError(
                f"{describe_rows(table, pos[mask][bad])}: column {column!r} is not an ISO 8601 "
                f"time: {part.iloc[bad[0]]!r}"
            )
        if mask is not aware:
            if tz is None:
                raise ValueError(
                    f"{describe_rows(table, pos[mask])}: column {column!r} has times without a "
                    f"UTC offset (e.g. {part.iloc[0]!r}); pass tz= the time zone they were "
                    "recorded in (e.g. tz='UTC')"
                )
            try:
                parsed = parsed.dt.tz_localize(tz, ambiguous="raise", nonexistent="raise")
            except Exception as exc:  # ambiguous / non-existent local times, unknown zone
                raise ValueError(
                    f"{table.attrs.get('source')}: column {column!r}: cannot read the times "
                    f"in time zone {tz!r}: {exc}"
                ) from exc
        ns = parsed.dt.tz_convert("UTC").dt.as_unit("ns").astype("int64").to_numpy()
        whole, frac = np.divmod(ns, 1_000_000_000)
        out[pos[mask]] = whole.astype(float) + frac / 1e9
    return out


def format_times(seconds: np.ndarray) -> np.ndarray:
    """Format UTC epoch seconds (shape (n,)) as ISO 8601 strings with milliseconds and ``Z``."""
    seconds = np.asarray(seconds, dtype=float)
    if not np.all(np.isfinite(seconds)):
        raise ValueError("cannot format non-finite times")
    ms = np.round(seconds * 1000.0).astype("int64")
    stamps = pd.to_datetime(ms, unit="ms", utc=True)
    return np.asarray(stamps.strftime("%Y-%m-%dT%H:%M:%S.%f").str[:-3] + "Z", dtype=object)


def _rename(table: pd.DataFrame, mapping: dict[str, str | None]) -> pd.DataFrame:
    """Rename file columns to canonical names; refuse if an extra column already has one."""
    mapping = {src: dst for dst, src in mapping.items() if src and src != dst}
    clash = [dst for dst in mapping.values() if dst in table.columns and dst not in mapping]
    if clash:
        raise ValueError(
            f"{table.attrs['source']}: column(s) {clash} exist and would be overwritten by "
            f"the renamed columns {mapping}; rename them in the file or choose other columns"
        )
    return table.rename(columns=mapping)


def _handle_missing(table: pd.DataFrame, columns: list[str], policy: str) -> pd.DataFrame:
    """Apply the missing-coordinates policy (``error``, ``drop``, ``keep``)."""
    if policy not in _MISSING_CHOICES:
        raise ValueError(f"missing_coordinates must be one of {_MISSING_CHOICES}, got {policy!r}")
    empty = table[columns].isna().any(axis=1).to_numpy()
    if not empty.any() or policy == "keep":
        return table
    if policy == "error":
        raise ValueError(
            f"{describe_rows(table, np.flatnonzero(empty))}: empty coordinates in column(s) "
            f"{columns}; pass missing_coordinates='drop' to remove these rows (they are "
            "reported) or 'keep' to keep them as missing fixes"
        )
    dropped = [{"rows": table.index[empty].tolist(), "reason": f"empty coordinates in {columns}"}]
    kept = table.loc[~empty].copy()
    kept.attrs["dropped"] = list(table.attrs.get("dropped", [])) + dropped
    logger.warning(
        "%s: dropped %d row(s) with empty coordinates (lines %s)",
        table.attrs["source"],
        int(empty.sum()),
        dropped[0]["rows"][:10],
    )
    return kept


def _check_lonlat(table: pd.DataFrame, lon: str, lat: str) -> None:
    for col, limit in ((lat, 90.0), (lon, 180.0)):
        values = table[col].to_numpy(dtype=float)
        bad = np.flatnonzero(np.abs(values) > limit)
        if bad.size:
            name = "latitude" if col == lat else "longitude"
            raise ValueError(
                f"{describe_rows(table, bad)}: {name} out of [-{limit:g}, {limit:g}] degrees in "
                f"column {col!r} (found {values[bad[0]]!r}); are longitude and latitude "
                "swapped or projected?"
            )


# --------------------------------------------------------------------------- tracks


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
    table = _read_csv(path)
    _require(
        table,
        {"id": id_col, "time": time_col, "x": x_col, "y": y_col},
        "read_tracks (time_col=None for data without times)",
    )
    table = _rename(table, {"id": id_col, "time": time_col, "x": x_col, "y": y_col})
    if id_col is None:
        if "id" in table.columns:
            raise ValueError(f"{path}: id_col=None but the file has an 'id' column")
        table.insert(0, "id", Path(path).stem)
    return _finish_tracks(table, time_col is not None, tz, missing_coordinates, min_fixes)


def _finish_tracks(
    table: pd.DataFrame, has_time: bool, tz: str | None, missing: str, min_fixes: int
) -> pd.DataFrame:
    table["x"] = _numeric(table, "x", "metres")
    table["y"] = _numeric(table, "y", "metres")
    table = _handle_missing(table, ["x", "y"], missing)
    if has_time:
        table["time"] = parse_times(table, "time", tz)
    for col in table.columns:
        if col not in ("id", "time", "x", "y"):
            converted = pd.to_numeric(table[col], errors="coerce")
            if converted.notna().sum() == table[col].notna().sum():
                table[col] = converted
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
    projection: Projection | str = "utm",
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
    projection : Projection or {"utm", "local"}
        A projection to use (e.g. shared with receivers), or how to choose one from the data's
        centre: its UTM zone, or an azimuthal equidistant projection about it.
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
    table = _read_csv(path)
    _require(
        table, {"id": id_col, "time": time_col, "lon": lon_col, "lat": lat_col}, "read_movebank"
    )
    table = _rename(table, {"id": id_col, "time": time_col, "lon": lon_col, "lat": lat_col})
    table["lon"] = _numeric(table, "lon", "degrees")
    table["lat"] = _numeric(table, "lat", "degrees")
    table = _handle_missing(table, ["lon", "lat"], missing_coordinates)
    _check_lonlat(table, "lon", "lat")
    proj = (
        projection
        if isinstance(projection, Projection)
        else choose_projection(table["lon"], table["lat"], projection)
    )
    x, y = proj.to_xy(table["lon"], table["lat"])
    table.insert(0, "x", x)
    table.insert(1, "y", y)
    out = _finish_tracks(table, True, tz, "keep", min_fixes)
    out.attrs["crs"] = proj.crs
    return out


# --------------------------------------------------------------------------- detections


def detect_format(path: str | Path) -> str:
    """Guess a detection log's format from its first line: ``"fathom"``, ``"vue"`` or
    ``"plain"``."""
    with open(path, encoding="utf-8-sig") as handle:
        first = handle.readline()
    fields = next(csv.reader([first]), [])
    if fields and fields[0].strip().upper() == "VEMCO DATA LOG":
        return "fathom"
    if {"Date and Time (UTC)", "Receiver", "Transmitter"} <= {f.strip() for f in fields}:
        return "vue"
    return "plain"


def read_detections(
    path: str | Path,
    format: str = "auto",
    *,
    transmitter: str | list[str] | None = None,
    tz: str | None = None,
) -> pd.DataFrame:
    """Read a detection log into the detections table.

    Parameters
    ----------
    path : str or Path
        Detection log.
    format : {"auto", "vue", "fathom", "plain"}
        ``"auto"`` uses :func:`detect_format`.

        * ``vue``: Innovasea VUE CSV export (header :data:`VUE_COLUMNS`). Times
          (``Date and Time (UTC)``) are UTC, to the millisecond, in each receiver's own clock.
          ``Receiver`` ``VR2W-128355`` = model ``VR2W`` + serial ``128355``; ``Transmitter``
          ``A69-1602-15266`` = code space ``A69-1602`` + ID ``15266``.
        * ``fathom``: Innovasea Fathom CSV (written by Fathom Connect / ``vdat.exe``). What we
          rely on, learned from the readers in the R packages glatos (``read_vdat_csv``) and
          rvdat (vignette "VDAT data structure"): line 1 is ``VEMCO DATA LOG,<format
          version>,<vdat version>``; line 2 ``RECORD TYPE,FIELD,...``; then rows whose first
          field is a record type. ``<TYPE>_DESC`` rows give the column names of ``<TYPE>``
          rows, so ``DET_DESC`` names the columns of detection (``DET``) rows; other records
          (diagnostics, temperature, configuration...) are ignored. DET columns used:
          ``Device Time (UTC)`` (receiver clock, UTC, to 0.1 ms), ``Time Correction (s)``
          (added when present), ``Model`` and ``Serial Number`` (receiver = model without
          its frequency suffix + ``-`` + serial, e.g. ``VR2AR-69`` + ``546310`` ->
          ``VR2AR-546310``, as VUE names it), ``Full ID`` (transmitter), ``Signal Strength
          (dB)``, ``Noise (dB)``, ``Sensor Value``, ``Sensor Unit`` when present.
        * ``plain``: CSV with ``time``, ``receiver``, ``transmitter`` and optional extra
          columns (e.g. ``depth`` in m), kept.
    transmitter : str or list of str, optional
        Keep only these transmitters' detections (full id ``A69-1602-15266`` or the ID part
        ``15266``). The number of other detections is logged and recorded in
        ``attrs["other_transmitters"]``.
    tz : str, optional
        Zone of naive times in a plain CSV (VUE and Fathom times are UTC by definition).

    Returns
    -------
    DataFrame
        ``time`` (s), ``receiver`` (str), ``transmitter`` (str), and when known
        ``receiver_model``, ``receiver_serial``, ``code_space``, ``transmitter_id``,
        ``sensor_value``, ``sensor_unit``, ``station``, ``signal_strength``, ``noise``
        (VUE / Fathom) or the extra columns of a plain file; sorted by time (stable), index =
        file line, ``attrs["format"]`` the format read.
    """
    fmt = detect_format(path) if format == "auto" else format
    readers = {"vue": _read_vue, "fathom": _read_fathom, "plain": _read_plain_detections}
    if fmt not in readers:
        raise ValueError(f"format must be 'auto' or one of {list(readers)}, got {format!r}")
    table = readers[fmt](Path(path), tz)
    for col in ("receiver", "transmitter"):
        empty = np.flatnonzero(table[col].isna().to_numpy())
        if empty.size:
            raise ValueError(f"{describe_rows(table, empty)}: column {col!r} is empty")
    bad = np.flatnonzero(~np.isfinite(table["time"].to_numpy()))
    if bad.size:
        raise ValueError(f"{describe_rows(table, bad)}: detection time is empty")
    parts = table["transmitter"].str.rsplit("-", n=1, expand=True)
    if "code_space" not in table.columns and parts.shape[1] == 2:
        table["code_space"] = parts[0].where(parts[1].notna())
        table["transmitter_id"] = parts[1]
    if transmitter is not None:
        wanted = {transmitter} if isinstance(transmitter, str) else set(transmitter)
        keep = table["transmitter"].isin(wanted).to_numpy()
        if "transmitter_id" in table.columns:
            keep = keep | table["transmitter_id"].isin(wanted).to_numpy()
        if not keep.any():
            raise ValueError(
                f"{path}: no detections of transmitter(s) {sorted(wanted)}; the file has "
                f"{sorted(table['transmitter'].unique())[:20]}"
            )
        others = int((~keep).sum())
        logger.info(
            "%s: kept %d detections of %s, left out %d of other transmitters",
            path,
            int(keep.sum()),
            sorted(wanted),
            others,
        )
        attrs = dict(table.attrs)
        table = table.loc[keep].copy()
        table.attrs = attrs | {"other_transmitters": others}
    table = table.iloc[np.argsort(table["time"].to_numpy(), kind="stable")]
    table.attrs["format"] = fmt
    return table


def _split_receiver(receiver: pd.Series) -> tuple[pd.Series, pd.Series]:
    parts = receiver.str.rsplit("-", n=1, expand=True)
    if parts.shape[1] < 2:
        return pd.Series(pd.NA, index=receiver.index), receiver
    return parts[0].where(parts[1].notna()), parts[1].fillna(parts[0])


#: optional columns of VUE and Fathom exports: our name, and whether the values are numbers
_OPTIONAL_COLUMNS = {
    "Signal Strength (dB)": ("signal_strength", True),
    "Noise (dB)": ("noise", True),
    "Sensor Value": ("sensor_value", True),
    "Sensor Unit": ("sensor_unit", False),
    "Transmitter Name": ("transmitter_name", False),
    "Transmitter Serial": ("transmitter_serial", False),
    "Station Name": ("station", False),
    "Latitude": ("latitude", True),
    "Longitude": ("longitude", True),
}
#: the optional columns each export can have, in the order they are copied
_VUE_OPTIONAL = (
    "Sensor Value",
    "Sensor Unit",
    "Transmitter Name",
    "Transmitter Serial",
    "Station Name",
    "Latitude",
    "Longitude",
)
_FATHOM_OPTIONAL = (
    "Signal Strength (dB)",
    "Noise (dB)",
    "Sensor Value",
    "Sensor Unit",
    "Station Name",
)


def _copy_optional(raw: pd.DataFrame, table: pd.DataFrame, columns: tuple[str, ...]) -> None:
    """Copy the ``columns`` of an export that it has and fills, then its attrs, in place.

    Names and types come from :data:`_OPTIONAL_COLUMNS`; numbers are parsed (an unparsable
    cell is an error naming its row).
    """
    for src in columns:
        dst, numeric = _OPTIONAL_COLUMNS[src]
        if src in raw.columns and raw[src].notna().any():
            table[dst] = _numeric(raw, src, "number") if numeric else raw[src]
    table.attrs = dict(raw.attrs)


def _read_vue(path: Path, tz: str | None) -> pd.DataFrame:
    raw = _read_csv(path)
    _require(
        raw,
        {"time": VUE_COLUMNS[0], "receiver": "Receiver", "transmitter": "Transmitter"},
        "a VUE export",
    )
    table = pd.DataFrame(index=raw.index)
    table["time"] = parse_times(raw, VUE_COLUMNS[0], "UTC")
    table["receiver"] = raw["Receiver"].str.strip()
    table["transmitter"] = raw["Transmitter"].str.strip()
    table["receiver_model"], table["receiver_serial"] = _split_receiver(table["receiver"])
    _copy_optional(raw, table, _VUE_OPTIONAL)
    return table


def _read_fathom(path: Path, tz: str | None) -> pd.DataFrame:
    with open(path, encoding="utf-8-sig", newline="") as handle:
        rows = list(csv.reader(handle))
    if not rows or rows[0][:1] != ["VEMCO DATA LOG"]:
        raise ValueError(f"{path}: line 1 should start with 'VEMCO DATA LOG' (Fathom CSV)")
    header = next((r for r in rows if r[:1] == ["DET_DESC"]), None)
    if header is None:
        raise ValueError(f"{path}: no DET_DESC line, so the DET columns are unknown")
    names = [h.strip() for h in header[1:]]
    while names and not names[-1]:
        names.pop()
    lines = [i + 1 for i, r in enumerate(rows) if r[:1] == ["DET"]]
    body = [rows[i - 1][1 : 1 + len(names)] for i in lines]
    body = [r + [""] * (len(names) - len(r)) for r in body]
    raw = pd.DataFrame(body, columns=names).replace("", np.nan)
    raw.index = pd.Index(lines, name="line")
    raw.attrs["source"] = str(path)
    raw.attrs["fathom_version"] = rows[0][1] if len(rows[0]) > 1 else ""
    _require(
        raw,
        {
            "time": "Device Time (UTC)",
            "model": "Model",
            "serial": "Serial Number",
            "transmitter": "Full ID",
        },
        "Fathom DET records",
    )
    table = pd.DataFrame(index=raw.index)
    table["time"] = parse_times(raw, "Device Time (UTC)", "UTC")
    if "Time Correction (s)" in raw.columns:
        correction = _numeric(raw, "Time Correction (s)", "seconds")
        table["time"] += np.nan_to_num(correction)
    model = raw["Model"].str.strip().str.replace(r"-\d+$", "", regex=True)
    table["receiver"] = model + "-" + raw["Serial Number"].str.strip()
    table["transmitter"] = raw["Full ID"].str.strip()
    table["receiver_model"] = model
    table["receiver_serial"] = raw["Serial Number"].str.strip()
    _copy_optional(raw, table, _FATHOM_OPTIONAL)
    return table


def _read_plain_detections(path: Path, tz: str | None) -> pd.DataFrame:
    raw = _read_csv(path)
    _require(
        raw,
        {"time": "time", "receiver": "receiver", "transmitter": "transmitter"},
        "a plain detections CSV",
    )
    table = raw.copy()
    table["time"] = parse_times(raw, "time", tz)
    for col in ("receiver", "transmitter"):
        table[col] = raw[col].str.strip()
    for col in table.columns:
        if col not in ("time", "receiver", "transmitter"):
            converted = pd.to_numeric(table[col], errors="coerce")
            if converted.notna().sum() == table[col].notna().sum():
                table[col] = converted
    return table


# --------------------------------------------------------------------------- receivers


def read_receivers(
    path: str | Path,
    *,
    receiver_col: str = "receiver",
    time_col: str | None = "time",
    x_col: str = "x",
    y_col: str = "y",
    lon_col: str = "lon",
    lat_col: str = "lat",
    tz: str | None = None,
    projection: Projection | str = "utm",
) -> pd.DataFrame:
    """Read receiver (hydrophone) positions: GPS tracks of AUVs / boats, or moorings.

    Parameters
    ----------
    path : str or Path
        CSV with a receiver column, positions either as ``x``/``y`` (m) or as ``lon``/``lat``
        (degrees, WGS 84; used when the x/y columns are absent), and a time column. A moored
        receiver is one row with an empty time (or the file has no time column).
    receiver_col, time_col, x_col, y_col, lon_col, lat_col : str
        Column names in the file.
    tz : str, optional
        Zone of naive times.
    projection : Projection or {"utm", "local"}
        For lon/lat input: the projection to use, or how to choose one from the data.

    Returns
    -------
    DataFrame
        Receiver positions: ``receiver`` (str), ``time`` (s, NaN for a moored receiver),
        ``x``, ``y`` (m), plus ``lon``/``lat`` for lon/lat input (``attrs["crs"]`` set) and the
        other columns; rows of a receiver contiguous and in time order; index = file line.
    """
    table = _read_csv(path)
    has_time = time_col is not None and time_col in table.columns
    if time_col is not None and not has_time and time_col != "time":
        _require(table, {"time": time_col}, "read_receivers")
    geographic = x_col not in table.columns and y_col not in table.columns
    coords = {"lon": lon_col, "lat": lat_col} if geographic else {"x": x_col, "y": y_col}
    _require(table, {"receiver": receiver_col, **coords}, "read_receivers")
    table = _rename(
        table, {"receiver": receiver_col, "time": time_col if has_time else None, **coords}
    )
    empty = np.flatnonzero(table["receiver"].isna().to_numpy())
    if empty.size:
        raise ValueError(f"{describe_rows(table, empty)}: column {receiver_col!r} is empty")
    table["receiver"] = table["receiver"].astype(str).str.strip()
    proj = None
    if geographic:
        table["lon"] = _numeric(table, "lon", "degrees")
        table["lat"] = _numeric(table, "lat", "degrees")
        _handle_missing(table, ["lon", "lat"], "error")
        _check_lonlat(table, "lon", "lat")
        proj = (
            projection
            if isinstance(projection, Projection)
            else choose_projection(table["lon"], table["lat"], projection)
        )
        table["x"], table["y"] = proj.to_xy(table["lon"], table["lat"])
    else:
        table["x"] = _numeric(table, "x", "metres")
        table["y"] = _numeric(table, "y", "metres")
        _handle_missing(table, ["x", "y"], "error")
    table["time"] = parse_times(table, "time", tz) if has_time else np.nan
    front = ["receiver", "time", "x", "y"]
    table = table[front + [c for c in table.columns if c not in front]]
    table = table.iloc[np.argsort(pd.factorize(table["receiver"])[0], kind="stable")]
    validate_receivers(table)
    if proj is not None:
        table.attrs["crs"] = proj.crs
    return table


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


# --------------------------------------------------------------------------- writing


def write_estimates(
    estimates: pd.DataFrame, path: str | Path, projection: Projection | None = None
) -> None:
    """Write estimates as CSV: ``time`` as ISO 8601 UTC with milliseconds, then ``x``, ``y``
    (m), ``lon``, ``lat`` (degrees, when ``projection`` is given) and the other columns.

    Parameters
    ----------
    estimates : DataFrame
        Estimates table (``time`` in UTC epoch s, ``x``, ``y`` in m, others as they are).
    path : str or Path
        Output CSV.
    projection : Projection, optional
        Projection of ``x``/``y``; adds ``lon``/``lat`` columns.
    """
    for col in ("time", "x", "y"):
        if col not in estimates.columns:
            raise ValueError(f"estimates: missing column {col!r}; found {list(estimates.columns)}")
    out = estimates.copy()
    out["time"] = format_times(out["time"].to_numpy(dtype=float))
    front = ["time", "x", "y"]
    if projection is not None:
        out["lon"], out["lat"] = projection.to_lonlat(out["x"], out["y"])
        front += ["lon", "lat"]
    out = out[front + [c for c in out.columns if c not in front]]
    out.to_csv(path, index=False, float_format="%.12g")
