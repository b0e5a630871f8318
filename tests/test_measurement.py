import numpy as np
import pandas as pd
import pytest
from scipy.stats import multivariate_normal

from hmmtrack.tracking.compiled.chunks import default_threads
from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement, predicted_range_and_rate
from hmmtrack.tracking.particles import Particles

COVARIANCE = np.array([[4.0, 0.3], [0.3, 0.25]])


def some_particles():
    return Particles.from_state(
        x=np.array([0.0, 10.0, -35.0, 120.0]),
        y=np.array([0.0, 5.0, 80.0, -7.0]),
        heading=np.array([0.0, 1.0, -2.0, 3.0]),
        speed=np.array([0.0, 1.2, 0.4, 2.5]),
    )


def observations():
    return pd.DataFrame(
        {
            "time": [100.0, 100.0],
            "receiver": ["auv1", "auv2"],
            "range": [60.0, 140.0],
            "range_rate": [0.5, -1.0],
            "receiver_x": [50.0, -20.0],
            "receiver_y": [30.0, -130.0],
            "receiver_vx": [1.0, 0.0],
            "receiver_vy": [-0.5, 1.5],
        }
    )


def test_loglik_matches_scipy_multivariate_normal():
    p, obs = some_particles(), observations()
    got = RangeRateMeasurement(COVARIANCE).loglik(p, obs)
    expected = np.zeros(p.n)
    for i in range(p.n):
        vx = p.speed[i] * np.cos(p.heading[i])
        vy = p.speed[i] * np.sin(p.heading[i])
        for _, row in obs.iterrows():
            dx, dy = row.receiver_x - p.x[i], row.receiver_y - p.y[i]
            r = np.hypot(dx, dy)
            r_dot = (dx * (row.receiver_vx - vx) + dy * (row.receiver_vy - vy)) / r
            expected[i] += multivariate_normal([row.range, row.range_rate], COVARIANCE).logpdf(
                [r, r_dot]
            )
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_mapping_of_arrays_and_single_rows_work():
    p, obs = some_particles(), observations()
    model = RangeRateMeasurement(COVARIANCE)
    as_mapping = {c: obs[c].to_numpy() for c in obs.columns}
    np.testing.assert_allclose(model.loglik(p, as_mapping), model.loglik(p, obs))
    both = model.loglik(p, obs.iloc[:1]) + model.loglik(p, obs.iloc[1:])
    np.testing.assert_allclose(model.loglik(p, obs), both)
    np.testing.assert_array_equal(model.loglik(p, obs.iloc[:0]), np.zeros(p.n))


@pytest.mark.parametrize(
    ("receiver_v", "particle_speed", "sign"),
    [((1.0, 0.0), 0.0, +1), ((-1.0, 0.0), 0.0, -1), ((0.0, 0.0), 1.0, -1), ((0.0, 3.0), 0.0, 0)],
)
def test_range_rate_sign(receiver_v, particle_speed, sign):
    """Receiver east of a particle: moving east opens the range (r_dot > 0); a particle
    heading east towards it closes it; moving north is tangential (r_dot = 0)."""
    p = Particles.from_state(x=[0.0], y=[0.0], heading=[0.0], speed=particle_speed)
    r, r_dot = predicted_range_and_rate(p, 100.0, 0.0, *receiver_v)
    assert r[0, 0] == 100.0
    assert np.sign(r_dot[0, 0]) == sign
    assert abs(r_dot[0, 0]) == pytest.approx(abs(receiver_v[0]) + particle_speed)


def test_particle_on_the_receiver_gives_finite_loglik():
    p = Particles.from_state(x=[50.0], y=[30.0], heading=[0.0], speed=1.0)
    r, r_dot = predicted_range_and_rate(p, 50.0, 30.0, 0.0, 0.0)
    assert r[0, 0] == 0.0 and r_dot[0, 0] == 0.0
    assert np.isfinite(RangeRateMeasurement(COVARIANCE).loglik(p, observations())).all()


