"""The reproduction report: our results beside the paper's, and whether its findings hold.

* :data:`PAPER` — every number the paper's "Results" section quotes;
* :func:`check_findings` — the paper's qualitative claims, each tested on our tables;
* :func:`write_summary` — ``reports/summary.md``: the motion-model table, the loss bands,
  the depth analysis, the findings and the figures, with a plain statement that the data
  are synthetic analogues of the paper's;
* :func:`save_figures` — lays out the report figures, drawn by the ``hmmtrack.plots``
  functions, and saves them as PNG;
* :func:`reproduce` — the whole pipeline behind ``hmmtrack reproduce``: datasets, the
  experiments of :mod:`hmmtrack.experiments`, figures, trial tables and summary.

This module orchestrates, formats and judges; the trials are run by
:mod:`hmmtrack.experiments` and every figure is drawn by a plotting function.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from hmmtrack.executors import get_executor
from hmmtrack.experiments import (
    DEFAULT_PARTICLES,
    LOSS_BANDS,
    LOSS_FRACTIONS,
    MOTIONS,
    compare_motion_models,
    depth_analysis,
    example_run,
    loss_bands,
    loss_sweep,
    paper_scenarios,
    summarise_trials,
)
from hmmtrack.scenarios import white_shark_tracks
from hmmtrack.scenarios.historical import WHITE_SHARK_TRACKS_SEED
from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm, prepare_white_shark_tracks

__all__ = [
    "PAPER",
    "FULL",
    "QUICK",
    "Finding",
    "RunSize",
    "check_findings",
    "reproduce",
    "save_figures",
    "write_summary",
]

#: the paper's numbers, keyed by our scenario names (hmmtrack.scenarios)
PAPER = {
    "datasets": {
        "stationary-tag": "Long Beach",
        "swimmer": "Santa Elena Bay",
        "shark-pursuit": "Simulated (shark pursuit)",
    },
    # average error after convergence (the paper's "RMSE"), m
    "error": {
        "stationary-tag": {"baseline": 5.42, "velocity": 4.44, "hmm": 6.11},
        "swimmer": {"baseline": 11.22, "velocity": 12.31, "hmm": 8.78},
        "shark-pursuit": {"baseline": 970.46, "velocity": 30.77, "hmm": 13.62},
    },
    # average time to convergence, s (quoted for Santa Elena Bay only)
    "convergence": {"swimmer": {"baseline": 27.0, "velocity": 40.0, "hmm": 180.0}},
    # measurement-loss bands on the simulated dataset, HMM model
    "loss_bands": pd.DataFrame(
        {
            "convergence_mean": [43.8, 71.4, 1342.0],
            "convergence_max": [129.0, 249.0, 6785.0],
            "error_mean": [15.07, 37.68, 391.61],
            "error_max": [23.18, 61.24, 1835.55],
        },
        index=list(LOSS_BANDS),
    ),
    # percent error of a slant range taken as horizontal, tag at 10.7 m: range m -> %
    "depth_percent_error": {20.0: 18.4, 50.0: 2.4, 100.0: 0.6},
}

#: an error after convergence above this is "diverged" (m): ten convergence thresholds
DIVERGED_ERROR = 100.0


@dataclass(frozen=True)
class Finding:
    """One of the paper's qualitative claims, tested on our results.

    Attributes
    ----------
    claim : str
        The claim, in the paper's words.
    holds : bool or None
        Whether our results support it; ``None`` when the data to test it are missing.
    evidence : str
        The numbers the verdict rests on.
    """

    claim: str
    holds: bool | None
    evidence: str


def _fmt(value: float, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    return f"{value:.{digits}g}" if abs(value) < 10**digits else f"{value:.0f}"


def _paper(value: float) -> str:
    """A number of the paper, as the paper prints it."""
    return "–" if math.isnan(value) else f"{value:g}"


def _markdown_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _cell(summary: pd.DataFrame, scenario: str, motion: str) -> pd.Series | None:
    rows = summary[(summary["scenario"] == scenario) & (summary["motion"] == motion)]
    return None if rows.empty else rows.iloc[0]


def check_findings(
    comparison: pd.DataFrame | None,
    loss: pd.DataFrame | None,
    depth_trials: pd.DataFrame | None = None,
) -> list[Finding]:
    """Test the paper's qualitative findings on our trials tables.

    Parameters
    ----------
    comparison : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.compare_motion_models`.
    loss : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.loss_sweep`.
    depth_trials : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.depth_analysis` (``depth_correction`` column).

    Returns
    -------
    list of Finding
        Shark pursuit: the HMM model has the lowest error; the baseline diverges (mean error
        after convergence above :data:`DIVERGED_ERROR`); loss: usable up to 80 % (the
        20–80 % band converges in at least 90 % of trials with a mean error below
        :data:`DIVERGED_ERROR`) and robust below 20 %; depth: the correction lowers the
        error on a diving shark.
    """
    findings = []
    summary = None if comparison is None else summarise_trials(comparison)
    cells = {} if summary is None else {m: _cell(summary, "shark-pursuit", m) for m in MOTIONS}
    if all(c is not None for c in cells.values()) and cells:
        errors = {m: float(c["mean_error_after_convergence"]) for m, c in cells.items()}
        evidence = ", ".join(f"{m} {_fmt(e)} m" for m, e in errors.items())
        findings.append(
            Finding(
                "Shark pursuit: the HMM motion model has the lowest error after convergence.",
                min(errors, key=errors.get) == "hmm",
                f"mean error after convergence: {evidence}",
            )
        )
        shark = comparison[comparison["scenario"] == "shark-pursuit"]
        share = {
            m: float(np.mean(g["mean_error_after_convergence"] > DIVERGED_ERROR))
            for m, g in shark.groupby("motion")
        }
        findings.append(
            Finding(
                "Shark pursuit: the baseline (random-walk) model diverges.",
                errors["baseline"] > DIVERGED_ERROR and errors["baseline"] > 5 * errors["hmm"],
                f"baseline mean error {_fmt(errors['baseline'])} m vs HMM {_fmt(errors['hmm'])} m; "
                "share of trials with error above "
                f"{DIVERGED_ERROR:g} m: "
                + ", ".join(f"{m} {100 * share.get(m, math.nan):.0f} %" for m in MOTIONS),
            )
        )
    else:
        findings.append(
            Finding(
                "Shark pursuit: HMM lowest error, baseline diverges.",
                None,
                "no shark-pursuit trials of all three models",
            )
        )
    if loss is not None and len(loss):
        bands = loss_bands(loss)
        mid = bands.loc[LOSS_BANDS[1]]
        usable = (
            mid["n_trials"] > 0
            and mid["n_converged"] >= 0.9 * mid["n_trials"]
            and mid["error_mean"] < DIVERGED_ERROR
        )
        findings.append(
            Finding(
                "The filter stays usable up to 80 % measurement loss.",
                bool(usable),
                f"20–80 % band: {int(mid['n_converged'])}/{int(mid['n_trials'])} trials converged, "
                f"mean error after convergence {_fmt(mid['error_mean'])} m "
                f"(max {_fmt(mid['error_max'])} m), mean time to convergence "
                f"{_fmt(mid['convergence_mean'])} s",
            )
        )
        low, high = bands.loc[LOSS_BANDS[0]], bands.loc[LOSS_BANDS[2]]
        findings.append(
            Finding(
                "Below 20 % loss the filter is robust; above 80 % error and convergence time grow "
                "drastically.",
                bool(
                    low["error_mean"] <= mid["error_mean"]
                    and high["error_mean"] > mid["error_mean"]
                    and high["convergence_mean"] > low["convergence_mean"]
                ),
                "mean error after convergence by band: "
                + ", ".join(f"{b} {_fmt(bands.loc[b, 'error_mean'])} m" for b in LOSS_BANDS)
                + "; mean time to convergence: "
                + ", ".join(f"{b} {_fmt(bands.loc[b, 'convergence_mean'])} s" for b in LOSS_BANDS),
            )
        )
    if depth_trials is not None and len(depth_trials):
        by = depth_trials.groupby("depth_correction")["mean_error_after_convergence"].mean()
        if {True, False} <= set(by.index):
            findings.append(
                Finding(
                    "Correcting ranges with the tag's depth removes the error a deep dive causes.",
                    bool(by[True] < by[False]),
                    f"diving shark, mean error after convergence: without correction "
                    f"{_fmt(by[False])} m, with correction {_fmt(by[True])} m",
                )
            )
    return findings


def _comparison_section(comparison: pd.DataFrame) -> str:
    summary = summarise_trials(comparison)
    rows = []
    for _, cell in summary.iterrows():
        scenario, motion = cell["scenario"], cell["motion"]
        paper_error = PAPER["error"].get(scenario, {}).get(motion, math.nan)
        paper_tc = PAPER["convergence"].get(scenario, {}).get(motion, math.nan)
        rows.append(
            [
                PAPER["datasets"].get(scenario, scenario),
                motion,
                _fmt(cell["mean_error_after_convergence"]),
                _paper(paper_error),
                _fmt(cell["median_error_after_convergence"]),
                _fmt(cell["rmse_after_convergence"]),
                _fmt(cell["time_to_convergence"]),
                _paper(paper_tc),
                f"{int(cell['n_converged'])}/{int(cell['n_trials'])}",
            ]
        )
    headers = [
        "dataset",
        "motion model",
        "mean error after conv. (m)",
        "paper (m)",
        "median (m)",
        "true RMSE after conv. (m)",
        "time to conv. (s)",
        "paper (s)",
        "converged",
    ]
    return (
        "## Motion-model comparison\n\n"
        'Per trial: the paper\'s "RMSE" (the *mean* position error from convergence to the '
        "end), the true root-mean-square error over the same span, and the time until "
        "√λ₁ < 10 m. Table: means over trials (time to convergence over converged trials; "
        "a trial that never converges is scored over its whole run, as the paper does).\n\n"
        + _markdown_table(headers, rows)
        + "\n"
    )


def _loss_section(loss: pd.DataFrame) -> str:
    ours, paper = loss_bands(loss), PAPER["loss_bands"]
    rows = [
        [
            band,
            f"{int(ours.loc[band, 'n_converged'])}/{int(ours.loc[band, 'n_trials'])}",
            *(f"{_fmt(ours.loc[band, c])} ({_paper(paper.loc[band, c])})" for c in paper.columns),
        ]
        for band in LOSS_BANDS
    ]
    fractions = np.unique(loss["loss_fraction"])
    per_fraction = len(loss) // max(len(fractions), 1)
    return (
        "## Measurement loss (shark pursuit, HMM model)\n\n"
        f"Detections thinned evenly at {len(fractions)} fractions from "
        f"{100 * fractions.min():.0f} % to {100 * fractions.max():.0f} % dropped, "
        f"{per_fraction} trials each. Ours (paper); statistics over converged trials.\n\n"
        + _markdown_table(
            [
                "band dropped",
                "converged",
                "mean conv. (s)",
                "max conv. (s)",
                "mean error (m)",
                "max error (m)",
            ],
            rows,
        )
        + "\n"
    )


def _depth_section(depth) -> str:
    paper = PAPER["depth_percent_error"]
    ours = dict(zip(depth.ranges, depth.percent_error, strict=True))
    rows = [[f"{r:g}", f"{ours.get(r, math.nan):.2f}", _paper(p)] for r, p in paper.items()]
    text = (
        "## Depth\n\n"
        f"Percent error of taking a slant range as horizontal, tag at {depth.depth:g} m:\n\n"
        + _markdown_table(["range (m)", "ours (%)", "paper (%)"], rows)
        + "\n"
    )
    if depth.trials is not None and len(depth.trials):
        summary = summarise_trials(depth.trials, by=("depth_correction",))
        rows = [
            [
                "with" if c["depth_correction"] else "without",
                _fmt(c["mean_error_after_convergence"]),
                _fmt(c["rmse_after_convergence"]),
                _fmt(c["time_to_convergence"]),
                f"{int(c['n_converged'])}/{int(c['n_trials'])}",
            ]
            for _, c in summary.iterrows()
        ]
        text += (
            f"\nDiving shark (max depth {depth.max_depth:.0f} m, depth-sensor tag), HMM "
            "model, with and without the depth correction (not in the paper, which only "
            "argues the correction):\n\n"
            + _markdown_table(
                [
                    "depth correction",
                    "mean error after conv. (m)",
                    "true RMSE (m)",
                    "time to conv. (s)",
                    "converged",
                ],
                rows,
            )
            + "\n"
        )
    return text


def write_summary(
    path: str | Path,
    *,
    comparison: pd.DataFrame | None = None,
    loss: pd.DataFrame | None = None,
    depth=None,
    figures: Mapping[str, str] | None = None,
    run: Mapping[str, object] | None = None,
) -> Path:
    """Write the reproduction summary as Markdown.

    Parameters
    ----------
    path : str or Path
        Output file (``reports/summary.md``); its folder is created.
    comparison, loss : pandas.DataFrame, optional
        Trials tables of :func:`hmmtrack.experiments.compare_motion_models` and
        :func:`hmmtrack.experiments.loss_sweep`.
    depth : hmmtrack.experiments.DepthAnalysis, optional
    figures : mapping of caption to file name, optional
        PNGs beside the summary, embedded in this order.
    run : mapping, optional
        Run parameters (seed, trials, particles, executor, wall time...), listed verbatim.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    parts = [
        "# hmmtrack: reproduction of the paper's results\n",
        "**The datasets are synthetic analogues, not the paper's data.** The Long Beach, "
        "Santa Elena Bay and white-shark field data are not public; `hmmtrack.scenarios` "
        "simulates datasets shaped like them (a stationary tag with one hydrophone on an AUV "
        "stepping away; a swimmer-carried tag between two drifting boats; a 150-min shark "
        "pursuit by two hydrophones with distance-dependent ping loss) and the white-shark "
        "HMM is fitted to synthetic tracks. Agreement is expected in kind, not digit for "
        "digit.\n",
    ]
    if run:
        parts.append("Run: " + "; ".join(f"{k} = {v}" for k, v in run.items()) + ".\n")
    findings = check_findings(comparison, loss, None if depth is None else depth.trials)
    verdict = {True: "holds", False: "does not hold", None: "not tested"}
    parts.append(
        "## The paper's findings on our analogues\n\n"
        + "\n".join(f"- **{verdict[f.holds]}** — {f.claim} ({f.evidence})" for f in findings)
        + "\n"
    )
    if comparison is not None and len(comparison):
        parts.append(_comparison_section(comparison))
    if loss is not None and len(loss):
        parts.append(_loss_section(loss))
    if depth is not None:
        parts.append(_depth_section(depth))
    if figures:
        parts.append(
            "## Figures\n\n"
            + "\n\n".join(
                f"**{caption}**\n\n![{caption}]({name})" for caption, name in figures.items()
            )
            + "\n"
        )
    path.write_text("\n".join(parts))
    return path


@dataclass(frozen=True)
class RunSize:
    """How big a reproduction run is.

    Attributes
    ----------
    n_trials : int
        Trials per motion model per dataset (the paper's 100).
    loss_fractions : tuple of float
        Fractions of detections dropped in the loss sweep (0–1).
    loss_trials : int
        Trials per loss fraction.
    depth_trials : int
        Diving-shark trials per variant (with / without depth correction).
    n_particles : int
    shark_tracks_sharks : int or None
        Sharks of the bundled synthetic white-shark tracks drawn under the HMM's densities
        (``None``: all 22).
    """

    n_trials: int
    loss_fractions: tuple[float, ...]
    loss_trials: int
    depth_trials: int
    n_particles: int
    shark_tracks_sharks: int | None = None


#: the paper-scale run (900 comparison trials plus the loss sweep and the diving shark)
FULL = RunSize(100, LOSS_FRACTIONS, 5, 10, DEFAULT_PARTICLES)
#: a first try: a few trials of everything, under a minute on two cores
QUICK = RunSize(2, (0.0, 0.25, 0.5, 0.75, 0.9, 1.0), 1, 1, 300, shark_tracks_sharks=3)

#: how the particle snapshots of the example trials are spaced: seconds after the start
SNAPSHOT_FRACTIONS = (0.0, 0.01, 0.03, 0.3, 1.0)

FIGURE_DPI = 100


def _save(fig, out: Path, name: str) -> str:
    fig.savefig(out / name, dpi=FIGURE_DPI, bbox_inches="tight")
    plt.close(fig)
    return name


def save_figures(
    out: Path,
    *,
    comparison: pd.DataFrame,
    loss: pd.DataFrame,
    depth,
    datasets: Mapping[str, object],
    examples: Mapping[str, object],
    shark_tracks: pd.DataFrame,
) -> dict[str, str]:
    """Draw and save every report figure as PNG in ``out``.

    Parameters
    ----------
    out : Path
        Folder (must exist).
    comparison, loss : pandas.DataFrame
        Trials tables of the motion-model comparison and the loss sweep.
    depth : hmmtrack.experiments.DepthAnalysis
    datasets : mapping of str to Scenario
        The paper's three datasets.
    examples : mapping of str to hmmtrack.experiments.ExampleRun
        One HMM-model run per dataset with particle snapshots, for the error-over-time
        figures.
    shark_tracks : pandas.DataFrame
        Prepared synthetic white-shark tracks (``speed``, ``angular_velocity``), drawn under
        the bundled HMM's densities.

    Returns
    -------
    dict of str to str
        Caption → file name, in reading order.
    """
    from hmmtrack.plots import results as plots
    from hmmtrack.plots.experiments import plot_scenario

    figures = {}
    fig, axes = plt.subplots(1, len(datasets), figsize=(5 * len(datasets), 4.5))
    for ax, scenario in zip(np.atleast_1d(axes), datasets.values(), strict=True):
        plot_scenario(scenario, ax=ax)
        ax.set_title(PAPER["datasets"].get(scenario.name, scenario.name) + " analogue")
    figures["Dataset overviews (synthetic analogues)"] = _save(fig, out, "datasets.png")

    fig = plots.motion_hmm_figure(load_white_shark_hmm(), shark_tracks)
    figures["State-dependent densities of the bundled white-shark HMM"] = _save(
        fig, out, "white_shark_hmm.png"
    )

    fig = plots.comparison_figure(comparison, titles=PAPER["datasets"])
    figures["Error after convergence and time to convergence per motion model"] = _save(
        fig, out, "motion_model_comparison.png"
    )

    for name, example in examples.items():
        fig = plots.example_figure(example)
        figures[f"One HMM-model trial on {PAPER['datasets'].get(name, name)}"] = _save(
            fig, out, f"example_{name}.png"
        )

    fig = plots.loss_figure(loss, PAPER["loss_bands"])
    figures["Measurement loss: time to convergence and error after convergence"] = _save(
        fig, out, "measurement_loss.png"
    )

    fig = plots.depth_figure(depth, PAPER["depth_percent_error"])
    figures["Depth: percent error of ignoring depth; diving shark with and without correction"] = (
        _save(fig, out, "depth.png")
    )
    return figures


def _shark_tracks(n_sharks: int | None) -> pd.DataFrame:
    """The bundled synthetic white-shark tracks (or their first sharks), prepared as for the
    fit of the bundled HMM."""
    tracks = white_shark_tracks(WHITE_SHARK_TRACKS_SEED)
    if n_sharks is not None:
        tracks = tracks[tracks["id"].isin(pd.unique(tracks["id"])[:n_sharks])]
    return prepare_white_shark_tracks(tracks)


def reproduce(
    out: str | Path = "reports",
    *,
    quick: bool = False,
    n_trials: int | None = None,
    n_particles: int | None = None,
    seed: int = 0,
    executor: Any = "processes",
    max_workers: int | None = None,
    progress: bool = False,
) -> Path:
    """Rerun the paper's experiments and write the figures, trial tables and summary.

    Parameters
    ----------
    out : str or Path
        Output folder; created.
    quick : bool
        :data:`QUICK` instead of :data:`FULL`.
    n_trials, n_particles : int, optional
        Override the run size's trials per model per dataset and particles.
    seed : int
        Experiment seed (datasets and trials derive from it).
    executor, max_workers, progress
        See :func:`hmmtrack.experiments.run_trials`.

    Returns
    -------
    Path
        ``out/summary.md``. Beside it: the PNG figures, ``motion_model_trials.csv``,
        ``loss_sweep_trials.csv`` and ``depth_trials.csv``.
    """
    size = QUICK if quick else FULL
    size = replace(
        size, n_trials=n_trials or size.n_trials, n_particles=n_particles or size.n_particles
    )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    clock = time.perf_counter()
    datasets = paper_scenarios(seed)
    common = {"seed": seed, "n_particles": size.n_particles, "progress": progress}
    pool = get_executor(executor, max_workers)
    try:
        comparison = compare_motion_models(
            list(datasets.values()), n_trials=size.n_trials, executor=pool, **common
        )
        loss = loss_sweep(
            datasets["shark_pursuit"],
            fractions=size.loss_fractions,
            n_trials=size.loss_trials,
            executor=pool,
            **common,
        )
        depth = depth_analysis(n_trials=size.depth_trials, executor=pool, **common)
    finally:
        if pool is not executor:
            pool.shutdown()
    examples = {
        scenario.name: example_run(scenario, seed, size.n_particles)
        for scenario in datasets.values()
    }
    comparison.to_csv(out / "motion_model_trials.csv", index=False)
    loss.to_csv(out / "loss_sweep_trials.csv", index=False)
    depth.trials.to_csv(out / "depth_trials.csv", index=False)
    figures = save_figures(
        out,
        comparison=comparison,
        loss=loss,
        depth=depth,
        datasets=datasets,
        examples=examples,
        shark_tracks=_shark_tracks(size.shark_tracks_sharks),
    )
    run = {
        "seed": seed,
        "size": "quick" if quick else "paper scale",
        "trials per model per dataset": size.n_trials,
        "particles": size.n_particles,
        "loss fractions": len(size.loss_fractions),
        "trials per loss fraction": size.loss_trials,
        "diving-shark trials per variant": size.depth_trials,
        "executor": type(pool).__name__,
        "wall time": f"{time.perf_counter() - clock:.0f} s",
    }
    return write_summary(
        out / "summary.md", comparison=comparison, loss=loss, depth=depth, figures=figures, run=run
    )
