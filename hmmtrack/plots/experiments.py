"""Dataset overview figures: where the hydrophones and the transmitter went in a scenario.

The analogue of the paper's dataset-overview figure (hydrophones in orange and blue, the
transmitter in green). Draws what a :class:`hmmtrack.scenarios.Scenario` holds; computes
nothing.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
from matplotlib.axes import Axes

from hmmtrack.scenarios import Scenario

#: hydrophone colours in the paper's order (orange, blue), then further ones
RECEIVER_COLOURS = ("tab:orange", "tab:blue", "tab:purple", "tab:brown")
#: transmitter colour (green, as the paper)
TRANSMITTER_COLOUR = "tab:green"


def plot_scenario(scenario: Scenario, ax: Axes | None = None) -> Axes:
    """Plot the hydrophones' logged paths and the transmitter's true path, seen from above.

    Moored hydrophones and a fixed tag are drawn as single markers; a circle marks where
    each moving thing starts and a cross where it ends.

    Parameters
    ----------
    scenario : Scenario
    ax : matplotlib Axes, optional
        Drawn into; a new figure's Axes if omitted.

    Returns
    -------
    Axes
        With equal aspect, axes in metres and a legend.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 5))
    paths = [
        (name, group, RECEIVER_COLOURS[k % len(RECEIVER_COLOURS)])
        for k, (name, group) in enumerate(scenario.receivers.groupby("receiver", sort=False))
    ]
    paths.append((f"transmitter {scenario.transmitter}", scenario.truth, TRANSMITTER_COLOUR))
    for label, table, colour in paths:
        x, y = table["x"].to_numpy(), table["y"].to_numpy()
        if len(table) == 1 or (x.min() == x.max() and y.min() == y.max()):
            ax.plot(x[:1], y[:1], marker="^", ms=9, ls="none", color=colour, label=label)
            continue
        ax.plot(x, y, color=colour, lw=1.2, label=label)
        ax.plot(x[0], y[0], marker="o", ms=6, color=colour)
        ax.plot(x[-1], y[-1], marker="x", ms=7, mew=2, color=colour)
    duration = scenario.end - scenario.start
    ax.set_title(
        f"{scenario.name} ({duration / 60:.0f} min)"
        if duration >= 600
        else f"{scenario.name} ({duration:.0f} s)"
    )
    ax.set_xlabel("x (m, east)")
    ax.set_ylabel("y (m, north)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    return ax
