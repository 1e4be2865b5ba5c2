"""The safety shield, the decision executor and the features as compiled kernels.

One implementation of each rule, written on floats and compiled (numba), called per env
from a batch (:func:`execute_batch`, :func:`encode_batch`, :func:`room_batch`) and per
world model by the classes around them
(:class:`~sdc_gym.stack.highway.shield.SafetyShield`,
:class:`~sdc_gym.stack.highway.decisions.DecisionExecutor`,
:class:`~sdc_gym.stack.highway.features.BehaviorFeatures`), which are documented there.
A world model reaches them as arrays:

* ``views`` ``(lanes, 6)``: per lane the nearest car ahead and behind, ``ahead_gap,
  ahead_speed, ahead_id, behind_gap, behind_speed, behind_id`` (gaps ``inf``, speeds 0
  and ids -1 where nobody is);
* the ego's ``ego_lane``, ``ego_d``, ``ego_speed``, the road's ``lane_width`` and
  ``road_radius``, the perception cycle's ``time``;
* the executor's state: ``ints`` ``(6,)`` = target lane, origin lane, changing, lane
  changes, refused, aborted; ``last_change`` (s) its time of the last change start.

The arithmetic is the rules' own on floats, ``math.exp`` included (the C library's, as
Python's), so results are those of the rules evaluated in Python.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)

# Columns of a lane view.
AHEAD_GAP, AHEAD_SPEED, AHEAD_ID, BEHIND_GAP, BEHIND_SPEED, BEHIND_ID = range(6)
# The executor's int state.
TARGET, ORIGIN, CHANGING, LANE_CHANGES, REFUSED, ABORTED = range(6)
# Speed moves (HighwayDecision.speed_move): cruise, hold, slow, a continuous target.
CRUISE, HOLD, SLOW, TARGET_SPEED = range(4)
# Shield parameters, in ShieldParameters' order.
(P_BRAKE_RANGE, P_APPROACH_GAIN, P_HARD_FRACTION, P_CURVE_GAIN, P_CURVE_DECAY,
 P_CURVE_OFFSET, P_GAP_MIN, P_HORIZON, P_MIN_AHEAD, P_MIN_RADIUS, P_FAR_WATCH, P_ABORT_GAP,
 P_ABORT_WINDOW) = range(13)

LANE_CHANGE_DONE_M = 0.5
"""A lane change is complete within this of the target lane's centre (the seed's)."""


# ---------------------------------------------------------------------- the seed's curves
@njit(cache=True)
def braking_percent(gap_m: float, gain_pct_per_m: float, decay_per_m: float,
                    offset_pct: float) -> float:
    """p(d): the % of the lead car's speed to drive at, ``gap_m`` behind it, in [0, 100]."""
    p = gain_pct_per_m / decay_per_m * (1.0 - math.exp((-decay_per_m) * gap_m)) - offset_pct
    return 0.0 if p < 0.0 else (100.0 if p > 100.0 else p)


@njit(cache=True)
def safety_gap_m(behind_speed: float, ego_speed: float, min_gap_m: float,
                 horizon_s: float) -> float:
    """The gap a car behind in a target lane needs: where it will be after ``horizon_s``
    at constant speeds, plus ``min_gap_m`` (never less than ``min_gap_m``)."""
    g = horizon_s * (behind_speed - ego_speed) + min_gap_m
    return g if g > min_gap_m else min_gap_m


# ---------------------------------------------------------------------- the shield
@njit(cache=True)
def braking_fraction(p: np.ndarray, gap_m: float) -> float:
    """p(gap) / 100."""
    return braking_percent(gap_m, p[P_CURVE_GAIN], p[P_CURVE_DECAY], p[P_CURVE_OFFSET]) * 0.01


@njit(cache=True)
def lead(views: np.ndarray, ego_lane: int, target_lane: int) -> tuple[float, float]:
    """Gap and speed of the nearest car ahead in the lanes from the ego's to the target."""
    lo, hi = min(ego_lane, target_lane), max(ego_lane, target_lane)
    gap, speed = math.inf, 0.0
    for lane in range(lo, hi + 1):
        if views[lane, AHEAD_GAP] < gap:
            gap, speed = views[lane, AHEAD_GAP], views[lane, AHEAD_SPEED]
    return gap, speed


