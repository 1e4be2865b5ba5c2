"""Placing traffic cars: the layout at reset and the respawn of recycled cars.

Both work on one env's row of a :class:`~sdc_gym.traffic.state.TrafficState` at a time
(VMAS's ``reset_world_at(env_index)``): they draw from that env's generator, a car at a
time, so a row is laid out exactly as a single env with that generator would lay it out.
The rules are in :mod:`sdc_gym.traffic.highway_traffic` ("Respawn rule"). A respawn's
search over its candidate spots (:func:`find_spot`) and the writing of a car
(:func:`write_car`) are compiled; the draws stay the generator's own calls, in order.
"""

from __future__ import annotations

import math
from typing import Any, Final

import numpy as np
from numba import njit
from numpy.typing import NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym import generator_kernel as draw
from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.traffic.config import MPH
from sdc_gym.traffic.idm import max_speed_for_gap
from sdc_gym.traffic.kinematics import (
    A_MAX,
    ACC,
    BRAKE_UNTIL,
    CUT_IN_UNTIL,
    DESIRED,
    EGO_D,
    EGO_S,
    EGO_SPEED,
    HALF_ACC,
    HALF_LENGTH,
    HELD,
    LC_END,
    LC_START,
    LENGTH,
    OMEGA,
    ORIGIN,
    PENDING,
    PHASE,
    RESPAWN_BLOCKED_UNTIL,
    RESPAWN_WAIT,
    SPAWN_COUNT,
    SPEED,
    STEP,
    TARGET_LANE,
    TSAB,
    TYPE_INDEX,
    WANDER_SPEED,
    WIDTH,
    D,
    S,
    interp,
)
from sdc_gym.traffic.state import IDLE, NEVER, TrafficState
from sdc_gym.traffic.vehicle_types import (
    TYPE_COMFORT_ACCEL,
    TYPE_COMFORT_DECEL,
    TYPE_LENGTHS,
    TYPE_MAX_SPEED_MPH,
    TYPE_WIDTHS,
    VEHICLE_TYPES,
)

# The kernels take the batch (sdc_gym.traffic.batch.TrafficBatch, which imports them) for
# its constants: typed by name only, so that the modules do not import each other.
TrafficBatch = Any

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

SPAWN_CANDIDATES = 24  # random spots tried per side when placing one car
RESPAWN_RETRY_STEPS = 100  # a car that found no room to respawn retries after this
RESPAWN_PAUSE_STEPS = 50  # and after any such failure nobody tries for this long

# The placement constants, in this order (TrafficBatch.placement_constants).
(K_LOOP, K_LANE_WIDTH, K_WANDER, K_DT, K_MIN_GAP, K_EGO_HALF_WIDTH, K_EGO_HALF_LENGTH,
 K_EGO_A_MAX, K_EGO_TSAB, K_IDM_T, K_IDM_S0, K_IDM_FLOOR, K_ROAD_END) = range(13)
PLACEMENT_CONSTANTS = 13
"""``K_ROAD_END``: an open road's end s (a spot must leave the car on ``[0, end]``); a
loop's is inf."""
_TYPE_LENGTH = TYPE_LENGTHS.copy()
_TYPE_WIDTH = TYPE_WIDTHS.copy()
_TYPE_ACCEL = TYPE_COMFORT_ACCEL.copy()
_TYPE_DECEL = TYPE_COMFORT_DECEL.copy()
STEP_ROW, RESPAWN_BLOCKED_ROW = STEP, RESPAWN_BLOCKED_UNTIL


def new_car(batch: TrafficBatch, st: TrafficState, r: int, i: int, type_index: int,
            s: float, lane: int, speed: float, desired: float,
            rng: np.random.Generator) -> None:
    """Write a fresh car into slot ``i`` of row ``r`` (its wander drawn from ``rng``)."""
    period = rng.uniform(*batch.config.wander_period)
    phase = rng.uniform(0.0, 2.0 * np.pi)
    write_car(st.car_floats, st.car_ints, st.step, batch.placement_constants, r, i,
              type_index, s, lane, speed, desired, period, phase)


