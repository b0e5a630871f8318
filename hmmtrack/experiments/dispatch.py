"""Many trials at once: experiment cells, batches, and their dispatch to an executor.

A :class:`Cell` is a scenario, a motion model and a treatment (loss fraction, depth
correction) with its own seed; :func:`run_trials` runs ``n_trials`` trials of each cell on
any executor of :mod:`hmmtrack.experiments.executors`, a few trials per task so that the scenario is
pickled once per batch. Trial ``k`` of a cell is always seeded with child ``k`` of the
cell's seed, so the results do not depend on the executor, the batching or the order in
which tasks finish. :func:`run_options` spells the settings of a run on local processes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hmmtrack.experiments.executors import get_executor, map_ordered
from hmmtrack.experiments.trials import (
    DEFAULT_PARTICLES,
    PAPER_FILTER,
    TrialResult,
    child_seed,
    run_trial,
)
from hmmtrack.scenarios import Scenario


@dataclass(frozen=True)
class Cell:
    """One cell of an experiment: a scenario, a motion model and a treatment, with its seed.

    Trial ``k`` of the cell is seeded with ``SeedSequence`` child ``k`` of ``seed``;
    ``dataset`` says which synthetic dataset of its scenario ``scenario`` is; with
    ``start_prior`` the particles start in the scenario's ``start_region``
    (:func:`hmmtrack.experiments.trials.track_scenario`); ``filter`` names the filter
    (:data:`hmmtrack.tracking.filter.FILTERS`) and ``measurement`` the measurement
    (:func:`hmmtrack.experiments.trials.track_scenario`).
    """

    scenario: Scenario
    motion: str
    seed: np.random.SeedSequence
    loss_fraction: float = 0.0
    depth_correction: bool = False
    dataset: int = 0
    start_prior: bool = False
    filter: str = PAPER_FILTER
    measurement: str = "range-rate"


@dataclass(frozen=True)
class _Batch:
    """Some trials of one cell, sent to a worker together (one pickled scenario)."""

    cell: Cell
    n_particles: int
    trials: tuple[int, ...]


def _run_batch(batch: _Batch) -> list[TrialResult]:
    cell = batch.cell
    return [
        run_trial(
            cell.scenario,
            cell.motion,
            child_seed(cell.seed, k),
            batch.n_particles,
            trial=k,
            dataset=cell.dataset,
            loss_fraction=cell.loss_fraction,
            depth_correction=cell.depth_correction,
            start_prior=cell.start_prior,
            filter=cell.filter,
            measurement=cell.measurement,
        )
        for k in batch.trials
    ]


def run_trials(
    cells: Sequence[Cell],
    n_trials: int,
    n_particles: int = DEFAULT_PARTICLES,
    *,
    executor: Any = "serial",
    max_workers: int | None = None,
    progress: bool = False,
    batch_size: int = 4,
    description: str | None = None,
) -> list[TrialResult]:
    """Run ``n_trials`` trials of every cell through an executor.

    Parameters
    ----------
    cells : sequence of Cell
    n_trials : int
        Trials per cell.
    n_particles : int
    executor : "serial", "processes", distributed.Client or Executor
        See :func:`hmmtrack.experiments.executors.get_executor`; an executor passed in is not shut
        down.
    max_workers : int, optional
        Local processes (default: all cores).
    progress : bool
        Progress bar over batches.
    batch_size : int
        Trials sent to a worker at once (the scenario is pickled once per batch). Does not
        change the results.
    description : str, optional
        Progress-bar label.

    Returns
    -------
    list of TrialResult
        Cell by cell, trial by trial, whatever executor ran them.
    """
    if n_trials < 1 or batch_size < 1:
        raise ValueError(f"n_trials and batch_size must be positive, got {n_trials}, {batch_size}")
    lean = [replace(cell, scenario=_lean(cell.scenario)) for cell in cells]
    batches = [
        _Batch(cell, int(n_particles), tuple(range(start, min(start + batch_size, n_trials))))
        for cell in lean
        for start in range(0, n_trials, batch_size)
    ]
    pool = get_executor(executor, max_workers)
    try:
        done = map_ordered(pool, _run_batch, batches, progress=progress, description=description)
    finally:
        if pool is not executor:
            pool.shutdown()
    return [result for batch in done for result in batch]


def run_options(
    workers: int, n_particles: int = DEFAULT_PARTICLES, progress: bool = True
) -> dict[str, Any]:
    """Keyword arguments of the studies for a run on this machine.

    Parameters
    ----------
    workers : int
        Local processes; 1 runs the trials serially in this process.
    n_particles : int
    progress : bool

    Returns
    -------
    dict
        ``executor``, ``max_workers``, ``n_particles`` and ``progress`` for
        :func:`run_trials` and the studies (``compare_motion_models(..., **run_options(2))``).
    """
    return {
        "executor": "serial" if workers == 1 else "processes",
        "max_workers": workers,
        "n_particles": n_particles,
        "progress": progress,
    }


def _lean(scenario: Scenario) -> Scenario:
    """The scenario without the tables a tracker never reads (cheaper to send to workers)."""
    return replace(
        scenario,
        pings=scenario.pings.iloc[:0],
        receivers_truth=scenario.receivers_truth.iloc[:0],
    )
