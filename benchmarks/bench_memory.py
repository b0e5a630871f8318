"""Peak memory of a long track: ``hmmtrack track`` over 30 days at the default particle count.

Workload (issue 14): a tag moored between two moored receivers (300 m and 250 m away) for
30 days, pinging every 8.179 s, each ping heard by each receiver with probability 0.7
(about 220,000 detections per receiver), the default settings of ``hmmtrack track`` (5,000
particles, the bundled HMM motion model, range-rate measurement), one estimate per second:
2,592,001 rows. The command streams its estimates to the output as they are made
(:class:`hmmtrack.io.EstimatesWriter`), so its memory is bounded by the particles and the
observations, not by the span; held in memory the estimates alone were 1.75 GB (issue 14).

It runs the command in a child process and prints the child's peak resident set size
(``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``), the wall-clock time, the rows written
and the machine (CPU, cores, load at the start and end: the time depends on them, the memory
hardly); while it runs, a line every ``--every`` seconds with the estimates written so far
and the child's resident and peak memory (flat while the output grows). The target is a peak
under 500 MB.

Run: ``python benchmarks/bench_memory.py`` (``--days 3`` for a shorter span,
``--particles N`` for another particle count).
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from machine import describe

from hmmtrack.io import format_times

PERIOD = 8.179
SOUND_SPEED = 1460.0
START = 1_700_000_000.0  # 2023-11-14T22:13:20Z
RECEIVERS = {"east": (300.0, 0.0), "north": (0.0, 250.0)}
HEARD = 0.7
TARGET_MB = 500.0


def write_inputs(folder: Path, days: float, seed: int = 0) -> tuple[Path, Path]:
    """Detections and receivers CSVs of the moored tag at the origin over ``days``."""
    rng = np.random.default_rng(seed)
    emissions = START + np.arange(int(days * 86400 / PERIOD)) * PERIOD
    parts = []
    for name, (x, y) in RECEIVERS.items():
        heard = emissions[rng.random(emissions.size) < HEARD]
        arrivals = heard + np.hypot(x, y) / SOUND_SPEED + rng.normal(0.0, 1e-4, heard.size)
        parts.append(pd.DataFrame({"time": arrivals, "receiver": name}))
    detections = pd.concat(parts).sort_values("time", kind="stable")
    detections["time"] = format_times(detections["time"].to_numpy())
    detections["transmitter"] = "A69-1602-1234"
    receivers = pd.DataFrame(
        {
            "receiver": list(RECEIVERS),
            "x": [p[0] for p in RECEIVERS.values()],
            "y": [p[1] for p in RECEIVERS.values()],
        }
    )
    detections.to_csv(folder / "detections.csv", index=False)
    receivers.to_csv(folder / "receivers.csv", index=False)
    return folder / "detections.csv", folder / "receivers.csv"


def _rss_mb(pid: int) -> str:
    """``"<now> MB (peak <peak> MB)"`` of a running process (Linux ``/proc``), or ``"?"``."""
    try:
        status = Path(f"/proc/{pid}/status").read_text().splitlines()
    except OSError:
        return "?"
    kb = {line.split(":")[0]: int(line.split()[1]) for line in status if line.startswith("Vm")}
    return f"{kb.get('VmRSS', 0) / 1024:.0f} MB (peak {kb.get('VmHWM', 0) / 1024:.0f} MB)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=30.0, help="span tracked (default 30)")
    parser.add_argument("--particles", type=int, help="particles (default: the command's)")
    parser.add_argument(
        "--every", type=float, default=60.0, help="seconds between progress lines (default 60)"
    )
    args = parser.parse_args()
    print(describe("start"))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        detections, receivers = write_inputs(folder, args.days)
        r0 = [f"--r0={name}={np.hypot(*xy):.1f}" for name, xy in RECEIVERS.items()]
        argv = [sys.executable, "-m", "hmmtrack", "track", "--detections", str(detections)]
        argv += ["--receivers", str(receivers), "--period", str(PERIOD), *r0]
        argv += ["--seed", "1", "-o", str(folder / "estimates.csv")]
        if args.particles is not None:
            argv += ["--particles", str(args.particles)]
        began = time.perf_counter()
        with open(folder / "stderr.txt", "w") as err:
            child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err)
            while child.poll() is None:
                time.sleep(args.every)
                written = sum(p.stat().st_size for p in folder.glob("*estimates*"))
                print(
                    f"  {time.perf_counter() - began:6.0f} s: {written / 1e6:6.1f} MB of "
                    f"estimates written, RSS {_rss_mb(child.pid)}",
                    flush=True,
                )
        seconds = time.perf_counter() - began
        if child.returncode != 0:
            message = (folder / "stderr.txt").read_text().strip()
            sys.exit(f"hmmtrack track failed ({child.returncode}): {message}")
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
        with open(folder / "estimates.csv") as out:
            rows = sum(1 for _ in out) - 1
        size_mb = (folder / "estimates.csv").stat().st_size / 1e6
    particles = args.particles or "default (5000)"
    print(f"{args.days:g} days, particles {particles}: {rows} estimates ({size_mb:.0f} MB CSV)")
    print(f"time: {seconds:.0f} s ({seconds / max(rows, 1) * 1e6:.1f} us per estimate)")
    verdict = "under" if peak_mb < TARGET_MB else "OVER"
    print(f"peak RSS of hmmtrack track: {peak_mb:.0f} MB ({verdict} the {TARGET_MB:.0f} MB target)")
    print(describe("end"))


if __name__ == "__main__":
    main()
