"""A stand-in for the Frenet-frame planners: its own map-file s, jerk-minimizing paths.

The other big family of public planners for the highway simulator plans in Frenet
coordinates of its own making: it fits splines ``x(s), y(s), dx(s), dy(s)`` through the
map file's waypoints against the file's s column, keeps the (s, d) state of every point
it sent, and compares its s with the sensor fusion's s to find gaps. That only works
when the simulator's s is the map file's s (polyline s, wrapping at the file's 6945.554
m); a simulator reporting its own smooth arc length (6947.43 m around) puts cars up to
1.9 m off and breaks the modular differences at the seam. Per telemetry message:

1. drop the states of the points the simulator consumed (``sent - len(previous_path)``),
   keep up to ``KEEP`` of the rest (resent unchanged: continuity), start from the last
   kept state (the car's own telemetry s, d and speed on the first message);
2. behaviour from the sensor fusion (s, d, speed of each car, its s ahead of ours
   modulo the loop): follow the lane unless its leader within 40 m is slower than us;
   then take an adjacent lane whose gap is open (30 m ahead, 15 m behind at the
   predicted positions), else follow the leader's speed at a 25 m gap;
3. a quintic (minimum-jerk) polynomial in s from the start state to the target speed
   with zero acceleration over ``HORIZON`` seconds, and one in d from the start state to
   the target lane's centre with zero speed and acceleration over ``LANE_CHANGE`` seconds;
   sampled every 0.02 s and turned into map points through the splines. The target speed
   along s is lowered on a bend where the lane right of the centre line is longer
   (``1 + curvature * d``) so the car's own speed stays under the limit.

    python frenet_planner.py --port 4567 --map ../data/highway_map.csv
"""

from __future__ import annotations

import math
import sys
from collections import deque
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make ``tests.planners`` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np
from scipy.interpolate import CubicSpline

from tests.planners.map_helpers import MapFile, planner_command_line, s_ahead
from tests.planners.protocol_planner import Planner, serve

DT = 0.02
MPH = 0.44704
SPEED_LIMIT = 49.0 * MPH  # m/s the car itself may reach
PATH_POINTS = 50
KEEP = 15  # previous points resent unchanged (0.3 s of continuity)
HORIZON = 2.0  # s: longitudinal quintic
LANE_CHANGE = 3.0  # s: lateral quintic
MAX_SPEED_CHANGE = 5.0  # m/s per horizon (2.5 m/s^2 on average)
LEAD_LOOK = 40.0  # m
GAP_AHEAD = 30.0
GAP_BEHIND = 15.0
FOLLOW_GAP = 25.0
LANE_WIDTH = 4.0
LANES = 3


def quintic(start: tuple[float, float, float], end: tuple[float, float, float],
            duration: float) -> np.ndarray:
    """Coefficients (a0..a5) of the minimum-jerk polynomial from ``start`` (position,
    speed, acceleration) to ``end`` in ``duration`` seconds."""
    p0, v0, a0 = start
    p1, v1, a1 = end
    t = duration
    matrix = np.array([[t**3, t**4, t**5],
                       [3 * t**2, 4 * t**3, 5 * t**4],
                       [6 * t, 12 * t**2, 20 * t**3]])
    rhs = np.array([p1 - (p0 + v0 * t + 0.5 * a0 * t**2), v1 - (v0 + a0 * t), a1 - a0])
    a3, a4, a5 = np.linalg.solve(matrix, rhs)
    return np.array([p0, v0, 0.5 * a0, a3, a4, a5])


def evaluate(coefficients: np.ndarray, t: np.ndarray | float) -> tuple[Any, Any, Any]:
    """Position, speed and acceleration of a quintic at time(s) ``t`` (clamped to its
    end: past it the end state continues at constant speed)."""
    c = coefficients
    pos = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))))
    vel = c[1] + t * (2 * c[2] + t * (3 * c[3] + t * (4 * c[4] + t * 5 * c[5])))
    acc = 2 * c[2] + t * (6 * c[3] + t * (12 * c[4] + t * 20 * c[5]))
    return pos, vel, acc


def sample(coefficients: np.ndarray, duration: float, times: np.ndarray) -> tuple[np.ndarray, ...]:
    """The quintic over ``times``, held at its end state (constant speed) past ``duration``."""
    inside = np.minimum(times, duration)
    pos, vel, acc = evaluate(coefficients, inside)
    extra = times - inside
    return pos + vel * extra, vel + 0 * extra, np.where(extra > 0, 0.0, acc)


