"""The behavior-level observation: a world model as a flat, normalised float32 vector.

One vector per decision, the same for the behavior-level env and for a trained policy
driving the path-level env. With ``n`` lanes (3 on the default highway) the entries are,
in order (:meth:`BehaviorFeatures.names` gives each one's name):

=====================  =====  ==================================================  =========
entry                  count  meaning                                             range
=====================  =====  ==================================================  =========
speed                  1      ego speed / cruise speed (49.83 mph)                [0, 1.2]
ego_lane               n      one-hot lane holding the ego's d                    {0, 1}
target_lane            n      one-hot lane the ego is driving to                  {0, 1}
offset                 1      (ego d - target lane centre) / lane width           [-3, 3]
changing               1      1 while a lane change is under way                  {0, 1}
since_change           1      time since the last lane change / 10 s, clipped     [0, 1]
curvature              1      ``radius_scale / road radius`` ahead, clipped       [0, 1]
allowed_left/right     2      1 when that lane move would start a change now      {0, 1}
per lane (n times):    4n
  ahead_gap                   gap to the nearest car ahead / sensing range        [0, 1]
  ahead_speed                 (its speed - ego speed) / cruise speed (0: nobody)  [-2, 2]
  behind_gap                  gap to the nearest car behind / sensing range       [0, 1]
  behind_speed                (its speed - ego speed) / cruise speed (0: nobody)  [-2, 2]
=====================  =====  ==================================================  =========

With ``extended=True`` (the behavior env's ``observation: "extended"``) ``3n`` entries
follow, per lane (n times):

=====================  =====  ==================================================  =========
second_gap                    gap to the second car ahead / sensing range         [0, 1]
second_speed                  (its speed - ego speed) / cruise speed (0: nobody)  [-2, 2]
ahead_lateral                 lateral rate of the nearest car ahead / 2 m/s       [-1, 1]
=====================  =====  ==================================================  =========

The second car tells a lane that is open beyond its first car from one that is a queue
(the seed planner sees only the nearest car per lane); ``ahead_lateral`` (positive moving
right) is the lane-change intent of the car a move would follow.

Gaps are centre to centre along the road (the world model's); an empty lane reads as a gap
of 1 (the sensing range) and a relative speed of 0. ``curvature`` is 1 at the seed's
no-lane-change radius (500 m) and tighter, 0 on a straight. ``allowed_*`` come from the
executor (its shield's lane-change rule, or just "a lane exists" without a shield): they
let a policy see what the shield would refuse.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.stack.highway import behavior_kernel as kernel
from sdc_gym.stack.highway.decisions import CRUISE_SPEED_MPS, DecisionExecutor
from sdc_gym.stack.highway.shield import views_of
from sdc_gym.stack.highway.world_model import WorldModel

SINCE_CHANGE_SCALE_S = 10.0
RADIUS_SCALE_M = 500.0
OFFSET_LIMIT = 3.0
REL_SPEED_LIMIT = 2.0
SPEED_RATIO_MAX = 1.2  # the speed entry's upper bound (x cruise speed)
LATERAL_SCALE_MPS = 2.0  # a lane change's lateral rate is about 1.3 m/s
OBSERVATION_TYPES = ("nearest", "extended")


class BehaviorFeatures:
    """Encodes world models for ``lane_count`` lanes (see the module docstring).

    Args:
        lane_count: lanes of the road.
        sensing_range_m: perception's range (gaps are divided by it).
        extended: add the second car ahead and the lateral rate of the car ahead per lane.
    """

    def __init__(self, lane_count: int, sensing_range_m: float = 200.0,
                 extended: bool = False) -> None:
        if lane_count < 1 or not sensing_range_m > 0.0:
            raise ValueError("lane_count >= 1 and sensing_range_m > 0")
        self.lane_count = lane_count
        self.sensing_range_m = sensing_range_m
        self.extended = extended
        self.base_size = 7 + 6 * lane_count
        self.size = self.base_size + (3 * lane_count if extended else 0)
        low = np.zeros(self.size, dtype=np.float32)
        high = np.ones(self.size, dtype=np.float32)
        n = lane_count
        high[0] = SPEED_RATIO_MAX
        low[1 + 2 * n], high[1 + 2 * n] = -OFFSET_LIMIT, OFFSET_LIMIT
        per_lane = 7 + 2 * n
        for lane in range(n):
            for column in (1, 3):  # relative speeds
                low[per_lane + 4 * lane + column] = -REL_SPEED_LIMIT
                high[per_lane + 4 * lane + column] = REL_SPEED_LIMIT
            if extended:
                i = self.base_size + 3 * lane
                low[i + 1], high[i + 1] = -REL_SPEED_LIMIT, REL_SPEED_LIMIT
                low[i + 2] = -1.0
        self.space = spaces.Box(low, high, dtype=np.float32)
        # The kernel's constants (sdc_gym.stack.highway.behavior_kernel.encode).
        self.scales = np.array([CRUISE_SPEED_MPS, sensing_range_m, SPEED_RATIO_MAX,
                                OFFSET_LIMIT, REL_SPEED_LIMIT, SINCE_CHANGE_SCALE_S,
                                RADIUS_SCALE_M])

    def names(self) -> list[str]:
        n = range(self.lane_count)
        return ["speed", *(f"ego_lane_{i}" for i in n), *(f"target_lane_{i}" for i in n),
                "offset", "changing", "since_change", "curvature", "allowed_left",
                "allowed_right",
                *(f"lane_{i}_{name}" for i in n
                  for name in ("ahead_gap", "ahead_speed", "behind_gap", "behind_speed")),
                *(f"lane_{i}_{name}" for i in (n if self.extended else ())
                  for name in ("second_gap", "second_speed", "ahead_lateral"))]

    def encode(self, world: WorldModel, executor: DecisionExecutor) -> NDArray[np.float32]:
        """The observation for ``world`` with the executor's lane-change state."""
        if world.lane_count != self.lane_count:
            raise ValueError(f"world has {world.lane_count} lanes, features expect "
                             f"{self.lane_count}")
        out = np.zeros(self.size, dtype=np.float32)
        batch = executor.batch
        kernel.encode(executor.shield is not None, batch.shield_array, views_of(world),
                      world.ego_lane, world.ego_d, world.ego_speed, world.lane_width,
                      world.road_radius, world.time, batch.ints, batch.last_change,
                      executor.env, self.scales, out)
        if self.extended:
            cars = world.cars
            kernel.encode_traffic(
                views_of(world), np.array([car.id for car in cars], dtype=np.int64),
                np.array([car.lane for car in cars], dtype=np.int64),
                np.array([car.gap for car in cars], dtype=np.float64),
                np.array([car.speed for car in cars], dtype=np.float64),
                np.array([car.d_rate for car in cars], dtype=np.float64), len(cars),
                world.ego_speed, self.scales, LATERAL_SCALE_MPS, out, self.base_size)
        return out
