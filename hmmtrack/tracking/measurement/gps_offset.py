"""Ranges and range-rates with the receivers' GPS error correlated in time (Rao-Blackwellised).

:class:`GpsOffsetMeasurement` is the ``"range-rate-gps"`` measurement of
:data:`hmmtrack.tracking.measurement.MEASUREMENTS`: the observations, search box, events and
recovery of the paper's :class:`~hmmtrack.tracking.measurement.range_rate.RangeRateMeasurement`,
with another noise model for the range.

Why. A receiver's logged position carries its GPS error, which wanders over about a minute,
so consecutive pings (8 s apart) see nearly the same error: the paper's likelihood, which
treats each ping as independent, must use a range sd several times the error's own (5 m
against 1.3 m) so as not to over-count them, and a cloud that stops forgetting old pings (a
still tag) is then either too wide (5 m) or overconfident (1.3 m; reports/decisions.md,
"Calibration after convergence"). Here the error is in the model instead.

The model. Receiver ``k``'s range error is a slowly varying offset ``b_k(t)`` plus white noise,

    r_obs = |x - rx_k| + b_k(t) + w,    w ~ N(0, sigma_white^2),

where ``b_k`` is the projection of the receiver's GPS error on the line of sight: an
Ornstein-Uhlenbeck process of stationary sd ``gps_sd`` and time constant
``gps_correlation_time`` (``tau``), so between two of the receiver's pings ``dt`` apart

    b_k(t + dt) = rho b_k(t) + N(0, (1 - rho^2) gps_sd^2),    rho = exp(-dt / tau).

A moored receiver's position is one fix (one logged row), whose error never decorrelates:
its offset is constant (``rho = 1``), a run-long bias that the filter learns but does not
average away. Taking the scalar projection as an AR(1) of its own ignores the turning of the
line of sight between pings (a few degrees per ping at the ranges of the paper's datasets);
the white noise holds the emission jitter and what that approximation leaves.

Given a particle's position the offsets are linear-Gaussian, so they are integrated out by a
Kalman filter per particle and receiver (Rao-Blackwellisation): each particle carries the
offsets' posterior means (fields ``gps_offset_0 .. gps_offset_{R-1}``, one per receiver of
the observations, resampled with the particle), and the posterior variance ``P_k``, which
does not depend on the particle's position, is the run state. A correction scores each
particle by the Kalman predictive density

    N(r_obs; |x - rx_k| + rho m_k, rho^2 P_k + (1 - rho^2) gps_sd^2 + sigma_white^2)

and commits the Kalman update of ``m_k`` and ``P_k`` once the weights are final. A receiver's
first scored ping starts from the stationary prior (mean 0, variance ``gps_sd^2``). Without
the run state (:meth:`GpsOffsetMeasurement.loglik`, used by the acquisition's grid and the
recovery on a range ring) the offsets are at that prior: the paper's likelihood with a range
variance of ``gps_sd^2 + sigma_white^2``.

The translation move. The offsets' means are learned along each particle's whole path, so
once the cloud has converged a moored receiver's constant offset is a static parameter: the
boat's range ties each particle's position along its line of sight to its own offset mean, the
motion noise re-spreads positions but not those means, and resampling alone thins them out
until a 1,000-particle cloud sits, too narrow, a few metres off (reports/decisions.md, "The
still tag's collapse"). The motion models are translation-invariant, so moving a particle's
whole path by ``δ`` leaves its prior unchanged and changes only its likelihood; to first order
in ``δ`` (each predicted range changes by ``u · δ``, ``u`` the unit vector from the receiver
to the particle at that ping) each innovation changes by ``h · δ`` and each offset mean by
``a_k · δ``, where

    h = -u - rho a_k,    a_k <- rho a_k + gain h,

so the log-likelihood of all the particle's pings along the translation is the quadratic
``G · δ - δ' I δ / 2`` with ``G = -Σ innovation h / S`` and ``I = Σ h h' / S``, carried per
particle (fields ``gps_slope_{k}_x/y`` for ``a_k``, ``gps_gradient_x/y``,
``gps_information_xx/xy/yy``). After every :data:`TRANSLATION_EVERY`-th correction every
particle draws its translation from that conditional, ``N(I⁻¹ G, I⁻¹)`` along each
eigenvector of ``I`` whose posterior sd is under :data:`MAX_TRANSLATION` (a generalised Gibbs
step, Liu & Sabatti 2000), and stays in place when the draw is longer than that: this leaves
the weighted posterior unchanged up to the linearisation and re-draws the offsets' means with
the positions. It leaves out the range-rates' change with the line of sight (``|v| |δ| / r``:
0.01 m/s for 1 m/s, 1 m, 100 m), the edge of the start region, and the moves that change
positions without the offsets (the tempering's ``regularisation_move``, a recovery's
re-placed particles), whose paths it then translates as if they had not jumped.

The range-rate stays white (sd ``sigma_range_rate``, uncorrelated with the range): the
observed rate comes from arrival times, which carry no GPS error, and the GPS error enters the
predicted rate only through the receiver's velocity, averaged over 20 s of fixes
(``velocity_window``): ``gps_sd sqrt(2 (1 - exp(-20 / tau))) / 20 s`` = 0.06 m/s for the
defaults, against the 0.5 m/s sd, and correlated over two or three pings at most.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.measurement.base import Score
from hmmtrack.tracking.measurement.range_rate import (
    RangeRateMeasurement,
    RangeRateSettings,
    predicted_row,
)
from hmmtrack.tracking.particles import Particles
from hmmtrack.tracking.receivers import ReceiverTracks
from hmmtrack.tracking.settings import positive, setting
from hmmtrack.tracking.tempering import Tempered

__all__ = [
    "GpsOffsetMeasurement",
    "GpsOffsetSettings",
    "OffsetState",
    "offset_steps",
    "translate",
]

#: stationary sd (m) of a receiver's GPS error along any horizontal direction: a consumer or
#: SBAS-aided receiver's horizontal error of 2-2.5 m rms is 1.4-1.8 m per axis (the
#: simulators' :data:`hmmtrack.scenarios.paper.HYDROPHONE_GPS` draws 1.5 m, 60 s)
GPS_SD = 1.5
#: e-folding time (s) of the GPS error: multipath and atmospheric errors of a GPS fix wander
#: over about a minute
GPS_CORRELATION_TIME = 60.0
#: the ESS fraction each tempered step keeps by default: a range known to a metre against a
#: start region hundreds of metres wide leaves a handful of particles in one pass
#: (reports/decisions.md, "Correlated GPS error in the measurement", "The gps measurement's
#: cost and calibration")
GPS_TEMPERING_ESS = 0.3
#: the one-pass ESS fraction below which a correction is tempered by default: above it the
#: correction is applied in one pass, as the paper's, which keeps the converged filter's cost
#: at today's (reports/decisions.md, "The gps measurement's cost and calibration")
GPS_TEMPERING_TRIGGER = 0.05
#: sd (m) of the range error that is independent from ping to ping: the emission jitter
#: (0.15-0.2 m) and what the model leaves out (the turning line of sight, detections taken at
#: the filter's 1 s steps); 0.5 m made the still tag's regions overconfident
#: (reports/decisions.md, "Correlated GPS error in the measurement")
SIGMA_WHITE = 1.0
#: longest translation (m) a particle is moved by (a longer draw leaves it in place, which keeps
#: the move reversible), and the largest posterior sd of a direction it is moved along: the
#: linearised ranges' second-order term δ²/2r is 0.09 m for 3 m at 50 m, and before
#: convergence the draws would be tens of metres, where the linearisation fails
MAX_TRANSLATION = 3.0
#: the particles are translated after every this many corrections (the first included): a
#: cloud's offsets' means thin out over hundreds of resamplings, and on held-out seeds a move
#: every 16 removed the still tag's collapses as one every correction did, at a quarter of
#: the cost (reports/decisions.md, "The still tag's collapse")
TRANSLATION_EVERY = 4
#: the particle fields of one translation's log-likelihood: gradient and information
TRANSLATION_FIELDS = (
    "gps_gradient_x",
    "gps_gradient_y",
    "gps_information_xx",
    "gps_information_xy",
    "gps_information_yy",
)


@dataclass(frozen=True)
class GpsOffsetSettings(RangeRateSettings):
    """The ``measurement`` section of the ``"range-rate-gps"`` measurement: the range-rate
    section's keys (``sigma_range`` unused: the range's error is the GPS offset and
    ``sigma_white``; ``range_rate_correlation`` must be 0: the range-rate's error is
    independent of the range's), and the receivers' GPS error.

    Parameters
    ----------
    gps_sd : float
        Stationary sd (m) of a receiver's GPS error along a line of sight.
    gps_correlation_time : float
        Its e-folding time ``tau`` (s).
    sigma_white : float
        Sd (m) of the range error independent from ping to ping. A key of its own, not the
        paper's ``sigma_range``: a configuration switched from ``range-rate`` keeps that
        key's value (5 m), which would silently be taken for this one.
    """

    name: ClassVar[str] = "range-rate-gps"

    gps_sd: float = setting(
        GPS_SD,
        help="sd of a receiver's GPS error along a line of sight (m)",
        check=positive,
        parse=float,
        metavar="METRES",
    )
    gps_correlation_time: float = setting(
        GPS_CORRELATION_TIME,
        help="e-folding time of the receivers' GPS error (s)",
        check=positive,
        parse=float,
        metavar="SECONDS",
    )
    sigma_white: float = setting(
        SIGMA_WHITE,
        help="sd of the range error independent from ping to ping (m)",
        check=positive,
        parse=float,
        metavar="METRES",
    )

    def validate(self) -> None:
        """The range and range-rate errors are independent here."""
        if self.range_rate_correlation != 0.0:
            raise ValueError(
                "range_rate_correlation must be 0 for the range-rate-gps measurement (its "
                f"range and range-rate errors are independent), got {self.range_rate_correlation}"
            )


@dataclass
class OffsetState:
    """A run's shared part of the offsets' Kalman filters, one entry per receiver.

    Attributes
    ----------
    variance : (R,) float
        Posterior variance ``P_k`` (m²) of receiver ``k``'s offset after its latest ping.
    time : (R,) float
        Time (s) of that ping; NaN before the receiver's first scored ping.
    corrections : int
        Corrections scored and committed so far (every :data:`TRANSLATION_EVERY`-th moves).
    """

    variance: np.ndarray
    time: np.ndarray
    corrections: int = 0


def offset_steps(state: OffsetState, receiver: np.ndarray, time: float, gps_sd, tau, white):
    """The shared Kalman scalars of one correction's rows, in order.

    Parameters
    ----------
    state : OffsetState
        Before the correction (not changed).
    receiver : (M,) int
        Receiver index of each row.
    time : float
        The correction's time (s).
    gps_sd, white : float
        ``gps_sd`` and ``sigma_white`` (m).
    tau : (R,) float
        Each receiver's correlation time (s; ``inf``: a moored receiver's constant offset).

    Returns
    -------
    rho, predictive, gain : (M,) float
        The AR(1) factor of each row's offset since the receiver's previous row (0 at its
        first: the stationary prior), the predictive variance ``S`` (m²) of its range and the
        Kalman gain ``P_pred / S``.
    after : OffsetState
        The state after the rows.
    """
    rho, predictive, gain, variance, last = _offset_steps(
        state.variance, state.time, receiver, float(time), float(gps_sd), tau, float(white)
    )
    return rho, predictive, gain, OffsetState(variance, last)


@njit(cache=True)
def _offset_steps(variance, last, receiver, time, gps_sd, tau, white):
    """:func:`offset_steps` on the state's arrays (copied, not changed): ``rho``,
    ``predictive``, ``gain`` (M,) and the variances and times (R,) after the rows."""
    variance, last = variance.copy(), last.copy()
    m = receiver.size
    rho, predictive, gain = np.empty(m), np.empty(m), np.empty(m)
    for j in range(m):
        k = receiver[j]
        rho[j] = 0.0 if np.isnan(last[k]) else math.exp(-(time - last[k]) / tau[k])
        prior = rho[j] ** 2 * variance[k] + (1.0 - rho[j] ** 2) * gps_sd**2
        predictive[j] = prior + white**2
        gain[j] = prior / predictive[j]
        variance[k] = prior * white**2 / predictive[j]
        last[k] = time
    return rho, predictive, gain, variance, last


@dataclass(frozen=True, eq=False)
class GpsOffsetMeasurement(RangeRateMeasurement):
    """Ranges with a per-receiver GPS offset integrated out by a Kalman filter per particle
    (module docstring), range-rates white.

    Parameters
    ----------
    covariance : (2, 2) array_like
        The likelihood without run state (offsets at their stationary prior):
        ``diag(gps_sd² + sigma_white², sigma_range_rate²)``, m², m²/s².
    receivers : tuple of str
        The receivers whose offsets the particles carry, in field order.
    moored : tuple of bool
        Whether each receiver is moored (its offset constant); default none.
    gps_sd, gps_correlation_time : float
        As :class:`GpsOffsetSettings`.
    sigma_white : float
        As :class:`GpsOffsetSettings`.
    """

    receivers: tuple[str, ...] = ()
    moored: tuple[bool, ...] = ()
    gps_sd: float = GPS_SD
    gps_correlation_time: float = GPS_CORRELATION_TIME
    sigma_white: float = SIGMA_WHITE
    name: ClassVar[str] = "range-rate-gps"
    settings: ClassVar[type] = GpsOffsetSettings
    #: tempered below the trigger, the moves within the mixture's components: the start
    #: region holds the tag and its mirror across the receivers' line, and a move shaped by
    #: the whole cloud merged them (reports/decisions.md, "The mirror merged by the tempered
    #: move")
    default_correction: ClassVar[Tempered] = Tempered(
        GPS_TEMPERING_ESS, GPS_TEMPERING_TRIGGER, within_components=True
    )
    _index: dict = field(init=False, repr=False, compare=False)
    _tau: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.covariance[0, 1] != 0.0:
            raise ValueError("the range and range-rate errors must be uncorrelated")
        object.__setattr__(self, "receivers", tuple(str(r) for r in self.receivers))
        moored = tuple(bool(m) for m in self.moored) or (False,) * len(self.receivers)
        if len(moored) != len(self.receivers):
            raise ValueError(
                f"moored has {len(moored)} entries for {len(self.receivers)} receivers"
            )
        object.__setattr__(self, "moored", moored)
        object.__setattr__(self, "_index", {r: k for k, r in enumerate(self.receivers)})
        tau = np.where(moored, np.inf, self.gps_correlation_time).astype(np.float64)
        object.__setattr__(self, "_tau", tau)

    @classmethod
    def of(
        cls,
        receivers,
        sigma_range_rate: float,
        gps_sd: float = GPS_SD,
        gps_correlation_time: float = GPS_CORRELATION_TIME,
        sigma_white: float = SIGMA_WHITE,
        moored=(),
    ) -> GpsOffsetMeasurement:
        """The measurement of these receivers (``moored``: which are) and noise levels (m,
        m/s, s)."""
        covariance = np.diag([gps_sd**2 + sigma_white**2, sigma_range_rate**2])
        return cls(
            covariance, tuple(receivers), tuple(moored), gps_sd, gps_correlation_time, sigma_white
        )

    @classmethod
    def from_settings(
        cls, settings: GpsOffsetSettings, observations: pd.DataFrame, receivers=None
    ) -> GpsOffsetMeasurement:
        """The measurement of ``settings`` for the receivers of ``observations``; which
        are moored is read from ``receivers`` (a positions table or
        :class:`~hmmtrack.tracking.receivers.ReceiverTracks`; ``None``: none is)."""
        names = pd.unique(observations["receiver"].astype(str))
        moored = ()
        if receivers is not None:
            tracks = (
                receivers
                if isinstance(receivers, ReceiverTracks)
                else ReceiverTracks.from_frame(receivers, velocity_window=settings.velocity_window)
            )
            moored = tuple(tracks.is_moored(name) for name in names)
        return cls.of(
            names,
            settings.sigma_range_rate,
            settings.gps_sd,
            settings.gps_correlation_time,
            settings.sigma_white,
            moored,
        )

    @property
    def fields(self) -> tuple[str, ...]:
        """The particle fields the measurement owns, in the kernel's order: the offsets' means
        (m, ``gps_offset_k``), their change per metre of a translation of the particle's path
        (``a_k``: ``gps_slope_k_x``, ``gps_slope_k_y``, receiver by receiver), and the
        translation's gradient and information (:data:`TRANSLATION_FIELDS`)."""
        r = range(len(self.receivers))
        means = tuple(f"gps_offset_{k}" for k in r)
        slopes = tuple(f"gps_slope_{k}_{c}" for k in r for c in "xy")
        return means + slopes + TRANSLATION_FIELDS

    def as_matrix(self, obs) -> np.ndarray:
        """Observations as an (M, 7) float matrix: :data:`RANGE_RATE_COLUMNS` and the
        receiver's index in :attr:`receivers` (an array is taken as already converted)."""
        if isinstance(obs, np.ndarray):
            return obs
        receiver = [self._index[str(r)] for r in np.asarray(obs["receiver"])]
        return np.column_stack([RangeRateMeasurement.as_matrix(obs), receiver])

    def start(self, particles: Particles, time: float, dt: float = 1.0) -> OffsetState:
        """Offsets' means and their translation terms 0 in every particle; variances at the
        prior, no ping yet."""
        for name in self.fields:
            particles.extra[name] = np.zeros(particles.n)
        r = len(self.receivers)
        return OffsetState(np.full(r, self.gps_sd**2), np.full(r, np.nan))

    def score(self, particles: Particles, rows: np.ndarray, time: float, state, weights):
        """The Kalman predictive log density of the rows for every particle; the offsets'
        Kalman update is committed once the weights are final."""
        rows = self.as_matrix(rows)
        steps = offset_steps(
            state,
            rows[:, 6].astype(np.int64),
            time,
            self.gps_sd,
            self._tau,
            self.sigma_white,
        )
        latest = []
        names = self.fields

        def scored(particles, weights=None):
            p = particles
            carried = tuple(p.extra[name] for name in names)
            loglik, updated = offset_loglik(
                p.x, p.y, p.cos_heading, p.sin_heading, p.speed, np.ascontiguousarray(rows),
                carried, *steps[:3], float(self.covariance[1, 1]),
            )  # fmt: skip
            latest[:] = [updated]
            return loglik

        def commit(particles):
            for k, name in enumerate(names):
                particles.extra[name] = latest[0][k]
            state.variance, state.time = steps[3].variance, steps[3].time

        def move(particles, rng):
            if state.corrections % TRANSLATION_EVERY == 0:
                translate(particles, len(self.receivers), rng.standard_normal((2, particles.n)))
            state.corrections += 1

        return Score(scored(particles), rescore=scored, commit=commit, move=move)


