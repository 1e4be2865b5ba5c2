"""The coarse Frenet helpers of the original Udacity planner template, for compatibility.

Planners written for the original highway simulator convert with piecewise-linear helpers
over the sparse map waypoints (``ClosestWaypoint``, ``NextWaypoint``, ``getFrenet``,
``getXY`` in the project template). They are reproduced here, semantics included, so a
ported planner behaves the same. **They are coarse**: s jumps at waypoints, d is measured
to a chord rather than the curve, and the sign of d is decided by comparing distances to a
fixed point ((1000, 2000) on the original map). sdc-gym itself uses the exact
:class:`~sdc_gym.geometry.reference_line.ReferenceLine`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

# The fixed point the original template uses to decide the sign of d.
ORIGINAL_SIGN_POINT = (1000.0, 2000.0)


@dataclass(frozen=True)
class CoarseFrenet:
    """Waypoint-based helpers over ``maps_x``, ``maps_y``, ``maps_s`` (the map file columns).

    Args:
        maps_x, maps_y, maps_s: the waypoint columns, in file order.
        sign_point: the template's fixed reference point for the sign of d; on maps other
            than the original, pass a point inside the loop (e.g. the waypoint centroid).
    """

    maps_x: NDArray[np.float64]
    maps_y: NDArray[np.float64]
    maps_s: NDArray[np.float64]
    sign_point: tuple[float, float] = ORIGINAL_SIGN_POINT

    @classmethod
    def from_waypoints(cls, waypoints: NDArray[np.float64],
                       sign_point: tuple[float, float] | None = None) -> CoarseFrenet:
        """From an (n, >=3) array of ``x y s ...`` rows (a map file's content)."""
        if sign_point is None:
            sign_point = (float(waypoints[:, 0].mean()), float(waypoints[:, 1].mean()))
        return cls(np.asarray(waypoints[:, 0], dtype=np.float64),
                   np.asarray(waypoints[:, 1], dtype=np.float64),
                   np.asarray(waypoints[:, 2], dtype=np.float64), sign_point)

    def closest_waypoint(self, x: float, y: float) -> int:
        """Index of the waypoint nearest to (x, y) (Euclidean; first one on ties)."""
        return int(np.argmin(np.hypot(self.maps_x - x, self.maps_y - y)))

    def next_waypoint(self, x: float, y: float, theta: float) -> int:
        """The closest waypoint, or the one after it when the closest lies behind the car
        (bearing to it more than pi/2 from the heading ``theta`` in radians)."""
        closest = self.closest_waypoint(x, y)
        bearing = math.atan2(self.maps_y[closest] - y, self.maps_x[closest] - x)
        angle = abs(theta - bearing)
        angle = min(2 * math.pi - angle, angle)
        if angle > math.pi / 2:
            closest = (closest + 1) % len(self.maps_x)
        return closest

    def get_frenet(self, x: float, y: float, theta: float) -> tuple[float, float]:
        """(s, d) by projecting onto the chord previous -> next waypoint (coarse)."""
        next_wp = self.next_waypoint(x, y, theta)
        prev_wp = next_wp - 1 if next_wp > 0 else len(self.maps_x) - 1
        n_x = self.maps_x[next_wp] - self.maps_x[prev_wp]
        n_y = self.maps_y[next_wp] - self.maps_y[prev_wp]
        x_x = x - self.maps_x[prev_wp]
        x_y = y - self.maps_y[prev_wp]
        proj_norm = (x_x * n_x + x_y * n_y) / (n_x * n_x + n_y * n_y)
        proj_x = proj_norm * n_x
        proj_y = proj_norm * n_y
        frenet_d = math.hypot(x_x - proj_x, x_y - proj_y)
        center_x = self.sign_point[0] - self.maps_x[prev_wp]
        center_y = self.sign_point[1] - self.maps_y[prev_wp]
        if math.hypot(center_x - x_x, center_y - x_y) <= math.hypot(center_x - proj_x,
                                                                    center_y - proj_y):
            frenet_d = -frenet_d
        # The template sums chord lengths up to prev_wp rather than reading maps_s.
        chords = np.hypot(np.diff(self.maps_x[: prev_wp + 1]), np.diff(self.maps_y[: prev_wp + 1]))
        frenet_s = float(chords.sum()) + math.hypot(proj_x, proj_y)
        return frenet_s, float(frenet_d)

    def get_xy(self, s: float, d: float) -> tuple[float, float]:
        """(x, y) by walking the chord that holds ``s`` and offsetting d to its right."""
        # The template scans for the last waypoint with maps_s < s; s <= maps_s[0] uses
        # the first segment (the template would read out of bounds there).
        prev_wp = max(int(np.searchsorted(self.maps_s, s, side="left")) - 1, 0)
        wp2 = (prev_wp + 1) % len(self.maps_x)
        heading = math.atan2(self.maps_y[wp2] - self.maps_y[prev_wp],
                             self.maps_x[wp2] - self.maps_x[prev_wp])
        seg_s = s - self.maps_s[prev_wp]
        seg_x = self.maps_x[prev_wp] + seg_s * math.cos(heading)
        seg_y = self.maps_y[prev_wp] + seg_s * math.sin(heading)
        perp = heading - math.pi / 2
        return float(seg_x + d * math.cos(perp)), float(seg_y + d * math.sin(perp))
