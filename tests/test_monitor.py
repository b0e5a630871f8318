"""The monitor (:mod:`hmmtrack.tracking.monitor`): a long gap, a silence the tag outswam and
a lost tag are noticed, recorded and re-acquired; on clean runs it stays quiet. The library's
default filter carries the long-gap rule (with its question after a silence the tag may have
outswum), not the lost-tag test."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from hmmtrack.tracking.acquisition import grid_loglik
from hmmtrack.tracking.filter import FilterSettings, ParticleFilter
from hmmtrack.tracking.measurement.gps_offset import GpsOffsetMeasurement
from hmmtrack.tracking.measurement.range_rate import RANGE_RATE_COLUMNS, RangeRateMeasurement
from hmmtrack.tracking.monitor import Monitor, grid_evidence
from hmmtrack.tracking.motion import BaselineMotion, VelocityMotion
from hmmtrack.tracking.pipeline import particle_filter

DAY = 86_400.0
N = 200
BOUNDS = (-600.0, 600.0, -600.0, 600.0)


def boat_observations(rng, tag=(0.0, 0.0), times=None) -> pd.DataFrame:
    """Range-rate rows of a still tag heard every 8 s by a boat circling at 1.5 m/s on a
    200 m circle around (0, 150) m (ranges 1 m, range-rates 0.1 m/s of noise): no mirror
    point, the circle breaks the symmetry of a straight line."""
    times = np.arange(0.0, 600.0, 8.0) if times is None else np.asarray(times, dtype=float)
    angle = 1.5 / 200.0 * times
    bx, by = 200.0 * np.cos(angle), 150.0 + 200.0 * np.sin(angle)
    vx, vy = -1.5 * np.sin(angle), 1.5 * np.cos(angle)
    dx, dy = tag[0] - bx, tag[1] - by
    r = np.hypot(dx, dy)
    rate = -(dx * vx + dy * vy) / r
    return pd.DataFrame(
        {
            "time": times,
            "range": r + rng.normal(0.0, 1.0, times.size),
            "range_rate": rate + rng.normal(0.0, 0.1, times.size),
            "receiver_x": bx,
            "receiver_y": by,
            "receiver_vx": vx,
            "receiver_vy": vy,
        }
    )[["time", *RANGE_RATE_COLUMNS]]


def run(observations, monitor, seed=0):
    pf = ParticleFilter(
        BaselineMotion(0.3),
        RangeRateMeasurement.from_std(5.0, 0.5),
        N,
        BOUNDS,
        resampling="systematic",
        rng=seed,
        monitor=monitor,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return pf.run(observations)


def velocity_filter(monitor, dt, seed=0):
    return ParticleFilter(
        VelocityMotion(0.05, 0.02),
        RangeRateMeasurement.from_std(5.0, 0.5),
        N,
        BOUNDS,
        resampling="systematic",
        rng=seed,
        monitor=monitor,
        dt=dt,
    )


def test_one_detection_after_30_days_gives_an_event_a_reacquisition_and_a_wide_cloud():
    """The tag left while unheard; one detection 30 days later, 860 m from its old place.
    Without the monitor the velocity model's cloud collapses on one particle far from the
    tag (the issue's confident wrong point); with it: ``long_gap`` and ``reacquired``
    events and a cloud hundreds of metres wide. (A 600 s step: 30 days of 1 s steps cost
    minutes; the still tag needs no finer one.)"""
    rng = np.random.default_rng(1)
    tag = (700.0, -500.0)
    after = boat_observations(rng, tag=tag, times=[30 * DAY + 16.0])
    observations = pd.concat([boat_observations(rng), after], ignore_index=True)
    ends = {}
    for monitored in (False, True):
        pf = velocity_filter(Monitor() if monitored else None, dt=600.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            result = pf.run(observations)
        last = result.estimates.iloc[-1]
        ends[monitored] = (np.hypot(last["x"] - tag[0], last["y"] - tag[1]), last["sqrt_lambda1"])
        kinds = list(result.events["kind"])
        assert kinds == (["long_gap", "reacquired"] if monitored else [])
    error, spread = ends[False]
    assert error > 500.0 and spread < 10.0  # confident and wrong
    error, spread = ends[True]
    assert spread > 100.0 and not (spread < 10.0 and error > 50.0)


def default_filter(dt, seed, measurement=None, **switches):
    """The filter ``track`` builds from a configuration that names no filter (the library's
    default, :data:`hmmtrack.tracking.filter.DEFAULT_FILTER`), with the test's parts; the
    range-rate measurement unless another is given."""
    settings = FilterSettings(n_particles=N, prediction_step=dt, **switches)
    if measurement is None:
        measurement = RangeRateMeasurement.from_std(5.0, 0.5)
    return particle_filter(settings, measurement, BOUNDS, VelocityMotion(0.05, 0.02), seed=seed)


def gps_measurement() -> GpsOffsetMeasurement:
    """The reproduction's default measurement (the boat's GPS offset carried by each
    particle) at its default noise, for the test's one boat."""
    return GpsOffsetMeasurement.of(["boat"], 0.5)


