"""The ``motion`` section of a tracking configuration: one settings class per motion model.

:data:`MOTION_SETTINGS` maps each motion model's name (``"baseline"``, ``"velocity"``,
``"hmm"``) to its settings class, whose fields are that model's settings with the defaults
of :func:`hmmtrack.tracking.motion.motion_model`; :meth:`build` makes the model. A
configuration file names the model and any settings that differ, e.g.
``{"name": "hmm", "model": "shark.json", "variant": "paper"}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.motion.hmm import HMM_VARIANTS
from hmmtrack.tracking.motion.registry import (
    BASELINE_SIGMA,
    HMM_HEADING_DIFFUSION,
    HMM_RESTING,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
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

    def build(self) -> VelocityMotion:
        """The motion model."""
        return VelocityMotion(sigma_speed=self.sigma_speed, sigma_turn_rate=self.sigma_turn_rate)


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

    def build(self, model=None):
        """The motion model; ``model`` (a fitted MovementHMM or a path) replaces
        :attr:`model`."""
        resting = {True: HMM_RESTING, False: None, None: "default"}[self.resting]
        return motion_model(
            "hmm",
            self.model if model is None else model,
            variant=self.variant,
            heading_diffusion=self.heading_diffusion,
            resting=resting,
        )


#: motion settings classes by motion model name
MOTION_SETTINGS: dict[str, type] = {
    cls.name: cls for cls in (BaselineSettings, VelocitySettings, HMMSettings)
}
