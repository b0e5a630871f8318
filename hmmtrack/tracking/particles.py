"""The particle set of the tracking filter: a structure of arrays, one entry per particle.

A particle is the paper's state ``[x, y, theta, v, omega]`` plus its log weight, its
behavioural state (used by the HMM motion model) and the time since its speed and turn
rate were last drawn (used by the time-consistent HMM motion model). ``cos_heading`` and
``sin_heading`` are kept beside ``heading`` so that the motion kernels rotate the heading
with one sine/cosine pair per step instead of recomputing three trigonometric functions.

This module only stores, creates, copies and selects particles; motion models
(:mod:`hmmtrack.tracking.motion`) move them and measurement models
(:mod:`hmmtrack.tracking.measurement.range_rate`)
weigh them.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field, fields

import numba
import numpy as np
import pandas as pd
from numba import njit

from hmmtrack.tracking.compiled.chunks import chunk_ancestors, in_chunks, next_chunk

__all__ = ["Bounds", "Particles", "as_bounds", "split_in_two", "sqrt_largest_eigenvalue"]

Bounds = tuple[float, float, float, float]


def as_bounds(bounds) -> Bounds:
    """Return ``bounds`` as ``(xmin, xmax, ymin, ymax)`` floats, refusing an empty box."""
    try:
        xmin, xmax, ymin, ymax = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise ValueError(
            f"bounds must be (xmin, xmax, ymin, ymax) in metres, got {bounds!r}"
        ) from None
    if not (np.isfinite([xmin, xmax, ymin, ymax]).all() and xmin < xmax and ymin < ymax):
        raise ValueError(
            "bounds must be finite with xmin < xmax and ymin < ymax, "
            f"got {(xmin, xmax, ymin, ymax)}"
        )
    return xmin, xmax, ymin, ymax


@dataclass
class Particles:
    """Particle arrays, each of shape ``(N,)``.

    Attributes
    ----------
    x, y : float64
        Position, projected metres (x east, y north).
    heading : float64
        Direction of motion, radians counter-clockwise from +x, in ``(-pi, pi]``.
    cos_heading, sin_heading : float64
        ``cos(heading)`` and ``sin(heading)``, kept in step with ``heading``.
    speed : float64
        Linear velocity ``v`` along the heading, m/s (the velocity model lets it be negative).
    turn_rate : float64
        Angular velocity ``omega``, rad/s.
    state : int64
        Behavioural state (HMM motion model), ``0 .. K-1``; 0 for the other models.
    time_since_draw : float64
        Seconds since speed and turn rate were last drawn (time-consistent HMM motion,
        which starts it uniform on ``[0, model.dt)`` so that particles redraw at staggered
        times; ``inf`` means a draw is due).
    log_weight : float64
        Log importance weight; ``-inf`` marks an impossible particle.
    extra : dict of str to (N,) array
        Further per-particle fields that other process or measurement models need (for
        example a transmitter clock's ``emission_time`` and ``period``); they are read as
        attributes (``particles.emission_time``) and copied, taken and resampled with the
        rest. Assign them through the dict (``particles.extra["emission_time"] = ...``):
        ``particles.emission_time = ...`` would make a plain attribute that :meth:`take`
        and :meth:`copy` do not carry.
    """

    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    cos_heading: np.ndarray
    sin_heading: np.ndarray
    speed: np.ndarray
    turn_rate: np.ndarray
    state: np.ndarray
    time_since_draw: np.ndarray
    log_weight: np.ndarray
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = np.shape(self.x)
        for name in _ARRAY_NAMES:
            dtype = np.int64 if name == "state" else np.float64
            value = np.require(getattr(self, name), dtype=dtype, requirements=("C", "W", "A"))
            if value.shape != n or value.ndim != 1:
                raise ValueError(f"Particles.{name} has shape {value.shape}, expected {n}")
            setattr(self, name, value)
        for name, value in self.extra.items():
            value = np.require(value, requirements=("C", "W", "A"))
            if value.shape != n:
                raise ValueError(f"Particles.extra[{name!r}] has shape {value.shape}, expected {n}")
            self.extra[name] = value

    def __getattr__(self, name: str) -> np.ndarray:
        extra = self.__dict__.get("extra", {})
        if name in extra:
            return extra[name]
        raise AttributeError(f"Particles has no field {name!r}")

    @property
    def n(self) -> int:
        """Number of particles ``N``."""
        return self.x.size

    @classmethod
    def from_state(
        cls,
        x: np.ndarray,
        y: np.ndarray,
        heading: np.ndarray,
        speed: np.ndarray | float = 0.0,
        turn_rate: np.ndarray | float = 0.0,
        state: np.ndarray | int = 0,
    ) -> Particles:
        """Build particles from the paper's state variables, with equal weights.

        Parameters
        ----------
        x, y : (N,) float, metres
        heading : (N,) float, radians
        speed : (N,) float or scalar, m/s
        turn_rate : (N,) float or scalar, rad/s
        state : (N,) int or scalar, behavioural state
        """
        x = np.asarray(x, dtype=np.float64)
        n = x.size
        heading = np.broadcast_to(np.asarray(heading, dtype=np.float64), (n,))
        return cls(
            x=x,
            y=np.asarray(y, dtype=np.float64),
            heading=heading,
            cos_heading=np.cos(heading),
            sin_heading=np.sin(heading),
            speed=np.broadcast_to(np.asarray(speed, dtype=np.float64), (n,)),
            turn_rate=np.broadcast_to(np.asarray(turn_rate, dtype=np.float64), (n,)),
            state=np.broadcast_to(np.asarray(state, dtype=np.int64), (n,)),
            time_since_draw=np.zeros(n),
            log_weight=np.full(n, -np.log(n)),
        )

    @classmethod
    def uniform(cls, rng: np.random.Generator, n: int, bounds) -> Particles:
        """The paper's Algorithm 1: ``n`` particles uniform in ``bounds``, at rest.

        Parameters
        ----------
        rng : numpy.random.Generator
        n : int
            Number of particles.
        bounds : (xmin, xmax, ymin, ymax), metres

        Returns
        -------
        Particles with x ~ U(xmin, xmax), y ~ U(ymin, ymax), heading ~ U(-pi/2, pi/2),
        speed 0, turn rate 0, state 0 and equal weights.
        """
        if n < 1:
            raise ValueError(f"need at least one particle, got n={n}")
        xmin, xmax, ymin, ymax = as_bounds(bounds)
        return cls.from_state(
            x=rng.uniform(xmin, xmax, n),
            y=rng.uniform(ymin, ymax, n),
            heading=rng.uniform(-np.pi / 2, np.pi / 2, n),
        )

    def copy(self) -> Particles:
        """Deep copy."""
        return self.take(np.arange(self.n))

    def take(
        self,
        indices: np.ndarray,
        equal_weights: bool = False,
        out: Particles | None = None,
        threads: int = 1,
        locate=None,
    ) -> Particles:
        """Particles ``self[indices]`` for every field (used after resampling).

        Parameters
        ----------
        indices : (M,) int array
            Ancestor of each new particle; with ``locate``, a contiguous int64 array that
            receives them.
        equal_weights : bool
            Give the new particles the equal log weights ``-log M`` instead of their
            ancestors' (what resampling does; the old ones are then not gathered).
        out : Particles, optional
            Particles whose arrays receive the fields and which are returned, when they are
            M particles in contiguous arrays of the fields' dtypes and are not ``self``
            (the particle filter's spare set: no fresh arrays to allocate and fault in);
            otherwise, and by default, the fields are new arrays. Extra fields are always
            new arrays.
        threads : int
            Threads for the compiled gather (in the chunks of
            :mod:`hmmtrack.tracking.compiled.chunks`; results do not depend on it).
        locate : NamedTuple, optional
            Finds the ancestors chunk by chunk in the pass that gathers them, into
            ``indices`` (:func:`hmmtrack.tracking.compiled.chunks.chunk_ancestors`; a
            resampling's :class:`hmmtrack.tracking.resampling.Prepared`: its inverse CDF's
            merge), so that they are in the cache when their particles are gathered.
        """
        indices = np.asarray(indices)
        if indices.ndim != 1 or indices.dtype.kind not in _INTEGER_KINDS:
            raise ValueError(
                f"Particles.take needs a 1-D integer array of indices, got a {indices.dtype} "
                f"array of shape {indices.shape}"
            )
        m = indices.size
        names = _MOTION_NAMES if equal_weights else _FLOAT_NAMES
        source, compiled = self, _contiguous(self, names)
        if locate is not None and not compiled:  # fields of another layout: the kernel reads
            source, compiled = _contiguous_copy(self), True  # contiguous copies
        if compiled:
            inside = locate is not None or _all_inside(indices, self.n)
            if inside:
                taken = out if _fits(out, m, source) else _empty(m, source.state.dtype)
                log_target = taken.log_weight
                log_source = log_target if equal_weights else source.log_weight
                in_chunks(
                    _gather_kernel, _gather_parallel, m, threads,
                    (
                        locate, indices,
                        *_motion_arrays(source),
                        *_motion_arrays(taken),
                        log_source, log_target, equal_weights, -math.log(max(m, 1)),
                        source.state,
                    ),
                    taken.state,
                )  # fmt: skip
        else:  # fields replaced by arrays of another layout: NumPy's indexing
            inside = m == 0 or 0 <= indices.min() <= indices.max() < self.n
            if inside:
                taken = object.__new__(Particles)
                for name in (*names, "state"):
                    setattr(taken, name, getattr(self, name)[indices])
                if equal_weights:
                    taken.log_weight = np.full(m, -np.log(m))
        if not inside:
            raise ValueError(
                f"Particles.take needs indices in 0..{self.n - 1}, got values from "
                f"{indices.min()} to {indices.max()}"
            )
        taken.extra = {name: value[indices] for name, value in self.extra.items()}
        return taken

    def normalised_weights(self) -> np.ndarray:
        """Weights ``exp(log_weight)`` scaled to sum one, shape ``(N,)``."""
        w = np.exp(self.log_weight - self.log_weight.max())
        return w / w.sum()

    def to_frame(self) -> pd.DataFrame:
        """Snapshot as a table: x, y, heading, speed, turn_rate, state, weight."""
        return pd.DataFrame(
            {
                "x": self.x,
                "y": self.y,
                "heading": self.heading,
                "speed": self.speed,
                "turn_rate": self.turn_rate,
                "state": self.state,
                "weight": self.normalised_weights(),
            }
        )


_ARRAY_NAMES = tuple(f.name for f in fields(Particles) if f.name != "extra")
_FLOAT_NAMES = tuple(name for name in _ARRAY_NAMES if name != "state")
_MOTION_NAMES = tuple(name for name in _FLOAT_NAMES if name != "log_weight")
#: the motion fields of particles as a tuple (one C call: 1.5 us less per gather than two
#: generators of ``getattr``, 2.7 against 1.2 us)
_motion_arrays = operator.attrgetter(*_MOTION_NAMES)
#: the float fields' dtype (a dtype: comparing with it is faster than with ``np.float64``,
#: which NumPy converts to a dtype at every comparison)
_FLOAT64 = np.dtype(np.float64)
#: the dtype kinds of NumPy's integer types (signed, unsigned): a test of ``dtype.kind``
#: costs a tenth of ``np.issubdtype(dtype, np.integer)``
_INTEGER_KINDS = ("i", "u")


def _empty(m: int, state_dtype) -> Particles:
    """Particles of ``m`` particles in new, uninitialised, contiguous arrays (nothing for
    ``__post_init__`` to check or convert)."""
    empty = object.__new__(Particles)
    for name in _FLOAT_NAMES:
        setattr(empty, name, np.empty(m))
    empty.state = np.empty(m, dtype=state_dtype)
    return empty


def _fits(out: Particles | None, m: int, source: Particles) -> bool:
    """Whether ``out`` can receive ``m`` particles taken from ``source``."""
    if out is None or out is source:
        return False
    shape = (m,)
    for name in _FLOAT_NAMES:
        a = getattr(out, name)
        flags = a.flags
        if not (
            a.shape == shape and a.dtype == _FLOAT64 and flags.c_contiguous and flags.writeable
        ):
            return False
    state = out.state
    flags = state.flags
    return (
        state.shape == shape
        and state.dtype == source.state.dtype
        and flags.c_contiguous
        and flags.writeable
    )


def _contiguous(p: Particles, names: tuple[str, ...]) -> bool:
    """Whether the float fields ``names`` of ``p`` are contiguous float64 arrays (what the
    compiled gather reads)."""
    for name in names:
        a = getattr(p, name)
        if not (a.dtype == _FLOAT64 and a.flags.c_contiguous):
            return False
    return True


def _contiguous_copy(p: Particles) -> Particles:
    """``p`` with every field a contiguous array of its dtype (copies where needed)."""
    copy = object.__new__(Particles)
    for name in _FLOAT_NAMES:
        setattr(copy, name, np.ascontiguousarray(getattr(p, name), dtype=np.float64))
    copy.state = np.ascontiguousarray(p.state)
    return copy


@njit(cache=True)
def _all_inside(indices, n):
    """Whether every index lies in ``0..n-1`` (one branch-free, vectorised pass)."""
    inside = True
    for i in range(indices.size):
        inside &= (indices[i] >= 0) & (indices[i] < n)
    return inside


@njit(cache=True, nogil=True)
def _gather_kernel(
    locate, indices, x, y, heading, cos_heading, sin_heading, speed, turn_rate,
    time_since_draw, x_to, y_to, heading_to, cos_heading_to, sin_heading_to, speed_to,
    turn_rate_to, time_since_draw_to, log_source, log_target, equal, log_fill, state_source,
    counter, state_target,
):  # fmt: skip
    """For each chunk not yet claimed (:func:`next_chunk`) of the ``M`` new particles
    ``lo:hi``: their ancestors ``indices[lo:hi]`` found by ``locate``
    (:func:`~hmmtrack.tracking.compiled.chunks.chunk_ancestors`; ``None``: given), then
    ``x_to[lo:hi] = x[indices[lo:hi]]`` and so on for every motion array, the same for the
    state and the log weight, or ``log_fill`` for every log weight when ``equal``. Indices
    must lie inside the sources. The arrays are separate arguments, not tuples: the call's
    dispatch types a tuple of arrays more slowly than the arrays themselves (about 1.5 us
    less per call for these two)."""
    sources = (x, y, heading, cos_heading, sin_heading, speed, turn_rate, time_since_draw)
    targets = (
        x_to, y_to, heading_to, cos_heading_to, sin_heading_to, speed_to, turn_rate_to,
        time_since_draw_to,
    )  # fmt: skip
    chunk, lo, hi = next_chunk(counter, indices.size)
    while chunk >= 0:
        if locate is not None:  # pruned when compiled for None: the indices are given
            chunk_ancestors(locate, lo, hi, indices)
        # loops over views of the chunk, not over lo:hi of the whole arrays: about 2x faster
        # (reports/decisions.md, "Resampling and correction passes")
        chunk_indices = indices[lo:hi]
        for k in range(len(sources)):
            _gather(sources[k], targets[k][lo:hi], chunk_indices)
        _gather(state_source, state_target[lo:hi], chunk_indices)
        if equal:
            log_target[lo:hi] = log_fill
        else:
            _gather(log_source, log_target[lo:hi], chunk_indices)
        chunk, lo, hi = next_chunk(counter, indices.size)


@njit(cache=True, inline="always")
def _gather(source, target, indices):
    """``target[i] = source[indices[i]]`` for every ``i`` of ``target`` (views of a chunk)."""
    for i in range(target.size):
        target[i] = source[indices[i]]


@njit(cache=True, nogil=True, parallel=True)
def _gather_parallel(
    threads, locate, indices, x, y, heading, cos_heading, sin_heading, speed, turn_rate,
    time_since_draw, x_to, y_to, heading_to, cos_heading_to, sin_heading_to, speed_to,
    turn_rate_to, time_since_draw_to, log_source, log_target, equal, log_fill, state_source,
    counter, state_target,
):  # fmt: skip
    for _ in numba.prange(threads):
        _gather_kernel(
            locate, indices, x, y, heading, cos_heading, sin_heading, speed, turn_rate,
            time_since_draw, x_to, y_to, heading_to, cos_heading_to, sin_heading_to,
            speed_to, turn_rate_to, time_since_draw_to, log_source, log_target, equal,
            log_fill, state_source, counter, state_target,
        )  # fmt: skip


def sqrt_largest_eigenvalue(var_x, var_y, cov_xy) -> np.ndarray | float:
    """√λ₁ of 2×2 covariances, the paper's closed form (its convergence measure).

    Parameters
    ----------
    var_x, var_y, cov_xy : array_like, shape (n,), or float
        Entries of the x-y covariance (m²).

    Returns
    -------
    numpy.ndarray, shape (n,), or float for float inputs
        ``sqrt((var_x + var_y)/2 + sqrt(((var_x − var_y)/2)² + cov_xy²))`` (m).
    """
    if not (isinstance(var_x, float) and isinstance(var_y, float) and isinstance(cov_xy, float)):
        var_x, var_y, cov_xy = (np.asarray(a, dtype=float) for a in (var_x, var_y, cov_xy))
    # written with operators only, so that plain floats (the filter's estimate every second)
    # take no NumPy call: about 0.3 against 3 us
    half_sum = 0.5 * (var_x + var_y)
    half_diff = 0.5 * (var_x - var_y)
    return (half_sum + (half_diff * half_diff + cov_xy * cov_xy) ** 0.5) ** 0.5


@njit(cache=True)
def split_in_two(x, y, w, min_variance, n_bins):
    """Split a weighted particle cloud in two along its principal axis (weighted 1-D 2-means).

    The positions are projected on the axis of the cloud's largest variance and the
    projection is binned in ``n_bins`` bins (so the split costs time linear in N); 2-means
    starts from the weighted quartiles and moves the cut to the midpoint of the two means
    until it stays in its bin. The cut of the projection ``u`` is ``threshold``: a particle
    belongs to the upper cluster when ``u >= threshold``.

    Parameters
    ----------
    x, y : numpy.ndarray, shape (N,)
        Positions (m).
    w : numpy.ndarray, shape (N,)
        Non-negative weights; a cloud whose weights sum to zero (e.g. a sample of a
        component whose weight sits on other particles) is not split.
    min_variance : float
        m²: a cloud whose largest variance is below it is not split.
    n_bins : int
        Bins of the projection (the cut lies on a bin edge).

    Returns
    -------
    separation : float
        Distance between the two clusters' weighted means along the axis (m); 0 when the
        cloud is not split (too narrow, or one side empty).
    minor : float
        Weight share of the lighter cluster.
    sd_lo, sd_hi : float
        Standard deviations of the lower and upper clusters along the axis (m).
    mean_x, mean_y, axis_x, axis_y : float
        Weighted mean (m) and unit principal axis; ``u = (x - mean_x) axis_x + (y - mean_y)
        axis_y``.
    threshold : float
        Cut of ``u`` (m); ``inf`` when not split.
    """
    total = mx = my = 0.0
    for i in range(x.size):
        total += w[i]
        mx += w[i] * x[i]
        my += w[i] * y[i]
    if not total > 0.0:  # no weight to judge a split by
        return 0.0, 0.0, 0.0, 0.0, math.nan, math.nan, 1.0, 0.0, math.inf
    mx, my = mx / total, my / total
    sxx = sxy = syy = 0.0
    for i in range(x.size):
        dx, dy = x[i] - mx, y[i] - my
        sxx += w[i] * dx * dx
        sxy += w[i] * dx * dy
        syy += w[i] * dy * dy
    sxx, sxy, syy = sxx / total, sxy / total, syy / total
    half = 0.5 * (sxx - syy)
    largest = 0.5 * (sxx + syy) + math.sqrt(half * half + sxy * sxy)
    if largest < min_variance:
        return 0.0, 0.0, 0.0, 0.0, mx, my, 1.0, 0.0, math.inf
    ax, ay = (
        (sxy, largest - sxx)
        if abs(sxy) > 1e-12 * largest
        else ((1.0, 0.0) if sxx >= syy else (0.0, 1.0))
    )
    norm = math.hypot(ax, ay)
    ax, ay = ax / norm, ay / norm
    u = np.empty(x.size)
    low, high = math.inf, -math.inf
    for i in range(x.size):
        u[i] = (x[i] - mx) * ax + (y[i] - my) * ay
        low = min(low, u[i])
        high = max(high, u[i])
    width = (high - low) / n_bins
    bin_w = np.zeros(n_bins)
    bin_wu = np.zeros(n_bins)
    bin_wu2 = np.zeros(n_bins)
    for i in range(u.size):
        k = min(int((u[i] - low) / width), n_bins - 1)
        bin_w[k] += w[i]
        bin_wu[k] += w[i] * u[i]
        bin_wu2[k] += w[i] * u[i] * u[i]
    cw, cwu, cwu2 = np.cumsum(bin_w), np.cumsum(bin_wu), np.cumsum(bin_wu2)
    total_u, total_u2 = cwu[-1], cwu2[-1]
    # start from the weighted quartiles; each iteration splits at the midpoint of the means
    lo = low + width * (np.searchsorted(cw, 0.25 * total) + 0.5)
    hi = low + width * (np.searchsorted(cw, 0.75 * total) + 0.5)
    k = -1
    w_lo = w_hi = 0.0
    for _ in range(50):
        k_new = min(max(int((0.5 * (lo + hi) - low) / width), 0), n_bins - 1)
        if k_new == k:
            break
        k = k_new
        w_lo, w_hi = cw[k], total - cw[k]
        if w_lo <= 0 or w_hi <= 0:
            return 0.0, 0.0, 0.0, 0.0, mx, my, ax, ay, math.inf
        lo, hi = cwu[k] / w_lo, (total_u - cwu[k]) / w_hi
    sd_lo = math.sqrt(max(cwu2[k] / w_lo - lo * lo, 0.0))
    sd_hi = math.sqrt(max((total_u2 - cwu2[k]) / w_hi - hi * hi, 0.0))
    minor = min(w_lo, w_hi) / total
    return hi - lo, minor, sd_lo, sd_hi, mx, my, ax, ay, low + width * (k + 1)
