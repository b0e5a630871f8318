"""Tests of :mod:`hmmtrack.tracking.config`: sections, their settings classes, presets, layers."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from hmmtrack.tracking import config as config_module
from hmmtrack.tracking.config import (
    MEASUREMENT_FILTERS,
    SECTIONS,
    TrackingConfig,
    merge_settings,
    nest,
    preset_names,
    read_preset,
    read_settings,
    section_classes,
    setting_sections,
)
from hmmtrack.tracking.filter import DEFAULT_FILTER, FILTERS, FilterSettings
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.arrival_time import ArrivalLikelihood, ArrivalTimeMeasurement
from hmmtrack.tracking.measurement.clocked import (
    SEARCH_RADIUS,
    TEMPERING_ESS,
    ArrivalTimeSettings,
    ClockedArrivalTime,
    default_clock_model,
)
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement, RangeRateSettings
from hmmtrack.tracking.motion import (
    MOTIONS,
    VELOCITY_SIGMA_SPEED,
    HMMMotion,
    VelocityMotion,
    motion_model,
)
from hmmtrack.tracking.motion.settings import (
    MOTION_SETTINGS,
    BaselineSettings,
    HMMSettings,
    VelocitySettings,
)
from hmmtrack.tracking.tempering import Tempered

PRESET = "two-moving-receivers"


def with_period(settings: dict, period: float = 8.0) -> dict:
    """``settings`` (a configuration dictionary) with the measurement's period."""
    return merge_settings(settings, {"measurement": {"period": period}})


def test_two_receiver_preset_holds_the_settings_tuned_on_the_observable_plan():
    """The preset gives the arrival-time filter the settings tuned on the observable plan
    (reports/two_auv_plan.md): σ 1.2 ms, VelocityMotion(0.1, 0.003) (the default speed
    spread, twice the earlier tuning's 0.05, so that particles keep up with a shark that
    speeds up; a turn rate that wanders about 7 times less than the default's), tempering
    below 30 % of the particles, 4,000 particles; and the benchmark's search box (240 m
    around the receivers, the scenario's detection reach)."""
    config = TrackingConfig.from_dict(with_period(read_preset(PRESET)))
    assert (config.measurement.name, config.motion.name) == ("arrival-time", "velocity")
    assert config.motion.build() == VelocityMotion(sigma_speed=0.1, sigma_turn_rate=0.003)
    measurement = arrival_measurement(config)
    assert measurement.arrival == ArrivalTimeMeasurement(
        ArrivalLikelihood(sigma=1.2e-3), sound_speed=config.measurement.sound_speed
    )
    assert config.filter.tempering_ess == 0.3
    assert measurement.search_radius == 240.0
    assert config.filter.n_particles == 4000
    assert measurement.clock == default_clock_model(8.0)


def test_every_bundled_preset_is_settings_only_and_valid():
    names = preset_names()
    assert PRESET in names
    for name in names:
        settings = read_preset(name)
        assert settings and not {"transmitter", "bounds", "start", "end"} & set(settings)
        measurement = settings.get("measurement", {})
        assert not {"period", "burst_interval", "burst_sequence"} & set(measurement)
        assert "description" not in settings  # descriptive text is dropped
        data = {"burst_interval": [20, 40]} if measurement.get("name") == "ping" else {"period": 2}
        TrackingConfig.from_dict(merge_settings(settings, {"measurement": data}), source=name)


def test_constant_velocity_preset_is_the_matched_model_of_the_simulated_array():
    """The preset a constant-velocity tag in a moored array wants (reports/decisions.md,
    "The matched model against the bound"): the ping measurement with its arrival sd from the
    pings, the velocity motion model at its defaults, the ping measurement's filter and
    smoother (5,000 particles, 60 s)."""
    settings = merge_settings(
        read_preset("constant-velocity-tag"), {"measurement": {"burst_interval": [20, 40]}}
    )
    config = TrackingConfig.from_dict(settings)
    assert (config.measurement.name, config.measurement.arrival_sigma) == ("ping", "pings")
    assert config.motion == VelocitySettings()
    assert (config.filter.n_particles, config.smoothing) == (5000, 60)


