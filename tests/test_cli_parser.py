"""The ``hmmtrack`` parser loads only the command it runs (lazy command imports)."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from hmmtrack.cli import COMMANDS, build_parser, named_command


def _subparsers(parser: argparse.ArgumentParser) -> argparse._SubParsersAction:
    (action,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {flag for action in parser._actions for flag in action.option_strings}


@pytest.mark.parametrize(
    ("argv", "command"),
    [
        (["track", "--detections", "d.csv"], "track"),
        (["-v", "sync", "-o", "c.json"], "sync"),
        (["-vv", "--debug", "fit", "--help"], "fit"),
        (["--verbose", "study", "arrival"], "study"),
        (["--help"], None),
        (["--version"], None),
        (["trak"], None),
        (["--debug", "trak", "track"], None),
        ([], None),
    ],
)
def test_named_command(argv, command):
    assert named_command(argv) == command


@pytest.mark.parametrize("name", list(COMMANDS))
def test_lazy_parser_builds_the_same_command(name):
    """Built alone, a command has every option it has in the full parser; the others keep
    their one-line help."""
    full = _subparsers(build_parser()).choices
    lazy_action = _subparsers(build_parser([name]))
    assert _options(lazy_action.choices[name]) == _options(full[name])
    assert {a.dest: a.help for a in lazy_action._choices_actions} == COMMANDS
    for other in set(COMMANDS) - {name}:
        assert _options(lazy_action.choices[other]) == set()


def test_full_parser_help_lines_are_the_commands_table():
    assert {a.dest: a.help for a in _subparsers(build_parser())._choices_actions} == COMMANDS


def test_help_and_sync_do_not_import_the_movement_hmm():
    """``hmmtrack --help`` imports no command module; ``hmmtrack sync`` not the HMM fitter
    (statsmodels and SciPy's distributions), in a fresh interpreter."""
    code = (
        "import sys\n"
        "from hmmtrack.cli import build_parser\n"
        "build_parser(sys.argv[1:])\n"
        "print(' '.join(m for m in ('hmmtrack.hmm', 'statsmodels', 'hmmtrack.tracking',"
        " 'hmmtrack.cli.fit') if m in sys.modules))\n"
    )

    def loaded(*argv: str) -> set[str]:
        out = subprocess.run(
            [sys.executable, "-c", code, *argv], capture_output=True, text=True, check=True
        )
        return set(out.stdout.split())

    assert loaded("--help") == set()
    assert loaded("sync", "--help") == {"hmmtrack.tracking"}
    assert loaded("fit", "--help") >= {"hmmtrack.hmm", "hmmtrack.cli.fit"}


def test_reproduce_help_states_the_paper_scale_design():
    """``hmmtrack reproduce --help`` states the paper-scale and quick runs' datasets and
    filter runs as :data:`hmmtrack.report.FULL` and :data:`~hmmtrack.report.QUICK` have them."""
    from hmmtrack.report import FULL, QUICK

    parser = _subparsers(build_parser(["reproduce"])).choices["reproduce"]
    helps = {action.dest: action.help for action in parser._actions}
    assert f"(default {FULL.n_trials}; quick: {QUICK.n_trials})" in helps["trials"]
    assert f"(default {FULL.n_datasets}; quick: {QUICK.n_datasets})" in helps["datasets"]
