"""Generate ``data/example_tracks.csv``, the small bundled example of animal tracks.

Run from the repository root (the output is identical for the same seed)::

    python data/make_example_tracks.py            # writes data/example_tracks.csv

The movement model (2 behavioural states, a Markov chain over fixes):

* fix times: irregular, the interval to the next fix uniform on 60..180 s (whole seconds);
* state at each fix: 1 = resident, 2 = transit; transition matrix per fix interval
  ``[[0.96, 0.04], [0.06, 0.94]]``, first state drawn from its stationary distribution
  ``(0.6, 0.4)``;
* speed over the interval (m/s): gamma with mean / sd 0.15 / 0.10 (resident, slow) and
  1.0 / 0.25 (transit, about 1 m/s); the step is speed x interval;
* turning angle at each fix (rad): von Mises about 0 with concentration 0.5 (resident,
  tortuous) and 8 (transit, directed).

Three animals (``shark-1``..``shark-3``) of 1,500 simulated fixes each, starting at
2024-06-01 00:00 UTC plus 0, 20 and 40 minutes from different points. ``shark-2`` loses
its tag signal for three hours in the middle: the fixes in that window are removed, so the
track splits there at any ``max_gap`` below three hours. Columns: ``id``, ``time`` (ISO 8601
UTC), ``x``, ``y`` (m, local east / north), and ``true_state`` (the simulated state, for
checking decoding; it is not a covariate).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io import format_times
from hmmtrack.random import as_generator

SEED = 20240601
START = pd.Timestamp("2024-06-01T00:00:00Z").timestamp()
N_FIXES = 1500
TRANSITION = np.array([[0.96, 0.04], [0.06, 0.94]])
STATIONARY = np.array([0.6, 0.4])
SPEED_MEAN = np.array([0.15, 1.0])  # m/s
SPEED_SD = np.array([0.10, 0.25])  # m/s
TURN_CONCENTRATION = np.array([0.5, 8.0])
GAP = ("shark-2", 30 * 3600.0, 33 * 3600.0)  # animal, gap start and end (s after its start)


def simulate_animal(rng: np.random.Generator, n: int, start: float, origin: tuple[float, float]):
    """Simulate one animal's fixes.

    Returns
    -------
    time : ndarray, shape (n,)
        UTC seconds.
    x, y : ndarray, shape (n,)
        Metres.
    state : ndarray, shape (n,)
        0 (resident) or 1 (transit).
    """
    interval = rng.integers(60, 181, size=n - 1).astype(float)
    state = np.empty(n, dtype=int)
    state[0] = rng.choice(2, p=STATIONARY)
    for k in range(1, n):
        state[k] = rng.choice(2, p=TRANSITION[state[k - 1]])
    shape = (SPEED_MEAN / SPEED_SD) ** 2
    scale = SPEED_SD**2 / SPEED_MEAN
    speed = rng.gamma(shape[state[:-1]], scale[state[:-1]])
    turn = rng.vonmises(0.0, TURN_CONCENTRATION[state[:-1]])
    heading = rng.uniform(-np.pi, np.pi) + np.cumsum(turn)
    step = speed * interval
    x = origin[0] + np.r_[0.0, np.cumsum(step * np.cos(heading))]
    y = origin[1] + np.r_[0.0, np.cumsum(step * np.sin(heading))]
    time = start + np.r_[0.0, np.cumsum(interval)]
    return time, x, y, state


def make_tracks(seed: int = SEED) -> pd.DataFrame:
    """The example tracks table (times in UTC seconds), as written by :func:`main`."""
    rng = as_generator(seed)
    frames = []
    for k in range(3):
        name = f"shark-{k + 1}"
        start = START + k * 1200.0
        time, x, y, state = simulate_animal(rng, N_FIXES, start, (2000.0 * k, -1500.0 * k))
        keep = np.ones(N_FIXES, dtype=bool)
        if name == GAP[0]:
            keep = ~((time - start > GAP[1]) & (time - start < GAP[2]))
        frames.append(
            pd.DataFrame({"id": name, "time": time, "x": x, "y": y, "true_state": state + 1}).loc[
                keep
            ]
        )
    return pd.concat(frames, ignore_index=True)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument(
        "-o", "--output", type=Path, default=Path(__file__).resolve().parent / "example_tracks.csv"
    )
    args = parser.parse_args(argv)
    table = make_tracks(args.seed)
    table["time"] = format_times(table["time"].to_numpy())
    table["x"] = table["x"].round(1)
    table["y"] = table["y"].round(1)
    table.to_csv(args.output, index=False)
    print(f"wrote {len(table)} fixes of {table['id'].nunique()} animals to {args.output}")


if __name__ == "__main__":
    main()
