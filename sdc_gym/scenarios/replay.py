"""Replays: an env's state as a scenario, and an incident report as a scenario file.

:func:`snapshot` writes down everything of a highway env that a scenario can restore, as a
scenario mapping: the ego's pose, speed, the path it has not driven yet and the paths in
flight; every traffic slot in slot order (kind, lane, s, speed, desired speed, and under
``state`` its exact lateral wander, lane change under way, held acceleration, sustained
lane wish, rogue timers, respawn wait; its ``d`` too, for the reader); the road events with
their objects; the scripted actions still to come; and under ``replay`` the traffic's
clock (the step, so that decision instants and wander phases fall as they did) and the
env generator's state (so that respawns and rogue moments to come are the recorded ones).

Started from such a mapping, the traffic continues exactly as it did, as long as the ego
drives as it did (traffic reacts to the ego). What a snapshot cannot restore:

* the agent's own state: an FSM planner starts afresh (Launch/Adapt, its cool-downs from
  the replay's start, an empty queue, planned from the car's pose and speed along the
  recorded path); a trained policy's recurrent state, a Kalman tracker's filters likewise;
* the metrics' running windows: the acceleration block and the jerk window restart at the
  replay's first step (the first samples are masked, as at any start), the straddling
  count and "distance without incident" start at 0, the lap count at 0;
* sensor faults in progress (a zero-s/d fault's remaining frames) start over.

So the same agent usually repeats the incident (its decisions come from the same
situation), and another agent may avoid it; ``tests/test_replay.py`` checks both on a
recorded collision.

:func:`incident_scenario` turns one report of ``incidents.json`` (which carries such a
snapshot, taken a few seconds before the incident, under ``replay``) into a scenario that
runs from there until a few seconds after the incident and passes when the incident does
not happen again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

from sdc_gym.config import excerpt
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.traffic.road_events import RoadEvents
from sdc_gym.traffic.slots import read_slot
from sdc_gym.traffic.state import IDLE, OBJECT, PARKED
from sdc_gym.traffic.vehicle_types import KINDS
from sdc_gym.validation.rules import is_real

NO_RECYCLE_FROM_STEPS = 2**59
"""A respawn wait at least this long is "never recycled" (a scenario's car)."""
DEFAULT_AFTER_S = 5.0
"""A replay runs this long past the incident's time."""


def snapshot(world: Any, env: int) -> dict[str, Any]:
    """Env ``env`` of ``world`` (a :class:`~sdc_gym.envs.highway_world.HighwayWorld`) now,
    as a scenario mapping (see the module docstring); its ``duration`` is the config's."""
    st = world.traffic.state
    cars = []
    car_slots = world.car_count
    last = max([i for i in range(car_slots) if st.role[env, i] != PARKED], default=-1)
    for i in range(last + 1):
        cars.append(_car_entry(read_slot(st, env, i), i))
    follower = world.ego
    path = follower.remaining(env)
    in_flight = []
    depth = follower.queue.shape[1]
    for k in range(int(follower.queue_count[env])):
        slot = (int(follower.queue_head[env]) + k) % depth
        length = int(follower.queue_length[env, slot])
        in_flight.append({"due": int(follower.queue_due[env, slot] - follower.frame[env]),
                          "points": follower.queue[env, slot, :length].tolist()})
    rng = world.rngs[env]
    controller = world.traffic.controllers[env]
    events = (_event_entries(world, env, controller) if isinstance(controller, RoadEvents)
              else [])
    scenario: dict[str, Any] = {
        "name": "snapshot",
        "description": "",
        "map": world.config["map"],
        "duration": float(world.episodes.max_duration[env]),
        "ego": {"s": float(world.s[env]), "d": float(world.d[env]),
                "speed": float(world.speed[env]), "x": float(follower.xy[env, 0]),
                "y": float(follower.xy[env, 1]), "yaw": float(follower.yaw[env]),
                "path": path.tolist(), "in_flight": in_flight},
        "cars": cars,
        "road_events": events,
        "replay": {"traffic_step": int(st.step[env]),
                   "generator_state": rng.bit_generator.state if rng is not None else None,
                   "respawn_blocked_steps": max(int(st.respawn_blocked_until[env])
                                                - int(st.step[env]), 0),
                   "source": {"time": float(world.metrics.time()[env]),
                              "env_config": plain({key: value for key, value
                                                   in world.config.items()
                                                   if key != "scenario"})}},
    }
    actions = _pending_actions(controller)
    if actions:
        scenario["actions"] = actions
    return scenario


def plain(value: Any) -> Any:
    """``value`` as JSON and YAML write it: mappings with string keys, lists, numbers."""
    if isinstance(value, dict):
        return {str(key): plain(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [plain(item) for item in value]
    if hasattr(value, "item") and callable(value.item):  # numpy scalars
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value


def _car_entry(slot: dict[str, Any], index: int) -> dict[str, Any]:
    kind = KINDS[slot["type_index"]].name
    entry: dict[str, Any] = {"name": str(index), "kind": kind, "lane": slot["lane"],
                             "s": slot["s"]}
    if slot["role"] == OBJECT:  # a stalled car
        entry["stalled"] = True
        entry["state"] = {"wander": slot["wander"]}
        return entry
    entry.update(speed=slot["speed"], desired_speed=max(slot["desired"], 1e-3),
                 lane_changes=not slot["hold_lane"],
                 recycle=slot["respawn_in"] < NO_RECYCLE_FROM_STEPS)
    state = {key: slot[key] for key in ("wander", "lane_change", "acc",
                                        "pending", "held", "brake_in", "cut_in_for",
                                        "respawn_in", "spawn_count", "forced_acc",
                                        "forced_until_steps")}
    if not entry["recycle"]:
        del state["respawn_in"]
    entry["state"] = state
    return entry


def _event_entries(world: Any, env: int, controller: RoadEvents) -> list[dict[str, Any]]:
    st = world.traffic.state
    loop = world.road.length
    entries = []
    for event in controller.active:
        first = event.slots[0]
        if event.kind == "closed_lane":
            entries.append({"kind": "closed_lane", "lane": event.lane,
                            "s": event.s_start % loop, "length": event.extra["length"]})
        elif event.kind == "cargo":
            entries.append({"kind": "cargo", "lane": event.lane, "s": float(st.s[env, first]),
                            "offset": event.extra["offset"], "size": event.extra["size"]})
        else:
            walking = event.walking
            entry = {"kind": "animal", "s": float(st.s[env, first]),
                     "from_d": float(st.d[env, first]) if walking else event.extra["from_d"],
                     "to_d": event.extra["to_d"], "speed": event.extra["speed"]}
            trigger_kind, value = event.trigger
            if not walking and trigger_kind != "time":
                entry["when"] = {trigger_kind: value}
            entries.append(entry)
    return entries


def _pending_actions(controller: Any) -> list[dict[str, Any]]:
    """A scenario's actions still to come, their triggers counted from now."""
    pending = getattr(controller, "pending", None)
    if not pending:
        return []
    actions = []
    for action in pending:
        kind, value = action.when.kind, action.when.value
        if kind == "time":
            value = max(value - controller.time, 0.0)
        elif kind == "ego_distance":
            value = max(value - controller.driven, 0.0)
        entry: dict[str, Any] = {"car": action.car, "when": {kind: value}, "do": action.do}
        for key in ("lane", "duration", "decel", "to_speed", "speed"):
            if getattr(action, key) is not None:
                entry[key] = getattr(action, key)
        actions.append(entry)
    return actions


def kind_in_snapshot(state: dict[str, Any], slot: int) -> str:
    """The kind of traffic slot ``slot`` in a snapshot (a car's kind, an object's event
    kind), or ``"unknown"``."""
    cars = state.get("cars", [])
    if 0 <= slot < len(cars):
        return cars[slot]["kind"]
    for event in state.get("road_events", []):
        if slot in event.get("ids", ()):
            return event["kind"]
    return "unknown"


REPORT_KEYS: Final = ("kind", "time", "replay")
"""The keys an incident report must have to be replayed (sdc_evaluation.incident_reports
writes them, with ``agent``, ``seed``, ``env_id``, ``env_config`` and more)."""
SNAPSHOT_KEYS: Final = ("map", "duration", "ego", "cars", "replay")
"""The keys of a report's ``replay`` snapshot (:func:`snapshot` writes them)."""
REPLAY_STATE_KEYS: Final = ("traffic_step", "generator_state", "respawn_blocked_steps",
                            "source")


def check_incident_report(report: Any) -> None:
    """``ValueError`` naming what is missing or wrong unless ``report`` is a whole incident
    report with its snapshot: ``{"replay": {}}`` was a KeyError, ``{"replay": 5}`` a
    traceback, and a report without ``kind`` or ``time`` ran a defaulted replay that
    "passed"."""
    if not isinstance(report, Mapping):
        raise ValueError(f"an incident report must be a mapping, got "
                         f"{type(report).__name__} ({excerpt(report)})")
    if report.get("replay") is None:
        raise ValueError("the incident report has no 'replay' snapshot (reports record one "
                         "when the env can take it: the highway envs)")
    missing = [key for key in REPORT_KEYS if key not in report]
    if missing:
        raise ValueError(f"the incident report lacks {missing} (a replay needs "
                         f"{list(REPORT_KEYS)}; evaluate.py's incidents.json has them)")
    if report["kind"] not in INCIDENT_KINDS:
        raise ValueError(f"the incident report's 'kind' must be one of {list(INCIDENT_KINDS)}"
                         f", got {excerpt(report['kind'])}")
    if not (is_real(report["time"]) and math.isfinite(report["time"]) and report["time"] >= 0):
        raise ValueError(f"the incident report's 'time' must be a finite number >= 0 s, got "
                         f"{excerpt(report['time'])}")
    state = report["replay"]
    if not isinstance(state, Mapping):
        raise ValueError(f"the incident report's 'replay' must be a snapshot mapping of "
                         f"{list(SNAPSHOT_KEYS)}, got {excerpt(state)}")
    missing = [key for key in SNAPSHOT_KEYS if key not in state]
    if missing:
        raise ValueError(f"the incident report's 'replay' snapshot lacks {missing} (a "
                         f"snapshot has {list(SNAPSHOT_KEYS)})")
    inner = state["replay"]
    if not isinstance(inner, Mapping) or any(key not in inner for key in REPLAY_STATE_KEYS):
        raise ValueError(f"the incident report's 'replay.replay' must be a mapping of "
                         f"{list(REPLAY_STATE_KEYS)}, got {excerpt(inner)}")
    source = inner["source"]
    if not isinstance(source, Mapping) or not is_real(source.get("time")) or not (
            0 <= source["time"] <= report["time"]):
        raise ValueError(f"the incident report's 'replay.replay.source' must be a mapping "
                         f"with the snapshot's 'time' (s, at most the incident's "
                         f"{excerpt(report['time'])}), got {excerpt(source)}")


def incident_scenario(report: dict[str, Any], after_s: float = DEFAULT_AFTER_S,
                      name: str | None = None) -> dict[str, Any]:
    """A scenario mapping that replays the incident of ``report`` (one entry of
    ``incidents.json``): from its snapshot (``report["replay"]``) until ``after_s`` s past
    the incident; it passes when the incident's kind does not happen."""
    check_incident_report(report)
    state = report["replay"]
    if not math.isfinite(after_s) or after_s <= 0:
        raise ValueError(f"after_s must be > 0 s, got {after_s!r}")
    kind = report.get("kind", "collision")
    start = float(state["replay"]["source"].get("time", 0.0))
    at = float(report.get("time", start))
    scenario = dict(state)
    scenario["name"] = name or (f"replay_{report.get('agent', 'agent')}_seed"
                                f"{report.get('seed', 0)}_{kind}_{at:.1f}s")
    what = f"{kind}" + (f" with a {report['with']}" if report.get("with") else "")
    scenario["description"] = (
        f"Replay of a {what} of {report.get('agent', '?')} (seed {report.get('seed', '?')})"
        f" at {at:.2f} s, from {at - start:.2f} s before it: env {report.get('env_id', '?')}"
        f" with config {report.get('env_config', {})}.")
    scenario["duration"] = round(at - start + after_s, 6)
    scenario["success"] = ({"no_collision": True} if kind == "collision"
                           else {"no_collision": False, "no_incidents": [kind]})
    scenario["replay"] = dict(state["replay"])
    scenario["replay"]["source"] = {
        **state["replay"]["source"], "agent": report.get("agent"), "seed": report.get("seed"),
        "incident": kind, "incident_time": at, "env_id": report.get("env_id"),
        "env_config": report.get("env_config")}
    return scenario


__all__ = ["DEFAULT_AFTER_S", "IDLE", "check_incident_report", "incident_scenario",
           "kind_in_snapshot", "snapshot"]
