"""Continuous-time paths: where a simulated animal or hydrophone is at any instant.

A :class:`Trajectory` is a piecewise-linear path through timed vertices (``x``, ``y`` and an
optional ``depth``), evaluated exactly at arbitrary times. The scenario generators describe
every moving thing (tag, AUV, boat) with one, so that detections can be simulated at the true
emission and arrival instants instead of at the nearest sample.

This module is for *exact positions of simulated things*; it is not a track reader (that is
:mod:`hmmtrack.tracks`) and does no smoothing or random drawing of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Trajectory:
    """A piecewise-linear path through timed vertices, constant before the first and after the last.

    Parameters
    ----------
    time : (n,) float array
        Vertex times (UTC seconds), strictly increasing; ``n >= 1`` (one vertex = a fixed
        point).
    x, y : (n,) float arrays
        Vertex positions (m, projected).
    depth : (n,) float array, optional
        Vertex depths (m, positive down); ``None`` means at the surface (depth 0).
    """

    time: np.ndarray
    x: np.ndarray
    y: np.ndarray
    depth: np.ndarray | None = None

    def __post_init__(self) -> None:
        arrays = {"time": self.time, "x": self.x, "y": self.y}
        if self.depth is not None:
            arrays["depth"] = self.depth
        for name, values in arrays.items():
            values = np.array(values, dtype=float)
            values.setflags(write=False)
            object.__setattr__(self, name, values)
        n = self.time.size
        if n == 0:
            raise ValueError("Trajectory: needs at least one vertex, got none")
        for name, values in arrays.items():
            values = getattr(self, name)
            if values.shape != (n,):
                raise ValueError(
                    f"Trajectory: column {name!r} has shape {values.shape}, expected ({n},) "
                    "like 'time'"
                )
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise ValueError(
                    f"Trajectory: column {name!r} has non-finite values at vertices "
                    f"{bad[:10].tolist()}"
                )
        steps = np.flatnonzero(np.diff(self.time) <= 0)
        if steps.size:
            raise ValueError(
                "Trajectory: 'time' must be strictly increasing; it is not after vertices "
                f"{steps[:10].tolist()}"
            )

    @classmethod
    def fixed(cls, x: float, y: float, depth: float | None = None) -> Trajectory:
        """A point that does not move (a moored hydrophone, an anchored tag)."""
        return cls(
            time=np.zeros(1),
            x=np.array([x]),
            y=np.array([y]),
            depth=None if depth is None else np.array([depth]),
        )

    @property
    def start(self) -> float:
        """Time of the first vertex (s)."""
        return float(self.time[0])

    @property
    def end(self) -> float:
        """Time of the last vertex (s)."""
        return float(self.time[-1])

    def position(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact position at times ``t``.

        Parameters
        ----------
        t : (m,) float array
            Times (UTC seconds); times outside ``[start, end]`` get the nearest end vertex.

        Returns
        -------
        x, y, depth : (m,) float arrays
            Position (m); depth is 0 where the trajectory has none.
        """
        t = np.asarray(t, dtype=float)
        x = np.interp(t, self.time, self.x)
        y = np.interp(t, self.time, self.y)
        depth = np.zeros_like(x) if self.depth is None else np.interp(t, self.time, self.depth)
        return x, y, depth

    def sample(self, t: np.ndarray) -> Trajectory:
        """A new trajectory with vertices at times ``t`` (linear interpolation of this one)."""
        x, y, depth = self.position(t)
        return Trajectory(t, x, y, None if self.depth is None else depth)
