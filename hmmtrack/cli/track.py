"""``hmmtrack track``: estimate a tagged animal's positions from detection logs.

Reads detections (VUE, Fathom or plain CSV) and receiver positions (x/y or lon/lat), runs
the tracker and writes one estimate per second as CSV (``time`` ISO 8601 UTC, ``x``, ``y``,
``lon``, ``lat`` when the receivers were given in lon/lat, the x-y covariance,
``sqrt_lambda1`` and ``n_eff``). With ``--truth`` it prints the paper's metrics; with
``--plot`` it draws the error over time and particle snapshots.

Two measurement models (``--measurement``), both run by
:func:`hmmtrack.tracking.pipeline.track`: ``range-rate``, the paper's ranges and range-rates
from the tag period and known initial ranges ``--r0``; ``arrival-time``, the tag's emission
clock carried in the particle state, no initial range needed, optionally smoothed with a fixed
lag (its detection times must be on one common time base).

Settings come, in increasing precedence, from ``--preset`` (a bundled set of settings
for one kind of deployment, e.g. ``two-moving-receivers``), ``--config`` (a JSON file, see
:mod:`hmmtrack.tracking.config`) and the command-line options; every setting a run usually needs
has an option: search box (``--bounds``, in the receivers file's frame: metres, or degrees
for lon/lat receivers, converted with their projection by :func:`hmmtrack.io.bounds_in_metres`),
measurement noise (``--sigma-range``, ``--sigma-range-rate``; ``--arrival-sigma``), the
detection curve that makes missed pings count (``--detection-curve``), the search radius,
tempering and velocity-motion noise. An option that the run's measurement or motion model
does not use is an error, not ignored.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import sys
import warnings

import numpy as np
import pandas as pd

from hmmtrack import io
from hmmtrack.analysis import metrics
from hmmtrack.cli import UserInputError
from hmmtrack.io.outputs import atomic_files, check_paths
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import (
    TrackingConfig,
    measurement_covariance_with,
    merge_settings,
    preset_names,
    read_preset,
    read_settings,
)
from hmmtrack.tracking.filter import RESAMPLE_WHEN
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.arrival_time import ArrivalLikelihood
from hmmtrack.tracking.measurement.clocked import SEARCH_RADIUS, TEMPERING_ESS
from hmmtrack.tracking.motion import (
    HMM_VARIANTS,
    MOTIONS,
    VELOCITY_SIGMA_SPEED,
    VELOCITY_SIGMA_TURN_RATE,
)
from hmmtrack.tracking.resampling import RESAMPLERS

logger = logging.getLogger(__name__)

#: defaults of the configuration (help texts, build_config)
_CONFIG_DEFAULTS = {f.name: f.default for f in dataclasses.fields(TrackingConfig)}


def _r0_pair(text: str) -> tuple[str, float]:
    name, sep, value = text.rpartition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected RECEIVER=METRES, got {text!r}")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"r0 of {name!r} is not a number: {value!r}") from None


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _positive(text: str) -> float:
    value = _finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _non_negative(text: str) -> float:
    value = _finite(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


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
        "--motion", choices=MOTIONS, help="motion model (default: the preset's, or hmm)"
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
            "state added by default (hmmtrack.tracking.motion.HMM_RESTING)"
        ),
    )
    parser.add_argument(
        "--measurement",
        choices=tuple(MEASUREMENTS),
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
    parser.add_argument(
        "--bounds",
        type=_finite,
        nargs=4,
        metavar=("XMIN", "XMAX", "YMIN", "YMAX"),
        help=(
            "search box of the initial particles, in the frame of the receivers file: "
            "metres for x/y receivers; for lon/lat receivers LON_MIN LON_MAX LAT_MIN LAT_MAX "
            "in degrees, converted with the receivers' projection (the smallest x/y box "
            "holding it; a --config file's bounds are metres of that projection). "
            "Default: range-rate, the receivers' first positions widened by "
            "r0 + --bounds-margin; arrival-time, the receivers widened by --search-radius"
        ),
    )
    parser.add_argument(
        "--bounds-margin",
        type=_non_negative,
        metavar="METRES",
        help=(
            "range-rate only: metres added around the derived search box (default "
            f"{_CONFIG_DEFAULTS['bounds_margin']:g}), "
            "and how far given --bounds may miss a receiver's first range"
        ),
    )
    parser.add_argument(
        "--sigma-range",
        type=_positive,
        metavar="METRES",
        help=(
            "range-rate only: standard deviation of the range in the measurement covariance "
            f"(m; default {math.sqrt(_CONFIG_DEFAULTS['measurement_covariance'][0][0]):g}); "
            "a --config file's correlation of range and range-rate is kept"
        ),
    )
    parser.add_argument(
        "--sigma-range-rate",
        type=_positive,
        metavar="M_PER_S",
        help=(
            "range-rate only: standard deviation of the range-rate (m/s; default "
            f"{math.sqrt(_CONFIG_DEFAULTS['measurement_covariance'][1][1]):g})"
        ),
    )
    parser.add_argument(
        "--arrival-sigma",
        type=_positive,
        metavar="SECONDS",
        help=(
            "arrival-time only: standard deviation of an arrival-time residual "
            f"(s; default {ArrivalLikelihood().sigma:g})"
        ),
    )
    parser.add_argument(
        "--detection-curve",
        type=_finite,
        nargs=2,
        metavar=("RANGE_50", "WIDTH"),
        help=(
            "arrival-time only: probability of hearing a ping against range, "
            "1 / (1 + exp((r - RANGE_50) / WIDTH)) (both in metres), so that pings the "
            "particles say should have been heard but were not count against them"
        ),
    )
    parser.add_argument(
        "--search-radius",
        type=_positive,
        metavar="METRES",
        help=(
            "arrival-time only, without --bounds: the search box is the receivers' positions "
            "at the start widened by this (about their detection range; default "
            f"{SEARCH_RADIUS:g})"
        ),
    )
    parser.add_argument(
        "--tempering-ess",
        type=_positive,
        metavar="FRACTION",
        help=(
            "arrival-time only: temper a correction that would leave fewer than this "
            f"fraction of the particles, in (0, 1] (default "
            f"{TEMPERING_ESS:g})"
        ),
    )
    parser.add_argument(
        "--sigma-speed",
        type=_non_negative,
        metavar="M_PER_S",
        help=(
            "velocity motion only: spread of the speed increments "
            f"(m/s per sqrt(s); default {VELOCITY_SIGMA_SPEED:g})"
        ),
    )
    parser.add_argument(
        "--sigma-turn-rate",
        type=_non_negative,
        metavar="RAD_PER_S",
        help=(
            "velocity motion only: spread of the turn-rate increments "
            f"(rad/s per sqrt(s); default {VELOCITY_SIGMA_TURN_RATE:g})"
        ),
    )
    parser.add_argument(
        "--ess-threshold",
        type=_positive,
        metavar="FRACTION",
        help=(
            "with --resample-when ess: resample below this fraction of N, in (0, 1] "
            f"(default {_CONFIG_DEFAULTS['ess_threshold']:g})"
        ),
    )
    parser.add_argument(
        "--sound-speed",
        type=_positive,
        metavar="M_PER_S",
        help=f"speed of sound (m/s, default {_CONFIG_DEFAULTS['sound_speed']:g})",
    )
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


#: options that one measurement or motion model only uses: option -> (setting, value)
_MODEL_OPTIONS = {
    "bounds_margin": ("measurement", "range-rate"),
    "sigma_range": ("measurement", "range-rate"),
    "sigma_range_rate": ("measurement", "range-rate"),
    "arrival_sigma": ("measurement", "arrival-time"),
    "detection_curve": ("measurement", "arrival-time"),
    "search_radius": ("measurement", "arrival-time"),
    "tempering_ess": ("measurement", "arrival-time"),
    "sigma_speed": ("motion", "velocity"),
    "sigma_turn_rate": ("motion", "velocity"),
    "ess_threshold": ("resample_when", "ess"),
}


def build_config(args: argparse.Namespace) -> TrackingConfig:
    """The run's settings: ``--preset`` (if any), overridden by the ``--config`` file (if
    any), overridden by the options.

    ``--bounds`` are taken as metres here; :func:`run` converts them with
    :func:`hmmtrack.io.bounds_in_metres` when the receivers are lon/lat.
    """
    if args.bounds is not None:
        xmin, xmax, ymin, ymax = args.bounds
        if not (xmin < xmax and ymin < ymax):
            raise UserInputError(
                "--bounds must be XMIN XMAX YMIN YMAX with XMIN < XMAX and YMIN < YMAX (metres "
                "for x/y receivers, LON_MIN LON_MAX LAT_MIN LAT_MAX degrees for lon/lat ones), "
                f"got {' '.join(f'{b:g}' for b in args.bounds)}"
            )
    overrides = {
        "bounds": args.bounds,
        "bounds_margin": args.bounds_margin,
        "arrival_sigma": args.arrival_sigma,
        "search_radius": args.search_radius,
        "tempering_ess": args.tempering_ess,
        "sigma_speed": args.sigma_speed,
        "sigma_turn_rate": args.sigma_turn_rate,
        "ess_threshold": args.ess_threshold,
        "detection_curve": (
            None
            if args.detection_curve is None
            else {"range_50": args.detection_curve[0], "width": args.detection_curve[1]}
        ),
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
    for name, (setting, needed) in _MODEL_OPTIONS.items():
        used = settings.get(setting, _CONFIG_DEFAULTS[setting])
        if getattr(args, name) is not None and used != needed:
            raise UserInputError(
                f"--{name.replace('_', '-')} is used with --{setting.replace('_', '-')} "
                f"{needed} only (this run's {setting} is {used})"
            )
    if args.sigma_range is not None or args.sigma_range_rate is not None:
        try:
            settings["measurement_covariance"] = measurement_covariance_with(
                settings.get("measurement_covariance", _CONFIG_DEFAULTS["measurement_covariance"]),
                args.sigma_range,
                args.sigma_range_rate,
            )
        except ValueError as exc:  # the covariance of the preset or file
            raise ValueError(f"{', '.join(sources)}: {exc}") from None
    if not args.config:
        arrival = settings.get("measurement") == "arrival-time"
        needed = ("period",) if arrival else ("period", "r0")
        missing = [f"--{k}" for k in needed if k not in settings]
        if missing:
            raise UserInputError(f"give {' and '.join(missing)}, or a --config file with them")
    return TrackingConfig.from_dict(settings, source=", ".join([*sources, "command line"]))


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


def _warn_ambiguous(ambiguity: pd.DataFrame) -> None:
    """Warn (stderr) when corrections left two separate clusters of particles."""
    ambiguous = ambiguity[ambiguity["ambiguous"].astype(bool)]
    if not ambiguous.empty:
        print(
            f"warning: {len(ambiguous)} of {len(ambiguity)} corrections left two "
            f"separate clusters of particles (mirror ambiguity), first at "
            f"{ambiguous['time'].iloc[0]}",
            file=sys.stderr,
        )


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
    inputs = {"--detections": args.detections, "--receivers": args.receivers}
    inputs |= {"--config": args.config, "--model": args.model, "--truth": args.truth}
    check_paths(inputs, outputs={"-o": args.output, "--plot": args.plot})
    seed = args.seed
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % 2**63)
        print(f"seed: {seed} (pass --seed {seed} to repeat this run)", file=sys.stderr)
    detections = io.read_detections(args.detections)
    receivers = io.read_receivers(args.receivers)
    projection = io.Projection.from_frame(receivers)
    truth = io.read_truth(args.truth, projection) if args.truth else None
    if args.bounds is not None and projection is not None:
        config = config.override(bounds=io.bounds_in_metres(args.bounds, projection))
    resting = None if args.no_resting else "default"
    motion = config.motion_model(args.model, variant=args.hmm_variant, resting=resting)
    snapshot_times = ()
    if args.plot:
        from hmmtrack.plots.tracking import snapshot_times as choose_snapshots

        tracked = tracking.select_transmitter(detections, config.transmitter)
        snapshot_times = choose_snapshots(*tracking.time_window(tracked["time"], config))
    with warnings.catch_warnings():
        # the filter warns of each event as it happens; they are logged once below
        warnings.filterwarnings("ignore", message=r"t=\S+: \w+: ", category=RuntimeWarning)
        result = tracking.track(
            detections,
            receivers,
            config,
            motion,
            seed=seed,
            snapshot_times=snapshot_times,
            smoothing_lag=args.smooth,
        )
    if result.ambiguity is not None:
        _warn_ambiguous(result.ambiguity)
    estimates = result.estimates if result.smoothed is None else result.smoothed
    events, snapshots, observations = result.events, result.snapshots, result.observations
    events = events[events["kind"] != "anchor_detection"]
    times = io.format_times(events["time"].to_numpy(dtype=float))
    for time, kind, detail in zip(times, events["kind"], events["detail"], strict=True):
        logger.warning("filter event at %s: %s: %s", time, kind, detail)
    errors = convergence = None
    if truth is not None:
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
    figure = None
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
    with atomic_files(*filter(None, (args.output, args.plot))) as written:
        io.write_estimates(estimates, written[0], projection=projection)
        if figure is not None:
            figure.savefig(written[1], dpi=120, bbox_inches="tight")
    print(f"wrote {len(estimates)} estimates to {args.output}")
    if args.plot:
        print(f"wrote {args.plot}")
    return 0
