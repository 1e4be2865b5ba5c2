"""The drive-by-wire stack's control nodes as numba kernels: the twist controller (PID on
speed, low-pass filter, yaw controller, brake torque) and pure pursuit, one implementation
for single cars and batches.

The node classes (:class:`~sdc_gym.stack.track.controllers.TwistController`,
:class:`~sdc_gym.stack.track.follower.PurePursuit`) call these for one car, the batched
stack (:mod:`sdc_gym.stack.track.stack_batch`) for every env inside one compiled loop.
The arithmetic conventions (bit for bit the scalar code's) and the per-env state layout
are those of :mod:`sdc_gym.stack.track.node_kernels`, which holds the planning nodes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import (
    py_hypot,
    py_max,
    py_min,
    py_remainder,
)
from sdc_gym.kernel_compiler import kernel

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_TWO_PI = 2.0 * math.pi
LATERAL_LIMIT_MIN_SPEED_MPS = 0.1  # below this the original yaw controller skips its limit


# ============================================================================ controllers
@kernel
def pid_update(kp: float, ki: float, kd: float, low: float, high: float, integral: float,
               last_error: float, has_last: bool, error: float, dt: float
               ) -> tuple[float, float]:
    """One PID sample: (output, the integral kept). The integral is kept only while the
    output is not clamped; the first sample after a reset has no derivative term."""
    candidate = integral + error * dt
    derivative = 0.0 if not has_last else (error - last_error) / dt
    output = kp * error + ki * candidate + kd * derivative
    if output > high:
        output = high
    elif output < low:
        output = low
    else:
        integral = candidate
    return output, integral


@kernel
def low_pass(a: float, value: float, x: float) -> float:
    """``a x + (1 - a) y_prev``."""
    return a * x + (1.0 - a) * value


@kernel
def yaw_steering(wheel_base: float, steer_ratio: float, min_speed: float,
                 max_lat_accel: float, max_steer_angle: float, target_linear: float,
                 target_angular: float, current_speed: float) -> float:
    """rad, the yaw controller's steering-wheel angle (positive: left)."""
    if abs(target_linear) > 0.0:
        angular = current_speed * target_angular / target_linear
    else:
        angular = 0.0
    if abs(current_speed) > LATERAL_LIMIT_MIN_SPEED_MPS:
        max_yaw_rate = abs(max_lat_accel / current_speed)
        angular = py_min(py_max(angular, -max_yaw_rate), max_yaw_rate)
    if angular == 0.0:
        return 0.0
    road_wheel = math.atan(wheel_base * angular / py_max(current_speed, min_speed))
    steering = steer_ratio * road_wheel
    return py_min(py_max(steering, -max_steer_angle), max_steer_angle)


class TwistParameters(NamedTuple):
    """The twist controller's constants (see ``TwistController``)."""

    kp: float
    ki: float
    kd: float
    decel_limit: float
    accel_limit: float
    filter_gain: float
    wheel_base: float
    steer_ratio: float
    min_speed: float
    max_lat_accel: float
    max_steer_angle: float
    brake_torque_per_decel: float
    hold_torque: float
    brake_deadband: float
    stop_target: float
    standstill_speed: float
    watchdog: float
    sample_time: float
    steering_filter_gain: float  # 1: no steering low-pass (the seed's)


class TwistState(NamedTuple):
    """Per env: the PID, the filter, the last call's time, the hold and the output."""

    integral: FloatArray
    last_error: FloatArray
    has_last_error: BoolArray
    filtered: FloatArray
    last_time: FloatArray
    has_last_time: BoolArray
    acceleration_command: FloatArray
    holding: BoolArray
    stale: BoolArray
    command: FloatArray  # (envs, 3): throttle, brake torque N m, steering-wheel angle rad
    steering_filtered: FloatArray  # the steering low-pass's output (when on)


def twist_state(envs: int) -> TwistState:
    z, b = np.zeros, (lambda: np.zeros(envs, dtype=bool))
    return TwistState(z(envs), z(envs), b(), z(envs), z(envs), b(), z(envs), b(), b(),
                      z((envs, 3)), z(envs))


