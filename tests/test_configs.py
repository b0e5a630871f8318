"""Tests of hmmtrack.experiments.configs: a scenario's settings carried into the tracker's."""

from __future__ import annotations

from hmmtrack.experiments.configs import arrival_config, tracking_config
from hmmtrack.scenarios.paper import stationary_tag
from hmmtrack.scenarios.realistic import moored_array


def test_tracking_config_carries_the_scenario_settings_and_the_changes():
    s = stationary_tag(2)
    config = tracking_config(s, n_particles=321, depth="sensor")
    assert (config.period, config.sound_speed, config.transmitter) == (
        s.period,
        s.sound_speed,
        s.transmitter,
    )
    assert dict(config.r0) == s.r0 and tuple(config.bounds) == s.bounds
    assert (config.start, config.end, config.n_particles, config.depth) == (
        s.start,
        s.end,
        321,
        "sensor",
    )
    assert tracking_config(s, bounds=None).bounds is None


def test_arrival_config_takes_the_case_window_over_the_settings():
    case = moored_array(3, duration=600.0)
    sc = case.scenario
    config = arrival_config(case, {"n_particles": 123, "period": 99.0, "start": 0.0}, 300.0)
    assert config.measurement == "arrival-time" and config.n_particles == 123
    assert (config.period, config.start, config.end) == (sc.period, sc.start, sc.start + 300.0)
    assert tuple(config.bounds) == case.search_bounds and not config.r0
    assert arrival_config(case).end == sc.end
