"""Monte Carlo experiments of the paper's "Results" section.

* :func:`run_trial` — one particle-filter run on a scenario with one motion model, scored
  with :mod:`hmmtrack.metrics` (time to convergence, the paper's "RMSE", which is a mean
  error after convergence, and the true RMSE after convergence);
* :func:`compare_motion_models` — many trials per motion model per scenario (the paper's
  300 trials per dataset), as a tidy table;
* :func:`loss_sweep` and :func:`loss_bands` — detections thinned evenly from 0 to 100 %
  on the shark pursuit, summarised in the paper's bands (<20 %, 20–80 %, >80 %);
* :func:`depth_analysis` — the paper's percent-error curve of ignoring depth, and a
  diving shark tracked with and without the depth correction.

Seeding: one experiment seed becomes a :class:`numpy.random.SeedSequence`; the scenario
datasets and the trials get children of it by ``SeedSequence.spawn`` (scenario ``i``,
motion ``j``, trial ``k`` always get the same child), so a table does not depend on the
executor, on the order in which trials finish, or on how they are batched, and asking
for more trials only appends rows.

Trials are dispatched through :mod:`hmmtrack.executors` (serial, local processes or a Dask
cluster). This module computes results; it draws nothing (see
:mod:`hmmtrack.plots.results`) and writes no files (see :mod:`hmmtrack.report`).

The default particle count, :data:`DEFAULT_PARTICLES`, is not given by the paper; it is
chosen so that the paper-scale run (3 scenarios × 3 models × 100 trials, plus the loss
sweep) finishes in under 10 minutes on a 2-core machine (``benchmarks/bench_reproduce.py``).
"""

from __future__ import annotations

import time as _time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from hmmtrack import metrics, ranging, scenarios, tracking
from hmmtrack.config import TrackingConfig
from hmmtrack.executors import get_executor, map_ordered
from hmmtrack.filter import ParticleFilter
from hmmtrack.measurement import RangeRateMeasurement
from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios import Scenario

__all__ = [
    "DEFAULT_PARTICLES",
    "HMM_VARIANT",
    "LOSS_BANDS",
    "LOSS_FRACTIONS",
    "MOTIONS",
    "PAPER_SCENARIOS",
    "Cell",
    "DepthAnalysis",
    "ExampleRun",
    "TrialResult",
    "compare_motion_models",
    "depth_analysis",
    "example_run",
    "experiment_seed",
    "loss_bands",
    "loss_sweep",
    "paper_scenarios",
    "run_trial",
    "run_trials",
    "summarise_trials",
    "track_scenario",
    "trials_table",
    "truncate",
]

#: the paper's three motion models, in its order
MOTIONS = ("baseline", "velocity", "hmm")

#: how the HMM motion model runs a model fitted at a time step other than the filter's 1 s
#: (see :class:`hmmtrack.motion.HMMMotion`): the bundled white-shark HMM is fitted on a 60 s
#: grid, so its transition matrix and step/turn draws are made consistent with 1 s
#: predictions. (The "paper" variant, a new state and new draws every second from the 60 s
#: model, switches behaviour 60 times too often and loses the shark on our analogue.)
HMM_VARIANT = "time_consistent"

#: particles per filter run when none is given (the paper does not say; see module doc)
DEFAULT_PARTICLES = 1000

#: spacing of the stored error-over-time curve of each trial (s); the metrics use every
#: estimate, this only keeps tables of many trials small
ERROR_CURVE_SPACING = 10.0

#: the paper's measurement-loss bands, and the fractions of detections dropped between them;
#: a fraction on an edge belongs to the middle band, as in "between 20 % and 80 %"
LOSS_BANDS = ("<20 %", "20–80 %", ">80 %")
LOSS_BAND_EDGES = (0.2, 0.8)

#: the paper's tag depth (m), the deepest white shark in its tracks
PAPER_DEPTH = 10.7

