"""``hmmtrack decode``: most probable states and state probabilities of tracks under a model.

Example::

    hmmtrack decode data/example_tracks.csv --model model.json -o states.csv

reads and prepares the tracks with the same options as ``hmmtrack fit``, loads the model file,
refuses tracks whose time step is not the model's (``--regularise`` the tracks to it, or pass
``--allow-other-step``) and writes :func:`hmmtrack.hmm.decoding.decode_table`: one row per row
of the track file, in file order (``line`` = its line in the file), the track columns,
``segment``, ``step``, ``angle``, the Viterbi ``state`` (1 = the state with the smallest mean
step, as moveHMM numbers them; empty for rows without a fix removed by ``--missing drop``),
``state_name`` (with ``--state-names`` or names in the model file) and ``p_state1`` ...
``p_stateK`` (posterior probabilities). With ``--regularise`` the rows are the regular grid's
instead. Times are written as ISO 8601 UTC; lengths (``x``, ``y``, ``step``) are in the unit
set by ``--scale`` (metres by default), as the model was fitted.
"""

from __future__ import annotations

import argparse

import numpy as np

from hmmtrack import io, tracks
from hmmtrack.cli import add_command
from hmmtrack.cli.fit import (
    add_state_names_argument,
    add_track_arguments,
    check_state_names_option,
    read_prepared,
)
from hmmtrack.hmm import MovementHMM
from hmmtrack.hmm.decoding import decode_table
from hmmtrack.io.outputs import atomic_files, check_paths


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "decode",
        description="Decode tracks with a fitted movement HMM (model JSON from hmmtrack fit).",
    )
    add_track_arguments(parser)
    parser.add_argument("--model", required=True, help="model JSON file (hmmtrack fit -o)")
    add_other_step_argument(parser)
    add_state_names_argument(parser)
    parser.add_argument("-o", "--output", required=True, help="CSV file to write")
    parser.set_defaults(func=run)


def add_other_step_argument(parser: argparse.ArgumentParser) -> None:
    """``--allow-other-step`` (shared by ``decode`` and ``plot``)."""
    parser.add_argument(
        "--allow-other-step",
        action="store_true",
        help="decode tracks whose time step differs from the model's by more than 10 %% "
        "(refused by default: steps over another duration are other quantities)",
    )


def load_model_for(args: argparse.Namespace) -> MovementHMM:
    """The ``--model`` file, refused when fitted to steps in another unit than ``--scale``."""
    model = MovementHMM.load(args.model)
    if model.step_unit != tracks.length_unit(args.scale):
        raise ValueError(
            f"{args.model} was fitted to steps in {model.step_unit}; --scale {args.scale:g} gives "
            f"{tracks.length_unit(args.scale)} (pass the --scale used with hmmtrack fit)"
        )
    return model


def calendar_times(seconds: np.ndarray) -> np.ndarray:
    """ISO 8601 UTC text of epoch seconds (shape (n,)); empty (None) where a time is NaN."""
    text = np.full(seconds.size, None, dtype=object)
    known = np.isfinite(seconds)
    text[known] = io.format_times(seconds[known])
    return text


def run(args: argparse.Namespace) -> int:
    check_paths({"tracks": args.tracks, "--model": args.model}, outputs={"-o": args.output})
    model = load_model_for(args)
    check_state_names_option(model.n_states, args.state_names)
    names = args.state_names or model.state_names
    prepared = read_prepared(args)
    out = decode_table(model, prepared, state_names=names, allow_other_step=args.allow_other_step)
    if "time" in out.columns:
        out["time"] = calendar_times(out["time"].to_numpy(dtype=float))
    with atomic_files(args.output) as (written,):
        out.to_csv(written, index=out.index.name == "line")
    counts = out["state"].value_counts().sort_index()
    listed = ", ".join(
        f"state {k}" + (f" ({names[k - 1]})" if names else "") + f": {n}" for k, n in counts.items()
    )
    print(f"{args.tracks}: {len(out)} rows decoded ({listed}); wrote {args.output}")
    return 0
