"""Even measurement thinning: the paper's measurement-loss sweep ("at 50 % every other goes").

This module removes detections deterministically and evenly; random loss belongs to the
detection simulation (:mod:`hmmtrack.scenarios.detection`).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pandas as pd

#: largest denominator used to read ``fraction`` as an exact ratio
MAX_DENOMINATOR = 1_000_000


def thin_evenly(detections: pd.DataFrame, fraction: float) -> pd.DataFrame:
    """Drop a fraction of the detections, evenly spread through each hydrophone's log.

    For each (``receiver``, ``transmitter``) stream, with its ``n`` detections numbered
    ``i = 0 .. n-1`` in time order, detection ``i`` is dropped when
    ``floor((i + 1) * fraction) > floor(i * fraction)``. Exactly ``floor(n * fraction)`` of
    the stream go, and they are as evenly spaced as whole detections allow: at 0.5 the 2nd,
    4th, 6th ... go; at 0.25 every 4th; at 0.75 all but every 4th; at 1 all. The first
    detection of a stream is kept for any fraction below 1, so accumulated ranges stay
    anchored to the scenario's ``r0`` (the range of that first detection). ``fraction`` is
    read as the nearest ratio with denominator at most :data:`MAX_DENOMINATOR`, so that 0.3
    means exactly 3/10.

    Parameters
    ----------
    detections : DataFrame
        Detections table (``time``, ``receiver``, ``transmitter``, ...).
    fraction : float
        Share of detections to drop, in ``[0, 1]``.

    Returns
    -------
    DataFrame
        The kept rows, in their original order, with a fresh index; all columns kept.
    """
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"thin_evenly: fraction must be in [0, 1], got {fraction}")
    missing = [c for c in ("time", "receiver", "transmitter") if c not in detections.columns]
    if missing:
        raise ValueError(
            f"thin_evenly: detections lack column(s) {missing}; found {list(detections.columns)}"
        )
    ratio = Fraction(fraction).limit_denominator(MAX_DENOMINATOR)
    keep = np.ones(len(detections), dtype=bool)
    order = np.argsort(detections["time"].to_numpy(), kind="stable")
    streams = detections.iloc[order].groupby(["receiver", "transmitter"], sort=False).indices
    for rows in streams.values():
        i = np.arange(rows.size, dtype=np.int64)
        dropped = ((i + 1) * ratio.numerator) // ratio.denominator > (
            i * ratio.numerator
        ) // ratio.denominator
        keep[order[rows[dropped]]] = False
    return detections[keep].reset_index(drop=True)
