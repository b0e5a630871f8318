"""Synthetic data with ground truth: white-shark tracks, detection logs and the paper's datasets.

The paper's field data are not public, so hmmtrack ships analogues built from documented
models. One module per job:

* :mod:`~hmmtrack.scenarios.trajectory` — exact continuous-time paths;
* :mod:`~hmmtrack.scenarios.shark_motion` — the ground-truth white-shark movement HMM;
* :mod:`~hmmtrack.scenarios.historical` — "historical" tracks sampled like a receiver array;
* :mod:`~hmmtrack.scenarios.detection` — emission clocks, acoustic paths, detection loss, GPS;
* :mod:`~hmmtrack.scenarios.scenario` — the :class:`Scenario` container;
* :mod:`~hmmtrack.scenarios.paper` — the paper's three datasets;
* :mod:`~hmmtrack.scenarios.thinning` — even measurement thinning for the loss sweep;
* :mod:`~hmmtrack.scenarios.white_shark_hmm` — the bundled motion model: fit, load, compare
  with the ground truth (imports :mod:`hmmtrack.hmm`, so it is not imported here);
* :mod:`~hmmtrack.scenarios.export` — write a scenario as the files ``hmmtrack track`` reads.
"""

from hmmtrack.scenarios.detection import (
    ExponentialDetection,
    GpsNoise,
    JitteredPeriodClock,
    simulate_pings,
)
from hmmtrack.scenarios.historical import white_shark_tracks
from hmmtrack.scenarios.paper import shark_pursuit, stationary_tag, swimmer
from hmmtrack.scenarios.scenario import Scenario
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH, SharkMotionModel
from hmmtrack.scenarios.thinning import thin_evenly
from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.detection import LogisticDetection

#: the scenario generators by their command-line names
GENERATORS = {
    "stationary-tag": stationary_tag,
    "swimmer": swimmer,
    "shark-pursuit": shark_pursuit,
}

__all__ = [
    "GENERATORS",
    "WHITE_SHARK_GROUND_TRUTH",
    "ExponentialDetection",
    "GpsNoise",
    "JitteredPeriodClock",
    "LogisticDetection",
    "Scenario",
    "SharkMotionModel",
    "Trajectory",
    "shark_pursuit",
    "simulate_pings",
    "stationary_tag",
    "swimmer",
    "thin_evenly",
    "white_shark_tracks",
]
