"""Perception's per-car work as compiled kernels over a batch of envs.

:func:`measure_batch` is steps 1-3 of :mod:`sdc_gym.stack.highway.perception` (the sensed
rows' Frenet coordinates and road normals from the geometry table, and the fault test)
and :func:`select_batch` step 5 (every lane's nearest car ahead and behind, ghosting, the
preferred lane, the circumradius ahead), for every env at once. Both are numba-compiled
from the per-car arithmetic on floats the layer was written with, so every value is the
one the per-car loop gives; :func:`summarize_batch` adds each env's preferred lane and
the road's circumradius ahead. The velocity projection between them stays a numpy complex
product (numpy fuses it; a per-element product rounds differently), as before.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry.exact_math import py_mod

SOUND, FAULTY, BOUNDARY = 0, 1, 2
MIN_CURVATURE = 1e-9  # 1/m: a circumcircle flatter than this counts as a straight (inf)


@njit(cache=True)
def measure_batch(fusion: np.ndarray, present: np.ndarray, table: np.ndarray,
                  length: float, scale: float, tolerance: float, out_s: np.ndarray,
                  out_d: np.ndarray, out_nx: np.ndarray, out_ny: np.ndarray,
                  out_bend: np.ndarray, out_fault: np.ndarray, out_count: np.ndarray,
                  out_xy: np.ndarray, out_velocity: np.ndarray, out_miss: np.ndarray,
                  out_ids: np.ndarray) -> None:
    """Per env, the present rows in order: s (wrapped), d, the road's right normal and
    curvature at s, and the fault verdict (``SOUND``, ``FAULTY``, or ``BOUNDARY``: within
    rounding of the tolerance, where numpy's modulus decides)."""
    below, above = tolerance * (1.0 - 1e-9), tolerance * (1.0 + 1e-9)
    sound_sq = (tolerance * (1.0 - 1e-6)) * (tolerance * (1.0 - 1e-6))
    for e in range(fusion.shape[0]):
        count = 0
        for k in range(fusion.shape[1]):
            if not present[e, k]:
                continue
            x, y = fusion[e, k, 1], fusion[e, k, 2]
            s = py_mod(fusion[e, k, 5], length)
            d = fusion[e, k, 6]
            u = s * scale
            i = int(u)  # s < length: at most n, the table's last row
            row = table[i]
            t = u - i
            nx = row[2] + t * row[7]
            ny = row[3] + t * row[8]
            miss_x = row[0] + t * row[5] + d * nx - x
            miss_y = row[1] + t * row[6] + d * ny - y
            verdict = SOUND
            zero = s == 0.0 and d == 0.0
            if miss_x * miss_x + miss_y * miss_y > sound_sq or zero:
                miss = math.hypot(miss_x, miss_y)
                if miss > above or zero:
                    verdict = FAULTY
                elif not miss <= below:
                    verdict = BOUNDARY
            out_s[e, count] = s
            out_d[e, count] = d
            out_nx[e, count] = nx
            out_ny[e, count] = ny
            out_bend[e, count] = row[4] + t * row[9]
            out_fault[e, count] = verdict
            out_xy[e, count, 0], out_xy[e, count, 1] = x, y
            out_velocity[e, count, 0] = fusion[e, k, 3]
            out_velocity[e, count, 1] = fusion[e, k, 4]
            out_miss[e, count, 0], out_miss[e, count, 1] = miss_x, miss_y
            out_ids[e, count] = int(fusion[e, k, 0])
            count += 1
        out_count[e] = count


@njit(cache=True)
def select_batch(s: np.ndarray, d: np.ndarray, speed: np.ndarray, ids: np.ndarray,
                 count: np.ndarray, ego_s: np.ndarray, ego_d: np.ndarray,
                 ego_lane: np.ndarray, length: float, lanes: int, inverse_width: float,
                 ghosting: bool, ghost_lateral: float, ghost_ahead: float,
                 ghost_behind: float, reach: float, views: np.ndarray,
                 car_lane: np.ndarray, car_gap: np.ndarray) -> None:
    """Per env the lane views ``views[e, lane] = (ahead gap, speed, id, behind gap, speed,
    id)`` (gap inf, speed 0, id -1 where nobody is within ``reach``) and each car's lane
    index and signed gap."""
    half = 0.5 * length
    best = np.empty(2 * lanes)
    nearest = np.zeros(2 * lanes, dtype=np.int64)
    for e in range(s.shape[0]):
        shift = half - ego_s[e]
        best[:] = np.inf
        nearest[:] = 0
        own = ego_lane[e]
        for k in range(count[e]):
            gap = py_mod(s[e, k] + shift, length) - half
            distance = abs(gap)
            value = d[e, k] * inverse_width
            finite = math.isfinite(value)
            lane = math.floor(value) if finite else 0
            row = -1
            if finite and 0 <= lane < lanes:
                row = lane + lanes if gap < 0 else lane
            if row >= 0 and distance < best[row]:
                best[row] = distance
                nearest[row] = k
            # Ghosting: an adjacent car drifting close to the ego also counts as the ego
            # lane's car ahead (it is in no other row of the ego lane).
            if (ghosting and finite and abs(d[e, k] - ego_d[e]) < ghost_lateral
                    and lane != own and abs(lane - own) == 1 and 0 <= lane < lanes
                    and -ghost_behind <= gap <= ghost_ahead and distance < best[own]):
                best[own] = distance
                nearest[own] = k
            if not finite:
                car_lane[e, k] = -1 if value < 0 else (lanes if value > 0 else -(2**63))
            elif lane < -1:
                car_lane[e, k] = -1
            elif lane > lanes:
                car_lane[e, k] = lanes
            else:
                car_lane[e, k] = lane
            car_gap[e, k] = gap
        for lane in range(lanes):
            ahead, behind = best[lane], best[lane + lanes]
            if ahead <= reach:
                views[e, lane, 0] = ahead
                views[e, lane, 1] = speed[e, nearest[lane]]
                views[e, lane, 2] = ids[e, nearest[lane]]
            else:
                views[e, lane, 0], views[e, lane, 1], views[e, lane, 2] = np.inf, 0.0, -1.0
            if behind <= reach:
                views[e, lane, 3] = behind
                views[e, lane, 4] = speed[e, nearest[lane + lanes]]
                views[e, lane, 5] = ids[e, nearest[lane + lanes]]
            else:
                views[e, lane, 3], views[e, lane, 4], views[e, lane, 5] = np.inf, 0.0, -1.0


@njit(cache=True)
def road_radius(table: np.ndarray, scale: float, length: float, s: float, lane: int) -> float:
    """Circumradius of ``lane``'s centre line at ``s`` from its table of 1 / radius
    (``table[lane]``, ``scale`` samples per metre; linear interpolation; ``inf`` where the
    circle is flatter than 1e-9 / m)."""
    row = table[lane]
    u = py_mod(s, length) * scale
    i = min(int(u), row.shape[0] - 2)
    low = row[i]
    curvature = low + (u - i) * (row[i + 1] - low)
    return 1.0 / curvature if curvature > MIN_CURVATURE else math.inf


@njit(cache=True)
def summarize_batch(views: np.ndarray, ego_s: np.ndarray, ego_lane: np.ndarray, middle: int,
                    table: np.ndarray, scale: float, length: float, preferred: np.ndarray,
                    radius: np.ndarray) -> None:
    """Per env the preferred lane (the one whose car ahead is furthest; ties: the middle
    lane, then the ego's, then the first) and the road's circumradius ahead in the ego
    lane."""
    for e in range(views.shape[0]):
        lanes = views.shape[1]
        best = views[e, 0, 0]
        for lane in range(1, lanes):
            if views[e, lane, 0] > best:
                best = views[e, lane, 0]
        own = ego_lane[e]
        if views[e, middle, 0] == best:
            preferred[e] = middle
        elif views[e, own, 0] == best:
            preferred[e] = own
        else:
            for lane in range(lanes):
                if views[e, lane, 0] == best:
                    preferred[e] = lane
                    break
        radius[e] = road_radius(table, scale, length, ego_s[e], own)


@njit(cache=True)
def ego_frenet(ego: np.ndarray, length: float, inverse_width: float, lanes: int,
               ego_s: np.ndarray, ego_d: np.ndarray, ego_speed: np.ndarray,
               ego_lane: np.ndarray) -> None:
    """Per env the ego's wrapped s, d, speed and lane (``floor(d / width)`` clipped to
    the road) from its observed ``(x, y, s, d, yaw, speed)``."""
    for e in range(ego.shape[0]):
        ego_s[e] = py_mod(ego[e, 2], length)
        ego_d[e] = ego[e, 3]
        ego_speed[e] = ego[e, 5]
        ego_lane[e] = int(min(max(math.floor(ego[e, 3] * inverse_width), 0), lanes - 1))
