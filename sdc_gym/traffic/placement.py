"""Placing traffic cars: the layout at reset and the respawn of recycled cars.

Both work on one env's row of a :class:`~sdc_gym.traffic.state.TrafficState` at a time
(VMAS's ``reset_world_at(env_index)``): they draw from that env's generator, a car at a
time, so a row is laid out exactly as a single env with that generator would lay it out.
The rules are in :mod:`sdc_gym.traffic.highway_traffic` ("Respawn rule").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.traffic.config import MPH
from sdc_gym.traffic.idm import desired_gap, max_speed_for_gap
from sdc_gym.traffic.state import IDLE, NEVER, TrafficState
from sdc_gym.traffic.vehicle_types import VEHICLE_TYPES

# The kernels take the batch (sdc_gym.traffic.batch.TrafficBatch, which imports them) for
# its constants: typed by name only, so that the modules do not import each other.
TrafficBatch = Any

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

SPAWN_CANDIDATES = 24  # random spots tried per side when placing one car
RESPAWN_RETRY_STEPS = 100  # a car that found no room to respawn retries after this
RESPAWN_PAUSE_STEPS = 50  # and after any such failure nobody tries for this long


def new_car(batch: TrafficBatch, st: TrafficState, r: int, i: int, type_index: int,
            s: float, lane: int, speed: float, desired: float,
            rng: np.random.Generator) -> None:
    """Write a fresh car into slot ``i`` of row ``r``."""
    cfg = batch.config
    vtype = VEHICLE_TYPES[type_index]
    st.type_index[r, i] = type_index
    st.length[r, i] = vtype.length
    st.width[r, i] = vtype.width
    st.half_length[r, i] = 0.5 * vtype.length
    st.a_max[r, i] = vtype.comfort_accel
    st.tsab[r, i] = 2.0 * math.sqrt(vtype.comfort_accel * vtype.comfort_decel)
    st.s[r, i] = s
    st.speed[r, i] = speed
    st.desired[r, i] = desired
    st.origin[r, i] = st.target_lane[r, i] = lane
    st.respawn_wait[r, i] = 0
    st.lc_start[r, i] = NEVER
    st.lc_end[r, i] = IDLE
    st.pending[r, i] = -1
    st.held[r, i] = 0
    st.acc[r, i] = st.half_acc[r, i] = 0.0
    st.brake_until[r, i] = st.cut_in_until[r, i] = 0
    omega = st.omega[r]
    phase = st.phase[r]
    omega[i] = 2.0 * np.pi / rng.uniform(*cfg.wander_period)
    phase[i] = rng.uniform(0.0, 2.0 * np.pi)
    st.wander_speed[r, i] = cfg.lateral_wander * omega[i]
    st.d[r, i] = (lane + 0.5) * batch.lane_width + cfg.lateral_wander * math.sin(
        omega[i] * int(st.step[r]) * batch.dt + phase[i])


def _row_objects(batch: TrafficBatch, st: TrafficState, r: int
                 ) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_],
                            FloatArray, FloatArray, FloatArray]:
    """Row ``r``'s objects (the cars, then the ego): s, d, speed, occupied lanes, half
    lengths, IDM a_max and 2 sqrt(a_max b)."""
    cfg = batch.config
    s_all = np.append(st.s[r], st.ego_s[r])
    d_all = np.append(st.d[r], st.ego_d[r])
    v_all = np.append(st.speed[r], st.ego_speed[r])
    lanes = batch.lane_ids
    occupies = np.vstack([(lanes == st.origin[r][:, None]) | (lanes == st.target_lane[r][:, None]),
                          batch.ego_lanes(st.ego_d[r:r + 1])])
    half = np.append(st.half_length[r], batch.ego_half_length)
    a = np.append(st.a_max[r], cfg.idm.a_max)
    tsab = np.append(st.tsab[r], batch.ego_tsab)
    return s_all, d_all, v_all, occupies, half, a, tsab


def find_spot(batch: TrafficBatch, st: TrafficState, r: int, placed: NDArray[np.bool_],
              type_index: int, offsets: FloatArray, lanes: IntArray,
              desired: FloatArray) -> tuple[int, float]:
    """First candidate (ego s + offset, lane) satisfying the respawn rule, and its speed.

    ``placed`` masks the cars that count; the ego always counts. Returns (-1, 0.0)
    when no candidate fits.
    """
    cfg = batch.config
    reference = batch.reference
    vtype = VEHICLE_TYPES[type_index]
    s_all, d_all, v_all, occupies, half, a_all, tsab_all = _row_objects(batch, st, r)
    idx = np.append(np.flatnonzero(placed), st.cars)  # the ego is object n
    s_o = s_all[idx]
    len_o = 2.0 * half[idx]
    v_o = v_all[idx]
    occ_o = occupies[idx]
    s_c = reference.wrap_s(st.ego_s[r] + offsets)
    scale_c = 1.0 + batch.geometry.curvature(s_c) * ((lanes + 0.5) * batch.lane_width)
    scale_o = 1.0 + batch.geometry.curvature(s_o) * d_all[idx]

    inlane = occ_o[:, lanes].T  # (candidates, objects)
    delta = reference.s_difference(s_o[None, :], s_c[:, None])
    ahead = np.where(inlane & (delta >= 0.0), delta, np.inf)
    behind = np.where(inlane & (delta < 0.0), -delta, np.inf)
    rows = np.arange(len(s_c))
    li = ahead.argmin(axis=1)
    fi = behind.argmin(axis=1)
    gap_lead = ahead[rows, li] * scale_c - 0.5 * (vtype.length + len_o[li])
    gap_follow = behind[rows, fi] * scale_o[fi] - 0.5 * (vtype.length + len_o[fi])
    speed = np.minimum(desired, max_speed_for_gap(
        gap_lead, v_o[li], cfg.idm, vtype.comfort_accel, vtype.comfort_decel))
    # The follower (a car or the ego) must not find the newcomer inside its desired
    # gap: it then brakes by at most its a_max, never hard.
    a_f = a_all[idx][fi]
    b_f = (0.5 * tsab_all[idx][fi]) ** 2 / a_f
    ok = (
        (gap_lead >= cfg.spawn_min_gap)
        & (gap_follow >= cfg.spawn_min_gap)
        & (gap_follow >= desired_gap(v_o[fi], speed, cfg.idm, a_f, b_f))
    )
    if not ok.any():
        return -1, 0.0
    k = int(ok.argmax())
    return k, float(speed[k])


def place(batch: TrafficBatch, st: TrafficState, r: int, i: int,
          placed: NDArray[np.bool_], rng: np.random.Generator, offsets: FloatArray) -> bool:
    """Draw a type, lanes and desired speeds for car ``i``; place it if a spot fits."""
    cfg = batch.config
    type_index = int(rng.choice(len(VEHICLE_TYPES), p=batch.type_p))
    lanes = rng.integers(0, batch.lanes, size=len(offsets))
    u = rng.random(len(offsets))
    lo_a, hi_a = cfg.speed_ahead_mph
    lo_b, hi_b = cfg.speed_behind_mph
    desired = MPH * np.where(offsets > 0, lo_a + u * (hi_a - lo_a), lo_b + u * (hi_b - lo_b))
    cap = VEHICLE_TYPES[type_index].max_speed_mph
    if cap < math.inf:  # a coach or a semi keeps to its own limit
        desired = np.minimum(desired, MPH * cap)
    k, speed = find_spot(batch, st, r, placed, type_index, offsets, lanes, desired)
    if k < 0:
        return False
    s = float(batch.reference.wrap_s(st.ego_s[r] + offsets[k]))
    new_car(batch, st, r, i, type_index, s, int(lanes[k]), speed, float(desired[k]), rng)
    return True


def recycle(batch: TrafficBatch, st: TrafficState, r: int, rel: FloatArray,
            rng: np.random.Generator) -> bool:
    """Respawn (a few of) row ``r``'s cars further than ``spawn_range`` from the ego.

    ``rel`` is each car's s minus the ego's (folded). Returns whether any car moved.
    """
    step = int(st.step[r])
    if step < st.respawn_blocked_until[r]:
        return False
    far = (np.abs(rel) > batch.range) & (st.respawn_wait[r] <= step)
    if not np.count_nonzero(far):
        return False
    cfg = batch.config
    idx = np.flatnonzero(far)
    idx = idx[np.argsort(-np.abs(rel[idx]), kind="stable")][: cfg.respawn_per_decision]
    moved = False
    (lo_a, hi_a), (lo_b, hi_b) = batch.respawn_bands
    for i in idx:
        placed = np.ones(st.cars, dtype=bool)
        placed[i] = False
        # The original's coin: ahead (slow) or behind (fast), whatever side it left.
        ahead = rng.random() < cfg.respawn_ahead_probability
        spots_ahead = rng.uniform(lo_a, hi_a, size=SPAWN_CANDIDATES)
        spots_behind = -rng.uniform(lo_b, hi_b, size=SPAWN_CANDIDATES)
        # The picked side's spots first, then the other side's (no room on the first).
        offsets = np.concatenate((spots_ahead, spots_behind) if ahead
                                 else (spots_behind, spots_ahead))
        if place(batch, st, r, int(i), placed, rng, offsets):
            st.spawn_count[r, i] += 1  # the slot keeps its id, as the original's cars
            moved = True
        else:  # no room (dense traffic): the car drives on; retry in a while
            st.respawn_wait[r, i] = step + RESPAWN_RETRY_STEPS
            st.respawn_blocked_until[r] = step + RESPAWN_PAUSE_STEPS
            break  # the others would not fit either, most likely
    return moved


def _free_spot(batch: TrafficBatch, st: TrafficState, r: int, i: int, rel: FloatArray,
               type_index: int, spread: float, rng: np.random.Generator
               ) -> tuple[float, int] | None:
    """Reset: a centre (s relative to the ego) and lane for car ``i``, drawn uniformly
    over the room that keeps ``spawn_min_gap`` to cars ``0 .. i-1`` and the ego."""
    cfg = batch.config
    half = 0.5 * VEHICLE_TYPES[type_index].length
    others = np.append(rel[:i], 0.0)  # placed cars, then the ego
    reach = (np.append(st.half_length[r, :i], batch.ego_half_length) + half
             + cfg.spawn_min_gap) / batch.geometry.min_scale
    lanes = batch.lane_ids
    placed = (lanes == st.origin[r, :i, None]) | (lanes == st.target_lane[r, :i, None])
    occupied = np.vstack([placed, batch.ego_lanes(st.ego_d[r:r + 1])])
    pieces: list[tuple[int, float, float]] = []
    for lane in range(batch.lanes):
        mask = occupied[:, lane]
        lo, hi = -spread + half, spread - half
        starts, ends = others[mask] - reach[mask], others[mask] + reach[mask]
        order = np.argsort(starts)
        starts, ends = starts[order], np.maximum.accumulate(ends[order])
        # Free room: before the first blocked interval, between them, after the last.
        room_lo = np.concatenate([[lo], ends])
        room_hi = np.concatenate([starts, [hi]])
        room_lo, room_hi = np.maximum(room_lo, lo), np.minimum(room_hi, hi)
        pieces += [(lane, a, b) for a, b in zip(room_lo, room_hi, strict=True) if b > a]
    if not pieces:
        return None
    sizes = np.array([b - a for _, a, b in pieces])
    lane, a, b = pieces[int(rng.choice(len(pieces), p=sizes / sizes.sum()))]
    return float(rng.uniform(a, b)), lane


def _settle_speeds(batch: TrafficBatch, st: TrafficState, r: int) -> None:
    """Reset: slow each car, front to back, to a speed whose IDM gap fits its leader."""
    cfg = batch.config
    n = st.cars
    s_all, _, v_all, occupies, half, a_all, tsab_all = _row_objects(batch, st, r)
    rel = batch.reference.s_difference(s_all, st.ego_s[r])  # the ego has rel 0
    scale = 1.0 + batch.geometry.curvature(s_all[:n]) * st.d[r]
    speed = st.speed[r]
    for i in np.argsort(-rel[:n], kind="stable"):
        lane = st.origin[r, i]
        ahead = occupies[:, lane] & (rel > rel[i])
        if not ahead.any():
            continue
        j = int(np.flatnonzero(ahead)[np.argmin(rel[ahead])])
        gap = (rel[j] - rel[i]) * scale[i] - half[i] - half[j]
        a_i = a_all[i]
        b_i = (tsab_all[i] / 2.0) ** 2 / a_i
        safe = float(max_speed_for_gap(gap, v_all[j], cfg.idm, a_i, b_i))
        speed[i] = v_all[i] = min(speed[i], safe)


def reset_row(batch: TrafficBatch, st: TrafficState, r: int, rng: np.random.Generator,
              ego_s: float, ego_d: float, ego_speed: float) -> None:
    """Lay out row ``r``'s ``car_count`` cars around the ego (see the module docstring).

    Raises ``ValueError`` if the cars cannot be placed within ``spawn_range``.
    """
    cfg = batch.config
    st.clear_rows(r, cfg.lane_change_duration)
    st.ego_s[r], st.ego_d[r], st.ego_speed[r] = float(ego_s) % batch.loop, ego_d, ego_speed
    spread_max = batch.range - 10.0
    spread = min(0.75 * batch.range / cfg.density, spread_max)
    rel = np.zeros(st.cars)
    for i in range(st.cars):
        type_index = int(rng.choice(len(VEHICLE_TYPES), p=batch.type_p))
        while (spot := _free_spot(batch, st, r, i, rel, type_index, spread, rng)) is None:
            if spread >= spread_max:
                raise ValueError(
                    f"cannot place {st.cars} traffic cars within +-{spread_max:.0f} m of "
                    f"the ego on {batch.lanes} lanes; lower car_count or raise spawn_range"
                )
            spread = min(1.25 * spread, spread_max)
        rel[i], lane = spot
        lo, hi = cfg.speed_ahead_mph if rel[i] > 0.0 else cfg.speed_behind_mph
        desired = MPH * rng.uniform(lo, hi)
        desired = min(desired, MPH * VEHICLE_TYPES[type_index].max_speed_mph)
        s = float(batch.reference.wrap_s(st.ego_s[r] + rel[i]))
        new_car(batch, st, r, i, type_index, s, lane, desired, desired, rng)
    _settle_speeds(batch, st, r)


def reset_row_to(batch: TrafficBatch, st: TrafficState, r: int, rng: np.random.Generator,
                 ego_s: float, ego_d: float, ego_speed: float, s: FloatArray,
                 lane: IntArray, speed: FloatArray, desired: FloatArray,
                 types: IntArray) -> None:
    """Row ``r`` from explicit cars (``len(s) == st.cars``)."""
    st.clear_rows(r, batch.config.lane_change_duration)
    st.ego_s[r], st.ego_d[r], st.ego_speed[r] = (float(ego_s) % batch.loop, float(ego_d),
                                                 float(ego_speed))
    for i in range(st.cars):
        new_car(batch, st, r, i, int(types[i]), float(s[i] % batch.loop), int(lane[i]),
                float(speed[i]), float(desired[i]), rng)
