"""Detection simulation: from a moving tag and moving hydrophones to a detection log.

The pieces, each replaceable:

* an *emission clock* (:class:`EmissionClock`): when the transmitter pings.
  :class:`JitteredPeriodClock` is the paper's tag, a constant period plus Gaussian jitter;
  clocks with a drifting or random-walk period plug in through the same one-method protocol;
* the *acoustic path*: a ping emitted at ``t_e`` from the tag's position reaches a hydrophone
  at ``t_a = t_e + |tag(t_e) - hydrophone(t_a)| / s`` (solved exactly for moving hydrophones;
  3-D when the tag has a depth, hydrophones at the surface);
* *detection loss*: a per-hydrophone probability of detection as a function of range
  (:class:`ExponentialDetection`, the paper's fixed loss per metre;
  :class:`hmmtrack.tracking.measurement.detection.LogisticDetection`, a range curve with a 50 %
  range;
  any callable of range);
* *receiver clocks*: an optional map from true arrival time to logged time per hydrophone
  (identity by default), where offsets and drifts plug in;
* *GPS noise* on the logged hydrophone positions (:class:`GpsNoise`, AR(1) in time).

Outputs are the tables of ``docs/interfaces.md``: detections (``time, receiver,
transmitter`` and ``depth`` for a depth-sensor tag) and receiver positions
(``receiver, time, x, y``), plus a *pings* table with every emission at every hydrophone,
detected or lost, for tests and analyses.

This module simulates; it does not estimate ranges (:mod:`hmmtrack.tracking.measurement.ranging`)
or read files.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from hmmtrack.scenarios.trajectory import Trajectory
from hmmtrack.tracking.measurement.ranging import SOUND_SPEED

#: columns of the pings table returned by :func:`simulate_pings`
PING_COLUMNS = (
    "ping",
    "emission_time",
    "receiver",
    "arrival_time",
    "logged_time",
    "range",
    "probability",
    "detected",
)


class EmissionClock(Protocol):
    """When a transmitter pings: ``emission_times(rng, start, end) -> (n,)`` sorted UTC s."""

    def emission_times(self, rng: np.random.Generator, start: float, end: float) -> np.ndarray:
        """Emission times (UTC s) of the pings whose nominal time lies in ``[start, end)``."""
        ...


@dataclass(frozen=True)
class JitteredPeriodClock:
    """A fixed-period transmitter: ping ``k`` at ``start + phase + k * period + e_k``.

    Parameters
    ----------
    period : float
        Nominal interval between pings (s), e.g. 8.179 for the paper's field tag.
    jitter_sd : float
        Standard deviation (s) of the independent Gaussian error ``e_k`` of each emission.
    phase : float
        Delay (s) of the first nominal ping after ``start``, in ``[0, period)``.
    """

    period: float
    jitter_sd: float = 0.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        if not self.period > 0:
            raise ValueError(f"JitteredPeriodClock: period must be > 0 s, got {self.period}")
        if not self.jitter_sd >= 0:
            raise ValueError(f"JitteredPeriodClock: jitter_sd must be >= 0, got {self.jitter_sd}")
        if not 0 <= self.phase < self.period:
            raise ValueError(f"JitteredPeriodClock: phase must be in [0, period), got {self.phase}")

    def emission_times(self, rng: np.random.Generator, start: float, end: float) -> np.ndarray:
        """Emission times (UTC s), shape (n,), of the pings nominally in ``[start, end)``."""
        n = int(np.ceil((end - start - self.phase) / self.period))
        nominal = start + self.phase + self.period * np.arange(max(n, 0))
        return np.sort(nominal + rng.normal(0.0, self.jitter_sd, nominal.size))


@dataclass(frozen=True)
class ExponentialDetection:
    """Detection probability ``exp(-loss_per_metre * range)``: a fixed loss per metre travelled.

    Parameters
    ----------
    loss_per_metre : float
        Rate lambda (1/m) at which a ping is lost per metre of range.
    """

    loss_per_metre: float

    def __call__(self, distance: np.ndarray) -> np.ndarray:
        """Probability of detection at ``distance`` (m), same shape."""
        return np.exp(-self.loss_per_metre * np.asarray(distance, dtype=float))


def loss_per_metre_for(distance: np.ndarray, expected_lost: float) -> float:
    """The loss rate lambda (1/m) at which ``expected_lost`` pings are lost on average.

    Solves ``sum(1 - exp(-lambda * distance)) = expected_lost`` (increasing in lambda).

    Parameters
    ----------
    distance : (n,) float array
        Range (m) of each ping, all positive.
    expected_lost : float
        Target number of lost pings, in ``(0, n)``.

    Returns
    -------
    float
        lambda (1/m).
    """
    distance = np.asarray(distance, dtype=float)
    if not 0 < expected_lost < distance.size:
        raise ValueError(
            f"loss_per_metre_for: expected_lost must be in (0, {distance.size}), "
            f"got {expected_lost}"
        )
    if np.any(distance <= 0):
        raise ValueError("loss_per_metre_for: every distance must be > 0 m")

    def excess(rate: float) -> float:
        return float(np.sum(-np.expm1(-rate * distance)) - expected_lost)

    upper = 1.0 / distance.min()
    while excess(upper) < 0:
        upper *= 2.0
    return float(brentq(excess, 0.0, upper, xtol=1e-15, rtol=1e-13))


def arrival_times(
    emission_time: np.ndarray,
    tag: Trajectory,
    receiver: Trajectory,
    sound_speed: float = SOUND_SPEED,
    max_iterations: int = 50,
) -> tuple[np.ndarray, np.ndarray]:
    """Arrival times of pings at a (possibly moving) hydrophone.

    Solves ``t_a = t_e + |tag(t_e) - receiver(t_a)| / sound_speed`` by fixed-point
    iteration on the time of flight; each iteration shrinks the error by the ratio of
    hydrophone speed to sound speed (~1e-3); it stops when the flight time changes by at most
    1 ns, leaving an error of ~1e-12 s (epoch times themselves resolve only ~2e-7 s).

    Parameters
    ----------
    emission_time : (n,) float array
        Emission times (UTC s).
    tag, receiver : Trajectory
        The transmitter and the hydrophone (the hydrophone's depth, if any, is used too).
    sound_speed : float
        Speed of sound (m/s).
    max_iterations : int
        Iterations allowed before giving up (``RuntimeError``).

    Returns
    -------
    arrival_time : (n,) float array
        UTC s.
    distance : (n,) float array
        Range (m) from the tag at emission to the hydrophone at arrival, so that
        ``arrival_time - emission_time == distance / sound_speed``.
    """
    emission_time = np.asarray(emission_time, dtype=float)
    tx, ty, tz = tag.position(emission_time)
    flight = np.zeros_like(emission_time)
    for _ in range(max_iterations):
        rx, ry, rz = receiver.position(emission_time + flight)
        distance = np.sqrt((tx - rx) ** 2 + (ty - ry) ** 2 + (tz - rz) ** 2)
        previous, flight = flight, distance / sound_speed
        if np.all(np.abs(flight - previous) <= 1e-9):
            break
    else:
        raise RuntimeError(
            "arrival_times: no convergence; is a hydrophone moving near the speed of sound?"
        )
    arrival = emission_time + flight
    return arrival, distance


def simulate_pings(
    rng: np.random.Generator,
    tag: Trajectory,
    receivers: Mapping[str, Trajectory],
    emission_time: np.ndarray,
    detection_probability: Mapping[str, Callable[[np.ndarray], np.ndarray]],
    *,
    sound_speed: float = SOUND_SPEED,
    receiver_clocks: Mapping[str, Callable[[np.ndarray], np.ndarray]] | None = None,
) -> pd.DataFrame:
    """Every ping at every hydrophone: arrival time, range, probability and whether detected.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws one uniform per ping and hydrophone, hydrophones in the order of ``receivers``.
    tag : Trajectory
        The transmitter's path.
    receivers : mapping of str to Trajectory
        Hydrophone name to path.
    emission_time : (n,) float array
        Emission times (UTC s), e.g. from an :class:`EmissionClock`.
    detection_probability : mapping of str to callable
        Hydrophone name to a function of range (m) returning the detection probability.
    sound_speed : float
        m/s.
    receiver_clocks : mapping of str to callable, optional
        Hydrophone name to a function from true arrival time to the time its clock logs;
        hydrophones not listed keep perfect clocks.

    Returns
    -------
    DataFrame
        Columns :data:`PING_COLUMNS`, one row per ping and hydrophone, sorted by hydrophone
        then ping.
    """
    missing = sorted(set(receivers) - set(detection_probability))
    if missing:
        raise ValueError(f"simulate_pings: no detection_probability for receivers {missing}")
    clocks = receiver_clocks or {}
    unknown = sorted(set(clocks) - set(receivers))
    if unknown:
        raise ValueError(f"simulate_pings: receiver_clocks for unknown receivers {unknown}")
    frames = []
    for name, path in receivers.items():
        arrival, distance = arrival_times(emission_time, tag, path, sound_speed)
        probability = detection_probability[name](distance)
        logged = clocks[name](arrival) if name in clocks else arrival
        frames.append(
            pd.DataFrame(
                {
                    "ping": np.arange(emission_time.size),
                    "emission_time": emission_time,
                    "receiver": name,
                    "arrival_time": arrival,
                    "logged_time": logged,
                    "range": distance,
                    "probability": probability,
                    "detected": rng.random(emission_time.size) < probability,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)[list(PING_COLUMNS)]


def detections_from_pings(
    pings: pd.DataFrame, transmitter: str, tag: Trajectory | None = None
) -> pd.DataFrame:
    """The detection log of the detected pings, sorted by logged time.

    Parameters
    ----------
    pings : DataFrame
        From :func:`simulate_pings`.
    transmitter : str
        Transmitter id written in every row.
    tag : Trajectory, optional
        For a depth-sensor tag: its path; the ``depth`` column then holds the tag's depth (m)
        at emission, as the tag encodes it in the ping.

    Returns
    -------
    DataFrame
        ``time`` (logged, UTC s), ``receiver``, ``transmitter`` and, with a depth tag,
        ``depth``.
    """
    detected = pings[pings["detected"]]
    table = pd.DataFrame(
        {
            "time": detected["logged_time"].to_numpy(),
            "receiver": detected["receiver"].to_numpy(),
            "transmitter": transmitter,
        }
    )
    if tag is not None and tag.depth is not None:
        table["depth"] = tag.position(detected["emission_time"].to_numpy())[2]
    return table.sort_values(["time", "receiver"], kind="stable").reset_index(drop=True)


@dataclass(frozen=True)
class GpsNoise:
    """GPS error on logged hydrophone positions: a stationary AR(1) process per axis.

    Parameters
    ----------
    sd : float
        Stationary standard deviation (m) of the error on each of x and y.
    correlation_time : float
        e-folding time (s) of the error's autocorrelation; 0 gives independent errors per
        fix. Real GPS errors wander slowly, and independent 1 Hz errors of a few metres would
        make hydrophone velocities from differenced positions meaningless.
    """

    sd: float
    correlation_time: float = 0.0

    def sample(self, rng: np.random.Generator, time: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Errors (m) on x and y at the sorted ``time`` (s), each shape (n,)."""
        time = np.asarray(time, dtype=float)
        if self.correlation_time <= 0 or time.size < 2:
            return rng.normal(0.0, self.sd, time.size), rng.normal(0.0, self.sd, time.size)
        rho = np.exp(-np.diff(time) / self.correlation_time)
        innovation_sd = self.sd * np.sqrt(1.0 - rho**2)
        errors = []
        for _ in range(2):
            shocks = rng.normal(0.0, 1.0, time.size)
            e = np.empty(time.size)
            e[0] = self.sd * shocks[0]
            for k in range(1, time.size):
                e[k] = rho[k - 1] * e[k - 1] + innovation_sd[k - 1] * shocks[k]
            errors.append(e)
        return errors[0], errors[1]


def receiver_positions(
    rng: np.random.Generator,
    receivers: Mapping[str, Trajectory],
    time: np.ndarray,
    gps: GpsNoise | None,
) -> pd.DataFrame:
    """The logged receiver positions table, with GPS noise.

    A hydrophone whose trajectory has a single vertex is moored: one row with ``time`` NaN.
    The others get one row per ``time``.

    Parameters
    ----------
    rng : numpy.random.Generator
    receivers : mapping of str to Trajectory
    time : (m,) float array
        Times (UTC s) at which moving hydrophones log their position (e.g. 1 Hz).
    gps : GpsNoise or None
        ``None`` gives the exact positions (and draws nothing from ``rng``).

    Returns
    -------
    DataFrame
        ``receiver``, ``time``, ``x``, ``y`` (m).
    """
    frames = []
    for name, path in receivers.items():
        t = np.array([np.nan]) if path.time.size == 1 else np.asarray(time, dtype=float)
        x, y, _ = path.position(np.nan_to_num(t, nan=path.start))
        if gps is not None:
            ex, ey = gps.sample(rng, np.nan_to_num(t, nan=0.0))
            x, y = x + ex, y + ey
        frames.append(pd.DataFrame({"receiver": name, "time": t, "x": x, "y": y}))
    return pd.concat(frames, ignore_index=True)