def test_unknown_preset_names_the_available_ones():
    with pytest.raises(ValueError, match=f"unknown preset 'nope'; available presets: .*{PRESET}"):
        read_preset("nope")


def test_a_preset_may_not_hold_data_or_unknown_keys(tmp_path, monkeypatch):
    monkeypatch.setattr(config_module, "PRESET_DIR", tmp_path)
    (tmp_path / "with-period.json").write_text(
        json.dumps({"measurement": {"period": 8.0}, "filter": {"n_particles": 10}})
    )
    (tmp_path / "with-bounds.json").write_text(json.dumps({"bounds": [0, 1, 0, 1]}))
    (tmp_path / "typo.json").write_text(
        json.dumps({"filter": {"n_particle": 10}, "description": "x"})
    )
    assert preset_names() == ["typo", "with-bounds", "with-period"]
    with pytest.raises(ValueError, match=r"with-period.json: key\(s\) \['measurement.period'\]"):
        read_preset("with-period")
    with pytest.raises(ValueError, match=r"key\(s\) \['bounds'\] describe one data set"):
        read_preset("with-bounds")
    with pytest.raises(ValueError, match=r"section 'filter': unknown key\(s\) \['n_particle'\]"):
        TrackingConfig.from_dict(with_period(read_preset("typo")), source="typo")


def test_later_layers_win_within_sections_and_r0_merges_by_receiver():
    """Preset < file < command line, key by key inside each section; ``None`` is "not
    given"."""
    preset = nest({"n_particles": 4000, "tempering_ess": 0.6, "arrival_sigma": 1.2e-3})
    file = nest(
        {"period": 8.0, "n_particles": 2000, "tempering_ess": 0.5, "r0": {"a": 1.0, "b": 2.0}}
    )
    flags = {
        "filter": {"n_particles": 1000, "tempering_ess": None},
        "measurement": {"r0": {"b": 5}},
    }
    merged = merge_settings(preset, file, flags)
    assert merged == {
        "filter": {"n_particles": 1000, "tempering_ess": 0.5},
        "measurement": {"arrival_sigma": 1.2e-3, "period": 8.0, "r0": {"a": 1.0, "b": 5}},
    }
    assert merge_settings(preset, file)["filter"]["n_particles"] == 2000
    assert merge_settings(preset)["filter"]["n_particles"] == 4000


