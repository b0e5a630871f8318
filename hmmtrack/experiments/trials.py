"""One particle-filter trial on a scenario, scored against its truth; and the trials' seeds.

:func:`track_scenario` runs the tracker of :mod:`hmmtrack.tracking.pipeline` on a
:class:`~hmmtrack.scenarios.Scenario` with one of the paper's motion models (optionally on
evenly thinned detections or with depth-corrected ranges); :func:`run_trial` scores such a
run with :mod:`hmmtrack.analysis.metrics` into a :class:`TrialResult`; :func:`example_run` keeps the
particle snapshots for the single-trial figures. :func:`experiment_seed` and
:func:`child_seed` give every trial its own ``SeedSequence`` child.

Not for dispatching many trials (:mod:`hmmtrack.experiments.dispatch`) nor for tables
(:mod:`hmmtrack.experiments.tables`).
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from hmmtrack import scenarios
from hmmtrack.analysis import metrics
from hmmtrack.analysis.mirror import mirror_share, mirror_track
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios import Scenario
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import measurement_motion
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.measurement.range_rate import OBSERVATION_COLUMNS, RangeRateMeasurement
from hmmtrack.tracking.motion import MOTIONS as MOTION_FACTORIES
from hmmtrack.tracking.motion import MotionModel
from hmmtrack.tracking.motion.settings import MOTION_SETTINGS, HMMSettings

#: the paper's three motion models, in its order (the names of the motion registry)
MOTIONS = tuple(MOTION_FACTORIES)

#: how the HMM motion model runs a model fitted at a time step other than the filter's 1 s
#: (see :class:`hmmtrack.tracking.motion.HMMMotion`): the bundled white-shark HMM is fitted on a 60
#: s
#: grid, so its transition matrix and step/turn draws are made consistent with 1 s
#: predictions. (The "paper" variant, a new state and new draws every second from the 60 s
#: model, switches behaviour 60 times too often and loses the shark on our analogue.)
HMM_VARIANT = "time_consistent"

#: particles per filter run when none is given. The paper does not say; 1000 keeps the
#: paper-scale run (900 comparison trials, 105 loss-sweep trials, 20 diving-shark trials)
#: under 10 minutes on 2 cores (``benchmarks/bench_reproduce.py``: about 9.5 minutes with
#: the cores shared with other jobs, a load of 5), while the shark-pursuit trials' run time is
#: still dominated by per-second overhead rather than particles (measured on one core:
#: 0.3 s per trial at 200 particles, 0.5 s at 1000, 1.0–1.8 s at 4000), and the error after
#: convergence did not improve from 1000 to 4000 particles in our checks.
DEFAULT_PARTICLES = 1000

#: spacing of the stored error-over-time curve of each trial (s); the metrics use every
#: estimate, this only keeps tables of many trials small
ERROR_CURVE_SPACING = 10.0

#: per-trial columns of every trials table, in order
TRIAL_COLUMNS = (
    "scenario",
    "dataset",
    "motion",
    "trial",
    "loss_fraction",
    "depth_correction",
    "start_prior",
    "n_particles",
    "time_to_convergence",
    "converged",
    "mean_error_after_convergence",
    "rmse_after_convergence",
    "calibration",
    "region_scale",
    "false_converged",
    "mirror_share",
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
    dataset : int
        Which synthetic dataset of the scenario (0 is the one :func:`paper_scenarios`
        builds; several datasets separate the spread between datasets from that between
        filter runs).
    calibration : float
        Share of the seconds after convergence whose 95 % region holds the truth (NaN when
        never converged; :func:`hmmtrack.analysis.metrics.uncertainty_metrics`).
    region_scale : float
        Factor by which those seconds' 95 % regions would have to be scaled to hold the
        truth in exactly 95 % of them (1 calibrated, below 1 too wide; NaN when never
        converged; :func:`hmmtrack.analysis.metrics.region_scale`).
    false_converged : float
        Share of the seconds declared converged with an error above 50 m.
    mirror_share : float
        Share of the seconds after convergence whose estimate is nearer the mirror track
        (the truth reflected across the line of the two receivers, which no range tells
        apart from it) than the truth, where the two are at least 50 m apart
        (:func:`hmmtrack.analysis.mirror.mirror_share`); NaN when the scenario does not have
        two receivers or the run never converged.
    start_prior : bool
        Whether the particles started in the scenario's ``start_region`` (where the tag is
        known to be at the start) rather than in its ``bounds``.
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
    dataset: int = 0
    calibration: float = math.nan
    region_scale: float = math.nan
    false_converged: float = math.nan
    mirror_share: float = math.nan
    start_prior: bool = False

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


def child_seed(root: np.random.SeedSequence, *key: int) -> np.random.SeedSequence:
    """The child of ``root`` at ``key``: what repeated ``spawn`` calls would hand out there,
    without ``spawn``'s hidden counter (so asking twice gives the same child)."""
    return np.random.SeedSequence(
        root.entropy, spawn_key=tuple(root.spawn_key) + key, pool_size=root.pool_size
    )


