"""``sdc_gym/HighwayLoop-v0``: the Udacity highway path-planning simulator as a Gymnasium env."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.envs.highway_world import (
    ACTION_MARGIN_M,
    EGO_LENGTH_M,
    EGO_WIDTH_M,
    HIGHWAY_DEFAULTS,
    HighwayWorld,
    incident_kinds,
)
from sdc_gym.envs.top_down_env import TopDownRenderEnv
from sdc_gym.metrics import DrivingMetrics
from sdc_gym.scenarios.options import CONFIG, OPTION, check_reset_options, scenario_option
from sdc_gym.sensors.highway_sensors import TelemetryMessage
from sdc_gym.traffic import HighwayTraffic
from sdc_gym.traffic.state import PARKED
from sdc_gym.traffic.vehicle_types import TYPE_COLORS
from sdc_gym.units import MPS_TO_MPH
from sdc_gym.vehicle.path_follower import PHYSICS_DT

if TYPE_CHECKING:
    from sdc_gym.render.highway_renderer import HighwayRenderer, HighwayScene

__all__ = ["ACTION_MARGIN_M", "EGO_LENGTH_M", "EGO_WIDTH_M", "PHYSICS_DT",
           "HighwayLoopEnv", "highway_spaces"]


def highway_spaces(world: HighwayWorld) -> tuple[spaces.Box, spaces.Dict]:
    """The action and observation spaces of one env of ``world``."""
    n = world.path_points
    low_xy, high_xy = world.action_low, world.action_high
    action_space = spaces.Box(
        low=np.tile(low_xy, (n, 1)).astype(np.float32),
        high=np.tile(high_xy, (n, 1)).astype(np.float32), dtype=np.float32)
    big = np.float32(1e6)
    observation_space = spaces.Dict({
        "ego": spaces.Box(-big, big, shape=(6,), dtype=np.float32),
        "previous_path": spaces.Box(-big, big, shape=(n, 2), dtype=np.float32),
        "previous_path_count": spaces.Discrete(n + 1),
        "end_path": spaces.Box(-big, big, shape=(2,), dtype=np.float32),
        "sensor_fusion": spaces.Box(-big, big, shape=(world.slots, 7), dtype=np.float32),
        # A 0/1 Box rather than MultiBinary, which cannot have size 0 (no traffic).
        "sensor_fusion_mask": spaces.Box(0, 1, shape=(world.slots,), dtype=np.int8),
    })
    return action_space, observation_space


class HighwayLoopEnv(TopDownRenderEnv):
    """
    ## Description

    The highway of Udacity's path-planning project (Term 3 simulator), rebuilt for speed:
    a closed three-lane loop of about 6.9 km with traffic, where the agent is a *path
    planner*. Every 0.02 s physics frame the ego car is placed exactly on the next point of
    the path it was given and faces the point after (the original's "perfect controller"),
    so the spacing of the points is the speed. A path that runs out stops the car dead,
    which reads as an enormous acceleration. A planner written for the original therefore
    drives here unchanged: the observation carries the original's telemetry fields and
    ``info["telemetry"]`` the telemetry object the original would send, in the original's
    conventions (see "Telemetry" below).

    Traffic (12 cars by default) is simulated with numpy arrays: IDM car following, lane
    changes when the target lane is clear by +-20 m, desired speeds of 40-50 mph for cars
    spawned ahead of the ego and 50-60 mph behind it, recycling of cars more than 200 m
    away, cars, SUVs, trucks and motorcycles of their own sizes (buses, vans and
    semi-trailers through ``traffic.vehicle_mix``), and an optional rogue mode (sudden
    cut-ins, hard braking) for stress tests. Rare road events (a closed lane, fallen cargo,
    an animal crossing) come at seeded rates with ``road_events``; a scenario file
    (``scenario``, or ``reset(options={"scenario": ...})``) sets up a situation exactly,
    with scripted traffic and its own success condition (``docs/scenarios.md``).

    Driving is judged by the original's rules (see :mod:`sdc_gym.metrics`): acceleration
    over 0.2 s blocks (limit 10 m/s^2), jerk over 1 s (10 m/s^3), speed (50 mph), leaving
    the road, straddling a lane line for more than 3 s, and contact with another car.

    ## Action Space

    ``Box(low, high, shape=(path_points, 2), float32)``: the whole path as the original's
    planners send it, map (x, y) points in metres, usually the unconsumed previous points
    followed by new ones. ``low``/``high`` are the map's bounding box widened by 100 m.

    *Sending fewer than ``path_points`` points*: either pass an array of shape ``(m, 2)``
    with ``m <= path_points`` (a list of points works too), or pad a full array by
    repeating the last real point: trailing repeats of the final point are not part of the
    path (a car parked on its last point would stop dead there anyway, so the motion is the
    same). NaN and inf are never markers: a non-finite, non-numeric or out-of-bounds point
    raises ``ValueError`` naming the point. An empty path is allowed: the car stops dead.

    When a path arrives, points before the one nearest the car are dropped, and that one
    too unless it is the path's first point and not exactly under the car (the original's
    ``perfect_controller`` rule, :mod:`sdc_gym.vehicle.perfect_controller`), so a planner
    that resends its consumed points never stalls the car. A path's last point is never
    driven to: with one point left, the next frame removes it and the car stands still
    (the previous path is then empty, like the original's). A path takes effect
    ``latency_steps`` physics frames after ``step`` is called; until then the car keeps
    consuming the old path. With the default ``latency_steps = steps_per_action`` it
    arrives at the end of the step, just before the observation (the original's
    lock-step: telemetry, reply ``latency`` frames later, next telemetry).

    ## Observation Space

    ``Dict``, float32 arrays in SI units (the telemetry in ``info`` has the original's):

    | key                   | shape           | content                                    |
    |-----------------------|-----------------|--------------------------------------------|
    | `ego`                 | (6,)            | x, y, s, d (m), yaw (rad), speed (m/s)     |
    | `previous_path`       | (N, 2)          | unconsumed path points, zero padded        |
    | `previous_path_count` | Discrete(N + 1) | valid rows of `previous_path`              |
    | `end_path`            | (2,)            | s, d of the last unconsumed point, else 0  |
    | `sensor_fusion`       | (C + K, 7)      | id, x, y, vx, vy, s, d per traffic slot    |
    | `sensor_fusion_mask`  | (C + K,) int8   | 1 where the row holds a sensed car/object  |

    N is ``path_points``, C the traffic ``car_count``, K the road-object slots
    (``road_events.object_slots``, or what the config's ``scenario`` needs; 0 by default).
    Road objects (closed-lane barriers, fallen cargo, animals) are rows ``C..C+K-1`` with
    their own ids, zero velocity but an animal's; ``info["road_events"]`` (when K > 0)
    lists the events on the road with their kinds and the ids of their rows.

    s is arc length along the exact reference line (0 at the first map waypoint, wrapping
    at the loop length; on an open road it never wraps); d is the offset to the right of
    the yellow centre line, so lane ``i`` is centred at ``d = 2 + 4 i``. The observation
    is always in this exact frame: the env's own agents (the FSM planner, the behavior
    envs' perception, the committed policies) read it, whatever the ``frenet`` setting.

    ## Telemetry

    ``info["telemetry"]`` (with ``telemetry_info``, the default) is the flat object the
    original sends in ``42["telemetry",{...}]``, field for field: x, y (m), yaw (degrees,
    counter-clockwise from +x, in [0, 360)), speed (mph), s, d, previous_path_x/y (the
    unconsumed points), end_path_s/d (of the last unconsumed point; 0, 0 when there is
    none), sensor_fusion rows ``[id, x, y, vx, vy, s, d]`` with ids the fixed slots
    ``0..C-1``; every number a 32-bit float rounded to 7 significant digits. With
    ``frenet: original`` (the default) its s and d are the original's: along the waypoint
    polyline of the map file (``CarAIControl.getFrenetFrame``, wrapping at the file's loop
    length, 6945.554 m on the original map; end_path from the ego car's closest waypoint),
    see :mod:`sdc_gym.geometry.original_frenet`; ``frenet: exact`` sends the exact ones of
    the observation instead. On the original map the first message reads x 909.48,
    y 1128.67, yaw 0, speed 0, s 124.8337, d 6.164966: the original's start (s 124.8336,
    d 6.164833) within the 7-digit rounding of the map file's waypoints.

    ## Rewards

    ``progress * (metres gained along s) / (speed_limit * step duration)`` (about 1 per
    step at the 50 mph limit) plus, for each incident that began during the step, its
    configured penalty (``reward_incident``; collision -10, others -1 by default).

    ## Starting State

    The ego car stands still in the middle lane at s = 124.8 m (the original's start) with
    an empty path: on the original map at (909.48, 1128.67) facing +x (yaw 0) like the
    original's car, on the built-in maps (and at a ``start_s``/``start_d`` of the config)
    facing along the road. It keeps that heading until a path moves it. Traffic is placed
    around it from the seed. On an open road (a map whose ends do not meet, ``road``;
    ``docs/bosch.md``) it stands in the middle lane 5 m past the first waypoint, facing
    along the road, with every car on the road ahead of it or beside it.

    ## Episode End

    Terminated: a collision when ``terminate_on_collision`` (default, for RL; set it False
    to count collisions and drive on, like the original and like ``evaluate.py`` does for
    external planners), ``laps`` laps completed (``is_success``), or the first incident of
    a kind ``stop_at_incident`` lists (``True``: any; the reason ``stop_at_incident``).
    On an open road, no laps: ``distance_target`` m driven (reason ``distance_target``,
    ``is_success``) or the road's end (``road_end``; a success without a target), the
    frame's time in ``summary["goal"]``.
    Truncated: ``max_duration`` simulated seconds (a scenario's ``duration``, reason
    ``scenario_end``; its success conditions are ``is_success`` and ``summary["scenario"]``
    has the verdict and its reason). The final ``info``
    carries ``summary`` (lap times, distance, incidents by kind, max acceleration and jerk,
    distance without incident, and ``incident_log``: each incident's kind, time, step,
    x, y, s, d and value), ``is_success`` and ``termination_reason``; every step's
    ``info`` has the same keys (``summary`` is ``None`` until the end).

    ## Arguments

    ``gym.make("sdc_gym/HighwayLoop-v0", config={...}, render_mode=None)``; unknown keys
    raise ``ConfigError`` listing the valid ones. See :attr:`DEFAULT_CONFIG` for every key
    with its unit.

    * ``kernel_threads`` (default 1): threads of the heaviest batched kernels (the
      traffic's segments, poses and decisions, the heading's ``atan2``; and the behavior
      env's motion plan): an int in 1..``NUMBA_NUM_THREADS``, anything else a
      ``ConfigError`` naming the valid range. Above 1 each of them runs its
      ``prange`` over the envs of a batch on that many threads (workqueue layer unless
      ``NUMBA_THREADING_LAYER`` chooses; compiled at the first such step); the bits are
      the same as on one thread. It pays only with a core to spare (docs/batched.md, "Two
      kernel threads"); for a batch of one it is pointless.

    ## Vectorized

    ``gym.make_vec("sdc_gym/HighwayLoop-v0", num_envs=E,
    vectorization_mode="vector_entry_point")`` gives
    :class:`~sdc_gym.envs.highway_vector.HighwayLoopVectorEnv`: the same world for ``E``
    envs as one batch of arrays (:class:`~sdc_gym.envs.highway_world.HighwayWorld`, of
    which this env is the batch of one), env ``i`` exactly this env with the same seed.

    ## Version History

    * v0: initial version; later, without changing any default episode: scenarios, road
      events (``road_events``), buses, vans and semi-trailers (``traffic.vehicle_mix``)
      and ``stop_at_incident``; open roads (``road``, ``distance_target``).
    """

    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = HIGHWAY_DEFAULTS

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        self._attach(HighwayWorld(config, envs=1), render_mode)

    def _attach(self, world: HighwayWorld, render_mode: str | None) -> None:
        """This env as the shell of ``world`` (a batch of one; the behavior env's too)."""
        self.world = world
        self.config = world.config
        self._init_render_mode(render_mode)
        self.road = world.road
        self.path_points = world.path_points
        self.steps_per_action = world.steps_per_action
        self.latency_steps = world.latency_steps
        self.ego_length, self.ego_width = world.ego_length, world.ego_width
        self.car_count = world.car_count
        self.slots = world.slots
        self.traffic_config, self.sensor_config = world.traffic_config, world.sensor_config
        self.rules = world.rules
        self.traffic = HighwayTraffic.view(world.traffic, 0)
        self.metrics = DrivingMetrics.view(world.metrics, 0)
        self._set_render_fps(PHYSICS_DT * self.steps_per_action)
        self.action_space, self.observation_space = highway_spaces(world)
        self._path = np.zeros((1, self.path_points, 2))
        self._length = np.zeros(1, dtype=np.int64)
        self._state_ready = False
        self._scenario: Any = CONFIG  # the last reset option's, kept as a batch env's

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        check_reset_options(options, type(self).__name__, (OPTION,))
        super().reset(seed=seed)
        self._scenario = scenario_option(options, self._scenario)
        self.world.reset_at(0, self.np_random, self._scenario)
        self._state_ready = True
        return self.world.observation(0), self._info((), final=False)

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if not self._state_ready:
            raise RuntimeError("call reset() before step()")
        path = self.world.validate_path(action)
        self._path[0, :len(path)] = path
        self._length[0] = len(path)
        result = self.world.step(self._path, self._length)
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        if self.render_mode == "human":
            self.render()
        info = self._info(result.incidents[0], final=terminated or truncated)
        return (self.world.observation(0), float(result.reward[0]), terminated, truncated,
                info)

    # ------------------------------------------------------------------ state
    @property
    def _s(self) -> float:
        return float(self.world.s[0])

    def _remaining_path(self) -> NDArray[np.float64]:
        return self.world.ego.remaining(0)

    def _info(self, incidents: Any, *, final: bool) -> dict[str, Any]:
        world = self.world
        info: dict[str, Any] = world.metrics.step_info(0)  # a new dict every call
        info["lane"] = world.lane(0)
        info["new_incidents"] = incident_kinds(incidents)
        info["is_success"] = world.is_success(0)
        info["termination_reason"] = world.done_reason[0] if final else ""
        info["summary"] = world.summary(0) if final else None
        if self.config["telemetry_info"]:
            info["telemetry"] = TelemetryMessage(*world.telemetry_arguments(0))
        if world.traffic.object_slots:
            info["road_events"] = world.road_events(0)
        return info

    def scenario_snapshot(self) -> dict[str, Any]:
        """The env's state now as a scenario mapping (a replay starts from it exactly:
        :func:`sdc_gym.scenarios.replay.snapshot`)."""
        from sdc_gym.scenarios.replay import snapshot

        return snapshot(self.world, 0)

    def summary(self) -> dict[str, Any]:
        """The episode's summary so far, as ``info["summary"]`` holds it at the end (an
        episode stopped from outside, e.g. by an evaluation, reads it here)."""
        return self.world.summary(0)

    # ------------------------------------------------------------------ rendering
    def _make_renderer(self) -> HighwayRenderer:
        from sdc_gym.render import HighwayRenderer

        return HighwayRenderer(
            self.road, **self._renderer_options())

    def _render_scene(self) -> HighwayScene:
        if not self._state_ready:
            raise RuntimeError("call reset() before render()")
        from sdc_gym.render import HighwayScene

        traffic = self.traffic
        world = self.world
        counts = self.metrics.incident_counts
        xy = world.ego.xy[0]
        shown = world.traffic.state.role[0] != PARKED
        zones = [(event["s_start"], event["s_start"] + event["length"], event["lane"])
                 for event in world.road_events(0) if event["kind"] == "closed_lane"]
        return HighwayScene(
            ego_xy=(float(xy[0]), float(xy[1])), ego_heading=float(world.ego.yaw[0]),
            ego_length=self.ego_length, ego_width=self.ego_width,
            cars_xy=np.stack([traffic.x, traffic.y], axis=-1)[shown],
            cars_heading=traffic.heading[shown], cars_length=traffic.length[shown],
            cars_width=traffic.width[shown], cars_color=TYPE_COLORS[traffic.type_index[shown]],
            path_xy=self._remaining_path(),
            speed_mph=float(world.speed[0]) * MPS_TO_MPH, time_s=self.metrics.time,
            laps=self.metrics.laps_completed, distance_m=self.metrics.distance,
            incidents=dict(counts), status=world.done_reason[0], closed_lanes=zones)
