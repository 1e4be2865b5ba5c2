"""Scenario cars, road objects and parked slots, on top of the traffic kernels.

Random traffic has only traffic cars (:data:`~sdc_gym.traffic.state.TRAFFIC`) and none of
this runs (``TrafficBatch.scripted`` is off). Once a batch holds a scenario or road events,
:class:`~sdc_gym.traffic.batch.TrafficBatch` calls these functions around the kernels,
which stay as they are (the same code for random and scripted traffic): the roles are
expressed through the values the kernels already read, and a few overrides after them.

* a **road object** (:data:`~sdc_gym.traffic.state.OBJECT`: a barrier of a closed lane,
  fallen cargo, an animal, a stalled car) is a slot standing in the lanes its footprint
  touches (``origin`` and ``target_lane``: :func:`footprint_lanes`), so IDM followers in
  those lanes brake for it and lane changes into them wait for it, as for a stopped car;
  it never recycles (its respawn wait never ends), never changes lanes (any the kernels
  start are undone: :func:`after_decision`) and its acceleration is its scripted one
  (0: it stands); its lateral position is its own (``base_d`` plus an animal's walk at
  ``lateral_rate``: :func:`place_objects`);
* a **parked** slot (:data:`~sdc_gym.traffic.state.PARKED`) is in lane -1, which no lane
  test matches: nobody follows it, nobody waits for it; it stands, is never recycled, and
  the world neither senses nor touches it;
* a car with ``hold_lane`` (a scenario's, unless it has ``lane_changes``) does not start
  lane changes of its own, nor does a car under a scripted acceleration (``forced_acc``
  until step ``forced_until``: a scenario's hard braking or stop), which drives at that
  acceleration whatever its leader;
* a traffic car stuck behind a road object (standing, its leader an object within
  :data:`STUCK_BEHIND_OBJECT_M`) merges into a next lane that is clear by the traffic's
  ``lane_change_clearance`` (:func:`merge_stuck`, called by the road events' controller):
  the kernels' own rule needs ``lane_change_min_speed``, the merge at a closed lane.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.traffic.state import IDLE, NEVER, OBJECT, PARKED, TRAFFIC, TrafficState

TrafficBatch = Any  # sdc_gym.traffic.batch.TrafficBatch (typed by name: no import circle)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

STUCK_BEHIND_OBJECT_M = 40.0
"""m (bumper gap): a standing car whose leader is a road object this close may merge."""
STILL_DESIRED_SPEED = 0.1
"""m/s: the IDM desired speed of slots that do not drive (objects, parked), as the ego's
floor; their scripted acceleration overrides what IDM makes of it."""
NEVER_RECYCLED = 2**61
"""A respawn wait no episode outlasts (steps): the slot is never recycled."""


def footprint_lanes(d: float, width: float, lane_width: float, lanes: int) -> tuple[int, int]:
    """``(origin, target_lane)`` of an object at ``d`` of ``width``: the first and last lane
    its footprint touches (equal for one lane), ``(-1, -1)`` off the road."""
    low = math.floor((d - 0.5 * width) / lane_width)
    high = math.floor((d + 0.5 * width) / lane_width)
    low, high = max(low, 0), min(high, lanes - 1)
    return (low, high) if low <= high else (-1, -1)


def start_lane_change(batch: TrafficBatch, st: TrafficState, row: int, car: int, lane: int,
                      duration: float) -> None:
    """Car ``car`` of row ``row`` starts a lane change into ``lane`` now, for ``duration``
    s (a scenario's cut-in, a merge at an object): what the decision kernel writes."""
    now = int(st.step[row])
    st.target_lane[row, car] = lane
    st.lc_start[row, car] = now
    st.lc_end[row, car] = now + math.ceil(duration / batch.dt - 1e-9)
    st.lc_duration[row, car] = duration
    st.pending[row, car], st.held[row, car] = -1, 0


def after_decision(st: TrafficState, lc_start_before: IntArray,
                   rows: NDArray[np.bool_] | None = None) -> None:
    """After a decision of the envs of ``st`` with ``rows`` (default all;
    ``lc_start_before``: ``lc_start`` before it): undo the lane changes the kernels started
    for slots that hold their lane (objects, parked, ``hold_lane``, a scripted acceleration
    in force), and put each scripted acceleration in force in place of the decided one."""
    now = st.step[:, None]
    forced = now < st.forced_until
    if rows is not None:
        forced &= rows[:, None]
    held = (st.role != TRAFFIC) | (st.hold_lane != 0) | forced
    undo = held & (st.lc_start == now) & (lc_start_before != now)
    if np.count_nonzero(undo):
        st.target_lane[undo] = st.origin[undo]
        st.lc_start[undo] = NEVER
        st.lc_end[undo] = IDLE
    if np.count_nonzero(forced):
        st.acc[forced] = st.forced_acc[forced]
        st.half_acc[forced] = 0.5 * st.forced_acc[forced]


def place_objects(geometry: Any, st: TrafficState, step0: IntArray, samples: Any,
                  rows: IntArray | None = None) -> None:
    """The road objects (and parked slots) where they are in a window's ``samples``
    (``(envs, frames, cars)``, written in place; frame ``k`` is step ``step0 + k + 1``):
    at d = ``base_d + lateral_rate * dt * (clip(step, from, until) - from)``, moving across
    at the rate while the step is in ``[from, until)``, their pose from the same
    ``geometry.pose`` as the cars'. Whatever the kernels made of them laterally is replaced.
    ``rows``: the envs of ``st`` that the samples' rows are (default all); ``step0`` per
    row."""
    role = st.role if rows is None else st.role[rows]
    row, car = np.nonzero(role != TRAFFIC)
    if not len(row):
        return
    env = row if rows is None else np.asarray(rows)[row]
    frames = samples.s.shape[1]
    steps = step0[row][:, None] + np.arange(1, frames + 1)[None, :]
    start = st.lateral_from[env, car][:, None]
    until = st.lateral_until[env, car][:, None]
    rate = st.lateral_rate[env, car][:, None]
    walked = (np.minimum(np.maximum(steps, start), until) - start) * geometry.dt
    d = st.base_d[env, car][:, None] + rate * walked
    d_dot = np.where((steps >= start) & (steps < until), rate, 0.0)
    placed = geometry.pose(samples.s[row, :, car], d, samples.speed[row, :, car], d_dot)
    for name in ("s", "d", "speed", "x", "y", "heading", "vx", "vy"):
        getattr(samples, name)[row, :, car] = getattr(placed, name)


def object_d(st: TrafficState, row: int, car: int, dt: float) -> float:
    """A road object's d at its row's current step."""
    step = int(st.step[row])
    start, until = int(st.lateral_from[row, car]), int(st.lateral_until[row, car])
    walked = (min(max(step, start), until) - start) * dt
    return float(st.base_d[row, car] + st.lateral_rate[row, car] * walked)


def merge_stuck(batch: TrafficBatch, st: TrafficState, row: int) -> None:
    """Traffic cars of row ``row`` standing behind a road object (within
    :data:`STUCK_BEHIND_OBJECT_M`) start a lane change into a next lane clear by
    ``lane_change_clearance`` (centre to centre, every slot and the ego), the lane
    towards the middle first."""
    cfg = batch.config
    reference = batch.reference
    objects = np.flatnonzero(st.role[row] == OBJECT)
    if not len(objects):
        return
    stuck = np.flatnonzero((st.role[row] == TRAFFIC) & (st.hold_lane[row] == 0)
                           & (st.lc_end[row] == IDLE)
                           & (st.speed[row] < cfg.lane_change_min_speed)
                           & (int(st.step[row]) >= st.forced_until[row]))
    if not len(stuck):
        return
    live = st.role[row] != PARKED
    lanes_of = np.stack([st.origin[row], st.target_lane[row]])
    ego_low, ego_high = footprint_lanes(float(st.ego_d[row]), cfg.ego_width,
                                        batch.lane_width, batch.lanes)
    middle = 0.5 * (batch.lanes - 1)
    for car in stuck.tolist():
        lane = int(st.origin[row, car])
        ahead = reference.s_difference(st.s[row, objects], st.s[row, car])
        gap = ahead - st.half_length[row, objects] - st.half_length[row, car]
        in_lane = (lanes_of[0, objects] <= lane) & (lanes_of[1, objects] >= lane)
        if not np.any(in_lane & (ahead > 0.0) & (gap < STUCK_BEHIND_OBJECT_M)):
            continue
        for target in sorted((lane - 1, lane + 1), key=lambda x: abs(x - middle)):
            if not 0 <= target < batch.lanes:
                continue
            there = live & ((lanes_of[0] == target) | (lanes_of[1] == target))
            there[car] = False
            near = np.abs(reference.s_difference(st.s[row], st.s[row, car]))
            blocked = bool(np.any(there & (near < cfg.lane_change_clearance)))
            ego_near = abs(float(reference.s_difference(st.ego_s[row], st.s[row, car])))
            if ego_low <= target <= ego_high and ego_near < cfg.lane_change_clearance:
                blocked = True
            if not blocked:
                start_lane_change(batch, st, row, car, target, cfg.lane_change_duration)
                break
