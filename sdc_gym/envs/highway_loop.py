"""``sdc_gym/HighwayLoop-v0``: the Udacity highway path-planning simulator as a Gymnasium env."""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.perfect_controller import adopted_start, frames_of_motion
from sdc_gym.envs.top_down_env import RENDER_CONFIG_DEFAULTS, TopDownRenderEnv
from sdc_gym.geometry.collision import contact_reach_sq, first_contact
from sdc_gym.geometry.original_frenet import FRENET_CONVENTIONS
from sdc_gym.metrics import INCIDENT_KINDS, DrivingMetrics, Incident, IncidentRules
from sdc_gym.road.builtin_highways import get_highway_map
from sdc_gym.road.highway_map import HighwayMap, MapFormatError
from sdc_gym.sensors.highway_sensors import HighwaySensors, SensorConfig, TelemetryMessage
from sdc_gym.traffic import VEHICLE_TYPES, HighwayTraffic, IDMParameters, TrafficConfig
from sdc_gym.units import MPS_TO_MPH
from sdc_gym.validation.actions import real_array
from sdc_gym.validation.env_configs import check_highway_config, check_highway_start

if TYPE_CHECKING:
    from sdc_gym.render.highway_renderer import HighwayRenderer, HighwayScene

PHYSICS_DT = 0.02  # s: the original simulator's frame, one path point per frame
ACTION_MARGIN_M = 100.0  # path points may lie this far outside the map's bounding box
EGO_LENGTH_M = 4.7
EGO_WIDTH_M = 1.9


def _dataclass_defaults(cls: type, exclude: tuple[str, ...] = ()) -> dict[str, Any]:
    """A dataclass's fields and defaults as a plain config dict (nested dataclasses too)."""
    defaults: dict[str, Any] = {}
    for field in dataclasses.fields(cls):
        if field.name in exclude:
            continue
        if field.default is not dataclasses.MISSING:
            value = field.default
        elif field.default_factory is not dataclasses.MISSING:
            value = field.default_factory()
        else:
            continue
        if dataclasses.is_dataclass(value):
            value = dataclasses.asdict(value)
        defaults[field.name] = value
    return defaults


