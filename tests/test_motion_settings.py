"""The velocity model's settings (``motion.settings.VelocitySettings``): the still regime as
two flat settings (``still_rate``, ``still_duration``), and the settings a measurement fills in
(``None``: the measurement's, ``config.MEASUREMENT_MOTIONS``, else the library's), through
Python, a configuration file and the command line."""

import json

import numpy as np
import pytest

from hmmtrack.cli import build_parser
from hmmtrack.cli.track import build_config, settings_options
from hmmtrack.experiments.trials import _motion
from hmmtrack.tracking import config as config_module
from hmmtrack.tracking.config import TrackingConfig, measurement_motion
from hmmtrack.tracking.motion import (
    VELOCITY_GPS,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
    VELOCITY_STILL,
    VELOCITY_STILL_DURATION,
    VelocityMotion,
    motion_model,
    still_regimes,
)
from hmmtrack.tracking.motion.regimes import Regime, VelocityRegimes
from hmmtrack.tracking.motion.settings import VELOCITY_LIBRARY, VelocitySettings
from hmmtrack.tracking.particles import Particles

#: the velocity model under range-rate-gps (reports/decisions.md, "A sticky still regime for
#: the velocity model"), written out in Python
GPS_MODEL = VelocityMotion(
    0.05,
    0.02,
    jump_rate=1 / 60,
    jump_sd=0.4,
    regimes=VelocityRegimes(
        (Regime(0.05, 0.02), Regime(0.005, 0.005, speed_reversion=0.5, turn_reversion=2.0)),
        ((0, 1 / 7200), (1 / 1800, 0)),
    ),
)
TRACK = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
TRACK += ["--period", "8", "--r0", "a=1", "--motion", "velocity"]


def velocity_config(measurement="range-rate-gps", **motion) -> TrackingConfig:
    return TrackingConfig.from_dict(
        {
            "measurement": {"name": measurement, "period": 8.0},
            "motion": {"name": "velocity", **motion},
        }
    )


def seeded_steps(motion, seed=11, n=500, steps=30) -> np.ndarray:
    """Positions, speeds and turn rates after ``steps`` NumPy steps of 1 s from a seed."""
    rng = np.random.default_rng(seed)
    p = Particles.from_state(x=np.zeros(n), y=np.zeros(n), heading=rng.uniform(0, 6, n))
    p.speed = np.full(n, 0.5)
    motion.initialise(rng, p)
    for _ in range(steps):
        motion.propagate(rng, p, 1.0)
    return np.stack([p.x, p.y, p.speed, p.turn_rate])


# -------------------------------------------------------------------- no still rate: today


def test_the_library_values_are_todays_model():
    assert VELOCITY_LIBRARY == {
        "sigma_speed": VELOCITY_SIGMA_SPEED,
        "jump_rate": 0.0,
        "jump_sd": 0.0,
        "still_rate": 0.0,
        "still_duration": VELOCITY_STILL_DURATION,
    }
    assert (VELOCITY_SIGMA_SPEED, VELOCITY_STILL_DURATION) == (0.1, 1800.0)
    today = VelocityMotion(0.1, 0.02)
    for settings in (VelocitySettings(), VelocitySettings(still_rate=0.0)):
        built = settings.build()
        assert built == today == motion_model("velocity")
        assert built.regimes is None and not built.switching
        np.testing.assert_array_equal(seeded_steps(built), seeded_steps(today))


def test_no_still_rate_keeps_the_given_walks_jumps_and_reversion_without_regimes():
    settings = VelocitySettings(
        sigma_speed=0.03, sigma_turn_rate=0.01, jump_rate=0.02, jump_sd=0.5,
        turn_reversion=8.0, still_rate=0.0, still_duration=30.0,
    )  # fmt: skip
    assert settings.build() == VelocityMotion(
        0.03, 0.01, jump_rate=0.02, jump_sd=0.5, turn_reversion=8.0
    )


def test_only_the_gps_measurement_sets_the_velocity_model():
    """The paper's measurements build today's velocity model (their seeded results stay as
    they were); range-rate-gps fills in its own."""
    for name in ("range-rate", "arrival-time", "ping"):
        assert measurement_motion(VelocitySettings(), name) == VelocityMotion(0.1, 0.02)
    assert measurement_motion(VelocitySettings(), "range-rate-gps") == GPS_MODEL


