"""``hmmtrack fit``: fit a movement HMM to a track file and save it as JSON.

Example::

    hmmtrack fit data/example_tracks.csv --states 2 --starts 5 --seed 1 -o model.json

reads the tracks (plain CSV in metres, or Movebank lon/lat with ``--format movebank``,
projected by ``--crs``; rows without a fix refused, dropped or kept by ``--missing``),
computes steps and turning angles (:func:`hmmtrack.tracks.prepare`), fits
(:class:`hmmtrack.hmm.MovementHMMEstimator`, with ``--formula 'transition ~ cosT + sinT'`` or
``--covariates`` on the transition probabilities, ``--formula 'step.mean ~ cosT + sinT'``
on a parameter of a stream's distribution, ``--stream depth=normal`` for a further data
stream), prints the parameters with Wald intervals,
the coefficients on the data's scale, the transition matrix, the log-likelihood
and AIC, and writes the model file; ``--plot DIR`` also writes the standard figures
(:func:`hmmtrack.plots.hmm.hmm_figures`). States are numbered from 1 (the smallest mean step,
unless ``--fix`` or ``--equal`` name states, which then keep their numbers); ``--state-names``
labels them in the output and is saved in the model file. ``--fix 'step.mean[1]=50'``,
``--equal 'angle.concentration[1]==angle.concentration[2]'`` and ``--stationary`` constrain
the fit (:mod:`hmmtrack.hmm.constraints`); ``--check-starts N`` fits from N starting values
and prints where each ended (:func:`hmmtrack.hmm.diagnostics.starts_table`; ``starts.png``
with ``--plot``). The reading options defined here are shared with ``hmmtrack decode`` and
``hmmtrack plot``.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pandas as pd

from hmmtrack import io, tracks
from hmmtrack.cli import add_command
from hmmtrack.hmm import MovementHMMEstimator, crw, diagnostics, distributions, imputation
from hmmtrack.hmm.model import check_state_names
from hmmtrack.io.geo import Projection
from hmmtrack.io.outputs import atomic_files, check_paths, staged_folder


def add_track_arguments(parser: argparse.ArgumentParser) -> None:
    """Options that say how to read a track file (shared by ``fit`` and ``decode``)."""
    parser.add_argument("tracks", help="track CSV file")
    group = parser.add_argument_group("reading the tracks")
    group.add_argument("--format", choices=("plain", "movebank"), default="plain")
    group.add_argument(
        "--id-col",
        help="animal id column (plain: id; movebank: "
        "individual-local-identifier); 'none' for a single animal",
    )
    group.add_argument(
        "--time-col",
        help="time column (plain: time; movebank: timestamp); 'none' when the data have no times",
    )
    group.add_argument("--x-col", default="x", help="east coordinate column, m (plain)")
    group.add_argument("--y-col", default="y", help="north coordinate column, m (plain)")
    group.add_argument("--lon-col", default="location-long", help="longitude column (movebank)")
    group.add_argument("--lat-col", default="location-lat", help="latitude column (movebank)")
    group.add_argument("--tz", help="time zone of times written without an offset")
    group.add_argument(
        "--crs",
        default="utm",
        metavar="{utm,local,EPSG:NNNN}",
        help="projection of movebank lon/lat to metres: the UTM zone of the data's centre "
        "(default), 'local' (azimuthal equidistant about it) or the EPSG code of a projected "
        "CRS in metres (e.g. EPSG:32611)",
    )
    group.add_argument(
        "--missing",
        choices=("error", "drop", "keep"),
        default="error",
        help="rows with empty coordinates (Movebank exports hold many): refuse naming them "
        "(default), drop them (listed in the log; --regularise then interpolates across "
        "them), or keep them as missing fixes (their steps and angles missing)",
    )
    group.add_argument(
        "--max-gap", type=float, help="split tracks at gaps longer than this many seconds"
    )
    group.add_argument(
        "--regularise",
        type=float,
        metavar="SECONDS",
        help="resample each track to this time step (--regularise-method; tracks are split "
        "at gaps over --max-gap first)",
    )
    group.add_argument(
        "--regularise-method",
        choices=("linear", "crw"),
        default="linear",
        help="linear interpolation between fixes (hmmtrack.tracks.regularise; default) or the "
        "positions predicted by a continuous-time correlated random walk fitted to each "
        "track (hmmtrack.hmm.crw.regularise, R's crawl; adds sd_x, sd_y in m)",
    )
    group.add_argument(
        "--scale",
        type=float,
        default=1.0,
        help="length unit in metres of steps (1000 fits kilometres, as moveHMM's elk example)",
    )


def _column(value: str | None, default: str | None) -> str | None:
    if value is None:
        return default
    return None if value.lower() == "none" else value


def read_prepared(args: argparse.Namespace) -> pd.DataFrame:
    """Read, regularise (``--regularise``) and prepare the tracks named by
    :func:`add_track_arguments` options."""
    table = read_table(args)
    if args.regularise is not None:
        if args.regularise_method == "crw":
            table = crw.regularise(table, args.regularise)
        else:
            table = tracks.regularise(table, args.regularise, max_gap=args.max_gap)
    return tracks.prepare(table, scale=args.scale, max_gap=args.max_gap)


def read_table(args: argparse.Namespace) -> pd.DataFrame:
    """The tracks table of the file (:mod:`hmmtrack.io` readers), split at gaps over
    ``--max-gap`` when it is to be regularised (a ``segment`` column); ``--regularise``
    checked."""
    if args.format == "movebank":
        projection = args.crs
        if projection not in ("utm", "local"):
            try:
                projection = Projection.from_epsg(projection)
            except ValueError as exc:
                raise ValueError(f"--crs {args.crs}: {exc}") from None
        table = io.read_movebank(
            args.tracks,
            id_col=_column(args.id_col, "individual-local-identifier"),
            time_col=_column(args.time_col, "timestamp"),
            lon_col=args.lon_col,
            lat_col=args.lat_col,
            tz=args.tz or "UTC",
            projection=projection,
            missing_coordinates=args.missing,
        )
    else:
        if args.crs != "utm":
            raise ValueError("--crs projects lon/lat; it needs --format movebank")
        table = io.read_tracks(
            args.tracks,
            id_col=_column(args.id_col, "id"),
            time_col=_column(args.time_col, "time"),
            x_col=args.x_col,
            y_col=args.y_col,
            tz=args.tz,
            missing_coordinates=args.missing,
        )
    if args.regularise is None:
        if args.regularise_method != "linear":
            raise ValueError("--regularise-method needs --regularise SECONDS (the time step)")
        return table
    if not (math.isfinite(args.regularise) and args.regularise > 0):
        raise ValueError(
            f"--regularise must be a positive number of seconds, got {args.regularise}"
        )
    if "time" not in table.columns:
        raise ValueError("--regularise needs the fixes' times; the tracks have none (--time-col)")
    if args.max_gap is not None and args.regularise_method == "crw":
        table = tracks.split_at_gaps(table, args.max_gap)
    return table


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "fit",
        description="Fit an N-state movement HMM by EM with multi-start and save it as JSON.",
    )
    add_track_arguments(parser)
    parser.add_argument("--states", type=int, default=2, help="number of states (default 2)")
    parser.add_argument("--step", default="gamma", choices=sorted(distributions.STEP_FAMILIES))
    parser.add_argument("--angle", default="vonmises", choices=sorted(distributions.ANGLE_FAMILIES))
    parser.add_argument(
        "--fix-angle-mean", action="store_true", help="fix the turning-angle means at 0"
    )
    parser.add_argument(
        "--covariates",
        nargs="+",
        default=[],
        metavar="COLUMN",
        help="columns on the transition probabilities (standardised, multinomial logit); "
        "short for --formula 'transition ~ COLUMN + ...'",
    )
    parser.add_argument(
        "--formula",
        action="append",
        default=[],
        metavar="'PARAMETER ~ TERMS'",
        help="formula of the transition probabilities ('transition ~ cosT + sinT', "
        "'transition ~ C(season) + cos(2*pi*hour/24)') or of a parameter of a stream's "
        "distribution through its link ('step.mean ~ cosT + sinT', 'angle.concentration ~ "
        "x'); repeat for several. Columns of the track file; factors with C(), any numpy "
        "expression; coefficients printed also on the data's scale",
    )
    parser.add_argument(
        "--impute",
        type=int,
        metavar="M",
        help="multiple imputation: fit to M tracks drawn from each track's continuous-time "
        "correlated random walk on the --regularise grid (hmmtrack.hmm.crw.impute) and pool "
        "the fits by Rubin's rules (hmmtrack.hmm.imputation.fit_imputed); the model saved is "
        "the pooled one (no log-likelihood)",
    )
    parser.add_argument(
        "--stream",
        action="append",
        default=[],
        metavar="COLUMN=FAMILY",
        help="a further data stream: a column of the track file and its family ("
        + ", ".join(sorted(distributions.VALUE_FAMILIES))
        + "), e.g. depth=normal; repeat for several; NaN = missing",
    )
    parser.add_argument(
        "--fix",
        action="append",
        default=[],
        metavar="'PARAMETER=VALUE'",
        help="hold a parameter at a value (states from 1): 'step.mean[1]=50' (a stream's "
        "parameter, in the data's units), 'transition[1,2]=0.05' (a probability; with 3+ "
        "states fix the row's other off-diagonal entries too), 'transition.dist_water[1,2]=0' "
        "(a logit coefficient), 'initial[1]=1'; repeat for several; saved in the model file",
    )
    parser.add_argument(
        "--equal",
        action="append",
        default=[],
        metavar="'A==B'",
        help="hold two states' parameter equal: 'angle.concentration[1]==angle.concentration[2]'"
        " (a parameter with a formula ties its coefficients); repeat for several",
    )
    parser.add_argument(
        "--stationary",
        action="store_true",
        help="the initial distribution is the stationary distribution of the transition "
        "matrix (at each track segment's first-row covariates), not a parameter",
    )
    parser.add_argument(
        "--check-starts",
        type=int,
        metavar="N",
        help="fit from N starting values (instead of --starts) and print each start's "
        "log-likelihood, iterations and whether it reached the best optimum; with --plot "
        "also starts.png (log-likelihood per start, parameter spread)",
    )
    parser.add_argument("--starts", type=int, default=5, help="EM starts (default 5)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the starts (default 1)")
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="workers for the starts (threads for the fused EM, else processes)",
    )
    parser.add_argument("--level", type=float, default=0.95, help="confidence level")
    add_state_names_argument(parser)
    parser.add_argument("-o", "--output", required=True, help="model JSON file to write")
    parser.add_argument(
        "--plot",
        metavar="DIR",
        help="folder to write the standard figures in (densities, pseudo-residuals, decoded "
        "tracks per animal, transition and stationary probabilities against each covariate); "
        "created if absent",
    )
    parser.set_defaults(func=run)


def add_state_names_argument(parser: argparse.ArgumentParser) -> None:
    """``--state-names`` (shared by ``fit``, ``decode`` and ``plot``)."""
    parser.add_argument(
        "--state-names",
        type=lambda text: [name.strip() for name in text.split(",")],
        metavar="NAME,NAME",
        help="names of the states in order, state 1 (the smallest mean step) first, e.g. "
        "encamped,exploratory: shown in tables and figures (fit: saved in the model file; "
        "decode, plot: default the model file's names)",
    )


def check_state_names_option(n_states: int, names: list[str] | None) -> None:
    """Refuse ``--state-names`` that are not one distinct name per state."""
    try:
        check_state_names(n_states, names)
    except ValueError as exc:
        raise ValueError(f"--state-names: {exc}") from None


def write_figures(
    folder: str, model, prepared: pd.DataFrame, states, state_names, starts=None
) -> list[str]:
    """Draw :func:`hmmtrack.plots.hmm.hmm_figures` (and ``starts.png`` of a
    :func:`~hmmtrack.hmm.diagnostics.starts_table` ``starts``) and write them into ``folder``
    (created, written as one set: a failure leaves the previous set)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hmmtrack.plots.hmm import hmm_figures, starts_figure

    figures = hmm_figures(model, prepared, states, state_names)
    if starts is not None:
        figures["starts.png"] = starts_figure(starts)
    with staged_folder(folder, "densities.png") as stage:
        for name, figure in figures.items():
            figure.savefig(stage / name, dpi=110)
            plt.close(figure)
    return sorted(figures)


