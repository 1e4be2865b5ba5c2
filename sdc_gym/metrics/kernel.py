"""The driving metrics' per-sample rules as one compiled kernel over a batch of envs.

:func:`record_batch` walks every env's new physics samples in step order, exactly as the
rules of :mod:`sdc_gym.metrics.driving_metrics` define them on Python floats: the step
geometry (step length, raw acceleration and jerk, Menger curvature of the last three
positions, all with CPython's ``math.hypot``:
:func:`~sdc_gym.geometry.exact_math.py_hypot`), the running sums (distance, progress,
block and window sums, strictly in step order), lap marks, the rising edges of every
incident rule and the block rule. Incidents and lap times come out as events in buffers
(env, sample index, kind, value), in the order the rules report them: by sample, then by
kind. The state is two matrices, one row per quantity and one column per env (the named
arrays of :class:`~sdc_gym.metrics.batch.DrivingMetricsBatch` are their rows).
"""

from __future__ import annotations

import numpy as np
from numba import njit

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry.exact_math import py_hypot, py_mod

# Rows of the float state.
(F_S_LAST, F_DISTANCE, F_PROGRESS, F_NEXT_LAP_MARK, F_LAST_MARK_TIME, F_MAX_SPEED,
 F_LAST_SPEED, F_MAX_RAW_ACC, F_MAX_RAW_JERK, F_LAST_RAW_ACC, F_LAST_RAW_JERK, F_BLK_SUM,
 F_KAP_SUM, F_PREV_BLOCK_V, F_WINDOW_SUM, F_PREV_WINDOW_MEAN, F_LAST_ACC, F_LAST_ACC_T,
 F_LAST_ACC_N, F_LAST_JERK, F_MAX_ACC, F_MAX_JERK, F_DIST_AT_INCIDENT,
 F_LONGEST_CLOSED) = range(24)
FLOAT_ROWS = ("s_last", "distance", "progress", "next_lap_mark", "last_mark_time",
              "max_speed", "last_speed", "max_raw_acc", "max_raw_jerk", "last_raw_acc",
              "last_raw_jerk", "blk_sum", "kap_sum", "prev_block_v", "window_sum",
              "prev_window_mean", "last_acc", "last_acc_t", "last_acc_n", "last_jerk",
              "max_acc", "max_jerk", "dist_at_incident", "longest_closed")
# Rows of the int state (flags are 0 / 1).
(I_STEPS, I_LAPS, I_BLK_N, I_KAP_N, I_WINDOW_N, I_STRADDLE_RUN, I_CONTACT, I_INCIDENT_TOTAL,
 I_HAS_PREV_WINDOW, I_ACC_FLAG, I_JERK_FLAG, I_SPEEDING, I_OFF_ROAD) = range(13)
INT_ROWS = ("steps", "laps", "blk_n", "kap_n", "window_n", "straddle_run", "contact",
            "incident_total", "has_prev_window", "acc_flag", "jerk_flag", "speeding",
            "off_road")
# The built-in kinds' order (INCIDENT_KINDS).
K_COLLISION, K_ACCELERATION, K_JERK, K_SPEED, K_LANE, K_OFF_ROAD = range(6)
# Rule constants, in this order.
(R_DT, R_BLOCK_STEPS, R_JERK_BLOCKS, R_MAX_ACC, R_MAX_JERK, R_SPEED_LIMIT, R_D_MIN, R_D_MAX,
 R_MAX_STRADDLE, R_LOOP, R_INV_DT2, R_INV_DT3, R_BLOCK_SECONDS, R_WINDOW_SECONDS) = range(14)


@njit(cache=True, inline="always")
def _emit(events: np.ndarray, count: int, env: int, index: int, kind: int,
          value: float) -> int:
    events[count, 0] = env
    events[count, 1] = index
    events[count, 2] = kind
    events[count, 3] = value
    return count + 1


