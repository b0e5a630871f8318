"""The bound report (``reports/clock_bound.md``): how well could any tracker do?

:func:`write_clock_bound` runs :func:`hmmtrack.experiments.clock_bound.clock_bound_study`
(with the clock-aware report's per-run filter errors beside the bounds, when that report
exists), draws the bound over time (:func:`hmmtrack.plots.studies.bound_curves`,
``clock_bound.png``) and writes the tables; a hand-written reading after the marker line
(:data:`hmmtrack.report.studies.READING_MARKER`) is kept.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from hmmtrack.experiments.clock_bound import (
    FILTER_PARTICLES,
    SWEEP,
    ClockBoundStudy,
    clock_bound_study,
)
from hmmtrack.experiments.clock_runs import DURATION
from hmmtrack.io.outputs import atomic_files
from hmmtrack.plots.studies import bound_curves
from hmmtrack.report.clock_aware import read_filter_errors
from hmmtrack.report.markdown import frame_markdown
from hmmtrack.report.studies import kept_reading, provenance, run_timed

#: the columns of the bound-against-filter table (the rest are in "Every run")
COMPACT = [
    "fitted clock, arrivals only: filter_m",
    "fitted clock, arrivals only: smoother_m",
    "fitted clock: filter_m",
    "fitted clock: smoother_m",
    "fitted clock: smoother_clock_ms",
    "filter's clock: filter_m",
    "clock known: filter_m",
    "pf_rms_m",
    "pf_smoothed_rms_m",
    "pf_mean_after_10_min_m",
    "pf_smoothed_mean_after_10_min_m",
    "pf_clock_known_mean_after_10_min_m",
]


def clock_bound_markdown(
    study: ClockBoundStudy, written_by: str, figure: str, filter_report: str, sweep_seeds: int
) -> str:
    """The report's Markdown (without the kept reading)."""
    compact = study.summary[["scenario"] + [c for c in COMPACT if c in study.summary]]
    parts = [
        "# How well could any tracker do? Posterior Cramér–Rao bounds for issue 5",
        "",
        f"{written_by}. Bounds are the square root of the trace of the "
        "position block (m) at each ping, given as its RMS over the pings from 10 min to 2 h "
        "(a lower bound on the RMS position error over that window); `*_clock_ms` is the "
        "same for the emission time (ms). `pf_rms_m` and `pf_smoothed_rms_m` are the "
        "arrival-time particle filter's and its 60 s smoother's RMS errors over the same "
        "window, run by this study; `pf_*mean*` are mean Euclidean errors over the same "
        f"window read from `{filter_report}` (the paper's metric). "
        "How q, σ and the clock prior are chosen: see `hmmtrack.experiments.clock_bound` "
        "and the reading below.",
        "",
        "## Bounds beside the particle filter (mean over seeds)",
        "",
        "`fitted clock`: clock unknown, prior fitted to the true schedule, with the "
        "detection curve; `arrivals only`: the same without the detection curve; "
        "`filter's clock`: the arrival-time filter's clock model, with the detection curve; "
        "`clock known`: with the detection curve. All columns per seed, with q, σ and the "
        'fitted clock, are under "Every run". `nan` in a `pf_*` column: no such run in '
        f"`{filter_report}` (it has clock-known runs for two geometries only).",
        "",
        frame_markdown(compact),
        "",
        "## Sensitivity of the bound to its priors (two-AUV cases, fitted clock and detection "
        "curve, mean over seeds)",
        "",
        frame_markdown(study.sensitivity),
        "",
    ]
    if len(study.sweep):
        parts += [
            f"## Planning sweep: two AUVs circling the shark together (mean over "
            f"{sweep_seeds} seeds, fitted clock)",
            "",
            "`filter_m`, `smoother_m`: with the detection curve; `arrivals_only_*`: without; "
            "`clock_known_filter_m`: emission times given, with the detection curve.",
            "",
            "`flyable`: 99 % of the AUVs' 1 s speeds ≤ 2.5 m/s.",
            "",
            frame_markdown(study.sweep),
            "",
        ]
    parts += [f"![bound over time, first seed]({figure})", ""]
    if len(study.plans):
        parts += [
            "## The particle filter on planned geometries (mean over seeds)",
            "",
            "Bounds (fitted clock, detection curve) beside the arrival-time filter run on "
            "the same plans (velocity motion, 60 s smoother lag); "
            "`pf_*after_convergence_m` is the paper's metric (mean error after "
            'convergence). 70 m, 90°, 600 s is the geometry of `steering="formation"`.',
            "",
            frame_markdown(study.plans),
            "",
        ]
    parts += ["## Every run", "", frame_markdown(study.runs), ""]
    if len(study.plans):
        parts += ["### Planned geometries, every run", "", frame_markdown(study.plan_runs), ""]
    return "\n".join(parts)


def write_clock_bound(
    out: Path | str,
    *,
    seeds: int = 3,
    sweep_seeds: int = 2,
    sweep: tuple = SWEEP,
    run_filter: bool = True,
    filter_report: Path | str | None = None,
    particles: int = FILTER_PARTICLES,
    duration: float = DURATION,
) -> Path:
    """Run the bound study and write ``out/clock_bound.md`` and ``out/clock_bound.png``.

    Parameters
    ----------
    out : path
        Folder (created if missing).
    seeds : int
        Scenario seeds ``0 .. seeds - 1`` of the cases and the filter's plans.
    sweep_seeds : int
        Scenario seeds of the planning sweep; 0: no sweep.
    sweep : (radii, lap times, separations in degrees)
        The planning sweep's grid.
    run_filter : bool
        Run the arrival-time filter too.
    filter_report : path, optional
        A clock-aware report whose per-run errors are set beside the bounds; default
        ``out/clock_aware.md``.
    particles : int
        The filter's particles.
    duration : float
        Length of each run (s).

    Returns
    -------
    pathlib.Path
    """
    out = Path(out)
    filter_report = Path(filter_report) if filter_report else out / "clock_aware.md"
    study, seconds, load = run_timed(
        clock_bound_study,
        range(seeds),
        sweep_seeds=range(sweep_seeds),
        sweep=sweep,
        run_filter=run_filter,
        filter_runs=read_filter_errors(filter_report),
        n_particles=particles,
        duration=duration,
    )
    command = (
        f"hmmtrack study clock-bound --seeds {seeds} --sweep-seeds {sweep_seeds} "
        f"--particles {particles} --duration {duration:g}" + ("" if run_filter else " --no-filter")
    )
    out.mkdir(parents=True, exist_ok=True)
    path = out / "clock_bound.md"
    figure = path.with_suffix(".png")
    reading = kept_reading(path)
    text = clock_bound_markdown(
        study, provenance(command, seconds, load), figure.name, str(filter_report), sweep_seeds
    )
    with atomic_files(path, figure) as (markdown, png):
        axes = bound_curves(study.curves)
        axes[0].figure.tight_layout()
        axes[0].figure.savefig(png, dpi=110)
        plt.close(axes[0].figure)
        markdown.write_text(text + ("\n" + reading if reading else ""))
    return path