@njit(cache=True)
def write_car(cf: np.ndarray, ci: np.ndarray, step: np.ndarray, constants: np.ndarray,
              r: int, i: int, type_index: int, s: float, lane: int, speed: float,
              desired: float, period: float, phase: float) -> None:
    """A fresh car of type ``type_index`` in slot ``i`` of row ``r``: at ``s`` in
    ``lane``, ``speed``, wanting ``desired``; its wander of ``period`` s at ``phase``."""
    length = _TYPE_LENGTH[type_index]
    accel, decel = _TYPE_ACCEL[type_index], _TYPE_DECEL[type_index]
    wander, lane_width, dt = constants[K_WANDER], constants[K_LANE_WIDTH], constants[K_DT]
    ci[TYPE_INDEX, r, i] = type_index
    cf[LENGTH, r, i] = length
    cf[WIDTH, r, i] = _TYPE_WIDTH[type_index]
    cf[HALF_LENGTH, r, i] = 0.5 * length
    cf[A_MAX, r, i] = accel
    cf[TSAB, r, i] = 2.0 * math.sqrt(accel * decel)
    cf[S, r, i] = s
    cf[SPEED, r, i] = speed
    cf[DESIRED, r, i] = desired
    ci[ORIGIN, r, i] = ci[TARGET_LANE, r, i] = lane
    ci[RESPAWN_WAIT, r, i] = 0
    ci[LC_START, r, i] = NEVER
    ci[LC_END, r, i] = IDLE
    ci[PENDING, r, i] = -1
    ci[HELD, r, i] = 0
    cf[ACC, r, i] = cf[HALF_ACC, r, i] = 0.0
    ci[BRAKE_UNTIL, r, i] = ci[CUT_IN_UNTIL, r, i] = 0
    omega = 2.0 * np.pi / period
    cf[OMEGA, r, i] = omega
    cf[PHASE, r, i] = phase
    cf[WANDER_SPEED, r, i] = wander * omega
    cf[D, r, i] = (lane + 0.5) * lane_width + wander * math.sin(omega * step[r] * dt + phase)


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


def choice(rng: np.random.Generator, cdf: FloatArray) -> int:
    """``rng.choice(len(p), p=p)`` for ``cdf = p.cumsum() / p.cumsum()[-1]``: numpy's own
    draw (one ``random()`` looked up in the cdf), without its checks per call."""
    return int(cdf.searchsorted(rng.random(), side="right"))


@njit(cache=True)
def recycle_rows(cf: np.ndarray, ci: np.ndarray, ei: np.ndarray, ef: np.ndarray,
                 constants: np.ndarray, kappa_grid: np.ndarray, kappa_table: np.ndarray,
                 type_cdf: np.ndarray, bands: np.ndarray, lanes: int, candidates: np.ndarray,
                 rngs: np.ndarray, ratio: np.ndarray) -> None:
    """Respawn every row's ``candidates`` (cars beyond ``spawn_range``, the farthest
    first, -1 padded; :func:`~sdc_gym.traffic.decisions.begin_decisions` picks them),
    each row drawing from its own generator (``rngs[r]``): :func:`recycle_row`. A row
    whose cars moved gets their IDM speed ratios ``max(v, 0) / v0`` anew (``ratio``)."""
    cars = cf.shape[2]
    for r in range(candidates.shape[0]):
        if candidates[r, 0] < 0:
            continue
        if recycle_row(cf, ci, ei, ef, constants, kappa_grid, kappa_table, type_cdf, bands,
                       lanes, r, candidates[r], rngs[r]):
            for c in range(cars):
                ratio[r, c] = max(cf[SPEED, r, c], 0.0) / cf[DESIRED, r, c]


