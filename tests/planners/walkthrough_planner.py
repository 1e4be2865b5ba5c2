"""A stand-in for the planners that descend from the course's project walkthrough.

Most public planners for the highway simulator grew out of the walkthrough video of the
path planning project (Udacity's "Project Q&A"): this is its pattern, in Python, served
over the original protocol exactly as the C++ planners serve it
(:mod:`tests.planners.protocol_planner`'s ``hasData`` framing). Per telemetry message:

1. ``prev_size = len(previous_path_x)``; when there is a previous path,
   ``car_s = end_path_s`` (the planner reasons from the end of what it already sent);
2. "too close": a car of the sensor fusion in our lane (by its ``d``) whose ``s``,
   projected ``prev_size * 0.02`` s ahead at its speed, is less than 30 m ahead of
   ``car_s``; then change lane if the next lane (left first) has nobody from 15 m behind
   to 30 m ahead, and slow down by 0.224 mph; otherwise speed up by 0.224 mph up to
   49.5 mph (``ref_vel``: the walkthrough's ramp of 0.224 mph per message);
3. spline anchors: with fewer than 2 previous points, ``(car_x - cos(car_yaw), car_y -
   sin(car_yaw))`` and the car, where ``car_yaw`` is the telemetry's yaw **in degrees**
   (the walkthrough's well-known slip: it only works because the original's first yaw is
   exactly 0, where cos and sin are the same in any unit), and ``ref_yaw =
   deg2rad(car_yaw)``; otherwise the last two previous points and their heading. Then the
   template's coarse ``getXY`` at ``car_s + 30, 60, 90`` m in the middle of the lane;
4. the anchors shifted and rotated into the car's frame at ``ref``; a cubic spline through
   them (scipy's ``CubicSpline``, natural ends like ``tk::spline``; like ``tk::spline`` it
   needs the anchors' x strictly increasing and fails otherwise); the previous path
   resent, then points along the spline spaced for ``ref_vel`` up to 50 points in all,
   rotated back to the map.

Two changes from the walkthrough, both of the kind its descendants made: gaps are
measured across the loop's seam (modulo the map's length; the walkthrough's plain
``check_car_s > car_s`` misses a car just past the seam), and slowing down stops at one
ramp step (the walkthrough's ``ref_vel`` can reach 0, where its point spacing divides by
zero, and go negative, where its points run backwards: a car close ahead at the start
does it).

    python walkthrough_planner.py --port 4567 --map ../data/highway_map.csv

A failure in planning (the spline's) ends the process with code 134, as the C++ planners'
``assert`` does (SIGABRT), after printing it.
"""

from __future__ import annotations

import math
import os
import sys
import traceback
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make ``tests.planners`` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from scipy.interpolate import CubicSpline

from tests.planners.map_helpers import MapFile, planner_command_line, s_ahead
from tests.planners.protocol_planner import Planner, serve

PATH_POINTS = 50
DT = 0.02
MPH_PER_MPS = 2.24  # the walkthrough's conversion
RAMP_MPH = 0.224  # per message: 5 m/s^2 at one message per frame
TOP_MPH = 49.5
TOO_CLOSE_M = 30.0
CLEAR_BEHIND_M = 15.0
ANCHORS_M = (30.0, 60.0, 90.0)
LANE_WIDTH = 4.0
LANES = 3


