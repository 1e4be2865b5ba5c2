"""Traffic motion between decision instants, in closed form, as compiled kernels.

Between two decisions every car holds its acceleration (a braking car stops at ``v = 0``
instead of reversing) and its lateral position follows its closed-form profile (the lane
change's minimum-jerk quintic plus the wander sine), so the state at each physics frame
of a *segment* is a handful of expressions of the frame's time. Along the lane a car
covers ``te (v0 + acc te / 2)`` metres by time ``te`` (``te`` = the time, or the stop
time if sooner); divided by ``1 + kappa d`` (``kappa`` taken at the decision) that is arc
length of the reference line, summed frame by frame from the segment's start.

:class:`TrafficGeometry` holds the road tables (point, tangent and curvature every 0.25 m,
interpolated linearly: positions within 0.1 mm of ``reference.to_xy``). The kernels
(:func:`segments`, :func:`poses`, :func:`lateral`, :func:`interp`) are numba-compiled
from the arithmetic the traffic was defined with (numpy's expressions over
``(envs, frames, cars)``): the same operations on the same floats, so the same bits.
The heading of the motion is the one exception: it stays numpy's ``arctan2`` over the
whole window (:meth:`TrafficGeometry.pose`), whose SIMD version rounds differently from
the C library's.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry import exact_math
from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.kernel_threads import SERIAL, KernelThreads
from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.traffic.config import TrafficConfig, TrafficSamples
from sdc_gym.traffic.state import TrafficState

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

GEOMETRY_STEP = 0.25  # m, spacing of the geometry look-up tables

# Rows of TrafficState's packed blocks, for the kernels.
_CF = {name: row for row, name in enumerate(TrafficState.CAR_FLOATS)}
_CI = {name: row for row, name in enumerate(TrafficState.CAR_INTS)}
_EI = {name: row for row, name in enumerate(TrafficState.ENV_INTS)}
_EF = {name: row for row, name in enumerate(TrafficState.ENV_FLOATS)}
LENGTH, WIDTH, HALF_LENGTH, A_MAX, TSAB = (_CF[n] for n in (
    "length", "width", "half_length", "a_max", "tsab"))
S, D, SPEED, DESIRED, X, Y, HEADING, VX, VY = (_CF[n] for n in (
    "s", "d", "speed", "desired", "x", "y", "heading", "vx", "vy"))
KAPPA, ACC, HALF_ACC, OMEGA, PHASE, WANDER_SPEED, LC_DURATION = (_CF[n] for n in (
    "kappa", "acc", "half_acc", "omega", "phase", "wander_speed", "lc_duration"))
IDS, SPAWN_COUNT, TYPE_INDEX, ORIGIN, TARGET_LANE, LC_START, LC_END = (_CI[n] for n in (
    "ids", "spawn_count", "type_index", "origin", "target_lane", "lc_start", "lc_end"))
PENDING, HELD, BRAKE_UNTIL, CUT_IN_UNTIL, RESPAWN_WAIT = (_CI[n] for n in (
    "pending", "held", "brake_until", "cut_in_until", "respawn_wait"))
STEP, RESPAWN_BLOCKED_UNTIL, ROGUE_BRAKE_COUNT, ROGUE_CUT_IN_COUNT = (_EI[n] for n in (
    "step", "respawn_blocked_until", "rogue_brake_count", "rogue_cut_in_count"))
EGO_S, EGO_D, EGO_SPEED = (_EF[n] for n in ("ego_s", "ego_d", "ego_speed"))


@njit(cache=True)
def interp(x: float, grid: np.ndarray, values: np.ndarray) -> float:
    """``np.interp(x, grid, values)`` for one ``x`` (numpy's own special cases and
    arithmetic, ``slope * (x - grid[j]) + values[j]`` with ``j`` the last grid point at or
    below ``x``, which a uniform grid's spacing locates at once)."""
    n = grid.shape[0]
    if math.isnan(x):
        return x
    if x > grid[n - 1]:
        return values[n - 1]
    if x < grid[0]:
        return values[0]
    j = int((x - grid[0]) / (grid[1] - grid[0]))
    j = min(max(j, 0), n - 1)
    while j > 0 and grid[j] > x:
        j -= 1
    while j < n - 1 and grid[j + 1] <= x:
        j += 1
    if j == n - 1 or grid[j] == x:
        return values[j]
    slope = (values[j + 1] - values[j]) / (grid[j + 1] - grid[j])
    result = slope * (x - grid[j]) + values[j]
    if math.isnan(result):
        result = slope * (x - grid[j + 1]) + values[j + 1]
        if math.isnan(result) and values[j] == values[j + 1]:
            result = values[j]
    return result


@njit(cache=True)
def interp_array(x: np.ndarray, grid: np.ndarray, values: np.ndarray) -> np.ndarray:
    """:func:`interp` elementwise (a flat array)."""
    out = np.empty(x.size)
    for i in range(x.size):
        out[i] = interp(x[i], grid, values)
    return out


@njit(cache=True, inline="always")
def lateral(cf: np.ndarray, ci: np.ndarray, e: int, c: int, base: int, k: int, dt: float,
            lane_width: float, wander: float) -> tuple[float, float]:
    """d and d_dot of car ``c`` of env ``e`` ``k`` frames after step ``base``: lane
    centre plus the wander sine, plus the lane change's quintic."""
    center = (ci[ORIGIN, e, c] + 0.5) * lane_width
    if wander > 0.0:
        angle = cf[OMEGA, e, c] * (base * dt + k * dt) + cf[PHASE, e, c]
        d = math.sin(angle) * wander + center
        d_dot = math.cos(angle) * cf[WANDER_SPEED, e, c]
    else:
        d = center + 0.0
        d_dot = 0.0
    origin, target = ci[ORIGIN, e, c], ci[TARGET_LANE, e, c]
    if target != origin:
        # Quintic minimum-jerk step 10 tau^3 - 15 tau^4 + 6 tau^5 and its time derivative
        # (30 shift / duration) tau^2 (1 - tau)^2.
        duration = cf[LC_DURATION, e, c]
        tau = (base + k - ci[LC_START, e, c]) * (dt / duration)
        tau = min(max(tau, 0.0), 1.0)
        tau2 = tau * tau
        step = tau2 * tau * (10.0 + tau * (6.0 * tau - 15.0))
        rest = 1.0 - tau
        rate = tau2 * (rest * rest)
        shift = (target - origin) * lane_width
        d += step * shift
        d_dot += rate * (30.0 * shift / duration)
    return d, d_dot


@njit(cache=True)
def segments(cf: np.ndarray, ci: np.ndarray, rows: np.ndarray, begin: np.ndarray,
             end: np.ndarray, step0: np.ndarray, dt: float, lane_width: float,
             wander: float, loop: float, s_out: np.ndarray, d_out: np.ndarray,
             v_out: np.ndarray, dd_out: np.ndarray, keep_end: bool) -> None:
    """Frames ``begin[e] .. end[e] - 1`` of the window (step ``step0[e]`` at its start) of
    every env ``e`` with ``rows[e]``, with the held accelerations: s (unwrapped), d, speed
    and d_dot into the ``(envs, frames, cars)`` outputs. ``keep_end``: the segment's end
    becomes the env's state (s wrapped, speed, d)."""
    envs, cars = cf.shape[1], cf.shape[2]
    for e in prange(envs):  # envs apart: a thread each in the parallel twin
        if not rows[e] or end[e] <= begin[e]:
            continue
        b = begin[e]
        base = step0[e] + b
        for c in range(cars):
            v0 = cf[SPEED, e, c]
            acc = cf[ACC, e, c]
            half_acc = cf[HALF_ACC, e, c]
            kappa = cf[KAPPA, e, c]
            s0 = cf[S, e, c]
            # Hold the acceleration, but a braking car stops at v = 0 instead of reversing.
            t_stop = (v0 if acc < 0.0 else math.inf) / max(-acc, 1e-12)
            previous = 0.0
            total = 0.0
            for j in range(end[e] - b):
                k = j + 1
                t = k * dt
                te = min(t, t_stop)
                v = acc * te + v0
                dist = te * (half_acc * te + v0)  # along the lane since the segment's start
                inc = dist - previous if j else dist
                previous = dist
                d, d_dot = lateral(cf, ci, e, c, base, k, dt, lane_width, wander)
                # Along-lane distance -> arc length of the reference line.
                total += inc / (kappa * d + 1.0)
                f = b + j
                s_out[e, f, c] = total + s0
                d_out[e, f, c] = d
                v_out[e, f, c] = v
                dd_out[e, f, c] = d_dot
            if keep_end:
                last = end[e] - 1
                cf[S, e, c] = py_mod(s_out[e, last, c], loop)
                cf[SPEED, e, c] = v_out[e, last, c]
                cf[D, e, c] = d_out[e, last, c]


@njit(cache=True)
def lateral_now(cf: np.ndarray, ci: np.ndarray, step: np.ndarray, first: int, dt: float,
                lane_width: float, wander: float, d_out: np.ndarray,
                dd_out: np.ndarray) -> None:
    """d and d_dot ``(rows, cars)`` of every car of the envs ``first, first + 1, ...`` (as
    many as ``d_out`` has rows) at its env's current step."""
    for r in range(d_out.shape[0]):
        e = first + r
        for c in range(cf.shape[2]):
            d_out[r, c], dd_out[r, c] = lateral(cf, ci, e, c, step[e] - 1, 1, dt, lane_width,
                                                wander)


@njit(cache=True)
def poses(table: np.ndarray, loop: float, grid_scale: float, grid_count: int,
          clamp_cell: bool, s: np.ndarray, d: np.ndarray, v: np.ndarray, d_dot: np.ndarray,
          s_out: np.ndarray, x_out: np.ndarray, y_out: np.ndarray, vx_out: np.ndarray,
          vy_out: np.ndarray, dir_x: np.ndarray, dir_y: np.ndarray) -> None:
    """World poses of Frenet states (flat arrays): wrapped s, x, y, the velocity, and the
    direction whose angle is the heading (for a car below 1 m/s its lane's tangent
    direction, so a (near) stopped car keeps pointing along its lane)."""
    for n in prange(s.shape[0]):  # points apart: a thread each in the parallel twin
        sw = py_mod(s[n], loop)
        u = sw * grid_scale
        cell = math.floor(u)
        if clamp_cell and cell > grid_count - 1:  # s == L after rounding
            cell = grid_count - 1
        f = u - cell
        row = table[int(cell)]
        px = row[6] * f + row[0]
        py = row[7] * f + row[1]
        tx = row[8] * f + row[2]
        ty = row[9] * f + row[3]
        nx = row[10] * f + row[4]  # the right normal (ty, -tx)
        ny = row[11] * f + row[5]
        dn, vn, ddn = d[n], v[n], d_dot[n]
        s_out[n] = sw
        x_out[n] = dn * nx + px
        y_out[n] = dn * ny + py
        vx_out[n] = vn * tx + ddn * nx
        vy_out[n] = vn * ty + ddn * ny
        pace = max(vn, 1.0)
        dir_x[n] = pace * tx + ddn * nx
        dir_y[n] = pace * ty + ddn * ny


class TrafficGeometry:
    """Road tables for the traffic (see the module docstring)."""

    def __init__(self, road: HighwayMap, config: TrafficConfig, dt: float,
                 kernel_threads: KernelThreads = SERIAL) -> None:
        self.config = config
        self.kernel_threads = kernel_threads
        self.dt = float(dt)
        self.reference = road.reference
        self.loop = float(road.length)
        self.half_loop = 0.5 * self.loop
        self.lanes = int(road.lane_count)
        self.lane_width = float(road.lane_width)
        count = max(math.ceil(self.loop / GEOMETRY_STEP), 16)
        self.grid_count = count
        self.grid_scale = count / self.loop  # grid cells per metre
        grid = np.arange(count + 1) * (self.loop / count)
        point, tangent = self.reference.frame(grid[:-1])
        table = np.vstack([np.hstack([point, tangent]), np.hstack([point, tangent])[:1]])
        geo, geo_step = table[:-1], np.diff(table, axis=0)
        # One row per grid point: x, y, tx, ty, ty, -tx (the right normal's components
        # follow the tangent), then the steps to the next grid point. One extra row, the
        # value at the end of the last cell, lets s == L (after rounding) skip the clamp
        # of the cell index.
        values = np.column_stack([geo, geo[:, 3], -geo[:, 2]])
        steps = np.column_stack([geo_step, geo_step[:, 3], -geo_step[:, 2]])
        end = values[-1] + 1.0 * steps[-1]
        self.table = np.ascontiguousarray(np.vstack([
            np.column_stack([values, steps]), np.append(end, np.zeros(6))[None]]))
        self.clamp_cell = self.loop * self.grid_scale > count
        kappa = self.reference.curvature(grid[:-1])
        self.kappa_grid = np.ascontiguousarray(grid)
        self.kappa_table = np.ascontiguousarray(np.append(kappa, kappa[0]))
        # Gaps at reset are laid out in s; divide by this to hold them in lane metres too.
        self.min_scale = max(1.0 - float(np.abs(kappa).max()) * road.road_width, 0.5)

    def curvature(self, s: FloatArray) -> FloatArray:
        """Signed curvature at wrapped ``s`` from the table (linear interpolation)."""
        values = np.ascontiguousarray(s, dtype=np.float64)
        return interp_array(values.ravel(), self.kappa_grid, self.kappa_table).reshape(
            values.shape)

    def segments(self, state: TrafficState, rows: NDArray[np.bool_], begin: IntArray,
                 end: IntArray, step0: IntArray, out: tuple[FloatArray, ...], *,
                 keep_end: bool) -> None:
        """:func:`segments` of ``state`` into the window arrays ``out`` (s, d, v, d_dot)."""
        self.kernel_threads.pick(segments)(
            state.car_floats, state.car_ints, rows, begin, end, step0, self.dt,
            self.lane_width, self.config.lateral_wander, self.loop, *out, keep_end)

    def pose(self, s: FloatArray, d: FloatArray, v: FloatArray,
             d_dot: FloatArray) -> TrafficSamples:
        """World pose of Frenet states (C-contiguous arrays of any one shape)."""
        shape = s.shape
        outputs = np.empty((7, *shape))
        threads = self.kernel_threads
        threads.pick(poses)(self.table, self.loop, self.grid_scale, self.grid_count,
                            self.clamp_cell, s.reshape(-1), d.reshape(-1), v.reshape(-1),
                            d_dot.reshape(-1), *(row.reshape(-1) for row in outputs))
        heading = exact_math.atan2(outputs[6], outputs[5], threads)
        return TrafficSamples._make(outputs[0], d, v, outputs[1], outputs[2], heading,
                                    outputs[3], outputs[4])

    def samples_now(self, state: TrafficState, env: int | None = None) -> TrafficSamples:
        """The current state as a one-frame :class:`TrafficSamples` (``(envs, 1, cars)``;
        with ``env``, that env's only: ``(1, 1, cars)``)."""
        rows = slice(None) if env is None else slice(env, env + 1)
        shape = (state.envs if env is None else 1, 1, state.cars)
        d, d_dot = np.empty(shape), np.empty(shape)
        lateral_now(state.car_floats, state.car_ints, state.step, 0 if env is None else env,
                    self.dt, self.lane_width, self.config.lateral_wander, d[:, 0], d_dot[:, 0])
        return self.pose(state.s[rows, None, :].copy(), d,
                         state.speed[rows, None, :].copy(), d_dot)

    @staticmethod
    def update_pose(state: TrafficState, samples: TrafficSamples,
                    rows: IntArray | slice = slice(None)) -> None:
        """Store the samples' last frame as the current state (of ``rows``)."""
        state.s[rows] = samples.s[:, -1]
        state.d[rows] = samples.d[:, -1]
        state.speed[rows] = samples.speed[:, -1]
        state.x[rows] = samples.x[:, -1]
        state.y[rows] = samples.y[:, -1]
        state.heading[rows] = samples.heading[:, -1]
        state.vx[rows] = samples.vx[:, -1]
        state.vy[rows] = samples.vy[:, -1]
