"""Lost shark-pursuit runs by motion model and particle count, with an oracle:
the HMM filter given the very model that drew the synthetic shark (reports/decisions.md,
"Session 22 lead: which lost runs any filter would lose").

Each run is one filter run of the reproduction's shark-pursuit trial (mode-keeping filter,
``range-rate-gps``, the start region, no acquisition) on dataset ``d`` of experiment seed
``s`` (:func:`hmmtrack.experiments.paper_datasets`), filter seed ``(0, 2, j, 100 + k)`` of the
experiment seed on dataset 0 and ``(4, 2, j, d, 100 + k)`` on dataset ``d`` (``j`` the
model's index, ``k`` the run): apart from the reproduction's own trial seeds. Motions:
``velocity`` and ``hmm`` are the reproduction's; ``truth`` is the HMM motion model built from
:data:`hmmtrack.scenarios.shark_motion.WHITE_SHARK_GROUND_TRUTH` (the synthetic shark's own
states, steps and turns) with the fitted model's filter settings, ``--heading-diffusion``
replacing its heading random walk. ``run`` appends a row per filter run to a CSV:

    python reports/mirror_losses.py run OUT.csv --seeds 165-194 --motions velocity truth
    python reports/mirror_losses.py run OUT.csv --pairs 168:4 190:0 --motions truth \\
        --particles 8000 --heading-diffusion 0.02

``summary`` prints, per motion, particle count and heading diffusion: runs, lost runs
(mean error after convergence above 50 m, or none), the false-converged share, and each
dataset with a lost run as a pattern of its runs (``L`` lost, ``.`` kept):

    python reports/mirror_losses.py summary OUT.csv
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.experiments import PAPER_SCENARIOS, paper_datasets
from hmmtrack.experiments.trials import (
    HMM_VARIANT,
    MOTIONS,
    child_seed,
    experiment_seed,
    run_trial,
)
from hmmtrack.hmm import Gamma, MovementHMM, VonMises
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH
from hmmtrack.tracking.config import measurement_motion
from hmmtrack.tracking.motion.settings import HMMSettings

SCENARIO = "shark_pursuit"
MEASUREMENT = "range-rate-gps"
#: a run is lost above this mean error after convergence (m)
LOST = 50.0
GROUPS = ["motion", "particles", "heading_diffusion"]


def ground_truth_hmm() -> MovementHMM:
    """The synthetic shark's own movement model as a :class:`MovementHMM` (60 s steps)."""
    truth = WHITE_SHARK_GROUND_TRUTH
    return MovementHMM(
        truth.initial,
        truth.transition,
        Gamma(mean=truth.step_mean, sd=truth.step_sd),
        VonMises(mean=np.zeros(truth.initial.size), concentration=truth.angle_concentration),
        dt=truth.dt,
        state_names=truth.state_names,
    )


def truth_motion(heading_diffusion: float | None):
    """The HMM motion model of :func:`ground_truth_hmm` under ``range-rate-gps``."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "truth.json"
        ground_truth_hmm().save(path)
        settings = HMMSettings(
            model=str(path), variant=HMM_VARIANT, heading_diffusion=heading_diffusion
        )
        return measurement_motion(settings, MEASUREMENT)


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def _datasets(args) -> list[tuple[int, int]]:
    pairs = [(s, d) for s in _seeds(args.seeds) for d in range(args.datasets)] if args.seeds else []
    return pairs + [tuple(map(int, p.split(":"))) for p in args.pairs]


def _one_run(scenario, name: str, motion, seed, args) -> dict:
    trial = run_trial(
        scenario,
        "hmm" if name == "truth" else name,
        seed,
        args.particles,
        start_prior=True,
        filter="mode-keeping",
        measurement=MEASUREMENT,
        motion=motion,
    )
    return {
        "error": trial.mean_error_after_convergence,
        "false_converged": trial.false_converged,
        "calibration": trial.calibration,
        "mirror_share": trial.mirror_share,
        "runtime_s": trial.runtime,
    }


def run(args) -> None:
    motions = {
        name: truth_motion(args.heading_diffusion) if name == "truth" else None
        for name in args.motions
    }
    i = PAPER_SCENARIOS.index(SCENARIO)
    for seed, d in _datasets(args):
        root = experiment_seed(seed)
        scenario = paper_datasets(seed, d + 1, names=[SCENARIO])[SCENARIO][d]
        rows = []
        for name, motion in motions.items():
            j = MOTIONS.index("hmm" if name == "truth" else name)
            for k in range(args.runs):
                key = (0, i, j, 100 + k) if d == 0 else (4, i, j, d, 100 + k)
                rows.append(
                    {"seed": seed, "dataset": d, "run": k, "motion": name,
                     "particles": args.particles,
                     "heading_diffusion": args.heading_diffusion if name == "truth" else np.nan}
                    | _one_run(scenario, name, motion, child_seed(root, *key), args)
                )  # fmt: skip
        table = pd.DataFrame(rows)
        table.to_csv(args.out, mode="a", header=not os.path.exists(args.out), index=False)
        print(f"seed {seed} dataset {d}: {table['error'].round(1).tolist()}", flush=True)


def summary(args) -> None:
    table = pd.concat([pd.read_csv(path) for path in args.tables], ignore_index=True)
    table["lost"] = ~(table["error"] <= LOST)
    for key, group in table.groupby(GROUPS, dropna=False):
        print(
            dict(zip(GROUPS, key, strict=True)),
            f"runs {len(group)}, lost {int(group['lost'].sum())}, "
            f"false converged {100 * group['false_converged'].mean():.3f} %",
        )
        for (seed, d), runs in group.groupby(["seed", "dataset"]):
            if runs["lost"].any():
                pattern = "".join("L" if lost else "." for lost in runs.sort_values("run")["lost"])
                print(f"    {seed}/{d}: {pattern}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    runner = commands.add_parser("run", help="append filter runs to a CSV")
    runner.add_argument("out")
    runner.add_argument("--seeds", default="", help="experiment seeds, e.g. 165-194")
    runner.add_argument("--datasets", type=int, default=6, help="datasets 0..D-1 per seed")
    runner.add_argument("--pairs", nargs="*", default=[], help="seed:dataset pairs")
    runner.add_argument("--runs", type=int, default=4, help="filter runs per dataset")
    runner.add_argument(
        "--motions", nargs="+", default=["velocity", "hmm", "truth"],
        choices=["velocity", "hmm", "truth"],
    )  # fmt: skip
    runner.add_argument("--particles", type=int, default=1000)
    runner.add_argument("--heading-diffusion", type=float, default=None)
    commands.add_parser("summary", help="lost runs per setting").add_argument("tables", nargs="+")
    args = parser.parse_args()
    {"run": run, "summary": summary}[args.command](args)


if __name__ == "__main__":
    main()