@njit(cache=True)
def speed_limit(p: np.ndarray, views: np.ndarray, ego_lane: int, target_lane: int,
                max_braking: float, normal_acceleration: float
                ) -> tuple[float, float, bool]:
    """The following cap behind the lead: speed (``inf`` when there is none), the
    acceleration to reach it, and whether it is a hard braking (replan)."""
    gap, u = lead(views, ego_lane, target_lane)
    if gap == math.inf:
        return math.inf, normal_acceleration, False
    if gap >= p[P_BRAKE_RANGE]:
        edge = braking_fraction(p, p[P_BRAKE_RANGE]) * u
        return edge + p[P_APPROACH_GAIN] * (gap - p[P_BRAKE_RANGE]), normal_acceleration, False
    fraction = braking_fraction(p, gap)
    if fraction < p[P_HARD_FRACTION]:
        return fraction * u, max_braking, True
    return fraction * u, normal_acceleration, False


@njit(cache=True)
def safe_behind(p: np.ndarray, behind_gap: float, behind_speed: float,
                ego_speed: float) -> bool:
    """The lane's car behind is beyond the seed's safety gap."""
    return behind_gap > safety_gap_m(behind_speed, ego_speed, p[P_GAP_MIN], p[P_HORIZON])


@njit(cache=True)
def safe_ahead(p: np.ndarray, ahead_gap: float, ahead_speed: float, ego_speed: float) -> bool:
    """The lane's car ahead leaves room for the change at the current speeds."""
    need = p[P_MIN_AHEAD] + p[P_HORIZON] * max(ego_speed - ahead_speed, 0.0)
    return ahead_gap > need


@njit(cache=True)
def lane_change_allowed(p: np.ndarray, views: np.ndarray, ego_lane: int, ego_speed: float,
                        road_radius: float, target_lane: int) -> bool:
    """Whether a change from the ego lane to the adjacent ``target_lane`` may start now."""
    lanes = views.shape[0]
    if abs(target_lane - ego_lane) != 1 or not 0 <= target_lane < lanes:
        return False
    if road_radius <= p[P_MIN_RADIUS]:
        return False
    if not (safe_behind(p, views[target_lane, BEHIND_GAP], views[target_lane, BEHIND_SPEED],
                        ego_speed)
            and safe_ahead(p, views[target_lane, AHEAD_GAP], views[target_lane, AHEAD_SPEED],
                           ego_speed)):
        return False
    far = 2 * target_lane - ego_lane
    if 0 <= far < lanes:
        if min(views[far, AHEAD_GAP], views[far, BEHIND_GAP]) < p[P_FAR_WATCH]:
            return False
    return True


@njit(cache=True)
def must_abort(p: np.ndarray, views: np.ndarray, ego_d: float, ego_speed: float,
               lane_width: float, origin_lane: int, target_lane: int) -> bool:
    """A lane change under way should go back (the shield's "Abort" rule)."""
    if abs(ego_d - (origin_lane + 0.5) * lane_width) > p[P_ABORT_WINDOW]:
        return False
    target = target_lane if target_lane >= 0 else target_lane + views.shape[0]
    return views[target, AHEAD_GAP] < p[P_ABORT_GAP] or not safe_behind(
        p, views[target, BEHIND_GAP], views[target, BEHIND_SPEED], ego_speed)


# ---------------------------------------------------------------------- the executor
@njit(cache=True)
def allowed_moves(shielded: bool, p: np.ndarray, views: np.ndarray, ego_lane: int,
                  ego_speed: float, road_radius: float, changing: bool) -> tuple[bool, bool]:
    """Whether a ``left`` and a ``right`` move would start a change now."""
    if changing:
        return False, False
    if not shielded:
        return ego_lane > 0, ego_lane < views.shape[0] - 1
    return (lane_change_allowed(p, views, ego_lane, ego_speed, road_radius, ego_lane - 1),
            lane_change_allowed(p, views, ego_lane, ego_speed, road_radius, ego_lane + 1))


