"""Figures of fitted movement HMMs: densities, covariate effects, residuals, decoded tracks.

* :func:`emission_density_plot` -- the paper's emission-density figure: a histogram of steps
  (or turning angles) with each state's density weighted by its stationary probability, and
  their sum; ``log=True`` puts heavy-tailed steps on a log axis, ``per_second=True`` draws
  speed or angular velocity (rad/s) instead.
* :func:`transition_probability_plot`, :func:`stationary_probability_plot` -- transition and
  stationary probabilities against a covariate with their confidence bands
  (:func:`hmmtrack.hmm.diagnostics.covariate_effects`).
* :func:`residual_series_plot`, :func:`residual_qq_plot`, :func:`residual_acf_plot` --
  pseudo-residual checks: time series, normal QQ plot, autocorrelation.
* :func:`decoded_track_plot` -- a track coloured by decoded state; :func:`animal_tracks_figure`
  one panel per animal.
* :func:`starts_figure` -- a check of starting values
  (:func:`hmmtrack.hmm.diagnostics.check_starts`): the log-likelihood each start reached and
  the spread of each parameter over the starts.
* :func:`hmm_figures` -- the standard set of figures of a fit (what ``hmmtrack fit --plot``
  and ``hmmtrack plot`` write).

States are numbered from 1 in every label, as moveHMM and the CLI number them; optional
``state_names`` (one per state) are shown beside the numbers. Each single-panel function takes
``ax=None`` (a new figure) and returns the Axes. The numbers come from :mod:`hmmtrack.hmm`
(model, :mod:`~hmmtrack.hmm.diagnostics`); nothing is computed here that the library does
not provide, except the changes of variable to per-second units and to a log axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import seaborn as sns
from matplotlib.collections import LineCollection

from hmmtrack import tracks
from hmmtrack.hmm import diagnostics
from hmmtrack.hmm.model import MovementHMM, check_state_names


def _axes(ax):
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    return ax


def state_labels(n_states: int, state_names: Sequence[str] | None = None) -> list[str]:
    """Legend labels of the states: ``"state 1"``, ... or ``"1 encamped"``, ... with names.

    Raises
    ------
    ValueError
        When ``state_names`` is not one distinct name per state.
    """
    check_state_names(n_states, state_names)
    if state_names is None:
        return [f"state {k + 1}" for k in range(n_states)]
    return [f"{k + 1} {name}" for k, name in enumerate(state_names)]


def _palette(n_states: int):
    return sns.color_palette("colorblind", n_states)


def emission_density_plot(
    model: MovementHMM,
    values: np.ndarray | pd.Series,
    kind: str = "step",
    per_second: bool = False,
    bins: int = 60,
    log: bool = False,
    state_names: Sequence[str] | None = None,
    ax=None,
):
    """Histogram of observations with the fitted state-dependent densities.

    Parameters
    ----------
    model : MovementHMM
    values : ndarray or Series, shape (n,)
        Steps (``model.step_unit``) or turning angles (rad); NaN ignored. With
        ``per_second`` pass speeds (unit/s) or angular velocities (rad/s) instead. A column of
        a prepared track (``prepared["step"]``) carries its length unit
        (``attrs["length_unit_m"]``): steps in another unit than the model's are refused.
    kind : {"step", "angle"}
    per_second : bool
        Draw speed / angular velocity: density of ``v = x / dt`` is ``dt f(v dt)``, with
        ``dt = model.dt`` (s); exact for data on a regular time step ``dt``.
    bins : int
    log : bool
        Steps on a logarithmic axis (heavy tails): the histogram has log-spaced bins and the
        curves are densities of ``log10`` of the step, ``x ln(10) f(x)``, so that areas
        still equal the stationary weights. Zero steps are left out of the histogram.
    state_names : sequence of str, optional
        One name per state, for the legend.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    if kind not in ("step", "angle"):
        raise ValueError(f"kind must be 'step' or 'angle', got {kind!r}")
    if log and kind != "step":
        raise ValueError("log=True is for steps (a log axis of turning angles has no meaning)")
    if per_second and not np.isfinite(model.dt):
        raise ValueError("the model has no time step (dt); per-second densities need one")
    scale_m = getattr(values, "attrs", {}).get("length_unit_m")
    if kind == "step" and scale_m is not None and tracks.length_unit(scale_m) != model.step_unit:
        raise ValueError(
            f"the steps are in {tracks.length_unit(scale_m)} (attrs['length_unit_m'] = "
            f"{scale_m:g}) but the model was fitted to steps in {model.step_unit}; prepare the "
            "track with the scale the model was fitted with"
        )
    labels = state_labels(model.n_states, state_names)
    ax = _axes(ax)
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    scale = model.dt if per_second else 1.0
    dist = model.step if kind == "step" else model.angle
    if kind == "step":
        top = np.quantile(values, 0.995) if values.size else dist.expected_value().max() * 3
        if log:
            values = values[values > 0]
            bottom = np.quantile(values, 0.001) / 2 if values.size else top / 1e4
            grid = np.geomspace(bottom, np.max(values, initial=top), 800)
        else:
            grid = np.linspace(top / 2000, top, 800)
            values = values[values <= top]
    else:
        grid = np.linspace(-np.pi, np.pi, 721) / scale
    weights = model.stationary()
    density = np.exp(dist.logpdf(grid * scale)) * scale * weights
    if log:
        density = density * (grid * np.log(10.0))[:, None]
    sns.histplot(
        values, stat="density", bins=bins, log_scale=log, color="0.82", edgecolor="white", ax=ax
    )
    palette = _palette(model.n_states)
    for k in range(model.n_states):
        ax.plot(grid, density[:, k], color=palette[k], lw=2, label=labels[k])
    ax.plot(grid, density.sum(axis=1), color="black", lw=1.5, ls="--", label="total")
    unit = model.step_unit
    names = {
        ("step", False): f"step length ({unit})",
        ("step", True): f"speed ({unit}/s)",
        ("angle", False): "turning angle (rad)",
        ("angle", True): "angular velocity (rad/s)",
    }
    ax.set_xlabel(names[kind, per_second] + (", log scale" if log else ""))
    ax.set_ylabel("density of log10(step)" if log else "density")
    if kind == "angle" and not per_second:
        ax.set_xticks(np.pi * np.array([-1, -0.5, 0, 0.5, 1]), ["-π", "-π/2", "0", "π/2", "π"])
    ax.legend(frameon=False, fontsize="small")
    return ax


