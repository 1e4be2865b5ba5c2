"""``sdc_gym/TrackLoop-v0``: the capstone track simulator, driven at the drive-by-wire level."""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.top_down_env import RENDER_CONFIG_DEFAULTS, TopDownRenderEnv
from sdc_gym.geometry.collision import boxes_overlap
from sdc_gym.lights.traffic_lights import (
    LIGHTS_DEFAULTS,
    RED,
    UNKNOWN,
    YELLOW,
    LightTiming,
    TrafficLights,
)
from sdc_gym.metrics.driving_metrics import Incident, IncidentRules
from sdc_gym.metrics.track_metrics import TRACK_INCIDENT_KINDS, TrackMetrics
from sdc_gym.road.builtin_tracks import get_track_map
from sdc_gym.road.track_map import TrackFormatError, TrackMap
from sdc_gym.sensors.track_camera import (
    CAMERA_DEFAULTS,
    PRESETS,
    TRAINING_SCALE,
    CameraConfig,
    TrackCamera,
)
from sdc_gym.units import MPS_TO_MPH
from sdc_gym.validation.actions import real_array
from sdc_gym.validation.env_configs import check_track_config
from sdc_gym.vehicle.dbw_vehicle import (
    PHYSICS_DT,
    VEHICLE_PRESETS,
    DBWVehicle,
    VehicleParameters,
    vehicle_parameters,
)
from sdc_gym.vehicle.manual_driver import ManualDriver

if TYPE_CHECKING:
    from sdc_gym.render.track_renderer import TrackRenderer, TrackScene

# --- the car's body around its reference point (the rear axle) -----------------------------
FRONT_OVERHANG_M = 1.0  # front axle to front bumper (the manual driver's assumption too)
REAR_OVERHANG_M = 1.0  # rear bumper to rear axle: a 5.0 m sim car, 4.85 m site car
CAR_WIDTH_M = 1.9
# --- obstacles: parked cars by default -------------------------------------------------------
OBSTACLE_LENGTH_M = 4.5
OBSTACLE_WIDTH_M = 1.8
OBSTACLE_CLEARANCE_M = 30.0  # random obstacles stay this far (along s) from the start
# Observation bounds for positions and distances (m); the tracks are a few km across.
POSITION_BOUND_M = 1e6
# The velocity bound is the car's top speed plus one frame of launch acceleration (a proven
# ceiling, see _speed_bound), plus this fraction for float32 rounding.
VELOCITY_BOUND_MARGIN = 0.05
# A default start keeps the front bumper this far (m, along the path) behind a stop line
# that would otherwise lie under the car.
START_LINE_MARGIN_M = 2.0
MANUAL_MODES = ("off", "random", "scripted")
LIGHT_PHASES = ("green_s", "yellow_s", "red_s")
# Children drawn from the env's np_random at every reset, one per random component, so that
# turning one component on or off (e.g. the camera) never changes the others.
_RNG_STREAMS = ("lights", "obstacles", "manual_schedule", "manual_driver", "camera")
_SEED_BOUND = 2**63 - 1


def _frames(seconds: float) -> int:
    """Physics frame index of a time in s (periods are applied at whole frames)."""
    return round(seconds / PHYSICS_DT)


def _is_number(value: Any) -> bool:
    """A finite real number (bools are not numbers here)."""
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value))


def top_speed(params: VehicleParameters) -> float:
    """m/s, the speed where full throttle balances the resistances (inf when there are
    none: nothing stops the car from speeding up).

    The net force ``F_engine(v) + F_creep(v) - F_resist(v)`` falls strictly with ``v``, so
    the root is unique; it is found by bisection (``F / c`` for the sim car's constant
    drive force ``F`` and linear drag ``c``: 52.61 m/s; a cubic in the site car's power-
    limited range: ``P / v = drag v^2 + F_roll``, 65.85 m/s).
    """
    if not _has_resistance(params):
        return math.inf

    def net(v: float) -> float:
        return params.engine_force(v) + params.creep_force(v) - params.resistance_force(v)

    low, high = 0.0, 1.0
    while net(high) > 0.0:
        low, high = high, 2.0 * high
    for _ in range(200):
        middle = 0.5 * (low + high)
        if middle in (low, high):
            break
        low, high = (middle, high) if net(middle) > 0.0 else (low, middle)
    return high


def _has_resistance(params: VehicleParameters) -> bool:
    """Whether anything resists motion (rolling, linear or aerodynamic drag)."""
    return (params.drag_coefficient > 0.0 or params.linear_drag > 0.0
            or params.rolling_force > 0.0)


def _speed_bound(params: VehicleParameters) -> float:
    """m/s no speed can exceed from a start at or below :func:`top_speed`.

    Below the top speed one explicit-Euler frame adds at most ``PHYSICS_DT`` times the
    largest acceleration (full throttle plus idle creep at rest); above it the net force
    is negative, so the speed falls. Hence ``top + PHYSICS_DT * a_launch`` is a ceiling
    for every throttle, brake and actuator lag.
    """
    launch = (params.max_drive_force + params.creep_force_at_rest
              - params.rolling_force) / params.total_mass
    return top_speed(params) + PHYSICS_DT * max(launch, 0.0)