# ------------------------------------------------------------------------- a still regime


@pytest.mark.parametrize(("rate", "duration"), [(1 / 600, 120.0), (0.01, 30.0), (2.0, 0.5)])
def test_a_still_rate_builds_moving_and_still_regimes(rate, duration):
    motion = VelocitySettings(
        sigma_speed=0.05, jump_rate=0.1, jump_sd=0.3, still_rate=rate, still_duration=duration
    ).build()
    regimes = motion.regimes
    assert motion.switching and motion.turn_reversion is None
    assert (motion.jump_rate, motion.jump_sd) == (0.1, 0.3)
    assert regimes.regimes == (Regime(0.05, VELOCITY_SIGMA_TURN_RATE), VELOCITY_STILL)
    np.testing.assert_allclose(
        regimes.generator(), [[-rate, rate], [1 / duration, -1 / duration]], rtol=1e-15
    )
    np.testing.assert_allclose(regimes.dwell(), [1 / rate, duration], rtol=1e-12)
    # a particle is still for the share rate / (rate + 1 / duration) of the time
    still = rate / (rate + 1 / duration)
    np.testing.assert_allclose(regimes.stationary(), [1 - still, still], rtol=1e-9)


def test_the_still_regime_is_the_named_constant():
    assert VELOCITY_STILL == Regime(0.005, 0.005, speed_reversion=0.5, turn_reversion=2.0)
    motion = VelocitySettings(still_rate=0.01).build()
    assert motion.regimes.regimes[1] is VELOCITY_STILL
    # over 2 s the still regime's speed decays by exp(-2 / 0.5) and its turn rate by
    # exp(-2 / 2), each with the Ornstein-Uhlenbeck step's spread
    # 0.005 sqrt(tau (1 - exp(-4 / tau)) / 2); the moving ones walk
    steps = motion.step_table(2.0)[0]
    spread = [0.005 * np.sqrt(tau * (1 - np.exp(-4 / tau)) / 2) for tau in (0.5, 2.0)]
    np.testing.assert_allclose(steps[:, 1], [np.exp(-4.0), spread[0], np.exp(-1.0), spread[1]])
    np.testing.assert_allclose(steps[:, 0], [1.0, 0.1 * np.sqrt(2.0), 1.0, 0.02 * np.sqrt(2.0)])


def test_the_still_duration_defaults_to_half_an_hour():
    regimes = VelocitySettings(still_rate=0.01).build().regimes
    assert regimes.rates == ((0.0, 0.01), (1 / 1800, 0.0))


def test_the_turn_reversion_moves_into_the_moving_regime():
    motion = VelocitySettings(turn_reversion=10.0, still_rate=0.01).build()
    assert motion.turn_reversion is None
    assert motion.regimes.regimes[0] == Regime(0.1, 0.02, turn_reversion=10.0)
    # and its transition is the reverting one: decay exp(-dt / tau)
    np.testing.assert_allclose(motion.step_table(1.0)[0][2, 0], np.exp(-0.1))


def test_the_settings_build_the_gps_model():
    assert VelocitySettings(**VELOCITY_GPS).build() == GPS_MODEL


@pytest.mark.parametrize(
    ("rate", "duration", "name"),
    [
        (0.0, 120.0, "still_rate"),
        (-1.0, 120.0, "still_rate"),
        (0.01, 0.0, "still_duration"),
        (0.01, np.inf, "still_duration"),
    ],
)
def test_still_regimes_refuses_a_rate_or_duration_that_is_not_positive(rate, duration, name):
    with pytest.raises(ValueError, match=f"{name} must be a number > 0"):
        still_regimes(Regime(0.1, 0.02), rate, duration)


# ----------------------------------------------------------------- filled in by the measurement


def test_the_measurement_entry_fills_in_the_unset_settings():
    assert config_module.MEASUREMENT_MOTIONS["range-rate-gps"]["velocity"] is VELOCITY_GPS
    assert measurement_motion(VelocitySettings(), "range-rate-gps") == GPS_MODEL
    assert velocity_config().motion_model() == GPS_MODEL
    assert _motion("velocity", "range-rate-gps") == GPS_MODEL
    # another measurement keeps the library's
    assert velocity_config("range-rate").motion_model() == VelocityMotion(0.1, 0.02)
    # and the HMM's entry is untouched
    assert config_module.MEASUREMENT_MOTIONS["range-rate-gps"]["hmm"]["speed_diffusion"] == 0.07


