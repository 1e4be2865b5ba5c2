"""The rules of each env's config, applied right after :func:`sdc_gym.config.resolve_config`.

One table per env (key path -> :mod:`~sdc_gym.validation.rules` rule), plus the checks
that depend on other keys or on the loaded road: a step no longer than the episode
(``steps_per_action x 0.02 s <= max_duration``), a start on the road. The sizes that
memory and time bound are :mod:`~sdc_gym.validation.bounds`; every error states its bound.
NaN and infinity are refused in every number of a config (a key whose rule allows
infinity says so), which covers reward weights, shield and vehicle parameters alike.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

from sdc_gym.config import ConfigError
from sdc_gym.kernel_threads import check_kernel_threads
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.validation.bounds import (
    MAX_CAR_COUNT,
    MAX_DECISION_PERIOD_S,
    MAX_DURATION_S,
    MAX_LAPS,
    MAX_OBSTACLES,
    MAX_PATH_POINTS,
    MAX_RENDER_PX,
    MAX_STEP_FRAMES,
)
from sdc_gym.validation.rules import Number, Pair, Rule, check_rules, check_value

PHYSICS_DT: Final = 0.02  # s: both loops' physics frame

POSITIVE = Number(0.0, low_open=True)
NON_NEGATIVE = Number(0.0)
PROBABILITY = Number(0.0, 1.0)
FINITE = Number()

class VehicleMix:
    """``traffic.vehicle_mix``: ``None``, one weight >= 0 per vehicle kind, or a mapping of
    kind names to weights (the kinds it leaves out weigh 0); not all 0."""

    def problem(self, value: Any) -> str | None:
        from sdc_gym.traffic.vehicle_types import VEHICLE_NAMES

        expectation = (f"None, a list of {len(VEHICLE_NAMES)} weights >= 0 (one per kind "
                       f"{list(VEHICLE_NAMES)}) or a mapping of kind names to weights, "
                       "not all 0")
        if value is None:
            return None
        if isinstance(value, Mapping):
            weights = list(value.values())
            if set(value) - set(VEHICLE_NAMES):
                return expectation
        elif isinstance(value, list | tuple):
            weights = list(value)
            if len(weights) != len(VEHICLE_NAMES):
                return expectation
        else:
            return expectation
        if any(NON_NEGATIVE.problem(w) for w in weights) or not sum(weights) > 0:
            return expectation
        return None


class StopKinds:
    """``stop_at_incident``: ``None``/``False`` (drive on), ``True`` (any kind) or a list
    of incident kinds."""

    def problem(self, value: Any) -> str | None:
        if value is None or isinstance(value, bool):
            return None
        if isinstance(value, list | tuple) and value and all(
                isinstance(kind, str) and kind in INCIDENT_KINDS for kind in value):
            return None
        return f"None, true, false or a non-empty list of incident kinds of {list(INCIDENT_KINDS)}"


RENDER_RULES: Final[dict[str, Rule]] = {
    "render_width": Number(1, MAX_RENDER_PX, integer=True, unit="px"),
    "render_height": Number(1, MAX_RENDER_PX, integer=True, unit="px"),
    "render_pixels_per_meter": Number(0.0, 1000.0, low_open=True, unit="px per m"),
}

HIGHWAY_RULES: Final[dict[str, Rule]] = {
    "path_points": Number(2, MAX_PATH_POINTS, integer=True, unit="points",
                          why="every step carries (path_points, 2) arrays"),
    "laps": Number(1, MAX_LAPS, integer=True),
    "distance_target": Number(0.0, 100_000.0, low_open=True, optional=True,
                              unit="m past the start on an open road"),
    "max_duration": Number(0.0, MAX_DURATION_S, low_open=True, unit="s"),
    "start_s": Number(optional=True, unit="m along the road"),
    "start_d": Number(optional=True, unit="m right of the centre line"),
    "ego_length": Number(0.5, 30.0, unit="m"),
    "ego_width": Number(0.5, 5.0, unit="m"),
    "traffic.car_count": Number(0, MAX_CAR_COUNT, integer=True, unit="cars",
                                why="traffic, sensing and collision cost grows with each car"),
    "traffic.density": Number(0.0, 100.0, low_open=True),
    "traffic.spawn_range": Number(20.0, 10_000.0, low_open=True, unit="m"),
    "traffic.respawn_ahead": Pair(Number(0.0, 10_000.0, unit="m"), strict=True),
    "traffic.respawn_behind": Pair(Number(0.0, 10_000.0, unit="m"), strict=True),
    "traffic.respawn_ahead_probability": PROBABILITY,
    "traffic.respawn_per_decision": Number(1, MAX_CAR_COUNT, integer=True),
    "traffic.spawn_min_gap": Number(0.0, 1000.0, unit="m"),
    "traffic.lane_change_clearance": Number(0.0, 1000.0, unit="m"),
    "traffic.lane_change_sustain": Number(0.0, 3600.0, unit="s"),
    "traffic.lane_change_duration": Number(0.0, 60.0, low_open=True, unit="s"),
    "traffic.lane_change_min_gain": Number(-100.0, 100.0, unit="m/s^2"),
    "traffic.lane_change_max_braking_imposed": Number(0.0, allow_inf=True, unit="m/s^2"),
    "traffic.lane_change_min_speed": Number(0.0, 100.0, unit="m/s"),
    "traffic.lateral_wander": Number(0.0, 1.0, unit="m, within a quarter of a lane"),
    "traffic.wander_period": Pair(Number(0.0, 3600.0, low_open=True, unit="s")),
    "traffic.rogue_rate": Number(0.0, 600.0, unit="events per car per minute"),
    "traffic.rogue_brake_decel": Number(0.0, 50.0, low_open=True, unit="m/s^2"),
    "traffic.rogue_brake_duration": Number(0.0, 60.0, low_open=True, unit="s"),
    "traffic.rogue_cut_in_gap": Number(0.0, 1000.0, unit="m"),
    "traffic.rogue_cut_in_duration": Number(0.0, 60.0, low_open=True, unit="s"),
    "traffic.rogue_cut_in_window": Number(0.0, 3600.0, unit="s"),
    "traffic.decision_period": Number(1, 1000, integer=True, unit="physics frames"),
    "traffic.speed_ahead_mph": Pair(Number(0.0, 200.0, unit="mph")),
    "traffic.speed_behind_mph": Pair(Number(0.0, 200.0, unit="mph")),
    "traffic.vehicle_mix": VehicleMix(),
    "traffic.idm.a_max": Number(0.0, 50.0, low_open=True, unit="m/s^2"),
    "traffic.idm.b": Number(0.0, 50.0, low_open=True, unit="m/s^2"),
    "traffic.idm.T": Number(0.0, 60.0, unit="s"),
    "traffic.idm.s0": Number(0.0, 1000.0, unit="m"),
    "traffic.idm.delta": Number(0.0, 100.0, low_open=True),
    "traffic.idm.max_braking": Number(0.0, 100.0, low_open=True, unit="m/s^2"),
    "sensors.position_noise": Number(0.0, 1000.0, unit="m"),
    "sensors.velocity_noise": Number(0.0, 1000.0, unit="m/s"),
    "sensors.dropout_probability": PROBABILITY,
    "sensors.zero_sd_probability": PROBABILITY,
    "sensors.zero_sd_zone": Number(0.0, 100_000.0, unit="m"),
    "sensors.zero_sd_frames": Pair(Number(1, 1_000_000, integer=True, unit="frames")),
    "incident_rules.dt": Number(0.0, 1.0, low_open=True, unit="s"),
    "incident_rules.block_steps": Number(1, 10_000, integer=True),
    "incident_rules.jerk_blocks": Number(1, 10_000, integer=True),
    "incident_rules.max_acceleration": Number(0.0, low_open=True, allow_inf=True,
                                              unit="m/s^2"),
    "incident_rules.max_jerk": Number(0.0, low_open=True, allow_inf=True, unit="m/s^3"),
    "incident_rules.speed_limit": Number(0.0, low_open=True, allow_inf=True, unit="m/s"),
    "incident_rules.max_straddle_steps": Number(0, 10**9, integer=True),
    "reward_progress": FINITE,
    "stop_at_incident": StopKinds(),
    "road_events.object_slots": Number(0, MAX_CAR_COUNT, integer=True, unit="slots",
                                       why="each is a sensor-fusion row and a traffic slot"),
    "road_events.closed_lane_per_km": Number(0.0, 100.0, unit="events per km driven"),
    "road_events.cargo_per_km": Number(0.0, 100.0, unit="events per km driven"),
    "road_events.animal_per_km": Number(0.0, 100.0, unit="events per km driven"),
    "road_events.spawn_ahead": Pair(Number(0.0, 10_000.0, unit="m ahead of the ego")),
    "road_events.clear_behind": Number(0.0, 10_000.0, unit="m behind the ego"),
    "road_events.closed_lane_length": Pair(Number(8.0, 5_000.0, unit="m")),
    "road_events.animal_speed": Pair(Number(0.0, 20.0, low_open=True, unit="m/s")),
    **RENDER_RULES,
}


def stop_kinds(value: Any) -> frozenset[str]:
    """The incident kinds ``stop_at_incident`` stops at (checked already): all of them for
    ``True``, none for ``None`` or ``False``."""
    if value is True:
        return frozenset(INCIDENT_KINDS)
    if not value:
        return frozenset()
    return frozenset(value)


def check_road_event_slots(config: Mapping[str, Any], owner: str) -> None:
    """Random road events need somewhere to go: rates above 0 with no object slots are an
    error (not silently no events)."""
    events = config["road_events"]
    rates = {key: events[key] for key in ("closed_lane_per_km", "cargo_per_km",
                                          "animal_per_km") if events[key]}
    if rates and events["object_slots"] == 0:
        raise ConfigError(f"{owner}: config key 'road_events.object_slots' must be >= 1 "
                          f"for random road events ({rates}): a closed lane takes one slot "
                          "per 8 m of closure, cargo and animals one each; got 0")


def step_frames_rule(max_duration: Any, key: str = "steps_per_action") -> Number:
    """``steps_per_action`` (or a behavior env's frames per decision): at least 1 frame,
    at most the episode (``max_duration / 0.02 s``) and :data:`MAX_STEP_FRAMES`."""
    episode = (math.ceil(max_duration / PHYSICS_DT - 1e-9)
               if isinstance(max_duration, int | float) and math.isfinite(max_duration)
               and max_duration > 0 else MAX_STEP_FRAMES)
    high = max(1, min(episode, MAX_STEP_FRAMES))
    return Number(1, high, integer=True, unit="physics frames of 0.02 s",
                  why=f"a step lasts at most the episode's max_duration ({max_duration!r} s) "
                      f"and at most {MAX_STEP_FRAMES} frames (its per-frame arrays and its "
                      "time in one call)")


def check_highway_config(config: Mapping[str, Any], owner: str) -> None:
    """The highway env's rules (table, step bound, latency), before anything is built."""
    check_rules(HIGHWAY_RULES, config, owner)
    check_kernel_threads(config["kernel_threads"], owner)
    check_road_event_slots(config, owner)
    frames = step_frames_rule(config["max_duration"])
    check_value(frames, config["steps_per_action"], owner, "steps_per_action")
    latency = config["latency_steps"]
    if latency is not None:
        check_value(Number(0, frames.high, integer=True, unit="physics frames", why=(
            "a path takes effect within the episode")), latency, owner, "latency_steps")


def check_highway_start(config: Mapping[str, Any], road_width: float, owner: str,
                        loop_length: float) -> None:
    """A configured start lies on the loaded map's road: d in [0, lanes x lane width], s
    in [0, loop length)."""
    check_value(Number(0.0, road_width, optional=True, unit="m right of the centre line, on "
                       f"the map's {road_width:g} m of road"), config["start_d"], owner,
                "start_d")
    check_start_s(config["start_s"], loop_length, owner)


def check_start_s(start_s: Any, loop_length: float, owner: str) -> None:
    """``start_s`` within one lap, [0, loop length): ``1e300`` wrapped around the loop
    silently (to wherever float rounding put it)."""
    check_value(Number(0.0, loop_length, high_open=True, optional=True,
                       unit=f"m along the {loop_length:,.1f} m loop"), start_s, owner,
                "start_s")


BEHAVIOR_RULES: Final[dict[str, Rule]] = {
    "slow_step_mps": Number(0.0, 50.0, low_open=True, unit="m/s"),
    "reward_lane_change": FINITE,
    "reward_refused": FINITE,
    "reward_room_ahead": FINITE,
    "shaping_gamma": PROBABILITY,
}


def check_highway_behavior_config(config: Mapping[str, Any], owner: str) -> None:
    """The behavior env's own keys; its ``highway`` block is the highway env's."""
    check_rules(BEHAVIOR_RULES, {k: v for k, v in config.items() if k != "highway"}, owner)
    highway = config["highway"]
    max_duration = highway.get("max_duration", 600.0) if isinstance(highway, Mapping) else None
    check_value(step_frames_rule(max_duration), config["decision_frames"], owner,
                "decision_frames")


TRACK_RULES: Final[dict[str, Rule]] = {
    "laps": Number(1, MAX_LAPS, integer=True),
    "max_duration": Number(0.0, MAX_DURATION_S, low_open=True, unit="s"),
    "speed_limit": Number(0.0, 100.0, low_open=True, optional=True, unit="m/s"),
    "start_s": Number(optional=True, unit="m along the path"),
    "start_d": Number(unit="m right of the path"),
    "start_speed": Number(0.0, unit="m/s"),
    "obstacles.count": Number(0, MAX_OBSTACLES, integer=True,
                              why="each obstacle is checked every frame"),
    "obstacles.max_offset_d": NON_NEGATIVE,
    "obstacles.length": Number(0.0, 100.0, low_open=True, unit="m"),
    "obstacles.width": Number(0.0, 20.0, low_open=True, unit="m"),
    "incident_rules.max_acceleration": Number(0.0, low_open=True, allow_inf=True,
                                              unit="m/s^2"),
    "incident_rules.max_jerk": Number(0.0, low_open=True, allow_inf=True, unit="m/s^3"),
    "incident_rules.road_half_width": Number(0.0, 100_000.0, low_open=True, optional=True,
                                             unit="m"),
    "reward_progress": FINITE,
    **RENDER_RULES,
}


def check_track_config(config: Mapping[str, Any], owner: str) -> None:
    """The track env's rules (table, step bound), before the track is loaded."""
    check_rules(TRACK_RULES, config, owner)
    if len(config["obstacles"]["positions"]) > MAX_OBSTACLES:
        raise ConfigError(f"{owner}: config key 'obstacles.positions' must hold at most "
                          f"{MAX_OBSTACLES} obstacles, got {len(config['obstacles']['positions'])}")
    check_value(step_frames_rule(config["max_duration"]), config["steps_per_action"], owner,
                "steps_per_action")


def check_track_behavior_config(config: Mapping[str, Any], owner: str) -> None:
    """The track behavior env's decision period; its ``track`` block's step first (the
    period is counted in the track env's steps)."""
    track = config["track"]
    if isinstance(track, Mapping) and "steps_per_action" in track:
        check_value(step_frames_rule(track.get("max_duration", 1200.0)),
                    track["steps_per_action"], owner, "track.steps_per_action")
    max_duration = track.get("max_duration", 1200.0) if isinstance(track, Mapping) else None
    episode = (max_duration if isinstance(max_duration, int | float) and math.isfinite(
        max_duration) and max_duration > 0 else MAX_DECISION_PERIOD_S)
    check_value(Number(0.0, min(episode, MAX_DECISION_PERIOD_S), low_open=True, unit="s",
                       why=f"a decision lasts at most the episode's max_duration "
                           f"({max_duration!r} s) and at most {MAX_DECISION_PERIOD_S:g} s "
                           "(its per-frame buffers)"),
                config["decision_period_s"], owner, "decision_period_s")
