"""Scenario files (and mappings) checked key by key into a
:class:`~sdc_gym.scenarios.model.Scenario`.

Every error names the file and line (from YAML's node tree,
:func:`~sdc_gym.validation.yaml_files.parse_yaml_lines`), the key path, what the value
must be and what it is::

    scenarios/stalled.yaml:14: scenario key 'cars[1].speed' must be a finite number in
    [0, 100] (m/s), got -3

Unknown keys list the valid ones (with a close match when there is one), as config keys
do. What depends on the road (a lane on a map of two lanes, a closed lane longer than the
loop) is checked when an env applies the scenario, with the same file and line
(:func:`where`). The format, key by key, is in ``docs/scenarios.md``.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from sdc_gym.config import ConfigError, excerpt
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.scenarios.model import (
    ACTIONS,
    EVENT_KINDS,
    TRIGGERS,
    Action,
    CarStart,
    EgoStart,
    ReplayState,
    RoadEvent,
    Scenario,
    Success,
    Trigger,
)
from sdc_gym.traffic.vehicle_types import VEHICLE_NAMES
from sdc_gym.validation.bounds import MAX_CAR_COUNT, MAX_DURATION_S, MAX_PATH_POINTS
from sdc_gym.validation.rules import Number, Pair, Rule, is_real

MAX_ACTIONS: Final = 10_000
MAX_EVENTS: Final = 1_000
DISTANCE = Number(-100_000.0, 100_000.0, unit="m")
POSITION = Number(-1e7, 1e7, unit="m, map coordinates")
SPEED = Number(0.0, 100.0, unit="m/s")
DESIRED = Number(0.0, 100.0, low_open=True, unit="m/s")
LANE = Number(0, 100, integer=True, unit="lane, 0 = next to the centre line")
DURATION = Number(0.0, 3600.0, low_open=True, unit="s")
DECEL = Number(0.0, 15.0, low_open=True, unit="m/s^2")
STEPS = Number(0, 10**12, integer=True, unit="physics steps")
TOP_KEYS: Final = ("name", "description", "map", "duration", "ego", "traffic", "cars",
                   "actions", "road_events", "success", "replay")
EGO_KEYS: Final = ("s", "lane", "d", "speed", "x", "y", "yaw", "path", "in_flight")
CAR_KEYS: Final = ("name", "kind", "lane", "gap", "s", "speed", "desired_speed",
                   "lane_changes", "stalled", "recycle", "state")
STATE_KEYS: Final = ("wander", "lane_change", "acc", "pending", "held",
                     "brake_in", "cut_in_for", "respawn_in", "spawn_count", "hold_lane",
                     "forced_acc", "forced_until_steps")
ACTION_KEYS: Final = {
    "cut_in": ("lane", "duration"), "lane_change": ("lane", "duration"),
    "brake": ("decel", "duration", "to_speed"), "stop": ("decel",), "go": ("speed",),
    "set_speed": ("speed",),
}
EVENT_KEYS: Final = {
    "closed_lane": ("lane", "gap", "s", "length"),
    "cargo": ("lane", "gap", "s", "offset", "size"),
    "animal": ("gap", "s", "from_d", "to_d", "speed", "when"),
}
SUCCESS_KEYS: Final = ("no_collision", "no_incidents", "reach_lane", "keep_lane",
                       "min_distance", "end_lane")
REPLAY_KEYS: Final = ("traffic_step", "generator_state", "respawn_blocked_steps", "source")
DEFAULT_DURATION_S: Final = 30.0


class _Checker:
    """Reads one scenario, naming file, line and key path in every error."""

    def __init__(self, source: str, lines: Mapping[str, int]) -> None:
        self.source = source
        self.lines = lines

    def where(self, path: str) -> str:
        line = self.lines.get(path)
        while line is None and path:  # a key that is missing: its parent's line
            path = path.rsplit(".", 1)[0] if "." in path else ""
            line = self.lines.get(path)
        return f"{self.source}:{line}" if line is not None else self.source

    def fail(self, path: str, expectation: str, value: Any) -> ConfigError:
        return ConfigError(f"{self.where(path)}: scenario key {path!r} must be "
                           f"{expectation}, got {excerpt(value)}")

    def mapping(self, value: Any, path: str, allowed: Sequence[str],
                required: Sequence[str] = ()) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(path or "(the file)", "a mapping", value)
        for key in value:
            if key not in allowed:
                close = difflib.get_close_matches(str(key), list(allowed), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                name = f"{path}.{key}" if path else str(key)
                raise ConfigError(f"{self.where(name)}: unknown scenario key {name!r}{hint}; "
                                  f"valid keys{' of ' + path if path else ''}: "
                                  f"{', '.join(allowed)}")
        for key in required:
            if key not in value:
                raise ConfigError(f"{self.where(path)}: scenario key "
                                  f"{(path + '.' if path else '') + key!r} is required")
        return value

    def value(self, rule: Rule, mapping: Mapping[str, Any], key: str, path: str,
              default: Any = None) -> Any:
        if key not in mapping:
            return default
        value = mapping[key]
        name = f"{path}.{key}" if path else key
        problem = rule.problem(value)
        if problem is not None:
            raise self.fail(name, problem, value)
        return float(value) if isinstance(rule, Number) and not rule.integer else (
            int(value) if isinstance(rule, Number) else value)

    def typed(self, mapping: Mapping[str, Any], key: str, path: str, default: Any,
              kind: type, expectation: str) -> Any:
        """``mapping[key]`` if it is a ``kind`` (else an error), ``default`` if absent."""
        if key not in mapping:
            return default
        value = mapping[key]
        if not isinstance(value, kind):
            raise self.fail(f"{path}.{key}" if path else key, expectation, value)
        return value

    def flag(self, mapping: Mapping[str, Any], key: str, path: str, default: bool) -> bool:
        return self.typed(mapping, key, path, default, bool, "true or false")

    def text(self, mapping: Mapping[str, Any], key: str, path: str, default: str) -> str:
        return self.typed(mapping, key, path, default, str, "a string")

    def choice(self, mapping: Mapping[str, Any], key: str, path: str,
               choices: Sequence[str], default: str | None = None) -> str:
        if key not in mapping:
            if default is None:
                raise ConfigError(f"{self.where(path)}: scenario key {path + '.' + key!r} "
                                  f"is required: one of {list(choices)}")
            return default
        value = mapping[key]
        if value not in choices or not isinstance(value, str):
            raise self.fail(f"{path}.{key}", f"one of {list(choices)}", value)
        return value

    def items(self, mapping: Mapping[str, Any], key: str, limit: int) -> list[Any]:
        value = mapping.get(key, [])
        if value is None:
            return []
        if not isinstance(value, list) or len(value) > limit:
            raise self.fail(key, f"a list of at most {limit} entries", value)
        return value

    def points(self, value: Any, path: str) -> tuple[tuple[float, float], ...]:
        expectation = (f"a list of at most {MAX_PATH_POINTS} [x, y] points, each a finite "
                       "number")
        if not isinstance(value, list) or len(value) > MAX_PATH_POINTS:
            raise self.fail(path, expectation, value)
        for point in value:
            if (not isinstance(point, list | tuple) or len(point) != 2
                    or any(POSITION.problem(c) for c in point)):
                raise self.fail(path, expectation, point)
        return tuple((float(x), float(y)) for x, y in value)

    def position(self, entry: Mapping[str, Any], path: str) -> tuple[float | None,
                                                                       float | None]:
        """``gap`` (relative to the ego's start) or ``s`` (absolute): exactly one."""
        if ("gap" in entry) == ("s" in entry):
            raise ConfigError(f"{self.where(path)}: scenario entry {path!r} needs exactly "
                              "one of 'gap' (m from the ego's start, > 0 ahead) and 's' "
                              "(m along the road)")
        return self.value(DISTANCE, entry, "gap", path), self.value(DISTANCE, entry, "s", path)

    def trigger(self, value: Any, path: str) -> Trigger:
        entry = self.mapping(value, path, TRIGGERS)
        if len(entry) != 1:
            raise self.fail(path, f"a mapping with exactly one of {list(TRIGGERS)}", value)
        kind = next(iter(entry))
        rule = (Number(0.0, MAX_DURATION_S, unit="s") if kind == "time" else
                Number(0.0, 1e7, unit="m") if kind == "ego_distance" else DISTANCE)
        return Trigger(kind, self.value(rule, entry, kind, path))


def check_scenario(data: Any, source: str = "<mapping>",
                   lines: Mapping[str, int] | None = None) -> Scenario:
    """``data`` (a parsed scenario file or a mapping) as a checked :class:`Scenario`;
    :class:`~sdc_gym.config.ConfigError` naming ``source``, the line and the key for the
    first problem."""
    check = _Checker(source, lines or {})
    top = check.mapping(data, "", TOP_KEYS)
    stem = Path(source).stem if source != "<mapping>" else "scenario"
    name = check.text(top, "name", "", stem)
    ego = _ego(check, top.get("ego", {}))
    traffic = check.mapping(top.get("traffic", {}) or {}, "traffic",
                            ("lane_changes", "recycle"))
    lane_changes = check.flag(traffic, "lane_changes", "traffic", False)
    recycle = check.flag(traffic, "recycle", "traffic", False)
    cars = tuple(_car(check, entry, f"cars[{i}]", lane_changes, recycle)
                 for i, entry in enumerate(check.items(top, "cars", MAX_CAR_COUNT)))
    names = [car.name for car in cars]
    for i, car in enumerate(cars):
        if names.index(car.name) != i:
            raise check.fail(f"cars[{i}].name", "a name no other car has", car.name)
    actions = tuple(_action(check, entry, f"actions[{i}]", cars)
                    for i, entry in enumerate(check.items(top, "actions", MAX_ACTIONS)))
    events = tuple(_event(check, entry, f"road_events[{i}]")
                   for i, entry in enumerate(check.items(top, "road_events", MAX_EVENTS)))
    return Scenario(
        name=name, description=check.text(top, "description", "", ""), source=source,
        duration=check.value(Number(0.0, MAX_DURATION_S, low_open=True, unit="s"), top,
                             "duration", "", DEFAULT_DURATION_S),
        ego=ego, cars=cars, actions=actions, road_events=events,
        success=_success(check, top.get("success", {}) or {}),
        map=check.text(top, "map", "", "") or None,
        replay=_replay(check, top["replay"]) if "replay" in top else None,
        where={path: check.where(path) for path in (lines or {})},
    )


def load_scenario(scenario: str | os.PathLike[str] | Mapping[str, Any] | Scenario
                  ) -> Scenario:
    """A scenario from a file path, a mapping or an already checked :class:`Scenario`."""
    from sdc_gym.validation.yaml_files import read_yaml_lines

    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, Mapping):
        return check_scenario(scenario)
    if isinstance(scenario, str | os.PathLike):
        data, lines = read_yaml_lines(scenario, "scenario file", ConfigError)
        return check_scenario(data, str(scenario), lines)
    raise ConfigError(f"a scenario must be a file path, a mapping or a Scenario, got "
                      f"{type(scenario).__name__} ({excerpt(scenario)})")


