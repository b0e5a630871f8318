"""A fixed-period tag's pings grouped (``ping-sequence`` with ``period``) against the
arrival-time filter: the grouped measurement's clock and broadening, its detection curve
the arrival-time filter's term for term when one receiver hears each ping, and better on
three moored receivers; the default that groups a fixed-period tag's pings only where three
receivers hear them, each kind of sequence's own arrival sd, and the matched-ping kernel the
same on one thread and two (reports/decisions.md, "Fixed-period tags with ping grouping",
"Fixed-period grouping with the detection curve", "Fixed-period grouping by default" and
"Never worse, judged over three filter seeds": the experiment's filter seeds, its summary and
the outlier count that shows an escape)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from hmmtrack.cli import build_parser
from hmmtrack.cli.track import _chosen_for_period, build_config
from hmmtrack.experiments.clock_runs import (
    clock_inputs,
    grouped_config,
    score_run,
    track_arrival,
)
from hmmtrack.experiments.grouping import (
    MIRROR_FROM,
    filter_seed_summary,
    outlier_pings,
    share_sweep,
)
from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.clocked import ClockState, default_clock_model, silence_since
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.measurement.sequence import (
    DRIFT_DENSITY,
    DRIFT_SD,
    GROUPING_RECEIVERS,
    GROUPING_SHARE,
    PERIOD_ARRIVAL_SIGMA,
    PERIOD_BROADENING,
    PHASE_DENSITY,
    SEQUENCE_ARRIVAL_SIGMA,
    SequenceState,
    broadened_sigma,
    fixed_period_measurement,
    period_clock_noise,
    sequence_ping_loglik,
)
from hmmtrack.tracking.motion import VelocityMotion
from hmmtrack.tracking.pipeline import track
from hmmtrack.tracking.receivers import ReceiverTracks

#: the measured case: 20 min of the clock-aware moored array, 2,000 particles
SEED, DURATION, PARTICLES = 0, 1200.0, 2000


def test_period_clock_noise_is_the_arrival_time_clock_model_per_second():
    clock = default_clock_model(8.0)
    phase, drift, drift_sd = period_clock_noise(8.0)
    # over one period the walks add the model's per-ping steps
    assert phase * 8.0 == pytest.approx(clock.phase_step_sd**2)
    assert (drift * 8.0) * 8.0**2 == pytest.approx(clock.period_step_sd**2)
    assert drift_sd * 8.0 == pytest.approx(clock.initial_period_sd)


def test_broadened_sigma_follows_the_cloud_spread():
    x = np.array([0.0, 300.0, 0.0, 300.0])
    y = np.array([0.0, 0.0, 400.0, 400.0])
    weights = np.full(4, 0.25)
    cloud = SimpleNamespace(x=x, y=y)
    spread = np.hypot(150.0, 200.0)  # root of the summed variances: 250 m
    expected = np.hypot(1e-3, 0.05 * spread / 1500.0)
    assert broadened_sigma(cloud, weights, 1e-3, 0.05, 1500.0) == pytest.approx(expected)
    # a collapsed cloud scores with the arrival sd itself
    point = SimpleNamespace(x=np.full(4, 7.0), y=np.full(4, -3.0))
    assert broadened_sigma(point, weights, 1e-3, 0.05, 1500.0) == 1e-3


def test_a_period_gives_the_period_clock_and_broadening_a_sequence_does_not():
    case = moored_array(SEED, duration=300.0)
    sc = case.scenario
    detections, _, _ = clock_inputs(case, SEED, 100, "velocity", 300.0)
    tracks = ReceiverTracks.from_frame(sc.receivers, outside="clamp")
    cls = MEASUREMENTS["ping-sequence"]
    built = {}
    for key, value in (("period", sc.period), ("burst_sequence", (sc.period,))):
        settings = TrackingConfig.from_keys(measurement="ping-sequence", **{key: value})
        obs = cls.observations(detections, tracks, settings.measurement)
        built[key] = cls.from_settings(settings.measurement, obs, tracks)
    assert built["period"].clock_noise == period_clock_noise(sc.period)
    assert built["period"].broadening == PERIOD_BROADENING
    assert built["burst_sequence"].clock_noise == (PHASE_DENSITY, DRIFT_DENSITY, DRIFT_SD)
    assert built["burst_sequence"].broadening == 0.0
    assert built["period"].schedule_period == pytest.approx(sc.period, rel=1e-3)
    assert built["burst_sequence"].schedule_period is None
    # each scores with its own arrival sd
    assert built["period"].sigma == PERIOD_ARRIVAL_SIGMA
    assert built["burst_sequence"].sigma == SEQUENCE_ARRIVAL_SIGMA
    assert dataclasses.replace(
        built["period"], clock_noise=(), broadening=0.0, schedule_period=None, sigma=0.0
    ) == dataclasses.replace(built["burst_sequence"], clock_noise=(), sigma=0.0)


#: three moorings (m), their detection curve, and a tag at TAG pinging every PERIOD s from
#: FIRST; ping k is heard by receiver k % 3 only, every fifth by none
MOORINGS = pd.DataFrame(
    {"receiver": ["r0", "r1", "r2"], "time": np.nan, "x": [0.0, 300.0, 150.0], "y": [0, 0, 260.0]}
)
CURVE = LogisticDetection(range_50=250.0, width=50.0)
TAG, PERIOD, FIRST, SOUND = (100.0, 120.0), 8.0, 1000.0, 1500.0


def _one_receiver_pings() -> pd.DataFrame:
    rows = []
    for k in range(12):
        if k % 5 == 4:
            continue
        name, x, y = MOORINGS.iloc[k % 3][["receiver", "x", "y"]]
        rows.append((FIRST + k * PERIOD + np.hypot(TAG[0] - x, TAG[1] - y) / SOUND, name))
    return pd.DataFrame(rows, columns=["time", "receiver"])


def test_one_receiver_per_ping_scores_heard_and_unheard_pings_as_the_arrival_time_filter():
    # the detection curve's terms are the arrival-time measurement's, per particle and to the
    # last bit for the silences (the same code on the same clocks: reference emission E,
    # period P); the timing terms differ by design (a per-particle clock with a reset
    # share against one shared covariance), so only these are compared
    detections = _one_receiver_pings()
    tracks = ReceiverTracks.from_frame(MOORINGS)
    keys = {"period": PERIOD, "sound_speed": SOUND, "detection_curve": CURVE}
    built, obs = {}, {}
    for name in ("arrival-time", "ping-sequence"):
        settings = TrackingConfig.from_keys(measurement=name, **keys).measurement
        cls = MEASUREMENTS[name]
        obs[name] = cls.observations(detections, tracks, settings)
        built[name] = cls.from_settings(settings, obs[name], tracks)
    arrival, grouped = built["arrival-time"], built["ping-sequence"]
    assert obs["ping-sequence"]["heard"].eq(1).all()
    pf = ParticleFilter(VelocityMotion(0.05, 0.02), arrival, 500, (-200, 500, -200, 460), rng=3)
    pf.initialise(FIRST)
    p = pf.particles
    p.speed = np.zeros(p.n)  # (a tag at rest: its range at emission is its range now)
    rng = np.random.default_rng(3)
    emission = FIRST + rng.normal(0.0, 0.05, p.n)
    period = grouped.schedule_period
    p.extra.update(emission_time=emission, period=np.full(p.n, period), period_rate=np.zeros(p.n))
    p.extra.update(sequence_offset=emission, sequence_drift=np.zeros(p.n))
    time = FIRST + 11 * PERIOD  # silences of pings 0-10 (r0 and r2 hear none of ping 1)
    silence_at, cut = silence_since(
        arrival.silence, p.emission_time, p.period, p.x, p.y, time, 1.0, FIRST, PERIOD, SOUND
    )
    silence_gp, _ = grouped._silence(p, time, SequenceState(1.0, scheduled=0.0, silence_from=FIRST))
    np.testing.assert_array_equal(silence_gp, silence_at)
    assert np.ptp(silence_at) > 5.0  # informative: unheard close to a receiver costs
    # the arrival-time correction scores them in its compiled call, added after the
    # detections' terms: to the last bit, the detections' score (no window) plus these
    rows_last = arrival.as_matrix(obs["arrival-time"].iloc[[-1]])

    def corrected(silence_from):
        state = ClockState(1.0, arrival.clock.initial_covariance(1e-3), silence_from=silence_from)
        return arrival._loglik(p, rows_last, time, state, p.normalised_weights())

    fused, (_, _, fused_cut), _ = corrected(FIRST)
    np.testing.assert_array_equal(fused, corrected(np.inf)[0] + silence_at)
    assert fused_cut == cut == time + 0.5 - arrival.silence.tolerance
    # heard: log p(range) of the one receiver of the last ping, the curve's share of each score
    state = ClockState(1.0, covariance=arrival.clock.initial_covariance(1e-3), silence_from=np.inf)
    weights = p.normalised_weights()
    rows_at = arrival.as_matrix(obs["arrival-time"].iloc[[-1]])
    rows_gp = grouped.as_matrix(obs["ping-sequence"].iloc[[-1]])
    ping_time = float(rows_at[0, 0])

    def heard(measurement, score):
        with_curve = score(measurement)
        return with_curve - score(dataclasses.replace(measurement, silence=None))

    heard_at = heard(arrival, lambda m: m._loglik(p, rows_at, ping_time, state, weights)[0])
    heard_gp = heard(grouped, lambda m: m._sequence_score(p, rows_gp, ping_time, None, 1e-3)[0])
    expected = CURVE.log_probability(np.hypot(p.x - rows_at[0, 1], p.y - rows_at[0, 2]))
    np.testing.assert_allclose(heard_gp, heard_at, rtol=0, atol=1e-9)
    np.testing.assert_allclose(heard_gp, expected, rtol=0, atol=1e-8)


@pytest.fixture(scope="module")
def moored():
    """The case, its detections and the arrival-time run's options."""
    case = moored_array(SEED, duration=DURATION)
    detections, _, options = clock_inputs(case, SEED, PARTICLES, "velocity", DURATION)
    return case, detections, options


