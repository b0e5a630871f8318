"""Throughput of the arrival-time filter's settings on the observable two-AUV plan, same run.

The filter alone (no smoother) on seed 0 of
:func:`hmmtrack.scenarios.realistic.realistic_shark_pursuit` (``steering="observable"``),
with the arrival-time defaults, the ``two-moving-receivers`` preset and the preset without
the detection curve (:mod:`hmmtrack.experiments.two_auv_plan`): particle-steps per second,
best of ``--repeats`` runs each, and the run-time ratio preset / defaults from the same run.
The machine (CPU, cores, load) is printed at the start and the end. The accuracy tables
are ``hmmtrack study two-auv-plan``'s.

    python benchmarks/bench_two_auv_plan.py [--duration 7200] [--repeats 2]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from machine import describe

from hmmtrack.experiments.two_auv_plan import (
    DEFAULT,
    NO_SILENCES,
    PLANS,
    arrival_run,
    plan_label,
    tuned_settings,
)
from hmmtrack.scenarios.realistic import realistic_shark_pursuit


def throughput(case, settings: dict, silences: bool, duration: float, repeats: int) -> float:
    """Particle-steps per second of the filter alone (no smoother), best of ``repeats``."""
    best = np.inf
    for _ in range(repeats):
        tic = time.perf_counter()
        arrival_run(case, settings, None, 0, silences, duration)
        best = min(best, time.perf_counter() - tic)
    return settings["filter"]["n_particles"] * duration / best


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=7200.0, help="s per run")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    print(describe("start"), flush=True)
    warnings.simplefilter("ignore", RuntimeWarning)  # re-initialised clouds: not timed apart
    case = realistic_shark_pursuit(0, steering=PLANS[0])
    tuned = tuned_settings()
    speed = {
        "default": throughput(case, DEFAULT, True, args.duration, args.repeats),
        "tuned": throughput(case, tuned, True, args.duration, args.repeats),
        NO_SILENCES: throughput(case, tuned, False, args.duration, args.repeats),
    }
    run_time_ratio = (tuned["filter"]["n_particles"] / speed["tuned"]) / (
        DEFAULT["filter"]["n_particles"] / speed["default"]
    )
    print(
        f"throughput, filter alone, {plan_label(PLANS[0])}, seed 0 (particle-steps/s): "
        + ", ".join(f"{k} {v / 1e6:.2f} M" for k, v in speed.items())
        + f"; tuned / default {speed['tuned'] / speed['default']:.2f}; "
        f"run time tuned / default {run_time_ratio:.2f}"
    )
    print(describe("end"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
