"""Two capstone teams' twist controllers, written from public descriptions, as stand-ins.

A drive-by-wire stack written for the original capstone simulator must drive here as it
did there (issue 19). These two controllers are how public capstone teams built the last
node of their stacks; each replaces sdc-gym's :class:`~sdc_gym.stack.track.controllers.
TwistController` under sdc-gym's waypoint updater and pure pursuit (:func:`with_controller`),
with the same call (``control(now, target_linear, target_angular, twist_time, speed,
velocity_time, dbw_enabled) -> DBWCommand``) and ``reset()``.

:class:`WalkthroughTwistController` (the course walkthrough's, which most teams started from)
    A low-pass filter (tau 0.5 s, ts 0.02 s; its first sample passes through) on the
    *current speed*; the original yaw controller (min_speed 0.1 m/s, the vehicle's full
    ``max_lat_accel``); throttle from a PID on the speed error (kp 0.3, ki 0.1, kd 0,
    output limited to [0, 0.2]); then, in this order: a target speed of exactly 0 with
    the filtered speed below 0.1 m/s holds the car with a fixed torque (400 N m, the
    walkthrough's figure for the simulator; 700 N m for Carla) and no throttle; else a
    throttle below 0.1 with a negative speed error brakes with ``|max(error, decel_limit)|
    x vehicle_mass x wheel_radius`` (the speed error in m/s taken as the deceleration)
    and no throttle. With drive-by-wire off only the PID is reset and nothing is sent.
:class:`ProportionalBrakeTwistController` (teams without a holding torque)
    The same yaw controller; throttle from a PID on the speed error (kp 0.4, ki 0.1,
    output in [0, accel_limit]) while the car is slower than its target; faster, no
    throttle and a brake proportional to the excess speed,
    ``brake_gain x (v - v_target) x total_mass x wheel_radius`` (1.5 /s: 270 N m at
    0.5 m/s for the sim car), capped at ``|decel_limit|``'s torque, and **0 below a
    deadband of 0.1 m/s**: no torque ever holds the car at rest.

Both trust the car to stay where it stops: on a car that creeps at idle the second one
rolls over its stop lines, which is what the old sim preset did (docs/track_vehicle.md).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

from sdc_gym.stack.track.controllers import (
    NO_COMMAND,
    PID,
    DBWCommand,
    LowPassFilter,
    YawController,
)
from sdc_gym.stack.track.dbw_stack import DBWStackAgent, dbw_stack_for_env
from sdc_gym.stack.track.detector import GroundTruthLightSource
from sdc_gym.stack.track.follower import CONTINUOUS_FOLLOWER
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT, VehicleParameters

YAW_MIN_SPEED_MPS = 0.1  # the walkthrough's YawController(..., 0.1, ...)
CAPSTONE_DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "udacity" / "capstone"

CARS: dict[str, dict[str, Any]] = {
    "sim": {},
    # The sim preset before issue 19 (vehicle_overrides that restore it exactly): an
    # automatic creeping at idle, held by 400 N m, 4 kN / 90 kW, aerodynamic drag and
    # rolling resistance, the kinematic bicycle with the launch file's 14.8 and 8 rad.
    "creeping": {"creep_hold_torque": 400.0, "creep_speed": 2.0, "max_drive_force": 4000.0,
                 "max_drive_power": 90_000.0, "drag_coefficient": 0.40,
                 "rolling_resistance": 0.015, "linear_drag": 0.0, "rest_speed": 0.0,
                 "response_steer_ratio": None, "steering_lock": None},
}
"""``vehicle_overrides`` by name: the sim preset, and the sim preset before issue 19."""


def original_track_config(**overrides: Any) -> dict[str, Any]:
    """``TrackLoop-v0`` config for the original simulator's track: ``wp_yaw_const.csv``
    with its 8 stop lines (``sim_traffic_light_config.yaml``), ground-truth light states
    in the observation, the sim car, 40 km/h; ``overrides`` replace keys."""
    return {"track": str(CAPSTONE_DATA / "wp_yaw_const.csv"),
            "light_config": str(CAPSTONE_DATA / "sim_traffic_light_config.yaml"),
            "observe_light_states": True, **overrides}


def _yaw_controller(vehicle: VehicleParameters) -> YawController:
    """The original yaw controller with the launch file's parameters (full lateral limit)."""
    return YawController(vehicle.wheel_base, vehicle.steer_ratio, YAW_MIN_SPEED_MPS,
                         vehicle.max_lat_accel, vehicle.max_steer_angle)


class _Clock:
    """The time between calls, the nominal period on the first one (rospy's last_time)."""

    def __init__(self, nominal_s: float) -> None:
        self.nominal_s = nominal_s
        self.last_s: float | None = None

    def tick(self, now_s: float) -> float:
        dt = self.nominal_s if self.last_s is None else now_s - self.last_s
        self.last_s = now_s
        return dt if dt > 0.0 else self.nominal_s