def test_from_std_and_bad_covariances():
    model = RangeRateMeasurement.from_std(2.0, 0.5, correlation=0.3)
    np.testing.assert_allclose(model.covariance, [[4.0, 0.3], [0.3, 0.25]])
    with pytest.raises(ValueError, match="positive definite"):
        RangeRateMeasurement(np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(ValueError, match="symmetric"):
        RangeRateMeasurement(np.array([[1.0, 0.1], [0.0, 1.0]]))
    with pytest.raises(ValueError, match=r"\(2, 2\)"):
        RangeRateMeasurement(np.eye(3))


def test_compiled_loglik_equals_the_numpy_prediction():
    rng = np.random.default_rng(5)
    p = Particles.from_state(
        x=rng.uniform(-500, 500, 500),
        y=rng.uniform(-500, 500, 500),
        heading=rng.uniform(-np.pi, np.pi, 500),
        speed=rng.gamma(2.0, 0.5, 500),
    )
    obs = observations()
    p.x[0], p.y[0] = obs["receiver_x"][0], obs["receiver_y"][0]  # on a receiver
    r_hat, r_dot_hat = predicted_range_and_rate(
        p, obs["receiver_x"], obs["receiver_y"], obs["receiver_vx"], obs["receiver_vy"]
    )
    errors = np.stack([r_hat - obs["range"].to_numpy(), r_dot_hat - obs["range_rate"].to_numpy()])
    precision = np.linalg.inv(COVARIANCE)
    mahalanobis = np.einsum("inm,ij,jnm->nm", errors, precision, errors)
    log_norm = -np.log(2 * np.pi) - 0.5 * np.log(np.linalg.det(COVARIANCE))
    expected = (log_norm - 0.5 * mahalanobis).sum(axis=1)
    np.testing.assert_allclose(
        RangeRateMeasurement(COVARIANCE).loglik(p, obs), expected, rtol=1e-12
    )


def test_loglik_in_chunks_is_the_same_on_any_number_of_threads():
    """The log-likelihood runs in chunks of 1,024 particles on the threads of the enclosing
    default_threads block; each particle's value is computed alone (last chunk partial)."""
    rng = np.random.default_rng(8)
    n = 3 * 1024 + 77
    p = Particles.from_state(
        x=rng.uniform(-500, 500, n),
        y=rng.uniform(-500, 500, n),
        heading=rng.uniform(-np.pi, np.pi, n),
        speed=rng.gamma(2.0, 0.5, n),
    )
    model, obs = RangeRateMeasurement(COVARIANCE), observations()
    with default_threads(1):
        one = model.loglik(p, obs)
    with default_threads(2):
        two = model.loglik(p, obs)
    np.testing.assert_array_equal(one, two)
    np.testing.assert_array_equal(one[-100:], model.loglik(p.take(np.arange(n - 100, n)), obs))


def test_matrix_form_scores_row_slices_like_the_table():
    """as_matrix reorders the model's columns (any table order, extra columns ignored), takes
    a matrix as converted, and loglik of a matrix row slice equals loglik of the same rows."""
    model = RangeRateMeasurement(COVARIANCE)
    p, obs = some_particles(), observations()
    shuffled = obs[list(reversed(obs.columns))]
    z = model.as_matrix(shuffled)
    assert z.shape == (2, 6)
    np.testing.assert_array_equal(z[:, 0], obs["range"])
    np.testing.assert_array_equal(z[:, 5], obs["receiver_vy"])
    np.testing.assert_array_equal(model.as_matrix({c: obs[c].to_numpy() for c in obs}), z)
    assert model.as_matrix(z) is z
    np.testing.assert_allclose(model.loglik(p, z[1:2]), model.loglik(p, obs.iloc[1:2]))
    np.testing.assert_allclose(model.loglik(p, z), model.loglik(p, obs))
