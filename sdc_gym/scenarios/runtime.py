"""A scenario while it runs in one env of a highway world: its start, its script, its verdict.

* :func:`scenario_slots` turns the scenario's cars and road events into one
  :class:`~sdc_gym.traffic.slots.SlotSpec` per traffic column (the car slots first, the
  ones the scenario leaves empty parked; then the object slots);
* :func:`ego_path` is the path the ego starts on when it starts moving: the points of its
  lane at its speed, one per 0.02 s frame for ``path_points`` frames, as if it had been
  driving (a planner that extends its previous path, or one that plans from the car's pose,
  joins it without a jerk);
* :class:`ScenarioScript` is the env's traffic controller (called at its decision
  instants, every 0.2 s): the scripted actions whose trigger holds, the animals' walks,
  random road events when the env has rates;
* :class:`ScenarioJudge` follows the episode and gives the verdict of the scenario's
  success conditions, with the reason (``passed``, or what failed and when).

Actions take effect at the traffic's first decision instant at or after their trigger
(decisions fall every ``decision_period`` frames, 0.2 s by default), as traffic cars' own
decisions do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, excerpt
from sdc_gym.scenarios.model import Action, Scenario
from sdc_gym.traffic.road_events import (
    ActiveEvent,
    RoadEventRates,
    RoadEvents,
    event_slots,
    trigger_met,
)
from sdc_gym.traffic.roles import start_lane_change
from sdc_gym.traffic.slots import PARKED_SLOT, LaneChange, SlotSpec
from sdc_gym.traffic.state import IDLE, OBJECT, TRAFFIC, TrafficState
from sdc_gym.traffic.vehicle_types import KIND_INDEX

TrafficBatch = Any  # sdc_gym.traffic.batch.TrafficBatch

NO_RECYCLE_STEPS = 2**60
"""A respawn wait no episode outlasts: the car is never recycled."""
DEFAULT_BRAKE_DECEL = 6.0  # m/s^2, a hard brake (traffic's rogue braking)
DEFAULT_STOP_DECEL = 4.0  # m/s^2, a firm stop


def scenario_slots(scenario: Scenario, car_slots: int, object_slots: int, ego_s: float,
                   lanes: int, lane_width: float, loop: float, dt: float
                   ) -> tuple[list[SlotSpec], list[ActiveEvent]]:
    """Every traffic column's spec and the road events (their slots numbered); a
    :class:`~sdc_gym.config.ConfigError` naming the file and line for what does not fit
    the road or the env's slots."""
    if len(scenario.cars) > car_slots:
        raise ConfigError(f"{scenario.at('cars')}: scenario {scenario.name!r} has "
                          f"{len(scenario.cars)} cars; the env has traffic.car_count = "
                          f"{car_slots} slots (raise it)")
    needed = scenario.objects_needed
    if needed > object_slots:
        raise ConfigError(f"{scenario.at('road_events')}: scenario {scenario.name!r} needs "
                          f"{needed} road-object slots; the env has road_events.object_slots"
                          f" = {object_slots} (raise it, or give the scenario in the config,"
                          " which sizes the slots)")
    specs = [_car_spec(scenario, i, ego_s, lanes) for i in range(len(scenario.cars))]
    specs += [PARKED_SLOT] * (car_slots - len(specs))
    events: list[ActiveEvent] = []
    objects: list[SlotSpec] = []
    for index, event in enumerate(scenario.road_events):
        path = f"road_events[{index}]"
        if event.kind != "animal" and not 0 <= event.lane < lanes:
            raise ConfigError(f"{scenario.at(path + '.lane')}: scenario key "
                              f"{path + '.lane'!r} must be a lane of the map, 0 to "
                              f"{lanes - 1}, got {event.lane}")
        if event.kind == "closed_lane" and event.length > 0.5 * loop:
            raise ConfigError(f"{scenario.at(path + '.length')}: scenario key "
                              f"{path + '.length'!r} must be at most half the loop "
                              f"({0.5 * loop:.0f} m), got {event.length}")
        s = (ego_s + event.gap if event.gap is not None else event.s) % loop
        slot_specs, record = event_slots(
            event.kind, s, event.lane, lane_width, lanes * lane_width, length=event.length,
            offset=event.offset, size=event.size, from_d=event.from_d, to_d=event.to_d,
            speed=event.speed, dt=dt)
        record.slots = list(range(car_slots + len(objects),
                                  car_slots + len(objects) + len(slot_specs)))
        record.trigger = (event.when.kind, event.when.value)
        objects += slot_specs
        events.append(record)
    specs += objects + [PARKED_SLOT] * (object_slots - len(objects))
    return specs, events


