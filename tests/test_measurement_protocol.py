"""Conformance of every registered measurement to the Measurement protocol.

Each case is a small synthetic data set of the kind the measurement is for (a stationary tag
for the paper's range-rate measurement, a moored array with wandering tag clock for the
arrival-time one); every test runs on every entry of ``MEASUREMENTS``, so a new measurement
is checked by adding its case here.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pandas as pd
import pytest

from hmmtrack import io, scenarios
from hmmtrack.analysis.metrics import truth_at
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.scenarios.realistic import moored_array
from hmmtrack.tracking import pipeline
from hmmtrack.tracking.acquisition import Acquisition, grid_loglik
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.base import EVENT_COLUMNS, Measurement, Score
from hmmtrack.tracking.motion import VelocityMotion
from hmmtrack.tracking.tempering import Plain, Tempered

N = 400
SEED = 3


@dataclasses.dataclass(frozen=True)
class Case:
    """One measurement's synthetic data: detections, receivers, configuration, truth."""

    detections: pd.DataFrame
    receivers: pd.DataFrame
    config: TrackingConfig
    truth: pd.DataFrame


def range_rate_case() -> Case:
    sc = scenarios.stationary_tag(1)
    end = sc.start + 600.0
    config = tracking_config(sc, bounds=None, end=end, n_particles=N, motion="velocity")
    return Case(sc.detections[sc.detections["time"] <= end], sc.receivers, config, sc.truth)


def range_rate_gps_case() -> Case:
    """The range-rate case with the receivers' GPS error as an offset per receiver (the
    stationary tag's boat is moored: its offset constant)."""
    case = range_rate_case()
    return dataclasses.replace(case, config=case.config.override(measurement="range-rate-gps"))


def arrival_time_case() -> Case:
    case = moored_array(2, duration=600.0)
    sc = case.scenario
    config = TrackingConfig.from_keys(
        period=sc.period,
        measurement="arrival-time",
        n_particles=N,
        start=sc.start,
        end=sc.end,
        motion="velocity",
    )
    return Case(case.corrected_detections(), sc.receivers, config, sc.truth)


def ping_case() -> Case:
    """The arrival-time case's moored array and tag, each ping scored on its time
    differences (the period not used), with the ping measurement's own motion (its random
    walk: with the velocity model and the ping's tempering at 60 % ESS the filter follows a
    far-field ray on seeds 3 and 4). Three receivers' time differences leave far-field rays
    nearly as likely as the tag, so the search box is the array plus 100 m."""
    case = arrival_time_case()
    config = case.config.override(measurement="ping", motion="baseline", search_radius=100.0)
    return dataclasses.replace(case, config=config)


def ping_sequence_case() -> Case:
    """The ping case with the tag's emissions as a known sequence: a fixed-period tag is a
    sequence of one interval (its clock's wander is the drift the alignment follows)."""
    case = ping_case()
    period = arrival_time_case().config.measurement.period
    config = case.config.override(measurement="ping-sequence", burst_sequence=(period,))
    return dataclasses.replace(case, config=config)


CASES = {
    "range-rate": range_rate_case,
    "range-rate-gps": range_rate_gps_case,
    "arrival-time": arrival_time_case,
    "ping": ping_case,
    "ping-sequence": ping_sequence_case,
}


@pytest.fixture(scope="module", params=sorted(MEASUREMENTS))
def built(request):
    """(name, case, observations, measurement) of each registered measurement."""
    name = request.param
    assert name in CASES, f"measurement {name!r} has no conformance case"
    case = CASES[name]()
    cls = MEASUREMENTS[name]
    observations = cls.observations(case.detections, case.receivers, case.config.measurement)
    measurement = cls.from_settings(case.config.measurement, observations, case.receivers)
    return name, case, observations, measurement


def started_filter(case, measurement, observations):
    """The filter of ``track`` on ``case``, initialised at the first scored observation."""
    settings = case.config.measurement
    bounds = measurement.start_box(observations, case.receivers, settings, None, None)
    motion = VelocityMotion(0.05, 0.02)
    pf = pipeline.particle_filter(case.config.filter, measurement, bounds, motion, seed=SEED)
    scored, _ = measurement.split(observations)
    pf.initialise(float(np.rint(scored["time"].iloc[0])))
    return pf, scored


