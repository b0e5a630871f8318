"""What the truth says about the measurements: the true (range, range-rate) of observations.

:func:`expected_measurements` gives the (range, range-rate) each observation would have had
from a known tag track, with the paper's equations; the difference to the observed values
estimates the measurement covariance Σ_z from a calibration segment or a simulation
(:func:`hmmtrack.tracking.measurement.ranging.estimate_measurement_covariance`).

Not for tracking (the tracker never sees the truth: :mod:`hmmtrack.tracking`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from hmmtrack.analysis.metrics import truth_at


def expected_measurements(observations: pd.DataFrame, truth: pd.DataFrame) -> np.ndarray:
    """True (range, range-rate) at each observation, from a known tag track.

    For a calibration segment or a simulation: with
    :func:`hmmtrack.tracking.measurement.ranging.estimate_measurement_covariance` it gives Σ_z from
    data, e.g.
    ``estimate_measurement_covariance(obs[["range", "range_rate"]], expected_measurements(
    obs, truth))`` over the rows whose range-rate is defined.

    Parameters
    ----------
    observations : pandas.DataFrame
        Observations table (:func:`hmmtrack.tracking.pipeline.build_observations`).
    truth : pandas.DataFrame
        ``time`` (s), ``x``, ``y`` (m) of the tag; one row for a fixed tag. The tag's
        velocity is the slope of the truth track (zero for one row).

    Returns
    -------
    numpy.ndarray, shape (n, 2)
        Range (m) and range-rate (m/s) the receivers' logged states and the true tag track
        imply, with the paper's equations (as the filter predicts them for a particle).
    """
    times = observations["time"].to_numpy(dtype=float)
    x, y = truth_at(truth, times)
    vx = np.zeros_like(times)
    vy = np.zeros_like(times)
    if len(truth) > 1:
        ordered = truth.sort_values("time")
        t_true = ordered["time"].to_numpy(dtype=float)
        vx = np.interp(times, t_true, np.gradient(ordered["x"].to_numpy(dtype=float), t_true))
        vy = np.interp(times, t_true, np.gradient(ordered["y"].to_numpy(dtype=float), t_true))
    dx = observations["receiver_x"].to_numpy(dtype=float) - x
    dy = observations["receiver_y"].to_numpy(dtype=float) - y
    dvx = observations["receiver_vx"].to_numpy(dtype=float) - vx
    dvy = observations["receiver_vy"].to_numpy(dtype=float) - vy
    r = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        rate = np.where(r > 0, (dx * dvx + dy * dvy) / r, 0.0)
    return np.column_stack([r, rate])
