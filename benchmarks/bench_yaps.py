"""The whole pipeline on YAPS's real example (../shared/data/yaps_ssu1): sync, track, smooth.

Runs issue 12's commands exactly, with every default: ``hmmtrack sync`` (clocks, sound speed
and the unfixed hydrophones' positions from the sync tags of the raw VUE export) and
``hmmtrack track`` of tag 15266 (random 20–40 s burst interval: the ping measurement, its
default random walk, tempering and fixed-lag smoothing), both through the command line. Times
the pipeline (sync and the default, smoothed track of the first seed; wall and process CPU
time, best of ``--repeats`` runs) and prints, for every seed, the accuracy against the GPS at
YAPS's ping times (median and RMSE) of the smoothed track (the default output) and of the
filter's (``--no-smooth``), beside YAPS's own (3.22 m, 4.34 m). Targets: median ≤ 3.0 m and
RMSE ≤ 4.0 m for each of seeds 1, 2, 3; the pipeline within 30 s on a 2-core machine. The
machine (CPU, cores, load) is printed at the start and the end.

    python benchmarks/bench_yaps.py [--seeds 1 2 3] [--repeats 1] [--figure F] [-- OPTION ...]

Options after ``--`` are added to every ``track`` command (e.g. ``-- --particles 2000``).
``--figure`` draws the GPS, the filter's and the smoother's per-second tracks of the first
seed, and the filter's position right after each ping.
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
#: YAPS's own fit of the same data at its ping times: median, RMSE (m)
YAPS = (3.22, 4.34)


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


def timed(args: list[str]) -> tuple[float, float]:
    """Run one CLI command; its wall and process CPU time (s)."""
    wall, cpu = time.perf_counter(), time.process_time()
    assert main(args) == 0, args[0]
    return time.perf_counter() - wall, time.process_time() - cpu


def sync(folder: Path) -> tuple[float, float]:
    """Issue 12's sync command in ``folder`` (``clocks.json``, ``synced.csv``); its times."""
    receivers = receivers_file(folder / "receivers.csv")
    vue = str(DATA / "VUE_Export_ssu1.csv")
    return timed(
        ["sync", "--detections", vue, "--receivers", str(receivers)]
        + ["--time-keeper", "VR2W-128367", "-o", str(folder / "clocks.json")]
        + ["--write-synced", str(folder / "synced.csv")]
    )


def track(folder: Path, seed: int, options: list[str], name: str) -> tuple[float, float]:
    """Issue 12's track command (plus ``options``) in ``folder``, writing ``<name>.csv`` and
    ``<name>_pings.csv``; its times."""
    vue = str(DATA / "VUE_Export_ssu1.csv")
    return timed(
        ["track", "--detections", vue, "--receivers", str(folder / "receivers.csv")]
        + ["--clocks", str(folder / "clocks.json"), "--transmitter", "15266"]
        + ["--burst-interval", "20", "40", "--seed", str(seed), "-o", str(folder / f"{name}.csv")]
        + ["--per-ping", str(folder / f"{name}_pings.csv"), *options]
    )


def main_() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--figure", help="PNG of the tracks over the GPS (first seed)")
    parser.add_argument("options", nargs="*", help="more track options (after --)")
    args = parser.parse_args()
    print(describe("start"))
    best: dict[str, tuple[float, float]] = {}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for _ in range(args.repeats):
            best["sync"] = min(best.get("sync", (np.inf, np.inf)), sync(folder))
            spent = track(folder, args.seeds[0], args.options, f"smoothed_{args.seeds[0]}")
            best["track"] = min(best.get("track", (np.inf, np.inf)), spent)
        for seed in args.seeds:
            if seed != args.seeds[0]:
                track(folder, seed, args.options, f"smoothed_{seed}")
            track(folder, seed, [*args.options, "--no-smooth"], f"filtered_{seed}")
            tracks = {
                kind: io.read_truth(folder / f"{kind}_{seed}.csv", None)
                for kind in ("filtered", "smoothed")
            }
            rows.append(
                (seed, *errors_at_yaps_pings(tracks["filtered"]))
                + errors_at_yaps_pings(tracks["smoothed"])
            )
            if args.figure and seed == args.seeds[0]:
                pings = pd.read_csv(folder / f"filtered_{seed}_pings.csv")
                draw(tracks, pings, args.figure)
    for step, (wall, cpu) in best.items():
        print(f"{step:6s} wall {wall:6.1f} s  cpu {cpu:6.1f} s")
    total = sum(wall for wall, _ in best.values())
    print(f"whole pipeline {total:.1f} s (target 30 s); track options: {args.options or 'none'}")
    print("at YAPS's ping times against the GPS (m; target median <= 3.0, RMSE <= 4.0):")
    print(" seed  filtered median  RMSE  smoothed median  RMSE")
    for seed, f_median, f_rmse, s_median, s_rmse in rows:
        print(f"{seed:5d}  {f_median:15.2f} {f_rmse:5.2f}  {s_median:15.2f} {s_rmse:5.2f}")
    print(f"YAPS on the same data: median {YAPS[0]:.2f} m, RMSE {YAPS[1]:.2f} m")
    if args.figure:
        print(f"wrote {args.figure}")
    print(describe("end"))


def draw(tracks: dict[str, pd.DataFrame], pings: pd.DataFrame, path: str) -> None:
    """The GPS, the filter's and the smoother's per-second tracks, the filter's position
    right after each ping and YAPS's own shipped track (its position at each ping), in
    metres."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gps = pd.read_csv(DATA / "ssu1_gps.csv")
    hydros = pd.read_csv(DATA / "ssu1_hydros.csv")
    origin = np.array([gps["utm_x"].min(), gps["utm_y"].min()])
    span = io.parse_times(gps, "ts", tz=None)[[0, -1]]
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.plot(gps["utm_x"] - origin[0], gps["utm_y"] - origin[1], "k-", lw=2, label="GPS")
    for (kind, table), colour in zip(tracks.items(), ("C1", "C0"), strict=True):
        inside = table["time"].between(*span)
        ax.plot(
            table.loc[inside, "x"] - origin[0],
            table.loc[inside, "y"] - origin[1],
            f"{colour}-",
            lw=1,
            label=f"{kind} (per second)",
        )
    ax.plot(pings["x"] - origin[0], pings["y"] - origin[1], "C3.", ms=4, label="filtered at pings")
    yaps = pd.read_csv(DATA / "yaps_reference_track_15266.csv")
    yaps = yaps[yaps["top"].between(*span)]
    ax.plot(yaps["x"] - origin[0], yaps["y"] - origin[1], "C4--", lw=1, label="YAPS (shipped fit)")
    ax.plot(hydros["x"] - origin[0], hydros["y"] - origin[1], "g^", label="hydrophones")
    margin = 30.0  # the array and its surroundings (a first, unconverged ping may lie off it)
    ax.set_xlim(hydros["x"].min() - origin[0] - margin, hydros["x"].max() - origin[0] + margin)
    ax.set_ylim(hydros["y"].min() - origin[1] - margin, hydros["y"].max() - origin[1] + margin)
    ax.set(xlabel="x (m)", ylabel="y (m)", aspect="equal", title="tag 15266, YAPS ssu1")
    ax.legend()
    fig.savefig(path, dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    main_()
