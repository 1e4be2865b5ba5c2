"""The drive-by-wire car of the track loop: longitudinal force balance + kinematic bicycle.

The track simulator is driven at the drive-by-wire level of the original course: each
physics step (50 Hz, :data:`PHYSICS_DT`) gets a throttle in ``[0, 1]``, a brake *torque*
in N m and a *steering-wheel* angle in rad. This module turns those into motion. How the
original simulator's car does it, with sources, and why the presets have the values they
have: ``docs/track_vehicle.md``.

Conventions
-----------
* The car's position ``(x, y)`` is the **centre of the rear axle** (the point whose
  velocity points along the body in a kinematic bicycle, so the path it traces is the
  one the reference stack's pure pursuit and yaw controller reason about). Use
  :meth:`DBWVehicle.center_xy`, :meth:`DBWVehicle.front_axle_xy` or
  :meth:`DBWVehicle.point_ahead` for other points of the body.
* ``yaw`` is the heading in rad, counter-clockwise from +x, wrapped to ``[-pi, pi]``.
* ``speed`` is in m/s and never negative: the car has no reverse gear in this model.
* Steering: road-wheel angle ``delta = steering_wheel_angle / road_wheel_ratio``
  (:attr:`VehicleParameters.road_wheel_ratio`: the car's own ratio, which need not be the
  ``steer_ratio`` the controllers are told); positive turns left.

Longitudinal model (per step)
-----------------------------
::

    F_engine(v) = min(max_drive_force, max_drive_power / v)     full-throttle force, N
    F_creep(v)  = creep_force_at_rest * max(0, 1 - v / creep_speed)   idle creep, N
    F_brake     = min(brake_torque / wheel_radius, tire_friction * m * g)
    F_resist(v) = rolling_resistance * m * g + linear_drag * v + drag_coefficient * v**2
    a = (F_creep + throttle * F_engine - F_brake - F_resist(v)) / m,  m = total_mass

``max_drive_power`` may be infinite (a constant drive force, as the original's Unity car
has); ``linear_drag`` is a force proportional to speed (a Unity rigid body's drag and its
wheels' damping), ``drag_coefficient`` the aerodynamic ``0.5 rho Cd A``.

Speed is advanced by explicit Euler (its fixed point is exactly the root of the force
balance, so a terminal speed is exact) and distance by the trapezoid rule, which is exact
for the constant acceleration within a step. Brakes and rolling resistance can stop the
car but never reverse it: a step that would cross zero speed ends at rest, with the
distance of the exact stop inside the step. A car coasting (no drive force at all) whose
speed falls below ``rest_speed`` comes to rest at the end of that step: a physics engine
puts such a slow body to rest (PhysX's sticky tyres and sleeping), where a speed-
proportional drag alone would only approach zero.

At rest, brake and rolling resistance act as *static* friction: the car pulls away only
when the drive force exceeds ``F_brake + F_roll``. An automatic gearbox creeps at idle
(the real car of the course, Carla; the original simulator's car does not): the creep is
set by the brake torque that exactly holds the stopped car (``creep_hold_torque``, 0 = no
creep; a brake torque equal to it holds)::

    creep_force_at_rest = creep_hold_torque / wheel_radius + F_roll   (0 without creep)

The creep fades linearly to zero at ``creep_speed`` (a torque converter at idle pushes
less as the wheels speed up); on the flat the car creeps at a little under that speed.

Lateral model
-------------
Kinematic bicycle about the rear axle: curvature ``kappa = tan(delta) / wheel_base`` and
``yaw_rate = v * kappa``. With ``road_wheel_ratio == steer_ratio`` this is the exact inverse
of the reference stack's yaw controller (``steering = steer_ratio * atan(wheel_base *
yaw_rate / v)``), so a fixed wheel angle drives a circle of radius ``wheel_base /
tan(delta)``. Within a step the curvature is constant and the rear axle moves along the
exact arc (chord ``ds * sin(h) / h`` at heading ``yaw + h``, ``h = kappa * ds / 2``): no
integration drift. The steering-wheel angle is clamped to the car's lock
(:attr:`VehicleParameters.steering_wheel_lock`).

Actuators
---------
Each actuator may lag its command by a first-order response with time constant ``tau``
(discretised exactly: ``y += (1 - exp(-dt / tau)) * (u - y)``); ``tau = 0`` applies the
command directly. The simulator preset has no lag, like the original Unity simulator,
which applies wheel torques and wheel angles the frame they arrive; the site preset has
small lags typical of a production drive-by-wire car (throttle by wire and engine
response, hydraulic brake pressure build-up, electric power steering).

The interface is plain numbers in and a plain state out (:meth:`DBWVehicle.step`), so
any driver can sit in front of it: the env, the built-in human, or a bridge speaking the
original simulator's protocol (``docs/track_vehicle.md``).

Implementation: the step is the numba kernel :func:`sdc_gym.vehicle.dbw_kernel.step_vehicle`
(over a batch of cars: the track world steps every env's car with it);
:class:`DBWVehicle` is its batch of one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sdc_gym.vehicle.dbw_kernel import (
    CONSTANTS_SIZE,
    CREEP0,
    CREEP_SLOPE,
    CREEP_SPEED,
    CURVATURE_PER_SWA,
    DRAG,
    FORCE_MAX,
    INVERSE_RADIUS,
    LINEAR_DRAG,
    MASS,
    MAX_BRAKE_FORCE,
    MAX_SWA,
    POWER_MAX,
    REST_PUSH,
    REST_SPEED,
    ROLLING,
    STATE_SIZE,
    WHEEL_BASE,
    reset_vehicle,
    step_vehicle,
)

PHYSICS_DT = 0.02
"""Physics step of the track loop, s (50 Hz, the original drive-by-wire loop rate)."""

GRAVITY = 9.81
"""m/s^2."""

FUEL_KG_PER_GALLON = 2.858
"""Mass of a US gallon of gasoline, kg (the reference stack's GAS_DENSITY)."""


def _is_real(value: object) -> bool:
    """A real number (int or float; bools are not numbers here)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def vehicle_constants(params: VehicleParameters) -> NDArray[np.float64]:
    """The step's constants for a car model (a float64 vector, see the module)."""
    c = np.zeros(CONSTANTS_SIZE)
    c[MASS] = params.total_mass
    c[INVERSE_RADIUS] = 1.0 / params.wheel_radius
    c[MAX_BRAKE_FORCE] = params.max_brake_force
    c[ROLLING] = params.rolling_force
    c[DRAG] = params.drag_coefficient
    c[LINEAR_DRAG] = params.linear_drag
    c[REST_SPEED] = params.rest_speed
    creep0 = params.creep_force_at_rest
    c[CREEP0] = creep0
    # At rest the drive force must beat the brake plus this: the creep beyond rolling
    # resistance is creep_hold_torque / wheel_radius (computed like the brake force so
    # that a brake torque equal to the holding torque ties exactly); without creep the
    # rolling resistance alone holds.
    c[REST_PUSH] = (params.creep_hold_torque * c[INVERSE_RADIUS] if creep0
                    else -params.rolling_force)
    c[CREEP_SLOPE] = creep0 / params.creep_speed
    c[CREEP_SPEED] = params.creep_speed if creep0 else 0.0
    c[FORCE_MAX] = params.max_drive_force
    c[POWER_MAX] = params.max_drive_power
    c[MAX_SWA] = params.steering_wheel_lock
    c[CURVATURE_PER_SWA] = 1.0 / params.road_wheel_ratio
    c[WHEEL_BASE] = params.wheel_base
    return c


def _lag_gain(time_constant: float, dt: float) -> float:
    """Exact first-order-lag gain for one step: 1 means no lag."""
    if time_constant <= 0.0:
        return 1.0
    return -math.expm1(-dt / time_constant)


def lag_gains(params: VehicleParameters, dt: float) -> NDArray[np.float64]:
    """(throttle, brake, steering) lag gains for steps of ``dt`` s."""
    return np.array([_lag_gain(params.throttle_time_constant, dt),
                     _lag_gain(params.brake_time_constant, dt),
                     _lag_gain(params.steering_time_constant, dt)])

@dataclass(frozen=True)
class VehicleParameters:
    """Everything that defines one car; see the module docstring for the equations.

    The first block are the original course's parameters (``spec/track_sim.md``, what the
    controllers are told); the second block are the car's physics: for the sim car those
    of the original simulator's Unity car, for the site car plausible figures for the real
    one (see :data:`SIM_VEHICLE`, :data:`SITE_VEHICLE` and ``docs/track_vehicle.md`` for
    the values and why). Override a field with ``dataclasses.replace(SIM_VEHICLE,
    linear_drag=0.0)`` or :meth:`replace`.

    Attributes:
        name: preset name ("sim", "site" or anything for custom cars).
        vehicle_mass: kg, empty car.
        fuel_capacity: US gallons of fuel on board (a full tank is assumed).
        brake_deadband: m/s^2, the reference controller's deadband: a commanded
            deceleration smaller than this is left to drag and rolling resistance rather
            than the brakes (as the course's controllers compare it with the controller's
            output in m/s^2); not used by the physics.
        decel_limit: m/s^2 (negative), the controller's deceleration limit.
        accel_limit: m/s^2, the controller's acceleration limit.
        wheel_radius: m, turns brake torque into brake force.
        wheel_base: m, rear axle to front axle.
        steer_ratio: steering-wheel angle / road-wheel angle.
        max_lat_accel: m/s^2, the yaw controller's lateral acceleration limit.
        max_steer_angle: rad, largest steering-*wheel* angle either way.
        max_drive_force: N at the wheels at full throttle, at low speed (traction and
            first-gear limited).
        max_drive_power: W at the wheels at full throttle; above
            ``max_drive_power / max_drive_force`` m/s the force falls as ``P / v``
            (``math.inf``: no power limit, the force is constant).
        drag_coefficient: N/(m/s)^2, the lumped ``0.5 * rho_air * Cd * frontal_area``.
        rolling_resistance: dimensionless rolling resistance coefficient ``C_rr``.
        creep_hold_torque: N m, brake torque that exactly holds the car at rest with
            zero throttle; the idle creep is derived from it, and 0 means the car does
            not creep (it stays at rest with no pedal at all).
        creep_speed: m/s, speed at which the idle creep force has faded to zero.
        tire_friction: tyre-road friction coefficient; caps the brake force at
            ``tire_friction * total_mass * g`` (harder pedal just locks the wheels).
        throttle_time_constant: s, first-order lag of the throttle (0 = none).
        brake_time_constant: s, first-order lag of the brake torque (0 = none).
        steering_time_constant: s, first-order lag of the steering angle (0 = none).
        linear_drag: N/(m/s), resistance proportional to speed (a Unity rigid body's
            ``drag`` times its mass, plus its wheel colliders' damping).
        rest_speed: m/s, a car coasting with no drive force that falls below this speed
            comes to rest (0 = never: only brakes and rolling resistance stop it).
        response_steer_ratio: steering-wheel angle / road-wheel angle of the car itself
            (what the physics turns); ``None``: ``steer_ratio``. The controllers are told
            ``steer_ratio`` (the course's launch file), the car answers with this one.
        steering_lock: rad, the steering-wheel angle at which the car's wheels reach
            their stops (commands beyond it are clamped; the env's action bound);
            ``None``: ``max_steer_angle``.
    """

    name: str
    vehicle_mass: float
    fuel_capacity: float
    brake_deadband: float
    decel_limit: float
    accel_limit: float
    wheel_radius: float
    wheel_base: float
    steer_ratio: float
    max_lat_accel: float
    max_steer_angle: float
    max_drive_force: float
    max_drive_power: float
    drag_coefficient: float
    rolling_resistance: float
    creep_hold_torque: float
    creep_speed: float
    tire_friction: float
    throttle_time_constant: float = 0.0
    brake_time_constant: float = 0.0
    steering_time_constant: float = 0.0
    linear_drag: float = 0.0
    rest_speed: float = 0.0
    response_steer_ratio: float | None = None
    steering_lock: float | None = None

    def __post_init__(self) -> None:
        positive = ("vehicle_mass", "wheel_radius", "wheel_base", "steer_ratio",
                    "max_steer_angle", "max_drive_force", "creep_speed", "tire_friction")
        non_negative = ("fuel_capacity", "drag_coefficient", "rolling_resistance",
                        "creep_hold_torque", "throttle_time_constant", "brake_time_constant",
                        "steering_time_constant", "max_lat_accel", "accel_limit",
                        "brake_deadband", "linear_drag", "rest_speed")
        optional_positive = ("response_steer_ratio", "steering_lock")
        for field in positive:
            value = getattr(self, field)
            if not (_is_real(value) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"VehicleParameters {self.name!r}: {field} must be a finite "
                                 f"number > 0, got {value!r}")
        if not (_is_real(self.max_drive_power) and self.max_drive_power > 0.0):
            raise ValueError(f"VehicleParameters {self.name!r}: max_drive_power must be a "
                             f"number > 0 (W; math.inf: no power limit), got "
                             f"{self.max_drive_power!r}")
        for field in optional_positive:
            value = getattr(self, field)
            if value is not None and not (_is_real(value) and math.isfinite(value)
                                          and value > 0.0):
                raise ValueError(f"VehicleParameters {self.name!r}: {field} must be None or "
                                 f"a finite number > 0, got {value!r}")
        for field in non_negative:
            value = getattr(self, field)
            if not (_is_real(value) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"VehicleParameters {self.name!r}: {field} must be a finite "
                                 f"number >= 0, got {value!r}")
        if not (math.isfinite(self.decel_limit) and self.decel_limit <= 0.0):
            raise ValueError(f"VehicleParameters {self.name!r}: decel_limit must be <= 0 "
                             f"(m/s^2), got {self.decel_limit!r}")

    # ------------------------------------------------------------------ derived values
    @property
    def fuel_mass(self) -> float:
        """kg of fuel on board (a full tank)."""
        return self.fuel_capacity * FUEL_KG_PER_GALLON

    @property
    def total_mass(self) -> float:
        """kg, car plus fuel: the mass the physics accelerates."""
        return self.vehicle_mass + self.fuel_mass

    @property
    def rolling_force(self) -> float:
        """N, rolling resistance ``C_rr * m * g`` (constant while moving)."""
        return self.rolling_resistance * self.total_mass * GRAVITY

    @property
    def creep_force_at_rest(self) -> float:
        """N, idle creep at standstill, so that ``creep_hold_torque`` exactly holds (0 for
        a car that does not creep, ``creep_hold_torque == 0``)."""
        if self.creep_hold_torque <= 0.0:
            return 0.0
        return self.creep_hold_torque / self.wheel_radius + self.rolling_force

    @property
    def road_wheel_ratio(self) -> float:
        """Steering-wheel angle / road-wheel angle of the car itself (the physics')."""
        return self.steer_ratio if self.response_steer_ratio is None else (
            self.response_steer_ratio)

    @property
    def steering_wheel_lock(self) -> float:
        """rad, the largest steering-wheel angle the car turns its wheels by."""
        return self.max_steer_angle if self.steering_lock is None else self.steering_lock

    def resistance_force(self, speed: float) -> float:
        """N resisting motion at ``speed`` m/s > 0: rolling + linear + aerodynamic drag."""
        return (self.drag_coefficient * speed * speed + self.linear_drag * speed
                + self.rolling_force)

    @property
    def max_brake_force(self) -> float:
        """N, the tyre friction limit on the brake force."""
        return self.tire_friction * self.total_mass * GRAVITY

    @property
    def max_road_wheel_angle(self) -> float:
        """rad, largest road-wheel angle (``steering_wheel_lock / road_wheel_ratio``)."""
        return self.steering_wheel_lock / self.road_wheel_ratio

    @property
    def min_turn_radius(self) -> float:
        """m, rear-axle radius at full lock (``wheel_base / tan(max road-wheel angle)``)."""
        return self.wheel_base / math.tan(self.max_road_wheel_angle)

    def engine_force(self, speed: float) -> float:
        """N, drive force at full throttle at ``speed`` m/s (traction or power limited)."""
        if speed * self.max_drive_force <= self.max_drive_power:
            return self.max_drive_force
        return self.max_drive_power / speed

    def creep_force(self, speed: float) -> float:
        """N, idle creep at ``speed`` m/s (fades linearly to 0 at ``creep_speed``)."""
        if speed >= self.creep_speed:
            return 0.0
        return self.creep_force_at_rest * (1.0 - speed / self.creep_speed)

    def replace(self, **changes: float | str | None) -> VehicleParameters:
        """A copy with some fields changed (``dataclasses.replace``, re-validated)."""
        return dataclasses.replace(self, **changes)


# The original simulator's Unity car (udacity/self-driving-car-sim, Car.prefab): see
# docs/track_vehicle.md for the sources.
_UNITY_WHEEL_TORQUE_NM = 2000.0 / 4  # m_FullTorqueOverAllWheels, four-wheel drive
_UNITY_WHEEL_RADII_M = (0.335, 0.335, 0.37, 0.37)  # front, front, rear, rear
_UNITY_BODY_MASS_KG = 1000.0  # Rigidbody m_Mass
_UNITY_BODY_DRAG = 0.1  # Rigidbody m_Drag, 1/s
_UNITY_WHEEL_DAMPING = 0.25  # WheelCollider m_WheelDampingRate, N m s/rad

SIM_VEHICLE = VehicleParameters(
    name="sim",
    vehicle_mass=1080.0,
    fuel_capacity=0.0,
    brake_deadband=0.2,
    decel_limit=-5.0,
    accel_limit=1.0,
    wheel_radius=0.335,
    wheel_base=3.0,
    steer_ratio=14.8,
    max_lat_accel=3.0,
    max_steer_angle=8.0,
    # The Unity car the launch file's 1080 kg (rigid body 1000 kg + 4 wheels of 20 kg) and
    # 0.335 m (front wheel radius) were read from: its CarController spreads
    # m_FullTorqueOverAllWheels = 2000 N m over the four wheels at full throttle (500 N m on
    # each of two 0.335 m and two 0.37 m wheels: 5688 N, 5.3 m/s^2) and has no torque curve
    # or power limit (its gears only set the engine sound).
    max_drive_force=_UNITY_WHEEL_TORQUE_NM * sum(1.0 / r for r in _UNITY_WHEEL_RADII_M),
    max_drive_power=math.inf,
    # Its rigid body's drag 0.1 /s on 1000 kg is 100 N per m/s, its wheel colliders' damping
    # 0.25 N m s/rad adds 0.25 / r^2 per wheel (8.1 N per m/s): 108.1 N per m/s in all,
    # 1.2 kN at 40 km/h. No aerodynamic drag, no rolling resistance in a wheel collider.
    drag_coefficient=0.0,
    rolling_resistance=0.0,
    linear_drag=_UNITY_BODY_DRAG * _UNITY_BODY_MASS_KG + _UNITY_WHEEL_DAMPING * sum(
        1.0 / (r * r) for r in _UNITY_WHEEL_RADII_M),
    # No idle creep: the car's motor torque is throttle x torque, 0 at zero throttle.
    creep_hold_torque=0.0,
    creep_speed=2.0,  # (no creep: unused)
    tire_friction=1.0,  # the wheel colliders' friction curves peak at 1 (dry asphalt)
    # Below 0.1 m/s a coasting car comes to rest: Unity's default sleep threshold 0.005
    # (mass-normalised kinetic energy, v^2 / 2) and PhysX's sticky tyres.
    rest_speed=0.1,
    # The original reports road-wheel angles up to 0.447241 rad (25.6 degrees) for wheel
    # commands 18.3345 times larger (CarND-Capstone issues #110/#111): the wheels reach
    # their stops at 8.2 rad, the Dataspeed SteeringCmd's range.
    response_steer_ratio=8.2 / 0.447241,
    steering_lock=8.2,
)
"""The original simulator's car (spec table, sim column; the physics of the original's
Unity car, docs/track_vehicle.md): no idle creep, a constant drive force, speed-
proportional drag, the original's steering ratio and lock. No actuator lag, like Unity."""

SITE_VEHICLE = VehicleParameters(
    name="site",
    vehicle_mass=1736.35,
    fuel_capacity=13.5,
    brake_deadband=0.1,
    decel_limit=-1.0,
    accel_limit=1.0,
    wheel_radius=0.2413,
    wheel_base=2.8498,
    steer_ratio=14.8,
    max_lat_accel=3.0,
    max_steer_angle=8.0,
    # The course's real car is a Lincoln MKZ hybrid (about 140 kW system power); 6 kN at
    # the wheels is ~3.4 m/s^2 at launch for its 1775 kg with fuel.
    max_drive_force=6000.0,
    max_drive_power=140_000.0,
    # 0.5 * 1.2 * Cd 0.30 * 2.4 m^2 = 0.43 (mid-size sedan); C_rr 0.015.
    drag_coefficient=0.43,
    rolling_resistance=0.015,
    # The real car is an automatic and creeps at idle: the course holds it with 700 N m.
    creep_hold_torque=700.0,  # spec: about 700 N m holds the stopped site car
    creep_speed=2.0,
    tire_friction=1.0,
    # A production drive-by-wire car responds with small delays: electronic throttle and
    # engine torque build-up, hydraulic brake pressure, electric power steering motor.
    throttle_time_constant=0.2,
    brake_time_constant=0.1,
    steering_time_constant=0.1,
)
"""The course's real car (spec table, site column), with small actuator lags."""

VEHICLE_PRESETS: dict[str, VehicleParameters] = {"sim": SIM_VEHICLE, "site": SITE_VEHICLE}
"""Presets by name."""


def vehicle_parameters(name: str) -> VehicleParameters:
    """The preset called ``name`` ("sim" or "site"); an unknown name lists the choices."""
    try:
        return VEHICLE_PRESETS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown vehicle preset {name!r}; choose one of {sorted(VEHICLE_PRESETS)}"
        ) from None


