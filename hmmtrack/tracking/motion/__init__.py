"""Motion models of the tracking filter: how particles move between corrections.

Every model satisfies :class:`MotionModel` (:mod:`hmmtrack.tracking.motion.base`): a NumPy
reference step ``propagate(rng, particles, dt)`` and, when ``compiled``, a fast path
``advance(...)`` that fuses many steps into one numba kernel drawing from per-particle random
streams (same equations; ``tests/test_motion.py`` checks them against each other).

Models (the paper's section "Motion Models")
--------------------------------------------
:class:`BaselineMotion`
    Random walk in position (:mod:`~hmmtrack.tracking.motion.baseline`).
:class:`VelocityMotion`
    Random walks in speed and turn rate, moving along constant-turn-rate arcs
    (:mod:`~hmmtrack.tracking.motion.velocity`, :mod:`~hmmtrack.tracking.motion.arcs`).
:class:`HMMMotion`
    Speed and turn rate drawn from the behavioural state of a fitted movement HMM, along
    arcs (:mod:`~hmmtrack.tracking.motion.hmm`; variants :data:`HMM_VARIANTS`).

:data:`MOTIONS` and :func:`motion_model` give them by name with hmmtrack's defaults
(:mod:`~hmmtrack.tracking.motion.registry`). The models do not read files, weigh or resample
particles.
"""

from hmmtrack.tracking.motion.base import MotionModel
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.motion.hmm import HMM_VARIANTS, HMMMotion
from hmmtrack.tracking.motion.registry import (
    BASELINE_SIGMA,
    HMM_GPS_SPEED_DIFFUSION,
    HMM_HEADING_DIFFUSION,
    HMM_RESTING,
    HMM_STILL_RESTING,
    MOTIONS,
    VELOCITY_GPS,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
    VELOCITY_STILL,
    VELOCITY_STILL_DURATION,
    RestingState,
    bundled_model_path,
    default_resting,
    motion_model,
    still_regimes,
)
from hmmtrack.tracking.motion.velocity import VelocityMotion

__all__ = [
    "BASELINE_SIGMA",
    "HMM_GPS_SPEED_DIFFUSION",
    "HMM_HEADING_DIFFUSION",
    "HMM_RESTING",
    "HMM_STILL_RESTING",
    "HMM_VARIANTS",
    "MOTIONS",
    "VELOCITY_GPS",
    "VELOCITY_SIGMA_SPEED",
    "VELOCITY_SIGMA_TURN_RATE",
    "VELOCITY_STILL",
    "VELOCITY_STILL_DURATION",
    "BaselineMotion",
    "HMMMotion",
    "MotionModel",
    "RestingState",
    "VelocityMotion",
    "bundled_model_path",
    "default_resting",
    "motion_model",
    "still_regimes",
]
