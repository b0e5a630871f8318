"""Tests of hmmtrack.experiments.configs: a scenario's settings carried into the tracker's."""

from __future__ import annotations

import json

from hmmtrack.experiments.configs import arrival_config, scenario_settings, tracking_config
from hmmtrack.scenarios.paper import stationary_tag
from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.tracking.config import TrackingConfig


def test_tracking_config_carries_the_scenario_settings_and_the_changes():
    s = stationary_tag(2)
    config = tracking_config(s, n_particles=321, depth="sensor")
    measurement = config.measurement
    assert (measurement.period, measurement.sound_speed, config.transmitter) == (
        s.period,
        s.sound_speed,
        s.transmitter,
    )
    assert dict(measurement.r0) == s.r0 and tuple(config.bounds) == s.bounds
    assert (config.start, config.end, config.filter.n_particles, measurement.depth) == (
        s.start,
        s.end,
        321,
        "sensor",
    )
    assert tracking_config(s, bounds=None).bounds is None


def test_scenario_settings_are_the_configuration_of_the_scenario():
    """What ``hmmtrack simulate`` writes as scenario.json reads back as the scenario's
    range-rate configuration."""
    s = stationary_tag(2)
    settings = json.loads(json.dumps(scenario_settings(s)))
    assert TrackingConfig.from_dict(settings) == tracking_config(s)
    assert settings["measurement"]["name"] == "range-rate"


def test_arrival_config_takes_the_case_window_over_the_settings():
    case = moored_array(3, duration=600.0)
    sc = case.scenario
    settings = {"filter": {"n_particles": 123}, "measurement": {"period": 99.0}, "start": 0.0}
    config = arrival_config(case, settings, 300.0)
    assert config.measurement.name == "arrival-time" and config.filter.n_particles == 123
    window = (config.measurement.period, config.start, config.end)
    assert window == (sc.period, sc.start, sc.start + 300.0)
    assert tuple(config.bounds) == case.search_bounds and not hasattr(config.measurement, "r0")
    assert arrival_config(case).end == sc.end


def test_arrival_config_gives_the_case_detection_curve_unless_told_not_to():
    """The case's detection curve reaches the filter (the two-AUV study's runs "with the
    curve" had lost it on the way and equalled the runs without)."""
    case = moored_array(3, duration=600.0)
    assert arrival_config(case).measurement.detection_curve == case.detection_probability
    assert arrival_config(case, silences=False).measurement.detection_curve is None
