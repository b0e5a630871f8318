"""Figures of one tracking run, like the paper's "error and particle snapshots" figures.

* :func:`plot_error_over_time` — position error against seconds since the start, with the
  time to convergence marked;
* :func:`plot_particles` — the particles at one instant (yellow, area ∝ weight), the
  estimated track so far (gold), the true position (green), the hydrophones (orange, blue,
  ...) and their latest measured ranges drawn as circles around them;
* :func:`plot_tracking_run` — the composite: error over time on top, snapshots below.

They draw what :func:`hmmtrack.tracking.pipeline.track` and :mod:`hmmtrack.analysis.metrics` return
and
compute nothing but display positions (a receiver's position at a snapshot time).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hmmtrack.analysis.metrics import Convergence
from hmmtrack.tracking.receivers import ReceiverTracks

#: hydrophone colours in the paper's order (orange, blue), then further ones
RECEIVER_COLOURS = ("tab:orange", "tab:blue", "tab:purple", "tab:brown")
PARTICLE_COLOUR = "gold"
ESTIMATE_COLOUR = "darkgoldenrod"
TRUTH_COLOUR = "tab:green"


def snapshot_times(start: float, end: float, n: int = 4) -> np.ndarray:
    """Times for ``n`` particle snapshots: the start, then log-spaced to the end.

    Parameters
    ----------
    start, end : float
        Run window (s).
    n : int
        Number of snapshots (≥ 2).

    Returns
    -------
    numpy.ndarray, shape (n,)
        Whole seconds after ``start`` (s), e.g. 0, 10, 110, 1200 s into a 1200 s run; fewer
        when the run is too short to hold ``n`` distinct seconds.
    """
    duration = float(end) - float(start)
    if n < 2 or duration < 1:
        raise ValueError(f"need n >= 2 snapshots in a run of at least 1 s, got {n}, {duration} s")
    offsets = np.geomspace(min(10.0, duration / 4) or 1.0, duration, n - 1)
    offsets = np.unique(np.concatenate([[0.0], np.floor(offsets)]))
    return float(start) + offsets


def plot_error_over_time(
    times, errors, convergence: Convergence | None = None, ax: Axes | None = None
) -> Axes:
    """Position error against time since the first estimate.

    Parameters
    ----------
    times : array_like, shape (n,)
        Estimate times (s).
    errors : array_like, shape (n,)
        Position errors (m), from :func:`hmmtrack.analysis.metrics.position_error`.
    convergence : Convergence, optional
        Marks the time to convergence (dashed line) when the run converged.
    ax : matplotlib Axes, optional

    Returns
    -------
    Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 3))
    times = np.asarray(times, dtype=float)
    elapsed = times - times[0]
    ax.plot(elapsed, errors, color="black", lw=1.0, label="position error")
    if convergence is not None and convergence.converged:
        ax.axvline(
            convergence.time_to_convergence,
            color="tab:red",
            ls="--",
            lw=1.0,
            label=f"converged at {convergence.time_to_convergence:.0f} s",
        )
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("error (m)")
    ax.set_xlim(elapsed[0], elapsed[-1])
    ax.set_ylim(bottom=0)
    ax.legend(loc="upper right", frameon=False)
    return ax


