"""Detection probability as a function of range, fitted from data, and what a silence tells.

A receiver hears a ping with a probability that falls with range. Modelled as a logistic
curve ``p(r) = max_probability / (1 + exp((r − range_50) / width))`` it does two jobs:

* scenarios draw which pings are heard (:mod:`hmmtrack.scenarios.clocks`,
  :mod:`hmmtrack.scenarios`);
* the arrival-time filter counts a ping that a receiver should have heard but did not
  against particles close to that receiver (:func:`silence_loglik`): each particle
  predicts when its ping reaches each receiver; if no detection came within a tolerance
  of that instant, the particle gains ``log(1 − p(range))``.

:class:`SilenceModel` holds what the filter needs for that: the receivers, their curve and
their detection times.

:func:`fit_detection_probability` estimates the curve by maximum likelihood from
``(range, heard)`` pairs - from a range test, a simulation, or a first tracking pass
(:func:`expected_pings` lists the pings an estimated track and emission schedule imply).

This module does not score arrival times (:mod:`hmmtrack.tracking.measurement.arrival_time`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit
from scipy.optimize import minimize
from scipy.special import expit, log_expit

from hmmtrack.tracking.compiled.hermite import hermite_basis, hermite_value
from hmmtrack.tracking.receivers import ReceiverTracks


@dataclass(frozen=True)
class LogisticDetection:
    """``p(r) = max_probability / (1 + exp((r − range_50) / width))``.

    Parameters
    ----------
    range_50 : float
        Range at which the probability is half of ``max_probability`` (m).
    width : float
        Range scale of the fall-off (m); ``p`` drops from 73 % to 27 % of the maximum over
        ``2·width``.
    max_probability : float
        Probability of hearing a ping next to the receiver, in (0, 1] (noise, collisions).
        The compiled silence scores (:func:`silence_loglik_recent_pings` and the clock-aware
        filter) take only curves with the default 1.
    """

    range_50: float
    width: float
    max_probability: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.range_50) and np.isfinite(self.width) and self.width > 0):
            raise ValueError(
                f"LogisticDetection needs a finite range_50 and a positive width (m), got "
                f"range_50={self.range_50}, width={self.width}"
            )
        if not 0.0 < self.max_probability <= 1.0:
            raise ValueError(
                f"LogisticDetection needs max_probability in (0, 1], got {self.max_probability}"
            )

    def _excess(self, range_m) -> np.ndarray:
        """``(r − range_50) / width``, dimensionless, same shape as ``range_m``."""
        return (np.asarray(range_m, dtype=float) - self.range_50) / self.width

    def probability(self, range_m) -> np.ndarray:
        """Probability (0-1) of hearing a ping at range ``range_m`` (m), same shape."""
        return self.max_probability * expit(-self._excess(range_m))

    def __call__(self, range_m) -> np.ndarray:
        """Same as :meth:`probability`, so the curve plugs into detection simulation."""
        return self.probability(range_m)

    def log_probability(self, range_m) -> np.ndarray:
        """``log p(range_m)``, stable far beyond ``range_50``."""
        return math.log(self.max_probability) + log_expit(-self._excess(range_m))

    def log_miss_probability(self, range_m) -> np.ndarray:
        """``log(1 − p(range_m))``, stable close to the receiver."""
        if self.max_probability == 1.0:
            return log_expit(self._excess(range_m))
        return np.log1p(-self.probability(range_m))

    def require_unit_maximum(self, caller: str) -> None:
        """Raise ValueError unless ``max_probability`` is 1 (what compiled scores assume)."""
        if self.max_probability != 1.0:
            raise ValueError(
                f"{caller} takes detection curves with max_probability 1, "
                f"got {self.max_probability}"
            )


def fit_detection_probability(range_m, heard) -> LogisticDetection:
    """Maximum-likelihood logistic detection curve from pings with known range.

    Parameters
    ----------
    range_m : array_like, shape (n,)
        Range of each ping from the receiver (m).
    heard : array_like of bool, shape (n,)
        Whether the receiver detected that ping.

    Returns
    -------
    LogisticDetection
    """
    r = np.asarray(range_m, dtype=float)
    y = np.asarray(heard)
    if r.ndim != 1 or y.shape != r.shape:
        raise ValueError(f"range_m and heard must be 1-D of equal length, got {r.shape}, {y.shape}")
    bad = np.flatnonzero(~np.isfinite(r))
    if bad.size:
        raise ValueError(f"range_m must be finite; rows {bad[:10].tolist()} are not")
    y = y.astype(bool)
    if y.all() or not y.any():
        raise ValueError(
            "fit_detection_probability needs both heard and missed pings; "
            f"got {int(y.sum())} heard of {y.size}"
        )
    scale = max(float(np.std(r)), 1.0)
    center = float(np.mean(r))
    u = (r - center) / scale

    def negative_loglik(theta: np.ndarray) -> float:
        a, b = theta
        eta = a - b * u
        return -float(np.sum(np.where(y, log_expit(eta), log_expit(-eta))))

    fit = minimize(negative_loglik, np.array([0.0, 1.0]), method="BFGS")
    a, b = fit.x
    if not fit.success and fit.status != 2:  # status 2: precision loss at the optimum
        raise ValueError(f"fit_detection_probability did not converge: {fit.message}")
    if b <= 0:
        raise ValueError(
            "fit_detection_probability: detections do not fall off with range "
            f"(fitted slope {b:.3g}); a logistic range curve does not describe these data"
        )
    return LogisticDetection(range_50=center + a * scale / b, width=scale / b)


def expected_pings(
    emission_times,
    tag_x,
    tag_y,
    receivers: ReceiverTracks,
    detections: pd.DataFrame,
    sound_speed: float,
    tolerance: float = 0.1,
) -> pd.DataFrame:
    """List which pings each receiver heard, for fitting :class:`LogisticDetection`.

    Parameters
    ----------
    emission_times : array_like, shape (n,)
        True or estimated emission times of the tag's pings (s).
    tag_x, tag_y : array_like, shape (n,)
        Tag position at each emission (m).
    receivers : ReceiverTracks
        Receiver positions; every receiver listed is taken to be listening throughout.
    detections : pandas.DataFrame
        Columns ``time`` (true time base, s) and ``receiver``.
    sound_speed : float
        m/s.
    tolerance : float
        A detection within ``tolerance`` seconds after the expected arrival (or before it)
        counts as hearing that ping (s).

    Returns
    -------
    pandas.DataFrame
        One row per (ping, receiver): ``emission_time``, ``receiver``, ``range`` (m),
        ``heard`` (bool).
    """
    emission_times = np.asarray(emission_times, dtype=float)
    tag_x = np.asarray(tag_x, dtype=float)
    tag_y = np.asarray(tag_y, dtype=float)
    frames = []
    for name in receivers.names:
        rx, ry, _, _ = receivers.state(name, emission_times)
        r = np.hypot(tag_x - rx, tag_y - ry)
        expected = emission_times + r / sound_speed
        heard_times = np.sort(
            detections.loc[detections["receiver"] == name, "time"].to_numpy(float)
        )
        heard = _any_within(heard_times, expected, tolerance)
        frames.append(
            pd.DataFrame(
                {"emission_time": emission_times, "receiver": name, "range": r, "heard": heard}
            )
        )
    return pd.concat(frames, ignore_index=True)


def _any_within(sorted_times: np.ndarray, targets: np.ndarray, tolerance: float) -> np.ndarray:
    """For each target, whether a time of ``sorted_times`` lies within ``tolerance`` of it."""
    if sorted_times.size == 0:
        return np.zeros(targets.shape, dtype=bool)
    i = np.searchsorted(sorted_times, targets - tolerance, side="left")
    i = np.minimum(i, sorted_times.size - 1)
    return np.abs(sorted_times[i] - targets) <= tolerance


def silence_loglik(
    expected_arrival: np.ndarray,
    range_m: np.ndarray,
    heard_times: np.ndarray,
    window_start: float,
    window_end: float,
    detection: LogisticDetection,
    tolerance: float,
) -> np.ndarray:
    """Log-likelihood each particle gains from a receiver's silence, shape (N,).

    A particle whose ping was due at the receiver in ``(window_start, window_end]`` and
    that the receiver did not hear (no detection within ``tolerance`` of the expected
    arrival) gains ``log(1 − p(range))``; all other particles gain 0 (a heard ping is
    scored by the arrival-time model).

    Parameters
    ----------
    expected_arrival : numpy.ndarray, shape (N,)
        Each particle's predicted arrival time of its ping at the receiver (s).
    range_m : numpy.ndarray, shape (N,)
        Each particle's range to the receiver (m).
    heard_times : numpy.ndarray, shape (M,)
        Sorted arrival times of the receiver's detections, true time base (s); must
        include detections up to ``window_end + tolerance``.
    window_start, window_end : float
        The filter step (s).
    detection : LogisticDetection
    tolerance : float
        Seconds.
    """
    due = (expected_arrival > window_start) & (expected_arrival <= window_end)
    out = np.zeros(expected_arrival.shape)
    if not due.any():
        return out
    missed = due & ~_any_within(heard_times, expected_arrival, tolerance)
    out[missed] = detection.log_miss_probability(range_m[missed])
    return out


@dataclass(frozen=True)
class HeardTimes:
    """Sorted detection times of K receivers in one array, the compiled silence score's form.

    Build it once per run (:meth:`of`); :meth:`select` picks receivers without copying times.

    Attributes
    ----------
    times : numpy.ndarray, shape (M,)
        Every receiver's sorted arrival times (s), one receiver after the other.
    first, stop : numpy.ndarray of int, shape (K,)
        Receiver ``k``'s times are ``times[first[k]:stop[k]]``.
    """

    times: np.ndarray
    first: np.ndarray
    stop: np.ndarray

    @classmethod
    def of(cls, heard_times) -> HeardTimes:
        """From one sorted array (K = 1) or a sequence of K sorted arrays (s)."""
        if isinstance(heard_times, np.ndarray):
            heard_times = [heard_times]
        sizes = np.array([np.size(h) for h in heard_times], dtype=np.int64)
        stop = np.cumsum(sizes)
        times = [np.asarray(h, dtype=float).ravel() for h in heard_times]
        return cls(np.concatenate([np.empty(0), *times]), stop - sizes, stop)

    def select(self, receivers) -> HeardTimes:
        """The receivers at positions ``receivers`` (int array), in that order."""
        return HeardTimes(self.times, self.first[receivers], self.stop[receivers])


#: no receiver (positions (0, 2), m) and their detection times: a window with nothing to score
NOWHERE = np.empty((0, 2))
NOTHING_HEARD = HeardTimes.of([])


def silence_loglik_recent_pings(
    emission_time: np.ndarray,
    period: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    receiver_xy: np.ndarray,
    n_back: int,
    heard_times,
    window_start: float,
    window_end: float,
    detection: LogisticDetection,
    tolerance: float,
    sound_speed: float,
) -> np.ndarray:
    """:func:`silence_loglik` summed over each particle's last ``n_back`` pings (compiled).

    Particle ``i``'s pings are ``emission_time[i] + k·period[i]``; the last ``n_back``
    whose arrival (``+ range / sound_speed``, range from ``(x[i], y[i])`` to the receiver)
    at a receiver is at or before ``window_end`` are each scored as :func:`silence_loglik`
    scores one expected arrival, and the scores of all receivers are summed.

    Parameters
    ----------
    emission_time, period : numpy.ndarray, shape (N,)
        Each particle's reference emission (s) and period (s).
    x, y : numpy.ndarray, shape (N,)
        Particle positions (m).
    receiver_xy : numpy.ndarray, shape (K, 2) or (2,)
        Positions of the K receivers (m).
    n_back : int
        Pings per particle to look at, >= 1.
    heard_times : numpy.ndarray, shape (M,), sequence of K of them, or HeardTimes
        Sorted arrival times of each receiver's detections (s).
    window_start, window_end : float
        The window (s), as in :func:`silence_loglik`.
    detection : LogisticDetection
    tolerance, sound_speed : float
        Seconds; m/s.

    Returns
    -------
    numpy.ndarray, shape (N,)
    """
    detection.require_unit_maximum("silence_loglik_recent_pings")
    receiver_xy = np.atleast_2d(np.asarray(receiver_xy, dtype=float))
    if not isinstance(heard_times, HeardTimes):
        heard_times = HeardTimes.of(heard_times)
    if heard_times.first.size != receiver_xy.shape[0] or receiver_xy.shape[1] != 2:
        raise ValueError(
            f"silence_loglik_recent_pings: receiver positions of shape {receiver_xy.shape} "
            f"(expected (K, 2)) but detection times of {heard_times.first.size} receiver(s)"
        )
    out = np.zeros(np.shape(emission_time))
    recent_pings_kernel(
        np.ascontiguousarray(emission_time, dtype=float),
        np.ascontiguousarray(period, dtype=float),
        np.ascontiguousarray(x, dtype=float),
        np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(receiver_xy),
        int(n_back),
        heard_times.times,
        heard_times.first,
        heard_times.stop,
        float(window_start),
        float(window_end),
        float(detection.range_50),
        float(detection.width),
        float(tolerance),
        float(sound_speed),
        out,
    )
    return out


@njit(cache=True)
def recent_pings_kernel(
    emission_time, period, x, y, receiver_xy, n_back, heard_times, first, stop, window_start,
    window_end, range_50, width, tolerance, sound_speed, out,
):  # fmt: skip
    """Compiled :func:`silence_loglik_recent_pings`: subtracts from ``out`` (N,) each
    particle's ``softplus((range_50 − range) / width) = −log(1 − p(range))`` once per ping
    due in the window and unheard, over the K receivers at ``receiver_xy`` (K, 2) whose
    sorted detection times are ``heard_times[first[k]:stop[k]]`` (a :class:`HeardTimes`'
    arrays); the clock-aware correction kernel calls it on its own particles' clocks.

    Receiver by receiver and ping by ping, each step is a pass over the particles without
    branches but the last (vector code; a particle's branches on whether its ping is due
    and heard cost more than the passes), in the order of the terms per particle.
    """
    slowness = 1.0 / sound_speed
    n = emission_time.size
    range_m = np.empty(n)
    travel = np.empty(n)
    last = np.empty(n)
    expected = np.empty(n)
    unheard = np.empty(n)  # 1.0: the ping is due in the window and not heard (so far)
    for k in range(receiver_xy.shape[0]):
        heard_k = heard_times[first[k] : stop[k]]
        # only detections within tolerance of the window can match a ping due in it
        lo = np.searchsorted(heard_k, window_start - tolerance)
        heard_k = heard_k[lo : np.searchsorted(heard_k, window_end + tolerance, side="right")]
        m = heard_k.size
        receiver_x, receiver_y = receiver_xy[k, 0], receiver_xy[k, 1]
        for i in range(n):
            dx = x[i] - receiver_x
            dy = y[i] - receiver_y
            range_m[i] = math.sqrt(dx * dx + dy * dy)
        for i in range(n):  # the last ping whose arrival is at or before the window's end
            travel[i] = range_m[i] * slowness
            last[i] = math.floor((window_end - travel[i] - emission_time[i]) / period[i])
        for back in range(n_back):
            for i in range(n):
                arrival = emission_time[i] + (last[i] - back) * period[i] + travel[i]
                expected[i] = arrival
                due = (window_start < arrival) & (arrival <= window_end)  # False for NaN
                unheard[i] = 1.0 if due else 0.0
            if m > 8:
                for i in range(n):
                    if unheard[i] > 0.0:
                        j = min(np.searchsorted(heard_k, expected[i] - tolerance), m - 1)
                        unheard[i] = 0.0 if abs(heard_k[j] - expected[i]) <= tolerance else 1.0
            else:  # (a window holds a few detections: a scan is cheaper)
                for j in range(m):
                    for i in range(n):
                        heard = abs(heard_k[j] - expected[i]) <= tolerance
                        unheard[i] = 0.0 if heard else unheard[i]
            for i in range(n):
                if unheard[i] > 0.0:  # log(1 − p) = log expit(x) = −softplus(−x)
                    out[i] -= softplus((range_50 - range_m[i]) / width)


#: grid of :func:`softplus`'s table: ``x`` from ``-SOFTPLUS_END`` to ``SOFTPLUS_END`` in
#: steps of ``SOFTPLUS_STEP``; beyond, ``softplus(x)`` is ``max(x, 0)`` to within 5e-18
SOFTPLUS_END, SOFTPLUS_STEP = 40.0, 1.0 / 20.0
_SOFTPLUS_X = np.linspace(-SOFTPLUS_END, SOFTPLUS_END, round(2 * SOFTPLUS_END / SOFTPLUS_STEP) + 1)
#: ``log(1 + e^x)`` and its slope ``expit(x)`` times the step, per node (one row per node)
_SOFTPLUS = np.column_stack([np.logaddexp(0.0, _SOFTPLUS_X), SOFTPLUS_STEP * expit(_SOFTPLUS_X)])


@njit(cache=True)
def softplus(x):
    """``log(1 + e^x)`` by cubic Hermite interpolation in a table built once (compiled).

    Within 3e-9 of the exact function (its fourth derivative is at most 1/8, so the
    interpolation error is at most ``step⁴/3072``; tested), about three times cheaper than
    ``log1p(exp(x))``. The compiled scores of the detection curve use it:
    ``log p = −softplus((r − range_50)/width)`` and ``log(1 − p) = −softplus(−x)``.

    Parameters
    ----------
    x : float

    Returns
    -------
    float
    """
    at = (x + SOFTPLUS_END) * (1.0 / SOFTPLUS_STEP)
    inside = (at >= 0.0) & (at < _SOFTPLUS.shape[0] - 1.0)  # False for NaN
    clipped = at if inside else 0.0
    k = int(clipped)
    h01, h10, h11 = hermite_basis(clipped - k)
    value = hermite_value(_SOFTPLUS, k, 0, h01, h10, h11)
    beyond = x if not x <= 0.0 else 0.0  # max(x, 0) off the table; NaN stays NaN
    return value if inside else beyond


def emission_schedule(clock: pd.DataFrame, end: float) -> np.ndarray:
    """Emission times (s) implied by a tracked clock, filled ping by ping up to ``end``.

    Parameters
    ----------
    clock : pandas.DataFrame
        Columns ``emission_time`` and ``period`` (s), one row per correction in time order,
        as the clock table of :attr:`hmmtrack.tracking.pipeline.TrackingResult.clock`.
    end : float
        Last time to fill to (s).

    Returns
    -------
    numpy.ndarray, shape (n,)
        Sorted, one per ping: each row's emission time stepped by its period until the
        next row's emission time (or ``end``).
    """
    emission = clock["emission_time"].to_numpy(dtype=float)
    period = clock["period"].to_numpy(dtype=float)
    stops = np.append(emission[1:], end)
    pings = [
        e + p * np.arange(max(int(np.round((stop - e) / p)), 1))
        for e, p, stop in zip(emission, period, stops, strict=True)
    ]
    return np.unique(np.concatenate(pings)) if pings else np.empty(0)


def fit_detection_probability_from_track(
    estimates: pd.DataFrame,
    clock: pd.DataFrame,
    receivers: ReceiverTracks,
    detections: pd.DataFrame,
    sound_speed: float,
    tolerance: float = 0.5,
) -> LogisticDetection:
    """Fit the detection curve from a tracking run: its track, its clock, the detections.

    A first pass of the arrival-time filter (without detection probability) gives where
    the tag was and when it pinged; every ping then has a range to every receiver and was
    heard or not (:func:`expected_pings`), which is what :func:`fit_detection_probability`
    needs. The fit is only as good as the track; pings are kept from the first correction.

    Parameters
    ----------
    estimates : pandas.DataFrame
        ``time``, ``x``, ``y`` of the track (m).
    clock : pandas.DataFrame
        ``emission_time``, ``period`` per correction (see :func:`emission_schedule`).
    receivers : ReceiverTracks
    detections : pandas.DataFrame
        ``time`` (common time base) and ``receiver``.
    sound_speed : float
        m/s.
    tolerance : float
        s, see :func:`expected_pings`.
    """
    times = estimates["time"].to_numpy(dtype=float)
    emissions = emission_schedule(clock, float(times[-1]))
    emissions = emissions[(emissions >= times[0]) & (emissions <= times[-1])]
    x = np.interp(emissions, times, estimates["x"].to_numpy(dtype=float))
    y = np.interp(emissions, times, estimates["y"].to_numpy(dtype=float))
    table = expected_pings(emissions, x, y, receivers, detections, sound_speed, tolerance)
    return fit_detection_probability(table["range"], table["heard"])


@dataclass(frozen=True)
class SilenceModel:
    """What an unheard ping tells: receivers, their detection curve and their detections.

    Parameters
    ----------
    receivers : ReceiverTracks
        Where the listening receivers are; a moving receiver listens within its GPS span.
    detection : LogisticDetection
        Detection probability against range (all receivers).
    heard : dict of str to numpy.ndarray
        Sorted detection times per receiver on the common time base (s).
    tolerance : float
        A detection this close (s) to a particle's expected arrival is that ping heard.
    """

    receivers: ReceiverTracks
    detection: LogisticDetection
    heard: dict[str, np.ndarray]
    tolerance: float = 1.0
    _grid: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _heard_all: list = field(default_factory=list, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.detection.require_unit_maximum("SilenceModel")

    def heard_times(self, names) -> HeardTimes:
        """Detection times of the receivers ``names`` in the compiled kernel's form."""
        if not self._heard_all:  # once: every receiver's times, and their positions there
            self._heard_all.append(HeardTimes.of(list(self.heard.values())))
            self._heard_all.append({name: k for k, name in enumerate(self.heard)})
        everyone, position = self._heard_all
        return everyone.select(np.array([position[n] for n in names], dtype=np.int64))

    def window(
        self, time: float, dt: float, window_start: float, nominal_period: float
    ) -> tuple[float, int, np.ndarray, HeardTimes]:
        """The unheard pings a correction at ``time`` scores: its window's end, the pings
        per particle to look at and the listening receivers, in the compiled kernel's form.

        The window runs from ``window_start`` (the last correction's cut) to this
        correction's cut, ``time + dt/2`` less :attr:`tolerance` (detections up to
        ``time + dt/2`` are in the correction at ``time``); a particle's pings whose arrival
        can fall in it number at most ``(cut − window_start) / nominal_period`` rounded up,
        and one to spare (at most 8).

        Parameters
        ----------
        time, dt : float
            The correction's time and the filter's step (s).
        window_start : float
            The last correction's cut (s).
        nominal_period : float
            The tag's nominal period (s).

        Returns
        -------
        cut : float
            The window's end and the next window's start (s); ``window_start`` when the
            window is empty.
        n_back : int
            Pings per particle to look at; 0 when there is nothing to score.
        xy : numpy.ndarray, shape (K, 2)
            Positions (m) of the receivers listening at ``time``.
        heard : HeardTimes
            Their detection times.
        """
        cut = time + 0.5 * dt - self.tolerance
        if cut <= window_start:
            return window_start, 0, NOWHERE, NOTHING_HEARD
        listening, xy = self.listening(time, dt)
        if not listening:
            return cut, 0, NOWHERE, NOTHING_HEARD
        n_back = min(int(np.ceil((cut - window_start) / nominal_period)) + 1, 8)
        return cut, n_back, xy, self.heard_times(listening)

    def listening(self, time: float, step: float = 1.0, chunk: int = 1024):
        """Receivers listening at ``time`` (within their GPS span) and their positions.

        Positions are looked up on a grid of ``step`` seconds computed ``chunk`` steps
        at a time (a filter asks once per correction, on its prediction grid).

        Returns
        -------
        names : list of str
        xy : numpy.ndarray, shape (K, 2)
            Positions (m) at ``time``.
        """
        grid = self._grid
        k = round((time - grid.get("start", np.inf)) / step) if grid else -1
        if not (0 <= k < chunk and abs(grid["start"] + k * step - time) < 1e-6 * step):
            times = time + step * np.arange(chunk)
            span = {n: self.receivers.span(n) for n in self.receivers.names}
            # (clipped to each span: positions outside it are never used)
            xy = {n: np.array(self.receivers.state(n, np.clip(times, *span[n]))[:2]) for n in span}
            grid.update(start=float(time), xy=xy, span=span)
            k = 0
        names = [n for n, (a, b) in grid["span"].items() if a <= time <= b]
        return names, np.array([grid["xy"][n][:, k] for n in names]).reshape(len(names), 2)

    @classmethod
    def from_observations(
        cls, observations: pd.DataFrame, receivers: ReceiverTracks, detection, tolerance=1.0
    ) -> SilenceModel:
        """Build from the arrival-time observations table the filter runs on."""
        heard = {
            name: np.sort(
                observations.loc[observations["receiver"] == name, "time"].to_numpy(dtype=float)
            )
            for name in receivers.names
        }
        return cls(receivers, detection, heard, tolerance)
