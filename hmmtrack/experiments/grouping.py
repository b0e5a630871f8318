"""A fixed-period tag tracked with its pings grouped, against the arrival-time filter, on the
clock-aware cases.

The arrival-time filter (:mod:`hmmtrack.tracking.measurement.clocked`, the clock-aware
study's method, :mod:`hmmtrack.experiments.arrival`) scores a tag's detections one after
the other against a clock carried by every particle. Grouped, the same detections are the
pings of the ``"ping-sequence"`` measurement (:mod:`hmmtrack.tracking.measurement.sequence`)
given the tag's period (a sequence of one interval, with the arrival-time clock model's
random walk): each ping's arrivals are scored jointly, its emission time integrated out
against the particle's clock. :func:`grouping_rows` runs both on the same detections of the
clock-aware cases (:func:`hmmtrack.experiments.arrival.cases`), each with and without the
case's detection curve (unheard pings as information), and scores them as the study does
(:func:`~hmmtrack.experiments.clock_runs.score_run`), with each run's CPU time.
This module runs and scores; it writes nothing.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import pandas as pd

from hmmtrack.experiments.arrival import cases
from hmmtrack.experiments.clock_runs import (
    DURATION,
    clock_inputs,
    score_run,
    track_arrival,
    without_silences,
)
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.pipeline import track

#: the clock-aware cases of :func:`grouping_rows` unless told: three moored receivers (most
#: pings heard by all three), two and three moving receivers (mostly one or two)
GROUPING_CASES = (
    "moored array, 3 receivers",
    "shark pursuit, 2 AUVs (circling)",
    "diagnostic: same pursuit, 3 AUVs",
)


#: the methods of :func:`grouping_rows`
METHODS = (
    "arrival-time",
    "arrival-time, no detection curve",
    "grouped pings",
    "grouped pings, no detection curve",
)


def grouped_config(options: dict, period: float, bounds, settings: dict | None = None):
    """The grouped run's configuration: the ``"ping-sequence"`` measurement of a tag of
    ``period`` (s), the arrival-time run's particles, window and detection curve
    (``options`` of :func:`~hmmtrack.experiments.clock_runs.clock_inputs`), the case's
    search ``bounds``, and more ``settings`` by key."""
    config = options["config"]
    keys = {
        "measurement": "ping-sequence",
        "period": float(period),
        "bounds": bounds,
        "n_particles": config.filter.n_particles,
        "detection_curve": config.measurement.detection_curve,
        "start": config.start,
        "end": config.end,
    }
    return TrackingConfig.from_keys(**(keys | dict(settings or {})))


def _run(method: str, case, seed: int, detections, options: dict, settings):
    """One run of ``method`` (:data:`METHODS`) on the case's detections."""
    sc = case.scenario
    if method == "arrival-time":
        return track_arrival(detections, sc.receivers, options)
    if method == "arrival-time, no detection curve":
        return track_arrival(detections, sc.receivers, without_silences(options))
    if method == "grouped pings, no detection curve":
        options = without_silences(options)
    config = grouped_config(options, sc.period, case.search_bounds, settings)
    return track(detections, sc.receivers, config, options["motion"], seed=seed)


def grouping_rows(
    seeds: Sequence[int],
    *,
    names: Sequence[str] = GROUPING_CASES,
    methods: Sequence[str] = METHODS,
    n_particles: int = 2000,
    motion: str = "velocity",
    duration: float = DURATION,
    settings: dict | None = None,
) -> pd.DataFrame:
    """The arrival-time filter and the grouped pings, each with and without the detection
    curve, on the same detections, per case and seed.

    Parameters
    ----------
    seeds : sequence of int
        Scenario seeds; the filters run with the same seed.
    names : sequence of str
        Cases of :func:`hmmtrack.experiments.arrival.cases`.
    methods : sequence of str
        Of :data:`METHODS`.
    n_particles : int
    motion : str
        :func:`hmmtrack.experiments.clock_runs.make_motion` name, for every run.
    duration : float
        Length of each run (s).
    settings : dict, optional
        More settings of the grouped run by key (e.g. ``arrival_sigma``).

    Returns
    -------
    pandas.DataFrame
        One row per case, seed and method: ``scenario``, ``seed``, ``method``, the columns of
        :func:`~hmmtrack.experiments.clock_runs.score_run`, ``cpu_s`` (the run's CPU time, s),
        and for the grouped run ``heard_per_ping`` (receivers per ping) and
        ``echoes_dropped``.
    """
    rows = []
    for seed in seeds:
        by_name = cases(seed, duration)
        for name in names:
            case = by_name[name]
            detections, _, options = clock_inputs(case, seed, n_particles, motion, duration)
            for method in methods:
                began = time.process_time()
                result = _run(method, case, seed, detections, options, settings)
                row = {"scenario": name, "seed": seed, "method": method}
                row |= score_run(result.estimates, case.scenario.truth)
                row["cpu_s"] = time.process_time() - began
                if method.startswith("grouped"):
                    obs = result.observations
                    row["heard_per_ping"] = float(obs.groupby("ping").size().mean())
                    row["echoes_dropped"] = int(obs.attrs.get("echoes_dropped", 0))
                rows.append(row)
    return pd.DataFrame(rows)