@dataclass(slots=True)
class VehicleState:
    """The car's state after a step (mutable: :meth:`DBWVehicle.step` updates it in place).

    Attributes:
        x, y: m, position of the rear-axle centre.
        yaw: rad, heading counter-clockwise from +x, in ``[-pi, pi]``.
        speed: m/s along the heading, >= 0.
        yaw_rate: rad/s (positive turning left).
        acceleration: m/s^2, longitudinal: mean over the last step.
        lateral_acceleration: m/s^2, ``speed * yaw_rate`` (positive to the left).
        throttle: actual throttle in [0, 1] after the actuator lag.
        brake_torque: N m, actual brake torque after the lag.
        steering_wheel_angle: rad, actual steering-wheel angle after the lag and clamp.
        road_wheel_angle: rad, ``steering_wheel_angle / steer_ratio``.
        odometer: m driven since reset.
    """

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    speed: float = 0.0
    yaw_rate: float = 0.0
    acceleration: float = 0.0
    lateral_acceleration: float = 0.0
    throttle: float = 0.0
    brake_torque: float = 0.0
    steering_wheel_angle: float = 0.0
    road_wheel_angle: float = 0.0
    odometer: float = 0.0

    def copy(self) -> VehicleState:
        """An independent snapshot."""
        return dataclasses.replace(self)


