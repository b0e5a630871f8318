"""Tests of hmmtrack.analysis.crb: closed forms, a brute-force batch information matrix,
finite-difference Jacobians, invariants; the fixed-tag fit against a grid search."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmmtrack.analysis.calibration import expected_measurements
from hmmtrack.analysis.crb import (
    BoundPrior,
    acceleration_psd_from_path,
    arrival_jacobians,
    arrival_time_bound,
    clock_dimension,
    detection_information,
    emission_clock_from_schedule,
    joint_transitions,
    kalman_covariances,
    rts_covariances,
    static_tag_crb,
    static_tag_fisher_information,
    static_tag_fit,
    tdoa_bound,
)
from hmmtrack.tracking.measurement.clock import EmissionClockModel
from hmmtrack.tracking.measurement.detection import LogisticDetection

C = 1500.0
PERIOD = 8.0


def moored(positions: dict[str, tuple[float, float]]) -> pd.DataFrame:
    return pd.DataFrame(
        [{"receiver": r, "time": np.nan, "x": x, "y": y} for r, (x, y) in positions.items()]
    )


def straight_truth(n_pings: int, velocity=(0.0, 0.0), start=(100.0, 50.0)):
    """A tag moving at constant velocity; emissions every PERIOD s from t = 0."""
    time = np.arange(0.0, PERIOD * n_pings + 1.0)
    truth = pd.DataFrame(
        {"time": time, "x": start[0] + velocity[0] * time, "y": start[1] + velocity[1] * time}
    )
    return truth, PERIOD * np.arange(n_pings)


def all_heard(n_pings: int, names) -> pd.DataFrame:
    return pd.DataFrame([{"ping": k, "receiver": r} for k in range(n_pings) for r in names])


def test_jacobian_matches_numerical_derivative_of_arrival_time():
    tag = np.array([[30.0, -40.0]])
    receiver = np.array([[-5.0, 12.0]])

    def arrival(state):  # t = e + |p - r| / c
        return state[4] + np.hypot(*(state[:2] - receiver[0])) / C

    state = np.array([30.0, -40.0, 0.3, -0.2, 17.0, PERIOD])
    numeric = np.array([(arrival(state + h) - arrival(state - h)) / 2e-4 for h in 1e-4 * np.eye(6)])
    (rows,) = arrival_jacobians(tag, receiver, np.array([0]), 1, 2, C)
    np.testing.assert_allclose(rows[0], numeric, rtol=1e-7, atol=1e-12)


def test_clock_dimension():
    assert clock_dimension(None) == 0
    assert clock_dimension(EmissionClockModel(PERIOD)) == 2
    assert clock_dimension(EmissionClockModel(PERIOD, rate_step_sd=1e-6)) == 3


def test_no_process_noise_equals_batch_fisher_inverse():
    """q = 0 and a rigid clock: every state is a linear map of the first, so the filter's
    last covariance and the smoother's first are the inverse batch information."""
    n_pings, sigma = 12, 2e-3
    truth, emissions = straight_truth(n_pings, velocity=(0.7, -0.3))
    receivers = {"a": (0.0, 0.0), "b": (400.0, 0.0), "c": (150.0, 300.0)}
    rng = np.random.default_rng(3)
    heard = all_heard(n_pings, receivers)
    heard = heard[rng.random(len(heard)) < 0.7].reset_index(drop=True)
    clock = EmissionClockModel(PERIOD, period_step_sd=0.0, phase_step_sd=0.0)
    prior = BoundPrior(position_sd=300.0, velocity_sd=2.0, emission_sd=2.0)
    table = arrival_time_bound(
        truth,
        moored(receivers),
        heard,
        emissions,
        clock=clock,
        acceleration_psd=0.0,
        sigma=sigma,
        sound_speed=C,
        prior=prior,
    )
    # closed form: z_k = Phi_k z_0 with x += v·t_k and e += k·P
    information = np.linalg.inv(prior.covariance(clock))
    maps = []
    for k, t in enumerate(emissions):
        phi = np.eye(6)
        phi[0, 2] = phi[1, 3] = t
        phi[4, 5] = k
        maps.append(phi)
        tag = truth[["x", "y"]].to_numpy()[int(t)]
        for r in heard.loc[heard["ping"] == k, "receiver"]:
            u = (tag - np.array(receivers[r])) / np.hypot(*(tag - np.array(receivers[r])))
            h = np.array([u[0] / C, u[1] / C, 0, 0, 1.0, 0]) @ phi
            information += np.outer(h, h) / sigma**2
    first = np.linalg.inv(information)
    last = maps[-1] @ first @ maps[-1].T
    np.testing.assert_allclose(
        table["smoother_position_m"].iloc[0], np.sqrt(first[0, 0] + first[1, 1]), rtol=1e-6
    )
    np.testing.assert_allclose(
        table["smoother_emission_s"].iloc[0], np.sqrt(first[4, 4]), rtol=1e-6
    )
    np.testing.assert_allclose(
        table["filter_position_m"].iloc[-1], np.sqrt(last[0, 0] + last[1, 1]), rtol=1e-6
    )
    np.testing.assert_allclose(table["filter_emission_s"].iloc[-1], np.sqrt(last[4, 4]), rtol=1e-6)