class TrackLoopEnv(TopDownRenderEnv):
    """
    ## Description

    The track of Udacity's self-driving-car capstone (the "System Integration" simulator):
    a closed loop of about 7 km with eight traffic lights, driven at the drive-by-wire
    level of the original's `dbw_node`: every 0.02 s physics frame (50 Hz, the original
    DBW loop rate) the car gets a throttle, a brake *torque* and a *steering-wheel* angle.
    The car is :class:`~sdc_gym.vehicle.dbw_vehicle.DBWVehicle` (force balance with engine,
    brakes through the wheel radius, rolling resistance and drag; a kinematic bicycle with
    the car's steering ratio and wheel base; optional actuator lag), with the course's
    "sim" or "site" parameters: the sim car is the original simulator's Unity car (no idle
    creep, constant drive force, speed-proportional drag, steering ratio 18.33 and lock
    8.2 rad), the site car the real one (an automatic that creeps at idle, actuator lags);
    ``docs/track_vehicle.md`` has the facts and their sources. Its reference point is the
    **centre of the rear axle**; the front bumper is ``wheel_base + 1.0`` m ahead of it
    (4.0 m for the sim car).

    Traffic lights cycle green, yellow, red (10 s / 3 s / 10 s by default, seeded phase
    offsets, or scripted), each pole 24 m past its stop line like the original. A pinhole
    camera on the car can render them into the observation (off by default). Static
    obstacles (parked cars, the original's ``obstacle`` topic) can be placed on the track.
    In *manual-override* periods (``dbw_enabled`` false, the original's manual toggle) a
    built-in human-like driver (:class:`~sdc_gym.vehicle.manual_driver.ManualDriver`) has
    the wheel and the agent's actions are ignored; a drive-by-wire stack must then stay
    silent and reset its controllers, as on the real car.

    Tracks: ``"default"`` (sdc-gym's own ~7 km loop with 8 lights), ``"site"`` (a small
    ~77 m lot with one light and the real car's parameters), or the original's waypoint
    CSV (``x,y,z,yaw``) with its traffic-light YAML (``track`` and ``light_config`` keys).

    ## Action Space

    ``Box([0, 0, -max_steer], [1, max_brake, max_steer], (3,), float32)``:

    | index | command              | unit | range                                   |
    |-------|----------------------|------|-----------------------------------------|
    | 0     | throttle             | -    | [0, 1]                                  |
    | 1     | brake torque         | N m  | [0, tire-locking torque]                |
    | 2     | steering-wheel angle | rad  | [-steering lock, steering lock]         |

    The brake limit is the torque at which the tyres lock,
    ``tire_friction * total_mass * g * wheel_radius`` (3549 N m for the sim car, 4201 N m
    for the site car): more pedal than that does not brake harder. It is well above the
    reference controller's ``mass * |decel_limit| * wheel_radius`` (1809 / 428 N m) and the
    site car's holding torque (700 N m; the sim car needs none). Road-wheel angle =
    steering-wheel angle / the car's ``road_wheel_ratio``; the steering limit is the car's
    lock (``steering_wheel_lock``): 8.2 rad and 18.33 for the sim car (0.447 rad at the
    wheels, as the original reports), 8 rad and 14.8 for the site car (0.54 rad). The
    controllers are told ``steer_ratio`` 14.8 and ``max_steer_angle`` 8 rad (the course's
    launch files) for both. The action is held for ``steps_per_action`` frames. A NaN,
    non-numeric or out-of-range component raises ``ValueError`` naming the component and
    its valid range.

    ## Observation Space

    ``Dict`` of float32 arrays in SI units, new arrays every step (never overwritten later,
    so observations may be kept):

    | key              | shape / space   | content                                          |
    |------------------|-----------------|--------------------------------------------------|
    | `pose`           | (3,)            | x, y (m, rear axle), yaw (rad, CCW from +x)      |
    | `velocity`       | (1,)            | speed (m/s), in [0, velocity bound]              |
    | `yaw_rate`       | (1,)            | rad/s, positive turning left                     |
    | `dbw_enabled`    | Discrete(2)     | 1: the agent drives; 0: manual override          |
    | `next_stop_line` | (2,)            | index of the next stop line ahead (-1: none),    |
    |                  |                 | its distance along the path from the rear axle   |
    |                  |                 | (m; the loop length when there is none)          |
    | `light_states`   | (k,) int8       | ground-truth state per light (RED 0, YELLOW 1,   |
    |                  |                 | GREEN 2, UNKNOWN 4); if `observe_light_states`   |
    | `camera`         | (H, W, 3) uint8 | the camera image; if `camera.enabled`            |
    | `obstacles`      | (n, 2)          | obstacle centres x, y (m); if obstacles are set  |

    ``dbw_enabled`` tells whether the *next* action will be applied. Light ``i`` belongs to
    stop line ``i``. The camera image is an observation, not the ``render()`` output.

    Bounds. Every observation lies in ``observation_space``. The velocity bound
    (:attr:`velocity_bound`) is derived from the car: its top speed at full throttle
    (:func:`top_speed`: engine force = drag + rolling resistance, 52.61 m/s for the sim
    car, 65.85 m/s for the site car) plus one frame of launch acceleration, which provably
    no throttle, brake or lag can exceed (see :func:`_speed_bound`), plus 5 % for float32
    rounding: 55.35 m/s (sim). Hence ``start_speed`` must not exceed the top speed, and
    ``vehicle_overrides`` that zero drag, linear drag and rolling resistance (no top speed)
    are a ``ConfigError``. The yaw-rate bound is that speed times the curvature at full
    lock.

    Which stop line is next. ``next_stop_line`` is the next line ahead of the *rear
    axle*. The metrics count a crossing when the *front bumper* passes a line, so while a
    line is under the car (distance below ``wheel_base + 1`` m) it is still in the
    observation although it has been crossed; ``info["next_stop_line_front"]`` and
    ``info["stop_line_distance_front"]`` name the next line the bumper will cross (the
    metrics' line) and its distance from the bumper. At every reset both name the same
    line: the car never starts with a line under it (see Starting State).

    ## Rewards

    ``reward_progress * (metres gained along the path) / (speed_limit * step duration)``
    (about 1 per step at the speed limit), plus, for each incident that began during the
    step, its penalty from ``reward_incident`` (collision and off_road -10, red_light -5,
    acceleration, jerk, speed and lane -1 by default).

    Only the agent's own driving counts: physics frames driven by the human in a manual
    override add no progress reward, and incidents that began on such a frame (at the
    frame where the metrics place them) no penalty; a step driven by the human from
    start to end earns 0. The metrics and the summary still record everything (they
    measure the car, whoever drives). ``info["manual_frames"]`` says how many of the
    step's physics frames the human drove (0 .. ``steps_per_action``; a period may begin
    or end inside a step).

    ## Starting State

    The car stands still (``start_speed``, default 0) at ``start_s`` and ``start_d``
    (default 0, on the path; within ``+-road_half_width``), facing along the path, with
    ``dbw_enabled`` true unless a manual period starts at 0 s.

    No stop line may lie under the car (between the rear axle and the front bumper): it
    would be crossed for the metrics and ahead for the observation. A ``start_s`` that
    puts one there is a ``ConfigError`` naming the line and the valid positions. The
    default ``start_s`` is the track's start, moved back, if a line lies under the car or
    less than :data:`START_LINE_MARGIN_M` (2 m) ahead of its bumper, until the front bumper
    is 2 m behind that line (the car then waits at the line like a car stopped there).
    The built-in tracks need no move; the original site lot (``churchlot_with_cars.csv``,
    its one stop line 1.98 m from the first waypoint) starts at s = 60.76 m of its 64.63 m
    loop, the site car's bumper 2 m behind the line. :attr:`start_s` holds the result.

    Randomness: everything random (light phase offsets, random obstacles, the random
    manual-override schedule, the human driver, the camera's brightness, noise and
    distance jitter) comes from ``np_random``: at every reset one child generator per
    component is drawn from it, so the same seed and actions give the same episode bit
    for bit, and switching one component on or off (e.g. the camera) does not change the
    others.

    ## Episode End

    Terminated: leaving the road (``|d| > road_half_width``, reason ``"off_road"``),
    touching an obstacle (``"collision"``), or ``laps`` laps completed
    (``"laps_completed"``, ``is_success``). Truncated: ``max_duration`` simulated seconds
    (``"max_duration"``). Every step's ``info`` has the same keys; at the end ``summary``
    holds lap times, distance, incidents by kind (``red_light`` included), max
    acceleration and jerk, distance without incident, is_success, termination_reason,
    incident_log, red-light violations, stop-line crossings by light state, stops near
    stop lines with their overshoot, cross-track error (max, RMS), max lateral
    acceleration, and the time spent in manual override (see
    :mod:`sdc_gym.metrics.track_metrics`).

    ## Info

    The metrics' step values (time, distance, progress, laps, speed, acceleration, jerk,
    incident counts ``incidents_<kind>``) and telemetry: ``x``, ``y``, ``yaw``, ``s``,
    ``d``, ``cross_track_error`` (m, = d), ``speed_mph``, ``lateral_acceleration``
    (m/s^2), ``throttle``, ``brake_torque``, ``steering_wheel_angle`` (the actuators'
    actual values), ``dbw_enabled``, ``manual_frames`` (physics frames of this step the
    human drove), ``next_stop_line``, ``stop_line_distance`` (m, from the rear axle; as
    in the observation), ``next_stop_line_front`` and ``stop_line_distance_front`` (the
    next line the front bumper will cross and its distance from the bumper, m; -1 and the
    loop length without lines), ``light_state_ahead`` (the light of ``next_stop_line``,
    UNKNOWN without lights), ``new_incidents``, ``is_success``, ``termination_reason``,
    ``summary`` (None until the end).

    ## Rendering

    ``render_mode="rgb_array"`` or ``"human"``: a top-down view following the car
    (:mod:`sdc_gym.render.track_renderer`): road, stop lines, lights in their state,
    obstacles, the car, and the agent's final waypoints when it gives them.

    Final waypoints travel from the agent to the env, the opposite way to ``info`` (which
    Gymnasium hands from the env to the agent), so the agent gives them with
    ``env.unwrapped.set_debug_path(points)``: an (m, 2) array of map x, y in metres, the
    original's ``drawline`` message. Call it whenever the path changes (e.g. after each
    step); the render draws the latest points until they are replaced, cleared with
    ``None`` or an empty array, or cleared by ``reset``. The env never reads them.

    ## Arguments

    ``gym.make("sdc_gym/TrackLoop-v0", config={...}, render_mode=None)``; unknown keys
    raise ``ConfigError`` listing the valid ones. See :attr:`DEFAULT_CONFIG` for every key
    with its unit; nested: ``lights`` (``green_s``, ``yellow_s``, ``red_s``, ``offsets_s``,
    ``script``: see :class:`~sdc_gym.lights.traffic_lights.TrafficLights`; or per-light
    cycles with ``timings``: one ``[green_s, yellow_s, red_s]`` row per light, instead of
    the three shared durations), ``camera`` (``enabled``, ``preset`` "full" = the track's
    800 x 600 camera or "training" = 200 x 150, and
    :class:`~sdc_gym.sensors.track_camera.CameraConfig` fields, e.g. ``distance_jitter``;
    checked even when the camera is off), ``obstacles``, ``manual``, ``incident_rules``,
    ``reward_incident``.

    Keys that would be silently ignored are errors: ``manual.periods`` unless the mode is
    ``"scripted"``, ``manual.interval_s`` / ``duration_s`` unless it is ``"random"``,
    ``obstacles.max_offset_d`` unless obstacles are random (``count`` without
    ``positions``), ``lights`` durations together with ``timings``. Keys whose default is
    None are type-checked (``speed_limit`` and ``start_s`` numbers, ``light_config`` a
    path, ``vehicle`` a preset name), obstacle positions and ``start_d`` must lie on the
    road. All at construction.

    ## Version History

    * v0: initial version.
    """

    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = {
        "track": "default",           # built-in name ("default", "site") or waypoint CSV path
        "light_config": None,         # traffic-light YAML path (with a CSV track only)
        "vehicle": None,              # "sim" or "site"; None: "site" on a site track, else "sim"
        "vehicle_overrides": {},      # VehicleParameters fields, e.g. {"creep_hold_torque": 400.0}
        "steps_per_action": 1,        # physics frames (0.02 s) per env step: 1 = 50 Hz
        "laps": 1,                    # laps for success
        "max_duration": 1200.0,       # s of simulated time before truncation
        "speed_limit": None,          # m/s; None: the track's (40 km/h sim, 10 km/h site)
        "start_s": None,              # m along the path; None: the track's start (moved
                                      # back if a stop line would lie under the car)
        "start_d": 0.0,               # m, right of the path, within +-road_half_width
        "start_speed": 0.0,           # m/s, up to the car's top speed
        # Cycle (s), fixed offsets (s) or scripts per light; "timings": None (every light
        # cycles green_s, yellow_s, red_s) or one [green_s, yellow_s, red_s] row per light.
        "lights": {**LIGHTS_DEFAULTS, "timings": None},
        "observe_light_states": False,    # add the ground-truth light states to observations
        "camera": {"enabled": False, **CAMERA_DEFAULTS},  # pinhole camera image observation
        "obstacles": {
            "count": 0,               # random obstacles (seeded), used when positions is empty
            "positions": [],          # [[s, d], ...] m: obstacles at these Frenet positions
            "max_offset_d": 0.0,      # m: random obstacles' |d| is uniform up to this
            "length": OBSTACLE_LENGTH_M,  # m
            "width": OBSTACLE_WIDTH_M,    # m
        },
        "manual": {
            "mode": "off",            # "off", "random" (seeded) or "scripted" (periods)
            "periods": [],            # scripted: [[start_s, end_s], ...] s of episode time
            "interval_s": [60.0, 180.0],  # random: uniform time in DBW before each period
            "duration_s": [5.0, 20.0],    # random: uniform length of each manual period
        },
        "incident_rules": {
            "max_acceleration": 10.0,  # m/s^2, block total acceleration (shared rules)
            "max_jerk": 10.0,          # m/s^3, window jerk
            "road_half_width": None,   # m; None: the track's (6 m sim, 3 m site)
        },
        "reward_progress": 1.0,        # weight of normalised progress
        "reward_incident": {"collision": -10.0, "acceleration": -1.0, "jerk": -1.0,
                            "speed": -1.0, "lane": -1.0, "off_road": -10.0,
                            "red_light": -5.0},
        **RENDER_CONFIG_DEFAULTS,      # render_width, render_height (px), zoom
    }

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        owner = "TrackLoop-v0"
        self.config = resolve_config(self.DEFAULT_CONFIG, config, owner=owner)
        cfg = self.config
        self._init_render_mode(render_mode)
        self._given = dict(config or {})  # the user's own keys, to catch ignored ones
        check_track_config(cfg, owner)  # ranges, finiteness, sizes (sdc_gym.validation)
        self._check_optional_keys(owner)

        try:
            self.track: TrackMap = get_track_map(cfg["track"], cfg["light_config"])
        except TrackFormatError as error:
            raise ConfigError(f"{owner}: config key 'track': {error}") from None
        track = self.track
        self.params = self._vehicle_parameters(owner)
        self.speed_limit = float(cfg["speed_limit"] if cfg["speed_limit"] is not None
                                 else track.speed_limit_mps)
        self.top_speed = top_speed(self.params)
        require(cfg["start_speed"] <= self.top_speed, owner, "start_speed",
                f"in [0, {math.floor(100.0 * self.top_speed) / 100.0:.2f}] m/s (up to the "
                f"{self.params.name!r} car's top speed at full throttle)", cfg["start_speed"])
        rules = cfg["incident_rules"]
        half_width = rules["road_half_width"]
        require(half_width is None or (_is_number(half_width) and half_width > 0), owner,
                "incident_rules.road_half_width", "None or a number > 0 (m)", half_width)
        self.road_half_width = float(half_width if half_width is not None
                                     else track.road_half_width_m)
        require(abs(cfg["start_d"]) <= self.road_half_width, owner, "start_d",
                f"in [{-self.road_half_width:g}, {self.road_half_width:g}] m (on the road)",
                cfg["start_d"])
        try:
            self.rules = IncidentRules(
                dt=PHYSICS_DT, max_acceleration=float(rules["max_acceleration"]),
                max_jerk=float(rules["max_jerk"]), speed_limit=self.speed_limit,
                road_d_min=-self.road_half_width, road_d_max=self.road_half_width,
                straddle_bands=())
        except ValueError as error:
            raise ConfigError(f"{owner}: {error}") from None
        self.lights = self._traffic_lights(owner)
        require(set(cfg["reward_incident"]) == set(TRACK_INCIDENT_KINDS), owner,
                "reward_incident", f"a mapping with exactly the kinds {list(TRACK_INCIDENT_KINDS)}",
                cfg["reward_incident"])
        self._check_obstacles(owner)
        self._check_manual(owner)

        self.steps_per_action = int(cfg["steps_per_action"])
        self.front_offset = self.params.wheel_base + FRONT_OVERHANG_M
        self.car_length = self.params.wheel_base + FRONT_OVERHANG_M + REAR_OVERHANG_M
        self.car_width = CAR_WIDTH_M
        # Rear axle to the body's centre, along the heading.
        self._centre_offset = 0.5 * (self.params.wheel_base + FRONT_OVERHANG_M
                                     - REAR_OVERHANG_M)
        self.vehicle = DBWVehicle(self.params)
        self.metrics = TrackMetrics(track, self.rules, self.front_offset)
        self.start_s = self._start_s(owner)
        self._set_render_fps(PHYSICS_DT * self.steps_per_action)

        # The camera block is validated even when the camera is off (no silent typos).
        camera_config = self._camera_config(config, owner)
        self.camera: TrackCamera | None = None
        if cfg["camera"]["enabled"]:
            self.camera = TrackCamera(camera_config)

        # Action bounds: float32 values, validated against exactly what the Box holds.
        max_brake = self.params.max_brake_force * self.params.wheel_radius
        max_steer = self.params.steering_wheel_lock
        self.action_space = spaces.Box(
            low=np.array([0.0, 0.0, -max_steer], dtype=np.float32),
            high=np.array([1.0, max_brake, max_steer], dtype=np.float32), dtype=np.float32)
        self.max_brake_torque = float(self.action_space.high[1])
        self.max_steering_angle = float(self.action_space.high[2])

        big = np.float32(POSITION_BOUND_M)
        k = track.light_count
        # Speed can never leave [0, velocity_bound] (see _speed_bound); the yaw rate is the
        # speed times the curvature at full lock.
        self.velocity_bound = (1.0 + VELOCITY_BOUND_MARGIN) * _speed_bound(self.params)
        max_wheel = self.params.max_road_wheel_angle
        yaw_rate_bound = (self.velocity_bound * math.tan(max_wheel) / self.params.wheel_base
                          if max_wheel < 0.5 * math.pi else math.inf)
        observation: dict[str, spaces.Space[Any]] = {
            "pose": spaces.Box(np.array([-big, -big, -np.pi], dtype=np.float32),
                               np.array([big, big, np.pi], dtype=np.float32), dtype=np.float32),
            "velocity": spaces.Box(0.0, self.velocity_bound, shape=(1,), dtype=np.float32),
            "yaw_rate": spaces.Box(-yaw_rate_bound, yaw_rate_bound, shape=(1,),
                                   dtype=np.float32),
            "dbw_enabled": spaces.Discrete(2),
            "next_stop_line": spaces.Box(np.array([-1.0, 0.0], dtype=np.float32),
                                         np.array([max(k - 1, -1), track.length],
                                                  dtype=np.float32), dtype=np.float32),
        }
        if cfg["observe_light_states"]:
            observation["light_states"] = spaces.Box(0, UNKNOWN, shape=(k,), dtype=np.int8)
        if self.camera is not None:
            camera = self.camera.config
            observation["camera"] = spaces.Box(0, 255, shape=(camera.height, camera.width, 3),
                                               dtype=np.uint8)
        self.obstacle_count = self._configured_obstacle_count()
        if self.obstacle_count:
            observation["obstacles"] = spaces.Box(-big, big, shape=(self.obstacle_count, 2),
                                                  dtype=np.float32)
        self.observation_space = spaces.Dict(observation)

        self._incident_penalty = {kind: float(value)
                                  for kind, value in cfg["reward_incident"].items()}
        self._progress_scale = cfg["reward_progress"] / (
            self.speed_limit * PHYSICS_DT * self.steps_per_action)
        # Per-frame buffers handed to the metrics (filled in place, one row per frame).
        frames = self.steps_per_action
        self._xy_buffer = np.zeros((frames, 2))
        self._s_buffer = np.zeros(frames)
        self._d_buffer = np.zeros(frames)
        self._speed_buffer = np.zeros(frames)
        self._lateral_buffer = [0.0] * frames
        self._manual_buffer = [False] * frames  # which frames of the step the human drove
        self._step_manual_frames = 0
        self._states_buffer: list[NDArray[np.int8]] = [self.lights.states] * frames
        self._buffers: tuple[Any, ...] = (
            self._xy_buffer, self._s_buffer, self._d_buffer, self._speed_buffer,
            self._lateral_buffer, self._states_buffer if track.light_count else None)
        self._laps = int(cfg["laps"])
        # Truncation at the first whole frame at or after max_duration.
        self._max_frames = math.ceil(cfg["max_duration"] / PHYSICS_DT - 1e-6)
        self._debug_path: NDArray[np.float64] = np.zeros((0, 2))
        self._state_ready = False

    # ------------------------------------------------------------------ configuration
    def _check_optional_keys(self, owner: str) -> None:
        """Keys whose default is None take any type in resolve_config: check them here."""
        cfg = self.config
        require(cfg["speed_limit"] is None or (_is_number(cfg["speed_limit"])
                                               and cfg["speed_limit"] > 0),
                owner, "speed_limit", "None or a number > 0 (m/s)", cfg["speed_limit"])
        require(cfg["start_s"] is None or _is_number(cfg["start_s"]), owner, "start_s",
                "None or a finite number (m along the path)", cfg["start_s"])
        require(cfg["light_config"] is None or isinstance(cfg["light_config"], str | os.PathLike),
                owner, "light_config", "None or the path (str) of a traffic-light YAML",
                cfg["light_config"])
        require(cfg["vehicle"] is None or isinstance(cfg["vehicle"], str), owner, "vehicle",
                f"None or one of {sorted(VEHICLE_PRESETS)}", cfg["vehicle"])
        require(cfg["start_speed"] >= 0, owner, "start_speed", ">= 0 m/s", cfg["start_speed"])

    def _vehicle_parameters(self, owner: str) -> VehicleParameters:
        cfg = self.config
        name = cfg["vehicle"]
        if name is None:
            name = "site" if self.track.is_site else "sim"
        if name not in VEHICLE_PRESETS:
            raise ConfigError(f"{owner}: config key 'vehicle' must be None or one of "
                              f"{sorted(VEHICLE_PRESETS)}, got {name!r}")
        params = vehicle_parameters(name)
        overrides = dict(cfg["vehicle_overrides"])
        fields = [field for field in VehicleParameters.__dataclass_fields__ if field != "name"]
        unknown = sorted(set(overrides) - set(fields))
        if unknown:
            raise ConfigError(f"{owner}.vehicle_overrides: unknown key(s) {unknown}. "
                              f"Valid keys: {', '.join(fields)}")
        try:
            params = params.replace(**overrides) if overrides else params
        except (TypeError, ValueError) as error:
            raise ConfigError(f"{owner}.vehicle_overrides: {error}") from None
        if not _has_resistance(params):
            # Nothing would hold the speed: no observation bound, no sensible car.
            raise ConfigError(f"{owner}.vehicle_overrides: drag_coefficient, linear_drag "
                              f"and rolling_resistance are all 0, so the car's top speed is "
                              f"unbounded; make at least one of them > 0")
        return params

    def _traffic_lights(self, owner: str) -> TrafficLights:
        """The lights from the ``lights`` block: shared or per-light (``timings``) cycles."""
        lights = dict(self.config["lights"])
        timings = lights.pop("timings")
        key = f"{owner}.lights"
        try:
            if timings is None:
                return TrafficLights.from_config(self.track.light_count, lights, owner=key)
            count = self.track.light_count
            shared = sorted(set(LIGHT_PHASES) & set(self._given.get("lights") or {}))
            require(not shared, owner, "lights.timings",
                    f"given without {shared} (timings replaces them)", timings)
            ok = isinstance(timings, list | tuple) and len(timings) == count and all(
                isinstance(row, list | tuple) and len(row) == len(LIGHT_PHASES)
                and all(_is_number(value) for value in row) for row in timings)
            require(ok, owner, "lights.timings",
                    f"None or {count} [green_s, yellow_s, red_s] rows, one per light (s)",
                    timings)
            return TrafficLights(count, [LightTiming(*map(float, row)) for row in timings],
                                 lights["offsets_s"], lights["script"])
        except ConfigError:
            raise
        except ValueError as error:
            raise ConfigError(f"{key}: {error}") from None

    def _start_s(self, owner: str) -> float:
        """Where the rear axle starts: never with a stop line under the car.

        A stop line between the rear axle and the front bumper would already be crossed by
        the bumper (the metrics' view) but still ahead of the rear axle (the observation's):
        ``start_s`` given like that is a ConfigError; the default (the track's start) is
        moved back until the front bumper is :data:`START_LINE_MARGIN_M` behind such a line.
        """
        track, given = self.track, self.config["start_s"]
        reference = track.reference
        start = float(reference.wrap_s(given if given is not None else track.start_s))
        margin = 0.0 if given is not None else START_LINE_MARGIN_M
        for _ in range(track.light_count + 1):
            ahead = (track.stop_line_s - start) % track.length
            under = np.flatnonzero(ahead < self.front_offset + margin)
            if not len(under):
                return start
            line = int(under[np.argmax(ahead[under])])  # the farthest one under the car
            line_s = float(track.stop_line_s[line])
            behind = math.floor(100.0 * float(reference.wrap_s(line_s - self.front_offset)))
            behind /= 100.0
            require(given is None, owner, "start_s",
                    f"a position with no stop line under the car: stop line {line} at "
                    f"s = {line_s:.2f} m lies between the rear axle and the front bumper "
                    f"({self.front_offset:g} m ahead); use start_s <= {behind:.2f} or "
                    f"> {line_s:.6f} (mod the loop length {track.length:.6f} m)", given)
            start = float(reference.wrap_s(line_s - self.front_offset - margin))
        raise ConfigError(f"{owner}: the stop lines of track {track.name!r} leave no "
                          f"{self.front_offset + margin:g} m gap to start the car in")

    def _camera_config(self, config: Mapping[str, Any] | None, owner: str) -> CameraConfig:
        """The track's camera (size, focal lengths) in the preset, with the user's fields."""
        given = dict((config or {}).get("camera") or {})
        given.pop("enabled", None)
        preset = given.get("preset", CAMERA_DEFAULTS["preset"])
        if preset not in PRESETS:
            raise ConfigError(f"{owner}.camera: config key 'preset' must be one of "
                              f"{PRESETS}, got {preset!r}")
        scale = TRAINING_SCALE if preset == "training" else 1.0
        track = self.track
        from_track = {"width": round(track.image_width * scale),
                      "height": round(track.image_height * scale),
                      "fx": track.focal_length_x * scale, "fy": track.focal_length_y * scale}
        return CameraConfig.from_mapping({**from_track, **given}, owner=f"{owner}.camera")

    def _check_obstacles(self, owner: str) -> None:
        obstacles = self.config["obstacles"]
        key = "obstacles"
        count, positions = obstacles["count"], obstacles["positions"]
        require(count >= 0, owner, f"{key}.count", "an int >= 0", count)
        ok = all(isinstance(p, list | tuple) and len(p) == 2
                 and all(isinstance(v, int | float) and not isinstance(v, bool)
                         and math.isfinite(v) for v in p) for p in positions)
        require(ok, owner, f"{key}.positions", "a list of [s, d] pairs of finite numbers (m)",
                positions)
        require(not (positions and count and count != len(positions)), owner, f"{key}.count",
                f"0 or len(positions) = {len(positions)} when positions are given", count)
        half_width = self.road_half_width
        off_road = [p for p in positions if abs(p[1]) > half_width]
        require(not off_road, owner, f"{key}.positions",
                f"[s, d] pairs on the road, d in [{-half_width:g}, {half_width:g}] m "
                f"(these are not: {off_road})", positions)
        max_offset = obstacles["max_offset_d"]
        require(0 <= max_offset <= half_width, owner, f"{key}.max_offset_d",
                f"in [0, {half_width:g}] m (the road half width)", max_offset)
        require(max_offset == 0 or (count and not positions), owner, f"{key}.max_offset_d",
                "0 unless obstacles are random (count > 0 and no positions): it only "
                "spreads random obstacles", max_offset)
        for size in ("length", "width"):
            require(obstacles[size] > 0, owner, f"{key}.{size}", "> 0 m", obstacles[size])
        require(positions or not count or self.track.length > 2 * OBSTACLE_CLEARANCE_M, owner,
                f"{key}.count", f"0 on a track shorter than {2 * OBSTACLE_CLEARANCE_M} m", count)

    def _configured_obstacle_count(self) -> int:
        obstacles = self.config["obstacles"]
        return len(obstacles["positions"]) or int(obstacles["count"])

    def _check_manual(self, owner: str) -> None:
        manual = self.config["manual"]
        mode = manual["mode"]
        require(mode in MANUAL_MODES, owner, "manual.mode", f"one of {MANUAL_MODES}", mode)
        periods = manual["periods"]
        ok = all(isinstance(p, list | tuple) and len(p) == 2
                 and all(isinstance(v, int | float) and not isinstance(v, bool)
                         and math.isfinite(v) for v in p) and 0 <= p[0] < p[1] for p in periods)
        require(ok, owner, "manual.periods",
                "a list of [start_s, end_s] with 0 <= start_s < end_s", periods)
        ordered = all(later[0] >= earlier[1] for earlier, later in itertools.pairwise(periods))
        require(ordered, owner, "manual.periods", "sorted and not overlapping", periods)
        require(mode != "scripted" or bool(periods), owner, "manual.periods",
                "non-empty when manual.mode is 'scripted'", periods)
        require(mode == "scripted" or not periods, owner, "manual.periods",
                f"empty unless manual.mode is 'scripted' (it is {mode!r}, which would "
                f"ignore them)", periods)
        given = self._given.get("manual") or {}
        for key in ("interval_s", "duration_s"):
            pair = manual[key]
            good = (len(pair) == 2 and all(_is_number(v) for v in pair)
                    and 0 < pair[0] <= pair[1])
            require(good, owner, f"manual.{key}", "[low, high] s with 0 < low <= high", pair)
            require(mode == "random" or key not in given, owner, f"manual.{key}",
                    f"left out unless manual.mode is 'random' (it is {mode!r}, which would "
                    f"ignore it)", pair)

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        cfg = self.config
        track = self.track
        seeds = self.np_random.integers(0, _SEED_BOUND, size=len(_RNG_STREAMS))
        rngs = {name: np.random.default_rng(int(value))
                for name, value in zip(_RNG_STREAMS, seeds, strict=True)}
        self._camera_rng = rngs["camera"]

        start_s = self.start_s
        start_d = float(cfg["start_d"])
        x, y = track.reference.to_xy(start_s, start_d).tolist()
        yaw = float(track.reference.heading(start_s))
        self.state = self.vehicle.reset(x, y, yaw, float(cfg["start_speed"]))
        self._s, self._d = start_s, start_d
        self._frame = 0
        self.lights.reset(rngs["lights"])
        self.metrics.reset(x, y, start_s, start_d, float(cfg["start_speed"]))
        self._place_obstacles(rngs["obstacles"])
        self._manual_frames = self._manual_schedule(rngs["manual_schedule"])
        self._manual_index = 0
        self._manual_frame_count = 0
        self._step_manual_frames = 0
        self.driver = ManualDriver(self.params, rngs["manual_driver"])
        self.dbw_enabled = not self._manual_at(0)
        self._done_reason = ""
        self._debug_path = np.zeros((0, 2))
        self._state_ready = True
        self._update_stop_line()
        return self._observation(), self._info([], final=False)

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if not self._state_ready:
            raise RuntimeError("call reset() before step()")
        throttle, brake, steering = self._read_action(action)
        first_frame, s_start = self._frame, self._s
        frames = self._simulate(throttle, brake, steering)
        buffers = self._buffers
        if frames < self.steps_per_action:  # the episode ended inside the step
            buffers = tuple(None if buffer is None else buffer[:frames] for buffer in buffers)
        driving = self.metrics.driving
        progress_before = driving.progress
        incidents = self.metrics.record(*buffers, self._contact_ids(frames))
        self._update_stop_line()

        # The agent earns only what happened while it drove: the human's frames (manual
        # override) give no progress reward and no incident penalty.
        gained = (driving.progress - progress_before if not self._step_manual_frames
                  else self._agent_progress(s_start, frames))
        reward = self._progress_scale * gained
        manual = self._manual_buffer
        for incident in incidents:
            # Incident.step counts physics frames since reset, from 1.
            if not (self._step_manual_frames and manual[incident.step - first_frame - 1]):
                reward += self._incident_penalty[incident.kind]
        terminated = truncated = False
        if self._contact >= 0:
            terminated, self._done_reason = True, "collision"
        elif abs(self._d) > self.road_half_width:
            terminated, self._done_reason = True, "off_road"
        elif driving.laps_completed >= self._laps:
            terminated, self._done_reason = True, "laps_completed"
        elif self._frame >= self._max_frames:
            truncated, self._done_reason = True, "max_duration"
        if self.render_mode == "human":
            self.render()
        info = self._info(incidents, final=terminated or truncated)
        return self._observation(), float(reward), terminated, truncated, info

    # ------------------------------------------------------------------ actions
    def _read_action(self, action: Any) -> tuple[float, float, float]:
        """The action as three Python floats, or a ValueError naming the bad component."""
        if isinstance(action, np.ndarray) and action.shape == (3,) and action.dtype.kind == "f":
            values = action.tolist()
        else:
            values = real_array(action, (3,), "action", "[throttle, brake_torque, "
                                "steering_wheel_angle]").tolist()
        throttle, brake, steering = values
        # One chained test for the common case; NaN fails every comparison.
        max_steer = self.max_steering_angle
        if not (0.0 <= throttle <= 1.0 and 0.0 <= brake <= self.max_brake_torque
                and -max_steer <= steering <= max_steer):
            self._raise_bad_action(values)
        return throttle, brake, steering

    def _raise_bad_action(self, values: list[float]) -> None:
        ranges = (("throttle", 0.0, 1.0, ""),
                  ("brake_torque", 0.0, self.max_brake_torque, " N m"),
                  ("steering_wheel_angle", -self.max_steering_angle, self.max_steering_angle,
                   " rad"))
        for index, ((name, low, high, unit), value) in enumerate(zip(ranges, values,
                                                                     strict=True)):
            if not low <= value <= high:
                raise ValueError(f"action[{index}] {name} = {value!r} is outside its valid "
                                 f"range [{low:g}, {high:g}]{unit} (NaN is never valid)")

    # ------------------------------------------------------------------ physics
    def _simulate(self, throttle: float, brake: float, steering: float) -> int:
        """Run the step's physics frames; returns how many ran (fewer if the episode ended)."""
        vehicle, lights, track = self.vehicle, self.lights, self.track
        project = track.reference.project_few
        xy, s_buf, d_buf, v_buf = (self._xy_buffer, self._s_buffer, self._d_buffer,
                                   self._speed_buffer)
        lateral, states_buf = self._lateral_buffer, self._states_buffer
        half_width = self.road_half_width
        has_obstacles = bool(self._obstacles_xy)
        self._contact = -1
        self._step_manual_frames = 0
        s = self._s
        for frame in range(self.steps_per_action):
            if self._manual_frames:
                self._update_mode()
            if self.dbw_enabled:
                st = vehicle.step(throttle, brake, steering)
                manual = False
            else:
                self._step_manual_frames += 1
                st = vehicle.step(*self.driver.act(self.state, track.reference, self.speed_limit,
                                                   self._manual_stop_distance(s)))
                manual = True
            self._frame += 1
            states_buf[frame] = lights.step(PHYSICS_DT)
            (s,), (d,) = project([[st.x, st.y]], [s + st.speed * PHYSICS_DT])
            self._manual_buffer[frame] = manual
            xy[frame, 0] = st.x
            xy[frame, 1] = st.y
            s_buf[frame] = s
            d_buf[frame] = d
            v_buf[frame] = st.speed
            lateral[frame] = st.lateral_acceleration
            self._s, self._d = s, d
            if has_obstacles and self._touches_obstacle():
                break
            if abs(d) > half_width:
                break
        else:  # all frames ran (steps_per_action >= 1, so frame is the last index)
            if self._manual_frames:
                self._update_mode()  # the observation tells whether the next action counts
        self._manual_frame_count += self._step_manual_frames
        return frame + 1

    def _agent_progress(self, s_start: float, frames: int) -> float:
        """m gained along the path in the step's frames the agent drove (the metrics'
        wrapped-difference formula); exactly 0 when the human drove them all."""
        length = self.track.length
        half = 0.5 * length
        gained, s_before = 0.0, s_start
        for s, manual in zip(self._s_buffer[:frames].tolist(), self._manual_buffer[:frames],
                             strict=True):
            if not manual:
                gained += (s - s_before + half) % length - half
            s_before = s
        return gained

    def _update_mode(self) -> None:
        """dbw_enabled for the frame about to run; (re)start the driver on a take-over."""
        manual = self._manual_at(self._frame)
        if manual and self.dbw_enabled:
            self.driver.reset(self.state)
        self.dbw_enabled = not manual

    def _manual_at(self, frame: int) -> bool:
        """Whether the frame starting at ``frame`` is in a manual period (moves forward)."""
        periods = self._manual_frames
        while self._manual_index < len(periods) and frame >= periods[self._manual_index][1]:
            self._manual_index += 1
        return (self._manual_index < len(periods)
                and periods[self._manual_index][0] <= frame)

    def _manual_schedule(self, rng: np.random.Generator) -> list[tuple[int, int]]:
        """Manual periods of this episode as [start, end) physics frames."""
        manual = self.config["manual"]
        if manual["mode"] == "scripted":
            return [(_frames(start), _frames(end)) for start, end in manual["periods"]]
        if manual["mode"] == "off":
            return []
        periods = []
        time_s = float(rng.uniform(*manual["interval_s"]))
        while time_s < self.config["max_duration"]:
            end_s = time_s + float(rng.uniform(*manual["duration_s"]))
            periods.append((_frames(time_s), _frames(end_s)))
            time_s = end_s + float(rng.uniform(*manual["interval_s"]))
        return periods

    def _manual_stop_distance(self, s: float) -> float | None:
        """The human stops for the next line if its light is red or yellow (rear axle, m)."""
        line, distance = self.track.next_stop_line(s)
        if line >= 0 and self.lights.states[line] in (RED, YELLOW):
            return distance
        return None

    # ------------------------------------------------------------------ obstacles
    def _place_obstacles(self, rng: np.random.Generator) -> None:
        obstacles = self.config["obstacles"]
        reference = self.track.reference
        if obstacles["positions"]:
            sd = np.array(obstacles["positions"], dtype=np.float64).reshape(-1, 2)
        elif obstacles["count"]:
            count = int(obstacles["count"])
            length = self.track.length
            s = self._s + rng.uniform(OBSTACLE_CLEARANCE_M, length - OBSTACLE_CLEARANCE_M,
                                      count)
            d = rng.uniform(-1.0, 1.0, count) * obstacles["max_offset_d"]
            sd = np.column_stack([reference.wrap_s(s), d])
        else:
            sd = np.zeros((0, 2))
        xy = reference.to_xy(sd[:, 0], sd[:, 1]).reshape(-1, 2)
        self._obstacles_xy: list[tuple[float, float]] = [tuple(p) for p in xy.tolist()]
        self._obstacles_heading = reference.heading(sd[:, 0]).reshape(-1)
        self.obstacles_sd = sd
        self._obstacles_observation = xy.astype(np.float32)
        half = 0.5 * np.hypot(self.car_length, self.car_width)
        reach = half + 0.5 * math.hypot(obstacles["length"], obstacles["width"])
        self._obstacle_reach_sq = reach * reach

    def _touches_obstacle(self) -> bool:
        """Record (as ``_contact``) the first obstacle the car's body touches now, if any."""
        st = self.state
        cx = st.x + self._centre_offset * math.cos(st.yaw)
        cy = st.y + self._centre_offset * math.sin(st.yaw)
        obstacles = self.config["obstacles"]
        for index, (ox, oy) in enumerate(self._obstacles_xy):
            if (ox - cx) ** 2 + (oy - cy) ** 2 <= self._obstacle_reach_sq and bool(
                    boxes_overlap((cx, cy), st.yaw, self.car_length, self.car_width,
                                  (ox, oy), self._obstacles_heading[index],
                                  obstacles["length"], obstacles["width"])):
                self._contact = index
                return True
        return False

    def _contact_ids(self, frames: int) -> NDArray[np.int64] | None:
        """Per-frame obstacle contact for the metrics (only the last frame can touch)."""
        if self._contact < 0:
            return None
        ids = np.full(frames, -1, dtype=np.int64)
        ids[-1] = self._contact
        return ids

    # ------------------------------------------------------------------ observation, info
    def _update_stop_line(self) -> None:
        line, distance = self.track.next_stop_line(self._s)
        if line < 0:
            distance = self.track.length
        self._next_line, self._line_distance = line, distance

    def _observation(self) -> dict[str, Any]:
        st = self.state
        values = np.array((st.x, st.y, st.yaw, st.speed, st.yaw_rate, self._next_line,
                           self._line_distance), dtype=np.float32)
        observation: dict[str, Any] = {
            "pose": values[0:3],
            "velocity": values[3:4],
            "yaw_rate": values[4:5],
            "dbw_enabled": int(self.dbw_enabled),
            "next_stop_line": values[5:7],
        }
        if self.config["observe_light_states"]:
            observation["light_states"] = self.lights.states.copy()
        if self.camera is not None:
            observation["camera"] = self.camera.render(
                st.x, st.y, st.yaw, self.track.light_positions, self.track.light_yaw,
                self.lights.states, self._camera_rng)
        if self.obstacle_count:
            observation["obstacles"] = self._obstacles_observation.copy()
        return observation

    def _info(self, incidents: list[Incident], *, final: bool) -> dict[str, Any]:
        st = self.state
        info: dict[str, Any] = self.metrics.step_info()
        line = self._next_line
        front_line, front_distance = self.metrics.next_stop_line
        if front_line < 0:
            front_distance = self.track.length  # like stop_line_distance without lines
        success = self.metrics.driving.laps_completed >= self._laps
        info.update({
            "x": st.x,
            "y": st.y,
            "yaw": st.yaw,
            "s": self._s,
            "d": self._d,
            "speed_mph": st.speed * MPS_TO_MPH,
            "throttle": st.throttle,
            "brake_torque": st.brake_torque,
            "steering_wheel_angle": st.steering_wheel_angle,
            "dbw_enabled": self.dbw_enabled,
            "manual_frames": self._step_manual_frames,
            "next_stop_line": line,
            "stop_line_distance": self._line_distance,
            "next_stop_line_front": front_line,
            "stop_line_distance_front": front_distance,
            "light_state_ahead": int(self.lights.states[line]) if line >= 0 else UNKNOWN,
            "new_incidents": [incident.kind for incident in incidents],
            "is_success": success,
            "termination_reason": self._done_reason if final else "",
            "summary": self.summary() if final else None,
        })
        return info

    def summary(self) -> dict[str, Any]:
        """The episode's summary so far, as ``info["summary"]`` holds it at the end (an
        episode stopped from outside, e.g. by an evaluation, reads it here)."""
        summary = self.metrics.summary()
        summary["is_success"] = self.metrics.driving.laps_completed >= self._laps
        summary["termination_reason"] = self._done_reason
        summary["incident_log"] = [incident.as_dict()
                                   for incident in self.metrics.driving.incidents]
        summary["manual_time"] = self._manual_frame_count * PHYSICS_DT
        summary["obstacles"] = [list(p) for p in self._obstacles_xy]
        return summary

    # ------------------------------------------------------------------ debug path, rendering
    def set_debug_path(self, points: ArrayLike | None) -> None:
        """Points (m, 2) in map metres for the top-down render to draw, e.g. the agent's
        final waypoints (the original's ``drawline``); ``None`` or empty clears them.
        Cleared at every reset."""
        if points is None:
            self._debug_path = np.zeros((0, 2))
            return
        path = np.asarray(points, dtype=np.float64)
        if path.size == 0:
            self._debug_path = np.zeros((0, 2))
            return
        if path.ndim != 2 or path.shape[1] != 2 or not np.isfinite(path).all():
            raise ValueError(f"debug path must be finite (m, 2) x, y points, got shape "
                             f"{path.shape}")
        self._debug_path = path.copy()

    # ------------------------------------------------------------------ rendering
    def _make_renderer(self) -> TrackRenderer:
        from sdc_gym.render.track_renderer import TrackRenderer

        return TrackRenderer(
            self.track, road_half_width=self.road_half_width,
            **self._renderer_options())

    def _render_scene(self) -> TrackScene:
        if not hasattr(self, "state"):
            raise RuntimeError("call reset() before render()")
        from sdc_gym.render.track_renderer import TrackScene

        st = self.state
        obstacles = self.config["obstacles"]
        return TrackScene(
            car_xy=(st.x + self._centre_offset * math.cos(st.yaw),
                    st.y + self._centre_offset * math.sin(st.yaw)),
            car_heading=st.yaw, car_length=self.car_length, car_width=self.car_width,
            light_states=self.lights.states,
            obstacles_xy=np.array(self._obstacles_xy, dtype=np.float64).reshape(-1, 2),
            obstacles_heading=self._obstacles_heading, obstacle_length=obstacles["length"],
            obstacle_width=obstacles["width"], path_xy=self._debug_path,
            speed_mph=st.speed * MPS_TO_MPH, time_s=self._frame * PHYSICS_DT,
            laps=self.metrics.driving.laps_completed, distance_m=self.metrics.driving.distance,
            dbw_enabled=self.dbw_enabled, next_line=self._next_line,
            line_distance_m=self._line_distance,
            incidents={kind: count for kind, count in self.metrics.incident_counts.items()
                       if count},
            status=self._done_reason)