def _car_spec(scenario: Scenario, index: int, ego_s: float, lanes: int) -> SlotSpec:
    car = scenario.cars[index]
    path = f"cars[{index}]"
    if not 0 <= car.lane < lanes:
        raise ConfigError(f"{scenario.at(path + '.lane')}: scenario key {path + '.lane'!r} "
                          f"must be a lane of the map, 0 to {lanes - 1}, got {car.lane}")
    s = ego_s + car.gap if car.gap is not None else float(car.s)  # type: ignore[arg-type]
    state = dict(car.state or {})
    change = state.pop("lane_change", None)
    wander = state.pop("wander", None)
    if change is not None:
        if not isinstance(change, dict) or set(change) != {"target", "elapsed_steps",
                                                          "duration"}:
            raise ConfigError(f"{scenario.at(path + '.state.lane_change')}: scenario key "
                              f"{path + '.state.lane_change'!r} must be a mapping of target, "
                              f"elapsed_steps and duration, got {excerpt(change)}")
        change = LaneChange(int(change["target"]), int(change["elapsed_steps"]),
                            float(change["duration"]))
    if wander is not None:
        wander = (float(wander[0]), float(wander[1]))
    if car.stalled:
        return SlotSpec(OBJECT, KIND_INDEX[car.kind], s, car.lane, 0.0, 0.0, hold_lane=True,
                        forced_until_steps=None, wander=wander or (0.0, 0.0))
    extras = {key: state[key] for key in ("acc", "pending", "held", "brake_in",
                                          "cut_in_for", "respawn_in", "spawn_count",
                                          "forced_acc", "forced_until_steps") if key in state}
    for key in ("pending", "held", "brake_in", "cut_in_for", "respawn_in", "spawn_count"):
        if key in extras:
            extras[key] = int(extras[key])
    if "forced_until_steps" in extras and extras["forced_until_steps"] is not None:
        extras["forced_until_steps"] = int(extras["forced_until_steps"])
    if not car.recycle:
        extras["respawn_in"] = NO_RECYCLE_STEPS
    hold = bool(state.get("hold_lane", not car.lane_changes))
    return SlotSpec(TRAFFIC, KIND_INDEX[car.kind], s, car.lane, car.speed, car.desired_speed,
                    hold_lane=hold, wander=wander, lane_change=change, **extras)


def ego_path(reference: Any, s: float, d: float, speed: float, points: int,
             dt: float) -> NDArray[np.float64]:
    """``points`` path points along the lane at offset ``d`` from ``s`` on, one frame of
    ``speed`` apart (the car stands one frame before the first)."""
    if speed <= 0.0 or points < 2:
        return np.zeros((0, 2))
    kappa = float(reference.curvature(s))
    step = speed * dt / max(1.0 + kappa * d, 0.2)  # arc length of the reference line
    along = s + step * np.arange(1, points + 1)
    return reference.to_xy(reference.wrap_s(along), np.full(points, d)).astype(np.float64)


class ScenarioScript(RoadEvents):
    """The traffic controller of an env running a scenario: its scripted actions, its road
    events (animals walk when their trigger holds), and random road events on top when the
    env has rates. ``start_step`` is the traffic's step at the reset."""

    def __init__(self, scenario: Scenario, events: list[ActiveEvent], rates: RoadEventRates,
                 rng: np.random.Generator, start_step: int = 0) -> None:
        super().__init__(rates, rng, start_step)
        self.scenario = scenario
        self.active = list(events)
        self.pending: list[Action] = list(scenario.actions)
        self.done: list[tuple[float, Action]] = []

    def before_decision(self, batch: TrafficBatch, st: TrafficState, row: int) -> None:
        step = self.track_ego(batch, st, row)
        for action in list(self.pending):
            car = action.car
            gap = float(batch.reference.s_difference(st.s[row, car], st.ego_s[row]))
            if trigger_met((action.when.kind, action.when.value), self.time, gap,
                           self.driven) and self._apply(batch, st, row, action):
                self.pending.remove(action)
                self.done.append((self.time, action))
        self.update(batch, st, row)
        if self.rates.random and step > 0.0:
            self._spawn(batch, st, row, step)

    def _apply(self, batch: TrafficBatch, st: TrafficState, row: int, action: Action) -> bool:
        """Do ``action`` now; ``False`` to try again at the next decision (a lane change
        while one is under way)."""
        car = action.car
        now = int(st.step[row])
        cfg = batch.config
        if action.do in ("cut_in", "lane_change"):
            if st.lc_end[row, car] != IDLE:
                return False
            lane = action.lane
            if lane is None:  # a cut-in: into the ego's lane
                lane = min(max(math.floor(float(st.ego_d[row]) / batch.lane_width), 0),
                           batch.lanes - 1)
            if lane == int(st.origin[row, car]):
                return True
            duration = action.duration or (cfg.rogue_cut_in_duration if action.do == "cut_in"
                                           else cfg.lane_change_duration)
            start_lane_change(batch, st, row, car, lane, duration)
        elif action.do == "brake":
            decel = action.decel or DEFAULT_BRAKE_DECEL
            seconds = action.duration if action.duration is not None else max(
                float(st.speed[row, car]) - float(action.to_speed or 0.0), 0.0) / decel
            st.forced_acc[row, car] = -decel
            st.forced_until[row, car] = now + max(1, round(seconds / batch.dt))
        elif action.do == "stop":
            st.forced_acc[row, car] = -(action.decel or DEFAULT_STOP_DECEL)
            st.forced_until[row, car] = IDLE
        elif action.do == "go":
            st.forced_until[row, car] = 0
            if action.speed is not None:
                st.desired[row, car] = action.speed
        elif action.do == "set_speed":
            st.desired[row, car] = action.speed
        return True


