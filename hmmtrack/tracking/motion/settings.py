"""The ``motion`` section of a tracking configuration: one settings class per motion model.

:data:`MOTION_SETTINGS` maps each motion model's name (``"baseline"``, ``"velocity"``,
``"hmm"``) to its settings class, whose fields are that model's settings with the defaults
of :func:`hmmtrack.tracking.motion.motion_model`; :meth:`build` makes the model. A setting
whose default is ``None``, "the measurement's", takes the value the run's measurement gives
it (:data:`hmmtrack.tracking.config.MEASUREMENT_MOTIONS`), else the library's when the model
is built. A configuration file names the model and any settings that differ, e.g.
``{"name": "hmm", "model": "shark.json", "variant": "paper"}`` or
``{"name": "velocity", "still_rate": 0.0005}`` (the velocity model with a still regime,
:func:`hmmtrack.tracking.motion.still_regimes`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.motion.hmm import HMM_VARIANTS
from hmmtrack.tracking.motion.regimes import Regime
from hmmtrack.tracking.motion.registry import (
    BASELINE_SIGMA,
    HMM_GPS_SPEED_DIFFUSION,
    HMM_HEADING_DIFFUSION,
    HMM_RESTING,
    HMM_STILL_RESTING,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
    VELOCITY_STILL,
    VELOCITY_STILL_DURATION,
    default_resting,
    motion_model,
    still_regimes,
)
from hmmtrack.tracking.motion.velocity import VelocityMotion
from hmmtrack.tracking.settings import (
    Settings,
    boolean,
    non_negative,
    one_of,
    positive,
    setting,
    text,
)

__all__ = [
    "MOTION_SETTINGS",
    "VELOCITY_LIBRARY",
    "BaselineSettings",
    "HMMSettings",
    "VelocitySettings",
]


@dataclass(frozen=True)
class BaselineSettings(Settings):
    """Settings of :class:`~hmmtrack.tracking.motion.BaselineMotion` (a random walk).

    Parameters
    ----------
    sigma_position : float
        Spread of the position steps (m per √s).
    """

    name: ClassVar[str] = "baseline"

    sigma_position: float = setting(
        BASELINE_SIGMA,
        help="spread of the baseline random walk's position steps (m per sqrt(s))",
        check=positive,
        parse=float,
        metavar="M_PER_SQRT_S",
    )

    def build(self) -> BaselineMotion:
        """The motion model."""
        return BaselineMotion(sigma=self.sigma_position)


#: the velocity settings a measurement may fill in (``None`` in :class:`VelocitySettings`),
#: with the library's values where neither the section nor the measurement gives one: today's
#: model (the paper's walks, no jumps, no still regime)
VELOCITY_LIBRARY = {
    "sigma_speed": VELOCITY_SIGMA_SPEED,
    "jump_rate": 0.0,
    "jump_sd": 0.0,
    "still_rate": 0.0,
    "still_duration": VELOCITY_STILL_DURATION,
}


def _measured(key: str, help: str, check, metavar: str):
    """A velocity setting left to the measurement: ``None`` by default, a float when given,
    its help saying the library's value (:data:`VELOCITY_LIBRARY`)."""
    default_text = f"the measurement's, else {VELOCITY_LIBRARY[key]:g}"
    return setting(
        None, help=help, check=check, parse=float, metavar=metavar, default_text=default_text
    )