def parse_formulas(texts: list[str]) -> dict[str, str]:
    """``{parameter: "~ terms"}`` of ``--formula 'parameter ~ terms'`` options (a formula
    without a parameter is the transition probabilities').

    Raises
    ------
    ValueError
        For a formula without ``~`` or a parameter given twice.
    """
    out: dict[str, str] = {}
    for text in texts:
        target, tilde, terms = text.partition("~")
        target = target.strip() or "transition"
        if not tilde:
            raise ValueError(
                f"--formula {text!r}: expected 'PARAMETER ~ terms' ('transition ~ cosT', "
                "'step.mean ~ cosT + sinT')"
            )
        if target in out:
            raise ValueError(f"--formula: two formulas of {target!r}")
        out[target] = "~" + terms
    return out


def parse_fixed(texts: list[str]) -> dict[str, float]:
    """``{parameter: value}`` of ``--fix 'PARAMETER=VALUE'`` options.

    Raises
    ------
    ValueError
        For an option without ``=``, a value that is not a number or a parameter given
        twice.
    """
    out: dict[str, float] = {}
    for text in texts:
        name, equals, value = text.rpartition("=")
        name = name.strip()
        try:
            number = float(value)
        except ValueError:
            number = None
        if not equals or not name or name.endswith("=") or number is None:
            raise ValueError(
                f"--fix {text!r}: expected PARAMETER=NUMBER ('step.mean[1]=50', "
                "'transition[1,2]=0.05')"
            )
        if name in out:
            raise ValueError(f"--fix: {name!r} given twice")
        out[name] = number
    return out


