"""Newton projections on a reference line's spline, as one compiled kernel.

:func:`newton_points` is :meth:`~sdc_gym.geometry.reference_line.ReferenceLine.project`'s
iteration for many points at once, each point iterating on its own until its step is
below the tolerance: the per-point arithmetic on floats the projection is defined by (a
complex times a real as the two products, ``Re(z conj(w))`` as ``z.x w.x + z.y w.y``; the
closing ``d`` over the C library's ``hypot`` of the velocity, as numpy's ``hypot``), so
the same bits as evaluating it over arrays. The spline's rows (``coef``) are the line's
``_coef_xy``; ``line`` holds its knot step, inverse knot step, segment count, total
parameter and parameter scale.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sdc_gym.geometry.exact_math import py_mod

NEWTON_ITERATIONS = 6  # at most; 2-3 from a guess within a metre
MAX_NEWTON_STEP_M = 50.0
NEWTON_TOLERANCE_M = 1e-6
# A local (warm-started) projection that lands further than this from the point, or moves
# s by more than this, is redone globally: the point is not where the guess said.
LOCAL_SEARCH_TRUST_M = 25.0


@njit(cache=True)
def newton_points(coef: np.ndarray, line: np.ndarray, length: float, x: np.ndarray,
                  y: np.ndarray, s_guess: np.ndarray, s_out: np.ndarray, d_out: np.ndarray,
                  moved_out: np.ndarray) -> int:
    """Project the points ``(x, y)`` (flat arrays) from their guessed s: s, d and how far
    s moved from the guess (m). Returns how many points the projection lost (moved or
    landed more than :data:`LOCAL_SEARCH_TRUST_M` away)."""
    lost = 0
    step_u, inverse, last = line[0], line[1], int(line[2]) - 1
    total, scale = line[3], line[4]
    for n in range(x.shape[0]):
        px, py = x[n], y[n]
        u0 = py_mod(s_guess[n], length) * scale
        u = u0
        for _ in range(NEWTON_ITERATIONS):
            i = min(int(u * inverse), last)
            row = coef[i]
            t = u - i * step_u
            offset_x = ((row[0] * t + row[2]) * t + row[4]) * t + row[6] - px
            offset_y = ((row[1] * t + row[3]) * t + row[5]) * t + row[7] - py
            velocity_x = (row[8] * t + row[10]) * t + row[4]
            velocity_y = (row[9] * t + row[11]) * t + row[5]
            f = offset_x * velocity_x + offset_y * velocity_y
            fp = (velocity_x * velocity_x + velocity_y * velocity_y) + (
                offset_x * (row[12] * t + row[10]) + offset_y * (row[13] * t + row[11]))
            step = f / fp
            step = min(step, MAX_NEWTON_STEP_M)
            step = max(step, -MAX_NEWTON_STEP_M)
            u = py_mod(u - step, total)
            if -NEWTON_TOLERANCE_M < step < NEWTON_TOLERANCE_M:
                break
        i = min(int(u * inverse), last)
        row = coef[i]
        t = u - i * step_u
        velocity_x = (row[8] * t + row[10]) * t + row[4]
        velocity_y = (row[9] * t + row[11]) * t + row[5]
        point_x = ((row[0] * t + row[2]) * t + row[4]) * t + row[6]
        point_y = ((row[1] * t + row[3]) * t + row[5]) * t + row[7]
        d_out[n] = ((px - point_x) * velocity_y - (py - point_y) * velocity_x) / math.hypot(
            velocity_x, velocity_y)
        moved_out[n] = (py_mod(u - u0 + 0.5 * total, total) - 0.5 * total) / scale
        s_out[n] = u / scale
        lost += abs(moved_out[n]) > LOCAL_SEARCH_TRUST_M or abs(d_out[n]) > LOCAL_SEARCH_TRUST_M
    return lost
