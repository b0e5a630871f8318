"""``hmmtrack track``: estimate a tagged animal's positions from detection logs.

Reads detections (VUE, Fathom or plain CSV) and receiver positions (x/y or lon/lat), runs
the tracker and writes one estimate per second as CSV (``time`` ISO 8601 UTC, ``x``, ``y``,
``lon``, ``lat`` when the receivers were given in lon/lat, the x-y covariance,
``sqrt_lambda1`` and ``n_eff``). With ``--truth`` it prints the paper's metrics; with
``--plot`` it draws the error over time and particle snapshots.

Two measurement models (``--measurement``): ``range-rate``, the paper's ranges and
range-rates from the tag period and known initial ranges ``--r0``
(:func:`hmmtrack.tracking.track`); ``arrival-time``, the tag's emission clock carried in
the particle state, no initial range needed, optionally smoothed with a fixed lag
(:func:`hmmtrack.clock_tracking.track_arrival_time`; its detection times must be on one
common time base).

Settings come, in increasing precedence, from ``--preset`` (a bundled set of settings
for one kind of deployment, e.g. ``two-moving-receivers``), ``--config`` (a JSON file, see
:mod:`hmmtrack.config`) and the command-line options.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack import io, metrics, tracking
from hmmtrack.cli import UserInputError
from hmmtrack.config import (
    MEASUREMENTS,
    TrackingConfig,
    merge_settings,
    preset_names,
    read_preset,
    read_settings,
)
from hmmtrack.filter import RESAMPLE_WHEN
from hmmtrack.motion import HMM_VARIANTS
from hmmtrack.resampling import RESAMPLERS


def _r0_pair(text: str) -> tuple[str, float]:
    name, sep, value = text.rpartition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected RECEIVER=METRES, got {text!r}")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"r0 of {name!r} is not a number: {value!r}") from None


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "track",
        help="estimate positions of a tag from detection logs (particle filter)",
        description=(
            "Track an acoustic tag from the detection times logged by hydrophones: ranges "
            "from the tag period (the paper's ΔTOF), a particle filter with the chosen "
            "motion model, one estimate per second written as CSV."
        ),
    )
    parser.add_argument("--detections", required=True, help="detection log (VUE, Fathom, plain)")
    parser.add_argument(
        "--receivers", required=True, help="receiver positions CSV (x/y or lon/lat)"
    )
    parser.add_argument("-o", "--output", required=True, help="estimates CSV to write")
    parser.add_argument(
        "--preset",
        metavar="NAME",
        help=(
            "named settings for a kind of deployment (available: "
            f"{', '.join(preset_names())}); --config and the options override them"
        ),
    )
    parser.add_argument(
        "--config",
        help="JSON file of settings (keys of TrackingConfig); overrides --preset",
    )
    parser.add_argument("--period", type=float, help="transmitter period T (s), e.g. 8.179")
    parser.add_argument(
        "--r0",
        type=_r0_pair,
        action="append",
        metavar="RECEIVER=METRES",
        help="range at the receiver's first detection (m); once per receiver",
    )
    parser.add_argument(
        "--motion", choices=tracking.MOTIONS, help="motion model (default: the preset's, or hmm)"
    )
    parser.add_argument(
        "--model", help="movement HMM JSON for --motion hmm (default: bundled white shark)"
    )
    parser.add_argument(
        "--hmm-variant",
        choices=HMM_VARIANTS,
        default="time_consistent",
        help=(
            "HMM motion variant: time_consistent (default) respects the time step the model "
            "was fitted at (state switches and speed/turn draws per fitted step, plus a "
            "small heading random walk); paper redraws speed, turn and state every second "
            "whatever that step (the paper's algorithm; under-disperses headings for a "
            "model fitted at a coarser step)"
        ),
    )
    parser.add_argument(
        "--no-resting",
        action="store_true",
        help=(
            "--motion hmm only: track with the movement HMM as fitted, without the resting "
            "state added by default (hmmtrack.tracking.HMM_RESTING)"
        ),
    )
    parser.add_argument(
        "--measurement",
        choices=MEASUREMENTS,
        help=(
            "range-rate (default unless the preset says otherwise): the paper's ranges and "
            "range-rates (needs --r0); "
            "arrival-time: the tag's emission clock in the particle state, no initial range"
        ),
    )
    parser.add_argument(
        "--smooth",
        type=int,
        metavar="LAG",
        help="arrival-time only: write the fixed-lag smoothed estimates (lag in seconds)",
    )
    parser.add_argument("--particles", type=int, help="number of particles")
    parser.add_argument(
        "--resampling",
        choices=sorted(RESAMPLERS),
        help="resampling scheme (default systematic; multinomial is the paper's)",
    )
    parser.add_argument(
        "--resample-when",
        choices=RESAMPLE_WHEN,
        help="resample after every correction (always: default, the paper) or on low ESS",
    )
    parser.add_argument("--sound-speed", type=float, help="speed of sound (m/s, default 1460)")
    parser.add_argument(
        "--transmitter", help="transmitter to track (full id or ID part) when the log holds several"
    )
    parser.add_argument(
        "--depth", help="depth correction: none (default), sensor, or a depth in metres"
    )
    parser.add_argument("--start", help="start of the run (ISO 8601 UTC; default first detection)")
    parser.add_argument("--end", help="end of the run (ISO 8601 UTC; default last detection)")
    parser.add_argument("--seed", type=int, help="random seed (printed when not given)")
    parser.add_argument(
        "--truth", help="true positions CSV (time, x, y or lon, lat): print metrics"
    )
    parser.add_argument("--plot", help="PNG: error over time (with --truth) and particle snapshots")
    parser.set_defaults(func=run)


def build_config(args: argparse.Namespace) -> TrackingConfig:
    """The run's settings: ``--preset`` (if any), overridden by the ``--config`` file (if
    any), overridden by the options."""
    overrides = {
        "period": args.period,
        "r0": dict(args.r0) if args.r0 else None,
        "n_particles": args.particles,
        "resampling": args.resampling,
        "resample_when": args.resample_when,
        "sound_speed": args.sound_speed,
        "transmitter": args.transmitter,
        "depth": args.depth,
        "start": args.start,
        "end": args.end,
        "measurement": args.measurement,
        "motion": args.motion,
    }
    layers, sources = [], []
    if args.preset:
        layers.append(read_preset(args.preset))
        sources.append(f"preset {args.preset!r}")
    if args.config:
        layers.append(read_settings(args.config))
        sources.append(args.config)
    settings = merge_settings(*layers, overrides)
    if not args.config:
        arrival = settings.get("measurement") == "arrival-time"
        needed = ("period",) if arrival else ("period", "r0")
        missing = [f"--{k}" for k in needed if k not in settings]
        if missing:
            raise UserInputError(f"give {' and '.join(missing)}, or a --config file with them")
    return TrackingConfig.from_dict(settings, source=", ".join([*sources, "command line"]))


def read_truth(path: str | Path, projection: io.Projection | None) -> pd.DataFrame:
    """Truth table from a CSV of ``time`` and ``x``, ``y`` (m) or ``lon``, ``lat`` (degrees).

    A single row (``time`` empty or absent) is a fixed tag.
    """
    table = pd.read_csv(path)
    table.attrs["source"] = str(path)
    if "time" not in table.columns:
        if len(table) != 1:
            raise ValueError(f"{path}: truth needs a 'time' column; found {list(table.columns)}")
        table["time"] = np.nan  # one row without time: a fixed tag
    if {"x", "y"} <= set(table.columns):
        x, y = table["x"].to_numpy(dtype=float), table["y"].to_numpy(dtype=float)
    elif {"lon", "lat"} <= set(table.columns):
        if projection is None:
            raise ValueError(f"{path}: truth in lon/lat needs receivers in lon/lat too")
        x, y = projection.to_xy(table["lon"], table["lat"])
    else:
        raise ValueError(
            f"{path}: truth needs x, y or lon, lat columns; found {list(table.columns)}"
        )
    time = io.parse_times(table, "time", tz=None)
    if len(table) > 1 and not np.isfinite(time).all():
        raise ValueError(f"{path}: empty time in a truth with several rows")
    return pd.DataFrame({"time": time, "x": x, "y": y})


def _within_truth(estimates: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    if len(truth) == 1:
        return estimates
    inside = estimates["time"].between(truth["time"].min(), truth["time"].max())
    if not inside.all():
        print(
            f"metrics over the {int(inside.sum())} of {len(estimates)} estimates inside the "
            "truth's time span",
            file=sys.stderr,
        )
    if not inside.any():
        raise ValueError("no estimate lies inside the truth's time span")
    return estimates.loc[inside].reset_index(drop=True)


def _track_arrival_time(args, config, detections, receivers, motion, seed):
    """Estimates and events of an arrival-time run (:mod:`hmmtrack.clock_tracking`)."""
    from hmmtrack.clock_tracking import track_arrival_time

    result = track_arrival_time(
        tracking.select_transmitter(detections, config.transmitter),
        receivers,
        motion=motion,
        smoothing_lag=args.smooth,
        seed=seed,
        **config.arrival_time_options(),
    )
    ambiguous = result.ambiguity[result.ambiguity["ambiguous"].astype(bool)]
    if not ambiguous.empty:
        print(
            f"warning: {len(ambiguous)} of {len(result.ambiguity)} corrections left two "
            f"separate clusters of particles (mirror ambiguity), first at "
            f"{ambiguous['time'].iloc[0]}",
            file=sys.stderr,
        )
    estimates = result.smoothed if args.smooth is not None else result.estimates
    return estimates, result.events


def run(args: argparse.Namespace) -> int:
    config = build_config(args)
    if args.smooth is not None and config.measurement != "arrival-time":
        raise UserInputError("--smooth needs --measurement arrival-time")
    if args.smooth is not None and args.smooth < 1:
        raise UserInputError(
            f"--smooth LAG must be a positive number of seconds, got {args.smooth}"
        )
    if args.model and config.motion != "hmm":
        raise UserInputError("--model is used with --motion hmm only")
    if args.no_resting and config.motion != "hmm":
        raise UserInputError("--no-resting is used with --motion hmm only")
    seed = args.seed
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % 2**63)
        print(f"seed: {seed} (pass --seed {seed} to repeat this run)", file=sys.stderr)
    detections = io.read_detections(args.detections)
    receivers = io.read_receivers(args.receivers)
    projection = io.Projection.from_frame(receivers)
    resting = None if args.no_resting else "default"
    motion = config.motion_model(args.model, variant=args.hmm_variant, resting=resting)
    snapshots, observations = {}, None
    if config.measurement == "arrival-time":
        estimates, events = _track_arrival_time(args, config, detections, receivers, motion, seed)
    else:
        snapshot_times = ()
        if args.plot:
            from hmmtrack.plots.tracking import snapshot_times as choose_snapshots

            tracked = tracking.select_transmitter(detections, config.transmitter)
            snapshot_times = choose_snapshots(*tracking.time_window(tracked["time"], config))
        result = tracking.track(
            detections, receivers, config, motion, seed=seed, snapshot_times=snapshot_times
        )
        estimates, events = result.estimates, result.events
        snapshots, observations = result.snapshots, result.observations
    io.write_estimates(estimates, args.output, projection=projection)
    print(f"wrote {len(estimates)} estimates to {args.output}")
    for event in events.itertuples(index=False):
        if event.kind != "anchor_detection":
            print(f"event at {event.time}: {event.kind}: {event.detail}", file=sys.stderr)
    truth = errors = convergence = None
    if args.truth:
        truth = read_truth(args.truth, projection)
        scored = _within_truth(estimates, truth)
        summary = metrics.tracking_metrics(scored, truth)
        converged = "" if summary.converged else " (never converged; 0 by the paper's rule)"
        print(f"time to convergence: {summary.time_to_convergence:.0f} s{converged}")
        print(
            "mean error after convergence (the paper's 'RMSE'): "
            f"{summary.mean_error_after_convergence:.2f} m"
        )
        print(f"root-mean-square error after convergence: {summary.rmse_after_convergence:.2f} m")
        errors = (scored["time"].to_numpy(), metrics.position_error(scored, truth))
        convergence = metrics.time_to_convergence(
            scored["time"].to_numpy(), scored["sqrt_lambda1"].to_numpy()
        )
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        from hmmtrack.plots.tracking import plot_tracking_run

        figure = plot_tracking_run(
            estimates,
            snapshots,
            receivers,
            observations=observations,
            truth=truth,
            errors=errors,
            convergence=convergence,
        )
        figure.savefig(args.plot, dpi=120, bbox_inches="tight")
        print(f"wrote {args.plot}")
    return 0