#: per-trial columns of every trials table, in order
TRIAL_COLUMNS = (
    "scenario",
    "motion",
    "trial",
    "loss_fraction",
    "depth_correction",
    "n_particles",
    "time_to_convergence",
    "converged",
    "mean_error_after_convergence",
    "rmse_after_convergence",
    "runtime",
)


@dataclass(frozen=True)
class TrialResult:
    """What one particle-filter trial measured.

    Attributes
    ----------
    scenario, motion : str
        Scenario name and motion model (``"baseline"``, ``"velocity"``, ``"hmm"``).
    trial : int
        Index of the trial in its experiment (its seed is child ``trial`` of the cell's).
    loss_fraction : float
        Fraction of detections dropped by :func:`hmmtrack.scenarios.thin_evenly` (0–1).
    depth_correction : bool
        Whether ranges were corrected with the tag's depth.
    n_particles : int
    time_to_convergence : float
        Seconds from the first estimate until √λ₁ < 10 m; 0 when never (the paper's rule).
    converged : bool
    mean_error_after_convergence : float
        The paper's "RMSE" (m): mean position error from convergence to the end.
    rmse_after_convergence : float
        The true root-mean-square position error over the same span (m).
    runtime : float
        Wall-clock seconds of the filter run (not part of the result's identity).
    error_time : numpy.ndarray, shape (n,)
        Times since the start (s) of the stored error curve, every
        :data:`ERROR_CURVE_SPACING` s.
    error : numpy.ndarray, shape (n,)
        Position error at those times (m).
    """

    scenario: str
    motion: str
    trial: int
    loss_fraction: float
    depth_correction: bool
    n_particles: int
    time_to_convergence: float
    converged: bool
    mean_error_after_convergence: float
    rmse_after_convergence: float
    runtime: float
    error_time: np.ndarray = field(repr=False)
    error: np.ndarray = field(repr=False)

    def row(self) -> dict[str, Any]:
        """The scalar fields, as one row of a trials table."""
        values = asdict(self)
        return {name: values[name] for name in TRIAL_COLUMNS}


def experiment_seed(seed: SeedLike) -> np.random.SeedSequence:
    """The root :class:`~numpy.random.SeedSequence` of an experiment.

    Parameters
    ----------
    seed : int, SeedSequence or None
        A ``Generator`` is refused: its state cannot be split reproducibly into trials.
    """
    if isinstance(seed, np.random.Generator):
        raise TypeError("experiments need an int or SeedSequence seed, not a Generator")
    if isinstance(seed, np.random.SeedSequence):
        return seed
    return np.random.SeedSequence(seed)


def _child(root: np.random.SeedSequence, *key: int) -> np.random.SeedSequence:
    """The child of ``root`` at ``key``: what repeated ``spawn`` calls would hand out there,
    without ``spawn``'s hidden counter (so asking twice gives the same child)."""
    return np.random.SeedSequence(
        root.entropy, spawn_key=tuple(root.spawn_key) + key, pool_size=root.pool_size
    )


def trials_table(results: Iterable[TrialResult]) -> pd.DataFrame:
    """Tidy table of trials: one row per trial, columns :data:`TRIAL_COLUMNS`.

    Rows are sorted by scenario order of appearance, motion, loss fraction, depth
    correction and trial, so the table does not depend on the order trials finished in.
    """
    table = pd.DataFrame([r.row() for r in results], columns=list(TRIAL_COLUMNS))
    table = table.astype(
        {"trial": int, "n_particles": int, "converged": bool, "depth_correction": bool}
    )
    keys = ["scenario", "motion", "loss_fraction", "depth_correction", "trial"]
    order = {name: i for i, name in enumerate(pd.unique(table["scenario"]))}
    motion_order = {name: i for i, name in enumerate(MOTIONS)}
    return table.sort_values(
        keys,
        key=lambda col: (
            col.map(order)
            if col.name == "scenario"
            else col.map(lambda m: motion_order.get(m, len(MOTIONS)))
            if col.name == "motion"
            else col
        ),
        kind="stable",
    ).reset_index(drop=True)