def test_default_models_are_those_of_the_trackers():
    """Without model settings a configuration names the trackers' defaults, so a run
    without a preset is what it was before the settings existed."""
    plain = TrackingConfig.from_keys(period=8.0)
    assert (plain.measurement.name, plain.motion.name) == ("range-rate", "hmm")
    assert isinstance(plain.motion.build(), HMMMotion)
    velocity = plain.override(motion="velocity")
    assert velocity.motion.build() == motion_model("velocity")
    assert plain.override(motion="velocity", sigma_turn_rate=0.01).motion.build() == (
        VelocityMotion(VELOCITY_SIGMA_SPEED, 0.01)
    )
    assert plain.override(motion="baseline").motion.build() == motion_model("baseline")
    arrival = arrival_measurement(plain.override(measurement="arrival-time"))
    assert arrival.search_radius == SEARCH_RADIUS
    assert arrival.default_correction == Tempered(TEMPERING_ESS)
    assert arrival.arrival == ArrivalTimeMeasurement(sound_speed=plain.measurement.sound_speed)
    assert RangeRateMeasurement.from_settings(plain.measurement).covariance.tolist() == [
        [25.0, 0.0],
        [0.0, 0.25],
    ]
    fitted = plain.override(resting=False).motion.build().model.n_states
    assert plain.motion.build().model.n_states == fitted + 1  # the resting state by default
    paper = plain.override(variant="paper").motion.build()
    assert paper.model.n_states == fitted and paper.heading_diffusion == 0.0
    assert paper.model.to_dict() == motion_model("hmm", variant="paper").model.to_dict()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"measurement": "toa"}, r"measurement name must be one of \['range-rate', 'arrival"),
        ({"motion": "levy"}, r"motion name must be one of \['baseline', 'velocity', 'hmm'\]"),
        ({"sigma_speed": 0.05}, r"section 'motion' \(hmm\): unknown key\(s\) \['sigma_speed'\]"),
        ({"motion": "velocity", "sigma_turn_rate": -0.1}, "sigma_turn_rate must be a non-neg"),
        ({"motion": "velocity", "sigma_speed": "fast"}, "sigma_speed must be a number"),
        ({"arrival_sigma": 1e-3}, r"\(range-rate\): unknown key\(s\) \['arrival_sigma'\]"),
        ({"measurement": "arrival-time", "arrival_sigma": 0}, "arrival_sigma must be a positive"),
        ({"tempering_ess": 1.5}, r"tempering_ess must lie in \(0, 1\)"),
        ({"tempering_ess": float("nan")}, "finite"),
        ({"search_radius": 200.0}, r"unknown key\(s\) \['search_radius'\]"),
        ({"measurement": "arrival-time", "search_radius": -5}, "search_radius must be a pos"),
        ({"n_particles": 0}, "n_particles must be a positive integer, got 0"),
        ({"n_particles": 10.5}, "n_particles must be a positive integer"),
        ({"resampling": "fancy"}, "resampling must be one of"),
        ({"resample_when": "never"}, "resample_when must be one of"),
        ({"ess_threshold": 1.5}, r"ess_threshold must lie in \(0, 1\]"),
        ({"prediction_step": 0}, "prediction_step must be a positive"),
        ({"sound_speed": -1}, "sound_speed must be a speed of sound in water between 1300"),
        ({"sigma_range": 0}, "sigma_range must be a positive"),
        ({"range_rate_correlation": 1.0}, r"range_rate_correlation must lie in \(-1, 1\)"),
        ({"depth": "deep"}, "depth must be one of"),
        ({"depth": -3}, "depth must be a non-negative"),
        ({"shallower": "skip"}, "shallower must be one of"),
        ({"r0": {"a": -1}}, "r0 of receiver 'a' must be a non-negative range"),
        ({"r0": [1, 2]}, "r0 must map receiver names to ranges"),
        ({"bounds": (0, 1, 5, 2)}, "bounds must be"),
        ({"start": "2022-06-08T17:00:00"}, "ISO 8601 text with a UTC offset"),
        ({"start": 10.0, "end": 5.0}, r"start \(10.0\) must be before end"),
        ({"smoothing_lag": -1}, "smoothing_lag must be a whole number >= 0"),
        ({"variant": "fast"}, "variant must be one of"),
        ({"resting": "no"}, "resting must be true or false"),
        ({"heading_diffusion": -0.1}, "heading_diffusion must be a non-negative"),
        ({"model": ""}, "model must be a non-empty string"),
        ({"sigma_position": 0, "motion": "baseline"}, "sigma_position must be a positive"),
    ],
)
def test_each_section_validates_its_own_keys(change, message):
    with pytest.raises(ValueError, match=message):
        TrackingConfig.from_keys(**({"period": 8.0} | change))


def test_settings_classes_refuse_bad_values_on_their_own():
    """Each settings class checks its fields when built, whatever builds it."""
    with pytest.raises(ValueError, match="n_particles must be a positive integer"):
        FilterSettings(n_particles=-5)
    with pytest.raises(ValueError, match="period must be a positive"):
        RangeRateSettings(period=0)
    with pytest.raises(ValueError, match="search_radius must be a positive"):
        ArrivalTimeSettings(period=8.0, search_radius=0)
    with pytest.raises(ValueError, match="sigma_speed must be a non-negative"):
        VelocitySettings(sigma_speed=-1)
    with pytest.raises(ValueError, match="variant must be one of"):
        HMMSettings(variant="fast")
    with pytest.raises(ValueError, match=r"file.json: missing required key\(s\) \['period'\]"):
        RangeRateSettings.from_dict({}, source="file.json")
    assert FilterSettings(n_particles=5000.0).n_particles == 5000
    assert RangeRateSettings(period="8.179", depth="10.5").depth == 10.5


