"""Where each receiver (hydrophone) is and how fast it moves, at any time.

:class:`ReceiverTracks` turns the receiver-positions table (``receiver``, ``time``, ``x``,
``y``; see ``docs/interfaces.md``) into a function of time: ``state(receiver, t) -> (x, y,
vx, vy)``, which the range-rate measurement model needs at every detection.

Positions are interpolated linearly between GPS fixes. Velocities are the slope of the
interpolated path over a window of ``velocity_window`` seconds centred on ``t``
(``(p(t + w/2) - p(t - w/2)) / w``, the window shrunk at the ends of the track). With
``velocity_window=0`` the velocity is the slope of the GPS segment containing ``t``, exact for
a path that is straight between fixes but as noisy as the fixes: with 1 Hz GPS and metre-level
noise, segment slopes scatter by about 1.4 m/s, comparable to a boat's speed. A window of
10-30 s averages that noise down (by about ``1/w`` for white noise) while following turns that
last longer than the window; for a constant-velocity path every window gives the exact
velocity. A moored receiver (one row, no time) is fixed, with zero velocity.

Not for: reading files (:mod:`hmmtrack.io`), ranging (:mod:`hmmtrack.tracking.measurement.ranging`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from hmmtrack.io import validate_receivers


@dataclass(frozen=True)
class _Track:
    time: np.ndarray  # (m,) s, strictly increasing; empty for a moored receiver
    x: np.ndarray  # (m,) m, or (1,) for a moored receiver
    y: np.ndarray


@dataclass(frozen=True)
class ReceiverTracks:
    """Receiver positions and velocities as functions of time.

    Build with :meth:`from_frame`. Frozen; safe to share between threads.

    Attributes
    ----------
    velocity_window : float
        Width (s) of the centred window over which velocities are averaged; 0 uses the slope
        of the GPS segment containing ``t``.
    outside : {"error", "clamp"}
        Times outside a mobile receiver's track raise ``ValueError`` (``"error"``), or get the
        nearest end position and zero velocity (``"clamp"``).
    """

    tracks: dict[str, _Track] = field(repr=False)
    velocity_window: float = 0.0
    outside: str = "error"

    @classmethod
    def from_frame(
        cls, positions: pd.DataFrame, *, velocity_window: float = 0.0, outside: str = "error"
    ) -> ReceiverTracks:
        """Build from a receiver-positions table (rows of a receiver in time order).

        Parameters
        ----------
        positions : DataFrame
            ``receiver`` (str), ``time`` (s; NaN on the single row of a moored receiver),
            ``x``, ``y`` (m), e.g. from :func:`hmmtrack.io.read_receivers`.
        velocity_window : float
            See the class docstring (s, >= 0).
        outside : {"error", "clamp"}
            See the class docstring.
        """
        if not velocity_window >= 0:
            raise ValueError(f"velocity_window must be >= 0 s, got {velocity_window!r}")
        if outside not in ("error", "clamp"):
            raise ValueError(f"outside must be 'error' or 'clamp', got {outside!r}")
        validate_receivers(positions)
        tracks = {}
        names = positions["receiver"].astype(str).to_numpy()
        time = positions["time"].to_numpy(dtype=float)
        x = positions["x"].to_numpy(dtype=float)
        y = positions["y"].to_numpy(dtype=float)
        for name in pd.unique(names):
            rows = names == name
            moored = np.isnan(time[rows]).all()
            tracks[str(name)] = _Track(
                time=np.empty(0) if moored else time[rows], x=x[rows], y=y[rows]
            )
        return cls(tracks=tracks, velocity_window=float(velocity_window), outside=outside)

    @property
    def names(self) -> tuple[str, ...]:
        """Receiver names, in the order of the table."""
        return tuple(self.tracks)

    def is_moored(self, receiver: str) -> bool:
        """Whether ``receiver`` is fixed (one position, no time)."""
        return self._track(receiver).time.size == 0

    def span(self, receiver: str) -> tuple[float, float]:
        """First and last GPS time (s) of a mobile receiver; ``(-inf, inf)`` if moored."""
        track = self._track(receiver)
        if track.time.size == 0:
            return (-np.inf, np.inf)
        return (float(track.time[0]), float(track.time[-1]))

    def _track(self, receiver: str) -> _Track:
        try:
            return self.tracks[receiver]
        except KeyError:
            raise KeyError(
                f"unknown receiver {receiver!r}; receivers with positions: {list(self.tracks)}"
            ) from None

    def state(
        self, receiver: str, t: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position and velocity of ``receiver`` at times ``t``.

        Parameters
        ----------
        receiver : str
            Receiver name (as in the positions table and the detections).
        t : float or ndarray, shape (n,)
            UTC seconds.

        Returns
        -------
        x, y, vx, vy : ndarray, each shape (n,)
            Position (m) and velocity (m/s).
        """
        track = self._track(receiver)
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not np.all(np.isfinite(t)):
            raise ValueError(f"receiver {receiver!r}: times must be finite")
        if track.time.size == 0:
            zeros = np.zeros_like(t)
            return np.full_like(t, track.x[0]), np.full_like(t, track.y[0]), zeros, zeros.copy()
        start, end = track.time[0], track.time[-1]
        outside = (t < start) | (t > end)
        if outside.any() and self.outside == "error":
            bad = t[outside]
            raise ValueError(
                f"receiver {receiver!r}: {bad.size} time(s) outside its GPS track "
                f"[{start:.3f}, {end:.3f}] s (first {bad[0]:.3f} s); extend the track or build "
                "ReceiverTracks with outside='clamp'"
            )
        tc = np.clip(t, start, end)
        x = np.interp(tc, track.time, track.x)
        y = np.interp(tc, track.time, track.y)
        if track.time.size == 1:
            return x, y, np.zeros_like(t), np.zeros_like(t)
        seg = np.clip(np.searchsorted(track.time, tc, side="right") - 1, 0, track.time.size - 2)
        dt = track.time[seg + 1] - track.time[seg]
        vx = (track.x[seg + 1] - track.x[seg]) / dt
        vy = (track.y[seg + 1] - track.y[seg]) / dt
        if self.velocity_window > 0:
            lo = np.clip(tc - self.velocity_window / 2, start, end)
            hi = np.clip(tc + self.velocity_window / 2, start, end)
            width = hi - lo
            chord = width > 0  # a window below the time resolution keeps the segment slope
            safe = np.where(chord, width, 1.0)
            dx = np.interp(hi, track.time, track.x) - np.interp(lo, track.time, track.x)
            dy = np.interp(hi, track.time, track.y) - np.interp(lo, track.time, track.y)
            vx = np.where(chord, dx / safe, vx)
            vy = np.where(chord, dy / safe, vy)
        if outside.any():
            vx = np.where(outside, 0.0, vx)
            vy = np.where(outside, 0.0, vy)
        return x, y, vx, vy
