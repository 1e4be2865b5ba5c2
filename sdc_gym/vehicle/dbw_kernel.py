"""The drive-by-wire car's physics as a numba kernel over a batch of cars.

The equations are those of :mod:`sdc_gym.vehicle.dbw_vehicle` (its module docstring
derives them): a longitudinal force balance advanced by explicit Euler with trapezoid
distance, static friction at rest, the exact kinematic-bicycle arc about the rear axle,
and first-order actuator lags. This module is their only implementation:
:class:`~sdc_gym.vehicle.dbw_vehicle.DBWVehicle` is the batch of one, and the track
world's frame kernel steps every env's car with the same function.

State. One row of :data:`STATE_SIZE` floats per car, the fields of
:class:`~sdc_gym.vehicle.dbw_vehicle.VehicleState` in their order (the column constants
below). Constants. :func:`~sdc_gym.vehicle.dbw_vehicle.vehicle_constants` derives, once
per car model, the numbers the step needs (total mass, brake force limit, creep, ...).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import py_max, py_min, py_remainder
from sdc_gym.kernel_compiler import kernel

# --- state columns: VehicleState's fields, in order ------------------------------------------
X, Y, YAW, SPEED, YAW_RATE, ACCELERATION, LATERAL_ACCELERATION = range(7)
THROTTLE, BRAKE_TORQUE, STEERING_WHEEL_ANGLE, ROAD_WHEEL_ANGLE, ODOMETER = range(7, 12)
STATE_SIZE = 12

# --- constants: one vector per car model -----------------------------------------------------
(MASS, INVERSE_RADIUS, MAX_BRAKE_FORCE, ROLLING, DRAG, LINEAR_DRAG, REST_SPEED, CREEP0,
 REST_PUSH, CREEP_SLOPE, CREEP_SPEED, FORCE_MAX, POWER_MAX, MAX_SWA, CURVATURE_PER_SWA,
 WHEEL_BASE) = range(16)
CONSTANTS_SIZE = 16

_TWO_PI = 2.0 * math.pi
# Below this half-turn per step (rad) sin(h)/h uses its series: no cancellation.
_SMALL_HALF_TURN = 1e-4


@kernel
def reset_vehicle(c: NDArray[np.float64], states: NDArray[np.float64], car: int, x: float,
                  y: float, yaw: float, speed: float, throttle: float, brake_torque: float,
                  steering_wheel_angle: float) -> None:
    """Place car ``car`` (rear axle at x, y, heading yaw, speed >= 0) with its lagged
    actuators at the given values (clamped to the hardware)."""
    max_swa = c[MAX_SWA]
    swa = py_min(py_max(steering_wheel_angle, -max_swa), max_swa)
    curvature = math.tan(swa * c[CURVATURE_PER_SWA]) / c[WHEEL_BASE]
    st = states[car]
    st[:] = 0.0
    st[X] = x
    st[Y] = y
    st[YAW] = py_remainder(yaw, _TWO_PI)
    st[SPEED] = speed
    st[YAW_RATE] = speed * curvature
    st[LATERAL_ACCELERATION] = speed * speed * curvature
    st[THROTTLE] = py_min(py_max(throttle, 0.0), 1.0)
    st[BRAKE_TORQUE] = py_max(brake_torque, 0.0)
    st[STEERING_WHEEL_ANGLE] = swa
    st[ROAD_WHEEL_ANGLE] = swa * c[CURVATURE_PER_SWA]


@kernel
def step_vehicle(c: NDArray[np.float64], gains: NDArray[np.float64],
                 states: NDArray[np.float64], car: int, throttle: float, brake_torque: float,
                 steering_wheel_angle: float, dt: float) -> None:
    """Advance car ``car`` by ``dt`` s under the commands (not NaN; clamped to what the
    hardware can do), in place."""
    st = states[car]
    gain_throttle, gain_brake, gain_steer = gains[0], gains[1], gains[2]

    # Actuators: clamp the command, then the first-order lag (gain 1: no lag).
    throttle = 0.0 if throttle < 0.0 else (1.0 if throttle > 1.0 else throttle)
    brake_torque = brake_torque if brake_torque > 0.0 else 0.0
    max_swa = c[MAX_SWA]
    swa = -max_swa if steering_wheel_angle < -max_swa else (
        max_swa if steering_wheel_angle > max_swa else steering_wheel_angle)
    if gain_throttle < 1.0:
        throttle = st[THROTTLE] + gain_throttle * (throttle - st[THROTTLE])
    if gain_brake < 1.0:
        brake_torque = st[BRAKE_TORQUE] + gain_brake * (brake_torque - st[BRAKE_TORQUE])
    if gain_steer < 1.0:
        swa = st[STEERING_WHEEL_ANGLE] + gain_steer * (swa - st[STEERING_WHEEL_ANGLE])

    # Longitudinal force balance.
    v0 = st[SPEED]
    engine = c[FORCE_MAX]
    if v0 * engine > c[POWER_MAX]:
        engine = c[POWER_MAX] / v0
    drive = throttle * engine
    if v0 < c[CREEP_SPEED]:
        drive += c[CREEP0] - c[CREEP_SLOPE] * v0
    brake = brake_torque * c[INVERSE_RADIUS]
    if brake > c[MAX_BRAKE_FORCE]:
        brake = c[MAX_BRAKE_FORCE]
    mass = c[MASS]
    if v0 <= 0.0:
        # At rest brake and rolling resistance are static friction: pull away only
        # when the drive force overcomes them (ties hold).
        net = throttle * engine + c[REST_PUSH] - brake
        if net > 0.0:
            v1 = net / mass * dt
            ds = 0.5 * v1 * dt
        else:
            v1 = 0.0
            ds = 0.0
    else:
        accel = (drive - brake - c[ROLLING] - c[LINEAR_DRAG] * v0
                 - c[DRAG] * v0 * v0) / mass
        v1 = v0 + accel * dt
        if v1 < 0.0:
            # Stopped inside the step: exact distance to rest, no reversing.
            ds = 0.5 * v0 * (v0 / -accel)
            v1 = 0.0
        else:
            ds = 0.5 * (v0 + v1) * dt
            if v1 < c[REST_SPEED] and drive <= 0.0:
                v1 = 0.0  # coasting this slowly, the car comes to rest

    # Lateral: kinematic bicycle about the rear axle, exact arc over the step.
    road_wheel = swa * c[CURVATURE_PER_SWA]
    curvature = math.tan(road_wheel) / c[WHEEL_BASE]
    half_turn = 0.5 * curvature * ds
    if -_SMALL_HALF_TURN < half_turn < _SMALL_HALF_TURN:
        chord = ds * (1.0 - half_turn * half_turn / 6.0)
    else:
        chord = ds * math.sin(half_turn) / half_turn
    yaw = st[YAW]
    mid_heading = yaw + half_turn
    st[X] += chord * math.cos(mid_heading)
    st[Y] += chord * math.sin(mid_heading)
    st[YAW] = py_remainder(yaw + 2.0 * half_turn, _TWO_PI)

    st[SPEED] = v1
    st[ACCELERATION] = (v1 - v0) / dt
    st[YAW_RATE] = v1 * curvature
    st[LATERAL_ACCELERATION] = v1 * v1 * curvature
    st[THROTTLE] = throttle
    st[BRAKE_TORQUE] = brake_torque
    st[STEERING_WHEEL_ANGLE] = swa
    st[ROAD_WHEEL_ANGLE] = road_wheel
    st[ODOMETER] += ds
