"""Arc lengths of cubic splines by 20-node Gauss-Legendre quadrature, loops and open
lines alike (exact to machine precision for the roads' smooth segments).

The weighted sums go through :func:`~sdc_gym.geometry.fixed_order.dot_rows`, one order of
operations on every processor (a BLAS ``@`` rounds per processor).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.fixed_order import dot_rows

FloatArray = NDArray[np.float64]

# Nodes and weights on [0, 1] (numpy computes them from Legendre's companion matrix).
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(20)
GL_NODES: FloatArray = 0.5 * (_NODES + 1.0)
GL_WEIGHTS: FloatArray = 0.5 * _WEIGHTS


def quadrature(speeds: FloatArray) -> FloatArray:
    """``speeds (..., 20) @ GL_WEIGHTS``: the integral over [0, 1] per row."""
    return dot_rows(speeds, GL_WEIGHTS)


def partial_lengths(spline: Any, starts: FloatArray, widths: FloatArray) -> FloatArray:
    """Arc length of ``spline`` from each ``starts`` over ``widths`` of its parameter."""
    nodes = starts[:, None] + widths[:, None] * GL_NODES[None, :]
    return widths * quadrature(np.hypot(*np.moveaxis(spline(nodes, 1), -1, 0)))


def segment_lengths(spline: Any, knots: FloatArray) -> FloatArray:
    """Exact arc length of each spline segment between consecutive knots."""
    return partial_lengths(spline, knots[:-1], np.diff(knots))


def points_at_arc_lengths(spline: Any, knots: FloatArray, lengths: FloatArray,
                          cumulative: FloatArray, targets: FloatArray,
                          iterations: int) -> FloatArray:
    """The points of ``spline`` at arc lengths ``targets`` from its first knot: s(u)
    inverted segment by segment with ``iterations`` Newton steps from the linear guess
    (``lengths`` of the segments, ``cumulative`` their running sum from 0)."""
    index = np.clip(np.searchsorted(cumulative, targets, side="right") - 1, 0,
                    len(lengths) - 1)
    u = knots[index] + (targets - cumulative[index]) * (np.diff(knots)[index] / lengths[index])
    for _ in range(iterations):
        lo = knots[index]
        partial = partial_lengths(spline, lo, u - lo)
        speed = np.hypot(*spline(u, 1).T)
        u = u - (cumulative[index] + partial - targets) / speed
    return spline(u)
