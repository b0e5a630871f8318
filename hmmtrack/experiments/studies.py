"""The paper's studies: datasets, motion-model comparison, loss sweep, depth analysis.

* :func:`paper_scenarios` — the synthetic analogues of the paper's three datasets, each
  from its own child seed (and :func:`truncate` for short runs); :func:`paper_datasets`
  — several synthetic datasets of each;
* :func:`compare_motion_models` — ``n_trials`` filter runs per motion model per dataset;
* :func:`loss_sweep` — detections thinned evenly, HMM model, on the shark pursuit;
* :func:`depth_analysis` — the percent-error curve of ignoring depth, and a diving shark
  tracked with and without the depth correction.

Seed layout (children of the experiment seed): comparison trials ``(0, i, j, k)`` on
dataset 0 and ``(4, i, j, d, k)`` on dataset ``d > 0``, loss sweep ``(1, i, k)``, diving
shark ``(2, 0, k)`` (both variants), datasets ``(3, i)`` (dataset 0) and ``(5, i, d)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from hmmtrack import scenarios
from hmmtrack.experiments.dispatch import Cell, run_trials
from hmmtrack.experiments.tables import trials_table
from hmmtrack.experiments.trials import (
    DEFAULT_PARTICLES,
    MOTIONS,
    PAPER_FILTER,
    child_seed,
    experiment_seed,
)
from hmmtrack.random import SeedLike
from hmmtrack.scenarios import Scenario
from hmmtrack.tracking.measurement import ranging

#: the paper's tag depth (m), the deepest white shark in its tracks
PAPER_DEPTH = 10.7


def truncate(scenario: Scenario, duration: float) -> Scenario:
    """The first ``duration`` seconds of a scenario (for quick runs, tests and notebooks).

    Parameters
    ----------
    scenario : Scenario
    duration : float
        Seconds to keep from ``scenario.start``; longer than the scenario keeps it whole.

    Returns
    -------
    Scenario
        Detections, logged and true receiver positions, truth and pings up to
        ``start + duration`` (moored receivers, whose ``time`` is NaN, are kept); ``end``
        moved there.
    """
    if not duration > 0:
        raise ValueError(f"duration must be positive (s), got {duration!r}")
    end = min(scenario.end, scenario.start + float(duration))

    def upto(table: pd.DataFrame, column: str = "time") -> pd.DataFrame:
        times = table[column].to_numpy(dtype=float)
        return table[np.isnan(times) | (times <= end)].reset_index(drop=True)

    ping_time = next(c for c in ("emission_time", "time") if c in scenario.pings.columns)
    return replace(
        scenario,
        detections=upto(scenario.detections),
        receivers=upto(scenario.receivers),
        receivers_truth=upto(scenario.receivers_truth),
        truth=upto(scenario.truth),
        pings=upto(scenario.pings, ping_time),
        end=end,
    )


#: scenario generators of the paper's three datasets, in the paper's order
PAPER_SCENARIOS = ("stationary_tag", "swimmer", "shark_pursuit")


def paper_scenarios(
    seed: SeedLike,
    names: Sequence[str] = PAPER_SCENARIOS,
    dive: bool = False,
    duration: float | None = None,
) -> dict[str, Scenario]:
    """The synthetic analogues of the paper's datasets, each from its own child seed.

    Parameters
    ----------
    seed : int or SeedSequence
        Experiment seed; dataset ``i`` of :data:`PAPER_SCENARIOS` gets child ``(3, i)``,
        the diving shark child ``(3, 3)``.
    names : sequence of str
        Which of :data:`PAPER_SCENARIOS` to build.
    dive : bool
        Build the diving shark pursuit (``shark_pursuit(dive=True)``) instead; ``names``
        is then ignored and the result has the one key ``"shark_pursuit"``.
    duration : float, optional
        Keep only the first ``duration`` seconds of each (:func:`truncate`).

    Returns
    -------
    dict of str to Scenario
    """
    root = experiment_seed(seed)
    if dive:
        built = {"shark_pursuit": scenarios.shark_pursuit(child_seed(root, 3, 3), dive=True)}
    else:
        unknown = [n for n in names if n not in PAPER_SCENARIOS]
        if unknown:
            raise ValueError(f"unknown scenario(s) {unknown}; expected some of {PAPER_SCENARIOS}")
        built = {
            name: getattr(scenarios, name)(child_seed(root, 3, PAPER_SCENARIOS.index(name)))
            for name in names
        }
    if duration is None:
        return built
    return {name: truncate(scenario, duration) for name, scenario in built.items()}


def paper_datasets(
    seed: SeedLike, n_datasets: int, names: Sequence[str] = PAPER_SCENARIOS
) -> dict[str, list[Scenario]]:
    """``n_datasets`` synthetic datasets of each of the paper's scenarios.

    One dataset per scenario makes a table of filter runs say how the filter varies on
    that dataset, not how it does on the scenario; several datasets separate the two.

    Parameters
    ----------
    seed : int or SeedSequence
        Experiment seed; dataset 0 of scenario ``i`` is :func:`paper_scenarios`'s (child
        ``(3, i)``), dataset ``d > 0`` is drawn from child ``(5, i, d)``.
    n_datasets : int
        Datasets per scenario (at least 1).
    names : sequence of str
        Which of :data:`PAPER_SCENARIOS`.

    Returns
    -------
    dict of str to list of Scenario
        ``n_datasets`` scenarios per name, dataset 0 first.
    """
    if int(n_datasets) != n_datasets or n_datasets < 1:
        raise ValueError(f"n_datasets must be a positive integer, got {n_datasets!r}")
    root = experiment_seed(seed)
    first = paper_scenarios(root, names)
    return {
        name: [first[name]]
        + [
            getattr(scenarios, name)(child_seed(root, 5, PAPER_SCENARIOS.index(name), d))
            for d in range(1, int(n_datasets))
        ]
        for name in names
    }


def _datasets(entry: Scenario | Sequence[Scenario]) -> list[Scenario]:
    """One entry of :func:`compare_motion_models`'s ``scenario_list`` as a list of datasets."""
    return [entry] if isinstance(entry, Scenario) else list(entry)


