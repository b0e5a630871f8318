"""Cramér–Rao bounds: how well could any tracker place the tag from these observations?

A bound answers a planning question ("with these receivers, moving like this, and a tag
clock that wanders like this, what position error can no estimator beat?") and a
diagnostic one (is a tracker's error the method's fault or the geometry's?). Three bounds:

* **a fixed tag from (range, range-rate) observations** (the paper's measurement):
  :func:`static_tag_fisher_information` and its inverse :func:`static_tag_crb`, with the
  observations' covariance Σ_z; :func:`static_tag_fit`, the best fixed-tag weighted
  least-squares fit to the same observations, shows how far the data themselves
  (hydrophone GPS errors included) place the tag from the truth;
* **a moving tag from arrival times, with its emission clock unknown**
  (:func:`arrival_time_bound`): the posterior (Bayesian) Cramér–Rao bound of Tichavský,
  Muravchik & Nehorai (1998) for the joint state

  * tag ``(x, y, vx, vy)`` (m, m/s) with a nearly-constant-velocity prior: white-noise
    acceleration of intensity ``q`` (m²/s³) on each axis;
  * emission clock ``(e, P[, R])`` of
    :class:`hmmtrack.tracking.measurement.clock.EmissionClockModel` (emission time, period,
    period rate) with that model's process noise per ping;

  observed through each detected ping's arrival time at receiver ``j``,
  ``t = e + |tag(e) − receiver_j(t)| / c + noise`` with Gaussian noise of standard deviation
  ``sigma`` (s), and optionally through whether each receiver heard each ping: a
  detection curve ``p(range)`` adds the expected Fisher information of that yes/no outcome
  about the range, ``p′(r)² / (p(1 − p))``, for every ping and listening receiver. For
  additive Gaussian noise and linear dynamics the bound's recursion is the covariance
  recursion of a Kalman filter whose measurement Jacobian (``u_jᵀ / c`` for the tag
  position, ``u_j`` the unit vector from the receiver to the tag; 1 for ``e``) is evaluated
  at the true states, so the filtering bound is that covariance and the smoothing bound
  (the best any offline method could do) is its Rauch–Tung–Striebel smoothed covariance.
  With ``clock=None`` the emission times are known and the clock states are dropped;
* **a moving tag from the time differences of each ping** (:func:`tdoa_bound`): the same
  tag prior and recursions, each ping's emission time a nuisance: independent per ping for
  a random burst interval (information from the differences between receivers only), or
  known up to an offset and a drift for a known interval sequence.

A bound holds only under its own priors: a smaller ``q`` or clock noise than the truth
really has gives a number that is *not* a bound for the truth. Heavy-tailed multipath
outliers and the clock's wrapping to the right ping are not in it (both can only make
estimation harder); the arrival-time information is that of the pings actually heard,
the detection curve's is its expectation.

Not for tracking (:mod:`hmmtrack.tracking`), for error measures
(:mod:`hmmtrack.analysis.metrics`) nor for simulating detections
(:mod:`hmmtrack.scenarios.clocks`); 2-D only (no depth).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import least_squares, minimize_scalar

from hmmtrack.analysis.metrics import finite_columns
from hmmtrack.tracking.measurement.clock import EmissionClockModel
from hmmtrack.tracking.measurement.detection import LogisticDetection
from hmmtrack.tracking.receivers import ReceiverTracks

#: indices of the tag's position (x, y) in the joint state
POSITION = slice(0, 2)
#: index of the emission time ``e`` in the joint state (clock unknown)
EMISSION = 4
#: longest flight time allowed for (s, ~3 km): a mobile receiver counts as listening to
#: pings emitted between its track's start and this long before its end
MAX_FLIGHT_TIME = 2.0


@dataclass(frozen=True)
class BoundPrior:
    """Prior spread of the state at the first ping (what is known before any detection).

    Parameters
    ----------
    position_sd : float
        Standard deviation of each position coordinate (m); no known initial range means
        about the size of the detection range.
    velocity_sd : float
        Standard deviation of each velocity component (m/s).
    emission_sd : float, optional
        Standard deviation of the first emission time (s). Default: ``P / sqrt(12)``, the
        spread of a clock phase uniform over one nominal period ``P``.
    """

    position_sd: float = 200.0
    velocity_sd: float = 1.5
    emission_sd: float | None = None

    def __post_init__(self) -> None:
        for name in ("position_sd", "velocity_sd", "emission_sd"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ValueError(f"BoundPrior.{name} must be positive, got {value}")

    def covariance(self, clock: EmissionClockModel | None) -> np.ndarray:
        """Prior covariance, shape (n, n), of the joint state (n = 4 + clock states)."""
        variances = [self.position_sd**2] * 2 + [self.velocity_sd**2] * 2
        if clock is not None:
            emission_sd = self.emission_sd or clock.nominal_period / np.sqrt(12.0)
            variances += [emission_sd**2, clock.initial_period_sd**2]
            if clock_dimension(clock) == 3:
                variances.append(clock.initial_rate_sd**2)
        return np.diag(variances)


def clock_dimension(clock: EmissionClockModel | None) -> int:
    """Clock states carried: 0 (clock known), 2 ``(e, P)`` or 3 ``(e, P, R)`` (rate in use)."""
    if clock is None:
        return 0
    return 3 if (clock.rate_step_sd > 0 or clock.initial_rate_sd > 0) else 2


def constant_velocity_transition(dt: float, acceleration_psd: float):
    """Transition and process-noise covariance of the nearly-constant-velocity model.

    Parameters
    ----------
    dt : float
        Time step (s).
    acceleration_psd : float
        Intensity ``q`` of the white-noise acceleration on each axis (m²/s³).

    Returns
    -------
    transition, noise : numpy.ndarray, each shape (4, 4)
        For the state ``(x, y, vx, vy)``; the noise is ``q·[[dt³/3, dt²/2], [dt²/2, dt]]``
        per axis.
    """
    transition = np.eye(4)
    transition[0, 2] = transition[1, 3] = dt
    block = acceleration_psd * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    noise = np.zeros((4, 4))
    noise[np.ix_([0, 2], [0, 2])] = block
    noise[np.ix_([1, 3], [1, 3])] = block
    return transition, noise


def clock_transition(clock: EmissionClockModel):
    """Transition and process noise of the emission clock over one ping.

    Returns
    -------
    transition, noise : numpy.ndarray, each shape (d, d)
        ``d = clock_dimension(clock)``; the same model as
        :meth:`hmmtrack.tracking.measurement.clock.EmissionClockModel.predict_covariance`.
    """
    d = clock_dimension(clock)
    transition = np.eye(d) + np.eye(d, k=1)
    sds = [clock.phase_step_sd, clock.period_step_sd, clock.rate_step_sd][:d]
    return transition, np.diag(np.square(sds))


def kalman_covariances(initial, transitions, noises, jacobians):
    """Filtered and predicted covariances of a linear-Gaussian model (the filtering bound).

    Parameters
    ----------
    initial : numpy.ndarray, shape (n, n)
        Prior covariance of the state at step 0.
    transitions, noises : numpy.ndarray, each shape (K - 1, n, n)
        ``F_k`` and ``Q_k`` from step k to k + 1.
    jacobians : sequence of K arrays, shape (m_k, n)
        Whitened measurement Jacobian at each step: each row divided by its measurement's
        standard deviation, so that the measurement noise is the identity (``m_k = 0``: no
        measurement). The information added at step k is ``jacobians[k].T @ jacobians[k]``.

    Returns
    -------
    filtered, predicted : numpy.ndarray, each shape (K, n, n)
        ``P_{k|k}`` and ``P_{k|k-1}`` (``predicted[0] = initial``). Updates use the Joseph
        form, which keeps the covariances symmetric and positive semi-definite.
    """
    n_steps = len(jacobians)
    n = initial.shape[0]
    filtered = np.empty((n_steps, n, n))
    predicted = np.empty((n_steps, n, n))
    covariance = np.array(initial, dtype=float)
    for k in range(n_steps):
        if k > 0:
            covariance = transitions[k - 1] @ covariance @ transitions[k - 1].T + noises[k - 1]
        predicted[k] = covariance
        h = jacobians[k]
        if h.shape[0]:
            innovation = h @ covariance @ h.T + np.eye(h.shape[0])
            gain = np.linalg.solve(innovation, h @ covariance).T
            keep = np.eye(n) - gain @ h
            covariance = keep @ covariance @ keep.T + gain @ gain.T
        covariance = 0.5 * (covariance + covariance.T)
        filtered[k] = covariance
    return filtered, predicted


def rts_covariances(filtered, predicted, transitions):
    """Rauch–Tung–Striebel smoothed covariances (the smoothing bound).

    Parameters
    ----------
    filtered, predicted : numpy.ndarray, each shape (K, n, n)
        From :func:`kalman_covariances`.
    transitions : numpy.ndarray, shape (K - 1, n, n)

    Returns
    -------
    numpy.ndarray, shape (K, n, n)
        ``P_{k|K-1}``, the covariance given all measurements.
    """
    smoothed = np.array(filtered, dtype=float)
    for k in range(len(filtered) - 2, -1, -1):
        cross = filtered[k] @ transitions[k].T
        try:
            gain = np.linalg.solve(predicted[k + 1], cross.T).T
        except np.linalg.LinAlgError:
            raise ValueError(
                f"the predicted covariance at step {k + 1} is singular: the smoothing bound "
                "needs prior spread or process noise in every state (e.g. initial_period_sd "
                "or period_step_sd > 0)"
            ) from None
        smoothed[k] = filtered[k] + gain @ (smoothed[k + 1] - predicted[k + 1]) @ gain.T
        smoothed[k] = 0.5 * (smoothed[k] + smoothed[k].T)
    return smoothed


def joint_transitions(emission_times, clock, acceleration_psd):
    """Joint (tag, clock) transitions and process noises between consecutive pings.

    Parameters
    ----------
    emission_times : numpy.ndarray, shape (K,)
        True emission times (s); the tag moves ``e_{k+1} − e_k`` seconds between pings.
    clock : EmissionClockModel or None
    acceleration_psd : float
        m²/s³.

    Returns
    -------
    transitions, noises : numpy.ndarray, each shape (K - 1, n, n)
    """
    d = clock_dimension(clock)
    n = 4 + d
    steps = np.diff(np.asarray(emission_times, dtype=float))
    transitions = np.zeros((steps.size, n, n))
    noises = np.zeros((steps.size, n, n))
    if d:
        clock_f, clock_q = clock_transition(clock)
        transitions[:, 4:, 4:] = clock_f
        noises[:, 4:, 4:] = clock_q
    for k, dt in enumerate(steps):
        transitions[k, :4, :4], noises[k, :4, :4] = constant_velocity_transition(
            dt, acceleration_psd
        )
    return transitions, noises


def arrival_jacobians(tag_xy, receiver_xy, ping, n_pings, clock_states, sound_speed):
    """Jacobians of arrival times with respect to the joint state, grouped by ping.

    Parameters
    ----------
    tag_xy : numpy.ndarray, shape (M, 2)
        True tag position at the emission of each detection's ping (m).
    receiver_xy : numpy.ndarray, shape (M, 2)
        Receiver position at each detection's arrival (m).
    ping : numpy.ndarray, shape (M,)
        Index (0 … ``n_pings`` − 1) of each detection's ping.
    n_pings : int
    clock_states : int
        0, 2 or 3 (:func:`clock_dimension`).
    sound_speed : float
        m/s.

    Returns
    -------
    list of ``n_pings`` arrays, shape (m_k, 4 + clock_states)
        Row ``[u_x / c, u_y / c, 0, 0, 1, 0(, 0)]`` per detection (s/m, s/s).
    """
    offset = np.asarray(tag_xy, dtype=float) - np.asarray(receiver_xy, dtype=float)
    distance = np.hypot(offset[:, 0], offset[:, 1])
    rows = np.zeros((distance.size, 4 + clock_states))
    rows[:, POSITION] = offset / (distance[:, None] * sound_speed)
    if clock_states:
        rows[:, EMISSION] = 1.0
    return _by_ping(rows, ping, n_pings)


def _by_ping(rows: np.ndarray, ping: np.ndarray, n_pings: int) -> list[np.ndarray]:
    """``rows`` (M, n) split into ``n_pings`` blocks by ``ping`` (M,), in row order."""
    order = np.argsort(ping, kind="stable")
    bounds = np.searchsorted(ping[order], np.arange(n_pings + 1))
    return [rows[order[bounds[k] : bounds[k + 1]]] for k in range(n_pings)]


def detection_information(detection: LogisticDetection, range_m) -> np.ndarray:
    """Expected Fisher information about the range from hearing or missing one ping (m⁻²).

    For a yes/no outcome with probability ``p(r)`` it is ``p′(r)² / (p(1 − p))``; for the
    logistic curve ``p = m·s``, ``s = 1 / (1 + exp((r − r50) / w))``, that is
    ``m·s·(1 − s)² / (w²·(1 − m·s))``.

    Parameters
    ----------
    detection : LogisticDetection
    range_m : array_like
        Ranges (m), any shape.

    Returns
    -------
    numpy.ndarray
        Same shape as ``range_m``.
    """
    s = detection.probability(range_m) / detection.max_probability
    m = detection.max_probability
    return m * s * (1 - s) ** 2 / (detection.width**2 * (1 - m * s))


def arrival_time_bound(
    truth: pd.DataFrame,
    receivers: pd.DataFrame,
    heard: pd.DataFrame,
    emission_times,
    *,
    clock: EmissionClockModel | None,
    acceleration_psd: float,
    sigma: float,
    sound_speed: float,
    prior: BoundPrior | None = None,
    detection: LogisticDetection | None = None,
) -> pd.DataFrame:
    """Filtering and smoothing posterior Cramér–Rao bounds, per ping, for a receiver plan.

    Parameters
    ----------
    truth : pandas.DataFrame
        True tag path: ``time`` (s, increasing), ``x``, ``y`` (m); interpolated linearly
        to the emission times, which must lie inside its span.
    receivers : pandas.DataFrame
        True receiver positions (``receiver``, ``time``, ``x``, ``y``; ``time`` NaN for a
        moored receiver), as :meth:`hmmtrack.tracking.receivers.ReceiverTracks.from_frame` takes.
    heard : pandas.DataFrame
        One row per detection: ``ping`` (int index into ``emission_times``) and
        ``receiver`` (str). Which pings each receiver heard; the times are not used.
    emission_times : array_like, shape (K,)
        True emission times of consecutive pings (s), strictly increasing.
    clock : EmissionClockModel or None
        The emission clock's prior model; ``None``: emission times known.
    acceleration_psd : float
        White-noise acceleration intensity ``q`` of the tag (m²/s³, > 0 or 0).
    sigma : float
        Standard deviation of an arrival time (s).
    sound_speed : float
        m/s.
    prior : BoundPrior, optional
        Spread of the state at the first ping; default :class:`BoundPrior()`.
    detection : LogisticDetection, optional
        Detection curve of every receiver: adds :func:`detection_information` for every
        ping and every receiver of ``receivers`` listening at its arrival (a mobile
        receiver within its track's time span). Default: hearing is not informative.

    Returns
    -------
    pandas.DataFrame
        One row per ping: ``time`` (true emission, s), ``ping``, ``detections`` (count),
        ``filter_position_m`` and ``smoother_position_m`` (square root of the trace of the
        position block of the bound, m: a bound on the RMS position error), and, with a
        clock, ``filter_emission_s`` and ``smoother_emission_s`` (standard-deviation
        bound on the emission time, s).
    """
    geometry = _heard_geometry(
        truth, receivers, heard, emission_times, acceleration_psd, sigma, sound_speed
    )
    emissions, ping, tag = geometry.emissions, geometry.ping, geometry.tag
    tag_xy, receiver_xy, tracks = geometry.tag_xy, geometry.receiver_xy, geometry.tracks
    prior = prior or BoundPrior()
    d = clock_dimension(clock)
    transitions, noises = joint_transitions(emissions, clock, acceleration_psd)
    jacobians = arrival_jacobians(tag_xy, receiver_xy, ping, emissions.size, d, sound_speed)
    jacobians = [rows / sigma for rows in jacobians]
    if detection is not None:
        extra = _detection_jacobians(tracks, tag, emissions, d, sound_speed, detection)
        jacobians = [np.vstack(pair) for pair in zip(jacobians, extra, strict=True)]
    filtered, predicted = kalman_covariances(
        prior.covariance(clock), transitions, noises, jacobians
    )
    smoothed = rts_covariances(filtered, predicted, transitions)
    out = pd.DataFrame(
        {
            "time": emissions,
            "ping": np.arange(emissions.size),
            "detections": np.bincount(ping, minlength=emissions.size),
            "filter_position_m": _position_bound(filtered),
            "smoother_position_m": _position_bound(smoothed),
        }
    )
    if d:
        out["filter_emission_s"] = np.sqrt(filtered[:, EMISSION, EMISSION])
        out["smoother_emission_s"] = np.sqrt(smoothed[:, EMISSION, EMISSION])
    return out


@dataclass(frozen=True)
class _Geometry:
    """The validated inputs of a bound: emissions (K,), each detection's ping (M,), the tag
    at every emission (K, 2), the tag (M, 2) and receiver (M, 2) of every detection, and the
    receivers' tracks."""

    emissions: np.ndarray
    ping: np.ndarray
    tag: np.ndarray
    tag_xy: np.ndarray
    receiver_xy: np.ndarray
    tracks: ReceiverTracks


def _heard_geometry(
    truth, receivers, heard, emission_times, acceleration_psd, sigma, sound_speed
) -> _Geometry:
    """Check a bound's inputs and place the tag and the receivers at every detection."""
    emissions = _validated_emissions(emission_times, truth)
    for name, value in (("acceleration_psd", acceleration_psd), ("sigma", sigma)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
    if not sigma > 0:
        raise ValueError(f"sigma must be positive (s), got {sigma}")
    if not (np.isfinite(sound_speed) and sound_speed > 0):
        raise ValueError(f"sound_speed must be positive (m/s), got {sound_speed}")
    ping, names = _validated_heard(heard, emissions.size)
    t_truth = truth["time"].to_numpy(dtype=float)
    tag = np.column_stack(
        [np.interp(emissions, t_truth, truth[c].to_numpy(dtype=float)) for c in ("x", "y")]
    )
    tag_xy = tag[ping]
    tracks = ReceiverTracks.from_frame(receivers)
    receiver_xy = _receiver_positions(tracks, names, tag_xy, emissions[ping], sound_speed)
    distance = np.hypot(*(tag_xy - receiver_xy).T)
    if np.any(distance < 1e-3):
        bad = np.flatnonzero(distance < 1e-3)[:5].tolist()
        raise ValueError(
            f"heard rows {bad}: the tag is within 1 mm of the receiver; the arrival-time "
            "Jacobian needs a direction"
        )
    return _Geometry(emissions, ping, tag, tag_xy, receiver_xy, tracks)


#: emission models of :func:`tdoa_bound`
EMISSION_MODELS = ("random", "sequence")


def tdoa_bound(
    truth: pd.DataFrame,
    receivers: pd.DataFrame,
    heard: pd.DataFrame,
    emission_times,
    *,
    emission: str,
    acceleration_psd: float,
    sigma: float,
    sound_speed: float,
    jitter_sd: float = 0.0,
    offset_sd: float = 1.0,
    drift_sd: float = 1e-4,
    prior: BoundPrior | None = None,
    noise=None,
) -> pd.DataFrame:
    """Posterior Cramér–Rao bounds, per ping, for a tag whose emission times are nuisances.

    The tag ``(x, y, vx, vy)`` moves as in :func:`arrival_time_bound`; ping ``k``'s arrival
    at receiver ``j`` is ``t = e_k + |tag(e_k) − receiver_j| / c + noise``, the noise of the
    ping's ``m_k`` arrivals Gaussian with covariance ``Σ_k = σ² I + jitter_sd² 1 1ᵀ``
    (independent timing errors, plus the emission's own jitter, common to every receiver).

    * ``emission="random"``: a random burst interval; each ``e_k`` is an independent unknown
      with a flat prior (an interval uniform over tens of seconds says nothing at the
      millisecond scale of the arrivals). Eliminating it leaves the information of the
      time differences only, ``Jᵀ (Σ⁻¹ − Σ⁻¹ 1 1ᵀ Σ⁻¹ / 1ᵀ Σ⁻¹ 1) J`` per ping (``J`` the
      ``m_k × 4`` Jacobian of the travel times, rows ``u_jᵀ / c``); a ping heard by one
      receiver tells nothing, and the jitter drops out.
    * ``emission="sequence"``: a known interval sequence; ``e_k = a + (1 + b) s_k`` with
      ``s_k = e_k − e_0`` the known schedule, ``a`` (s) and the crystal's relative drift
      ``b`` two unknown constants (prior sds ``offset_sd``, ``drift_sd``) joined to the
      state, so every ping's arrivals inform the position directly.

    The filtering bound is the Kalman covariance at the truth, the smoothing bound its
    Rauch–Tung–Striebel smoothed covariance (:func:`kalman_covariances`,
    :func:`rts_covariances`). Unheard pings are no information here.

    Parameters
    ----------
    truth, receivers, heard, emission_times, acceleration_psd, sigma, sound_speed
        As :func:`arrival_time_bound`.
    emission : {"random", "sequence"}
    jitter_sd : float
        Standard deviation of each emission's jitter (s).
    offset_sd, drift_sd : float
        Prior standard deviations of ``a`` (s) and ``b`` (dimensionless), for
        ``emission="sequence"``.
    prior : BoundPrior, optional
        Spread of the tag's position and velocity at the first ping.
    noise : array_like, shape (M,), optional
        Timing error (s) of each row of ``heard``: the draws of one realisation. With it the
        bound's efficient estimator is run on them (:func:`linear_tdoa_errors`), to tell how
        far a single run's error may sit from the bound by the draws' luck alone.

    Returns
    -------
    pandas.DataFrame
        One row per ping: ``time``, ``ping``, ``detections``, ``filter_position_m``,
        ``smoother_position_m`` (m, bounds on the RMS position error); with ``noise``
        also ``filter_error_m`` and ``smoother_error_m``, the position errors (m) of the
        exact Kalman filter and Rauch–Tung–Striebel smoother of the linearised model given
        those draws (the bound is their RMS in expectation over the draws).
    """
    if emission not in EMISSION_MODELS:
        raise ValueError(f"emission must be one of {EMISSION_MODELS}, got {emission!r}")
    for name, value in (("jitter_sd", jitter_sd), ("offset_sd", offset_sd), ("drift_sd", drift_sd)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {value}")
    geometry = _heard_geometry(
        truth, receivers, heard, emission_times, acceleration_psd, sigma, sound_speed
    )
    emissions, ping = geometry.emissions, geometry.ping
    known = emission == "sequence"
    rows = arrival_jacobians(
        geometry.tag_xy, geometry.receiver_xy, ping, emissions.size, 2 * known, sound_speed
    )
    schedule = emissions - emissions[0]
    jacobians = []
    for k, block in enumerate(rows):
        if known:
            block[:, EMISSION + 1] = schedule[k]
        jacobians.append(_whitened_ping(block, sigma, jitter_sd, eliminate=not known))
    transitions, noises = joint_transitions(emissions, None, acceleration_psd)
    initial = (prior or BoundPrior()).covariance(None)
    if known:
        transitions, noises = _with_constants(transitions), _with_constants(noises, 0.0)
        initial = np.pad(initial, (0, 2))
        initial[4, 4], initial[5, 5] = offset_sd**2, drift_sd**2
    filtered, predicted = kalman_covariances(initial, transitions, noises, jacobians)
    smoothed = rts_covariances(filtered, predicted, transitions)
    out = pd.DataFrame(
        {
            "time": emissions,
            "ping": np.arange(emissions.size),
            "detections": np.bincount(ping, minlength=emissions.size),
            "filter_position_m": _position_bound(filtered),
            "smoother_position_m": _position_bound(smoothed),
        }
    )
    if noise is None:
        return out
    noise = np.asarray(noise, dtype=float)
    if noise.shape != ping.shape or not np.all(np.isfinite(noise)):
        raise ValueError(f"noise must be finite with one value per heard row {ping.shape}")
    draws = [
        _whitened_ping(np.column_stack([block, e]), sigma, jitter_sd, not known)[:, -1]
        for block, e in zip(rows, _by_ping(noise[:, None], ping, emissions.size), strict=True)
    ]
    states = np.zeros((emissions.size, initial.shape[0]))
    states[:, :4] = _tag_states(truth, emissions)
    filter_errors, smoother_errors = linear_tdoa_errors(
        states, transitions, jacobians, draws, filtered, predicted
    )
    return out.assign(
        filter_error_m=np.hypot(*filter_errors[:, POSITION].T),
        smoother_error_m=np.hypot(*smoother_errors[:, POSITION].T),
    )


def _tag_states(truth: pd.DataFrame, emissions: np.ndarray) -> np.ndarray:
    """The true ``(x, y, vx, vy)`` (m, m/s) at each emission, shape (K, 4): the path
    interpolated linearly, its velocity by central differences."""
    t = truth["time"].to_numpy(dtype=float)
    columns = []
    for c in ("x", "y"):
        position = truth[c].to_numpy(dtype=float)
        columns.append((np.interp(emissions, t, position), np.gradient(position, t)))
    (x, vx), (y, vy) = columns
    return np.column_stack([x, y, np.interp(emissions, t, vx), np.interp(emissions, t, vy)])


def linear_tdoa_errors(states, transitions, jacobians, draws, filtered, predicted):
    """Errors of the exact Kalman filter and RTS smoother of a linear-Gaussian model whose
    measurements are the truth seen through ``jacobians`` plus the given whitened draws.

    The efficient estimator of :func:`kalman_covariances`' model on one realisation: the
    filter starts at the truth (its prior mean; the prior is forgotten after a few fixes),
    predicts with ``F``, and is corrected by ``z_k = H_k x_k + w_k``; its error recursion
    needs no ``z``: ``ε_{k|k-1} = F ε_{k-1|k-1} + (F x_{k-1} − x_k)`` (the path's own
    departure from the model's mean motion) and ``ε_{k|k} = ε_{k|k-1} + P_{k|k} H_kᵀ (w_k −
    H_k ε_{k|k-1})``; the smoother's is ``ε_{k|K} = ε_{k|k} + G_k (ε_{k+1|K} −
    ε_{k+1|k})``, ``G_k = P_{k|k} Fᵀ P_{k+1|k}⁻¹``.

    Parameters
    ----------
    states : numpy.ndarray, shape (K, n)
        The true state at each step.
    transitions : numpy.ndarray, shape (K - 1, n, n)
    jacobians, draws : sequences of K arrays, shapes (m_k, n) and (m_k,)
        Whitened measurement Jacobians and the whitened noise of the same rows.
    filtered, predicted : numpy.ndarray, each shape (K, n, n)
        From :func:`kalman_covariances` of the same model.

    Returns
    -------
    filter_errors, smoother_errors : numpy.ndarray, each shape (K, n)
        Estimate minus truth.
    """
    n_steps, n = states.shape
    ahead = np.zeros((n_steps, n))
    errors = np.zeros((n_steps, n))
    for k in range(n_steps):
        if k > 0:
            f = transitions[k - 1]
            ahead[k] = f @ errors[k - 1] + f @ states[k - 1] - states[k]
        h = jacobians[k]
        errors[k] = ahead[k] + filtered[k] @ h.T @ (draws[k] - h @ ahead[k])
    smoothed = errors.copy()
    for k in range(n_steps - 2, -1, -1):
        gain = np.linalg.solve(predicted[k + 1], (filtered[k] @ transitions[k].T).T).T
        smoothed[k] = errors[k] + gain @ (smoothed[k + 1] - ahead[k + 1])
    return errors, smoothed


def _whitened_ping(rows: np.ndarray, sigma: float, jitter_sd: float, eliminate: bool):
    """Whitened Jacobian ``H`` (m, n) of one ping's arrivals with covariance
    ``σ² I + jitter² 1 1ᵀ``: ``HᵀH = Jᵀ Σ⁻¹ J``, or with the emission time eliminated
    (``eliminate``) ``Jᵀ (Σ⁻¹ − Σ⁻¹ 1 1ᵀ Σ⁻¹ / 1ᵀ Σ⁻¹ 1) J``."""
    m = rows.shape[0]
    if m == 0:
        return rows
    lower = np.linalg.cholesky(sigma**2 * np.eye(m) + jitter_sd**2 * np.ones((m, m)))
    whitened = np.linalg.solve(lower, rows)
    if eliminate:  # project out the whitened direction of the common emission time
        w = np.linalg.solve(lower, np.ones(m))
        whitened = whitened - np.outer(w, w @ whitened) / (w @ w)
    return whitened


def _with_constants(blocks: np.ndarray, value: float = 1.0) -> np.ndarray:
    """(K, 4, 4) blocks padded to (K, 6, 6) with two constant states (``value`` on their
    diagonal: 1 for transitions, 0 for process noise)."""
    out = np.pad(blocks, ((0, 0), (0, 2), (0, 2)))
    out[:, 4, 4] = out[:, 5, 5] = value
    return out


def acceleration_psd_from_path(truth: pd.DataFrame, window: float) -> float:
    """White-noise acceleration intensity ``q`` (m²/s³) that matches a path's velocity changes.

    The path's mean velocity over consecutive windows of ``window`` seconds is compared
    window to window. For a nearly-constant-velocity model (velocity a Brownian motion of
    intensity ``q`` per axis) the difference of two consecutive window means has variance
    ``2·q·window / 3`` per axis, so ``q = 3·mean(Δv̄²) / (2·window)`` over both axes and
    all windows. A path that is not nearly-constant-velocity (turns, speed changes) gets
    the ``q`` that matches its velocity changes at that time scale; other scales give
    another ``q``.

    Parameters
    ----------
    truth : pandas.DataFrame
        ``time`` (s, increasing), ``x``, ``y`` (m).
    window : float
        Averaging window (s), e.g. the tag's period.
    """
    time = truth["time"].to_numpy(dtype=float)
    if not (window > 0 and time[-1] - time[0] >= 3 * window):
        raise ValueError(
            f"window must be positive and fit 3 times into the path's {time[-1] - time[0]} s, "
            f"got {window}"
        )
    edges = np.arange(time[0], time[-1] + 1e-9, window)
    means = [
        np.diff(np.interp(edges, time, truth[c].to_numpy(dtype=float))) / window for c in ("x", "y")
    ]
    changes = np.concatenate([np.diff(m) for m in means])
    return float(3.0 * np.mean(changes**2) / (2.0 * window))


def emission_clock_from_schedule(
    emission_times, jitter_sd: float, *, nominal_period: float | None = None
) -> EmissionClockModel:
    """The integrated-random-walk clock that best explains an emission schedule.

    Fits ``rate_step_sd`` of an :class:`~hmmtrack.tracking.measurement.clock.EmissionClockModel`
    whose period
    changes only through its rate (``period_step_sd = phase_step_sd = 0``) by maximum
    likelihood: a Kalman filter over the emission times observed with independent jitter
    ``jitter_sd``. This is how a bound gets a clock prior no looser than the truth's own
    clock; the fitted model also gets ``initial_rate_sd`` = the spread of the rate the
    fitted walk reaches over the schedule, and ``initial_period_sd`` = the spread of the
    schedule's local periods (but at least 1 µs).

    Parameters
    ----------
    emission_times : array_like, shape (K,)
        Consecutive emission times (s, no missing pings), K >= 20.
    jitter_sd : float
        Standard deviation of each emission's independent jitter (s, > 0).
    nominal_period : float, optional
        Default: the mean period of the schedule.

    Returns
    -------
    EmissionClockModel
    """
    times = np.asarray(emission_times, dtype=float)
    if times.ndim != 1 or times.size < 20 or np.any(np.diff(times) <= 0):
        raise ValueError("emission_times must be >= 20 strictly increasing times (s)")
    if not jitter_sd > 0:
        raise ValueError(f"jitter_sd must be positive (s), got {jitter_sd}")
    k = np.arange(times.size, dtype=float)
    mean_period = (times[-1] - times[0]) / (times.size - 1)
    deviation = times - times[0] - mean_period * k
    local_periods = np.diff(times[:: max(times.size // 20, 1)]) / max(times.size // 20, 1)

    def negative_loglik(log_rate_sd: float) -> float:
        return -_clock_loglik(deviation, jitter_sd, float(np.exp(log_rate_sd)))

    fit = minimize_scalar(negative_loglik, bounds=(np.log(1e-9), np.log(1e-3)), method="bounded")
    rate_step_sd = float(np.exp(fit.x))
    return EmissionClockModel(
        nominal_period or mean_period,
        period_step_sd=0.0,
        phase_step_sd=0.0,
        initial_period_sd=max(float(np.std(local_periods)), 1e-6),
        rate_step_sd=rate_step_sd,
        initial_rate_sd=rate_step_sd * np.sqrt(times.size),
    )


def _clock_loglik(deviation: np.ndarray, jitter_sd: float, rate_step_sd: float) -> float:
    """Gaussian log-likelihood of an emission schedule's deviation from a constant period
    under a rate random walk (state: deviation, period deviation, rate; diffuse start)."""
    transition = np.eye(3) + np.eye(3, k=1)
    noise = np.diag([0.0, 0.0, rate_step_sd**2])
    mean = np.array([deviation[0], 0.0, 0.0])
    covariance = np.diag([jitter_sd**2, 1e-4, 1e-8])
    total = 0.0
    for k in range(1, deviation.size):
        mean = transition @ mean
        covariance = transition @ covariance @ transition.T + noise
        innovation_var = covariance[0, 0] + jitter_sd**2
        residual = deviation[k] - mean[0]
        gain = covariance[:, 0] / innovation_var
        mean = mean + gain * residual
        covariance = covariance - np.outer(gain, covariance[0, :])
        if k >= 3:  # the first innovations only pin down the diffuse start
            total -= 0.5 * (np.log(2 * np.pi * innovation_var) + residual**2 / innovation_var)
    return total


def _detection_jacobians(tracks, tag, emissions, clock_states, sound_speed, detection):
    """Whitened rows ``sqrt(I(r))·u_jᵀ`` per ping for every listening receiver."""
    names = np.array(tracks.names)
    n_pings = emissions.size
    pairs_ping = np.repeat(np.arange(n_pings), names.size)
    pairs_name = np.tile(names, n_pings)
    listening = np.ones(pairs_ping.size, dtype=bool)
    for name in names:  # a mobile receiver listens within its track's span
        start, end = tracks.span(str(name))
        rows = pairs_name == name
        reach = emissions[pairs_ping[rows]]
        listening[rows] = (reach >= start) & (reach + MAX_FLIGHT_TIME <= end)
    pairs_ping, pairs_name = pairs_ping[listening], pairs_name[listening]
    tag_xy = tag[pairs_ping]
    receiver_xy = _receiver_positions(
        tracks, pairs_name, tag_xy, emissions[pairs_ping], sound_speed
    )
    offset = tag_xy - receiver_xy
    distance = np.maximum(np.hypot(offset[:, 0], offset[:, 1]), 1e-9)
    rows = np.zeros((distance.size, 4 + clock_states))
    # hearing depends on the range only, not on the velocity or the clock
    rows[:, POSITION] = (
        offset * np.sqrt(detection_information(detection, distance) / distance**2)[:, None]
    )
    return _by_ping(rows, pairs_ping, emissions.size)


def _position_bound(covariances: np.ndarray) -> np.ndarray:
    return np.sqrt(covariances[:, 0, 0] + covariances[:, 1, 1])


def _validated_emissions(emission_times, truth: pd.DataFrame) -> np.ndarray:
    emissions = np.asarray(emission_times, dtype=float)
    if emissions.ndim != 1 or emissions.size < 2:
        raise ValueError(f"emission_times must be 1-D with >= 2 pings, got {emissions.shape}")
    if not np.all(np.isfinite(emissions)) or np.any(np.diff(emissions) <= 0):
        raise ValueError("emission_times must be finite and strictly increasing")
    missing = [c for c in ("time", "x", "y") if c not in truth]
    if missing:
        raise ValueError(f"truth: missing column(s) {missing}; expected time, x, y")
    t = truth["time"].to_numpy(dtype=float)
    if np.any(np.diff(t) <= 0):
        raise ValueError("truth: column time must be strictly increasing")
    outside = np.flatnonzero((emissions < t[0]) | (emissions > t[-1]))
    if outside.size:
        raise ValueError(
            f"emission_times: pings {outside[:5].tolist()} (of {outside.size}) fall outside "
            f"the truth's time span [{t[0]}, {t[-1]}]"
        )
    return emissions


def _validated_heard(heard: pd.DataFrame, n_pings: int):
    missing = [c for c in ("ping", "receiver") if c not in heard]
    if missing:
        raise ValueError(f"heard: missing column(s) {missing}; expected ping, receiver")
    ping = heard["ping"].to_numpy()
    if ping.size and not np.issubdtype(ping.dtype, np.integer):
        raise ValueError(f"heard: column ping must hold integers, got dtype {ping.dtype}")
    ping = ping.astype(np.int64)
    bad = np.flatnonzero((ping < 0) | (ping >= n_pings))
    if bad.size:
        raise ValueError(
            f"heard rows {bad[:5].tolist()}: column ping must index emission_times "
            f"(0 … {n_pings - 1})"
        )
    names = heard["receiver"].astype(str).to_numpy()
    pairs = pd.DataFrame({"ping": ping, "receiver": names})
    duplicated = np.flatnonzero(pairs.duplicated().to_numpy())
    if duplicated.size:
        raise ValueError(
            f"heard rows {duplicated[:5].tolist()}: the same ping heard twice by one receiver"
        )
    return ping, names


def _receiver_positions(tracks, names, tag_xy, emitted, sound_speed) -> np.ndarray:
    """Receiver positions (M, 2) at each detection's arrival.

    The flight time solves ``c·s = |tag − receiver(emitted + s)|`` by fixed-point
    iteration; each step shrinks the error by the receiver's speed over ``c`` (< 1e-2 for
    vehicles), so three steps are exact to rounding for any vehicle.
    """
    out = np.empty((names.size, 2))
    for name in pd.unique(names):
        rows = names == name
        flight = np.zeros(int(rows.sum()))
        for _ in range(4):
            x, y, _, _ = tracks.state(str(name), emitted[rows] + flight)
            flight = np.hypot(tag_xy[rows, 0] - x, tag_xy[rows, 1] - y) / sound_speed
        out[rows] = np.column_stack([x, y])
    return out


def static_tag_fisher_information(
    observations: pd.DataFrame, x: float, y: float, covariance
) -> np.ndarray:
    """Fisher information on a fixed tag's position from (range, range-rate) observations.

    Each observation is ``z = (r, ṙ)`` with ``r = |p_h − p|`` and
    ``ṙ = u·v_h`` (``u = (p_h − p)/r``, ``v_h`` the hydrophone's velocity; the tag does not
    move), observed with Gaussian noise of covariance Σ_z, independent between
    observations. With the Jacobian ``H = ∂z/∂p = −[uᵀ; (v_h − ṙ u)ᵀ / r]`` the information
    is ``Σ_k H_kᵀ Σ_z⁻¹ H_k``.

    Parameters
    ----------
    observations : pandas.DataFrame
        ``receiver_x``, ``receiver_y`` (m), ``receiver_vx``, ``receiver_vy`` (m/s) of each
        scored observation (rows without a range-rate, the anchors, should be left out).
    x, y : float
        The tag's position (m).
    covariance : array_like, shape (2, 2)
        Σ_z of (range m, range-rate m/s).

    Returns
    -------
    numpy.ndarray, shape (2, 2)
        Information matrix (m⁻²); its inverse is the Cramér–Rao bound
        (:func:`static_tag_crb`).
    """
    hx, hy, vx, vy = finite_columns(
        observations, "observations", ("receiver_x", "receiver_y", "receiver_vx", "receiver_vy")
    )
    precision = np.linalg.inv(np.asarray(covariance, dtype=float))
    dx, dy = hx - x, hy - y
    r = np.hypot(dx, dy)
    if np.any(r <= 0):
        raise ValueError("the tag position coincides with a receiver; the bound is undefined")
    ux, uy = dx / r, dy / r
    rate = ux * vx + uy * vy
    jacobian = np.empty((r.size, 2, 2))  # (k, measurement, coordinate)
    jacobian[:, 0, 0], jacobian[:, 0, 1] = -ux, -uy
    jacobian[:, 1, 0] = -(vx - rate * ux) / r
    jacobian[:, 1, 1] = -(vy - rate * uy) / r
    return np.einsum("kmi,mn,knj->ij", jacobian, precision, jacobian)


def static_tag_crb(observations: pd.DataFrame, x: float, y: float, covariance) -> np.ndarray:
    """Cramér–Rao bound on a fixed tag's position: the inverse Fisher information.

    Parameters
    ----------
    observations, x, y, covariance
        See :func:`static_tag_fisher_information`.

    Returns
    -------
    numpy.ndarray, shape (2, 2)
        Lower bound (m²) on the covariance of any unbiased estimate of ``(x, y)`` from these
        observations; ``sqrt(trace)`` bounds the RMS position error. ``inf`` entries when the
        geometry leaves a direction unobserved (singular information).
    """
    information = static_tag_fisher_information(observations, x, y, covariance)
    eigenvalues = np.linalg.eigvalsh(information)
    if eigenvalues[0] <= 1e-12 * max(eigenvalues[-1], 1e-300):
        return np.full((2, 2), np.inf)
    return np.linalg.inv(information)


def _static_measurements(receivers, x: float, y: float) -> np.ndarray:
    """(range, range-rate) of a fixed tag at (x, y) from receivers ``(x, y, vx, vy)``."""
    hx, hy, vx, vy = receivers
    dx, dy = hx - x, hy - y
    r = np.hypot(dx, dy)
    rate = np.divide(dx * vx + dy * vy, r, out=np.zeros_like(r), where=r > 0)
    return np.column_stack([r, rate])


def static_tag_fit(observations: pd.DataFrame, start, covariance) -> tuple[np.ndarray, float]:
    """Weighted least-squares position of a fixed tag from (range, range-rate) observations.

    Minimises ``Σ_k (z_k − h_k(p))ᵀ Σ_z⁻¹ (z_k − h_k(p))`` over the position ``p`` (the
    measurement model of :func:`static_tag_fisher_information`) with Levenberg–Marquardt
    from ``start``; with two range circles the cost can have a second local minimum near
    their other intersection, so the start chooses which minimum is found.

    Parameters
    ----------
    observations : pandas.DataFrame
        ``range`` (m), ``range_rate`` (m/s), ``receiver_x``, ``receiver_y`` (m),
        ``receiver_vx``, ``receiver_vy`` (m/s) of the scored observations.
    start : array_like, shape (2,)
        Starting position (m).
    covariance : array_like, shape (2, 2)
        Σ_z of (range m, range-rate m/s).

    Returns
    -------
    position : numpy.ndarray, shape (2,)
        The fitted ``(x, y)`` (m).
    chi2 : float
        The minimised cost (dimensionless).
    """
    (measured_range, measured_rate) = finite_columns(
        observations, "observations", ("range", "range_rate")
    )
    measured = np.column_stack([measured_range, measured_rate])
    receivers = finite_columns(
        observations, "observations", ("receiver_x", "receiver_y", "receiver_vx", "receiver_vy")
    )
    whitener = np.linalg.cholesky(np.linalg.inv(np.asarray(covariance, dtype=float)))

    def residuals(p):
        return ((_static_measurements(receivers, *p) - measured) @ whitener).ravel()

    fit = least_squares(residuals, np.asarray(start, dtype=float), method="lm")
    return fit.x, float(2.0 * fit.cost)
