"""Road events as traffic slots: a closed lane, fallen cargo, an animal crossing.

Each event puts road objects (:data:`~sdc_gym.traffic.state.OBJECT` slots,
:mod:`sdc_gym.traffic.roles`) into the object columns of the traffic, so that everything
that deals with cars deals with them too, with no code of its own: IDM followers brake
for them (a stopped leader), traffic changes lanes away from them (the lane behind one
offers less acceleration; a car stuck behind one merges even from a standstill), lane
changes into a lane they block wait (clearance), the ego's contact test sees them (a
``collision`` incident, whose value is the object's id), the sensors report them as
sensor-fusion rows (ids after the cars', zero velocity but an animal's) and the renderer
draws them.

* **Closed lane** (``closed_lane``): cones and barriers closing ``lane`` from ``s`` over
  ``length`` m, as a chain of :data:`~sdc_gym.traffic.vehicle_types.BARRIER` pieces of
  8 m (the last one shorter), so that the closure follows the road's bends. Traffic in the
  lane merges out before it; the ego must too.
* **Fallen cargo** (``cargo``): one :data:`~sdc_gym.traffic.vehicle_types.CARGO` object
  (1.4 m x 1.2 m unless sized) at ``offset`` m from the lane's centre.
* **Animal** (``animal``): an :data:`~sdc_gym.traffic.vehicle_types.ANIMAL` (1.6 m x
  0.6 m) that walks across the road at ``speed`` m/s from ``from_d`` to ``to_d`` (m right
  of the centre line), occupying each lane while its body is in it, and leaves the road.

Random events on the loop (:class:`RandomRoadEvents`, config ``road_events``): each kind
has a rate per km the ego drives; an event appears ``spawn_ahead`` m ahead of the ego
(beyond the sensors' and the traffic's reach, so nothing pops up in view), in a random
lane, and is cleared (its slots parked) once the ego is ``clear_behind`` m past it. The
draws come from the env's generator, at the traffic's decision instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sdc_gym.traffic.roles import footprint_lanes, merge_stuck, object_d
from sdc_gym.traffic.slots import SlotSpec, park, write_slot
from sdc_gym.traffic.state import OBJECT, PARKED, TrafficState
from sdc_gym.traffic.vehicle_types import ANIMAL, BARRIER, CARGO, KINDS

TrafficBatch = Any  # sdc_gym.traffic.batch.TrafficBatch (typed by name: no import circle)

BARRIER_PIECE_M = KINDS[BARRIER].length
LEFT_ROAD_AT_M = 1.5  # m beyond the road's edge where a crossing animal is gone


def slots_needed(event: Any) -> int:
    """Object slots a :class:`~sdc_gym.scenarios.model.RoadEvent` (or an event of the
    same fields) fills: one per barrier piece of a closed lane, else one."""
    if event.kind == "closed_lane":
        return max(1, math.ceil(event.length / BARRIER_PIECE_M - 1e-9))
    return 1


@dataclass
class ActiveEvent:
    """A road event on the road: ``kind``, its stretch of road ``s_start`` to ``s_end``
    (wrapped; ``s_end`` may pass the loop's end), the ``lane`` it blocks (an animal's: -1,
    it crosses them all), its object slots, and an animal's walk (``walk``: rate m/s and
    steps; it starts once its ``trigger`` holds, see :func:`trigger_met`)."""

    kind: str
    s_start: float
    s_end: float
    lane: int
    slots: list[int]
    walk: tuple[float, int] | None = None
    walking: bool = False
    trigger: tuple[str, float] = ("time", 0.0)
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self, loop: float) -> dict[str, Any]:
        """Plain numbers for ``info["road_events"]`` (and replays)."""
        return {"kind": self.kind, "lane": self.lane, "s_start": self.s_start,
                "s_end": self.s_end % loop, "ids": list(self.slots), **self.extra}


def event_slots(kind: str, s: float, lane: int, lane_width: float, road_width: float, *,
                length: float = 150.0, offset: float = 0.0,
                size: tuple[float, float] | None = None, from_d: float = -1.5,
                to_d: float | None = None, speed: float = 1.5, dt: float = 0.02
                ) -> tuple[list[SlotSpec], ActiveEvent]:
    """The slot specs of one event (``s``: a closed lane's start, else the object's
    centre) and its record (with the slots still to be numbered)."""
    if kind == "closed_lane":
        count = slots_needed(_Length(length))
        pieces = []
        for k in range(count):
            start = k * BARRIER_PIECE_M
            piece = min(BARRIER_PIECE_M, length - start)
            pieces.append(SlotSpec(OBJECT, BARRIER, s + start + 0.5 * piece, lane,
                                   hold_lane=True, forced_until_steps=None,
                                   length=piece if piece != BARRIER_PIECE_M else None))
        return pieces, ActiveEvent(kind, s, s + length, lane, [], extra={"length": length})
    if kind == "cargo":
        length_m, width_m = size if size is not None else (KINDS[CARGO].length,
                                                           KINDS[CARGO].width)
        spec = SlotSpec(OBJECT, CARGO, s, lane, hold_lane=True, forced_until_steps=None,
                        length=length_m, width=width_m, d_offset=offset)
        return [spec], ActiveEvent(kind, s - 0.5 * length_m, s + 0.5 * length_m, lane, [],
                                   extra={"offset": offset, "size": [length_m, width_m]})
    if kind == "animal":
        to_d = road_width + LEFT_ROAD_AT_M if to_d is None else to_d
        start_lane = math.floor(from_d / lane_width)
        rate = math.copysign(speed, to_d - from_d)
        steps = max(1, round(abs(to_d - from_d) / speed / dt))
        spec = SlotSpec(OBJECT, ANIMAL, s, start_lane, hold_lane=True,
                        forced_until_steps=None,
                        d_offset=from_d - (start_lane + 0.5) * lane_width)
        half = 0.5 * KINDS[ANIMAL].length
        return [spec], ActiveEvent(kind, s - half, s + half, -1, [], walk=(rate, steps),
                                   extra={"from_d": from_d, "to_d": to_d, "speed": speed})
    raise ValueError(f"unknown road event kind {kind!r}; the kinds are closed_lane, cargo, "
                     "animal")


@dataclass(frozen=True)
class _Length:
    length: float
    kind: str = "closed_lane"


def trigger_met(trigger: tuple[str, float], time: float, gap: float, driven: float) -> bool:
    """Whether a trigger ``(kind, value)`` holds: the episode's ``time`` (s) has reached
    ``time``; the gap (s of the thing minus the ego's, > 0 ahead) has fallen to
    ``gap_below`` or risen to ``gap_above``; the ego has ``driven`` ``ego_distance`` m."""
    kind, value = trigger
    if kind == "time":
        return time >= value - 1e-9
    if kind == "gap_below":
        return gap <= value
    if kind == "gap_above":
        return gap >= value
    if kind == "ego_distance":
        return driven >= value
    raise ValueError(f"unknown trigger {kind!r}")


def free_object_slots(batch: TrafficBatch, st: TrafficState, row: int) -> list[int]:
    """The parked object columns of ``row`` (after the car slots)."""
    cars = batch.config.car_count
    return [cars + int(i) for i in np.flatnonzero(st.role[row, cars:] == PARKED)]


def place_event(batch: TrafficBatch, st: TrafficState, row: int, specs: list[SlotSpec],
                event: ActiveEvent, rng: np.random.Generator) -> bool:
    """Write an event's objects into free object slots of ``row``; ``False`` (nothing
    written) when there are not enough."""
    free = free_object_slots(batch, st, row)
    if len(free) < len(specs):
        return False
    event.slots = free[:len(specs)]
    for i, spec in zip(event.slots, specs, strict=False):
        write_slot(batch, st, row, i, spec, rng)
    return True


def start_walk(st: TrafficState, row: int, event: ActiveEvent) -> None:
    """An animal starts walking now (its drift from this step on)."""
    assert event.walk is not None
    rate, steps = event.walk
    now = int(st.step[row])
    for i in event.slots:
        st.lateral_rate[row, i] = rate
        st.lateral_from[row, i] = now
        st.lateral_until[row, i] = now + steps
    event.walking = True


def clear_event(st: TrafficState, row: int, event: ActiveEvent) -> None:
    """Take an event off the road: its slots parked."""
    for i in event.slots:
        park(st, row, i)


def gone(batch: TrafficBatch, st: TrafficState, row: int, event: ActiveEvent,
         clear_behind: float) -> bool:
    """Whether the ego is ``clear_behind`` m past the event, or an animal has walked off
    the road (its walk over)."""
    behind = batch.reference.s_difference(st.ego_s[row], event.s_end % batch.loop)
    if 0.0 < behind < batch.half_loop and behind > clear_behind:
        return True
    if event.walking and event.walk is not None:
        return int(st.step[row]) >= int(st.lateral_until[row, event.slots[0]]) + 50
    return False


@dataclass(frozen=True)
class RoadEventRates:
    """Random road events on the loop (config ``road_events``).

    Attributes:
        object_slots: object columns of the traffic (0: no road events at all).
        closed_lane_per_km, cargo_per_km, animal_per_km: expected events per km the
            ego drives (0: none of the kind).
        spawn_ahead: (min, max) m ahead of the ego where a random event appears.
        clear_behind: m behind the ego beyond which an event is taken off the road.
        closed_lane_length: (min, max) m of a random closed lane.
        animal_speed: (min, max) m/s of a random animal's walk.
    """

    object_slots: int = 0
    closed_lane_per_km: float = 0.0
    cargo_per_km: float = 0.0
    animal_per_km: float = 0.0
    spawn_ahead: tuple[float, float] = (260.0, 340.0)
    clear_behind: float = 150.0
    closed_lane_length: tuple[float, float] = (80.0, 200.0)
    animal_speed: tuple[float, float] = (1.0, 3.0)

    @property
    def random(self) -> bool:
        return (self.closed_lane_per_km + self.cargo_per_km + self.animal_per_km) > 0.0


class RoadEvents:
    """An env's road events: the ones on the road, and (with rates) the random ones to
    come. It is the env's traffic controller (called at its decision instants), or part of
    a scenario's (:mod:`sdc_gym.scenarios.runtime`)."""

    def __init__(self, rates: RoadEventRates, rng: np.random.Generator,
                 start_step: int = 0) -> None:
        self.rates = rates
        self.rng = rng
        self.active: list[ActiveEvent] = []
        self.start_step = start_step
        self.last_ego_s: float | None = None
        self.driven = 0.0  # m the ego drove since the reset (at decision instants)
        self.time = 0.0  # s since the reset, at the last decision instant

    def track_ego(self, batch: TrafficBatch, st: TrafficState, row: int) -> float:
        """Update the time and the distance driven; the metres since the last call."""
        ego_s = float(st.ego_s[row])
        step = 0.0
        if self.last_ego_s is not None:
            step = max(float(batch.reference.s_difference(ego_s, self.last_ego_s)), 0.0)
        self.last_ego_s = ego_s
        self.driven += step
        self.time = (int(st.step[row]) - self.start_step) * batch.dt
        return step

    def before_decision(self, batch: TrafficBatch, st: TrafficState, row: int) -> None:
        step = self.track_ego(batch, st, row)
        self.update(batch, st, row)
        if self.rates.random and step > 0.0:
            self._spawn(batch, st, row, step)

    def update(self, batch: TrafficBatch, st: TrafficState, row: int) -> None:
        """Start the walks whose trigger holds, move the walking animals' lanes; take the
        events passed off the road; let the cars stuck behind an object merge."""
        for event in list(self.active):
            if event.walk is not None and not event.walking:
                gap = float(batch.reference.s_difference(st.s[row, event.slots[0]],
                                                         st.ego_s[row]))
                if trigger_met(event.trigger, self.time, gap, self.driven):
                    start_walk(st, row, event)
            if event.walking:
                for i in event.slots:  # the lanes its body is in now
                    st.origin[row, i], st.target_lane[row, i] = footprint_lanes(
                        object_d(st, row, i, batch.dt), float(st.width[row, i]),
                        batch.lane_width, batch.lanes)
            if gone(batch, st, row, event, self.rates.clear_behind):
                clear_event(st, row, event)
                self.active.remove(event)
        merge_stuck(batch, st, row)

    def _spawn(self, batch: TrafficBatch, st: TrafficState, row: int, driven: float) -> None:
        rates = self.rates
        rng = self.rng
        for kind, per_km in (("closed_lane", rates.closed_lane_per_km),
                             ("cargo", rates.cargo_per_km),
                             ("animal", rates.animal_per_km)):
            if per_km <= 0.0 or rng.random() >= per_km * driven / 1000.0:
                continue
            ahead = rng.uniform(*rates.spawn_ahead)
            lane = int(rng.integers(0, batch.lanes))
            s = float(batch.reference.wrap_s(st.ego_s[row] + ahead))
            options: dict[str, Any] = {}
            if kind == "closed_lane":
                options["length"] = float(rng.uniform(*rates.closed_lane_length))
            elif kind == "cargo":
                options["offset"] = float(rng.uniform(-1.0, 1.0))
            else:
                side = rng.random() < 0.5
                road = batch.lanes * batch.lane_width
                options["from_d"], options["to_d"] = ((-LEFT_ROAD_AT_M, road + LEFT_ROAD_AT_M)
                                                      if side else
                                                      (road + LEFT_ROAD_AT_M, -LEFT_ROAD_AT_M))
                options["speed"] = float(rng.uniform(*rates.animal_speed))
            specs, event = event_slots(kind, s, lane, batch.lane_width,
                                       batch.lanes * batch.lane_width, dt=batch.dt,
                                       **options)
            if kind == "animal":  # it waits by the road until the ego comes near
                event.trigger = ("gap_below", float(rng.uniform(40.0, 120.0)))
            if place_event(batch, st, row, specs, event, rng):
                self.active.append(event)

    def records(self, loop: float) -> list[dict[str, Any]]:
        """The events on the road, as plain numbers."""
        return [event.as_dict(loop) for event in self.active]
