"""The arrival-time measurement: detections scored on their arrival times, with the
transmitter's emission clock carried by every particle.

:class:`ClockedArrivalTime` is the ``"arrival-time"`` measurement of
:data:`hmmtrack.tracking.measurement.MEASUREMENTS` (the
:class:`hmmtrack.tracking.measurement.base.Measurement` protocol). What it adds to the
particle filter, through the protocol's hooks:

* every particle carries the emission clock as a Kalman filter conditioned on its path
  (a Rao-Blackwellised clock): fields ``emission_time`` (mean time of the particle's
  reference emission, s), ``period`` (mean period, s) and ``period_rate`` (s per ping, 0
  unless the clock model has a rate), with one ``(3, 3)`` covariance shared by all
  particles (:class:`hmmtrack.tracking.measurement.clock.EmissionClockModel`), kept in the
  run's :class:`ClockState`. A detection is scored on its marginal likelihood - the clock
  integrated out - so particles are not lost for lack of the exact clock, and each
  detection then updates every particle's clock (one compiled pass per detection over all
  particles; committed once the correction's weights are final);
* no known initial range: the clock phase is unknown (uniform over one period) until the
  first detection, whose arrival time then fixes each particle's emission time given its
  position - the exact posterior of a uniform phase, so the first detection carries no
  weight and geometry plus motion resolve the rest;
* when detections keep fitting no particle's clock (a clock jump, not multipath) the clock
  is re-acquired from the latest one and a ``"clock_reacquired"`` event recorded;
* optionally, unheard pings count against particles near a receiver
  (:class:`hmmtrack.tracking.measurement.detection.SilenceModel`).

Its corrections are tempered by default (:class:`hmmtrack.tracking.tempering.Tempered`): a
detection scored on its arrival time is sharp (a few metres) against a cloud that may span
kilometres. The ambiguity and clock tables of a run are collectors
(:mod:`hmmtrack.tracking.diagnostics`).

This module does not read files, and its pure scoring of a detection against given clocks
is :mod:`hmmtrack.tracking.measurement.arrival_time`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.diagnostics import Ambiguity, ClockTrace
from hmmtrack.tracking.measurement.arrival_time import (
    ArrivalLikelihood,
    ArrivalTimeMeasurement,
    check_arrival_observations,
    emission_distance,
    emission_range,
    mixture_constants,
    mixture_log_densities,
    particle_depths,
    wrap_arrival,
)
from hmmtrack.tracking.measurement.base import (
    Bounds,
    Score,
    no_events,
    period_setting,
    sound_speed_setting,
)
from hmmtrack.tracking.measurement.clock import EmissionClockModel, predict_clock_covariance
from hmmtrack.tracking.measurement.detection import (
    NOTHING_HEARD,
    NOWHERE,
    LogisticDetection,
    SilenceModel,
    recent_pings_kernel,
    silence_loglik_recent_pings,
    softplus,
)
from hmmtrack.tracking.receivers import ReceiverTracks
from hmmtrack.tracking.settings import Settings, number, positive, setting
from hmmtrack.tracking.tempering import Tempered

__all__ = [
    "CLOCK_FIELDS",
    "SEARCH_RADIUS",
    "TEMPERING_ESS",
    "ArrivalTimeSettings",
    "ClockState",
    "ClockedArrivalTime",
    "arrival_observations",
    "curve_to_dict",
    "default_clock_model",
    "detection_curve_setting",
    "receiver_tracks",
    "search_box",
    "search_radius_setting",
    "silence_since",
]

#: particle fields of the emission clock's mean (s, s, s per ping)
CLOCK_FIELDS = ("emission_time", "period", "period_rate")
#: half-width (m) added around the receivers for the search box without bounds: about a
#: receiver's detection range
SEARCH_RADIUS = 1000.0
#: tempered corrections below this fraction of effective particles; two receivers on a
#: fast-turning plan need 0.6 (benchmarks/bench_two_auv_plan.py)
TEMPERING_ESS = 0.3


def search_radius_setting():
    """The ``search_radius`` key of a measurement section that needs no initial range (m):
    the search box without bounds is the receivers' positions widened by it
    (:func:`search_box`)."""
    return setting(
        SEARCH_RADIUS,
        help=(
            "without bounds, the search box is the receivers' positions at the start widened "
            "by this (m; about their detection range)"
        ),
        check=positive,
        parse=float,
        metavar="METRES",
    )


def _detection_curve(name: str, value) -> LogisticDetection:
    if isinstance(value, LogisticDetection):
        curve = value
    else:
        keys = ("range_50", "width")
        if isinstance(value, list | tuple) and len(value) == 2:
            value = dict(zip(keys, value, strict=True))
        if not isinstance(value, Mapping) or set(value) != set(keys):
            raise ValueError(
                f'{name} must be {{"range_50": metres, "width": metres}} (the logistic curve of '
                f"hmmtrack.tracking.measurement.detection.LogisticDetection), got {value!r}"
            )
        curve = LogisticDetection(*(number(f"{name} {k}", value[k]) for k in keys))
    curve.require_unit_maximum(name)
    return curve


def detection_curve_setting():
    """The ``detection_curve`` key of a measurement section that scores unheard pings: the
    receivers' logistic probability of hearing a ping against range
    (:class:`~hmmtrack.tracking.measurement.detection.LogisticDetection`, in a file
    ``{"range_50": m, "width": m}``); ``None``: missed pings carry no information."""
    return setting(
        None,
        help=(
            "probability of hearing a ping against range, 1 / (1 + exp((r - RANGE_50) / WIDTH)) "
            "(both in metres), so that pings the particles say should have been heard but were "
            "not count against them"
        ),
        check=_detection_curve,
        parse=float,
        metavar=("RANGE_50", "WIDTH"),
        nargs=2,
        default_text="none, missed pings tell nothing",
    )


def curve_to_dict(out: dict, curve: LogisticDetection | None) -> dict:
    """``out`` (a settings section's :meth:`~hmmtrack.tracking.settings.Settings.to_dict`)
    with its detection curve as ``{"range_50", "width"}`` (m) when there is one."""
    if curve is not None:
        out["detection_curve"] = {"range_50": curve.range_50, "width": curve.width}
    return out


@dataclass(frozen=True)
class ArrivalTimeSettings(Settings):
    """The ``measurement`` section of the ``"arrival-time"`` measurement.

    Parameters
    ----------
    period : float
        Nominal transmitter period (s) of the clock model (:func:`default_clock_model`).
    sound_speed : float
        Speed of sound (m/s).
    arrival_sigma : float
        Standard deviation (s) of a direct-path arrival-time residual
        (:class:`~hmmtrack.tracking.measurement.arrival_time.ArrivalLikelihood`'s ``sigma``).
    detection_curve : LogisticDetection or None
        The receivers' probability of hearing a ping against range (``max_probability`` 1;
        in a file ``{"range_50": m, "width": m}``), so that pings a particle says should
        have been heard but were not count against it; ``None``: missed pings carry no
        information.
    search_radius : float
        Without given bounds, the search box is the receivers' positions at the start
        widened by this many metres (about their detection range).
    """

    name: ClassVar[str] = "arrival-time"

    period: float = period_setting()
    sound_speed: float = sound_speed_setting()
    arrival_sigma: float = setting(
        ArrivalLikelihood.sigma,
        help="standard deviation of an arrival-time residual (s)",
        check=positive,
        parse=float,
        metavar="SECONDS",
    )
    detection_curve: LogisticDetection | None = detection_curve_setting()
    search_radius: float = search_radius_setting()

    def to_dict(self) -> dict:
        """As :meth:`Settings.to_dict`, the detection curve as ``{"range_50", "width"}``."""
        return curve_to_dict(super().to_dict(), self.detection_curve)


@njit(cache=True)
def _clock_row_kernel(
    residual, ping, distance, weights, emission_time, period, rate, loglik, sigma,
    late_fraction, late_mean, uniform_fraction, gain, range_50, width, total, direct,
):  # fmt: skip
    """Score one detection against every particle's clock and update the clocks in place.

    Adds to ``loglik`` the marginal log density of each residual (innovation standard
    deviation ``sigma``; :func:`hmmtrack.tracking.measurement.arrival_time.mixture_log_densities`,
    into the scratch
    arrays ``total`` and ``direct``, shape (N,)) and, when ``range_50`` is not NaN, the
    logistic ``log p(distance)`` of being heard; moves each clock
    ``(emission_time, period, rate)`` to the matched ping and applies the Kalman gain (3,)
    scaled by the probability that the arrival is direct.

    Returns
    -------
    accepted : float
        Weighted mean probability that the arrival is direct (scales the covariance update).
    closest : float
        Smallest absolute residual (s).
    """
    accepted = 0.0
    closest = math.inf
    constants = mixture_constants(sigma, late_fraction, late_mean, uniform_fraction)
    mixture_log_densities(residual, period, constants, total, direct)
    for i in range(residual.size):
        eps = residual[i]
        loglik[i] += total[i]
        if not math.isnan(range_50):  # log p = −softplus((distance − range_50) / width)
            loglik[i] -= softplus((distance[i] - range_50) / width)
        m = ping[i]
        shift = direct[i] * eps
        emission_time[i] += m * period[i] + 0.5 * m * (m - 1.0) * rate[i] + gain[0] * shift
        period[i] += m * rate[i] + gain[1] * shift
        rate[i] += gain[2] * shift
        accepted += weights[i] * direct[i]
        closest = min(closest, abs(eps))
    return accepted, closest


@njit(cache=True)
def _correction_kernel(
    x, y, speed, cos_heading, sin_heading, tag_depth, weights, emission_time, period, rate,
    arrival, receiver_x, receiver_y, row_offset, time, sound_speed, covariance, noise,
    measurement_sd, late_fraction, late_mean, uniform_fraction, range_50, width, lock_sigmas,
    silences, silence_xy, n_back, heard_times, heard_first, heard_stop, window_start,
    window_end, tolerance, loglik,
):  # fmt: skip
    """Score detections one after the other and update every particle's clock in place.

    With ``silences`` (a detection curve), first score the unheard pings of the window
    ``(window_start, window_end]`` on the clocks as they come in
    (:func:`hmmtrack.tracking.measurement.detection.recent_pings_kernel`: ``n_back`` pings
    per particle at the K receivers ``silence_xy`` (K, 2), their detection times
    ``heard_times[heard_first[k]:heard_stop[k]]``, ``tolerance`` s), added to ``loglik``
    after the detections' terms. Then for each row: match every particle's clock to the
    ping that fits (:func:`hmmtrack.tracking.measurement.arrival_time.match_particle`),
    move the shared covariance to the median matched ping, score and update
    (:func:`_clock_row_kernel`).

    Returns
    -------
    covariance : numpy.ndarray, shape (3, 3)
        Shared clock covariance after the last row.
    lost : bool
        Whether some row fitted no particle within ``lock_sigmas`` innovation sds.
    """
    n = x.size
    silence = np.zeros(n if silences else 0)
    if silences:
        recent_pings_kernel(
            emission_time, period, x, y, silence_xy, n_back, heard_times, heard_first,
            heard_stop, window_start, window_end, range_50, width, tolerance, sound_speed,
            silence,
        )  # fmt: skip
    vx = speed * cos_heading
    vy = speed * sin_heading
    residual = np.empty(n)
    ping = np.empty(n)
    distance = np.empty(n)
    total = np.empty(n)  # scratch of _clock_row_kernel
    direct = np.empty(n)
    lost = False
    slowness = 1.0 / sound_speed
    for j in range(arrival.size):
        lag = time - arrival[j]
        # match_particle in two loops: the ranges' compiles to vector code
        for i in range(n):
            distance[i] = emission_distance(
                x[i], y[i], vx[i], vy[i], tag_depth[i] + row_offset[j], lag, receiver_x[j],
                receiver_y[j], slowness,
            )  # fmt: skip
        lo, hi, missing = math.inf, -math.inf, False  # range of the matched pings
        for i in range(n):
            residual[i], ping[i] = wrap_arrival(
                distance[i], emission_time[i], period[i], rate[i], arrival[j], slowness
            )
            lo = min(lo, ping[i])
            hi = max(hi, ping[i])
            missing |= math.isnan(ping[i])
        ahead = max(int(np.nan if missing else _median_in_range(ping, lo, hi)), 0)
        predicted = predict_clock_covariance(covariance, ahead, noise)
        innovation_var = predicted[0, 0] + measurement_sd * measurement_sd
        sigma = math.sqrt(innovation_var)
        gain = predicted[:, 0] / innovation_var
        accepted, closest = _clock_row_kernel(
            residual, ping, distance, weights, emission_time, period, rate, loglik, sigma,
            late_fraction, late_mean, uniform_fraction, gain, range_50, width, total, direct,
        )  # fmt: skip
        lost = lost or closest > lock_sigmas * sigma
        covariance = predicted - accepted * innovation_var * np.outer(gain, gain)
    for i in range(silence.size):
        loglik[i] += silence[i]
    return covariance, lost


@njit(cache=True)
def _median_ping(ping):
    """``np.median`` of whole numbers (N,) held as floats, by counting them (linear in N)
    when they span at most :data:`MEDIAN_COUNT_SPAN` values (the matched pings of a cloud
    mostly agree); by ``np.median`` otherwise."""
    lo = hi = ping[0]
    for value in ping:
        if math.isnan(value):
            return np.nan
        lo = min(lo, value)
        hi = max(hi, value)
    return _median_in_range(ping, lo, hi)


@njit(cache=True)
def _median_in_range(ping, lo, hi):
    """:func:`_median_ping` of pings (no NaN) known to lie in ``[lo, hi]``."""
    if not hi - lo < MEDIAN_COUNT_SPAN:
        return np.median(ping)
    counts = np.zeros(int(hi - lo) + 1, dtype=np.int64)
    for value in ping:
        counts[int(value - lo)] += 1
    n = ping.size
    below = (n - 1) // 2  # the middle order statistics (0-based): below and n // 2
    first = -1
    seen = 0
    for k in range(counts.size):
        seen += counts[k]
        if first < 0 and seen > below:
            first = k
        if seen > n // 2:
            return 0.5 * ((lo + first) + (lo + k))
    return np.nan  # not reached


#: span of matched pings up to which :func:`_median_ping` counts instead of sorting
MEDIAN_COUNT_SPAN = 4096


def default_clock_model(period: float) -> EmissionClockModel:
    """The tag clock model of the arrival-time measurement when none is given.

    ``EmissionClockModel(period, period_step_sd=3e-4, phase_step_sd=1e-4,
    initial_period_sd=1e-3·period)``: a period random walk of 0.3 ms per ping, the size of a
    real tag's block-to-block changes (reasons in reports/decisions.md, "Arrival-time
    measurement").

    Parameters
    ----------
    period : float
        Nominal transmitter period (s).
    """
    return EmissionClockModel(period, 3e-4, 1e-4, 1e-3 * period)


def arrival_observations(detections: pd.DataFrame, receivers: ReceiverTracks) -> pd.DataFrame:
    """The arrival-time filter's input: detections with receiver positions at arrival.

    Parameters
    ----------
    detections : pandas.DataFrame
        ``time`` (common time base, s; see
        :func:`hmmtrack.tracking.measurement.clock.to_common_time`),
        ``receiver``; ``depth`` (m) is kept for depth-sensor tags.
    receivers : ReceiverTracks

    Returns
    -------
    pandas.DataFrame
        ``time``, ``receiver``, ``receiver_x``, ``receiver_y`` (m) and ``depth`` when
        given, sorted by time.
    """
    missing = [c for c in ("time", "receiver") if c not in detections.columns]
    if missing:
        raise ValueError(f"detections lack column(s) {missing}; expected time, receiver")
    unknown = sorted(set(detections["receiver"].astype(str)) - set(receivers.names))
    if unknown:
        rows = np.flatnonzero(detections["receiver"].astype(str).isin(unknown).to_numpy())
        raise ValueError(
            f"detections rows {rows[:10].tolist()} name receiver(s) {unknown} that have no "
            f"positions; receivers with positions: {list(receivers.names)}"
        )
    columns = ["time", "receiver"] + (["depth"] if "depth" in detections.columns else [])
    obs = detections[columns].copy()
    check_arrival_observations(obs.assign(receiver_x=0.0, receiver_y=0.0), "detections")
    obs["receiver"] = obs["receiver"].astype(str)
    obs["receiver_x"] = np.nan
    obs["receiver_y"] = np.nan
    for name in receivers.names:
        rows = (obs["receiver"] == name).to_numpy()
        if rows.any():
            x, y, _, _ = receivers.state(name, obs["time"].to_numpy(dtype=float)[rows])
            obs.loc[rows, "receiver_x"] = x
            obs.loc[rows, "receiver_y"] = y
    return obs.sort_values("time", kind="stable").reset_index(drop=True)


def receiver_tracks(receivers) -> ReceiverTracks:
    """Receiver tracks of a positions table (positions held outside their GPS span)."""
    if isinstance(receivers, ReceiverTracks):
        return receivers
    return ReceiverTracks.from_frame(receivers, outside="clamp")


def search_box(observations: pd.DataFrame, receivers, radius: float, bounds, start) -> Bounds:
    """``bounds`` when given, else the receivers' positions at ``start`` (s; default: the
    first observation) widened by ``radius`` (m): the search box of measurements that need
    no initial range."""
    if bounds is not None:
        return tuple(float(b) for b in bounds)
    tracks = receiver_tracks(receivers)
    at = float(observations["time"].min()) if start is None else float(start)
    xs, ys = zip(*(tracks.state(name, at)[:2] for name in tracks.names), strict=True)
    xs, ys = np.concatenate(xs), np.concatenate(ys)
    return (
        float(xs.min() - radius),
        float(xs.max() + radius),
        float(ys.min() - radius),
        float(ys.max() + radius),
    )


@dataclass
class ClockState:
    """The mutable state of one run of :class:`ClockedArrivalTime` (its ``start`` hook's).

    Attributes
    ----------
    dt : float
        The filter's prediction step (s): detections up to ``time + dt/2`` are in a
        correction at ``time``.
    covariance : numpy.ndarray, shape (3, 3)
        Covariance of the clock ``(emission_time, period, period_rate)`` shared by all
        particles; NaN until the first detection.
    started : bool
        Whether the clock was started from a first detection.
    lost : int
        Corrections in a row with a detection that fitted no particle's clock.
    silence_from : float
        Unheard pings count from this time on (s): the last correction's cut.
    """

    dt: float
    covariance: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    started: bool = False
    lost: int = 0
    silence_from: float = -np.inf


@dataclass(frozen=True)
class ClockedArrivalTime:
    """Arrival-time measurement with a Rao-Blackwellised emission clock (module docstring).

    Parameters
    ----------
    clock : EmissionClockModel
        The tag's clock model (:func:`default_clock_model` of the nominal period, or e.g.
        :meth:`EmissionClockModel.temperature_drift` for tags known to drift smoothly).
    arrival : ArrivalTimeMeasurement
        Residual density and speed of sound.
    silence : SilenceModel, optional
        Detection probability as information: every detection adds ``log p(range)`` and
        every unheard ping ``log(1 − p(range))`` to a particle's log weight.
    lock_sigmas : float
        A detection fits no particle when its residual exceeds this many predicted
        standard deviations for every particle.
    lost_corrections : int
        After this many corrections in a row with a detection that fits no particle (more
        than multipath can explain), the clock is re-acquired from the latest one.
    search_radius : float
        Without bounds, the search box is the receivers' positions at the start widened by
        this many metres.
    """

    clock: EmissionClockModel
    arrival: ArrivalTimeMeasurement = field(default_factory=ArrivalTimeMeasurement)
    silence: SilenceModel | None = None
    lock_sigmas: float = 10.0
    lost_corrections: int = 3
    search_radius: float = SEARCH_RADIUS
    name: ClassVar[str] = "arrival-time"
    settings: ClassVar[type] = ArrivalTimeSettings
    columns: ClassVar[tuple[str, ...]] = ArrivalTimeMeasurement.columns
    fields: ClassVar[tuple[str, ...]] = CLOCK_FIELDS
    default_correction: ClassVar[Tempered] = Tempered(TEMPERING_ESS)
    default_motion: ClassVar[dict | None] = None
    default_smoothing_lag: ClassVar[int | None] = None

    def __post_init__(self) -> None:
        if not (self.lock_sigmas > 0 and int(self.lost_corrections) >= 1):
            raise ValueError(
                f"lock_sigmas must be positive and lost_corrections at least 1, got "
                f"{self.lock_sigmas} and {self.lost_corrections}"
            )
        if not (np.isfinite(self.search_radius) and self.search_radius > 0):
            raise ValueError(f"search_radius must be positive (m), got {self.search_radius}")
        clock = self.clock
        noise = np.array([clock.phase_step_sd**2, clock.period_step_sd**2, clock.rate_step_sd**2])
        object.__setattr__(self, "_noise", noise)

    # ------------------------------------------------------------------ from data

    @classmethod
    def observations(cls, detections: pd.DataFrame, receivers, settings=None) -> pd.DataFrame:
        """:func:`arrival_observations` with the receivers' positions held outside their
        GPS span."""
        return arrival_observations(detections, receiver_tracks(receivers))

    @classmethod
    def from_settings(
        cls, settings: ArrivalTimeSettings, observations: pd.DataFrame, receivers
    ) -> ClockedArrivalTime:
        """The measurement of ``settings``: :func:`default_clock_model` of the period,
        :class:`ArrivalLikelihood` with ``arrival_sigma``, the speed of sound, the search
        radius and, with a detection curve, a silence model of these observations and
        receivers."""
        silence = None
        if settings.detection_curve is not None:
            silence = SilenceModel.from_observations(
                observations, receiver_tracks(receivers), settings.detection_curve
            )
        return cls(
            default_clock_model(settings.period),
            ArrivalTimeMeasurement(
                ArrivalLikelihood(sigma=settings.arrival_sigma), sound_speed=settings.sound_speed
            ),
            silence,
            search_radius=settings.search_radius,
        )

    def start_box(
        self,
        observations: pd.DataFrame,
        receivers,
        settings: ArrivalTimeSettings | None = None,
        bounds: Bounds | None = None,
        start=None,
    ):
        """:func:`search_box` of :attr:`search_radius` (no initial range needed)."""
        return search_box(observations, receivers, self.search_radius, bounds, start)

    def split(self, observations: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Every detection is scored: all rows, no events."""
        return observations, no_events()

    def collectors(self) -> tuple:
        """Fresh :class:`~hmmtrack.tracking.diagnostics.Ambiguity` and
        :class:`~hmmtrack.tracking.diagnostics.ClockTrace` collectors for a run."""
        return (Ambiguity(), ClockTrace())

    # ------------------------------------------------------------------ scoring

    def loglik(self, particles, obs: pd.DataFrame, time: float | None = None) -> np.ndarray:
        """Log density (N,) of detections ``obs`` given each particle's clock mean
        (:meth:`ArrivalTimeMeasurement.loglik`; in a run the filter scores with
        :meth:`score`, which integrates the clock out)."""
        return self.arrival.loglik(particles, obs, time)

    def start(self, particles, time: float, dt: float = 1.0) -> ClockState:
        """Clock fields unknown (NaN; no rate) until a detection; a fresh run state."""
        n = particles.n
        particles.extra.update(
            emission_time=np.full(n, np.nan), period=np.full(n, np.nan), period_rate=np.zeros(n)
        )
        return ClockState(dt=float(dt))

    @staticmethod
    def as_matrix(table: pd.DataFrame) -> np.ndarray:
        """Detections as an (M, 5) matrix: arrival time (s), receiver x and y (m), and the
        vertical offset (tag minus receiver depth, m) without and with a particle depth
        field (:func:`hmmtrack.tracking.measurement.arrival_time.vertical_parts`)."""
        with_depth = np.zeros(len(table))
        if "receiver_depth" in table:
            with_depth -= table["receiver_depth"].to_numpy(dtype=float)
        without = with_depth.copy()
        if "depth" in table:
            without += table["depth"].to_numpy(dtype=float)
        columns = [table[c].to_numpy(dtype=float) for c in ("time", "receiver_x", "receiver_y")]
        return np.column_stack([*columns, without, with_depth])

    def score(self, particles, rows: np.ndarray, time: float, state: ClockState, weights):
        """One correction's marginal log-likelihood (see the module docstring).

        Starts the clock on the first detection; re-acquires it (and says so in the events)
        after :attr:`lost_corrections` corrections in a row with a detection that fitted no
        particle. The clocks' Kalman step of the latest scoring is committed once the
        weights are final.
        """
        if not state.started:
            self._start_clock(particles, rows, time, state)
        latest = []

        def scored(particles, weights, state=state):
            loglik, update, lost = self._loglik(particles, rows, time, state, weights)
            latest[:] = [update]
            return loglik, lost

        loglik, lost = scored(particles, weights)
        state.lost = state.lost + 1 if lost else 0
        events = ()
        if state.lost >= self.lost_corrections:
            state.lost = 0
            self._start_clock(particles, rows, time, state, reacquire=True)
            events = (("clock_reacquired", f"no particle fitted the {len(rows)} detection(s)"),)
            loglik, _ = scored(particles, weights)

        def commit(particles):
            clocks, covariance, silence_from = latest[0]
            particles.extra.update(zip(CLOCK_FIELDS, clocks, strict=True))
            state.covariance = covariance
            state.silence_from = silence_from

        return Score(
            loglik,
            rescore=lambda particles, weights: scored(particles, weights)[0],
            commit=commit,
            events=events,
        )

    def _start_clock(self, p, rows, time, state: ClockState, reacquire: bool = False) -> None:
        """Set every particle's emission time from the first detection of ``rows``.

        Given a particle's position, a uniform prior on the phase and one arrival time
        leave only the measurement noise on its emission time. A re-acquisition keeps the
        particles' periods.
        """
        arrival, receiver_x, receiver_y, offset = (float(v[0]) for v in _parts(p, rows[:1]))
        sound_speed = self.arrival.sound_speed
        r = emission_range(
            p.x,
            p.y,
            p.speed * p.cos_heading,
            p.speed * p.sin_heading,
            time - arrival,
            receiver_x,
            receiver_y,
            particle_depths(p) + offset,
            sound_speed,
        )
        p.extra["emission_time"] = arrival - r / sound_speed
        covariance = self.clock.initial_covariance(self.arrival.likelihood.sigma)
        if reacquire:
            covariance[1, 1] = max(covariance[1, 1], float(np.var(p.period)))
            covariance[2, 2] = max(covariance[2, 2], float(np.var(p.period_rate)))
        else:
            p.extra["period"] = np.full(p.n, self.clock.nominal_period)
            p.extra["period_rate"] = np.zeros(p.n)
            # silences count from the first ping on: earlier pings may predate the tag
            state.silence_from = float(np.min(p.emission_time))
        state.covariance = covariance
        state.started = True

    def _loglik(self, p, rows, time: float, state: ClockState, weights):
        """Marginal log-likelihood (N,) of ``rows`` per particle, the pending update
        ``(clocks, covariance, silence_from)`` and whether some detection fitted no
        particle's clock within :attr:`lock_sigmas`.

        Rows are taken one after the other: each is scored against every particle's
        predicted clock (mean and shared covariance moved to the ping that fits), then the
        clock is updated with it (Kalman gain scaled by the posterior probability that the
        detection is a direct arrival), so simultaneous detections of one ping are scored
        jointly. With a silence model, it includes ``log p(range)`` of each detection and
        the unheard pings since the last correction (:func:`silence_since`'s terms, scored
        in the same compiled call).
        """
        likelihood = self.arrival.likelihood
        clocks = tuple(np.array(p.extra[name], dtype=float) for name in CLOCK_FIELDS)
        loglik = np.zeros(p.n)
        silence = self.silence
        silence_from, n_back, xy, heard = state.silence_from, 0, NOWHERE, NOTHING_HEARD
        if silence is not None:
            silence_from, n_back, xy, heard = silence.window(
                time, state.dt, state.silence_from, self.clock.nominal_period
            )
        arrival, receiver_x, receiver_y, row_offset = _parts(p, rows)
        covariance, lost = _correction_kernel(
            p.x, p.y, p.speed, p.cos_heading, p.sin_heading, particle_depths(p), weights,
            *clocks, arrival, receiver_x, receiver_y, row_offset, float(time),
            self.arrival.sound_speed, state.covariance, self._noise, likelihood.sigma,
            likelihood.late_fraction, likelihood.late_mean, likelihood.uniform_fraction,
            np.nan if silence is None else silence.detection.range_50,
            np.nan if silence is None else silence.detection.width, self.lock_sigmas,
            silence is not None, xy, n_back, heard.times, heard.first, heard.stop,
            state.silence_from, silence_from, np.nan if silence is None else silence.tolerance,
            loglik,
        )  # fmt: skip
        # (the sum of finite log-likelihoods of this size is finite)
        if not math.isfinite(loglik.sum()):
            raise ValueError(
                f"arrival-time log-likelihood not finite at time {time} for detections at "
                f"{arrival.tolist()} (receivers at x {receiver_x.tolist()}, "
                f"y {receiver_y.tolist()})"
            )
        return loglik, (clocks, covariance, silence_from), lost