def summarise_trials(
    table: pd.DataFrame, by: Sequence[str] = ("scenario", "motion")
) -> pd.DataFrame:
    """Per-group means of a trials table, as the paper reports them.

    Parameters
    ----------
    table : pandas.DataFrame
        A trials table (:func:`trials_table`).
    by : sequence of str
        Grouping columns.

    Returns
    -------
    pandas.DataFrame
        One row per group: ``n_trials``, ``n_converged``,
        ``mean_error_after_convergence`` (mean over trials of the paper's "RMSE", m),
        ``median_error_after_convergence`` (m), ``rmse_after_convergence`` (mean over
        trials, m), ``time_to_convergence`` (mean over converged trials, s; NaN when none
        converged) and ``max_time_to_convergence`` (s).
    """
    groups = table.groupby(list(by), sort=False)
    converged_times = table["time_to_convergence"].where(table["converged"])
    summary = pd.DataFrame(
        {
            "n_trials": groups.size(),
            "n_converged": groups["converged"].sum().astype(int),
            "mean_error_after_convergence": groups["mean_error_after_convergence"].mean(),
            "median_error_after_convergence": groups["mean_error_after_convergence"].median(),
            "rmse_after_convergence": groups["rmse_after_convergence"].mean(),
            "time_to_convergence": converged_times.groupby(
                [table[c] for c in by], sort=False
            ).mean(),
            "max_time_to_convergence": converged_times.groupby(
                [table[c] for c in by], sort=False
            ).max(),
        }
    )
    return summary.reset_index()


def loss_bands(table: pd.DataFrame) -> pd.DataFrame:
    """The paper's measurement-loss summary: mean and max per band of fractions dropped.

    Parameters
    ----------
    table : pandas.DataFrame
        Trials table with ``loss_fraction`` (0–1), ``converged``, ``time_to_convergence``
        (s) and ``mean_error_after_convergence`` (m), e.g. from :func:`loss_sweep`.

    Returns
    -------
    pandas.DataFrame
        Indexed by band label (:data:`LOSS_BANDS`): ``n_trials``, ``n_converged``,
        ``convergence_mean`` / ``convergence_max`` (s, over converged trials),
        ``error_mean`` / ``error_max`` (m, over converged trials). A band with no
        converged trial has NaN statistics and says so through ``n_converged = 0``.

    Raises
    ------
    ValueError
        If a loss fraction lies outside [0, 1] (naming the rows).
    """
    fraction = table["loss_fraction"].to_numpy(dtype=float)
    bad = np.flatnonzero(~((fraction >= 0) & (fraction <= 1)))
    if bad.size:
        raise ValueError(f"loss_fraction outside [0, 1] in row(s) {bad[:10].tolist()}")
    low, high = LOSS_BAND_EDGES
    labels = np.select([fraction < low, fraction <= high], LOSS_BANDS[:2], LOSS_BANDS[2])
    rows = {}
    for label in LOSS_BANDS:
        band = table[labels == label]
        ok = band[band["converged"].to_numpy(dtype=bool)]
        rows[label] = {
            "n_trials": len(band),
            "n_converged": len(ok),
            "convergence_mean": ok["time_to_convergence"].mean(),
            "convergence_max": ok["time_to_convergence"].max(),
            "error_mean": ok["mean_error_after_convergence"].mean(),
            "error_max": ok["mean_error_after_convergence"].max(),
        }
    return pd.DataFrame.from_dict(rows, orient="index")


#: moments of the example runs' particle snapshots: seconds after the start, and the end
SNAPSHOT_SECONDS = (0.0, 15.0, 40.0, 300.0)


