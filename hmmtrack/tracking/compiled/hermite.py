"""Cubic Hermite interpolation in tables of values and slopes, for compiled kernels.

A tabulated function of one variable is stored as rows of ``(value, step * slope)`` pairs
at equally spaced nodes; between nodes ``k`` and ``k + 1``, at fraction ``t`` of the step,
the interpolant is ``f_k h00 + f_{k+1} h01 + d_k h10 + d_{k+1} h11`` with the cubic Hermite
basis ``h``. Used by the tabulated multipath mixture of
:mod:`hmmtrack.tracking.measurement.arrival_time` and the
softplus table of :mod:`hmmtrack.tracking.measurement.detection`. Not for: building the tables
(their owners do, with closed-form slopes) or choosing the grid.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def hermite_basis(t):
    """Cubic Hermite basis at ``t`` in [0, 1]: ``(h01, h10, h11)`` (``h00 = 1 - h01``)."""
    t2 = t * t
    h01 = t2 * (3.0 - 2.0 * t)
    h10 = t * (1.0 - t) * (1.0 - t)
    h11 = t2 * (t - 1.0)
    return h01, h10, h11


@njit(cache=True, inline="always")
def hermite_value(table, k, column, h01, h10, h11):
    """Interpolant between nodes ``k`` and ``k + 1`` of ``table`` (rows: nodes), whose
    column ``column`` holds the values and column ``column + 1`` the slopes times the step,
    with the basis of :func:`hermite_basis`."""
    value = table[k, column] + h01 * (table[k + 1, column] - table[k, column])
    value += h10 * table[k, column + 1] + h11 * table[k + 1, column + 1]
    return value
