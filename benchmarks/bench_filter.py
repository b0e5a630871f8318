"""Particle-filter throughput: compiled filter against the plain NumPy filter, same run.

Workload (issue 3): a 3,600 s trial, predictions every second, two receivers (one moving
along a line, one anchored) each hearing a ping about every 8 s, the paper's multinomial
resampling after every correction, estimates every second. For N = 1,000, 10,000 and
100,000 particles and the velocity and HMM motion models it prints particle-steps per
second of ``ParticleFilter`` with its compiled kernels and of the same filter with
``backend="numpy"`` (every second one vectorised ``motion.propagate`` with a NumPy
``Generator``), their ratio, and the rate of the compiled prediction alone (no
corrections: the ceiling the per-correction work is measured against), and the threads
the automatic choice settled on (``ParticleFilter(threads=None)``, timed per call).
Wall-clock numbers depend on the machine's load, printed before and after (1-, 5- and
15-minute load averages of the shared machine), with the compiled filter's particle-steps
per second of process CPU time (``M/CPU-s``, all threads: what a run costs however busy
the machine is); the ratio is measured in the same run. The last lines compare
N = 10,000 with issue 3's target of 40 M particle-steps/s.

Run: ``python benchmarks/bench_filter.py`` (``--quick`` for a 600 s trial and N up to
10,000; ``--sizes 10000`` picks the particle numbers; ``--repeat k`` keeps the best of k
runs; ``--threads t`` fixes the compiled filter's threads).
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
import pandas as pd

from hmmtrack.filter import ParticleFilter
from hmmtrack.hmm import Gamma, MovementHMM, VonMises
from hmmtrack.measurement import RangeRateMeasurement
from hmmtrack.motion import HMMMotion, VelocityMotion

BOUNDS = (-1000.0, 1000.0, -1000.0, 1000.0)
TARGET = 40e6  # particle-steps/s at N = 10,000 (issue 3)
MEASUREMENT = RangeRateMeasurement.from_std(3.0, 0.2)


def shark_model() -> MovementHMM:
    """Two behaviours at the filter's 1 s step: slow and tortuous, fast and directed."""
    return MovementHMM(
        initial=np.array([0.5, 0.5]),
        transition=np.array([[0.98, 0.02], [0.03, 0.97]]),
        step=Gamma(mean=np.array([0.4, 1.2]), sd=np.array([0.3, 0.5])),
        angle=VonMises(mean=np.zeros(2), concentration=np.array([2.0, 30.0])),
        dt=1.0,
    )


def observations(duration: float, seed: int = 0) -> pd.DataFrame:
    """Pings every ~8 s from a tag swimming at 1 m/s, heard by two receivers."""
    rng = np.random.default_rng(seed)
    frames = []
    for name, offset, moving in (("auv", 0.2, True), ("mooring", 4.1, False)):
        t = np.arange(offset, duration, 8.0)
        t = t + rng.normal(0, 0.05, t.size)
        tag_x, tag_y = 100.0 + 0.7 * t, -50.0 + 0.7 * t
        hx = -300.0 + 0.9 * t if moving else np.full(t.size, 400.0)
        hy = 200.0 + 0.0 * t if moving else np.full(t.size, -400.0)
        hvx = np.full(t.size, 0.9 if moving else 0.0)
        hvy = np.zeros(t.size)
        dx, dy = hx - tag_x, hy - tag_y
        r = np.hypot(dx, dy)
        frames.append(
            pd.DataFrame(
                {
                    "time": t,
                    "receiver": name,
                    "range": r + rng.normal(0, 3.0, t.size),
                    "range_rate": (dx * (hvx - 0.7) + dy * (hvy - 0.7)) / r
                    + rng.normal(0, 0.2, t.size),
                    "receiver_x": hx,
                    "receiver_y": hy,
                    "receiver_vx": hvx,
                    "receiver_vy": hvy,
                }
            )
        )
    return pd.concat(frames, ignore_index=True).sort_values("time", kind="stable")