def translate(particles: Particles, n_receivers: int, normals: np.ndarray) -> None:
    """Move each particle's path by a translation drawn from its conditional posterior, in
    place (the module docstring's translation move): positions, offsets' means and the
    translation's gradient change, ``a_k`` and the information do not.

    Parameters
    ----------
    particles : Particles
        With the fields of :meth:`GpsOffsetMeasurement.start`.
    n_receivers : int
    normals : (2, N) float
        Standard normal draws.
    """
    e = particles.extra
    means = tuple(e[f"gps_offset_{k}"] for k in range(n_receivers))
    slopes = tuple(e[f"gps_slope_{k}_{c}"] for k in range(n_receivers) for c in "xy")
    _translate(
        particles.x, particles.y, *(e[name] for name in TRANSLATION_FIELDS), means, slopes,
        normals, MAX_TRANSLATION,
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _translate(x, y, gx, gy, ixx, ixy, iyy, means, slopes, normals, longest):
    """:func:`translate` on arrays, in place (``means``: R arrays (N,); ``slopes``: 2R, x
    and y of each receiver in turn). Per particle the eigenvectors ``v`` of the 2 × 2
    information ``I``; along each with eigenvalue ``λ ≥ 1 / longest²`` a step
    ``t = v · G / λ + z / √λ``; none when the steps' sum is longer than ``longest`` (m)."""
    floor = 1.0 / (longest * longest)
    for i in range(x.size):
        a, b, c = ixx[i], ixy[i], iyy[i]
        half_trace = 0.5 * (a + c)
        root = math.sqrt(0.25 * (a - c) ** 2 + b * b)
        dx = dy = 0.0
        for e in range(2):
            lam = half_trace + root if e == 0 else half_trace - root
            if lam < floor:
                continue
            if b != 0.0:  # eigenvector of [[a, b], [b, c]] for lam
                vx, vy = lam - c, b
                norm = math.sqrt(vx * vx + vy * vy)
                vx, vy = vx / norm, vy / norm
            elif (a >= c) == (e == 0):
                vx, vy = 1.0, 0.0
            else:
                vx, vy = 0.0, 1.0
            t = (vx * gx[i] + vy * gy[i]) / lam + normals[e, i] / math.sqrt(lam)
            dx += t * vx
            dy += t * vy
        if dx * dx + dy * dy > longest * longest:
            continue
        x[i] += dx
        y[i] += dy
        for k in range(len(means)):
            means[k][i] += slopes[2 * k][i] * dx + slopes[2 * k + 1][i] * dy
        gx[i] -= a * dx + b * dy
        gy[i] -= b * dx + c * dy


def offset_loglik(
    x, y, cos_heading, sin_heading, speed, rows, carried, rho, predictive, gain, rate_var
):
    """Per-particle log-likelihood (N,) and the updated carried fields (a tuple of F arrays
    (N,)) of one correction from ``carried`` (the same): the R offsets' means, their 2R slopes
    ``a_k`` and the translation's gradient (2) and information (3) (:func:`_offset_kernel`)."""
    loglik = np.empty(x.size)
    updated = tuple(np.empty(x.size) for _ in carried)
    _offset_kernel(
        x, y, cos_heading, sin_heading, speed, rows, carried, rho, predictive, gain, rate_var,
        loglik, updated,
    )  # fmt: skip
    return loglik, updated


@njit(cache=True, nogil=True)
def _offset_kernel(
    x, y, cos_heading, sin_heading, speed, z, carried, rho, predictive, gain, rate_var, out,
    updated,
):  # fmt: skip
    """For every particle: the Kalman predictive log density of each row ``j`` of ``z``
    ((M, 7): :data:`RANGE_RATE_COLUMNS` and the receiver index ``k``; the predicted range and
    range-rate :func:`~hmmtrack.tracking.measurement.range_rate.predicted_row`) with offset mean
    ``rho[j] * m_k`` and variance ``predictive[j]``, plus the white range-rate's (variance
    ``rate_var``), summed into ``out`` (N,); the carried fields after each row's update into
    ``updated`` (F arrays (N,)), from ``carried`` (the same: the R means, then ``a_k``'s x and
    y per receiver, then the translation's gradient x, y and information xx, xy, yy): the mean
    ``m_k + gain[j] * innovation``, ``a_k + gain[j] * h`` and the gradient and information
    of the innovation's sensitivity ``h = -u - rho[j] a_k`` (module docstring)."""
    n_fields = len(carried)
    r = (n_fields - 5) // 3
    g = 3 * r  # first translation field
    local = np.empty(n_fields)
    rate_norm = -0.5 * math.log(2.0 * math.pi * rate_var)
    range_norm = np.empty(z.shape[0])
    for j in range(z.shape[0]):
        range_norm[j] = math.log(2.0 * math.pi * predictive[j])
    for i in range(x.size):
        for f in range(n_fields):
            local[f] = carried[f][i]
        vx = speed[i] * cos_heading[i]
        vy = speed[i] * sin_heading[i]
        total = 0.0
        for j in range(z.shape[0]):
            k = int(z[j, 6])
            r_hat, r_dot_hat = predicted_row(z, j, x[i], y[i], vx, vy)
            ux = (x[i] - z[j, 2]) / r_hat if r_hat > 0 else 0.0
            uy = (y[i] - z[j, 3]) / r_hat if r_hat > 0 else 0.0
            sx = r + 2 * k  # a_k's fields
            hx = -ux - rho[j] * local[sx]
            hy = -uy - rho[j] * local[sx + 1]
            mean = rho[j] * local[k]
            innovation = z[j, 0] - r_hat - mean
            total += -0.5 * (range_norm[j] + innovation * innovation / predictive[j])
            local[k] = mean + gain[j] * innovation
            local[sx] = rho[j] * local[sx] + gain[j] * hx
            local[sx + 1] = rho[j] * local[sx + 1] + gain[j] * hy
            scaled = innovation / predictive[j]
            local[g] -= scaled * hx
            local[g + 1] -= scaled * hy
            local[g + 2] += hx * hx / predictive[j]
            local[g + 3] += hx * hy / predictive[j]
            local[g + 4] += hy * hy / predictive[j]
            e_v = r_dot_hat - z[j, 1]
            total += rate_norm - 0.5 * e_v * e_v / rate_var
        for f in range(n_fields):
            updated[f][i] = local[f]
        out[i] = total
