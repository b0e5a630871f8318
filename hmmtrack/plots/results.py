"""Figures of the paper's "Results" section, drawn from the tables of :mod:`hmmtrack.experiments`.

* :func:`error_histograms` — error after convergence per motion model on one scenario
  (one panel of the paper's motion-model comparison figure);
* :func:`loss_sweep` — time to convergence or error after convergence against the
  fraction of detections dropped, log scale, with the paper's bands;
* :func:`depth_percent_error` — the percent error of taking a slant range as horizontal;
* :func:`depth_profile` and :func:`depth_trials` — the diving shark's dive, and its
  per-trial errors without and with the depth correction.

Each function takes results and ``ax=None`` and returns the Axes; none computes results.
:func:`comparison_figure`, :func:`loss_figure` and :func:`depth_figure` lay these out as
the report's figures, and :func:`example_figure` and :func:`motion_hmm_figure` lay out the
figures of :mod:`hmmtrack.plots.tracking` (one run with particle snapshots) and
:mod:`hmmtrack.plots.hmm` (state-dependent densities) the way the paper shows them; all are
shared by ``hmmtrack reproduce`` and the notebooks.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

from hmmtrack.experiments import LOSS_BAND_EDGES, LOSS_BANDS

__all__ = [
    "error_histograms",
    "loss_sweep",
    "depth_percent_error",
    "depth_profile",
    "depth_trials",
    "comparison_figure",
    "loss_figure",
    "depth_figure",
    "example_figure",
    "motion_hmm_figure",
]

#: colours of the motion models, the same in every figure
MOTION_COLOURS = {"baseline": "tab:red", "velocity": "tab:blue", "hmm": "tab:green"}

_QUANTITY_LABELS = {
    "time_to_convergence": "time to convergence (s)",
    "mean_error_after_convergence": "mean error after convergence (m)",
    "rmse_after_convergence": "RMSE after convergence (m)",
}


def _axes(ax: Axes | None) -> Axes:
    return plt.subplots()[1] if ax is None else ax


def _log_scale(ax: Axes, axis: str = "y") -> None:
    """Log scale with plain numbers at 1, 2 and 5 times powers of ten."""
    getattr(ax, f"set_{axis}scale")("log")
    target = ax.xaxis if axis == "x" else ax.yaxis
    target.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    target.set_major_formatter(FormatStrFormatter("%g"))
    target.set_minor_formatter(NullFormatter())


def _require(table: pd.DataFrame, columns: Sequence[str], name: str) -> None:
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ValueError(f"{name} table lacks column(s) {missing}; expected {list(columns)}")


def error_histograms(
    table: pd.DataFrame,
    scenario: str | None = None,
    quantity: str = "mean_error_after_convergence",
    bins: int = 30,
    ax: Axes | None = None,
) -> Axes:
    """Histogram of a per-trial metric for each motion model, on a log-spaced axis.

    For ``time_to_convergence`` only trials that converged are counted (the legend says
    how many); the paper's 0 s of a run that never converged is not a time.

    Parameters
    ----------
    table : pandas.DataFrame
        Trials table of :func:`hmmtrack.experiments.compare_motion_models` (columns
        ``scenario``, ``motion`` and ``quantity``).
    scenario : str, optional
        Which scenario to draw; required when the table holds several.
    quantity : str
        Column to histogram (m or s).
    bins : int
        Number of log-spaced bins spanning all models' values.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    _require(table, ("scenario", "motion", quantity), "trials")
    names = table["scenario"].unique()
    if scenario is None:
        if len(names) != 1:
            raise ValueError(f"the table holds scenarios {list(names)}; choose one")
        scenario = names[0]
    rows = table[table["scenario"] == scenario]
    if rows.empty:
        raise ValueError(f"no trials of scenario {scenario!r}; the table has {list(names)}")
    if quantity == "time_to_convergence" and "converged" in rows.columns:
        total = rows.groupby("motion", sort=False).size()
        rows = rows[rows["converged"].to_numpy(dtype=bool)]
    else:
        total = None
    ax = _axes(ax)
    values = rows[quantity].to_numpy(dtype=float)
    positive = values[values > 0]
    low, high = (positive.min(), positive.max()) if positive.size else (1.0, 10.0)
    edges = np.geomspace(low / 1.05, high * 1.05, bins + 1)
    for motion, group in rows.groupby("motion", sort=False):
        data = group[quantity].to_numpy(dtype=float)
        label = f"{motion} (mean {np.mean(data):.3g})"
        if total is not None:
            label = f"{motion} (mean {np.mean(data):.3g}; {len(data)}/{total[motion]} conv.)"
        ax.hist(
            np.clip(data, edges[0], edges[-1]),
            bins=edges,
            histtype="stepfilled",
            alpha=0.45,
            color=MOTION_COLOURS.get(motion),
            edgecolor=MOTION_COLOURS.get(motion),
            label=label,
        )
    _log_scale(ax, "x")
    ax.set_xlabel(_QUANTITY_LABELS.get(quantity, quantity))
    ax.set_ylabel("trials")
    ax.set_title(str(scenario))
    ax.legend(fontsize="small")
    return ax