def _trials_table(
    cells: Sequence[Cell],
    n_trials: int,
    n_particles: int,
    executor: Any,
    max_workers: int | None,
    progress: bool,
    description: str,
) -> pd.DataFrame:
    """:func:`run_trials` on ``cells``, as a trials table (:func:`trials_table`)."""
    results = run_trials(
        cells,
        n_trials,
        n_particles,
        executor=executor,
        max_workers=max_workers,
        progress=progress,
        description=description,
    )
    return trials_table(results)


def compare_motion_models(
    scenario_list: Sequence[Scenario],
    motions: Sequence[str] = MOTIONS,
    n_trials: int = 100,
    seed: SeedLike = 0,
    executor: Any = "serial",
    n_particles: int = DEFAULT_PARTICLES,
    *,
    max_workers: int | None = None,
    progress: bool = False,
    start_prior: bool = False,
    filter: str = PAPER_FILTER,
    measurement: str = "range-rate",
) -> pd.DataFrame:
    """The paper's motion-model comparison: ``n_trials`` filter runs per model per scenario.

    Parameters
    ----------
    scenario_list : sequence of Scenario, or of sequences of Scenario
        E.g. ``paper_scenarios(seed).values()``; an entry that is a sequence holds several
        datasets of one scenario (``paper_datasets(seed, 20).values()``), each tracked
        ``n_trials`` times.
    motions : sequence of str
        Motion models, of :data:`MOTIONS`.
    n_trials : int
        Trials per model per dataset (100 in the paper, which had one dataset per scenario).
    seed : int or SeedSequence
        Experiment seed; trial ``k`` of model ``j`` on scenario ``i`` is seeded with child
        ``(0, i, j, k)`` on its dataset 0 and ``(4, i, j, d, k)`` on dataset ``d > 0``.
    executor, max_workers, progress
        See :func:`run_trials`.
    n_particles : int
    start_prior : bool
        Start the particles in each scenario's ``start_region`` instead of its ``bounds``
        (:func:`hmmtrack.experiments.trials.track_scenario`); the paper's filter does not.
    filter : str
        Named filter of every trial (:data:`hmmtrack.tracking.filter.FILTERS`).
    measurement : str
        Measurement of every trial (:func:`hmmtrack.experiments.trials.track_scenario`).

    Returns
    -------
    pandas.DataFrame
        Trials table (:func:`trials_table`), one row per trial.
    """
    unknown = [m for m in motions if m not in MOTIONS]
    if unknown:
        raise ValueError(f"unknown motion model(s) {unknown}; expected some of {MOTIONS}")
    root = experiment_seed(seed)
    cells = [
        Cell(
            scenario,
            motion,
            child_seed(root, 0, i, j) if d == 0 else child_seed(root, 4, i, j, d),
            dataset=d,
            start_prior=start_prior,
            filter=filter,
            measurement=measurement,
        )
        for i, entry in enumerate(scenario_list)
        for d, scenario in enumerate(_datasets(entry))
        for j, motion in enumerate(motions)
    ]
    return _trials_table(
        cells, n_trials, n_particles, executor, max_workers, progress, "motion-model trials"
    )


