"""Tests of the bundled presets and the model settings of :mod:`hmmtrack.tracking.config`."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from hmmtrack.tracking import config as config_module
from hmmtrack.tracking.config import (
    DATA_KEYS,
    TrackingConfig,
    measurement_covariance_with,
    merge_settings,
    preset_names,
    read_preset,
)
from hmmtrack.tracking.measurement.arrival_time import ArrivalLikelihood, ArrivalTimeMeasurement
from hmmtrack.tracking.measurement.clocked import (
    SEARCH_RADIUS,
    TEMPERING_ESS,
    ClockedArrivalTime,
    default_clock_model,
)
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.motion import VELOCITY_SIGMA_SPEED, HMMMotion, VelocityMotion, motion_model
from hmmtrack.tracking.tempering import Tempered

PRESET = "two-moving-receivers"


def test_two_receiver_preset_holds_the_settings_tuned_on_the_observable_plan():
    """The preset gives the arrival-time filter the settings tuned on the observable plan
    (reports/two_auv_plan.md): σ 1.2 ms, VelocityMotion(0.1, 0.003) (the default speed
    spread, twice the earlier tuning's 0.05, so that particles keep up with a shark that
    speeds up; a turn rate that wanders about 7 times less than the default's), tempering
    below 30 % of the particles, 4,000 particles; and the benchmark's search box (240 m
    around the receivers, the scenario's detection reach)."""
    config = TrackingConfig.from_dict(read_preset(PRESET) | {"period": 8.0})
    assert (config.measurement, config.motion) == ("arrival-time", "velocity")
    assert config.motion_model() == VelocityMotion(sigma_speed=0.1, sigma_turn_rate=0.003)
    measurement = arrival_measurement(config)
    assert measurement.arrival == ArrivalTimeMeasurement(
        ArrivalLikelihood(sigma=1.2e-3), sound_speed=config.sound_speed
    )
    assert config.tempering_ess == 0.3
    assert measurement.search_radius == 240.0
    assert config.n_particles == 4000
    assert measurement.clock == default_clock_model(8.0)


def test_every_bundled_preset_is_settings_only_and_valid():
    names = preset_names()
    assert PRESET in names
    for name in names:
        settings = read_preset(name)
        assert settings and not set(settings) & set(DATA_KEYS)
        assert "description" not in settings  # descriptive text is dropped
        TrackingConfig.from_dict(settings | {"period": 2.0}, source=name)


def test_unknown_preset_names_the_available_ones():
    with pytest.raises(ValueError, match=f"unknown preset 'nope'; available presets: {PRESET}"):
        read_preset("nope")


def test_a_preset_may_not_hold_data_or_unknown_keys(tmp_path, monkeypatch):
    monkeypatch.setattr(config_module, "PRESET_DIR", tmp_path)
    (tmp_path / "with-period.json").write_text(json.dumps({"period": 8.0, "n_particles": 10}))
    (tmp_path / "typo.json").write_text(json.dumps({"n_particle": 10, "description": "x"}))
    assert preset_names() == ["typo", "with-period"]
    with pytest.raises(ValueError, match=r"with-period.json: key\(s\) \['period'\] are not"):
        read_preset("with-period")
    with pytest.raises(ValueError, match=r"key\(s\) \['n_particle'\]"):
        read_preset("typo")


def test_later_layers_win_and_r0_merges_by_receiver():
    """Preset < file < command line; ``None`` is "not given"."""
    preset = {"n_particles": 4000, "tempering_ess": 0.6, "arrival_sigma": 1.2e-3}
    file = {"period": 8.0, "n_particles": 2000, "tempering_ess": 0.5, "r0": {"a": 1.0, "b": 2.0}}
    flags = {"n_particles": 1000, "tempering_ess": None, "r0": {"b": 5.0}}
    merged = merge_settings(preset, file, flags)
    assert merged == {
        "n_particles": 1000,
        "tempering_ess": 0.5,
        "arrival_sigma": 1.2e-3,
        "period": 8.0,
        "r0": {"a": 1.0, "b": 5.0},
    }
    assert merge_settings(preset, file)["n_particles"] == 2000
    assert merge_settings(preset)["n_particles"] == 4000


def test_default_models_are_those_of_the_trackers():
    """Without model settings a configuration names the trackers' defaults, so a run
    without a preset is what it was before the settings existed."""
    plain = TrackingConfig(period=8.0)
    assert (plain.measurement, plain.motion) == ("range-rate", "hmm")
    assert isinstance(plain.motion_model(), HMMMotion)
    velocity = TrackingConfig(period=8.0, motion="velocity")
    assert velocity.motion_model() == motion_model("velocity")
    assert TrackingConfig(period=8.0, motion="velocity", sigma_turn_rate=0.01).motion_model() == (
        VelocityMotion(VELOCITY_SIGMA_SPEED, 0.01)
    )
    arrival = arrival_measurement(TrackingConfig(period=8.0, measurement="arrival-time"))
    assert arrival.search_radius == SEARCH_RADIUS
    assert arrival.default_correction == Tempered(TEMPERING_ESS)
    assert arrival.arrival == ArrivalTimeMeasurement(sound_speed=plain.sound_speed)
    with pytest.raises(ValueError, match="motion 'hmm' only"):
        velocity.motion_model(model="shark.json")
    with pytest.raises(ValueError, match="motion 'hmm' only"):
        velocity.motion_model(resting=None)
    fitted = plain.motion_model(resting=None).model.n_states
    assert plain.motion_model().model.n_states == fitted + 1  # the resting state by default


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"measurement": "toa"}, "measurement must be one of"),
        ({"motion": "levy"}, "motion must be one of"),
        ({"sigma_speed": 0.05}, "sigma_speed is a setting of motion 'velocity', not 'hmm'"),
        ({"motion": "velocity", "sigma_turn_rate": -0.1}, "sigma_turn_rate must be a non-neg"),
        ({"motion": "velocity", "sigma_speed": "fast"}, "sigma_speed must be a number"),
        ({"arrival_sigma": 1e-3}, "arrival_sigma is a setting of measurement 'arrival-time'"),
        ({"measurement": "arrival-time", "arrival_sigma": 0}, "arrival_sigma must be a positive"),
        ({"measurement": "arrival-time", "tempering_ess": 1.5}, r"tempering_ess must lie in"),
        ({"measurement": "arrival-time", "tempering_ess": float("nan")}, "finite"),
        ({"search_radius": 200.0}, "search_radius is a setting of measurement 'arrival-time'"),
        ({"measurement": "arrival-time", "search_radius": -5}, "search_radius must be a pos"),
    ],
)
def test_model_settings_are_validated(change, message):
    with pytest.raises(ValueError, match=message):
        TrackingConfig(**({"period": 8.0} | change))


