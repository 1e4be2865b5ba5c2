"""The path-level highway of ``envs`` envs at once: config once, state as arrays, one step.

:class:`HighwayWorld` is the simulation behind ``sdc_gym/HighwayLoop-v0`` (the batch of
one) and its vector env: every layer is a kernel over a leading env axis, the ego's
perfect controller (:class:`~sdc_gym.vehicle.path_follower.PathFollower`), its exact
projection on the reference line, the traffic
(:class:`~sdc_gym.traffic.batch.TrafficBatch`), contact
(:func:`~sdc_gym.geometry.collision.first_contacts`), the metrics
(:class:`~sdc_gym.metrics.batch.DrivingMetricsBatch`) and the sensors. Envs are reset one
at a time (:meth:`HighwayWorld.reset_at`, each from its own generator) and stepped
together (:meth:`HighwayWorld.step`); env ``i`` of a batch is exactly a single env with
the same generator and paths, frame for frame.

An env may run a scenario (config ``scenario``, or one per reset: :meth:`reset_at`'s
``scenario``; :mod:`sdc_gym.scenarios`): its start instead of the random layout, its
script at the traffic's decision instants, its duration and its verdict as the episode's
success. Road events (config ``road_events``, or a scenario's) put road objects into
object slots after the cars' (:mod:`sdc_gym.traffic.road_events`): the sensor fusion has
a row for every slot (parked ones masked out), and ``info["road_events"]`` lists the
events on the road. ``world.episodes`` (:mod:`sdc_gym.scenarios.world_episodes`) keeps
all of it per env.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.road_ends import RoadGoal
from sdc_gym.envs.top_down_env import RENDER_CONFIG_DEFAULTS
from sdc_gym.geometry.collision import first_contacts
from sdc_gym.geometry.exact_math import py_hypot
from sdc_gym.geometry.original_frenet import FRENET_CONVENTIONS
from sdc_gym.kernel_threads import KernelThreads
from sdc_gym.metrics import INCIDENT_KINDS, Incident, IncidentRules
from sdc_gym.metrics.batch import DrivingMetricsBatch
from sdc_gym.road.builtin_highways import get_highway_map
from sdc_gym.road.highway_map import ROAD_KINDS, HighwayMap, MapFormatError
from sdc_gym.scenarios.world_episodes import CONFIG, EpisodeSettings
from sdc_gym.sensors.highway_sensors import HighwaySensors, SensorConfig
from sdc_gym.traffic import IDMParameters, TrafficConfig
from sdc_gym.traffic.batch import TrafficBatch
from sdc_gym.traffic.placement import RENYI_PARKING, reset_capacity
from sdc_gym.traffic.road_events import RoadEventRates
from sdc_gym.traffic.state import PARKED
from sdc_gym.validation.actions import real_array
from sdc_gym.validation.bounds import check_batch_sizes, check_env_count
from sdc_gym.validation.env_configs import check_highway_config, check_highway_start
from sdc_gym.vehicle.path_follower import PHYSICS_DT, PathFollower

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

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


HIGHWAY_DEFAULTS: dict[str, Any] = {
    "map": "default",            # built-in name ("default", "oval") or path to x y s dx dy
    "road": "auto",              # "auto" (loop or open road by its ends), "loop", "open"
    "path_points": 50,           # capacity of the action path (points)
    "steps_per_action": 3,       # physics frames (0.02 s) per env step
    "latency_steps": None,       # frames before a path takes effect; None = steps_per_action
    "laps": 1,                   # laps for success (a loop)
    "distance_target": None,     # m past the start for success on an open road; None: its end
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
    "scenario": None,            # scenario file path or mapping (docs/scenarios.md); None:
                                 # random traffic (reset options may give one per episode)
    "stop_at_incident": None,    # end the episode at the first incident: True (any kind),
                                 # or a list of kinds; None / False: drive on
    "road_events": _dataclass_defaults(RoadEventRates),  # object slots, random event rates
    "kernel_threads": 1,         # threads of the heaviest batched kernels (1..NUMBA_NUM_THREADS)
    **RENDER_CONFIG_DEFAULTS,      # render_width, render_height (px), zoom
}
"""``HighwayLoop-v0``'s config keys with their defaults (units in the comments)."""