def compile_recycling(batch: TrafficBatch) -> None:
    """Compile (or load from the cache) :func:`recycle_rows` for ``batch``'s arrays now,
    by a call that respawns nothing (every row's candidates -1): otherwise numba compiles
    it at the first recycle, mid-episode (~3 s of CPU inside one step on a fresh clone)."""
    cf, ci, ei, ef = batch.state.blocks
    none = np.full_like(batch.scratch_candidates, -1)
    recycle_rows(cf, ci, ei, ef, batch.placement_constants, batch.geometry.kappa_grid,
                 batch.geometry.kappa_table, batch.type_cdf, batch.respawn_draws, batch.lanes,
                 none, batch.rng_pointers, np.zeros_like(batch.scratch_ratio))


def respawn_draws(batch: TrafficBatch) -> FloatArray:
    """The bounds of a respawn's draws, as :func:`recycle_row` takes them: the bands
    ahead and behind (m), the desired speeds ahead and behind (mph), the wander period
    (s), the chance of the side ahead."""
    cfg = batch.config
    (lo_a, hi_a), (lo_b, hi_b) = batch.respawn_bands
    return np.array([lo_a, hi_a, lo_b, hi_b, *cfg.speed_ahead_mph, *cfg.speed_behind_mph,
                     *cfg.wander_period, cfg.respawn_ahead_probability])


@njit(cache=True)
def recycle_row(cf: np.ndarray, ci: np.ndarray, ei: np.ndarray, ef: np.ndarray,
                constants: np.ndarray, kappa_grid: np.ndarray, kappa_table: np.ndarray,
                type_cdf: np.ndarray, bands: np.ndarray, lanes: int, r: int,
                candidates: np.ndarray, rng: np.ndarray) -> bool:
    """The respawn rule for row ``r``'s candidates, in order, each drawing from the row's
    generator (``rng``: its :func:`~sdc_gym.generator_kernel.generator_pointers`)
    exactly as the rule's definition does with the generator's methods: the side's coin,
    24 spots per side, the type, lanes and desired speeds of the candidate spots, and the
    wander of a placed car. A car that finds no spot stays and retries later, and the row
    pauses its respawns."""
    step = ei[STEP_ROW, r]
    moved = False
    offsets = np.empty(2 * SPAWN_CANDIDATES)
    spot_lanes = np.empty(2 * SPAWN_CANDIDATES, dtype=np.int64)
    desired = np.empty(2 * SPAWN_CANDIDATES)
    for i in candidates:
        if i < 0:
            break
        # The original's coin: ahead (slow) or behind (fast), whatever side it left.
        ahead = draw.random(rng) < bands[10]
        # The picked side's spots first, then the other side's (no room on the first).
        first, second = (0, SPAWN_CANDIDATES) if ahead else (SPAWN_CANDIDATES, 0)
        for k in range(SPAWN_CANDIDATES):
            offsets[first + k] = draw.uniform(rng, bands[0], bands[1])
        for k in range(SPAWN_CANDIDATES):
            offsets[second + k] = -draw.uniform(rng, bands[2], bands[3])
        type_index = np.searchsorted(type_cdf, draw.random(rng), side="right")
        for k in range(offsets.shape[0]):
            spot_lanes[k] = draw.integers(rng, lanes)
        span_ahead, span_behind = bands[5] - bands[4], bands[7] - bands[6]
        for k in range(offsets.shape[0]):
            u = draw.random(rng)
            desired[k] = MPH * (bands[4] + u * span_ahead if offsets[k] > 0
                                else bands[6] + u * span_behind)
            # A coach or a semi keeps to its own limit (inf for the others: no change).
            desired[k] = min(desired[k], MPH * TYPE_MAX_SPEED_MPH[type_index])
        k, speed = find_spot(cf, ci, ef, constants, kappa_grid, kappa_table, r, i,
                             type_index, offsets, spot_lanes, desired)
        if k < 0:  # no room (dense traffic): the car drives on; retry in a while
            ci[RESPAWN_WAIT, r, i] = step + RESPAWN_RETRY_STEPS
            ei[RESPAWN_BLOCKED_ROW, r] = step + RESPAWN_PAUSE_STEPS
            break  # the others would not fit either, most likely
        s = py_mod(ef[EGO_S, r] + offsets[k], constants[K_LOOP])
        period = draw.uniform(rng, bands[8], bands[9])
        phase = draw.uniform(rng, 0.0, 2.0 * np.pi)
        write_car(cf, ci, ei[STEP_ROW], constants, r, i, type_index, s, spot_lanes[k], speed,
                  desired[k], period, phase)
        ci[SPAWN_COUNT, r, i] += 1  # the slot keeps its id, as the original's cars
        moved = True
    return moved


