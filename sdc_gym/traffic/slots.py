"""Explicit traffic slots: what a scenario, a road event or a replay puts into the traffic.

A random reset lays cars out by the respawn rules (:mod:`sdc_gym.traffic.placement`). A
scenario says where every slot starts instead: a :class:`SlotSpec` per slot (a traffic
car, a road object, or nothing: parked), which :func:`write_slot` writes into one row of
a :class:`~sdc_gym.traffic.state.TrafficState`. A traffic car is written by the same
:func:`~sdc_gym.traffic.placement.new_car` as a random one (its lateral wander drawn from
the env's generator) unless the spec carries the exact state of a recorded car
(``wander``, a lane change under way, its held acceleration, its sustained lane wish and
timers: what :func:`read_slot` records), which a replay restores to the bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sdc_gym.traffic.placement import new_car
from sdc_gym.traffic.roles import NEVER_RECYCLED, STILL_DESIRED_SPEED, footprint_lanes
from sdc_gym.traffic.state import IDLE, NEVER, OBJECT, PARKED, TRAFFIC, TrafficState
from sdc_gym.traffic.vehicle_types import KINDS

TrafficBatch = Any  # sdc_gym.traffic.batch.TrafficBatch (typed by name: no import circle)


@dataclass(frozen=True)
class LaneChange:
    """A lane change under way: to ``target`` lane, begun ``elapsed_steps`` physics steps
    ago, lasting ``duration`` s."""

    target: int
    elapsed_steps: int
    duration: float


@dataclass(frozen=True)
class SlotSpec:
    """One traffic slot at a reset (see the module docstring).

    Attributes:
        role: :data:`~sdc_gym.traffic.state.TRAFFIC`, ``OBJECT`` or ``PARKED``.
        type_index: index into :data:`~sdc_gym.traffic.vehicle_types.KINDS`.
        s: m along the road (wrapped); lane: the lane it is in (a lane change's origin).
        speed, desired: m/s, its speed and IDM desired speed.
        hold_lane: no lane changes of its own.
        length, width: m, a size other than its kind's (a closed lane's last piece).
        d_offset: m right of its lane's centre: a road object's place across the lane
            (its footprint's lanes are the ones it stands in); traffic cars keep to their
            lane's centre (plus their wander).
        forced_acc, forced_until_steps: a scripted acceleration (m/s^2) in force for this
            many steps from the reset (``None``: for ever; 0: none).
        lateral_rate: m/s, a drift across the road (an animal) from ``lateral_from_steps``
            to ``lateral_until_steps`` after the reset.
        wander: ``(omega, phase)`` of the lateral wander, recorded; ``None``: drawn.
        lane_change, acc, pending, held, brake_in, cut_in_for, respawn_in, spawn_count:
            a recorded car's lane change, held acceleration (m/s^2), sustained lane wish
            (lane, decisions held), rogue braking and cut-in timers and respawn wait
            (steps from the reset), respawns so far.
    """

    role: int
    type_index: int
    s: float
    lane: int
    speed: float = 0.0
    desired: float = 0.0
    hold_lane: bool = False
    length: float | None = None
    width: float | None = None
    d_offset: float = 0.0
    forced_acc: float = 0.0
    forced_until_steps: int | None = 0
    lateral_rate: float = 0.0
    lateral_from_steps: int = 0
    lateral_until_steps: int = 0
    wander: tuple[float, float] | None = None
    lane_change: LaneChange | None = None
    acc: float = 0.0
    pending: int = -1
    held: int = 0
    brake_in: int = 0
    cut_in_for: int = 0
    respawn_in: int = 0
    spawn_count: int = 0


PARKED_SLOT = SlotSpec(PARKED, 0, 0.0, -1)
PARKED_D = -20.0
"""m: where a parked slot waits across the road (well left of it: no contact test can
reach it, whatever the world does)."""


def write_slot(batch: TrafficBatch, st: TrafficState, r: int, i: int, spec: SlotSpec,
               rng: np.random.Generator) -> None:
    """Write ``spec`` into slot ``i`` of row ``r`` (whose ``step`` and ego are set)."""
    if spec.role == PARKED:
        park(st, r, i)
        return
    step = int(st.step[r])
    kind = KINDS[spec.type_index]
    if spec.role == TRAFFIC and spec.wander is None:
        new_car(batch, st, r, i, spec.type_index, spec.s % batch.loop, spec.lane,
                spec.speed, spec.desired, rng)
    else:
        new_car_exact(batch, st, r, i, spec, *(spec.wander or (0.0, 0.0)))
    st.role[r, i] = spec.role
    st.hold_lane[r, i] = int(spec.hold_lane or spec.role == OBJECT)
    if spec.length is not None or spec.width is not None:
        length = kind.length if spec.length is None else spec.length
        st.length[r, i], st.half_length[r, i] = length, 0.5 * length
        st.width[r, i] = kind.width if spec.width is None else spec.width
    until = spec.forced_until_steps
    st.forced_acc[r, i] = spec.forced_acc
    st.forced_until[r, i] = IDLE if until is None else (step + until if until else 0)
    if spec.role == OBJECT:  # it stands (or walks) where it is, in its footprint's lanes
        st.base_d[r, i] = (spec.lane + 0.5) * batch.lane_width + spec.d_offset
        st.d[r, i] = st.base_d[r, i]
        st.desired[r, i] = STILL_DESIRED_SPEED
        st.origin[r, i], st.target_lane[r, i] = footprint_lanes(
            float(st.base_d[r, i]), float(st.width[r, i]), batch.lane_width, batch.lanes)
        st.lateral_rate[r, i] = spec.lateral_rate
        st.lateral_from[r, i] = step + spec.lateral_from_steps
        st.lateral_until[r, i] = step + spec.lateral_until_steps
    if spec.lane_change is not None:
        change = spec.lane_change
        st.target_lane[r, i] = change.target
        st.lc_start[r, i] = step - change.elapsed_steps
        st.lc_end[r, i] = st.lc_start[r, i] + math.ceil(change.duration / batch.dt - 1e-9)
        st.lc_duration[r, i] = change.duration
    st.acc[r, i] = spec.acc
    st.half_acc[r, i] = spec.acc * 0.5
    st.pending[r, i], st.held[r, i] = spec.pending, spec.held
    st.brake_until[r, i] = step + spec.brake_in if spec.brake_in > 0 else 0
    st.cut_in_until[r, i] = step + spec.cut_in_for if spec.cut_in_for > 0 else 0
    st.respawn_wait[r, i] = (NEVER_RECYCLED if spec.role == OBJECT else
                             step + spec.respawn_in if spec.respawn_in > 0 else 0)
    st.spawn_count[r, i] = spec.spawn_count


def park(st: TrafficState, r: int, i: int) -> None:
    """Slot ``i`` of row ``r`` holds nothing: lane -1 (which no lane test matches), no
    speed (a scripted standstill), never recycled, not sensed and not touched (the world
    masks it). It waits at the ego's s, :data:`PARKED_D` left of the road, out of reach."""
    st.role[r, i] = PARKED
    st.type_index[r, i] = 0
    st.length[r, i], st.width[r, i] = KINDS[0].length, KINDS[0].width
    st.half_length[r, i] = 0.5 * KINDS[0].length
    st.a_max[r, i], st.tsab[r, i] = 1.0, 2.0
    st.origin[r, i] = st.target_lane[r, i] = -1
    st.s[r, i] = st.ego_s[r]
    st.d[r, i] = st.base_d[r, i] = PARKED_D
    st.speed[r, i] = st.acc[r, i] = st.half_acc[r, i] = 0.0
    st.desired[r, i] = STILL_DESIRED_SPEED
    st.omega[r, i] = st.phase[r, i] = st.wander_speed[r, i] = 0.0
    st.lateral_rate[r, i] = 0.0
    st.lateral_from[r, i] = st.lateral_until[r, i] = 0
    st.hold_lane[r, i] = 1
    st.forced_acc[r, i], st.forced_until[r, i] = 0.0, IDLE
    st.lc_start[r, i], st.lc_end[r, i] = NEVER, IDLE
    st.pending[r, i], st.held[r, i] = -1, 0
    st.brake_until[r, i] = st.cut_in_until[r, i] = 0
    st.respawn_wait[r, i] = NEVER_RECYCLED


def new_car_exact(batch: TrafficBatch, st: TrafficState, r: int, i: int, spec: SlotSpec,
                  omega: float, phase: float) -> None:
    """A slot with a given wander (``omega`` rad/s, ``phase`` rad; 0, 0 for an object):
    :func:`~sdc_gym.traffic.placement.new_car` without its two draws."""
    kind = KINDS[spec.type_index]
    st.type_index[r, i] = spec.type_index
    st.length[r, i], st.width[r, i] = kind.length, kind.width
    st.half_length[r, i] = 0.5 * kind.length
    st.a_max[r, i] = kind.comfort_accel
    st.tsab[r, i] = 2.0 * math.sqrt(kind.comfort_accel * kind.comfort_decel)
    st.s[r, i] = spec.s % batch.loop
    st.speed[r, i], st.desired[r, i] = spec.speed, spec.desired
    st.origin[r, i] = st.target_lane[r, i] = spec.lane
    st.lc_start[r, i], st.lc_end[r, i] = NEVER, IDLE
    st.omega[r, i], st.phase[r, i] = omega, phase
    st.wander_speed[r, i] = (batch.config.lateral_wander * omega if spec.role == TRAFFIC
                             else 0.0)
    wander = batch.config.lateral_wander if spec.role == TRAFFIC else 0.0
    st.d[r, i] = (spec.lane + 0.5) * batch.lane_width + wander * math.sin(
        omega * int(st.step[r]) * batch.dt + phase)


def read_slot(st: TrafficState, r: int, i: int) -> dict[str, Any]:
    """Slot ``i`` of row ``r`` as plain numbers: everything :class:`SlotSpec` takes, with
    the times counted from the row's current step (what a replay restores)."""
    step = int(st.step[r])
    changing = int(st.target_lane[r, i]) != int(st.origin[r, i])
    until = int(st.forced_until[r, i])
    return {
        "role": int(st.role[r, i]), "type_index": int(st.type_index[r, i]),
        "s": float(st.s[r, i]), "d": float(st.d[r, i]), "lane": int(st.origin[r, i]),
        "speed": float(st.speed[r, i]), "desired": float(st.desired[r, i]),
        "hold_lane": bool(st.hold_lane[r, i]), "length": float(st.length[r, i]),
        "width": float(st.width[r, i]), "base_d": float(st.base_d[r, i]),
        "forced_acc": float(st.forced_acc[r, i]),
        "forced_until_steps": None if until >= IDLE else max(until - step, 0),
        "lateral_rate": float(st.lateral_rate[r, i]),
        "lateral_from_steps": int(st.lateral_from[r, i]) - step,
        "lateral_until_steps": int(st.lateral_until[r, i]) - step,
        "wander": [float(st.omega[r, i]), float(st.phase[r, i])],
        "lane_change": ({"target": int(st.target_lane[r, i]),
                         "elapsed_steps": step - int(st.lc_start[r, i]),
                         "duration": float(st.lc_duration[r, i])} if changing else None),
        "acc": float(st.acc[r, i]), "pending": int(st.pending[r, i]),
        "held": int(st.held[r, i]),
        "brake_in": max(int(st.brake_until[r, i]) - step, 0),
        "cut_in_for": max(int(st.cut_in_until[r, i]) - step, 0),
        "respawn_in": max(int(st.respawn_wait[r, i]) - step, 0),
        "spawn_count": int(st.spawn_count[r, i]),
    }
