"""``sdc_gym/TrackLoop-v0``: the capstone track simulator, driven at the drive-by-wire level."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.envs.top_down_env import TopDownRenderEnv
from sdc_gym.envs.track_setup import TRACK_DEFAULTS, top_speed
from sdc_gym.envs.track_world import TrackWorld
from sdc_gym.metrics.track_metrics import TrackMetrics
from sdc_gym.scenarios.options import check_reset_options
from sdc_gym.units import MPS_TO_MPH
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT, VehicleState

if TYPE_CHECKING:
    from sdc_gym.render.track_renderer import TrackRenderer, TrackScene

__all__ = ["TrackLoopEnv", "top_speed"]

# The resolved configuration's values the env exposes (TrackSetup's attributes).
_SETUP_ATTRIBUTES = ("track", "params", "speed_limit", "top_speed", "road_half_width", "rules",
                     "lights", "steps_per_action", "front_offset", "car_length", "car_width",
                     "start_s", "camera", "max_brake_torque", "max_steering_angle",
                     "velocity_bound", "obstacle_count")


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

    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = TRACK_DEFAULTS

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        self._attach(TrackWorld(config, envs=1), render_mode)

    @classmethod
    def over(cls, world: TrackWorld, render_mode: str | None = None) -> TrackLoopEnv:
        """The ``TrackLoop-v0`` view of env 0 of an existing one-env world (e.g. the
        behavior env's): its attributes, ``summary()`` and ``render()``; the world's owner
        resets and steps it."""
        made = object.__new__(cls)
        made._attach(world, render_mode)
        made._state_ready = True
        return made

    def _attach(self, world: TrackWorld, render_mode: str | None) -> None:
        if world.envs != 1:
            raise ValueError(f"TrackLoopEnv is one env; the world has {world.envs}")
        self.world = world
        setup = world.setup
        self.config = setup.config
        self._init_render_mode(render_mode)
        for name in _SETUP_ATTRIBUTES:
            setattr(self, name, getattr(setup, name))
        self._set_render_fps(PHYSICS_DT * self.steps_per_action)
        self.action_space = setup.action_space
        self.observation_space = setup.observation_space
        self._active = np.ones(1, dtype=bool)
        self._debug_path: NDArray[np.float64] = np.zeros((0, 2))
        self._state_ready = False

    @property
    def state(self) -> VehicleState:
        """The car now (a snapshot)."""
        return self.world.vehicle_state(0)

    @property
    def dbw_enabled(self) -> bool:
        """Whether the next action is applied (False: a manual-override frame follows)."""
        return bool(self.world.state.dbw_enabled[0])

    @property
    def obstacles_sd(self) -> NDArray[np.float64]:
        """(n, 2) the episode's obstacles' Frenet positions, m."""
        return self.world.obstacles_sd[0]

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        check_reset_options(options, type(self).__name__, ())  # no scenarios on a track
        super().reset(seed=seed)
        self.world.reset_at(0, self.np_random)
        self._debug_path = np.zeros((0, 2))
        self._state_ready = True
        return self.world.observation(0), self.world.info(0, [], final=False)

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if not self._state_ready:
            raise RuntimeError("call reset() before step()")
        world = self.world
        world.state.command[0] = world.setup.read_action(action)
        rewards, incidents = world.step(self._active)
        new, reward = incidents[0], rewards[0]
        terminated = bool(world.state.terminated[0])
        truncated = bool(world.state.truncated[0])
        if self.render_mode == "human":
            self.render()
        info = world.info(0, new, final=terminated or truncated)
        return world.observation(0), float(reward), terminated, truncated, info

    def summary(self) -> dict[str, Any]:
        """The episode's summary so far, as ``info["summary"]`` holds it at the end (an
        episode stopped from outside, e.g. by an evaluation, reads it here)."""
        return self.world.summary(0)

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

    def _make_renderer(self) -> TrackRenderer:
        from sdc_gym.render.track_renderer import TrackRenderer

        return TrackRenderer(
            self.track, road_half_width=self.road_half_width,
            **self._renderer_options())

    def _render_scene(self) -> TrackScene:
        if not self.world.ready[0]:
            raise RuntimeError("call reset() before render()")
        from sdc_gym.render.track_renderer import TrackScene

        world, st = self.world, self.state
        offset = world.setup.centre_offset
        obstacles = self.config["obstacles"]
        metrics = world.metrics
        counts = metrics.driving.counts[0].tolist()
        return TrackScene(
            car_xy=(st.x + offset * math.cos(st.yaw), st.y + offset * math.sin(st.yaw)),
            car_heading=st.yaw, car_length=self.car_length, car_width=self.car_width,
            light_states=world.state.light_states[0],
            obstacles_xy=world.state.obstacles[0].reshape(-1, 2),
            obstacles_heading=world.obstacles_heading[0], obstacle_length=obstacles["length"],
            obstacle_width=obstacles["width"], path_xy=self._debug_path,
            speed_mph=st.speed * MPS_TO_MPH, time_s=int(world.state.frame[0]) * PHYSICS_DT,
            laps=int(metrics.driving.laps[0]), distance_m=float(metrics.driving.distance[0]),
            dbw_enabled=self.dbw_enabled, next_line=int(world.state.next_line[0]),
            line_distance_m=float(world.state.line_distance[0]),
            incidents={kind: count for kind, count in zip(metrics.driving.kinds, counts,
                                                          strict=True) if count},
            status=world.done_reason[0])

    @property
    def metrics(self) -> TrackMetrics:
        """The episode's metrics so far (read them; the env records)."""
        return TrackMetrics.view(self.world.metrics, 0)