#: default loss fractions of the sweep: 0 to 100 % in 5 % steps
LOSS_FRACTIONS = tuple(round(0.05 * i, 2) for i in range(21))


def loss_sweep(
    scenario: Scenario | None = None,
    fractions: Sequence[float] = LOSS_FRACTIONS,
    n_trials: int = 5,
    motion: str = "hmm",
    seed: SeedLike = 0,
    executor: Any = "serial",
    n_particles: int = DEFAULT_PARTICLES,
    *,
    max_workers: int | None = None,
    progress: bool = False,
    start_prior: bool = False,
    filter: str = PAPER_FILTER,
    measurement: str = "range-rate",
) -> pd.DataFrame:
    """The paper's measurement-loss sweep: detections thinned evenly, HMM model.

    Parameters
    ----------
    scenario : Scenario, optional
        Default: the shark pursuit of ``paper_scenarios(seed)``.
    fractions : sequence of float
        Fractions of detections dropped (0–1), with
        :func:`hmmtrack.scenarios.thin_evenly` (0.5 drops every other detection).
    n_trials : int
        Trials per fraction.
    motion : str
    seed : int or SeedSequence
        Trial ``k`` at fraction ``i`` is seeded with child ``(1, i, k)``.
    executor, max_workers, progress, n_particles
        See :func:`run_trials`.
    start_prior : bool
        Start in the scenario's ``start_region`` where it records one
        (:func:`hmmtrack.experiments.trials.track_scenario`).
    filter : str
        Named filter of every trial (:data:`hmmtrack.tracking.filter.FILTERS`).
    measurement : str
        Measurement of every trial (:func:`hmmtrack.experiments.trials.track_scenario`).

    Returns
    -------
    pandas.DataFrame
        Trials table with a ``loss_fraction`` column; summarise with :func:`loss_bands`.
    """
    fractions = [float(f) for f in fractions]
    bad = [f for f in fractions if not 0.0 <= f <= 1.0]
    if bad:
        raise ValueError(f"loss fractions must lie in [0, 1], got {bad}")
    root = experiment_seed(seed)
    if scenario is None:
        scenario = paper_scenarios(root, names=("shark_pursuit",))["shark_pursuit"]
    cells = [
        Cell(
            scenario,
            motion,
            child_seed(root, 1, i),
            loss_fraction=f,
            start_prior=start_prior,
            filter=filter,
            measurement=measurement,
        )
        for i, f in enumerate(fractions)
    ]
    return _trials_table(
        cells, n_trials, n_particles, executor, max_workers, progress, "loss sweep"
    )