def parse_streams(texts: list[str]) -> dict[str, str]:
    """``{column: family}`` of ``--stream COLUMN=FAMILY`` options.

    Raises
    ------
    ValueError
        For an option without ``=`` or a column given twice.
    """
    out: dict[str, str] = {}
    for text in texts:
        column, equals, family = text.partition("=")
        if not equals or not column.strip() or not family.strip():
            raise ValueError(f"--stream {text!r}: expected COLUMN=FAMILY (depth=normal)")
        if column.strip() in out:
            raise ValueError(f"--stream: two families of {column.strip()!r}")
        out[column.strip()] = family.strip()
    return out


def run(args: argparse.Namespace) -> int:
    check_paths({"tracks": args.tracks}, outputs={"-o": args.output}, folders={"--plot": args.plot})
    formulas = parse_formulas(args.formula)
    check_state_names_option(args.states, args.state_names)
    if args.check_starts is not None and args.check_starts < 1:
        raise ValueError(f"--check-starts must be a positive number, got {args.check_starts}")
    options = {
        "step": args.step,
        "angle": args.angle,
        "estimate_angle_mean": not args.fix_angle_mean,
        "covariates": tuple(args.covariates),
        "formulas": formulas,
        "streams": parse_streams(args.stream),
        "fixed": parse_fixed(args.fix),
        "equal": tuple(args.equal),
        "stationary": args.stationary,
        "state_names": args.state_names,
        "n_starts": args.starts if args.check_starts is None else args.check_starts,
        "n_jobs": args.jobs,
        "step_unit": tracks.length_unit(args.scale),
    }
    if args.impute is not None:
        return run_imputed(args, options)
    prepared = read_prepared(args)
    estimator = MovementHMMEstimator(n_states=args.states, seed=args.seed, **options)
    model = estimator.fit(prepared).model_
    intervals = diagnostics.confidence_intervals(model, prepared, level=args.level)
    starts = None
    if args.check_starts is not None:
        columns = diagnostics.coefficient_names(model)
        starts = diagnostics.starts_table(estimator.starts_, columns=columns)
    with atomic_files(args.output) as (written,):
        model.save(written)
        if args.plot:
            states = model.viterbi(prepared, allow_other_step=True)
            figures = write_figures(args.plot, model, prepared, states, args.state_names, starts)
    print(f"{args.tracks}: {len(prepared)} rows, {prepared['segment'].nunique()} segments")
    print(diagnostics.summary(model, intervals))
    if starts is None:
        values = ", ".join(f"{s.log_likelihood:.4f}" for s in estimator.starts_)
        print(f"starts (log-likelihood after EM): {values}")
    else:
        print(_starts_summary(starts))
    print(f"wrote {args.output}")
    if args.plot:
        print(f"wrote {', '.join(figures)} in {args.plot}")
    return 0


