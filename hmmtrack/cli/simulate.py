"""``hmmtrack simulate``: write one of the paper-like synthetic datasets as files.

Writes ``detections.csv``, ``receivers.csv``, ``truth.csv`` and ``scenario.json`` (the
tracker's settings of the scenario: period, r0, bounds, sound speed, time window; a
``--config`` file of ``hmmtrack track``) into a directory, the inputs ``hmmtrack track``
reads, so that the tracker can be tried on our analogues of the paper's datasets.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hmmtrack.experiments.configs import scenario_settings
from hmmtrack.io.outputs import check_paths, staged_folder
from hmmtrack.scenarios import GENERATORS
from hmmtrack.scenarios.export import FILE_NAMES, write_scenario


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="write a synthetic dataset (detections, receivers, truth, settings)",
        description=(
            "Simulate one of the paper's three datasets (synthetic analogues) and write "
            "detections.csv, receivers.csv, truth.csv and scenario.json into a directory."
        ),
    )
    parser.add_argument("scenario", choices=sorted(GENERATORS), help="which dataset")
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
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.dive and args.scenario != "shark-pursuit":
        raise ValueError("--dive applies to shark-pursuit only")
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