def loss_sweep(
    table: pd.DataFrame,
    quantity: str = "time_to_convergence",
    paper: Mapping[str, float] | None = None,
    ax: Axes | None = None,
) -> Axes:
    """A per-trial metric against the fraction of detections dropped, log scale.

    Parameters
    ----------
    table : pandas.DataFrame
        Trials table of :func:`hmmtrack.experiments.loss_sweep` (``loss_fraction``,
        ``converged`` and ``quantity``). Trials that never converged are drawn as hollow
        markers at their value (0 s time to convergence is drawn at the axis floor).
    quantity : str
        ``"time_to_convergence"`` (s) or ``"mean_error_after_convergence"`` (m) or any
        other trials column.
    paper : mapping of band label to value, optional
        The paper's band means, drawn as horizontal segments over their bands.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    _require(table, ("loss_fraction", "converged", quantity), "loss sweep")
    ax = _axes(ax)
    percent = 100.0 * table["loss_fraction"].to_numpy(dtype=float)
    values = table[quantity].to_numpy(dtype=float)
    converged = table["converged"].to_numpy(dtype=bool)
    floor = np.nanmin(values[values > 0]) / 2 if np.any(values > 0) else 1.0
    shown = np.where(values > 0, values, floor)
    ax.scatter(
        percent[converged], shown[converged], s=12, color="tab:green", alpha=0.6, label="trial"
    )
    if np.any(~converged):
        ax.scatter(
            percent[~converged],
            shown[~converged],
            s=16,
            facecolors="none",
            edgecolors="tab:red",
            label="never converged",
        )
    means = (
        pd.DataFrame({"percent": percent[converged], "value": values[converged]})
        .groupby("percent")["value"]
        .mean()
    )
    ax.plot(means.index, means.to_numpy(), color="k", lw=1.5, label="mean of converged")
    for edge in LOSS_BAND_EDGES:
        ax.axvline(100 * edge, color="grey", ls=":", lw=1)
    if paper:
        bounds = (0.0, *(100 * e for e in LOSS_BAND_EDGES), 100.0)
        spans = {band: (bounds[i], bounds[i + 1]) for i, band in enumerate(LOSS_BANDS)}
        for i, (band, value) in enumerate(paper.items()):
            start, stop = spans[band]
            ax.hlines(
                value,
                start,
                stop,
                colors="tab:purple",
                lw=2.5,
                label="paper, band mean" if i == 0 else None,
            )
    _log_scale(ax)
    ax.set_xlabel("detections dropped (%)")
    ax.set_ylabel(_QUANTITY_LABELS.get(quantity, quantity))
    ax.set_xlim(-2, 102)
    ax.legend(fontsize="small")
    return ax


def depth_percent_error(
    ranges: np.ndarray,
    percent_error: np.ndarray,
    depth: float,
    paper: Mapping[float, float] | None = None,
    ax: Axes | None = None,
) -> Axes:
    """The percent error of taking a slant range as horizontal, against the range.

    Parameters
    ----------
    ranges : numpy.ndarray, shape (n,)
        Measured (slant) ranges (m).
    percent_error : numpy.ndarray, shape (n,)
        Percent error at those ranges (%), from
        :func:`hmmtrack.tracking.measurement.ranging.depth_percent_error`.
    depth : float
        Tag depth the curve is for (m).
    paper : mapping of range (m) to percent error (%), optional
        The paper's quoted points, drawn as markers.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax)
    ax.plot(ranges, percent_error, color="tab:blue", label=f"depth {depth:g} m")
    if paper:
        ax.scatter(list(paper), list(paper.values()), color="tab:red", zorder=3, label="paper")
        for r, p in paper.items():
            ax.annotate(
                f"{p:g} %", (r, p), textcoords="offset points", xytext=(6, 6), fontsize="small"
            )
    _log_scale(ax)
    ax.set_xlabel("measured range (m)")
    ax.set_ylabel("range error (%)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def depth_profile(time: np.ndarray, depth: np.ndarray, ax: Axes | None = None) -> Axes:
    """A tag's depth against time, surface at the top.

    Parameters
    ----------
    time : numpy.ndarray, shape (T,)
        Time since the start (s).
    depth : numpy.ndarray, shape (T,)
        Depth (m, positive down).
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax)
    minutes = np.asarray(time, dtype=float) / 60.0
    ax.fill_between(minutes, depth, color="tab:blue", alpha=0.3, lw=0)
    ax.plot(minutes, depth, color="tab:blue", lw=1)
    ax.set_ylim(max(float(np.max(depth)), 1.0) * 1.1, 0)
    ax.set_xlabel("time (min)")
    ax.set_ylabel("tag depth (m)")
    return ax


def depth_trials(trials: pd.DataFrame, ax: Axes | None = None) -> Axes:
    """Per-trial error after convergence without and with the depth correction.

    Parameters
    ----------
    trials : pandas.DataFrame
        Trials table of :func:`hmmtrack.experiments.depth_analysis` (``depth_correction``,
        ``mean_error_after_convergence``).
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
        One dot per trial (spread sideways in trial order), a bar at each variant's median.
    """
    _require(trials, ("depth_correction", "mean_error_after_convergence"), "depth trials")
    ax = _axes(ax)
    labels = []
    for position, (correct, group) in enumerate(trials.groupby("depth_correction")):
        errors = group["mean_error_after_convergence"].to_numpy(dtype=float)
        colour = "tab:green" if correct else "tab:red"
        ax.scatter(
            position + np.linspace(-0.12, 0.12, errors.size), errors, s=18, color=colour, alpha=0.7
        )
        median = float(np.median(errors))
        ax.hlines(median, position - 0.25, position + 0.25, color=colour, lw=2.5)
        labels.append(f"{'with' if correct else 'without'} correction\n(median {median:.3g} m)")
    ax.set_xticks(range(len(labels)), labels)
    ax.set_xlim(-0.6, len(labels) - 0.4)
    _log_scale(ax)
    ax.set_ylabel("mean error after convergence (m)")
    return ax


# ----------------------------------------------------------------------- report figures
# Figure-level layouts shared by ``hmmtrack reproduce`` and the notebooks.


def comparison_figure(table: pd.DataFrame, titles: Mapping[str, str] | None = None) -> Figure:
    """The paper's motion-model comparison: one row per scenario, error and convergence time.

    Parameters
    ----------
    table : pandas.DataFrame
        Trials table of :func:`hmmtrack.experiments.compare_motion_models`.
    titles : mapping of scenario name to title, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = list(pd.unique(table["scenario"]))
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 3.2 * len(names)), squeeze=False)
    for row, name in zip(axes, names, strict=True):
        error_histograms(table, name, ax=row[0])
        error_histograms(table, name, quantity="time_to_convergence", ax=row[1])
        for ax in row:
            ax.set_title((titles or {}).get(name, name))
    fig.tight_layout()
    return fig


