"""From raw detections of sync tags to emissions heard by several receivers.

Receivers' clocks may disagree by minutes, so the detections of one sync-tag emission
cannot be grouped on the raw times. Two steps:

1. :func:`coarse_clocks` - for each sync tag, the differences between a receiver's
   detection times and those of the tag's *anchor* (its own receiver, or the receiver that
   heard it most) pile up at one value, the clock difference plus a fixed travel time,
   drifting slowly: the peak of their histogram within ``max_clock_offset``, then a line
   fitted through the differences near it, gives that pair's offset and drift. A weighted
   least-squares solve over all pairs puts every receiver on the time keeper's clock to a
   fraction of a second (travel times are ignored here).
2. :func:`group_pings` - on that coarse time base, a sync tag's detections within the
   array's largest travel time (plus a tolerance) of the first detection of a group are one
   emission; a second detection of it at the same receiver is an echo (multipath) and is
   dropped and counted.

Not for: the clock fit itself (:mod:`hmmtrack.sync.fit`).
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

logger = logging.getLogger(__name__)

#: histogram bin (s) for the peak of detection-time differences; wider than the drift of a
#: receiver pair over a few days (20 ppm x 1 day = 1.7 s) would blur the peak
PEAK_BIN = 2.0
#: detection-time differences farther than this (s) from a pair's fitted line are not its
#: matches (travel times are constant for moored pairs; only clock curvature remains)
MATCH_TOLERANCE = 0.05
#: lowest plausible sound speed (m/s), for the array's largest travel time
SLOWEST_SOUND = 1400.0


def pair_offset(
    times: np.ndarray, anchor: np.ndarray, max_clock_offset: float, reference: float
) -> tuple[float, float, int]:
    """Clock offset and drift of one receiver against an anchor, from one tag's detections.

    Parameters
    ----------
    times, anchor : (n,), (m,) sorted float arrays
        Detection times (s) of the same sync tag at the receiver and at the anchor, each in
        its own clock.
    max_clock_offset : float
        Largest clock difference (s) considered.
    reference : float
        Time (s) at which the offset is stated.

    Returns
    -------
    offset : float
        ``times - anchor`` at ``reference`` (s; includes the constant travel time).
    drift : float
        Rate of change of that difference (s/s).
    matches : int
        Detections matched to an anchor detection (0: no peak found).
    """
    lo = np.searchsorted(anchor, times - max_clock_offset)
    hi = np.searchsorted(anchor, times + max_clock_offset, side="right")
    counts = hi - lo
    if counts.sum() == 0:
        return np.nan, np.nan, 0
    own = np.repeat(np.arange(times.size), counts)
    other = np.concatenate([np.arange(a, b) for a, b in zip(lo, hi, strict=True)])
    diff = times[own] - anchor[other]
    at = anchor[other] - reference
    edges = np.arange(-max_clock_offset, max_clock_offset + PEAK_BIN, PEAK_BIN)
    histogram, _ = np.histogram(diff, bins=edges)
    peak = np.argmax(histogram)
    near = np.abs(diff - 0.5 * (edges[peak] + edges[peak + 1])) <= 1.5 * PEAK_BIN
    slope, intercept = 0.0, float(np.median(diff[near]))
    for tolerance in (PEAK_BIN, 0.5, MATCH_TOLERANCE):
        near = np.abs(diff - intercept - slope * at) <= tolerance
        if near.sum() < 2:
            return np.nan, np.nan, 0
        if np.ptp(at[near]) > 0:
            slope, intercept = np.polyfit(at[near], diff[near], 1)
        else:
            intercept = float(np.median(diff[near]))
    return float(intercept), float(slope), int(near.sum())


def coarse_clocks(
    sync: pd.DataFrame,
    anchors: dict[str, str],
    receivers: list[str],
    time_keeper: str,
    max_clock_offset: float,
    min_detections: int,
) -> tuple[dict[str, tuple[float, float]], float]:
    """Every receiver's offset and drift against the time keeper, to a fraction of a second.

    Parameters
    ----------
    sync : DataFrame
        Sync-tag detections: ``time`` (each receiver's clock, s), ``receiver``, ``sync_tag``.
    anchors : dict of str to str
        Sync tag -> the receiver its other detections are compared with.
    receivers : list of str
        Receivers to synchronise (the time keeper among them).
    time_keeper : str
    max_clock_offset : float
        Largest clock difference (s) between two receivers.
    min_detections : int
        A receiver pair needs this many matched detections to count.

    Returns
    -------
    clocks : dict of str to (offset s, drift s/s)
        Receiver time minus time keeper's time is ``offset + drift * (t - reference)``.
    reference : float
        The reference time (s): the first sync detection.
    """
    reference = float(sync["time"].min())
    index = {name: i for i, name in enumerate(receivers)}
    rows, targets, weights = [], [], []
    matched = dict.fromkeys(receivers, 0)
    for tag, anchor in anchors.items():
        of_tag = sync[sync["sync_tag"] == tag]
        anchor_times = np.sort(of_tag.loc[of_tag["receiver"] == anchor, "time"].to_numpy())
        for name, group in of_tag.groupby("receiver", sort=False):
            if name == anchor:
                continue
            offset, drift, n = pair_offset(
                np.sort(group["time"].to_numpy()), anchor_times, max_clock_offset, reference
            )
            if n < min_detections:
                continue
            matched[name] += n
            matched[anchor] += n
            row = np.zeros(len(receivers))
            row[index[name]], row[index[anchor]] = 1.0, -1.0
            rows.append(row)
            targets.append((offset, drift))
            weights.append(np.sqrt(n))
    connected = _connected(rows, receivers, time_keeper)
    lonely = [name for name in receivers if name not in connected]
    if lonely:
        raise ValueError(
            f"receiver(s) {lonely} have too few sync detections matched to another receiver's "
            f"(fewer than {min_detections} per sync tag; matched: "
            f"{ {name: matched[name] for name in lonely} }); they cannot be put on the time "
            f"keeper's clock: remove them from the receivers file or lower min_detections"
        )
    design = np.array(rows) * np.array(weights)[:, None]
    keep = [i for i, name in enumerate(receivers) if name != time_keeper]
    solution, *_ = np.linalg.lstsq(
        design[:, keep], np.array(targets) * np.array(weights)[:, None], rcond=None
    )
    clocks = {time_keeper: (0.0, 0.0)}
    for j, i in enumerate(keep):
        clocks[receivers[i]] = (float(solution[j, 0]), float(solution[j, 1]))
    return clocks, reference


def _connected(rows: list[np.ndarray], receivers: list[str], time_keeper: str) -> set[str]:
    """Receivers linked to the time keeper through the pairs of ``rows``."""
    links = [tuple(np.flatnonzero(row)) for row in rows]
    reached = {receivers.index(time_keeper)}
    grew = True
    while grew:
        grew = False
        for a, b in links:
            if (a in reached) != (b in reached):
                reached |= {a, b}
                grew = True
    return {receivers[i] for i in reached}


def largest_travel_time(positions: np.ndarray) -> float:
    """The array's largest travel time (s): its largest receiver separation at the slowest
    plausible sound speed (:data:`SLOWEST_SOUND`), the span of one emission's arrivals.

    Parameters
    ----------
    positions : (R, 2) or (R, 3) float array
        Receiver positions (m).
    """
    positions = np.asarray(positions, dtype=float)
    separation = np.linalg.norm(positions[:, None] - positions[None], axis=-1)
    return float(np.max(separation, initial=0.0)) / SLOWEST_SOUND


def group_pings(
    sources: np.ndarray, receivers: np.ndarray, times: np.ndarray, window: float
) -> tuple[np.ndarray, int]:
    """Group detections into emissions: each source's detections close in time are one ping.

    A source's detections within ``window`` (s) after the first detection of a group belong
    to that group; a second detection of it at the same receiver is an echo (multipath)
    and is dropped and counted. Used for sync tags (:func:`hmmtrack.sync.fit.fit_clocks`)
    and for tracked tags (:mod:`hmmtrack.tracking.measurement.pings`).

    Parameters
    ----------
    sources : (n,) array
        The emitter of each detection (e.g. the sync tag's ID); one value for one tag.
    receivers : (n,) array
        The receiver of each detection.
    times : (n,) float array
        Each detection's time on a common time base (s; coarse is enough).
    window : float
        The array's largest travel time plus the clocks' error (s); for a tag whose
        emissions can be closer together than that, the shortest interval between them.

    Returns
    -------
    ping : (n,) int array
        Emission index of each detection (0, 1, ... in order of source, then time), -1 for
        a dropped echo.
    echoes : int
        Echoes dropped.
    """
    times = np.asarray(times, dtype=float)
    sources = np.asarray(sources)
    receivers = np.asarray(receivers)
    ping = np.full(times.size, -1, dtype=np.int64)
    next_ping, echoes = 0, 0
    for source in pd.unique(sources):
        rows = np.flatnonzero(sources == source)
        rows = rows[np.argsort(times[rows], kind="stable")]
        start, heard = -np.inf, set()
        for row, time in zip(rows.tolist(), times[rows].tolist(), strict=True):
            if time > start + window:
                start, heard = time, set()
                next_ping += 1
            if receivers[row] in heard:
                echoes += 1
                continue
            heard.add(receivers[row])
            ping[row] = next_ping - 1
    return ping, echoes