class _StandIn:
    """What both stand-ins share: the vehicle, the original yaw controller, a throttle PID,
    the clock; with drive-by-wire off only the PID is reset and nothing is sent."""

    def __init__(self, vehicle: VehicleParameters, throttle_pid: PID,
                 sample_time_s: float) -> None:
        self.vehicle = vehicle
        self.yaw = _yaw_controller(vehicle)
        self.throttle_pid = throttle_pid
        self.sample_time_s = sample_time_s
        self.reset()

    def reset(self) -> None:
        self.throttle_pid.reset()
        self._clock = _Clock(self.sample_time_s)

    def control(self, now_s: float, target_linear_mps: float, target_angular_radps: float,
                twist_time_s: float, current_speed_mps: float, velocity_time_s: float,
                dbw_enabled: bool) -> DBWCommand:
        if not dbw_enabled:
            self.throttle_pid.reset()
            return NO_COMMAND
        return self._command(self._clock.tick(now_s), target_linear_mps,
                             target_angular_radps, current_speed_mps)

    def _command(self, dt: float, target_linear_mps: float, target_angular_radps: float,
                 speed_mps: float) -> DBWCommand:
        raise NotImplementedError


class WalkthroughTwistController(_StandIn):
    """The course walkthrough's twist controller (see the module docstring)."""

    def __init__(self, vehicle: VehicleParameters, *, hold_torque: float = 400.0,
                 sample_time_s: float = PHYSICS_DT) -> None:
        self.hold_torque = float(hold_torque)
        super().__init__(vehicle, PID(0.3, 0.1, 0.0, 0.0, 0.2), sample_time_s)

    def reset(self) -> None:
        super().reset()
        self.velocity_filter = LowPassFilter(0.5, 0.02)
        self._filter_ready = False

    def _command(self, dt: float, target_linear_mps: float, target_angular_radps: float,
                 speed_mps: float) -> DBWCommand:
        if not self._filter_ready:  # the original filter passes its first sample through
            self.velocity_filter.value = speed_mps
            self._filter_ready = True
        speed = self.velocity_filter.filt(speed_mps)
        steering = self.yaw.steering(target_linear_mps, target_angular_radps, speed)
        error = target_linear_mps - speed
        throttle = self.throttle_pid.step(error, dt)
        brake = 0.0
        if target_linear_mps == 0.0 and speed < 0.1:
            throttle, brake = 0.0, self.hold_torque
        elif throttle < 0.1 and error < 0.0:
            decel = max(error, self.vehicle.decel_limit)
            throttle = 0.0
            brake = abs(decel) * self.vehicle.vehicle_mass * self.vehicle.wheel_radius
        return DBWCommand(throttle, brake, steering)


class ProportionalBrakeTwistController(_StandIn):
    """PID throttle, brake proportional to the excess speed, none below 0.1 m/s."""

    def __init__(self, vehicle: VehicleParameters, *, brake_gain_per_s: float = 1.5,
                 brake_deadband_mps: float = 0.1,
                 sample_time_s: float = PHYSICS_DT) -> None:
        self.brake_gain_per_s = float(brake_gain_per_s)
        self.brake_deadband_mps = float(brake_deadband_mps)
        self.torque_per_decel = vehicle.total_mass * vehicle.wheel_radius
        self.max_brake = abs(vehicle.decel_limit) * self.torque_per_decel
        super().__init__(vehicle, PID(0.4, 0.1, 0.0, 0.0, vehicle.accel_limit), sample_time_s)

    def _command(self, dt: float, target_linear_mps: float, target_angular_radps: float,
                 speed_mps: float) -> DBWCommand:
        steering = self.yaw.steering(target_linear_mps, target_angular_radps, speed_mps)
        excess = speed_mps - target_linear_mps
        throttle = self.throttle_pid.step(-excess, dt)
        if excess <= 0.0:
            return DBWCommand(throttle, 0.0, steering)
        brake = 0.0
        if speed_mps > self.brake_deadband_mps:
            brake = min(self.brake_gain_per_s * excess * self.torque_per_decel, self.max_brake)
        return DBWCommand(0.0, brake, steering)


ControllerFactory = Callable[[VehicleParameters], object]
STAND_INS: dict[str, ControllerFactory] = {
    "walkthrough": WalkthroughTwistController,
    "proportional_brake": ProportionalBrakeTwistController,
}
"""The stand-ins by name (each takes the env's vehicle parameters)."""


def with_controller(env: gym.Env, name: str) -> DBWStackAgent:
    """sdc-gym's stack on ground-truth lights with its twist controller replaced by the
    stand-in ``name`` (or kept: ``"sdc_gym"``)."""
    agent = dbw_stack_for_env(env, GroundTruthLightSource(), name=name,
                              follower=CONTINUOUS_FOLLOWER)
    if name != "sdc_gym":
        try:
            factory = STAND_INS[name]
        except KeyError:
            raise ValueError(f"unknown controller {name!r}; choose 'sdc_gym' or one of "
                             f"{sorted(STAND_INS)}") from None
        agent.controller = factory(env.unwrapped.params)  # type: ignore[assignment]
        agent.reset()
    return agent


def drive_episode(env: gym.Env, agent: Any, seed: int) -> dict[str, Any]:
    """Reset ``env`` with ``seed`` and ``agent``, step until the episode ends; the last info
    (its ``"summary"`` is the episode's)."""
    observation, info = env.reset(seed=seed)
    agent.reset()
    while True:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        if terminated or truncated:
            return info


__all__ = [
    "CARS",
    "STAND_INS",
    "ProportionalBrakeTwistController",
    "WalkthroughTwistController",
    "drive_episode",
    "original_track_config",
    "with_controller",
]