@kernel
def twist_reset(st: TwistState, env: int) -> None:
    """Forget the PID state and the filter (manual mode, a new episode)."""
    st.integral[env] = 0.0
    st.last_error[env] = 0.0
    st.has_last_error[env] = False
    st.filtered[env] = 0.0
    st.steering_filtered[env] = 0.0
    st.has_last_time[env] = False
    st.acceleration_command[env] = 0.0
    st.holding[env] = False
    st.stale[env] = False


@kernel
def longitudinal(p: TwistParameters, acceleration: float) -> tuple[float, float]:
    """(throttle, brake torque N m) for a filtered acceleration command (m/s^2)."""
    if acceleration > 0.0:
        return py_min(acceleration, 1.0), 0.0
    if acceleration < -p.brake_deadband:
        return 0.0, p.brake_torque_per_decel * -acceleration
    return 0.0, 0.0


@kernel
def twist_control(p: TwistParameters, st: TwistState, env: int, now: float,
                  target_linear: float, target_angular: float, twist_time: float,
                  current_speed: float, velocity_time: float, dbw_enabled: bool) -> None:
    """The twist controller at ``now``: its command into ``st.command[env]``."""
    command = st.command[env]
    if not dbw_enabled:
        twist_reset(st, env)
        command[0] = 0.0
        command[1] = 0.0
        command[2] = 0.0
        return
    stale = (now - twist_time > p.watchdog or now - velocity_time > p.watchdog)
    st.stale[env] = stale
    if stale:
        target_linear = 0.0
    dt = p.sample_time if not st.has_last_time[env] else now - st.last_time[env]
    if dt <= 0.0:
        dt = p.sample_time
    st.last_time[env] = now
    st.has_last_time[env] = True
    steering = yaw_steering(p.wheel_base, p.steer_ratio, p.min_speed, p.max_lat_accel,
                            p.max_steer_angle, target_linear, target_angular, current_speed)
    if p.steering_filter_gain < 1.0:  # off (gain 1) leaves the seed's arithmetic untouched
        steering = low_pass(p.steering_filter_gain, st.steering_filtered[env], steering)
        st.steering_filtered[env] = steering
    holding = target_linear < p.stop_target and current_speed < p.standstill_speed
    if st.holding[env] and not holding:
        # Pulling away from a hold: a fresh PID and filter (no integral from braking).
        st.integral[env] = 0.0
        st.has_last_error[env] = False
        st.filtered[env] = 0.0
    st.holding[env] = holding
    error = target_linear - current_speed
    output, st.integral[env] = pid_update(p.kp, p.ki, p.kd, p.decel_limit, p.accel_limit,
                                          st.integral[env], st.last_error[env],
                                          st.has_last_error[env], error, dt)
    st.last_error[env] = error
    st.has_last_error[env] = True
    filtered = low_pass(p.filter_gain, st.filtered[env], output)
    st.filtered[env] = filtered
    st.acceleration_command[env] = filtered
    throttle, brake = longitudinal(p, filtered)
    if holding:
        command[0] = 0.0
        command[1] = py_max(brake, p.hold_torque)
    else:
        command[0] = throttle
        command[1] = brake
    command[2] = steering


# ============================================================================ pure pursuit
class FollowerConstants(NamedTuple):
    """Pure pursuit settings (``FollowerParameters``)."""

    lookahead_min: float
    lookahead_gain: float
    displacement_threshold: float
    angle_threshold: float
    speed_from_next_waypoint: bool


class FollowerState(NamedTuple):
    """Per env: the kept angular velocity and the last call's look-ahead geometry."""

    angular: FloatArray
    target_x: FloatArray
    target_y: FloatArray
    lookahead: FloatArray
    curvature: FloatArray
    recomputed: BoolArray


def follower_state(envs: int) -> FollowerState:
    return FollowerState(np.zeros(envs), np.zeros(envs), np.zeros(envs), np.zeros(envs),
                         np.zeros(envs), np.zeros(envs, dtype=bool))


