"""The two-AUV plan report (``reports/two_auv_plan.md``): the preset on the observable plan.

:func:`write_two_auv_plan` runs :func:`hmmtrack.experiments.two_auv_plan.two_auv_plan_study`
and writes its tables; the filters' throughput is ``benchmarks/bench_two_auv_plan.py``'s.
"""

from __future__ import annotations

from pathlib import Path

from hmmtrack.experiments.clock_runs import DURATION
from hmmtrack.experiments.two_auv_plan import (
    DEFAULT,
    NO_SILENCES,
    PRESET,
    TUNED_FILTER_SEEDS,
    TwoAuvPlanStudy,
    tuned_settings,
    two_auv_plan_study,
)
from hmmtrack.io.outputs import atomic_files
from hmmtrack.report.markdown import frame_markdown
from hmmtrack.report.studies import provenance, run_timed


def settings_lines() -> str:
    """The settings compared, as Markdown list items."""
    return (
        f"- default (the arrival-time defaults, velocity motion): {DEFAULT}\n"
        f"- tuned (`--preset {PRESET}`, hmmtrack/data/presets/{PRESET}.json): "
        f"{tuned_settings()}\n"
        f"- {NO_SILENCES}: the same without the detection curve (missed pings carry no "
        "information), as `hmmtrack track --preset` runs without `--detection-curve 160 40`"
    )


def two_auv_plan_markdown(study: TwoAuvPlanStudy, written_by: str, n_seeds: int) -> str:
    """The report's Markdown: ``written_by`` (the provenance line), the settings, the
    summary and every run."""
    return (
        "# Two AUVs on an observable plan: arrival-time filter against the paper's method\n\n"
        f"{written_by}. Errors in metres, 2 h runs, no initial range "
        "for the arrival-time filter; the paper's range-rate method gets the true initial "
        "ranges and the best constant period, on the same detections. `filtered_m` / "
        "`smoothed_m`: mean error after convergence of the filter and of its 60 s "
        "fixed-lag smoother; `bound_*`: posterior Cramér–Rao bound (RMS from 10 min on).\n\n"
        + settings_lines()
        + f"\n\n## Mean over {n_seeds} seeds (tuned: {len(TUNED_FILTER_SEEDS)} filter "
        "seeds each)\n\n"
        + frame_markdown(study.summary)
        + "\n\n## Every run\n\n"
        + frame_markdown(study.runs)
        + "\n\nThe filters' throughput is measured by "
        "`python benchmarks/bench_two_auv_plan.py`.\n"
    )


def write_two_auv_plan(
    out: Path | str, *, seeds: int = 3, particles: int | None = None, duration: float = DURATION
) -> Path:
    """Run the two-AUV plan study and write ``out/two_auv_plan.md``.

    Parameters
    ----------
    out : path
        Folder (created if missing).
    seeds : int
        Scenario seeds ``0 .. seeds - 1``.
    particles : int, optional
        Replaces every setting's particle count (quick runs).
    duration : float
        Length of each run (s).

    Returns
    -------
    pathlib.Path
    """
    out = Path(out)
    study, seconds, load = run_timed(
        two_auv_plan_study, range(seeds), n_particles=particles, duration=duration
    )
    command = f"hmmtrack study two-auv-plan --seeds {seeds} --duration {duration:g}" + (
        "" if particles is None else f" --particles {particles}"
    )
    out.mkdir(parents=True, exist_ok=True)
    path = out / "two_auv_plan.md"
    with atomic_files(path) as (written,):
        written.write_text(two_auv_plan_markdown(study, provenance(command, seconds, load), seeds))
    return path