@njit(cache=True)
def record_batch(rules: np.ndarray, bands: np.ndarray, fs: np.ndarray, ints: np.ndarray,
                 back: np.ndarray, counts: np.ndarray, xy: np.ndarray, s: np.ndarray,
                 d: np.ndarray, speed: np.ndarray, contact_ids: np.ndarray,
                 has_contacts: bool, extra: np.ndarray, events: np.ndarray,
                 laps_out: np.ndarray) -> tuple[int, int]:
    """Record ``k`` samples of every env (see the module docstring).

    Args:
        rules: the constants (``R_*``); ``bands``: ``(m, 2)`` straddle bands.
        fs, ints: the state (rows ``F_*`` / ``I_*``, one column per env).
        back: ``(envs, 6)`` the three positions before the next sample (x, then y).
        counts: ``(envs, kinds)`` incidents per kind.
        xy, s, d, speed: the samples, ``(envs, k, 2)`` and ``(envs, k)``.
        contact_ids: ``(envs, k)`` the car in contact or -1 (read if ``has_contacts``).
        extra: ``(m, 4)`` incidents the caller detected: env, sample, kind, value, in
            (env, sample) order.
        events: ``(capacity, 4)`` filled with env, sample, kind, value.
        laps_out: ``(capacity, 2)`` filled with env, lap time.

    Returns:
        The number of incident events and of lap events.
    """
    dt = rules[R_DT]
    block_steps = int(rules[R_BLOCK_STEPS])
    jerk_blocks = int(rules[R_JERK_BLOCKS])
    loop = rules[R_LOOP]
    half = 0.5 * loop
    inv_dt2, inv_dt3 = rules[R_INV_DT2], rules[R_INV_DT3]
    max_straddle = int(rules[R_MAX_STRADDLE])
    envs, k = speed.shape
    count = 0
    lap_count = 0
    extra_at = 0
    kinds = counts.shape[1]
    cum_progress = np.empty(k + 1)
    for e in range(envs):
        t0 = ints[I_STEPS, e]
        # x, y of p[t-3], p[t-2], p[t-1]; the velocity * dt, acceleration * dt^2 and step
        # length of the last sample, as a sample-by-sample walk carries them.
        x0, x1, x2 = back[e, 0], back[e, 1], back[e, 2]
        y0, y1, y2 = back[e, 3], back[e, 4], back[e, 5]
        vx2, vy2 = x2 - x1, y2 - y1
        vx1, vy1 = x1 - x0, y1 - y0
        ax2, ay2 = vx2 - vx1, vy2 - vy1
        l2 = py_hypot(vx2, vy2)
        distance = fs[F_DISTANCE, e]
        progress = fs[F_PROGRESS, e]
        s_last = fs[F_S_LAST, e]
        start = count  # this env's events
        cum_progress[0] = progress
        raw_acc = raw_jerk = 0.0
        while extra_at < extra.shape[0] and int(extra[extra_at, 0]) < e:
            extra_at += 1
        for i in range(k):
            t = t0 + 1 + i
            x, y = xy[e, i, 0], xy[e, i, 1]
            vx = x - x2
            vy = y - y2
            step_len = py_hypot(vx, vy)
            ax = vx - vx2
            ay = vy - vy2
            raw_acc = py_hypot(ax, ay)
            raw_jerk = py_hypot(ax - ax2, ay - ay2)
            den = l2 * step_len * py_hypot(x - x1, y - y1)
            curv = 2.0 * abs(vx2 * vy - vy2 * vx) / den if den != 0.0 else 0.0
            valid = True
            if t < 2:  # the sample uses positions from before the reset
                valid = False
                raw_acc = 0.0
            if t < 3:
                raw_jerk = 0.0
            x1, y1, x2, y2 = x2, y2, x, y
            vx2, vy2, ax2, ay2, l2 = vx, vy, ax, ay, step_len
            # Running sums, lap marks.
            distance += step_len
            ds = py_mod(s[e, i] - s_last + half, loop) - half
            s_last = s[e, i]
            progress += ds
            cum_progress[i + 1] = progress
            v = speed[e, i]
            if v > fs[F_MAX_SPEED, e]:
                fs[F_MAX_SPEED, e] = v
            value = raw_acc * inv_dt2
            if value > fs[F_MAX_RAW_ACC, e]:
                fs[F_MAX_RAW_ACC, e] = value
            value = raw_jerk * inv_dt3
            if value > fs[F_MAX_RAW_JERK, e]:
                fs[F_MAX_RAW_JERK, e] = value
            first = count  # this sample's events, in kind order
            # Collision: a new contact (another car, or after a gap).
            if has_contacts:
                cid = contact_ids[e, i]
                if cid < 0:
                    ints[I_CONTACT, e] = -1
                else:
                    if cid != ints[I_CONTACT, e]:
                        count = _emit(events, count, e, i, K_COLLISION, float(cid))
                    ints[I_CONTACT, e] = cid
            # The block rule (acceleration, then jerk, at the block's last sample).
            fs[F_BLK_SUM, e] += v
            if valid:
                fs[F_KAP_SUM, e] += curv
                ints[I_KAP_N, e] += 1
            ints[I_BLK_N, e] += 1
            if ints[I_BLK_N, e] >= block_steps:
                count = _close_block(rules, fs, ints, e, i, events, count, block_steps,
                                     jerk_blocks)
            # Speeding, lane straddling, off road: rising edges.
            speeding = v > rules[R_SPEED_LIMIT]
            if speeding and not ints[I_SPEEDING, e]:
                count = _emit(events, count, e, i, K_SPEED, v)
            ints[I_SPEEDING, e] = speeding
            dd = d[e, i]
            if bands.shape[0]:
                inside = False
                for b in range(bands.shape[0]):
                    if bands[b, 0] < dd < bands[b, 1]:
                        inside = True
                if inside:
                    ints[I_STRADDLE_RUN, e] += 1
                    if ints[I_STRADDLE_RUN, e] == max_straddle + 1:
                        count = _emit(events, count, e, i, K_LANE,
                                      ints[I_STRADDLE_RUN, e] * dt)
                else:
                    ints[I_STRADDLE_RUN, e] = 0
            off = dd < rules[R_D_MIN] or dd > rules[R_D_MAX]
            if off and not ints[I_OFF_ROAD, e]:
                count = _emit(events, count, e, i, K_OFF_ROAD, dd)
            ints[I_OFF_ROAD, e] = off
            # The caller's kinds, after the built-in ones, in kind order (stable).
            for kind in range(6, kinds):
                j = extra_at
                while j < extra.shape[0] and int(extra[j, 0]) == e:
                    if int(extra[j, 1]) == i and int(extra[j, 2]) == kind:
                        count = _emit(events, count, e, i, kind, extra[j, 3])
                    j += 1
            # Each incident ends the stretch without incident at this sample's distance.
            for j in range(first, count):
                counts[e, int(events[j, 2])] += 1
                stretch = distance - fs[F_DIST_AT_INCIDENT, e]
                if stretch > fs[F_LONGEST_CLOSED, e]:
                    fs[F_LONGEST_CLOSED, e] = stretch
                fs[F_DIST_AT_INCIDENT, e] = distance
        if not has_contacts:
            ints[I_CONTACT, e] = -1
        ints[I_INCIDENT_TOTAL, e] += count - start
        ints[I_STEPS, e] = t0 + k
        fs[F_DISTANCE, e] = distance
        fs[F_PROGRESS, e] = progress
        fs[F_S_LAST, e] = s_last
        fs[F_LAST_SPEED, e] = speed[e, k - 1]
        fs[F_LAST_RAW_ACC, e] = raw_acc * inv_dt2
        fs[F_LAST_RAW_JERK, e] = raw_jerk * inv_dt3
        if progress >= fs[F_NEXT_LAP_MARK, e]:
            lap_count = _count_laps(fs, ints, e, t0, cum_progress, k, dt, loop, laps_out,
                                    lap_count)
        for j in range(3):
            m = k - 3 + j
            if m >= 0:
                back[e, j], back[e, 3 + j] = xy[e, m, 0], xy[e, m, 1]
            else:
                back[e, j], back[e, 3 + j] = back[e, j + k], back[e, 3 + j + k]
    return count, lap_count