@kernel
def curvature_to_point(x: float, y: float, yaw: float, target_x: float,
                       target_y: float) -> float:
    """1/m, curvature of the arc from the pose (tangent to the heading) through the
    target: ``2 y_local / (x_local^2 + y_local^2)``."""
    dx = target_x - x
    dy = target_y - y
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    local_x = cos_yaw * dx + sin_yaw * dy
    local_y = -sin_yaw * dx + cos_yaw * dy
    squared = local_x * local_x + local_y * local_y
    if squared <= 0.0:
        return 0.0
    return 2.0 * local_y / squared


@kernel
def target_point(x: float, y: float, fx: FloatArray, fy: FloatArray,
                 lookahead: float) -> tuple[float, float]:
    """The polyline ``(fx, fy)``'s point at ``lookahead`` m from (x, y): the first point
    farther than that, moved back along its segment onto the circle."""
    limit = lookahead * lookahead
    count = fx.size
    i = -1
    for k in range(count):
        dx = fx[k] - x
        dy = fy[k] - y
        if dx * dx + dy * dy > limit:
            i = k
            break
    if i < 0:
        return fx[count - 1], fy[count - 1]
    if i == 0:
        return fx[0], fy[0]
    # Segment P0 -> P1 enters the circle's outside: |P0 + t (P1 - P0) - C| = L, t in
    # (0, 1]; P0 lies inside the circle, so the larger root is the crossing.
    p0x, p0y = fx[i - 1] - x, fy[i - 1] - y
    ux, uy = (fx[i] - x) - p0x, (fy[i] - y) - p0y
    a = ux * ux + uy * uy
    b = p0x * ux + p0y * uy
    c = p0x * p0x + p0y * p0y - limit
    t = (-b + math.sqrt(py_max(b * b - a * c, 0.0))) / a
    return x + p0x + t * ux, y + p0y + t * uy


@kernel
def is_following(fc: FollowerConstants, x: float, y: float, yaw: float, fx: FloatArray,
                 fy: FloatArray) -> bool:
    """The pose is on the path: near the line through the first two final waypoints and
    along its direction."""
    if fx.size < 2:
        return False
    ax, ay = fx[0], fy[0]
    ux, uy = fx[1] - ax, fy[1] - ay
    norm = py_hypot(ux, uy)
    if norm <= 0.0:
        return False
    displacement = abs(ux * (y - ay) - uy * (x - ax)) / norm
    angle = abs(py_remainder(math.atan2(uy, ux) - yaw, _TWO_PI))
    return displacement < fc.displacement_threshold and angle < fc.angle_threshold


@kernel
def command_speed(fc: FollowerConstants, x: float, y: float, yaw: float, fx: FloatArray,
                  fy: FloatArray, fspeed: FloatArray) -> float:
    """m/s, the first final waypoint's speed (or the first one ahead of the car's)."""
    if not fc.speed_from_next_waypoint:
        return fspeed[0]
    cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
    for k in range(fx.size):
        if (fx[k] - x) * cos_yaw + (fy[k] - y) * sin_yaw > 0.0:
            return fspeed[k]
    return fspeed[fx.size - 1]


@kernel
def follow(fc: FollowerConstants, st: FollowerState, env: int, x: float, y: float,
           yaw: float, speed: float, fx: FloatArray, fy: FloatArray, fspeed: FloatArray
           ) -> tuple[float, float]:
    """Pure pursuit along the final waypoints: the twist (linear m/s, angular rad/s)."""
    lookahead = py_max(fc.lookahead_min, fc.lookahead_gain * speed)
    st.lookahead[env] = lookahead
    tx, ty = target_point(x, y, fx, fy, lookahead)
    st.target_x[env] = tx
    st.target_y[env] = ty
    recomputed = not is_following(fc, x, y, yaw, fx, fy)
    st.recomputed[env] = recomputed
    if recomputed:
        curvature = curvature_to_point(x, y, yaw, tx, ty)
        st.curvature[env] = curvature
        st.angular[env] = speed * curvature
    return command_speed(fc, x, y, yaw, fx, fy, fspeed), st.angular[env]