@njit(cache=True)
def execute(shielded: bool, p: np.ndarray, constants: np.ndarray, views: np.ndarray,
            ego_lane: int, ego_d: float, ego_speed: float, lane_width: float,
            road_radius: float, time: float, lane_move: int, speed_move: int,
            target_speed: float, ints: np.ndarray, last_change: np.ndarray, e: int
            ) -> tuple[int, float, float, bool]:
    """One decision of env ``e`` (row ``e`` of ``ints``, ``last_change``): the motion
    layer's target lane, target speed, acceleration and replan flag. ``constants``:
    slow step, cruise speed, normal acceleration, maximum braking (m/s, m/s^2)."""
    slow_step, cruise = constants[0], constants[1]
    normal_acceleration, max_braking = constants[2], constants[3]
    lanes = views.shape[0]
    # The lane-change state: a change completes near the target's centre, or goes back.
    if ints[e, TARGET] < 0:
        ints[e, TARGET] = ego_lane
    if ints[e, CHANGING] and abs(ego_d - (ints[e, TARGET] + 0.5) * lane_width) \
            <= LANE_CHANGE_DONE_M:
        ints[e, CHANGING] = 0
    if ints[e, CHANGING] and shielded and must_abort(p, views, ego_d, ego_speed, lane_width,
                                                     ints[e, ORIGIN], ints[e, TARGET]):
        ints[e, TARGET], ints[e, ORIGIN] = ints[e, ORIGIN], ints[e, TARGET]
        ints[e, ABORTED] += 1
    v = ego_speed
    if speed_move == CRUISE:
        goal = cruise
    elif speed_move == HOLD:
        goal = v
    elif speed_move == SLOW:
        goal = max(v - slow_step, 0.0)
    else:
        goal = target_speed
    goal = min(goal, cruise)
    accel, replan = normal_acceleration, False
    if shielded:
        limit, limit_accel, hard = speed_limit(p, views, ego_lane, ints[e, TARGET],
                                               max_braking, normal_acceleration)
        if limit < goal:
            goal, accel, replan = limit, limit_accel, hard
    if lane_move and not ints[e, CHANGING]:
        new = ego_lane + lane_move
        ok = 0 <= new < lanes
        if ok and shielded:
            ok = not replan and lane_change_allowed(p, views, ego_lane, ego_speed, road_radius,
                                                    new)
        if ok:
            ints[e, ORIGIN], ints[e, TARGET] = ints[e, TARGET], new
            ints[e, CHANGING] = 1
            last_change[e] = time
            ints[e, LANE_CHANGES] += 1
        else:
            ints[e, REFUSED] += 1
    return ints[e, TARGET], max(goal, 0.0), accel, replan


@njit(cache=True)
def execute_batch(shielded: bool, p: np.ndarray, constants: np.ndarray, views: np.ndarray,
                  ego_lane: np.ndarray, ego_d: np.ndarray, ego_speed: np.ndarray,
                  lane_width: float, road_radius: np.ndarray, time: np.ndarray,
                  lane_move: np.ndarray, speed_move: np.ndarray, target_speed: np.ndarray,
                  ints: np.ndarray, last_change: np.ndarray, out_lane: np.ndarray,
                  out_speed: np.ndarray, out_accel: np.ndarray, out_replan: np.ndarray) -> None:
    """:func:`execute` for every env of a batch (``views`` ``(envs, lanes, 6)``)."""
    for e in range(views.shape[0]):
        out_lane[e], out_speed[e], out_accel[e], out_replan[e] = execute(
            shielded, p, constants, views[e], ego_lane[e], ego_d[e], ego_speed[e],
            lane_width, road_radius[e], time[e], lane_move[e], speed_move[e],
            target_speed[e], ints, last_change, e)


# ---------------------------------------------------------------------- the features
@njit(cache=True)
def encode(shielded: bool, p: np.ndarray, views: np.ndarray, ego_lane: int, ego_d: float,
           ego_speed: float, lane_width: float, road_radius: float, time: float,
           ints: np.ndarray, last_change: np.ndarray, e: int, scales: np.ndarray,
           out: np.ndarray) -> None:
    """The observation of one world model and env ``e``'s executor state into ``out``
    (float32). ``scales``: cruise speed, sensing range, speed ratio max, offset limit,
    relative speed limit, since-change scale, radius scale."""
    cruise, reach, ratio_max = scales[0], scales[1], scales[2]
    offset_limit, rel_limit, since_scale, radius_scale = scales[3], scales[4], scales[5], \
        scales[6]
    n = views.shape[0]
    v = ego_speed
    target = ints[e, TARGET] if ints[e, TARGET] >= 0 else ego_lane
    out[:] = 0.0
    out[0] = min(v / cruise, ratio_max)
    out[1 + ego_lane] = 1.0
    out[1 + n + target] = 1.0
    offset = (ego_d - (target + 0.5) * lane_width) / lane_width
    out[1 + 2 * n] = min(max(offset, -offset_limit), offset_limit)
    out[2 + 2 * n] = float(ints[e, CHANGING])
    out[3 + 2 * n] = min((time - last_change[e]) / since_scale, 1.0)
    out[4 + 2 * n] = 0.0 if math.isinf(road_radius) else min(radius_scale / road_radius, 1.0)
    left, right = allowed_moves(shielded, p, views, ego_lane, ego_speed, road_radius,
                                ints[e, CHANGING] != 0)
    out[5 + 2 * n] = 1.0 if left else 0.0
    out[6 + 2 * n] = 1.0 if right else 0.0
    base = 7 + 2 * n
    for lane in range(n):
        i = base + 4 * lane
        if views[lane, AHEAD_ID] != -1:
            out[i] = min(views[lane, AHEAD_GAP] / reach, 1.0)
            rel = (views[lane, AHEAD_SPEED] - v) / cruise
            out[i + 1] = min(max(rel, -rel_limit), rel_limit)
        else:
            out[i] = 1.0
        if views[lane, BEHIND_ID] != -1:
            out[i + 2] = min(views[lane, BEHIND_GAP] / reach, 1.0)
            rel = (views[lane, BEHIND_SPEED] - v) / cruise
            out[i + 3] = min(max(rel, -rel_limit), rel_limit)
        else:
            out[i + 2] = 1.0


