"""What perception hands to behavior: the ego, each lane's nearest cars, the road ahead.

All distances are metres along the loop (modular s differences), speeds m/s along the
road. A lane with no car within sensing range has ``inf`` gaps and speed 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

NO_CAR = -1


@dataclass(frozen=True)
class TrackedCar:
    """One car as perception believes it is (filtered when tracking is on).

    Attributes:
        id: the sensor fusion id.
        s, d: Frenet position (m); s wrapped to ``[0, loop length)``.
        speed: m/s along the road (the s rate, scaled to metres of lane).
        d_rate: m/s lateral (positive moving right).
        lane: lane index holding d (-1 / lane_count when off the road).
        gap: signed s distance from the ego to the car (m, > 0 ahead), centre to centre.
    """

    id: int
    s: float
    d: float
    speed: float
    d_rate: float
    lane: int
    gap: float


@dataclass(frozen=True)
class LaneView:
    """The nearest car ahead and behind in one lane, as seen from the ego.

    Gaps are centre-to-centre s distances (> 0 both ways); ``inf`` when nobody is there.
    """

    lane: int
    ahead_gap: float = math.inf
    ahead_speed: float = 0.0
    ahead_id: int = NO_CAR
    behind_gap: float = math.inf
    behind_speed: float = 0.0
    behind_id: int = NO_CAR

    @property
    def has_ahead(self) -> bool:
        return self.ahead_id != NO_CAR

    @property
    def has_behind(self) -> bool:
        return self.behind_id != NO_CAR


@dataclass(frozen=True)
class WorldModel:
    """One perception cycle's picture of the world.

    Attributes:
        time: s since the episode started (the agent's clock: consumed points x 0.02 s).
        ego_s, ego_d: the ego's Frenet position (m).
        ego_speed: m/s.
        ego_lane: lane index holding ego_d.
        lane_count, lane_width: the road's lanes (m).
        lanes: one :class:`LaneView` per lane, index = lane. With ghosting on, a car in an
            adjacent lane drifting close to the ego appears in the ego lane's view too.
        cars: every perceived car.
        preferred_lane: the lane whose car ahead is furthest away (ties: the middle lane,
            then the ego's own lane).
        road_radius: circumradius (m) of the ego lane through s, s + 60, s + 120: the
            seed's "lower visibility" test for lane changes (inf on a straight).
    """

    time: float
    ego_s: float
    ego_d: float
    ego_speed: float
    ego_lane: int
    lane_count: int
    lane_width: float
    lanes: tuple[LaneView, ...]
    cars: tuple[TrackedCar, ...]
    preferred_lane: int
    road_radius: float

    def lane_center(self, lane: int) -> float:
        return (lane + 0.5) * self.lane_width

    @property
    def ego_offset(self) -> float:
        """Signed distance of the ego from its lane's centre (m, + to the right)."""
        return self.ego_d - self.lane_center(self.ego_lane)