def _effect_rows(effects: pd.DataFrame, kind: str) -> pd.DataFrame:
    rows = effects[effects["kind"] == kind]
    if rows.empty:
        raise ValueError(f"no {kind} rows in the effects table (diagnostics.covariate_effects)")
    return rows


def _band(ax, rows: pd.DataFrame, color, label: str | None) -> None:
    """One probability against the covariate: a line and band (numeric), or points with
    error bars (levels of a factor)."""
    x = rows["value"].to_numpy()
    if pd.api.types.is_numeric_dtype(rows["value"]):
        ax.fill_between(x, rows["lower"], rows["upper"], color=color, alpha=0.25, lw=0)
        ax.plot(x, rows["estimate"], color=color, lw=2, label=label)
    else:
        estimate = rows["estimate"].to_numpy()
        error = np.vstack([estimate - rows["lower"], rows["upper"] - estimate])
        ax.errorbar(x.astype(str), estimate, yerr=error, fmt="o", color=color, capsize=3,
                    label=label)  # fmt: skip


def transition_probability_plot(
    effects: pd.DataFrame,
    variable: str,
    state_names: Sequence[str] | None = None,
    level: float = 0.95,
    axes=None,
):
    """Transition probabilities against a covariate, one panel per ``from -> to`` pair.

    Parameters
    ----------
    effects : DataFrame
        :func:`hmmtrack.hmm.diagnostics.covariate_effects` of ``variable``.
    variable : str
        The covariate's name (x axis label).
    state_names : sequence of str, optional
    level : float
        Coverage of the bands in ``effects`` (for the title).
    axes : ndarray of Axes, shape (K, K), optional

    Returns
    -------
    ndarray of Axes, shape (K, K)
        Panel ``[i, j]``: probability of moving from state ``i + 1`` to state ``j + 1``.
    """
    rows = _effect_rows(effects, "transition")
    k = int(rows["from_state"].max())
    labels = state_labels(k, state_names)
    if axes is None:
        _, axes = plt.subplots(k, k, figsize=(3.2 * k, 2.6 * k), sharex=True, squeeze=False)
    palette = _palette(k)
    for i in range(k):
        for j in range(k):
            ax = axes[i, j]
            pair = rows[(rows["from_state"] == i + 1) & (rows["to_state"] == j + 1)]
            _band(ax, pair, palette[j], None)
            ax.set_ylim(0, 1)
            ax.set_title(f"{labels[i]} → {labels[j]}", fontsize="medium")
            if i == k - 1:
                ax.set_xlabel(variable)
            if j == 0:
                ax.set_ylabel("probability")
    axes[0, 0].figure.suptitle(f"transition probabilities ({level:.0%} bands)", fontsize="medium")
    return axes