@dataclass(frozen=True)
class VelocitySettings(Settings):
    """Settings of :class:`~hmmtrack.tracking.motion.VelocityMotion`.

    A setting that defaults to ``None`` is the measurement's
    (:data:`hmmtrack.tracking.config.MEASUREMENT_MOTIONS`, filled in by
    :func:`hmmtrack.tracking.config.measurement_motion`), else the library's
    (:data:`VELOCITY_LIBRARY`: today's model, the paper's walks without jumps or a still
    regime).

    Parameters
    ----------
    sigma_speed : float or None
        Spread of the speed increments (m/s per √s) of a moving particle; ``None``: the
        measurement's, else :data:`~hmmtrack.tracking.motion.VELOCITY_SIGMA_SPEED` (0.1).
    sigma_turn_rate : float
        Spread of the turn-rate increments (rad/s per √s) of a moving particle.
    jump_rate : float or None
        Expected number of speed jumps per second (0: none, the paper's model); ``None``: the
        measurement's, else 0.
    jump_sd : float or None
        Spread of one speed jump (m/s); ``None``: the measurement's, else 0.
    turn_reversion : float or None
        Reversion time of a moving particle's turn rate to zero (s; an Ornstein-Uhlenbeck
        turn rate); ``None``: none, the paper's random walk.
    still_rate : float or None
        Rate (1/s) at which a moving particle enters the still regime
        (:data:`~hmmtrack.tracking.motion.VELOCITY_STILL`; the two regimes of
        :func:`~hmmtrack.tracking.motion.still_regimes`); 0: no still regime, today's model;
        ``None``: the measurement's, else 0.
    still_duration : float or None
        Mean time (s, > 0) a particle stays in the still regime (it leaves at rate
        ``1 / still_duration``), used when ``still_rate`` > 0; ``None``: the measurement's,
        else :data:`~hmmtrack.tracking.motion.VELOCITY_STILL_DURATION` (1,800 s).
    """

    name: ClassVar[str] = "velocity"

    sigma_speed: float | None = _measured(
        "sigma_speed",
        "spread of a moving particle's speed increments (m/s per sqrt(s))",
        non_negative,
        "M_PER_S",
    )
    sigma_turn_rate: float = setting(
        VELOCITY_SIGMA_TURN_RATE,
        help="spread of a moving particle's turn-rate increments (rad/s per sqrt(s))",
        check=non_negative,
        parse=float,
        metavar="RAD_PER_S",
    )
    jump_rate: float | None = _measured(
        "jump_rate",
        "expected number of speed jumps per second, each N(0, jump_sd^2) m/s beside the "
        "speed's random walk (an animal whose speed changes at once)",
        non_negative,
        "PER_S",
    )
    jump_sd: float | None = _measured(
        "jump_sd", "spread of one speed jump (m/s)", non_negative, "M_PER_S"
    )
    turn_reversion: float | None = setting(
        None,
        help=(
            "reversion time of a moving particle's turn rate to zero (s): an "
            "Ornstein-Uhlenbeck turn rate, whose heading diffuses where the walk's circles"
        ),
        check=positive,
        parse=float,
        metavar="SECONDS",
        default_text="none (the paper's random walk)",
    )
    still_rate: float | None = _measured(
        "still_rate",
        "rate at which a moving particle enters the still regime (per s), whose speed "
        f"reverts to zero in {VELOCITY_STILL.speed_reversion:g} s and turn rate in "
        f"{VELOCITY_STILL.turn_reversion:g} s; 0: no still regime",
        non_negative,
        "PER_S",
    )
    still_duration: float | None = _measured(
        "still_duration",
        "mean time a particle stays in the still regime (s), with a still rate",
        positive,
        "SECONDS",
    )

    def build(self) -> VelocityMotion:
        """The motion model; settings left to the measurement (``None``) take the library's
        values (:data:`VELOCITY_LIBRARY`), a configuration fills them in from its measurement
        first (:meth:`hmmtrack.tracking.config.TrackingConfig.motion_model`). A still rate of
        0 builds today's model (no regimes); a positive one, two regimes
        (:func:`~hmmtrack.tracking.motion.still_regimes`): moving, with the speed and turn
        settings and ``turn_reversion``, and still."""
        value = {
            key: library if getattr(self, key) is None else getattr(self, key)
            for key, library in VELOCITY_LIBRARY.items()
        }
        walks = {"sigma_speed": value["sigma_speed"], "sigma_turn_rate": self.sigma_turn_rate}
        jumps = {"jump_rate": value["jump_rate"], "jump_sd": value["jump_sd"]}
        if value["still_rate"] == 0.0:
            return VelocityMotion(**walks, **jumps, turn_reversion=self.turn_reversion)
        moving = Regime(**walks, turn_reversion=self.turn_reversion)
        regimes = still_regimes(moving, value["still_rate"], value["still_duration"])
        return VelocityMotion(**walks, **jumps, regimes=regimes)


