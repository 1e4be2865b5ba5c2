"""Waypoint follower: linear time-varying model predictive control (MPC) on OSQP.

The seed team's further work (seed 000): "replace the pure pursuit algorithm with a MPC".
:class:`MPCFollower` takes the place of :class:`~sdc_gym.stack.track.follower.PurePursuit`
in the stack (same input, the final waypoints, and the same output, a twist command), so
the waypoint updater and the twist controller are unchanged.

Model: the kinematic bicycle at the rear axle, written in its errors to the reference path
(the final-waypoint polyline): lateral offset ``e_y`` (m, positive: the car is left of the
path) and heading error ``e_psi`` (rad). With the path's curvature ``kappa_ref(s)`` and the
commanded curvature ``kappa`` (the input), at speed ``v``::

    d e_y / dt   = v sin(e_psi)              ~ v e_psi
    d e_psi / dt = v (kappa - kappa_ref(s))

linearised along the reference (``e_psi`` small) and discretised exactly for a constant
``v`` over a step ``dt``::

    e_y'   = e_y + v dt e_psi + (v dt)^2 / 2 (kappa - kappa_ref)
    e_psi' = e_psi + v dt (kappa - kappa_ref)

Time-varying: step ``k`` of the horizon has its own speed ``v_k`` (the waypoints' target
speeds at the predicted arc position, within ``+-accel_mps2 * t`` of the current speed: the
speed controller's pace) and its own ``kappa_ref_k`` (the path's mean curvature over the
step). The cost over ``N`` steps::

    sum_k  q_y e_y,k^2 + q_psi e_psi,k^2      (k = 1..N, the last times terminal_factor)
         + r (kappa_k - kappa_ref,k)^2 + r_d (kappa_k - kappa_k-1)^2   (k = 0..N-1)

with ``kappa_-1`` the previous command, subject to ``|kappa_k| <= min(kappa_max,
a_lat / v_k^2)``: the steering lock and the yaw controller's lateral-acceleration limit.
The states are eliminated (condensed QP in the ``N`` curvatures: dense, small), and OSQP
solves it; the first curvature is the command: angular velocity = linear * kappa, which the
yaw controller turns back into exactly that curvature's wheel angle.

Determinism: OSQP's adaptive rho is re-evaluated every ``adaptive_rho_interval``
iterations (25), not at a fraction of the measured setup time (its default, interval 0,
makes the iterations depend on the machine's speed); the solver is set up afresh at every
:meth:`MPCFollower.reset`, warm-started within an episode, and its linear algebra is its
own (QDLDL, no BLAS), so the same episode gives the same commands bit for bit. The QP's
matrices are built in a numba kernel with scalar loops (no BLAS products).

Units: m, rad, m/s, rad/s; the pose is the rear axle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import osqp
from numpy.typing import NDArray
from scipy import sparse

from sdc_gym.geometry.exact_math import py_max, py_min, py_remainder
from sdc_gym.kernel_compiler import TypedCall, kernel
from sdc_gym.stack.track.control_kernels import FollowerConstants, command_speed
from sdc_gym.stack.track.follower import TwistCommand
from sdc_gym.stack.track.waypoints import FinalWaypoints

FloatArray = NDArray[np.float64]
_TWO_PI = 2.0 * math.pi
ADAPTIVE_RHO_INTERVAL = 25  # iterations: fixed, so the iterations never depend on timing


@dataclass(frozen=True)
class MPCParameters:
    """The MPC follower's settings (see the module docstring for the cost).

    Attributes:
        horizon_steps, step_s: ``N`` steps of ``dt`` s (default 15 x 0.1 s = 1.5 s).
        lateral_weight: ``q_y``, per m^2 of lateral offset.
        heading_weight: ``q_psi``, per rad^2 of heading error.
        curvature_weight: ``r``, per (1/m)^2 of curvature off the path's.
        curvature_rate_weight: ``r_d``, per (1/m)^2 of change between steps.
        terminal_factor: the last step's state weights times this.
        max_curvature: 1/m, the steering lock's curvature (``tan(lock / ratio) / L``).
        max_lateral_accel_mps2: the bound ``v^2 |kappa|`` keeps within.
        accel_mps2: the pace (m/s^2) the predicted speed may move from the current one.
        min_speed_mps: floor of the linearisation speed (the model is degenerate at 0).
        speed_from_next_waypoint: the command speed as
            :attr:`~sdc_gym.stack.track.follower.FollowerParameters.speed_from_next_waypoint`.
        max_iter, eps_abs, eps_rel: OSQP's iteration cap and tolerances.
    """

    horizon_steps: int = 15
    step_s: float = 0.1
    lateral_weight: float = 1.0
    heading_weight: float = 1.0
    curvature_weight: float = 10.0
    curvature_rate_weight: float = 100.0
    terminal_factor: float = 5.0
    max_curvature: float = 0.2
    max_lateral_accel_mps2: float = 2.85
    accel_mps2: float = 1.0
    min_speed_mps: float = 1.0
    speed_from_next_waypoint: bool = False
    max_iter: int = 200
    eps_abs: float = 1e-6
    eps_rel: float = 1e-6

    def __post_init__(self) -> None:
        if not (isinstance(self.horizon_steps, int) and 2 <= self.horizon_steps <= 200):
            raise ValueError(f"MPCParameters: horizon_steps must be an int in [2, 200], "
                             f"got {self.horizon_steps!r}")
        if not isinstance(self.max_iter, int) or self.max_iter < 1:
            raise ValueError(f"MPCParameters: max_iter must be an int >= 1, "
                             f"got {self.max_iter!r}")
        for key in ("step_s", "lateral_weight", "max_curvature", "max_lateral_accel_mps2",
                    "min_speed_mps", "eps_abs", "eps_rel", "terminal_factor"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"MPCParameters: {key} must be a finite number > 0, "
                                 f"got {value!r}")
        for key in ("heading_weight", "curvature_weight", "curvature_rate_weight",
                    "accel_mps2"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"MPCParameters: {key} must be a finite number >= 0, "
                                 f"got {value!r}")
        if self.curvature_weight == 0.0 and self.curvature_rate_weight == 0.0:
            raise ValueError("MPCParameters: curvature_weight and curvature_rate_weight are "
                             "both 0: the QP has no input cost and may have no unique "
                             "solution; give one of them > 0")


def mpc_parameters_for(wheel_base: float, steer_ratio: float, max_steer_angle: float,
                       max_lateral_accel_mps2: float, **overrides: float | int | bool
                       ) -> MPCParameters:
    """The MPC's settings with the car's limits as the controllers are told them: the
    curvature at the steering-wheel lock and the lateral-acceleration limit."""
    max_curvature = math.tan(max_steer_angle / steer_ratio) / wheel_base
    return MPCParameters(max_curvature=max_curvature,
                         max_lateral_accel_mps2=max_lateral_accel_mps2, **overrides)


# ============================================================================ kernels
@kernel
def path_geometry(fx: FloatArray, fy: FloatArray, arc: FloatArray,
                  heading: FloatArray) -> None:
    """Arc length at every point of the polyline (``arc``, from its first point) and the
    unwrapped heading of every segment (``heading``, ``fx.size - 1``)."""
    arc[0] = 0.0
    previous = 0.0
    for i in range(fx.size - 1):
        dx = fx[i + 1] - fx[i]
        dy = fy[i + 1] - fy[i]
        arc[i + 1] = arc[i] + math.sqrt(dx * dx + dy * dy)
        h = math.atan2(dy, dx)
        if i > 0:
            h = previous + py_remainder(h - previous, _TWO_PI)
        heading[i] = h
        previous = h


@kernel
def heading_at(s: float, arc: FloatArray, heading: FloatArray, segments: int) -> float:
    """The path's heading at arc length ``s``: linear between segment midpoints, extended
    linearly before the first (the list starts just ahead of the car, whose projection
    lies before it: there the path keeps its first curvature) and constant after the
    last."""
    if s <= 0.5 * (arc[0] + arc[1]):
        if segments < 2:
            return heading[0]
        m0 = 0.5 * (arc[0] + arc[1])
        m1 = 0.5 * (arc[1] + arc[2])
        slope = (heading[1] - heading[0]) / (m1 - m0) if m1 > m0 else 0.0
        return heading[0] + slope * (s - m0)
    for i in range(segments - 1):
        m1 = 0.5 * (arc[i + 1] + arc[i + 2])
        if s <= m1:
            m0 = 0.5 * (arc[i] + arc[i + 1])
            t = (s - m0) / (m1 - m0) if m1 > m0 else 1.0
            return heading[i] + t * (heading[i + 1] - heading[i])
    return heading[segments - 1]


@kernel
def value_at(s: float, arc: FloatArray, values: FloatArray) -> float:
    """``values`` (one per point) at arc length ``s``, linear between points."""
    count = values.size
    if s <= arc[0]:
        return values[0]
    for i in range(count - 1):
        if s <= arc[i + 1]:
            span = arc[i + 1] - arc[i]
            t = (s - arc[i]) / span if span > 0.0 else 1.0
            return values[i] + t * (values[i + 1] - values[i])
    return values[count - 1]


@kernel
def project(x: float, y: float, fx: FloatArray, fy: FloatArray,
            arc: FloatArray) -> tuple[float, float]:
    """(arc length of the pose's projection onto the polyline, signed lateral offset, m,
    positive left of the path). The first segment extends backwards and the last forwards,
    so a car behind the list's first point is measured across the path, not to the point."""
    best = math.inf
    best_s = 0.0
    best_d = 0.0
    last = fx.size - 2
    for i in range(fx.size - 1):
        ux = fx[i + 1] - fx[i]
        uy = fy[i + 1] - fy[i]
        length2 = ux * ux + uy * uy
        if length2 <= 0.0:
            continue
        px = x - fx[i]
        py = y - fy[i]
        t = (px * ux + py * uy) / length2
        if t < 0.0 and i > 0:
            t = 0.0
        if t > 1.0 and i < last:
            t = 1.0
        dx = px - t * ux
        dy = py - t * uy
        distance2 = dx * dx + dy * dy
        if distance2 < best:
            best = distance2
            length = math.sqrt(length2)
            best_s = arc[i] + t * length
            best_d = (ux * py - uy * px) / length
    return best_s, best_d


