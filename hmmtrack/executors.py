"""Where Monte Carlo trials run: one ``concurrent.futures`` seam for serial, local and Dask runs.

:func:`get_executor` turns a user's choice (``"serial"``, ``"processes"`` or a Dask
``distributed.Client``) into a :class:`concurrent.futures.Executor`, and :func:`map_ordered`
runs a function over a list of tasks on any such executor and returns the results in task
order, with an optional progress bar. Because every trial carries its own seed, the answer
does not depend on which executor ran it or in what order the tasks finished.

This module is for *dispatching* work; it knows nothing about trials, filters or seeds
(those live in :mod:`hmmtrack.experiments`). Dask is an optional extra (``hmmtrack[dask]``)
and is never imported here: a Dask client is recognised by its ``get_executor`` method.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from typing import Any

__all__ = ["SerialExecutor", "get_executor", "map_ordered", "default_workers"]


class SerialExecutor(Executor):
    """An executor that runs each task in the calling process when it is submitted.

    The reference against which parallel executors are checked; also the cheapest choice for
    tiny runs, since nothing is pickled.
    """

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # handed to the caller through the future, as in the pools
            future.set_exception(exc)
        return future


def default_workers() -> int:
    """Number of worker processes used when none is given: the CPUs this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - platforms without sched_getaffinity
        return os.cpu_count() or 1


#: how local worker processes start: "forkserver" forks workers from a fresh server process,
#: so they never inherit a parent's running OpenMP runtime (which is not fork-safe)
_START_METHOD = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"


def _single_threaded_worker() -> None:
    """Worker initialiser: numba's parallel kernels use one thread in each worker process."""
    import numba

    numba.set_num_threads(1)


def get_executor(kind: str | Any = "serial", max_workers: int | None = None) -> Executor:
    """Return an executor for ``kind``.

    Parameters
    ----------
    kind : {"serial", "processes"} or distributed.Client or Executor
        ``"serial"`` runs tasks in this process; ``"processes"`` uses a local
        :class:`~concurrent.futures.ProcessPoolExecutor` whose workers start clean (no
        fork of this process, whose OpenMP threads may already be running) and run compiled
        kernels on one thread each (one process per core, no oversubscription); a Dask
        ``distributed.Client`` (any object with a ``get_executor`` method) sends the tasks
        to its cluster; an existing
        :class:`~concurrent.futures.Executor` is returned as it is.
    max_workers : int, optional
        Worker processes for ``"processes"`` (default :func:`default_workers`, i.e. all
        cores). Ignored for ``"serial"``; for a Dask client the cluster decides.

    Returns
    -------
    concurrent.futures.Executor
        Use it as a context manager (``with get_executor(...) as ex:``) so that local pools
        are shut down. Shutting down a Dask client's executor leaves the client running.

    Raises
    ------
    ValueError
        For an unknown ``kind`` string or a ``max_workers`` below 1.
    """
    if max_workers is not None and max_workers < 1:
        raise ValueError(f"max_workers must be a positive integer, got {max_workers!r}")
    if isinstance(kind, Executor):
        return kind
    if hasattr(kind, "get_executor"):
        return kind.get_executor()
    if kind == "serial":
        return SerialExecutor()
    if kind == "processes":
        return ProcessPoolExecutor(
            max_workers=max_workers or default_workers(),
            mp_context=multiprocessing.get_context(_START_METHOD),
            initializer=_single_threaded_worker,
        )
    raise ValueError(
        f"unknown executor {kind!r}: expected 'serial', 'processes', a dask distributed.Client "
        "or a concurrent.futures.Executor"
    )


def map_ordered(
    executor: Executor,
    fn: Callable[[Any], Any],
    tasks: Sequence[Any],
    progress: bool = False,
    description: str | None = None,
) -> list[Any]:
    """Run ``fn(task)`` for every task on ``executor``; return the results in task order.

    Parameters
    ----------
    executor : concurrent.futures.Executor
        From :func:`get_executor`. ``fn`` must be a module-level function (picklable) for
        process pools and Dask.
    fn : callable
        One argument, the task.
    tasks : sequence
        The tasks, shape (n,).
    progress : bool
        Show a ``tqdm`` bar that advances as tasks finish (in any order).
    description : str, optional
        Label of the progress bar.

    Returns
    -------
    list, shape (n,)
        ``[fn(t) for t in tasks]``, whatever order the workers finished in.

    Raises
    ------
    Exception
        The first exception raised by a task, after the remaining tasks are cancelled.
    """
    futures = [executor.submit(fn, task) for task in tasks]
    index = {id(f): i for i, f in enumerate(futures)}
    results: list[Any] = [None] * len(futures)
    try:
        for future in _progress(as_completed(futures), len(futures), progress, description):
            results[index[id(future)]] = future.result()
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    return results


def _progress(
    futures: Iterable[Future], total: int, show: bool, description: str | None
) -> Iterator[Future]:
    if not show:
        return iter(futures)
    from tqdm.auto import tqdm

    return iter(tqdm(futures, total=total, desc=description, unit="task"))
