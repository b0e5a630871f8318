"""The closed-loop report (``reports/closed_loop.md``): AUVs steered on the estimate or the truth.

:func:`write_closed_loop` runs :func:`hmmtrack.experiments.closed_loop_study.closed_loop_study`,
draws the first scenario's error over time (:func:`hmmtrack.plots.studies.closed_loop_errors`,
``closed_loop.png``) and writes the tables; a hand-written reading after the marker line
(:data:`hmmtrack.report.studies.READING_MARKER`) is kept.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from hmmtrack.experiments.clock_runs import DURATION
from hmmtrack.experiments.closed_loop_study import (
    MAX_SPEED,
    PLAN,
    PRESET,
    SETTLED,
    ClosedLoopStudy,
    closed_loop_study,
)
from hmmtrack.io.outputs import atomic_files
from hmmtrack.plots.studies import closed_loop_errors
from hmmtrack.report.markdown import frame_markdown
from hmmtrack.report.studies import READING_MARKER, kept_reading, provenance, run_timed


def closed_loop_markdown(
    study: ClosedLoopStudy, written_by: str, latency: float, duration: float, figure: str
) -> str:
    """The report's Markdown (without the kept reading), ending with the reading's marker."""
    return (
        "# Two AUVs steered on the filter's estimate (closed loop)\n\n"
        f"{written_by}. `{PRESET}` preset without the detection curve, "
        f"{duration / 3600:.0f} h, no initial range, the observable plan "
        f"({PLAN.describe()}); open loop: stations around the true shark; closed loop: "
        f"around the filter's online estimate ({latency:g} s old, carried forward by "
        f"the lead velocity), AUVs capped at {MAX_SPEED:g} m/s "
        "(`hmmtrack.experiments.closed_loop.fly_closed_loop`). Errors in metres; `filtered_m`: "
        "mean error after convergence; `smoothed_m`: the 60 s fixed-lag smoother rerun "
        f"offline; geometry at the true shark from {SETTLED} s on.\n\n"
        "## Summary\n\n"
        + frame_markdown(study.summary)
        + f"\n\nLoop run time, closed / open: {study.loop_ratio:.2f}.\n\n"
        f"![error over time, seed 0]({figure})\n\n## Every run\n\n"
        + frame_markdown(study.runs)
        + "\n\n"
    )


def write_closed_loop(
    out: Path | str,
    *,
    seeds: int = 3,
    filter_seeds: int = 1,
    latency: float = 2.0,
    particles: int | None = None,
    duration: float = DURATION,
) -> Path:
    """Run the closed-loop study and write ``out/closed_loop.md`` and ``out/closed_loop.png``.

    Parameters
    ----------
    out : path
        Folder (created if missing).
    seeds : int
        Scenario seeds ``0 .. seeds - 1``.
    filter_seeds : int
        Filter seeds per scenario.
    latency : float
        Steering delay (s).
    particles : int, optional
        Default: the preset's.
    duration : float
        Length of each run (s).

    Returns
    -------
    pathlib.Path
    """
    out = Path(out)
    study, seconds, load = run_timed(
        closed_loop_study,
        range(seeds),
        filter_seeds=filter_seeds,
        latency=latency,
        n_particles=particles,
        duration=duration,
    )
    command = (
        f"hmmtrack study closed-loop --seeds {seeds} --filter-seeds {filter_seeds} "
        f"--latency {latency:g} --duration {duration:g}"
        + ("" if particles is None else f" --particles {particles}")
    )
    out.mkdir(parents=True, exist_ok=True)
    path = out / "closed_loop.md"
    figure = path.with_suffix(".png")
    reading = kept_reading(path) or READING_MARKER
    text = closed_loop_markdown(
        study, provenance(command, seconds, load), latency, duration, figure.name
    )
    with atomic_files(path, figure) as (markdown, png):
        ax = closed_loop_errors(study.series, 0)
        ax.figure.tight_layout()
        ax.figure.savefig(png, dpi=120)
        plt.close(ax.figure)
        markdown.write_text(text + reading)
    return path