def _ego(check: _Checker, value: Any) -> EgoStart:
    entry = check.mapping(value or {}, "ego", EGO_KEYS)
    if "lane" in entry and "d" in entry:
        raise ConfigError(f"{check.where('ego')}: scenario key 'ego' takes 'lane' or 'd', "
                          "not both")
    pose = [key for key in ("x", "y", "yaw") if key in entry]
    if pose and len(pose) != 3:
        raise ConfigError(f"{check.where('ego')}: scenario key 'ego' takes x, y and yaw "
                          f"together (a recorded pose), got only {pose}")
    lane = check.value(LANE, entry, "lane", "ego")
    d = check.value(Number(-100.0, 100.0, unit="m right of the centre line"), entry, "d", "ego")
    in_flight = []
    for i, item in enumerate(entry.get("in_flight", []) or []):
        path = f"ego.in_flight[{i}]"
        sent = check.mapping(item, path, ("due", "points"), ("due", "points"))
        in_flight.append((check.value(Number(0, 10**6, integer=True, unit="frames"), sent,
                                      "due", path), check.points(sent["points"], path + ".points")))
    return EgoStart(
        s=check.value(DISTANCE, entry, "s", "ego"), d=d, lane=lane,
        speed=check.value(SPEED, entry, "speed", "ego", 0.0),
        x=check.value(POSITION, entry, "x", "ego"), y=check.value(POSITION, entry, "y", "ego"),
        yaw=check.value(Number(-100.0, 100.0, unit="rad"), entry, "yaw", "ego"),
        path=check.points(entry["path"], "ego.path") if "path" in entry else None,
        in_flight=tuple(in_flight))


