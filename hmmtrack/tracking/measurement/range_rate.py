"""The paper's measurement: ranges and range-rates from the tag period and known initial ranges.

:class:`RangeRateMeasurement` is the ``"range-rate"`` measurement of
:data:`hmmtrack.tracking.measurement.MEASUREMENTS` (the
:class:`hmmtrack.tracking.measurement.base.Measurement` protocol): it builds the observations
table from detections (:meth:`RangeRateMeasurement.observations`: ranges and range-rates of
:mod:`hmmtrack.tracking.measurement.ranging`, optionally depth-corrected, joined with the
detecting receiver's position and velocity), derives the search box from the known initial
ranges (:func:`search_bounds`, :func:`check_bounds`), recovers degenerate weights on a range
ring, and scores particles.

Its likelihood is the paper's (section "Correction Step"): each observation
``z_j = (r, r_dot)`` from hydrophone ``j`` is Gaussian around the particle's predicted range
and range-rate,

    r_hat = sqrt((x_h - x)^2 + (y_h - y)^2)
    r_dot_hat = ((x_h - x)(vx_h - vx) + (y_h - y)(vy_h - vy)) / r_hat

with the particle's velocity ``(vx, vy) = speed * (cos heading, sin heading)`` and a fixed
covariance ``Sigma_z``, simultaneous observations independent (their log densities add).
A positive range-rate means the tag and hydrophone move apart. The first detection
of each receiver anchors its ranges (its range is the given ``r0``) but has no range-rate,
so it is not passed to the likelihood (:meth:`RangeRateMeasurement.split` makes it an
``"anchor_detection"`` event).

The log-likelihood is a compiled loop over particles and observations, on the (M, 6) matrix
form of the observations (:meth:`RangeRateMeasurement.as_matrix`: the filter converts a
whole run's observations once and scores row slices), chunk by chunk
(:func:`hmmtrack.tracking.compiled.weighing.chunk_loglik` of :class:`RangeRateTerms`): the
filter's correction runs it inside its weighing pass (:meth:`RangeRateMeasurement.loglik_terms`),
:meth:`RangeRateMeasurement.loglik` on its own, on the threads of the enclosing
:func:`~hmmtrack.tracking.compiled.chunks.default_threads` block, else on one (the same
values on any number);
:func:`predicted_range_and_rate` is the same prediction in NumPy (for tests and plots).

This module does not resample or move particles, and does not compute ranges from
detection times (that is :mod:`hmmtrack.tracking.measurement.ranging`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
import pandas as pd
from numba import njit, types
from numba.extending import overload

from hmmtrack.tracking.compiled.weighing import chunk_loglik, loglik_chunks
from hmmtrack.tracking.measurement import ranging
from hmmtrack.tracking.measurement.base import (
    EVENT_COLUMNS,
    Bounds,
    no_events,
    period_setting,
    sound_speed_setting,
)
from hmmtrack.tracking.particles import Particles
from hmmtrack.tracking.receivers import ReceiverTracks
from hmmtrack.tracking.resampling import log_normalise
from hmmtrack.tracking.settings import Settings, non_negative, number, one_of, positive, setting
from hmmtrack.tracking.tempering import Plain

__all__ = [
    "OBSERVATION_COLUMNS",
    "RANGE_RATE_COLUMNS",
    "RangeRateMeasurement",
    "RangeRateSettings",
    "check_bounds",
    "predicted_range_and_rate",
    "predicted_row",
    "search_bounds",
]

#: columns of the observations table, in order (``docs/interfaces.md`` plus the
#: transmitter and the pings missed since the receiver's previous detection)
OBSERVATION_COLUMNS = (
    "time",
    "receiver",
    "transmitter",
    "range",
    "range_rate",
    "missed_pings",
    "receiver_x",
    "receiver_y",
    "receiver_vx",
    "receiver_vy",
)


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


@njit(cache=True, inline="always")
def predicted_row(z, j, x, y, vx, vy):
    """Predicted range (m) and range-rate (m/s) of observation row ``j`` of ``z`` (columns
    in the order of :data:`RANGE_RATE_COLUMNS`) for one particle at ``(x, y)`` m moving at
    ``(vx, vy)`` m/s: :func:`predicted_range_and_rate`'s equations in compiled kernels (the
    range-rate 0 for a particle exactly at the receiver)."""
    dx = z[j, 2] - x
    dy = z[j, 3] - y
    r_hat = math.sqrt(dx * dx + dy * dy)
    r_dot_hat = (dx * (z[j, 4] - vx) + dy * (z[j, 5] - vy)) / r_hat if r_hat > 0 else 0.0
    return r_hat, r_dot_hat


#: depth policies that are not a number (see :attr:`RangeRateSettings.depth`)
DEPTH_POLICIES = ("none", "sensor")


def _r0_pair(text: str) -> tuple[str, float]:
    """``RECEIVER=METRES`` of the command line."""
    name, sep, value = text.rpartition("=")
    if not sep or not name:
        raise ValueError(f"expected RECEIVER=METRES, got {text!r}")
    return name, value


def _ranges(name: str, value) -> dict[str, float]:
    if not isinstance(value, Mapping):
        raise ValueError(f"{name} must map receiver names to ranges (m), got {value!r}")
    ranges = {}
    for receiver, metres in value.items():
        try:
            ranges[str(receiver)] = non_negative(name, metres)
        except ValueError:
            raise ValueError(
                f"{name} of receiver {receiver!r} must be a non-negative range in metres, "
                f"got {metres!r}"
            ) from None
    return ranges


def _depth(name: str, value) -> str | float:
    if isinstance(value, str):
        if value in DEPTH_POLICIES:
            return value
        try:
            value = float(value)
        except ValueError:
            raise ValueError(
                f"{name} must be one of {list(DEPTH_POLICIES)} or a depth in metres, got {value!r}"
            ) from None
    return non_negative(name, value)


def _correlation(name: str, value) -> float:
    result = number(name, value)
    if not -1 < result < 1:
        raise ValueError(f"{name} must lie in (-1, 1), got {value!r}")
    return result


@dataclass(frozen=True)
class RangeRateSettings(Settings):
    """The ``measurement`` section of the ``"range-rate"`` measurement.

    Parameters
    ----------
    period : float
        Transmitter period ``T`` (s).
    r0 : mapping of str to float
        Known range (m, ≥ 0) between the tag and each receiver at that receiver's first
        detection, by receiver name; one per detecting receiver.
    sound_speed : float
        Speed of sound (m/s); 1460 as the paper.
    sigma_range, sigma_range_rate, range_rate_correlation : float
        ``Sigma_z`` of (range m, range-rate m/s) as standard deviations and a correlation
        (:attr:`covariance`). The paper gives no value; estimate it with
        :func:`hmmtrack.tracking.measurement.ranging.estimate_measurement_covariance`, then
        inflate it: the likelihood must also absorb the particles' spread. The default
        (5 m, 0.5 m/s, uncorrelated) is 3-5 times the errors measured on the synthetic
        scenarios (reports/decisions.md, "Tracking defaults").
    depth : "none", "sensor" or float
        Depth correction of the ranges: ``"none"`` (2-D, the paper), ``"sensor"`` (the
        detections' ``depth`` column) or an assumed constant depth (m).
    shallower : {"raise", "clip"}
        What a depth correction does with a range shorter than the depth
        (:func:`hmmtrack.tracking.measurement.ranging.depth_correction`).
    velocity_window : float
        Width (s) over which receiver velocities are averaged from their GPS tracks
        (:class:`hmmtrack.tracking.receivers.ReceiverTracks`); 0: the slope of the GPS segment.
    bounds_margin : float
        Margin (m) added around the search box derived from ``r0``
        (:func:`search_bounds`), and the slack of :func:`check_bounds` for given bounds.
    max_gap : float
        Longest gap (s) between a receiver's detections that its range chain spans
        (:func:`hmmtrack.tracking.measurement.ranging.range_table`); its detections after a
        longer one are not used, with a ``range_chain_broken`` event. An hour: 450 pings of
        an 8 s tag, over which a period known to 1 ms adds 660 m of range.
    """

    name: ClassVar[str] = "range-rate"

    period: float = period_setting()
    r0: Mapping[str, float] = setting(
        default_factory=dict,
        help="range at the receiver's first detection (m); once per receiver",
        check=_ranges,
        parse=_r0_pair,
        metavar="RECEIVER=METRES",
        append=True,
        data=True,
    )
    sound_speed: float = sound_speed_setting()
    sigma_range: float = setting(
        5.0,
        help="standard deviation of the range in the measurement covariance (m)",
        check=positive,
        parse=float,
        metavar="METRES",
    )
    sigma_range_rate: float = setting(
        0.5,
        help="standard deviation of the range-rate in the measurement covariance (m/s)",
        check=positive,
        parse=float,
        metavar="M_PER_S",
    )
    range_rate_correlation: float = setting(
        0.0,
        help="correlation of range and range-rate errors, in (-1, 1)",
        check=_correlation,
        parse=float,
        metavar="RHO",
    )
    depth: str | float = setting(
        "none",
        help="depth correction: none, sensor (the detections' depth column), or a depth (m)",
        check=_depth,
    )
    shallower: str = setting(
        "raise",
        help="what a depth correction does with a range shorter than the depth",
        check=one_of("raise", "clip"),
        choices=("raise", "clip"),
    )
    velocity_window: float = setting(
        20.0,
        help="window (s) over which receiver velocities are averaged from their GPS fixes",
        check=non_negative,
        parse=float,
        metavar="SECONDS",
    )
    bounds_margin: float = setting(
        100.0,
        help=(
            "metres added around the search box derived from r0, and how far given bounds "
            "may miss a receiver's first range"
        ),
        check=non_negative,
        parse=float,
        metavar="METRES",
    )
    max_gap: float = setting(
        3600.0,
        help=(
            "longest gap (s) between a receiver's detections that its ranges are counted "
            "across; its detections after a longer gap are not used"
        ),
        check=positive,
        parse=float,
        metavar="SECONDS",
    )

    @property
    def covariance(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """``Sigma_z``: ``((var_r, cov), (cov, var_rdot))`` in m², m²/s, m²/s²."""
        cov = self.range_rate_correlation * self.sigma_range * self.sigma_range_rate
        return ((self.sigma_range**2, cov), (cov, self.sigma_range_rate**2))


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
    name: ClassVar[str] = "range-rate"
    settings: ClassVar[type] = RangeRateSettings
    columns: ClassVar[tuple[str, ...]] = RANGE_RATE_COLUMNS
    fields: ClassVar[tuple[str, ...]] = ()
    default_correction: ClassVar[Plain] = Plain()
    default_motion: ClassVar[dict | None] = None
    default_smoothing_lag: ClassVar[int | None] = None

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
    def from_settings(
        cls, settings: RangeRateSettings, observations=None, receivers=None
    ) -> RangeRateMeasurement:
        """The measurement of ``settings.covariance`` (the data are not needed)."""
        return cls(np.array(settings.covariance))

    @classmethod
    def observations(
        cls,
        detections: pd.DataFrame,
        receivers: pd.DataFrame | ReceiverTracks,
        settings: RangeRateSettings,
    ) -> pd.DataFrame:
        """Observations table of one transmitter's detections, receiver positions and settings.

        Parameters
        ----------
        detections : pandas.DataFrame
            Detections of one transmitter (``time`` s, ``receiver``, ``transmitter``;
            ``depth`` m for the ``"sensor"`` depth policy).
        receivers : pandas.DataFrame or ReceiverTracks
            Receiver positions table (``docs/interfaces.md``), turned into tracks with
            ``settings.velocity_window``, or tracks built from it.
        settings : RangeRateSettings
            Period, sound speed, ``r0`` per receiver, depth policy.

        Returns
        -------
        pandas.DataFrame
            One row per detection, sorted by time, with :data:`OBSERVATION_COLUMNS`:
            ``range`` (m), ``range_rate`` (m/s; NaN on each receiver's first detection),
            ``missed_pings``, and the receiver's position (m) and velocity (m/s) at the
            detection time.

        Raises
        ------
        ValueError
            When a receiver lacks ``r0`` or positions at a detection time, the period does
            not fit the detections (:func:`ranging.check_period_fits
            <hmmtrack.tracking.measurement.ranging.check_period_fits>`), or a depth
            correction is impossible (messages name what and where).
        """
        tracks = (
            receivers
            if isinstance(receivers, ReceiverTracks)
            else ReceiverTracks.from_frame(receivers, velocity_window=settings.velocity_window)
        )
        ranging.check_period_fits(detections, settings.period, settings.sound_speed)
        table = ranging.range_table(
            detections, settings.period, settings.r0, settings.sound_speed, settings.max_gap
        )
        table = _depth_corrected(table, detections, settings)
        unknown = sorted(set(table["receiver"]) - set(tracks.names))
        if unknown:
            raise ValueError(
                f"no positions for receiver(s) {unknown} of the detections; receiver positions "
                f"are known for {list(tracks.names)}"
            )
        state = np.empty((len(table), 4))
        for receiver, rows in table.groupby("receiver", sort=False).indices.items():
            state[rows] = np.column_stack(tracks.state(receiver, table["time"].to_numpy()[rows]))
        for k, column in enumerate(("receiver_x", "receiver_y", "receiver_vx", "receiver_vy")):
            table[column] = state[:, k]
        return table[list(OBSERVATION_COLUMNS)]

    def start_box(
        self,
        observations: pd.DataFrame,
        receivers,
        settings: RangeRateSettings,
        bounds: Bounds | None = None,
        start=None,
    ):
        """``bounds`` (checked by :func:`check_bounds`) or :func:`search_bounds`, with
        ``settings.r0`` and ``settings.bounds_margin``."""
        r0, margin = settings.r0, settings.bounds_margin
        bounds = bounds or search_bounds(observations, r0, margin)
        check_bounds(bounds, observations, r0, margin)
        return tuple(float(b) for b in bounds)

    def split(self, observations: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
        """The rows with a range-rate, and an ``"anchor_detection"`` event for each receiver's
        first detection (its range is ``r0``; no range-rate, not scored), and a
        ``"range_chain_broken"`` event for each receiver whose ranges stop after a long gap
        (``max_gap``: its later detections are not scored)."""
        broken = observations["range"].isna().to_numpy()
        anchors = observations["range_rate"].isna().to_numpy() & ~broken
        if not (anchors.any() or broken.any()):
            return observations, no_events()
        anchor_events = pd.DataFrame(
            {
                "time": observations.loc[anchors, "time"].to_numpy(),
                "kind": "anchor_detection",
                "detail": [
                    f"first detection of receiver {r}: range r0 = {d:.1f} m anchors its ranges; "
                    "no range-rate, not used in the likelihood"
                    for r, d in observations.loc[anchors, ["receiver", "range"]].itertuples(
                        index=False
                    )
                ],
            }
        )
        parts = [anchor_events, _broken_chains(observations, broken)]
        events = pd.concat([p for p in parts if not p.empty], ignore_index=True)
        events = events.sort_values("time", kind="stable", ignore_index=True)
        return observations.loc[~(anchors | broken)], events

    def collectors(self) -> tuple:
        """No diagnostics of its own."""
        return ()

    def recover(self, particles: Particles, obs, time: float, rng) -> str | None:
        """Re-place particles whose weights degenerated on a range ring; what was done.

        On the ring of the observed range around the receiver with the shortest range
        (radius ``range + N(0, var(r))``, any heading, at rest; other fields kept), weighted
        by all the observations ``obs`` (a table, or a mapping of columns); ``None`` (the
        particles' positions moved, to be replaced by the filter) when that is degenerate too.
        """
        p = particles
        ranges = np.asarray(obs["range"], dtype=np.float64)
        j = int(np.argmin(ranges))
        sd = float(np.sqrt(self.covariance[0][0]))
        radius = np.abs(ranges[j] + sd * rng.standard_normal(p.n))
        bearing = rng.uniform(-np.pi, np.pi, p.n)
        heading = rng.uniform(-np.pi, np.pi, p.n)
        p.x = np.asarray(obs["receiver_x"], dtype=np.float64)[j] + radius * np.cos(bearing)
        p.y = np.asarray(obs["receiver_y"], dtype=np.float64)[j] + radius * np.sin(bearing)
        p.heading, p.cos_heading, p.sin_heading = heading, np.cos(heading), np.sin(heading)
        p.speed, p.turn_rate = np.zeros(p.n), np.zeros(p.n)
        log_weight = np.asarray(self.loglik(p, obs, time=time), dtype=float)
        if not (np.isfinite(log_weight.max()) and not np.any(np.isnan(log_weight))):
            return None
        p.log_weight = log_normalise(log_weight)
        return f"reinitialised on the {ranges[j]:.1f} m range ring of receiver " + (
            str(np.asarray(obs["receiver"])[j]) if "receiver" in obs else f"row {j}"
        )

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
        obs : mapping of column name to (M,) array, DataFrame, or (M, 6) array
            M simultaneous observations with the columns :data:`RANGE_RATE_COLUMNS`, or
            their :meth:`as_matrix` form.
        time : float, optional
            Filter time; unused (observations are scored where the particles are now).

        Returns
        -------
        (N,) float; finite unless a squared error overflows (``-inf`` then).
        """
        return loglik_chunks(self.loglik_terms(particles, obs), particles.n)

    def loglik_terms(self, particles: Particles, obs, time: float | None = None) -> RangeRateTerms:
        """The arguments of :meth:`loglik`'s compiled loop (:class:`RangeRateTerms`), which
        the filter's correction runs in its weighing pass
        (:func:`hmmtrack.tracking.compiled.weighing.chunk_loglik`); parameters as
        :meth:`loglik`."""
        p = particles
        return RangeRateTerms(
            p.x, p.y, p.cos_heading, p.sin_heading, p.speed,
            np.ascontiguousarray(self.as_matrix(obs)), self._precision, self._log_norm,
        )  # fmt: skip

    @staticmethod
    def as_matrix(obs) -> np.ndarray:
        """Observations as the (M, 6) float matrix that :meth:`loglik` scores fastest.

        Parameters
        ----------
        obs : mapping of column name to (M,) array, DataFrame, or (M, 6) array
            Columns :data:`RANGE_RATE_COLUMNS` (m, m/s); other columns are ignored. An
            array is taken as already converted.

        Returns
        -------
        (M, 6) float, columns in the order of :data:`RANGE_RATE_COLUMNS`.
        """
        if isinstance(obs, np.ndarray):
            return obs
        if isinstance(obs, pd.DataFrame):
            return obs[list(RANGE_RATE_COLUMNS)].to_numpy(dtype=np.float64)
        z = np.empty((len(obs["range"]), len(RANGE_RATE_COLUMNS)))
        for j, name in enumerate(RANGE_RATE_COLUMNS):
            z[:, j] = np.asarray(obs[name], dtype=np.float64)
        return z


def _broken_chains(observations: pd.DataFrame, broken: np.ndarray) -> pd.DataFrame:
    """One ``range_chain_broken`` event per receiver with ``broken`` rows, at the first."""
    rows = []
    times = observations["time"].to_numpy(dtype=float)
    for receiver, where in observations.groupby("receiver", sort=False).indices.items():
        lost = where[broken[where]]
        if lost.size:
            gap = times[lost[0]] - times[where[np.searchsorted(where, lost[0]) - 1]]
            detail = (
                f"receiver {receiver}: its {lost.size} detection(s) from here on not used: the "
                f"{gap:.0f} s gap before this one is longer than max_gap (--max-gap), across "
                "which the count of pings, and so the range, is not trusted"
            )
            rows.append((times[lost[0]], "range_chain_broken", detail))
    return pd.DataFrame(rows, columns=list(EVENT_COLUMNS))


def _depth_corrected(table: pd.DataFrame, detections: pd.DataFrame, settings):
    """Replace ranges by horizontal ranges and recompute range-rates, per receiver."""
    if settings.depth == "none":
        return table
    if settings.depth == "sensor":
        if "depth" not in detections.columns:
            raise ValueError(
                "depth policy 'sensor' needs a 'depth' column (m) in the detections; "
                f"found {list(detections.columns)}"
            )
        depth_of = detections[["time", "receiver", "depth"]].astype({"receiver": str})
        merged = table.merge(depth_of, on=["time", "receiver"], how="left", validate="1:1")
        depth = merged["depth"].to_numpy(dtype=float)
        missing = np.flatnonzero(~np.isfinite(depth))
        if missing.size:
            raise ValueError(
                f"depth policy 'sensor': no depth reading for detection(s) at times "
                f"{table['time'].iloc[missing[:10]].tolist()} (receivers "
                f"{table['receiver'].iloc[missing[:10]].tolist()})"
            )
    else:
        depth = np.full(len(table), float(settings.depth))
    table = table.copy()
    table["range"] = ranging.depth_correction(
        table["range"].to_numpy(), depth, shallower=settings.shallower
    )
    for _, rows in table.groupby(["receiver", "transmitter"], sort=False).groups.items():
        table.loc[rows, "range_rate"] = ranging.range_rates(
            table.loc[rows, "time"].to_numpy(), table.loc[rows, "range"].to_numpy()
        )
    return table


def search_bounds(
    observations: pd.DataFrame, r0: dict[str, float], margin: float
) -> tuple[float, float, float, float]:
    """Box that holds the tag at the start: each receiver's first position ± (r0 + margin).

    Parameters
    ----------
    observations : pandas.DataFrame
        Observations table (:func:`build_observations`).
    r0 : dict of str to float
        Range at each receiver's first detection (m).
    margin : float
        Extra margin (m).

    Returns
    -------
    (xmin, xmax, ymin, ymax) : tuple of float
        The union of the receivers' squares (m): the tag lies inside each receiver's square
        at that receiver's first detection.
    """
    if observations.empty:
        raise ValueError("no observations to derive search bounds from; give bounds explicitly")
    first = observations.drop_duplicates("receiver", keep="first")
    reach = first["receiver"].map(r0).to_numpy(dtype=float) + margin
    x, y = first["receiver_x"].to_numpy(), first["receiver_y"].to_numpy()
    return (
        float((x - reach).min()),
        float((x + reach).max()),
        float((y - reach).min()),
        float((y + reach).max()),
    )


def check_bounds(
    bounds: tuple[float, float, float, float],
    observations: pd.DataFrame,
    r0: dict[str, float],
    margin: float,
) -> None:
    """Refuse search bounds that cannot hold the tag at the receivers' first detections.

    At its first detection, receiver ``j`` is ``r0[j]`` from the tag, so the box must come
    within ``r0[j] + margin`` of where the receiver was (e.g. bounds given in another frame
    than the receivers fail this).

    Raises
    ------
    ValueError
        Naming the receiver, its position and the bounds.
    """
    xmin, xmax, ymin, ymax = bounds
    first = observations.drop_duplicates("receiver", keep="first")
    for name, x, y in first[["receiver", "receiver_x", "receiver_y"]].itertuples(index=False):
        gap = np.hypot(max(xmin - x, 0.0, x - xmax), max(ymin - y, 0.0, y - ymax))
        if gap > r0[name] + margin:
            raise ValueError(
                f"search bounds {tuple(bounds)} lie {gap:.0f} m from receiver {name!r} at "
                f"({x:.1f}, {y:.1f}) m, farther than its r0 ({r0[name]:.1f} m) + margin "
                f"({margin:.0f} m): are the bounds in the receivers' frame?"
            )


class RangeRateTerms(NamedTuple):
    """What the range-rate log-likelihood of one correction reads: the particles' positions
    (m), heading cosines and sines and speeds (m/s), each (N,); the observations ``z``
    (M, 6) in the order of :data:`RANGE_RATE_COLUMNS`; the precision ``Sigma_z^-1`` (2, 2)
    and the Gaussian's log normalising constant (:func:`_range_rate_chunk`)."""

    x: np.ndarray
    y: np.ndarray
    cos_heading: np.ndarray
    sin_heading: np.ndarray
    speed: np.ndarray
    z: np.ndarray
    precision: np.ndarray
    log_norm: float


@overload(chunk_loglik)
def _range_rate_chunk(scored, lo, hi, out):
    """:func:`~hmmtrack.tracking.compiled.weighing.chunk_loglik` of :class:`RangeRateTerms`:
    :meth:`RangeRateMeasurement.loglik` of the particles ``lo:hi`` into ``out``, each
    particle's value computed alone (:func:`predicted_row`)."""
    if not (isinstance(scored, types.BaseNamedTuple) and scored.instance_class is RangeRateTerms):
        return None

    def chunk(scored, lo, hi, out):
        z, precision, log_norm = scored.z, scored.precision, scored.log_norm
        p00, p01, p11 = precision[0, 0], precision[0, 1], precision[1, 1]
        # loops over views of the chunk (the house form of chunked passes: 2-3x faster than
        # indexing lo:hi of the whole arrays)
        xs, ys = scored.x[lo:hi], scored.y[lo:hi]
        cs, ss, vs = scored.cos_heading[lo:hi], scored.sin_heading[lo:hi], scored.speed[lo:hi]
        for i in range(xs.size):
            vx = vs[i] * cs[i]
            vy = vs[i] * ss[i]
            total = 0.0
            for j in range(z.shape[0]):
                r_hat, r_dot_hat = predicted_row(z, j, xs[i], ys[i], vx, vy)
                e_r = r_hat - z[j, 0]
                e_v = r_dot_hat - z[j, 1]
                total += log_norm - 0.5 * (
                    p00 * e_r * e_r + 2.0 * p01 * e_r * e_v + p11 * e_v * e_v
                )
            out[i] = total

    return chunk
