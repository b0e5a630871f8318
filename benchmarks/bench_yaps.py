"""The whole pipeline on YAPS's real example (../shared/data/yaps_ssu1): sync, track, smooth.

Times ``hmmtrack sync`` (clocks, sound speed and the unfixed hydrophones' positions from the
sync tags of the raw VUE export) and ``hmmtrack track`` of tag 15266 (random 20–40 s burst
interval: the ping measurement, fixed-lag smoothing), both through the command line, wall
and process CPU time, best of ``--repeats`` runs; and prints the accuracy against the GPS at
YAPS's ping times (median and RMSE, filtered and smoothed) beside YAPS's own (3.22 m,
4.34 m). Target: the whole pipeline within 30 s on a 2-core machine. The machine (CPU, cores,
load) is printed at the start and the end.

    python benchmarks/bench_yaps.py [--particles 2000] [--seed 1] [--repeats 1] [--figure F]

``--figure`` draws the GPS, the filtered position at every ping heard and the smoothed track.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from machine import describe

from hmmtrack import io
from hmmtrack.cli import main

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "yaps_ssu1"
#: the hydrophones YAPS's ssu1 example holds at their surveyed positions (its idx)
FIXED = (2, 3, 6, 8, 11, 13, 14, 15, 16, 17)
#: the tracking options of the YAPS runs (reasons in reports/decisions.md, "Ping measurement")
TRACK_OPTIONS = [
    "--burst-interval", "20", "40", "--motion", "baseline", "--sigma-position", "2.5",
    "--arrival-sigma", "0.002", "--tempering-ess", "0.6", "--smooth", "60",
]  # fmt: skip


def receivers_file(path: Path) -> Path:
    """``receivers.csv`` from ``ssu1_hydros.csv``
    (:func:`hmmtrack.io.receivers_from_yaps_hydros`)."""
    io.receivers_from_yaps_hydros(DATA / "ssu1_hydros.csv", fixed_idx=FIXED).to_csv(
        path, index=False
    )
    return path


def errors_at_yaps_pings(table: pd.DataFrame) -> tuple[float, float]:
    """Median and RMSE (m) of a per-second track interpolated at YAPS's ping times against
    the GPS interpolated there (the 142 pings inside the GPS span)."""
    gps = pd.read_csv(DATA / "ssu1_gps.csv")
    gps_time = io.parse_times(gps, "ts", tz=None)
    top = pd.read_csv(DATA / "yaps_reference_track_15266.csv")["top"].to_numpy()
    top = top[(top >= gps_time.min()) & (top <= gps_time.max())]
    error = np.hypot(
        np.interp(top, table["time"], table["x"]) - np.interp(top, gps_time, gps["utm_x"]),
        np.interp(top, table["time"], table["y"]) - np.interp(top, gps_time, gps["utm_y"]),
    )
    return float(np.median(error)), float(np.sqrt(np.mean(error**2)))


def run(folder: Path, particles: int, seed: int) -> dict:
    """Sync and track through the CLI in ``folder``; times (s) and output paths."""
    receivers = receivers_file(folder / "receivers.csv")
    vue = str(DATA / "VUE_Export_ssu1.csv")
    clocks = folder / "clocks.json"
    times = {}
    for step, args in (
        (
            "sync",
            ["sync", "--detections", vue, "--receivers", str(receivers)]
            + ["--time-keeper", "VR2W-128367", "--refine-positions", "3", "-o", str(clocks)],
        ),
        (
            "track",
            ["track", "--detections", vue, "--receivers", str(receivers), "--clocks", str(clocks)]
            + ["--transmitter", "15266", *TRACK_OPTIONS, "--particles", str(particles)]
            + ["--seed", str(seed), "-o", str(folder / "smoothed.csv")]
            + ["--per-ping", str(folder / "pings.csv")],
        ),
    ):
        wall, cpu = time.perf_counter(), time.process_time()
        assert main(args) == 0, step
        times[step] = (time.perf_counter() - wall, time.process_time() - cpu)
    return times


def main_() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--figure", help="PNG of the tracks over the GPS")
    args = parser.parse_args()
    print(describe("start"))
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for _ in range(args.repeats):
            for step, (wall, cpu) in run(folder, args.particles, args.seed).items():
                best[step] = min(best.get(step, (np.inf, np.inf)), (wall, cpu))
        smoothed = io.read_truth(folder / "smoothed.csv", None)
        pings = pd.read_csv(folder / "pings.csv")
    total = sum(wall for wall, _ in best.values())
    for step, (wall, cpu) in best.items():
        print(f"{step:6s} wall {wall:6.1f} s  cpu {cpu:6.1f} s")
    print(f"whole pipeline {total:.1f} s (target 30 s); {args.particles} particles")
    median, rmse = errors_at_yaps_pings(smoothed)
    print(f"smoothed at YAPS's ping times: median {median:.2f} m, RMSE {rmse:.2f} m")
    print(f"{len(pings)} pings heard; YAPS on the same data: median 3.22 m, RMSE 4.34 m")
    if args.figure:
        draw(smoothed, pings, args.figure)
        print(f"wrote {args.figure}")
    print(describe("end"))


def draw(smoothed: pd.DataFrame, pings: pd.DataFrame, path: str) -> None:
    """The GPS, the filtered position at each ping and the smoothed track, in metres."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gps = pd.read_csv(DATA / "ssu1_gps.csv")
    hydros = pd.read_csv(DATA / "ssu1_hydros.csv")
    origin = np.array([gps["utm_x"].min(), gps["utm_y"].min()])
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.plot(gps["utm_x"] - origin[0], gps["utm_y"] - origin[1], "k-", lw=2, label="GPS")
    inside = smoothed["time"].between(*io.parse_times(gps, "ts", tz=None)[[0, -1]])
    ax.plot(
        smoothed.loc[inside, "x"] - origin[0],
        smoothed.loc[inside, "y"] - origin[1],
        "C0-",
        lw=1,
        label="smoothed (per second)",
    )
    ax.plot(
        pings["x"] - origin[0], pings["y"] - origin[1], "C3.", ms=5, label="filtered (per ping)"
    )
    ax.plot(hydros["x"] - origin[0], hydros["y"] - origin[1], "g^", label="hydrophones")
    margin = 30.0  # the array and its surroundings (a first, unconverged ping may lie off it)
    ax.set_xlim(hydros["x"].min() - origin[0] - margin, hydros["x"].max() - origin[0] + margin)
    ax.set_ylim(hydros["y"].min() - origin[1] - margin, hydros["y"].max() - origin[1] + margin)
    ax.set(xlabel="x (m)", ylabel="y (m)", aspect="equal", title="tag 15266, YAPS ssu1")
    ax.legend()
    fig.savefig(path, dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    main_()