def _grouped(case, detections, options) -> dict:
    config = grouped_config(options, case.scenario.period, case.search_bounds)
    result = track(detections, case.scenario.receivers, config, options["motion"], seed=SEED)
    return score_run(result.estimates, case.scenario.truth)


def test_grouping_helps_when_three_receivers_hear_the_pings(moored):
    # measured with the detection curve at the default 2 ms arrival sd (session 10): 2.17 m
    # against 2.96 m from 10 min on (1 h runs, 18 fresh seeds: median ratio 0.75)
    case, detections, options = moored
    arrival = score_run(
        track_arrival(detections, case.scenario.receivers, options).estimates,
        case.scenario.truth,
    )
    grouped = _grouped(case, detections, options)
    assert grouped["converged"] and arrival["converged"]
    assert grouped["error_after_10_min_m"] < 0.8 * arrival["error_after_10_min_m"]
    assert grouped["error_after_10_min_m"] < 2.5


def _pings_heard_by(counts) -> pd.DataFrame:
    """Detections of the tag at TAG by the first ``counts[k]`` moorings at ping ``k``."""
    rows = []
    for k, count in enumerate(counts):
        for _, (name, x, y) in MOORINGS.iloc[:count][["receiver", "x", "y"]].iterrows():
            rows.append((FIRST + k * PERIOD + np.hypot(TAG[0] - x, TAG[1] - y) / SOUND, name))
    return pd.DataFrame(rows, columns=["time", "receiver"])


