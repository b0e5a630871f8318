"""Readers of detection logs: Innovasea VUE export, Innovasea Fathom CSV, or plain CSV.

All return the *detections* table of ``docs/interfaces.md``: ``time`` (UTC seconds, each
receiver's own clock), ``receiver``, ``transmitter`` and what else the format holds, sorted by
time, ``attrs["format"]`` the format read.
"""

from __future__ import annotations

import csv
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io.tables import (
    numeric,
    numeric_columns,
    read_csv,
    require,
    unreadable_as_value_error,
)
from hmmtrack.io.times import parse_times
from hmmtrack.tracks import describe_rows

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


def detect_format(path: str | Path) -> str:
    """Guess a detection log's format from its first line: ``"fathom"``, ``"vue"`` or
    ``"plain"``."""
    with unreadable_as_value_error(path), open(path, encoding="utf-8-sig") as handle:
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
    time_unit: str = "s",
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
    time_unit : {"s", "ms"}
        Unit of numeric times (UTC since the epoch, :func:`hmmtrack.io.times.parse_times`).

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
    table = readers[fmt](Path(path), tz, time_unit)
    for col in ("receiver", "transmitter"):
        empty = np.flatnonzero(table[col].isna().to_numpy())
        if empty.size:
            raise ValueError(f"{describe_rows(table, empty)}: column {col!r} is empty")
    bad = np.flatnonzero(~np.isfinite(table["time"].to_numpy()))
    if bad.size:
        raise ValueError(f"{describe_rows(table, bad)}: detection time is empty")
    if "code_space" not in table.columns:
        _split_transmitter(table)
    if transmitter is not None:
        wanted = {transmitter} if isinstance(transmitter, str) else set(transmitter)
        keep = np.zeros(len(table), dtype=bool)
        for name in sorted(wanted):
            try:
                keep |= transmitter_rows(table, name)
            except ValueError as exc:
                raise ValueError(f"{path}: {exc}") from exc
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


def transmitter_rows(table: pd.DataFrame, transmitter: str) -> np.ndarray:
    """Which rows of a detections table are of one transmitter, shape ``(n_rows,)`` bool.

    ``transmitter`` is a full id (``A69-1602-15266``), or, when no full id equals it and the
    table has a ``transmitter_id`` column, an ID part (``15266``). An ID part is only a name
    within its code space: when it is the ID part of tags in more than one code space
    (``A69-1602-42`` and ``A69-9001-42``), merging them would track two animals as one, so it
    is refused.

    Raises
    ------
    ValueError
        For an ID part shared by several full ids, listing them.
    """
    full = table["transmitter"].astype(str)
    keep = (full == transmitter).to_numpy()
    if keep.any() or "transmitter_id" not in table.columns:
        return keep
    keep = (table["transmitter_id"].astype(str) == transmitter).to_numpy()
    matched = sorted(full[keep].unique())
    if len(matched) > 1:
        raise ValueError(
            f"transmitter {transmitter!r} is ambiguous: it is the ID part of {matched} (one ID "
            "in different code spaces, different tags); give the full ID, e.g. --transmitter "
            f"{matched[0]}"
        )
    return keep


def _split_transmitter(table: pd.DataFrame) -> None:
    """Add ``code_space`` and ``transmitter_id`` (``A69-1602`` and ``15266`` of
    ``A69-1602-15266``; missing for a name without ``-``) when some name has that form.
    Split once per distinct name: a season's log holds few tags but millions of rows."""
    codes, names = pd.factorize(table["transmitter"])
    parts = [name.rsplit("-", 1) for name in names]
    if not any(len(p) == 2 for p in parts):
        return
    dtype = table["transmitter"].dtype
    for column, k in (("code_space", 0), ("transmitter_id", 1)):
        values = np.array([p[k] if len(p) == 2 else np.nan for p in parts], dtype=object)
        table[column] = pd.Series(values[codes], index=table.index, dtype=dtype)


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
        dst, is_number = _OPTIONAL_COLUMNS[src]
        if src in raw.columns and raw[src].notna().any():
            table[dst] = numeric(raw, src, "number") if is_number else raw[src]
    table.attrs = dict(raw.attrs)


def _read_vue(path: Path, tz: str | None, unit: str) -> pd.DataFrame:
    raw = read_csv(path)
    require(
        raw,
        {"time": VUE_COLUMNS[0], "receiver": "Receiver", "transmitter": "Transmitter"},
        "a VUE export",
    )
    table = pd.DataFrame(index=raw.index)
    table["time"] = parse_times(raw, VUE_COLUMNS[0], "UTC", unit)
    table["receiver"] = raw["Receiver"].str.strip()
    table["transmitter"] = raw["Transmitter"].str.strip()
    table["receiver_model"], table["receiver_serial"] = _split_receiver(table["receiver"])
    _copy_optional(raw, table, _VUE_OPTIONAL)
    return table


def _read_fathom(path: Path, tz: str | None, unit: str) -> pd.DataFrame:
    with unreadable_as_value_error(path), open(path, encoding="utf-8-sig", newline="") as handle:
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
    require(
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
    table["time"] = parse_times(raw, "Device Time (UTC)", "UTC", unit)
    if "Time Correction (s)" in raw.columns:
        correction = numeric(raw, "Time Correction (s)", "seconds")
        table["time"] += np.nan_to_num(correction)
    model = raw["Model"].str.strip().str.replace(r"-\d+$", "", regex=True)
    table["receiver"] = model + "-" + raw["Serial Number"].str.strip()
    table["transmitter"] = raw["Full ID"].str.strip()
    table["receiver_model"] = model
    table["receiver_serial"] = raw["Serial Number"].str.strip()
    _copy_optional(raw, table, _FATHOM_OPTIONAL)
    return table


def _read_plain_detections(path: Path, tz: str | None, unit: str) -> pd.DataFrame:
    raw = read_csv(path)
    require(
        raw,
        {"time": "time", "receiver": "receiver", "transmitter": "transmitter"},
        "a plain detections CSV",
    )
    table = raw.copy()
    table["time"] = parse_times(raw, "time", tz, unit)
    for col in ("receiver", "transmitter"):
        table[col] = raw[col].str.strip()
    numeric_columns(table, skip=("time", "receiver", "transmitter"))
    return table


def drop_duplicate_detections(detections: pd.DataFrame) -> pd.DataFrame:
    """The detections without exact repeats: one row per (time, receiver, transmitter).

    A receiver hears a tag's ping once; a second row with the same time, receiver and
    transmitter is the same detection logged twice (an offload read twice, logs merged),
    carrying no information. Every measurement gets each detection once: counting it twice
    would double its weight (arrival time), and a pair at one time has no range rate. The
    first row is kept and the number dropped is logged as a warning.
    """
    key = [c for c in ("time", "receiver", "transmitter") if c in detections.columns]
    repeated = detections.duplicated(subset=key, keep="first").to_numpy()
    if not repeated.any():
        return detections
    source = detections.attrs.get("source", "detections")
    logger.warning(
        "%s: dropped %d exact duplicate detection(s) (same %s as an earlier row), e.g. rows %s",
        source,
        int(repeated.sum()),
        ", ".join(key),
        detections.index[repeated][:5].tolist(),
    )
    return detections.loc[~repeated]
