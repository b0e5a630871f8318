"""Fit receiver clocks from sync-tag detections: :func:`fit_clocks`.

The model. Sync tag ``s`` is moored at receiver ``h(s)``; its emission ``p`` leaves at
time ``E_p`` (common time base) and reaches receiver ``r`` after ``|P_r - P_h| / c``; the
receiver logs it at ``t = E_p + |P_r - P_h| / c + correction_r(t) + e``. Each receiver's
correction (``hmmtrack.sync.clocks``) is a quadratic spline in its own time with knots at
the segment starts, continuous with a continuous rate (a clock does not jump), so each
segment has an offset, a drift and a drift rate; the time keeper's correction is zero. The
sound speed ``c`` is one unknown per segment, or fixed, or from temperature and salinity
(:func:`hmmtrack.sync.sound.mackenzie_sound_speed`). Receivers not marked ``fixed`` may
have their x, y refined with a Gaussian prior around the file's position (sd
``refine_positions`` m); depths stay as given.

The residuals ``e`` are Student-t (``degrees_of_freedom``, default 3, as YAPS uses) with
one scale for all receivers: sync detections carry multipath echoes, late by milliseconds
to seconds, and a Gaussian fit would be dragged by them. (A scale per receiver makes the
likelihood unbounded: with a free emission time per ping, one receiver's residuals can all
be made zero and its scale collapse.) The fit is an EM algorithm on the
t-distribution as a scale mixture of Gaussians: the E-step gives each detection a weight
``(nu + 1) / (nu + (e / sigma)**2)``; the M-step is one Gauss-Newton step of the weighted
least squares over the emission times, clock coefficients, sound speeds and positions
(sparse analytic Jacobian, normal equations solved by a sparse direct solver, step halved
while the weighted cost grows), then the scale ``sigma**2 = sum(w e**2) / n``. Why not
:func:`scipy.optimize.least_squares` with a robust loss: its loss has a fixed scale, which
must be estimated here, and it would bend the Gaussian position priors too; and its sparse
trust-region solver (LSMR) needed thousands of iterations per solve on this problem, whose
emission-time and clock-offset columns are nearly collinear (see ``reports/decisions.md``).
Detections farther than ``reject_scales`` scales from the fit get weight zero and are
reported as rejected outliers.

Not for: applying the clocks (:func:`hmmtrack.sync.clocks.apply_clocks`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import sparse
from scipy.sparse.linalg import spsolve

from hmmtrack.sync.clocks import DAY, PPM, ReceiverClocks
from hmmtrack.sync.pings import coarse_clocks, group_pings, largest_travel_time
from hmmtrack.sync.sound import mackenzie_sound_speed

logger = logging.getLogger(__name__)

#: the coarse clocks' error allowed for when grouping detections into emissions (s)
GROUPING_TOLERANCE = 0.5
#: the first residual scale (s) of every receiver, before EM shrinks it to the data's
INITIAL_SCALE = 0.05
#: smallest residual scale (s), so that a receiver with a perfect fit keeps finite weights
MIN_SCALE = 1e-6
#: starting sound speed (m/s) when it is estimated
INITIAL_SOUND_SPEED = 1480.0
#: prior sd (m) of an unfixed receiver's x, y that ``hmmtrack sync`` refines by default when
#: the receivers file marks which are ``fixed``: a mooring dropped from a boat lands within
#: metres of its logged position, and a wider prior lets receivers outside the sync tags'
#: reach wander (reports/decisions.md, "Receiver clock synchronisation")
REFINE_POSITIONS_SD = 3.0


@dataclass(frozen=True)
class SyncFit:
    """Result of :func:`fit_clocks`.

    Attributes
    ----------
    clocks : ReceiverClocks
        The fitted clocks (write with :func:`hmmtrack.sync.write_clocks`).
    residuals : DataFrame
        One row per sync detection used: ``ping``, ``sync_tag``, ``receiver``,
        ``receiver_time`` (s), ``time`` (common time base, s), ``emission_time`` (s),
        ``distance`` (m), ``residual_ms``, ``weight`` (EM weight, 0 when rejected),
        ``rejected`` (bool).
    summary : DataFrame
        One row per receiver: ``receiver``, ``detections``, ``rejected``,
        ``residual_sd_ms`` (kept residuals), ``residual_median_ms``, ``sync_tag``,
        ``fixed``, ``moved_m`` (refinement of the position).
    scale_ms : float
        The Student-t scale of the residuals (ms).
    iterations : int
        EM iterations run.
    """

    clocks: ReceiverClocks
    residuals: pd.DataFrame
    summary: pd.DataFrame
    scale_ms: float
    iterations: int


def array_table(receivers: pd.DataFrame) -> pd.DataFrame:
    """One row per moored receiver: ``receiver``, ``x``, ``y``, ``z`` (0 when absent),
    ``sync_tag`` (str or None), ``fixed`` (bool); refuses mobile receivers."""
    mobile = receivers["time"].notna().to_numpy()
    if mobile.any():
        names = sorted(receivers.loc[mobile, "receiver"].unique())
        raise ValueError(f"clock synchronisation needs moored receivers; {names} are mobile")
    array = pd.DataFrame(
        {
            "receiver": receivers["receiver"].to_numpy(),
            "x": receivers["x"].to_numpy(dtype=float),
            "y": receivers["y"].to_numpy(dtype=float),
            "z": receivers["z"].to_numpy(dtype=float) if "z" in receivers else 0.0,
            "sync_tag": receivers["sync_tag"].to_numpy() if "sync_tag" in receivers else None,
            "fixed": receivers["fixed"].to_numpy(dtype=bool) if "fixed" in receivers else False,
        }
    )
    array["sync_tag"] = array["sync_tag"].where(array["sync_tag"].notna(), None)
    return array.reset_index(drop=True)


def sync_detections(
    detections: pd.DataFrame, array: pd.DataFrame
) -> tuple[pd.DataFrame, dict[str, str]]:
    """The detections of the array's sync tags by its receivers.

    Parameters
    ----------
    detections : DataFrame
        Detections table (``time``, ``receiver``, ``transmitter`` and ``transmitter_id``
        when the names have a code space).
    array : DataFrame
        From :func:`array_table`.

    Returns
    -------
    sync : DataFrame
        ``time``, ``receiver``, ``sync_tag`` (as written in the receivers file), ``home``
        (the receiver the tag is moored at).
    homes : dict of str to str
        Sync tag -> its receiver.
    """
    tagged = array[array["sync_tag"].notna()]
    if tagged.empty:
        raise ValueError(
            "no sync tags in the receivers file: give the transmitter moored at a receiver "
            "in a 'sync_tag' column (full id like A69-1602-59334 or the ID part 59334)"
        )
    twice = tagged["sync_tag"][tagged["sync_tag"].duplicated()].tolist()
    if twice:
        raise ValueError(f"sync tag(s) {twice} are given for more than one receiver")
    homes = dict(zip(tagged["sync_tag"], tagged["receiver"], strict=True))
    names = [detections["transmitter"].astype(str)]
    if "transmitter_id" in detections:
        names.append(detections["transmitter_id"].astype(str))
    tag = pd.Series(None, index=detections.index, dtype=object)
    for column in names:
        tag = tag.where(tag.notna(), column.where(column.isin(list(homes))))
    heard = tag.notna().to_numpy()
    never = [t for t in homes if not (tag == t).any()]
    if never:
        raise ValueError(
            f"sync tag(s) {never} of the receivers file are never heard in the detections; "
            f"the detections have transmitters {sorted(detections['transmitter'].unique())[:20]}"
        )
    sync = pd.DataFrame(
        {
            "time": detections["time"].to_numpy(dtype=float)[heard],
            "receiver": detections["receiver"].to_numpy()[heard],
            "sync_tag": tag.to_numpy()[heard],
        }
    )
    outside = ~sync["receiver"].isin(array["receiver"])
    if outside.any():
        logger.warning(
            "left out %d sync detections at receivers not in the receivers file: %s",
            int(outside.sum()),
            sorted(sync.loc[outside, "receiver"].unique()),
        )
        sync = sync[~outside].reset_index(drop=True)
    sync["home"] = sync["sync_tag"].map(homes)
    return sync, homes


def fit_clocks(
    detections: pd.DataFrame,
    receivers: pd.DataFrame,
    *,
    time_keeper: str | None = None,
    segment_length: float = 43200.0,
    sound_speed: float | None = None,
    temperature: float | None = None,
    salinity: float | None = None,
    refine_positions: float | None = None,
    self_detections: bool = False,
    min_detections: int = 10,
    max_clock_offset: float = 300.0,
    degrees_of_freedom: float = 3.0,
    reject_scales: float = 10.0,
    max_iterations: int = 100,
    tolerance: float = 1e-4,
) -> SyncFit:
    """Fit every receiver's clock relative to a time keeper from sync-tag detections.

    Parameters
    ----------
    detections : DataFrame
        Detections table (:func:`hmmtrack.io.read_detections`), each receiver's own clock;
        transmitters other than the sync tags are ignored.
    receivers : DataFrame
        Moored receivers (:func:`hmmtrack.io.read_receivers`) with ``sync_tag`` (and
        optionally ``z``, ``fixed``). Every receiver in it is synchronised.
    time_keeper : str, optional
        The receiver whose clock is the common time base; default the one with the most
        sync detections.
    segment_length : float
        Longest clock segment (s): the span of the sync detections is cut into equal
        segments no longer than this, each with its own offset, drift and drift rate.
    sound_speed : float, optional
        Fixed sound speed (m/s). Default: estimated per segment, unless ``temperature``
        and ``salinity`` are given (Mackenzie 1981).
    temperature, salinity : float, optional
        Water temperature (degC) and salinity (PSU) for a fixed sound speed.
    refine_positions : float, optional
        Prior standard deviation (m) of the x, y of receivers not marked ``fixed``; those
        positions are refined. Default: all positions as given.
    self_detections : bool
        Use the detections of a sync tag by its own receiver (modelled at distance 0; off by
        default, as in YAPS: a tag a metre from its hydrophone is not at distance 0).
    min_detections : int
        Fewest sync detections a receiver needs, in every segment.
    max_clock_offset : float
        Largest clock difference (s) between two receivers before synchronisation.
    degrees_of_freedom : float
        Of the Student-t residuals.
    reject_scales : float
        Residuals beyond this many scales are rejected outliers.
    max_iterations : int
        EM iterations at most.
    tolerance : float
        EM stops when the scale changes by less than this fraction (and the fit by less
        than a microsecond, and the rejected outliers are the same).

    Returns
    -------
    SyncFit
    """
    array = array_table(receivers)
    names = array["receiver"].tolist()
    if time_keeper is not None and time_keeper not in names:
        raise ValueError(
            f"time keeper {time_keeper!r} is not in the receivers file; receivers: {names}"
        )
    sync, homes = sync_detections(detections, array)
    if not self_detections:
        sync = sync[sync["receiver"] != sync["home"]].reset_index(drop=True)
    counts = sync["receiver"].value_counts()
    few = {name: int(counts.get(name, 0)) for name in names if counts.get(name, 0) < min_detections}
    if few:
        raise ValueError(
            f"receiver(s) with too few sync detections (fewer than {min_detections}): {few}; "
            "remove them from the receivers file or lower min_detections"
        )
    if time_keeper is None:
        time_keeper = str(counts.index[0])
    anchors = {}
    for tag, home in homes.items():
        heard = sync.loc[sync["sync_tag"] == tag, "receiver"].value_counts()
        anchors[tag] = home if heard.get(home, 0) >= min_detections else str(heard.index[0])
    coarse, reference = coarse_clocks(
        sync, anchors, names, time_keeper, max_clock_offset, min_detections
    )
    offset = np.array([coarse[n][0] for n in sync["receiver"]])
    drift = np.array([coarse[n][1] for n in sync["receiver"]])
    recorded = sync["time"].to_numpy()
    coarse_time = recorded - offset - drift * (recorded - reference)
    ping, echoes = group_pings(
        sync["sync_tag"].to_numpy(),
        sync["receiver"].to_numpy(),
        coarse_time,
        largest_travel_time(array[["x", "y", "z"]].to_numpy(dtype=float)) + GROUPING_TOLERANCE,
    )
    heard_by = pd.Series(ping[ping >= 0]).value_counts()
    keep = (ping >= 0) & np.isin(ping, heard_by.index[heard_by >= 2])
    sync = sync[keep].reset_index(drop=True)
    ping, coarse_time = pd.factorize(ping[keep])[0], coarse_time[keep]
    logger.info(
        "sync: %d detections in %d emissions heard by 2+ receivers; %d echoes dropped",
        len(sync),
        ping.max() + 1,
        echoes,
    )
    start, end = float(coarse_time.min()), float(coarse_time.max())
    n_segments = max(1, math.ceil((end - start) / segment_length))
    bounds = np.linspace(start, end, n_segments + 1)
    if sound_speed is None and temperature is not None and salinity is not None:
        sound_speed, method = float(mackenzie_sound_speed(temperature, salinity)), "mackenzie"
    else:
        method = "estimated" if sound_speed is None else "fixed"
    problem = _Problem(
        sync,
        ping,
        coarse_time,
        array,
        time_keeper,
        bounds,
        sound_speed,
        refine_positions,
        coarse,
        reference,
    )
    problem.check_coverage(min_detections)
    x, scale, weight, rejected, iterations = problem.solve(
        degrees_of_freedom, reject_scales, max_iterations, tolerance
    )
    settings = {
        "segment_length_s": segment_length,
        "sound_speed": sound_speed,
        "temperature_c": temperature,
        "salinity_psu": salinity,
        "refine_positions_sd_m": refine_positions,
        "self_detections": self_detections,
        "min_detections": min_detections,
        "max_clock_offset_s": max_clock_offset,
        "degrees_of_freedom": degrees_of_freedom,
        "reject_scales": reject_scales,
    }
    return problem.result(x, scale, weight, rejected, iterations, method, echoes, settings)


class _Problem:
    """The sync model's unknowns, residuals and Jacobian (see the module docstring).

    Unknowns, in order: emission times (s, relative to ``origin``), then per receiver other
    than the time keeper the spline coefficients of its correction (s; basis ``1, d, d**2,
    (d - knot_j)_+**2`` in days ``d`` since the first segment start), then sound speeds
    (m/s, one per segment, when estimated), then x, y (m, relative to the array's centre)
    of refined receivers.
    """

    def __init__(
        self,
        sync,
        ping,
        coarse_time,
        array,
        time_keeper,
        bounds,
        sound_speed,
        refine_sd,
        coarse,
        reference,
    ):
        self.sync, self.array, self.time_keeper = sync, array, time_keeper
        self.bounds, self.refine_sd = bounds, refine_sd
        names = array["receiver"].tolist()
        self.names = names
        self.receiver = np.array([names.index(n) for n in sync["receiver"]])
        self.home = np.array([names.index(n) for n in sync["home"]])
        self.ping = ping
        self.n_pings = int(ping.max()) + 1
        self.origin = float(np.floor(bounds[0]))
        self.time = sync["time"].to_numpy() - self.origin
        # the spline basis of every detection, in its receiver's time
        days = (sync["time"].to_numpy() - bounds[0]) / DAY
        knots = (bounds[1:-1] - bounds[0]) / DAY
        self.basis = np.column_stack(
            [np.ones_like(days), days, days**2] + [np.clip(days - k, 0, None) ** 2 for k in knots]
        )
        self.n_basis = self.basis.shape[1]
        self.clocked = [i for i, n in enumerate(names) if n != time_keeper]
        self.clock_column = np.full(len(names), -1)
        self.clock_column[self.clocked] = self.n_pings + self.n_basis * np.arange(len(self.clocked))
        n = self.n_pings + self.n_basis * len(self.clocked)
        first_heard = pd.Series(coarse_time).groupby(ping).min().to_numpy()
        #: segment of each emission, for its sound speed
        self.segment = np.clip(
            np.searchsorted(bounds, first_heard, side="right") - 1, 0, len(bounds) - 2
        )
        self.fixed_speed = sound_speed
        self.speed_column = n
        n += 0 if sound_speed is not None else len(bounds) - 1
        self.centre = array[["x", "y"]].to_numpy().mean(axis=0)
        self.file_xy = array[["x", "y"]].to_numpy() - self.centre
        self.z = array["z"].to_numpy(dtype=float)
        refined = ~array["fixed"].to_numpy(dtype=bool) if refine_sd is not None else None
        self.refined = np.flatnonzero(refined) if refined is not None else np.array([], int)
        self.position_column = np.full(len(names), -1)
        self.position_column[self.refined] = n + 2 * np.arange(self.refined.size)
        self.n_unknowns = n + 2 * self.refined.size
        # starting values: coarse clocks, emission times from the coarse times
        x0 = np.zeros(self.n_unknowns)
        x0[: self.n_pings] = first_heard - self.origin
        for i in self.clocked:
            c, d = coarse[names[i]]
            # offset + drift (t - reference) in the basis 1, days since bounds[0]
            x0[self.clock_column[i]] = c + d * (bounds[0] - reference)
            x0[self.clock_column[i] + 1] = d * DAY
        if sound_speed is None:
            x0[self.speed_column : self.speed_column + len(bounds) - 1] = INITIAL_SOUND_SPEED
        for i in self.refined:
            x0[self.position_column[i] : self.position_column[i] + 2] = self.file_xy[i]
        self.x0 = x0

    def check_coverage(self, min_detections: int) -> None:
        """Refuse a receiver with fewer than ``min_detections`` detections in a segment."""
        segment = np.clip(
            np.searchsorted(self.bounds, self.sync["time"].to_numpy(), side="right") - 1,
            0,
            len(self.bounds) - 2,
        )
        table = pd.crosstab(self.sync["receiver"], segment).reindex(
            index=self.names, columns=range(len(self.bounds) - 1), fill_value=0
        )
        few = [
            f"{name} (segment {k}: {table.loc[name, k]})"
            for name in self.names
            for k in table.columns
            if table.loc[name, k] < min_detections
        ]
        if few:
            raise ValueError(
                f"receiver(s) with too few sync detections heard by another receiver too "
                f"(fewer than {min_detections} per segment): {few}; use longer segments, "
                "lower min_detections, or remove the receiver"
            )

    # -- model ----------------------------------------------------------------------------

    def _xy(self, x: np.ndarray) -> np.ndarray:
        xy = self.file_xy.copy()
        for i in self.refined:
            xy[i] = x[self.position_column[i] : self.position_column[i] + 2]
        return xy

    def _speed(self, x: np.ndarray) -> np.ndarray:
        if self.fixed_speed is not None:
            return np.full(len(self.bounds) - 1, self.fixed_speed)
        return x[self.speed_column : self.speed_column + len(self.bounds) - 1]

    def geometry(self, x: np.ndarray):
        """Distances (m), their xy gradient w.r.t. the receiver (unit vectors), speeds."""
        xy = self._xy(x)
        delta = xy[self.receiver] - xy[self.home]
        dz = self.z[self.receiver] - self.z[self.home]
        distance = np.sqrt(np.sum(delta**2, axis=1) + dz**2)
        unit = np.divide(
            delta, distance[:, None], out=np.zeros_like(delta), where=distance[:, None] > 0
        )
        return distance, unit, self._speed(x)[self.segment[self.ping]]

    def correction(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros(len(self.time))
        clocked = self.clock_column[self.receiver] >= 0
        cols = self.clock_column[self.receiver[clocked]][:, None] + np.arange(self.n_basis)
        out[clocked] = np.sum(self.basis[clocked] * x[cols], axis=1)
        return out

    def errors(self, x: np.ndarray) -> np.ndarray:
        """Residuals (s): logged minus predicted arrival time, one per detection."""
        distance, _, speed = self.geometry(x)
        return self.time - x[self.ping] - distance / speed - self.correction(x)

    def _residuals(self, x: np.ndarray, gain: np.ndarray) -> np.ndarray:
        out = [gain * self.errors(x)]
        if self.refined.size:
            out.append(
                (
                    x[self.position_column[self.refined][:, None] + [0, 1]]
                    - self.file_xy[self.refined]
                ).ravel()
                / self.refine_sd
            )
        return np.concatenate(out)

    def _jacobian(self, x: np.ndarray, gain: np.ndarray) -> sparse.csr_matrix:
        n = len(self.time)
        distance, unit, speed = self.geometry(x)
        rows, cols, vals = [np.arange(n)], [self.ping], [-gain]
        clocked = np.flatnonzero(self.clock_column[self.receiver] >= 0)
        rows.append(np.repeat(clocked, self.n_basis))
        cols.append(
            (self.clock_column[self.receiver[clocked]][:, None] + np.arange(self.n_basis)).ravel()
        )
        vals.append((-gain[clocked, None] * self.basis[clocked]).ravel())
        if self.fixed_speed is None:
            rows.append(np.arange(n))
            cols.append(self.speed_column + self.segment[self.ping])
            vals.append(gain * distance / speed**2)
        for end, sign in ((self.receiver, -1.0), (self.home, 1.0)):
            moved = np.flatnonzero(self.position_column[end] >= 0)
            for axis in (0, 1):
                rows.append(moved)
                cols.append(self.position_column[end[moved]] + axis)
                vals.append(sign * gain[moved] * unit[moved, axis] / speed[moved])
        m = 2 * self.refined.size
        if m:
            rows.append(n + np.arange(m))
            cols.append((self.position_column[self.refined][:, None] + [0, 1]).ravel())
            vals.append(np.full(m, 1.0 / self.refine_sd))
        return sparse.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(n + m, self.n_unknowns),
        )

    def _gauss_newton_step(self, x: np.ndarray, gain: np.ndarray) -> np.ndarray:
        """One Gauss-Newton step at ``x`` (columns scaled to unit norm), halved while the
        weighted sum of squares grows."""
        residual = self._residuals(x, gain)
        jacobian = self._jacobian(x, gain)
        norm = np.sqrt(np.asarray(jacobian.multiply(jacobian).sum(axis=0)).ravel())
        idle = norm == 0  # e.g. an emission whose detections are all rejected: it stays put
        norm[idle] = 1.0
        scaled = jacobian @ sparse.diags(1.0 / norm)
        normal = (scaled.T @ scaled + sparse.diags(idle.astype(float))).tocsc()
        step = spsolve(normal, scaled.T @ residual) / norm
        cost = residual @ residual
        for _ in range(20):
            trial = x - step
            fitted = self._residuals(trial, gain)
            if fitted @ fitted <= cost:
                return trial
            step = 0.5 * step
        return x

    def solve(self, nu, reject_scales, max_iterations, tolerance):
        """EM for Student-t residuals; returns unknowns, the scale (s), weights, rejected."""
        x = self.x0.copy()
        scale = INITIAL_SCALE
        weight = np.ones(len(self.time))
        rejected = np.zeros(len(self.time), dtype=bool)
        iteration = 0
        while iteration < max_iterations:
            iteration += 1
            moved = self._gauss_newton_step(x, np.sqrt(weight) / scale)
            shift = np.max(np.abs(self.errors(moved) - self.errors(x)))
            x = moved
            error = self.errors(x)
            previous = scale
            scale = max(np.sqrt(np.sum(weight * error**2) / max(np.sum(~rejected), 1)), MIN_SCALE)
            z = error / scale
            was = rejected
            rejected = np.abs(z) > reject_scales
            weight = np.where(rejected, 0.0, (nu + 1.0) / (nu + z**2))
            change = abs(scale / previous - 1.0)
            if change < tolerance and shift < MIN_SCALE and np.array_equal(was, rejected):
                break
        return x, scale, weight, rejected, iteration

    # -- results --------------------------------------------------------------------------

    def coefficients(self, x: np.ndarray) -> np.ndarray:
        """(R, K, 3): offset_s, drift_ppm, drift_rate_ppm_per_day at each segment start."""
        n_segments = len(self.bounds) - 1
        knots = (self.bounds[1:-1] - self.bounds[0]) / DAY
        out = np.zeros((len(self.names), n_segments, 3))
        for i in self.clocked:
            a = x[self.clock_column[i] : self.clock_column[i] + self.n_basis]
            for k in range(n_segments):
                d = (self.bounds[k] - self.bounds[0]) / DAY
                active = knots <= d + 1e-12
                lag = np.where(active, d - knots, 0.0)
                value = a[0] + a[1] * d + a[2] * d**2 + np.sum(a[3:] * lag**2)
                slope = a[1] + 2 * a[2] * d + np.sum(2 * a[3:] * lag)  # s per day
                curvature = a[2] + np.sum(a[3:][active])  # s per day**2
                out[i, k] = (value, slope / DAY / PPM, 2 * curvature / DAY / PPM)
        return out

    def result(self, x, scale, weight, rejected, iterations, method, echoes, settings):
        distance, _, _ = self.geometry(x)
        error = self.errors(x)
        emission = x[: self.n_pings][self.ping] + self.origin
        residuals = pd.DataFrame(
            {
                "ping": self.ping,
                "sync_tag": self.sync["sync_tag"].to_numpy(),
                "receiver": self.sync["receiver"].to_numpy(),
                "receiver_time": self.sync["time"].to_numpy(),
                "time": self.sync["time"].to_numpy() - self.correction(x),
                "emission_time": emission,
                "distance": distance,
                "residual_ms": 1e3 * error,
                "weight": weight,
                "rejected": rejected,
            }
        )
        file_positions = self.array[["x", "y", "z"]].to_numpy(dtype=float)
        positions = file_positions.copy()
        positions[self.refined, :2] = self._xy(x)[self.refined] + self.centre
        kept = residuals[~residuals["rejected"]].groupby("receiver")["residual_ms"]
        by = residuals.groupby("receiver")
        summary = pd.DataFrame(
            {
                "receiver": self.names,
                "detections": by.size().reindex(self.names, fill_value=0).to_numpy(),
                "rejected": by["rejected"].sum().reindex(self.names, fill_value=0).to_numpy(),
                "residual_sd_ms": kept.std(ddof=1).reindex(self.names).to_numpy(),
                "residual_median_ms": kept.median().reindex(self.names).to_numpy(),
                "sync_tag": self.array["sync_tag"].to_numpy(),
                "fixed": self.array["fixed"].to_numpy(dtype=bool),
                "moved_m": np.linalg.norm(positions[:, :2] - file_positions[:, :2], axis=1),
            }
        )
        clocks = ReceiverClocks(
            time_keeper=self.time_keeper,
            receivers=tuple(self.names),
            segment_starts=self.bounds[:-1].copy(),
            segment_ends=self.bounds[1:].copy(),
            coefficients=self.coefficients(x),
            sound_speed=self._speed(x).copy(),
            sound_speed_method=method,
            positions=positions,
            file_positions=file_positions,
            fixed=self.array["fixed"].to_numpy(dtype=bool),
            sync_tags=tuple(t if isinstance(t, str) else None for t in self.array["sync_tag"]),
            residual_sd_ms=summary["residual_sd_ms"].to_numpy(dtype=float),
            detections=summary["detections"].to_numpy(dtype=int),
            rejected=summary["rejected"].to_numpy(dtype=int),
            pings=self.n_pings,
            echoes_dropped=echoes,
            settings=settings,
        )
        return SyncFit(
            clocks=clocks,
            residuals=residuals,
            summary=summary,
            scale_ms=1e3 * scale,
            iterations=iterations,
        )
