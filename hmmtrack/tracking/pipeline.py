"""The tracking pipeline: detections + receiver positions + configuration → position estimates.

:func:`track` runs the particle filter (:class:`hmmtrack.tracking.filter.ParticleFilter`) for
every measurement model, the one the configuration's ``measurement`` section names
(:data:`hmmtrack.tracking.measurement.MEASUREMENTS`): the measurement builds the observations
from one transmitter's detections (:func:`build_observations`), derives the search box, adds
its own particle fields, hooks and diagnostics; :func:`track` chooses the correction policy
(the measurement's default, or tempered at the ``filter`` section's ``tempering_ess``), adds
a fixed-lag smoother when the run smooths (the configuration's ``smoothing_lag``, else the
measurement's default: the ping measurement smooths), runs the filter and
returns one :class:`TrackingResult`.

The motion model is one of the paper's (:mod:`hmmtrack.tracking.motion`), the one the
configuration's ``motion`` section builds unless a motion model is given.

The defaults were chosen on the synthetic analogues of the paper's three datasets; the
measurements behind them are in reports/decisions.md ("Tracking defaults", "Motion models",
"Tracking configuration"). The paper's
algorithm stays reachable: ``config.override(resampling="multinomial",
resample_when="always", variant="paper")`` (the HMM motion model in the paper's variant).

Detections logged by receivers with unsynchronised clocks are moved to the common time base
of the configuration's ``clocks`` file (:mod:`hmmtrack.sync`) before the measurement sees
them (:func:`tracked_detections`).

This module reads only the files the configuration names (motion model, clock file) and
computes no metrics (see :mod:`hmmtrack.io`, :mod:`hmmtrack.analysis.metrics`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.io.detections import drop_duplicate_detections, transmitter_rows
from hmmtrack.io.times import format_times
from hmmtrack.random import SeedLike, as_generator
from hmmtrack.sync import apply_clocks, read_clocks
from hmmtrack.tracking.acquisition import Acquisition
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.filter import FilterSettings, ParticleFilter
from hmmtrack.tracking.measurement import MEASUREMENTS
from hmmtrack.tracking.measurement.base import EVENT_COLUMNS
from hmmtrack.tracking.mirror import MirrorLine
from hmmtrack.tracking.mixture import Mixture, Modes, with_modes
from hmmtrack.tracking.monitor import Monitor
from hmmtrack.tracking.motion.baseline import BaselineMotion
from hmmtrack.tracking.receivers import ReceiverTracks
from hmmtrack.tracking.smoothing import Smoothed
from hmmtrack.tracking.tempering import Tempered

__all__ = [
    "TrackingResult",
    "build_observations",
    "clock_positions",
    "on_common_time",
    "particle_filter",
    "select_transmitter",
    "time_window",
    "track",
    "tracked_detections",
]

logger = logging.getLogger(__name__)


def select_transmitter(detections: pd.DataFrame, transmitter: str | None) -> pd.DataFrame:
    """The detections of one transmitter.

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table.
    transmitter : str or None
        Transmitter to keep: full id (``A69-1602-15266``) or, when the table has a
        ``transmitter_id`` column (every log read by :func:`hmmtrack.io.read_detections`),
        its ID part (``15266``) if that names one tag; ``None`` requires the table to hold
        exactly one (or no ``transmitter`` column).

    Returns
    -------
    pandas.DataFrame
        The rows of that transmitter (the others are counted in a log message).

    Raises
    ------
    ValueError
        For no such transmitter, or an ID part shared by tags in different code spaces
        (:func:`hmmtrack.io.detections.transmitter_rows`).
    """
    if "transmitter" not in detections.columns:
        if transmitter is None:  # (arrival-time detections of one tag may carry no id)
            return detections
        raise ValueError("detections table lacks column 'transmitter'")
    found = sorted(detections["transmitter"].astype(str).unique())
    if transmitter is None:
        if len(found) != 1:
            raise ValueError(
                f"the detections hold {len(found)} transmitters {found[:20]}; choose one "
                "(configuration key 'transmitter' or --transmitter)"
            )
        return detections
    source = detections.attrs.get("source", "detections")
    try:
        keep = transmitter_rows(detections, transmitter)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from exc
    if not keep.any():
        raise ValueError(
            f"{source}: no detections of transmitter {transmitter!r}; the table has {found[:20]}"
        )
    if not keep.all():
        logger.info(
            "tracking transmitter %s: %d detections, %d of other transmitters not used",
            transmitter,
            int(keep.sum()),
            int((~keep).sum()),
        )
    return detections.loc[keep]


def on_common_time(detections: pd.DataFrame, clocks: str | Path) -> pd.DataFrame:
    """Detections moved from each receiver's clock to the common time base of a clock file.

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table (``time`` s on each receiver's own clock, ``receiver``).
    clocks : str or Path
        Clock file of ``hmmtrack sync`` (:func:`hmmtrack.sync.read_clocks`).

    Returns
    -------
    pandas.DataFrame
        :func:`hmmtrack.sync.apply_clocks`: ``time`` common, ``receiver_time`` as logged,
        sorted by time.

    Raises
    ------
    ValueError
        For an unreadable clock file or one of another schema or version (naming the file
        and field), a receiver of the detections without a clock (naming it), or detections
        outside the time span the clocks were fitted over (saying by how much: a clock is
        not extrapolated).
    """
    fitted = read_clocks(clocks)
    try:
        synchronised = apply_clocks(detections, fitted)
    except ValueError as exc:
        raise ValueError(f"{clocks}: {exc}") from None
    first, last = float(fitted.segment_starts[0]), float(fitted.segment_ends[-1])
    times = synchronised["time"].to_numpy(dtype=float)
    before, after = times < first, times > last
    if before.any() or after.any():
        parts = []
        if before.any():
            parts.append(f"{int(before.sum())} up to {first - times.min():.1f} s before its start")
        if after.any():
            parts.append(f"{int(after.sum())} up to {times.max() - last:.1f} s after its end")
        window = " to ".join(format_times(np.array([first, last])))
        raise ValueError(
            f"{clocks}: {' and '.join(parts)} of the {len(times)} detections lie outside the "
            f"clock file's time span ({window}); fit the clocks over the whole deployment "
            "(hmmtrack sync on detections covering the tracked tag's)"
        )
    return synchronised


def clock_positions(receivers, clocks: str | Path):
    """The receivers with the positions the clock file's fit refined (receivers not marked
    fixed, ``hmmtrack sync --refine-positions``): the synced times are consistent with
    those positions, not the surveyed ones. Other receivers, and receiver tracks (GPS),
    are returned as given.

    Parameters
    ----------
    receivers : pandas.DataFrame or ReceiverTracks
    clocks : str or Path
        Clock file of ``hmmtrack sync``.
    """
    if isinstance(receivers, ReceiverTracks):
        return receivers
    fitted = read_clocks(clocks)
    moved = {
        name: position
        for name, position, given in zip(
            fitted.receivers, fitted.positions, fitted.file_positions, strict=True
        )
        if not np.array_equal(position, given)
    }
    if not moved:
        return receivers
    out = receivers.copy()
    rows = out["receiver"].astype(str).isin(list(moved)).to_numpy()
    for axis, column in enumerate(("x", "y")):
        out.loc[rows, column] = [moved[name][axis] for name in out.loc[rows, "receiver"]]
    logger.info("%d receiver position(s) refined by the clock file %s", len(moved), clocks)
    return out


def tracked_detections(detections: pd.DataFrame, config: TrackingConfig) -> pd.DataFrame:
    """The detections of ``config.transmitter`` (:func:`select_transmitter`), on the common
    time base of ``config.clocks`` when set (:func:`on_common_time`): what the measurement
    builds its observations from. Exact duplicate detections are dropped first
    (:func:`hmmtrack.io.detections.drop_duplicate_detections`), in the receivers' own
    clocks as logged."""
    chosen = drop_duplicate_detections(select_transmitter(detections, config.transmitter))
    return chosen if config.clocks is None else on_common_time(chosen, config.clocks)


def time_window(
    times, config: TrackingConfig, start: float | None = None, end: float | None = None
) -> tuple[float, float]:
    """Start and end (s) of a run: as given, else ``config.start``/``config.end``, else the
    first detection time rounded down and the last rounded up to whole seconds.

    Parameters
    ----------
    times : array_like, shape (n,)
        Detection times of the tracked transmitter (s), n ≥ 1.
    config : TrackingConfig
    start, end : float, optional
        Explicit window (s).
    """
    times = np.asarray(times, dtype=float)
    start = config.start if start is None else start
    end = config.end if end is None else end
    start = float(np.floor(times.min())) if start is None else float(start)
    end = float(np.ceil(times.max())) if end is None else float(end)
    return start, end


def build_observations(
    detections: pd.DataFrame, receivers: pd.DataFrame | ReceiverTracks, config: TrackingConfig
) -> pd.DataFrame:
    """The filter's observations of ``config.transmitter`` (:func:`tracked_detections`: on
    the common time base of ``config.clocks`` when set), as the configuration's measurement
    builds them (its ``observations``: :meth:`RangeRateMeasurement.observations
    <hmmtrack.tracking.measurement.range_rate.RangeRateMeasurement.observations>`,
    :func:`hmmtrack.tracking.measurement.clocked.arrival_observations`).

    Parameters
    ----------
    detections : pandas.DataFrame
        Detections table (``time`` s, ``receiver``, ``transmitter``; what else the
        measurement reads, e.g. ``depth`` m).
    receivers : pandas.DataFrame or ReceiverTracks
        Receiver positions table (``docs/interfaces.md``), or tracks built from it.
    config : TrackingConfig

    Raises
    ------
    ValueError
        When the transmitter is ambiguous, the clock file does not fit the detections
        (:func:`on_common_time`) or the measurement cannot build its observations (messages
        name what and where).
    """
    chosen = tracked_detections(detections, config)
    settings = config.measurement
    return MEASUREMENTS[settings.name].observations(chosen, receivers, settings)


def _require_usable(
    observations: pd.DataFrame,
    scored: pd.DataFrame,
    start: float,
    end: float,
    config: TrackingConfig,
    source: str | None,
) -> None:
    """Refuse a window with fewer than two detections, or none the likelihood uses (e.g. only
    the range-rate anchors): the filter would write a confident-looking per-second track
    from nothing but its prior."""
    dt = config.filter.prediction_step
    last = np.floor((end - start) / dt + 1e-9)

    def inside(table: pd.DataFrame) -> int:
        ticks = np.rint((table["time"].to_numpy(dtype=float) - start) / dt)
        return int(((ticks >= 0) & (ticks <= last)).sum())

    n_detections, n_scored = inside(observations), inside(scored)
    if n_detections >= 2 and n_scored >= 1:
        return
    window = " to ".join(format_times(np.array([start, end])))
    unused = (
        "" if n_scored or not n_detections else f", none of them used by {config.measurement.name}"
    )
    raise ValueError(
        f"{source or 'detections'}: the window {window} holds "
        f"{n_detections} detection(s) of the tracked transmitter{unused}; tracking needs at "
        "least two with information: widen the window (--start/--end) or check --transmitter"
    )


def _discard(estimates: pd.DataFrame) -> None:
    """A sink that keeps nothing (the filter's estimates of a streamed, smoothed run)."""


def _with_modes_so_far(sink: Callable[[pd.DataFrame], None], modes: Modes):
    """``sink`` fed each table of estimates with the modes beside it (:func:`with_modes`),
    from the modes recorded so far: the filter resamples at a time before it yields that
    time's estimate, so every resampling at or before a table's last time is recorded and
    the columns are those of the whole run's table. Each table reads the modes from the
    latest resampling at or before the previous table's last time on, and releases the
    rows before it, so neither the cost per table nor the memory grows with the run."""
    since = None

    def write(estimates: pd.DataFrame) -> None:
        nonlocal since
        sink(with_modes(estimates, modes.table(since)))
        since = float(estimates["time"].iloc[-1])
        modes.release(since)

    return write


@dataclass(frozen=True)
class TrackingResult:
    """What :func:`track` returns, for every measurement.

    Attributes
    ----------
    estimates : pandas.DataFrame or None
        One row per prediction step: ``time`` (s), ``x``, ``y`` (m), ``var_x``, ``var_y``,
        ``cov_xy`` (m²), ``sqrt_lambda1`` (m), ``n_eff``; with the modes reported
        (``config.filter.modes`` or ``mixture``) also
        :data:`hmmtrack.tracking.mixture.ESTIMATE_MODE_COLUMNS` (the second mode's
        position and weight, and ``converged``); ``None`` when they went to a sink
        (``track(..., estimates_to=...)``).
    snapshots : dict of float to pandas.DataFrame
        Particles (``x``, ``y``, ..., ``weight``) at the requested snapshot times.
    events : pandas.DataFrame
        ``time``, ``kind``, ``detail``: the filter's events (degenerate weights, a
        re-acquired clock, ...) and the measurement's (the range-rate anchor detections not
        passed to the likelihood), by time.
    observations : pandas.DataFrame
        The observations table built from the detections (all of them, anchors included).
    bounds : (xmin, xmax, ymin, ymax)
        Search box the particles started in (m).
    smoothed : pandas.DataFrame or None
        Fixed-lag smoothed estimates (:data:`hmmtrack.tracking.smoothing.SMOOTHED_COLUMNS`),
        when the configuration has a smoothing lag.
    ambiguity : pandas.DataFrame or None
        One row per correction (:data:`hmmtrack.tracking.diagnostics.AMBIGUITY_COLUMNS`),
        when recorded (the arrival-time measurement does).
    clock : pandas.DataFrame or None
        The estimated emission clock after each correction
        (:data:`hmmtrack.tracking.diagnostics.CLOCK_COLUMNS`; arrival-time measurement).
    modes : pandas.DataFrame or None
        The mixture's components after each resampling
        (:data:`hmmtrack.tracking.mixture.MODE_COLUMNS`), with ``config.filter.mixture`` or
        ``config.filter.modes``; ``None`` when the estimates, which carry the two heaviest
        modes' columns, went to a sink.
    pings : pandas.DataFrame or None
        Per correction of the ping measurement: the ping's estimated emission time and
        position (:class:`hmmtrack.tracking.measurement.tdoa.PingTrace`).
    """

    estimates: pd.DataFrame | None
    snapshots: dict
    events: pd.DataFrame
    observations: pd.DataFrame
    bounds: tuple[float, float, float, float]
    smoothed: pd.DataFrame | None = None
    ambiguity: pd.DataFrame | None = None
    clock: pd.DataFrame | None = None
    modes: pd.DataFrame | None = None
    pings: pd.DataFrame | None = None


def particle_filter(
    settings: FilterSettings,
    measurement,
    bounds,
    motion,
    *,
    seed: SeedLike = None,
    collect=(),
    mirror: MirrorLine | None = None,
) -> ParticleFilter:
    """The filter :func:`track` runs, not yet started (e.g. to step it online).

    Parameters
    ----------
    settings : FilterSettings
        Particles, resampling, prediction step and ``tempering_ess`` (a configuration's
        ``filter`` section).
    measurement : Measurement
        E.g. ``MEASUREMENTS[name].from_settings(config.measurement, observations, receivers)``.
    bounds : (xmin, xmax, ymin, ymax)
        Search box (m).
    motion
        Motion model.
    seed : int, SeedSequence or Generator
    collect : sequence of collectors
        Besides the measurement's own (``measurement.collectors()``).
    mirror : MirrorLine, optional
        With ``settings.mixture``, the line along which the mixture splits a component that
        straddles it (:class:`hmmtrack.tracking.mirror.MirrorLine`; :func:`track` gives the
        run's with ``settings.mirror_split``); none by default.

    Returns
    -------
    ParticleFilter
        Corrected by the measurement's default policy, or tempered at
        ``settings.tempering_ess`` when set (with the default's acceptance of moves);
        with ``settings.mixture``, resampled by components
        (:class:`hmmtrack.tracking.mixture.Mixture`) and reporting them
        (:class:`hmmtrack.tracking.mixture.Modes`; with ``settings.modes`` too, the
        clusters of the cloud); with ``settings.acquisition``, started
        from the first corrections' likelihood
        (:class:`hmmtrack.tracking.acquisition.Acquisition`); with ``settings.long_gap``
        and ``settings.monitor``, watched for a long gap and a lost tag and re-acquired
        (:class:`hmmtrack.tracking.monitor.Monitor`, those two rules).
    """
    correction = measurement.default_correction
    if settings.tempering_ess is not None:  # the measurement's kind of moves kept, no trigger
        correction = (
            replace(correction, ess=settings.tempering_ess, trigger=None)
            if isinstance(correction, Tempered)
            else Tempered(settings.tempering_ess)
        )
    return ParticleFilter(
        motion,
        measurement,
        n_particles=settings.n_particles,
        bounds=bounds,
        resampling=settings.resampling,
        resample_when=settings.resample_when,
        ess_threshold=settings.ess_threshold,
        rng=as_generator(seed),
        dt=settings.prediction_step,
        correction=correction,
        collect=[
            *measurement.collectors(),
            *collect,
            *([Modes()] if settings.mixture or settings.modes else []),
        ],
        mixture=Mixture(mirror=mirror) if settings.mixture else None,
        acquisition=(
            getattr(measurement, "default_acquisition", Acquisition())
            if settings.acquisition
            else None
        ),
        monitor=(
            Monitor(long_gap=settings.long_gap, loss=settings.monitor)
            if settings.long_gap or settings.monitor
            else None
        ),
    )


def track(
    detections: pd.DataFrame,
    receivers: pd.DataFrame | ReceiverTracks,
    config: TrackingConfig,
    motion=None,
    *,
    seed: SeedLike = None,
    start: float | None = None,
    end: float | None = None,
    snapshot_times: Sequence[float] = (),
    measurement=None,
    collect: Sequence = (),
    estimates_to: Callable[[pd.DataFrame], None] | None = None,
) -> TrackingResult:
    """Estimate the tag's position every prediction step (the ``filter`` section's, 1 s).

    Parameters
    ----------
    detections, receivers, config
        See :func:`build_observations`; the configuration's sections name the measurement,
        the motion model (its model file, variant, resting state; settings it leaves unset
        are the measurement's, :meth:`~hmmtrack.tracking.config.TrackingConfig.motion_model`),
        the filter's settings,
        its ``clocks`` a clock file mapping the receivers' times to the common time base
        (and the positions it refined, :func:`clock_positions`),
        and its smoothing lag
        (:attr:`~hmmtrack.tracking.config.TrackingConfig.smoothing`) a fixed-lag smoother.
    motion : motion model, optional
        The motion model to run instead of the one the ``motion`` section builds.
    seed : int, SeedSequence or Generator
        Seed of every random draw of the filter; the same seed gives the same estimates.
    start, end : float, optional
        Time window (s); by default ``config.start`` and ``config.end``, and when those are
        unset the first and last detection of the tracked transmitter, in whole seconds.
    snapshot_times : sequence of float
        Times (s) at which to keep copies of the particles.
    measurement : Measurement, optional
        The measurement to run instead of the one the ``measurement`` section builds (its
        class's ``from_settings``), e.g. an arrival-time measurement with another clock
        model; it must be of the class the section names.
    collect : sequence of collectors
        More collectors (:mod:`hmmtrack.tracking.diagnostics`) besides the measurement's.
    estimates_to : callable, optional
        A sink for the per-second estimates, called with tables of them as they are made
        (:meth:`hmmtrack.tracking.filter.ParticleFilter.run`), e.g.
        :class:`hmmtrack.io.EstimatesWriter`: memory then stays bounded by the particles,
        not the span, and the result's ``estimates`` are ``None``. With the modes reported
        (``config.filter.modes`` or ``mixture``) each table carries their columns
        (:func:`hmmtrack.tracking.mixture.with_modes`) and the result's ``modes`` are
        ``None`` (the modes table grows by one row per resampling, about 290,000 rows in a
        30-day run: 34-140 MB kept). When the run smooths, the sink takes the smoothed
        estimates instead (``lag`` steps late), the filter's are dropped, and the result's
        ``smoothed`` are ``None`` too.

    Returns
    -------
    TrackingResult
    """
    settings = config.measurement
    kind = MEASUREMENTS[settings.name]
    if config.clocks is not None:
        receivers = clock_positions(receivers, config.clocks)
    observations = build_observations(detections, receivers, config)
    if observations.empty:
        raise ValueError("no detections to track from")
    if measurement is None:
        measurement = kind.from_settings(settings, observations, receivers)
    elif not isinstance(measurement, kind):
        raise ValueError(
            f"measurement {type(measurement).__name__} is not the configuration's "
            f"{settings.name!r} ({kind.__name__})"
        )
    if isinstance(motion, str):
        raise ValueError(
            f"motion {motion!r}: give a motion model, or name it in the configuration "
            "(its motion section, e.g. config.override(motion=...))"
        )
    if motion is None:
        motion = config.motion_model()
    bounds = measurement.start_box(
        observations, receivers, settings, config.bounds, config.start if start is None else start
    )
    start, end = time_window(observations["time"].to_numpy(), config, start, end)
    scored, measurement_events = measurement.split(observations)
    _require_usable(observations, scored, start, end, config, detections.attrs.get("source"))
    collectors = [*collect]
    if config.smoothing is not None:
        bridge = measurement.bridge(scored) if hasattr(measurement, "bridge") else None
        backward = (
            motion.sigma
            if isinstance(motion, BaselineMotion) and getattr(measurement, "backward", False)
            else None
        )  # (backward simulation: a random walk's smoother, where the measurement asks)
        pin_fixes = backward is None  # (traced ancestry is broken at tempered pings: Smoothed)
        collectors.append(
            Smoothed(
                config.smoothing,
                sink=estimates_to,
                bridge=bridge,
                backward=backward,
                pin_fixes=pin_fixes,
            )
        )
        if estimates_to is not None:
            estimates_to = _discard  # the sink takes the smoothed estimates instead
    mirror = (
        MirrorLine.from_observations(scored, receivers)
        if config.filter.mixture and config.filter.mirror_split
        else None
    )
    pf = particle_filter(
        config.filter, measurement, bounds, motion, seed=seed, collect=collectors, mirror=mirror
    )
    modes = next((c for c in pf.collect if isinstance(c, Modes)), None)
    if estimates_to is not None and estimates_to is not _discard and modes is not None:
        modes.keep = False  # (they leave with the estimates)
        estimates_to = _with_modes_so_far(estimates_to, modes)
    result = pf.run(scored, start, end, snapshot_times, estimates_to=estimates_to)
    events = pd.concat(
        [df for df in (measurement_events, result.events) if not df.empty]
        or [pd.DataFrame(columns=list(EVENT_COLUMNS))],
        ignore_index=True,
    ).sort_values("time", kind="stable", ignore_index=True)
    estimates = result.estimates
    if "modes" in result.collected and estimates is not None:  # (streamed: added per table)
        estimates = with_modes(estimates, result.collected["modes"])
    return TrackingResult(
        estimates=estimates,
        snapshots=result.snapshots,
        events=events,
        observations=observations,
        bounds=tuple(float(b) for b in bounds),
        **result.collected,
    )
