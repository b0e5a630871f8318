"""Measurement models of the tracking filter: log-likelihood of observations for all particles.

A measurement model has one method, ``loglik(particles, obs, time=None) -> (N,)``: the log
density of the observations made at one filter step, for every particle at once, with
simultaneous observations treated as independent (their log densities add). The filter
(:mod:`hmmtrack.tracking.filter`) only ever calls that method, so any model with the same method
plugs in (for instance :class:`hmmtrack.tracking.measurement.arrival_time.ArrivalTimeMeasurement`,
which scores raw
arrival times against a per-particle transmitter clock).

:class:`RangeRateMeasurement` is the paper's model (section "Correction Step"): each
observation ``z_j = (r, r_dot)`` from hydrophone ``j`` is Gaussian around the particle's
predicted range and range-rate,

    r_hat = sqrt((x_h - x)^2 + (y_h - y)^2)
    r_dot_hat = ((x_h - x)(vx_h - vx) + (y_h - y)(vy_h - vy)) / r_hat

with the particle's velocity ``(vx, vy) = speed * (cos heading, sin heading)`` and a fixed
covariance ``Sigma_z``. A positive range-rate means the tag and hydrophone move apart.

The log-likelihood is a compiled loop over particles and observations;
:func:`predicted_range_and_rate` is the same prediction in NumPy (for tests and plots).
A model may also offer ``as_matrix(obs) -> (M, k)`` and ``loglik_matrix(particles, z)``:
the filter then converts a whole run's observations once and scores row slices.

This module does not resample or move particles, and does not compute ranges from
detection times (that is :mod:`hmmtrack.tracking.measurement.ranging`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.particles import Particles

__all__ = ["RANGE_RATE_COLUMNS", "RangeRateMeasurement", "predicted_range_and_rate"]

#: columns of the observations table (docs/interfaces.md) that this model reads
RANGE_RATE_COLUMNS = (
    "range",
    "range_rate",
    "receiver_x",
    "receiver_y",
    "receiver_vx",
    "receiver_vy",
)


def predicted_range_and_rate(
    particles: Particles, receiver_x, receiver_y, receiver_vx, receiver_vy
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted range (m) and range-rate (m/s) of every particle to one or more receivers.

    Parameters
    ----------
    particles : Particles
        N particles.
    receiver_x, receiver_y : float or (M,) float
        Receiver positions, metres.
    receiver_vx, receiver_vy : float or (M,) float
        Receiver velocities, m/s.

    Returns
    -------
    r_hat, r_dot_hat : (N, M) float
        ``r_dot_hat`` is 0 for a particle exactly at the receiver (where it is undefined).
    """
    hx = np.atleast_1d(np.asarray(receiver_x, dtype=np.float64))[None, :]
    hy = np.atleast_1d(np.asarray(receiver_y, dtype=np.float64))[None, :]
    hvx = np.atleast_1d(np.asarray(receiver_vx, dtype=np.float64))[None, :]
    hvy = np.atleast_1d(np.asarray(receiver_vy, dtype=np.float64))[None, :]
    dx = hx - particles.x[:, None]
    dy = hy - particles.y[:, None]
    dvx = hvx - (particles.speed * particles.cos_heading)[:, None]
    dvy = hvy - (particles.speed * particles.sin_heading)[:, None]
    r_hat = np.hypot(dx, dy)
    safe = np.where(r_hat > 0, r_hat, 1.0)
    r_dot_hat = np.where(r_hat > 0, (dx * dvx + dy * dvy) / safe, 0.0)
    return r_hat, r_dot_hat


