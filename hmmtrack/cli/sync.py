"""``hmmtrack sync``: fit receiver clocks from sync tags and write the clock file.

Example::

    hmmtrack sync --detections VUE_Export_ssu1.csv --receivers receivers.csv \\
        --time-keeper VR2W-128367 -o clocks.json --write-synced synced.csv

reads the detections (VUE, Fathom or plain CSV) and the receivers file (``receiver, x, y``
and optional ``z``, ``sync_tag``, ``fixed``), fits every receiver's clock relative to the
time keeper (:func:`hmmtrack.sync.fit_clocks`; when the file has a ``fixed`` column, the
positions of the receivers not marked fixed are refined within
:data:`~hmmtrack.sync.fit.REFINE_POSITIONS_SD` m unless ``--refine-positions`` says
otherwise), and writes the clock file (JSON), the
per-receiver residual table (CSV, beside the clock file unless ``--residuals`` names it),
optionally a residual plot (``--plot``) and the detections on the common time base
(``--write-synced``: ``time`` in epoch seconds to the microsecond, ``receiver_time`` the
logged time).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hmmtrack import io
from hmmtrack.cli import add_command, add_time_unit
from hmmtrack.io.outputs import atomic_files, check_paths
from hmmtrack.sync import apply_clocks, fit_clocks, write_clocks
from hmmtrack.sync.fit import REFINE_POSITIONS_SD
from hmmtrack.tracking.measurement.ranging import check_sound_speed


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "sync",
        description=(
            "Synchronise a moored receiver array: fit every receiver's clock (offset, drift, "
            "drift rate per segment) relative to a time keeper from the detections of sync "
            "tags moored at known receivers."
        ),
    )
    parser.add_argument("--detections", required=True, help="detection log (VUE/Fathom/CSV)")
    parser.add_argument(
        "--receivers",
        required=True,
        help="receivers CSV: receiver,x,y[,z][,sync_tag][,fixed] (moored)",
    )
    parser.add_argument("-o", "--out", required=True, help="clock file to write (JSON)")
    add_time_unit(parser, "the detections and receivers")
    parser.add_argument(
        "--time-keeper", help="receiver whose clock is the common time base (default: most heard)"
    )
    parser.add_argument(
        "--segment-length",
        type=float,
        default=43200.0,
        metavar="S",
        help="longest clock segment (s); the span is cut into equal segments (default 43200)",
    )
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument("--sound-speed", type=float, metavar="M_S", help="fixed sound speed (m/s)")
    speed.add_argument(
        "--water",
        type=float,
        nargs=2,
        metavar=("TEMPERATURE", "SALINITY"),
        help="sound speed from water temperature (degC) and salinity (PSU), Mackenzie 1981",
    )
    parser.add_argument(
        "--refine-positions",
        type=float,
        metavar="SD",
        help=(
            "refine x, y of receivers not marked fixed, prior sd SD metres; 0: keep every "
            f"position (default: {REFINE_POSITIONS_SD:g} when the receivers file has a fixed "
            "column, else 0)"
        ),
    )
    parser.add_argument(
        "--self-detections",
        action="store_true",
        help="also use sync tags heard by their own receiver (taken at distance 0)",
    )
    parser.add_argument(
        "--min-detections",
        type=int,
        default=10,
        help="fewest sync detections per receiver and segment (default 10)",
    )
    parser.add_argument(
        "--max-clock-offset",
        type=float,
        default=300.0,
        metavar="S",
        help="largest clock difference between receivers before sync (s, default 300)",
    )
    parser.add_argument("--residuals", help="per-receiver residual table (CSV)")
    parser.add_argument("--plot", help="residual plot (PNG)")
    parser.add_argument("--write-synced", metavar="FILE", help="detections on the common time")
    parser.add_argument("--tz", help="time zone of naive times in a plain detections CSV")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    out = Path(args.out)
    table = Path(args.residuals) if args.residuals else out.with_name(out.stem + "_residuals.csv")
    check_paths(
        {"--detections": args.detections, "--receivers": args.receivers},
        outputs={
            "-o": out,
            "--residuals": table,
            "--plot": args.plot,
            "--write-synced": args.write_synced,
        },
    )
    if args.sound_speed is not None:
        check_sound_speed("--sound-speed", args.sound_speed)
    detections = io.read_detections(args.detections, tz=args.tz, time_unit=args.time_unit)
    receivers = io.read_receivers(args.receivers, time_unit=args.time_unit)
    temperature, salinity = args.water if args.water else (None, None)
    refine = args.refine_positions
    if refine is None:
        refine = REFINE_POSITIONS_SD if "fixed" in receivers else 0.0
    fit = fit_clocks(
        detections,
        receivers,
        time_keeper=args.time_keeper,
        segment_length=args.segment_length,
        sound_speed=args.sound_speed,
        temperature=temperature,
        salinity=salinity,
        refine_positions=refine or None,
        self_detections=args.self_detections,
        min_detections=args.min_detections,
        max_clock_offset=args.max_clock_offset,
    )
    clocks = fit.clocks
    written = [p for p in (out, table, args.plot, args.write_synced) if p]
    with atomic_files(*written) as temporary:
        files = iter(temporary)
        write_clocks(clocks, next(files))
        fit.summary.to_csv(next(files), index=False, float_format="%.6g")
        if args.plot:
            import matplotlib

            matplotlib.use("Agg")
            from hmmtrack.plots.sync import plot_sync_residuals

            figure = plot_sync_residuals(fit.residuals).figure
            figure.savefig(next(files), dpi=120, bbox_inches="tight")
        if args.write_synced:
            synced = apply_clocks(detections[detections["receiver"].isin(clocks.receivers)], clocks)
            synced.to_csv(next(files), index=False, float_format="%.6f")
    speeds = ", ".join(f"{c:.1f}" for c in clocks.sound_speed)
    print(
        f"synchronised {len(clocks.receivers)} receivers to {clocks.time_keeper} from "
        f"{clocks.pings} sync emissions ({int(clocks.detections.sum())} detections, "
        f"{int(clocks.rejected.sum())} outliers rejected, {clocks.echoes_dropped} echoes "
        f"dropped) in {len(clocks.segment_starts)} segment(s); sound speed "
        f"{speeds} m/s ({clocks.sound_speed_method}); residual scale {fit.scale_ms:.3f} ms; "
        f"{time.perf_counter() - started:.1f} s"
    )
    for path in written:
        print(f"  wrote {path}")
    return 0
