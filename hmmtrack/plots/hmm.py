"""Figures of fitted movement HMMs: emission densities, decoded tracks, pseudo-residuals.

* :func:`emission_density_plot` -- the paper's emission-density figure: a histogram of steps
  (or turning angles) with each state's density weighted by its stationary probability, and
  their sum; ``per_second=True`` draws speed (m/s) or angular velocity (rad/s) instead.
* :func:`decoded_track_plot` -- the track coloured by decoded state.
* :func:`residual_qq_plot`, :func:`residual_acf_plot` -- pseudo-residual checks.

Each takes ``ax=None`` (a new figure) and returns the Axes. The numbers come from
:mod:`hmmtrack.hmm` (model, :mod:`~hmmtrack.hmm.diagnostics`); nothing is computed here that
the library does not provide, except the change of variable to per-second units.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import seaborn as sns
from matplotlib.collections import LineCollection

from hmmtrack.hmm import diagnostics
from hmmtrack.hmm.model import MovementHMM


def _axes(ax):
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    return ax


def emission_density_plot(
    model: MovementHMM,
    values: np.ndarray,
    kind: str = "step",
    per_second: bool = False,
    bins: int = 60,
    ax=None,
):
    """Histogram of observations with the fitted state-dependent densities.

    Parameters
    ----------
    model : MovementHMM
    values : ndarray, shape (n,)
        Steps (``model.step_unit``) or turning angles (rad); NaN ignored. With
        ``per_second`` pass speeds (unit/s) or angular velocities (rad/s) instead.
    kind : {"step", "angle"}
    per_second : bool
        Draw speed / angular velocity: density of ``v = x / dt`` is ``dt f(v dt)``, with
        ``dt = model.dt`` (s); exact for data on a regular time step ``dt``.
    bins : int
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    if kind not in ("step", "angle"):
        raise ValueError(f"kind must be 'step' or 'angle', got {kind!r}")
    if per_second and not np.isfinite(model.dt):
        raise ValueError("the model has no time step (dt); per-second densities need one")
    ax = _axes(ax)
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    scale = model.dt if per_second else 1.0
    dist = model.step if kind == "step" else model.angle
    if kind == "step":
        top = np.quantile(values, 0.995) if values.size else dist.expected_value().max() * 3
        grid = np.linspace(top / 2000, top, 800)
        values = values[values <= top]
    else:
        grid = np.linspace(-np.pi, np.pi, 721) / scale
    weights = model.stationary()
    density = np.exp(dist.logpdf(grid * scale)) * scale * weights
    sns.histplot(values, stat="density", bins=bins, color="0.8", edgecolor="white", ax=ax)
    palette = sns.color_palette("colorblind", model.n_states)
    for k in range(model.n_states):
        ax.plot(grid, density[:, k], color=palette[k], lw=2, label=f"state {k + 1}")
    ax.plot(grid, density.sum(axis=1), color="black", lw=1.5, ls="--", label="total")
    unit = model.step_unit
    labels = {
        ("step", False): f"step length ({unit})",
        ("step", True): f"speed ({unit}/s)",
        ("angle", False): "turning angle (rad)",
        ("angle", True): "angular velocity (rad/s)",
    }
    ax.set_xlabel(labels[kind, per_second])
    ax.set_ylabel("density")
    ax.legend(frameon=False)
    return ax


def decoded_track_plot(prepared: pd.DataFrame, states: np.ndarray, ax=None):
    """Track coloured by decoded state: the step from each fix drawn in that fix's state colour.

    Parameters
    ----------
    prepared : DataFrame
        Prepared track with ``x``, ``y`` and ``segment``.
    states : ndarray of int, shape (T,)
        States 0..K-1 (e.g. :meth:`MovementHMM.viterbi`).
    ax : matplotlib Axes, optional
    """
    ax = _axes(ax)
    states = np.asarray(states)
    if states.shape != (len(prepared),):
        raise ValueError(f"states have shape {states.shape}; expected ({len(prepared)},)")
    xy = prepared[["x", "y"]].to_numpy(dtype=float)
    segment = prepared["segment"].to_numpy()
    same = segment[1:] == segment[:-1]
    pieces = np.stack([xy[:-1], xy[1:]], axis=1)[same]
    piece_states = states[:-1][same]
    palette = sns.color_palette("colorblind", int(states.max()) + 1)
    for k in np.unique(piece_states):
        ax.add_collection(
            LineCollection(
                pieces[piece_states == k], colors=[palette[k]], lw=1.0, label=f"state {k + 1}"
            )
        )
    ax.autoscale()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (east)")
    ax.set_ylabel("y (north)")
    ax.legend(frameon=False)
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