def test_a_preset_with_the_other_measurement_is_a_clear_error():
    with pytest.raises(ValueError, match=r"cli: (\w+) is a setting of measurement 'arrival-time'"):
        TrackingConfig.from_dict(
            merge_settings(read_preset(PRESET), {"period": 8.0, "measurement": "range-rate"}),
            source="cli",
        )


def arrival_measurement(config):
    """The arrival-time measurement ``config`` builds, for one detection at a receiver."""
    receivers = pd.DataFrame({"receiver": ["a"], "time": [np.nan], "x": [0.0], "y": [0.0]})
    detections = pd.DataFrame({"time": [5.0], "receiver": ["a"]})
    observations = ClockedArrivalTime.observations(detections, receivers)
    return ClockedArrivalTime.from_config(config, observations, receivers)


def test_detection_curve_setting_round_trips_and_reaches_the_arrival_time_measurement():
    """A mapping or a LogisticDetection; JSON round trip; the curve becomes the arrival-time
    measurement's silence model's; absent, it has no silence model."""
    config = TrackingConfig(
        period=8.0, measurement="arrival-time", detection_curve={"range_50": 160, "width": "40"}
    )
    assert config.detection_curve == LogisticDetection(range_50=160.0, width=40.0)
    assert arrival_measurement(config).silence.detection is config.detection_curve
    data = json.loads(json.dumps(config.to_dict()))
    assert data["detection_curve"] == {"range_50": 160.0, "width": 40.0}
    assert TrackingConfig.from_dict(data) == config
    same = TrackingConfig(
        period=8.0, measurement="arrival-time", detection_curve=LogisticDetection(160.0, 40.0)
    )
    assert same == config
    plain = TrackingConfig(period=8.0, measurement="arrival-time")
    assert arrival_measurement(plain).silence is None
    assert TrackingConfig.from_dict(json.loads(json.dumps(plain.to_dict()))) == plain


