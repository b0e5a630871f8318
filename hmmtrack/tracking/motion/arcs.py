"""Constant-turn-rate arcs: the geometry the velocity and HMM motion models move along.

A particle at heading ``theta`` with speed ``v`` (m/s) and turn rate ``omega`` (rad/s)
moves for ``dt`` seconds along the arc of the paper's eqs. mm_xc..mm_theta, written here in
a form that tends to the straight line ``v dt (cos theta, sin theta)`` as ``omega -> 0``
without cancellation. :func:`arc_displacement` and :func:`move_along_arc` are the NumPy
reference; :func:`arc_pass` and :func:`finish_headings` are their compiled twins, inlined
into the motion kernels, which take each step as a branch-free (vectorised) pass with a
polynomial arc and call a scalar pass only when some turns are wider than :data:`WIDE_TURN`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hmmtrack.tracking.particles import Particles

__all__ = ["WIDE_TURN", "arc_displacement", "arc_pass", "finish_headings", "move_along_arc"]

#: below this |omega dt| the NumPy arc uses its Taylor series (first omitted term ~2e-16)
_SERIES_BELOW = 1e-2


def arc_displacement(
    cos_heading: np.ndarray, sin_heading: np.ndarray, arc_length: np.ndarray, turn_angle: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Displacement along a constant-turn-rate arc (NumPy reference).

    With ``phi = omega dt`` and arc length ``s = v dt``, the paper's eqs. mm_xc..mm_y give
    ``dx = (v/omega)(sin(theta + phi) - sin theta)`` and
    ``dy = -(v/omega)(cos(theta + phi) - cos theta)``, rewritten as
    ``dx = s (cos theta sinc(phi) - sin theta cosc(phi))`` and
    ``dy = s (sin theta sinc(phi) + cos theta cosc(phi))`` with
    ``sinc(phi) = sin(phi)/phi`` and ``cosc(phi) = (1 - cos phi)/phi``; both use their
    Taylor series for ``|phi| < 1e-2`` (error about 1e-16 relative), so ``phi = 0`` gives
    the straight line exactly.

    Parameters
    ----------
    cos_heading, sin_heading : (N,) float
        Heading at the start of the step.
    arc_length : (N,) float
        Distance travelled along the arc, ``v dt``, metres.
    turn_angle : (N,) float
        Heading change ``omega dt``, radians.

    Returns
    -------
    dx, dy : (N,) float, metres
    """
    phi = np.asarray(turn_angle, dtype=np.float64)
    phi2 = phi * phi
    small = np.abs(phi) < _SERIES_BELOW
    safe = np.where(small, 1.0, phi)
    sinc = np.where(small, 1.0 - phi2 / 6.0 * (1.0 - phi2 / 20.0), np.sin(safe) / safe)
    cosc = np.where(
        small, phi / 2.0 * (1.0 - phi2 / 12.0 * (1.0 - phi2 / 30.0)), (1.0 - np.cos(safe)) / safe
    )
    dx = arc_length * (cos_heading * sinc - sin_heading * cosc)
    dy = arc_length * (sin_heading * sinc + cos_heading * cosc)
    return dx, dy


def move_along_arc(p: Particles, dt: float) -> None:
    """Move ``p`` in place for ``dt`` s along arcs of its speed and turn rate (NumPy)."""
    phi = p.turn_rate * dt
    dx, dy = arc_displacement(p.cos_heading, p.sin_heading, p.speed * dt, phi)
    p.x += dx
    p.y += dy
    cos_phi, sin_phi = np.cos(phi), np.sin(phi)
    c = p.cos_heading * cos_phi - p.sin_heading * sin_phi
    s = p.sin_heading * cos_phi + p.cos_heading * sin_phi
    p.cos_heading, p.sin_heading = c, s
    p.heading = np.arctan2(s, c)


# Taylor coefficients (-1)^k / (2k + 1)! of sinc(a) = sin(a) / a and (-1)^k / (2k + 2)! of
# (1 - cos a) / a^2, in powers of a^2 (multiplications, not divisions)
_SINC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(7))
_COSC_SERIES = tuple((-1.0) ** k / math.factorial(2 * k + 2) for k in range(7))
#: half-angle doublings of the compiled arc: the series runs at ``phi / 2**4``
_DOUBLINGS = 4
#: the compiled arc's polynomial path covers ``|omega dt|`` up to this (rad); wider turns
#: (rare: more than 229 degrees in one step) use the library's sine and cosine
WIDE_TURN = 4.0


@njit(cache=True, inline="always")
def _series(c, a2):
    """``c[0] + c[1] a2 + ... + c[6] a2^6`` (Horner)."""
    return c[0] + a2 * (c[1] + a2 * (c[2] + a2 * (c[3] + a2 * (c[4] + a2 * (c[5] + a2 * c[6])))))


