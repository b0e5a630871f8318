"""Synthetic "historical white-shark tracks": the stand-in for the paper's 124k-position dataset.

The paper fits its motion HMM to positions of 22 white sharks computed by a fixed receiver
array off Santa Barbara (May-August 2020), data that are not public. :func:`white_shark_tracks`
draws a dataset of the same shape from the documented ground-truth model
(:data:`~hmmtrack.scenarios.shark_motion.WHITE_SHARK_GROUND_TRUTH`) and samples it the way
such an array positions animals (:class:`ArraySampling`):

* each shark makes *visits* to the array (exponential length, mean 6 h), starting anywhere in
  a 16 km x 1.4 km coastal strip, placed at random non-overlapping times in the season;
  paths are mirrored at the shore (a straight east-west line) and only fixes inside the
  array's 20 km x 3 km coverage are recorded;
* within a visit, fixes come 60-180 s apart (``60 + 120 * Beta(1.2, 5)``, mean 83 s), each
  with a Gaussian position error of 3 m per axis;
* after any fix, with probability 1/12, the next pings are lost for ``180 s + Exp(15 min)``:
  dropped stretches that cut the track into segments when split at gaps over 3 min (the
  paper's rule), segments of 12 fixes on average;
* 124,000 positions are shared among the 22 sharks by Dirichlet weights.

Times are whole UTC seconds; positions are UTM zone 11N metres (EPSG:32611) rounded to 0.1 m,
with the CRS in ``attrs["crs"]``. The true behavioural state of the step in progress at each
fix is kept as ``true_state`` (0 resident, 1 transit) so that decoding can be checked.

This module simulates data; reading and preparing tracks is :mod:`hmmtrack.tracks` and
:mod:`hmmtrack.io`; the script ``data/make_white_shark_tracks.py`` writes the bundled CSV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH, SharkMotionModel

#: seed of the bundled dataset (``data/white_shark_tracks.csv.gz``)
WHITE_SHARK_TRACKS_SEED = 2020

#: shortest time (s) between two visits of a shark, so that visits never merge into a segment
MIN_ABSENCE = 3600.0

#: columns of the table returned by :func:`white_shark_tracks`
TRACK_COLUMNS = ("id", "time", "x", "y", "true_state")


@dataclass(frozen=True)
class ArraySampling:
    """How a fixed receiver array positions an animal.

    Parameters
    ----------
    min_interval, max_interval : float
        Range (s) of the interval between consecutive fixes of an uninterrupted stretch.
    interval_shape : (float, float)
        Beta shape parameters of ``(interval - min) / (max - min)``.
    position_error : float
        Standard deviation (m) of the position error on each of x and y.
    mean_fixes_per_stretch : float
        Mean number of fixes between dropped stretches (geometric).
    max_gap_within_stretch : float
        Longest interval (s) of a stretch; every dropout is longer (the split threshold).
    mean_dropout : float
        Mean (s) of the exponential excess of a dropout over ``max_gap_within_stretch``.
    mean_visit : float
        Mean length (s) of a visit to the array (exponential, at least 30 min).
    area : (float, float, float, float)
        ``(xmin, xmax, ymin, ymax)`` (m, EPSG:32611) where visits start.
    coastline : float
        Northing (m) of the shore, a straight east-west line (land to the north); paths are
        mirrored at it, which keeps steps and, von Mises turns being symmetric, the turning
        angle distribution unchanged.
    coverage : (float, float, float, float)
        ``(xmin, xmax, ymin, ymax)`` (m) of the area the array can position an animal in;
        fixes outside it are not recorded.
    """

    min_interval: float = 60.0
    max_interval: float = 180.0
    interval_shape: tuple[float, float] = (1.2, 5.0)
    position_error: float = 3.0
    mean_fixes_per_stretch: float = 12.0
    max_gap_within_stretch: float = 180.0
    mean_dropout: float = 900.0
    mean_visit: float = 6 * 3600.0
    area: tuple[float, float, float, float] = (250_000.0, 266_000.0, 3_808_300.0, 3_809_700.0)
    coastline: float = 3_809_800.0
    coverage: tuple[float, float, float, float] = (
        248_000.0,
        268_000.0,
        3_806_800.0,
        3_809_800.0,
    )

    def __post_init__(self) -> None:
        (axmin, axmax, aymin, aymax), (cxmin, cxmax, cymin, cymax) = self.area, self.coverage
        if not (cxmin <= axmin <= axmax <= cxmax and cymin <= aymin <= aymax <= cymax):
            raise ValueError(
                f"ArraySampling: the area where visits start {self.area} must lie inside the "
                f"coverage {self.coverage}, so that every visit's first fix is recorded"
            )
        if aymax > self.coastline:
            raise ValueError(f"ArraySampling: area {self.area} reaches past the coastline")
        if not 0 < self.min_interval <= self.max_interval <= self.max_gap_within_stretch:
            raise ValueError(
                "ArraySampling: need 0 < min_interval <= max_interval <= max_gap_within_stretch"
            )

    def fix_times(self, rng: np.random.Generator, duration: float) -> np.ndarray:
        """Fix times (s from the start of a visit, whole seconds) within ``[0, duration]``.

        Returns
        -------
        (m,) float array
            Starts at 0; intervals are in ``[min_interval, max_interval]`` within a stretch
            and longer than ``max_gap_within_stretch`` across a dropout.
        """
        n = int(duration / self.min_interval) + 2
        a, b = self.interval_shape
        intervals = self.min_interval + (self.max_interval - self.min_interval) * rng.beta(a, b, n)
        dropout = rng.random(n) < 1.0 / self.mean_fixes_per_stretch
        intervals[dropout] = (
            self.max_gap_within_stretch + 1.0 + rng.exponential(self.mean_dropout, dropout.sum())
        )
        time = np.round(np.concatenate([[0.0], np.cumsum(intervals)]))
        return time[time <= duration]


#: the sampling of the bundled dataset
ARRAY_SAMPLING = ArraySampling()


def _visit(
    rng: np.random.Generator, model: SharkMotionModel, sampling: ArraySampling
) -> pd.DataFrame:
    """One visit to the array: fixes at times from 0 (s) and positions (m, EPSG:32611)."""
    duration = max(1800.0, rng.exponential(sampling.mean_visit))
    xmin, xmax, ymin, ymax = sampling.area
    path, states = model.simulate_path(
        rng,
        int(np.ceil(duration / model.dt)),
        start_time=0.0,
        start_x=rng.uniform(xmin, xmax),
        start_y=rng.uniform(ymin, ymax),
    )
    time = sampling.fix_times(rng, duration)
    x, y, _ = path.position(time)
    y = sampling.coastline - np.abs(sampling.coastline - y)  # mirrored at the shore
    error = rng.normal(0.0, sampling.position_error, (2, time.size))
    step = np.minimum((time // model.dt).astype(np.int64), states.size - 1)
    cxmin, cxmax, cymin, cymax = sampling.coverage
    seen = (x >= cxmin) & (x <= cxmax) & (y >= cymin) & (y <= cymax)
    return pd.DataFrame(
        {
            "time": time[seen],
            "x": np.round(x + error[0], 1)[seen],
            "y": np.round(y + error[1], 1)[seen],
            "true_state": states[step][seen],
        }
    )


def white_shark_tracks(
    seed: SeedLike = WHITE_SHARK_TRACKS_SEED,
    *,
    n_animals: int = 22,
    n_positions: int = 124_000,
    season: tuple[str, str] = ("2020-05-01T00:00:00Z", "2020-09-01T00:00:00Z"),
    model: SharkMotionModel = WHITE_SHARK_GROUND_TRUTH,
    sampling: ArraySampling = ARRAY_SAMPLING,
) -> pd.DataFrame:
    """Simulate the synthetic historical white-shark tracks.

    Parameters
    ----------
    seed : int, SeedSequence or Generator
        The default gives the bundled dataset.
    n_animals : int
        Number of sharks, ids ``shark-01``, ``shark-02``, ...
    n_positions : int
        Total number of positions (exact).
    season : (str, str)
        ISO 8601 UTC start and end of the tracking season.
    model : SharkMotionModel
        Ground-truth movement model.
    sampling : ArraySampling
        How the array positions the sharks.

    Returns
    -------
    DataFrame
        :data:`TRACK_COLUMNS`: ``id`` (str), ``time`` (UTC s, whole seconds), ``x``, ``y``
        (m, EPSG:32611), ``true_state`` (int); sorted by id then time;
        ``attrs["crs"] = "EPSG:32611"``.
    """
    if n_animals < 1 or n_positions < n_animals:
        raise ValueError(
            f"white_shark_tracks: need n_animals >= 1 and n_positions >= n_animals, got "
            f"{n_animals} and {n_positions}"
        )
    rng = as_generator(seed)
    season_start, season_end = (pd.Timestamp(s).timestamp() for s in season)
    quotas = rng.multinomial(n_positions, rng.dirichlet(np.full(n_animals, 2.0)))
    width = max(2, len(str(n_animals)))
    frames = []
    for animal, quota in enumerate(quotas):
        visits, count = [], 0
        while count < quota:
            visit = _visit(rng, model, sampling).iloc[: quota - count]
            visits.append(visit)
            count += len(visit)
        lengths = np.array([v["time"].iloc[-1] + model.dt for v in visits])
        free = season_end - season_start - lengths.sum() - MIN_ABSENCE * len(visits)
        if free <= 0:
            raise ValueError(
                f"white_shark_tracks: shark {animal + 1} needs {lengths.sum() / 86400:.1f} days "
                "of visits, more than the season; lower n_positions or raise n_animals"
            )
        gaps = MIN_ABSENCE + np.round(free * rng.dirichlet(np.ones(len(visits) + 1))[:-1])
        offsets = season_start + np.cumsum(gaps) + np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
        for visit, offset in zip(visits, offsets, strict=True):
            visit["time"] = visit["time"] + offset
        animal_frame = pd.concat(visits, ignore_index=True)
        animal_frame.insert(0, "id", f"shark-{animal + 1:0{width}d}")
        frames.append(animal_frame)
    tracks = pd.concat(frames, ignore_index=True)[list(TRACK_COLUMNS)]
    tracks.attrs["crs"] = "EPSG:32611"
    return tracks
