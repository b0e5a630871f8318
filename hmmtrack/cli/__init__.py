"""Command-line interface: ``hmmtrack <command> ...``.

Each command lives in its own module of this package and exposes two functions:

``register(subparsers)``
    adds its ``argparse`` sub-parser and sets ``func`` on it;
``run(args) -> int``
    does the work and returns the exit code.

The commands hold no logic that the library lacks: they parse arguments, call library
functions and print or write what those return.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from hmmtrack import __version__

#: command modules, in the order ``hmmtrack --help`` lists them
COMMANDS = ("fit", "decode", "track", "sync", "simulate", "reproduce", "study")


class UserInputError(Exception):
    """Raised for bad input that the user can fix; the CLI prints it without a traceback."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hmmtrack",
        description="Movement HMMs and particle-filter tracking of acoustically tagged animals.",
    )
    parser.add_argument("--version", action="version", version=f"hmmtrack {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"hmmtrack.cli.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args) or 0)
    except (UserInputError, ValueError, FileNotFoundError) as exc:
        print(f"hmmtrack {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