@dataclass
class StepResult:
    """What one :meth:`HighwayWorld.step` did, per env: rewards, flags, the incidents that
    began (an empty tuple for most envs), and whether an incident of each env was a
    collision."""

    reward: FloatArray
    terminated: NDArray[np.bool_]
    truncated: NDArray[np.bool_]
    incidents: list[Any]


@njit(cache=True)
def path_lengths(paths: np.ndarray, lengths: np.ndarray, low: np.ndarray, high: np.ndarray,
                 out: np.ndarray) -> int:
    """Each path's length without trailing repeats of its last point (at least 1 of a
    path of repeats) into ``out``; the first env with a point outside ``[low, high]``
    or not finite (NaN compares false), or -1."""
    for e in range(paths.shape[0]):
        count = lengths[e]
        for k in range(count):
            x, y = paths[e, k, 0], paths[e, k, 1]
            if not (low[0] <= x <= high[0] and low[1] <= y <= high[1]):
                return e
        out[e] = count
        if count > 1 and paths[e, count - 2, 0] == paths[e, count - 1, 0] and \
                paths[e, count - 2, 1] == paths[e, count - 1, 1]:
            last = -1  # the last point that differs from the last one
            for k in range(count):
                if paths[e, k, 0] != paths[e, count - 1, 0] or \
                        paths[e, k, 1] != paths[e, count - 1, 1]:
                    last = k
            out[e] = last + 2 if last >= 0 else 1
    return -1


@njit(cache=True)
def ego_points(xy: np.ndarray, speed: np.ndarray, s_before: np.ndarray, path: np.ndarray,
               path_start: np.ndarray, path_length: np.ndarray, dt: float,
               points: np.ndarray, guesses: np.ndarray, has_end: np.ndarray) -> None:
    """The points to project per env (its frames, then its path's end, or the last frame
    again when the path is used up) and their guessed s: the last s plus the distance
    driven, the end its straight-line distance (CPython's ``math.hypot``) further on."""
    envs, frames = speed.shape
    for e in range(envs):
        guess = s_before[e]
        for f in range(frames):
            guess += speed[e, f] * dt
            guesses[e, f] = guess
            points[e, f, 0], points[e, f, 1] = xy[e, f, 0], xy[e, f, 1]
        has_end[e] = path_start[e] < path_length[e]
        last = max(path_length[e] - 1, 0)
        end_x = path[e, last, 0] if has_end[e] else xy[e, frames - 1, 0]
        end_y = path[e, last, 1] if has_end[e] else xy[e, frames - 1, 1]
        points[e, frames, 0], points[e, frames, 1] = end_x, end_y
        guesses[e, frames] = guess + py_hypot(end_x - xy[e, frames - 1, 0],
                                              end_y - xy[e, frames - 1, 1])


