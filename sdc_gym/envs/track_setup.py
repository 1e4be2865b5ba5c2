"""The configuration of ``sdc_gym/TrackLoop-v0``: defaults, checks, and what follows from them.

:class:`TrackSetup` resolves a config once (the track, the car's parameters, the incident
rules, the traffic lights, the start, the camera, the spaces, the reward's constants);
:class:`~sdc_gym.envs.track_world.TrackWorld` runs any number of envs of it. The keys and
their units are :data:`TRACK_DEFAULTS` (``TrackLoopEnv.DEFAULT_CONFIG``); the env's
docstring (:class:`~sdc_gym.envs.track_loop.TrackLoopEnv`) documents them.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.top_down_env import RENDER_CONFIG_DEFAULTS
from sdc_gym.lights.traffic_lights import (
    LIGHTS_DEFAULTS,
    UNKNOWN,
    LightTiming,
    TrafficLights,
)
from sdc_gym.metrics.incidents import IncidentRules
from sdc_gym.metrics.track_metrics import TRACK_INCIDENT_KINDS
from sdc_gym.road.builtin_tracks import get_track_map
from sdc_gym.road.track_map import TrackFormatError, TrackMap
from sdc_gym.sensors.track_camera import (
    CAMERA_DEFAULTS,
    PRESETS,
    TRAINING_SCALE,
    CameraConfig,
    TrackCamera,
)
from sdc_gym.validation.actions import real_array
from sdc_gym.validation.env_configs import check_start_s, check_track_config
from sdc_gym.vehicle.dbw_vehicle import (
    PHYSICS_DT,
    VEHICLE_PRESETS,
    VehicleParameters,
    vehicle_parameters,
)

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
RNG_STREAMS = ("lights", "obstacles", "manual_schedule", "manual_driver", "camera")
SEED_BOUND = 2**63 - 1


def frames_of(seconds: float) -> int:
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



TRACK_DEFAULTS: dict[str, Any] = {
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


class TrackSetup:
    """A ``TrackLoop-v0`` config, resolved and checked once: the track, the car, the rules,
    the lights, the start, the camera, the spaces and the reward's constants. Every env of
    a batch shares it (each env's state lives in
    :class:`~sdc_gym.envs.track_world.TrackWorld`).

    Bad input is a :class:`~sdc_gym.config.ConfigError` naming the key, the value and the
    valid choices, raised here, at construction.
    """

    def __init__(self, config: Mapping[str, Any] | None, owner: str = "TrackLoop-v0") -> None:
        self.config = resolve_config(TRACK_DEFAULTS, config, owner=owner)
        cfg = self.config
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
        self.centre_offset = 0.5 * (self.params.wheel_base + FRONT_OVERHANG_M
                                    - REAR_OVERHANG_M)
        self.start_s = self._start_s(owner)

        # The camera block is validated even when the camera is off (no silent typos).
        self.camera_config = self._camera_config(config, owner)
        self.camera: TrackCamera | None = None
        if cfg["camera"]["enabled"]:
            self.camera = TrackCamera(self.camera_config)

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

        self.incident_penalty = {kind: float(value)
                                 for kind, value in cfg["reward_incident"].items()}
        self.progress_scale = cfg["reward_progress"] / (
            self.speed_limit * PHYSICS_DT * self.steps_per_action)
        self.laps = int(cfg["laps"])
        # Truncation at the first whole frame at or after max_duration.
        self.max_frames = math.ceil(cfg["max_duration"] / PHYSICS_DT - 1e-6)

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
        check_start_s(given, track.length, owner)
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


    # ------------------------------------------------------------------ per episode
    def manual_schedule(self, rng: np.random.Generator) -> list[tuple[int, int]]:
        """An episode's manual periods as [start, end) physics frames (random ones drawn
        from ``rng``)."""
        manual = self.config["manual"]
        if manual["mode"] == "scripted":
            return [(frames_of(start), frames_of(end)) for start, end in manual["periods"]]
        if manual["mode"] == "off":
            return []
        periods = []
        time_s = float(rng.uniform(*manual["interval_s"]))
        while time_s < self.config["max_duration"]:
            end_s = time_s + float(rng.uniform(*manual["duration_s"]))
            periods.append((frames_of(time_s), frames_of(end_s)))
            time_s = end_s + float(rng.uniform(*manual["interval_s"]))
        return periods

    # ------------------------------------------------------------------ actions
    def read_action(self, action: Any) -> tuple[float, float, float]:
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
            self.raise_bad_action(values)
        return throttle, brake, steering

    def raise_bad_action(self, values: list[float]) -> None:
        """The ValueError for an action outside the box, naming the first bad component."""
        ranges = (("throttle", 0.0, 1.0, ""),
                  ("brake_torque", 0.0, self.max_brake_torque, " N m"),
                  ("steering_wheel_angle", -self.max_steering_angle, self.max_steering_angle,
                   " rad"))
        for index, ((name, low, high, unit), value) in enumerate(zip(ranges, values,
                                                                     strict=True)):
            if not low <= value <= high:
                raise ValueError(f"action[{index}] {name} = {value!r} is outside its valid "
                                 f"range [{low:g}, {high:g}]{unit} (NaN is never valid)")
