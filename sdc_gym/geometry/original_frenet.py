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

On an open road (``closed=False``; the Udacity-Bosch Challenge's maps) nothing wraps:
there is no chord from the last waypoint back to the first, so the previous waypoint is
clamped to the first chord and the last one (``0 .. n-2``). A point past the last waypoint
is measured along the last chord extended (s beyond the file's last s, growing); a point
behind the first waypoint reads ``s = |projection|`` on the first chord, the original's
own rule (its s is a sum that never subtracts), so s is never negative.

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
    closed: bool = True

    def __post_init__(self) -> None:
        rows = np.asarray(self.waypoints, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] < 5 or len(rows) < 3:
            raise ValueError(f"waypoints must be (n >= 3, 5) rows x y s dx dy, got {rows.shape}")
        object.__setattr__(self, "waypoints", rows)
        # Per waypoint i, as the previous one of a chord i -> i + 1: its x, y, s, the chord
        # vector, its squared length and length; and the road's direction (-dy, dx) at i
        # (the next-waypoint test). One gather per call instead of a dozen.
        chord = np.roll(rows[:, :2], -1, axis=0) - rows[:, :2]
        length_sq = (chord**2).sum(axis=1)
        object.__setattr__(self, "_chords", np.column_stack(
            [rows[:, :3], chord, length_sq, np.sqrt(length_sq)]))
        object.__setattr__(self, "_direction", np.column_stack([-rows[:, 4], rows[:, 3]]))

    @property
    def loop_length(self) -> float:
        """The polyline's length: the last waypoint's s plus the closing chord (an open
        road's: the last waypoint's s)."""
        if not self.closed:
            return float(self._chords[-1, 2])
        return float(self._chords[-1, 2] + self._chords[-1, 6])

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
        closest = self.closest_waypoint(xy if anchor_xy is None else anchor_xy)
        # Beyond the closest waypoint along the road's direction there?
        offset = self.waypoints[closest, :2] - xy
        beyond = (offset * self._direction[closest]).sum(axis=1) < 0
        prev_wp = np.where(beyond, closest, closest - 1)
        if self.closed:
            prev_wp %= len(self.waypoints)
        else:  # no closing chord: the first chord before the start, the last past the end
            prev_wp = np.clip(prev_wp, 0, len(self.waypoints) - 2)
        table = self._chords[prev_wp]
        rel = xy - table[:, :2]
        chord = table[:, 3:5]
        along = (rel * chord).sum(axis=1) / table[:, 5]
        normal = rel - along[:, None] * chord
        d = np.sqrt((normal**2).sum(axis=1))
        left = chord[:, 0] * rel[:, 1] - chord[:, 1] * rel[:, 0] > 0  # left of travel: d < 0
        d[left] *= -1.0
        s = table[:, 2] + np.abs(along) * table[:, 6]  # |projection|: never subtracted
        return s, d