def test_registry_names_the_classes_that_satisfy_the_protocol(built):
    name, _, _, measurement = built
    assert type(measurement) is MEASUREMENTS[name]
    assert measurement.name == name
    assert isinstance(measurement, Measurement)
    assert isinstance(measurement.default_correction, Plain | Tempered)
    assert all(isinstance(c, str) for c in (*measurement.columns, *measurement.fields))


def test_observations_hold_the_columns_sorted_by_time_and_finite(built):
    _, case, observations, measurement = built
    assert len(observations) > 10
    assert {"time", *measurement.columns} <= set(observations.columns)
    assert observations["time"].is_monotonic_increasing
    scored, _ = measurement.split(observations)
    values = scored[["time", *measurement.columns]].to_numpy(dtype=float)
    assert np.isfinite(values).all()
    # the pipeline's build_observations is the measurement's, after choosing the transmitter
    pd.testing.assert_frame_equal(
        pipeline.build_observations(case.detections, case.receivers, case.config), observations
    )


def test_split_keeps_rows_and_describes_the_others_as_events(built):
    _, _, observations, measurement = built
    scored, events = measurement.split(observations)
    assert list(events.columns) == list(EVENT_COLUMNS)
    assert len(scored) + len(events) == len(observations)
    assert set(scored.index) <= set(observations.index)
    assert set(events["time"]) <= set(observations["time"])


def test_start_box_holds_the_truth_at_the_start_and_keeps_given_bounds(built):
    _, case, observations, measurement = built
    start = float(observations["time"].iloc[0])
    settings = case.config.measurement
    xmin, xmax, ymin, ymax = measurement.start_box(
        observations, case.receivers, settings, None, None
    )
    x, y = (float(v[0]) for v in truth_at(case.truth, np.array([start])))
    assert xmin < x < xmax and ymin < y < ymax
    assert xmax - xmin < 10_000 and ymax - ymin < 10_000  # a search box, not the ocean
    given = (x - 50.0, x + 50.0, y - 50.0, y + 50.0)
    assert measurement.start_box(observations, case.receivers, settings, given, None) == given


def test_owned_fields_are_created_and_carried_through_resampling(built):
    _, case, observations, measurement = built
    pf, _ = started_filter(case, measurement, observations)
    p = pf.particles
    for name in measurement.fields:
        assert np.shape(p.extra[name]) == (N,)
    p.log_weight = np.log(np.random.default_rng(0).dirichlet(np.ones(N)))
    before = {name: p.extra[name].copy() for name in measurement.fields}
    pf.resample()
    for name in measurement.fields:
        np.testing.assert_array_equal(pf.particles.extra[name], before[name][pf.last_ancestors])


def test_loglik_and_score_give_finite_floats_per_particle(built):
    _, case, observations, measurement = built
    pf, scored = started_filter(case, measurement, observations)
    first = scored[np.rint(scored["time"]) == pf.time]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        pf.correct(first)  # (starts what the measurement starts on a first observation)
    p = pf.particles
    loglik = measurement.loglik(p, first, pf.time)
    assert loglik.shape == (N,) and loglik.dtype == np.float64
    assert np.isfinite(loglik).all()
    assert np.ptp(loglik) > 0  # it tells particles apart
    score = getattr(measurement, "score", None)
    if score is not None:
        rows = measurement.as_matrix(first)
        state = pf.measurement_state
        result = score(p, rows, pf.time, state, pf.weights()[0])
        assert isinstance(result, Score)
        for values in (result.loglik, result.rescore(p, pf.weights()[0])):
            assert values.shape == (N,) and np.isfinite(values).all()
        x, log_weight = p.x.copy(), p.log_weight.copy()
        if result.commit is not None:
            result.commit(p)
        np.testing.assert_array_equal(p.x, x)
        np.testing.assert_array_equal(p.log_weight, log_weight)