def plot_particles(
    snapshot: pd.DataFrame,
    receivers: pd.DataFrame,
    truth: pd.DataFrame | None = None,
    ax: Axes | None = None,
    *,
    time: float | None = None,
    estimates: pd.DataFrame | None = None,
    observations: pd.DataFrame | None = None,
    start: float | None = None,
) -> Axes:
    """Particles at one instant with hydrophones, their measured ranges and the truth.

    Parameters
    ----------
    snapshot : pandas.DataFrame
        Particles: ``x``, ``y`` (m), ``weight`` (normalised; drawn as the marker area).
    receivers : pandas.DataFrame
        Receiver positions table (``receiver``, ``time``, ``x``, ``y``).
    truth : pandas.DataFrame, optional
        ``time``, ``x``, ``y``: the true position at ``time`` is drawn (a single row is a
        fixed tag).
    ax : matplotlib Axes, optional
    time : float, optional
        Snapshot time (s); needed for the receivers' positions, ranges and the track.
    estimates : pandas.DataFrame, optional
        Estimates table: the estimated track up to ``time`` is drawn, and with the mode
        columns (:func:`hmmtrack.tracking.mixture.with_modes`) the second mode at
        ``time`` (a ring, labelled with its weight).
    observations : pandas.DataFrame, optional
        Observations table: each receiver's latest range at or before ``time`` is drawn as
        a circle around where the receiver is at ``time``.
    start : float, optional
        Run start (s) for the title's elapsed time.

    Returns
    -------
    Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 5))
    # marker area proportional to the weight (2 pt² for an average particle)
    area = np.clip(2.0 * len(snapshot) * snapshot["weight"].to_numpy(), 0.05, 30.0)
    ax.scatter(
        snapshot["x"], snapshot["y"], s=area, color=PARTICLE_COLOUR, alpha=0.5, label="particles"
    )
    if estimates is not None and time is not None:
        done = estimates[estimates["time"] <= time + 1e-9]
        ax.plot(done["x"], done["y"], color=ESTIMATE_COLOUR, lw=1.5, label="estimate")
        if "mode2_x" in done and len(done) and np.isfinite(done["mode2_x"].iloc[-1]):
            last = done.iloc[-1]
            ax.plot(
                last["mode2_x"],
                last["mode2_y"],
                marker="o",
                ms=12,
                mfc="none",
                ls="none",
                color=ESTIMATE_COLOUR,
                label=f"second mode ({last['mode2_weight']:.2f})",
            )
    tracks = ReceiverTracks.from_frame(receivers, outside="clamp")
    for k, name in enumerate(tracks.names):
        colour = RECEIVER_COLOURS[k % len(RECEIVER_COLOURS)]
        at = receivers["time"].min() if time is None else time
        x, y, _, _ = tracks.state(name, np.array([at if np.isfinite(at) else 0.0]))
        ax.plot(x, y, marker="^", ms=9, ls="none", color=colour, label=name)
        if observations is None or time is None:
            continue
        heard = observations[(observations["receiver"] == name) & (observations["time"] <= time)]
        if len(heard):
            radius = float(heard["range"].iloc[-1])
            ax.add_patch(plt.Circle((x[0], y[0]), radius, fill=False, color=colour, lw=1.0))
    if truth is not None:
        if len(truth) == 1 or time is None:
            tx, ty = truth["x"].iloc[:1], truth["y"].iloc[:1]
        else:
            tx = [np.interp(time, truth["time"], truth["x"])]
            ty = [np.interp(time, truth["time"], truth["y"])]
        ax.plot(tx, ty, marker="*", ms=12, ls="none", color=TRUTH_COLOUR, label="truth")
    if time is not None:
        ax.set_title(f"{time - (start if start is not None else time):.0f} s")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return ax


def plot_tracking_run(
    estimates: pd.DataFrame,
    snapshots: dict,
    receivers: pd.DataFrame,
    *,
    observations: pd.DataFrame | None = None,
    truth: pd.DataFrame | None = None,
    errors: tuple | None = None,
    convergence: Convergence | None = None,
) -> Figure:
    """The paper's run figure: error over time on top, particle snapshots below.

    Parameters
    ----------
    estimates : pandas.DataFrame
        Estimates table of the run.
    snapshots : dict of float to pandas.DataFrame
        Particle snapshots by time (:attr:`hmmtrack.tracking.pipeline.TrackingResult.snapshots`).
    receivers : pandas.DataFrame
        Receiver positions table.
    observations, truth : pandas.DataFrame, optional
        See :func:`plot_particles`.
    errors : (times, errors), optional
        Position errors over time (s, m); the top panel is left out without them.
    convergence : Convergence, optional
        Marked on the error panel.

    Returns
    -------
    matplotlib.figure.Figure
    """
    n = max(len(snapshots), 1)
    figure = plt.figure(figsize=(3.2 * n, 6.4 if errors is not None else 3.4))
    grid = figure.add_gridspec(2 if errors is not None else 1, n, height_ratios=None)
    row = 0
    if errors is not None:
        plot_error_over_time(*errors, convergence=convergence, ax=figure.add_subplot(grid[0, :]))
        row = 1
    start = float(estimates["time"].iloc[0])
    for k, (time, snapshot) in enumerate(sorted(snapshots.items())):
        ax = figure.add_subplot(grid[row, k])
        plot_particles(
            snapshot,
            receivers,
            truth,
            ax,
            time=time,
            estimates=estimates,
            observations=observations,
            start=start,
        )
        if k == 0:
            ax.legend(loc="upper left", fontsize=7, frameon=False, markerscale=1.5)
        else:
            ax.set_ylabel("")
    figure.tight_layout()
    return figure
