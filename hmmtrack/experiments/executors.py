"""Where Monte Carlo trials run: one ``concurrent.futures`` seam for serial, local and Dask runs.

:func:`get_executor` turns a user's choice (``"serial"``, ``"processes"`` or a Dask
``distributed.Client``) into a :class:`concurrent.futures.Executor`, and :func:`map_ordered`
runs a function over a list of tasks on any such executor and returns the results in task
order, with an optional progress bar. Because every trial carries its own seed, the answer
does not depend on which executor ran it or in what order the tasks finished.

Local processes and scripts
---------------------------
Local worker processes start clean (``forkserver``, or ``spawn`` where there is no
forkserver) and, before their first task, **run the main script again** (as module
``__mp_main__``) so that functions defined in it can be found. A script that asks for
``executor="processes"`` must therefore keep its top-level work under a guard::

    from hmmtrack import experiments

    if __name__ == "__main__":
        table = experiments.compare_motion_models(..., executor="processes")

Without the guard every worker would start a pool of its own while starting up and die, and
the pool would fail with a bare ``BrokenProcessPool``; :func:`get_executor` checks this and
refuses with an error naming the script and line instead. ``python -c``, notebooks and
``python -m package`` have no script to re-run and need no guard.

When a worker does die (killed by the out-of-memory killer, a crash in compiled code, a module
that fails to import in the worker), :func:`map_ordered` raises a ``BrokenProcessPool`` that
names each worker's exit code or signal and what it usually means. Workers print a Python
traceback on stderr when they crash in compiled code (:mod:`faulthandler`).

This module is for *dispatching* work; it knows nothing about trials, filters or seeds
(those live in :mod:`hmmtrack.experiments`). Dask is an optional extra (``hmmtrack[dask]``)
and is never imported here: a Dask client is recognised by its ``get_executor`` method.
"""

from __future__ import annotations

import ast
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from types import FrameType
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


def _start_worker() -> None:
    """Worker initialiser: numba's parallel kernels use one thread in each worker process, and
    a crash in compiled code prints the worker's Python traceback on stderr."""
    import faulthandler

    import numba

    faulthandler.enable()
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
    RuntimeError
        For ``"processes"`` asked for by a script's top-level code outside an
        ``if __name__ == "__main__":`` block, which every worker would run again while
        starting (see the module docstring).
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
        _refuse_unguarded_script()
        return ProcessPoolExecutor(
            max_workers=max_workers or default_workers(),
            mp_context=multiprocessing.get_context(_START_METHOD),
            initializer=_start_worker,
        )
    raise ValueError(
        f"unknown executor {kind!r}: expected 'serial', 'processes', a dask distributed.Client "
        "or a concurrent.futures.Executor"
    )


def _refuse_unguarded_script() -> None:
    """Raise if the main script's top-level code is calling us outside any ``if`` block.

    Workers re-run the main script before their first task (module docstring); code outside
    an ``if`` block would then start a pool inside every starting worker. Any top-level
    ``if`` is trusted to be a guard: only code that runs whenever the script runs is refused.
    """
    frame = _main_script_frame()
    if frame is None:
        return
    path = frame.f_code.co_filename
    try:
        with open(path, encoding="utf-8") as file:
            source = file.read()
        unguarded = _runs_on_import(source, frame.f_lineno)
    except (OSError, SyntaxError, ValueError):  # the script cannot be read back: do not guess
        return
    if unguarded:
        raise RuntimeError(
            f"executor='processes' was requested by the top-level code of the script {path} "
            f'(line {frame.f_lineno}), outside an `if __name__ == "__main__":` block. Each '
            "worker process runs the main script again while starting, so every worker would "
            "start workers of its own and die (BrokenProcessPool). Put the script's top-level "
            'work under `if __name__ == "__main__":`, or use executor="serial".'
        )