def test_acquisition_grid_scores_the_first_corrections_through_the_protocol(built):
    """The acquisition's grid (the measurement's own ``score`` or ``loglik`` on points at
    rest) is highest near the tag, and the particles it draws start around it."""
    _, case, observations, measurement = built
    pf, scored = started_filter(case, measurement, observations)
    ticks = np.rint(scored["time"].to_numpy() - pf.time).astype(int)
    pf.acquisition = acquisition = Acquisition()
    as_matrix = getattr(measurement, "as_matrix", None)
    pf._acquire(pf.time, ticks, scored if as_matrix is None else as_matrix(scored))
    assert [e["kind"] for e in pf.events] == ["acquired"]
    corrections = [(pf.time + t, scored[ticks == t]) for t in np.unique(ticks)[:4]]
    if getattr(measurement, "as_matrix", None) is not None:
        corrections = [(t, measurement.as_matrix(rows)) for t, rows in corrections]
    grid, loglik = grid_loglik(measurement, pf.bounds, acquisition.cells, corrections, pf.dt)
    x, y = (float(v[0]) for v in truth_at(case.truth, np.array([pf.time])))
    best = int(np.argmax(loglik))
    cell = max(pf.bounds[1] - pf.bounds[0], pf.bounds[3] - pf.bounds[2]) / acquisition.cells
    assert np.hypot(grid.x[best] - x, grid.y[best] - y) < 3 * cell
    weights = pf.weights()[0]
    near = np.hypot(pf.particles.x - x, pf.particles.y - y) < 5 * cell
    # drawn where the likelihood is (a uniform start puts a small share there) ...
    area = np.pi * (5 * cell) ** 2 / ((pf.bounds[1] - pf.bounds[0]) * (pf.bounds[3] - pf.bounds[2]))
    assert near.mean() > 5 * area
    # ... and weighted back to the uniform prior (weights ∝ 1 / proposal)
    assert weights[near].sum() < 3 * area + 0.05


def test_collectors_are_fresh_each_run(built):
    _, _, _, measurement = built
    first, second = measurement.collectors(), measurement.collectors()
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        assert a is not b and type(a) is type(b)
        for hook in ("start", "corrected", "settled", "resampled", "result"):
            assert callable(getattr(a, hook))


def test_track_runs_every_measurement_to_the_tag(built):
    """One track() for every measurement: finite estimates every second, the collectors'
    tables in the result, and after 10 minutes within 25 m of the truth."""
    name, case, _, _ = built
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = pipeline.track(case.detections, case.receivers, case.config, seed=SEED)
    estimates = result.estimates
    assert len(estimates) == int(case.config.end - case.config.start) + 1
    assert np.isfinite(estimates[["x", "y", "sqrt_lambda1"]].to_numpy()).all()
    collected = [f for f in ("ambiguity", "clock", "pings") if getattr(result, f) is not None]
    expected = {
        "arrival-time": ["ambiguity", "clock"],
        "ping": ["pings"],
        "ping-sequence": ["pings"],
    }
    assert collected == expected.get(name, [])
    last = estimates.iloc[-1]
    x, y = (float(v[0]) for v in truth_at(case.truth, np.array([last["time"]])))
    assert np.hypot(last["x"] - x, last["y"] - y) < 25.0


def test_exact_duplicate_detections_are_dropped_once_for_every_measurement(built, caplog):
    """The same detection logged twice is used once, whatever the measurement (a pair at one
    time has no range-rate; arrival time would count it twice)."""
    _, case, observations, _ = built
    repeated = case.detections.iloc[[3, 7, 7, 20]]
    doubled = pd.concat([case.detections, repeated]).sort_values("time", kind="stable")
    with caplog.at_level("WARNING", logger="hmmtrack.io.detections"):
        rebuilt = pipeline.build_observations(doubled, case.receivers, case.config)
    pd.testing.assert_frame_equal(rebuilt, observations)
    assert "dropped 4 exact duplicate detection(s)" in caplog.text
    near = case.detections.iloc[[3]].assign(time=case.detections["time"].iloc[3] + 1e-3)
    with_near = pd.concat([case.detections, near]).sort_values("time", kind="stable")
    assert len(io.drop_duplicate_detections(with_near)) == len(case.detections) + 1