#: the filter of the paper's experiments (:data:`hmmtrack.tracking.filter.FILTERS`), named
#: so that they run it whatever the library's default filter is
PAPER_FILTER = "paper"

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
    start_prior: bool = False,
    snapshot_times: Sequence[float] = (),
    filter: str = PAPER_FILTER,
    measurement: str = "range-rate",
    motion: MotionModel | None = None,
):
    """Track the tag of ``scenario`` with one motion model (no scoring).

    Parameters
    ----------
    scenario : Scenario
    motion_name : {"baseline", "velocity", "hmm"}
        :func:`hmmtrack.tracking.motion.motion_model` with its defaults; the HMM (the bundled
        white-shark model) in the :data:`HMM_VARIANT` variant, with the settings the
        measurement gives it (:func:`_motion`).
    seed : int, SeedSequence or Generator
    n_particles : int
    loss_fraction : float
        Fraction (0–1) of detections dropped with :func:`hmmtrack.scenarios.thin_evenly`.
    depth_correction : bool
        Correct the ranges with the tag's depth sensor.
    start_prior : bool
        Where the scenario records a ``start_region`` (where the field team knows the tag to
        be at the start), start the particles there instead of in the paper's
        ``scenario.bounds``, and skip the filter's acquisition (there is nothing left for it
        to find, and its still-tag grid is the weakest start for a moving tag). Two receivers
        leave the tag's mirror across their line exactly as likely as the tag; this is the
        information that picks the right one (``reports/decisions.md``, issue 13's shark
        pursuit and "Which configuration wins"). A scenario without one starts in its
        ``bounds``, as without the option.
    snapshot_times : sequence of float
        UTC seconds at which to keep the particles.
    filter : str
        Named filter (:data:`hmmtrack.tracking.filter.FILTERS`): ``"paper"`` or
        ``"mode-keeping"``.
    measurement : {"range-rate", "range-rate-gps"}
        The paper's measurement, or the same with the receivers' GPS error correlated in
        time (:mod:`hmmtrack.tracking.measurement.gps_offset`), at their default noise.
    motion : MotionModel, optional
        Track with this motion model as it is instead of ``motion_name``'s defaults (e.g. an
        HMM of another movement model: ``reports/mirror_losses.py`` gives the filter the
        model that drew the synthetic shark).

    Returns
    -------
    hmmtrack.tracking.pipeline.TrackingResult or hmmtrack.tracking.filter.FilterResult
        Estimates every second from ``scenario.start`` to ``scenario.end``, and snapshots.
        When no detection is left (``loss_fraction = 1``) the filter runs on its motion
        model alone and its own result is returned (no observations to report).
    """
    detections = scenario.detections
    if loss_fraction > 0:
        detections = scenarios.thin_evenly(detections, loss_fraction)
    bounds = scenario.bounds
    known_start = {}
    if start_prior and scenario.start_region is not None:
        bounds = scenario.start_region
        known_start = {"acquisition": False}
    config = tracking_config(
        scenario,
        n_particles=n_particles,
        depth="sensor" if depth_correction else "none",
        shallower="clip",
        bounds=bounds,
        filter=filter,
        measurement=measurement,
        **known_start,
    )
    if motion is None:
        motion = _motion(motion_name, measurement)
    if detections.empty:  # everything dropped: the filter runs on its motion model alone
        pf = ParticleFilter(
            motion,
            RangeRateMeasurement(np.array(config.measurement.covariance)),
            n_particles=n_particles,
            bounds=bounds,
            rng=as_generator(seed),
        )
        no_data = pd.DataFrame(columns=list(OBSERVATION_COLUMNS), dtype=float)
        return pf.run(no_data, scenario.start, scenario.end, snapshot_times)
    return tracking.track(
        detections,
        scenario.receivers,
        config,
        motion,
        seed=seed,
        snapshot_times=snapshot_times,
    )


