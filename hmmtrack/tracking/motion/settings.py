"""The ``motion`` section of a tracking configuration: one settings class per motion model.

:data:`MOTION_SETTINGS` maps each motion model's name (``"baseline"``, ``"velocity"``,
``"hmm"``) to its settings class, whose fields are that model's settings with the defaults
of :func:`hmmtrack.tracking.motion.motion_model`; :meth:`build` makes the model. A
configuration file names the model and any settings that differ, e.g.
``{"name": "hmm", "model": "shark.json", "variant": "paper"}``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.motion.hmm import HMM_VARIANTS
from hmmtrack.tracking.motion.registry import (
    BASELINE_SIGMA,
    HMM_GPS_SPEED_DIFFUSION,
    HMM_HEADING_DIFFUSION,
    HMM_RESTING,
    HMM_STILL_RESTING,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
    default_resting,
    motion_model,
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

__all__ = ["MOTION_SETTINGS", "BaselineSettings", "HMMSettings", "VelocitySettings"]


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


@dataclass(frozen=True)
class VelocitySettings(Settings):
    """Settings of :class:`~hmmtrack.tracking.motion.VelocityMotion`.

    Parameters
    ----------
    sigma_speed : float
        Spread of the speed increments (m/s per √s).
    sigma_turn_rate : float
        Spread of the turn-rate increments (rad/s per √s).
    jump_rate : float
        Expected number of speed jumps per second (0: none, the paper's model).
    jump_sd : float
        Spread of one speed jump (m/s).
    turn_reversion : float or None
        Reversion time of the turn rate to zero (s; an Ornstein-Uhlenbeck turn rate);
        ``None``: none, the paper's random walk.
    """

    name: ClassVar[str] = "velocity"

    sigma_speed: float = setting(
        VELOCITY_SIGMA_SPEED,
        help="spread of the speed increments (m/s per sqrt(s))",
        check=non_negative,
        parse=float,
        metavar="M_PER_S",
    )
    sigma_turn_rate: float = setting(
        VELOCITY_SIGMA_TURN_RATE,
        help="spread of the turn-rate increments (rad/s per sqrt(s))",
        check=non_negative,
        parse=float,
        metavar="RAD_PER_S",
    )
    jump_rate: float = setting(
        0.0,
        help=(
            "expected number of speed jumps per second, each N(0, jump_sd^2) m/s beside the "
            "speed's random walk (an animal whose speed changes at once)"
        ),
        check=non_negative,
        parse=float,
        metavar="PER_S",
    )
    jump_sd: float = setting(
        0.0,
        help="spread of one speed jump (m/s)",
        check=non_negative,
        parse=float,
        metavar="M_PER_S",
    )
    turn_reversion: float | None = setting(
        None,
        help=(
            "reversion time of the turn rate to zero (s): an Ornstein-Uhlenbeck turn rate, "
            "whose heading diffuses where the walk's circles"
        ),
        check=positive,
        parse=float,
        metavar="SECONDS",
        default_text="none (the paper's random walk)",
    )

    def build(self) -> VelocityMotion:
        """The motion model."""
        return VelocityMotion(
            sigma_speed=self.sigma_speed,
            sigma_turn_rate=self.sigma_turn_rate,
            jump_rate=self.jump_rate,
            jump_sd=self.jump_sd,
            turn_reversion=self.turn_reversion,
        )


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
