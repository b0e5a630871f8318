"""Executors: serial, local processes and a Dask cluster give the same results, in task order."""

from __future__ import annotations

import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd
import pytest

from hmmtrack.executors import SerialExecutor, default_workers, get_executor, map_ordered


def noisy_walk(seed: np.random.SeedSequence) -> np.ndarray:
    """Stand-in trial: a seeded random walk whose run time varies, so tasks finish out of order."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(size=200)
    time.sleep(float(rng.uniform(0, 0.02)))
    return np.cumsum(steps)


def failing(task: int) -> int:
    if task == 3:
        raise ArithmeticError(f"task {task} failed")
    return task


SEEDS = np.random.SeedSequence(2024).spawn(12)


def _serial_reference() -> list[np.ndarray]:
    return [noisy_walk(s) for s in SEEDS]


def test_serial_executor_runs_in_order_and_keeps_exceptions_in_futures():
    with get_executor("serial") as ex:
        assert isinstance(ex, SerialExecutor)
        out = map_ordered(ex, noisy_walk, SEEDS)
        future = ex.submit(failing, 3)
    for got, want in zip(out, _serial_reference(), strict=True):
        np.testing.assert_array_equal(got, want)
    with pytest.raises(ArithmeticError, match="task 3"):
        future.result()


def test_processes_equal_serial_bit_for_bit():
    with get_executor("processes", max_workers=2) as ex:
        out = map_ordered(ex, noisy_walk, SEEDS, progress=False)
    for got, want in zip(out, _serial_reference(), strict=True):
        np.testing.assert_array_equal(got, want)


def test_results_come_back_in_task_order_when_tasks_finish_out_of_order():
    # threads finish in an order set by the sleeps; the results must still be in task order
    with ThreadPoolExecutor(max_workers=4) as pool:
        ex = get_executor(pool)
        assert ex is pool
        out = map_ordered(ex, noisy_walk, SEEDS, progress=True, description="walks")
    for got, want in zip(out, _serial_reference(), strict=True):
        np.testing.assert_array_equal(got, want)


def test_first_task_error_propagates():
    with get_executor("processes", max_workers=2) as ex, pytest.raises(ArithmeticError):
        map_ordered(ex, failing, list(range(6)))


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="unknown executor 'threads'"):
        get_executor("threads")
    with pytest.raises(ValueError, match="max_workers"):
        get_executor("processes", max_workers=0)
    assert default_workers() >= 1


@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


def test_dask_cluster_equals_serial_bit_for_bit(dask_client):
    import cloudpickle

    # the workers cannot import this test module, so its functions travel by value
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        with get_executor(dask_client) as ex:
            out = map_ordered(ex, noisy_walk, SEEDS)
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    for got, want in zip(out, _serial_reference(), strict=True):
        np.testing.assert_array_equal(got, want)


def test_filter_trials_on_dask_and_processes_equal_serial_bit_for_bit(dask_client):
    from hmmtrack import experiments

    datasets = experiments.paper_scenarios(4, names=("swimmer", "shark_pursuit"))
    scenarios = [datasets["swimmer"], experiments.truncate(datasets["shark_pursuit"], 400.0)]
    kwargs = {"n_trials": 2, "seed": 8, "n_particles": 80}
    serial = experiments.compare_motion_models(scenarios, **kwargs)
    on_dask = experiments.compare_motion_models(scenarios, executor=dask_client, **kwargs)
    on_processes = experiments.compare_motion_models(
        scenarios, executor="processes", max_workers=2, **kwargs
    )
    assert len(serial) == 12
    for other in (on_dask, on_processes):
        pd.testing.assert_frame_equal(serial.drop(columns="runtime"), other.drop(columns="runtime"))