def _car(check: _Checker, value: Any, path: str, lane_changes: bool,
         recycle: bool) -> CarStart:
    entry = check.mapping(value, path, CAR_KEYS, ("lane",))
    gap, s = check.position(entry, path)
    stalled = check.flag(entry, "stalled", path, False)
    if stalled:
        speed = check.value(Number(0.0, 0.0, unit="m/s: a stalled car stands"), entry,
                            "speed", path, 0.0)
    else:
        if "speed" not in entry:
            raise ConfigError(f"{check.where(path)}: scenario key {path + '.speed'!r} is "
                              "required (m/s; or 'stalled: true')")
        speed = check.value(SPEED, entry, "speed", path)
    desired = check.value(DESIRED, entry, "desired_speed", path,
                          max(speed, 0.1) if not stalled else 0.1)
    state = None
    if "state" in entry:
        state = dict(check.mapping(entry["state"], f"{path}.state", STATE_KEYS))
        for key, item in state.items():
            if key in ("wander", "lane_change"):
                continue
            if item is not None and not (is_real(item) or isinstance(item, bool)):
                raise check.fail(f"{path}.state.{key}", "a number", item)
    name = entry.get("name", str(int(path[5:-1])))
    if not isinstance(name, str | int) or isinstance(name, bool):
        raise check.fail(f"{path}.name", "a string", name)
    return CarStart(
        name=str(name), kind=check.choice(entry, "kind", path, VEHICLE_NAMES, "car"),
        lane=check.value(LANE, entry, "lane", path), gap=gap, s=s, speed=speed,
        desired_speed=desired,
        lane_changes=check.flag(entry, "lane_changes", path, lane_changes),
        stalled=stalled, recycle=check.flag(entry, "recycle", path, recycle), state=state)