class SmoothMap:
    """Splines of x, y, dx, dy over the map file's s, periodic at the file's loop length."""

    def __init__(self, road: MapFile) -> None:
        self.road = road
        self.max_s = road.max_s
        s = np.array([*road.s, self.max_s])
        columns = [np.array([*c, c[0]]) for c in (road.x, road.y, road.dx, road.dy)]
        self.x, self.y, self.dx, self.dy = (CubicSpline(s, c, bc_type="periodic")
                                            for c in columns)

    def to_xy(self, s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = np.mod(s, self.max_s)
        dx, dy = self.dx(s), self.dy(s)
        norm = np.hypot(dx, dy)
        return self.x(s) + d * dx / norm, self.y(s) + d * dy / norm

    def to_frenet(self, x: float, y: float, s_guess: float) -> tuple[float, float]:
        """(s, d) of a point in the planner's own frame (the inverse of :meth:`to_xy`:
        the point lies on the normal line at s), searched 10 m around a guess (the
        telemetry's s: the same map-file s, so it is close)."""
        s = np.mod(s_guess + np.arange(-10.0, 10.0, 0.001), self.max_s)
        dx, dy = self.dx(s), self.dy(s)
        norm = np.hypot(dx, dy)
        rel_x, rel_y = x - self.x(s), y - self.y(s)
        along = (rel_x * -dy + rel_y * dx) / norm  # off the normal line, along the road
        best = int(np.argmin(np.abs(along)))
        return float(s[best]), float((rel_x[best] * dx[best] + rel_y[best] * dy[best])
                                     / norm[best])

    def length_factor(self, s: np.ndarray, d: float) -> float:
        """The largest ratio of distance along the lane at ``d`` to distance along s."""
        s = np.mod(s, self.max_s)
        x1, y1, x2, y2 = self.x(s, 1), self.y(s, 1), self.x(s, 2), self.y(s, 2)
        curvature = (x1 * y2 - y1 * x2) / np.hypot(x1, y1) ** 3
        return float(np.max(1.0 + curvature * d))


class FrenetPlanner:
    """See the module docstring."""

    def __init__(self, road: MapFile) -> None:
        self.map = SmoothMap(road)
        self.states: deque[tuple[float, float, float, float, float, float]] = deque()
        self.sent = 0
        self.lane: int | None = None

    def plan(self, telemetry: dict[str, Any]) -> tuple[list[float], list[float]]:
        t = telemetry
        previous_x, previous_y = list(t["previous_path_x"]), list(t["previous_path_y"])
        consumed = self.sent - len(previous_x)
        for _ in range(min(max(consumed, 0), len(self.states))):
            self.states.popleft()
        keep = min(KEEP, len(previous_x), len(self.states))
        kept = list(self.states)[:keep]
        if kept:
            s0, v0, a0, d0, dv0, da0 = kept[-1]
        else:  # the first message (or the path ran out): start where the car is
            s0, d0 = self.map.to_frenet(t["x"], t["y"], t["s"])
            v0, a0, dv0, da0 = t["speed"] * MPH, 0.0, 0.0, 0.0
        if self.lane is None:
            self.lane = min(max(int(t["d"] // LANE_WIDTH), 0), LANES - 1)
        target_speed = self._behave(s0, v0, len(kept), t["sensor_fusion"])
        target_d = 2.0 + LANE_WIDTH * self.lane
        factor = self.map.length_factor(s0 + np.linspace(0.0, 60.0, 13), target_d)
        target_speed = min(target_speed, SPEED_LIMIT / factor)
        target_speed = min(max(target_speed, v0 - MAX_SPEED_CHANGE), v0 + MAX_SPEED_CHANGE)
        target_speed = max(target_speed, 0.0)
        travel = 0.5 * (v0 + target_speed) * HORIZON
        lon = quintic((s0, v0, a0), (s0 + travel, target_speed, 0.0), HORIZON)
        lat = quintic((d0, dv0, da0), (target_d, 0.0, 0.0), LANE_CHANGE)
        times = DT * np.arange(1, PATH_POINTS - keep + 1)
        s, sv, sa = sample(lon, HORIZON, times)
        d, dv, da = sample(lat, LANE_CHANGE, times)
        x, y = self.map.to_xy(s, d)
        self.states = deque(kept)
        self.states.extend(zip((s % self.map.max_s).tolist(), sv.tolist(), sa.tolist(),
                               d.tolist(), dv.tolist(), da.tolist(), strict=True))
        next_x = previous_x[:keep] + x.tolist()
        next_y = previous_y[:keep] + y.tolist()
        self.sent = len(next_x)
        return next_x, next_y

    def _behave(self, s0: float, v0: float, horizon_points: int,
                sensor_fusion: list[list[float]]) -> float:
        """Pick the lane; return the target speed along s."""
        lead = {lane: (math.inf, SPEED_LIMIT) for lane in range(LANES)}
        blocked = dict.fromkeys(range(LANES), False)
        lookahead = horizon_points * DT  # the cars move on while our kept points run out
        for _car_id, _x, _y, vx, vy, s, d in sensor_fusion:
            if not 0.0 < d < LANES * LANE_WIDTH:
                continue
            lane = int(d // LANE_WIDTH)
            speed = math.hypot(vx, vy)
            gap = s_ahead(s0, s + speed * lookahead, self.map.max_s)
            if 0.0 < gap < lead[lane][0]:
                lead[lane] = (gap, speed)
            future = gap + (speed - v0) * HORIZON  # where it will be relative to us
            if -GAP_BEHIND < gap < GAP_AHEAD or -GAP_BEHIND < future < GAP_AHEAD:
                blocked[lane] = True
        gap, speed = lead[self.lane]
        if gap < LEAD_LOOK and speed < SPEED_LIMIT - 0.5:
            options = [lane for lane in (self.lane - 1, self.lane + 1)
                       if 0 <= lane < LANES and not blocked[lane]
                       and lead[lane][0] > gap + 10.0]
            if options:
                self.lane = max(options, key=lambda lane: lead[lane][0])
                return SPEED_LIMIT
            # Follow: the leader's speed, less while closer than the following gap.
            return max(speed + (gap - FOLLOW_GAP) * 0.2, 0.0)
        return SPEED_LIMIT


def main() -> None:
    args = planner_command_line(__doc__)
    serve(Planner(FrenetPlanner(MapFile.load(args.map)), "none", 0), args.port)


if __name__ == "__main__":
    main()