@kernel
def build_qp(x: float, y: float, yaw: float, speed: float, fx: FloatArray, fy: FloatArray,
             fspeed: FloatArray, previous_kappa: float, horizon: int, dt: float, q_y: float,
             q_psi: float, r: float, r_d: float, terminal: float, max_curvature: float,
             max_lat_accel: float, accel: float, min_speed: float, arc: FloatArray,
             heading: FloatArray, kappa_ref: FloatArray, speeds: FloatArray,
             gain: FloatArray, p_data: FloatArray, q: FloatArray, lower: FloatArray,
             upper: FloatArray) -> tuple[float, float]:
    """The condensed QP ``min 1/2 u'Pu + q'u, lower <= u <= upper`` of the pose along the
    polyline: ``p_data`` (P's upper triangle, column by column), ``q``, the bounds, and the
    horizon's ``kappa_ref`` and ``speeds``. Returns the initial errors (e_y, e_psi).
    ``gain`` (2, horizon) is work space: the state's sensitivity to the inputs."""
    segments = fx.size - 1
    path_geometry(fx, fy, arc, heading)
    s, e_y = project(x, y, fx, fy, arc)
    if s < 0.0 and segments >= 2:
        # Behind the first point the path is the first segment's line extended, but the
        # road keeps curving: measure from the arc of the path's first curvature instead
        # (on a 50 m circle with points 1 m apart the line is 2 cm off it 1 m back).
        m0 = 0.5 * arc[1]
        m1 = 0.5 * (arc[1] + arc[2])
        k0 = (heading[1] - heading[0]) / (m1 - m0) if m1 > m0 else 0.0
        e_y -= k0 * (0.5 * s * s - m0 * s)
    e_psi = py_remainder(yaw - heading_at(s, arc, heading, segments), _TWO_PI)
    for i in range(p_data.size):
        p_data[i] = 0.0
    for k in range(horizon):
        gain[0, k] = 0.0
        gain[1, k] = 0.0
        q[k] = 0.0
    f_y = e_y
    f_psi = e_psi
    for k in range(horizon):
        t = k * dt
        planned = value_at(s, arc, fspeed)
        v = py_min(py_max(planned, speed - accel * t), speed + accel * t)
        speeds[k] = v
        v_lin = py_max(v, min_speed)
        ds = v_lin * dt
        half = 0.5 * py_max(ds, 0.5)  # the mean curvature over at least 0.5 m of path
        middle = s + 0.5 * ds
        kr = (heading_at(middle + half, arc, heading, segments)
              - heading_at(middle - half, arc, heading, segments)) / (2.0 * half)
        kappa_ref[k] = kr
        limit = py_min(max_curvature, max_lat_accel / (v_lin * v_lin))
        lower[k] = -limit
        upper[k] = limit
        # x_{k+1} = A x_k + B (u_k - kr): free response f and sensitivity G = d x / d u.
        b_y = 0.5 * ds * ds
        b_psi = ds
        f_y = f_y + ds * f_psi - b_y * kr
        f_psi = f_psi - b_psi * kr
        for j in range(k):
            gain[0, j] = gain[0, j] + ds * gain[1, j]
        gain[0, k] = b_y
        gain[1, k] = b_psi
        w_y = q_y * (terminal if k == horizon - 1 else 1.0)
        w_psi = q_psi * (terminal if k == horizon - 1 else 1.0)
        # P += G' Q G, q += G' Q f (columns above k are zero).
        for j in range(k + 1):
            base = j * (j + 1) // 2
            for i in range(j + 1):
                p_data[base + i] += 2.0 * (w_y * gain[0, i] * gain[0, j]
                                           + w_psi * gain[1, i] * gain[1, j])
            q[j] += 2.0 * (w_y * gain[0, j] * f_y + w_psi * gain[1, j] * f_psi)
        s = s + ds
    for k in range(horizon):
        diagonal = k * (k + 1) // 2 + k
        p_data[diagonal] += 2.0 * (r + r_d)
        q[k] -= 2.0 * r * kappa_ref[k]
        if k + 1 < horizon:
            p_data[diagonal] += 2.0 * r_d  # u_k also starts the next step's change
            p_data[(k + 1) * (k + 2) // 2 + k] -= 2.0 * r_d
    q[0] -= 2.0 * r_d * previous_kappa
    return e_y, e_psi


def _upper_triangle(size: int) -> sparse.csc_matrix:
    """A dense upper-triangular CSC pattern (ones) whose data order is ``build_qp``'s."""
    rows = [i for j in range(size) for i in range(j + 1)]
    indptr = np.concatenate([[0], np.cumsum(np.arange(1, size + 1))])
    return sparse.csc_matrix((np.ones(len(rows)), np.array(rows), indptr), shape=(size, size))


class MPCFollower:
    """The MPC waypoint follower; see the module docstring. Same interface as
    :class:`~sdc_gym.stack.track.follower.PurePursuit` (``reset``, ``follow``).

    Attributes after :meth:`follow`: ``curvature`` (the command, 1/m),
    ``cross_track_error`` (m) and ``heading_error`` (rad) to the final waypoints,
    ``reference_curvature`` and ``speeds`` (the horizon's), ``iterations`` and ``status``
    (OSQP's).
    """

    def __init__(self, params: MPCParameters | None = None) -> None:
        self.params = params or MPCParameters()
        n = self.params.horizon_steps
        self.constants = FollowerConstants(0.0, 0.0, 0.0, 0.0,
                                           bool(self.params.speed_from_next_waypoint))
        self._pattern = _upper_triangle(n)
        self.p_data = np.zeros(n * (n + 1) // 2)
        self.q = np.zeros(n)
        self.lower = np.zeros(n)
        self.upper = np.zeros(n)
        self.gain = np.zeros((2, n))
        self.kappa_ref = np.zeros(n)
        self.speeds = np.zeros(n)
        self._build = TypedCall(build_qp)
        self.reset()

    def reset(self) -> None:
        """A new episode: a fresh solver (no warm start or rho from before) and no command."""
        n = self.params.horizon_steps
        p = self.params
        self.solver = osqp.OSQP()
        self.solver.setup(
            P=self._pattern.copy(), q=np.zeros(n), A=sparse.identity(n, format="csc"),
            l=-np.ones(n), u=np.ones(n), verbose=False, warm_starting=True,
            polishing=False, adaptive_rho=True, adaptive_rho_interval=ADAPTIVE_RHO_INTERVAL,
            max_iter=p.max_iter, eps_abs=p.eps_abs, eps_rel=p.eps_rel,
            check_termination=ADAPTIVE_RHO_INTERVAL)
        self.curvature = 0.0
        self.cross_track_error = 0.0
        self.heading_error = 0.0
        self.iterations = 0
        self.status = ""
        self._arc = np.zeros(0)
        self._heading = np.zeros(0)

    def solve(self, x: float, y: float, yaw: float, speed_mps: float,
              final: FinalWaypoints) -> float:
        """1/m, the curvature to command now (the QP's first input), clipped to its bound
        (OSQP's iterate may exceed a bound by its tolerance)."""
        if len(final) < 2:
            raise ValueError(f"MPCFollower.follow: needs at least 2 final waypoints, got "
                             f"{len(final)}")
        p = self.params
        fx, fy = _floats(final.x), _floats(final.y)
        if self._arc.size != fx.size:
            self._arc = np.zeros(fx.size)
            self._heading = np.zeros(fx.size - 1)
        self.cross_track_error, self.heading_error = self._build(
            float(x), float(y), float(yaw), float(speed_mps), fx, fy, _floats(final.speed),
            float(self.curvature), p.horizon_steps, float(p.step_s), float(p.lateral_weight),
            float(p.heading_weight), float(p.curvature_weight),
            float(p.curvature_rate_weight), float(p.terminal_factor), float(p.max_curvature),
            float(p.max_lateral_accel_mps2), float(p.accel_mps2), float(p.min_speed_mps),
            self._arc, self._heading, self.kappa_ref, self.speeds, self.gain, self.p_data,
            self.q, self.lower, self.upper)
        self.solver.update(Px=self.p_data, q=self.q, l=self.lower, u=self.upper)
        result = self.solver.solve(raise_error=False)  # the status is checked below
        self.iterations = int(result.info.iter)
        self.status = str(result.info.status)
        if result.x is None or not np.isfinite(result.x[0]):
            raise RuntimeError(f"MPCFollower: OSQP returned no solution (status "
                               f"{self.status!r})")
        self.curvature = py_min(py_max(float(result.x[0]), self.lower[0]), self.upper[0])
        return self.curvature

    def follow(self, x: float, y: float, yaw: float, speed_mps: float,
               final: FinalWaypoints) -> TwistCommand:
        """The twist command for the pose and speed along ``final``: the command speed as
        pure pursuit's, the angular velocity ``linear * kappa`` (the yaw controller then
        steers the curvature ``kappa``)."""
        kappa = self.solve(x, y, yaw, speed_mps, final)
        linear = command_speed(self.constants, float(x), float(y), float(yaw),
                               _floats(final.x), _floats(final.y), _floats(final.speed))
        return TwistCommand(linear_mps=float(linear), angular_radps=float(linear) * kappa)


def _floats(values: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.ascontiguousarray(values, dtype=np.float64)