def track_scenario(
    scenario: Scenario,
    motion_name: str,
    seed: SeedLike,
    n_particles: int = DEFAULT_PARTICLES,
    *,
    loss_fraction: float = 0.0,
    depth_correction: bool = False,
    snapshot_times: Sequence[float] = (),
):
    """Track the tag of ``scenario`` with one motion model (no scoring).

    Parameters
    ----------
    scenario : Scenario
    motion_name : {"baseline", "velocity", "hmm"}
        :func:`hmmtrack.tracking.motion_model` with its defaults; the HMM (the bundled
        white-shark model) in the :data:`HMM_VARIANT` variant.
    seed : int, SeedSequence or Generator
    n_particles : int
    loss_fraction : float
        Fraction (0–1) of detections dropped with :func:`hmmtrack.scenarios.thin_evenly`.
    depth_correction : bool
        Correct the ranges with the tag's depth sensor.
    snapshot_times : sequence of float
        UTC seconds at which to keep the particles.

    Returns
    -------
    hmmtrack.tracking.TrackingResult or hmmtrack.filter.FilterResult
        Estimates every second from ``scenario.start`` to ``scenario.end``, and snapshots.
        When no detection is left (``loss_fraction = 1``) the filter runs on its motion
        model alone and its own result is returned (no observations to report).
    """
    detections = scenario.detections
    if loss_fraction > 0:
        detections = scenarios.thin_evenly(detections, loss_fraction)
    config = TrackingConfig(
        period=scenario.period,
        r0=scenario.r0,
        sound_speed=scenario.sound_speed,
        transmitter=scenario.transmitter,
        bounds=scenario.bounds,
        n_particles=n_particles,
        depth="sensor" if depth_correction else "none",
        shallower="clip",
        start=scenario.start,
        end=scenario.end,
    )
    if detections.empty:  # everything dropped: the filter runs on its motion model alone
        pf = ParticleFilter(
            _motion(motion_name),
            RangeRateMeasurement(np.array(config.measurement_covariance)),
            n_particles=n_particles,
            bounds=scenario.bounds,
            rng=as_generator(seed),
        )
        no_data = pd.DataFrame(columns=list(tracking.OBSERVATION_COLUMNS), dtype=float)
        return pf.run(no_data, scenario.start, scenario.end, snapshot_times)
    return tracking.track(
        detections,
        scenario.receivers,
        config,
        _motion(motion_name),
        seed=seed,
        snapshot_times=snapshot_times,
    )


def _motion(motion_name: str):
    """The motion model of a trial: tracking's defaults, the HMM in :data:`HMM_VARIANT`."""
    if motion_name == "hmm":
        return tracking.motion_model("hmm", variant=HMM_VARIANT)
    return tracking.motion_model(motion_name)


@dataclass(frozen=True)
class ExampleRun:
    """One scored run with particle snapshots, for the paper's single-trial figures.

    Attributes
    ----------
    scenario : Scenario
    result : hmmtrack.tracking.TrackingResult
        Estimates, snapshots and observations of the run.
    errors : numpy.ndarray, shape (n,)
        Position error at each estimate (m).
    convergence : hmmtrack.metrics.Convergence
    """

    scenario: Scenario
    result: Any
    errors: np.ndarray
    convergence: metrics.Convergence


def example_run(
    scenario: Scenario,
    seed: SeedLike,
    n_particles: int = DEFAULT_PARTICLES,
    motion_name: str = "hmm",
) -> ExampleRun:
    """One run with particle snapshots, for the error-over-time figures.

    Snapshots at :data:`SNAPSHOT_SECONDS` after the start (those inside the run) and at the
    end.

    Returns
    -------
    ExampleRun
    """
    times = [scenario.start + s for s in SNAPSHOT_SECONDS if scenario.start + s < scenario.end]
    result = track_scenario(
        scenario, motion_name, seed, n_particles, snapshot_times=[*times, scenario.end]
    )
    estimates = result.estimates
    return ExampleRun(
        scenario=scenario,
        result=result,
        errors=metrics.position_error(estimates, scenario.truth),
        convergence=metrics.time_to_convergence(estimates["time"], estimates["sqrt_lambda1"]),
    )


