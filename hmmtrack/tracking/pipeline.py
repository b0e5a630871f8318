"""The tracking pipeline: detections + receiver positions + configuration → position estimates.

:func:`track` runs the particle filter (:class:`hmmtrack.tracking.filter.ParticleFilter`) for
every measurement model, the one ``config.measurement`` names
(:data:`hmmtrack.tracking.measurement.MEASUREMENTS`): the measurement builds the observations
from one transmitter's detections (:func:`build_observations`), derives the search box, adds
its own particle fields, hooks and diagnostics; :func:`track` chooses the correction policy
(the measurement's default, or tempered at ``config.tempering_ess``), runs the filter and
returns one :class:`TrackingResult`.

The motion model is one of the paper's, chosen by name (:func:`motion_model`):
``"baseline"``, ``"velocity"`` or ``"hmm"`` (a saved :class:`hmmtrack.hmm.MovementHMM`, by
default the bundled white-shark model ``hmmtrack/data/white_shark_hmm.json``), to which the
time-consistent variant adds a resting state by default (:data:`HMM_RESTING`: a tag may be
shed, its animal dead or resting; ``motion_model("hmm", resting=None)`` switches it off).

The defaults were chosen on the synthetic analogues of the paper's three datasets; the
measurements behind them are in reports/decisions.md ("Tracking defaults"). The paper's
algorithm stays reachable: ``TrackingConfig(resampling="multinomial",
resample_when="always")`` with ``motion_model("hmm", variant="paper")``.

This module reads no files and computes no metrics (see :mod:`hmmtrack.io`,
:mod:`hmmtrack.analysis.metrics`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.base import EVENT_COLUMNS
from hmmtrack.tracking.motion import BaselineMotion, HMMMotion, VelocityMotion, step_metres
from hmmtrack.tracking.receivers import ReceiverTracks
from hmmtrack.tracking.smoothing import Smoothed
from hmmtrack.tracking.tempering import Tempered

__all__ = [
    "MOTIONS",
    "HMM_RESTING",
    "RestingState",
    "TrackingResult",
    "build_observations",
    "bundled_model_path",
    "motion_model",
    "particle_filter",
    "select_transmitter",
    "time_window",
    "track",
]

logger = logging.getLogger(__name__)

#: the paper's motion models, by name
MOTIONS = ("baseline", "velocity", "hmm")

#: random-walk step spread of the baseline model (m per √s). The paper gives no value. On
#: the stationary tag over 100 scenario seeds (``benchmarks/bench_stationary.py``, 5,000
#: particles) 1 m/√s kept only 71 % of the trials under 10 m: the walk lets the cloud spread
#: tens of metres along the boat's range circle within minutes, forgets the early detections
#: that told the tag from the second intersection of the two range circles, and its mean
#: falls between the two (error 10-17 m); 0.5 gave 97 %, 0.3 gives 98 % (mean 3.3 m). On the
#: moving tags (20 trials, 1,000 particles; swimmer / shark pursuit mean error after
#: convergence) 0.3 gives 108 / 898 m, 0.5 gives 89 / 707 m, 1.0 gave 96 / 327 m: lost
#: either way, as in the paper (its baseline: 11.2 / 970 m)
BASELINE_SIGMA = 0.3
#: spreads of the velocity model's speed (m/s per √s) and turn-rate (rad/s per √s)
#: increments. The paper gives no values. Measured as above (stationary tag / swimmer /
#: shark pursuit): (0.05, 0.05) 3.7 / 62 / 46 m; (0.1, 0.1) 3.3 / 55 / 42 m; (0.1, 0.02)
#: 3.1 / 17 / 35 m (20 trials with systematic resampling: 3.3 / 32 / 39 m, medians
#: 3.2 / 3.5 / 12 m); (0.02, 0.02) 3.6 / 98 / 48 m; (0.2, 0.02) 3.4 / 15 / 79 m: speed
#: must follow a swimming animal, turn rates change slowly
VELOCITY_SIGMA_SPEED = 0.1
VELOCITY_SIGMA_TURN_RATE = 0.02

#: heading random walk (rad/√s) of the HMM motion model in its time-consistent variant
#: (:class:`hmmtrack.tracking.motion.HMMMotion`). Speed and turn rate are held for the fitted step
#: (60 s for the bundled model), so without it the copies of a particle that resampling
#: makes move identically until their next draw: the cloud collapses onto a few velocities
#: and slides coherently (on the stationary tag: error 10-26 m while √λ₁ said 4 m). Mean
#: error after convergence (stationary tag / swimmer / shark pursuit, 10 trials): 0 gave
#: 26 / 78 / 77 m, 0.05 gave 22 / 61 / 26 m, 0.1 gave 23 / 61 / 27 m, 0.2 gave 9 / 38 / 34 m
#: (shark-pursuit medians 8-10 m for every value > 0). More diffusion makes the cloud less
#: ballistic, which a fixed tag wants and a swimming shark does not. Share of stationary-tag
#: scenario seeds under 10 m (100 seeds, 5,000 particles, ``benchmarks/bench_stationary.py``)
#: against shark-pursuit / swimmer mean (median) error (30 trials, 1,000 particles): 0.2:
#: 62 %, 36 (9.6) / 29 (4.0) m; 0.3: ~72 %, 39 (12) / 27 (4.4) m; 0.4: 90 %, 38 (15) /
#: 41 (5.2) m; 0.5: ~97 %, 48 (44) / 38 (5.9) m. 0.2 is kept for the animals the model was
#: fitted to
HMM_HEADING_DIFFUSION = 0.2


@dataclass(frozen=True)
class RestingState:
    """A resting state added to a movement HMM at tracking time
    (:meth:`hmmtrack.hmm.MovementHMM.with_resting_state`).

    Attributes
    ----------
    enter_per_hour : float
        Rate (per hour) at which a swimming animal comes to rest.
    leave_per_hour : float
        Rate (per hour) at which a resting tag starts swimming again.
    drift_speed : float
        Mean speed of a resting tag (m/s): its steps over the model's time step have mean and
        standard deviation ``drift_speed * model.dt``, in uniform directions.
    """

    enter_per_hour: float
    leave_per_hour: float
    drift_speed: float


#: resting state of the HMM motion model (time-consistent variant) by default: a tag may be
#: shed, its animal dead or resting, although the bundled white-shark model always swims
#: (0.36 or 1.05 m/s). Entered at 0.5 per hour, left at 2 per hour (mean rest 30 min; 20 %
#: of the particles rest under the prior), drifting at 0.05 m/s (an exactly motionless state
#: lets resampled copies of one resting particle pile up on one point: 95 % ellipse coverage
#: 0.21 on the stationary tag). Share of stationary-tag trials under 10 m
#: (``benchmarks/bench_stationary.py``, 100 scenario seeds, 5,000 / 1,000 particles):
#: without it 62 / 64 %, with it 98 / 84 % (1 / 4 per hour: 96 / 89 %, at 0.1 m/s 97 / 89 %;
#: 0.5 / 1 per hour: 98 / 90 %; at 5,000 particles 0.2 / 2 per hour: 91 %, 0.03 m/s: 99 %
#: with coverage 0.92). Its cloud is tight (2.5 m): the few trials that settle on the second
#: intersection of the range circles are confidently wrong (coverage < 0.5 in 10 % of the
#: trials at 1,000 particles, 1 % at 5,000; 1 / 4 per hour at 0.1 m/s: 4 % and 0 %). On the
#: moving tags (200 trials, 1,000 particles, share under 20 m, swimmer / shark pursuit)
#: 0.66 / 0.51 against 0.70 / 0.53 without (1 / 4 per hour at 0.1 m/s: 0.66 / 0.49; 0.5 / 1
#: per hour, 33 % resting, 0.58 / 0.50 over 100 trials): within the trial-to-trial noise
#: (±0.05 on a difference), though every resting setting measured lies a little below.
#: ``motion_model("hmm", resting=None)`` switches it off
HMM_RESTING = RestingState(enter_per_hour=0.5, leave_per_hour=2.0, drift_speed=0.05)


def bundled_model_path() -> Path:
    """Path of the bundled white-shark movement HMM (``hmmtrack/data/white_shark_hmm.json``)."""
    path = Path(str(resources.files("hmmtrack") / "data" / "white_shark_hmm.json"))
    if not path.is_file():
        raise FileNotFoundError(f"the bundled white-shark model is missing: {path}")
    return path


def motion_model(
    name: str,
    model: str | Path | object | None = None,
    variant: str = "time_consistent",
    heading_diffusion: float | None = None,
    resting: RestingState | None | str = "default",
):
    """One of the paper's motion models, by name, with hmmtrack's default parameters.

    Parameters
    ----------
    name : {"baseline", "velocity", "hmm"}
        ``baseline``: :class:`~hmmtrack.tracking.motion.BaselineMotion` with ``sigma`` =
        :data:`BASELINE_SIGMA`; ``velocity``: :class:`~hmmtrack.tracking.motion.VelocityMotion` with
        :data:`VELOCITY_SIGMA_SPEED` and :data:`VELOCITY_SIGMA_TURN_RATE`; ``hmm``:
        :class:`~hmmtrack.tracking.motion.HMMMotion` of ``model``.
    model : path, MovementHMM or None
        For ``hmm`` only: a saved model file, a fitted model, or ``None`` for the bundled
        white-shark model.
    variant : {"time_consistent", "paper"}
        For ``hmm`` only, see :class:`~hmmtrack.tracking.motion.HMMMotion`. ``"time_consistent"``
        (default) respects the time step the model was fitted at; ``"paper"`` is the
        paper's algorithm (new draws every prediction step).
    heading_diffusion : float, optional
        For ``hmm`` only: heading random walk (rad/√s) of
        :class:`~hmmtrack.tracking.motion.HMMMotion`; by default :data:`HMM_HEADING_DIFFUSION` in
        the
        time-consistent variant and 0 in the paper's.
    resting : RestingState, None or "default"
        For ``hmm`` only: add a resting state to the model
        (:meth:`~hmmtrack.hmm.MovementHMM.with_resting_state`), so that the filter can hold
        a tag that does not move (shed, dead, resting) although the fitted animal always
        swims; it costs moving tags little (measurements at :data:`HMM_RESTING`). The
        estimates' particles then carry ``K + 1`` states, the last one resting. ``"default"``:
        :data:`HMM_RESTING` in the time-consistent variant, none in the paper's; ``None``:
        the model as given.

    Returns
    -------
    A motion model for :class:`hmmtrack.tracking.filter.ParticleFilter`.
    """
    if name not in MOTIONS:
        raise ValueError(f"motion must be one of {MOTIONS}, got {name!r}")
    if name != "hmm" and (
        model is not None or heading_diffusion is not None or resting != "default"
    ):
        raise ValueError(
            "a movement model, heading diffusion and a resting state are used by motion 'hmm' "
            f"only, not {name!r}"
        )
    if name == "baseline":
        return BaselineMotion(sigma=BASELINE_SIGMA)
    if name == "velocity":
        return VelocityMotion(
            sigma_speed=VELOCITY_SIGMA_SPEED, sigma_turn_rate=VELOCITY_SIGMA_TURN_RATE
        )
    from hmmtrack.hmm import MovementHMM

    if model is None:
        model = bundled_model_path()
    if isinstance(model, str | Path):
        model = MovementHMM.load(model)
    if heading_diffusion is None:
        heading_diffusion = HMM_HEADING_DIFFUSION if variant == "time_consistent" else 0.0
    if isinstance(resting, str):
        if resting != "default":
            raise ValueError(f"resting must be a RestingState, None or 'default', got {resting!r}")
        resting = HMM_RESTING if variant == "time_consistent" else None
    if resting is not None:
        model = model.with_resting_state(
            resting.enter_per_hour,
            resting.leave_per_hour,
            resting_step=resting.drift_speed * model.dt / step_metres(model),
        )
    return HMMMotion(model, variant=variant, heading_diffusion=heading_diffusion)


def select_transmitter(detections: pd.DataFrame, transmitter: str | None) -> pd.DataFrame:
    """The detections of one transmitter.

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table.
    transmitter : str or None
        Transmitter to keep: full id (``A69-1602-15266``) or, when the table has a
        ``transmitter_id`` column (VUE and Fathom logs), its ID part (``15266``); ``None``
        requires the table to hold exactly one (or no ``transmitter`` column).

    Returns
    -------
    pandas.DataFrame
        The rows of that transmitter (the others are counted in a log message).
    """
    if "transmitter" not in detections.columns:
        if transmitter is None:  # (arrival-time detections of one tag may carry no id)
            return detections
        raise ValueError("detections table lacks column 'transmitter'")
    found = sorted(detections["transmitter"].astype(str).unique())
    if transmitter is None:
        if len(found) != 1:
            raise ValueError(
                f"the detections hold {len(found)} transmitters {found[:20]}; choose one "
                "(configuration key 'transmitter' or --transmitter)"
            )
        return detections
    keep = (detections["transmitter"].astype(str) == transmitter).to_numpy()
    if not keep.any() and "transmitter_id" in detections.columns:  # "15266" of "A69-1602-15266"
        keep = (detections["transmitter_id"].astype(str) == transmitter).to_numpy()
    if not keep.any():
        raise ValueError(
            f"no detections of transmitter {transmitter!r}; the table has {found[:20]}"
        )
    if not keep.all():
        logger.info(
            "tracking transmitter %s: %d detections, %d of other transmitters not used",
            transmitter,
            int(keep.sum()),
            int((~keep).sum()),
        )
    return detections.loc[keep]


def time_window(
    times, config: TrackingConfig, start: float | None = None, end: float | None = None
) -> tuple[float, float]:
    """Start and end (s) of a run: as given, else ``config.start``/``config.end``, else the
    first detection time rounded down and the last rounded up to whole seconds.

    Parameters
    ----------
    times : array_like, shape (n,)
        Detection times of the tracked transmitter (s), n ≥ 1.
    config : TrackingConfig
    start, end : float, optional
        Explicit window (s).
    """
    times = np.asarray(times, dtype=float)
    start = config.start if start is None else start
    end = config.end if end is None else end
    start = float(np.floor(times.min())) if start is None else float(start)
    end = float(np.ceil(times.max())) if end is None else float(end)
    return start, end


def build_observations(
    detections: pd.DataFrame, receivers: pd.DataFrame | ReceiverTracks, config: TrackingConfig
) -> pd.DataFrame:
    """The filter's observations of ``config.transmitter``, as ``config.measurement`` builds
    them (its ``observations``: :meth:`RangeRateMeasurement.observations
    <hmmtrack.tracking.measurement.range_rate.RangeRateMeasurement.observations>`,
    :func:`hmmtrack.tracking.measurement.clocked.arrival_observations`).

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table (``time`` s, ``receiver``, ``transmitter``; what else the
        measurement reads, e.g. ``depth`` m).
    receivers : pandas.DataFrame or ReceiverTracks
        Receiver positions table (``docs/interfaces.md``), or tracks built from it.
    config : TrackingConfig

    Raises
    ------
    ValueError
        When the transmitter is ambiguous or the measurement cannot build its observations
        (messages name what and where).
    """
    chosen = select_transmitter(detections, config.transmitter)
    return MEASUREMENTS[config.measurement].observations(chosen, receivers, config)


@dataclass(frozen=True)
class TrackingResult:
    """What :func:`track` returns, for every measurement.

    Attributes
    ----------
    estimates : pandas.DataFrame
        One row per prediction step: ``time`` (s), ``x``, ``y`` (m), ``var_x``, ``var_y``,
        ``cov_xy`` (m²), ``sqrt_lambda1`` (m), ``n_eff``.
    snapshots : dict of float to pandas.DataFrame
        Particles (``x``, ``y``, ..., ``weight``) at the requested snapshot times.
    events : pandas.DataFrame
        ``time``, ``kind``, ``detail``: the filter's events (degenerate weights, a
        re-acquired clock, ...) and the measurement's (the range-rate anchor detections not
        passed to the likelihood), by time.
    observations : pandas.DataFrame
        The observations table built from the detections (all of them, anchors included).
    bounds : (xmin, xmax, ymin, ymax)
        Search box the particles started in (m).
    smoothed : pandas.DataFrame or None
        Fixed-lag smoothed estimates (:data:`hmmtrack.tracking.smoothing.SMOOTHED_COLUMNS`),
        when a smoothing lag was given.
    ambiguity : pandas.DataFrame or None
        One row per correction (:data:`hmmtrack.tracking.diagnostics.AMBIGUITY_COLUMNS`),
        when recorded (the arrival-time measurement does).
    clock : pandas.DataFrame or None
        The estimated emission clock after each correction
        (:data:`hmmtrack.tracking.diagnostics.CLOCK_COLUMNS`; arrival-time measurement).
    """

    estimates: pd.DataFrame
    snapshots: dict
    events: pd.DataFrame
    observations: pd.DataFrame
    bounds: tuple[float, float, float, float]
    smoothed: pd.DataFrame | None = None
    ambiguity: pd.DataFrame | None = None
    clock: pd.DataFrame | None = None


def particle_filter(
    config: TrackingConfig, measurement, bounds, motion, *, seed: SeedLike = None, collect=()
) -> ParticleFilter:
    """The filter :func:`track` runs, not yet started (e.g. to step it online).

    Parameters
    ----------
    config : TrackingConfig
        Particles, resampling, prediction step and ``tempering_ess``.
    measurement : Measurement
        E.g. ``MEASUREMENTS[config.measurement].from_config(config, observations, receivers)``.
    bounds : (xmin, xmax, ymin, ymax)
        Search box (m).
    motion
        Motion model.
    seed : int, SeedSequence or Generator
    collect : sequence of collectors
        Besides the measurement's own (``measurement.collectors()``).

    Returns
    -------
    ParticleFilter
        Corrected by the measurement's default policy, or tempered at
        ``config.tempering_ess`` when set.
    """
    correction = (
        measurement.default_correction
        if config.tempering_ess is None
        else Tempered(config.tempering_ess)
    )
    return ParticleFilter(
        motion,
        measurement,
        n_particles=config.n_particles,
        bounds=bounds,
        resampling=config.resampling,
        resample_when=config.resample_when,
        ess_threshold=config.ess_threshold,
        rng=as_generator(seed),
        dt=config.prediction_step,
        correction=correction,
        collect=[*measurement.collectors(), *collect],
    )


def track(
    detections: pd.DataFrame,
    receivers: pd.DataFrame | ReceiverTracks,
    config: TrackingConfig,
    motion: str | object | None = None,
    *,
    model: str | Path | object | None = None,
    seed: SeedLike = None,
    start: float | None = None,
    end: float | None = None,
    snapshot_times: Sequence[float] = (),
    smoothing_lag: int | None = None,
    measurement=None,
    collect: Sequence = (),
) -> TrackingResult:
    """Estimate the tag's position every ``config.prediction_step`` seconds.

    Parameters
    ----------
    detections, receivers, config
        See :func:`build_observations`; ``config.measurement`` names the measurement.
    motion : {"baseline", "velocity", "hmm"}, motion model or None
        A name for :func:`motion_model`, or a motion model object; ``None`` (default): the
        one ``config`` names, with its noise (:meth:`TrackingConfig.motion_model`; "hmm" by
        default).
    model : path or MovementHMM, optional
        Movement HMM for ``motion="hmm"``; the bundled white-shark model when ``None``.
    seed : int, SeedSequence or Generator
        Seed of every random draw of the filter; the same seed gives the same estimates.
    start, end : float, optional
        Time window (s); by default ``config.start`` and ``config.end``, and when those are
        unset the first and last detection of the tracked transmitter, in whole seconds.
    snapshot_times : sequence of float
        Times (s) at which to keep copies of the particles.
    smoothing_lag : int, optional
        Steps (s) of a fixed-lag smoother (:class:`hmmtrack.tracking.smoothing.Smoothed`);
        its estimates are :attr:`TrackingResult.smoothed`.
    measurement : Measurement, optional
        The measurement to run instead of the one ``config`` builds (its class's
        ``from_config``), e.g. an arrival-time measurement with another clock model; it
        must be of the class ``config.measurement`` names.
    collect : sequence of collectors
        More collectors (:mod:`hmmtrack.tracking.diagnostics`) besides the measurement's.

    Returns
    -------
    TrackingResult
    """
    kind = MEASUREMENTS[config.measurement]
    observations = build_observations(detections, receivers, config)
    if observations.empty:
        raise ValueError("no detections to track from")
    if measurement is None:
        measurement = kind.from_config(config, observations, receivers)
    elif not isinstance(measurement, kind):
        raise ValueError(
            f"measurement {type(measurement).__name__} is not the configuration's "
            f"{config.measurement!r} ({kind.__name__})"
        )
    if motion is None:
        motion = config.motion_model(model)
    elif isinstance(motion, str):
        motion = motion_model(motion, model)
    elif model is not None:
        raise ValueError("model is used only with motion='hmm' given by name")
    bounds = measurement.start_box(
        observations, receivers, config, config.start if start is None else start
    )
    start, end = time_window(observations["time"].to_numpy(), config, start, end)
    scored, measurement_events = measurement.split(observations)
    collectors = [*collect]
    if smoothing_lag is not None:
        collectors.append(Smoothed(smoothing_lag))
    pf = particle_filter(config, measurement, bounds, motion, seed=seed, collect=collectors)
    result = pf.run(scored, start, end, snapshot_times)
    events = pd.concat(
        [df for df in (measurement_events, result.events) if not df.empty]
        or [pd.DataFrame(columns=list(EVENT_COLUMNS))],
        ignore_index=True,
    ).sort_values("time", kind="stable", ignore_index=True)
    return TrackingResult(
        estimates=result.estimates,
        snapshots=result.snapshots,
        events=events,
        observations=observations,
        bounds=tuple(float(b) for b in bounds),
        **result.collected,
    )
