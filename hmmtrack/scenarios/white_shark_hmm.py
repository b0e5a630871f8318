"""The bundled "white-shark HMM": the paper's motion model, fitted with our fitter to our tracks.

The paper fits a 2-state HMM (gamma speeds, von Mises turns) to its white-shark positions and
uses it as the particle filter's motion prior. We do the same on the synthetic historical
tracks (:func:`~hmmtrack.scenarios.historical.white_shark_tracks`), following the paper's
preparation: split each shark's track where fixes are more than 3 min apart, interpolate each
segment to a regular 60 s grid, take step lengths and turning angles, and fit 2 states
(gamma / von Mises) with :func:`hmmtrack.hmm.fit_movement_hmm`. The result ships as package
data ``hmmtrack/data/white_shark_hmm.json`` (written by ``data/make_white_shark_hmm.py``) and
is loaded with :func:`load_white_shark_hmm`.

Because the grid is interpolated between fixes 1-3 min apart, the fitted model describes the
*regularised* track, not the simulation grid: chords of a tortuous path are shorter and
straighter than the path, so the resident state's fitted steps are shorter and its turns
more concentrated than the ground truth's; the transit state, nearly straight, is recovered
closely. :func:`compare_with_ground_truth` puts the two side by side.

This module prepares and fits; the fitter itself is :mod:`hmmtrack.hmm`, the track maths
:mod:`hmmtrack.tracks`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from hmmtrack import tracks as track_maths
from hmmtrack.hmm import MovementHMM, fit_movement_hmm
from hmmtrack.random import SeedLike
from hmmtrack.scenarios.shark_motion import WHITE_SHARK_GROUND_TRUTH, SharkMotionModel
from hmmtrack.tracking.motion import bundled_model_path

#: the paper's segment rule: consecutive fixes at most 3 min apart (s)
MAX_GAP = 180.0
#: time step (s) of the regular grid the model is fitted on
GRID_STEP = 60.0


def prepare_white_shark_tracks(
    tracks: pd.DataFrame, max_gap: float = MAX_GAP, step: float = GRID_STEP
) -> pd.DataFrame:
    """Split at gaps, regularise and compute steps and turning angles (the paper's recipe).

    Parameters
    ----------
    tracks : DataFrame
        Tracks table (``id``, ``time`` s, ``x``, ``y`` m); other columns are ignored.
    max_gap : float
        Split where consecutive fixes are more than this (s) apart.
    step : float
        Grid time step (s).

    Returns
    -------
    DataFrame
        Prepared track (:func:`hmmtrack.tracks.prepare`) on the regular grid.
    """
    fixes = tracks[["id", "time", "x", "y"]]
    segments = track_maths.split_at_gaps(fixes, max_gap)
    return track_maths.prepare(track_maths.regularise(segments, step))


def fit_white_shark_hmm(
    tracks: pd.DataFrame, *, n_starts: int = 5, seed: SeedLike = 1, n_jobs: int = 1
) -> MovementHMM:
    """Fit the 2-state gamma / von Mises movement HMM to white-shark tracks.

    Parameters
    ----------
    tracks : DataFrame
        Tracks table, e.g. :func:`~hmmtrack.scenarios.historical.white_shark_tracks`.
    n_starts : int
        EM starts of the fitter.
    seed : int or SeedSequence
        Seed of the starts.
    n_jobs : int
        Processes for the starts (results do not depend on it).

    Returns
    -------
    MovementHMM
        States ordered by mean step (0 = resident, 1 = transit), ``dt`` = 60 s.
    """
    prepared = prepare_white_shark_tracks(tracks)
    return fit_movement_hmm(
        prepared,
        n_states=2,
        seed=seed,
        n_starts=n_starts,
        n_jobs=n_jobs,
        step="gamma",
        angle="vonmises",
        dt=GRID_STEP,
    )


def load_white_shark_hmm() -> MovementHMM:
    """The bundled white-shark motion model (package data ``white_shark_hmm.json``)."""
    return MovementHMM.load(bundled_model_path())


def compare_with_ground_truth(
    model: MovementHMM, truth: SharkMotionModel = WHITE_SHARK_GROUND_TRUTH
) -> pd.DataFrame:
    """Fitted against true parameters, one row per parameter and state.

    Parameters
    ----------
    model : MovementHMM
        A fitted 2-state gamma / von Mises model, states ordered by mean step.
    truth : SharkMotionModel

    Returns
    -------
    DataFrame
        ``parameter`` (``step_mean`` m, ``step_sd`` m, ``angle_concentration``,
        ``stay_probability`` per ``dt``), ``state`` (name), ``truth``, ``fitted``,
        ``relative_error`` (``fitted / truth - 1``).
    """
    if model.dt != truth.dt:
        raise ValueError(f"model dt {model.dt} s differs from the ground truth's {truth.dt} s")
    step = model.step.to_dict()
    angle = model.angle.to_dict()
    fitted = {
        "step_mean": np.asarray(step["mean"], dtype=float),
        "step_sd": np.asarray(step["sd"], dtype=float),
        "angle_concentration": np.asarray(angle["concentration"], dtype=float),
        "stay_probability": np.diag(np.asarray(model.transition, dtype=float)),
    }
    true = {
        "step_mean": truth.step_mean,
        "step_sd": truth.step_sd,
        "angle_concentration": truth.angle_concentration,
        "stay_probability": np.diag(truth.transition),
    }
    rows = [
        {
            "parameter": name,
            "state": truth.state_names[k],
            "truth": float(true[name][k]),
            "fitted": float(fitted[name][k]),
        }
        for name in fitted
        for k in range(truth.n_states)
    ]
    table = pd.DataFrame(rows)
    table["relative_error"] = table["fitted"] / table["truth"] - 1.0
    return table
