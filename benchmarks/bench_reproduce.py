"""How long the paper-scale ``hmmtrack reproduce`` takes on this machine.

Default: a scaled run, clearly labelled, extrapolated to paper scale. It times, with local
processes (all cores), a fraction of each experiment's trials (the motion-model comparison,
the loss sweep and the diving shark), scales each part by its trial count to the full run
(:data:`hmmtrack.report.FULL`), and compares with the same comparison trials run serially
in this process (the baseline; the ratio is the parallel speed-up).

``--full`` runs the real thing (``hmmtrack.report.reproduce`` into a temporary folder) and
prints its wall time instead of an extrapolation. The machine (CPU, cores, load) is printed
at the start and the end.

Usage::

    python benchmarks/bench_reproduce.py [--trials 4] [--particles N] [--workers N] [--full]
"""

from __future__ import annotations

import argparse
import tempfile
import time

import matplotlib

matplotlib.use("Agg")

from machine import describe  # noqa: E402

from hmmtrack import experiments  # noqa: E402
from hmmtrack.experiments.executors import default_workers, get_executor  # noqa: E402
from hmmtrack.report import FULL, QUICK, reproduce  # noqa: E402


def timed(label: str, fn, *args, **kwargs):
    start = time.perf_counter()
    value = fn(*args, **kwargs)
    seconds = time.perf_counter() - start
    print(f"  {label:<58s} {seconds:8.1f} s")
    return value, seconds


def scaled(trials: int, particles: int, workers: int) -> None:
    print(
        f"scaled run: {trials} trial(s) per comparison cell, 1 per loss fraction, 1 per "
        f"depth variant; {particles} particles; {workers} worker process(es)"
    )
    datasets, _ = timed("build the three datasets", experiments.paper_scenarios, 0)
    shark = datasets["shark_pursuit"]
    # compile the numba kernels once in this process (the serial baseline runs here)
    timed(
        "warm-up (one short trial per motion model, compiles kernels)",
        experiments.compare_motion_models,
        [experiments.truncate(shark, 60.0)],
        n_trials=1,
        n_particles=particles,
    )
    with get_executor("processes", workers) as pool:
        common = {"seed": 0, "n_particles": particles, "executor": pool}
        _, t_start = timed(
            "start the worker processes (imports, compiled kernels)",
            experiments.compare_motion_models,
            [experiments.truncate(shark, 60.0)],
            n_trials=workers,
            **common,
        )
        _, t_comparison = timed(
            f"comparison, {9 * trials} trials, processes",
            experiments.compare_motion_models,
            list(datasets.values()),
            n_trials=trials,
            **common,
        )
        _, t_loss = timed(
            f"loss sweep, {len(FULL.loss_fractions)} trials, processes",
            experiments.loss_sweep,
            shark,
            n_trials=1,
            **common,
        )
        _, t_depth = timed(
            "diving shark, 2 trials, processes", experiments.depth_analysis, n_trials=1, **common
        )
    _, t_serial = timed(
        f"comparison, {9 * trials} trials, serial (baseline)",
        experiments.compare_motion_models,
        list(datasets.values()),
        n_trials=trials,
        seed=0,
        n_particles=particles,
    )
    full = (
        t_start
        + t_comparison * FULL.n_datasets * FULL.n_trials / trials
        + t_loss * FULL.loss_trials
        + t_depth * FULL.depth_trials
    )
    print(
        f"EXTRAPOLATED paper-scale run ({9 * FULL.n_datasets * FULL.n_trials} comparison "
        "trials + "
        f"{len(FULL.loss_fractions) * FULL.loss_trials} loss-sweep trials + "
        f"{2 * FULL.depth_trials} diving-shark trials), pool start + trials: {full:.0f} s "
        f"= {full / 60:.1f} min (budget 10 min)"
    )
    print(
        f"parallel speed-up over serial on the comparison: {t_serial / t_comparison:.2f}x "
        f"with {workers} workers"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--trials", type=int, default=4, help="trials per comparison cell of the scaled run"
    )
    parser.add_argument("--particles", type=int, default=FULL.n_particles)
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument("--full", action="store_true", help="time the real paper-scale run")
    parser.add_argument("--quick", action="store_true", help="time the real --quick run")
    args = parser.parse_args()
    print(describe("start"), flush=True)
    if args.full or args.quick:
        size = "quick" if args.quick else "paper-scale"
        with tempfile.TemporaryDirectory() as out:
            _, seconds = timed(
                f"MEASURED {size} reproduce ({args.workers} workers)",
                reproduce,
                out,
                quick=args.quick,
                n_particles=args.particles if not args.quick else QUICK.n_particles,
                max_workers=args.workers,
            )
        print(f"{size} run: {seconds:.0f} s = {seconds / 60:.1f} min")
    else:
        scaled(args.trials, args.particles, args.workers)
    print(describe("end"))


if __name__ == "__main__":
    main()
