"""CSV tables with file-line bookkeeping: the steps every reader of :mod:`hmmtrack.io` shares.

A table read here holds strings (cells as written), has an index named ``"line"`` (each row's
1-based line in the file, header = line 1) and ``attrs["source"]`` (the file name), so that
errors raised later (:func:`hmmtrack.tracks.describe_rows`) still name file lines. Blank
lines carry no data and are skipped. The helpers check required columns, convert numbers,
rename file columns to the canonical names and apply the missing-coordinates policy; rows
removed on request are listed in ``attrs["dropped"]`` (``[{"rows": [line, ...], "reason":
str}]``) and logged as a warning; nothing else is ever removed.

Not for: a format's own columns (the reader modules beside this one).
"""

from __future__ import annotations

import contextlib
import csv
import logging
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.tracks import describe_rows

logger = logging.getLogger(__name__)

_MISSING_CHOICES = ("error", "drop", "keep")


def read_csv(path: str | Path, **kwargs) -> pd.DataFrame:
    """Read a CSV as strings, index = 1-based file line (header = 1), blank lines skipped;
    a file without data rows is refused."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    with unreadable_as_value_error(path), warnings.catch_warnings():
        warnings.simplefilter("error", pd.errors.ParserWarning)  # cells beyond the header
        table = pd.read_csv(
            path,
            dtype=str,
            keep_default_na=False,
            na_values=["", "NA", "NaN", "nan"],  # empty cells and R's NA are missing
            skip_blank_lines=False,
            encoding="utf-8-sig",
            index_col=False,  # never take extra cells for an index: refuse them
            **kwargs,
        )
    table.index = pd.RangeIndex(2, 2 + len(table), name="line")
    table = table.loc[table.notna().any(axis=1)].copy()
    if table.empty:
        raise ValueError(f"{path}: no data rows (only a header line)")
    table.attrs["source"] = str(path)
    return table


@contextlib.contextmanager
def unreadable_as_value_error(path: str | Path) -> Iterator[None]:
    """Turn what text and CSV parsing raise on a malformed file (bytes that are not UTF-8,
    no header, a ragged row, an unclosed quote) into a one-line ``ValueError`` naming the
    file and, where known, its line."""
    try:
        yield
    except UnicodeDecodeError:
        raise ValueError(f"{path}: {_not_utf8(Path(path))}") from None
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: empty file (no header line)") from None
    except pd.errors.ParserWarning:
        raise ValueError(f"{path}: {_long_row(Path(path))}") from None
    except (pd.errors.ParserError, csv.Error) as exc:
        reason = " ".join(str(exc).replace("Error tokenizing data. C error: ", "").split())
        raise ValueError(
            f"{path}: not a readable CSV: {reason} (rows need as many cells as the header; "
            "quote cells that hold commas or quotes)"
        ) from None


def _long_row(path: Path) -> str:
    with open(path, encoding="utf-8-sig", newline="") as handle:
        rows = csv.reader(handle)
        width = len(next(rows, []))
        for row in rows:
            if len(row) > width:
                return (
                    f"line {rows.line_num} has {len(row)} cells, the header {width} (quote cells "
                    "that hold commas)"
                )
    return "rows have more cells than the header (quote cells that hold commas)"


def _not_utf8(path: Path) -> str:
    data = path.read_bytes()
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        return (
            f"line {line} is not UTF-8 text (byte 0x{data[exc.start]:02x}); save the file as "
            "UTF-8 (spreadsheets: 'CSV UTF-8')"
        )
    return "not UTF-8 text; save the file as UTF-8"


def require(table: pd.DataFrame, columns: dict[str, str | None], what: str) -> None:
    """Raise if a required column is absent; ``columns`` maps role -> file column name."""
    missing = {role: col for role, col in columns.items() if col and col not in table.columns}
    if missing:
        wanted = ", ".join(f"{col!r} ({role})" for role, col in missing.items())
        raise ValueError(
            f"{table.attrs['source']}: {what} needs column(s) {wanted}; the file has "
            f"{list(table.columns)} (column names can be set with the *_col arguments)"
        )


def numeric(table: pd.DataFrame, column: str, unit: str) -> np.ndarray:
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


def numeric_columns(table: pd.DataFrame, skip: tuple[str, ...]) -> None:
    """Convert, in place, each column not in ``skip`` whose every filled cell is a number."""
    for col in table.columns:
        if col not in skip:
            converted = pd.to_numeric(table[col], errors="coerce")
            if converted.notna().sum() == table[col].notna().sum():
                table[col] = converted


def rename(table: pd.DataFrame, mapping: dict[str, str | None]) -> pd.DataFrame:
    """Rename file columns to canonical names; refuse if an extra column already has one."""
    mapping = {src: dst for dst, src in mapping.items() if src and src != dst}
    clash = [dst for dst in mapping.values() if dst in table.columns and dst not in mapping]
    if clash:
        raise ValueError(
            f"{table.attrs['source']}: column(s) {clash} exist and would be overwritten by "
            f"the renamed columns {mapping}; rename them in the file or choose other columns"
        )
    return table.rename(columns=mapping)


def handle_missing(
    table: pd.DataFrame, columns: list[str], policy: str, remedy: str = ""
) -> pd.DataFrame:
    """Apply the missing-coordinates policy (``error``, ``drop``, ``keep``).

    ``remedy`` is appended to the ``error`` policy's message: how the caller's user can
    choose another policy (empty where there is none, e.g. receivers).
    """
    if policy not in _MISSING_CHOICES:
        raise ValueError(f"missing_coordinates must be one of {_MISSING_CHOICES}, got {policy!r}")
    empty = table[columns].isna().any(axis=1).to_numpy()
    if not empty.any() or policy == "keep":
        return table
    if policy == "error":
        raise ValueError(
            f"{describe_rows(table, np.flatnonzero(empty))}: empty coordinates in column(s) "
            f"{columns}{'; ' + remedy if remedy else ''}"
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
