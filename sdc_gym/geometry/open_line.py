"""Open reference lines: a road that runs one way from its first waypoint to its last.

A loop's reference line (:class:`~sdc_gym.geometry.reference_line.ReferenceLine`) is a
periodic spline whose s wraps at its length. An open road (the Udacity-Bosch Challenge's
highway: 5.1 km of gently curving road that does not come back) is the same object built
by :func:`build_open_line`, so that every layer (the projection kernel, traffic, the
motion layer, perception, metrics) takes "closed or open" from the line and keeps one
kernel each. The conventions:

* **s from the first waypoint, no wrap.** s = 0 at the first waypoint and
  :attr:`~ReferenceLine.end_s` at the last, the exact arc length of the smooth line.
* **A period far beyond the road.** The kernels fold s and differences of s modulo the
  line's :attr:`~ReferenceLine.length`; an open line's length is its *period*
  (:func:`open_period`: a power of two at least four times the road), so within the road
  and the traffic's range nothing ever comes around: a fold of a difference is the
  difference itself (to ~1e-12 m, the rounding of adding half a power of two).
* **End conditions.** The smooth line is a *natural* cubic spline (zero curvature at both
  ends; also the default of ``tk::spline``, the spline library of most participants'
  planners). Real maps end in a few uneven chords (the final Bosch map turns 7 degrees
  between its first two): a not-a-knot end would carry that kink's curvature on and tilt
  the start 11 degrees, where the natural end stays within a degree of the chords (on a
  constant 600 m bend it ends 0.6 degrees short of the arc's tangent). Beyond the last
  waypoint the line runs on as a straight run-out along the end tangent, one extra
  exactly linear segment row: position, heading and curvature (0) are continuous into
  it, so cars that drive off the end, or a path that looks past it, stay on a sane line
  instead of an extrapolated cubic. Nothing is ever placed behind s = 0
  (the ego starts ahead of it, traffic spawns within ``[0, end_s]``, everything drives
  forward); a projection there clamps to s = 0 (:mod:`~sdc_gym.geometry.projection_kernel`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from sdc_gym.geometry.arc_length import points_at_arc_lengths, segment_lengths

FloatArray = NDArray[np.float64]

PERIOD_FACTOR = 4.0
"""An open line's period is the smallest power of two at least this many times its
length: differences of s up to twice the road (the road plus any traffic range) fold to
themselves."""


def open_period(end_s: float) -> float:
    """The period of s on an open road of ``end_s`` metres (see :data:`PERIOD_FACTOR`)."""
    return float(2.0 ** math.ceil(math.log2(PERIOD_FACTOR * end_s)))


def build_open_line(line: Any, points: FloatArray, resample_step: float,
                    newton_iterations: int) -> None:
    """Fill ``line``'s attributes as an open line through ``points`` (validated ``(n, 2)``,
    n >= 3, consecutive points distinct), as ``ReferenceLine.__init__`` does for a loop:
    the same arc-length resampling, the same coefficient layout, plus the run-out row.
    ``line`` is the ``ReferenceLine`` being built (typed ``Any``: this module, its open
    half, does not import it even for typing, so no import circle)."""
    from sdc_gym.geometry.projection_kernel import LineGeometry

    chord = np.hypot(*np.diff(points, axis=0).T)
    line.waypoints = points
    line.polyline_length = float(chord.sum())
    line.closed = False
    coarse_knots = np.concatenate([[0.0], np.cumsum(chord)])
    coarse = CubicSpline(coarse_knots, points, bc_type="natural")
    seg = segment_lengths(coarse, coarse_knots)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    coarse_length = float(cum[-1])
    count = max(int(np.ceil(coarse_length / resample_step)), 8)
    targets = np.linspace(0.0, coarse_length, count + 1)  # both ends are knots
    resampled = points_at_arc_lengths(coarse, coarse_knots, seg, cum, targets,
                                      newton_iterations + 2)
    spline = CubicSpline(targets, resampled, bc_type="natural")
    end_s = float(segment_lengths(spline, targets).sum())
    line.end_s = end_s
    line.length = open_period(end_s)
    line._param_scale = coarse_length / end_s
    line._samples_s = targets / line._param_scale
    line._tree = cKDTree(resampled)
    line._knot_step = coarse_length / count
    line._inverse_step = 1.0 / line._knot_step
    a, b, c, d = (spline.c[k, :, 0] + 1j * spline.c[k, :, 1] for k in range(4))
    rows = np.stack([a, b, c, d, 3 * a, 2 * b, 6 * a], axis=1)
    # The run-out: from the last knot on, the end point plus t times the end velocity.
    end_point = complex(*spline(coarse_length))
    end_velocity = complex(*spline(coarse_length, 1))
    run_out = np.array([[0, 0, end_velocity, end_point, 0, 0, 0]], dtype=np.complex128)
    line._coef = np.ascontiguousarray(np.vstack([rows, run_out]))
    line._segments = count + 1
    xy_rows = np.stack([line._coef.real, line._coef.imag], axis=-1).reshape(count + 1, -1)
    line._coef_xy = np.ascontiguousarray(xy_rows)
    line._coef_rows = line._coef_xy.tolist()
    line._total_param = line.length * line._param_scale
    line._geometry = LineGeometry(line._coef_xy, float(line._knot_step),
                                  float(line._inverse_step), int(line._segments - 1),
                                  float(line._total_param), float(line._param_scale),
                                  float(line.length), False)