def from_the_boat(observations: pd.DataFrame) -> pd.DataFrame:
    """``observations`` with the receiver's name the gps measurement reads."""
    return observations.assign(receiver="boat")


def quietly_run(pf, observations):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return pf.run(observations)


def end_of(result, tag) -> tuple[float, float]:
    """The last estimate's distance from ``tag`` (m) and its √λ₁ (m)."""
    last = result.estimates.iloc[-1]
    return float(np.hypot(last["x"] - tag[0], last["y"] - tag[1])), float(last["sqrt_lambda1"])


@pytest.mark.parametrize(
    ("gps", "n_seeds", "confident", "at_least"),
    [(False, 3, 10.0, 2), (True, 5, 15.0, 3)],
    ids=["range-rate", "range-rate-gps"],
)
def test_the_default_filter_reacquires_after_30_days_and_is_not_confidently_wrong(
    gps, n_seeds, confident, at_least
):
    """The 30-day case through the library's default (no monitor switch), with the range-rate
    measurement and with the one the reproduction defaults to (whose offsets must not hide
    the gap): ``long_gap`` and ``reacquired`` events after the acquisition's, and the end
    either near the tag or honestly uncertain, on every seed; without the long-gap rule the
    same filter collapses onto a confident wrong point (√λ₁ under ``confident`` m, more than
    100 m off) on ``at_least`` seeds (gps: 4 of the 5 within 15 m, 570-1,600 m off)."""
    rng = np.random.default_rng(1)
    tag = (700.0, -500.0)
    after = boat_observations(rng, tag=tag, times=[30 * DAY + 16.0])
    observations = pd.concat([boat_observations(rng), after], ignore_index=True)
    measurement = None
    if gps:
        observations, measurement = from_the_boat(observations), gps_measurement()
    confident_and_wrong = 0
    for seed in range(n_seeds):
        result = quietly_run(default_filter(600.0, seed, measurement), observations)
        assert list(result.events["kind"]) == ["acquired", "long_gap", "reacquired"]
        assert result.events["time"].iloc[-1] == pytest.approx(30 * DAY + 16.0, abs=600.0)
        error, spread = end_of(result, tag)
        assert spread > 100.0 or error < 50.0
        without = default_filter(600.0, seed, measurement, long_gap=False)
        error, spread = end_of(quietly_run(without, observations), tag)
        confident_and_wrong += spread < confident and error > 100.0
    assert confident_and_wrong >= at_least


def test_the_default_filter_raises_no_event_on_a_clean_run():
    """A still tag heard every 8 s for 20 min (3 seeds) through the default filter, with the
    range-rate and with the gps measurement: the acquisition's event only, and the run ends
    within 10 m."""
    for seed in range(3):
        rng = np.random.default_rng(200 + seed)
        observations = boat_observations(rng, times=np.arange(0.0, 1200.0, 8.0))
        for measurement in (None, gps_measurement()):
            heard = observations if measurement is None else from_the_boat(observations)
            result = quietly_run(default_filter(1.0, seed, measurement), heard)
            assert list(result.events["kind"]) == ["acquired"]
            last = result.estimates.iloc[-1]
            assert np.hypot(last["x"], last["y"]) < 10.0