def test_single_receiver_known_clock_is_range_only():
    """One moored receiver, a fixed tag, clock known: only the range is learnt,
    radial variance 1 / (1/p² + N/(σc)²), the tangential stays at the prior."""
    n_pings, sigma, p = 40, 1e-3, 50.0
    truth, emissions = straight_truth(n_pings, start=(60.0, 80.0))
    prior = BoundPrior(position_sd=p, velocity_sd=1e-9)
    table = arrival_time_bound(
        truth,
        moored({"a": (0.0, 0.0)}),
        all_heard(n_pings, ["a"]),
        emissions,
        clock=None,
        acceleration_psd=0.0,
        sigma=sigma,
        sound_speed=C,
        prior=prior,
    )
    k = np.arange(1, n_pings + 1)
    radial = 1.0 / (1.0 / p**2 + k / (sigma * C) ** 2)
    np.testing.assert_allclose(table["filter_position_m"], np.sqrt(radial + p**2), rtol=1e-6)
    assert "filter_emission_s" not in table


def brute_force_covariances(initial, transitions, noises, jacobians):
    """Smoothed covariances as diagonal blocks of the inverse joint information of all
    states, and filtered ones as the last block of the same built up to each step."""
    n, n_steps = initial.shape[0], len(jacobians)
    information = np.zeros((n * n_steps, n * n_steps))
    information[:n, :n] = np.linalg.inv(initial)
    filtered = []
    for k in range(n_steps):
        block = slice(n * k, n * (k + 1))
        if k:
            link = np.hstack([-transitions[k - 1], np.eye(n)])
            both = slice(n * (k - 1), n * (k + 1))
            information[both, both] += link.T @ np.linalg.inv(noises[k - 1]) @ link
        information[block, block] += jacobians[k].T @ jacobians[k]
        upto = n * (k + 1)
        filtered.append(np.linalg.inv(information[:upto, :upto])[block, block])
    inverse = np.linalg.inv(information)
    smoothed = [inverse[n * k : n * (k + 1), n * k : n * (k + 1)] for k in range(n_steps)]
    return np.array(filtered), np.array(smoothed)


