"""``hmmtrack track``: estimate a tagged animal's positions from detection logs.

Reads detections (VUE, Fathom or plain CSV) and receiver positions (x/y or lon/lat), runs
the tracker and writes one estimate per second as CSV (``time`` ISO 8601 UTC, ``x``, ``y``,
``lon``, ``lat`` when the receivers were given in lon/lat, the x-y covariance,
``sqrt_lambda1`` and ``n_eff``): the filter's estimates, or with smoothing the fixed-lag
smoother's, whose last column is ``n_ancestors`` instead of ``n_eff`` (the run prints which).
With ``--truth`` it prints the paper's metrics; with ``--plot`` it draws the error over time
and particle snapshots.

The measurement models (``--measurement``), all run by
:func:`hmmtrack.tracking.pipeline.track`: ``range-rate``, the paper's ranges and range-rates
from the tag period and known initial ranges ``--r0``; ``arrival-time``, the tag's emission
clock carried in the particle state, no initial range needed, optionally smoothed with a fixed
lag (its detection times must be on one common time base: ``--clocks``, the clock file of
``hmmtrack sync``, moves each receiver's logged times to it); ``ping`` (``--burst-interval``),
each ping's time differences across receivers, smoothed by default (offline array data, as
YAPS; ``--no-smooth`` writes the filter's estimates, streamed to the file as they are made).

Settings come, in increasing precedence, from ``--preset`` (a bundled set of settings
for one kind of deployment, e.g. ``two-moving-receivers``), ``--config`` (a JSON file, see
:mod:`hmmtrack.tracking.config`) and the command-line options. The options are generated
from the settings classes of the configuration's sections (:func:`settings_options`): one
per setting, with its help text, check and default, so that every default lives beside its
component. ``--bounds`` are in the receivers file's frame: metres, or degrees for lon/lat
receivers, converted with their projection by :func:`hmmtrack.io.bounds_in_metres`. An option
that the run's measurement or motion model does not use is an error, not ignored.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import warnings
from collections.abc import Iterator

import numpy as np
import pandas as pd

from hmmtrack import io
from hmmtrack.analysis import metrics
from hmmtrack.cli import UserInputError, add_command, add_time_unit
from hmmtrack.io.outputs import atomic_files, check_paths
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import (
    MEASUREMENT_FILTERS,
    SECTIONS,
    TrackingConfig,
    merge_settings,
    nest,
    preset_names,
    read_preset,
    read_settings,
    section_classes,
    section_default,
)
from hmmtrack.tracking.filter import DEFAULT_FILTER, FILTERS
from hmmtrack.tracking.measurement.sequence import (
    GROUPING_RECEIVERS,
    GROUPING_SHARE,
    fixed_period_measurement,
)
from hmmtrack.tracking.measurement.tdoa import per_ping_table
from hmmtrack.tracking.settings import boolean

logger = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class Option:
    """One generated option: a setting's key, its section and the components that have it.

    Attributes
    ----------
    key : str
        The setting's key (the option's ``dest``).
    section : str or None
        Its section (``None``: a key of the run itself).
    components : tuple of str
        Names of the section's components whose settings have the key (all of them, or
        ``(None,)`` for the filter and the run).
    owner : type
        The settings class of the first of them.
    field : dataclasses.Field
        Its field (the same help, check and default in all of them).
    fields : tuple of dataclasses.Field
        The field of each component: a word that one with its own parser takes is accepted
        on the command line (e.g. the ping measurement's ``--arrival-sigma pings``), and
        checked again by the run's own component when its configuration is built.
    """

    key: str
    section: str | None
    components: tuple
    owner: type
    field: dataclasses.Field
    fields: tuple = ()

    @property
    def flag(self) -> str:
        """``--option``."""
        return "--" + (self.field.metadata["option"] or self.key.replace("_", "-"))

    @property
    def spelled(self) -> str:
        """The option as the user may have spelled it (``--resting/--no-resting``)."""
        if self.field.metadata["check"] is boolean:
            return f"{self.flag}/--no-{self.flag[2:]}"
        return self.flag

    @property
    def default_text(self) -> str | None:
        """The default as the help says it (``None``: no default, e.g. the period)."""
        text = self.field.metadata["default_text"]
        if text is not None:
            return text
        if self.field.default is dataclasses.MISSING:
            return None
        return (
            format(self.field.default, "g")
            if isinstance(self.field.default, float)
            else (str(self.field.default))
        )


def settings_options() -> Iterator[Option]:
    """The options of every setting: the run's own keys, then each section's, a key shared
    by several components of a section (e.g. ``period``) once."""
    sections = {None: {None: TrackingConfig}} | {s: section_classes(s) for s in SECTIONS}
    for section, classes in sections.items():
        seen: dict[str, list] = {}
        for name, cls in classes.items():
            for field in dataclasses.fields(cls):
                if "help" in field.metadata:
                    seen.setdefault(field.name, []).append((name, cls, field))
        for key, found in seen.items():
            _, owner, field = found[0]
            names = tuple(name for name, _, _ in found)
            fields = tuple(f for _, _, f in found)
            yield Option(key, section, names, owner, field, fields)


def _checked(option: Option):
    """argparse type of a one-word option: parsed and checked by its setting, or when the
    first component's refuses it by another component's that parses words its own way (the
    ping measurement's ``--arrival-sigma pings``); the first one's error otherwise."""
    parse = option.field.metadata["parse"]
    own = [f for f in option.fields if f.metadata["parse"] is not parse]

    def convert(text: str):
        errors = []
        for field in (option.field, *own):
            parse, check = field.metadata["parse"], field.metadata["check"]
            try:
                value = parse(text)
                return value if check is None else check(option.key, value)
            except ValueError as exc:
                errors.append(exc)
        raise argparse.ArgumentTypeError(str(errors[0])) from None

    return convert


def _add(parser: argparse.ArgumentParser, option: Option) -> None:
    meta = option.field.metadata
    help_text = meta["help"]
    if option.components != (None,) and len(option.components) < len(
        section_classes(option.section)
    ):
        help_text = f"{option.section} {' or '.join(option.components)} only: {help_text}"
    if meta["requires"] is not None:
        key, value = meta["requires"]
        help_text = f"with --{key.replace('_', '-')} {value} only: {help_text}"
    if option.default_text is not None:
        help_text += f" (default: {option.default_text})"
    kwargs = {"dest": option.key, "help": help_text, "metavar": meta["metavar"]}
    if meta["check"] is boolean:
        kwargs = {"dest": option.key, "help": help_text}
        parser.add_argument(option.flag, action=argparse.BooleanOptionalAction, **kwargs)
        return
    if meta["choices"] is not None:
        kwargs.update(choices=meta["choices"], metavar=None)
    if meta["append"]:
        kwargs.update(action="append", type=meta["parse"])
    elif meta["nargs"] is not None:
        kwargs.update(nargs=meta["nargs"], type=_checked_word(meta["parse"]))
    elif meta["choices"] is None:
        kwargs["type"] = _checked(option)
    parser.add_argument(option.flag, **kwargs)


def _checked_word(parse):
    """argparse type of one word of a several-word option (checked as a whole later)."""

    def convert(text: str):
        try:
            value = parse(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if isinstance(value, float) and not np.isfinite(value):
            raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
        return value

    return convert


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "track",
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
    add_time_unit(parser, "the detections, receivers and truth")
    parser.add_argument(
        "--tz",
        help="time zone of ISO times written without a UTC offset in the detections, receivers "
        "and truth (e.g. UTC, America/Los_Angeles); such times are refused without it",
    )
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
        help="JSON file of settings (sections measurement, motion, filter); overrides --preset",
    )
    parser.add_argument(
        "--measurement",
        choices=tuple(section_classes("measurement")),
        help=(
            "range-rate (default): the paper's ranges and range-rates (needs --r0); "
            "arrival-time: the tag's emission clock in the particle state, no initial range "
            "(with --period and no --r0 the default, or ping-sequence when the tag's pings "
            f"are heard by {GROUPING_RECEIVERS} or more receivers, {100 * GROUPING_SHARE:.0f} "
            "%% of them or more); "
            "ping (the default with --burst-interval): each ping's arrivals at several receivers "
            "scored on their time differences, for random-interval tags; ping-sequence (the "
            "default with --burst-sequence): the same with the emission times of a known "
            "pseudo-random interval sequence, or with --period those of a fixed-period tag "
            "(its pings grouped; arrival-time scores them one detection at a time)"
        ),
    )
    parser.add_argument(
        "--motion",
        choices=tuple(section_classes("motion")),
        help=f"motion model (default: {SECTIONS['motion']}; baseline for --measurement ping)",
    )
    parser.add_argument(
        "--filter",
        choices=tuple(FILTERS),
        help=(
            "named filter: mode-keeping (--acquisition --mixture --long-gap: particles drawn "
            "from the first detections' likelihood, every mode of the posterior kept, the tag "
            "re-acquired after a long silence), paper (the "
            "paper's algorithm: particles uniform in the box, the whole cloud resampled) or "
            "acquired (the paper's with --acquisition); the "
            f"switch options override it (default: {DEFAULT_FILTER}; "
            + "; ".join(f"{f} for --measurement {m}" for m, f in MEASUREMENT_FILTERS.items())
            + ")"
        ),
    )
    for option in settings_options():
        _add(parser, option)
    parser.add_argument(
        "--no-smooth",
        dest="smoothing_lag",
        action="store_const",
        const=0,
        help="write the filter's estimates (the same as --smooth 0)",
    )
    parser.add_argument("--seed", type=int, help="random seed (printed when not given)")
    parser.add_argument(
        "--truth", help="true positions CSV (time, x, y or lon, lat): print metrics"
    )
    parser.add_argument("--plot", help="PNG: error over time (with --truth) and particle snapshots")
    parser.add_argument(
        "--per-ping",
        metavar="FILE",
        help=(
            "CSV of every ping heard (ping measurements): estimated emission time, x, y, their "
            "sds, the receivers that heard it, and the smoothed position when smoothed"
        ),
    )
    parser.set_defaults(func=run)


def _given(args: argparse.Namespace) -> dict:
    """The settings given as options, by key (``r0`` pairs as a mapping)."""
    given = {key: getattr(args, key) for key in ("measurement", "motion", "filter")}
    if given["measurement"] is None and args.burst_sequence is not None:
        given["measurement"] = "ping-sequence"  # a known sequence is the ping-sequence's
    elif given["measurement"] is None and args.burst_interval is not None:
        given["measurement"] = "ping"  # a random burst interval is the ping measurement's
    for option in settings_options():
        value = getattr(args, option.key)
        if option.field.metadata["append"] and value is not None:
            value = dict(value)
        given[option.key] = value
    return {key: value for key, value in given.items() if value is not None}


def build_config(args: argparse.Namespace, fixed_period: str = "arrival-time") -> TrackingConfig:
    """The run's settings: ``--preset`` (if any), overridden by the ``--config`` file (if
    any), overridden by the options.

    A run that names no measurement and gives a period but no ``r0`` tracks a fixed-period
    tag with the measurement ``fixed_period`` (:func:`run` chooses it from the tag's pings,
    :func:`~hmmtrack.tracking.measurement.sequence.fixed_period_measurement`).
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
    given, settings, sources = _layered(args)
    if _fixed_period(settings):
        settings["measurement"] = {"name": fixed_period, **settings["measurement"]}
    for option in settings_options():
        if option.key in given:
            _check_used(option, settings)
    if not args.config:
        measurement = settings.get("measurement", {})
        needed = {
            "range-rate": ("period", "r0"),
            "range-rate-gps": ("period", "r0"),
            "ping": (),
            "ping-sequence": (),
        }.get(measurement.get("name", "range-rate"), ("period",))
        missing = [f"--{k}" for k in needed if k not in measurement]
        if missing:
            raise UserInputError(f"give {' and '.join(missing)}, or a --config file with them")
    return TrackingConfig.from_dict(settings, source=", ".join([*sources, "command line"]))


def _layered(args: argparse.Namespace) -> tuple[dict, dict, list[str]]:
    """The options given (:func:`_given`), the settings of ``--preset``, ``--config`` and
    the options merged, and the sources' names."""
    given = _given(args)
    layers, sources = [], []
    if args.preset:
        layers.append(read_preset(args.preset))
        sources.append(f"preset {args.preset!r}")
    if args.config:
        layers.append(read_settings(args.config))
        sources.append(args.config)
    return given, merge_settings(*layers, nest(given)), sources


def _fixed_period(settings: dict) -> bool:
    """Whether merged ``settings`` are a fixed-period tag's whose measurement is not named:
    a period, no known ranges (``r0``: the range-rate measurement's)."""
    measurement = settings.get("measurement", {})
    return "name" not in measurement and "period" in measurement and "r0" not in measurement


def _chosen_for_period(args, config, detections, receivers) -> TrackingConfig:
    """``config`` with the measurement the tag's pings choose
    (:func:`~hmmtrack.tracking.measurement.sequence.fixed_period_measurement`), for a
    fixed-period tag's settings that name no measurement (:func:`_fixed_period`, which the
    caller has checked); the run says which and why."""
    tracked = tracking.tracked_detections(detections, config)
    if config.clocks is not None:
        receivers = tracking.clock_positions(receivers, config.clocks)
    name, share = fixed_period_measurement(tracked, receivers, config.measurement.period)
    print(
        f"measurement: {name} ({100 * share:.0f} % of the pings heard by "
        f"{GROUPING_RECEIVERS} or more receivers; pings are grouped from "
        f"{100 * GROUPING_SHARE:.0f} %; --measurement names one)",
        file=sys.stderr,
    )
    return config if name == config.measurement.name else build_config(args, name)


def _require_pings(args, config: TrackingConfig, chosen: str = "") -> None:
    """Refuse ``--per-ping`` unless the run's measurement scores pings (``chosen`` says how
    that measurement was chosen)."""
    if args.per_ping and config.measurement.name not in ("ping", "ping-sequence"):
        raise UserInputError(
            f"--per-ping is used with --measurement ping or ping-sequence only (this run's is "
            f"{config.measurement.name}{chosen})"
        )


def _check_used(option: Option, settings: dict) -> None:
    """Refuse an option that the run's components do not use."""
    section = settings.get(option.section, {}) if option.section else settings
    if option.components != (None,):
        name = section.get("name", section_default(settings, option.section)["name"])
        if name not in option.components:
            raise UserInputError(
                f"{option.spelled} is used with --{option.section} "
                f"{' or '.join(option.components)} only (this run's {option.section} is {name})"
            )
    requires = option.field.metadata["requires"]
    if requires is not None:
        key, value = requires
        default = {f.name: f.default for f in dataclasses.fields(option.owner)}
        used = section.get(key, default[key])
        if used != value:
            raise UserInputError(
                f"{option.spelled} is used with --{key.replace('_', '-')} {value} only "
                f"(this run's {key} is {used})"
            )


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


def _report(result, args: argparse.Namespace, receivers: pd.DataFrame, truth):
    """Say what the run found (ambiguity, the filter's events, the metrics against
    ``truth``) and draw the ``--plot`` figure (``None`` without one)."""
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
    if not args.plot:
        return None
    import matplotlib

    matplotlib.use("Agg")
    from hmmtrack.plots.tracking import plot_tracking_run

    return plot_tracking_run(
        estimates,
        snapshots,
        receivers,
        observations=observations,
        truth=truth,
        errors=errors,
        convergence=convergence,
    )


def run(args: argparse.Namespace) -> int:
    config = build_config(args)  # (the arrival-time measurement until the pings choose)
    inputs = {"--detections": args.detections, "--receivers": args.receivers}
    inputs |= {"--config": args.config, "--model": args.model, "--truth": args.truth}
    inputs |= {"--clocks": config.clocks}
    sequence = getattr(config.measurement, "burst_sequence", None)
    if isinstance(sequence, str):
        inputs["--burst-sequence"] = sequence
    undecided = _fixed_period(_layered(args)[1])  # (the pings choose the measurement)
    if not undecided:
        _require_pings(args, config)
    check_paths(
        inputs, outputs={"-o": args.output, "--plot": args.plot, "--per-ping": args.per_ping}
    )
    seed = args.seed
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % 2**63)
        print(f"seed: {seed} (pass --seed {seed} to repeat this run)", file=sys.stderr)
    detections = io.read_detections(args.detections, tz=args.tz, time_unit=args.time_unit)
    receivers = io.read_receivers(args.receivers, tz=args.tz, time_unit=args.time_unit)
    projection = io.Projection.from_frame(receivers)
    truth = io.read_truth(args.truth, projection, args.time_unit, args.tz) if args.truth else None
    if undecided:
        config = _chosen_for_period(args, config, detections, receivers)
        _require_pings(
            args, config, ", chosen by the pings: --measurement ping-sequence groups them"
        )
    if args.bounds is not None and projection is not None:
        config = config.override(bounds=io.bounds_in_metres(args.bounds, projection))
    snapshot_times = ()
    if args.plot:
        from hmmtrack.plots.tracking import snapshot_times as choose_snapshots

        tracked = tracking.tracked_detections(detections, config)
        snapshot_times = choose_snapshots(*tracking.time_window(tracked["time"], config))
    # estimates (the smoothed ones when the run smooths) go to the output as they are made
    # (memory bounded by the particles and the observations, not the span) unless the
    # metrics, the plot or a smoothed run's per-ping table need them all at the end
    stream = truth is None and not args.plot
    stream = stream and not (args.per_ping and config.smoothing)  # (it uses the smoothed)
    outputs = [args.output, args.plot, args.per_ping]
    with atomic_files(*filter(None, outputs)) as written:
        paths = dict(zip([p for p in outputs if p], written, strict=True))
        with open(paths[args.output], "w", newline="") as file:
            writer = io.EstimatesWriter(file, projection)
            with warnings.catch_warnings():
                # the filter warns of each event as it happens; they are logged once below
                warnings.filterwarnings("ignore", message=r"t=\S+: \w+: ", category=RuntimeWarning)
                result = tracking.track(
                    detections,
                    receivers,
                    config,
                    seed=seed,
                    snapshot_times=snapshot_times,
                    estimates_to=writer if stream else None,
                )
            figure = _report(result, args, receivers, truth)
            attrs = result.observations.attrs
            if "arrival_sigma" in attrs:  # (a ping measurement's: say what it chose)
                chosen = f"{1e3 * attrs['arrival_sigma']:.3g} ms"
                print(f"arrival sd: {chosen} ({attrs['arrival_sigma_source']})", file=sys.stderr)
            if not stream:
                writer(result.estimates if result.smoothed is None else result.smoothed)
        if figure is not None:
            figure.savefig(paths[args.plot], dpi=120, bbox_inches="tight")
        if args.per_ping:
            pings = per_ping_table(result.pings, result.observations, result.smoothed)
            io.write_estimates(pings, paths[args.per_ping], projection=projection)
    which = "" if config.smoothing is None else f"fixed-lag smoothed (lag {config.smoothing}) "
    print(f"wrote {writer.rows} {which}estimates to {args.output}")
    if args.per_ping:
        print(f"wrote {len(pings)} pings to {args.per_ping}")
    if args.plot:
        print(f"wrote {args.plot}")
    return 0