def _starts_summary(starts: pd.DataFrame) -> str:
    """The ``--check-starts`` report: how many starts reached the best optimum, then each
    start's log-likelihood, iterations and convergence."""
    best = starts.loc[starts["best"], "log_likelihood"]
    head = (
        f"check of starting values: {len(best)} of {len(starts)} starts reached the best "
        f"log-likelihood {best.max():.5f} (within 1e-3)"
    )
    shown = starts[["start", "log_likelihood", "n_iter", "converged", "best", "error"]]
    return head + "\n" + shown.to_string(index=False, float_format=lambda v: f"{v:.5f}")


def run_imputed(args: argparse.Namespace, options: dict) -> int:
    """``fit --impute M``: fit to M imputed tracks, pool by Rubin's rules, save the pool."""
    if args.impute < 1:
        raise ValueError(f"--impute must be a positive number of imputed tracks, got {args.impute}")
    if args.regularise is None:
        raise ValueError("--impute M draws tracks on a regular grid: give --regularise SECONDS")
    if args.plot:
        raise ValueError(
            "--plot with --impute: the figures' bands would ignore the imputation; fit without "
            "--impute (e.g. --regularise-method crw) or draw with hmmtrack plot"
        )
    table = read_table(args)
    draws = crw.impute(table, args.regularise, args.impute, np.random.default_rng(args.seed))
    imputed = [tracks.prepare(draw, scale=args.scale) for draw in draws]
    result = imputation.fit_imputed(imputed, args.states, seed=args.seed, **options)
    with atomic_files(args.output) as (written,):
        result.model.save(written)
    print(
        f"{args.tracks}: {args.impute} tracks imputed on a {args.regularise:g} s grid, "
        f"{len(imputed[0])} rows each"
    )
    print(diagnostics.summary(result.model))
    print("pooled working-scale estimates (Rubin's rules):")
    print(imputation.pooled_table(result).to_string(float_format=lambda v: f"{v:.6g}"))
    print(f"wrote {args.output}")
    return 0