def test_recursions_equal_brute_force_batch_information():
    rng = np.random.default_rng(11)
    n_pings, sigma = 9, 1.5e-3
    emissions = np.cumsum(PERIOD + 0.01 * rng.standard_normal(n_pings))
    clock = EmissionClockModel(
        PERIOD, period_step_sd=2e-4, phase_step_sd=1e-4, rate_step_sd=3e-5, initial_rate_sd=1e-4
    )
    transitions, noises = joint_transitions(emissions, clock, 0.01)
    tag = rng.uniform(-100, 100, (20, 2))
    receiver = rng.uniform(-100, 100, (20, 2))
    ping = rng.integers(0, n_pings, 20)
    jacobians = arrival_jacobians(tag, receiver, ping, n_pings, 3, C)
    initial = BoundPrior(emission_sd=1.0).covariance(clock)
    jacobians = [rows / sigma for rows in jacobians]
    filtered, predicted = kalman_covariances(initial, transitions, noises, jacobians)
    smoothed = rts_covariances(filtered, predicted, transitions)
    want_filtered, want_smoothed = brute_force_covariances(initial, transitions, noises, jacobians)
    for got, want in ((filtered, want_filtered), (smoothed, want_smoothed)):
        scale = np.sqrt(np.einsum("kii->ki", want))
        np.testing.assert_allclose(
            got / scale[:, :, None] / scale[:, None, :],
            want / scale[:, :, None] / scale[:, None, :],
            atol=1e-7,
        )


def pursuit_like(seed: int, n_pings: int = 60):
    """A curving tag and two receivers circling it (1 Hz tracks)."""
    rng = np.random.default_rng(seed)
    time = np.arange(0.0, PERIOD * n_pings + 2.0)
    heading = np.cumsum(0.01 * rng.standard_normal(time.size))
    x, y = np.cumsum(np.cos(heading)), np.cumsum(np.sin(heading))
    truth = pd.DataFrame({"time": time, "x": x, "y": y})
    rows = []
    for j, name in enumerate(["a", "b", "c"]):
        bearing = 2 * np.pi * time / 600.0 + j * 2.1
        rows.append(
            pd.DataFrame(
                {
                    "receiver": name,
                    "time": time,
                    "x": x + 90 * np.cos(bearing),
                    "y": y + 90 * np.sin(bearing),
                }
            )
        )
    heard = all_heard(n_pings, ["a", "b", "c"])
    heard = heard[rng.random(len(heard)) < 0.6].reset_index(drop=True)
    emissions = 1.0 + PERIOD * np.arange(n_pings) + 0.02 * np.sin(np.arange(n_pings) / 7)
    return truth, pd.concat(rows, ignore_index=True), heard, emissions


def bound(truth, receivers, heard, emissions, clock, q=2e-3, sigma=1e-3):
    return arrival_time_bound(
        truth,
        receivers,
        heard,
        emissions,
        clock=clock,
        acceleration_psd=q,
        sigma=sigma,
        sound_speed=C,
    )


COLUMNS = ["filter_position_m", "smoother_position_m"]


@pytest.mark.parametrize("seed", [0, 1])
def test_adding_a_receiver_never_increases_the_bound(seed):
    truth, receivers, heard, emissions = pursuit_like(seed)
    clock = EmissionClockModel(PERIOD)
    two = heard[heard["receiver"] != "c"]
    with_two = bound(truth, receivers[receivers["receiver"] != "c"], two, emissions, clock)
    with_three = bound(truth, receivers, heard, emissions, clock)
    for column in COLUMNS + ["filter_emission_s", "smoother_emission_s"]:
        assert np.all(with_three[column] <= with_two[column] * (1 + 1e-9))
    assert with_three["smoother_position_m"].mean() < 0.8 * with_two["smoother_position_m"].mean()