@njit(cache=True)
def encode_batch(shielded: bool, p: np.ndarray, views: np.ndarray, ego_lane: np.ndarray,
                 ego_d: np.ndarray, ego_speed: np.ndarray, lane_width: float,
                 road_radius: np.ndarray, time: np.ndarray, ints: np.ndarray,
                 last_change: np.ndarray, scales: np.ndarray, rows: np.ndarray,
                 out: np.ndarray) -> None:
    """:func:`encode` for the envs with ``rows`` (``out`` ``(envs, size)`` float32)."""
    for e in range(views.shape[0]):
        if rows[e]:
            encode(shielded, p, views[e], ego_lane[e], ego_d[e], ego_speed[e], lane_width,
                   road_radius[e], time[e], ints, last_change, e, scales, out[e])


@njit(cache=True)
def encode_traffic(views: np.ndarray, ids: np.ndarray, car_lane: np.ndarray,
                   car_gap: np.ndarray, car_speed: np.ndarray, car_d_rate: np.ndarray,
                   count: int, ego_speed: float, scales: np.ndarray, lateral_scale: float,
                   out: np.ndarray, base: int) -> None:
    """The extended observation's traffic entries into ``out[base:]``: per lane the second
    car ahead (the nearest ahead in the lane, other than the lane view's car, at least as
    far: gap / sensing range and relative speed / cruise speed; 1 and 0 when nobody) and
    the lateral rate of the lane view's car ahead / ``lateral_scale`` (its lane-change
    intent, positive moving right; 0 when nobody)."""
    cruise, reach, rel_limit = scales[0], scales[1], scales[4]
    n = views.shape[0]
    for lane in range(n):
        i = base + 3 * lane
        first_gap, first_id = views[lane, AHEAD_GAP], views[lane, AHEAD_ID]
        second_gap, second_speed = math.inf, 0.0
        lateral = 0.0
        for k in range(count):
            if ids[k] == first_id and first_id != -1:
                lateral = car_d_rate[k]
                continue
            gap = car_gap[k]
            if (car_lane[k] == lane and gap >= 0.0 and gap < second_gap and gap <= reach
                    and (first_id == -1 or gap >= first_gap)):
                second_gap, second_speed = gap, car_speed[k]
        if first_id == -1:
            lateral = 0.0  # no first car: then no second either
            second_gap = math.inf
        if math.isinf(second_gap):
            out[i] = 1.0
            out[i + 1] = 0.0
        else:
            out[i] = min(second_gap / reach, 1.0)
            rel = (second_speed - ego_speed) / cruise
            out[i + 1] = min(max(rel, -rel_limit), rel_limit)
        out[i + 2] = min(max(lateral / lateral_scale, -1.0), 1.0)


@njit(cache=True)
def encode_traffic_batch(views: np.ndarray, ids: np.ndarray, car_lane: np.ndarray,
                         car_gap: np.ndarray, car_speed: np.ndarray, car_d_rate: np.ndarray,
                         count: np.ndarray, ego_speed: np.ndarray, scales: np.ndarray,
                         lateral_scale: float, rows: np.ndarray, out: np.ndarray,
                         base: int) -> None:
    """:func:`encode_traffic` for the envs with ``rows`` (``out`` ``(envs, size)``)."""
    for e in range(views.shape[0]):
        if rows[e]:
            encode_traffic(views[e], ids[e], car_lane[e], car_gap[e], car_speed[e],
                           car_d_rate[e], count[e], ego_speed[e], scales, lateral_scale,
                           out[e], base)


@njit(cache=True)
def room(views: np.ndarray, ego_lane: int, target_lane: int, weight: float,
         reach: float) -> float:
    """The shaping potential: weight x room ahead in the target lane / sensing range."""
    lane = target_lane if target_lane >= 0 else ego_lane
    return weight * min(views[lane, AHEAD_GAP], reach) / reach


@njit(cache=True)
def room_batch(views: np.ndarray, ego_lane: np.ndarray, ints: np.ndarray, weight: float,
               reach: float, out: np.ndarray) -> None:
    """:func:`room` of every env."""
    for e in range(views.shape[0]):
        out[e] = room(views[e], ego_lane[e], ints[e, TARGET], weight, reach)