def _action(check: _Checker, value: Any, path: str, cars: tuple[CarStart, ...]) -> Action:
    if not isinstance(value, Mapping):
        raise check.fail(path, "a mapping", value)
    do = check.choice(value, "do", path, ACTIONS)
    entry = check.mapping(value, path, ("car", "when", "do", *ACTION_KEYS[do]),
                          ("car", "when"))
    reference = entry["car"]
    names = [car.name for car in cars]
    if isinstance(reference, int) and not isinstance(reference, bool):
        index = reference if 0 <= reference < len(cars) else -1
    else:
        index = names.index(str(reference)) if str(reference) in names else -1
    if index < 0:
        raise check.fail(f"{path}.car", f"a car's name or index (cars: {names})", reference)
    action = Action(
        car=index, when=check.trigger(entry["when"], f"{path}.when"), do=do,
        lane=check.value(LANE, entry, "lane", path),
        duration=check.value(DURATION, entry, "duration", path),
        decel=check.value(DECEL, entry, "decel", path),
        to_speed=check.value(SPEED, entry, "to_speed", path),
        speed=check.value(DESIRED, entry, "speed", path))
    if do == "lane_change" and action.lane is None:
        raise ConfigError(f"{check.where(path)}: scenario key {path + '.lane'!r} is "
                          "required for a lane_change")
    if do == "set_speed" and action.speed is None:
        raise ConfigError(f"{check.where(path)}: scenario key {path + '.speed'!r} is "
                          "required for set_speed")
    if do == "brake" and (action.duration is None) == (action.to_speed is None):
        raise ConfigError(f"{check.where(path)}: scenario action {path!r} (brake) needs "
                          "exactly one of 'duration' (s) and 'to_speed' (m/s)")
    return action


