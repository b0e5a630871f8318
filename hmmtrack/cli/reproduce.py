"""``hmmtrack reproduce``: rerun the paper's experiments and write ``reports/``.

Writes every figure (PNG) and ``summary.md`` (our numbers beside the paper's) with
:func:`hmmtrack.report.reproduce`. ``--quick`` is a small run for a first try (a minute or
two); without it the run is paper-scale (100 trials per motion model per scenario,
spread over 50 synthetic datasets × 2 filter runs, plus the measurement-loss sweep). By
default every run is ours (the mode-keeping filter, started where the field team knew the tag
to be, the ``range-rate-gps`` measurement); ``--filter paper --no-start-prior --measurement
range-rate`` is the paper's algorithm.
"""

from __future__ import annotations

import argparse
import sys

from hmmtrack.cli import UserInputError, add_command
from hmmtrack.io.outputs import check_paths

#: the named filters (:data:`hmmtrack.tracking.filter.FILTERS`), written out so that
#: ``--help`` imports no tracking code
FILTER_NAMES = ("paper", "mode-keeping", "acquired")

DESCRIPTION = (
    "Rerun the paper's experiments on the bundled synthetic datasets and write every figure "
    "(PNG), the trial tables (CSV) and summary.md (our numbers beside the paper's). --quick is "
    "a small first try (a minute or two); without it the run is paper-scale: 100 trials per "
    "motion model per scenario (50 synthetic datasets x 2 filter runs), the measurement-loss "
    "sweep and the diving shark. Every run uses the mode-keeping filter from where the field "
    "team knew the tag to be at the start, with the receivers' GPS error correlated in time; "
    "--filter paper --no-start-prior --measurement range-rate runs the paper's algorithm."
)


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "reproduce",
        description=DESCRIPTION,
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="small run for a first try (a few trials, fewer particles)",
    )
    parser.add_argument("--out", default="reports", help="output folder (default: reports)")
    parser.add_argument(
        "--trials",
        type=int,
        default=None,
        help="filter runs per motion model per synthetic dataset (default 2; quick: 1)",
    )
    parser.add_argument(
        "--datasets",
        type=int,
        default=None,
        help="synthetic datasets per scenario in the motion-model comparison "
        "(default 50; quick: 2); --datasets 1 --trials 100 is the paper's design",
    )
    parser.add_argument(
        "--particles",
        type=int,
        default=None,
        help="particles per filter run (default 1000, the reproduction's; quick: 300)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        help="local worker processes (default: all cores; 1 = serial)",
    )
    parser.add_argument(
        "--dask-scheduler",
        default=None,
        metavar="ADDRESS",
        help="run trials on a Dask cluster at ADDRESS (needs hmmtrack[dask])",
    )
    parser.add_argument(
        "--dask-timeout",
        type=float,
        default=30.0,
        metavar="SECONDS",
        help="how long to wait for the Dask scheduler to answer (default 30)",
    )
    parser.add_argument("--seed", type=int, default=0, help="experiment seed (default 0)")
    parser.add_argument(
        "--filter",
        choices=FILTER_NAMES,
        default="mode-keeping",
        help="the filter of every run: mode-keeping (default: particles drawn from the first "
        "corrections' likelihood, every mode kept by mixture resampling) or paper (the "
        "paper's); summary.md says which ran",
    )
    parser.add_argument(
        "--start-prior",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="start each run where the field team knew the tag to be at the start (the "
        "swimmer's and the shark pursuit's start regions; no acquisition there; default), or "
        "with --no-start-prior in the whole search box as the paper does: two receivers cannot "
        "tell the tag from its mirror. The paper's algorithm: --filter paper --no-start-prior",
    )
    parser.add_argument(
        "--measurement",
        choices=("range-rate", "range-rate-gps"),
        default="range-rate-gps",
        help="the measurement of every run: range-rate-gps (default: each receiver's GPS "
        "error an offset correlated in time, integrated out per particle) or range-rate (the "
        "paper's, ranges with a 5 m sd standing for that error); summary.md says which ran. "
        "The paper's algorithm: --filter paper --no-start-prior --measurement range-rate",
    )
    progress = parser.add_mutually_exclusive_group()
    progress.add_argument(
        "--progress",
        dest="progress",
        action="store_true",
        default=None,
        help="show progress bars (default: when attached to a terminal)",
    )
    progress.add_argument("--no-progress", dest="progress", action="store_false")
    parser.set_defaults(func=run)


def _positive(name: str, value: int | None) -> None:
    if value is not None and value < 1:
        raise UserInputError(f"{name} must be a positive integer, got {value}")


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")  # figures go to files; no display needed
    from hmmtrack.report import reproduce

    _positive("--trials", args.trials)
    _positive("--datasets", args.datasets)
    _positive("--particles", args.particles)
    _positive("--workers", args.workers)
    check_paths(folders={"--out": args.out})
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    client = None
    if args.dask_scheduler:
        try:
            from distributed import Client
        except ImportError:
            raise UserInputError(
                "--dask-scheduler needs Dask: pip install 'hmmtrack[dask]'"
            ) from None
        if not args.dask_timeout > 0:
            raise UserInputError(f"--dask-timeout must be positive, got {args.dask_timeout:g}")
        try:
            client = Client(args.dask_scheduler, timeout=args.dask_timeout)
        except OSError as exc:  # nothing listening, a wrong address: a failure, exit 1
            raise OSError(
                f"--dask-scheduler {args.dask_scheduler}: no Dask scheduler answered within "
                f"{args.dask_timeout:g} s ({exc}); start one (dask scheduler) or check the "
                "address"
            ) from None
        executor = client
    else:
        executor = "serial" if args.workers == 1 else "processes"
    try:
        summary = reproduce(
            args.out,
            quick=args.quick,
            n_trials=args.trials,
            n_particles=args.particles,
            n_datasets=args.datasets,
            seed=args.seed,
            executor=executor,
            max_workers=args.workers,
            progress=progress,
            filter=args.filter,
            start_prior=args.start_prior,
            measurement=args.measurement,
        )
    finally:
        if client is not None:
            client.close()
    print(f"wrote {summary} and its figures")
    return 0