@dataclass
class Verdict:
    """Whether the scenario passed, and why (or why not)."""

    passed: bool
    reason: str

    def as_dict(self, scenario: Scenario) -> dict[str, Any]:
        return {"name": scenario.name, "source": scenario.source, "passed": self.passed,
                "reason": self.reason}


class ScenarioJudge:
    """Follows one episode of a scenario (:meth:`update` every env step) and judges it
    against the scenario's success conditions (:meth:`verdict`)."""

    def __init__(self, scenario: Scenario, lane_width: float, lanes: int) -> None:
        self.scenario = scenario
        self.lane_width = lane_width
        self.lanes = lanes
        success = scenario.success
        self.reached_at: float | None = None
        self.left_at: tuple[float, int] | None = None
        self.last_lane: int | None = None
        self.time = 0.0
        self.first_collision: tuple[float, str] | None = None
        self.first_incident: dict[str, float] = {}
        self._reach = success.reach_lane
        self._keep = success.keep_lane

    def lane_of(self, d: float) -> int:
        return math.floor(d / self.lane_width)

    def update(self, time: float, d: float, incidents: list[Any],
               collided_with: str | None = None) -> None:
        """One env step: the time and the ego's d at its end, the incidents it began
        (``collided_with``: the kind of what a collision hit)."""
        self.time = time
        lane = self.lane_of(d)
        self.last_lane = lane
        if self._reach is not None and self.reached_at is None and lane == self._reach[0]:
            self.reached_at = time
        if self._keep is not None and self.left_at is None and lane != self._keep[0] \
                and time <= self._keep[1] + 1e-9:
            self.left_at = (time, lane)
        for incident in incidents:
            self.first_incident.setdefault(incident.kind, incident.time)
            if incident.kind == "collision" and self.first_collision is None:
                self.first_collision = (incident.time, collided_with or "a car")

    def verdict(self, distance: float) -> Verdict:
        """The verdict so far (the final one at the episode's end); ``distance`` driven."""
        success = self.scenario.success
        if success.no_collision and self.first_collision is not None:
            time, kind = self.first_collision
            return Verdict(False, f"collision with {kind} at {time:.2f} s")
        for kind in success.no_incidents:
            if kind in self.first_incident:
                return Verdict(False, f"{kind} incident at {self.first_incident[kind]:.2f} s")
        if self._reach is not None:
            lane, within = self._reach
            if self.reached_at is None or self.reached_at > within + 1e-9:
                when = (f"at {self.reached_at:.2f} s" if self.reached_at is not None
                        else "never")
                return Verdict(False, f"not in lane {lane} within {within:g} s (reached it "
                                      f"{when})")
        if self._keep is not None:
            lane, seconds = self._keep
            if self.left_at is not None:
                return Verdict(False, f"left lane {lane} for lane {self.left_at[1]} at "
                                      f"{self.left_at[0]:.2f} s, before {seconds:g} s")
            if self.time < seconds - 1e-9:
                return Verdict(False, f"the episode ended at {self.time:.2f} s, before "
                                      f"{seconds:g} s in lane {lane}")
        if success.min_distance is not None and distance < success.min_distance:
            return Verdict(False, f"drove {distance:.1f} m, less than {success.min_distance:g} m")
        if success.end_lane is not None and self.last_lane != success.end_lane:
            return Verdict(False, f"ended in lane {self.last_lane}, not {success.end_lane}")
        parts = ["no collision" if success.no_collision else ""]
        if self._reach is not None:
            parts.append(f"lane {self._reach[0]} at {self.reached_at:.2f} s")
        if self._keep is not None:
            parts.append(f"kept lane {self._keep[0]} for {self._keep[1]:g} s")
        if success.min_distance is not None:
            parts.append(f"{distance:.0f} m driven")
        if success.end_lane is not None:
            parts.append(f"ended in lane {success.end_lane}")
        return Verdict(True, "passed: " + ", ".join(part for part in parts if part)
                       + f" in {self.time:.1f} s")
