"""Figures of the studies behind ``hmmtrack study``: each takes a study's tables and returns Axes.

* :func:`stationary_errors` — stationary-tag errors against the Cramér–Rao bound and the
  geometry angle (:mod:`hmmtrack.experiments.stationary`);
* :func:`bound_curves` — the position bound over time per case
  (:mod:`hmmtrack.experiments.clock_bound`);
* :func:`closed_loop_errors` — the filter's error over time, AUVs steered on the truth or
  on the estimate (:mod:`hmmtrack.experiments.closed_loop_study`).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

#: the bound curves drawn per case, and their colours
BOUND_STYLES = {
    "fitted clock, arrivals only": "tab:orange",
    "fitted clock": "tab:red",
    "clock known": "tab:blue",
}


def stationary_errors(table: pd.DataFrame, axes=None):
    """Error after convergence against the bound (left) and the geometry angle (right).

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`hmmtrack.experiments.stationary.stationary_trials`; only the largest particle
        count is drawn.
    axes : pair of matplotlib Axes, optional
        A new 11 × 4.4 in figure when omitted.

    Returns
    -------
    (Axes, Axes)
    """
    table = table[table["particles"] == table["particles"].max()]
    if axes is None:
        _, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    left, right = axes
    for name, rows in table.groupby("motion", sort=False):
        default = name in ("baseline", "velocity", "hmm")
        style = {"s": 16 if default else 10, "alpha": 0.85 if default else 0.45}
        marker = "o" if default else "x"
        left.scatter(rows["crb_m"], rows["error"], marker=marker, label=name, **style)
        right.scatter(rows["angle_deg"], rows["error"], marker=marker, label=name, **style)
    for ax in (left, right):
        ax.axhline(10.0, color="k", lw=0.8, ls="--")
        ax.set_ylabel("mean error after convergence (m)")
        ax.set_yscale("log")
    lim = [0.3, table["error"].max() * 1.2]
    left.plot(lim, lim, color="grey", lw=0.8, label="error = bound")
    left.set_xscale("log")
    left.set_xlabel("Cramér–Rao bound, √trace, filter's Σ_z (m)")
    right.set_xlabel("angle at the tag between boat and AUV line (degrees)")
    left.legend(fontsize=7)
    left.figure.suptitle(
        f"Stationary tag, {table['seed'].nunique()} scenario seeds, "
        f"{table['particles'].max()} particles",
        fontsize=10,
    )
    return left, right


def bound_curves(curves: dict, axes=None):
    """The position bound over time (filtering solid, smoothing dashed), one panel per case.

    Parameters
    ----------
    curves : dict of str to dict of str to DataFrame
        Case name -> bound label -> :func:`hmmtrack.analysis.crb.arrival_time_bound` table
        (:attr:`hmmtrack.experiments.clock_bound.ClockBoundStudy.curves`); the labels of
        :data:`BOUND_STYLES` are drawn.
    axes : array of Axes, optional
        At least one per case; a new figure with three panels per row when omitted.

    Returns
    -------
    numpy.ndarray of Axes
    """
    names = list(curves)
    if axes is None:
        n_rows = int(np.ceil(len(names) / 3))
        _, axes = plt.subplots(n_rows, 3, figsize=(13, 3.4 * n_rows), sharey=True, sharex=True)
    axes = np.ravel(axes)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    for ax, name in zip(axes, names, strict=False):
        tables = curves[name]
        start = tables["clock known"]["time"].iloc[0]
        for label, colour in BOUND_STYLES.items():
            table = tables[label]
            minutes = (table["time"] - start) / 60
            ax.plot(minutes, table["filter_position_m"], color=colour, lw=0.8, label=label)
            ax.plot(minutes, table["smoother_position_m"], color=colour, lw=0.8, ls="--")
        ax.axhline(10.0, color="k", lw=0.6)
        ax.set_yscale("log")
        ax.set_ylim(0.3, 300)
        ax.set_title(name.replace("shark pursuit, ", "").replace("diagnostic: ", ""), fontsize=9)
        ax.set_xlabel("time since start (min)")
    for ax in axes[::3]:
        ax.set_ylabel("position bound √tr (m)\nsolid: filtering, dashed: smoothing")
    axes[0].legend(fontsize=7, loc="lower right")
    return axes


def closed_loop_errors(series: dict, seed: int, ax=None):
    """The filter's error over time per steering mode (1 s, and its 60 s running mean).

    Parameters
    ----------
    series : dict of str to (numpy.ndarray, numpy.ndarray)
        Mode -> (elapsed s, error m)
        (:attr:`hmmtrack.experiments.closed_loop_study.ClosedLoopStudy.series`).
    seed : int
        The scenario seed, for the title.
    ax : Axes, optional

    Returns
    -------
    Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(9, 4))
    for (mode, (elapsed, error)), colour in zip(series.items(), ("C0", "C3"), strict=False):
        minutes = elapsed / 60.0
        mean = pd.Series(error).rolling(60, min_periods=1, center=True).mean()
        ax.plot(minutes, error, color=colour, alpha=0.25, lw=0.5)
        ax.plot(minutes, mean, color=colour, lw=1.5, label=f"{mode}, 60 s mean")
    ax.axhline(10.0, color="k", lw=0.8, ls="--", label="10 m")
    ax.set(
        xlabel="time since start (min)",
        ylabel="filter error (m)",
        ylim=(0, 40),
        title=f"Observable plan, seed {seed}: AUVs steered on the truth vs on the estimate",
    )
    ax.legend(loc="upper right")
    return ax
