"""The drive-by-wire reference stack wired as an agent for ``sdc_gym/TrackLoop-v0``.

:class:`DBWStackAgent` runs the nodes of :mod:`sdc_gym.stack.track` once per env step (a tick),
each at its own rate (:mod:`sdc_gym.stack.track.rates`), in data-flow order::

    detector (light report) -> behavior + updater (final waypoints) -> follower (twist)
    -> twist controller (throttle, brake torque, steering-wheel angle)

A node that does not run at a tick leaves its last output in place (like a ROS topic's
last message), and the action is the last command of the twist controller. Messages are
stamped with the agent's clock (``tick * loop period``) so the watchdogs of the updater
and the twist controller see their ages: the pose and the speed arrive every tick, the
light information at the detector's rate, the twist at the follower's.

The follower is chosen by name (:data:`FOLLOWERS`, :func:`make_follower`): ``"pure_pursuit"``
(the original's) or ``"mpc"`` (:class:`~sdc_gym.stack.track.mpc.MPCFollower`, the seed
team's further work), both from the final waypoints to a twist command.

The behavior layer is any :class:`~sdc_gym.stack.track.behavior.TrackBehaviorPolicy` (default the
rule-based :class:`~sdc_gym.stack.track.behavior.StopAtRedLights`), asked at every updater tick.

Stop geometry: the env's pose is the rear axle and its stop-line metrics use the front
bumper (``front_offset`` m ahead), so the updater's target speed is zero from
``front_offset + STOP_GAP_M`` before the line on: the bumper comes to rest about 1 m
before it (see :data:`STOP_GAP_M`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import UNKNOWN
from sdc_gym.road.track_map import TrackMap
from sdc_gym.stack.track.behavior import (
    StopAtRedLights,
    StopAtRedParameters,
    TrackBehaviorDecision,
    TrackBehaviorPolicy,
    TrackSituation,
)
from sdc_gym.stack.track.controllers import (
    NO_COMMAND,
    DBWCommand,
    TwistController,
    TwistControllerParameters,
)
from sdc_gym.stack.track.detector import (
    DetectorParameters,
    LightReport,
    LightStateSource,
    TrafficLightDetector,
    next_stop_line,
)
from sdc_gym.stack.track.follower import (
    CONTINUOUS_FOLLOWER,
    FollowerParameters,
    PurePursuit,
    TwistCommand,
)
from sdc_gym.stack.track.mpc import MPCFollower, MPCParameters, mpc_parameters_for
from sdc_gym.stack.track.rates import NodeRates, RateScheduler, node_rates
from sdc_gym.stack.track.waypoints import (
    FinalWaypoints,
    UpdaterParameters,
    WaypointUpdater,
    load_waypoints,
    stop_line_waypoints,
)
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT, VehicleParameters

STOP_GAP_M = 1.6
"""m between the front bumper and the stop line where the target speed becomes 0. The
speed controller lags the ramp and carries the car about 0.6 m further (measured on the
default track, sim car), so it comes to rest about 1 m before the line, the middle of the
0..2 m window."""
DEFAULT_FRONT_OFFSET_M = 4.0
"""m from the rear axle to the front bumper when not given (the sim car: 3 m + 1 m)."""
RAMP_DECEL_MPS2 = 1.5
"""m/s^2, the stop ramp's deceleration, at most half the vehicle's ``|decel_limit|``."""
FOLLOWERS = ("pure_pursuit", "mpc")
"""The waypoint followers by name (:func:`make_follower`)."""


def make_follower(kind: str, controller: TwistController,
                  follower_params: FollowerParameters | None = None,
                  mpc_params: MPCParameters | None = None) -> PurePursuit | MPCFollower:
    """The follower ``kind`` (:data:`FOLLOWERS`). The MPC's default limits are those the
    twist ``controller`` is told: the curvature at the steering lock and its lateral
    acceleration limit (its ``speed_from_next_waypoint`` is ``follower_params``')."""
    if kind == "pure_pursuit":
        if mpc_params is not None:
            raise ValueError("make_follower: mpc_params given with follower 'pure_pursuit'")
        return PurePursuit(follower_params)
    if kind == "mpc":
        if mpc_params is None:
            c = controller.constants
            next_speed = follower_params.speed_from_next_waypoint if follower_params else False
            mpc_params = mpc_parameters_for(c.wheel_base, c.steer_ratio, c.max_steer_angle,
                                            c.max_lat_accel,
                                            speed_from_next_waypoint=next_speed)
        return MPCFollower(mpc_params)
    raise ValueError(f"unknown follower {kind!r}; choose one of {list(FOLLOWERS)}")


class DBWStackAgent:
    """The reference stack; see the module docstring.

    Args:
        name: label for reports.
        track: the track (waypoints, stop lines).
        vehicle: the car's parameters (limits, mass, geometry for the controllers).
        light_source: the detector's :class:`~sdc_gym.stack.track.detector.LightStateSource`.
        speed_limit_mps: cruise speed (default: the track's).
        loop_period_s: s per env step (``PHYSICS_DT * steps_per_action``).
        rates: node rates (a preset name or :class:`~sdc_gym.stack.track.rates.NodeRates`).
        behavior: the go/stop policy (default :class:`StopAtRedLights` for ``vehicle``).
        front_offset_m: rear axle to front bumper, m (for the stop margin).
        follower_kind: the waypoint follower, a name of :data:`FOLLOWERS`.
        mpc_params: the MPC's settings (``follower_kind="mpc"``; default from the car).

    Attributes after :meth:`act`: ``light_report``, ``decision``, ``final_waypoints``,
    ``twist``, ``command`` (the nodes' last outputs) and ``node_runs`` (runs per node).
    """

    def __init__(
        self,
        name: str,
        track: TrackMap,
        vehicle: VehicleParameters,
        light_source: LightStateSource,
        *,
        speed_limit_mps: float | None = None,
        loop_period_s: float = PHYSICS_DT,
        rates: str | NodeRates = "original",
        behavior: TrackBehaviorPolicy | None = None,
        front_offset_m: float = DEFAULT_FRONT_OFFSET_M,
        updater_params: UpdaterParameters | None = None,
        follower_params: FollowerParameters | None = None,
        controller_params: TwistControllerParameters | None = None,
        detector_params: DetectorParameters | None = None,
        follower_kind: str = "pure_pursuit",
        mpc_params: MPCParameters | None = None,
    ) -> None:
        if not isinstance(light_source, LightStateSource):
            raise TypeError(f"light_source must have classify(observation) -> int, got "
                            f"{type(light_source).__name__}")
        self.name = name
        self.track = track
        self.vehicle = vehicle
        self.speed_limit_mps = float(track.speed_limit_mps if speed_limit_mps is None
                                     else speed_limit_mps)
        self.rates = node_rates(rates)
        self.scheduler = RateScheduler(loop_period_s, self.rates.as_mapping())
        self.waypoints = load_waypoints(track, self.speed_limit_mps)
        max_decel = abs(vehicle.decel_limit)
        self.stop_margin_m = front_offset_m + STOP_GAP_M
        updater_params = updater_params or UpdaterParameters(
            stop_margin_m=self.stop_margin_m,
            stop_decel_mps2=min(RAMP_DECEL_MPS2, 0.5 * max_decel))
        self.stop_margin_m = updater_params.stop_margin_m
        self.updater = WaypointUpdater(self.waypoints, updater_params,
                                       track.stop_lines_xy)
        self.detector = TrafficLightDetector(stop_line_waypoints(track, self.waypoints),
                                             light_source, detector_params)
        self.behavior: TrackBehaviorPolicy = behavior or StopAtRedLights(StopAtRedParameters(
            max_decel_mps2=max_decel,
            comfortable_decel_mps2=min(StopAtRedParameters.comfortable_decel_mps2, max_decel)))
        self.controller = TwistController(vehicle, 1.0 / self.scheduler.rate("dbw"),
                                          controller_params)
        self.follower_kind = follower_kind
        self.follower = make_follower(follower_kind, self.controller, follower_params,
                                      mpc_params)
        self.reset()

    def reset(self) -> None:
        """A new episode: every node forgets its state (the loader's output is kept)."""
        self.scheduler.reset()
        self.updater.reset()
        self.detector.reset()
        self.behavior.reset()
        self.follower.reset()
        self.controller.reset()
        self.light_report: LightReport = self.detector.report
        self.decision: TrackBehaviorDecision | None = None
        self.final_waypoints: FinalWaypoints | None = None
        self.twist: TwistCommand | None = None
        self._twist_time = -math.inf
        self.command: DBWCommand = NO_COMMAND
        self.node_runs = dict.fromkeys(self.scheduler.names, 0)

    def situation(self, observation: Mapping[str, Any],
                  time_s: float | None = None) -> TrackSituation:
        """What the behavior layer sees at ``time_s`` (default: the next tick's time): the
        next stop line of ``observation`` and the detector's last report (its state only
        if it is about that line)."""
        line, distance = next_stop_line(observation)
        report = self.light_report
        state = report.state if report.stop_line == line else UNKNOWN
        waypoint = int(self.detector.stop_waypoints[line]) if line >= 0 else -1
        return TrackSituation(time_s=self.scheduler.time_s if time_s is None else time_s,
                              speed_mps=float(observation["velocity"][0]),
                              speed_limit_mps=self.speed_limit_mps, stop_line=line,
                              stop_waypoint=waypoint, stop_line_distance_m=distance,
                              light_state=state, stop_margin_m=self.stop_margin_m)

    def act(self, observation: Mapping[str, Any]) -> NDArray[np.float32]:
        """``[throttle, brake torque N m, steering-wheel angle rad]`` for this step."""
        now = self.scheduler.time_s
        x, y, yaw = (float(value) for value in observation["pose"])
        speed = float(observation["velocity"][0])
        dbw_enabled = bool(int(observation["dbw_enabled"]))
        for node in self.scheduler.tick():
            self.node_runs[node] += 1
            if node == "detector":
                self.light_report = self.detector.detect(observation, now)
            elif node == "updater":
                self.decision = self.behavior.decide(self.situation(observation, now))
                light_time = self.light_report.time_s if self.track.light_count else None
                self.final_waypoints = self.updater.update(
                    now, x, y, yaw, now, self.decision.stop_waypoint, light_time,
                    self.decision.target_speed_mps)
            elif node == "follower" and self.final_waypoints is not None:
                self.twist = self.follower.follow(x, y, yaw, speed, self.final_waypoints)
                self._twist_time = now
            elif node == "dbw":
                twist = self.twist or TwistCommand(0.0, 0.0)
                self.command = self.controller.control(
                    now, twist.linear_mps, twist.angular_radps, self._twist_time, speed, now,
                    dbw_enabled)
        command = self.command
        return np.array([command.throttle, command.brake_torque, command.steering],
                        dtype=np.float32)


def dbw_stack_for_env(
    env: gym.Env | Any,
    light_source: LightStateSource,
    *,
    name: str,
    rates: str | NodeRates = "original",
    behavior: TrackBehaviorPolicy | None = None,
    follower: FollowerParameters | None = None,
    follower_kind: str = "pure_pursuit",
    mpc_params: MPCParameters | None = None,
    controller: TwistControllerParameters | None = None,
) -> DBWStackAgent:
    """The stack for a ``TrackLoop-v0`` env (or its
    :class:`~sdc_gym.envs.track_setup.TrackSetup`): its track, car, speed limit, loop
    period and front bumper offset; ``follower`` defaults to
    :data:`~sdc_gym.stack.track.follower.CONTINUOUS_FOLLOWER`; ``follower_kind`` names the
    follower (:data:`FOLLOWERS`), ``controller`` the twist controller's settings."""
    unwrapped = getattr(env, "unwrapped", env)
    loop = PHYSICS_DT * int(getattr(unwrapped, "steps_per_action", 1))
    return DBWStackAgent(
        name, unwrapped.track, unwrapped.params, light_source,
        speed_limit_mps=unwrapped.speed_limit, loop_period_s=loop, rates=rates,
        behavior=behavior,
        follower_params=CONTINUOUS_FOLLOWER if follower is None else follower,
        follower_kind=follower_kind, mpc_params=mpc_params, controller_params=controller,
        front_offset_m=float(getattr(unwrapped, "front_offset", DEFAULT_FRONT_OFFSET_M)))
