"""Hashes of seeded tracking runs: the check that a speed change left every answer as it was.

Two sets of runs, each on threads forced to 1 and to 2 (the compiled paths must give the same
bits on any number of threads, and the same bits before and after a change):

* ``bench``: ``bench_filter``'s workload (300 s, seed 7) with the velocity model and the three
  HMM variants (paper, time-consistent, the 60 s default) at 10,000 and 60,000 particles, the
  paper's multinomial resampling after every correction; hashed are the estimates and the
  final particles' x and behavioural state;
* ``swim``: the swimmer scenario (dataset 0, seed 3) through ``pipeline.track`` with the
  paper's and the mode-keeping filter, velocity and HMM motion, at 10,000 particles
  (multinomial) and 60,000 (systematic and multinomial); hashed are the estimates.

Run: ``python benchmarks/run_hashes.py [bench|swim|all] > hashes.txt`` before and after a
change (from the repository root with ``PYTHONPATH=.``, a fresh ``NUMBA_CACHE_DIR`` after
editing compiled code) and ``diff`` the two files. One line per run: its name and hash.
"""

from __future__ import annotations

import argparse
import hashlib
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import bench_filter as bf
import numpy as np

from hmmtrack import scenarios
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.tracking import pipeline
from hmmtrack.tracking.filter import ParticleFilter
from hmmtrack.tracking.motion import HMMMotion, VelocityMotion, motion_model

THREADS = (1, 2)


def digest(array: np.ndarray) -> str:
    """First 12 hex digits of the SHA-1 of an array's bytes."""
    return hashlib.sha1(np.ascontiguousarray(array).tobytes()).hexdigest()[:12]


@contextmanager
def forced_threads(threads: int) -> Iterator[None]:
    """Every :class:`ParticleFilter` made in this block runs on ``threads`` threads (the
    pipeline builds its filter itself and has no thread option)."""
    init = ParticleFilter.__init__

    def forced(self, *args, **kwargs):
        init(self, *args, **{**kwargs, "threads": threads})

    ParticleFilter.__init__ = forced
    try:
        yield
    finally:
        ParticleFilter.__init__ = init


def bench_runs() -> Iterator[tuple[str, str]]:
    """``bench_filter``'s workload: (name, hash of the estimates, x and state)."""
    obs = bf.observations(300.0)
    models = {
        "velocity": VelocityMotion(sigma_speed=0.05, sigma_turn_rate=0.02),
        "hmm-paper": HMMMotion(bf.shark_model(), "paper"),
        "hmm-tc": HMMMotion(bf.shark_model(), "time_consistent"),
        "hmm-default": motion_model("hmm"),
    }
    for name, motion in models.items():
        for n in (10_000, 60_000):
            for threads in THREADS:
                pf = ParticleFilter(motion, bf.MEASUREMENT, n, bf.BOUNDS, rng=7, threads=threads)
                estimates = pf.run(obs, start=0.0, end=300.0).estimates.to_numpy(dtype=float)
                p = pf.particles
                yield (
                    f"bench {name} {n} t{threads}",
                    f"{digest(estimates)} {digest(p.x)}{digest(p.state)}",
                )


def swimmer_runs() -> Iterator[tuple[str, str]]:
    """The swimmer through ``pipeline.track``: (name, hash of the estimates)."""
    scenario = scenarios.swimmer(0)
    for filter_name in ("paper", "mode-keeping"):
        for motion_name in ("velocity", "hmm"):
            for n, resampling in ((10_000, "multinomial"), (60_000, "systematic"),
                                  (60_000, "multinomial")):  # fmt: skip
                for threads in THREADS:
                    config = tracking_config(
                        scenario, n_particles=n, filter=filter_name, resampling=resampling
                    )
                    with forced_threads(threads):
                        result = pipeline.track(
                            scenario.detections, scenario.receivers, config,
                            motion_model(motion_name), seed=3,
                        )  # fmt: skip
                    yield (
                        f"swim {filter_name} {motion_name} {n} {resampling} t{threads}",
                        digest(result.estimates.to_numpy(dtype=float)),
                    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("which", nargs="?", choices=("bench", "swim", "all"), default="all")
    which = parser.parse_args().which
    warnings.simplefilter("ignore")
    runs = []
    if which in ("bench", "all"):
        runs.append(bench_runs())
    if which in ("swim", "all"):
        runs.append(swimmer_runs())
    for run in runs:
        for name, value in run:
            print(name, value, flush=True)


if __name__ == "__main__":
    main()
