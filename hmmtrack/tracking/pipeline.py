"""The tracking pipeline: detections + receiver positions + configuration → position estimates.

:func:`build_observations` turns a detections table into the filter's observations table
(``docs/interfaces.md``): ranges and range-rates from :mod:`hmmtrack.tracking.measurement.ranging`
(optionally
depth-corrected), each joined with the detecting receiver's position and velocity at the
detection time from :class:`hmmtrack.tracking.receivers.ReceiverTracks`.

:func:`track` runs the paper's particle filter (:class:`hmmtrack.tracking.filter.ParticleFilter`
with :class:`hmmtrack.tracking.measurement.range_rate.RangeRateMeasurement`) on those observations
with one
of the paper's motion models chosen by name (:func:`motion_model`): ``"baseline"``,
``"velocity"`` or ``"hmm"`` (a saved :class:`hmmtrack.hmm.MovementHMM`, by default the
bundled white-shark model ``hmmtrack/data/white_shark_hmm.json``), to which the
time-consistent variant adds a resting state by default (:data:`HMM_RESTING`: a tag may be
shed, its animal dead or resting; ``motion_model("hmm", resting=None)`` switches it off).

:func:`expected_measurements` gives the true (range, range-rate) of each observation
from a known tag track, to estimate Σ_z from a calibration segment or a simulation.

The first detection of each receiver anchors its ranges (its range is the given ``r0``)
but has no range-rate, so it is not passed to the paper's (range, range-rate) likelihood;
:func:`track` records each such detection as an ``"anchor_detection"`` event.

Defaults and the paper's configuration
---------------------------------------
The paper leaves the noise levels, measurement covariance and particle count unstated;
the defaults here and in :class:`hmmtrack.tracking.config.TrackingConfig` were chosen on the
synthetic analogues of its three datasets (stationary tag, swimmer, shark pursuit; 10-20
trials per cell at 1,000 particles, fixed seeds; the measurements are quoted beside each
constant). With them, mean (median) error after convergence over 20 trials, baseline /
velocity / HMM: stationary tag 3.4 (3.5) / 3.3 (3.2) / 4.2 (3.6) m; swimmer 108 (132) /
32 (3.5) / 32 (4.3) m; shark pursuit 898 (903) / 39 (12) / 37 (9.9) m (the HMM with its
resting state, :data:`HMM_RESTING`; without it 7.2 (5.9) / 29 (4.2) / 34 (9.8) m). Most of
the swimmer's mean comes from trials that settle on the mirror intersection of the two range
circles (20-25 % of them for velocity and HMM); at
:class:`~hmmtrack.tracking.config.TrackingConfig`'s
default of 5,000 particles none of 20 did (velocity 5.4 m, HMM 5.3 m), the baseline still
in 85 %. The shark-pursuit trials are bimodal at either count (about 9 m, or about 70 m
when the filter follows the mirror for the first 45 minutes). The paper's algorithm stays reachable:
``TrackingConfig(resampling="multinomial", resample_when="always")`` with
``motion_model("hmm", variant="paper")``; on the same trials it gives HMM errors of 76 / 53 /
325 m (the paper variant under-disperses headings, see :class:`hmmtrack.tracking.motion.HMMMotion`).

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

from hmmtrack.analysis import metrics
from hmmtrack.random import SeedLike, as_generator
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.measurement import ranging
from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement
from hmmtrack.tracking.motion import BaselineMotion, HMMMotion, VelocityMotion, step_metres
from hmmtrack.tracking.receivers import ReceiverTracks

__all__ = [
    "MOTIONS",
    "HMM_RESTING",
    "OBSERVATION_COLUMNS",
    "RestingState",
    "TrackingResult",
    "build_observations",
    "bundled_model_path",
    "check_bounds",
    "expected_measurements",
    "motion_model",
    "search_bounds",
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

#: columns of the observations table, in order (``docs/interfaces.md`` plus the
#: transmitter and the pings missed since the receiver's previous detection)
OBSERVATION_COLUMNS = (
    "time",
    "receiver",
    "transmitter",
    "range",
    "range_rate",
    "missed_pings",
    "receiver_x",
    "receiver_y",
    "receiver_vx",
    "receiver_vy",
)


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
        requires the table to hold exactly one.

    Returns
    -------
    pandas.DataFrame
        The rows of that transmitter (the others are counted in a log message).
    """
    if "transmitter" not in detections.columns:
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


