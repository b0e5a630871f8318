"""Command-line interface: ``hmmtrack <command> ...``.

Each command lives in its own module of this package and exposes two functions:

``register(subparsers)``
    adds its ``argparse`` sub-parser (:func:`add_command`, with the one-line help listed in
    :data:`COMMANDS`) and sets ``func`` on it;
``run(args) -> int``
    does the work and returns the exit code.

Only the command being run is imported (:func:`build_parser`), so that ``hmmtrack --help``
and light commands do not load the libraries of the heavy ones. The commands hold no logic
that the library lacks: they parse arguments, call library
functions and print or write what those return.

:func:`main` is the one place where failures become messages and exit codes (a command's
``run`` raises; it never prints a traceback or exits itself):

====  ============================================================================
code  meaning
====  ============================================================================
0     done
1     the run failed: disk full, no permission, out of memory, a busy output folder,
      a lost cluster or worker process (``OSError`` other than a missing file,
      ``MemoryError``, ``BrokenProcessPool``)
2     bad input the user can fix: options, input files, output paths checked
      before the work starts (``UserInputError``, ``ValueError``,
      ``FileNotFoundError``, ``IsADirectoryError``, ``NotADirectoryError``)
130   interrupted (Ctrl-C, SIGINT); 143 for SIGTERM
====  ============================================================================

Each failure is one line on stderr, ``hmmtrack COMMAND: error: ...``; ``--debug`` adds the
traceback. SIGINT and SIGTERM raise :class:`Interrupted`, so that the outputs being written
(:mod:`hmmtrack.io.outputs`) are removed on the way out. Python warnings are logged as one
line each (``WARNING: ...``), without the source line that Python prints.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Iterator
from concurrent.futures.process import BrokenProcessPool

from hmmtrack import __version__
from hmmtrack.io.times import TIME_UNITS

#: command modules and their one-line help, in the order ``hmmtrack --help`` lists them
COMMANDS = {
    "fit": "fit a movement HMM (step length, turning angle) to tracks",
    "decode": "Viterbi states and state probabilities of tracks under a fitted model",
    "plot": "figures of a fitted movement HMM on tracks (densities, residuals, states)",
    "track": "estimate positions of a tag from detection logs (particle filter)",
    "sync": "fit receiver clocks from sync tags (clock file for tracking)",
    "simulate": "write a synthetic dataset (detections, receivers, truth, settings)",
    "reproduce": "rerun the paper's experiments; write figures and summary.md",
    "study": "rerun a study behind reports/ and write its report",
}

#: options of ``hmmtrack`` itself that may come before the command
GLOBAL_FLAGS = ("-v", "--verbose", "--debug")

#: exit codes (see the module docstring)
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 128  # + the signal's number: 130 for SIGINT, 143 for SIGTERM

#: exceptions that mean "fix the command line or the input files"
BAD_INPUT = (ValueError, FileNotFoundError, IsADirectoryError, NotADirectoryError)


class UserInputError(Exception):
    """Raised for bad input that the user can fix; the CLI prints it without a traceback."""


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM received (``signum``); a ``KeyboardInterrupt``, so that library code
    catching ``Exception`` lets it through and ``finally`` blocks clean up."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def add_time_unit(parser: argparse.ArgumentParser, files: str) -> None:
    """``--time-unit {s,ms}``: the unit of numeric times in ``files`` (ISO 8601 text ignores
    it; :func:`hmmtrack.io.times.parse_times`)."""
    parser.add_argument(
        "--time-unit",
        choices=TIME_UNITS,
        default="s",
        help=f"unit of numeric (epoch) times in {files}: s or ms (default: s)",
    )


def _raise_interrupted(signum: int, frame) -> None:
    raise Interrupted(signum)


@contextlib.contextmanager
def _signals_raise() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`Interrupted` inside the block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, _raise_interrupted) for s in signals}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _log_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` for the CLI: one log line, no source path or line."""
    logging.getLogger("py.warnings").warning("%s", message)


def add_command(subparsers, name: str, **kwargs) -> argparse.ArgumentParser:
    """The sub-parser of command ``name``, with its one-line help from :data:`COMMANDS`
    (``kwargs`` go to ``add_parser``: ``description``, ``epilog``...)."""
    return subparsers.add_parser(name, help=COMMANDS[name], **kwargs)


def named_command(argv: list[str]) -> str | None:
    """The command that ``argv`` runs (``None`` when it names none, e.g. ``--help``): the
    first word after the global flags, if it is one of :data:`COMMANDS`."""
    for word in argv:
        if word in COMMANDS:
            return word
        if word not in GLOBAL_FLAGS and not (word.startswith("-v") and set(word[1:]) == {"v"}):
            return None
    return None


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``hmmtrack`` parser. Given ``argv``, only the command it names is imported and
    gets its full sub-parser; the others get a placeholder with their one-line help, which
    is all ``hmmtrack --help`` shows. A command's module imports its libraries (SciPy,
    statsmodels, numba kernels), so this keeps ``hmmtrack sync`` from loading the movement
    HMM and ``hmmtrack --help`` from loading anything. Without ``argv``, every command is
    built (for tests and documentation)."""
    loaded = COMMANDS if argv is None else {named_command(argv)}
    parser = argparse.ArgumentParser(
        prog="hmmtrack",
        description="Movement HMMs and particle-filter tracking of acoustically tagged animals.",
    )
    parser.add_argument("--version", action="version", version=f"hmmtrack {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    parser.add_argument(
        "--debug",
        action="store_true",
        help="print the traceback of a failure (default: a one-line message)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, summary in COMMANDS.items():
        if name in loaded:
            importlib.import_module(f"hmmtrack.cli.{name}").register(sub)
        else:
            sub.add_parser(name, help=summary, add_help=False)
    return parser


def message(exc: BaseException) -> str:
    """One line saying what went wrong: the exception's text (an ``OSError``'s file and
    reason), its lines joined."""
    if isinstance(exc, MemoryError):
        return "out of memory; try fewer particles or a shorter time window"
    if isinstance(exc, OSError) and exc.strerror and exc.filename:
        text = f"{exc.filename}: {exc.strerror}"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def main(argv: list[str] | None = None) -> int:
    """Run ``hmmtrack`` with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(argv).parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2), format="%(levelname)s: %(message)s"
    )
    with warnings.catch_warnings():
        warnings.showwarning = _log_warning
        try:
            with _signals_raise():
                return int(args.func(args) or 0)
        except KeyboardInterrupt as exc:
            error = exc
            signum = getattr(exc, "signum", signal.SIGINT)
            code, failure = (
                EXIT_INTERRUPTED + signum,
                f"interrupted ({signal.Signals(signum).name})",
            )
        except (UserInputError, *BAD_INPUT) as exc:
            error, code, failure = exc, EXIT_BAD_INPUT, message(exc)
        except (OSError, MemoryError, BrokenProcessPool) as exc:
            error, code, failure = exc, EXIT_FAILURE, message(exc)
    if args.debug:
        traceback.print_exception(type(error), error, error.__traceback__)
    print(f"hmmtrack {args.command}: error: {failure}", file=sys.stderr)
    return code