def _main_script_frame() -> FrameType | None:
    """The frame running the top-level code of the main script that workers will re-run, if
    such a script is on the call stack (not for ``python -c``, notebooks or ``python -m
    package``, whose main module is not re-run)."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    module_name = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if path is None or module_name == "__main__" or module_name.endswith(".__main__"):
        return None
    main_globals = vars(main)
    frame = sys._getframe(1)
    while frame is not None:
        code = frame.f_code
        if frame.f_globals is main_globals and code.co_name == "<module>":
            return frame if code.co_filename == path else None
        frame = frame.f_back
    return None


def _runs_on_import(source: str, line: int) -> bool:
    """Whether line ``line`` of a module's ``source`` runs every time the module is run.

    Parameters
    ----------
    source : str
        Python source of the module.
    line : int
        1-based line number.

    Returns
    -------
    bool
        True when the line lies in a top-level statement other than an ``if`` block (such as
        ``if __name__ == "__main__":``); False inside any top-level ``if`` or outside every
        statement.
    """
    for statement in ast.parse(source).body:
        if statement.lineno <= line <= (statement.end_lineno or statement.lineno):
            return not isinstance(statement, ast.If)
    return False


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
    concurrent.futures.process.BrokenProcessPool
        When a worker of a local process pool died: the message names every worker's exit
        code or signal and its usual cause; the pool is shut down.
    Exception
        The first exception raised by a task, after the remaining tasks are cancelled.
    """
    futures: list[Future] = []
    results: list[Any] = [None] * len(tasks)
    try:
        futures.extend(executor.submit(fn, task) for task in tasks)
        index = {id(f): i for i, f in enumerate(futures)}
        for future in _progress(as_completed(futures), len(futures), progress, description):
            results[index[id(future)]] = future.result()
    except BaseException as error:
        for future in futures:
            future.cancel()
        if isinstance(error, BrokenProcessPool) and isinstance(executor, ProcessPoolExecutor):
            raise BrokenProcessPool(_worker_deaths(executor)) from error
        raise
    return results


#: what a worker's end usually means, by exit code (negative: killed by that signal)
_EXIT_CAUSES = {
    1: "an uncaught Python error outside the tasks, printed on stderr above: a module that "
    "fails to import in the worker (a source file edited while the run starts?), or a script "
    're-run by the worker whose top-level code is not under `if __name__ == "__main__":`',
    -signal.SIGKILL: "SIGKILL is what the kernel's out-of-memory killer sends: check memory "
    "use (and `dmesg`), or run fewer workers (max_workers)",
    -signal.SIGSEGV: "a crash in compiled code (a numba kernel or a C library); the worker's "
    "Python traceback is on stderr above",
    -signal.SIGABRT: "an abort in compiled code (a numba kernel, OpenMP or a C library); see "
    "stderr above",
    -signal.SIGTERM: "stopped by the pool once another worker had died, or by another program",
}


def _worker_deaths(pool: ProcessPoolExecutor) -> str:
    """Message of a broken local pool: every worker's exit code or signal and its usual cause.

    Shuts the broken pool down first, so that every worker has ended and has its exit code.
    """
    # CPython keeps the workers as ``_processes`` (pid -> multiprocessing.Process); without
    # it the message lacks the exit codes but keeps the advice
    workers = dict(getattr(pool, "_processes", None) or {})
    pool.shutdown(wait=True)
    stopped_by_pool = (None, -signal.SIGTERM)
    if any(process.exitcode not in stopped_by_pool for process in workers.values()):
        lines = ["a worker process of the local process pool died, so the pool stopped."]
    else:
        lines = ["the local process pool broke for the reason chained above, and stopped."]
    lines[0] += " The remaining tasks were not run."
    for pid, process in sorted(workers.items()):
        code = process.exitcode
        cause = _EXIT_CAUSES.get(code)
        lines.append(f"  worker {pid}: {_exit_name(code)}" + (f" ({cause})" if cause else ""))
    lines.append(
        "Tasks carry their own seeds, so running the same call again gives the same results; "
        'executor="serial" runs them in this process and shows any error directly.'
    )
    return "\n".join(lines)


def _exit_name(code: int | None) -> str:
    """``exit code 1``, ``killed by SIGKILL`` or ``still running`` for a process's exit code."""
    if code is None:
        return "still running"
    if code >= 0:
        return f"exit code {code}"
    try:
        return f"killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"killed by signal {-code}"


def _progress(
    futures: Iterable[Future], total: int, show: bool, description: str | None
) -> Iterator[Future]:
    if not show:
        return iter(futures)
    from tqdm.auto import tqdm

    return iter(tqdm(futures, total=total, desc=description, unit="task"))