def silence_since(
    silence: SilenceModel, emission_time, period, x, y, time: float, dt: float,
    window_start: float, nominal_period: float, sound_speed: float,
) -> tuple[np.ndarray, float]:  # fmt: skip
    """Log-likelihood (N,) of the pings unheard since the last correction, and the start of
    the next window (s).

    The window and the pings looked at are :meth:`SilenceModel.window`'s. Each particle's
    pings ``emission_time + k·period`` due at a listening receiver in the window and not
    heard there score ``log(1 − p(range))``
    (:func:`~hmmtrack.tracking.measurement.detection.silence_loglik_recent_pings`); a
    period rate is left out (over the at most 8 pings looked at it moves an arrival by well
    under the tolerance).

    Parameters
    ----------
    silence : SilenceModel
    emission_time, period : numpy.ndarray, shape (N,)
        Each particle's reference emission (s) and period (s).
    x, y : numpy.ndarray, shape (N,)
        Particle positions (m).
    time, dt : float
        The correction's time and the filter's step (s).
    window_start : float
        The last correction's cut (s).
    nominal_period : float
        The tag's nominal period (s): how many pings back to look.
    sound_speed : float
        m/s.
    """
    cut, n_back, xy, heard = silence.window(time, dt, window_start, nominal_period)
    if not n_back:
        return np.zeros(np.shape(x)[0]), cut
    loglik = silence_loglik_recent_pings(
        emission_time, period, x, y, xy, n_back, heard, window_start, cut, silence.detection,
        silence.tolerance, sound_speed,
    )  # fmt: skip
    return loglik, cut


def _parts(particles, rows: np.ndarray) -> tuple[np.ndarray, ...]:
    """Arrival times, receiver x and y and vertical offsets (M,) of :meth:`as_matrix` rows,
    the offset for particles with or without a ``depth`` field."""
    offset = 4 if getattr(particles, "depth", None) is not None else 3
    return tuple(np.ascontiguousarray(rows[:, k]) for k in (0, 1, 2, offset))