def best_time(make, obs, duration, repeat) -> tuple[float, float, ParticleFilter]:
    """Shortest wall-clock and process CPU times (s) of ``repeat`` runs, and the last filter.

    CPU time (all threads) is what a run costs however busy the machine is; wall-clock time
    is what it takes.
    """
    wall = cpu = np.inf
    for k in range(repeat):
        pf = make(k)
        start, start_cpu = time.perf_counter(), time.process_time()
        pf.run(obs, start=0.0, end=duration)
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu, pf


def load() -> str:
    """The machine's 1-, 5- and 15-minute load averages (2 cores)."""
    return "load average " + ", ".join(f"{v:.2f}" for v in os.getloadavg())


def prediction_only(motion, n: int, duration: float, threads: int | None) -> float:
    """Particle-steps per second of the compiled prediction alone, in 8-step calls."""
    pf = ParticleFilter(motion, MEASUREMENT, n, BOUNDS, rng=0, threads=threads)
    pf.initialise(0.0)
    start = time.perf_counter()
    for _ in range(int(duration) // 8):
        pf.predict(8)
    return n * 8 * (int(duration) // 8) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="600 s trial, N <= 10,000")
    parser.add_argument(
        "--sizes", type=int, nargs="+", default=None, help="particle numbers (default: all)"
    )
    parser.add_argument("--repeat", type=int, default=2, help="best of this many runs")
    parser.add_argument(
        "--threads", type=int, default=None, help="threads of the compiled filter (default: auto)"
    )
    args = parser.parse_args()
    duration = 600.0 if args.quick else 3600.0
    sizes = args.sizes or ((1_000, 10_000) if args.quick else (1_000, 10_000, 100_000))
    obs = observations(duration)
    models = {
        "velocity": VelocityMotion(sigma_speed=0.05, sigma_turn_rate=0.02),
        "hmm": HMMMotion(shark_model(), "paper"),
        "hmm_time_consistent": HMMMotion(shark_model(), "time_consistent"),
    }
    print(
        f"{duration:.0f} s trial, {len(obs)} observations from 2 receivers, "
        f"threads={args.threads or 'auto'} of {numba.config.NUMBA_NUM_THREADS}; "
        f"best of {args.repeat}; {load()}"
    )
    print(f"{'model':<20}{'N':>8}{'compiled s':>12}{'M steps/s':>11}{'numpy s':>10}"
          f"{'M steps/s':>11}{'ratio':>8}{'predict-only M/s':>18}{'threads':>9}"
          f"{'M/CPU-s':>9}")  # fmt: skip
    rates = {}
    for name, motion in models.items():
        # warm-up: loads (or on the very first run compiles) the cached kernels
        warm_up = obs[obs["time"] < 20.0]
        ParticleFilter(motion, MEASUREMENT, 100, BOUNDS, rng=0).run(warm_up, start=0.0, end=20.0)
        for n in sizes:
            steps = n * duration
            compiled, compiled_cpu, pf = best_time(
                lambda k, m=motion, n=n: ParticleFilter(
                    m, MEASUREMENT, n, BOUNDS, rng=k, threads=args.threads
                ),
                obs, duration, args.repeat,
            )  # fmt: skip
            reference, _, _ = best_time(
                lambda k, m=motion, n=n: ParticleFilter(
                    m, MEASUREMENT, n, BOUNDS, rng=k, backend="numpy"
                ),
                obs, duration, 1 if n >= 100_000 else args.repeat,
            )  # fmt: skip
            kernel = prediction_only(motion, n, duration, args.threads)
            print(
                f"{name:<20}{n:>8}{compiled:>12.3f}{steps / compiled / 1e6:>11.1f}"
                f"{reference:>10.3f}{steps / reference / 1e6:>11.1f}"
                f"{reference / compiled:>8.1f}{kernel / 1e6:>18.1f}"
                f"{args.threads or pf._thread_choice.best():>9}"
                f"{steps / compiled_cpu / 1e6:>9.1f}"
            )
            if n == 10_000:
                rates[name] = steps / compiled
    print(load())
    for name, rate in rates.items():
        verdict = "met" if rate >= TARGET else "NOT met"
        print(
            f"target {TARGET / 1e6:.0f} M/s at N = 10,000, {name}: {rate / 1e6:.1f} M/s, {verdict}"
        )


if __name__ == "__main__":
    main()