@pytest.mark.parametrize("seed", [0, 1])
def test_more_process_noise_never_decreases_the_bound(seed):
    truth, receivers, heard, emissions = pursuit_like(seed)
    two = heard[heard["receiver"] != "c"]
    receivers = receivers[receivers["receiver"] != "c"]
    clock = EmissionClockModel(PERIOD, period_step_sd=1e-4, rate_step_sd=1e-6)
    noisier_clock = EmissionClockModel(PERIOD, period_step_sd=3e-4, rate_step_sd=3e-6)
    base = bound(truth, receivers, two, emissions, clock)
    for other in (
        bound(truth, receivers, two, emissions, clock, q=6e-3),
        bound(truth, receivers, two, emissions, noisier_clock),
    ):
        for column in COLUMNS:
            assert np.all(other[column] >= base[column] * (1 - 1e-9))
        assert other["smoother_position_m"].mean() > 1.05 * base["smoother_position_m"].mean()


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    keep=st.floats(0.2, 0.9),
    extra=st.sampled_from(["a", "b", "c"]),
)
def test_more_detections_never_increase_the_bound(seed, keep, extra):
    """Any subset of the detections gives a bound at least as large (information only adds)."""
    truth, receivers, heard, emissions = pursuit_like(seed, n_pings=25)
    rng = np.random.default_rng(seed)
    subset = heard[(rng.random(len(heard)) < keep) & (heard["receiver"] != extra)]
    clock = EmissionClockModel(PERIOD, rate_step_sd=1e-6, initial_rate_sd=1e-5)
    fewer = bound(truth, receivers, subset, emissions, clock)
    more = bound(truth, receivers, heard, emissions, clock)
    for column in COLUMNS + ["filter_emission_s", "smoother_emission_s"]:
        assert np.all(more[column] <= fewer[column] * (1 + 1e-9))


def test_known_clock_bound_is_below_unknown_clock_bound():
    truth, receivers, heard, emissions = pursuit_like(2)
    known = bound(truth, receivers, heard, emissions, None)
    unknown = bound(truth, receivers, heard, emissions, EmissionClockModel(PERIOD))
    for column in COLUMNS:
        assert np.all(known[column] <= unknown[column] * (1 + 1e-9))


def test_moving_receivers_are_looked_up_at_the_arrival_time():
    """A receiver moving at 50 m/s: the bound uses its position when the ping reaches it
    (flight times up to ~1 s, tens of metres of travel), not at emission."""
    truth, emissions = straight_truth(5, start=(0.0, 0.0))
    time = np.arange(0.0, 100.0)
    speed = 50.0
    mover = pd.DataFrame({"receiver": "m", "time": time, "x": 300.0, "y": speed * time})
    got = bound(truth, mover, all_heard(5, ["m"]), emissions, None, q=0.0)

    def filtered_bound(receiver_xy):
        jacobians = arrival_jacobians(np.zeros((5, 2)), receiver_xy, np.arange(5), 5, 0, C)
        transitions, noises = joint_transitions(emissions, None, 0.0)
        filtered, _ = kalman_covariances(
            BoundPrior().covariance(None), transitions, noises, [h / 1e-3 for h in jacobians]
        )
        return np.sqrt(filtered[:, 0, 0] + filtered[:, 1, 1])

    flight = np.full(5, 0.1)
    for _ in range(50):  # where the mover meets each ping: |(300, v (t_e + s))| = c s
        flight = np.hypot(300.0, speed * (emissions + flight)) / C
    at_arrival = filtered_bound(np.column_stack([np.full(5, 300.0), speed * (emissions + flight)]))
    at_emission = filtered_bound(np.column_stack([np.full(5, 300.0), speed * emissions]))
    np.testing.assert_allclose(got["filter_position_m"], at_arrival, rtol=1e-4)
    assert np.max(np.abs(at_emission / at_arrival - 1)) > 1e-2


@pytest.mark.parametrize("max_probability", [1.0, 0.8])
def test_detection_information_is_the_bernoulli_fisher_information(max_probability):
    curve = LogisticDetection(range_50=160.0, width=40.0, max_probability=max_probability)
    r = np.linspace(20.0, 400.0, 30)
    h = 1e-3
    p = curve.probability(r)
    slope = (curve.probability(r + h) - curve.probability(r - h)) / (2 * h)
    # E[(d/dr log P(outcome))²] summed over heard (prob. p) and missed (1 − p)
    brute = p * (slope / p) ** 2 + (1 - p) * (slope / (1 - p)) ** 2
    np.testing.assert_allclose(detection_information(curve, r), brute, rtol=1e-6)