def stationary_probability_plot(
    effects: pd.DataFrame,
    variable: str,
    state_names: Sequence[str] | None = None,
    level: float = 0.95,
    ax=None,
):
    """Stationary state probabilities against a covariate, one line (and band) per state.

    Parameters as :func:`transition_probability_plot`; returns the Axes.
    """
    rows = _effect_rows(effects, "stationary")
    k = int(rows["to_state"].max())
    labels = state_labels(k, state_names)
    ax = _axes(ax)
    palette = _palette(k)
    for j in range(k):
        _band(ax, rows[rows["to_state"] == j + 1], palette[j], labels[j])
    ax.set_ylim(0, 1)
    ax.set_xlabel(variable)
    ax.set_ylabel(f"stationary probability ({level:.0%} band)")
    ax.legend(frameon=False, fontsize="small")
    return ax


def residual_series_plot(residuals: np.ndarray, label: str = "", segments=None, ax=None):
    """Pseudo-residuals in row order, with the ±1.96 band of a standard normal.

    Parameters
    ----------
    residuals : ndarray, shape (T,)
        One stream's pseudo-residuals (NaN where the observation is missing).
    label : str
        The stream's name (y axis).
    segments : ndarray, shape (T,), optional
        Segment (track) of each row: boundaries drawn as vertical lines.
    ax : matplotlib Axes, optional
    """
    ax = _axes(ax)
    residuals = np.asarray(residuals, dtype=float)
    rows = np.arange(residuals.size)
    ax.axhspan(-1.96, 1.96, color="0.9", lw=0)
    ax.plot(rows, residuals, color="C0", lw=0.4)
    ax.scatter(rows, residuals, s=2, color="C0")
    if segments is not None:
        segments = np.asarray(segments)
        for boundary in np.flatnonzero(segments[1:] != segments[:-1]) + 1:
            ax.axvline(boundary - 0.5, color="0.5", lw=0.6, ls=":")
    ax.axhline(0, color="black", lw=0.8)
    ax.set_xlabel("row (track order)")
    ax.set_ylabel(f"{label} pseudo-residual".strip())
    return ax


def residual_qq_plot(residuals: np.ndarray, label: str = "", ax=None):
    """Normal QQ plot of pseudo-residuals (NaN skipped) with the identity line."""
    ax = _axes(ax)
    theoretical, sample = diagnostics.qq_points(residuals)
    ax.scatter(theoretical, sample, s=4, color="C0")
    limit = np.nanmax(np.abs(np.concatenate([theoretical, sample]))) if sample.size else 3.0
    ax.plot([-limit, limit], [-limit, limit], color="black", lw=1)
    ax.set_xlabel("standard normal quantiles")
    ax.set_ylabel(f"{label} pseudo-residual quantiles".strip())
    return ax


def residual_acf_plot(residuals: np.ndarray, n_lags: int = 40, label: str = "", ax=None):
    """Autocorrelation of pseudo-residuals with the ±1.96/sqrt(n) band."""
    ax = _axes(ax)
    values = diagnostics.autocorrelation(residuals, n_lags)
    lags = np.arange(values.size)
    ax.vlines(lags, 0, values, color="C0")
    band = 1.96 / np.sqrt(np.isfinite(np.asarray(residuals, dtype=float)).sum())
    ax.axhspan(-band, band, color="C0", alpha=0.15, lw=0)
    ax.axhline(0, color="black", lw=0.8)
    ax.set_xlabel("lag")
    ax.set_ylabel(f"ACF {label}".strip())
    return ax


