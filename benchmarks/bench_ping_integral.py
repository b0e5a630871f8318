"""Cost of the grouped ping's emission integral (``sequence_ping_integral``) per call, against
the two versions before it, same process.

The versions: ``uniform`` (main at 5385d21: core plus a uniform outlier, one trapezoid per
cluster), ``3^n`` (0c062b5: the physical outlier shape, one truncated Gaussian per assignment
of the arrivals to core, late tail and floor) and ``now`` (this tree: the same density by
pieces, closed form where no core counts and Gauss-Legendre where one does). The old ones are
read from git (``git show COMMIT:hmmtrack/tracking/measurement/sequence.py``), so this runs in
a checkout with that history. Inputs as the fixed-period moorings score them: core sd 2 ms,
outlier share 0.05, floor half-width 1 s; per ping the two priors every particle scores (its
clock, sd 1 ms about the truth, and the reset prior, sd 1 s); pings ``clean`` (every arrival
direct) and ``late`` (one arrival 30 ms late). Reported: µs per call (mean over the pings and
both priors, each call's best of five), and ``now`` over ``uniform``. The machine (CPU, cores,
load) is printed at the start and the end.

    python benchmarks/bench_ping_integral.py [--receivers 1 2 3 5 6 8 10 12] [--pings 200]
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from machine import describe

from hmmtrack.tracking.measurement.sequence import sequence_ping_integral

SOURCE = "hmmtrack/tracking/measurement/sequence.py"
#: the versions compared with the tree's, by commit
VERSIONS = {"uniform": "5385d21", "3^n": "0c062b5"}
SIGMA, FRACTION, HALF_WIDTH = 2e-3, 0.05, 1.0
#: the 3^n version is timed on fewer pings above this many receivers (0.5 s a call at 12)
SLOW_RECEIVERS = 8


def old_integral(commit: str, folder: Path):
    """``sequence_ping_integral`` of ``commit``, imported from its source under ``folder``."""
    root = Path(__file__).resolve().parents[1]
    text = subprocess.run(
        ["git", "show", f"{commit}:{SOURCE}"], cwd=root, check=True, capture_output=True,
        text=True,
    ).stdout  # fmt: skip
    path = folder / f"sequence_{commit}.py"
    path.write_text(text)
    name = f"sequence_{commit}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module.sequence_ping_integral


def pings(rng, n: int, count: int, late: bool):
    """``count`` pings of ``n`` residuals (s) and their two priors (mean, variance)."""
    out = []
    for _ in range(count):
        residual = rng.normal(0.0, SIGMA, n)
        if late:
            residual[0] += 0.03
        mu = rng.normal(0.0, 1e-3)
        out.append((residual, mu, 1e-3**2))
        out.append((residual, mu, 1.0))
    return out


def per_call(integral, calls, repeats: int = 5) -> float:
    """µs per call of ``integral``: the mean over ``calls`` of each call's best of
    ``repeats`` (on a shared machine a pass over many calls is seldom left alone)."""
    best = np.full(len(calls), np.inf)
    for _ in range(repeats):
        for k, (residual, mu, var) in enumerate(calls):
            start = time.perf_counter()
            integral(residual, mu, var, SIGMA, FRACTION, HALF_WIDTH)
            best[k] = min(best[k], time.perf_counter() - start)
    return 1e6 * float(best.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--receivers", type=int, nargs="+", default=[1, 2, 3, 5, 6, 8, 10, 12])
    parser.add_argument("--pings", type=int, default=200)
    args = parser.parse_args()
    print(describe("start"))
    with tempfile.TemporaryDirectory() as folder:
        versions = {k: old_integral(c, Path(folder)) for k, c in VERSIONS.items()}
        versions = {"uniform": versions["uniform"], "now": sequence_ping_integral} | versions
        rng = np.random.default_rng(0)
        print("receivers  ping   " + "".join(f"{k:>10}" for k in versions) + "  now/uniform")
        for n in args.receivers:
            for late in (False, True):
                calls = pings(rng, n, args.pings, late)
                times = {}
                for key, integral in versions.items():
                    integral(*calls[0], SIGMA, FRACTION, HALF_WIDTH)  # compiled
                    few = key == "3^n" and n > SLOW_RECEIVERS
                    times[key] = per_call(integral, calls[:4] if few else calls, 1 if few else 5)
                row = "".join(f"{times[k]:>10.1f}" for k in versions)
                kind = "late" if late else "clean"
                print(f"{n:>9}  {kind:<5}  {row}  {times['now'] / times['uniform']:>10.2f}")
    print(describe("end"))


if __name__ == "__main__":
    main()