@njit(cache=True)
def find_spot(cf: np.ndarray, ci: np.ndarray, ef: np.ndarray, constants: np.ndarray,
              kappa_grid: np.ndarray, kappa_table: np.ndarray, r: int, skip: int,
              type_index: int, offsets: np.ndarray, lanes: np.ndarray,
              desired: np.ndarray) -> tuple[int, float]:
    """The first candidate (ego s + offset, lane) satisfying the respawn rule for a car of
    type ``type_index``, and its speed, among row ``r``'s cars but ``skip`` and the ego;
    (-1, 0.0) when none fits."""
    cars = cf.shape[2]
    loop, lane_width = constants[K_LOOP], constants[K_LANE_WIDTH]
    half = 0.5 * loop
    length = _TYPE_LENGTH[type_index]
    accel, decel = _TYPE_ACCEL[type_index], _TYPE_DECEL[type_index]
    min_gap = constants[K_MIN_GAP]
    ego_s, ego_d = ef[EGO_S, r], ef[EGO_D, r]
    low = math.floor((ego_d - constants[K_EGO_HALF_WIDTH]) / lane_width)
    high = math.floor((ego_d + constants[K_EGO_HALF_WIDTH]) / lane_width)
    # The objects that count: the cars but `skip`, then the ego.
    count = cars if skip < 0 else cars - 1
    s_o = np.empty(count + 1)
    d_o = np.empty(count + 1)
    v_o = np.empty(count + 1)
    length_o = np.empty(count + 1)
    a_o = np.empty(count + 1)
    tsab_o = np.empty(count + 1)
    scale_o = np.empty(count + 1)
    origin_o = np.empty(count + 1, dtype=np.int64)
    target_o = np.empty(count + 1, dtype=np.int64)
    j = 0
    for c in range(cars):
        if c == skip:
            continue
        s_o[j], d_o[j], v_o[j] = cf[S, r, c], cf[D, r, c], cf[SPEED, r, c]
        length_o[j] = 2.0 * cf[HALF_LENGTH, r, c]
        a_o[j], tsab_o[j] = cf[A_MAX, r, c], cf[TSAB, r, c]
        origin_o[j], target_o[j] = ci[ORIGIN, r, c], ci[TARGET_LANE, r, c]
        j += 1
    s_o[j], d_o[j], v_o[j] = ego_s, ego_d, ef[EGO_SPEED, r]
    length_o[j] = 2.0 * constants[K_EGO_HALF_LENGTH]
    a_o[j], tsab_o[j] = constants[K_EGO_A_MAX], constants[K_EGO_TSAB]
    for j in range(count + 1):
        scale_o[j] = 1.0 + interp(s_o[j], kappa_grid, kappa_table) * d_o[j]
    road_end = constants[K_ROAD_END]
    for k in range(offsets.shape[0]):
        s_c = py_mod(ego_s + offsets[k], loop)
        # An open road: only spots on it (behind its start, ego_s + offset < 0 reads as
        # near the period, past the end too).
        if road_end < math.inf and not 0.5 * length <= s_c <= road_end - 0.5 * length:
            continue
        lane = lanes[k]
        scale_c = 1.0 + interp(s_c, kappa_grid, kappa_table) * ((lane + 0.5) * lane_width)
        # The nearest object ahead and behind in the lane (the first of equals; the first
        # object when there is none).
        ahead, behind = math.inf, math.inf
        li, fi = 0, 0
        for j in range(count + 1):
            if j < count:
                inlane = origin_o[j] == lane or target_o[j] == lane
            else:
                inlane = low <= lane <= high
            delta = py_mod(s_o[j] - s_c + half, loop) - half
            value = delta if inlane and delta >= 0.0 else math.inf
            if value < ahead:
                ahead, li = value, j
            value = -delta if inlane and delta < 0.0 else math.inf
            if value < behind:
                behind, fi = value, j
        gap_lead = ahead * scale_c - 0.5 * (length + length_o[li])
        gap_follow = behind * scale_o[fi] - 0.5 * (length + length_o[fi])
        speed = min(desired[k], _max_speed_for_gap(gap_lead, v_o[li], accel, decel,
                                                   constants))
        # The follower (a car or the ego) must not find the newcomer inside its desired
        # gap: it then brakes by at most its a_max, never hard.
        a_f = a_o[fi]
        b_f = (0.5 * tsab_o[fi]) * (0.5 * tsab_o[fi]) / a_f
        if (gap_lead >= min_gap and gap_follow >= min_gap
                and gap_follow >= _desired_gap(v_o[fi], speed, a_f, b_f, constants)):
            return k, speed
    return -1, 0.0