def test_detection_curve_alone_gives_range_information_from_every_ping():
    """No ping heard, clock known, a fixed tag and one moored receiver: each ping adds
    I(r) along the range; the tangential variance stays at the prior."""
    n_pings, p = 30, 50.0
    truth, emissions = straight_truth(n_pings, start=(120.0, 90.0))
    curve = LogisticDetection(range_50=160.0, width=40.0)
    table = arrival_time_bound(
        truth,
        moored({"a": (0.0, 0.0)}),
        pd.DataFrame({"ping": np.array([], dtype=int), "receiver": []}),
        emissions,
        clock=None,
        acceleration_psd=0.0,
        sigma=1e-3,
        sound_speed=C,
        prior=BoundPrior(position_sd=p, velocity_sd=1e-9),
        detection=curve,
    )
    k = np.arange(1, n_pings + 1)
    radial = 1.0 / (1.0 / p**2 + k * detection_information(curve, 150.0))
    np.testing.assert_allclose(table["filter_position_m"], np.sqrt(radial + p**2), rtol=1e-6)


def test_acceleration_psd_recovered_from_a_constant_velocity_path():
    rng = np.random.default_rng(5)
    q, dt, n = 0.004, 1.0, 200_000
    velocity = np.cumsum(np.sqrt(q * dt) * rng.standard_normal((n, 2)), axis=0)
    # positions as sums of the 1 s velocities: the 8 s window means then differ from the
    # continuous-time law by (2L² + 1) / (2L²) = 0.8 % for L = 8 samples
    position = np.cumsum(velocity * dt, axis=0)
    truth = pd.DataFrame({"time": np.arange(n) * dt, "x": position[:, 0], "y": position[:, 1]})
    estimate = acceleration_psd_from_path(truth, 8.0)
    assert estimate == pytest.approx(q, rel=0.05)


def test_emission_clock_fit_recovers_rate_step():
    rng = np.random.default_rng(9)
    n, rate_sd, jitter = 2000, 2e-6, 65e-6
    rate = np.cumsum(rate_sd * rng.standard_normal(n))
    period = PERIOD + np.cumsum(rate)
    emissions = np.concatenate([[0.0], np.cumsum(period[:-1])]) + jitter * rng.standard_normal(n)
    model = emission_clock_from_schedule(emissions, jitter)
    assert model.rate_step_sd == pytest.approx(rate_sd, rel=0.2)
    assert model.period_step_sd == 0.0 and model.phase_step_sd == 0.0


def test_a_clock_with_no_spread_is_refused_by_the_smoother():
    truth, emissions = straight_truth(4)
    rigid = EmissionClockModel(PERIOD, period_step_sd=0.0, phase_step_sd=0.0, initial_period_sd=0.0)
    with pytest.raises(ValueError, match="singular"):
        bound(truth, moored({"a": (0.0, 0.0)}), all_heard(4, ["a"]), emissions, rigid, q=0.0)


def test_bad_input_names_rows_and_columns():
    truth, emissions = straight_truth(4)
    receivers = moored({"a": (0.0, 0.0)})
    kwargs = dict(clock=None, acceleration_psd=0.0, sigma=1e-3, sound_speed=C)
    with pytest.raises(ValueError, match=r"heard rows \[1\].*column ping"):
        arrival_time_bound(
            truth, receivers, pd.DataFrame({"ping": [0, 9], "receiver": "a"}), emissions, **kwargs
        )
    with pytest.raises(ValueError, match=r"heard rows \[1\].*twice"):
        arrival_time_bound(
            truth, receivers, pd.DataFrame({"ping": [2, 2], "receiver": "a"}), emissions, **kwargs
        )
    with pytest.raises(ValueError, match=r"pings \[4\].*outside"):
        arrival_time_bound(
            truth, receivers, all_heard(4, ["a"]), np.append(emissions, 1e6), **kwargs
        )
    with pytest.raises(ValueError, match=r"missing column\(s\) \['receiver'\]"):
        arrival_time_bound(truth, receivers, pd.DataFrame({"ping": [0]}), emissions, **kwargs)
    with pytest.raises(KeyError, match="unknown receiver 'z'"):
        arrival_time_bound(
            truth, receivers, pd.DataFrame({"ping": [0], "receiver": "z"}), emissions, **kwargs
        )


# --------------------------------------------------------------------------- information limit


