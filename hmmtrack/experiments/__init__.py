"""Monte Carlo experiments of the paper's "Results" section.

* :func:`run_trial` — one particle-filter run on a scenario with one motion model, scored
  with :mod:`hmmtrack.analysis.metrics` (time to convergence, the paper's "RMSE", which is a mean
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

Submodules: :mod:`~hmmtrack.experiments.trials` (one trial, its seed and score),
:mod:`~hmmtrack.experiments.dispatch` (many trials on an executor),
:mod:`~hmmtrack.experiments.tables` (trial tables, loss bands),
:mod:`~hmmtrack.experiments.studies` (the paper's datasets and studies) and
:mod:`~hmmtrack.experiments.configs` (a scenario's settings as the tracker's configuration).
The studies behind ``hmmtrack study`` (not imported here): :mod:`~hmmtrack.experiments.stationary`,
:mod:`~hmmtrack.experiments.arrival`, :mod:`~hmmtrack.experiments.clock_bound`,
:mod:`~hmmtrack.experiments.two_auv_plan` and :mod:`~hmmtrack.experiments.closed_loop_study`,
with the clock studies' shared runs in :mod:`~hmmtrack.experiments.clock_runs`; any
measurement against its Cramér–Rao bound on a simulated moored array with sync tags:
:mod:`~hmmtrack.experiments.array_runs`.

Trials are dispatched through :mod:`hmmtrack.experiments.executors` (serial, local processes or a
Dask
cluster). This package computes results; it draws nothing (see
:mod:`hmmtrack.plots.results`) and writes no files (see :mod:`hmmtrack.report`).

The default particle count, :data:`DEFAULT_PARTICLES`, is not given by the paper; it is
chosen so that the paper-scale run (3 scenarios × 3 models × 100 trials, plus the loss
sweep) finishes in under 10 minutes on a 2-core machine (``benchmarks/bench_reproduce.py``).
"""

from hmmtrack.experiments.dispatch import Cell, run_options, run_trials
from hmmtrack.experiments.studies import (
    LOSS_FRACTIONS,
    PAPER_DEPTH,
    PAPER_SCENARIOS,
    DepthAnalysis,
    compare_motion_models,
    depth_analysis,
    loss_sweep,
    paper_datasets,
    paper_scenarios,
    truncate,
)
from hmmtrack.experiments.tables import (
    LOSS_BAND_EDGES,
    LOSS_BANDS,
    MOSTLY_OUTSIDE,
    calibration_spread,
    dataset_spread,
    loss_bands,
    summarise_trials,
    trials_table,
)
from hmmtrack.experiments.trials import (
    DEFAULT_PARTICLES,
    ERROR_CURVE_SPACING,
    HMM_VARIANT,
    MOTIONS,
    SNAPSHOT_SECONDS,
    TRIAL_COLUMNS,
    ExampleRun,
    TrialResult,
    child_seed,
    example_run,
    experiment_seed,
    run_trial,
    track_scenario,
)

__all__ = [
    "DEFAULT_PARTICLES",
    "ERROR_CURVE_SPACING",
    "HMM_VARIANT",
    "LOSS_BAND_EDGES",
    "LOSS_BANDS",
    "LOSS_FRACTIONS",
    "MOSTLY_OUTSIDE",
    "MOTIONS",
    "PAPER_DEPTH",
    "PAPER_SCENARIOS",
    "SNAPSHOT_SECONDS",
    "TRIAL_COLUMNS",
    "Cell",
    "DepthAnalysis",
    "ExampleRun",
    "TrialResult",
    "child_seed",
    "compare_motion_models",
    "calibration_spread",
    "dataset_spread",
    "depth_analysis",
    "example_run",
    "experiment_seed",
    "loss_bands",
    "loss_sweep",
    "paper_datasets",
    "paper_scenarios",
    "run_trial",
    "run_options",
    "run_trials",
    "summarise_trials",
    "track_scenario",
    "trials_table",
    "truncate",
]