def _depth_corrected(table: pd.DataFrame, detections: pd.DataFrame, config: TrackingConfig):
    """Replace ranges by horizontal ranges and recompute range-rates, per receiver."""
    if config.depth == "none":
        return table
    if config.depth == "sensor":
        if "depth" not in detections.columns:
            raise ValueError(
                "depth policy 'sensor' needs a 'depth' column (m) in the detections; "
                f"found {list(detections.columns)}"
            )
        depth_of = detections[["time", "receiver", "depth"]].astype({"receiver": str})
        merged = table.merge(depth_of, on=["time", "receiver"], how="left", validate="1:1")
        depth = merged["depth"].to_numpy(dtype=float)
        missing = np.flatnonzero(~np.isfinite(depth))
        if missing.size:
            raise ValueError(
                f"depth policy 'sensor': no depth reading for detection(s) at times "
                f"{table['time'].iloc[missing[:10]].tolist()} (receivers "
                f"{table['receiver'].iloc[missing[:10]].tolist()})"
            )
    else:
        depth = np.full(len(table), float(config.depth))
    table = table.copy()
    table["range"] = ranging.depth_correction(
        table["range"].to_numpy(), depth, shallower=config.shallower
    )
    for _, rows in table.groupby(["receiver", "transmitter"], sort=False).groups.items():
        table.loc[rows, "range_rate"] = ranging.range_rates(
            table.loc[rows, "time"].to_numpy(), table.loc[rows, "range"].to_numpy()
        )
    return table


def build_observations(
    detections: pd.DataFrame, receivers: pd.DataFrame | ReceiverTracks, config: TrackingConfig
) -> pd.DataFrame:
    """Observations table of the filter from detections, receiver positions and config.

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table (``time`` s, ``receiver``, ``transmitter``; ``depth`` m for the
        ``"sensor"`` depth policy).
    receivers : pandas.DataFrame or ReceiverTracks
        Receiver positions table (``docs/interfaces.md``), turned into tracks with
        ``config.velocity_window``, or tracks built from it.
    config : TrackingConfig
        Period, sound speed, ``r0`` per receiver, transmitter, depth policy.

    Returns
    -------
    pandas.DataFrame
        One row per detection of the tracked transmitter, sorted by time, with
        :data:`OBSERVATION_COLUMNS`: ``range`` (m), ``range_rate`` (m/s; NaN on each
        receiver's first detection), ``missed_pings``, and the receiver's position (m) and
        velocity (m/s) at the detection time.

    Raises
    ------
    ValueError
        When the transmitter is ambiguous, a receiver lacks ``r0`` or positions at a
        detection time, or a depth correction is impossible (messages name what and where).
    """
    tracks = (
        receivers
        if isinstance(receivers, ReceiverTracks)
        else ReceiverTracks.from_frame(receivers, velocity_window=config.velocity_window)
    )
    chosen = select_transmitter(detections, config.transmitter)
    table = ranging.range_table(chosen, config.period, config.r0, config.sound_speed)
    table = _depth_corrected(table, chosen, config)
    unknown = sorted(set(table["receiver"]) - set(tracks.names))
    if unknown:
        raise ValueError(
            f"no positions for receiver(s) {unknown} of the detections; receiver positions "
            f"are known for {list(tracks.names)}"
        )
    state = np.empty((len(table), 4))
    for receiver, rows in table.groupby("receiver", sort=False).indices.items():
        state[rows] = np.column_stack(tracks.state(receiver, table["time"].to_numpy()[rows]))
    for k, column in enumerate(("receiver_x", "receiver_y", "receiver_vx", "receiver_vy")):
        table[column] = state[:, k]
    return table[list(OBSERVATION_COLUMNS)]


