"""``hmmtrack decode``: most probable states and state probabilities of tracks under a model.

Example::

    hmmtrack decode data/example_tracks.csv --model model.json -o states.csv

reads and prepares the tracks with the same options as ``hmmtrack fit``, loads the model file,
refuses tracks whose time step is not the model's (``--regularise`` the tracks to it, or pass
``--allow-other-step``) and writes one row per fix: the track columns, ``segment``, ``step``,
``angle``, the Viterbi ``state`` (1 = the state with the smallest mean step, as moveHMM numbers
them) and ``p_state1`` ... ``p_stateK`` (posterior probabilities). Times are written as ISO 8601
UTC; lengths (``x``, ``y``, ``step``) are in the unit set by ``--scale`` (metres by default), as the
model was fitted.
"""

from __future__ import annotations

import argparse

import numpy as np

from hmmtrack import io
from hmmtrack.cli.fit import add_track_arguments, read_prepared, step_unit
from hmmtrack.hmm import MovementHMM
from hmmtrack.io.outputs import atomic_files, check_paths


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "decode",
        help="Viterbi states and state probabilities of tracks under a fitted model",
        description="Decode tracks with a fitted movement HMM (model JSON from hmmtrack fit).",
    )
    add_track_arguments(parser)
    parser.add_argument("--model", required=True, help="model JSON file (hmmtrack fit -o)")
    parser.add_argument(
        "--allow-other-step",
        action="store_true",
        help="decode tracks whose time step differs from the model's by more than 10 %% "
        "(refused by default: steps over another duration are other quantities)",
    )
    parser.add_argument("-o", "--output", required=True, help="CSV file to write")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    check_paths({"tracks": args.tracks, "--model": args.model}, outputs={"-o": args.output})
    model = MovementHMM.load(args.model)
    if model.step_unit != step_unit(args.scale):
        raise ValueError(
            f"{args.model} was fitted to steps in {model.step_unit}; --scale {args.scale:g} gives "
            f"{step_unit(args.scale)} (pass the --scale used with hmmtrack fit)"
        )
    prepared = read_prepared(args)
    states = model.viterbi(prepared, allow_other_step=args.allow_other_step)
    probabilities = model.state_probabilities(prepared, allow_other_step=True)
    out = prepared.copy()
    out["state"] = states + 1
    for k in range(model.n_states):
        out[f"p_state{k + 1}"] = probabilities[:, k]
    if "time" in out.columns:
        out["time"] = io.format_times(out["time"].to_numpy())
    with atomic_files(args.output) as (written,):
        out.to_csv(written, index=False)
    counts = ", ".join(
        f"state {k + 1}: {n}" for k, n in enumerate(np.bincount(states, minlength=model.n_states))
    )
    print(f"{args.tracks}: {len(out)} rows decoded ({counts}); wrote {args.output}")
    return 0