def receivers_table(x, y, vx, vy):
    return pd.DataFrame(
        {"receiver_x": x, "receiver_y": y, "receiver_vx": vx, "receiver_vy": vy}, dtype=float
    )


def test_crb_of_two_moored_receivers_at_right_angles():
    """n detections each from (d, 0) and (0, d): J = n / σ_r² I, the CRB σ_r² / n I."""
    n, d, sigma_r = 25, 80.0, 3.0
    obs = receivers_table([d] * n + [0.0] * n, [0.0] * n + [d] * n, 0.0, 0.0)
    crb = static_tag_crb(obs, 0.0, 0.0, [[sigma_r**2, 0.0], [0.0, 0.04]])
    np.testing.assert_allclose(crb, sigma_r**2 / n * np.eye(2), rtol=1e-12, atol=1e-15)


def test_crb_of_a_receiver_passing_the_tag():
    """A receiver at (d, 0) moving (0, w): range fixes x, range-rate fixes y through
    ∂ṙ/∂y = −w/d, so the CRB is diag(σ_r², d² σ_ṙ² / w²)."""
    d, w, sigma_r, sigma_rate = 50.0, 1.5, 4.0, 0.3
    obs = receivers_table([d], [0.0], [0.0], [w])
    crb = static_tag_crb(obs, 0.0, 0.0, [[sigma_r**2, 0.0], [0.0, sigma_rate**2]])
    np.testing.assert_allclose(crb, np.diag([sigma_r**2, (d * sigma_rate / w) ** 2]), rtol=1e-12)


def test_fisher_information_matches_a_numerical_jacobian():
    """J = Σ Hᵀ Σ_z⁻¹ H with H from finite differences of expected_measurements."""

    rng = np.random.default_rng(5)
    obs = receivers_table(*rng.uniform(-200, 200, (2, 12)), *rng.normal(0, 1.5, (2, 12)))
    obs["time"] = np.arange(12.0)
    tag = np.array([12.0, -7.0])
    covariance = np.array([[16.0, 0.3], [0.3, 0.09]])

    def measured(p):
        return expected_measurements(
            obs, pd.DataFrame({"time": [np.nan], "x": [p[0]], "y": [p[1]]})
        )

    h = 1e-5
    jacobian = np.stack(
        [(measured(tag + h * e) - measured(tag - h * e)) / (2 * h) for e in np.eye(2)], axis=-1
    )  # (k, measurement, coordinate)
    expected = np.einsum("kmi,mn,knj->ij", jacobian, np.linalg.inv(covariance), jacobian)
    got = static_tag_fisher_information(obs, *tag, covariance)
    np.testing.assert_allclose(got, expected, rtol=1e-6)


def test_crb_is_infinite_when_a_direction_is_unobserved():
    """One moored receiver fixes the range only: no information across it."""
    obs = receivers_table([30.0] * 10, [40.0] * 10, 0.0, 0.0)
    assert np.isinf(static_tag_crb(obs, 0.0, 0.0, np.diag([4.0, 0.1]))).all()


def fixed_tag_measurements(obs, tag):
    """(range, range-rate) of a fixed tag: expected_measurements as the oracle."""

    truth = pd.DataFrame({"time": [np.nan], "x": [tag[0]], "y": [tag[1]]})
    return expected_measurements(obs, truth)


def two_receiver_observations(rng, tag, noise):
    """A moored receiver and one driving past, every 8 s, measured around a fixed tag."""
    t = np.arange(0.0, 400.0, 8.0)
    obs = receivers_table(
        np.r_[np.full(t.size, 30.0), -150.0 + 1.5 * t],
        np.r_[np.full(t.size, 20.0), np.full(t.size, -60.0)],
        np.r_[np.zeros(t.size), np.full(t.size, 1.5)],
        0.0,
    )
    obs["time"] = np.r_[t, t]
    exact = fixed_tag_measurements(obs, tag)
    obs["range"] = exact[:, 0] + noise[0] * rng.standard_normal(exact.shape[0])
    obs["range_rate"] = exact[:, 1] + noise[1] * rng.standard_normal(exact.shape[0])
    return obs


