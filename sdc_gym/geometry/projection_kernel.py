"""Newton projections onto a reference line's spline, compiled (numba) per point.

:func:`project_point` is the projection of one point: Newton on
``f(u) = (r(u) - p) . r'(u)`` from its guess until its own step is below
:data:`NEWTON_TOLERANCE_M` (at most :data:`NEWTON_ITERATIONS`), on the spline's
coefficients as floats, with the per-point arithmetic the projection is defined by (a
complex times a real as the two products, ``Re(z conj(w))`` as ``z.x w.x + z.y w.y``, the
closing ``d`` over the C library's ``hypot`` of the velocity, as numpy's ``hypot``), so
the same bits as evaluating it over arrays. It is the only implementation:
:meth:`ReferenceLine.project <sdc_gym.geometry.reference_line.ReferenceLine.project>`
runs :func:`project_points` over arrays of points (the highway's cars and frames), and
the track world's frame kernel calls :func:`project_point` for every env's car.

A line is handed to the kernels as a :class:`LineGeometry` tuple (built once by
:meth:`ReferenceLine.geometry`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.kernel_compiler import kernel

NEWTON_ITERATIONS = 6
"""Newton iterations at most (2-3 from a guess within a metre)."""
MAX_NEWTON_STEP_M = 50.0
"""The largest step one iteration may take."""
NEWTON_TOLERANCE_M = 1e-6
"""A point stops iterating after a step under this (its error is then ~1e-12 m)."""
LOCAL_SEARCH_TRUST_M = 25.0
"""A local (warm-started) projection that lands further than this from the point, or
moves s by more than this, is redone globally: the point is not where the guess said."""


class LineGeometry(NamedTuple):
    """What the kernels need of a reference line (see ``ReferenceLine.__init__``)."""

    coef_xy: NDArray[np.float64]  # (segments, 14): a.x, a.y, b.x, ..., 6a.x, 6a.y per segment
    knot_step: float  # parameter length of a segment
    inverse_step: float
    last_segment: int
    total_param: float  # parameter length of the loop
    param_scale: float  # parameter per metre of arc length
    length: float  # loop length, m (an open line's: the period of s, far past its end)
    closed: bool  # False: an open line, s from 0 (clamped there), no wrap


@kernel
def project_point(line: LineGeometry, x: float, y: float, s0: float
                  ) -> tuple[float, float, float]:
    """(s, d, how far s moved from ``s0``) of the point ``(x, y)``, Newton from ``s0``."""
    rows = line.coef_xy
    step_u, inverse, last = line.knot_step, line.inverse_step, line.last_segment
    total, scale = line.total_param, line.param_scale
    u0 = py_mod(s0, line.length) * scale
    if not line.closed and s0 < 0.0:
        u0 = 0.0  # an open line begins at s = 0
    u = u0
    for _ in range(NEWTON_ITERATIONS):
        i = min(int(u * inverse), last)
        c = rows[i]
        t = u - i * step_u
        offset_x = ((c[0] * t + c[2]) * t + c[4]) * t + c[6] - x
        offset_y = ((c[1] * t + c[3]) * t + c[5]) * t + c[7] - y
        velocity_x = (c[8] * t + c[10]) * t + c[4]
        velocity_y = (c[9] * t + c[11]) * t + c[5]
        f = offset_x * velocity_x + offset_y * velocity_y
        fp = (velocity_x * velocity_x + velocity_y * velocity_y) + (
            offset_x * (c[12] * t + c[10]) + offset_y * (c[13] * t + c[11]))
        step = f / fp
        if step > MAX_NEWTON_STEP_M:  # NaN passes through, as np.minimum lets it
            step = MAX_NEWTON_STEP_M
        if step < -MAX_NEWTON_STEP_M:
            step = -MAX_NEWTON_STEP_M
        # A loop wraps; an open line clamps at its start (past its end runs the straight
        # run-out, sdc_gym.geometry.open_line).
        u = py_mod(u - step, total) if line.closed else max(u - step, 0.0)
        if -NEWTON_TOLERANCE_M < step < NEWTON_TOLERANCE_M:
            break
    i = min(int(u * inverse), last)
    c = rows[i]
    t = u - i * step_u
    velocity_x = (c[8] * t + c[10]) * t + c[4]
    velocity_y = (c[9] * t + c[11]) * t + c[5]
    point_x = ((c[0] * t + c[2]) * t + c[4]) * t + c[6]
    point_y = ((c[1] * t + c[3]) * t + c[5]) * t + c[7]
    d = ((x - point_x) * velocity_y - (y - point_y) * velocity_x) / math.hypot(velocity_x,
                                                                             velocity_y)
    if line.closed:
        moved = (py_mod(u - u0 + 0.5 * total, total) - 0.5 * total) / scale
    else:
        moved = (u - u0) / scale
    return u / scale, d, moved


@kernel
def is_lost(d: float, moved: float) -> bool:
    """Whether a local projection is not to be trusted (see :data:`LOCAL_SEARCH_TRUST_M`;
    NaN is not lost, as numpy's comparisons say)."""
    return abs(moved) > LOCAL_SEARCH_TRUST_M or abs(d) > LOCAL_SEARCH_TRUST_M


@kernel
def project_points(coef_xy: NDArray[np.float64], knot_step: float, inverse_step: float,
                   last_segment: int, total_param: float, param_scale: float, length: float,
                   closed: bool, x: NDArray[np.float64], y: NDArray[np.float64],
                   s0: NDArray[np.float64], s: NDArray[np.float64], d: NDArray[np.float64],
                   moved: NDArray[np.float64]) -> int:
    """:func:`project_point` for flat arrays of points, into ``s``, ``d``, ``moved``;
    returns how many the local search lost (:func:`is_lost`). The line comes as the
    fields of its :class:`LineGeometry` (``project_points(*geometry, x, ...)``): arrays
    and numbers are what numba's dispatcher types fastest when Python calls a kernel (a
    tuple argument costs tens of microseconds per call)."""
    line = LineGeometry(coef_xy, knot_step, inverse_step, last_segment, total_param,
                        param_scale, length, closed)
    lost = 0
    for k in range(x.size):
        s[k], d[k], moved[k] = project_point(line, x[k], y[k], s0[k])
        lost += is_lost(d[k], moved[k])
    return lost