@dataclass(frozen=True)
class HMMSettings(Settings):
    """Settings of :class:`~hmmtrack.tracking.motion.HMMMotion` (a fitted movement HMM).

    Parameters
    ----------
    model : str or None
        Saved :class:`hmmtrack.hmm.MovementHMM` (JSON; a relative path in a configuration
        file is relative to that file); ``None``: the bundled white-shark model.
    variant : {"time_consistent", "paper"}
        ``"time_consistent"`` respects the time step the model was fitted at; ``"paper"``
        redraws speed, turn and state every prediction step (the paper's algorithm).
    heading_diffusion : float or None
        Heading random walk (rad/√s); ``None``: the variant's (0.2 time-consistent, 0 paper).
    resting : bool or None
        Add the resting state :data:`hmmtrack.tracking.motion.HMM_RESTING` (a tag may be
        shed, its animal dead or resting); ``None``: the variant's (on time-consistent, off
        paper).
    resting_drift : float or None
        Mean speed (m/s, > 0) of a resting tag, when the model has the resting state;
        ``None``: the measurement's (:data:`hmmtrack.tracking.config.MEASUREMENT_MOTIONS`:
        0.002 under ``range-rate-gps``), else :data:`~hmmtrack.tracking.motion.HMM_RESTING`'s
        0.05.
    speed_diffusion : float or None
        Random walk of the log of the held speed (per √s) of the swimming states
        (:class:`~hmmtrack.tracking.motion.HMMMotion`); ``None``: the measurement's
        (:data:`~hmmtrack.tracking.config.MEASUREMENT_MOTIONS`:
        :data:`~hmmtrack.tracking.motion.HMM_GPS_SPEED_DIFFUSION` under ``range-rate-gps``),
        else 0.
    """

    name: ClassVar[str] = "hmm"

    model: str | None = setting(
        None,
        help="movement HMM JSON (hmmtrack fit)",
        check=text,
        metavar="PATH",
        default_text="the bundled white shark",
    )
    variant: str = setting(
        "time_consistent",
        help=(
            "time_consistent respects the time step the model was fitted at (state switches "
            "and speed/turn draws per fitted step, plus a small heading random walk); paper "
            "redraws speed, turn and state every second whatever that step (the paper's "
            "algorithm; under-disperses headings for a model fitted at a coarser step)"
        ),
        check=one_of(*HMM_VARIANTS),
        option="hmm-variant",
        choices=HMM_VARIANTS,
    )
    heading_diffusion: float | None = setting(
        None,
        help="heading random walk (rad/sqrt(s))",
        check=non_negative,
        parse=float,
        metavar="RAD_PER_SQRT_S",
        default_text=f"{HMM_HEADING_DIFFUSION:g} time-consistent, 0 paper",
    )
    resting: bool | None = setting(
        None,
        help=(
            "add a resting state to the movement HMM (a tag may be shed, its animal dead or "
            f"resting; entered {HMM_RESTING.enter_per_hour:g} and left "
            f"{HMM_RESTING.leave_per_hour:g} times per hour)"
        ),
        check=boolean,
        default_text="on time-consistent, off paper",
    )
    resting_drift: float | None = setting(
        None,
        help=(
            "mean speed of a resting tag (m/s), when the model has the resting state; a "
            "measurement that parts a still cloud's copies itself (range-rate-gps) holds it "
            "nearly still"
        ),
        check=positive,
        parse=float,
        metavar="M_PER_S",
        default_text=(
            f"{HMM_STILL_RESTING.drift_speed:g} for range-rate-gps, "
            f"else {HMM_RESTING.drift_speed:g}"
        ),
    )
    speed_diffusion: float | None = setting(
        None,
        help=(
            "random walk of the log of the swimming states' held speed (per sqrt(s)): parts "
            "resampled copies in speed; under range-rate-gps the narrow regions need it"
        ),
        check=non_negative,
        parse=float,
        metavar="PER_SQRT_S",
        default_text=f"{HMM_GPS_SPEED_DIFFUSION:g} for range-rate-gps, else 0",
    )

    def build(self, model=None):
        """The motion model; ``model`` (a fitted MovementHMM or a path) replaces
        :attr:`model`. Settings left to the measurement (``None``) take the defaults of
        :func:`hmmtrack.tracking.motion.motion_model`; a configuration fills them in from its
        measurement first (:meth:`hmmtrack.tracking.config.TrackingConfig.motion_model`)."""
        resting = (
            default_resting(self.variant)
            if self.resting is None
            else (HMM_RESTING if self.resting else None)
        )
        if resting is not None and self.resting_drift is not None:
            resting = dataclasses.replace(resting, drift_speed=self.resting_drift)
        return motion_model(
            "hmm",
            self.model if model is None else model,
            variant=self.variant,
            heading_diffusion=self.heading_diffusion,
            resting=resting,
            speed_diffusion=self.speed_diffusion or 0.0,
        )


#: motion settings classes by motion model name
MOTION_SETTINGS: dict[str, type] = {
    cls.name: cls for cls in (BaselineSettings, VelocitySettings, HMMSettings)
}
