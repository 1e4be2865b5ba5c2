"""One decision instant of the traffic, for the envs of a batch that are at one.

At a decision every car of those envs gets, in this order (see
:mod:`sdc_gym.traffic.highway_traffic` for the rules):

1. finished lane changes free their origin lane;
2. cars beyond ``spawn_range`` are recycled (:func:`sdc_gym.traffic.placement.recycle_rows`);
3. the leader and follower of every car in every lane (:mod:`sdc_gym.traffic.leaders`),
   and the bumper gaps to them along the follower's lane;
4. IDM accelerations in every lane (as if there), with the leader over the lane(s) the car
   occupies, and the braking a lane change would impose on the new follower (MOBIL's
   safety criterion);
5. lane-change wishes (clear +-clearance, incentive, safety), sustained, at most one
   start per target lane per env (the lowest slot);
6. rogue events (hard braking, cut-ins), when enabled.

Steps 1, 3-6 are compiled kernels over the deciding envs (:func:`begin_decisions`,
:func:`finish_decisions`), the arithmetic that of the traffic's definition on floats, so
the same bits; recycling draws from each env's generator and runs in Python between them
(it is rare), as does the rogue events' draw. The free-road term of IDM,
``(v / v0) ** delta``, is numpy's ``power`` over every object of the round (its SIMD
version rounds differently from the C library's ``pow``). The accelerations are held
until the next decision.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym import generator_kernel as draw
from sdc_gym.geometry.exact_math import py_mod
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
    KAPPA,
    LC_DURATION,
    LC_END,
    LC_START,
    ORIGIN,
    PENDING,
    RESPAWN_BLOCKED_UNTIL,
    RESPAWN_WAIT,
    ROGUE_BRAKE_COUNT,
    ROGUE_CUT_IN_COUNT,
    SPEED,
    STEP,
    TARGET_LANE,
    TSAB,
    D,
    S,
    interp,
)
from sdc_gym.traffic.leaders import nearest_objects
from sdc_gym.traffic.placement import recycle_rows
from sdc_gym.traffic.state import IDLE, NEVER, TrafficState

# The kernels take the batch (sdc_gym.traffic.batch.TrafficBatch, which imports them) for
# its constants: typed by name only, so that the modules do not import each other.
TrafficBatch = Any

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# The decision constants, in this order (TrafficBatch.decision_constants).
(C_LOOP, C_RANGE, C_LANES, C_LANE_WIDTH, C_EGO_HALF_WIDTH, C_EGO_HALF_LENGTH, C_EGO_A_MAX,
 C_EGO_TSAB, C_IDM_T, C_IDM_S0, C_IDM_MAX_BRAKING, C_IDM_FLOOR, C_CLEARANCE, C_MIN_GAIN,
 C_MAX_IMPOSED, C_MIN_SPEED, C_LC_DURATION, C_LC_STEPS, C_SUSTAIN, C_ROGUE_P,
 C_ROGUE_DECEL, C_BRAKE_STEPS, C_CUT_IN_WINDOW, C_CUT_IN_GAP, C_CUT_IN_DURATION,
 C_CUT_IN_STEPS, C_DECISION_DT, C_ROAD_END) = range(28)
CONSTANTS = 28
_NOT_ZERO = 1e-2  # highway-env's utils.not_zero (sdc_gym.traffic.idm)


@njit(cache=True)
def begin_decisions(cf: np.ndarray, ci: np.ndarray, ei: np.ndarray, ef: np.ndarray,
                    rows: np.ndarray, end: np.ndarray, step0: np.ndarray,
                    ego_s: np.ndarray, ego_d: np.ndarray, ego_speed: np.ndarray,
                    constants: np.ndarray, ratio: np.ndarray, candidates: np.ndarray) -> int:
    """Step 1 for the envs with ``rows`` (at their window frame ``end``): the ego's
    latest state before the decision, finished lane changes; each object's IDM speed
    ratio ``max(v, 0) / v0`` (the ego "wants" its current speed); and per env the cars to
    recycle (``candidates``, -1 padded): those beyond the recycling range (or, on an open
    road, past its end ``C_ROAD_END``: they leave; a loop's is inf) whose retry wait
    is over, the farthest first (the first of equals), at most ``respawn_per_decision``,
    none while the env's respawns pause. Returns how many envs have any."""
    loop = constants[C_LOOP]
    half = 0.5 * loop
    cars = cf.shape[2]
    rel = np.empty(cars + 1)
    taken = np.zeros(cars, dtype=np.bool_)
    count = 0
    for e in range(cf.shape[1]):
        candidates[e, :] = -1
        if not rows[e]:
            continue
        before = end[e] - 1  # the ego's latest state before the decision
        if before >= 0:
            ef[EGO_S, e] = py_mod(ego_s[e, before], loop)
            ef[EGO_D, e] = ego_d[e, before]
            ef[EGO_SPEED, e] = ego_speed[e, before]
        now = step0[e] + end[e]
        ei[STEP, e] = now
        for c in range(cars):  # finished lane changes free their origin lane
            if ci[LC_END, e, c] <= now:
                ci[ORIGIN, e, c] = ci[TARGET_LANE, e, c]
                ci[LC_START, e, c] = NEVER
                ci[LC_END, e, c] = IDLE
        ego_v0 = max(ef[EGO_SPEED, e], 0.1)
        for c in range(cars):
            ratio[e, c] = max(cf[SPEED, e, c], 0.0) / cf[DESIRED, e, c]
        ratio[e, cars] = max(ef[EGO_SPEED, e], 0.0) / ego_v0
        road_end = constants[C_ROAD_END]
        if _relative(cf, ef, e, loop, half, rel) <= constants[C_RANGE] or (
                now < ei[RESPAWN_BLOCKED_UNTIL, e]):
            if not _any_past(cf, e, road_end):
                continue
        if now < ei[RESPAWN_BLOCKED_UNTIL, e]:
            continue
        taken[:] = False
        for slot in range(candidates.shape[1]):
            pick, farthest = -1, 0.0
            for c in range(cars):
                far = abs(rel[c])
                if cf[S, e, c] > road_end:  # past an open road's end: it leaves first
                    far = math.inf
                if (not taken[c] and far > constants[C_RANGE]
                        and ci[RESPAWN_WAIT, e, c] <= now and (pick < 0 or far > farthest)):
                    pick, farthest = c, far
            if pick < 0:
                break
            taken[pick] = True
            candidates[e, slot] = pick
        count += candidates[e, 0] >= 0
    return count


@njit(cache=True, inline="always")
def _any_past(cf: np.ndarray, e: int, road_end: float) -> bool:
    """Whether a car of env ``e`` is past ``road_end`` (an open road's end; inf: none)."""
    for c in range(cf.shape[2]):
        if cf[S, e, c] > road_end:
            return True
    return False


@njit(cache=True, inline="always")
def _relative(cf: np.ndarray, ef: np.ndarray, e: int, loop: float, half: float,
              out: np.ndarray) -> float:
    """s of every object (the cars, then the ego) minus the ego's, folded to [-L/2, L/2);
    the largest magnitude."""
    cars = cf.shape[2]
    ego_s = ef[EGO_S, e]
    farthest = 0.0
    for j in range(cars + 1):
        s = cf[S, e, j] if j < cars else ego_s
        value = py_mod(s - ego_s + half, loop) - half
        out[j] = value
        if abs(value) > farthest:
            farthest = abs(value)
    return farthest


@njit(cache=True, inline="always")
def _idm(v: float, vt: float, afree: float, a: float, tsab: float, leader_v: float,
         gap: float, s0: float, max_braking: float, floor: bool) -> float:
    """IDM from a follower's terms (:func:`sdc_gym.traffic.idm.idm_core`'s operations)."""
    w = (v - leader_v) * v / tsab  # closing term
    if floor:
        w = max(w + vt, 0.0) + s0
    else:
        w = w + (s0 + vt)
    w = w / max(gap, _NOT_ZERO)
    w = w * w
    w = w * a
    return max(afree - w, -max_braking)


@njit(cache=True, inline="always")
def _begin_change(ci: np.ndarray, cf: np.ndarray, e: int, c: int, lane: int, now: int,
                  steps: int, duration: float) -> None:
    ci[TARGET_LANE, e, c] = lane
    ci[LC_START, e, c] = now
    ci[LC_END, e, c] = now + steps
    cf[LC_DURATION, e, c] = duration
    ci[PENDING, e, c] = -1
    ci[HELD, e, c] = 0


@njit(cache=True, inline="always")
def _stopping_gap(v_back: float, v_front: float, delay: float, max_braking: float) -> float:
    """Gap a car at ``v_back`` eats up behind one at ``v_front`` before it has matched its
    speed, braking at ``max_braking`` after ``delay`` seconds."""
    closing = max(v_back - v_front, 0.0)
    return closing * delay + closing * closing / (2.0 * max_braking)


@njit(cache=True)
def finish_decisions(cf: np.ndarray, ci: np.ndarray, ei: np.ndarray, ef: np.ndarray,
                     rows: np.ndarray, constants: np.ndarray, kappa_grid: np.ndarray,
                     kappa_table: np.ndarray, free: np.ndarray, rngs: np.ndarray,
                     parts: int) -> None:
    """Steps 3-6 for the envs with ``rows``: ``free`` is ``(envs, objects)`` the IDM
    free-road power ``(v / v0) ** delta``; ``rngs`` each env's generator (its
    :func:`~sdc_gym.generator_kernel.generator_pointers`), which the rogue events draw
    from (``Generator.random((2 + lanes, cars))``), when rogue mode is on. ``parts``:
    the envs in that many contiguous blocks, each with its own scratch arrays (1 for the
    serial kernel; the kernel threads for its parallel twin,
    :mod:`sdc_gym.kernel_threads`); an env's arithmetic is the same in any block."""
    envs, cars = cf.shape[1], cf.shape[2]
    objects = cars + 1
    lanes = int(constants[C_LANES])
    loop = constants[C_LOOP]
    half = 0.5 * loop
    lane_width = constants[C_LANE_WIDTH]
    ego_half_width = constants[C_EGO_HALF_WIDTH]
    s0, max_braking = constants[C_IDM_S0], constants[C_IDM_MAX_BRAKING]
    floor = constants[C_IDM_FLOOR] != 0.0
    clearance, min_gain = constants[C_CLEARANCE], constants[C_MIN_GAIN]
    limit = -constants[C_MAX_IMPOSED]
    min_speed = constants[C_MIN_SPEED]
    sustain = int(constants[C_SUSTAIN])
    rogue_p = constants[C_ROGUE_P]
    # Scratch of one block of envs: a part's own, so that parts may run on threads of
    # their own (the parallel twin's prange; the serial kernel runs one part).
    for part in prange(parts):
        rel = np.empty(objects)
        occupies = np.zeros((lanes, objects), dtype=np.bool_)
        order = np.empty(objects, dtype=np.int64)
        position = np.empty(objects + 4, dtype=np.int64)
        first_from = np.empty((lanes, objects + 1), dtype=np.int64)
        last_upto = np.empty((lanes, objects + 1), dtype=np.int64)
        ahead = np.empty((lanes, cars), dtype=np.int64)
        behind = np.empty((lanes, cars), dtype=np.int64)
        ds_ahead = np.empty((lanes, cars))
        ds_behind = np.empty((lanes, cars))
        lead_gap = np.empty((lanes, cars))
        follow_gap = np.empty((lanes, cars))
        lead_v = np.empty((lanes, cars))
        acc_lane = np.empty((lanes, cars))
        imposed = np.empty((lanes, cars))
        scale = np.empty(objects)
        half_all = np.empty(objects)
        v_all = np.empty(objects)
        vt = np.empty(objects)
        afree = np.empty(objects)
        a_all = np.empty(objects)
        tsab = np.empty(objects)
        acc = np.empty(cars)
        want = np.empty(cars, dtype=np.int64)
        start = np.empty(cars, dtype=np.bool_)
        first = np.empty(lanes + 1, dtype=np.int64)
        u = np.empty((2 + lanes, cars))
        for e in range(part * envs // parts, (part + 1) * envs // parts):
            if not rows[e]:
                continue
            now = ei[STEP, e]
            farthest = _relative(cf, ef, e, loop, half, rel)
            # The objects: the cars, then the ego (every lane its footprint touches).
            ego_d = ef[EGO_D, e]
            low = math.floor((ego_d - ego_half_width) / lane_width)
            high = math.floor((ego_d + ego_half_width) / lane_width)
            for lane in range(lanes):
                for c in range(cars):
                    occupies[lane, c] = (ci[ORIGIN, e, c] == lane) or \
                        (ci[TARGET_LANE, e, c] == lane)
                occupies[lane, cars] = low <= lane <= high
            for j in range(objects):
                if j < cars:
                    s, d, v = cf[S, e, j], cf[D, e, j], cf[SPEED, e, j]
                    half_all[j], a_all[j], tsab[j] = cf[HALF_LENGTH, e, j], cf[A_MAX, e, j], \
                        cf[TSAB, e, j]
                else:
                    s, d, v = ef[EGO_S, e], ego_d, ef[EGO_SPEED, e]
                    half_all[j], a_all[j], tsab[j] = constants[C_EGO_HALF_LENGTH], \
                        constants[C_EGO_A_MAX], constants[C_EGO_TSAB]
                kappa = interp(s, kappa_grid, kappa_table)
                if j < cars:
                    cf[KAPPA, e, j] = kappa
                scale[j] = kappa * d + 1.0
                v_all[j] = v
                vt[j] = v * constants[C_IDM_T]
                afree[j] = (1.0 - free[e, j]) * a_all[j]
            nearest_objects(rel, occupies, farthest >= 0.25 * loop, loop, order, position,
                            first_from, last_upto, ahead, ds_ahead, behind, ds_behind)
            for lane in range(lanes):
                for c in range(cars):
                    leader, follower = ahead[lane, c], behind[lane, c]
                    own_half = half_all[c]
                    lead_gap[lane, c] = ds_ahead[lane, c] * scale[c] - (own_half + half_all[leader])
                    follow_gap[lane, c] = ds_behind[lane, c] * scale[follower] - (
                        own_half + half_all[follower])
                    lead_v[lane, c] = v_all[leader]
            # IDM in every lane (as if there), with the own leader (the nearest over the
            # lanes the car occupies), and for the new follower behind it in every lane.
            brake_any = False
            for c in range(cars):
                own = ci[ORIGIN, e, c]
                own_gap = lead_gap[own, c]
                if ci[TARGET_LANE, e, c] != own:
                    # The first lane of the smallest gap, lanes not occupied at inf (a car
                    # with no leader in its lanes reads lane 0's leader speed at gap inf).
                    own = -1
                    for lane in range(lanes):
                        gap = lead_gap[lane, c] + (0.0 if occupies[lane, c] else math.inf)
                        if own < 0 or gap < own_gap:
                            own_gap, own = gap, lane
                v = v_all[c]
                acc[c] = _idm(v, vt[c], afree[c], a_all[c], tsab[c], lead_v[own, c], own_gap,
                              s0, max_braking, floor)
                for lane in range(lanes):
                    acc_lane[lane, c] = _idm(v, vt[c], afree[c], a_all[c], tsab[c],
                                             lead_v[lane, c], lead_gap[lane, c], s0,
                                             max_braking, floor)
                    f = behind[lane, c]
                    imposed[lane, c] = _idm(v_all[f], vt[f], afree[f], a_all[f], tsab[f], v,
                                            follow_gap[lane, c], s0, max_braking, floor)
                brake_any |= now < ci[BRAKE_UNTIL, e, c]
            # Lane-change wishes: clear +-clearance, MOBIL incentive and safety; sustained.
            any_start = False
            for c in range(cars):
                origin = ci[ORIGIN, e, c]
                eligible = (ci[LC_END, e, c] == IDLE and cf[SPEED, e, c] >= min_speed
                            and now >= ci[BRAKE_UNTIL, e, c])
                pick, best = -1, -math.inf
                if eligible:
                    for lane in range(lanes):
                        if (abs(lane - origin) == 1 and acc_lane[lane, c] - acc[c] > min_gain
                                and ds_ahead[lane, c] >= clearance
                                and ds_behind[lane, c] >= clearance
                                and acc_lane[lane, c] >= limit
                                and (imposed[lane, c] >= limit or math.isinf(follow_gap[lane, c]))
                                and (pick < 0 or acc_lane[lane, c] > best)):
                            pick, best = lane, acc_lane[lane, c]
                want[c] = pick
                wish = pick >= 0 and pick == ci[PENDING, e, c]
                held = (ci[HELD, e, c] + 1) * wish
                ci[HELD, e, c] = held
                ci[PENDING, e, c] = pick
                start[c] = held >= sustain if sustain else pick >= 0
                any_start |= start[c]
            if any_start:
                # One start per target lane per decision (the lowest slot): two cars entering
                # a lane at once did not see each other in their checks. The others keep their
                # sustained wish and retry at the next decision.
                first[:] = cars
                for c in range(cars):
                    if start[c] and first[want[c]] == cars:
                        first[want[c]] = c
                for c in range(cars):
                    if start[c] and first[want[c]] == c:
                        _begin_change(ci, cf, e, c, want[c], now, int(constants[C_LC_STEPS]),
                                      constants[C_LC_DURATION])
            if rogue_p > 0.0:
                for row in range(2 + lanes):
                    for c in range(cars):
                        u[row, c] = draw.random(rngs[e])
                _rogue(cf, ci, ei, e, now, constants, u, acc, ds_ahead, ds_behind,
                       lead_gap, follow_gap, lead_v, v_all, behind)
            for c in range(cars):
                cf[ACC, e, c] = acc[c]
                cf[HALF_ACC, e, c] = acc[c] * 0.5


@njit(cache=True)
def _rogue(cf: np.ndarray, ci: np.ndarray, ei: np.ndarray, e: int, now: int,
           constants: np.ndarray, u: np.ndarray, acc: np.ndarray, ds_ahead: np.ndarray,
           ds_behind: np.ndarray, lead_gap: np.ndarray, follow_gap: np.ndarray,
           lead_v: np.ndarray, v_all: np.ndarray, behind: np.ndarray) -> None:
    """Rogue events of env ``e``: hard-braking episodes and cut-ins (see
    :class:`~sdc_gym.traffic.config.TrafficConfig`).

    A cut-in takes a gap the normal rule refuses (someone within the clearance) but one
    that braking at ``idm.max_braking`` after a decision period's delay survives, for
    the car cutting in and for its new follower (a car or the ego): a surprise, not a
    certain crash.
    """
    cars = cf.shape[2]
    lanes = u.shape[0] - 2
    rogue_p = constants[C_ROGUE_P]
    min_speed = constants[C_MIN_SPEED]
    clearance = constants[C_CLEARANCE]
    delay, gap = constants[C_DECISION_DT], constants[C_CUT_IN_GAP]
    max_braking = constants[C_IDM_MAX_BRAKING]
    for c in range(cars):
        brake_until = ci[BRAKE_UNTIL, e, c]  # as it was before this decision's events
        event = u[0, c] < rogue_p
        if event and u[1, c] < 0.5 and now >= brake_until:
            ci[BRAKE_UNTIL, e, c] = now + int(constants[C_BRAKE_STEPS])
            ei[ROGUE_BRAKE_COUNT, e] += 1
        if event and u[1, c] >= 0.5:
            ci[CUT_IN_UNTIL, e, c] = now + int(constants[C_CUT_IN_WINDOW])
        # Eligible as for a lane change (those that just started one are not idle).
        trying = (cf[SPEED, e, c] >= min_speed and ci[LC_END, e, c] == IDLE
                  and now >= brake_until and now < ci[CUT_IN_UNTIL, e, c])
        if trying:
            v = cf[SPEED, e, c]
            origin = ci[ORIGIN, e, c]
            pick, best = 0, -1.0
            found = False
            for lane in range(lanes):
                clear = ds_ahead[lane, c] >= clearance and ds_behind[lane, c] >= clearance
                room = (lead_gap[lane, c] >= gap + _stopping_gap(v, lead_v[lane, c], delay,
                                                                 max_braking)
                        and follow_gap[lane, c] >= gap + _stopping_gap(
                            v_all[behind[lane, c]], v, delay, max_braking))
                score = u[2 + lane, c] if (abs(lane - origin) == 1 and not clear and room) \
                    else -1.0
                if score > best:
                    pick, best = lane, score
                found |= abs(lane - origin) == 1 and not clear and room
            if found:
                _begin_change(ci, cf, e, c, pick, now, int(constants[C_CUT_IN_STEPS]),
                              constants[C_CUT_IN_DURATION])
                ci[CUT_IN_UNTIL, e, c] = 0
                ei[ROGUE_CUT_IN_COUNT, e] += 1
        if now < ci[BRAKE_UNTIL, e, c]:
            acc[c] = min(acc[c], -constants[C_ROGUE_DECEL])


def decide(batch: TrafficBatch, rows: NDArray[np.bool_], end: IntArray, step0: IntArray,
           ego_s: FloatArray, ego_d: FloatArray, ego_speed: FloatArray) -> None:
    """One decision instant for every env with ``rows`` (see the module docstring): at
    window frame ``end[e]`` of the advance that started at step ``step0[e]``, with the
    ego's ``(envs, frames)`` states."""
    st: TrafficState = batch.state
    cf, ci, ei, ef = st.blocks
    ratio, candidates = batch.scratch_ratio, batch.scratch_candidates
    if begin_decisions(cf, ci, ei, ef, rows, end, step0, ego_s, ego_d, ego_speed,
                       batch.decision_constants, ratio, candidates):
        recycle_rows(cf, ci, ei, ef, batch.placement_constants, batch.geometry.kappa_grid,
                     batch.geometry.kappa_table, batch.type_cdf, batch.respawn_draws,
                     batch.lanes, candidates, batch.rng_pointers, ratio)
    free = ratio ** batch.config.idm.delta
    threads = batch.kernel_threads
    threads.pick(finish_decisions)(cf, ci, ei, ef, rows, batch.decision_constants,
                                   batch.geometry.kappa_grid, batch.geometry.kappa_table,
                                   free, batch.rng_pointers, threads.threads)
