"""The original highway simulator's own Frenet conversion (what its telemetry reports).

The Unity simulator computes every s and d it sends with one routine,
``CarAIControl.getFrenetFrame`` (``udacity/self-driving-car-sim``, file
``Assets/Standard Assets/Vehicles/Car/Scripts/CarAIControl.cs``), over the same 181
waypoints as ``highway_map.csv``:

1. the waypoint closest to the **car running the script** (``MyClosestWaypoint``: the
   car's own position, not the point being converted; it matters for ``end_path_s/d``,
   which the ego car's script computes for the last point of its path);
2. the next waypoint: that one, or the one after it when the point lies beyond it along
   the road (the inner product of waypoint minus point with the road's direction at the
   waypoint, ``(-dy, dx)``, is negative);
3. the point projected on the chord from the previous waypoint to the next one;
   ``s = s[previous] + |projection|`` (the file's s column is exactly the sum of chord
   lengths the script adds up), ``d`` the distance to that line, negative when the point
   is on the side of the fixed map point (1000, 2000), i.e. left of the chord.

So s follows the waypoint polyline and wraps at the file's loop length (6945.554 m for
the original map), d is measured to chords rather than to the smooth centre line, and
``end_path_s`` is an extrapolation along the chord under the ego car when the path ends
beyond the next waypoint. :mod:`sdc_gym.geometry.coarse_frenet` is the planner
template's cousin of this routine (closest waypoint to the point itself, next waypoint by
the car's heading, s re-summed from the rounded x, y columns).

The sign: within the road (|d| well under the fixed point's distance from any chord),
"nearer to (1000, 2000) than the projection is" is the same as "left of the chord" on the
original map (the fixed point lies left of all 181 chords; a test pins it). This module
uses the left-of-chord test, which means the same on every map, including ours.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

FRENET_CONVENTIONS = ("original", "exact")
"""The ``frenet`` setting of the highway env's telemetry: ``original`` (this module, what
the Unity simulator sends) or ``exact`` (the smooth reference line the env simulates on)."""


@dataclass(frozen=True)
class OriginalFrenet:
    """``getFrenetFrame`` over a map's waypoints (rows ``x y s dx dy`` of the map file).

    Call :meth:`convert` with the points and, for each, the position of the car whose
    closest waypoint is used (the point itself for a car's own s, d; the ego car's
    position for the end of its path).
    """

    waypoints: FloatArray = field(repr=False)

    def __post_init__(self) -> None:
        rows = np.asarray(self.waypoints, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] < 5 or len(rows) < 3:
            raise ValueError(f"waypoints must be (n >= 3, 5) rows x y s dx dy, got {rows.shape}")
        object.__setattr__(self, "waypoints", rows)

    @property
    def loop_length(self) -> float:
        """The polyline's length: the last waypoint's s plus the closing chord."""
        last, first = self.waypoints[-1], self.waypoints[0]
        return float(last[2] + np.hypot(first[0] - last[0], first[1] - last[1]))

    def closest_waypoint(self, xy: ArrayLike) -> NDArray[np.intp]:
        """Index of the waypoint nearest each (x, y) (Euclidean; the first one on ties)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        w = self.waypoints
        dist_sq = (xy[:, :1] - w[:, 0]) ** 2 + (xy[:, 1:] - w[:, 1]) ** 2
        return np.argmin(dist_sq, axis=1)

    def convert(self, xy: ArrayLike, anchor_xy: ArrayLike | None = None
                ) -> tuple[FloatArray, FloatArray]:
        """(s, d) of the points ``xy`` (shape ``(n, 2)`` or ``(2,)``), as the original.

        ``anchor_xy``: the position of the car whose closest waypoint starts the search,
        one per point or one for all (default: each point itself).
        """
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        anchor = xy if anchor_xy is None else np.broadcast_to(
            np.asarray(anchor_xy, dtype=np.float64).reshape(-1, 2), xy.shape)
        w = self.waypoints
        count = len(w)
        closest = self.closest_waypoint(anchor)
        cx, cy = w[closest, 0], w[closest, 1]
        # Beyond the closest waypoint along the road's direction there (-dy, dx)?
        beyond = (cx - xy[:, 0]) * -w[closest, 4] + (cy - xy[:, 1]) * w[closest, 3] < 0
        next_wp = np.where(beyond, (closest + 1) % count, closest)
        prev_wp = (next_wp - 1) % count
        px, py = w[prev_wp, 0], w[prev_wp, 1]
        chord_x, chord_y = w[next_wp, 0] - px, w[next_wp, 1] - py
        rel_x, rel_y = xy[:, 0] - px, xy[:, 1] - py
        along = (rel_x * chord_x + rel_y * chord_y) / (chord_x * chord_x + chord_y * chord_y)
        proj_x, proj_y = along * chord_x, along * chord_y
        d = np.hypot(rel_x - proj_x, rel_y - proj_y)
        left = chord_x * rel_y - chord_y * rel_x > 0  # left of travel: d < 0
        d = np.where(left, -d, d)
        s = w[prev_wp, 2] + np.hypot(proj_x, proj_y)  # |projection|: never subtracted
        return s, d