def _event(check: _Checker, value: Any, path: str) -> RoadEvent:
    if not isinstance(value, Mapping):
        raise check.fail(path, "a mapping", value)
    kind = check.choice(value, "kind", path, EVENT_KINDS)
    entry = check.mapping(value, path, ("kind", *EVENT_KEYS[kind]),
                          ("lane",) if kind != "animal" else ())
    gap, s = check.position(entry, path)
    size = check.value(Pair(Number(0.1, 20.0, unit="m")), entry, "size", path)
    return RoadEvent(
        kind=kind, gap=gap, s=s, lane=check.value(LANE, entry, "lane", path, 0),
        length=check.value(Number(8.0, 5000.0, unit="m"), entry, "length", path, 150.0),
        offset=check.value(Number(-2.0, 2.0, unit="m from the lane's centre"), entry,
                           "offset", path, 0.0),
        size=(float(size[0]), float(size[1])) if size is not None else None,
        from_d=check.value(Number(-20.0, 100.0, unit="m right of the centre line"), entry,
                           "from_d", path, -1.5),
        to_d=check.value(Number(-20.0, 100.0, unit="m right of the centre line"), entry,
                         "to_d", path),
        speed=check.value(Number(0.0, 20.0, low_open=True, unit="m/s"), entry, "speed",
                          path, 1.5),
        when=check.trigger(entry["when"], f"{path}.when") if "when" in entry
        else Trigger("time", 0.0))


def _success(check: _Checker, value: Any) -> Success:
    entry = check.mapping(value, "success", SUCCESS_KEYS)
    kinds = entry.get("no_incidents", [])
    if not isinstance(kinds, list) or any(kind not in INCIDENT_KINDS for kind in kinds):
        raise check.fail("success.no_incidents", f"a list of incident kinds of "
                         f"{list(INCIDENT_KINDS)}", kinds)

    def lane_and_time(key: str, time_key: str) -> tuple[int, float] | None:
        if key not in entry:
            return None
        item = check.mapping(entry[key], f"success.{key}", ("lane", time_key),
                             ("lane", time_key))
        return (check.value(LANE, item, "lane", f"success.{key}"),
                check.value(Number(0.0, MAX_DURATION_S, unit="s"), item, time_key,
                            f"success.{key}"))

    return Success(
        no_collision=check.flag(entry, "no_collision", "success", True),
        no_incidents=tuple(kinds), reach_lane=lane_and_time("reach_lane", "within"),
        keep_lane=lane_and_time("keep_lane", "for"),
        min_distance=check.value(Number(0.0, 1e8, unit="m"), entry, "min_distance",
                                 "success"),
        end_lane=check.value(LANE, entry, "end_lane", "success"))


def _replay(check: _Checker, value: Any) -> ReplayState:
    entry = check.mapping(value, "replay", REPLAY_KEYS)
    state = entry.get("generator_state")
    if state is not None and not isinstance(state, Mapping):
        raise check.fail("replay.generator_state", "a mapping (numpy's bit generator "
                         "state)", state)
    source = entry.get("source", {}) or {}
    if not isinstance(source, Mapping):
        raise check.fail("replay.source", "a mapping", source)
    return ReplayState(
        traffic_step=check.value(STEPS, entry, "traffic_step", "replay", 0),
        generator_state=dict(state) if state is not None else None,
        respawn_blocked_steps=check.value(STEPS, entry, "respawn_blocked_steps", "replay", 0),
        source=dict(source))
