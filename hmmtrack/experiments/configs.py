"""The tracker's settings for a synthetic scenario: what a study tells the filter about a case.

A scenario (:mod:`hmmtrack.scenarios`) is the synthetic world and knows nothing of the
tracker; these functions read the settings a tracker may be given from it (period, sound
speed, time window, initialisation box, and for the paper's method the true initial ranges)
and build a :class:`~hmmtrack.tracking.config.TrackingConfig`.

* :func:`tracking_config` — the paper's range-rate method on a
  :class:`~hmmtrack.scenarios.scenario.Scenario` (true ``r0`` and its box);
  :func:`scenario_settings` — the scenario's part of it as a configuration dictionary (the
  ``scenario.json`` of ``hmmtrack simulate``);
* :func:`arrival_config` — the arrival-time method on a
  :class:`~hmmtrack.scenarios.clocks.ClockScenario` (no initial range, the case's search box).
"""

from __future__ import annotations

from collections.abc import Mapping

from hmmtrack.scenarios.clocks import ClockScenario
from hmmtrack.scenarios.scenario import Scenario
from hmmtrack.tracking.config import TrackingConfig, merge_settings, nest


def scenario_settings(scenario: Scenario) -> dict:
    """What ``scenario`` tells the paper's range-rate method, as a configuration dictionary
    (the settings of the ``scenario.json`` that ``hmmtrack simulate`` writes).

    Returns
    -------
    dict
        ``transmitter``, ``bounds``, ``start``, ``end`` and the ``measurement`` section
        (``range-rate``: ``period``, ``sound_speed``, the true ``r0``).
    """
    return nest(
        {
            "transmitter": scenario.transmitter,
            "bounds": list(scenario.bounds),
            "start": scenario.start,
            "end": scenario.end,
            "measurement": "range-rate",
            "period": scenario.period,
            "sound_speed": scenario.sound_speed,
            "r0": dict(scenario.r0),
        }
    )


def tracking_config(scenario: Scenario, **changes) -> TrackingConfig:
    """The configuration that tracks ``scenario`` with the paper's range-rate method.

    Parameters
    ----------
    scenario : Scenario
    **changes
        Settings by key that differ from the scenario's (e.g. ``n_particles``, ``depth``;
        ``bounds=None`` derives the search box from ``r0``).

    Returns
    -------
    TrackingConfig
        ``period``, ``r0``, ``sound_speed``, ``transmitter``, ``bounds``, ``start`` and
        ``end`` from the scenario, the rest from ``changes`` or the defaults.
    """
    keys = {
        "period": scenario.period,
        "r0": dict(scenario.r0),
        "sound_speed": scenario.sound_speed,
        "transmitter": scenario.transmitter,
        "bounds": scenario.bounds,
        "start": scenario.start,
        "end": scenario.end,
    }
    return TrackingConfig.from_keys(**(keys | changes))


def arrival_config(
    case: ClockScenario,
    settings: Mapping | None = None,
    duration: float | None = None,
    *,
    silences: bool = True,
) -> TrackingConfig:
    """The configuration that tracks ``case`` from arrival times, with no initial range.

    Parameters
    ----------
    case : ClockScenario
    settings : mapping, optional
        A configuration dictionary (e.g. a preset's,
        :func:`hmmtrack.tracking.config.read_preset`); the case's own keys below win over it.
    duration : float, optional
        Track the first ``duration`` seconds (s); default: the whole scenario.
    silences : bool
        Give the filter the case's detection curve
        (:attr:`~hmmtrack.scenarios.clocks.ClockScenario.detection_probability`), so that
        the pings a receiver should have heard and did not count; False for a run without
        it (missed pings carry no information, as ``hmmtrack track`` runs without
        ``--detection-curve``, and as an online filter must run: the silence model reads
        the whole detection table).

    Returns
    -------
    TrackingConfig
        ``measurement="arrival-time"`` unless ``settings`` say otherwise, with the case's
        mean period, :attr:`~hmmtrack.scenarios.clocks.ClockScenario.search_bounds`, time
        window, sound speed and (``silences``) detection curve.
    """
    sc = case.scenario
    end = sc.end if duration is None else sc.start + duration
    window = {
        "period": sc.period,
        "bounds": case.search_bounds,
        "start": sc.start,
        "end": end,
        "sound_speed": sc.sound_speed,
        "detection_curve": case.detection_probability if silences else None,
    }
    layers = (nest({"measurement": "arrival-time"}), settings or {}, nest(window))
    return TrackingConfig.from_dict(merge_settings(*layers), source="arrival_config")