class HighwayWorld:
    """``envs`` highway loops driven by paths (see the module docstring).

    Args:
        config: ``HighwayLoop-v0`` config overrides (checked; see :data:`HIGHWAY_DEFAULTS`).
        envs: number of envs.
        owner: name for error messages.
        batch_names: the env and the key of ``steps_per_action`` in the batch bounds'
            messages (the behavior env's ``decision_frames``); None: ``owner``'s.
    """

    def __init__(self, config: dict[str, Any] | None = None, envs: int = 1,
                 owner: str = "HighwayLoop-v0",
                 batch_names: tuple[str, str] | None = None) -> None:
        self.config = cfg = resolve_config(HIGHWAY_DEFAULTS, config, owner=owner)
        envs = check_env_count(envs, f"{owner}: num_envs")
        check_highway_config(cfg, owner)  # ranges, finiteness, sizes (sdc_gym.validation)
        if cfg["latency_steps"] is None:
            cfg["latency_steps"] = cfg["steps_per_action"]
        require(cfg["frenet"] in FRENET_CONVENTIONS, owner, "frenet",
                f"one of {list(FRENET_CONVENTIONS)}", cfg["frenet"])
        self.envs = envs
        require(cfg["road"] in ROAD_KINDS, owner, "road", f"one of {list(ROAD_KINDS)}",
                cfg["road"])
        try:
            self.road: HighwayMap = get_highway_map(cfg["map"], cfg["road"])
        except MapFormatError as error:
            raise ConfigError(f"{owner}: config key 'map': {error}") from None
        check_highway_start(cfg, self.road.road_width, owner, self.road.reference.length)
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
        self.car_count = self.traffic_config.car_count
        # The batch's products (num_envs x each size), before its first per-env array.
        batch_owner, frames_key = batch_names or (owner, "steps_per_action")
        check_batch_sizes(batch_owner, envs, frames_per_step=self.steps_per_action,
                          path_points=self.path_points, cars=self.car_count,
                          frames_key=frames_key, cars_key="traffic.car_count")
        self.episodes = EpisodeSettings(cfg, owner, self.road, self.car_count, envs, _to_tuple)
        # The heaviest kernels' threads (sdc_gym.kernel_threads: the same bits on any).
        self.kernel_threads = KernelThreads(cfg["kernel_threads"])
        self.traffic = TrafficBatch(self.road, self.traffic_config, envs=envs, dt=PHYSICS_DT,
                                    object_slots=self.episodes.object_slots,
                                    kernel_threads=self.kernel_threads)
        capacity = reset_capacity(self.traffic)
        # A config's scenario places its own cars (checked against the road and each
        # other); the bound is for the cars placed at random around the ego.
        scenario = self.episodes.scenario
        random_cars = self.car_count - (len(scenario.cars) if scenario is not None else 0)
        if random_cars > capacity:
            raise ConfigError(
                f"{owner}: config key 'traffic.car_count' must be at most {capacity} on this "
                f"road ({self.road.lane_count} lanes, cars placed within +-"
                f"{self.traffic.range - 10.0:.0f} m of the ego: spawn_range, capped at 0.45 x "
                f"the {self.road.length:,.0f} m loop; a random layout fills "
                f"{RENYI_PARKING:.0%} of it), got {self.car_count}; lower car_count or raise "
                "spawn_range, or lower spawn_min_gap")
        self.slots = self.traffic.slots  # sensor-fusion rows: cars, then road objects
        self.sensors = HighwaySensors(self.sensor_config, self.slots, self.road.length,
                                      envs)
        self.metrics = DrivingMetricsBatch(self.rules, self.road.length, envs)
        self.ego = PathFollower(envs, self.path_points, self.steps_per_action,
                                self.latency_steps)
        low_xy = self.road.waypoints[:, :2].min(axis=0) - ACTION_MARGIN_M
        high_xy = self.road.waypoints[:, :2].max(axis=0) + ACTION_MARGIN_M
        self.action_low, self.action_high = low_xy, high_xy
        self.incident_penalty = {kind: float(value)
                                 for kind, value in cfg["reward_incident"].items()}
        self.progress_scale = cfg["reward_progress"] / (
            self.rules.speed_limit * PHYSICS_DT * self.steps_per_action)
        self.start_s = float(self.road.reference.wrap_s(
            cfg["start_s"] if cfg["start_s"] is not None else self.road.start_s))
        self.start_d = float(cfg["start_d"] if cfg["start_d"] is not None else self.road.start_d)
        self.goal = RoadGoal(self.road, self.start_s, cfg["distance_target"], envs, owner)
        self.start_xy = self.road.reference.to_xy(self.start_s, self.start_d).astype(np.float64)
        # The original's car faces +x at its start (yaw exactly 0 in the first telemetry)
        # until a path turns it; our own maps, and a start set in the config, face the road.
        at_map_start = cfg["start_s"] is None and cfg["start_d"] is None
        self.start_yaw = (self.road.start_heading() if at_map_start
                          else float(self.road.reference.heading(self.start_s)))
        # The telemetry's s/d convention (the Dict observation always has the exact ones).
        self.telemetry_frenet = (self.road.original_frenet if cfg["frenet"] == "original"
                                 else None)
        # Per-env state beyond the layers': Frenet pose, the path end's s, d, the latest
        # sensor fusion, the episode's end.
        self.s = np.zeros(envs)
        self.d = np.zeros(envs)
        self.speed = np.zeros(envs)
        self.end_sd = np.zeros((envs, 2))
        self.fusion = np.zeros((envs, self.slots, 7))
        self.fusion_mask = np.ones((envs, self.slots), dtype=bool)
        self.collided = np.zeros(envs, dtype=bool)
        self.done_reason = [""] * envs
        self.rngs: list[np.random.Generator | None] = [None] * envs
        self._all_reset = False
        self._all_rows_present = self.sensor_config.dropout_probability == 0.0

    # ------------------------------------------------------------------ episodes
    def reset_at(self, env: int, rng: np.random.Generator, scenario: Any = CONFIG) -> None:
        """Start env ``env``'s episode; all its randomness comes from ``rng``.

        ``scenario``: the config's (the default), ``None`` (random traffic), or a scenario
        (a file path, a mapping or a :class:`~sdc_gym.scenarios.model.Scenario`).
        """
        self.goal.reset_at(env, self.start_xy)
        if self.episodes.reset(self, env, rng, scenario):
            return
        self.rngs[env] = rng
        self.ego.reset_at(env, self.start_xy, self.start_yaw)
        self.s[env], self.d[env], self.speed[env] = self.start_s, self.start_d, 0.0
        self.end_sd[env] = 0.0
        self.traffic.reset_at(env, rng, self.start_s, self.start_d)
        self.episodes.random_started(self, env, rng)
        self.sensors.reset_at(env)
        self.metrics.reset_at(env, float(self.start_xy[0]), float(self.start_xy[1]),
                              self.start_s, self.start_d, 0.0)
        self.collided[env] = False
        self.done_reason[env] = ""
        self.read_sensors(np.array([env]))

    # ------------------------------------------------------------------ paths
    def validate_path(self, action: Any) -> FloatArray:
        """One env's action as an ``(m, 2)`` float array of real points (trailing repeats
        of the last point dropped), or a clear ``ValueError``."""
        points = real_array(action, None, "path", f"(x, y) map points, shape (m, 2) with "
                            f"m <= path_points = {self.path_points}")
        if points.ndim != 2 or points.shape[1] != 2:  # the empty path too: shape (0, 2)
            raise ValueError(f"path must have shape (m, 2) with m <= {self.path_points}, "
                             f"got {points.shape}")
        if len(points) > self.path_points:
            raise ValueError(f"path has {len(points)} points; at most path_points = "
                             f"{self.path_points} (raise the 'path_points' config key)")
        if len(points) == 0:
            return np.zeros((0, 2))
        count = len(points)
        lengths = np.array([count])
        if not points.flags.c_contiguous:
            points = np.ascontiguousarray(points)
        length = self.check_paths(points[None], lengths)
        return points[: int(length[0])]

    def check_paths(self, paths: FloatArray, lengths: IntArray) -> IntArray:
        """Check ``(envs, points, 2)`` paths (their first ``lengths`` points); the
        lengths without trailing repeats of the last point (padding: a car parked on its
        last point would stop dead there anyway). A non-finite or out-of-bounds point
        raises ``ValueError`` naming it."""
        trimmed = np.empty(len(lengths), dtype=np.int64)
        bad = path_lengths(paths, lengths, self.action_low, self.action_high, trimmed)
        if bad >= 0:
            self._raise_bad_point(paths[bad, :lengths[bad]], bad if self.envs > 1 else None)
        return trimmed

    def _raise_bad_point(self, points: FloatArray, env: int | None) -> None:
        where = "" if env is None else f"env {env}: "
        finite = np.isfinite(points).all(axis=1)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise ValueError(f"{where}path point {bad} is not finite: {points[bad].tolist()} "
                             "(NaN/inf are not allowed; send fewer points or repeat the last)")
        outside = ((points < self.action_low) | (points > self.action_high)).any(axis=1)
        bad = int(np.flatnonzero(outside)[0])
        raise ValueError(
            f"{where}path point {bad} {points[bad].tolist()} is outside the action bounds "
            f"x in [{self.action_low[0]:.1f}, {self.action_high[0]:.1f}], "
            f"y in [{self.action_low[1]:.1f}, {self.action_high[1]:.1f}]")

    # ------------------------------------------------------------------ stepping
    def step(self, paths: FloatArray, lengths: IntArray) -> StepResult:
        """Every env sends its path (checked by :meth:`check_paths`) and the world runs
        ``steps_per_action`` physics frames."""
        if not self._all_reset:
            if any(rng is None for rng in self.rngs):
                raise RuntimeError("call reset() before step()")
            self._all_reset = True
        self.ego.send(paths, lengths)
        frames = self.steps_per_action
        xy, yaw, speed = self.ego.drive()
        s, d = self._project(xy, speed)
        samples = self.traffic.advance(frames, s, d, speed)
        st = self.traffic.state
        contact = first_contacts(xy, yaw, self.ego_length, self.ego_width, samples.x,
                                 samples.y, samples.heading, st.length, st.width, st.ids)
        metrics = self.metrics
        progress_before = metrics.progress.copy()
        incidents = metrics.record(xy, s, d, speed, contact)
        # Copies, not strided views: the kernels take C-contiguous arrays (one signature).
        self.s, self.d, self.speed = s[:, -1].copy(), d[:, -1].copy(), speed[:, -1].copy()
        self.read_sensors()

        reward = self.progress_scale * (metrics.progress - progress_before)
        collision = np.zeros(self.envs, dtype=bool)
        for env in [env for env, new in enumerate(incidents) if new]:
            for incident in incidents[env]:
                reward[env] += self.incident_penalty[incident.kind]
                if incident.kind == "collision":
                    collision[env] = True
        self.collided |= collision
        stopped = self.episodes.record(self, incidents, self.d)
        terminated = collision & self.config["terminate_on_collision"]
        if self.goal.active:  # an open road: its goal, not laps
            lapped = ~terminated & self.goal.record(xy, s, metrics.steps, self.rules.dt)
        else:
            lapped = ~terminated & (metrics.laps >= self.config["laps"])
        terminated = terminated | lapped | stopped
        truncated = ~terminated & (metrics.steps * self.rules.dt
                                   >= self.episodes.max_duration - 1e-9)
        for env in np.flatnonzero(terminated | truncated).tolist():
            self.done_reason[env] = ("collision" if collision[env] and not lapped[env]
                                     and self.config["terminate_on_collision"]
                                     else (self.goal.reason(env) if self.goal.active
                                           else "laps_completed") if lapped[env]
                                     else self.episodes.reason(env) or "max_duration")
        return StepResult(reward, terminated, truncated, incidents)

    def _project(self, xy: FloatArray, speed: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Frenet s, d ``(envs, frames)`` of the ego's frames; the path's end point rides
        in the same projection (into :attr:`end_sd`)."""
        envs, frames = speed.shape
        points = np.empty((envs, frames + 1, 2))
        guesses = np.empty((envs, frames + 1))
        has_end = np.empty(envs, dtype=np.bool_)
        ego_points(xy, speed, self.s, self.ego.path, self.ego.path_start,
                   self.ego.path_length, PHYSICS_DT, points, guesses, has_end)
        s, d = self.road.reference.project(points[..., 0], points[..., 1], guesses)
        self.end_sd = np.where(has_end[:, None], np.stack([s[:, -1], d[:, -1]], axis=1), 0.0)
        return np.ascontiguousarray(s[:, :-1]), np.ascontiguousarray(d[:, :-1])

    def read_sensors(self, rows: IntArray | None = None) -> None:
        """Sensor fusion of the traffic's current state (the last frame of the step)."""
        st = self.traffic.state
        if rows is None:
            self.fusion, mask = self.sensors.read(st.ids, st.x, st.y, st.vx, st.vy, st.s,
                                                  st.d, self.rngs)  # type: ignore[arg-type]
            if self.traffic.scripted:
                self.fusion, mask = _hide_parked(self.fusion, mask, st.role)
            self.fusion_mask = mask
            return
        fusion, mask = self.sensors.read(st.ids[rows], st.x[rows], st.y[rows], st.vx[rows],
                                         st.vy[rows], st.s[rows], st.d[rows],
                                         [self.rngs[e] for e in rows.tolist()])  # type: ignore[misc]
        if self.traffic.scripted:
            fusion, mask = _hide_parked(fusion, mask, st.role[rows])
        self.fusion = self.fusion.copy()
        self.fusion[rows] = fusion
        self.fusion_mask = self.fusion_mask.copy()
        self.fusion_mask[rows] = mask

    # ------------------------------------------------------------------ observations
    def ego_array(self) -> FloatArray:
        """``(envs, 6)``: x, y, s, d (m), yaw (rad), speed (m/s)."""
        return np.column_stack([self.ego.xy, self.s, self.d, self.ego.yaw, self.speed])

    def observation(self, env: int) -> dict[str, Any]:
        """Env ``env``'s ``HighwayLoop-v0`` observation."""
        remaining = self.ego.remaining(env)
        count = len(remaining)
        previous = np.zeros((self.path_points, 2), dtype=np.float32)
        previous[:count] = remaining
        return {
            "ego": np.array([*self.ego.xy[env].tolist(), self.s[env], self.d[env],
                             self.ego.yaw[env], self.speed[env]], dtype=np.float32),
            "previous_path": previous,
            "previous_path_count": count,
            "end_path": self.end_sd[env].astype(np.float32),
            "sensor_fusion": self.fusion[env].astype(np.float32),
            "sensor_fusion_mask": self.fusion_mask[env].astype(np.int8),
        }

    def observations(self) -> dict[str, NDArray]:
        """Every env's observation as batched arrays (the vector env's)."""
        follower = self.ego
        steps = np.arange(self.path_points)[None, :]
        count = follower.path_length - follower.path_start
        index = np.minimum(follower.path_start[:, None] + steps, self.path_points - 1)
        previous = follower.path[np.arange(self.envs)[:, None], index]
        previous[steps >= count[:, None]] = 0.0
        return {
            "ego": self.ego_array().astype(np.float32),
            "previous_path": previous.astype(np.float32),
            "previous_path_count": count.astype(np.int64),
            "end_path": self.end_sd.astype(np.float32),
            "sensor_fusion": self.fusion.astype(np.float32),
            "sensor_fusion_mask": self.fusion_mask.astype(np.int8),
        }

    def lane(self, env: int) -> int:
        lane = math.floor(self.d[env] / self.road.lane_width)
        return min(max(lane, -1), self.road.lane_count)  # as HighwayMap.lane_of

    def is_success(self, env: int) -> bool:
        verdict = self.episodes.is_success(self, env)  # a scenario's own conditions
        if verdict is not None:
            return verdict
        if self.goal.active:
            return bool(self.goal.reached[env])
        return bool(self.metrics.laps[env] >= self.config["laps"])

    def summary(self, env: int) -> dict[str, Any]:
        """Env ``env``'s episode summary so far (``info["summary"]`` at the end)."""
        summary = self.metrics.summary(env)
        summary["is_success"] = self.is_success(env)
        summary["termination_reason"] = self.done_reason[env]
        summary["collided"] = bool(self.collided[env])
        if self.goal.active:
            summary["goal"] = self.goal.summary(env)
        summary["incident_log"] = [incident.as_dict()
                                   for incident in self.metrics.incidents[env]]
        scenario = self.episodes.summary(self, env)
        if scenario is not None:
            summary["scenario"] = scenario
        return summary

    def road_events(self, env: int) -> list[dict[str, Any]]:
        """The road events on env ``env``'s road (``info["road_events"]``)."""
        return self.episodes.road_events(self, env)

    def telemetry_arguments(self, env: int) -> tuple[Any, ...]:
        """Arguments of :func:`~sdc_gym.sensors.highway_sensors.telemetry_message` for
        env ``env`` (arrays copied: the message is built lazily)."""
        fusion = self.fusion[env]
        every_row = self._all_rows_present and not self.traffic.scripted
        rows = fusion.copy() if every_row else fusion[self.fusion_mask[env]]
        return (*self.ego.xy[env].tolist(), float(self.ego.yaw[env]), float(self.speed[env]),
                float(self.s[env]), float(self.d[env]), self.ego.remaining(env).copy(),
                *self.end_sd[env].tolist(), rows, self.telemetry_frenet)


def _hide_parked(fusion: FloatArray, mask: NDArray[np.bool_], role: IntArray
                 ) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Parked slots (free object slots, car slots a scenario leaves empty) are not sensed:
    their rows zero, their mask 0."""
    parked = role == PARKED
    if not np.count_nonzero(parked):
        return fusion, mask
    fusion = fusion.copy()
    fusion[parked] = 0.0
    return fusion, mask & ~parked


def incident_kinds(incidents: tuple[Incident, ...] | list[Incident]) -> list[str]:
    return [incident.kind for incident in incidents]