def decoded_track_plot(
    prepared: pd.DataFrame,
    states: np.ndarray,
    state_names: Sequence[str] | None = None,
    n_states: int | None = None,
    ax=None,
):
    """Track coloured by decoded state: each step in its state's colour and each fix a dot.

    States with short steps would vanish as coloured lines of almost no length; the dots at
    the fixes keep them visible, drawn from the last state to the first, so that state 1
    (the shortest steps) is on top.

    Parameters
    ----------
    prepared : DataFrame
        Prepared track with ``x``, ``y`` (its length unit, ``attrs["length_unit_m"]``) and
        ``segment``.
    states : ndarray of int, shape (T,)
        States 0..K-1 (e.g. :meth:`MovementHMM.viterbi`); labelled from 1.
    state_names : sequence of str, optional
    n_states : int, optional
        ``K``, for colours and legend (default ``states.max() + 1``).
    ax : matplotlib Axes, optional
    """
    ax = _axes(ax)
    states = np.asarray(states)
    if states.shape != (len(prepared),):
        raise ValueError(f"states have shape {states.shape}; expected ({len(prepared)},)")
    k = int(states.max()) + 1 if n_states is None else n_states
    labels = state_labels(k, state_names)
    palette = _palette(k)
    xy = prepared[["x", "y"]].to_numpy(dtype=float)
    segment = prepared["segment"].to_numpy()
    same = segment[1:] == segment[:-1]
    pieces = np.stack([xy[:-1], xy[1:]], axis=1)[same]
    piece_states = states[:-1][same]
    for state in range(k - 1, -1, -1):
        chosen = piece_states == state
        if chosen.any():
            ax.add_collection(
                LineCollection(pieces[chosen], colors=[palette[state]], lw=1.0, alpha=0.8)
            )
    for state in range(k - 1, -1, -1):
        at = states == state
        ax.scatter(*xy[at].T, s=6, color=palette[state], label=labels[state], zorder=3 + k - state)
    ax.autoscale()
    ax.set_aspect("equal", adjustable="datalim")
    unit = tracks.length_unit(prepared.attrs.get("length_unit_m", 1.0))
    ax.set_xlabel(f"x, east ({unit})")
    ax.set_ylabel(f"y, north ({unit})")
    handles, names = ax.get_legend_handles_labels()
    ax.legend(handles[::-1], names[::-1], frameon=False, fontsize="small", markerscale=2)
    return ax


def animal_tracks_figure(
    prepared: pd.DataFrame,
    states: np.ndarray,
    state_names: Sequence[str] | None = None,
    n_states: int | None = None,
    n_columns: int = 2,
):
    """One :func:`decoded_track_plot` panel per animal (``id``), each on its own scale.

    Returns
    -------
    matplotlib.figure.Figure
    """
    states = np.asarray(states)
    k = int(states.max()) + 1 if n_states is None else n_states
    animals = pd.unique(prepared["id"])
    n_columns = min(n_columns, animals.size)
    n_rows = math.ceil(animals.size / n_columns)
    fig, axes = plt.subplots(
        n_rows, n_columns, figsize=(5 * n_columns, 4.4 * n_rows), squeeze=False
    )
    for ax, animal in zip(axes.flat, animals, strict=False):
        rows = (prepared["id"] == animal).to_numpy()
        decoded_track_plot(prepared[rows], states[rows], state_names, k, ax=ax)
        ax.set_title(str(animal))
    for ax in axes.flat[animals.size :]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig


