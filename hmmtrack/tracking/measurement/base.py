"""What a measurement model is to the tracker: the :class:`Measurement` protocol.

A measurement turns detections into the filter's observations and scores particles
against them. :func:`hmmtrack.tracking.pipeline.track` knows measurements only through this
protocol, and :class:`hmmtrack.tracking.filter.ParticleFilter` only through ``loglik`` and
the optional hooks below, so a new measurement (random burst intervals, TDOA across
receivers, ...) plugs in as a class registered in
:data:`hmmtrack.tracking.measurement.MEASUREMENTS`, touching neither.

Required (checked for every registered measurement by ``tests/test_measurement_protocol.py``):

* ``name``, ``columns`` (observation columns ``loglik`` reads besides ``time``; the filter
  checks them up front) and ``fields`` (particle fields the measurement owns: it creates them
  in ``start``; resampling carries them as ``Particles.extra``);
* ``settings`` (a class attribute): its settings class, the ``measurement`` section of a
  configuration (:class:`hmmtrack.tracking.settings.Settings`; the section's ``name`` is
  the measurement's);
* ``observations(detections, receivers, settings)`` (a classmethod): the observations table
  of one transmitter's detections;
* ``from_settings(settings, observations, receivers)`` (a classmethod): the measurement its
  settings describe, for that data;
* ``start_box(observations, receivers, settings, bounds, start)``: the search box of the
  initial particles, ``(xmin, xmax, ymin, ymax)`` m (``bounds`` when given, checked);
* ``split(observations) -> (scored, events)``: the rows the filter is given and events for
  those it is not (the range-rate anchors: a receiver's first detection has no range-rate);
* ``loglik(particles, obs, time) -> (N,)``: the log density of the observations made at one
  filter step, for every particle;
* ``collectors()``: the diagnostics a run reports (fresh collectors,
  :mod:`hmmtrack.tracking.diagnostics`; the arrival-time measurement's ambiguity and clock);
* ``default_correction``: the correction policy it is run with unless the configuration
  says otherwise (:mod:`hmmtrack.tracking.tempering`);
* ``default_motion``: the motion section (``name`` and settings) it is run with unless the
  configuration names another model, the settings given overriding its own (``None``: the
  configuration's default, :data:`hmmtrack.tracking.config.SECTIONS`);
* ``default_smoothing_lag``: the fixed-lag smoother's lag (steps) it is run with unless the
  configuration says otherwise (``None``: no smoothing; offline data such as a moored
  array's random-interval tags is smoothed by default).

Optional hooks, used by the filter when present:

* ``start(particles, time, dt) -> state``: create the owned fields at the start of a run
  (``dt``: the filter's prediction step, s) and return the run's mutable state (kept by the
  filter as ``measurement_state`` and handed to ``score``; e.g. the shared clock covariance
  of the arrival-time measurement);
* ``as_matrix(table)``: the run's observations converted once to the measurement's own
  row-sliceable form, which ``loglik`` and ``score`` then receive instead of table slices;
* ``score(particles, rows, time, state, weights) -> Score``: one correction's
  log-likelihood with what the measurement does around it (see :class:`Score`); without
  it, the filter scores with ``loglik``;
* ``bridge(observations) -> (knots, gap) | None``: the times of the corrections that fix
  the tag's position and the gap between two of them beyond which the smoother bridges them
  by a straight line (:class:`hmmtrack.tracking.smoothing.Smoothed`; the ping measurement:
  a missed ping of a random-interval tag);
* ``loglik_terms(particles, rows, time) -> NamedTuple``: the arguments of ``loglik``'s
  compiled per-chunk loop, registered as an overload of
  :func:`hmmtrack.tracking.compiled.weighing.chunk_loglik` for that ``NamedTuple`` class;
  with the plain correction and no ``score`` hook, the filter then computes the
  log-likelihood inside its weighing's first pass (one parallel region and one pass over
  the particles less, the same values). Used only where the class that defines it also
  defines ``loglik`` (a subclass that overrides ``loglik`` alone is scored by it);
* ``recover(particles, table, time, rng) -> str | None``: re-place the particles after
  degenerate weights (every particle impossible) and describe what was done; ``None``
  leaves the filter's fallback, uniform in the bounds.

This module holds no measurement; the implementations are
:mod:`hmmtrack.tracking.measurement.range_rate` and
:mod:`hmmtrack.tracking.measurement.clocked`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from hmmtrack.tracking.measurement.ranging import SOUND_SPEED, check_sound_speed
from hmmtrack.tracking.settings import positive, setting

Bounds = tuple[float, float, float, float]


@dataclass(frozen=True)
class Score:
    """One correction's log-likelihood, and what its measurement does around it.

    Attributes
    ----------
    loglik : numpy.ndarray, shape (N,)
        Log density of the correction's observations for every particle.
    rescore : callable
        ``rescore(particles, weights) -> (N,)``: the same observations scored again on
        particles that were resampled and moved since (tempered corrections); ``weights``
        are their normalised weights.
    commit : callable or None
        ``commit(particles)``: what the measurement does once the weights are final (the
        Kalman step of each particle's emission clock, computed by the last scoring).
    move : callable or None
        ``move(particles, rng)``: a move of each particle that leaves the weighted posterior
        unchanged, made after ``commit`` with the filter's generator (the gps offsets'
        translation of each particle's path).
    events : tuple of (kind, detail)
        Events for the filter to record (e.g. a re-acquired clock).
    """

    loglik: np.ndarray
    rescore: Callable[[Any, np.ndarray], np.ndarray]
    commit: Callable[[Any], None] | None = None
    move: Callable[[Any, np.random.Generator], None] | None = None
    events: tuple[tuple[str, str], ...] = ()


@runtime_checkable
class Measurement(Protocol):
    """A measurement model (see the module docstring for the optional hooks)."""

    name: ClassVar[str]
    settings: ClassVar[type]
    columns: ClassVar[tuple[str, ...]]
    fields: ClassVar[tuple[str, ...]]
    default_correction: ClassVar[Any]
    default_motion: ClassVar[Mapping[str, Any] | None]
    default_smoothing_lag: ClassVar[int | None]

    @classmethod
    def observations(cls, detections: pd.DataFrame, receivers, settings) -> pd.DataFrame:
        """The observations table of one transmitter's ``detections`` (``time`` s and
        :attr:`columns`), sorted by time."""
        ...

    @classmethod
    def from_settings(cls, settings, observations: pd.DataFrame, receivers) -> Measurement:
        """The measurement ``settings`` describe, for these observations and receivers."""
        ...

    def start_box(
        self, observations: pd.DataFrame, receivers, settings, bounds: Bounds | None, start
    ) -> Bounds:
        """Search box (m) that holds the tag at ``start`` (s; None: the first observation):
        ``bounds`` when given, else derived from the data."""
        ...

    def split(self, observations: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
        """The rows the filter scores, and events (``time``, ``kind``, ``detail``) for
        the rows it does not."""
        ...

    def loglik(self, particles, obs, time: float | None = None) -> np.ndarray:
        """Log density (N,) of the observations ``obs`` made at ``time`` (s)."""
        ...

    def collectors(self) -> tuple:
        """Fresh collectors (:mod:`hmmtrack.tracking.diagnostics`) a run of this
        measurement reports with."""
        ...


#: the columns of an events table
EVENT_COLUMNS = ("time", "kind", "detail")


def no_events() -> pd.DataFrame:
    """An empty events table."""
    return pd.DataFrame(columns=list(EVENT_COLUMNS))


def period_setting():
    """The ``period`` key of a measurement section: the tag's nominal period (s)."""
    return setting(
        help="transmitter period T (s), e.g. 8.179",
        check=positive,
        parse=float,
        metavar="SECONDS",
        data=True,
    )


def sound_speed_setting():
    """The ``sound_speed`` key of a measurement section (m/s)."""
    return setting(
        SOUND_SPEED,
        help="speed of sound (m/s), between 1300 and 1700",
        check=check_sound_speed,
        parse=float,
        metavar="M_PER_S",
    )