def expected_measurements(observations: pd.DataFrame, truth: pd.DataFrame) -> np.ndarray:
    """True (range, range-rate) at each observation, from a known tag track.

    For a calibration segment or a simulation: with
    :func:`hmmtrack.tracking.measurement.ranging.estimate_measurement_covariance` it gives Σ_z from
    data, e.g.
    ``estimate_measurement_covariance(obs[["range", "range_rate"]], expected_measurements(
    obs, truth))`` over the rows whose range-rate is defined.

    Parameters
    ----------
    observations : pandas.DataFrame
        Observations table (:func:`build_observations`).
    truth : pandas.DataFrame
        ``time`` (s), ``x``, ``y`` (m) of the tag; one row for a fixed tag. The tag's
        velocity is the slope of the truth track (zero for one row).

    Returns
    -------
    numpy.ndarray, shape (n, 2)
        Range (m) and range-rate (m/s) the receivers' logged states and the true tag track
        imply, with the paper's equations (as the filter predicts them for a particle).
    """
    times = observations["time"].to_numpy(dtype=float)
    x, y = metrics.truth_at(truth, times)
    vx = np.zeros_like(times)
    vy = np.zeros_like(times)
    if len(truth) > 1:
        ordered = truth.sort_values("time")
        t_true = ordered["time"].to_numpy(dtype=float)
        vx = np.interp(times, t_true, np.gradient(ordered["x"].to_numpy(dtype=float), t_true))
        vy = np.interp(times, t_true, np.gradient(ordered["y"].to_numpy(dtype=float), t_true))
    dx = observations["receiver_x"].to_numpy(dtype=float) - x
    dy = observations["receiver_y"].to_numpy(dtype=float) - y
    dvx = observations["receiver_vx"].to_numpy(dtype=float) - vx
    dvy = observations["receiver_vy"].to_numpy(dtype=float) - vy
    r = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        rate = np.where(r > 0, (dx * dvx + dy * dvy) / r, 0.0)
    return np.column_stack([r, rate])


def search_bounds(
    observations: pd.DataFrame, r0: dict[str, float], margin: float
) -> tuple[float, float, float, float]:
    """Box that holds the tag at the start: each receiver's first position ± (r0 + margin).

    Parameters
    ----------
    observations : pandas.DataFrame
        Observations table (:func:`build_observations`).
    r0 : dict of str to float
        Range at each receiver's first detection (m).
    margin : float
        Extra margin (m).

    Returns
    -------
    (xmin, xmax, ymin, ymax) : tuple of float
        The union of the receivers' squares (m): the tag lies inside each receiver's square
        at that receiver's first detection.
    """
    if observations.empty:
        raise ValueError("no observations to derive search bounds from; give bounds explicitly")
    first = observations.drop_duplicates("receiver", keep="first")
    reach = first["receiver"].map(r0).to_numpy(dtype=float) + margin
    x, y = first["receiver_x"].to_numpy(), first["receiver_y"].to_numpy()
    return (
        float((x - reach).min()),
        float((x + reach).max()),
        float((y - reach).min()),
        float((y + reach).max()),
    )


