"""What the traffic kernels do differently for scenario cars, road objects and parked slots.

Random traffic has only traffic cars (:data:`~sdc_gym.traffic.state.TRAFFIC`), and the
kernels skip everything here (``TrafficBatch.scripted`` is off). Once a batch holds a
scenario or road events, these small masks and terms enter the decision and motion
kernels (:mod:`sdc_gym.traffic.decisions`, :mod:`sdc_gym.traffic.kinematics`); with every
slot a plain traffic car they change nothing, to the bit:

* a **road object** (:data:`~sdc_gym.traffic.state.OBJECT`: a barrier of a closed lane,
  fallen cargo, an animal) occupies every lane its footprint touches (so IDM followers in
  those lanes brake for it and lane changes into them wait), is never recycled and never
  decides: its acceleration is its scripted one (0, standing still);
* a **parked** slot (:data:`~sdc_gym.traffic.state.PARKED`) occupies no lane: nobody
  follows it, nobody waits for it, it is never recycled (nor sensed, nor touched: the
  world masks it);
* a car with ``hold_lane`` does not change lanes of its own; a car under a scripted
  acceleration (``forced_acc`` until ``forced_until``: a scenario's hard braking or stop)
  does not either, and drives at that acceleration whatever its leader;
* a traffic car stuck behind a road object (its leader, within
  :data:`STUCK_BEHIND_OBJECT_M`) may merge into the next lane at any speed, also from a
  standstill (the normal rule needs ``lane_change_min_speed``): the merge at a closed lane.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.traffic.gather import gather
from sdc_gym.traffic.state import OBJECT, PARKED, TRAFFIC, TrafficState

TrafficBatch = Any  # sdc_gym.traffic.batch.TrafficBatch (typed by name: no import circle)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

STUCK_BEHIND_OBJECT_M = 40.0
"""m (bumper gap): a car whose leader is a road object this close may merge at any speed."""
MIN_DESIRED_SPEED = 0.1
"""m/s: IDM's desired speed of slots that do not drive (objects, parked), as the ego's."""


def occupy_footprints(batch: TrafficBatch, st: TrafficState, cars: NDArray[np.bool_]) -> None:
    """Road objects occupy the lanes their footprint touches (``cars``: ``(envs, lanes,
    cars)``, written in place); parked slots none."""
    role = st.role[:, None, :]
    is_object = role == OBJECT
    if np.count_nonzero(is_object):
        half = 0.5 * st.width[:, None, :]
        lane = batch.lane_column
        low = np.floor((st.d[:, None, :] - half) / batch.lane_width)
        high = np.floor((st.d[:, None, :] + half) / batch.lane_width)
        np.copyto(cars, (lane >= low) & (lane <= high), where=is_object)
    cars &= role != PARKED


def recyclable(st: TrafficState, rel: FloatArray) -> FloatArray:
    """``rel`` of the cars, with 0 for the slots that are never recycled (objects, parked)."""
    return np.where(st.role == TRAFFIC, rel, 0.0)


def live(st: TrafficState, rel: FloatArray) -> FloatArray:
    """``rel`` of every object (cars, then the ego), with 0 for the parked slots: only the
    others decide whether gaps need folding."""
    out = rel.copy()
    out[:, :-1] = np.where(st.role == PARKED, 0.0, rel[:, :-1])
    return out


def desired_speeds(st: TrafficState) -> FloatArray:
    """IDM's desired speeds, floored at :data:`MIN_DESIRED_SPEED` (objects stand still)."""
    return np.maximum(st.desired, MIN_DESIRED_SPEED)


def stuck_behind_object(st: TrafficState, leaders: IntArray, own: IntArray,
                        own_gap: FloatArray) -> NDArray[np.bool_]:
    """``(envs, cars)``: the car's own leader is a road object within
    :data:`STUCK_BEHIND_OBJECT_M` (``leaders``: ``(envs, lanes, cars)`` object indices,
    ``own`` the lane of each car's own leader, ``own_gap`` its bumper gap)."""
    role_all = np.concatenate([st.role, np.full((st.envs, 1), TRAFFIC)], axis=1)
    leader = gather(leaders.transpose(0, 2, 1), own.transpose(0, 2, 1))[..., 0]
    return (gather(role_all, leader) == OBJECT) & (own_gap[:, 0] < STUCK_BEHIND_OBJECT_M)


def free_to_decide(st: TrafficState, now: IntArray) -> NDArray[np.bool_]:
    """``(envs, cars)``: traffic cars without ``hold_lane`` and without a scripted
    acceleration in force: the ones that may start lane changes of their own."""
    return (st.role == TRAFFIC) & (st.hold_lane == 0) & (now >= st.forced_until)


def scripted_acceleration(st: TrafficState, now: IntArray, acc: FloatArray) -> FloatArray:
    """The decided accelerations, with each scripted one in force instead."""
    return np.where(now < st.forced_until, st.forced_acc, acc)


def lateral_terms(state: Any, frames: IntArray, dt: float, d: FloatArray,
                  d_dot: FloatArray) -> None:
    """Add each slot's lateral offset and scripted drift to ``d`` and ``d_dot``
    (``(envs, frames, cars)``, in place) at the absolute steps ``frames``
    (``(envs, frames, 1)``): ``d_offset + lateral_rate * dt * (clip(step, from, until) -
    from)``, and the rate while the step is in ``[from, until)``."""
    moved = (state.d_offset != 0.0) | (state.lateral_rate != 0.0)
    if not np.count_nonzero(moved):
        return
    env, car = np.nonzero(moved)
    steps = np.broadcast_to(frames, (*d.shape[:2], 1))[env, :, 0]
    start = state.lateral_from[env, car][:, None]
    until = state.lateral_until[env, car][:, None]
    rate = state.lateral_rate[env, car][:, None]
    walked = (np.minimum(np.maximum(steps, start), until) - start) * dt
    d[env, :, car] += state.d_offset[env, car][:, None] + rate * walked
    d_dot[env, :, car] += np.where((steps >= start) & (steps < until), rate, 0.0)
