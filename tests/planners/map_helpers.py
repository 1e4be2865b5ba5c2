"""What the course's planners do with ``highway_map.csv``, written as they write it.

Every planner built from the project template starts by reading the map file (``x y s dx
dy`` per line) into ``map_waypoints_x/y/s/dx/dy`` from a path relative to its working
directory; the walkthrough then converts with the template's ``getXY`` (linear along the
chord holding s, offset d along its right normal). Planners do not import the simulator's
code, so neither do these stand-ins: the helpers are written out here, from the template
(``helpers.h`` of ``udacity/CarND-Path-Planning-Project``).
"""

from __future__ import annotations

import argparse
import bisect
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MapFile:
    """The map file's columns, as the template's ``main.cpp`` loads them."""

    x: list[float]
    y: list[float]
    s: list[float]
    dx: list[float]
    dy: list[float]

    @classmethod
    def load(cls, path: str) -> MapFile:
        columns: list[list[float]] = [[], [], [], [], []]
        with open(path, encoding="utf-8") as handle:
            for line in handle:
                fields = line.split()
                if len(fields) == 5:
                    for column, value in zip(columns, fields, strict=True):
                        column.append(float(value))
        if len(columns[0]) < 3:
            raise SystemExit(f"{path}: not a highway map (x y s dx dy per line)")
        return cls(*columns)

    @property
    def max_s(self) -> float:
        """The loop length the planners hard-code (6945.554 for the original): the last
        waypoint's s plus the closing chord."""
        return self.s[-1] + math.hypot(self.x[0] - self.x[-1], self.y[0] - self.y[-1])

    def get_xy(self, s: float, d: float) -> tuple[float, float]:
        """The template's ``getXY``: along the chord holding ``s``, ``d`` to its right
        (not wrapped: past the last waypoint it runs on along the closing chord)."""
        prev_wp = max(bisect.bisect_left(self.s, s) - 1, 0)  # last waypoint with s_i < s
        wp2 = (prev_wp + 1) % len(self.x)
        heading = math.atan2(self.y[wp2] - self.y[prev_wp], self.x[wp2] - self.x[prev_wp])
        seg_s = s - self.s[prev_wp]
        seg_x = self.x[prev_wp] + seg_s * math.cos(heading)
        seg_y = self.y[prev_wp] + seg_s * math.sin(heading)
        perp = heading - math.pi / 2
        return seg_x + d * math.cos(perp), seg_y + d * math.sin(perp)


def s_ahead(s_from: float, s_to: float, max_s: float) -> float:
    """``s_to - s_from`` folded into ``[-max_s / 2, max_s / 2)`` (the loop's seam)."""
    return (s_to - s_from + max_s / 2) % max_s - max_s / 2


def planner_command_line(description: str | None) -> argparse.Namespace:
    """The stand-ins' command line, the template's two settings: ``--port`` (4567) and
    ``--map`` (``../data/highway_map.csv``, relative to the working folder)."""
    parser = argparse.ArgumentParser(description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--port", type=int, default=4567)
    parser.add_argument("--map", default="../data/highway_map.csv", help="relative to the cwd")
    return parser.parse_args()
