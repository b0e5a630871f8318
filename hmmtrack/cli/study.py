"""``hmmtrack study NAME``: rerun one of the studies behind ``reports/`` and write its report.

Each study is a subcommand whose options are the study's size; the work is done by the
study's report writer in :mod:`hmmtrack.report` (which runs :mod:`hmmtrack.experiments`):

* ``stationary`` — ``stationary_tag.md`` (:func:`hmmtrack.report.stationary.write_stationary`);
* ``arrival`` — ``clock_aware.md`` (:func:`hmmtrack.report.clock_aware.write_clock_aware`);
* ``clock-bound`` — ``clock_bound.md`` (:func:`hmmtrack.report.clock_bound.write_clock_bound`);
* ``two-auv-plan`` — ``two_auv_plan.md`` (:func:`hmmtrack.report.two_auv_plan.write_two_auv_plan`);
* ``closed-loop`` — ``closed_loop.md`` (:func:`hmmtrack.report.closed_loop.write_closed_loop`).

The defaults are the sizes the reports in ``reports/`` were written with; the clock studies
take minutes to hours at that size, ``--seeds 1 --duration 900 --particles 300`` is a quick
look.
"""

from __future__ import annotations

import argparse
import importlib
import warnings

from hmmtrack.cli import UserInputError, add_command
from hmmtrack.io.outputs import check_paths

#: subcommand -> (report module, writer, help)
STUDIES = {
    "stationary": (
        "stationary",
        "write_stationary",
        "stationary tag over many geometries, with bounds (stationary_tag.md)",
    ),
    "arrival": (
        "clock_aware",
        "write_clock_aware",
        "arrival-time against range-rate tracking on realistic clocks (clock_aware.md)",
    ),
    "clock-bound": (
        "clock_bound",
        "write_clock_bound",
        "Cramér-Rao bounds of the clock cases and a planning sweep (clock_bound.md)",
    ),
    "two-auv-plan": (
        "two_auv_plan",
        "write_two_auv_plan",
        "two AUVs on the observable plan against the paper's method (two_auv_plan.md)",
    ),
    "closed-loop": (
        "closed_loop",
        "write_closed_loop",
        "the same AUVs steered on the filter's estimate vs the truth (closed_loop.md)",
    ),
}


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _seconds(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "study",
        description=__doc__.split("\n\n")[0],
    )
    studies = parser.add_subparsers(dest="study", metavar="NAME")
    studies.required = True
    options = {}
    for name, (_, _, text) in STUDIES.items():
        options[name] = studies.add_parser(name, help=text, description=text)
        options[name].add_argument(
            "--out", default="reports", help="output folder (default: reports)"
        )
        options[name].set_defaults(func=run)
    stationary = options["stationary"]
    stationary.add_argument("--seeds", type=_positive, default=100, help="scenario seeds 0..n-1")
    stationary.add_argument("--particles", type=_positive, nargs="+", default=[1000, 5000])
    stationary.add_argument(
        "--moving-trials", type=int, default=100, help="trials per moving-tag scenario"
    )
    stationary.add_argument(
        "--moving-particles", type=_positive, default=1000, help="particles of those trials"
    )
    for name in ("arrival", "clock-bound", "two-auv-plan", "closed-loop"):
        options[name].add_argument(
            "--duration", type=_seconds, default=7200.0, help="length of each run (s)"
        )
    arrival = options["arrival"]
    arrival.add_argument("--seeds", type=_positive, default=2)
    arrival.add_argument("--particles", type=_positive, default=3000)
    arrival.add_argument("--lag", type=_positive, default=60, help="smoother lag (s)")
    arrival.add_argument("--motion", default="velocity", choices=("velocity", "hmm", "hmm-tc"))
    bound = options["clock-bound"]
    bound.add_argument("--seeds", type=_positive, default=3)
    bound.add_argument("--sweep-seeds", type=int, default=2, help="0: no planning sweep")
    bound.add_argument("--particles", type=_positive, default=3000, help="the filter's")
    bound.add_argument("--no-filter", action="store_true", help="skip the particle-filter runs")
    bound.add_argument(
        "--filter-report",
        default=None,
        help="clock-aware report whose errors are set beside the bounds "
        "(default: OUT/clock_aware.md)",
    )
    plan = options["two-auv-plan"]
    plan.add_argument("--seeds", type=_positive, default=3)
    plan.add_argument("--particles", type=_positive, default=None, help="default: the settings'")
    loop = options["closed-loop"]
    loop.add_argument("--seeds", type=_positive, default=3)
    loop.add_argument("--filter-seeds", type=_positive, default=1, help="per scenario")
    loop.add_argument("--latency", type=float, default=2.0, help="steering delay (s)")
    loop.add_argument("--particles", type=_positive, default=None, help="default: the preset's")


def _keywords(args: argparse.Namespace) -> dict:
    """The writer's keyword arguments from the parsed options."""
    if args.study == "stationary":
        return {
            "seeds": args.seeds,
            "particles": tuple(args.particles),
            "moving_trials": args.moving_trials,
            "moving_particles": args.moving_particles,
        }
    common = {"seeds": args.seeds, "duration": args.duration, "particles": args.particles}
    if args.study == "arrival":
        return common | {"lag": args.lag, "motion": args.motion}
    if args.study == "clock-bound":
        if args.sweep_seeds < 0:
            raise UserInputError(f"--sweep-seeds must be >= 0, got {args.sweep_seeds}")
        return common | {
            "sweep_seeds": args.sweep_seeds,
            "run_filter": not args.no_filter,
            "filter_report": args.filter_report,
        }
    if args.study == "closed-loop":
        return common | {"filter_seeds": args.filter_seeds, "latency": args.latency}
    return common


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")  # figures go to files; no display needed
    module, writer, _ = STUDIES[args.study]
    report = getattr(args, "filter_report", None)
    check_paths({"--filter-report": report}, folders={"--out": args.out})
    write = getattr(importlib.import_module(f"hmmtrack.report.{module}"), writer)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # re-initialised clouds are in the runs
        path = write(args.out, **_keywords(args))
    print(f"wrote {path}")
    return 0
