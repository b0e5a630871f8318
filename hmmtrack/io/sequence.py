"""The burst-interval sequence of a tag with a known pseudo-random interval (YAPS's "pbi").

A tag of this kind waits ``interval[k]`` seconds after its ``k``-th ping, taking the
intervals of a fixed sequence in order and starting again at its beginning when it runs out.
The file is a CSV with an ``interval`` column (s), one row per interval in the order the tag
uses them (``hmmtrack simulate moored-array`` writes one as ``burst_sequence.csv``).

Not for: aligning the sequence to the detections
(:mod:`hmmtrack.tracking.measurement.sequence`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io.tables import numeric, read_csv, require
from hmmtrack.tracks import describe_rows

__all__ = ["read_burst_sequence"]


def read_burst_sequence(path: str | Path) -> np.ndarray:
    """The intervals (s) of a burst-sequence file, in file order.

    Parameters
    ----------
    path : str or Path
        CSV with an ``interval`` column (s); other columns are ignored.

    Returns
    -------
    numpy.ndarray, shape (L,)
        Positive finite intervals (s).

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        An unreadable file, no ``interval`` column, or an empty, non-numeric, non-finite or
        non-positive interval (naming the file, its line and the column).
    """
    table = read_csv(path)
    require(table, {"burst interval": "interval"}, "a burst sequence")
    intervals = numeric(table, "interval", "s")
    bad = np.flatnonzero(~(np.isfinite(intervals) & (intervals > 0)))
    if bad.size:
        found = table["interval"].iloc[bad[0]]
        raise ValueError(
            f"{describe_rows(table, bad)}: column 'interval' must hold positive finite intervals "
            f"(s), found {'an empty cell' if pd.isna(found) else repr(found)}"
        )
    return intervals