def test_unknown_keys_name_the_file_the_section_and_the_valid_keys(tmp_path):
    path = tmp_path / "run.json"
    path.write_text(json.dumps({"measurement": {"period": 8.0}, "filter": {"particles": 10}}))
    with pytest.raises(ValueError) as error:
        TrackingConfig.from_json(path)
    message = str(error.value)
    assert message.startswith(f"{path}, section 'filter': unknown key(s) ['particles']")
    assert f"valid keys are {list(FilterSettings.keys())}" in message
    path.write_text(json.dumps({"measurement": {"period": 8.0}, "n_particles": 10}))
    with pytest.raises(ValueError, match=r"run.json: unknown key\(s\) \['n_particles'\]; valid"):
        TrackingConfig.from_json(path)
    path.write_text(json.dumps({"measurement": {"period": 8.0}, "motion": "velocity"}))
    with pytest.raises(ValueError, match="motion must be a JSON object of settings"):
        TrackingConfig.from_json(path)


def test_round_trip_config_to_json_and_back(tmp_path):
    config = TrackingConfig.from_keys(
        period=8.179,
        r0={"a": 1.5, "b": 30},
        bounds=(0, 10, -5, 5),
        sigma_range=3.0,
        sigma_range_rate=0.2,
        range_rate_correlation=0.5,
        depth="10.7",
        start="2022-06-08T17:00:00Z",
        end=1654708800,
        motion="velocity",
        sigma_speed=0.05,
        resampling="multinomial",
        tempering_ess=0.4,
        smoothing_lag=30,
    )
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config.to_dict()))
    again = TrackingConfig.from_json(path)
    assert again == config and again.to_dict() == config.to_dict()
    assert config.start == 1654707600.0 and config.measurement.depth == 10.7
    assert config.override(n_particles=None, period=5.0).measurement.period == 5.0
    np.testing.assert_allclose(config.measurement.covariance, [[9.0, 0.3], [0.3, 0.04]])
    arrival = config.override(measurement="arrival-time", detection_curve=[160, 40])
    assert arrival.measurement.period == 8.179  # the key both measurements have is kept
    assert TrackingConfig.from_dict(json.loads(json.dumps(arrival.to_dict()))) == arrival
    assert TrackingConfig.from_dict(
        json.loads(json.dumps(TrackingConfig.from_keys(period=1).to_dict()))
    ) == (TrackingConfig.from_keys(period=1))


def test_a_relative_model_path_is_relative_to_the_config_file(tmp_path):
    (tmp_path / "runs").mkdir()
    path = tmp_path / "runs" / "config.json"
    path.write_text(json.dumps({"motion": {"name": "hmm", "model": "shark.json"}}))
    assert read_settings(path)["motion"]["model"] == str(tmp_path / "runs" / "shark.json")
    absolute = str(tmp_path / "model.json")
    path.write_text(json.dumps({"motion": {"model": absolute}}))
    assert read_settings(path)["motion"]["model"] == absolute


def test_every_key_has_one_section_and_the_registries_have_settings():
    """A key names one setting wherever it appears (so the command line has one option per
    key); the measurement and motion registries each have a settings class per name."""
    assert set(section_classes("measurement")) == set(MEASUREMENTS)
    assert set(MOTION_SETTINGS) == set(MOTIONS)
    owners = {}
    for section in SECTIONS:
        for cls in section_classes(section).values():
            for key in cls.keys():
                owners.setdefault(key, set()).add(section)
    assert all(len(sections) == 1 for sections in owners.values()), owners
    assert set(setting_sections()) == set(owners) | set(TrackingConfig.keys()) - set(SECTIONS)
    shared = [cls for cls in section_classes("measurement").values()]
    fields = [{f.name: f for f in dataclasses.fields(cls)} for cls in shared]
    for key in ("period", "sound_speed"):  # one definition of the keys both measurements have
        assert fields[0][key].default == fields[1][key].default
        assert fields[0][key].metadata == fields[1][key].metadata


def test_a_preset_with_the_other_measurement_is_a_clear_error():
    with pytest.raises(ValueError, match=r"cli, section 'measurement' \(range-rate\): unknown"):
        TrackingConfig.from_dict(
            merge_settings(read_preset(PRESET), nest({"period": 8.0, "measurement": "range-rate"})),
            source="cli",
        )


def arrival_measurement(config):
    """The arrival-time measurement ``config`` builds, for one detection at a receiver."""
    receivers = pd.DataFrame({"receiver": ["a"], "time": [np.nan], "x": [0.0], "y": [0.0]})
    detections = pd.DataFrame({"time": [5.0], "receiver": ["a"]})
    observations = ClockedArrivalTime.observations(detections, receivers)
    return ClockedArrivalTime.from_settings(config.measurement, observations, receivers)


