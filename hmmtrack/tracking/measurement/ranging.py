"""Ranging: detection times of a fixed-period tag → range and range-rate per hydrophone.

A fixed-period acoustic tag emits a ping every ``T`` seconds. A hydrophone logs the
arrival time of each ping it hears; the arrival time is the emission time plus the time
of flight (TOF). The TOF itself is unknown, but its change between two detections is
not: the paper's ΔTOF,

    Δtof = mod(Δt − T/2, T) − T/2,

which also absorbs any number of missed pings (``Δt`` close to a multiple of ``T``).
Multiplied by the sound speed ``s`` it is the change of range, and with a known initial
range ``r0`` the ranges telescope to

    r_k = r0 + s·((t_k − t_0) − n_k·T),

where ``n_k`` is the cumulative (integer) count of periods between the first and the
``k``-th detection. Summing integers and evaluating the floating-point part once from
``t_k − t_0`` keeps rounding errors from accumulating over long tracks.

This module also estimates the quantities the ranging needs or that correct it: the
measurement covariance Σ_z of (range, range_rate) against a known truth, the tag period
from a stationary segment, a linear drift re-calibration from a known final range, and
the depth correction ``r_2D = sqrt(r² − d²)``.

It is not for filtering: it neither drops nor smooths detections (every detection in is
one row out), and it knows nothing about particles or receiver positions.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from hmmtrack.io.detections import drop_duplicate_detections
from hmmtrack.tracking.settings import number

#: speed of sound in sea water used by the paper (m/s), the one default of the package;
#: fresh water is about 1416-1450
SOUND_SPEED = 1460.0
#: plausible sound speeds in water (m/s): fresh or sea water from 0 to 40 degC, any depth a
#: tag reaches, lies inside; a value outside is a unit slip (e.g. km/s) or a typo
SOUND_SPEED_RANGE = (1300.0, 1700.0)

#: fastest relative radial speed of tag and receiver the period check allows (m/s): a shark
#: bursting past a moving AUV; a period error shows as a steady range change faster than this
PERIOD_CHECK_SPEED = 5.0
#: intervals of at most this many periods are used by the period check (a small period error
#: cannot change their count of periods)
PERIOD_CHECK_PINGS = 4

#: columns of the table returned by :func:`range_table`
RANGE_COLUMNS = ("time", "receiver", "transmitter", "range", "range_rate", "missed_pings")


def _check_period(period: float) -> float:
    period = float(period)
    if not np.isfinite(period) or period <= 0:
        raise ValueError(f"period must be a positive number of seconds, got {period!r}")
    return period


def check_sound_speed(name: str, value) -> float:
    """A sound speed (m/s) inside :data:`SOUND_SPEED_RANGE`, or a ``ValueError`` naming
    ``name`` and the range."""
    speed = number(name, value)
    low, high = SOUND_SPEED_RANGE
    if not low <= speed <= high:
        raise ValueError(
            f"{name} must be a speed of sound in water between {low:g} and {high:g} m/s "
            f"(sea water about 1450-1550, fresh about 1400-1480), got {value!r}"
        )
    return speed


def _check_times(times, name: str = "times") -> np.ndarray:
    times = np.asarray(times, dtype=float)
    if times.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {times.shape}")
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size:
        raise ValueError(
            f"{name} must be finite; non-finite values at positions {bad[:10].tolist()}"
        )
    back = np.flatnonzero(np.diff(times) <= 0)
    if back.size:
        raise ValueError(
            f"{name} must be strictly increasing; not so after positions {back[:10].tolist()}"
        )
    return times


def period_counts(dt, period: float) -> np.ndarray:
    """Number of tag periods in each interval between consecutive detections.

    Parameters
    ----------
    dt : array_like, shape (n,)
        Intervals between consecutive detections (s).
    period : float
        Tag period ``T`` (s).

    Returns
    -------
    numpy.ndarray of int64, shape (n,)
        ``floor(dt / T + 1/2)``: the nearest whole number of periods (halves round up),
        the integer that the paper's ``mod`` removes. ``count − 1`` pings were missed.
    """
    period = _check_period(period)
    return np.floor(np.asarray(dt, dtype=float) / period + 0.5).astype(np.int64)


def delta_tof(dt, period: float) -> np.ndarray:
    """The paper's change of time of flight between two detections.

    Parameters
    ----------
    dt : array_like, shape (n,)
        Intervals between consecutive detections of one receiver–transmitter pair (s).
    period : float
        Tag period ``T`` (s).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``mod(dt − T/2, T) − T/2`` (s), in ``[−T/2, T/2)``. Positive when the tag moved
        away from the hydrophone.
    """
    period = _check_period(period)
    dt = np.asarray(dt, dtype=float)
    return np.mod(dt - 0.5 * period, period) - 0.5 * period


def ranges(times, period: float, r0: float, sound_speed: float = SOUND_SPEED) -> np.ndarray:
    """Ranges at each detection of one receiver–transmitter pair, from a known first range.

    Parameters
    ----------
    times : array_like, shape (n,)
        Detection (arrival) times, strictly increasing (s).
    period : float
        Tag period ``T`` (s).
    r0 : float
        Range at the first detection (m).
    sound_speed : float
        Speed of sound ``s`` (m/s).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``r_k = r0 + s·((t_k − t_0) − n_k·T)`` (m), with ``n_k`` the cumulative sum of
        :func:`period_counts` of the intervals; equal to ``r0`` plus the sum of the
        paper's ``s·Δtof`` without accumulating their rounding errors.

    Notes
    -----
    With emission-time jitter ``ε_k`` (emissions at ``k·T + ε_k``) the error of ``r_k`` is
    ``s·(ε_k − ε_0)``: bounded by ``2·s·max|ε|`` however long the track, as long as the
    range changes by less than ``s·T/2`` between consecutive detections.
    """
    period = _check_period(period)
    times = _check_times(times)
    if times.size == 0:
        return np.empty(0)
    counts = np.concatenate([[0], np.cumsum(period_counts(np.diff(times), period))])
    return float(r0) + float(sound_speed) * ((times - times[0]) - counts * period)


def range_rates(times, range_values) -> np.ndarray:
    """Range-rate at each detection: backward difference with the previous detection.

    Parameters
    ----------
    times : array_like, shape (n,)
        Detection times, strictly increasing (s).
    range_values : array_like, shape (n,)
        Ranges at those times (m), e.g. from :func:`ranges`.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``(r_k − r_{k−1}) / (t_k − t_{k−1})`` (m/s), negative when approaching. The first
        detection has no predecessor and gets NaN: its range is a measurement, its
        range-rate is not (the measurement model must then use the range alone).
    """
    times = _check_times(times)
    range_values = np.asarray(range_values, dtype=float)
    if range_values.shape != times.shape:
        raise ValueError(
            f"range_values has shape {range_values.shape}, times has shape {times.shape}"
        )
    rate = np.full(times.shape, np.nan)
    rate[1:] = np.diff(range_values) / np.diff(times)
    return rate


def check_period_fits(
    detections: pd.DataFrame, period: float, sound_speed: float = SOUND_SPEED
) -> None:
    """Refuse a period that the detections' intervals contradict, naming a better one.

    Between two detections of a receiver, ``Δt − n·T`` (``n`` pings) is the change of time
    of flight: a relative radial speed times ``n·T`` over the sound speed. For a wrong
    period it grows by the period's error every ping (8.0 s for an 8.179 s tag: 0.179 s, a
    261 m range error added per ping), so its median per ping, over every receiver's
    intervals of 1 to :data:`PERIOD_CHECK_PINGS` pings, must stay within what
    :data:`PERIOD_CHECK_SPEED` explains.

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections of one transmitter (``time`` s, ``receiver``).
    period, sound_speed : float
        Tag period (s) and sound speed (m/s) of the ranging.

    Raises
    ------
    ValueError
        Naming the given period, the residual per ping and the median period of the
        intervals (the better estimate); or, when the intervals per ping spread more than
        that speed explains (a tag with random delays), saying so.
    """
    period = _check_period(period)
    per_ping = []
    for _, group in detections.groupby(detections["receiver"].astype(str), sort=False):
        dt = np.diff(np.sort(group["time"].to_numpy(dtype=float)))
        counts = period_counts(dt, period)
        short = (counts >= 1) & (counts <= PERIOD_CHECK_PINGS)
        per_ping.append(dt[short] / counts[short])
    intervals = np.concatenate(per_ping) if per_ping else np.empty(0)
    if intervals.size < 3:
        return
    low, estimate, high = (float(q) for q in np.quantile(intervals, [0.25, 0.5, 0.75]))
    allowed = PERIOD_CHECK_SPEED * period / sound_speed
    if high - low > allowed:
        raise ValueError(
            f"the detections are not those of a fixed-period tag: the {intervals.size} "
            f"intervals between a receiver's detections of 1 to {PERIOD_CHECK_PINGS} pings "
            f"vary from {low:.3f} to {high:.3f} s per ping (quartiles), more than a tag and "
            f"receiver moving at {PERIOD_CHECK_SPEED:g} m/s explain ({allowed:.4f} s): a tag "
            "with random delays? The range-rate measurement needs a fixed period (--period)"
        )
    if abs(estimate - period) > allowed:
        raise ValueError(
            f"period {period:g} s does not fit the detections: the {intervals.size} intervals "
            f"between a receiver's detections of 1 to {PERIOD_CHECK_PINGS} pings are "
            f"{estimate:.4f} s per ping (median), {abs(estimate - period):.4f} s from the "
            f"period, more than a tag and receiver moving apart at {PERIOD_CHECK_SPEED:g} m/s "
            f"explain ({allowed:.4f} s); is the period {estimate:.4g} s? Give --period "
            f"{estimate:.4g} (the configuration's period)"
        )


def range_table(
    detections: pd.DataFrame,
    period: float,
    r0: Mapping[str, float],
    sound_speed: float = SOUND_SPEED,
    max_gap: float | None = None,
) -> pd.DataFrame:
    """Ranges and range-rates of a detections table, per (receiver, transmitter) pair.

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table (``time`` s, ``receiver``, ``transmitter``), any order.
    period : float
        Tag period ``T`` (s).
    r0 : mapping of str to float
        Range at each receiver's first detection (m), keyed by receiver name. Every
        receiver in ``detections`` needs one.
    sound_speed : float
        Speed of sound (m/s).
    max_gap : float, optional
        Longest interval (s) between a pair's detections that its range chain spans: a
        period's error adds up over every ping of a gap, and a long one can hide a ping
        more or less, so the ranges from the first detection after a longer gap on are not
        trusted (NaN range and range-rate; the chain is broken). ``None``: no limit.

    Returns
    -------
    pandas.DataFrame
        One row per detection, sorted by time then receiver, with columns
        ``time`` (s), ``receiver``, ``transmitter``, ``range`` (m; NaN after a broken chain),
        ``range_rate`` (m/s, NaN on the first detection of a pair and after a broken chain)
        and ``missed_pings`` (pings missed since the pair's previous detection, 0 on the
        first).

    Raises
    ------
    ValueError
        If a column is missing or a receiver has no ``r0``. A detection logged twice (same
        time, receiver and transmitter) is used once, by the pipeline's one rule
        (:func:`hmmtrack.io.detections.drop_duplicate_detections`, a warning counts them).
    """
    missing = [c for c in ("time", "receiver", "transmitter") if c not in detections.columns]
    if missing:
        raise ValueError(
            f"detections table lacks column(s) {missing}; expected time, receiver, transmitter"
        )
    period = _check_period(period)
    no_r0 = sorted(set(detections["receiver"].astype(str)) - set(map(str, r0)))
    if no_r0:
        raise ValueError(
            f"no initial range r0 for receiver(s) {no_r0}; give one per receiver "
            f"(known: {sorted(map(str, r0))})"
        )
    bad_time = np.flatnonzero(~np.isfinite(detections["time"].to_numpy(dtype=float)))
    if bad_time.size:
        raise ValueError(f"detections table has non-finite time in row(s) {bad_time[:10].tolist()}")
    detections = drop_duplicate_detections(detections)
    parts = []
    for (receiver, transmitter), group in detections.groupby(
        [detections["receiver"].astype(str), detections["transmitter"].astype(str)], sort=True
    ):
        group = group.sort_values("time", kind="stable")
        times = group["time"].to_numpy(dtype=float)
        r = ranges(times, period, r0[receiver], sound_speed)
        if max_gap is not None:
            gaps = np.flatnonzero(np.diff(times) > max_gap)
            if gaps.size:
                r[gaps[0] + 1 :] = np.nan
        missed = np.zeros(times.size, dtype=np.int64)
        missed[1:] = period_counts(np.diff(times), period) - 1
        parts.append(
            pd.DataFrame(
                {
                    "time": times,
                    "receiver": receiver,
                    "transmitter": transmitter,
                    "range": r,
                    "range_rate": range_rates(times, r),
                    "missed_pings": missed,
                }
            )
        )
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=float) for c in RANGE_COLUMNS})
    table = pd.concat(parts, ignore_index=True)
    return table.sort_values(["time", "receiver"], kind="stable", ignore_index=True)


def estimate_measurement_covariance(measured, truth) -> np.ndarray:
    """Measurement covariance Σ_z of (range, range_rate) from a segment with known truth.

    Parameters
    ----------
    measured : array_like, shape (n, 2)
        Measured ``range`` (m) and ``range_rate`` (m/s), e.g. from :func:`range_table`
        over a calibration segment or a simulation.
    truth : array_like, shape (n, 2)
        True range and range-rate at the same times.

    Returns
    -------
    numpy.ndarray, shape (2, 2)
        Sample covariance (``n − 1`` denominator) of the errors ``measured − truth``:
        ``[[var(r), cov(r, ṙ)], [cov(ṙ, r), var(ṙ)]]`` in m², m²/s, m²/s².

    Raises
    ------
    ValueError
        On mismatched shapes, fewer than 3 rows, or non-finite values (the rows are named;
        drop first detections, whose range-rate is NaN, before calling).
    """
    measured = np.asarray(measured, dtype=float)
    truth = np.asarray(truth, dtype=float)
    if measured.ndim != 2 or measured.shape[1] != 2 or measured.shape != truth.shape:
        raise ValueError(
            f"measured and truth must both have shape (n, 2); got {measured.shape} and "
            f"{truth.shape}"
        )
    if measured.shape[0] < 3:
        raise ValueError(f"need at least 3 rows to estimate a covariance, got {measured.shape[0]}")
    errors = measured - truth
    bad = np.flatnonzero(~np.isfinite(errors).all(axis=1))
    if bad.size:
        raise ValueError(
            f"non-finite range or range_rate in row(s) {bad[:10].tolist()} "
            f"({bad.size} in all); expected finite values"
        )
    return np.cov(errors, rowvar=False)


def estimate_period(times, period_guess: float | None = None, iterations: int = 20) -> float:
    """Tag period from the detection times of a stationary tag and hydrophone.

    Fits ``t_k = t_0 + n_k·T`` by least squares, with ``n_k`` the cumulative integer
    counts of periods (so missed pings are allowed), alternating between rounding the
    counts and refitting ``T`` until the counts stop changing.

    Parameters
    ----------
    times : array_like, shape (n,)
        Detection times, strictly increasing (s), at least 3; range constant over them.
    period_guess : float, optional
        Starting value (s). Defaults to the shortest interval between detections, which
        is right as long as at least one pair of consecutive pings was heard and the
        guess is off by less than half a period over the longest gap.
    iterations : int
        Maximum number of round-and-refit passes.

    Returns
    -------
    float
        The least-squares period (s).
    """
    times = _check_times(times)
    if times.size < 3:
        raise ValueError(f"need at least 3 detection times to estimate a period, got {times.size}")
    dt = np.diff(times)
    period = _check_period(dt.min() if period_guess is None else period_guess)
    counts = None
    for _ in range(iterations):
        new_counts = np.concatenate([[0], np.cumsum(period_counts(dt, period))])
        if counts is not None and np.array_equal(new_counts, counts):
            break
        counts = new_counts
        slope, _ = np.polyfit(counts.astype(float), times - times[0], 1)
        period = float(slope)
    return period


def recalibrate_drift(
    times, range_values, final_range: float, final_time: float | None = None
) -> np.ndarray:
    """Remove a linear range drift, given the true range at the end of the track.

    The paper's suggestion for long deployments with a recovered tag. Assumption: the
    drift comes from a constant error of the period used for ranging (or a constant
    relative clock drift), so the range error grows linearly in time from zero at the
    first detection (where ``r0`` is known) to ``range(final_time) − final_range``.

    Parameters
    ----------
    times : array_like, shape (n,)
        Detection times, strictly increasing (s).
    range_values : array_like, shape (n,)
        Ranges from :func:`ranges` (m).
    final_range : float
        True range at ``final_time`` (m).
    final_time : float, optional
        When ``final_range`` holds (s); the last detection time by default. The range
        there is interpolated linearly between detections.

    Returns
    -------
    numpy.ndarray, shape (n,)
        Corrected ranges (m): ``r_k − e·(t_k − t_0)/(t_f − t_0)`` with ``e`` the error at
        ``t_f``.
    """
    times = _check_times(times)
    range_values = np.asarray(range_values, dtype=float)
    if range_values.shape != times.shape or times.size < 2:
        raise ValueError(
            f"need matching times and ranges with at least 2 detections; got shapes "
            f"{times.shape} and {range_values.shape}"
        )
    t_final = times[-1] if final_time is None else float(final_time)
    if not times[0] < t_final <= times[-1]:
        raise ValueError(
            f"final_time {t_final} must lie after the first detection ({times[0]}) and not "
            f"after the last ({times[-1]})"
        )
    error = np.interp(t_final, times, range_values) - float(final_range)
    return range_values - error * (times - times[0]) / (t_final - times[0])


def depth_correction(range_values, depth, shallower: str = "raise") -> np.ndarray:
    """Horizontal range from a slant range and a depth: ``r_2D = sqrt(r² − d²)``.

    Parameters
    ----------
    range_values : array_like, shape (n,)
        Measured (slant) ranges (m).
    depth : float or array_like, shape (n,)
        Depth difference between tag and hydrophone (m, ≥ 0); a tag depth sensor's reading
        or an assumed constant.
    shallower : {"raise", "clip"}
        What to do where ``r < d`` (impossible geometry, from range noise or a wrong
        depth): ``"raise"`` names the positions; ``"clip"`` returns 0 there (the tag is
        taken to be right below the hydrophone).

    Returns
    -------
    numpy.ndarray, shape (n,)
        Horizontal ranges (m).
    """
    r = np.asarray(range_values, dtype=float)
    d = np.broadcast_to(np.asarray(depth, dtype=float), r.shape)
    if np.any(d < 0) or not np.isfinite(d).all():
        raise ValueError("depth must be finite and non-negative (m)")
    if shallower not in ("raise", "clip"):
        raise ValueError(f"shallower must be 'raise' or 'clip', got {shallower!r}")
    inside = np.flatnonzero(np.abs(r) < d)
    if inside.size and shallower == "raise":
        raise ValueError(
            f"range shorter than depth at position(s) {inside[:10].tolist()} "
            f"({inside.size} in all); use shallower='clip' to set them to 0"
        )
    return np.sqrt(np.maximum(r * r - d * d, 0.0))


def depth_percent_error(range_values, depth) -> np.ndarray:
    """The paper's percentage error of taking a slant range as horizontal.

    Parameters
    ----------
    range_values : array_like, shape (n,)
        Measured (slant) ranges (m), greater than ``depth``.
    depth : float or array_like
        Depth (m).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``100·(r − r_2D)/r_2D`` (%); 18.4 at 20 m, 2.4 at 50 m, 0.6 at 100 m for 10.7 m.
    """
    r = np.asarray(range_values, dtype=float)
    horizontal = depth_correction(r, depth)
    at_depth = np.flatnonzero(horizontal == 0)
    if at_depth.size:
        raise ValueError(
            f"range equals depth at position(s) {at_depth[:10].tolist()}: the percentage "
            "error is unbounded there"
        )
    return 100.0 * (r - horizontal) / horizontal
