"""Calendar times: ISO 8601 text in files <-> UTC seconds since the Unix epoch.

Time strings are ISO 8601 (``2019-09-09 16:04:11.193``, ``2019-09-09T16:04:11.193Z``,
``...+02:00``). Strings with an offset are converted to UTC. Naive strings (no offset) need
an explicit ``tz`` (an IANA name such as ``"UTC"`` or ``"America/Los_Angeles"``); without one
the reader raises an error naming the column, because guessing a zone silently shifts a
track by hours. Formats that define their zone (VUE ``Date and Time (UTC)``, Fathom
``Device Time (UTC)``, Movebank ``timestamp``) are read as UTC. Numeric time columns are taken
as UTC seconds since the epoch, or milliseconds when the reader is told so (``time_unit="ms"``,
the CLI's ``--time-unit ms``); numbers too large for seconds (after the year 5000, as epoch
milliseconds of any date after 1973 are) are refused, since read as seconds they put every
detection in a future millennium and the intervals between them 1,000 times too long. Times
are ``float64`` seconds with millisecond and finer precision kept (whole seconds and the
fraction are converted apart).

This is the only module of the package that parses or prints calendar times.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from hmmtrack.tracks import describe_rows

#: numeric times (s) beyond this are refused as seconds: year 5138, while epoch milliseconds of
#: any date after March 1973 exceed it
LARGEST_SECONDS = 1e11
#: numeric time units a reader accepts
TIME_UNITS = ("s", "ms")

_OFFSET = re.compile(r"\d:\d{2}(?::\d{2}(?:\.\d*)?)?\s*(?:Z|[+-]\d{2}(?::?\d{2})?)$", re.I)


def parse_times(table: pd.DataFrame, column: str, tz: str | None, unit: str = "s") -> np.ndarray:
    """Parse a time column of ``table`` to UTC seconds since the epoch.

    Parameters
    ----------
    table : DataFrame
        Table read by this module (index = file lines) holding ``column``.
    column : str
        Column of ISO 8601 strings, or of numbers (taken as UTC epoch seconds).
    tz : str or None
        Zone of strings without an offset; ``None`` makes such strings an error.
    unit : {"s", "ms"}
        Unit of a numeric column (:data:`TIME_UNITS`; UTC since the epoch); ISO 8601
        strings ignore it.

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
    if unit not in TIME_UNITS:
        raise ValueError(f"time unit must be one of {list(TIME_UNITS)}, got {unit!r}")
    if len(text) and numeric.notna().all():
        values = numeric.to_numpy(dtype=float)
        if unit == "ms":  # whole seconds and the fraction apart, as for ISO 8601 text
            whole, fraction = np.divmod(values, 1000.0)
            values = whole + fraction / 1000.0
        out[pos] = values
        largest = np.flatnonzero(np.abs(out) > LARGEST_SECONDS)
        if largest.size:
            raise ValueError(
                f"{describe_rows(table, pos[largest])}: column {column!r} holds numbers such as "
                f"{text.iloc[largest[0]]} ({unit}), after the year 5000 as epoch seconds: "
                "epoch milliseconds? Pass --time-unit ms (time_unit='ms'), or write the "
                "times as ISO 8601"
            )
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
                    f"UTC offset (e.g. {part.iloc[0]!r}); give the time zone they were recorded "
                    "in: --tz UTC on the command line, tz='UTC' in Python"
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
