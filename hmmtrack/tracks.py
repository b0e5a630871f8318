"""Track maths: validation, gap splitting, regular grids, step lengths and turning angles.

This module turns a *tracks* table (``id``, ``time``, ``x``, ``y`` in UTC seconds and
projected metres, see ``docs/interfaces.md``) into the *prepared track* that a movement HMM
is fitted to, with the conventions of moveHMM's ``prepData``:

* row ``t`` holds the step from fix ``t`` to fix ``t + 1`` and the turning angle at fix ``t``;
* the first angle of a segment and its last step and angle are missing (NaN);
* an angle next to a zero-length step is missing (the heading is undefined there);
* ``dt`` is the time to the next fix, ``speed = step / dt`` and
  ``angular_velocity = angle / dt`` (the paper's per-second observables).

It is *not* for file formats, calendar times or map projections (that is
:mod:`hmmtrack.io`) and holds no model maths (that is :mod:`hmmtrack.hmm`).

Row locations in error messages: tables read by :mod:`hmmtrack.io` carry an index named
``"line"`` holding the 1-based line of the source file (header = line 1) and the file name in
``attrs["source"]``; errors then name file lines. Other tables are described by their index
labels. Rows removed on request (short segments) are never lost silently: they are listed in
``attrs["dropped"]`` (a list of ``{"rows": [...], "reason": str}``) and logged as a warning.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import pandas as pd

logger = logging.getLogger(__name__)

_MAX_LISTED = 10


def describe_rows(table: pd.DataFrame, positions: Sequence[int] | np.ndarray) -> str:
    """Describe rows of ``table`` for an error message.

    Parameters
    ----------
    table : DataFrame
        The table; if its index is named ``"line"`` the labels are file line numbers and the
        file name is taken from ``table.attrs["source"]``.
    positions : sequence of int
        0-based row positions (``iloc``) of the offending rows.

    Returns
    -------
    str
        For example ``"tracks.csv lines 5, 9"`` or ``"rows 3, 4"``; at most ten rows are
        listed, followed by the number of others.
    """
    positions = np.asarray(positions, dtype=np.int64)
    labels = [str(v) for v in table.index[positions[:_MAX_LISTED]]]
    more = len(positions) - len(labels)
    listed = ", ".join(labels) + (f" and {more} more" if more > 0 else "")
    if table.index.name == "line":
        noun = "line" if len(positions) == 1 else "lines"
        source = table.attrs.get("source")
        return f"{source} {noun} {listed}" if source else f"{noun} {listed}"
    noun = "row" if len(positions) == 1 else "rows"
    return f"{noun} {listed}"


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Wrap angles (rad) to ``(-pi, pi]``, moveHMM's convention for turning angles."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
    # np.mod can round a tiny negative argument up to 2*pi, giving -pi: fold it onto +pi
    return np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)


def _require_columns(tracks: pd.DataFrame, columns: Sequence[str], what: str) -> None:
    missing = [c for c in columns if c not in tracks.columns]
    if missing:
        raise ValueError(f"{what}: missing column(s) {missing}; found {list(tracks.columns)}")


def _group_codes(labels: pd.Series) -> np.ndarray:
    """Integer codes of ``labels`` numbered in order of first appearance, shape (n,)."""
    codes, _ = pd.factorize(labels, sort=False)
    return codes


def _grouped_order(labels: pd.Series) -> np.ndarray:
    """Positions that make each label's rows contiguous, keeping their order, shape (n,)."""
    return np.argsort(_group_codes(labels), kind="stable")