@dataclass(frozen=True, eq=False)
class RangeRateMeasurement:
    """The paper's Gaussian likelihood of (range, range-rate) observations.

    Parameters
    ----------
    covariance : (2, 2) array_like
        ``Sigma_z``: ``[[var(r), cov(r, r_dot)], [cov(r_dot, r), var(r_dot)]]`` in m^2,
        m^2/s, m^2/s^2. Must be symmetric positive definite.
    """

    covariance: np.ndarray
    columns: ClassVar[tuple[str, ...]] = RANGE_RATE_COLUMNS

    def __post_init__(self) -> None:
        sigma = np.array(self.covariance, dtype=np.float64)
        if sigma.shape != (2, 2) or not np.all(np.isfinite(sigma)):
            raise ValueError(f"covariance must be a finite (2, 2) matrix, got {self.covariance!r}")
        if not np.allclose(sigma, sigma.T, rtol=1e-12, atol=0.0):
            raise ValueError(f"covariance must be symmetric, got {sigma.tolist()}")
        try:
            cholesky = np.linalg.cholesky(sigma)
        except np.linalg.LinAlgError:
            raise ValueError(
                f"covariance must be positive definite, got {sigma.tolist()}"
            ) from None
        object.__setattr__(self, "covariance", sigma)
        object.__setattr__(self, "_precision", np.linalg.inv(sigma))
        log_det = 2.0 * np.log(np.diag(cholesky)).sum()
        object.__setattr__(self, "_log_norm", -np.log(2.0 * np.pi) - 0.5 * log_det)

    @classmethod
    def from_std(
        cls, range_std: float, range_rate_std: float, correlation: float = 0.0
    ) -> RangeRateMeasurement:
        """Build from standard deviations (m, m/s) and their correlation."""
        off = correlation * range_std * range_rate_std
        return cls(np.array([[range_std**2, off], [off, range_rate_std**2]]))

    def loglik(self, particles: Particles, obs, time: float | None = None) -> np.ndarray:
        """Sum over observations of ``log N([r_hat, r_dot_hat] | z_j, Sigma_z)``, per particle.

        Parameters
        ----------
        particles : Particles
            N particles.
        obs : mapping of column name to (M,) array, or DataFrame
            M simultaneous observations with the columns :data:`RANGE_RATE_COLUMNS`.
        time : float, optional
            Filter time; unused (observations are scored where the particles are now).

        Returns
        -------
        (N,) float; finite unless a squared error overflows (``-inf`` then).
        """
        return self.loglik_matrix(particles, self.as_matrix(obs))

    @staticmethod
    def as_matrix(obs) -> np.ndarray:
        """Observations as the (M, 6) float matrix that :meth:`loglik_matrix` scores.

        Parameters
        ----------
        obs : mapping of column name to (M,) array, or DataFrame
            Columns :data:`RANGE_RATE_COLUMNS` (m, m/s); other columns are ignored.

        Returns
        -------
        (M, 6) float, columns in the order of :data:`RANGE_RATE_COLUMNS`.
        """
        if isinstance(obs, pd.DataFrame):
            return obs[list(RANGE_RATE_COLUMNS)].to_numpy(dtype=np.float64)
        z = np.empty((len(obs["range"]), len(RANGE_RATE_COLUMNS)))
        for j, name in enumerate(RANGE_RATE_COLUMNS):
            z[:, j] = np.asarray(obs[name], dtype=np.float64)
        return z

    def loglik_matrix(self, particles: Particles, z: np.ndarray) -> np.ndarray:
        """:meth:`loglik` of observations already in :meth:`as_matrix` form ``z`` (M, 6).

        The filter converts all observations once and passes row slices here.
        """
        return _range_rate_loglik(
            particles.x,
            particles.y,
            particles.cos_heading,
            particles.sin_heading,
            particles.speed,
            np.ascontiguousarray(z),
            self._precision,
            self._log_norm,
        )


@njit(cache=True)
def _range_rate_loglik(x, y, cos_heading, sin_heading, speed, z, precision, log_norm):
    """Compiled :meth:`RangeRateMeasurement.loglik`; ``z`` is (M, 6) in the order of
    :data:`RANGE_RATE_COLUMNS`. Same equations as :func:`predicted_range_and_rate`."""
    out = np.zeros(x.size)
    p00, p01, p11 = precision[0, 0], precision[0, 1], precision[1, 1]
    for i in range(x.size):
        vx = speed[i] * cos_heading[i]
        vy = speed[i] * sin_heading[i]
        total = 0.0
        for j in range(z.shape[0]):
            dx = z[j, 2] - x[i]
            dy = z[j, 3] - y[i]
            r_hat = math.sqrt(dx * dx + dy * dy)
            r_dot_hat = (dx * (z[j, 4] - vx) + dy * (z[j, 5] - vy)) / r_hat if r_hat > 0 else 0.0
            e_r = r_hat - z[j, 0]
            e_v = r_dot_hat - z[j, 1]
            total += log_norm - 0.5 * (p00 * e_r * e_r + 2.0 * p01 * e_r * e_v + p11 * e_v * e_v)
        out[i] = total
    return out