def run_trial(
    scenario: Scenario,
    motion_name: str,
    seed: SeedLike,
    n_particles: int = DEFAULT_PARTICLES,
    *,
    trial: int = 0,
    loss_fraction: float = 0.0,
    depth_correction: bool = False,
) -> TrialResult:
    """Run the particle filter once on ``scenario`` and score it against the truth.

    Parameters
    ----------
    scenario : hmmtrack.scenarios.Scenario
    motion_name : {"baseline", "velocity", "hmm"}
        The HMM model is the bundled white-shark model.
    seed : int, SeedSequence or Generator
        Seed of the filter's random draws.
    n_particles : int
    trial : int
        Index recorded in the result.
    loss_fraction : float
        Fraction (0–1) of detections dropped evenly before tracking.
    depth_correction : bool
        Correct ranges with the tag's depth sensor (the detections' ``depth`` column).

    Returns
    -------
    TrialResult
    """
    clock = _time.perf_counter()
    run = track_scenario(
        scenario,
        motion_name,
        seed,
        n_particles,
        loss_fraction=loss_fraction,
        depth_correction=depth_correction,
    )
    runtime = _time.perf_counter() - clock
    estimates = run.estimates
    scores = metrics.tracking_metrics(estimates, scenario.truth)
    errors = metrics.position_error(estimates, scenario.truth)
    elapsed = estimates["time"].to_numpy(dtype=float) - float(estimates["time"].iloc[0])
    _, keep = np.unique(np.floor(elapsed / ERROR_CURVE_SPACING), return_index=True)
    return TrialResult(
        scenario=scenario.name,
        motion=motion_name,
        trial=int(trial),
        loss_fraction=float(loss_fraction),
        depth_correction=bool(depth_correction),
        n_particles=int(n_particles),
        time_to_convergence=scores.time_to_convergence,
        converged=scores.converged,
        mean_error_after_convergence=scores.mean_error_after_convergence,
        rmse_after_convergence=scores.rmse_after_convergence,
        runtime=runtime,
        error_time=elapsed[keep],
        error=errors[keep],
    )


@dataclass(frozen=True)
class _Batch:
    """Trials of one experiment cell, sent to a worker together (one pickled scenario)."""

    scenario: Scenario
    motion: str
    n_particles: int
    loss_fraction: float
    depth_correction: bool
    trials: tuple[tuple[int, np.random.SeedSequence], ...]


def _run_batch(batch: _Batch) -> list[TrialResult]:
    return [
        run_trial(
            batch.scenario,
            batch.motion,
            seed,
            batch.n_particles,
            trial=k,
            loss_fraction=batch.loss_fraction,
            depth_correction=batch.depth_correction,
        )
        for k, seed in batch.trials
    ]


@dataclass(frozen=True)
class Cell:
    """One cell of an experiment: a scenario, a motion model and a treatment, with its seed.

    Trial ``k`` of the cell is seeded with ``SeedSequence`` child ``k`` of ``seed``.
    """

    scenario: Scenario
    motion: str
    seed: np.random.SeedSequence
    loss_fraction: float = 0.0
    depth_correction: bool = False


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
        See :func:`hmmtrack.executors.get_executor`; an executor passed in is not shut down.
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
    batches = [
        _Batch(
            scenario=_lean(cell.scenario),
            motion=cell.motion,
            n_particles=int(n_particles),
            loss_fraction=float(cell.loss_fraction),
            depth_correction=cell.depth_correction,
            trials=tuple(
                (k, _child(cell.seed, k)) for k in range(start, min(start + batch_size, n_trials))
            ),
        )
        for cell in cells
        for start in range(0, n_trials, batch_size)
    ]
    pool = get_executor(executor, max_workers)
    try:
        done = map_ordered(pool, _run_batch, batches, progress=progress, description=description)
    finally:
        if pool is not executor:
            pool.shutdown()
    return [result for batch in done for result in batch]