# One explicit signature: typed from record_batch, whose running count starts as the
# literal 0, numba would otherwise compile it twice (Literal[int](0) and int64).
@njit("int64(float64[:, ::1], int64[:, ::1], int64, int64, float64[::1], int64, float64, "
      "float64, float64[:, ::1], int64)", cache=True)
def _count_laps(fs: np.ndarray, ints: np.ndarray, e: int, t0: int, cum_progress: np.ndarray,
                k: int, dt: float, loop: float, laps_out: np.ndarray, lap_count: int) -> int:
    """Every lap mark the chunk's progress crossed, timed by linear interpolation (run
    when the chunk ends past the next mark)."""
    for i in range(1, k + 1):
        p0, p1 = cum_progress[i - 1], cum_progress[i]
        while p1 >= fs[F_NEXT_LAP_MARK, e]:
            mark = fs[F_NEXT_LAP_MARK, e]
            # p0 < mark <= p1 here, so p1 > p0 and the fraction lies in (0, 1].
            t_cross = (t0 + i - 1 + (mark - p0) / (p1 - p0)) * dt
            laps_out[lap_count, 0] = e
            laps_out[lap_count, 1] = t_cross - fs[F_LAST_MARK_TIME, e]
            lap_count += 1
            fs[F_LAST_MARK_TIME, e] = t_cross
            ints[I_LAPS, e] += 1
            fs[F_NEXT_LAP_MARK, e] = (ints[I_LAPS, e] + 1) * loop
    return lap_count