def loss_figure(table: pd.DataFrame, paper: pd.DataFrame | None = None) -> Figure:
    """The paper's measurement-loss figure: convergence time and error against loss, log scale.

    Parameters
    ----------
    table : pandas.DataFrame
        Trials table of :func:`hmmtrack.experiments.loss_sweep`.
    paper : pandas.DataFrame, optional
        The paper's bands (index :data:`~hmmtrack.experiments.LOSS_BANDS`, columns
        ``convergence_mean`` and ``error_mean``), drawn as segments.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, quantity, column in zip(
        axes,
        ("time_to_convergence", "mean_error_after_convergence"),
        ("convergence_mean", "error_mean"),
        strict=True,
    ):
        loss_sweep(table, quantity, paper=None if paper is None else paper[column].to_dict(), ax=ax)
    fig.tight_layout()
    return fig


def depth_figure(analysis, paper: Mapping[float, float] | None = None) -> Figure:
    """The depth analysis: percent-error curve, and the diving shark if it was tracked.

    Parameters
    ----------
    analysis : hmmtrack.experiments.DepthAnalysis
    paper : mapping of range (m) to percent error (%), optional

    Returns
    -------
    matplotlib.figure.Figure
        The curve; with diving-shark trials also the shark's depth profile and the
        per-trial errors without and with the correction.
    """
    panels = 3 if analysis.trials is not None else 1
    fig, axes = plt.subplots(1, panels, figsize=(4.8 * panels, 4), squeeze=False)
    depth_percent_error(
        analysis.ranges, analysis.percent_error, analysis.depth, paper=paper, ax=axes[0, 0]
    )
    if analysis.trials is not None:
        depth_profile(*analysis.depth_profile, ax=axes[0, 1])
        axes[0, 1].set_title("diving shark (depth-sensor tag)")
        depth_trials(analysis.trials, ax=axes[0, 2])
        axes[0, 2].set_title("diving shark, HMM model")
    fig.tight_layout()
    return fig


def example_figure(example) -> Figure:
    """One trial: error over time above, particle snapshots below (the paper's run figures).

    Parameters
    ----------
    example : hmmtrack.experiments.ExampleRun

    Returns
    -------
    matplotlib.figure.Figure
    """
    from hmmtrack.plots.tracking import plot_tracking_run

    run, scenario = example.result, example.scenario
    return plot_tracking_run(
        run.estimates,
        run.snapshots,
        scenario.receivers,
        observations=run.observations,
        truth=scenario.truth,
        errors=(run.estimates["time"], example.errors),
        convergence=example.convergence,
    )


def motion_hmm_figure(model, prepared: pd.DataFrame) -> Figure:
    """The paper's state-dependent densities: speed and angular velocity per state.

    Parameters
    ----------
    model : hmmtrack.hmm.MovementHMM
        A fitted 2-state gamma / von Mises model with a time step ``dt`` (s).
    prepared : pandas.DataFrame
        The prepared tracks it was fitted to (``speed`` m/s, ``angular_velocity`` rad/s),
        drawn as histograms under the densities.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from hmmtrack.plots.hmm import emission_density_plot

    _require(prepared, ("speed", "angular_velocity"), "prepared track")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    emission_density_plot(model, prepared["speed"].to_numpy(), "step", per_second=True, ax=axes[0])
    emission_density_plot(
        model, prepared["angular_velocity"].to_numpy(), "angle", per_second=True, ax=axes[1]
    )
    axes[1].set_xlim(-0.06, 0.06)
    fig.tight_layout()
    return fig