@pytest.mark.parametrize(
    ("curve", "message"),
    [
        ({"range_50": 160}, r'detection_curve must be \{"range_50": metres, "width": metres\}'),
        ([160, 40], "detection_curve must be"),
        ({"range_50": 160, "width": 40, "slope": 1}, "detection_curve must be"),
        ({"range_50": 160, "width": "wide"}, "detection_curve width must be a number"),
        ({"range_50": float("nan"), "width": 40}, "detection_curve range_50 must be a finite"),
        ({"range_50": 160, "width": 0}, "positive width"),
        (LogisticDetection(160.0, 40.0, max_probability=0.9), "max_probability 1"),
    ],
)
def test_bad_detection_curves_are_clear_errors(curve, message):
    with pytest.raises(ValueError, match=message):
        TrackingConfig(period=8.0, measurement="arrival-time", detection_curve=curve)


def test_detection_curve_is_refused_for_the_range_rate_measurement():
    with pytest.raises(ValueError, match=r"file.json: detection_curve is a setting of measure"):
        TrackingConfig.from_dict(
            {"period": 8.0, "detection_curve": {"range_50": 160, "width": 40}},
            source="file.json",
        )


def test_a_preset_may_carry_a_detection_curve(tmp_path, monkeypatch):
    monkeypatch.setattr(config_module, "PRESET_DIR", tmp_path)
    settings = {"measurement": "arrival-time", "detection_curve": {"range_50": 90, "width": 15}}
    (tmp_path / "reef.json").write_text(json.dumps(settings))
    config = TrackingConfig.from_dict(read_preset("reef") | {"period": 30.0})
    assert arrival_measurement(config).silence.detection == LogisticDetection(90.0, 15.0)


def test_measurement_covariance_with_new_standard_deviations():
    """Σ_z = [[σ_r², ρ σ_r σ_ṙ], [ρ σ_r σ_ṙ, σ_ṙ²]]: the given σ replace the old ones, ρ
    stays (here 0.3 / (3 × 0.2) = 0.5)."""
    covariance = [[9.0, 0.3], [0.3, 0.04]]
    np.testing.assert_allclose(
        measurement_covariance_with(covariance, sigma_range=6.0), [[36.0, 0.6], [0.6, 0.04]]
    )
    np.testing.assert_allclose(
        measurement_covariance_with(covariance, sigma_range_rate=0.1),
        [[9.0, 0.15], [0.15, 0.01]],
    )
    np.testing.assert_allclose(measurement_covariance_with(covariance), covariance)
    np.testing.assert_allclose(
        measurement_covariance_with(((25.0, 0.0), (0.0, 0.25)), 2.0, 0.3),
        [[4.0, 0.0], [0.0, 0.09]],
    )
    new = np.array(measurement_covariance_with(covariance, 4.0, 0.7))
    rho = new[0, 1] / np.sqrt(new[0, 0] * new[1, 1])
    assert rho == pytest.approx(0.5) and np.linalg.eigvalsh(new).min() > 0
    with pytest.raises(ValueError, match="sigma_range must be a positive finite number"):
        measurement_covariance_with(covariance, sigma_range=0.0)
    with pytest.raises(ValueError, match="sigma_range_rate must be a finite number"):
        measurement_covariance_with(covariance, sigma_range_rate=float("inf"))
    with pytest.raises(ValueError, match="positive definite"):
        measurement_covariance_with([[1, 2], [2, 1]], sigma_range=1.0)