def test_a_value_given_wins_over_the_measurements():
    motion = velocity_config(sigma_speed=0.08, still_duration=60.0).motion_model()
    assert motion.regimes.regimes[0] == Regime(0.08, 0.02)
    assert motion.regimes.rates == ((0.0, 1 / 7200), (1 / 60, 0.0))
    assert (motion.jump_rate, motion.jump_sd) == (1 / 60, 0.4)  # the measurement's
    # a given 0 switches the measurement's jumps or still regime off
    plain = velocity_config(still_rate=0.0, jump_rate=0.0).motion_model()
    assert plain == VelocityMotion(0.05, 0.02, jump_rate=0.0, jump_sd=0.4)
    assert plain.regimes is None
    # the command line's options win the same way
    args = build_parser().parse_args([*TRACK, "--measurement", "range-rate-gps",
                                      "--still-rate", "0"])  # fmt: skip
    assert build_config(args).motion_model() == VelocityMotion(0.05, 0.02, 1 / 60, 0.4)


# ----------------------------------------------------------------- file and command line


def test_the_still_regime_round_trips_through_a_configuration_file(tmp_path):
    config = velocity_config(still_rate=0.002, still_duration=90.0, jump_rate=0.05, jump_sd=0.3)
    written = config.to_dict()
    assert written["motion"] == {
        "name": "velocity", "sigma_speed": None, "sigma_turn_rate": 0.02, "jump_rate": 0.05,
        "jump_sd": 0.3, "turn_reversion": None, "still_rate": 0.002, "still_duration": 90.0,
    }  # fmt: skip
    path = tmp_path / "run.json"
    path.write_text(json.dumps(written))
    read = TrackingConfig.from_json(path)
    assert read == config
    assert read.motion_model().regimes.rates == ((0.0, 0.002), (1 / 90, 0.0))
    # the speed walk left unset is the measurement's (range-rate-gps)
    assert read.motion_model().regimes.regimes[0] == Regime(0.05, 0.02)


def test_the_still_regime_is_given_on_the_command_line():
    parser = build_parser()
    args = parser.parse_args([*TRACK, "--still-rate", "0.004", "--still-duration", "45"])
    config = build_config(args)
    assert config.motion == VelocitySettings(still_rate=0.004, still_duration=45.0)
    assert config.motion_model().regimes.rates == ((0.0, 0.004), (1 / 45, 0.0))
    assert build_config(parser.parse_args(TRACK)).motion_model() == VelocityMotion(0.1, 0.02)


def test_the_help_says_the_measurements_else_the_librarys_default():
    options = {option.key: option for option in settings_options()}
    for key, library in [("sigma_speed", "0.1"), ("jump_rate", "0"), ("jump_sd", "0"),
                         ("still_rate", "0"), ("still_duration", "1800")]:  # fmt: skip
        assert options[key].flag == "--" + key.replace("_", "-")
        assert options[key].default_text == f"the measurement's, else {library}"
        assert options[key].components == ("velocity",)


# ------------------------------------------------------------------------------ bad values


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("still_rate", -0.01, "still_rate must be a non-negative number"),
        ("still_rate", float("nan"), "still_rate must be a finite number"),
        ("still_duration", 0.0, "still_duration must be a positive finite number"),
        ("still_duration", -5.0, "still_duration must be a positive finite number"),
        ("sigma_speed", -0.1, "sigma_speed must be a non-negative number"),
    ],
)
def test_bad_values_are_refused_naming_the_key(tmp_path, key, value, message):
    with pytest.raises(ValueError, match=message):
        VelocitySettings(**{key: value})
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"measurement": {"period": 8.0},
                                "motion": {"name": "velocity", key: value}}))  # fmt: skip
    with pytest.raises(ValueError, match=f"bad.json.*motion.*{message}"):
        TrackingConfig.from_json(path)


def test_the_command_line_refuses_a_zero_duration(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args([*TRACK, "--still-duration", "0"])
    assert "still_duration must be a positive finite number" in capsys.readouterr().err
