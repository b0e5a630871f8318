"""``hmmtrack simulate``: write one of the paper-like synthetic datasets as files.

Writes ``detections.csv``, ``receivers.csv``, ``truth.csv`` and ``scenario.json`` (the
tracker's settings of the scenario: period, r0, bounds, sound speed, time window; a
``--config`` file of ``hmmtrack track``) into a directory, the inputs ``hmmtrack track``
reads, so that the tracker can be tried on our analogues of the paper's datasets.

``hmmtrack simulate moored-array --burst-interval 20 40 -o DIR`` writes a moored array with
unsynchronised receiver clocks, sync tags and a tag on a pseudo-random burst interval, the
inputs of ``hmmtrack sync`` and of tracking with its clock file
(:func:`hmmtrack.scenarios.export.write_tagged_array`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hmmtrack.cli import add_command
from hmmtrack.experiments.configs import scenario_settings
from hmmtrack.io.outputs import check_paths, staged_folder
from hmmtrack.scenarios import GENERATORS
from hmmtrack.scenarios.array import tagged_array
from hmmtrack.scenarios.export import (
    ARRAY_FILE_NAMES,
    FILE_NAMES,
    write_scenario,
    write_tagged_array,
)

#: the moored array with sync tags and a random-interval tag (:func:`tagged_array`)
ARRAY = "moored-array"


def register(subparsers) -> None:
    parser = add_command(
        subparsers,
        "simulate",
        description=(
            "Simulate one of the paper's three datasets (synthetic analogues) and write "
            "detections.csv, receivers.csv, truth.csv and scenario.json into a directory; "
            f"or '{ARRAY}': a moored array with unsynchronised clocks, sync tags and a tag on "
            "a pseudo-random burst interval (also receivers_truth.csv, emissions.csv and "
            "burst_sequence.csv)."
        ),
    )
    parser.add_argument("scenario", choices=[*sorted(GENERATORS), ARRAY], help="which dataset")
    parser.add_argument("--seed", type=int, required=True, help="random seed (int)")
    parser.add_argument("-o", "--out", required=True, help="output directory")
    parser.add_argument(
        "--dive",
        action="store_true",
        help="shark-pursuit only: a diving shark with a depth-sensor tag (depth column)",
    )
    parser.add_argument(
        "--plot", action="store_true", help="also write overview.png (paths seen from above)"
    )
    parser.add_argument(
        "--burst-interval",
        type=float,
        nargs=2,
        metavar=("MIN", "MAX"),
        help=f"{ARRAY} only: the tag's burst interval range (s; default 20 40, equal: fixed)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.dive and args.scenario != "shark-pursuit":
        raise ValueError("--dive applies to shark-pursuit only")
    if args.scenario == ARRAY:
        return run_array(args)
    if args.burst_interval is not None:
        raise ValueError(f"--burst-interval applies to {ARRAY} only")
    check_paths(folders={"-o": args.out})
    generator = GENERATORS[args.scenario]
    scenario = generator(args.seed, dive=True) if args.dive else generator(args.seed)
    with staged_folder(args.out, last=FILE_NAMES["metadata"]) as stage:
        names = {
            key: path.name
            for key, path in write_scenario(scenario, stage, scenario_settings(scenario)).items()
        }
        if args.plot:
            import matplotlib

            matplotlib.use("Agg")
            from hmmtrack.plots.experiments import plot_scenario

            names["overview"] = "overview.png"
            figure = plot_scenario(scenario).figure
            figure.savefig(stage / names["overview"], dpi=120, bbox_inches="tight")
    paths = {key: Path(args.out) / name for key, name in names.items()}
    n_receivers = scenario.receivers["receiver"].nunique()
    print(
        f"{scenario.name}: {len(scenario.detections)} detections at {n_receivers} receivers "
        f"over {scenario.end - scenario.start:.0f} s"
    )
    for path in paths.values():
        print(f"  wrote {path}")
    return 0


def run_array(args: argparse.Namespace) -> int:
    """``hmmtrack simulate moored-array``: a 4 x 4 array over 12 h, the tag tracked 2 h."""
    if args.plot:
        raise ValueError(f"--plot does not apply to {ARRAY}")
    check_paths(folders={"-o": args.out})
    case = tagged_array(
        args.seed,
        burst_interval=tuple(args.burst_interval or (20.0, 40.0)),
        duration=43200.0,
        echo_fraction=0.01,
    )
    with staged_folder(args.out, last=ARRAY_FILE_NAMES["metadata"]) as stage:
        names = {key: path.name for key, path in write_tagged_array(case, stage).items()}
    heard = int(case.pings["detected"].sum())
    print(
        f"{ARRAY}: {len(case.detections)} detections at {len(case.array.receivers)} receivers "
        f"over {case.array.end - case.array.start:.0f} s; tag {case.transmitter}: "
        f"{case.emission_times.size} pings, {heard} heard"
    )
    for name in names.values():
        print(f"  wrote {Path(args.out) / name}")
    return 0