def _lean(scenario: Scenario) -> Scenario:
    """The scenario without the tables a tracker never reads (cheaper to send to workers)."""
    return replace(
        scenario,
        pings=scenario.pings.iloc[:0],
        receivers_truth=scenario.receivers_truth.iloc[:0],
    )


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
        built = {"shark_pursuit": scenarios.shark_pursuit(_child(root, 3, 3), dive=True)}
    else:
        unknown = [n for n in names if n not in PAPER_SCENARIOS]
        if unknown:
            raise ValueError(f"unknown scenario(s) {unknown}; expected some of {PAPER_SCENARIOS}")
        built = {
            name: getattr(scenarios, name)(_child(root, 3, PAPER_SCENARIOS.index(name)))
            for name in names
        }
    if duration is None:
        return built
    return {name: truncate(scenario, duration) for name, scenario in built.items()}


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
) -> pd.DataFrame:
    """The paper's motion-model comparison: ``n_trials`` filter runs per model per scenario.

    Parameters
    ----------
    scenario_list : sequence of Scenario
        E.g. ``paper_scenarios(seed).values()``.
    motions : sequence of str
        Motion models, of :data:`MOTIONS`.
    n_trials : int
        Trials per model per scenario (100 in the paper).
    seed : int or SeedSequence
        Experiment seed; trial ``k`` of model ``j`` on scenario ``i`` is seeded with child
        ``(0, i, j, k)``.
    executor, max_workers, progress
        See :func:`run_trials`.
    n_particles : int

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
        Cell(scenario, motion, _child(root, 0, i, j))
        for i, scenario in enumerate(scenario_list)
        for j, motion in enumerate(motions)
    ]
    results = run_trials(
        cells,
        n_trials,
        n_particles,
        executor=executor,
        max_workers=max_workers,
        progress=progress,
        description="motion-model trials",
    )
    return trials_table(results)


#: default loss fractions of the sweep: 0 to 100 % in 5 % steps
LOSS_FRACTIONS = tuple(np.round(np.linspace(0.0, 1.0, 21), 2))


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
        Cell(scenario, motion, _child(root, 1, i), loss_fraction=f) for i, f in enumerate(fractions)
    ]
    results = run_trials(
        cells,
        n_trials,
        n_particles,
        executor=executor,
        max_workers=max_workers,
        progress=progress,
        description="loss sweep",
    )
    return trials_table(results)


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
    curves : dict of str to (time, error)
        Error over time (s since start, m) of the first trial with and without correction.
    """

    depth: float
    ranges: np.ndarray
    percent_error: np.ndarray
    max_depth: float = float("nan")
    depth_profile: tuple[np.ndarray, np.ndarray] | None = None
    trials: pd.DataFrame | None = None
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


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
) -> DepthAnalysis:
    """Percent-error curve of ignoring depth, and the diving shark with and without correction.

    Parameters
    ----------
    n_trials : int
        Trials of the diving shark per variant (0 skips the filter runs).
    seed : int or SeedSequence
        The diving shark is ``paper_scenarios(seed, dive=True)``; trial ``k`` without / with
        correction is seeded with child ``(2, 0, k)`` / ``(2, 1, k)``.
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
        Cell(diving, motion, _child(root, 2, int(correct)), depth_correction=correct)
        for correct in (False, True)
    ]
    results = run_trials(
        cells,
        n_trials,
        n_particles,
        executor=executor,
        max_workers=max_workers,
        progress=progress,
        description="diving shark",
    )
    labels = {False: "without depth correction", True: "with depth correction"}
    curves = {labels[r.depth_correction]: (r.error_time, r.error) for r in results if r.trial == 0}
    truth = diving.truth
    elapsed = truth["time"].to_numpy(dtype=float) - float(truth["time"].iloc[0])
    profile = truth["depth"].to_numpy(dtype=float)
    return DepthAnalysis(
        depth=depth,
        ranges=ranges,
        percent_error=percent,
        max_depth=float(profile.max()),
        depth_profile=(elapsed, profile),
        trials=trials_table(results),
        curves=curves,
    )
