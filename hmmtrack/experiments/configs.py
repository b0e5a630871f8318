"""The tracker's settings for a synthetic scenario: what a study tells the filter about a case.

A scenario (:mod:`hmmtrack.scenarios`) is the synthetic world and knows nothing of the
tracker; these functions read the settings a tracker may be given from it (period, sound
speed, time window, initialisation box, and for the paper's method the true initial ranges)
and build a :class:`~hmmtrack.tracking.config.TrackingConfig`.

* :func:`tracking_config` — the paper's range-rate method on a
  :class:`~hmmtrack.scenarios.scenario.Scenario` (true ``r0`` and its box);
* :func:`arrival_config` — the arrival-time method on a
  :class:`~hmmtrack.scenarios.clocks.ClockScenario` (no initial range, the case's search box).
"""

from __future__ import annotations

from collections.abc import Mapping

from hmmtrack.scenarios.clocks import ClockScenario
from hmmtrack.scenarios.scenario import Scenario
from hmmtrack.tracking.config import TrackingConfig


def tracking_config(scenario: Scenario, **changes) -> TrackingConfig:
    """The configuration that tracks ``scenario`` with the paper's range-rate method.

    Parameters
    ----------
    scenario : Scenario
    **changes
        Settings that differ from the scenario's (e.g. ``n_particles``, ``depth``).

    Returns
    -------
    TrackingConfig
        ``period``, ``r0``, ``sound_speed``, ``transmitter``, ``bounds``, ``start`` and
        ``end`` from the scenario, the rest from ``changes`` or the defaults.
    """
    settings = {
        "period": scenario.period,
        "r0": dict(scenario.r0),
        "sound_speed": scenario.sound_speed,
        "transmitter": scenario.transmitter,
        "bounds": scenario.bounds,
        "start": scenario.start,
        "end": scenario.end,
    }
    return TrackingConfig(**(settings | changes))


def arrival_config(
    case: ClockScenario, settings: Mapping | None = None, duration: float | None = None
) -> TrackingConfig:
    """The configuration that tracks ``case`` from arrival times, with no initial range.

    Parameters
    ----------
    case : ClockScenario
    settings : mapping, optional
        Keys of :class:`~hmmtrack.tracking.config.TrackingConfig` (e.g. a preset's,
        :func:`hmmtrack.tracking.config.read_preset`); the case's own keys below win over them.
    duration : float, optional
        Track the first ``duration`` seconds (s); default: the whole scenario.

    Returns
    -------
    TrackingConfig
        ``measurement="arrival-time"`` unless ``settings`` say otherwise, with the case's
        mean period, :attr:`~hmmtrack.scenarios.clocks.ClockScenario.search_bounds`, time
        window and sound speed.
    """
    sc = case.scenario
    end = sc.end if duration is None else sc.start + duration
    window = {
        "period": sc.period,
        "bounds": case.search_bounds,
        "start": sc.start,
        "end": end,
        "sound_speed": sc.sound_speed,
    }
    return TrackingConfig.from_dict({"measurement": "arrival-time", **(settings or {}), **window})
