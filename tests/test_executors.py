"""Executors: serial, local processes and a Dask cluster give the same results, in task order."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import numpy as np
import pandas as pd
import pytest

from hmmtrack.experiments.executors import (
    SerialExecutor,
    _runs_on_import,
    default_workers,
    get_executor,
    map_ordered,
)


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


def end_own_worker(task: int) -> int:
    """Task 2 ends its worker process the way the out-of-memory killer would, or with a code."""
    if task == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    if task == 3:
        os._exit(7)
    return task


@pytest.mark.parametrize(
    ("tasks", "death", "cause"),
    [([0, 1, 2], "killed by SIGKILL", "out-of-memory"), ([0, 1, 3], "exit code 7", None)],
)
def test_a_dead_worker_is_named_with_its_exit_code_and_usual_cause(tasks, death, cause):
    with get_executor("processes", max_workers=2) as ex:
        with pytest.raises(BrokenProcessPool) as info:
            map_ordered(ex, end_own_worker, tasks)
    message = str(info.value)
    assert f": {death}" in message
    assert cause is None or cause in message
    assert "killed by SIGTERM (stopped by the pool" in message  # the other worker
    assert isinstance(info.value.__cause__, BrokenProcessPool)  # the pool's own terse error


def _refuse_to_load():
    raise EOFError("this result cannot be unpickled")


class ResultThatFailsToLoad:
    """Pickles in the worker, fails to unpickle in the parent (which breaks the pool)."""

    def __reduce__(self):
        return _refuse_to_load, ()


def unloadable_result(task: int) -> ResultThatFailsToLoad:
    return ResultThatFailsToLoad()


def test_a_pool_broken_without_a_worker_dying_blames_no_worker():
    with get_executor("processes", max_workers=1) as ex:
        with pytest.raises(BrokenProcessPool) as info:
            map_ordered(ex, unloadable_result, [0])
    message = str(info.value)
    assert message.startswith("the local process pool broke for the reason chained above")
    assert "killed by SIGTERM" in message and "process pool died" not in message
    assert "cannot be unpickled" in str(info.value.__cause__.__cause__)


def run_script(directory, body: str) -> subprocess.CompletedProcess:
    """Run ``body`` as a script file, as `python script.py` would (workers re-run it)."""
    script = directory / "script.py"
    script.write_text(textwrap.dedent(body))
    return subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, check=False
    )


def test_a_script_asking_for_processes_outside_a_main_guard_is_refused_by_line(tmp_path):
    # without the check, each worker re-runs the script while starting, starts a pool of its
    # own, dies, and the parent sees a bare BrokenProcessPool
    done = run_script(
        tmp_path,
        """\
        from hmmtrack.experiments.executors import get_executor, map_ordered

        with get_executor("processes", max_workers=1) as ex:
            print(map_ordered(ex, abs, [-1, -2]))
        """,
    )
    assert done.returncode == 1
    assert "RuntimeError" in done.stderr and "BrokenProcessPool:" not in done.stderr
    assert f"script {tmp_path / 'script.py'} (line 3)" in done.stderr
    assert 'if __name__ == "__main__":' in done.stderr


def test_a_guarded_script_runs_its_tasks_on_processes(tmp_path):
    done = run_script(
        tmp_path,
        """\
        from hmmtrack.experiments.executors import get_executor, map_ordered


        def main():
            with get_executor("processes", max_workers=2) as ex:
                print(map_ordered(ex, abs, [-1, -2, 3]))


        if __name__ == "__main__":
            main()
        """,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[1, 2, 3]"


def test_only_lines_outside_top_level_if_blocks_run_on_import():
    source = textwrap.dedent(
        """\
        import os

        def main():
            return 1

        main()
        if __name__ == "__main__":
            main()
        elif os.environ.get("WORKER") is None:
            main()
        with open(os.devnull) as f:
            main()
        """
    )
    flags = [_runs_on_import(source, line) for line in range(1, 13)]
    assert flags == [True, False, True, True, False, True] + [False] * 4 + [True, True]


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
