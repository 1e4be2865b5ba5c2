"""A loop read from a file must be a sane road: closed, simple, of sane radius and length.

Two steps, because the second needs the smooth line the first protects:

* :func:`check_loop_points` on the file's (x, y) points, before anything is built from
  them: coordinates inside the observation bounds, a loop length between ``min_length``
  and :data:`MAX_LOOP_LENGTH_M` (the smooth line is resampled every 2 m: a 1e12 m map
  would need terabytes), *closed* (the last point near the first: a file runs once around
  the loop, and the loop closes from its last point back to its first), and not
  collinear (points on one line enclose no area; the closed spline through them folds
  back on itself);
* :func:`check_reference_line` on the smooth line: *simple* (it never crosses itself:
  no figure eight, no loop that runs over its own road) and its smallest radius of
  curvature at least ``min_radius`` (a 1 m bend is no road for a car).

Each failure raises ``error`` (the loader's format error, a ``ValueError``) naming the
file, the figure found and the valid range.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from sdc_gym.geometry.reference_line import ReferenceLine

MAX_LOOP_LENGTH_M: Final = 100_000.0
"""The longest loop (100 km; the original's are 7 km): bounded by memory and set-up time."""
MAX_COORDINATE_M: Final = 900_000.0
"""|x| and |y| of map points: observations bound positions at 1e6 m."""
MAX_CLOSING_FRACTION: Final = 0.10
"""The gap from the last point to the first may be this fraction of the loop length (the
original files: 0.45 % highway, 0.19 % track) ..."""
MAX_CLOSING_STEPS: Final = 10.0
"""... or this many times the file's longest step between points (a sparse loop, e.g. a
square of 4 points, closes with one ordinary step; the original track: 5 x)."""
MIN_WIDTH_RATIO: Final = 1e-3
"""The points' RMS distance from their best-fit line, over the loop length, below which
they are collinear (a circle: 0.11; the original loops: 0.05 to 0.1)."""
CURVATURE_SAMPLE_M: Final = 0.5  # spacing of the curvature and crossing checks


def _polyline_length(xy: NDArray[np.float64]) -> tuple[float, float, float]:
    """Length of the closed polyline through ``xy``, its closing chord (last -> first) and
    its longest other step."""
    steps = np.hypot(*np.diff(xy, axis=0).T)
    closing = float(np.hypot(*(xy[0] - xy[-1])))
    return float(steps.sum()) + closing, closing, float(steps.max())


def ends_meet(xy: NDArray[np.float64]) -> bool:
    """The geometric rule that tells a loop from an open road: the ends of the points meet
    when the gap from the last point to the first is at most :data:`MAX_CLOSING_FRACTION`
    of the closed polyline's length, or at most :data:`MAX_CLOSING_STEPS` times its longest
    other step *and* at most half the open polyline's length (a sparse loop, a square of 4
    points, closes with one ordinary step; a short straight of a few long steps does not
    come back). The original loops: 0.45 % and 0.19 %; the Bosch Challenge's open roads:
    their ends lie 4.8 km apart, 49 % of the closed polyline and 75 x its longest step."""
    if len(xy) < 2:
        return True
    length, closing, longest = _polyline_length(xy)
    open_length = length - closing
    return bool(closing <= MAX_CLOSING_FRACTION * length
                or (closing <= MAX_CLOSING_STEPS * longest and closing <= 0.5 * open_length))


def check_loop_points(xy: NDArray[np.float64], where: str, error: type[Exception], *,
                      min_length: float, max_length: float = MAX_LOOP_LENGTH_M) -> None:
    """The checks on the raw points (see the module docstring); fewer than 4 points are
    left to :class:`~sdc_gym.geometry.reference_line.ReferenceLine`'s own error."""
    if len(xy) < 4:
        return
    extent = float(np.abs(xy).max())
    if extent > MAX_COORDINATE_M:
        raise error(f"{where}: a coordinate of {extent:.4g} m; map points must lie within "
                    f"+-{MAX_COORDINATE_M:g} m (the observations' bounds)")
    length, closing, longest = _polyline_length(xy)
    if length > max_length:
        raise error(f"{where}: the loop is {length:.6g} m long; it must be in "
                    f"[{min_length:g}, {max_length:g}] m")
    if np.hypot(*np.diff(xy, axis=0).T).min() < 1e-6:
        return  # repeated points: the reference line's own error names them
    if length < min_length:
        raise error(f"{where}: the loop is {length:.6g} m long; it must be in "
                    f"[{min_length:g}, {max_length:g}] m")
    if not ends_meet(xy):
        raise error(f"{where}: not a closed loop: the last point is {closing:.1f} m from the "
                    f"first, {100 * closing / length:.0f} % of the loop's {length:.0f} m and "
                    f"{closing / longest:.0f} x its longest step (at most "
                    f"{100 * MAX_CLOSING_FRACTION:g} %, or {MAX_CLOSING_STEPS:g} x and half "
                    "the open length): a file "
                    "runs once around a loop and ends near its start (an open road's ends "
                    "do not meet: say road: open)")
    width = _rms_distance_from_best_line(xy)
    if width < MIN_WIDTH_RATIO * length:
        raise error(f"{where}: the points are (nearly) collinear: {width:.3g} m RMS from one "
                    f"line for a loop of {length:.0f} m (at least {MIN_WIDTH_RATIO:g} x its "
                    "length), so the loop folds back on itself")


def _rms_distance_from_best_line(xy: NDArray[np.float64]) -> float:
    """RMS distance (m) of the points from their best-fitting straight line: the smaller
    singular value of the centred points over sqrt(n), from the 2 x 2 scatter matrix in
    closed form (LAPACK's SVD rounds differently per processor)."""
    centred = xy - xy.mean(axis=0)
    sxx = float((centred[:, 0] * centred[:, 0]).sum())
    syy = float((centred[:, 1] * centred[:, 1]).sum())
    sxy = float((centred[:, 0] * centred[:, 1]).sum())
    smallest = 0.5 * (sxx + syy) - math.hypot(0.5 * (sxx - syy), sxy)
    return math.sqrt(max(smallest, 0.0) / len(xy))


def _crossing(points: NDArray[np.float64], closed: bool = True) -> tuple[int, int] | None:
    """Two non-adjacent segments of the polyline ``points`` (closed: with the segment from
    the last point back to the first) that cross, if any."""
    count = len(points)
    ends = np.roll(points, -1, axis=0)
    if not closed:  # no closing segment: the pairs with it are dropped below
        ends[-1] = points[-1]
    middle = 0.5 * (points + ends)
    reach = float(np.hypot(*(ends - points).T).max())
    pairs = cKDTree(middle).query_pairs(reach, output_type="ndarray")
    if not len(pairs):
        return None
    i, j = pairs[:, 0], pairs[:, 1]
    apart = (np.minimum(np.abs(i - j), count - np.abs(i - j)) > 1 if closed
             else (np.abs(i - j) > 1) & (i < count - 1) & (j < count - 1))
    i, j = i[apart], j[apart]
    a, b, c, d = points[i], ends[i], points[j], ends[j]

    def side(p: NDArray[np.float64], q: NDArray[np.float64],
             r: NDArray[np.float64]) -> NDArray[np.float64]:
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (
            r[:, 0] - p[:, 0])

    # Each side's sign, 0 within rounding: a crossing exactly at a sample (the first
    # waypoint of a figure eight) has a side of +-1e-10 whose random sign hid it; touching
    # counts as crossing, exactly collinear segments (a straight) do not.
    tolerance = 1e-9 * reach * reach
    signs = [np.where(np.abs(value) <= tolerance, 0.0, np.sign(value)) for value in (
        side(a, b, c), side(a, b, d), side(c, d, a), side(c, d, b))]
    collinear = (signs[0] == 0) & (signs[1] == 0) & (signs[2] == 0) & (signs[3] == 0)
    crosses = (signs[0] * signs[1] <= 0) & (signs[2] * signs[3] <= 0) & ~collinear
    if not crosses.any():
        return None
    first = int(np.flatnonzero(crosses)[0])
    return int(i[first]), int(j[first])


def check_reference_line(reference: ReferenceLine, where: str, error: type[Exception], *,
                         min_radius: float) -> None:
    """The checks on the smooth line (see the module docstring); an open line's from its
    start to its end (:attr:`~ReferenceLine.end_s`)."""
    closed = reference.closed
    count = max(int(reference.end_s / CURVATURE_SAMPLE_M), 16)
    s = np.linspace(0.0, reference.end_s, count + (0 if closed else 1), endpoint=not closed)
    curvature = np.abs(reference.curvature(s))
    sharpest = int(np.argmax(curvature))
    if curvature[sharpest] * min_radius > 1.0:
        x, y = reference.position(s[sharpest])
        raise error(f"{where}: the road bends with a radius of {1.0 / curvature[sharpest]:.3g} m"
                    f" at s = {s[sharpest]:.1f} m (x {x:.1f}, y {y:.1f}); the smallest radius "
                    f"allowed is {min_radius:g} m")
    crossing = _crossing(reference.position(s), closed)
    if crossing is not None:
        first, second = (float(s[index]) for index in crossing)
        x, y = reference.position(first)
        shape = "a loop must be simple, not a figure eight" if closed else (
            "an open road must not run over itself")
        raise error(f"{where}: the road crosses itself (at s = {first:.1f} m and s = "
                    f"{second:.1f} m, near x {x:.1f}, y {y:.1f}): {shape}")


def check_open_points(xy: NDArray[np.float64], where: str, error: type[Exception], *,
                      min_length: float, max_length: float = MAX_LOOP_LENGTH_M) -> None:
    """The checks on an open road's raw points: at least 3 of them, coordinates inside
    the observation bounds, a length (first point to last along the polyline) in
    ``[min_length, max_length]``, and ends that do not meet (that is a loop)."""
    if len(xy) < 3:
        raise error(f"{where}: an open road needs at least 3 waypoints, got {len(xy)}")
    extent = float(np.abs(xy).max())
    if extent > MAX_COORDINATE_M:
        raise error(f"{where}: a coordinate of {extent:.4g} m; map points must lie within "
                    f"+-{MAX_COORDINATE_M:g} m (the observations' bounds)")
    length = float(np.hypot(*np.diff(xy, axis=0).T).sum())
    if not min_length <= length <= max_length:
        raise error(f"{where}: the open road is {length:.6g} m long; it must be in "
                    f"[{min_length:g}, {max_length:g}] m")
    if ends_meet(xy):
        _, closing, _ = _polyline_length(xy)
        raise error(f"{where}: a loop given as an open road: its last point is {closing:.1f} m "
                    f"from its first, so its ends meet (the rule: a gap over "
                    f"{100 * MAX_CLOSING_FRACTION:g} % of the closed polyline and over "
                    f"{MAX_CLOSING_STEPS:g} x its longest step is open); say road: loop "
                    "or auto")
