"""A stand-in for the walkthrough planners that participants took to the Bosch Challenge.

The Udacity-Bosch Challenge (2017) ran on an open road, and participants took their
walkthrough-pattern planners (:mod:`tests.planners.walkthrough_planner`) there by reading
``data/highway_map_bosch1.csv`` in place of the loop's map (e.g.
shawnxiaow1118/SDC_Term3_Path_Planning, where our copy of the map comes from). The
pattern as written cannot drive an open road; these are the three changes the road
forces, each the smallest one that works:

1. **No seam.** s runs one way from the first waypoint; gaps are plain differences
   ``check_car_s - car_s`` (the loop's fold by ``max_s`` would put a car at the road's far
   end just behind the ego near its start).
2. **The start's yaw in radians.** The walkthrough hands the telemetry's yaw in degrees
   to cos and sin for its first anchor, which works only where the car starts at yaw 0;
   the Bosch road starts heading 1.6 degrees, and 1.6 "radians" put that anchor beside the
   car, the spline's x no longer increases and the planner aborts. They converted it.
3. **getXY clamped at the ends.** The template's getXY takes the chord after the last
   waypoint to be the one back to the first (a loop's closing chord); on the open road it
   is the last chord, extended.

    python bosch_walkthrough_planner.py --port 4567 --map ../data/highway_map_bosch1.csv
"""

from __future__ import annotations

import bisect
import math
import sys
from pathlib import Path

if __package__ in (None, ""):  # run as a script: make ``tests.planners`` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.planners.map_helpers import MapFile, planner_command_line
from tests.planners.protocol_planner import Planner, serve
from tests.planners.walkthrough_planner import AbortOnFailure, Walkthrough


class OpenMapFile(MapFile):
    """The map file as an open road: getXY on the chord holding s, the first one before
    the start and the last one (extended) past the end."""

    def get_xy(self, s: float, d: float) -> tuple[float, float]:
        last = len(self.x) - 1
        prev_wp = min(max(bisect.bisect_left(self.s, s) - 1, 0), last - 1)
        wp2 = prev_wp + 1
        heading = math.atan2(self.y[wp2] - self.y[prev_wp], self.x[wp2] - self.x[prev_wp])
        seg_s = s - self.s[prev_wp]
        seg_x = self.x[prev_wp] + seg_s * math.cos(heading)
        seg_y = self.y[prev_wp] + seg_s * math.sin(heading)
        perp = heading - math.pi / 2
        return seg_x + d * math.cos(perp), seg_y + d * math.sin(perp)


class BoschWalkthrough(Walkthrough):
    """The walkthrough with the open road's three changes (see the module docstring)."""

    @staticmethod
    def start_anchor(car_x: float, car_y: float, car_yaw: float) -> tuple[float, float]:
        yaw = math.radians(car_yaw)
        return car_x - math.cos(yaw), car_y - math.sin(yaw)

    @staticmethod
    def gap(car_s: float, check_car_s: float, max_s: float) -> float:
        return check_car_s - car_s


def main() -> None:
    args = planner_command_line(__doc__)
    road = OpenMapFile(*MapFile.load(args.map).__dict__.values())
    serve(Planner(AbortOnFailure(BoschWalkthrough(road)), "none", 0), args.port)


if __name__ == "__main__":
    main()
