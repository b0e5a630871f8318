"""Figure of a clock synchronisation: the sync residuals of every receiver.

:func:`plot_sync_residuals` draws what :func:`hmmtrack.sync.fit_clocks` returns
(``SyncFit.residuals``): per receiver, its kept residuals (ms) as points coloured by sync
tag over a box, the rejected outliers counted in the labels. A well synchronised array has
every box centred on zero and a fraction of a millisecond wide; a receiver whose points
split by sync tag is misplaced (refine its position), one with a wide box has a clock the
segments cannot follow, or multipath.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes


def plot_sync_residuals(
    residuals: pd.DataFrame, ax: Axes | None = None, limit_ms: float = 5.0
) -> Axes:
    """Sync residuals by receiver (ms), kept ones as points over boxes.

    Parameters
    ----------
    residuals : DataFrame
        ``SyncFit.residuals``: ``receiver``, ``sync_tag``, ``residual_ms``, ``rejected``.
    ax : Axes, optional
        Where to draw; a new figure when omitted.
    limit_ms : float
        The residual axis spans ``±limit_ms``; points beyond it are drawn at the edge.

    Returns
    -------
    Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(max(6.0, 0.45 * residuals["receiver"].nunique()), 4.0))
    names = sorted(residuals["receiver"].unique())
    kept = residuals[~residuals["rejected"]]
    values = [kept.loc[kept["receiver"] == n, "residual_ms"].to_numpy() for n in names]
    ax.boxplot(values, positions=np.arange(len(names)), widths=0.6, showfliers=False)
    rng = np.random.default_rng(0)  # horizontal jitter of the points only
    position = {n: i for i, n in enumerate(names)}
    for tag, rows in kept.groupby("sync_tag"):
        where = rows["receiver"].map(position).to_numpy()
        ax.scatter(
            where + rng.uniform(-0.25, 0.25, where.size),
            np.clip(rows["residual_ms"].to_numpy(), -limit_ms, limit_ms),
            s=3,
            alpha=0.4,
            linewidths=0,
            label=tag,
        )
    ax.legend(title="sync tag", fontsize=7, title_fontsize=7, markerscale=3, loc="upper right")
    rejected = residuals.groupby("receiver")["rejected"].sum()
    ax.set_xticks(np.arange(len(names)))
    ax.set_xticklabels(
        [f"{n} ({int(rejected.get(n, 0))})" for n in names], rotation=60, ha="right", fontsize=7
    )
    ax.axhline(0.0, color="grey", linewidth=0.8)
    ax.set_ylim(-limit_ms, limit_ms)
    ax.set_ylabel("sync residual (ms)")
    ax.set_xlabel("receiver (outliers rejected)")
    ax.set_title("Sync-tag arrival residuals after clock fit")
    return ax