def test_a_fixed_period_tag_is_grouped_by_default_only_where_three_receivers_hear_its_pings():
    # the share of pings heard by three or more decides; two receivers never group
    n = 40
    at_share = math.ceil(GROUPING_SHARE * n)
    for counts, expected in (
        ([3] * n, "ping-sequence"),
        ([2] * n, "arrival-time"),
        ([3] * at_share + [2] * (n - at_share), "ping-sequence"),
        ([3] * (at_share - 1) + [1] * (n - at_share + 1), "arrival-time"),
    ):
        name, share = fixed_period_measurement(_pings_heard_by(counts), MOORINGS, PERIOD)
        assert name == expected
        assert share == pytest.approx(np.mean(np.array(counts) >= GROUPING_RECEIVERS))
    # the command line: --period and no --r0 names no measurement, and the pings choose;
    # a named measurement or known ranges are kept whatever the pings
    base = ["track", "--detections", "d.csv", "--receivers", "r.csv", "-o", "e.csv"]
    parser = build_parser()
    three, two = _pings_heard_by([3] * n), _pings_heard_by([2] * n)

    def chosen(*extra, detections=three):
        args = parser.parse_args([*base, *extra])
        return _chosen_for_period(args, build_config(args), detections, MOORINGS).measurement

    grouped = chosen("--period", "8")
    assert grouped.name == "ping-sequence" and grouped.period == 8.0
    assert grouped.chosen_sigma() == PERIOD_ARRIVAL_SIGMA
    assert chosen("--period", "8", detections=two).name == "arrival-time"
    assert chosen("--period", "8", "--measurement", "arrival-time").name == "arrival-time"
    assert chosen("--period", "8", "--r0", "r0=100").name == "range-rate"
    curve = chosen("--period", "8", "--detection-curve", "250", "50")
    assert curve.name == "ping-sequence" and curve.detection_curve == CURVE