def silence_observations(tag, silence: float, count: int) -> pd.DataFrame:
    """The still tag heard every 8 s for 600 s, then ``count`` detections 8 s apart from
    ``tag`` (m), the first ``silence`` s after the last one."""
    rng = np.random.default_rng(1)
    before = boat_observations(rng)
    first = before["time"].iloc[-1] + silence
    after = boat_observations(rng, tag=tag, times=first + 8.0 * np.arange(count))
    return pd.concat([before, after], ignore_index=True)


#: the tag 830 m from where it was heard, as in the 25-min case of issue 13
OUTSWUM_TAG = (830.0 * np.cos(-np.pi / 4), 830.0 * np.sin(-np.pi / 4))


def test_a_silence_the_tag_outswam_gives_an_event_and_an_honest_cloud():
    """The 25-min case: 1,505 s of silence (under ``MAX_GAP``) while the tag swam 830 m,
    then one detection, or three. The default filter records ``outswum`` and
    ``reacquired`` and ends with the tag within 3 √λ₁ of its mean (3 seeds); without the
    long-gap rule it ends on a confident wrong point (√λ₁ under 10 m, over 200 m off) in
    most of them."""
    confident_and_wrong = 0
    for count in (1, 3):
        observations = silence_observations(OUTSWUM_TAG, 1505.0, count)
        for seed in range(3):
            result = quietly_run(default_filter(1.0, seed), observations)
            assert list(result.events["kind"]) == ["acquired", "outswum", "reacquired"]
            error, spread = end_of(result, OUTSWUM_TAG)
            assert spread > 100.0 and error < 3.0 * spread
            without = quietly_run(default_filter(1.0, seed, long_gap=False), observations)
            error, spread = end_of(without, OUTSWUM_TAG)
            confident_and_wrong += spread < 10.0 and error > 200.0
    assert confident_and_wrong >= 4


def test_a_correction_that_leaves_the_cloud_no_spread_after_such_a_silence_is_outswum():
    """The 25-min case with the grid's comparison out of reach (a margin of 1e9 nats) is
    still caught: its correction leaves the cloud fewer than ``SPREAD_ESS`` effective
    particles, so ``outswum`` and ``reacquired``, and the tag within 3 √λ₁."""
    observations = silence_observations(OUTSWUM_TAG, 1505.0, 1)
    monitor = Monitor(loss=False, margin=1e9)
    result = quietly_run(velocity_filter(monitor, dt=1.0), observations)
    assert list(result.events["kind"]) == ["outswum", "reacquired"]
    assert "effective particles" in result.events["detail"].iloc[0]
    error, spread = end_of(result, OUTSWUM_TAG)
    assert spread > 100.0 and error < 3.0 * spread


def test_a_silence_the_tag_did_not_outswim_changes_nothing():
    """The still tag heard again after 1,505 s (the rule asks, the cloud explains the
    detection), and the moved tag heard after 600 s (shorter than
    ``Monitor.outswim_gap``, 667 s: the rule does not ask): no event, and the estimates
    equal those of the filter without the rule, draw for draw."""
    assert Monitor().outswim_gap() == pytest.approx(1000.0 / 1.5)
    for tag, silence in (((0.0, 0.0), 1505.0), (OUTSWUM_TAG, 600.0)):
        observations = silence_observations(tag, silence, 3)
        for seed in range(2):
            result = quietly_run(default_filter(1.0, seed), observations)
            assert list(result.events["kind"]) == ["acquired"]
            without = quietly_run(default_filter(1.0, seed, long_gap=False), observations)
            assert result.estimates.equals(without.estimates)
        last = result.estimates.iloc[-1]
        if silence > 1000.0:
            assert np.hypot(last["x"], last["y"]) < 10.0