def _to_tuple(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


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
    away, cars, SUVs, trucks and motorcycles of their own sizes, and an optional rogue mode
    (sudden cut-ins, hard braking) for stress tests.

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
    ``perfect_controller`` rule, :mod:`sdc_gym.envs.perfect_controller`), so a planner
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
    | `sensor_fusion`       | (C, 7)          | id, x, y, vx, vy, s, d per traffic car     |
    | `sensor_fusion_mask`  | (C,) int8 0/1   | 1 where the row holds a sensed car         |

    N is ``path_points``, C the traffic ``car_count``.

    s is arc length along the exact reference line (0 at the first map waypoint, wrapping
    at the loop length); d is the offset to the right of the yellow centre line, so lane
    ``i`` is centred at ``d = 2 + 4 i``. The observation is always in this exact frame:
    the env's own agents (the FSM planner, the behavior envs' perception, the committed
    policies) read it, whatever the ``frenet`` setting.

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
    around it from the seed.

    ## Episode End

    Terminated: a collision when ``terminate_on_collision`` (default, for RL; set it False
    to count collisions and drive on, like the original and like ``evaluate.py`` does for
    external planners), or ``laps`` laps completed
    (``is_success``). Truncated: ``max_duration`` simulated seconds. The final ``info``
    carries ``summary`` (lap times, distance, incidents by kind, max acceleration and jerk,
    distance without incident, and ``incident_log``: each incident's kind, time, step,
    x, y, s, d and value), ``is_success`` and ``termination_reason``; every step's
    ``info`` has the same keys (``summary`` is ``None`` until the end).

    ## Arguments

    ``gym.make("sdc_gym/HighwayLoop-v0", config={...}, render_mode=None)``; unknown keys
    raise ``ConfigError`` listing the valid ones. See :attr:`DEFAULT_CONFIG` for every key
    with its unit.

    ## Version History

    * v0: initial version.
    """

    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = {
        "map": "default",            # built-in name ("default", "oval") or path to x y s dx dy
        "path_points": 50,           # capacity of the action path (points)
        "steps_per_action": 3,       # physics frames (0.02 s) per env step
        "latency_steps": None,       # frames before a path takes effect; None = steps_per_action
        "laps": 1,                   # laps for success
        "max_duration": 600.0,       # s of simulated time before truncation
        "terminate_on_collision": True,
        "start_s": None,             # m; None = the map's start (124.8336)
        "start_d": None,             # m; None = the map's start (middle lane)
        "ego_length": EGO_LENGTH_M,  # m
        "ego_width": EGO_WIDTH_M,    # m
        "traffic": _dataclass_defaults(TrafficConfig, exclude=("ego_length", "ego_width")),
        "sensors": _dataclass_defaults(SensorConfig),    # see SensorConfig
        "incident_rules": _dataclass_defaults(IncidentRules),  # see sdc_gym.metrics
        "reward_progress": 1.0,      # weight of normalised progress
        "reward_incident": {"collision": -10.0, "acceleration": -1.0, "jerk": -1.0,
                            "speed": -1.0, "lane": -1.0, "off_road": -1.0},
        "telemetry_info": True,      # info["telemetry"]: the original's message (built lazily)
        "frenet": "original",        # telemetry s/d: "original" (waypoint polyline) | "exact"
        **RENDER_CONFIG_DEFAULTS,      # render_width, render_height (px), zoom
    }

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        owner = "HighwayLoop-v0"
        self.config = resolve_config(self.DEFAULT_CONFIG, config, owner=owner)
        cfg = self.config
        self._init_render_mode(render_mode)
        check_highway_config(cfg, owner)  # ranges, finiteness, sizes (sdc_gym.validation)
        if cfg["latency_steps"] is None:
            cfg["latency_steps"] = cfg["steps_per_action"]
        require(cfg["frenet"] in FRENET_CONVENTIONS, owner, "frenet",
                f"one of {list(FRENET_CONVENTIONS)}", cfg["frenet"])

        try:
            self.road: HighwayMap = get_highway_map(cfg["map"])
        except MapFormatError as error:
            raise ConfigError(f"{owner}: config key 'map': {error}") from None
        check_highway_start(cfg, self.road.road_width, owner)
        traffic_cfg = dict(cfg["traffic"])
        traffic_cfg["idm"] = IDMParameters(**traffic_cfg["idm"])
        traffic_cfg.update(ego_length=cfg["ego_length"], ego_width=cfg["ego_width"])
        try:
            self.traffic_config = TrafficConfig(**{k: _to_tuple(v) for k, v in traffic_cfg.items()})
            self.sensor_config = SensorConfig(**{k: _to_tuple(v)
                                                 for k, v in cfg["sensors"].items()})
            self.rules = IncidentRules(**{k: _to_tuple(v)
                                          for k, v in cfg["incident_rules"].items()})
        except (TypeError, ValueError) as error:
            raise ConfigError(f"{owner}: {error}") from None
        require(set(cfg["reward_incident"]) == set(INCIDENT_KINDS), owner, "reward_incident",
                f"a mapping with exactly the kinds {list(INCIDENT_KINDS)}",
                cfg["reward_incident"])

        self.path_points = int(cfg["path_points"])
        self.steps_per_action = int(cfg["steps_per_action"])
        self.latency_steps = int(cfg["latency_steps"])
        self.ego_length = float(cfg["ego_length"])
        self.ego_width = float(cfg["ego_width"])
        self.traffic = HighwayTraffic(self.road, self.traffic_config, dt=PHYSICS_DT)
        self.car_count = self.traffic_config.car_count
        self.sensors = HighwaySensors(self.sensor_config, self.car_count, self.road.length)
        self.metrics = DrivingMetrics(self.rules, self.road.length)
        self._set_render_fps(PHYSICS_DT * self.steps_per_action)

        low_xy = self.road.waypoints[:, :2].min(axis=0) - ACTION_MARGIN_M
        high_xy = self.road.waypoints[:, :2].max(axis=0) + ACTION_MARGIN_M
        self._action_low = low_xy
        self._action_high = high_xy
        n = self.path_points
        self.action_space = spaces.Box(
            low=np.tile(low_xy, (n, 1)).astype(np.float32),
            high=np.tile(high_xy, (n, 1)).astype(np.float32), dtype=np.float32)
        big = np.float32(1e6)
        self.observation_space = spaces.Dict({
            "ego": spaces.Box(-big, big, shape=(6,), dtype=np.float32),
            "previous_path": spaces.Box(-big, big, shape=(n, 2), dtype=np.float32),
            "previous_path_count": spaces.Discrete(n + 1),
            "end_path": spaces.Box(-big, big, shape=(2,), dtype=np.float32),
            "sensor_fusion": spaces.Box(-big, big, shape=(self.car_count, 7), dtype=np.float32),
            # A 0/1 Box rather than MultiBinary, which cannot have size 0 (no traffic).
            "sensor_fusion_mask": spaces.Box(0, 1, shape=(self.car_count,), dtype=np.int8),
        })
        self._incident_penalty = {kind: float(value)
                                  for kind, value in cfg["reward_incident"].items()}
        self._progress_scale = cfg["reward_progress"] / (
            self.rules.speed_limit * PHYSICS_DT * self.steps_per_action)
        self._empty_path = np.zeros((0, 2))
        # Per-step constants: the path bounds tiled to the path's shape (same-shape
        # comparisons skip numpy's broadcasting set-up), and whether every sensed row is
        # present (then the telemetry takes the fusion rows without a masked copy).
        self._action_low_rows = np.tile(low_xy, (n, 1))
        self._action_high_rows = np.tile(high_xy, (n, 1))
        self._all_rows_present = self.sensor_config.dropout_probability == 0.0
        self._reach_sq: NDArray[np.float64] | None = None  # contact reach per traffic car ...
        self._reach_version = -1  # ... for this traffic.sizes_version
        # The telemetry's s/d convention (the Dict observation always has the exact ones).
        self._telemetry_frenet = (self.road.original_frenet if cfg["frenet"] == "original"
                                  else None)
        self._state_ready = False

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        road = self.road
        start_s = self.config["start_s"] if self.config["start_s"] is not None else road.start_s
        start_d = self.config["start_d"] if self.config["start_d"] is not None else road.start_d
        self._s = float(road.reference.wrap_s(start_s))
        self._d = float(start_d)
        self._xy = road.reference.to_xy(self._s, self._d).astype(np.float64)
        # The original's car faces +x at its start (yaw exactly 0 in the first telemetry)
        # until a path turns it; our own maps, and a start set in the config, face the road.
        at_map_start = self.config["start_s"] is None and self.config["start_d"] is None
        self._yaw = (road.start_heading() if at_map_start
                     else float(road.reference.heading(self._s)))
        self._speed = 0.0
        self._path = self._empty_path
        self._path_start = 0
        self._pending: deque[tuple[int, NDArray[np.float64]]] = deque()
        self._frame = 0
        self.traffic.reset(self.np_random, self._s, self._d)
        self.sensors.reset()
        self.metrics.reset(float(self._xy[0]), float(self._xy[1]), self._s, self._d, 0.0)
        self._collided = False
        self._end_sd = (0.0, 0.0)
        self._done_reason = ""
        self._state_ready = True
        self._read_sensors()
        return self._observation(), self._info([], final=False)

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if not self._state_ready:
            raise RuntimeError("call reset() before step()")
        path = self._validate_path(action)
        self._pending.append((self._frame + self.latency_steps, path))

        frames = self.steps_per_action
        xy, yaw, speed = self._drive_ego(frames)
        # The per-frame values go on as Python lists: projection, traffic and metrics work
        # on a few floats each, where lists beat numpy's fixed cost per call.
        points, speeds = xy.tolist(), speed.tolist()
        s, d = self._project(points, speeds)
        traffic = self.traffic
        samples = traffic.advance(frames, s, d, speeds)
        contact = first_contact(
            xy, yaw, self.ego_length, self.ego_width, samples.x, samples.y, samples.heading,
            traffic.length, traffic.width, traffic.ids, reach_sq=self._contact_reach())
        progress_before = self.metrics.progress
        incidents = self.metrics.record(points, s, d, speeds, contact)

        self._xy, self._yaw, self._speed = xy[-1], float(yaw[-1]), speeds[-1]
        self._s, self._d = s[-1], d[-1]
        self._read_sensors()

        reward = self._progress_scale * (self.metrics.progress - progress_before)
        for incident in incidents:
            reward += self._incident_penalty[incident.kind]
        terminated = truncated = False
        if any(incident.kind == "collision" for incident in incidents):
            self._collided = True
            if self.config["terminate_on_collision"]:
                terminated, self._done_reason = True, "collision"
        if not terminated and self.metrics.laps_completed >= self.config["laps"]:
            terminated, self._done_reason = True, "laps_completed"
        if not terminated and self.metrics.time >= self.config["max_duration"] - 1e-9:
            truncated, self._done_reason = True, "max_duration"
        if self.render_mode == "human":
            self.render()
        info = self._info(incidents, final=terminated or truncated)
        return self._observation(), float(reward), terminated, truncated, info

    # ------------------------------------------------------------------ ego motion
    def _validate_path(self, action: Any) -> NDArray[np.float64]:
        """The action as an (m, 2) float array of real points, or a clear ValueError."""
        points = real_array(action, None, "path", f"(x, y) map points, shape (m, 2) with "
                            f"m <= path_points = {self.path_points}")
        if points.size == 0:
            return self._empty_path
        if points.ndim != 2 or points.shape[1] != 2:
            raise ValueError(f"path must have shape (m, 2) with m <= {self.path_points}, "
                             f"got {points.shape}")
        if len(points) > self.path_points:
            raise ValueError(f"path has {len(points)} points; at most path_points = "
                             f"{self.path_points} (raise the 'path_points' config key)")
        # One test covers NaN, inf and out-of-bounds (NaN compares false); the message
        # is worked out only when it fails.
        count = len(points)
        inside = points >= self._action_low_rows[:count]
        inside &= points <= self._action_high_rows[:count]
        if np.count_nonzero(inside) < inside.size:  # not inside.all(), at a third of the cost
            self._raise_bad_point(points)
        # Trailing repeats of the last point are padding (see the class docstring).
        if count > 1 and (last_two := points[-2:].tolist())[0] == last_two[1]:
            differs = np.flatnonzero(np.any(points != points[-1], axis=1))
            points = points[: (int(differs[-1]) + 2 if len(differs) else 1)]
        return points

    def _raise_bad_point(self, points: NDArray[np.float64]) -> None:
        finite = np.isfinite(points).all(axis=1)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise ValueError(f"path point {bad} is not finite: {points[bad].tolist()} "
                             "(NaN/inf are not allowed; send fewer points or repeat the last)")
        outside = ((points < self._action_low) | (points > self._action_high)).any(axis=1)
        bad = int(np.flatnonzero(outside)[0])
        raise ValueError(
            f"path point {bad} {points[bad].tolist()} is outside the action bounds "
            f"x in [{self._action_low[0]:.1f}, {self._action_high[0]:.1f}], "
            f"y in [{self._action_low[1]:.1f}, {self._action_high[1]:.1f}]")

    def _project(self, points: list[list[float]],
                 speeds: list[float]) -> tuple[list[float], list[float]]:
        """Frenet s, d of the ego's frames (positions and speeds as lists); the path's end
        point rides in the same call."""
        frames = len(points)
        guesses = []
        guess = self._s
        for frame_speed in speeds:  # warm start: last s plus the distance driven
            guess += frame_speed * PHYSICS_DT
            guesses.append(guess)
        has_end = self._path_start < len(self._path)
        if has_end:
            end = self._path[-1].tolist()
            # The path's end lies about its straight-line distance ahead of the car.
            guesses.append(guess + math.hypot(end[0] - points[-1][0], end[1] - points[-1][1]))
            points = [*points, end]
        s, d = self.road.reference.project_few(points, guesses)
        self._end_sd = (s[frames], d[frames]) if has_end else (0.0, 0.0)
        return s[:frames], d[:frames]

    def _apply_path(self, path: NDArray[np.float64]) -> None:
        """Adopt a newly arrived path by the original's rule
        (:func:`~sdc_gym.envs.perfect_controller.adopted_start`): the points before the
        one nearest the car are dropped, and that one too unless it is the first point
        and not exactly under the car. A planner that resends the points the car consumed
        while its reply was on the way so never stalls the car."""
        if len(path) == 0:
            self._path, self._path_start = self._empty_path, 0
            return
        self._path, self._path_start = path, adopted_start(path, self._xy)

    def _drive_ego(self, frames: int) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                               NDArray[np.float64]]:
        """Move the ego ``frames`` physics frames along its path(s); arrays per frame."""
        # Row 0: where the car starts; row 1 + k: where frame k leaves it.
        track = np.empty((frames + 1, 2))
        track[0] = self._xy
        yaw = np.empty(frames)
        pending = self._pending
        done = 0
        while done < frames:
            if pending and pending[0][0] <= self._frame:
                self._apply_path(pending.popleft()[1])
            horizon = frames - done
            if pending:
                horizon = min(horizon, pending[0][0] - self._frame)
            path, first = self._path, self._path_start
            moves, discard_last = frames_of_motion(len(path) - first, horizon)
            if moves:
                stop = first + moves
                track[done + 1:done + 1 + moves] = path[first:stop]
                delta = path[first + 1:stop + 1] - path[first:stop]
                yaw[done:done + moves] = np.arctan2(delta[:, 1], delta[:, 0])
                self._path_start = stop
                self._xy = path[stop - 1]
                self._yaw = float(yaw[done + moves - 1])
            if discard_last:  # one point left: a frame removes it, the car stands still
                self._path_start = len(path)
            if moves < horizon:
                # Path exhausted: the car stands where it is (the original's stop dead).
                track[done + 1 + moves:done + 1 + horizon] = self._xy
                yaw[done + moves:done + horizon] = self._yaw
            done += horizon
            self._frame += horizon
        # A path due now arrives before the observation (the original's lock-step: the
        # reply is applied, then the next telemetry goes out).
        while pending and pending[0][0] <= self._frame:
            self._apply_path(pending.popleft()[1])
        step = track[1:] - track[:-1]
        speed = np.hypot(step[:, 0], step[:, 1])
        speed /= PHYSICS_DT
        return track[1:], yaw, speed

    # ------------------------------------------------------------------ observation, info
    def _read_sensors(self) -> None:
        """Sensor fusion of the traffic's current state (the last frame of the step)."""
        traffic = self.traffic
        self._fusion, self._fusion_mask = self.sensors.read(
            traffic.ids, traffic.x, traffic.y, traffic.vx, traffic.vy, traffic.s, traffic.d,
            self.np_random)

    def _contact_reach(self) -> NDArray[np.float64]:
        """The collision broad phase's reach per car, kept while the cars' sizes stay."""
        traffic = self.traffic
        if traffic.sizes_version != self._reach_version:
            self._reach_sq = contact_reach_sq(self.ego_length, self.ego_width, traffic.length,
                                              traffic.width)
            self._reach_version = traffic.sizes_version
        assert self._reach_sq is not None
        return self._reach_sq

    def _remaining_path(self) -> NDArray[np.float64]:
        return self._path[self._path_start:]

    def _observation(self) -> dict[str, Any]:
        remaining = self._remaining_path()
        count = len(remaining)
        previous = np.zeros((self.path_points, 2), dtype=np.float32)
        previous[:count] = remaining
        end_s, end_d = self._end_sd
        return {
            "ego": np.array([*self._xy.tolist(), self._s, self._d, self._yaw, self._speed],
                            dtype=np.float32),
            "previous_path": previous,
            "previous_path_count": count,
            "end_path": np.array([end_s, end_d], dtype=np.float32),
            "sensor_fusion": self._fusion.astype(np.float32),
            "sensor_fusion_mask": self._fusion_mask.astype(np.int8),
        }

    def _info(self, incidents: list[Incident], *, final: bool) -> dict[str, Any]:
        info: dict[str, Any] = self.metrics.step_info()  # a new dict every call
        lane = math.floor(self._d / self.road.lane_width)
        info["lane"] = min(max(lane, -1), self.road.lane_count)  # as HighwayMap.lane_of
        info["new_incidents"] = [incident.kind for incident in incidents]
        info["is_success"] = self.metrics.laps_completed >= self.config["laps"]
        info["termination_reason"] = self._done_reason if final else ""
        info["summary"] = self.summary() if final else None
        if self.config["telemetry_info"]:
            info["telemetry"] = TelemetryMessage(
                *self._xy.tolist(), self._yaw, self._speed, self._s, self._d,
                self._remaining_path(), *self._end_sd,
                self._fusion if self._all_rows_present else self._fusion[self._fusion_mask],
                self._telemetry_frenet)
        return info

    def summary(self) -> dict[str, Any]:
        """The episode's summary so far, as ``info["summary"]`` holds it at the end (an
        episode stopped from outside, e.g. by an evaluation, reads it here)."""
        summary = self.metrics.summary()
        summary["is_success"] = self.metrics.laps_completed >= self.config["laps"]
        summary["termination_reason"] = self._done_reason
        summary["collided"] = self._collided
        summary["incident_log"] = [incident.as_dict() for incident in self.metrics.incidents]
        return summary

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
        colors = np.array([vehicle.color for vehicle in VEHICLE_TYPES], dtype=np.uint8)
        counts = self.metrics.incident_counts
        return HighwayScene(
            ego_xy=(float(self._xy[0]), float(self._xy[1])), ego_heading=self._yaw,
            ego_length=self.ego_length, ego_width=self.ego_width,
            cars_xy=np.stack([traffic.x, traffic.y], axis=-1), cars_heading=traffic.heading,
            cars_length=traffic.length, cars_width=traffic.width,
            cars_color=colors[traffic.type_index], path_xy=self._remaining_path(),
            speed_mph=self._speed * MPS_TO_MPH, time_s=self.metrics.time,
            laps=self.metrics.laps_completed, distance_m=self.metrics.distance,
            incidents=dict(counts), status=self._done_reason)
