"""The seed's motion layer as one compiled kernel over a batch of planners.

:func:`plan_batch` runs :class:`~sdc_gym.stack.highway.motion.SeedMotionPlanner`'s cycle
(locate the car in its queue, trim or replan, extend the queue by gated pursuit steering)
for every env of a batch whose ``active`` flag is set, each on its own state row. It is
numba-compiled from the per-point arithmetic the layer is defined by (the module
docstring of :mod:`sdc_gym.stack.highway.motion`): the same operations on the same
floats as the planner stepped on Python floats, so every point is the same bit for bit;
``math``'s functions compile to the same C library calls Python makes. Exponents reach
the kernel as arguments: a literal ``x ** 2`` could be compiled to ``x * x``, which the C
library's ``pow`` does not always equal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry.exact_math import py_mod

# Columns of a queue row: one row per planned state.
X, Y, S, D, HEADING, INCREMENT = range(6)


@njit(cache=True)
def line_frame(coef: np.ndarray, knot_step: float, inverse_step: float, segments: int,
               param_scale: float, length: float, s: float, three: float
               ) -> tuple[float, float, float, float, float]:
    """Point, right unit normal and curvature of the reference line at ``s``
    (:meth:`~sdc_gym.geometry.reference_line.ReferenceLine.line_frames` for one s)."""
    u = py_mod(s, length) * param_scale
    i = int(u * inverse_step)
    if i > segments - 1:
        i = segments - 1
    row = coef[i]
    t = u - i * knot_step
    velocity_x = (row[8] * t + row[10]) * t + row[4]
    velocity_y = (row[9] * t + row[11]) * t + row[5]
    speed = math.hypot(velocity_x, velocity_y)
    curvature = (velocity_x * (row[13] * t + row[11])
                 - velocity_y * (row[12] * t + row[10])) / speed ** three
    return (((row[0] * t + row[2]) * t + row[4]) * t + row[6],
            ((row[1] * t + row[3]) * t + row[5]) * t + row[7],
            velocity_y / speed, -velocity_x / speed, curvature)


@njit(cache=True)
def plan_batch(params: np.ndarray, coef: np.ndarray, line: np.ndarray,
               buffer: np.ndarray, start: np.ndarray, stop: np.ndarray,
               end_row: np.ndarray, has_end: np.ndarray, last_row: np.ndarray,
               has_last: np.ndarray, counters: np.ndarray, floats: np.ndarray,
               flags: np.ndarray, ego: np.ndarray, target_lane: np.ndarray,
               target_speed: np.ndarray, acceleration: np.ndarray, replan: np.ndarray,
               steering: np.ndarray, active: np.ndarray, target_d: np.ndarray,
               out: np.ndarray, out_length: np.ndarray, two: float, three: float) -> None:
    """One planning cycle of every active env (see the module docstring).

    ``params``: path_length, replan_keep, look_ahead, steering_gate,
    steering_gate_lane_change, min_steering_increment, start_increment, max_increment,
    arrival (the eased rate's factor), lane_change_tolerance, unwind_margin,
    frames_per_cycle, latency_frames, batch_points, match tolerance squared, step (s),
    lane count, lane width. ``line``: knot_step, inverse_step, segments, param_scale,
    length. ``target_d``: per env the d to steer at, NaN for the target lane's centre (an
    eased lane change). Per env: ``counters`` (cycles, consumed, lead), ``floats`` (ds_ratio,
    curvature_target, anchor x, anchor y, target_d), ``flags`` (lane_changing,
    queued_muted).
    """
    path_length = int(params[0])
    replan_keep = int(params[1])
    fpc = int(params[11])
    latency = int(params[12])
    tolerance2 = params[14]
    step_s = params[15]
    lanes = int(params[16])
    lane_width = params[17]
    capacity = buffer.shape[1]
    for e in prange(buffer.shape[0]):  # envs apart: a thread each in the parallel twin
        if not active[e]:
            continue
        # ---- locate the car: drop the queued points it consumed
        counters[e, 1] = 0
        cx, cy = ego[e, 0], ego[e, 1]
        if start[e] != stop[e]:
            size = stop[e] - start[e]
            reach = min(size, counters[e, 2] + 2 * fpc + 2)
            expected = min(fpc, reach) - 1
            px, py = buffer[e, start[e] + expected, X], buffer[e, start[e] + expected, Y]
            if (px - cx) ** two + (py - cy) ** two <= tolerance2:
                counters[e, 1] = expected + 1
            else:
                for index in range(reach):
                    px = buffer[e, start[e] + index, X]
                    py = buffer[e, start[e] + index, Y]
                    if (px - cx) ** two + (py - cy) ** two <= tolerance2:
                        counters[e, 1] = index + 1
                        break
            consumed = counters[e, 1]
            if not consumed:
                if (floats[e, 2] - cx) ** two + (floats[e, 3] - cy) ** two > tolerance2:
                    # Lost (the env moved the car off our points): plan afresh.
                    start[e] = stop[e] = 0
                    has_end[e] = has_last[e] = False
                    counters[e, 0] = 0
            elif consumed >= size:
                # The path ran out under the car: continue from the car as observed.
                start[e] = stop[e] = 0
                has_end[e] = has_last[e] = False
                counters[e, 0] = 0
            else:
                floats[e, 2], floats[e, 3] = px, py  # the point the car stands on
                start[e] += consumed
        if not has_end[e] and not has_last[e]:
            for c in range(5):
                last_row[e, c] = ego[e, c]
            last_row[e, INCREMENT] = ego[e, 5] * step_s
            has_last[e] = True
            floats[e, 2], floats[e, 3] = ego[e, 0], ego[e, 1]
            if counters[e, 0] == 0 and ego[e, 5] > 0.0 and latency > 0:
                # A moving start (a scenario, a replay): the car drives `latency` more
                # frames on the path it has before this plan arrives. Plan from where it
                # will be, and do not take it for lost before it reaches this plan.
                ahead = latency * last_row[e, INCREMENT]
                last_row[e, X] += ahead * math.cos(ego[e, 4])
                last_row[e, Y] += ahead * math.sin(ego[e, 4])
                last_row[e, S] += ahead
                floats[e, 2] = floats[e, 3] = math.nan
        # The car consumes `lead` more queued points from the paths already sent before
        # this one arrives; none while it is still waiting for its first path.
        lead = min(latency, counters[e, 0] * fpc)
        counters[e, 2] = lead
        replay_from = 0
        replay_count = 0
        replay = np.empty(0)
        if replan[e] or (steering[e] and flags[e, 1]):
            if not replan[e]:  # steering returns: plan the unsteered states again
                keep = start[e] + lead + replan_keep
                if stop[e] > keep:
                    replay = buffer[e, keep:stop[e], INCREMENT].copy()
                    replay_count = len(replay)
            keep_count = lead + replan_keep
            if stop[e] - start[e] > keep_count:
                stop[e] = start[e] + keep_count
                if keep_count > 0:
                    for column in range(buffer.shape[2]):
                        end_row[e, column] = buffer[e, stop[e] - 1, column]
                    has_end[e] = True
                else:
                    has_end[e] = False
        flags[e, 1] = not steering[e]
        lane = min(max(int(target_lane[e]), 0), lanes - 1)
        floats[e, 4] = (lane + 0.5) * lane_width
        if not math.isnan(target_d[e]):
            floats[e, 4] = target_d[e]
        missing = path_length - (stop[e] - start[e])
        if missing > 0:
            replay_from = _extend(params, coef, line, buffer, start, stop, end_row,
                                  has_end, last_row, floats, e, missing, target_speed[e],
                                  acceleration[e], steering[e], replay, replay_count,
                                  replay_from, three, capacity)
        counters[e, 0] += 1
        end_d = end_row[e, D] if has_end[e] else last_row[e, D]
        flags[e, 0] = abs(end_d - floats[e, 4]) > params[9]
        count = min(path_length, stop[e] - start[e])
        for k in range(count):
            out[e, k, 0] = buffer[e, start[e] + k, 0]
            out[e, k, 1] = buffer[e, start[e] + k, 1]
        out_length[e] = count


@njit(cache=True)
def _extend(params: np.ndarray, coef: np.ndarray, line: np.ndarray, buffer: np.ndarray,
            start: np.ndarray, stop: np.ndarray, end_row: np.ndarray, has_end: np.ndarray,
            last_row: np.ndarray, floats: np.ndarray, e: int, count: int,
            target_speed: float, acceleration: float, steering: bool, replay: np.ndarray,
            replay_count: int, replay_from: int, three: float, capacity: int) -> int:
    """Append ``count`` states to env ``e``'s queue (the seed's steps 2 to 6); the first
    ones take their increments from ``replay`` (states planned again)."""
    look_ahead, gate_normal, gate_change = params[2], params[3], params[4]
    min_increment, start_increment, max_increment = params[5], params[6], params[7]
    arrival, tolerance, margin = params[8], params[9], params[10]
    batch_points = int(params[13])
    step_s = params[15]
    knot_step, inverse_step, segments = line[0], line[1], int(line[2])
    param_scale, length = line[3], line[4]
    row = end_row[e] if has_end[e] else last_row[e]
    x, y, s, d, heading, increment = row[0], row[1], row[2], row[3], row[4], row[5]
    target_d = floats[e, 4]
    goal = min(max(target_speed * step_s, 0.0), max_increment)
    change = max(acceleration, 0.0) * step_s * step_s
    c, sn = math.cos(heading), math.sin(heading)
    # Move the queue back to the buffer's start when the new states would not fit.
    size = stop[e] - start[e]
    if stop[e] + count > capacity:
        if size + count > capacity:
            raise ValueError("motion queue buffer too small")
        # Element by element, front to back (the rows only move towards the start):
        # numba's array assignment costs seconds of compilation for its error message.
        first = start[e]
        for row in range(size):
            for column in range(buffer.shape[2]):
                buffer[e, row, column] = buffer[e, first + row, column]
        start[e], stop[e] = 0, size
    write = stop[e]
    increments = np.empty(batch_points)
    s_pred = np.empty(batch_points)
    frames = np.empty((batch_points, 5))
    while count > 0:
        k = count if count < batch_points else batch_points
        count -= k
        # Speeds first: they do not depend on the steering.
        for j in range(k):
            if replay_from < replay_count:
                increment = replay[replay_from]
                replay_from += 1
                increments[j] = increment
                continue
            # Arrive at the goal speed with the acceleration easing to zero at a
            # bounded jerk, a <= sqrt(2 J |dv|).
            gap = goal - increment
            step_change = arrival * math.sqrt(abs(gap))
            if not step_change < change:
                step_change = change
            if gap > 0.0:
                increment += step_change
                if goal < increment:
                    increment = goal
                if increment < start_increment:
                    increment = goal if goal < start_increment else start_increment
            else:
                increment -= step_change
                if goal > increment:
                    increment = goal
            increments[j] = max_increment if max_increment < increment else increment
        # Lane error, gate and stretched look-ahead for this batch.
        error = d - target_d
        changing = abs(error) > tolerance
        gate = gate_change if changing else gate_normal
        speed_step = max(increments[k - 1], min_increment)
        distance = max(look_ahead, math.sqrt(margin * abs(error) * speed_step / gate))
        # Aim point on the target lane, moved out by the pursuit's sagitta in bends.
        lane_curvature = floats[e, 1] / (1.0 + floats[e, 1] * target_d)
        aim_d = target_d + 0.5 * lane_curvature * distance * distance
        s_start = s
        travelled = 0.0
        ratio = floats[e, 0]
        for j in range(k):
            travelled += increments[j]
            s_pred[j] = s + ratio * travelled
        for j in range(k):
            fx, fy, fnx, fny, fbend = line_frame(coef, knot_step, inverse_step, segments,
                                                 param_scale, length, s_pred[j], three)
            frames[j, 0], frames[j, 1], frames[j, 2] = fx, fy, fnx
            frames[j, 3], frames[j, 4] = fny, fbend
        aims = np.empty((k, 2))
        last_curvature = 0.0
        for j in range(k):
            ax, ay, anx, any_, last_curvature = line_frame(
                coef, knot_step, inverse_step, segments, param_scale, length,
                s_pred[j] + distance, three)
            aims[j, 0] = ax + aim_d * anx
            aims[j, 1] = ay + aim_d * any_
        floats[e, 1] = last_curvature
        if changing:
            # The narrow gate, centred on the lane's own turn, inside the normal gate.
            car_curvature = frames[0, 4]
            turn = car_curvature / (1.0 + car_curvature * d) * speed_step
            low = max(turn - gate, -gate_normal)
            high = min(turn + gate, gate_normal)
        else:
            low, high = -gate, gate
        for j in range(k):
            step = increments[j]
            if steering and step >= min_increment:
                dx, dy = aims[j, 0] - x, aims[j, 1] - y
                bearing = math.atan2(dy * c - dx * sn, dx * c + dy * sn)
                if low > bearing:
                    bearing = low
                heading += high if high < bearing else bearing
                c, sn = math.cos(heading), math.sin(heading)
            x += step * c
            y += step * sn
            # Frenet s, d: one Newton step from the predicted s.
            rx, ry, nx, ny, bend = frames[j, 0], frames[j, 1], frames[j, 2], frames[j, 3], \
                frames[j, 4]
            ox, oy = x - rx, y - ry
            d = ox * nx + oy * ny
            s = s_pred[j] + (oy * nx - ox * ny) / (1.0 + bend * d)
            buffer[e, write, 0] = x
            buffer[e, write, 1] = y
            buffer[e, write, 2] = py_mod(s, length)
            buffer[e, write, 3] = d
            buffer[e, write, 4] = heading
            buffer[e, write, 5] = step
            write += 1
        if travelled > 1e-6:
            floats[e, 0] = min(max((s - s_start) / travelled, 0.5), 2.0)
        s = py_mod(s, length)
    stop[e] = write
    for column in range(buffer.shape[2]):
        end_row[e, column] = buffer[e, write - 1, column]
    has_end[e] = True
    return replay_from