def _motion(motion_name: str, measurement: str = "range-rate"):
    """The motion model of a trial: tracking's defaults under ``measurement``, the HMM in
    :data:`HMM_VARIANT`, by the tracking layer's rule
    (:func:`hmmtrack.tracking.config.measurement_motion`; e.g. under ``range-rate-gps`` the
    HMM's resting tag holds still and its held speeds take a log random walk)."""
    settings = (
        HMMSettings(variant=HMM_VARIANT) if motion_name == "hmm" else MOTION_SETTINGS[motion_name]()
    )
    return measurement_motion(settings, measurement)


@dataclass(frozen=True)
class ExampleRun:
    """One scored run with particle snapshots, for the paper's single-trial figures.

    Attributes
    ----------
    scenario : Scenario
    result : hmmtrack.tracking.pipeline.TrackingResult
        Estimates, snapshots and observations of the run.
    errors : numpy.ndarray, shape (n,)
        Position error at each estimate (m).
    convergence : hmmtrack.analysis.metrics.Convergence
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
    filter: str = PAPER_FILTER,
    start_prior: bool = False,
    measurement: str = "range-rate",
) -> ExampleRun:
    """One run with particle snapshots, for the error-over-time figures.

    Snapshots at :data:`SNAPSHOT_SECONDS` after the start (those inside the run) and at the
    end; ``filter``, ``start_prior`` and ``measurement`` as in :func:`track_scenario`.

    Returns
    -------
    ExampleRun
    """
    times = [scenario.start + s for s in SNAPSHOT_SECONDS if scenario.start + s < scenario.end]
    result = track_scenario(
        scenario,
        motion_name,
        seed,
        n_particles,
        snapshot_times=[*times, scenario.end],
        filter=filter,
        start_prior=start_prior,
        measurement=measurement,
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
    dataset: int = 0,
    loss_fraction: float = 0.0,
    depth_correction: bool = False,
    start_prior: bool = False,
    filter: str = PAPER_FILTER,
    measurement: str = "range-rate",
    motion: MotionModel | None = None,
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
    trial, dataset : int
        Indices recorded in the result (filter run, synthetic dataset).
    loss_fraction : float
        Fraction (0–1) of detections dropped evenly before tracking.
    depth_correction : bool
        Correct ranges with the tag's depth sensor (the detections' ``depth`` column).
    start_prior : bool
        Start in the scenario's ``start_region`` (:func:`track_scenario`).
    filter, measurement : str
        Named filter and measurement, as in :func:`track_scenario`.
    motion : MotionModel, optional
        Track with this motion model as it is (:func:`track_scenario`); ``motion_name``
        still names the trial.

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
        start_prior=start_prior,
        filter=filter,
        measurement=measurement,
        motion=motion,
    )
    runtime = _time.perf_counter() - clock
    estimates = run.estimates
    scores = metrics.tracking_metrics(estimates, scenario.truth)
    honesty = metrics.uncertainty_metrics(estimates, scenario.truth)
    errors = metrics.position_error(estimates, scenario.truth)
    elapsed = estimates["time"].to_numpy(dtype=float) - float(estimates["time"].iloc[0])
    after = elapsed >= scores.time_to_convergence if scores.converged else elapsed < 0
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
        dataset=int(dataset),
        calibration=honesty.calibration,
        region_scale=honesty.region_scale,
        false_converged=honesty.false_converged,
        mirror_share=_mirror_share(scenario, estimates[after]),
        start_prior=bool(start_prior and scenario.start_region is not None),
    )


def _mirror_share(scenario: Scenario, estimates: pd.DataFrame) -> float:
    """:func:`hmmtrack.analysis.mirror.mirror_share` of ``estimates`` on a scenario with two
    receivers (their logged positions); NaN with any other number of receivers."""
    if scenario.receivers["receiver"].nunique() != 2:
        return math.nan
    return mirror_share(estimates, scenario.truth, mirror_track(scenario.truth, scenario.receivers))