def validate_tracks(tracks: pd.DataFrame, *, min_fixes: int = 2) -> None:
    """Check a tracks table and raise ``ValueError`` naming the rows at fault.

    Checks: the columns ``id``, ``x``, ``y`` exist; ``x``, ``y`` are numeric and not infinite
    (NaN marks a missing fix and is allowed); when ``time`` exists it is finite and strictly
    increasing within each animal (in row order); each animal has at least ``min_fixes``
    rows.

    Parameters
    ----------
    tracks : DataFrame
        Tracks table (``id``, optional ``time`` in s, ``x``, ``y`` in m).
    min_fixes : int
        Fewest rows an animal may have.
    """
    _require_columns(tracks, ("id", "x", "y"), "tracks")
    for col in ("x", "y"):
        if not pd.api.types.is_numeric_dtype(tracks[col]):
            bad = np.flatnonzero(
                pd.to_numeric(tracks[col], errors="coerce").isna() & tracks[col].notna()
            )
            raise ValueError(
                f"{describe_rows(tracks, bad)}: column {col!r} must be numeric (metres), "
                f"found {tracks[col].iloc[bad[0]]!r}"
            )
        infinite = np.flatnonzero(np.isinf(tracks[col].to_numpy(dtype=float)))
        if infinite.size:
            raise ValueError(
                f"{describe_rows(tracks, infinite)}: column {col!r} is infinite; "
                "expected finite metres (NaN for a missing fix)"
            )
    ids = tracks["id"]
    if ids.isna().any():
        bad = np.flatnonzero(ids.isna())
        raise ValueError(f"{describe_rows(tracks, bad)}: column 'id' is empty")
    codes = _group_codes(ids)
    if "time" in tracks.columns:
        if not pd.api.types.is_numeric_dtype(tracks["time"]):
            raise ValueError(
                f"tracks: column 'time' must hold UTC seconds (float), found dtype "
                f"{tracks['time'].dtype}; read calendar times with hmmtrack.io"
            )
        time = tracks["time"].to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(time))
        if bad.size:
            raise ValueError(
                f"{describe_rows(tracks, bad)}: column 'time' is missing or not finite"
            )
        order = np.argsort(codes, kind="stable")
        same = codes[order][1:] == codes[order][:-1]
        step = np.diff(time[order])
        for kind, mask in (("duplicate", same & (step == 0)), ("decreasing", same & (step < 0))):
            if mask.any():
                at = np.flatnonzero(mask)
                pairs = np.unique(np.concatenate([order[at], order[at + 1]]))
                animal = ids.iloc[order[at[0] + 1]]
                raise ValueError(
                    f"{describe_rows(tracks, pairs)}: {kind} times within animal "
                    f"{animal!r} (column 'time'); times must be strictly increasing per "
                    "animal"
                )
    counts = np.bincount(codes)
    few = np.flatnonzero(counts < min_fixes)
    if few.size:
        names = pd.unique(ids)[few]
        rows = np.flatnonzero(np.isin(codes, few))
        raise ValueError(
            f"{describe_rows(tracks, rows)}: animal(s) {list(names)} have fewer than "
            f"{min_fixes} fixes ({list(counts[few])})"
        )


def _record_dropped(table: pd.DataFrame, dropped: list[dict]) -> None:
    if dropped:
        table.attrs["dropped"] = list(table.attrs.get("dropped", [])) + dropped
        for entry in dropped:
            logger.warning("dropped %d row(s): %s", len(entry["rows"]), entry["reason"])


def split_at_gaps(tracks: pd.DataFrame, max_gap: float, *, min_fixes: int = 1) -> pd.DataFrame:
    """Split each animal's track where consecutive fixes are more than ``max_gap`` apart.

    Parameters
    ----------
    tracks : DataFrame
        Tracks table with ``id`` and ``time`` (s), rows of an animal in time order.
    max_gap : float
        Largest time (s) between consecutive fixes of one segment (the paper used 180 s).
    min_fixes : int
        Segments with fewer fixes are removed; the removed rows are listed in
        ``attrs["dropped"]`` and logged. The default 1 keeps every segment.

    Returns
    -------
    DataFrame
        A copy with a ``segment`` column (str): the animal ``id`` when it is one segment,
        else ``"id#1"``, ``"id#2"``, ... in time order. Rows of an animal are made contiguous
        (order within an animal kept); the index is kept.
    """
    if not max_gap > 0:
        raise ValueError(f"max_gap must be a positive number of seconds, got {max_gap!r}")
    _require_columns(tracks, ("id", "time"), "split_at_gaps")
    validate_tracks(tracks, min_fixes=1)
    out = tracks.iloc[_grouped_order(tracks["id"])].copy()
    ids = out["id"].astype(str).to_numpy()
    time = out["time"].to_numpy(dtype=float)
    new_animal = np.r_[True, ids[1:] != ids[:-1]]
    starts = new_animal | (np.r_[False, np.diff(time) > max_gap] & ~new_animal)
    animal_code = np.cumsum(new_animal) - 1
    k = pd.Series(starts).groupby(animal_code).cumsum().to_numpy()  # 1-based within animal
    n_segments = np.bincount(animal_code, weights=starts).astype(int)
    split = n_segments[animal_code] > 1
    out["segment"] = np.where(split, np.char.add(np.char.add(ids, "#"), k.astype(str)), ids)
    if min_fixes > 1:
        segment = out["segment"]
        short = (segment.map(segment.value_counts()) < min_fixes).to_numpy()
        if short.any():
            dropped = [
                {
                    "rows": out.index[(segment == name).to_numpy()].tolist(),
                    "reason": f"segment {name!r} has fewer than {min_fixes} fixes "
                    f"(split_at_gaps, max_gap={max_gap} s)",
                }
                for name in pd.unique(segment[short])
            ]
            out = out.iloc[np.flatnonzero(~short)].copy()
            _record_dropped(out, dropped)
    return out


