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

:func:`arrival_spread` estimates the sd of a direct arrival's residual from the pings
themselves, before any filtering (as YAPS estimates its ``σ_toa``): every ping heard by
:data:`SPREAD_RECEIVERS` or more receivers is fixed on its own by robust least squares
(position and emission time, :func:`ping_fixes`), and the pooled residuals, each scaled by
``√(n/(n − 3))`` for the three fitted parameters, give a robust sd (1.4826 × their median
absolute value) and the share of outliers beyond :data:`OUTLIER_SDS` of it. The arrival sd
is a property of the data (clocks, timing, the array's geometry and the model's fit to it),
not one default.

Not for: scoring pings (:mod:`hmmtrack.tracking.measurement.tdoa`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.sync.pings import group_pings, largest_travel_time
from hmmtrack.tracking.measurement.clocked import arrival_observations
from hmmtrack.tracking.receivers import ReceiverTracks

__all__ = [
    "PING_COLUMNS",
    "PING_TOLERANCE",
    "OUTLIER_SDS",
    "SPREAD_PINGS",
    "SPREAD_RECEIVERS",
    "ArrivalSpread",
    "arrival_spread",
    "HUBER_SDS",
    "ping_fixes",
    "pooled_sd",
    "ping_observations",
    "ping_window",
]

logger = logging.getLogger(__name__)

#: the synchronised clocks' error allowed for when grouping a tag's detections (s): well
#: above a fitted clock's (milliseconds), well below a burst interval
PING_TOLERANCE = 0.05
#: columns of :func:`ping_observations` besides those of ``arrival_observations``
PING_COLUMNS = ("arrival", "ping", "heard")
#: receivers a ping needs to enter :func:`arrival_spread`: one more than the three fitted
#: parameters (x, y, emission time), so that its residuals have a spread
SPREAD_RECEIVERS = 4
#: at most this many pings (evenly spaced) enter :func:`arrival_spread`: a robust sd is
#: settled long before, and a deployment's thousands of pings would cost seconds each
SPREAD_PINGS = 400
#: residuals beyond this many robust sds count as outliers (multipath) in
#: :func:`arrival_spread`
OUTLIER_SDS = 5.0
#: residuals beyond this many robust sds weigh less in :func:`ping_fixes` (Huber): the
#: core is fitted by least squares, a multipath arrival does not drag the fix
HUBER_SDS = 3.0
#: the first iteration's scale (s) of :func:`ping_fixes`: a synchronised clock's millisecond
_FIX_SCALE = 1e-3
#: Gauss-Newton iterations of :func:`ping_fixes` (the fits settle within ten)
_FIX_ITERATIONS = 20


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


def ping_fixes(
    arrival: np.ndarray, receiver_xy: np.ndarray, vertical: np.ndarray, sound_speed: float
) -> tuple[np.ndarray, float]:
    """Pings fixed one by one: the position and emission time that fit each ping's arrivals
    best, and the arrivals' robust sd.

    Iteratively reweighted Gauss-Newton over all pings at once: Huber weights at
    :data:`HUBER_SDS` robust sds, the sd re-estimated from the pooled residuals at every
    iteration (:func:`pooled_sd`), so that the core arrivals are fitted by least squares (no
    bias towards zero residuals, as an L1 fit has) and a multipath arrival does not drag
    its ping's fix.

    Parameters
    ----------
    arrival : (P, R) float array
        Arrival times of each ping at up to ``R`` receivers (s, common time base, relative
        to anything per ping); NaN where a receiver did not hear it. At least 4 per ping.
    receiver_xy : (P, R, 2) float array
        The receivers' positions (m).
    vertical : (P, R) float array
        Tag minus receiver depth (m; 0 in 2-D).
    sound_speed : float
        m/s.

    Returns
    -------
    residual : (P, R) float array
        Each arrival minus its ping's fitted emission and travel time (s; NaN where none).
    sigma : float
        The robust sd (s) of the direct arrivals (:func:`pooled_sd`).
    """
    heard = np.isfinite(arrival)
    counts = heard.sum(axis=1)
    origin = np.nanmin(arrival, axis=1)
    t = np.where(heard, arrival - origin[:, None], 0.0)
    xy = np.where(heard[..., None], receiver_xy, 0.0)
    vertical = np.where(heard, vertical, 0.0)
    # start: the receivers' centroid, emitted at the first arrival
    theta = np.column_stack([xy.sum(axis=1) / counts[:, None], np.zeros(len(t))])
    sigma = _FIX_SCALE
    for _ in range(_FIX_ITERATIONS):
        offset = theta[:, None, :2] - xy
        distance = np.sqrt(np.sum(offset**2, axis=2) + vertical**2)
        residual = np.where(heard, t - theta[:, None, 2] - distance / sound_speed, 0.0)
        sigma = pooled_sd(residual, heard, counts)
        cut = HUBER_SDS * sigma
        weight = np.where(heard, np.minimum(1.0, cut / np.maximum(np.abs(residual), 1e-300)), 0.0)
        unit = offset / np.maximum(distance, 1e-6)[..., None] / sound_speed
        jacobian = np.concatenate([unit, np.ones(t.shape)[..., None]], axis=2)  # −∂r/∂θ
        normal = np.einsum("pri,pr,prj->pij", jacobian, weight, jacobian)
        normal += 1e-9 * np.eye(3) * np.trace(normal, axis1=1, axis2=2)[:, None, None]
        gradient = np.einsum("pri,pr,pr->pi", jacobian, weight, residual)
        theta += np.linalg.solve(normal, gradient[..., None])[..., 0]
    offset = theta[:, None, :2] - xy
    distance = np.sqrt(np.sum(offset**2, axis=2) + vertical**2)
    residual = np.where(heard, t - theta[:, None, 2] - distance / sound_speed, np.nan)
    return residual, pooled_sd(np.nan_to_num(residual), heard, counts)


def pooled_sd(residual: np.ndarray, heard: np.ndarray, counts: np.ndarray) -> float:
    """1.4826 × the median absolute residual over all pings, each scaled by
    ``√(n/(n − 3))`` for its ping's three fitted parameters (``n`` its receivers): a robust
    sd of the arrivals (s).

    Parameters
    ----------
    residual, heard : (P, R) float and bool arrays
    counts : (P,) int array
        Receivers per ping (≥ 4).
    """
    return 1.4826 * float(np.median(_scaled_residuals(residual, counts)[heard]))


def _scaled_residuals(residual: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``|residual|`` (P, R) scaled by ``√(n/(n − 3))`` for each ping's three fitted
    parameters (``n = counts`` (P,), its receivers): comparable across pings."""
    return np.abs(residual) * np.sqrt(counts / (counts - 3.0))[:, None]


@dataclass(frozen=True)
class ArrivalSpread:
    """The arrival sd the pings themselves show (:func:`arrival_spread`).

    Attributes
    ----------
    sigma : float
        Robust sd of a direct arrival's residual (s); NaN when no ping had enough receivers.
    outlier_fraction : float
        Share of residuals beyond :data:`OUTLIER_SDS` × ``sigma``.
    pings : int
        Pings fixed.
    residuals : int
        Residuals pooled.
    """

    sigma: float
    outlier_fraction: float
    pings: int
    residuals: int


def arrival_spread(
    observations: pd.DataFrame, sound_speed: float, min_receivers: int = SPREAD_RECEIVERS
) -> ArrivalSpread:
    """The sd of a direct arrival's residual, from least-squares fixes of single pings
    (see the module docstring).

    Parameters
    ----------
    observations : pandas.DataFrame
        :func:`ping_observations`' table (``arrival``, ``ping``, ``heard``,
        ``receiver_x``, ``receiver_y``; ``receiver_depth`` and ``depth`` when known).
    sound_speed : float
        m/s.
    min_receivers : int
        Pings heard by fewer receivers are left out (≥ 4: three parameters are fitted).
    """
    rows = observations[observations["heard"] >= min_receivers]
    pings = pd.unique(rows["ping"])
    if pings.size == 0:
        return ArrivalSpread(np.nan, np.nan, 0, 0)
    if pings.size > SPREAD_PINGS:
        pings = pings[np.linspace(0, pings.size - 1, SPREAD_PINGS).round().astype(int)]
        rows = rows[rows["ping"].isin(pings)]
    vertical = np.zeros(len(rows))
    if "receiver_depth" in rows:
        vertical -= rows["receiver_depth"].to_numpy(dtype=float)
    if "depth" in rows:
        vertical += rows["depth"].to_numpy(dtype=float)
    # one row per ping, one column per receiver that heard it
    which = np.searchsorted(np.sort(pings), rows["ping"].to_numpy())
    order = rows.groupby("ping").cumcount().to_numpy()
    shape = (pings.size, int(order.max()) + 1)
    arrival = np.full(shape, np.nan)
    xy = np.zeros((*shape, 2))
    depth = np.zeros(shape)
    arrival[which, order] = rows["arrival"].to_numpy(dtype=float)
    xy[which, order] = rows[["receiver_x", "receiver_y"]].to_numpy(dtype=float)
    depth[which, order] = np.nan_to_num(vertical)
    residual, sigma = ping_fixes(arrival, xy, depth, sound_speed)
    heard = np.isfinite(residual)
    counts = heard.sum(axis=1)
    outliers = float(np.mean(_scaled_residuals(residual, counts)[heard] > OUTLIER_SDS * sigma))
    return ArrivalSpread(sigma, outliers, int(pings.size), int(heard.sum()))