@njit(cache=True)
def _close_block(rules: np.ndarray, fs: np.ndarray, ints: np.ndarray, e: int, i: int,
                 events: np.ndarray, count: int, block_steps: int, jerk_blocks: int) -> int:
    """Close env ``e``'s block at sample ``i``: its total acceleration, and the jerk
    window it completes."""
    v = fs[F_BLK_SUM, e] / block_steps
    kappa_n = ints[I_KAP_N, e]
    kappa_mean = fs[F_KAP_SUM, e] / kappa_n if kappa_n > 0 else 0.0
    acc_t = (v - fs[F_PREV_BLOCK_V, e]) / rules[R_BLOCK_SECONDS]
    acc_n = v * v * kappa_mean
    total = py_hypot(acc_t, acc_n)
    fs[F_PREV_BLOCK_V, e] = v
    fs[F_LAST_ACC_T, e] = acc_t
    fs[F_LAST_ACC_N, e] = acc_n
    fs[F_LAST_ACC, e] = total
    if total > fs[F_MAX_ACC, e]:
        fs[F_MAX_ACC, e] = total
    violating = total >= rules[R_MAX_ACC]
    if violating and not ints[I_ACC_FLAG, e]:
        count = _emit(events, count, e, i, K_ACCELERATION, total)
    ints[I_ACC_FLAG, e] = violating
    fs[F_BLK_SUM, e] = 0.0
    fs[F_KAP_SUM, e] = 0.0
    ints[I_BLK_N, e] = 0
    ints[I_KAP_N, e] = 0
    fs[F_WINDOW_SUM, e] += total
    ints[I_WINDOW_N, e] += 1
    if ints[I_WINDOW_N, e] == jerk_blocks:
        mean = fs[F_WINDOW_SUM, e] / jerk_blocks
        fs[F_WINDOW_SUM, e] = 0.0
        ints[I_WINDOW_N, e] = 0
        if ints[I_HAS_PREV_WINDOW, e]:  # the first window has no jerk
            jerk = (mean - fs[F_PREV_WINDOW_MEAN, e]) / rules[R_WINDOW_SECONDS]
            fs[F_LAST_JERK, e] = jerk
            if abs(jerk) > fs[F_MAX_JERK, e]:
                fs[F_MAX_JERK, e] = abs(jerk)
            violating = abs(jerk) >= rules[R_MAX_JERK]
            if violating and not ints[I_JERK_FLAG, e]:
                count = _emit(events, count, e, i, K_JERK, jerk)
            ints[I_JERK_FLAG, e] = violating
        fs[F_PREV_WINDOW_MEAN, e] = mean
        ints[I_HAS_PREV_WINDOW, e] = 1
    return count