def lane_of(d: float) -> int:
    """The lane holding ``d`` (the walkthrough's ``d < 2 + 4 * lane + 2 && d > ...``)."""
    return int(d // LANE_WIDTH) if 0.0 < d < LANES * LANE_WIDTH else -1


class Walkthrough:
    """The walkthrough's planner state (lane, reference velocity) and its message handler."""

    def __init__(self, road: MapFile) -> None:
        self.road = road
        self.lane = 1
        self.ref_vel = 0.0  # mph

    def plan(self, telemetry: dict[str, Any]) -> tuple[list[float], list[float]]:
        t = telemetry
        previous_x, previous_y = list(t["previous_path_x"]), list(t["previous_path_y"])
        prev_size = len(previous_x)
        car_x, car_y, car_yaw = t["x"], t["y"], t["yaw"]
        car_s = t["end_path_s"] if prev_size > 0 else t["s"]
        self._behave(car_s, prev_size, t["sensor_fusion"])

        ptsx: list[float] = []
        ptsy: list[float] = []
        ref_x, ref_y, ref_yaw = car_x, car_y, math.radians(car_yaw)
        if prev_size < 2:
            back_x, back_y = self.start_anchor(car_x, car_y, car_yaw)
            ptsx += [back_x, car_x]
            ptsy += [back_y, car_y]
        else:
            ref_x, ref_y = previous_x[-1], previous_y[-1]
            ref_x_prev, ref_y_prev = previous_x[-2], previous_y[-2]
            ref_yaw = math.atan2(ref_y - ref_y_prev, ref_x - ref_x_prev)
            ptsx += [ref_x_prev, ref_x]
            ptsy += [ref_y_prev, ref_y]
        for ahead in ANCHORS_M:
            x, y = self.road.get_xy(car_s + ahead, 2.0 + LANE_WIDTH * self.lane)
            ptsx.append(x)
            ptsy.append(y)
        cos_r, sin_r = math.cos(-ref_yaw), math.sin(-ref_yaw)
        shifted = [(x - ref_x, y - ref_y) for x, y in zip(ptsx, ptsy, strict=True)]
        local_x = [x * cos_r - y * sin_r for x, y in shifted]
        local_y = [x * sin_r + y * cos_r for x, y in shifted]
        spline = CubicSpline(local_x, local_y, bc_type="natural")  # x must increase

        next_x, next_y = previous_x, previous_y
        target_x = 30.0
        target_y = float(spline(target_x))
        target_dist = math.hypot(target_x, target_y)
        steps = target_dist / (DT * self.ref_vel / MPH_PER_MPS)
        x_add_on = 0.0
        cos_b, sin_b = math.cos(ref_yaw), math.sin(ref_yaw)
        for _ in range(PATH_POINTS - prev_size):
            x_point = x_add_on + target_x / steps
            y_point = float(spline(x_point))
            x_add_on = x_point
            next_x.append(x_point * cos_b - y_point * sin_b + ref_x)
            next_y.append(x_point * sin_b + y_point * cos_b + ref_y)
        return next_x, next_y

    @staticmethod
    def start_anchor(car_x: float, car_y: float, car_yaw: float) -> tuple[float, float]:
        """The anchor behind a car without a previous path: ``car_yaw`` in degrees handed
        to cos and sin, as in the walkthrough."""
        return car_x - math.cos(car_yaw), car_y - math.sin(car_yaw)

    @staticmethod
    def gap(car_s: float, check_car_s: float, max_s: float) -> float:
        """How far ``check_car_s`` is ahead of ``car_s``: across the loop's seam."""
        return s_ahead(car_s, check_car_s, max_s)

    def _behave(self, car_s: float, prev_size: int, sensor_fusion: list[list[float]]) -> None:
        """The "too close" logic: lane and reference velocity for this message."""
        max_s = self.road.max_s
        ahead_in: dict[int, list[float]] = {lane: [] for lane in range(LANES)}
        for _car_id, _x, _y, vx, vy, s, d in sensor_fusion:
            lane = lane_of(d)
            if lane < 0:
                continue
            check_car_s = s + prev_size * DT * math.hypot(vx, vy)
            ahead_in[lane].append(self.gap(car_s, check_car_s, max_s))
        too_close = any(0.0 < gap < TOO_CLOSE_M for gap in ahead_in[self.lane])
        if too_close:
            for lane in (self.lane - 1, self.lane + 1):
                if 0 <= lane < LANES and not any(-CLEAR_BEHIND_M < gap < TOO_CLOSE_M
                                                 for gap in ahead_in[lane]):
                    self.lane = lane
                    break
            # Never below one ramp step: at 0 the walkthrough's spacing divides by zero,
            # below it its points run backwards.
            self.ref_vel = max(self.ref_vel - RAMP_MPH, RAMP_MPH)
        elif self.ref_vel < TOP_MPH:
            self.ref_vel += RAMP_MPH


class AbortOnFailure:
    """The brain, but a planning failure ends the process like a C++ ``assert``."""

    def __init__(self, brain: Walkthrough) -> None:
        self.brain = brain

    def plan(self, telemetry: dict[str, Any]) -> tuple[list[float], list[float]]:
        try:
            return self.brain.plan(telemetry)
        except Exception:  # any failure aborts, as assert() does
            traceback.print_exc()
            print("Assertion failed: planning (the spline's x must increase)", flush=True)
            os._exit(134)


def main() -> None:
    args = planner_command_line(__doc__)
    serve(Planner(AbortOnFailure(Walkthrough(MapFile.load(args.map))), "none", 0), args.port)


if __name__ == "__main__":
    main()
