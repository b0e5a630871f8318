"""Steering plans for AUV hydrophones that follow a tagged shark.

A vehicle homes on a *station* (a point ``radius`` metres from the shark at a bearing,
optionally led ahead of it by its recent velocity) through a first-order low-pass, as the
paper's hydrophones follow their fixed offsets:

* :func:`station`, :func:`recent_velocity`, :func:`homing_memory` — the pieces, shared with
  the closed loop (:mod:`hmmtrack.experiments.closed_loop`) that steers on an estimate;
* :func:`steered_auv` — one vehicle's true path around a known shark path;
* :func:`circling_pair`, :func:`rotating_pair` (:func:`pair_bearings`) — two-vehicle plans;
* :class:`RotatingPlan` and :data:`ROTATING_PLANS` — named rotating plans.

It simulates paths only; detections come from :mod:`hmmtrack.scenarios.clocks`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from hmmtrack.scenarios.trajectory import Trajectory


def steered_auv(
    tag: Trajectory,
    radius: float,
    bearing: np.ndarray,
    time_constant: float = 60.0,
    lead_window: float | None = None,
) -> Trajectory:
    """An AUV steered to a station ``radius`` metres from the shark at a given bearing.

    The station is the shark's position plus ``radius · (cos bearing, sin bearing)``; the
    AUV follows it through a first-order low-pass filter of time constant
    ``time_constant`` (a vehicle that homes on a moving set point), as the paper's
    hydrophones follow their fixed offsets. A constant ``bearing`` is the paper's trailing
    vehicle; a bearing that turns makes the vehicle circle the shark. Such a vehicle
    trails a set point moving at a steady velocity ``v`` by ``v · lag`` with
    ``lag = e^(-1/τ) / (1 - e^(-1/τ))`` s (≈ ``time_constant`` − ½ s), so behind a
    travelling shark it flies behind its station; with ``lead_window`` the station is moved
    ahead of the shark by the shark's recent velocity times ``lag``, the velocity being the
    exponential average, with time constant ``lead_window``, of its 1 s displacements up to
    that second (what an operator who follows the track knows), and the vehicle then holds
    its station on a shark that keeps its course. The stations are placed from the true
    shark track, as the paper's simulated hydrophone paths are built from it.

    Parameters
    ----------
    tag : Trajectory
        The shark's path sampled every second (``tag.time`` must be evenly spaced by 1 s).
    radius : float
        Distance of the station from the shark (m).
    bearing : numpy.ndarray, shape (n,)
        Bearing of the station from the shark at each of ``tag.time`` (rad, from +x).
    time_constant : float
        Low-pass time constant (s).
    lead_window : float, optional
        Time constant (s) of the average of the shark's velocity that leads the station;
        ``None`` (default): the station is on the shark's position, without lead.

    Returns
    -------
    Trajectory
        The AUV's true path at ``tag.time``.
    """
    if not np.allclose(np.diff(tag.time), 1.0):
        raise ValueError("steered_auv: the shark's path must be sampled every 1 s")
    keep, lag = homing_memory(time_constant)
    lead = None
    if lead_window is not None:
        lead = (
            lag * recent_velocity(tag.x, lead_window),
            lag * recent_velocity(tag.y, lead_window),
        )
    x, y = station(tag.x, tag.y, radius, bearing, lead)
    # y[k] = keep·y[k-1] + (1 - keep)·target[k], started at the first target
    x = lfilter([1.0 - keep], [1.0, -keep], x - x[0]) + x[0]
    y = lfilter([1.0 - keep], [1.0, -keep], y - y[0]) + y[0]
    return Trajectory(tag.time, x, y)


def homing_memory(time_constant: float) -> tuple[float, float]:
    """The homing low-pass of :func:`steered_auv`: its memory per second and its lag.

    Parameters
    ----------
    time_constant : float
        Low-pass time constant τ (s).

    Returns
    -------
    keep : float
        ``e^(-1/τ)``: the share of last second's position kept each second.
    lag : float
        ``keep / (1 - keep)`` (s): how far in time a vehicle trails a set point moving at
        a steady velocity, the lead that cancels it.
    """
    keep = float(np.exp(-1.0 / time_constant))
    return keep, keep / (1.0 - keep)


def station(shark_x, shark_y, radius: float, bearing, lead=None):
    """A vehicle's station: ``radius`` metres from the shark at ``bearing``, plus a lead.

    Parameters
    ----------
    shark_x, shark_y : float or numpy.ndarray, shape (n,)
        The shark's position (m).
    radius : float
        Distance of the station from the shark (m).
    bearing : float or numpy.ndarray, shape (n,)
        Bearing of the station from the shark (rad, from +x).
    lead : tuple of (float or numpy.ndarray), optional
        ``(x, y)`` offset (m) ahead of the shark (its recent velocity times the homing lag,
        see :func:`steered_auv`); ``None``: no lead.

    Returns
    -------
    x, y : float or numpy.ndarray, shape (n,)
        The station (m).
    """
    x = shark_x + radius * np.cos(bearing)
    y = shark_y + radius * np.sin(bearing)
    if lead is not None:
        x = x + lead[0]
        y = y + lead[1]
    return x, y


def recent_velocity(position: np.ndarray, window: float) -> np.ndarray:
    """Exponential average of the 1 s displacements of one coordinate up to each second.

    Parameters
    ----------
    position : numpy.ndarray, shape (n,)
        One coordinate sampled every second (m).
    window : float
        Time constant of the average (s, > 0).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``v[k] = a·v[k-1] + (1 - a)·(position[k] - position[k-1])`` with ``a = e^(-1/window)``,
        ``v[0] = 0`` (m/s): causal, it uses no later position.
    """
    if not (np.isfinite(window) and window > 0):
        raise ValueError(f"recent_velocity: window must be a positive number of s, got {window!r}")
    keep = np.exp(-1.0 / window)
    step = np.diff(position, prepend=position[0])
    return lfilter([1.0 - keep], [1.0, -keep], step)


def circling_pair(
    tag: Trajectory,
    phi: float,
    *,
    trail_radius: float = 80.0,
    circle_radius: float = 130.0,
    lap_time: float = 1200.0,
) -> dict[str, Trajectory]:
    """Two AUVs steered so that the tag's position and clock are both observable.

    ``auv-1`` trails the shark at ``trail_radius`` on the fixed bearing ``phi``; ``auv-2``
    circles it at ``circle_radius``, one lap every ``lap_time`` seconds, starting a
    quarter turn from ``auv-1``. Two vehicles holding a fixed geometry around the shark
    (the paper's pursuit) leave a common shift of the emission clock nearly
    indistinguishable from a radial shift of the position, and keep the mirror
    intersection of their two range circles; a vehicle whose bearing from the shark turns
    sees the same position shift as a range change that varies around the lap, which a
    smooth path cannot follow, and moves the mirror intersection around. With two
    receivers this reduces the clock-position ambiguity but does not remove it (a common
    clock shift still maps to a position shift along the bisector of the two bearings;
    reports/clock_aware.md measures what is left). The defaults keep the
    circling vehicle's speed relative to the shark at 2π·130/1200 ≈ 0.7 m/s (about 2 m/s
    at most over ground for a shark at ~1 m/s) and both vehicles inside the detection
    range (50 % at 160 m).

    Parameters
    ----------
    tag : Trajectory
        The shark's path sampled every second.
    phi : float
        Bearing of the trailing vehicle from the shark (rad).
    trail_radius, circle_radius : float
        Distances from the shark (m).
    lap_time : float
        Time of one lap of the circling vehicle (s).

    Returns
    -------
    dict of str to Trajectory
        ``auv-1`` (trailing) and ``auv-2`` (circling).
    """
    elapsed = tag.time - tag.time[0]
    return {
        "auv-1": steered_auv(tag, trail_radius, np.full(elapsed.size, phi)),
        "auv-2": steered_auv(
            tag, circle_radius, phi + 0.5 * np.pi + 2.0 * np.pi * elapsed / lap_time
        ),
    }


def rotating_pair(
    tag: Trajectory,
    phi: float,
    *,
    radius: float = 70.0,
    lap_time: float = 600.0,
    separation: float = 0.5 * np.pi,
    time_constant: float = 20.0,
    lead_window: float | None = None,
) -> dict[str, Trajectory]:
    """Two AUVs that keep a right angle at the shark and circle it together.

    Both AUVs hold stations ``radius`` metres from the shark, ``separation`` radians apart
    in bearing, and the pair turns around the shark once every ``lap_time`` seconds. The
    fixed angle keeps the two range circles crossing at a right angle (the tag is never
    near the line through the AUVs, where two ranges fix it poorly and the mirror
    intersection merges with it), and the turning moves the bisector along which a
    common clock shift would move the fix, so that a wrong clock shows as a path the
    shark would have to swim in circles. The vehicles home on their stations more
    tightly than :func:`steered_auv`'s default (20 s), or the pair would lag behind a
    travelling shark instead of circling it; the defaults keep their speeds like
    :func:`circling_pair`'s (about 1 m/s median, 99 % of the time under ~2.2 m/s for a
    shark at ≤ 1.5 m/s). Even at 20 s a pair that turns in minutes falls behind a fast
    shark and closes its angle; ``lead_window`` leads the stations by the shark's
    velocity so that it does not (:class:`RotatingPlan`).

    Parameters
    ----------
    tag : Trajectory
        The shark's path sampled every second.
    phi : float
        Bearing of ``auv-1`` from the shark at the start (rad).
    radius : float
        Distance of both stations from the shark (m).
    lap_time : float
        Time of one turn of the pair (s).
    separation : float
        Angle between the two stations' bearings (rad).
    time_constant : float
        Low-pass time constant of the vehicles' homing (s, see :func:`steered_auv`).
    lead_window : float, optional
        Stations led ahead of the shark by its recent velocity (see :func:`steered_auv`);
        ``None`` (default): no lead.

    Returns
    -------
    dict of str to Trajectory
        ``auv-1`` and ``auv-2``.
    """
    bearings = pair_bearings(tag.time - tag.time[0], phi, lap_time, separation)
    return {
        name: steered_auv(tag, radius, bearing, time_constant, lead_window)
        for name, bearing in bearings.items()
    }


def pair_bearings(elapsed, phi: float, lap_time: float, separation: float) -> dict:
    """Bearings of :func:`rotating_pair`'s two stations from the shark.

    Parameters
    ----------
    elapsed : float or numpy.ndarray, shape (n,)
        Time since the start of the plan (s).
    phi : float
        Bearing of ``auv-1``'s station at the start (rad).
    lap_time : float
        Time of one turn of the pair (s).
    separation : float
        Angle from ``auv-1``'s station to ``auv-2``'s (rad).

    Returns
    -------
    dict of str to (float or numpy.ndarray, shape (n,))
        ``auv-1`` and ``auv-2``: bearing (rad, from +x).
    """
    bearing = phi + 2.0 * np.pi * elapsed / lap_time
    return {"auv-1": bearing, "auv-2": bearing + separation}


@dataclass(frozen=True)
class RotatingPlan:
    """A steering plan for two AUVs that circle the shark together (:func:`rotating_pair`).

    The defaults are the "observable" plan: both stations 27 m from the shark, 135° apart,
    the pair turning once every 150 s, each station led ahead of the shark by the shark's
    recent velocity (``lead_window``, see :func:`steered_auv`) so that the vehicles hold
    that geometry behind a travelling shark instead of falling behind it and closing their
    angle. On this plan the arrival-time filter with the ``two-moving-receivers`` preset
    stays under 10 m over 2 h (reports/two_auv_plan.md; how the plan was chosen:
    reports/decisions.md, "Two-AUV steering plan"). The stations are placed from the true
    shark track, as the paper's simulated hydrophone paths are built from it;
    :func:`hmmtrack.experiments.closed_loop.fly_closed_loop` flies the plan on the filter's
    online estimate instead (reports/closed_loop.md).

    Parameters
    ----------
    radius, lap_time, separation, time_constant, lead_window
        As :func:`rotating_pair`'s (other defaults).
    """

    radius: float = 27.0
    lap_time: float = 150.0
    separation: float = float(np.radians(135.0))
    time_constant: float = 20.0
    lead_window: float | None = 30.0

    def __post_init__(self) -> None:
        for name in ("radius", "lap_time", "time_constant", "lead_window"):
            value = getattr(self, name)
            if name == "lead_window" and value is None:
                continue
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"RotatingPlan: {name} must be a positive number, got {value!r}")
        if not 0 < self.separation < 2 * np.pi:
            raise ValueError(
                f"RotatingPlan: separation must lie in (0, 2π) rad, got {self.separation!r}"
            )

    def bearings(self, elapsed, phi: float) -> dict:
        """The stations' bearings from the shark (rad) at ``elapsed`` s (:func:`pair_bearings`)."""
        return pair_bearings(elapsed, phi, self.lap_time, self.separation)

    def receivers(self, tag: Trajectory, phi: float) -> dict[str, Trajectory]:
        """The two AUVs' true paths around ``tag`` (see :func:`rotating_pair`)."""
        return rotating_pair(tag, phi, **dataclasses.asdict(self))

    def describe(self) -> str:
        """``"30 m, 135°, lap 150 s, led"`` (``led``: stations led by the shark's velocity)."""
        led = "" if self.lead_window is None else ", led"
        return (
            f"{self.radius:g} m, {np.degrees(self.separation):.0f}°, lap {self.lap_time:g} s{led}"
        )


#: named plans of :func:`rotating_pair`, steerings of
#: :func:`hmmtrack.scenarios.realistic.realistic_shark_pursuit`:
#: ``formation`` keeps a right angle (70 m, one turn per 10 min, no lead); ``observable``
#: is the plan on which two AUVs track the shark to under 10 m in every run measured
#: (:class:`RotatingPlan`'s defaults)
ROTATING_PLANS = {
    "formation": RotatingPlan(
        radius=70.0, lap_time=600.0, separation=0.5 * np.pi, lead_window=None
    ),
    "observable": RotatingPlan(),
}
