"""The mirror line: the line through the two receivers that heard the tag last.

A tag heard by two receivers ``a`` and ``b`` and by no other is placed by its ranges to them,
and the reflection of any track across the line through ``a(t)`` and ``b(t)``, taken at every
time ``t``, keeps both ranges at every time: so it keeps their rates of change too (the
range-rates), whatever the receivers' motion. The two sides of that line are then told apart
by nothing the receivers measure, only by the start region and the motion model (a track whose
mirror image has to turn where the receivers turn). With ``FilterSettings.mirror_split`` (off
in every named filter), :class:`hmmtrack.tracking.mixture.Mixture` splits each component that
straddles the line along it, so that the weight on each side is the exact sum of its
particles' weights, not a share that resampling lets drift while the two intersections of the
rings still overlap (reports/decisions.md, "The mirror split": on fresh synthetic shark
pursuits it kept the HMM on the tag's side where drift had lost it, and did not lower the
velocity model's losses, where its motion prior favours the mirror's track).

:class:`MirrorLine` answers, at any time, with the positions of the two receivers whose latest
detections up to then are the latest (both at that time, from their tracks), or ``None``
before two receivers have heard the tag.

This module reads no files and scores no observations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.tracking.receivers import ReceiverTracks

__all__ = ["MirrorLine"]


@dataclass(frozen=True)
class MirrorLine:
    """The line through the two receivers that heard the tag last, at any time.

    Build with :meth:`from_observations`.

    Attributes
    ----------
    times : numpy.ndarray, shape (M,)
        Times (s) of the observations, increasing.
    last : numpy.ndarray, shape (M,), int64
        Receiver (index into ``paths``) of each observation.
    other : numpy.ndarray, shape (M,), int64
        The receiver heard last before observation ``j`` among the others than ``last[j]``
        (its latest observation at or before ``times[j]``), ``-1`` when there is none yet.
    paths : tuple of (time, x, y) arrays
        Each receiver's GPS track (s, m, m; times increasing), one row without a time for a
        moored receiver; a time outside a mobile receiver's track takes its nearest end.
    """

    times: np.ndarray
    last: np.ndarray
    other: np.ndarray
    paths: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]

    @classmethod
    def from_observations(
        cls, observations: pd.DataFrame, receivers: pd.DataFrame | ReceiverTracks
    ) -> MirrorLine | None:
        """The mirror line of a run's observations.

        Parameters
        ----------
        observations : pandas.DataFrame
            ``time`` (s) and ``receiver`` of each observation (any order).
        receivers : pandas.DataFrame or ReceiverTracks
            Receiver positions (``receiver``, ``time``, ``x``, ``y``), see
            ``docs/interfaces.md``.

        Returns
        -------
        MirrorLine or None
            ``None`` when the observations name no receiver (no ``receiver`` column) or
            fewer than two.
        """
        if "receiver" not in observations or observations["receiver"].nunique() < 2:
            return None
        ordered = observations.sort_values("time", kind="stable")
        codes, names = pd.factorize(ordered["receiver"])
        last = codes.astype(np.int64)
        # the latest observation by another receiver is the one just before the run of
        # observations by the same receiver that holds j
        index = np.arange(last.size)
        run_start = np.maximum.accumulate(np.where(np.r_[True, last[1:] != last[:-1]], index, 0))
        other = np.where(run_start > 0, last[run_start - 1], -1)
        tracks = (
            receivers
            if isinstance(receivers, ReceiverTracks)
            else ReceiverTracks.from_frame(receivers)
        ).tracks
        paths = tuple(
            (tracks[str(name)].time, tracks[str(name)].x, tracks[str(name)].y) for name in names
        )
        return cls(ordered["time"].to_numpy(dtype=float), last, other, paths)

    def at(self, time: float) -> tuple[float, float, float, float] | None:
        """Positions ``(ax, ay, bx, by)`` (m) at ``time`` of the two receivers heard last up
        to ``time`` (s): the one heard last and, among the others, the one heard last; ``None``
        before two receivers have heard the tag."""
        j = int(np.searchsorted(self.times, time, side="right")) - 1
        if j < 0 or self.other[j] < 0:
            return None
        return (
            *_position(self.paths[self.last[j]], time),
            *_position(self.paths[self.other[j]], time),
        )


def _position(path, time: float) -> tuple[float, float]:
    """Where a receiver is at ``time`` (s): linear between its fixes, its nearest end
    outside them (``numpy.interp``), its one position when moored (m). (Not
    :meth:`ReceiverTracks.state`: its velocities and checks cost six times as much, once per
    resampling.)"""
    times, x, y = path
    if times.size == 0:
        return float(x[0]), float(y[0])
    return float(np.interp(time, times, x)), float(np.interp(time, times, y))