def test_detection_curve_setting_round_trips_and_reaches_the_arrival_time_measurement():
    """A mapping or a LogisticDetection; JSON round trip; the curve becomes the arrival-time
    measurement's silence model's; absent, it has no silence model."""
    config = TrackingConfig.from_keys(
        period=8.0, measurement="arrival-time", detection_curve={"range_50": 160, "width": "40"}
    )
    curve = config.measurement.detection_curve
    assert curve == LogisticDetection(range_50=160.0, width=40.0)
    assert arrival_measurement(config).silence.detection is curve
    data = json.loads(json.dumps(config.to_dict()))
    assert data["measurement"]["detection_curve"] == {"range_50": 160.0, "width": 40.0}
    assert TrackingConfig.from_dict(data) == config
    same = TrackingConfig.from_keys(
        period=8.0, measurement="arrival-time", detection_curve=LogisticDetection(160.0, 40.0)
    )
    assert same == config
    plain = TrackingConfig.from_keys(period=8.0, measurement="arrival-time")
    assert arrival_measurement(plain).silence is None
    assert TrackingConfig.from_dict(json.loads(json.dumps(plain.to_dict()))) == plain


@pytest.mark.parametrize(
    ("curve", "message"),
    [
        ({"range_50": 160}, r'detection_curve must be \{"range_50": metres, "width": metres\}'),
        ([160, 40, 1], "detection_curve must be"),
        ({"range_50": 160, "width": 40, "slope": 1}, "detection_curve must be"),
        ({"range_50": 160, "width": "wide"}, "detection_curve width must be a number"),
        ({"range_50": float("nan"), "width": 40}, "detection_curve range_50 must be a finite"),
        ({"range_50": 160, "width": 0}, "positive width"),
        (LogisticDetection(160.0, 40.0, max_probability=0.9), "max_probability 1"),
    ],
)
def test_bad_detection_curves_are_clear_errors(curve, message):
    with pytest.raises(ValueError, match=message):
        TrackingConfig.from_keys(period=8.0, measurement="arrival-time", detection_curve=curve)


def test_detection_curve_is_refused_for_the_range_rate_measurement():
    with pytest.raises(ValueError, match=r"file.json, section 'measurement' \(range-rate\): unkn"):
        TrackingConfig.from_dict(
            {"measurement": {"period": 8.0, "detection_curve": {"range_50": 160, "width": 40}}},
            source="file.json",
        )


def test_a_preset_may_carry_a_detection_curve(tmp_path, monkeypatch):
    monkeypatch.setattr(config_module, "PRESET_DIR", tmp_path)
    settings = {
        "measurement": {"name": "arrival-time", "detection_curve": {"range_50": 90, "width": 15}}
    }
    (tmp_path / "reef.json").write_text(json.dumps(settings))
    config = TrackingConfig.from_dict(with_period(read_preset("reef"), 30.0))
    assert arrival_measurement(config).silence.detection == LogisticDetection(90.0, 15.0)


def test_standard_deviations_and_correlation_make_the_measurement_covariance():
    """Σ_z = [[σ_r², ρ σ_r σ_ṙ], [ρ σ_r σ_ṙ, σ_ṙ²]]; the defaults are the paper-scale
    (5 m, 0.5 m/s) diagonal, exactly."""
    settings = RangeRateSettings(period=8.0, sigma_range=3.0, sigma_range_rate=0.2,
                                 range_rate_correlation=0.5)  # fmt: skip
    np.testing.assert_allclose(settings.covariance, [[9.0, 0.3], [0.3, 0.04]])
    wider = dataclasses.replace(settings, sigma_range=6.0)
    np.testing.assert_allclose(wider.covariance, [[36.0, 0.6], [0.6, 0.04]])
    assert RangeRateSettings(period=8.0).covariance == ((25.0, 0.0), (0.0, 0.25))
    new = np.array(dataclasses.replace(settings, sigma_range=4.0, sigma_range_rate=0.7).covariance)
    rho = new[0, 1] / np.sqrt(new[0, 0] * new[1, 1])
    assert rho == pytest.approx(0.5) and np.linalg.eigvalsh(new).min() > 0


