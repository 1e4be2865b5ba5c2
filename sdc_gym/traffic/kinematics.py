"""Traffic motion between decision instants, in closed form, for a batch of envs.

Between two decisions every car holds its acceleration (a braking car stops at ``v = 0``
instead of reversing) and its lateral position follows its closed-form profile (the lane
change's minimum-jerk quintic plus the wander sine), so the states at all physics frames
of a *segment* come out of a handful of array expressions over ``(envs, frames, cars)``.
Along the lane a car covers ``te (v0 + acc te / 2)`` metres by time ``te`` (``te`` = the
time, or the stop time if sooner); divided by ``1 + kappa d`` (``kappa`` taken at the
decision) that is arc length of the reference line, summed frame by frame from the
segment's start.

:class:`TrafficGeometry` holds the road tables (point, tangent and curvature every 0.25 m,
interpolated linearly: positions within 0.1 mm of ``reference.to_xy``) and turns Frenet
states into world poses (:meth:`TrafficGeometry.pose`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.traffic.config import TrafficConfig, TrafficSamples
from sdc_gym.traffic.state import TrafficState

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

GEOMETRY_STEP = 0.25  # m, spacing of the geometry look-up tables


class RowsOf:
    """The fields of some rows of a :class:`TrafficState`, taken when first read (the
    segment kernels read a dozen of the state's forty fields)."""

    def __init__(self, state: TrafficState, rows: IntArray) -> None:
        self._state = state
        self._rows = rows

    def __getattr__(self, name: str) -> NDArray:
        value = getattr(self._state, name)[self._rows]
        setattr(self, name, value)
        return value


class TrafficGeometry:
    """Road tables for the traffic (see the module docstring) and the segment kernels."""

    def __init__(self, road: HighwayMap, config: TrafficConfig, dt: float) -> None:
        self.config = config
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
        # Component-first for one gather per lookup: rows x, y, tx, ty, ty, -tx (the right
        # normal's components follow the tangent), then the steps to the next grid point.
        # One extra column, the value at the end of the last cell, lets s == L (after
        # rounding) skip the clamp of the cell index.
        values = np.column_stack([geo, geo[:, 3], -geo[:, 2]]).T
        steps = np.column_stack([geo_step, geo_step[:, 3], -geo_step[:, 2]]).T
        end = values[:, -1] + 1.0 * steps[:, -1]
        self.table = np.ascontiguousarray(np.vstack([
            np.column_stack([values, end]), np.column_stack([steps, np.zeros(6)])]))
        self.clamp_cell = self.loop * self.grid_scale > count
        self.loop_0d = np.array(self.loop)
        self.grid_scale_0d = np.array(self.grid_scale)
        kappa = self.reference.curvature(grid[:-1])
        self.kappa_grid = grid
        self.kappa_table = np.append(kappa, kappa[0])
        # Gaps at reset are laid out in s; divide by this to hold them in lane metres too.
        self.min_scale = max(1.0 - float(np.abs(kappa).max()) * road.road_width, 0.5)

    def curvature(self, s: FloatArray) -> FloatArray:
        """Signed curvature at wrapped ``s`` from the table (linear interpolation)."""
        return np.interp(s, self.kappa_grid, self.kappa_table)

    # ------------------------------------------------------------------ lateral motion
    def lateral(self, state: TrafficState | RowsOf, base: IntArray, k: IntArray,
                angle: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        """d and d_dot ``(envs, frames, cars)`` at ``k`` frames after step ``base``.

        ``base`` is ``(envs, 1, 1)``, ``k`` ``(envs or 1, frames, 1)``; ``angle`` the
        wander's, if the caller has it.
        """
        cfg = self.config
        center = (state.origin + 0.5) * self.lane_width
        center = center[:, None, :]
        if cfg.lateral_wander > 0.0:
            if angle is None:
                angle = state.omega[:, None, :] * (base * self.dt + k * self.dt)
                angle += state.phase[:, None, :]
            d = np.sin(angle)
            d *= cfg.lateral_wander
            d += center
            d_dot = np.cos(angle)
            d_dot *= state.wander_speed[:, None, :]
        else:
            d = center + np.zeros(np.broadcast_shapes(base.shape, k.shape))
            d_dot = np.zeros(d.shape)
        changing = state.target_lane != state.origin
        if np.count_nonzero(changing):
            # Quintic minimum-jerk step 10 tau^3 - 15 tau^4 + 6 tau^5 and its time
            # derivative (30 shift / duration) tau^2 (1 - tau)^2, for the cars changing
            # lanes (the others' shift is zero: they would add zeros).
            env, car = np.nonzero(changing)
            duration = state.lc_duration[env, car][:, None]
            frames = np.broadcast_to(base + k, (*d.shape[:2], 1))[env, :, 0]
            j = frames - state.lc_start[env, car][:, None]
            tau = np.minimum(np.maximum(j * (self.dt / duration), 0.0), 1.0)
            tau2 = tau * tau
            step = tau2 * tau * (10.0 + tau * (6.0 * tau - 15.0))
            rate = tau2 * (1.0 - tau) ** 2
            shift = ((state.target_lane[env, car] - state.origin[env, car])
                     * self.lane_width)[:, None]
            step *= shift
            rate *= 30.0 * shift / duration
            d[env, :, car] += step
            d_dot[env, :, car] += rate
        return d, d_dot

    # ------------------------------------------------------------------ segments
    def segment(self, state: TrafficState | RowsOf, frames: int, base: IntArray
                ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``frames`` frames with the held accelerations from every env's current state:
        s (unwrapped), d, speed, d_dot, each ``(envs, frames, cars)``; ``base`` (``(envs,)``)
        is the step at each segment's start."""
        dt = self.dt
        k = np.arange(1, frames + 1, dtype=np.int64)[None, :, None]  # frames into it
        t = k * dt
        base = base[:, None, None]
        v0 = state.speed[:, None, :]
        acc = state.acc[:, None, :]
        # Hold the acceleration, but a braking car stops at v = 0 instead of reversing.
        t_stop = np.where(acc < 0.0, v0, np.inf) / np.maximum(-acc, 1e-12)
        te = np.minimum(t, t_stop)
        v = acc * te
        v += v0
        inner = state.half_acc[:, None, :] * te
        inner += v0
        dist = te * inner  # along the lane since the segment's start
        inc = np.empty_like(dist)
        inc[:, 0] = dist[:, 0]
        np.subtract(dist[:, 1:], dist[:, :-1], out=inc[:, 1:])
        angle = None
        if self.config.lateral_wander > 0.0:
            angle = state.omega[:, None, :] * (base * dt + t)
            angle += state.phase[:, None, :]
        d, d_dot = self.lateral(state, base, k, angle)
        # Along-lane distance -> arc length of the reference line: ds = dist / (1 + kappa d).
        scale = state.kappa[:, None, :] * d
        scale += 1.0
        inc /= scale
        s = np.add.accumulate(inc, axis=1)
        s += state.s[:, None, :]
        return s, d, v, d_dot

    def pose(self, s: FloatArray, d: FloatArray, v: FloatArray,
             d_dot: FloatArray) -> TrafficSamples:
        """World pose of Frenet states (any shape): one table lookup for all of them."""
        s = s % self.loop_0d
        u = s * self.grid_scale_0d
        # Cell index and fraction; floor is the cast's truncation for u >= 0, and u - floor
        # is float arithmetic, which numpy runs without the int-to-float buffering of u - i.
        cell = np.floor(u)
        if self.clamp_cell:  # s == L after rounding; else the table's extra column
            np.minimum(cell, self.grid_count - 1, out=cell)
        f = u - cell
        g = self.table.take(cell.astype(np.intp), axis=1)  # (12, ...): values, then steps
        geo = g[6:] * f
        geo += g[:6]  # x, y, tx, ty, ty, -tx
        normal = geo[4:]
        # Right normal n = (ty, -tx); velocity = v * tangent + d_dot * n.
        xy = d * normal
        xy += geo[:2]
        vxy = v * geo[2:4]
        vxy += d_dot * normal
        # Heading of the motion; a (near) stopped car keeps pointing along its lane (for
        # v >= 1 m/s this is the velocity itself, to the bit).
        direction = np.maximum(v, 1.0) * geo[2:4]
        direction += d_dot * normal
        heading = np.arctan2(direction[1], direction[0])
        return TrafficSamples._make(s, d, v, xy[0], xy[1], heading, vxy[0], vxy[1])

    def samples_now(self, state: TrafficState) -> TrafficSamples:
        """The current state as a one-frame :class:`TrafficSamples` (``(envs, 1, cars)``)."""
        base = (state.step - 1)[:, None, None]
        d, d_dot = self.lateral(state, base, np.ones((1, 1, 1), dtype=np.int64))
        return self.pose(state.s[:, None, :], d, state.speed[:, None, :], d_dot)

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