def test_the_moored_arrays_detection_range_moves_the_share_heard_by_three_across_the_rule():
    # the threshold sweep's family: a shorter range, fewer pings reach the far mooring
    shares = {}
    for detection_range in (0.8, 1.75):
        case = moored_array(0, duration=1800, detection_range=detection_range)
        sc = case.scenario
        assert case.detection_probability.range_50 == pytest.approx(
            detection_range / 1.75 * moored_array(0, duration=1800).detection_probability.range_50
        )
        name, shares[detection_range] = fixed_period_measurement(
            case.corrected_detections(), sc.receivers, sc.period
        )
        assert name == ("ping-sequence" if detection_range == 1.75 else "arrival-time")
    assert shares[0.8] < GROUPING_SHARE < shares[1.75]
    assert 0.03 < shares[0.8] < 0.08 and shares[1.75] > 0.7


def test_the_filter_seed_summary_averages_each_method_over_its_filter_seeds():
    # per dataset the means over filter seeds run by both methods; "within noise" when the
    # method's mean is no higher than the baseline's worst filter seed; pooled the ratios'
    # geometric mean
    runs = [
        ("a", 1, 1, "arrival-time", 10.0),
        ("a", 1, 1001, "arrival-time", 11.0),
        ("a", 1, 2001, "arrival-time", 12.0),
        ("a", 1, 1, "grouped pings", 9.0),
        ("a", 1, 1001, "grouped pings", 10.0),
        ("a", 1, 2001, "grouped pings", 11.0),
        ("a", 1, 3001, "grouped pings", 99.0),  # no arrival-time run at this filter seed
        ("b", 2, 2, "arrival-time", 5.0),
        ("b", 2, 1002, "arrival-time", 5.0),
        ("b", 2, 2002, "arrival-time", 5.5),
        ("b", 2, 2, "grouped pings", 5.0),
        ("b", 2, 1002, "grouped pings", 5.0),
        ("b", 2, 2002, "grouped pings", 10.0),
        ("b", 2, 2, "other", 1.0),
    ]
    rows = pd.DataFrame(
        runs, columns=["scenario", "seed", "filter_seed", "method", "error_after_10_min_m"]
    )
    per_dataset, pooled = filter_seed_summary(rows, n_boot=2000)
    a, b = per_dataset.to_dict("records")
    assert a["filter_seeds"] == 3 and a["grouped pings_m"] == pytest.approx(10.0)
    assert a["arrival-time_spread"] == pytest.approx(1.2) and a["grouped pings_spread"] == 11 / 9
    assert a["ratio"] == pytest.approx(10 / 11) and a["within_noise"]
    assert b["ratio"] == pytest.approx(20 / 15.5) and not b["within_noise"]  # spread 1.1
    assert pooled["geometric_ratio"] == pytest.approx(math.sqrt(10 / 11 * 20 / 15.5))
    assert pooled["ratio_lo"] == pytest.approx(10 / 11) and pooled["ratio_hi"] == pytest.approx(
        20 / 15.5
    )
    assert not pooled["not_worse"] and pooled["within_noise"] == 1
    assert pooled["arrival-time_m"] == pytest.approx((11 + 31 / 6) / 2)


def test_the_share_sweep_runs_each_dataset_at_every_filter_seed_on_the_same_detections():
    kwargs = {"methods": ("arrival-time",), "n_particles": 300, "duration": 900.0}
    once = share_sweep([3], [1.2], **kwargs)
    rows = share_sweep([3], [1.2], filter_offsets=(0, 1000), **kwargs)
    assert list(rows["seed"]) == [3, 3] and list(rows["filter_seed"]) == [3, 1003]
    assert rows["share_by_3"].nunique() == 1
    errors = rows["error_after_10_min_m"]
    assert errors.iloc[0] == once["error_after_10_min_m"].iloc[0]
    assert errors.iloc[1] != errors.iloc[0]