def check_bounds(
    bounds: tuple[float, float, float, float],
    observations: pd.DataFrame,
    r0: dict[str, float],
    margin: float,
) -> None:
    """Refuse search bounds that cannot hold the tag at the receivers' first detections.

    At its first detection, receiver ``j`` is ``r0[j]`` from the tag, so the box must come
    within ``r0[j] + margin`` of where the receiver was (e.g. bounds given in another frame
    than the receivers fail this).

    Raises
    ------
    ValueError
        Naming the receiver, its position and the bounds.
    """
    xmin, xmax, ymin, ymax = bounds
    first = observations.drop_duplicates("receiver", keep="first")
    for name, x, y in first[["receiver", "receiver_x", "receiver_y"]].itertuples(index=False):
        gap = np.hypot(max(xmin - x, 0.0, x - xmax), max(ymin - y, 0.0, y - ymax))
        if gap > r0[name] + margin:
            raise ValueError(
                f"search bounds {tuple(bounds)} lie {gap:.0f} m from receiver {name!r} at "
                f"({x:.1f}, {y:.1f}) m, farther than its r0 ({r0[name]:.1f} m) + margin "
                f"({margin:.0f} m): are the bounds in the receivers' frame?"
            )


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


@dataclass(frozen=True)
class TrackingResult:
    """What :func:`track` returns.

    Attributes
    ----------
    estimates : pandas.DataFrame
        One row per prediction step: ``time`` (s), ``x``, ``y`` (m), ``var_x``, ``var_y``,
        ``cov_xy`` (m²), ``sqrt_lambda1`` (m), ``n_eff``.
    snapshots : dict of float to pandas.DataFrame
        Particles (``x``, ``y``, ..., ``weight``) at the requested snapshot times.
    events : pandas.DataFrame
        ``time``, ``kind``, ``detail``: the filter's events (degenerate weights, ...) and
        the anchor detections not passed to the likelihood.
    observations : pandas.DataFrame
        The observations table built from the detections (all of them, anchors included).
    bounds : (xmin, xmax, ymin, ymax)
        Search box the particles started in (m).
    """

    estimates: pd.DataFrame
    snapshots: dict
    events: pd.DataFrame
    observations: pd.DataFrame
    bounds: tuple[float, float, float, float]


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
) -> TrackingResult:
    """Estimate the tag's position every ``config.prediction_step`` seconds.

    Parameters
    ----------
    detections, receivers, config
        See :func:`build_observations`.
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

    Returns
    -------
    TrackingResult
    """
    observations = build_observations(detections, receivers, config)
    if observations.empty:
        raise ValueError("no detections to track from")
    if motion is None:
        motion = config.motion_model(model)
    elif isinstance(motion, str):
        motion = motion_model(motion, model)
    elif model is not None:
        raise ValueError("model is used only with motion='hmm' given by name")
    bounds = config.bounds or search_bounds(observations, config.r0, config.bounds_margin)
    check_bounds(bounds, observations, config.r0, config.bounds_margin)
    start, end = time_window(observations["time"].to_numpy(), config, start, end)
    anchors = observations["range_rate"].isna().to_numpy()
    pf = ParticleFilter(
        motion,
        RangeRateMeasurement(np.array(config.measurement_covariance)),
        n_particles=config.n_particles,
        bounds=bounds,
        resampling=config.resampling,
        resample_when=config.resample_when,
        ess_threshold=config.ess_threshold,
        rng=as_generator(seed),
        dt=config.prediction_step,
    )
    result = pf.run(observations.loc[~anchors], start, end, snapshot_times)
    anchor_events = pd.DataFrame(
        {
            "time": observations.loc[anchors, "time"].to_numpy(),
            "kind": "anchor_detection",
            "detail": [
                f"first detection of receiver {r}: range r0 = {d:.1f} m anchors its ranges; "
                "no range-rate, not used in the likelihood"
                for r, d in observations.loc[anchors, ["receiver", "range"]].itertuples(index=False)
            ],
        }
    )
    events = pd.concat(
        [df for df in (anchor_events, result.events) if not df.empty]
        or [pd.DataFrame(columns=["time", "kind", "detail"])],
        ignore_index=True,
    ).sort_values("time", kind="stable", ignore_index=True)
    return TrackingResult(
        estimates=result.estimates,
        snapshots=result.snapshots,
        events=events,
        observations=observations,
        bounds=tuple(float(b) for b in bounds),
    )