@njit(cache=True, inline="always")
def _arc_coefficients(phi):
    """``sinc(phi) = sin(phi)/phi`` and ``cosc(phi) = (1 - cos phi)/phi`` for
    ``|phi| <= WIDE_TURN``, branch-free (so that loops of it vectorise).

    The Taylor series at ``a = phi / 16`` (``|a| <= 0.25``: first omitted term below 1e-20
    relative), then four doublings ``sinc(2a) = sinc(a) (1 - a cosc(a))`` and
    ``cosc(2a) = a sinc(a)^2`` (from ``sin 2a = 2 sin a cos a`` and
    ``1 - cos 2a = 2 sin^2 a``): no cancellation anywhere, about 1e-15 absolute error, and
    ``phi = 0`` gives ``(1, 0)`` exactly (the straight line).
    """
    a = phi * (0.5**_DOUBLINGS)
    a2 = a * a
    sinc = _series(_SINC_SERIES, a2)
    cosc = a * _series(_COSC_SERIES, a2)
    for _ in range(_DOUBLINGS):
        sinc, cosc = sinc * (1.0 - a * cosc), a * sinc * sinc
        a = 2.0 * a
    return sinc, cosc


@njit(cache=True, inline="always")
def arc_pass(x, y, c, s, heading, v, turn, dt):
    """Move particles in place for ``dt`` s along the arcs of speed ``v`` (m/s) and turn rate
    ``turn`` (rad/s), all arrays (n,) (the NumPy path's equations, :func:`arc_displacement`).

    A branch-free (vectorised) pass for turns up to :data:`WIDE_TURN` that also counts the
    wider ones, then, only when there are any, :func:`_wide_turns` for those. ``(cos, sin)``
    of the heading are rotated by ``phi``; ``heading`` gains ``phi`` (wrapped later,
    :func:`finish_headings`).
    """
    n_wide = 0
    for i in range(x.size):
        phi = turn[i] * dt
        length = v[i] * dt
        narrow = abs(phi) <= WIDE_TURN
        n_wide += not narrow
        phi = phi if narrow else 0.0  # wide turns: no move here, see below
        length = length if narrow else 0.0
        sinc, cosc = _arc_coefficients(phi)
        ci = c[i]
        si = s[i]
        x[i] += length * (ci * sinc - si * cosc)
        y[i] += length * (si * sinc + ci * cosc)
        sin_phi = phi * sinc
        cos_phi = 1.0 - phi * cosc
        c[i] = ci * cos_phi - si * sin_phi
        s[i] = si * cos_phi + ci * sin_phi
        heading[i] += phi
    if n_wide > 0:
        _wide_turns(x, y, c, s, heading, v, turn, dt)


# not inlined: a call LLVM cannot if-convert, so the arc pass never computes sine and cosine
# for every particle (a vectorising LLVM, e.g. with SVML, would do so for an inlined loop)
@njit(cache=True, nogil=True)
def _wide_turns(x, y, c, s, heading, v, turn, dt):
    """:func:`arc_pass` for the particles whose ``|turn dt|`` exceeds :data:`WIDE_TURN`
    (more than 229 degrees in one step), with the library's sine and cosine."""
    for i in range(x.size):
        phi = turn[i] * dt
        if abs(phi) > WIDE_TURN:
            length = v[i] * dt
            sin_phi = math.sin(phi)
            cos_phi = math.cos(phi)
            sinc = sin_phi / phi
            cosc = (1.0 - cos_phi) / phi
            ci = c[i]
            si = s[i]
            x[i] += length * (ci * sinc - si * cosc)
            y[i] += length * (si * sinc + ci * cosc)
            c[i] = ci * cos_phi - si * sin_phi
            s[i] = si * cos_phi + ci * sin_phi
            heading[i] += phi


@njit(cache=True, inline="always")
def finish_headings(heading, c, s):
    """Wrap the headings (n,) into ``(-pi, pi]`` and pull ``(cos, sin)``
    back onto the unit circle (one Newton step of ``1/sqrt``: rotations drift it by ~1e-16
    per step), without the cost of ``atan2``.

    A heading is wrapped by subtracting ``2 pi`` while it is above ``pi``, then adding it
    while it is at or below ``-pi``. A branch-free (vectorised) pass takes the first of those
    subtractions or additions, which is all that a heading within one turn of the interval
    needs, and counts the headings still outside; only when there are any does
    :func:`_wrap_headings` go on with them, so every heading takes the same operations.
    """
    n_outside = 0
    for i in range(heading.size):
        angle = heading[i]
        angle = angle - 2.0 * math.pi if angle > math.pi else angle
        angle = angle + 2.0 * math.pi if angle <= -math.pi else angle
        heading[i] = angle
        n_outside += (angle > math.pi) | (angle <= -math.pi)
        factor = 1.5 - 0.5 * (c[i] * c[i] + s[i] * s[i])
        c[i] *= factor
        s[i] *= factor
    if n_outside > 0:
        _wrap_headings(heading)


# not inlined, like _wide_turns: the loops stay out of the vectorised pass
@njit(cache=True, nogil=True)
def _wrap_headings(heading):
    """Wrap the headings (n,) into ``(-pi, pi]`` in place, ``2 pi`` at a time (headings more
    than a turn outside, after :func:`finish_headings`' pass)."""
    for i in range(heading.size):
        while heading[i] > math.pi:
            heading[i] -= 2.0 * math.pi
        while heading[i] <= -math.pi:
            heading[i] += 2.0 * math.pi