def test_static_fit_recovers_an_exact_tag():
    rng = np.random.default_rng(2)
    tag = np.array([5.0, -3.0])
    obs = two_receiver_observations(rng, tag, (0.0, 0.0))
    position, chi2 = static_tag_fit(obs, tag + [4.0, 3.0], np.diag([25.0, 0.25]))
    np.testing.assert_allclose(position, tag, atol=1e-6)
    assert chi2 == pytest.approx(0.0, abs=1e-9)


def test_static_fit_is_the_grid_minimum_of_the_weighted_cost():
    rng = np.random.default_rng(3)
    tag = np.array([5.0, -3.0])
    covariance = np.diag([4.0, 0.04])
    obs = two_receiver_observations(rng, tag, (2.0, 0.2))
    position, chi2 = static_tag_fit(obs, tag, covariance)
    measured = obs[["range", "range_rate"]].to_numpy()
    grid = np.linspace(-1.5, 1.5, 61)
    costs = np.array(
        [
            [
                (((fixed_tag_measurements(obs, tag + [a, b]) - measured) ** 2)
                 / np.diag(covariance)).sum()
                for b in grid
            ]
            for a in grid
        ]
    )  # fmt: skip
    i, j = np.unravel_index(costs.argmin(), costs.shape)
    assert chi2 <= costs.min() + 1e-9  # no grid point beats the fit
    np.testing.assert_allclose(position, tag + [grid[i], grid[j]], atol=0.05 + 1e-9)


TRIANGLE = {"a": (0.0, 0.0), "b": (300.0, 20.0), "c": (120.0, 260.0)}


def tdoa(truth, receivers, heard, emissions, emission, **options):
    options = {"acceleration_psd": 0.0, "sigma": 2e-4, "sound_speed": C} | options
    return tdoa_bound(truth, receivers, heard, emissions, emission=emission, **options)


def test_tdoa_bound_of_a_static_tag_is_the_closed_form_information_of_time_differences():
    """Static tag, three moored receivers, every ping heard by all: the bound after K pings
    is the inverse of K times Jᵀ (Σ⁻¹ − Σ⁻¹ 1 1ᵀ Σ⁻¹ / 1ᵀ Σ⁻¹ 1) J (flat prior)."""
    n_pings, sigma, jitter = 40, 2e-4, 1e-4
    truth, emissions = straight_truth(n_pings)
    prior = BoundPrior(position_sd=1e5, velocity_sd=1e-9)
    table = tdoa(
        truth, moored(TRIANGLE), all_heard(n_pings, "abc"), emissions, "random",
        sigma=sigma, jitter_sd=jitter, prior=prior,
    )  # fmt: skip
    tag = np.array([100.0, 50.0])
    offset = tag - np.array(list(TRIANGLE.values()))
    jacobian = offset / (np.hypot(*offset.T)[:, None] * C)
    covariance = sigma**2 * np.eye(3) + jitter**2 * np.ones((3, 3))
    precision = np.linalg.inv(covariance)
    ones = np.ones(3)
    projected = precision - np.outer(precision @ ones, ones @ precision) / (ones @ precision @ ones)
    information = jacobian.T @ projected @ jacobian
    expected = np.sqrt(np.trace(np.linalg.inv(n_pings * information)))
    assert table["filter_position_m"].iloc[-1] == pytest.approx(expected, rel=1e-6)
    # a static tag: the smoother knows at every ping what the filter knows at the last
    np.testing.assert_allclose(table["smoother_position_m"], expected, rtol=1e-6)
    # the emission time drops out: jitter does not change the random-interval bound
    plain = tdoa(
        truth, moored(TRIANGLE), all_heard(n_pings, "abc"), emissions, "random",
        sigma=sigma, prior=prior,
    )  # fmt: skip
    np.testing.assert_allclose(plain["filter_position_m"], table["filter_position_m"], rtol=1e-9)
    # one receiver per ping is no information at all
    still = BoundPrior(position_sd=200.0, velocity_sd=1e-9)
    alone = tdoa(truth, moored(TRIANGLE), all_heard(n_pings, "a"), emissions, "random", prior=still)
    np.testing.assert_allclose(alone["filter_position_m"], np.sqrt(2) * 200.0, rtol=1e-9)


