"""``hmmtrack reproduce``: datasets, experiments, figures, trial tables and summary in one call.

:func:`reproduce` runs the studies of :mod:`hmmtrack.experiments` at a :class:`RunSize`
(:data:`FULL`, the paper's scale, or :data:`QUICK`), saves every figure with
:func:`save_figures` (each drawn by a :mod:`hmmtrack.plots` function) and writes
``summary.md`` with :func:`hmmtrack.report.summary.write_summary`.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from hmmtrack.experiments import (
    DEFAULT_PARTICLES,
    LOSS_FRACTIONS,
    MOTIONS,
    compare_motion_models,
    depth_analysis,
    example_run,
    loss_sweep,
    paper_datasets,
)
from hmmtrack.experiments.executors import default_workers, get_executor
from hmmtrack.io.outputs import staged_folder
from hmmtrack.plots import results as plots
from hmmtrack.plots.experiments import plot_scenario
from hmmtrack.report.paper import PAPER, dataset_name
from hmmtrack.report.summary import write_summary
from hmmtrack.scenarios import white_shark_tracks
from hmmtrack.scenarios.historical import WHITE_SHARK_TRACKS_SEED
from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm, prepare_white_shark_tracks
from hmmtrack.tracking.filter import FILTERS


@dataclass(frozen=True)
class RunSize:
    """How big a reproduction run is.

    Attributes
    ----------
    n_trials : int
        Filter runs per motion model per synthetic dataset.
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
    n_datasets : int
        Synthetic datasets per scenario in the motion-model comparison
        (:func:`hmmtrack.experiments.paper_datasets`); the loss sweep, the diving shark and
        the example runs use dataset 0.
    """

    n_trials: int
    loss_fractions: tuple[float, ...]
    loss_trials: int
    depth_trials: int
    n_particles: int
    shark_tracks_sharks: int | None = None
    n_datasets: int = 1


#: the paper-scale run: the paper's 100 trials per model per scenario, spread over 50
#: synthetic datasets × 2 filter runs (900 comparison trials), plus the loss sweep and 50
#: paired trials of the diving shark. The spread between datasets dominates a cell's
#: figures, so more datasets and fewer runs each estimate them with less spread, and two
#: runs a dataset still measure the spread between runs (reports/decisions.md, "The
#: reproduction's design")
FULL = RunSize(2, LOSS_FRACTIONS, 5, 50, DEFAULT_PARTICLES, n_datasets=50)
#: a first try: a few trials of everything, about 1.5 minutes on two quiet cores
QUICK = RunSize(1, (0.0, 0.25, 0.5, 0.75, 0.9, 1.0), 1, 1, 300, shark_tracks_sharks=3, n_datasets=2)

FIGURE_DPI = 100

logger = logging.getLogger(__name__)


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
    figures = {}
    fig, axes = plt.subplots(1, len(datasets), figsize=(5 * len(datasets), 4.5))
    for ax, scenario in zip(np.atleast_1d(axes), datasets.values(), strict=True):
        plot_scenario(scenario, ax=ax)
        ax.set_title(dataset_name(scenario.name) + " analogue")
    fig.tight_layout()
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
    n_datasets: int | None = None,
    seed: int = 0,
    executor: Any = "processes",
    max_workers: int | None = None,
    progress: bool = False,
    filter: str = "mode-keeping",
    start_prior: bool = True,
    measurement: str = "range-rate-gps",
) -> Path:
    """Rerun the paper's experiments and write the figures, trial tables and summary.

    Parameters
    ----------
    out : str or Path
        Output folder, created in a folder that must exist. The run is built in a temporary
        sibling folder and moved into ``out`` at the end, under a lock against a concurrent
        run into the same folder (:func:`hmmtrack.io.outputs.staged_folder`): a failed or
        interrupted run leaves ``out`` as it was.
    quick : bool
        :data:`QUICK` instead of :data:`FULL`.
    n_trials, n_particles, n_datasets : int, optional
        Override the run size's filter runs per model per dataset, particles and synthetic
        datasets per scenario.
    seed : int
        Experiment seed (datasets and trials derive from it).
    executor, max_workers, progress
        See :func:`hmmtrack.experiments.run_trials`.
    filter : str
        The filter every run uses, by name (:data:`hmmtrack.tracking.filter.FILTERS`):
        ``"mode-keeping"`` (default) or the paper's (``"paper"``); the summary says which.
    start_prior : bool
        Start each run in its scenario's ``start_region`` where it records one (the swimmer's
        and the shark pursuit's: where the field team knows the tag to be at the start),
        without acquisition there (:func:`hmmtrack.experiments.trials.track_scenario`);
        False starts in the whole search box, as the paper does. ``filter="paper",
        start_prior=False`` is the paper's algorithm. The defaults are the configuration
        that met the paper's errors at every experiment seed (``reports/decisions.md``,
        issue 13).
    measurement : str
        The measurement of every run: the receivers' GPS error as an offset correlated in
        time, integrated out per particle (``"range-rate-gps"``, default,
        :mod:`hmmtrack.tracking.measurement.gps_offset`), or the paper's (``"range-rate"``:
        a 5 m range sd stands for that error); the summary says which. The default is the
        measurement whose 95 % regions held the truth in 90-98 % of seconds in the most
        cells at held-out experiment seeds (``reports/decisions.md``, issue 13).

    Returns
    -------
    Path
        ``out/summary.md``. Beside it: the PNG figures, ``motion_model_trials.csv``,
        ``loss_sweep_trials.csv`` and ``depth_trials.csv``.
    """
    size = QUICK if quick else FULL
    size = replace(
        size,
        n_trials=n_trials or size.n_trials,
        n_particles=n_particles or size.n_particles,
        n_datasets=n_datasets or size.n_datasets,
    )
    out = Path(out)
    with staged_folder(out, last="summary.md") as stage:
        _run(
            stage,
            size,
            quick=quick,
            seed=seed,
            executor=executor,
            max_workers=max_workers,
            progress=progress,
            filter=filter,
            start_prior=start_prior,
            measurement=measurement,
        )
    return out / "summary.md"


def _run(
    out: Path,
    size: RunSize,
    *,
    quick: bool,
    seed: int,
    executor: Any,
    max_workers: int | None,
    progress: bool,
    filter: str,
    start_prior: bool,
    measurement: str,
) -> None:
    """The run of :func:`reproduce` at ``size``, its files written into ``out``."""
    clock = time.perf_counter()
    all_datasets = paper_datasets(seed, size.n_datasets)
    datasets = {name: versions[0] for name, versions in all_datasets.items()}
    common = {
        "seed": seed,
        "n_particles": size.n_particles,
        "progress": progress,
        "filter": filter,
        "start_prior": start_prior,
        "measurement": measurement,
    }
    pool = get_executor(executor, max_workers)
    try:
        logger.info(
            "motion-model comparison: %d trials",
            len(datasets) * size.n_datasets * len(MOTIONS) * size.n_trials,
        )
        comparison = compare_motion_models(
            list(all_datasets.values()), n_trials=size.n_trials, executor=pool, **common
        )
        logger.info("loss sweep: %d trials", len(size.loss_fractions) * size.loss_trials)
        loss = loss_sweep(
            datasets["shark_pursuit"],
            fractions=size.loss_fractions,
            n_trials=size.loss_trials,
            executor=pool,
            **common,
        )
        logger.info("diving shark: %d trials", 2 * size.depth_trials)
        depth = depth_analysis(n_trials=size.depth_trials, executor=pool, **common)
    finally:
        if pool is not executor:
            pool.shutdown()
    logger.info("example runs and figures")
    examples = {
        scenario.name: example_run(
            scenario,
            seed,
            size.n_particles,
            filter=filter,
            start_prior=start_prior,
            measurement=measurement,
        )
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
        "filter": f"{filter} ({_switches(filter)})",
        "measurement": measurement,
        "start": "the scenario's start region where it records one, without acquisition there"
        if start_prior
        else "the whole search box (the paper's)",
        "size": "quick" if quick else "paper scale",
        "synthetic datasets per scenario": size.n_datasets,
        "filter runs per model per dataset": size.n_trials,
        "particles": size.n_particles,
        "loss fractions": len(size.loss_fractions),
        "trials per loss fraction": size.loss_trials,
        "diving-shark trials per variant": size.depth_trials,
        "executor": type(pool).__name__
        + (f" ({max_workers or default_workers()} workers)" if executor == "processes" else ""),
        "wall time": f"{time.perf_counter() - clock:.0f} s",
        "machine load (1-min average) at the end": f"{os.getloadavg()[0]:.1f}",
    }
    write_summary(
        out / "summary.md", comparison=comparison, loss=loss, depth=depth, figures=figures, run=run
    )


def _switches(filter: str) -> str:
    """What the named filter does, in words (for the summary's run line)."""
    on = [key for key, value in FILTERS[filter].items() if value]
    return "the paper's filter" if not on else " + ".join(on)