def test_a_ping_needs_an_outlier_where_its_arrivals_cannot_all_be_direct_paths():
    # 100 pings from TAG: heard by the three moorings, every other one with the third
    # mooring's arrival 30 ms late (multipath), every fifth by two moorings only (not
    # counted); at the tag the late pings need an outlier, 60 m away every ping does
    positions = MOORINGS[["x", "y"]].to_numpy()
    rows = []
    for k in range(100):
        for i, (x, y) in enumerate(positions[: 2 if k % 5 == 0 else 3]):
            late = 0.03 if i == 2 and k % 2 else 0.0
            arrival = FIRST + k * PERIOD + np.hypot(TAG[0] - x, TAG[1] - y) / SOUND + late
            rows.append((k, arrival, x, y))
    obs = pd.DataFrame(rows, columns=["ping", "arrival", "receiver_x", "receiver_y"])
    obs["time"] = obs.groupby("ping")["arrival"].transform("min")
    times = np.arange(FIRST - 10.0, FIRST + 100 * PERIOD + 10.0)
    counted = [k for k in range(100) if k % 5 and k * PERIOD >= MIRROR_FROM]
    late = np.mean([k % 2 == 1 for k in counted])
    at_tag = pd.DataFrame({"time": times, "x": TAG[0], "y": TAG[1]})
    assert outlier_pings(obs, at_tag, SOUND) == pytest.approx(late)
    away = at_tag.assign(y=TAG[1] + 60.0)
    assert outlier_pings(obs, away, SOUND) == 1.0


def test_each_kind_of_sequence_has_its_own_arrival_sd_unless_told():
    def measurement(**keys):
        return TrackingConfig.from_keys(measurement="ping-sequence", **keys).measurement

    assert measurement(period=8.0).chosen_sigma() == PERIOD_ARRIVAL_SIGMA == 2e-3
    assert measurement(burst_sequence=(20.0, 30.0)).chosen_sigma() == SEQUENCE_ARRIVAL_SIGMA
    assert SEQUENCE_ARRIVAL_SIGMA == 1e-3
    assert measurement(period=8.0, arrival_sigma=5e-4).chosen_sigma() == 5e-4
    # the measurement built from the settings scores with it
    detections = _pings_heard_by([3] * 10)
    cls = MEASUREMENTS["ping-sequence"]
    for keys, sigma in (({"period": PERIOD}, 2e-3), ({"burst_sequence": (PERIOD,)}, 1e-3)):
        settings = measurement(**keys)
        obs = cls.observations(detections, ReceiverTracks.from_frame(MOORINGS), settings)
        assert cls.from_settings(settings, obs, MOORINGS).sigma == sigma


def test_a_matched_ping_scores_the_same_on_one_thread_and_two():
    rng = np.random.default_rng(5)
    n = 5000  # five chunks
    x, y = rng.uniform(-200, 500, (2, n))
    vx, vy = rng.normal(0, 0.5, (2, n))
    depth = np.zeros(n)
    clock = np.abs(rng.normal(0, 1e-3, (5, n)))
    clock[3] = 0.0
    rows = _pings_heard_by([3])
    arrival = rows["time"].to_numpy()
    xy = MOORINGS.set_index("receiver").loc[rows["receiver"], ["x", "y"]].to_numpy()
    out = {}
    for threads in (1, 2):
        loglik, emission, updated = np.empty(n), np.empty(n), np.empty((5, n))
        sequence_ping_loglik(
            x, y, vx, vy, depth, arrival, *xy.T.copy(), np.zeros(arrival.size), FIRST + 1.0,
            SOUND, FIRST, PERIOD, clock, np.array([1e-10, 1e-14]), 2e-3, 0.05, 2.0, loglik,
            emission, updated, threads=threads,
        )  # fmt: skip
        out[threads] = (loglik, emission, updated)
    for one, two in zip(out[1], out[2], strict=True):
        np.testing.assert_array_equal(one, two)
    assert np.ptp(out[1][0]) > 1.0  # particles scored apart
