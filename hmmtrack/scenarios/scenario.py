"""The :class:`Scenario` container and the one routine that turns simulated paths into one.

A scenario is everything a tracking run needs plus its ground truth: the detection log, the
logged hydrophone positions, the true tag path, the transmitter period, the true range ``r0``
of each hydrophone's first detection and a box to initialise particles in
(``docs/interfaces.md``). The paper's three datasets are built in
:mod:`hmmtrack.scenarios.paper`; this module only assembles.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.scenarios.detection import (
    GpsNoise,
    detections_from_pings,
    receiver_positions,
    simulate_pings,
)
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.ranging import SOUND_SPEED

#: margin (m) added around the discs of radius r0 to make the initialisation box
BOUNDS_MARGIN = 100.0


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """A synthetic tracking dataset with its ground truth.

    Attributes
    ----------
    name : str
        Short name, e.g. ``"shark-pursuit"``.
    detections : DataFrame
        ``time`` (UTC s, as logged), ``receiver``, ``transmitter``; ``depth`` (m) for a
        depth-sensor tag.
    receivers : DataFrame
        Logged hydrophone positions with GPS noise: ``receiver``, ``time`` (NaN for a moored
        hydrophone), ``x``, ``y`` (m).
    truth : DataFrame
        The tag's true position every second: ``time``, ``x``, ``y`` and ``depth`` for a
        diving tag.
    period : float
        Nominal transmitter period (s).
    r0 : dict of str to float
        True range (m, 3-D) of each hydrophone's first detection: from the tag at that ping's
        emission to the hydrophone at its arrival, the range that anchors the paper's
        accumulated ΔTOF ranges. Hydrophones that never detect the tag have no entry.
    bounds : tuple of float
        ``(xmin, xmax, ymin, ymax)`` (m): every point within ``r0 + 100 m`` of a hydrophone
        where it first detected the tag, the box the paper's filter initialises particles in.
    sound_speed : float
        m/s.
    start, end : float
        UTC s; the run covers ``[start, end]``.
    description : str
        What the scenario imitates and how it differs from the paper's data.
    transmitter : str
        Transmitter id used in ``detections``.
    pings : DataFrame
        Every emission at every hydrophone, detected or lost (columns
        :data:`hmmtrack.scenarios.detection.PING_COLUMNS`).
    receivers_truth : DataFrame
        Like ``receivers`` without GPS noise.
    start_region : tuple of float or None
        ``(xmin, xmax, ymin, ymax)`` (m): where the field team knows the tag to be at
        ``start`` (e.g. around its fix of the animal when the pursuit is launched), for a
        tracker told so instead of the uninformed ``bounds``; ``None``: nothing is known.
        Two receivers cannot tell the tag from its mirror across their line
        (:mod:`hmmtrack.analysis.mirror`); this is the prior information that can.
    """

    name: str
    detections: pd.DataFrame
    receivers: pd.DataFrame
    truth: pd.DataFrame
    period: float
    r0: dict[str, float]
    bounds: tuple[float, float, float, float]
    sound_speed: float = SOUND_SPEED
    start: float
    end: float
    description: str
    transmitter: str
    pings: pd.DataFrame
    receivers_truth: pd.DataFrame
    start_region: tuple[float, float, float, float] | None = None


def assemble_scenario(
    rng: np.random.Generator,
    *,
    name: str,
    description: str,
    tag: Trajectory,
    receivers: Mapping[str, Trajectory],
    emission_time: np.ndarray,
    period: float,
    detection_probability: Mapping[str, Callable[[np.ndarray], np.ndarray]],
    gps: GpsNoise,
    start: float,
    end: float,
    transmitter: str,
    sound_speed: float = SOUND_SPEED,
    receiver_clocks: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None,
) -> Scenario:
    """Simulate emissions, detections and logged positions for given paths.

    Parameters
    ----------
    rng : numpy.random.Generator
        Used in this order: detection draws, GPS noise.
    name, description, transmitter : str
    tag : Trajectory
        The transmitter's true path (with depth for a depth-sensor tag).
    receivers : mapping of str to Trajectory
        True hydrophone paths; a single-vertex path is a moored hydrophone.
    emission_time : (n,) float array
        Emission times (UTC s), e.g. from an
        :class:`~hmmtrack.scenarios.detection.EmissionClock`.
    period : float
        The nominal period (s) reported to the tracker.
    detection_probability : mapping of str to callable
        Per hydrophone, range (m) -> probability.
    gps : GpsNoise
        Error on logged positions of hydrophones (1 Hz for moving ones).
    start, end : float
        UTC s.
    sound_speed : float
        m/s.
    receiver_clocks : mapping of str to callable, optional
        Per hydrophone, true arrival time -> logged time (see
        :func:`~hmmtrack.scenarios.detection.simulate_pings`); perfect clocks by default.

    Returns
    -------
    Scenario
    """
    pings = simulate_pings(
        rng,
        tag,
        receivers,
        emission_time,
        detection_probability,
        sound_speed=sound_speed,
        receiver_clocks=receiver_clocks,
    )
    detections = detections_from_pings(pings, transmitter, tag)
    seconds = start + np.arange(int(np.floor(end - start)) + 1, dtype=float)
    # a ping emitted just before ``end`` is logged after it: the GPS logs run on to cover it
    last_logged = detections["time"].max() if len(detections) else end
    logged_seconds = start + np.arange(int(np.ceil(max(end, last_logged) - start)) + 1, dtype=float)
    logged = receiver_positions(rng, receivers, logged_seconds, gps)
    exact = receiver_positions(rng, receivers, logged_seconds, gps=None)
    x, y, depth = tag.position(seconds)
    truth = pd.DataFrame({"time": seconds, "x": x, "y": y})
    if tag.depth is not None:
        truth["depth"] = depth
    detected = pings[pings["detected"]].sort_values("logged_time", kind="stable")
    first = detected.drop_duplicates("receiver").set_index("receiver")
    r0, boxes = {}, []
    for receiver, path in receivers.items():  # in the order of ``receivers``
        if receiver not in first.index:
            continue
        r0[receiver] = float(first.at[receiver, "range"])
        rx, ry, _ = path.position(np.array([first.at[receiver, "arrival_time"]]))
        reach = r0[receiver] + BOUNDS_MARGIN
        boxes.append((rx[0] - reach, rx[0] + reach, ry[0] - reach, ry[0] + reach))
    if not boxes:
        raise ValueError(f"assemble_scenario: no receiver of scenario {name!r} detected the tag")
    boxes = np.array(boxes)
    bounds = (
        float(boxes[:, 0].min()),
        float(boxes[:, 1].max()),
        float(boxes[:, 2].min()),
        float(boxes[:, 3].max()),
    )
    return Scenario(
        name=name,
        detections=detections,
        receivers=logged,
        truth=truth,
        period=period,
        r0=r0,
        bounds=bounds,
        sound_speed=sound_speed,
        start=start,
        end=end,
        description=description,
        transmitter=transmitter,
        pings=pings,
        receivers_truth=exact,
    )
