"""One tag's detections grouped into pings: the arrivals of one emission at several receivers.

A ping is heard by every receiver in range within the array's largest travel time, so on the
common time base (receiver clocks synchronised, :mod:`hmmtrack.sync`) the detections within
that window (plus a tolerance for the clocks' error) of a ping's first detection are that
ping; a second detection of it at the same receiver is an echo (multipath), dropped and
counted (:func:`hmmtrack.sync.pings.group_pings`, shared with the sync tags' grouping). A tag
whose emissions can follow each other faster than the array's travel span (a burst interval
shorter than it) is grouped with that shortest interval as the window instead, so that two
pings are never merged.

:func:`ping_observations` is the observations table of the ping measurement
(:mod:`hmmtrack.tracking.measurement.tdoa`): every kept detection, with its ping's index, its
first arrival (the filter scores the whole ping at once, at that time) and the number of
receivers that heard it.

Not for: scoring pings (:mod:`hmmtrack.tracking.measurement.tdoa`).
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from hmmtrack.sync.pings import group_pings, largest_travel_time
from hmmtrack.tracking.measurement.clocked import arrival_observations
from hmmtrack.tracking.receivers import ReceiverTracks

__all__ = ["PING_COLUMNS", "PING_TOLERANCE", "ping_observations", "ping_window"]

logger = logging.getLogger(__name__)

#: the synchronised clocks' error allowed for when grouping a tag's detections (s): well
#: above a fitted clock's (milliseconds), well below a burst interval
PING_TOLERANCE = 0.05
#: columns of :func:`ping_observations` besides those of ``arrival_observations``
PING_COLUMNS = ("arrival", "ping", "heard")


def ping_window(
    positions: np.ndarray, min_interval: float | None = None, tolerance: float = PING_TOLERANCE
) -> float:
    """The grouping window (s): the array's largest travel time plus ``tolerance``, or the
    shortest interval between two emissions when that is shorter.

    Parameters
    ----------
    positions : (R, 2) float array
        Receiver positions (m).
    min_interval : float, optional
        Shortest time between two emissions of the tag (s), e.g. the lower end of a random
        burst interval; ``None``: unknown (longer than the array's travel span).
    tolerance : float
        Clock error allowed for (s).
    """
    window = largest_travel_time(positions) + tolerance
    return window if min_interval is None else min(window, float(min_interval))


def ping_observations(
    detections: pd.DataFrame,
    receivers: ReceiverTracks,
    min_interval: float | None = None,
    tolerance: float = PING_TOLERANCE,
) -> pd.DataFrame:
    """One tag's detections grouped into pings (see the module docstring).

    Parameters
    ----------
    detections : pandas.DataFrame
        ``time`` (common time base, s), ``receiver`` (and ``depth`` m for depth tags).
    receivers : ReceiverTracks
    min_interval, tolerance : float
        As :func:`ping_window`.

    Returns
    -------
    pandas.DataFrame
        :func:`~hmmtrack.tracking.measurement.clocked.arrival_observations`' columns, with
        ``arrival`` (the detection's time, s), ``time`` replaced by its ping's first arrival
        (s), ``ping`` (0, 1, ... in time order) and ``heard`` (receivers that heard the
        ping), echoes dropped; sorted by ping and arrival. ``attrs``: ``echoes_dropped``
        and ``window`` (s).
    """
    obs = arrival_observations(detections, receivers)
    positions = np.unique(obs[["receiver_x", "receiver_y"]].to_numpy().round(), axis=0)
    window = ping_window(positions, min_interval, tolerance)
    ping, echoes = group_pings(
        np.zeros(len(obs)), obs["receiver"].to_numpy(), obs["time"].to_numpy(), window
    )
    if echoes:
        logger.info("dropped %d echo(es): a second detection of a ping at one receiver", echoes)
    obs = obs.assign(arrival=obs["time"], ping=ping)[ping >= 0]
    grouped = obs.groupby("ping")
    obs["time"] = grouped["arrival"].transform("min")
    obs["heard"] = grouped["arrival"].transform("size").astype(np.int64)
    obs = obs.sort_values(["ping", "arrival"], kind="stable").reset_index(drop=True)
    obs.attrs.update(echoes_dropped=int(echoes), window=float(window))
    return obs