def starts_figure(table: pd.DataFrame) -> plt.Figure:
    """Two panels of a check of starting values (:func:`~hmmtrack.hmm.diagnostics.starts_table`).

    Left: each start's log-likelihood after EM, starts sorted from the best, those that
    reached the best optimum in one colour; the gap to the best on a symmetric-log axis so
    that both 1e-3 and 100 nats show. Right: every parameter's value at each start relative
    to the best start's (``value / best - 1``; the difference for angle means, in rad), one
    row per parameter, so that a parameter the starts disagree on stands out.

    Returns
    -------
    Figure
    """
    ok = table[np.isfinite(table["log_likelihood"])]
    if ok.empty:
        raise ValueError("starts_figure: every start failed; nothing to draw")
    fig, (left, right) = plt.subplots(
        1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [1, 1.3]}
    )
    ordered = ok.sort_values("log_likelihood", ascending=False, kind="stable")
    best_value = ordered["log_likelihood"].iloc[0]
    gap = best_value - ordered["log_likelihood"].to_numpy()
    colours = np.where(ordered["best"].to_numpy(), "tab:blue", "tab:orange")
    rank = np.arange(1, len(ordered) + 1)
    left.scatter(rank, gap, c=colours, zorder=3)
    left.set_yscale("symlog", linthresh=1e-3)
    left.set_ylim(-2e-4, max(1.0, 2.0 * gap.max()))  # agreeing starts sit on 0, not zoomed
    left.set_xlabel("start, sorted by log-likelihood")
    left.set_ylabel("log-likelihood below the best (nats)")
    n_best = int(ordered["best"].sum())
    left.set_title(f"{n_best} of {len(table)} starts at the best {best_value:.5f}")
    left.grid(alpha=0.3)

    first = list(table.columns).index("error") + 1  # the parameters follow the error column
    parameters = [c for c in table.columns[first:] if not c.startswith("initial")]
    best_row = ordered.iloc[0]
    widest = 0.1
    for y, name in enumerate(parameters):
        values = ok[name].to_numpy(dtype=float)
        reference = float(best_row[name])
        if name.startswith("angle.mean") or reference == 0:
            spread = values - reference
        else:
            spread = values / reference - 1.0
        widest = max(widest, float(np.nanmax(np.abs(spread))))
        right.scatter(
            spread,
            np.full(values.size, y),
            c=np.where(ok["best"], "tab:blue", "tab:orange"),
            s=18,
            alpha=0.7,
        )
    right.set_yticks(range(len(parameters)), parameters, fontsize=8)
    right.invert_yaxis()
    right.set_xscale("symlog", linthresh=1e-3)
    right.set_xlim(-1.5 * widest, 1.5 * widest)
    right.axvline(0, color="0.5", lw=0.8)
    right.set_xlabel("relative to the best start (angle means: difference, rad)")
    right.set_title("parameters by start (blue: at the best optimum)")
    fig.tight_layout()
    return fig


def hmm_figures(
    model: MovementHMM,
    prepared: pd.DataFrame,
    states: np.ndarray,
    state_names: Sequence[str] | None = None,
    level: float = 0.95,
) -> dict[str, plt.Figure]:
    """The standard figures of a fit, by file name.

    * ``densities.png``: steps over a linear and a log axis, turning angles;
    * ``residuals.png``: one row per stream (steps, angles, each further stream), its
      pseudo-residuals in row order, QQ plot and ACF;
    * ``tracks.png``: the decoded tracks, one panel per animal;
    * ``transition_<variable>.png`` and ``stationary_<variable>.png`` for each variable of
      the transition formula, with ``level`` bands.

    Parameters
    ----------
    model : MovementHMM
    prepared : DataFrame
        The prepared track (the one fitted, for the bands).
    states : ndarray of int, shape (T,)
        Decoded states 0..K-1 of ``prepared``.
    state_names : sequence of str, optional
    level : float

    Returns
    -------
    dict of str to Figure
    """
    state_labels(model.n_states, state_names)  # refuse a wrong number of names first
    figures = {}
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    step = prepared["step"]
    emission_density_plot(model, step, "step", state_names=state_names, ax=axes[0])
    emission_density_plot(model, step, "step", log=True, state_names=state_names, ax=axes[1])
    emission_density_plot(model, prepared["angle"], "angle", state_names=state_names, ax=axes[2])
    fig.tight_layout()
    figures["densities.png"] = fig

    residuals = diagnostics.pseudo_residuals(model, prepared)
    streams = list(model.emissions)
    fig, axes = plt.subplots(
        len(streams),
        3,
        figsize=(15, 3.5 * len(streams)),
        gridspec_kw={"width_ratios": [2, 1, 1]},
        squeeze=False,
    )
    for row, stream in enumerate(streams):
        values = residuals[f"{stream}_residual"].to_numpy()
        residual_series_plot(values, stream, prepared["segment"].to_numpy(), ax=axes[row, 0])
        residual_qq_plot(values, stream, ax=axes[row, 1])
        residual_acf_plot(values, label=stream, ax=axes[row, 2])
    fig.tight_layout()
    figures["residuals.png"] = fig

    figures["tracks.png"] = animal_tracks_figure(prepared, states, state_names, model.n_states)

    if model.transition_design is not None:
        for variable in sorted(model.transition_design.spec.required_variables):
            effects = diagnostics.covariate_effects(model, prepared, variable, level=level)
            axes = transition_probability_plot(effects, variable, state_names, level)
            axes[0, 0].figure.tight_layout()
            figures[f"transition_{variable}.png"] = axes[0, 0].figure
            ax = stationary_probability_plot(effects, variable, state_names, level)
            ax.figure.tight_layout()
            figures[f"stationary_{variable}.png"] = ax.figure
    return figures