@njit(cache=True, inline="always")
def _max_speed_for_gap(gap: float, leader_speed: float, a: float, b: float,
                       constants: np.ndarray) -> float:
    """:func:`~sdc_gym.traffic.idm.max_speed_for_gap` for one gap."""
    c = 0.5 / math.sqrt(a * b)
    finite = math.isfinite(gap)
    lin = constants[K_IDM_T] - c * (leader_speed if finite else 0.0)
    room = max(gap - constants[K_IDM_S0], 0.0)
    v = (math.sqrt(lin * lin + 4.0 * c * room) - lin) / (2.0 * c)
    return max(v, 0.0) if finite else math.inf


@njit(cache=True, inline="always")
def _desired_gap(v: float, leader_speed: float, a: float, b: float,
                 constants: np.ndarray) -> float:
    """:func:`~sdc_gym.traffic.idm.desired_gap` for one follower."""
    closing = v * (v - leader_speed) / (2.0 * math.sqrt(a * b))
    if constants[K_IDM_FLOOR] != 0.0:
        return constants[K_IDM_S0] + max(v * constants[K_IDM_T] + closing, 0.0)
    return constants[K_IDM_S0] + v * constants[K_IDM_T] + closing


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
    lo_road, hi_road = -math.inf, math.inf
    if batch.road_end < math.inf:  # an open road: only the road between its ends
        lo_road = -float(st.ego_s[r]) + half
        hi_road = batch.road_end - float(st.ego_s[r]) - half
    for lane in range(batch.lanes):
        mask = occupied[:, lane]
        lo, hi = max(-spread + half, lo_road), min(spread - half, hi_road)
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


RENYI_PARKING: Final = 0.7476
"""Rényi's parking constant: cars parked one at a time at uniformly random free spots
fill this fraction of a long lane before no spot is left (the reset's layout is such a
random parking, with each car's exclusion its length plus ``spawn_min_gap``)."""


def reset_capacity(batch: TrafficBatch) -> int:
    """How many cars a reset's random layout holds on average before it jams: the lanes'
    window (``+-(range - 10 m)`` around the ego) x Rényi's constant / the mix's mean
    exclusion length (car length + ``spawn_min_gap``, longer on curves), less the ego.
    Above it a reset fails almost surely, so ``car_count`` is refused at ``make``; below
    it, near it, a reset can still jam (its error names ``car_count``)."""
    cfg = batch.config
    window = 2.0 * (batch.range - 10.0)
    mean_length = math.fsum(p * length for p, length in zip(
        batch.type_p.tolist(), TYPE_LENGTHS[:len(batch.type_p)].tolist(), strict=True))
    exclusion = (mean_length + cfg.spawn_min_gap) / batch.geometry.min_scale
    return max(0, int(batch.lanes * RENYI_PARKING * window / exclusion) - 1)  # - the ego


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
        type_index = choice(rng, batch.type_cdf)
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
