"""The paper's motion models by name, with hmmtrack's default parameters.

:data:`MOTIONS` maps each name (``"baseline"``, ``"velocity"``, ``"hmm"``) to a factory of
that model with the defaults below; :func:`motion_model` is the one entry point that
configurations, the command line and the experiments call. The paper gives no noise
levels: the defaults were chosen on the synthetic analogues of its three datasets (the
trials are in ``reports/decisions.md``, "Motion models"). The HMM model is by default the
bundled white-shark model (:func:`bundled_model_path`) with a resting state added
(:data:`HMM_RESTING`) in the time-consistent variant.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from hmmtrack.tracking.motion.base import MotionModel
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.motion.hmm import HMMMotion, step_metres
from hmmtrack.tracking.motion.regimes import Regime, VelocityRegimes
from hmmtrack.tracking.motion.velocity import VelocityMotion

__all__ = [
    "BASELINE_SIGMA",
    "HMM_GPS_SPEED_DIFFUSION",
    "HMM_HEADING_DIFFUSION",
    "HMM_RESTING",
    "HMM_STILL_RESTING",
    "MOTIONS",
    "VELOCITY_SIGMA_SPEED",
    "VELOCITY_SIGMA_TURN_RATE",
    "VELOCITY_GPS",
    "VELOCITY_STILL",
    "VELOCITY_STILL_DURATION",
    "RestingState",
    "bundled_model_path",
    "default_resting",
    "motion_model",
    "still_regimes",
]

#: random-walk step spread of the baseline model (m per √s): small enough that the cloud
#: keeps the early detections that tell a fixed tag from its mirror position
BASELINE_SIGMA = 0.3
#: spreads of the velocity model's speed (m/s per √s) and turn-rate (rad/s per √s)
#: increments: speed must follow a swimming animal, turn rates change slowly
VELOCITY_SIGMA_SPEED = 0.1
VELOCITY_SIGMA_TURN_RATE = 0.02
#: the velocity model's still regime (:func:`still_regimes`): a tag that holds still, its
#: speed reverting to zero in 0.5 s (so that a speed jump barely moves a still particle) and
#: its turn rate in 2 s, with small walks (m/s and rad/s per √s) that part resampled copies
#: (reports/decisions.md, "A sticky still regime for the velocity model")
VELOCITY_STILL = Regime(0.005, 0.005, speed_reversion=0.5, turn_reversion=2.0)
#: mean time (s) a particle of the velocity model stays in :data:`VELOCITY_STILL` once it
#: has entered it, when the settings give an entry rate and no duration: 30 min, as the HMM's
#: resting state (:data:`HMM_RESTING`, left twice an hour)
VELOCITY_STILL_DURATION = 1800.0
#: the velocity model's settings under a measurement that parts a still cloud's copies itself
#: and narrows the regions enough to show the speed walk's width (``range-rate-gps``): a
#: smaller speed walk (m/s per √s) with speed jumps (per s, m/s) that follow a sudden change
#: of speed, and a still regime entered twice in four hours and left twice an hour, as the
#: HMM's resting state (reports/decisions.md, "A sticky still regime for the velocity model")
VELOCITY_GPS = {
    "sigma_speed": 0.05,
    "jump_rate": 1 / 60,
    "jump_sd": 0.4,
    "still_rate": 1 / 7200,
}
#: heading random walk (rad/√s) of the HMM motion model in its time-consistent variant
#: (:class:`~hmmtrack.tracking.motion.HMMMotion`): lets the resampled copies of a particle,
#: which hold one speed and turn rate for the fitted step, part; kept small for the
#: swimming animals the model was fitted to
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
#: shed, its animal dead or resting, although the bundled white-shark model always swims;
#: mean rest 30 min, 20 % of the particles resting under the prior, a slow drift so that
#: resampled copies of a resting particle do not pile up on one point.
#: ``motion_model("hmm", resting=None)`` switches it off
HMM_RESTING = RestingState(enter_per_hour=0.5, leave_per_hour=2.0, drift_speed=0.05)
#: resting state of the HMM motion model under a measurement that spreads a still cloud
#: itself (the ``range-rate-gps`` measurement's translation move re-draws every particle's
#: position from its own conditional posterior): :data:`HMM_RESTING`'s rates, and a resting
#: tag that holds still. The default's drift is there only to part resampled copies; as a
#: motion it makes a still tag's regions about 1.2 times too wide along its best-measured
#: line of sight (reports/decisions.md, "A resting tag that holds still")
HMM_STILL_RESTING = RestingState(enter_per_hour=0.5, leave_per_hour=2.0, drift_speed=0.002)
#: log-speed random walk (per √s) of the HMM motion model's swimming states under a
#: measurement that narrows the cloud enough for its few distinct held speeds to show (the
#: ``range-rate-gps`` measurement): resampling copies held speeds exactly, and 1,000
#: particles kept about 30 distinct ones, so the cloud's centre wandered along the motion.
#: Chosen among 0-0.07 on seeds 25-29: the moving shark's regions are calibrated on both
#: axes at 0.07 (reports/decisions.md, "The gps option's overconfidence on the moving shark"
#: and "The HMM's held speed as a log-speed random walk")
HMM_GPS_SPEED_DIFFUSION = 0.07


def still_regimes(moving: Regime, still_rate: float, still_duration: float) -> VelocityRegimes:
    """Two regimes of the velocity model: moving, and still (:data:`VELOCITY_STILL`).

    Parameters
    ----------
    moving : Regime
        The moving regime's walks (the model's own speed and turn-rate settings).
    still_rate : float
        Rate (1/s, > 0) at which a moving particle enters the still regime.
    still_duration : float
        Mean time (s, > 0) a particle stays still: it leaves at rate ``1 / still_duration``.

    Returns
    -------
    VelocityRegimes
        Regimes ``(moving, VELOCITY_STILL)`` (a particle's ``state`` 0 moving, 1 still) with
        generator ``((-still_rate, still_rate), (1 / still_duration, -1 / still_duration))``.
    """
    if not (math.isfinite(still_rate) and still_rate > 0):
        raise ValueError(f"still_rate must be a number > 0, got {still_rate}")
    if not (math.isfinite(still_duration) and still_duration > 0):
        raise ValueError(f"still_duration must be a number > 0, got {still_duration}")
    rates = ((0.0, still_rate), (1.0 / still_duration, 0.0))
    return VelocityRegimes((moving, VELOCITY_STILL), rates)


def default_resting(variant: str) -> RestingState | None:
    """The resting state the HMM motion model gets by default in ``variant``:
    :data:`HMM_RESTING` in the time-consistent variant, none in the paper's."""
    return HMM_RESTING if variant == "time_consistent" else None


#: file name of the bundled white-shark model in the package data
BUNDLED_MODEL = "white_shark_hmm.json"


def bundled_model_path() -> Path:
    """Path of the bundled white-shark movement HMM (``hmmtrack/data/white_shark_hmm.json``)."""
    path = Path(str(resources.files("hmmtrack") / "data" / BUNDLED_MODEL))
    if not path.is_file():
        raise FileNotFoundError(f"the bundled white-shark model is missing: {path}")
    return path


def _baseline() -> BaselineMotion:
    return BaselineMotion(sigma=BASELINE_SIGMA)


def _velocity() -> VelocityMotion:
    return VelocityMotion(
        sigma_speed=VELOCITY_SIGMA_SPEED, sigma_turn_rate=VELOCITY_SIGMA_TURN_RATE
    )


def _hmm(
    model: str | Path | object | None = None,
    variant: str = "time_consistent",
    heading_diffusion: float | None = None,
    resting: RestingState | None | str = "default",
    speed_diffusion: float = 0.0,
) -> HMMMotion:
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
        resting = default_resting(variant)
    spread: float | tuple[float, ...] = speed_diffusion
    if resting is not None:
        swimming = model.n_states
        model = model.with_resting_state(
            resting.enter_per_hour,
            resting.leave_per_hour,
            resting_step=resting.drift_speed * model.dt / step_metres(model),
        )
        if speed_diffusion > 0.0:  # a resting tag holds its drift
            spread = (speed_diffusion,) * swimming + (0.0,)
    return HMMMotion(
        model, variant=variant, heading_diffusion=heading_diffusion, speed_diffusion=spread
    )


#: the paper's motion models, by name: a factory of each with hmmtrack's defaults (the
#: ``"hmm"`` factory takes :func:`motion_model`'s HMM options)
MOTIONS: dict[str, Callable[..., MotionModel]] = {
    "baseline": _baseline,
    "velocity": _velocity,
    "hmm": _hmm,
}


def motion_model(
    name: str,
    model: str | Path | object | None = None,
    variant: str = "time_consistent",
    heading_diffusion: float | None = None,
    resting: RestingState | None | str = "default",
    speed_diffusion: float = 0.0,
) -> MotionModel:
    """One of the paper's motion models, by name, with hmmtrack's default parameters.

    Parameters
    ----------
    name : {"baseline", "velocity", "hmm"}
        ``baseline``: :class:`~hmmtrack.tracking.motion.BaselineMotion` with ``sigma`` =
        :data:`BASELINE_SIGMA`; ``velocity``: :class:`~hmmtrack.tracking.motion.VelocityMotion`
        with :data:`VELOCITY_SIGMA_SPEED` and :data:`VELOCITY_SIGMA_TURN_RATE`; ``hmm``:
        :class:`~hmmtrack.tracking.motion.HMMMotion` of ``model``.
    model : path, MovementHMM or None
        For ``hmm`` only: a saved model file, a fitted model, or ``None`` for the bundled
        white-shark model.
    variant : {"time_consistent", "paper"}
        For ``hmm`` only, see :class:`~hmmtrack.tracking.motion.HMMMotion`.
        ``"time_consistent"`` (default) respects the time step the model was fitted at;
        ``"paper"`` is the paper's algorithm (new draws every prediction step).
    heading_diffusion : float, optional
        For ``hmm`` only: heading random walk (rad/√s) of
        :class:`~hmmtrack.tracking.motion.HMMMotion`; by default :data:`HMM_HEADING_DIFFUSION`
        in the time-consistent variant and 0 in the paper's.
    resting : RestingState, None or "default"
        For ``hmm`` only: add a resting state to the model
        (:meth:`~hmmtrack.hmm.MovementHMM.with_resting_state`), so that the filter can hold
        a tag that does not move (shed, dead, resting) although the fitted animal always
        swims; it costs moving tags little (measurements at :data:`HMM_RESTING`). The
        estimates' particles then carry ``K + 1`` states, the last one resting. ``"default"``:
        :data:`HMM_RESTING` in the time-consistent variant, none in the paper's; ``None``:
        the model as given.
    speed_diffusion : float
        For ``hmm`` only: random walk of the log of the held speed (per √s) of
        :class:`~hmmtrack.tracking.motion.HMMMotion`, in the fitted model's states; the
        resting state keeps its drift. 0 (default): none.

    Returns
    -------
    MotionModel
        A motion model for :class:`hmmtrack.tracking.filter.ParticleFilter`.
    """
    if name not in MOTIONS:
        raise ValueError(f"motion must be one of {tuple(MOTIONS)}, got {name!r}")
    if name != "hmm":
        if (
            model is not None
            or heading_diffusion is not None
            or resting != "default"
            or speed_diffusion != 0.0
        ):
            raise ValueError(
                "a movement model, heading and speed diffusion and a resting state are used by "
                f"motion 'hmm' only, not {name!r}"
            )
        return MOTIONS[name]()
    return MOTIONS[name](model, variant, heading_diffusion, resting, speed_diffusion)