class DBWVehicle:
    """One drive-by-wire car; see the module docstring for the model.

    Usage::

        car = DBWVehicle(vehicle_parameters("sim"))
        car.reset(x, y, yaw)
        state = car.step(throttle, brake_torque, steering_wheel_angle)  # PHYSICS_DT

    :meth:`step` mutates and returns :attr:`state`; take :meth:`VehicleState.copy` to keep
    a snapshot. The physics is :func:`~sdc_gym.vehicle.dbw_kernel.step_vehicle`, the
    kernel the track world steps every env's car with: this class is its batch of one.
    """

    def __init__(self, params: VehicleParameters = SIM_VEHICLE) -> None:
        if not isinstance(params, VehicleParameters):
            raise TypeError(f"params must be VehicleParameters, got {type(params).__name__}")
        self.params = params
        self.state = VehicleState()
        self._constants = vehicle_constants(params)
        self._max_swa = float(self._constants[MAX_SWA])
        self._wheel_base = params.wheel_base
        self._row = np.zeros((1, STATE_SIZE))
        self._lag_dt = math.nan
        self._gains = np.ones(3)

    # ------------------------------------------------------------------ set-up
    def reset(
        self,
        x: float,
        y: float,
        yaw: float,
        speed: float = 0.0,
        *,
        throttle: float = 0.0,
        brake_torque: float = 0.0,
        steering_wheel_angle: float = 0.0,
    ) -> VehicleState:
        """Place the car (rear axle at ``x, y``, heading ``yaw``) and set the actuators.

        The actuator keywords set the lagged actuator states (e.g. start parked with the
        brake already at ``brake_torque``); without lag they only matter until the next
        step.
        """
        values = {"x": x, "y": y, "yaw": yaw, "speed": speed}
        for key, value in values.items():
            if not math.isfinite(value):
                raise ValueError(f"DBWVehicle.reset: {key} must be finite, got {value!r}")
        if speed < 0.0:
            raise ValueError(f"DBWVehicle.reset: speed must be >= 0 m/s (no reverse), "
                             f"got {speed!r}")
        reset_vehicle(self._constants, self._row, 0, float(x), float(y), float(yaw),
                      float(speed), float(throttle), float(brake_torque),
                      float(steering_wheel_angle))
        self.state = VehicleState(*self._row[0].tolist())
        return self.state

    def _set_dt(self, dt: float) -> None:
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"DBWVehicle.step: dt must be a finite number > 0 s, got {dt!r}")
        self._lag_dt = dt
        self._gains = lag_gains(self.params, dt)

    # ------------------------------------------------------------------ physics
    def step(
        self,
        throttle: float,
        brake_torque: float,
        steering_wheel_angle: float,
        dt: float = PHYSICS_DT,
    ) -> VehicleState:
        """Advance ``dt`` seconds under the commands; returns the (mutated) state.

        Commands are clamped to what the hardware can do: throttle to ``[0, 1]``, brake
        torque to ``>= 0`` N m, steering-wheel angle to ``+-max_steer_angle`` rad (infinite
        values clamp too; NaN raises ``ValueError``). The caller (the env) validates them
        and reports out-of-range actions.
        """
        if dt != self._lag_dt:
            self._set_dt(dt)
        # NaN is the one value no clamp can fix (it compares false with everything).
        if throttle != throttle or brake_torque != brake_torque or (
                steering_wheel_angle != steering_wheel_angle):
            raise ValueError(f"DBWVehicle.step: commands must not be NaN, got throttle "
                             f"{throttle!r}, brake_torque {brake_torque!r}, "
                             f"steering_wheel_angle {steering_wheel_angle!r}")
        st = self.state
        row = self._row
        row[0] = (st.x, st.y, st.yaw, st.speed, st.yaw_rate, st.acceleration,
                  st.lateral_acceleration, st.throttle, st.brake_torque,
                  st.steering_wheel_angle, st.road_wheel_angle, st.odometer)
        step_vehicle(self._constants, self._gains, row, 0, float(throttle), float(brake_torque),
                     float(steering_wheel_angle), float(dt))
        (st.x, st.y, st.yaw, st.speed, st.yaw_rate, st.acceleration, st.lateral_acceleration,
         st.throttle, st.brake_torque, st.steering_wheel_angle, st.road_wheel_angle,
         st.odometer) = row[0].tolist()
        return st

    # ------------------------------------------------------------------ body points
    def point_ahead(self, distance: float) -> tuple[float, float]:
        """(x, y) in m of the body point ``distance`` m ahead of the rear axle."""
        st = self.state
        return st.x + distance * math.cos(st.yaw), st.y + distance * math.sin(st.yaw)

    def center_xy(self) -> tuple[float, float]:
        """(x, y) in m of the wheelbase midpoint (the car's geometric centre here)."""
        return self.point_ahead(0.5 * self._wheel_base)

    def front_axle_xy(self) -> tuple[float, float]:
        """(x, y) in m of the front-axle centre."""
        return self.point_ahead(self._wheel_base)