@dataclass(frozen=True)
class DepthAnalysis:
    """The paper's depth analysis, and a diving shark tracked with and without correction.

    Attributes
    ----------
    depth : float
        Tag depth of the percent-error curve (m).
    ranges : numpy.ndarray, shape (n,)
        Measured (slant) ranges (m).
    percent_error : numpy.ndarray, shape (n,)
        ``100·(r − r_2D)/r_2D`` at those ranges (%).
    max_depth : float
        Deepest point of the diving shark (m).
    depth_profile : (time, depth)
        The diving shark's depth against time since the start (s, m), shape (T,) each.
    trials : pandas.DataFrame or None
        Trials table of the diving shark, ``depth_correction`` False and True.
    """

    depth: float
    ranges: np.ndarray
    percent_error: np.ndarray
    max_depth: float = float("nan")
    depth_profile: tuple[np.ndarray, np.ndarray] | None = None
    trials: pd.DataFrame | None = None


def depth_analysis(
    n_trials: int = 10,
    seed: SeedLike = 0,
    executor: Any = "serial",
    n_particles: int = DEFAULT_PARTICLES,
    *,
    depth: float = PAPER_DEPTH,
    ranges: np.ndarray | None = None,
    motion: str = "hmm",
    duration: float | None = None,
    max_workers: int | None = None,
    progress: bool = False,
    start_prior: bool = False,
    filter: str = PAPER_FILTER,
    measurement: str = "range-rate",
) -> DepthAnalysis:
    """Percent-error curve of ignoring depth, and the diving shark with and without correction.

    Parameters
    ----------
    n_trials : int
        Trials of the diving shark per variant (0 skips the filter runs).
    seed : int or SeedSequence
        The diving shark is ``paper_scenarios(seed, dive=True)``; trial ``k`` is seeded with
        child ``(2, 0, k)`` both without and with the correction, so the two variants are
        paired: same detections, same filter draws.
    executor, max_workers, progress, n_particles
        See :func:`run_trials`.
    depth : float
        Depth of the percent-error curve (m); the paper's 10.7 m.
    ranges : numpy.ndarray, optional
        Slant ranges of the curve (m); default every metre from just below ``depth`` + 1 to
        200 m, which includes the paper's 20, 50 and 100 m.
    motion : str
    duration : float, optional
        Track only the first ``duration`` seconds of the diving shark (:func:`truncate`).
    start_prior : bool
        Start in the diving shark's ``start_region`` where it records one
        (:func:`hmmtrack.experiments.trials.track_scenario`).
    filter : str
        Named filter of every trial (:data:`hmmtrack.tracking.filter.FILTERS`).
    measurement : str
        Measurement of every trial (:func:`hmmtrack.experiments.trials.track_scenario`).

    Returns
    -------
    DepthAnalysis
    """
    if ranges is None:
        ranges = np.arange(np.floor(depth) + 1.0, 201.0)
    ranges = np.asarray(ranges, dtype=float)
    percent = ranging.depth_percent_error(ranges, depth)
    if n_trials == 0:
        return DepthAnalysis(depth=depth, ranges=ranges, percent_error=percent)
    root = experiment_seed(seed)
    diving = paper_scenarios(root, dive=True, duration=duration)["shark_pursuit"]
    cells = [
        Cell(
            diving,
            motion,
            child_seed(root, 2, 0),
            depth_correction=correct,
            start_prior=start_prior,
            filter=filter,
            measurement=measurement,
        )
        for correct in (False, True)
    ]
    trials = _trials_table(
        cells, n_trials, n_particles, executor, max_workers, progress, "diving shark"
    )
    truth = diving.truth
    elapsed = truth["time"].to_numpy(dtype=float) - float(truth["time"].iloc[0])
    profile = truth["depth"].to_numpy(dtype=float)
    return DepthAnalysis(
        depth=depth,
        ranges=ranges,
        percent_error=percent,
        max_depth=float(profile.max()),
        depth_profile=(elapsed, profile),
        trials=trials,
    )
