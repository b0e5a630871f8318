"""Throughput of the arrival-time filter against the paper's range-rate filter, same run.

Best of ``--repeats`` alternating runs (wall and process CPU time) of the range-rate filter
(:func:`hmmtrack.tracking.pipeline.track`) and of the arrival-time filter — the core
(arrival-time likelihood and clock state, no detection probability), with detection
probability (the silences, as the clock-aware study runs it), and with the fixed-lag
smoother too — on seed 0 of the circling pursuit and of the moored array, both filters at
the same particles and motion model; and the same (without the smoother) for the bundled
``two-moving-receivers`` preset on its pursuit (two AUVs on the observable plan), both
filters at the preset's particles and motion model. Ratios are arrival-time time over
range-rate time (target: at most 2), from the same run. The machine (CPU, cores, load) is
printed at the start and the end. The accuracy tables are ``hmmtrack study arrival``'s.

    python benchmarks/bench_arrival.py [--particles 3000] [--duration 7200] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from functools import partial

import numpy as np
import pandas as pd
from machine import describe

from hmmtrack.experiments.clock_runs import (
    clock_inputs,
    config_options,
    track_arrival,
    without_silences,
)
from hmmtrack.experiments.configs import arrival_config
from hmmtrack.scenarios.realistic import moored_array, realistic_shark_pursuit
from hmmtrack.tracking.config import read_preset
from hmmtrack.tracking.pipeline import track

#: the bundled preset timed beside the defaults (hmmtrack/data/presets/)
PRESET = "two-moving-receivers"


def preset_inputs(case, seed: int, duration: float):
    """:func:`clock_inputs` with the :data:`PRESET`'s settings: its particles, likelihood,
    tempering and motion for both filters; the case's window, box and detection curve."""
    settings = read_preset(PRESET)
    detections, config, options = clock_inputs(
        case, seed, settings["filter"]["n_particles"], "velocity", duration
    )
    options |= config_options(arrival_config(case, settings, duration))
    return detections, config, options


def timing_rows(n_particles, motion, lag, duration, repeats) -> list[dict]:
    """One row per case: best wall times (s), throughputs (M particle-steps/s) and ratios."""
    cases = [
        (name, case, clock_inputs(case, 0, n_particles, motion, duration), lag)
        for name, case in (
            ("shark pursuit, 2 AUVs (circling)", realistic_shark_pursuit(0)),
            ("moored array, 3 receivers", moored_array(0, duration=duration)),
        )
    ]
    case = realistic_shark_pursuit(0, steering="observable")
    cases.append(
        (f"preset {PRESET} (observable plan)", case, preset_inputs(case, 0, duration), None)
    )
    rows = []
    for name, case, (detections, config, options), smoothing_lag in cases:
        receivers = case.scenario.receivers
        runs = {
            "range-rate": partial(track, detections, receivers, config, options["motion"], seed=0),
            "arrival-time": partial(
                track_arrival, detections, receivers, without_silences(options)
            ),
            "+ silences": partial(track_arrival, detections, receivers, options),
        }
        if smoothing_lag is not None:
            runs["+ smoother"] = partial(
                track_arrival, detections, receivers, options | {"smoothing_lag": smoothing_lag}
            )
        wall = dict.fromkeys(runs, np.inf)
        cpu = dict.fromkeys(runs, np.inf)
        load = os.getloadavg()[0]
        for _ in range(repeats):
            for label, run in runs.items():
                tic, tic_cpu = time.perf_counter(), time.process_time()
                run()
                wall[label] = min(wall[label], time.perf_counter() - tic)
                cpu[label] = min(cpu[label], time.process_time() - tic_cpu)
        steps = config.filter.n_particles * (config.end - config.start)
        rows.append(
            {
                "case": name,
                "particles": config.filter.n_particles,
                "detections": len(detections),
                **{f"{label} s": wall.get(label, np.nan) for label in (*runs, "+ smoother")},
                "range-rate M steps/s": steps / wall["range-rate"] / 1e6,
                "arrival-time M steps/s": steps / wall["arrival-time"] / 1e6,
                "ratio arrival-time / range-rate": wall["arrival-time"] / wall["range-rate"],
                "ratio with silences": wall["+ silences"] / wall["range-rate"],
                "CPU ratio": cpu["arrival-time"] / cpu["range-rate"],
                "CPU ratio with silences": cpu["+ silences"] / cpu["range-rate"],
                "smoother cost (x with silences)": wall.get("+ smoother", np.nan)
                / wall["+ silences"],
                "load (1 min) before": load,
                "load after": os.getloadavg()[0],
            }
        )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--particles", type=int, default=3000)
    parser.add_argument("--duration", type=float, default=7200.0, help="s per run")
    parser.add_argument("--lag", type=int, default=60, help="smoother lag (s)")
    parser.add_argument("--motion", default="velocity", choices=("velocity", "hmm", "hmm-tc"))
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    print(describe("start"), flush=True)
    warnings.simplefilter("ignore", RuntimeWarning)  # re-initialised clouds: not timed apart
    rows = timing_rows(args.particles, args.motion, args.lag, args.duration, args.repeats)
    pd.set_option("display.width", 250)
    pd.set_option("display.max_columns", 30)
    print(pd.DataFrame(rows).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(describe("end"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
