"""A closed, smooth reference line parameterised by exact arc length.

Every road in sdc-gym (highway loop, track loop) hangs off one of these: lanes are
offsets along its right-hand normal, traffic lives in its Frenet frame (s, d), and the ego
car is projected onto it every physics step.

Construction
------------
1. A periodic cubic spline ``r(u) = (x(u), y(u))`` through the waypoints (scipy
   ``CubicSpline(bc_type="periodic")``), ``u`` the cumulative chord length.
2. Its exact arc length per segment by Gauss-Legendre quadrature (20 nodes: exact to
   machine precision for these smooth segments).
3. The curve is resampled every ``resample_step`` metres *by arc length* (Newton on the
   quadrature), and a second periodic spline is fitted through the resampled points with
   the arc length itself as parameter. The knots sit at exact arc length and between
   them the parameter's speed is 1 within a few parts per million, so ``s`` below *is*
   distance along the line (to micrometres), and evaluating a point is one cubic.

Conventions (those of the Udacity simulators)
----------------------------------------------
``s`` grows in the driving direction and wraps at :attr:`length`; ``d`` grows to the
*right* of travel (on a counter-clockwise loop: outwards). ``heading`` is the direction of
travel in radians, counter-clockwise from +x. ``curvature`` is signed: positive when the
line turns left (counter-clockwise).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from sdc_gym.geometry.arc_length import points_at_arc_lengths, segment_lengths
from sdc_gym.geometry.exact_math import atan2, complex_abs, fused_product_sum, power
from sdc_gym.geometry.open_line import build_open_line
from sdc_gym.geometry.projection_kernel import LOCAL_SEARCH_TRUST_M as _LOCAL_SEARCH_TRUST_M
from sdc_gym.geometry.projection_kernel import MAX_NEWTON_STEP_M as _MAX_NEWTON_STEP_M
from sdc_gym.geometry.projection_kernel import NEWTON_ITERATIONS as _NEWTON_ITERATIONS
from sdc_gym.geometry.projection_kernel import NEWTON_TOLERANCE_M as _NEWTON_TOLERANCE_M
from sdc_gym.geometry.projection_kernel import LineGeometry, project_points

FloatArray = NDArray[np.float64]

# Batches up to this many points are projected in plain Python (see ReferenceLine._newton).
_SCALAR_BATCH_LIMIT = 12


class ReferenceLineError(ValueError):
    """The waypoints cannot make a closed reference line (too few, not finite, repeated)."""


def _cross(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> FloatArray:
    """``(conj(a) * b).imag``, the z of the cross product a x b, as numpy rounds it on
    x86-64-v3 processors (:func:`~sdc_gym.geometry.exact_math.fused_product_sum`), on any."""
    return fused_product_sum(a.real, b.imag, -a.imag, b.real)


def _dot(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> FloatArray:
    """``(a * conj(b)).real``, the dot product of a and b, rounded the same way."""
    return fused_product_sum(a.real, b.real, a.imag, b.imag)


class ReferenceLine:
    """Closed smooth curve with Frenet conversions; see the module docstring.

    Args:
        waypoints: (n, 2) points in driving order, the loop closing from the last back to
            the first (do not repeat the first point at the end).
        resample_step: spacing in metres of the arc-length resampling.
        closed: ``False`` builds an *open* line from the first point to the last
            (:mod:`sdc_gym.geometry.open_line`: s from the first point, no wrap within the
            road, :attr:`end_s` its end, :attr:`length` then the period of s).
    """

    def __init__(self, waypoints: ArrayLike, resample_step: float = 2.0, *,
                 closed: bool = True) -> None:
        points = np.asarray(waypoints, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2:
            raise ReferenceLineError(
                f"waypoints must be an (n, 2) array of x, y; got shape {points.shape}"
            )
        if len(points) < (4 if closed else 3):
            kind = "a closed reference line needs at least 4" if closed else (
                "an open reference line needs at least 3")
            raise ReferenceLineError(f"{kind} waypoints; got {len(points)}")
        if not np.all(np.isfinite(points)):
            bad = int(np.flatnonzero(~np.all(np.isfinite(points), axis=1))[0])
            raise ReferenceLineError(f"waypoint {bad} is not finite: {points[bad].tolist()}")
        if not closed:
            steps = np.hypot(*np.diff(points, axis=0).T)
            if np.any(steps < 1e-6):
                bad = int(np.flatnonzero(steps < 1e-6)[0])
                raise ReferenceLineError(f"waypoints {bad} and {bad + 1} coincide; "
                                         "consecutive waypoints must be distinct")
            build_open_line(self, points, resample_step, _NEWTON_ITERATIONS)
            return
        self.closed: bool = True
        if np.allclose(points[0], points[-1]):
            points = points[:-1]  # tolerate a repeated closing point
        closed = np.vstack([points, points[:1]])
        chord = np.hypot(*np.diff(closed, axis=0).T)
        if np.any(chord < 1e-6):
            bad = int(np.flatnonzero(chord < 1e-6)[0])
            raise ReferenceLineError(
                f"waypoints {bad} and {(bad + 1) % len(points)} coincide; "
                "consecutive waypoints must be distinct"
            )
        self.waypoints: FloatArray = points
        self.polyline_length: float = float(chord.sum())

        coarse_knots = np.concatenate([[0.0], np.cumsum(chord)])
        coarse = CubicSpline(coarse_knots, closed, bc_type="periodic")
        seg = segment_lengths(coarse, coarse_knots)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        coarse_length = float(cum[-1])

        # Resample at equal arc-length steps: invert s(u) segment by segment with Newton.
        count = max(int(np.ceil(coarse_length / resample_step)), 8)
        targets = np.linspace(0.0, coarse_length, count, endpoint=False)
        resampled = points_at_arc_lengths(coarse, coarse_knots, seg, cum, targets,
                                          _NEWTON_ITERATIONS + 2)

        knots = np.append(targets, coarse_length)
        spline = CubicSpline(knots, np.vstack([resampled, resampled[:1]]), bc_type="periodic")
        self.length: float = float(segment_lengths(spline, knots).sum())
        self.end_s: float = self.length  # a loop's s ends where it starts again
        # Knot spacing is exact arc length of the coarse curve; rescale the tiny residual.
        self._param_scale = coarse_length / self.length
        self._samples_s = targets / self._param_scale
        self._tree = cKDTree(resampled)
        # Knots are uniform, so a segment is found by one multiplication (no search), and a
        # point is a gather plus Horner on complex numbers x + iy: one array operation per
        # term for both coordinates. This is ~10x cheaper than CubicSpline.__call__, which
        # matters because traffic and the ego are placed every physics step.
        self._knot_step = coarse_length / count
        self._inverse_step = 1.0 / self._knot_step
        self._segments = count
        a, b, c, d = (spline.c[k, :, 0] + 1j * spline.c[k, :, 1] for k in range(4))
        # Columns: position a, b, c, d; first derivative 3a, 2b (and c); second 6a (and 2b).
        self._coef = np.ascontiguousarray(np.stack([a, b, c, d, 3 * a, 2 * b, 6 * a], axis=1))
        # The same rows as 14 floats, x and y of each coefficient in turn (a.x, a.y, b.x,
        # ...), for the evaluations in real arithmetic (_newton_arrays, line_frames).
        xy_rows = np.stack([self._coef.real, self._coef.imag], axis=-1).reshape(count, -1)
        self._coef_xy = np.ascontiguousarray(xy_rows)
        self._coef_rows: list[list[float]] = self._coef_xy.tolist()  # for line_frames_few
        self._total_param = coarse_length
        self._geometry = LineGeometry(self._coef_xy, float(self._knot_step),
                                      float(self._inverse_step), int(self._segments - 1),
                                      float(self._total_param), float(self._param_scale),
                                      float(self.length), True)

    # ------------------------------------------------------------------ evaluation
    def __deepcopy__(self, memo: dict[int, Any]) -> ReferenceLine:
        # Nothing of a line changes after it is built, so copies of an env share it (its
        # list rows for the scalar path made a deep copy of an env 4x slower).
        return self

    def _param(self, s: ArrayLike) -> FloatArray:
        return np.mod(np.asarray(s, dtype=np.float64), self.length) * self._param_scale

    def _local(self, u: FloatArray) -> tuple[NDArray[np.complex128], FloatArray]:
        """Coefficient rows (..., 7) of the segments holding parameters ``u``, and offsets."""
        index = np.minimum((u * self._inverse_step).astype(np.intp), self._segments - 1)
        return self._coef[index], u - index * self._knot_step

    @staticmethod
    def _point(c: NDArray[np.complex128], t: FloatArray) -> NDArray[np.complex128]:
        return ((c[..., 0] * t + c[..., 1]) * t + c[..., 2]) * t + c[..., 3]

    @staticmethod
    def _velocity(c: NDArray[np.complex128], t: FloatArray) -> NDArray[np.complex128]:
        return (c[..., 4] * t + c[..., 5]) * t + c[..., 2]

    @staticmethod
    def _pair(z: NDArray[np.complex128]) -> FloatArray:
        """Complex x + iy as a float array with a trailing (x, y) axis (no copy)."""
        return np.asarray(z)[..., None].view(np.float64)

    def position(self, s: ArrayLike) -> FloatArray:
        """Point(s) on the line at arc length ``s``: shape ``s.shape + (2,)``."""
        return self._pair(self._point(*self._local(self._param(s))))

    def tangent(self, s: ArrayLike) -> FloatArray:
        """Unit tangent(s) (direction of travel): shape ``s.shape + (2,)``."""
        velocity = self._velocity(*self._local(self._param(s)))
        return self._pair(velocity / complex_abs(velocity))

    def normal(self, s: ArrayLike) -> FloatArray:
        """Unit normal(s) pointing to the *right* of travel (the direction of +d)."""
        velocity = self._velocity(*self._local(self._param(s)))
        return self._pair(-1j * velocity / complex_abs(velocity))

    def heading(self, s: ArrayLike) -> FloatArray:
        """Direction of travel in radians, counter-clockwise from +x."""
        velocity = self._velocity(*self._local(self._param(s)))
        return atan2(velocity.imag, velocity.real)  # np.angle, without numpy's SIMD atan2

    def curvature(self, s: ArrayLike) -> FloatArray:
        """Signed curvature in 1/m (positive turning left); radius = 1 / |curvature|."""
        c, t = self._local(self._param(s))
        velocity = self._velocity(c, t)
        acceleration = c[..., 6] * t + c[..., 5]
        return _cross(velocity, acceleration) / power(complex_abs(velocity), 3.0)

    def frame(self, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Point and unit tangent at ``s`` in one pass (each with a trailing (x, y) axis)."""
        c, t = self._local(self._param(s))
        velocity = self._velocity(c, t)
        return self._pair(self._point(c, t)), self._pair(velocity / complex_abs(velocity))

    # ------------------------------------------------------------------ Frenet
    def to_xy(self, s: ArrayLike, d: ArrayLike) -> FloatArray:
        """Frenet (s, d) to map (x, y), exact on the spline: ``r(s) + d * normal(s)``."""
        c, t = self._local(self._param(s))
        velocity = self._velocity(c, t)
        # The right-hand normal is the unit tangent turned by -90 degrees: times -i.
        offset = np.asarray(d, dtype=np.float64) * -1j
        return self._pair(self._point(c, t) + offset * velocity / complex_abs(velocity))

    def to_xy_and_curvature(self, s: ArrayLike, d: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """:meth:`to_xy` and :meth:`curvature` from one evaluation (for planners)."""
        c, t = self._local(self._param(s))
        velocity = self._velocity(c, t)
        speed = complex_abs(velocity)
        offset = np.asarray(d, dtype=np.float64) * -1j
        curvature = _cross(velocity, c[..., 6] * t + c[..., 5]) / power(speed, 3.0)
        return self._pair(self._point(c, t) + offset * velocity / speed), curvature

    def wrap_s(self, s: ArrayLike) -> FloatArray:
        """Arc length folded into ``[0, length)``."""
        return np.mod(s, self.length)

    def s_difference(self, s_to: ArrayLike, s_from: ArrayLike) -> FloatArray:
        """Signed shortest distance along the loop from ``s_from`` to ``s_to``."""
        half = 0.5 * self.length
        return np.mod(np.asarray(s_to) - np.asarray(s_from) + half, self.length) - half

    def nearest_sample_s(self, xy: ArrayLike) -> FloatArray:
        """Global coarse search: s of the nearest resampled point (within the step)."""
        _, index = self._tree.query(np.asarray(xy, dtype=np.float64))
        return self._samples_s[index]

    def to_frenet(
        self, xy: ArrayLike, s_guess: ArrayLike | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Map (x, y) to Frenet (s, d): the foot of the perpendicular on the spline.

        Vectorized over leading dimensions of ``xy`` (shape ``(..., 2)``). With
        ``s_guess`` (same leading shape, e.g. last step's s of a moving car) the search
        starts there; points whose warm start does not converge nearby are redone with a
        global search (a k-d tree over the resampled points), so a bad guess costs time,
        never correctness.
        """
        points = np.asarray(xy, dtype=np.float64)
        if s_guess is None:
            s = self.nearest_sample_s(points)
            s, d, _ = self._newton(points, s)
            return s, d
        s0 = np.broadcast_to(np.asarray(s_guess, dtype=np.float64), points.shape[:-1])
        s, d, moved = self._newton(points, s0)
        lost = np.maximum(np.abs(moved), np.abs(d)) > _LOCAL_SEARCH_TRUST_M
        if lost.any():
            s = np.array(s, copy=True)
            d = np.array(d, copy=True)
            s_global, d_global, _ = self._newton(points[lost], self.nearest_sample_s(points[lost]))
            s[lost] = s_global
            d[lost] = d_global
        return s, d

    def _newton(
        self, points: FloatArray, s0: ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Newton on f(u) = Re((r(u) - p) conj(r'(u))) = 0; returns s, d, how far s moved.

        Small batches (the ego's few frames per step) run on Python complex numbers: below
        ~10 points numpy's fixed cost per call (~1 us, ~40 calls) outweighs its per-element
        speed. Both paths compute the same iteration and agree to rounding.
        """
        if points.size <= 2 * _SCALAR_BATCH_LIMIT:
            return self._newton_scalar(points, s0)
        p = points[..., 0] + 1j * points[..., 1]
        u0 = self._param(s0)
        u = u0
        total = self._total_param
        for _ in range(_NEWTON_ITERATIONS):
            c, t = self._local(u)
            offset = self._point(c, t) - p
            velocity = self._velocity(c, t)
            acceleration = c[..., 6] * t + c[..., 5]
            f = _dot(offset, velocity)
            fp = _dot(velocity, velocity) + _dot(offset, acceleration)
            step = np.maximum(np.minimum(f / fp, _MAX_NEWTON_STEP_M), -_MAX_NEWTON_STEP_M)
            u = np.mod(u - step, total) if self.closed else np.maximum(u - step, 0.0)
            # Quadratic convergence: after a step under 1e-6 m the error is ~1e-12 m.
            if np.abs(step).max() < _NEWTON_TOLERANCE_M:
                break
        c, t = self._local(u)
        velocity = self._velocity(c, t)
        # d is the offset's component along the right normal -i * tangent.
        d = _cross(p - self._point(c, t), velocity) / complex_abs(velocity)
        scale = self._param_scale
        moved = ((np.mod(u - u0 + 0.5 * total, total) - 0.5 * total) if self.closed
                 else u - u0) / scale
        return u / scale, d, moved

    def _newton_scalar(
        self, points: FloatArray, s0: ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`_newton` for a few points: :meth:`_newton_arrays` (each point's own
        iteration), from the guesses as s."""
        shape = points.shape[:-1]
        flat_u0 = np.broadcast_to(self._param(s0), shape).ravel().tolist()
        scale = self._param_scale
        flat = points.reshape(-1, 2)
        s, d, moved = self._newton_arrays(flat[:, 0], flat[:, 1],
                                          np.array([u0 / scale for u0 in flat_u0]))
        return s.reshape(shape), d.reshape(shape), moved.reshape(shape)

    def line_frames(self, s: ArrayLike) -> tuple[FloatArray, ...]:
        """Point, right unit normal and curvature of the line at arc lengths ``s`` (any
        shape): arrays ``(x, y, nx, ny, curvature)``, ``to_xy(s, d) == (x + d nx,
        y + d ny)``; agrees with the vectorized methods to rounding.

        The arithmetic is that of a per-point evaluation on Python floats (x and y apart,
        the speed as ``abs`` of a complex, the cube as ``pow``), so that planners that
        were written that way keep their numbers whatever the batch.
        """
        s = np.asarray(s, dtype=np.float64)
        u = np.remainder(s, self.length) * self._param_scale
        i = (u * self._inverse_step).astype(np.intp)
        np.minimum(i, self._segments - 1, out=i)
        c = self._coef_xy[i]  # (..., 14)
        t = u - i * self._knot_step
        ax, ay, bx, by, cx, cy, dx, dy, a3x, a3y, b2x, b2y, a6x, a6y = np.moveaxis(c, -1, 0)
        velocity_x = (a3x * t + b2x) * t + cx
        velocity_y = (a3y * t + b2y) * t + cy
        speed = np.hypot(velocity_x, velocity_y)
        # Im(conj(velocity) * acceleration): the cross product of r' and r''.
        curvature = (velocity_x * (a6y * t + b2y) - velocity_y * (a6x * t + b2x)) / power(
            speed, 3.0)
        return (((ax * t + bx) * t + cx) * t + dx, ((ay * t + by) * t + cy) * t + dy,
                velocity_y / speed, -velocity_x / speed, curvature)

    def line_frames_few(self, s_values: list[float]) -> list[tuple[float, float, float, float,
                                                                  float]]:
        """:meth:`line_frames` for a list of arc lengths, as tuples ``(x, y, nx, ny,
        curvature)`` of Python floats."""
        # The same operations as line_frames on Python floats, without building arrays
        # (a planner asks for a point or a few per step): ``%`` is numpy's remainder (both
        # are fmod and then the divisor's sign), ``int`` its truncation, ``abs`` of a
        # complex the C library's hypot (np.hypot), ``** 3.0`` the C library's pow.
        if not all(map(math.isfinite, s_values)):
            return list(zip(*(column.tolist() for column in self.line_frames(s_values)),
                            strict=True))
        rows, length, scale = self._coef_rows, self.length, self._param_scale
        inverse_step, knot_step, last = self._inverse_step, self._knot_step, self._segments - 1
        frames = []
        for s in s_values:
            u = (float(s) % length) * scale
            i = min(int(u * inverse_step), last)
            ax, ay, bx, by, cx, cy, dx, dy, a3x, a3y, b2x, b2y, a6x, a6y = rows[i]
            t = u - i * knot_step
            velocity_x = (a3x * t + b2x) * t + cx
            velocity_y = (a3y * t + b2y) * t + cy
            speed = abs(complex(velocity_x, velocity_y))
            curvature = (velocity_x * (a6y * t + b2y) - velocity_y * (a6x * t + b2x)) / (
                speed ** 3.0)
            frames.append((((ax * t + bx) * t + cx) * t + dx, ((ay * t + by) * t + cy) * t + dy,
                           velocity_y / speed, -velocity_x / speed, curvature))
        return frames

    def project(self, x: ArrayLike, y: ArrayLike, s_guess: ArrayLike
                ) -> tuple[FloatArray, FloatArray]:
        """:meth:`to_frenet` of points ``(x, y)`` (arrays of one shape) from their guessed
        s: each point's own Newton iteration (it stops when that point's step is below
        1e-6 m), redone from the global search for the points it left more than 25 m
        away (the car is not where the guess said)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        s, d, moved, lost = self._newton_arrays(x, y, np.asarray(s_guess, dtype=np.float64),
                                                count_lost=True)
        if lost:
            lost_points = (np.abs(moved) > _LOCAL_SEARCH_TRUST_M) | (
                np.abs(d) > _LOCAL_SEARCH_TRUST_M)
            xl, yl = x[lost_points], y[lost_points]
            s0 = self.nearest_sample_s(np.stack([xl, yl], axis=-1))
            s[lost_points], d[lost_points], _ = self._newton_arrays(xl, yl, s0)
        return s, d

    def project_few(self, points: list[list[float]],
                    s_guesses: list[float]) -> tuple[list[float], list[float]]:
        """:meth:`project` for points and guesses given and returned as Python lists."""
        xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        # project()'s first pass without its array checks (a caller projects a point or
        # a few per step); should it lose a point, project() redoes them all the same way.
        x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
        s0 = np.ascontiguousarray(s_guesses, dtype=np.float64)
        if s0.shape == x.shape:
            out = np.empty((3, x.size))
            if not project_points(*self._geometry, x, y, s0, *out):
                return out[0].tolist(), out[1].tolist()
        s, d = self.project(x, y, s_guesses)
        return s.tolist(), d.tolist()

    def geometry(self) -> LineGeometry:
        """The line as the projection kernels take it (see
        :mod:`~sdc_gym.geometry.projection_kernel`)."""
        return self._geometry

    def _newton_arrays(self, x: FloatArray, y: FloatArray, s0: FloatArray,
                       count_lost: bool = False) -> Any:
        """Newton projections of points from their guessed s: (s, d, how far s moved),
        and with ``count_lost`` how many the local search lost.

        Every point iterates until its own step is below the tolerance (at most
        ``_NEWTON_ITERATIONS``), on the coefficients as floats (``_coef_xy``), in one
        compiled pass (:func:`~sdc_gym.geometry.projection_kernel.project_points`).
        """
        shape = np.shape(x)
        if np.shape(y) == shape == np.shape(s0):
            flat = [np.ascontiguousarray(a, dtype=np.float64).reshape(-1) for a in (x, y, s0)]
        else:
            shape = np.broadcast_shapes(np.shape(x), np.shape(y), np.shape(s0))
            flat = [np.ascontiguousarray(np.broadcast_to(a, shape), dtype=np.float64).ravel()
                    for a in (x, y, s0)]
        out = np.empty((3, flat[0].size))
        lost = project_points(*self._geometry, *flat, *out)
        result = out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape)
        return (*result, lost) if count_lost else result