def regularise(tracks: pd.DataFrame, step: float, *, max_gap: float | None = None) -> pd.DataFrame:
    """Resample each segment to a fixed time step by linear interpolation.

    Each segment (``segment`` column, else each animal) gets the grid
    ``t0, t0 + step, ...`` up to its last fix, ``t0`` being its first fix. A grid time is
    interpolated linearly between the two fixes around it; when those fixes are more than
    ``max_gap`` apart, or one of them is a missing fix (NaN), the row is kept with NaN
    coordinates: missing data, never invented data.

    Parameters
    ----------
    tracks : DataFrame
        Tracks table with ``id``, ``time`` (s), ``x``, ``y`` (m), optionally ``segment``.
    step : float
        Time step of the grid (s).
    max_gap : float, optional
        Longest interval between fixes (s) that is interpolated across; ``None`` interpolates
        across every interval inside a segment (split first with :func:`split_at_gaps`).

    Returns
    -------
    DataFrame
        Columns ``id``, ``segment``, ``time``, ``x``, ``y`` and the extra columns of
        ``tracks``: numeric ones interpolated like ``x``, others taken from the fix at or
        before the grid time. A fresh ``RangeIndex``; ``attrs`` are kept.
    """
    if not step > 0:
        raise ValueError(f"step must be a positive number of seconds, got {step!r}")
    _require_columns(tracks, ("id", "time", "x", "y"), "regularise")
    validate_tracks(tracks, min_fixes=1)
    segment = tracks["segment"] if "segment" in tracks.columns else tracks["id"].astype(str)
    order = _grouped_order(segment)
    src = tracks.iloc[order].reset_index(drop=True)
    seg = segment.iloc[order].to_numpy()
    t = src["time"].to_numpy(dtype=float)
    first = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])  # first fix of each segment
    last = np.r_[first[1:], len(t)] - 1
    n_grid = np.floor((t[last] - t[first]) / step + 1e-9).astype(np.int64) + 1
    # grid point g belongs to segment owner[g] and is t0 + step·k there
    owner = np.repeat(np.arange(first.size), n_grid)
    k = np.arange(owner.size) - np.repeat(np.cumsum(n_grid) - n_grid, n_grid)
    grid = t[first][owner] + step * k
    left = _fix_at_or_before(
        np.repeat(np.arange(first.size), np.diff(np.r_[first, len(t)])), t, owner, grid
    )
    right = np.minimum(left + 1, last[owner])
    span = t[right] - t[left]
    frac = np.divide(grid - t[left], span, out=np.zeros_like(grid), where=span > 0)
    exact = np.isclose(grid, t[left], rtol=0.0, atol=1e-9)
    too_long = (span > max_gap) & ~exact if max_gap is not None else np.zeros_like(exact)
    columns = {
        "id": src["id"].to_numpy()[first][owner],
        "segment": seg[first][owner],
        "time": grid,
    }
    for col in (c for c in src.columns if c not in ("id", "segment", "time")):
        values = src[col].to_numpy()
        if pd.api.types.is_numeric_dtype(src[col]) and not pd.api.types.is_bool_dtype(src[col]):
            v = values.astype(float)
            interp = np.where(exact, v[left], v[left] + frac * (v[right] - v[left]))
            columns[col] = np.where(too_long, np.nan, interp)
        else:
            columns[col] = values[left]
    out = pd.DataFrame(columns)
    out.attrs = dict(tracks.attrs)
    return out


def _fix_at_or_before(
    fix_segment: np.ndarray, fix_time: np.ndarray, grid_segment: np.ndarray, grid_time: np.ndarray
) -> np.ndarray:
    """Index of the last fix of the same segment at or before each grid time, shape (G,).

    Fixes are grouped by segment (codes increasing) and sorted by time within each; every
    grid time is at or after its segment's first fix. One stable sort of fixes and grid
    points together by (segment, time), fixes before grid points at equal times.
    """
    segment = np.r_[fix_segment, grid_segment]
    time = np.r_[fix_time, grid_time]
    is_fix = np.r_[np.ones(fix_time.size, bool), np.zeros(grid_time.size, bool)]
    order = np.lexsort((~is_fix, time, segment))
    fixes_so_far = np.cumsum(is_fix[order]) - 1
    left = np.empty(grid_time.size, dtype=np.int64)
    at_grid = ~is_fix[order]
    left[order[at_grid] - fix_time.size] = fixes_so_far[at_grid]
    return left


