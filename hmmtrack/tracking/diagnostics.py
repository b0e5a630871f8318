"""Collectors: what a particle filter records about itself while it runs.

A collector is passed to :class:`hmmtrack.tracking.filter.ParticleFilter` (``collect=[...]``,
as in the ``particles`` library) and called by it at fixed points of a run: ``start(pf)``
after the particles are drawn, ``corrected(pf)`` after each correction, ``settled(pf)``
when the particles at ``pf.time`` are final (before they move or are resampled),
``resampled(pf, ancestors)`` after each resampling; ``result()`` returns its tables by the
name of their :class:`hmmtrack.tracking.pipeline.TrackingResult` field. ``every_step``
asks the filter to predict one step at a time (so that ``settled`` sees every second).

Here: :class:`Ambiguity` (is the cloud two separated clusters? the paper's
two-intersection case, :func:`ambiguity`) and :class:`ClockTrace` (the estimated emission
clock of the arrival-time measurement, :func:`clock_summary`). The fixed-lag smoother's
collector is :class:`hmmtrack.tracking.smoothing.Smoothed`.

Collectors observe; they never change the particles, the weights or the random draws.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.particles import split_in_two

#: columns of the ambiguity table (:class:`Ambiguity`)
AMBIGUITY_COLUMNS = ("time", "separation", "minor_weight", "ambiguous")
#: columns of the clock table (:class:`ClockTrace`)
CLOCK_COLUMNS = ("time", "emission_time", "period", "emission_time_sd", "period_sd")


class Ambiguity:
    """Per correction: :func:`ambiguity` of the weighted cloud (table ``ambiguity``)."""

    every_step = False

    def start(self, pf) -> None:
        self._rows: list[tuple] = []

    def corrected(self, pf) -> None:
        p = pf.particles
        self._rows.append((pf.time, *ambiguity(p.x, p.y, pf.weights()[0])))

    def settled(self, pf) -> None:
        """Nothing to record."""

    def resampled(self, pf, ancestors) -> None:
        """Nothing to record."""

    def result(self) -> dict[str, pd.DataFrame]:
        return {"ambiguity": pd.DataFrame(self._rows, columns=list(AMBIGUITY_COLUMNS))}


class ClockTrace:
    """Per correction: the estimated emission clock (table ``clock``, :data:`CLOCK_COLUMNS`).

    Reads the particles' clock fields ``emission_time`` and ``period`` and the shared clock
    covariance ``pf.measurement_state.covariance`` (:mod:`hmmtrack.tracking.measurement.clocked`).
    """

    every_step = False

    def start(self, pf) -> None:
        self._rows: list[tuple] = []

    def corrected(self, pf) -> None:
        p = pf.particles
        covariance = pf.measurement_state.covariance
        summary = clock_summary(
            p.emission_time, p.period, pf.weights()[0], covariance[0, 0], covariance[1, 1]
        )
        self._rows.append((pf.time, *summary))

    def settled(self, pf) -> None:
        """Nothing to record."""

    def resampled(self, pf, ancestors) -> None:
        """Nothing to record."""

    def result(self) -> dict[str, pd.DataFrame]:
        return {"clock": pd.DataFrame(self._rows, columns=list(CLOCK_COLUMNS))}


def ambiguity(x, y, weights, min_separation: float = 20.0) -> tuple[float, float, bool]:
    """Is a particle cloud two separated clusters? (the paper's two-intersection case)

    The cloud is projected on its principal axis and split in two by weighted 1-D 2-means
    (on :data:`AMBIGUITY_BINS` bins of the projection, so in time linear in N); it is
    called ambiguous when the smaller cluster holds at least 5 % of the weight and the
    clusters' centres lie more than ``min_separation`` apart and more than three times
    the sum of their standard deviations along the axis.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Particle positions (m).
    weights : numpy.ndarray, shape (N,)
        Normalised weights.
    min_separation : float
        m.

    Returns
    -------
    separation : float
        Distance between the two cluster centres along the axis (m).
    minor_weight : float
        Weight of the smaller cluster.
    ambiguous : bool
    """
    separation, minor, split = _ambiguity_kernel(
        np.ascontiguousarray(x, dtype=float),
        np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(weights, dtype=float),
        float(min_separation),
        AMBIGUITY_BINS,
    )
    return float(separation), float(minor), bool(split)


#: bins of the projected cloud in :func:`ambiguity` (cluster centres to 1/1024 of its span)
AMBIGUITY_BINS = 1024


@njit(cache=True)
def _ambiguity_kernel(x, y, w, min_separation, n_bins):
    """:func:`ambiguity` (compiled): the binned 2-means split of
    :func:`hmmtrack.tracking.particles.split_in_two` and its criterion."""
    # two clusters this far apart, the smaller with 5 % of the weight, would spread the
    # cloud at least this much along the axis joining them
    split = split_in_two(x, y, w, 0.05 * 0.95 * min_separation**2, n_bins)
    separation, minor, sd_lo, sd_hi = split[0], split[1], split[2], split[3]
    if separation == 0.0:
        return 0.0, 0.0, False
    split = minor >= 0.05 and separation > max(min_separation, 3.0 * (sd_lo + sd_hi))
    return separation, minor, split


@njit(cache=True)
def clock_summary(emission_time, period, weights, var_emission, var_period):
    """The estimated clock: a row of :data:`CLOCK_COLUMNS` after ``time``.

    Particles' reference emissions need not be the same ping, so two nearly equal clocks
    can differ by whole periods: emission times are taken relative to the heaviest
    particle's clock, wrapped to its nearest ping
    (:func:`hmmtrack.tracking.measurement.arrival_time.wrap_to_ping`).

    Parameters
    ----------
    emission_time, period, weights : numpy.ndarray, shape (N,)
        Particles' clock means (s) and normalised weights.
    var_emission, var_period : float
        Shared clock variances (s²) added to the spread of the means.

    Returns
    -------
    emission_time, period, emission_time_sd, period_sd : float
        Seconds.
    """
    best = np.argmax(weights)
    reference, step = emission_time[best], period[best]
    offset = np.empty(weights.size)
    mean_offset = mean_period = 0.0
    for i in range(weights.size):
        offset[i] = emission_time[i] - reference
        offset[i] -= np.rint(offset[i] / step) * step
        mean_offset += weights[i] * offset[i]
        mean_period += weights[i] * period[i]
    spread_offset = spread_period = 0.0
    for i in range(weights.size):
        spread_offset += weights[i] * (offset[i] - mean_offset) ** 2
        spread_period += weights[i] * (period[i] - mean_period) ** 2
    return (
        reference + mean_offset,
        mean_period,
        math.sqrt(spread_offset + var_emission),
        math.sqrt(spread_period + var_period),
    )