def test_the_switches_build_the_two_rules():
    """The default carries the long-gap rule alone (and so never asks for the weights
    before a correction); ``monitor`` adds the lost-tag test; the paper's filter has
    neither; a monitor with neither rule is refused."""
    measurement = RangeRateMeasurement.from_std(5.0, 0.5)

    def built(**keys):
        settings = FilterSettings(n_particles=N, **keys)
        return particle_filter(settings, measurement, BOUNDS, BaselineMotion(0.3)).monitor

    default = built()
    assert (default.long_gap, default.loss) == (True, False)
    assert default.max_gap == 1800.0
    monitored = built(monitor=True)
    assert (monitored.long_gap, monitored.loss) == (True, True)
    only_loss = built(long_gap=False, monitor=True)
    assert (only_loss.long_gap, only_loss.loss) == (False, True)
    assert built(acquisition=False, mixture=False, long_gap=False) is None
    with pytest.raises(ValueError, match="long_gap or loss"):
        Monitor(long_gap=False, loss=False)


def jump_observations(seed: int) -> pd.DataFrame:
    """A still tag at the origin for 10 min, then 320 m away for 20 min."""
    rng = np.random.default_rng(seed)
    moved = boat_observations(rng, tag=(250.0, -200.0), times=np.arange(600.0, 1800.0, 8.0))
    return pd.concat([boat_observations(rng), moved], ignore_index=True)


def test_a_lost_tag_is_noticed_and_reacquired():
    """The random walk cannot follow a 320 m jump: without the monitor the filter ends
    more than 100 m off with a cloud of a few metres; with it, ``tag_lost`` and
    ``reacquired`` events and the tag found within 10 m (3 seeds)."""
    for seed in range(3):
        observations = jump_observations(seed)
        for monitor in (None, Monitor()):
            result = run(observations, monitor, seed)
            last = result.estimates.iloc[-1]
            error = np.hypot(last["x"] - 250.0, last["y"] + 200.0)
            kinds = set(result.events["kind"])
            if monitor is None:
                assert error > 100.0 and last["sqrt_lambda1"] < 10.0 and not kinds
            else:
                assert error < 10.0 and kinds == {"tag_lost", "reacquired"}


def test_the_monitor_is_quiet_on_clean_runs():
    """Clean runs of a still tag (10 seeds, 150 corrections each): no alarm while the
    estimate was within 50 m of the tag (measured: none in 4,500 corrections of 20
    seeds; the alarms there caught runs that had settled 40-140 m off), and every run
    ends within 10 m."""
    false_alarms = 0
    for seed in range(10):
        rng = np.random.default_rng(100 + seed)
        result = run(boat_observations(rng, times=np.arange(0.0, 1200.0, 8.0)), Monitor(), seed)
        estimates = result.estimates.set_index("time")
        for time in result.events.loc[result.events["kind"] == "tag_lost", "time"]:
            before = estimates.loc[time - 1.0]
            false_alarms += np.hypot(before["x"], before["y"]) < 50.0
        last = result.estimates.iloc[-1]
        assert np.hypot(last["x"], last["y"]) < 10.0
    assert false_alarms == 0


def still_corrections(rng):
    """Corrections (time, rows) of the still tag heard every 8 s for 2 min."""
    return [
        (t, boat_observations(rng, times=[t]).to_numpy()[:, 1:]) for t in np.arange(0.0, 120.0, 8.0)
    ]


def test_the_grid_evidence_is_an_average_over_the_box_not_its_best_cell():
    """Still (``speed`` 0): the log of the mean likelihood over the cells, far below the
    best cell's (the comparison the monitor used to make); a swimming prior (1.5 m/s)
    spreads each earlier correction's likelihood, so the evidence changes but stays
    below the best cell's."""
    measurement = RangeRateMeasurement.from_std(5.0, 0.5)
    corrections = still_corrections(np.random.default_rng(5))
    _, total = grid_loglik(measurement, BOUNDS, 64, corrections)
    top = total.max()
    expected = top + np.log(np.mean(np.exp(total - top)))
    still = grid_evidence(measurement, BOUNDS, 64, corrections, 0.0)
    assert still == pytest.approx(expected, abs=1e-9)
    assert still < top - 5.0
    swimming = grid_evidence(measurement, BOUNDS, 64, corrections, 1.5)
    assert swimming != still and swimming < top