def length_unit(scale: float) -> str:
    """Name of a length unit of ``scale`` metres: ``"m"``, ``"km"`` or ``"<scale> m"``.

    ``scale`` is what :func:`prepare` divides lengths by (``attrs["length_unit_m"]`` of a
    prepared track); the name labels steps in model files, tables and figures.
    """
    return {1.0: "m", 1000.0: "km"}.get(float(scale), f"{scale:g} m")


def prepare(
    tracks: pd.DataFrame,
    *,
    scale: float = 1.0,
    max_gap: float | None = None,
    min_fixes: int = 1,
) -> pd.DataFrame:
    """Compute steps, turning angles, time steps, speeds and angular velocities.

    Parameters
    ----------
    tracks : DataFrame
        Tracks table: ``id``, ``x``, ``y`` (m), optionally ``time`` (s) and ``segment``.
        Without ``time``, ``dt``, ``speed`` and ``angular_velocity`` are NaN. NaN
        coordinates mark missing fixes (their steps and angles are NaN).
    scale : float
        Length unit in metres: ``x``, ``y`` and ``step`` are divided by it (moveHMM's elk
        example works in km, ``scale=1000``). Recorded in ``attrs["length_unit_m"]``.
    max_gap : float, optional
        If given and there is no ``segment`` column yet, split at gaps longer than this
        (s) first, with :func:`split_at_gaps` and ``min_fixes``.
    min_fixes : int
        Passed to :func:`split_at_gaps`.

    Returns
    -------
    DataFrame
        A copy, rows of each segment contiguous, with ``segment`` (str), ``step`` (length
        unit, fix t to t+1), ``angle`` (rad in ``(-pi, pi]``, turn at fix t), ``dt`` (s, to
        the next fix), ``speed`` (length unit per s) and ``angular_velocity`` (rad/s). A
        segment's first angle and last step, angle, ``dt`` are NaN; an angle next to a
        zero-length step is NaN.
    """
    if not scale > 0:
        raise ValueError(f"scale must be a positive length in metres, got {scale!r}")
    _require_columns(tracks, ("id", "x", "y"), "prepare")
    if "segment" in tracks.columns:
        validate_tracks(tracks, min_fixes=1)
        out = tracks.iloc[_grouped_order(tracks["segment"])].copy()
    elif max_gap is not None:
        out = split_at_gaps(tracks, max_gap, min_fixes=min_fixes)
    else:
        validate_tracks(tracks, min_fixes=1)
        out = tracks.iloc[_grouped_order(tracks["id"])].copy()
        out["segment"] = out["id"].astype(str)
    out["x"] = out["x"].to_numpy(dtype=float) / scale
    out["y"] = out["y"].to_numpy(dtype=float) / scale
    x = out["x"].to_numpy()
    y = out["y"].to_numpy()
    seg = out["segment"].to_numpy()
    n = len(out)
    same_next = np.r_[seg[1:] == seg[:-1], False] if n else np.zeros(0, dtype=bool)
    dx = np.full(n, np.nan)
    dy = np.full(n, np.nan)
    dx[:-1] = np.diff(x)
    dy[:-1] = np.diff(y)
    dx[~same_next] = np.nan
    dy[~same_next] = np.nan
    step = np.hypot(dx, dy)
    heading = np.where(step > 0, np.arctan2(dy, dx), np.nan)
    angle = np.full(n, np.nan)
    if n > 1:
        angle[1:] = wrap_angle(heading[1:] - heading[:-1])
        angle[1:][~same_next[:-1]] = np.nan
    if "time" in out.columns:
        dt = np.full(n, np.nan)
        dt[:-1] = np.diff(out["time"].to_numpy(dtype=float))
        dt[~same_next] = np.nan
    else:
        dt = np.full(n, np.nan)
    out["step"] = step
    out["angle"] = angle
    out["dt"] = dt
    out["speed"] = step / dt
    out["angular_velocity"] = angle / dt
    out.attrs["length_unit_m"] = float(scale)
    return out