def test_the_ping_measurement_brings_its_own_motion_and_smoothing():
    """A ping run (random-interval tags, offline array data) takes the ping measurement's
    random walk and smoother unless told; other measurements keep the configuration's."""
    ping = TrackingConfig.from_keys(measurement="ping")
    assert ping.motion == BaselineSettings(sigma_position=2.5) and ping.smoothing == 60
    assert TrackingConfig.from_keys(measurement="ping", sigma_position=3.0).motion == (
        BaselineSettings(sigma_position=3.0)
    )
    assert TrackingConfig.from_keys(measurement="ping", motion="baseline").motion == (
        BaselineSettings(sigma_position=2.5)
    )
    assert TrackingConfig.from_keys(measurement="ping", motion="velocity").motion == (
        VelocitySettings()
    )
    assert TrackingConfig.from_keys(measurement="ping", smoothing_lag=0).smoothing is None
    assert TrackingConfig.from_keys(measurement="ping", smoothing_lag=30).smoothing == 30
    other = TrackingConfig.from_keys(period=8.0)
    assert other.motion == HMMSettings() and other.smoothing is None
    assert TrackingConfig.from_dict(ping.to_dict()) == ping


def test_a_named_filter_sets_its_switches_and_the_section_keys_override_them(tmp_path):
    """``filter="paper"`` / ``"mode-keeping"`` (:data:`FILTERS`) sets the four switches
    whatever the default filter is; explicit keys win; renaming the filter in ``override``
    replaces the switches; a configuration file may name the filter too."""
    base = {"period": 8.0, "r0": {"a": 10.0}}
    switches = ("acquisition", "mixture", "long_gap", "monitor")
    default = TrackingConfig.from_keys(**base).filter
    assert {k: getattr(default, k) for k in switches} == FILTERS[DEFAULT_FILTER]
    paper = TrackingConfig.from_keys(**base, filter="paper", n_particles=300)
    assert {k: getattr(paper.filter, k) for k in switches} == dict.fromkeys(switches, False)
    keeping = paper.override(filter="mode-keeping")
    assert (keeping.filter.acquisition, keeping.filter.mixture) == (True, True)
    assert keeping.filter.n_particles == 300  # the other keys stay
    assert keeping.override(n_particles=200).filter.mixture  # no rename: switches stay
    assert not keeping.override(filter="paper").filter.mixture
    mixed = TrackingConfig.from_keys(**base, filter="mode-keeping", mixture=False)
    assert (mixed.filter.acquisition, mixed.filter.mixture) == (True, False)
    path = tmp_path / "run.json"
    path.write_text(json.dumps({"measurement": base, "filter": {"name": "mode-keeping"}}))
    assert TrackingConfig.from_json(path).filter == dataclasses.replace(
        keeping.filter, n_particles=5000
    )
    with pytest.raises(ValueError, match="filter name must be one of"):
        TrackingConfig.from_keys(**base, filter="best")


def test_the_ping_measurement_runs_the_papers_filter_unless_told():
    """A configuration that names no filter runs :data:`DEFAULT_FILTER` (mode-keeping) with
    every measurement but those of :data:`MEASUREMENT_FILTERS` (ping: the paper's); a named
    filter or an explicit switch wins, and the switches survive a round trip."""
    switches = ("acquisition", "mixture", "long_gap", "monitor")

    def on(config):
        return tuple(getattr(config.filter, k) for k in switches)

    assert MEASUREMENT_FILTERS == {"ping": "paper"}
    for measurement in ("range-rate", "arrival-time", "ping-sequence"):
        config = TrackingConfig.from_keys(measurement=measurement, period=8.0)
        assert on(config) == (True, True, True, False), measurement
    ping = TrackingConfig.from_keys(measurement="ping")
    assert on(ping) == (False, False, False, False)
    assert TrackingConfig.from_dict(ping.to_dict()) == ping
    assert on(TrackingConfig.from_keys(measurement="ping", filter="mode-keeping")) == (
        True,
        True,
        True,
        False,
    )
    assert on(TrackingConfig.from_keys(measurement="ping", acquisition=True)) == (
        True,
        False,
        False,
        False,
    )
