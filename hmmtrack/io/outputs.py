"""Outputs written whole or not at all, and a command's paths checked before it computes.

A tool run on a season of irreplaceable detections must never overwrite an input, never
leave a half-written file that looks complete, and never lose the previous good output to a
failed or interrupted run. Three pieces give that:

* :func:`check_paths` -- before any work: every input a readable file, every output's folder
  present and writable, no output the same file as an input (symlinks and other spellings
  included) or as another output, a folder output not an existing file;
* :func:`atomic_files` -- each file written to a temporary file in its own folder and renamed
  onto its name only when every file of the set was written; removed on any exception,
  ``KeyboardInterrupt`` included (the CLI turns SIGINT and SIGTERM into one);
* :func:`staged_folder` -- a folder of outputs built in a temporary sibling folder, under a
  lock file against a concurrent run into the same folder, and moved into place at the end.

The renames that commit a set of outputs run with SIGINT and SIGTERM deferred, so a signal
never splits a set: it is delivered once the set is in place.

Environment variable ``HMMTRACK_PAUSE_BEFORE_COMMIT`` (for tests of interruption only): a
file path; when set, a writer that has written all its temporary files creates that file and
waits up to :data:`PAUSE_SECONDS` before committing, so that a test can signal the process
in its write phase deterministically.

Not for: what goes into the files (the readers and writers beside this module).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Iterator, Mapping
from pathlib import Path

#: the test hook's environment variable (see the module docstring)
PAUSE_VARIABLE = "HMMTRACK_PAUSE_BEFORE_COMMIT"
#: how long the test hook waits for a signal (s)
PAUSE_SECONDS = 60.0

_DEFERRED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _describe(option: str, path: str | Path) -> str:
    return f"{option} {path}"


def check_paths(
    inputs: Mapping[str, str | Path | None] = {},
    outputs: Mapping[str, str | Path | None] = {},
    folders: Mapping[str, str | Path | None] = {},
) -> None:
    """Refuse, before any work, paths that would fail late or destroy an input.

    Parameters
    ----------
    inputs : mapping of str to path or None
        Option name (as the user typed it, e.g. ``"--detections"``) -> file read; ``None``
        entries (options not given) are skipped. Each must be a readable file.
    outputs : mapping of str to path or None
        Option name -> file written. Each must not be a folder, its folder must exist and be
        writable, and it must not be the same file as an input or another output.
    folders : mapping of str to path or None
        Option name -> folder written (created if absent). It must not be an existing file,
        its parent folder must exist and be writable, and no input may lie inside it.

    Raises
    ------
    FileNotFoundError
        An input, or an output's folder, does not exist.
    IsADirectoryError, NotADirectoryError
        An input or output file is a folder; a folder output is a file.
    PermissionError
        An input is not readable, or an output's folder not writable.
    ValueError
        An output is the same file as an input or another output, or a folder output
        holds an input.
    """
    given_inputs = {k: Path(v) for k, v in inputs.items() if v is not None}
    for option, path in given_inputs.items():
        if not path.exists():
            raise FileNotFoundError(f"{_describe(option, path)}: no such file")
        if path.is_dir():
            raise IsADirectoryError(f"{_describe(option, path)}: is a folder, not a file")
        if not os.access(path, os.R_OK):
            raise PermissionError(f"{_describe(option, path)}: not readable")
    given_outputs = {k: Path(v) for k, v in outputs.items() if v is not None}
    for option, path in given_outputs.items():
        if path.is_dir():
            raise IsADirectoryError(
                f"{_describe(option, path)}: is a folder; give a file name to write"
            )
        _check_writable_folder(option, path, path.parent)
    for option, path in given_outputs.items():
        for other, source in given_inputs.items():
            if _same_file(path, source):
                raise ValueError(
                    f"{_describe(option, path)} is the input {_describe(other, source)}: "
                    "writing it would destroy the input; choose another output name"
                )
    seen: dict[Path, str] = {}
    for option, path in given_outputs.items():
        key = _resolved(path)
        if key in seen:
            raise ValueError(
                f"{_describe(option, path)} and {_describe(seen[key], path)} name the same "
                "file; give each output its own name"
            )
        seen[key] = option
    for option, folder in ((k, Path(v)) for k, v in folders.items() if v is not None):
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(
                f"{_describe(option, folder)}: is an existing file, not a folder; "
                "give a folder name"
            )
        _check_writable_folder(option, folder, folder.parent)
        for other, source in given_inputs.items():
            if folder.exists() and _resolved(source).is_relative_to(_resolved(folder)):
                raise ValueError(
                    f"{_describe(option, folder)} holds the input {_describe(other, source)}: "
                    "the run would replace it; choose another output folder"
                )


def _check_writable_folder(option: str, path: Path, folder: Path) -> None:
    folder = folder if str(folder) else Path(".")
    if not folder.is_dir():
        raise FileNotFoundError(
            f"{_describe(option, path)}: the folder {folder} does not exist; create it first"
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(f"{_describe(option, path)}: the folder {folder} is not writable")


def _resolved(path: Path) -> Path:
    return Path(os.path.realpath(path))


def _same_file(a: Path, b: Path) -> bool:
    if a.exists() and b.exists():
        return os.path.samefile(a, b)
    return _resolved(a) == _resolved(b)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends, then deliver the first one that came.

    Only the main thread can set handlers; elsewhere the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {
        s: signal.signal(s, lambda signum, frame: pending.append(signum)) for s in _DEFERRED_SIGNALS
    }
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if pending:
            signal.raise_signal(pending[0])


def _pause_for_tests() -> None:
    marker = os.environ.get(PAUSE_VARIABLE)
    if marker:
        Path(marker).write_text(f"{os.getpid()}\n")
        deadline = time.monotonic() + PAUSE_SECONDS
        while time.monotonic() < deadline:
            time.sleep(0.05)


def _temporary_name(path: Path) -> Path:
    """A fresh name beside ``path`` that keeps its suffixes (writers infer formats from them)
    and, hidden and marked ``.tmp-``, never looks like a finished output."""
    handle, name = tempfile.mkstemp(prefix=".tmp-", suffix=f"-{path.name}", dir=path.parent)
    os.close(handle)
    os.chmod(name, 0o666 & ~_umask())  # as a plain open() would create it, not mkstemp's 0o600
    return Path(name)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _remove(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


@contextlib.contextmanager
def atomic_files(*paths: str | Path) -> Iterator[list[Path]]:
    """Temporary files to write ``paths`` through, renamed onto them when the block ends
    without an exception; removed when it raises (or is interrupted).

    Parameters
    ----------
    *paths : str or Path
        The files to write, in their final folders (each folder must exist).

    Yields
    ------
    list of Path
        One temporary path per output, in the same folder (so the rename is atomic) and with
        the same suffixes; the block must write every one.

    Examples
    --------
    >>> with atomic_files("estimates.csv") as (temporary,):  # doctest: +SKIP
    ...     table.to_csv(temporary)
    """
    finals = [Path(p) for p in paths]
    temporaries: list[Path] = []
    try:
        for final in finals:
            temporaries.append(_temporary_name(final))
        yield list(temporaries)
        _pause_for_tests()
        with _signals_deferred():
            for temporary, final in zip(temporaries, finals, strict=True):
                os.replace(temporary, final)
    finally:
        with _signals_deferred():
            for temporary in temporaries:
                _remove(temporary)


def _lock_path(folder: Path) -> Path:
    return folder.parent / f".{folder.name}.lock"


def _holder(lock: Path) -> int | None:
    """The live process id written in ``lock``, or None (no file, unreadable, dead holder)."""
    try:
        pid = int(lock.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:  # alive, another user's
        return pid
    return pid


@contextlib.contextmanager
def _folder_lock(folder: Path) -> Iterator[None]:
    """Hold ``.<name>.lock`` beside ``folder`` (this process's id inside); a lock left by a
    process that is no longer running is taken over."""
    lock = _lock_path(folder)
    for _ in range(2):
        try:
            handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            pid = _holder(lock)
            if pid is not None and pid != os.getpid():
                raise FileExistsError(
                    f"{folder}: another hmmtrack run (process {pid}) is writing this folder; "
                    f"wait for it to end (or delete {lock} if no such process is running)"
                ) from None
            _remove(lock)  # stale: its process is gone
            continue
        with os.fdopen(handle, "w") as stream:
            stream.write(f"{os.getpid()}\n")
        break
    try:
        yield
    finally:
        _remove(lock)


@contextlib.contextmanager
def staged_folder(folder: str | Path, last: str) -> Iterator[Path]:
    """A temporary sibling of ``folder`` to build a set of outputs in, moved into ``folder``
    when the block ends without an exception; removed when it raises (or is interrupted).

    A new ``folder`` is the staged folder renamed. An existing one may hold other files
    (``reports/`` holds every study's report): there the staged files replace their
    namesakes one by one, ``last`` (the file that marks a set as complete, e.g.
    ``summary.md``) deleted first and moved in last, so that a run stopped even by a crash
    leaves either the previous set or no ``last``. A lock file ``.<name>.lock`` beside
    ``folder`` refuses a concurrent run into the same folder.

    Parameters
    ----------
    folder : str or Path
        Output folder; its parent must exist.
    last : str
        Name of the set's completion marker inside the folder.

    Yields
    ------
    Path
        The staging folder (empty, beside ``folder``).

    Raises
    ------
    FileExistsError
        Another live process holds the folder's lock.
    """
    folder = Path(folder)
    with _folder_lock(folder):
        stage = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=folder.parent))
        try:
            os.chmod(stage, 0o777 & ~_umask())
            yield stage
            _pause_for_tests()
            with _signals_deferred():
                _move_into(stage, folder, last)
        finally:
            with _signals_deferred():
                _remove(stage)


def _move_into(stage: Path, folder: Path, last: str) -> None:
    if not folder.exists():
        os.rename(stage, folder)
        return
    _remove(folder / last)
    for entry in sorted(stage.iterdir()):
        if entry.name != last:
            if (folder / entry.name).is_dir():
                _remove(folder / entry.name)
            os.replace(entry, folder / entry.name)
    if (stage / last).exists():
        os.replace(stage / last, folder / last)
