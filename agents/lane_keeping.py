"""The first baseline: keep the lane, follow the car ahead with a jerk-limited speed profile.

A path-level planner for ``sdc_gym/HighwayLoop-v0`` that speaks the original's protocol:
each call it receives the unconsumed previous path and returns it extended with new
points. Like the seed planner it keeps its own queue of planned states (the simulator's
echo of the previous path is rounded), trims what the car consumed, and appends points
until the queue holds ``horizon_points``.

Speed: an IDM-style target acceleration toward ``target_speed_mph`` and behind the nearest
car ahead in the lane (from sensor fusion), limited to ``max_acceleration`` and changed at
most ``max_jerk`` per second, so the profile is smooth by construction. Position: the next
point is ``v * dt`` further along the lane centre; the step in s is divided by
``1 + curvature * d`` because a lane right of a left bend is longer than the centre line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.units import MPH_TO_MPS

PHYSICS_DT = 0.02  # s per path point, the simulator's frame


@dataclass(frozen=True)
class LaneKeepingParameters:
    """Tuning of :class:`LaneKeepingDriver` (units in the names' comments)."""

    horizon_points: int = 15          # points kept ahead of the car (0.3 s)
    target_speed_mph: float = 49.0    # cruise speed, under the 50 mph limit
    max_acceleration: float = 5.0     # m/s^2 magnitude, either sign
    max_jerk: float = 5.0             # m/s^3 on the commanded acceleration
    comfortable_acceleration: float = 2.0   # m/s^2, IDM a
    comfortable_deceleration: float = 3.0   # m/s^2, IDM b
    time_headway: float = 1.5         # s, IDM T
    jam_gap: float = 12.0             # m, IDM s0 centre to centre (a truck is 10 m long)
    sensing_range: float = 150.0      # m ahead in s
    lane_half_width: float = 2.0      # m: a car is in our lane when |d - lane d| < this
    lateral_rate: float = 0.002       # m per point: how fast d converges to the lane centre


class LaneKeepingDriver:
    """Drives ``HighwayLoop-v0`` in its starting lane; see the module docstring."""

    name = "lane_keeping"

    def __init__(self, road: HighwayMap, params: LaneKeepingParameters | None = None) -> None:
        self.road = road
        self.params = params or LaneKeepingParameters()
        self.reset()

    def reset(self) -> None:
        """Forget the planned queue (call at the start of each episode)."""
        # Queue of planned states, one row per point: x, y, s, d, v, a, road curvature.
        self._queue = np.zeros((0, 7))
        self._lane_d: float | None = None

    def act(self, observation: dict[str, NDArray]) -> NDArray[np.float64]:
        """The path to send: the unconsumed planned points plus new ones."""
        p = self.params
        ego = observation["ego"].astype(np.float64)
        remaining = int(observation["previous_path_count"])
        if self._lane_d is None:
            self._lane_d = float(self.road.lane_center(self.road.lane_of(ego[3])))
        # The simulator consumed the head of our queue; keep what it still has.
        self._queue = self._queue[len(self._queue) - min(remaining, len(self._queue)):]
        if len(self._queue):
            _, _, s, d, v, a, curvature = self._queue[-1].tolist()
        else:
            s, d, v, a = float(ego[2]), float(ego[3]), float(ego[5]), 0.0
            curvature = float(self.road.reference.curvature(s))
        new = p.horizon_points - len(self._queue)
        if new <= 0:
            return self._queue[:, :2].copy()
        lead_gap, lead_speed = self._lead(observation, s, v, len(self._queue))
        reference = self.road.reference
        rows = np.empty((new, 7))
        v_goal = p.target_speed_mph * MPH_TO_MPS
        # The new points span about a metre: the curvature at the last planned point is
        # exact enough for all of them (it is refreshed with every batch).
        for i in range(new):
            a = self._next_acceleration(v, a, v_goal, lead_gap, lead_speed)
            v = max(v + a * PHYSICS_DT, 0.0)
            d += min(max(self._lane_d - d, -p.lateral_rate), p.lateral_rate)
            s += v * PHYSICS_DT / (1.0 + curvature * d)
            lead_gap -= (v - lead_speed) * PHYSICS_DT
            rows[i, 2:6] = s, d, v, a
        rows[:, :2], rows[:, 6] = reference.to_xy_and_curvature(rows[:, 2], rows[:, 3])
        rows[:, 2] = reference.wrap_s(rows[:, 2])
        self._queue = np.vstack([self._queue, rows])
        return self._queue[:, :2].copy()

    def _lead(self, observation: dict[str, NDArray], s_plan: float, v_plan: float,
              queued: int) -> tuple[float, float]:
        """Bumper-ish gap and speed of the nearest car ahead in our lane, at the end of the
        queued plan (cars are moved forward by the plan's remaining duration)."""
        p = self.params
        fusion = observation["sensor_fusion"]
        speed = np.hypot(fusion[:, 3], fusion[:, 4])
        half = 0.5 * self.road.length
        # Modular gap along s from the end of our plan, cars moved on by the plan's duration.
        gap = np.mod(fusion[:, 5] + speed * (queued * PHYSICS_DT) - s_plan + half,
                     self.road.length) - half
        ahead = ((observation["sensor_fusion_mask"] > 0) & (gap > 0) & (gap < p.sensing_range)
                 & (np.abs(fusion[:, 6] - self._lane_d) < p.lane_half_width))
        if not ahead.any():
            return math.inf, 0.0
        nearest = int(np.argmin(np.where(ahead, gap, np.inf)))
        return float(gap[nearest]), float(speed[nearest])

    def _next_acceleration(self, v: float, a: float, v_goal: float, gap: float,
                           lead_speed: float) -> float:
        """IDM target acceleration, clipped, reached at a bounded jerk."""
        p = self.params
        target = p.comfortable_acceleration * (1.0 - (v / v_goal) ** 4)
        if gap != math.inf:
            desired = p.jam_gap + v * p.time_headway + v * (v - lead_speed) / (
                2.0 * math.sqrt(p.comfortable_acceleration * p.comfortable_deceleration))
            target -= p.comfortable_acceleration * (max(desired, 0.0) / max(gap, 0.1)) ** 2
        target = min(max(target, -p.max_acceleration), p.max_acceleration)
        step = p.max_jerk * PHYSICS_DT
        return min(max(target, a - step), a + step)