@pytest.mark.parametrize("seed", [1, 2])
def test_known_sequence_bound_is_at_most_the_random_interval_bound(seed):
    truth, receivers, heard, emissions = pursuit_like(seed)
    options = {"acceleration_psd": 0.01, "jitter_sd": 1e-4}
    random = tdoa(truth, receivers, heard, emissions, "random", **options)
    known = tdoa(truth, receivers, heard, emissions, "sequence", **options)
    for column in COLUMNS:
        assert np.all(known[column] <= random[column] * (1 + 1e-9))
    # pings heard by one receiver inform the sequence's position only: it is far better
    assert known["smoother_position_m"].mean() < 0.5 * random["smoother_position_m"].mean()


def test_known_sequence_with_a_known_offset_and_drift_is_the_known_clock_bound():
    truth, receivers, heard, emissions = pursuit_like(3)
    known = tdoa(
        truth, receivers, heard, emissions, "sequence",
        acceleration_psd=2e-3, sigma=1e-3, offset_sd=1e-9, drift_sd=1e-12,
    )  # fmt: skip
    clock = bound(truth, receivers, heard, emissions, None)
    for column in COLUMNS:
        np.testing.assert_allclose(known[column], clock[column], rtol=1e-6)


def test_tdoa_bound_refuses_an_unknown_emission_model():
    truth, emissions = straight_truth(5)
    with pytest.raises(ValueError, match=r"emission must be one of \('random', 'sequence'\)"):
        tdoa(truth, moored(TRIANGLE), all_heard(5, "abc"), emissions, "periodic")


def test_tdoa_oracle_errors_have_the_bound_as_their_mean_square():
    """The bound's efficient estimator (exact Kalman filter and RTS smoother of the
    linearised model): its errors are linear in the noise, so the sum of its squared
    position errors over one impulse of one sd per arrival is its mean-square error over
    the draws, which is the bound exactly (no process noise, the velocity known); a common
    error of a ping (its emission time) changes nothing, and without noise on a
    constant-velocity path it is exact."""
    n_pings, sigma = 6, 2e-4
    truth, emissions = straight_truth(n_pings, velocity=(0.3, -0.2))
    heard = all_heard(n_pings, "abc")
    # a path the model knows but for its position: no process noise, velocity known
    prior = BoundPrior(position_sd=1e4, velocity_sd=1e-6)
    options = {"acceleration_psd": 0.0, "sigma": sigma, "prior": prior}
    columns = ["filter_error_m", "smoother_error_m"]
    squares = 0.0
    for row in range(len(heard)):
        impulse = sigma * (np.arange(len(heard)) == row)
        table = tdoa(truth, moored(TRIANGLE), heard, emissions, "random", noise=impulse, **options)
        squares = squares + table[columns].to_numpy() ** 2
    bounds = table[["filter_position_m", "smoother_position_m"]].to_numpy()
    np.testing.assert_allclose(np.sqrt(squares), bounds, rtol=1e-6)
    noise = np.random.default_rng(5).normal(0.0, sigma, len(heard))
    drawn = tdoa(truth, moored(TRIANGLE), heard, emissions, "random", noise=noise, **options)
    shifted = noise + heard["ping"].to_numpy() * 1e-3  # one emission-time error per ping
    moved = tdoa(truth, moored(TRIANGLE), heard, emissions, "random", noise=shifted, **options)
    np.testing.assert_allclose(moved[columns], drawn[columns], atol=1e-9)
    assert drawn[columns].to_numpy().min() > 1e-3
    quiet = tdoa(truth, moored(TRIANGLE), heard, emissions, "random", noise=0 * noise, **options)
    np.testing.assert_allclose(quiet[columns], 0.0, atol=1e-9)
