"""``hmmtrack plot``: the standard figures of a fitted model on tracks, after the fact.

Example::

    hmmtrack plot model.json data/example_tracks.csv -o figures/

reads and prepares the tracks with the options of ``hmmtrack fit`` (use the same ones, and
the same ``--scale``), decodes them with the model file and writes the figures of
:func:`hmmtrack.plots.hmm.hmm_figures` into the folder: ``densities.png`` (step densities on a
linear and a log axis, turning angles), ``residuals.png`` (pseudo-residuals in track order, QQ
plot and ACF per stream), ``tracks.png`` (decoded tracks, one panel per animal) and, for
each variable of the transition formula, ``transition_<variable>.png`` and
``stationary_<variable>.png`` with 95 % bands (the bands assume the tracks are the ones the
model was fitted to).
"""

from __future__ import annotations

import argparse

from hmmtrack.cli import add_command
from hmmtrack.cli.decode import add_other_step_argument, load_model_for
from hmmtrack.cli.fit import (
    add_state_names_argument,
    add_track_arguments,
    check_state_names_option,
    read_prepared,
    write_figures,
)
from hmmtrack.io.outputs import check_paths


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "plot",
        description="Draw the standard figures of a fitted movement HMM (model JSON from "
        "hmmtrack fit) on tracks.",
    )
    parser.add_argument("model", help="model JSON file (hmmtrack fit -o)")
    add_track_arguments(parser)
    add_other_step_argument(parser)
    add_state_names_argument(parser)
    parser.add_argument(
        "-o", "--output", required=True, metavar="DIR", help="folder to write the figures in"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    check_paths({"model": args.model, "tracks": args.tracks}, folders={"-o": args.output})
    model = load_model_for(args)
    check_state_names_option(model.n_states, args.state_names)
    prepared = read_prepared(args)
    states = model.viterbi(prepared, allow_other_step=args.allow_other_step)
    names = args.state_names or model.state_names
    figures = write_figures(args.output, model, prepared, states, names)
    print(f"wrote {', '.join(figures)} in {args.output}")
    return 0
