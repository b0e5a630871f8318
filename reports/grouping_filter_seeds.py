"""Grouped pings against the arrival-time filter on the moored array, each over three filter
seeds per dataset (reports/decisions.md, "Never worse, judged over three filter seeds").

``run`` appends one dataset's rows at a time to a CSV (a stopped run keeps what it finished):

    python reports/grouping_filter_seeds.py run OUT.csv --seeds 130-145 --radii 1.1 1.45
    python reports/grouping_filter_seeds.py run OUT.csv --pairs 112:1.1 56:1.2 \\
        --methods "grouped pings" --label "grouped pings, uniform outlier"

``--label`` renames the method in the rows: run from another checkout (``PYTHONPATH``) to
measure that code's grouped filter on the same datasets and filter seeds. ``summary`` reads
any number of such CSVs and prints each labelled grouped method against arrival-time
(:func:`hmmtrack.experiments.grouping.filter_seed_summary`):

    python reports/grouping_filter_seeds.py summary OUT.csv BEFORE.csv
"""

from __future__ import annotations

import argparse
import os

import pandas as pd

from hmmtrack.experiments.grouping import FILTER_OFFSETS, filter_seed_summary, share_sweep

BASELINE = "arrival-time"


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def run(args) -> None:
    pairs = [(s, r) for s in _seeds(args.seeds) for r in args.radii] if args.seeds else []
    pairs += [(int(s), float(r)) for s, r in (p.split(":") for p in args.pairs)]
    for seed, radii in pairs:
        rows = share_sweep([seed], [radii], methods=args.methods, filter_offsets=FILTER_OFFSETS)
        if args.label:
            rows["method"] = rows["method"].replace("grouped pings", args.label)
        if os.path.exists(args.out):
            columns = list(pd.read_csv(args.out, nrows=0).columns)
            if list(rows.columns) != columns:
                raise SystemExit(f"{args.out} has other columns (older code?): use a new file")
        rows.to_csv(args.out, mode="a", header=not os.path.exists(args.out), index=False)
        print(rows[["scenario", "seed", "filter_seed", "method", "error_after_10_min_m"]])


def summary(args) -> None:
    rows = pd.concat([pd.read_csv(path) for path in args.csv], ignore_index=True)
    for method in rows["method"].unique():
        if method == BASELINE:
            continue
        per_dataset, pooled = filter_seed_summary(rows, method, BASELINE)
        print(f"\n## {method} against {BASELINE}\n")
        print(per_dataset.round(3).to_string(index=False))
        print({k: round(v, 3) if isinstance(v, float) else v for k, v in pooled.items()})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(required=True)
    runs = commands.add_parser("run")
    runs.add_argument("out")
    runs.add_argument("--seeds", help="a seed or a range FIRST-LAST")
    runs.add_argument("--radii", type=float, nargs="+", default=[1.1, 1.45])
    runs.add_argument("--pairs", nargs="*", default=[], help="SEED:RADII datasets")
    runs.add_argument("--methods", nargs="+", default=[BASELINE, "grouped pings"])
    runs.add_argument("--label", help="the grouped method's name in the rows")
    runs.set_defaults(command=run)
    summaries = commands.add_parser("summary")
    summaries.add_argument("csv", nargs="+")
    summaries.set_defaults(command=summary)
    args = parser.parse_args()
    args.command(args)


if __name__ == "__main__":
    main()
