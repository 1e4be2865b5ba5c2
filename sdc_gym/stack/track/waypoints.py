"""Waypoint loader and waypoint updater: the base path with speeds, and the final waypoints.

The first two nodes of the drive-by-wire reference stack (spec "The nodes"):

Waypoint loader (:func:`load_waypoints`, runs once)
    The track's waypoints in driving order with a target speed each: the speed limit
    everywhere. The original loader also ramped the speed down towards the *end of the
    list* (``v = min(v, sqrt(2 * 1.0 * dist_to_end))``, zero below 1 m/s) because its paths
    ended there. On a closed loop the end of the list is just the seam where the loop
    closes, so that ramp would stop the car once per lap for nothing: it is off by default
    and available as ``seam_ramp=True`` only to reproduce the quirk.

Waypoint updater (:class:`WaypointUpdater`, runs at its own rate)
    Finds the next waypoint ahead of the car (a full search at start, then a window of 5
    behind and 50 ahead of the previous index, wrapping at the seam; a full search again
    when the closest waypoint in the window is more than 2 m away) and publishes the next
    ``count`` (default 200) waypoints as :class:`FinalWaypoints` with their speeds:

    * the base speed, capped by the behavior layer's target speed;
    * with a stop requested at a stop-line waypoint: zero speed from the *stop point*
      ``stop_margin_m`` before the stop line onwards (the line itself when the updater
      was given the stop lines' positions, else the waypoint, up to half a spacing off),
      and before it ``v = min(v, sqrt(2 * stop_decel * distance_to_stop_point))``
      (constant comfortable deceleration), speeds below ``min_ramp_speed`` set to zero as
      in the original loader. The original updater ramped by 0.2 m/s per waypoint
      backwards instead; on 0.64 m spacing that is ``v = 0.31 * distance``, i.e. a
      deceleration ``v dv/ds = 0.31 v`` that is harsh at speed (3.5 m/s^2 at 40 km/h) and
      a slow crawl at the end, and it depends on the waypoint spacing. The square-root
      ramp is the constant-deceleration profile the speed controller can follow;
    * watchdog: when the pose or the light information is older than ``watchdog_s``
      (0.5 s), every speed is zero (an emergency stop, the seed team's safety net).

Conventions: positions in metres in the map frame, yaw in rad counter-clockwise from +x,
speeds in m/s, times in s on the agent's clock. The *pose* is the env's reference point,
the rear axle; ``stop_margin_m`` is therefore "front bumper offset + wanted gap". Distances
along the path are those of the closed polyline through the waypoints (``s`` of waypoint
``i`` = the polyline length from waypoint 0), which is what the original stack measured.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.geometry import exact_math
from sdc_gym.kernel_compiler import TypedCall
from sdc_gym.road.track_map import TrackMap, loop_points
from sdc_gym.stack.track.node_kernels import (
    UpdaterConstants,
    lower_for_stop,
    next_waypoint,
    update_waypoints,
    updater_state,
)

# --- the original loader's end-of-list ramp (reproduced only on request) -------------------
SEAM_RAMP_DECEL_MPS2 = 1.0
SEAM_RAMP_MIN_SPEED_MPS = 1.0

# --- updater defaults (spec) -----------------------------------------------------------------
DEFAULT_FINAL_COUNT = 200
SEARCH_BEHIND = 5
SEARCH_AHEAD = 50
FULL_SEARCH_DISTANCE_M = 2.0
WATCHDOG_S = 0.5
# Stop geometry: the sim car's front bumper is 4.0 m ahead of the rear axle (wheel base 3 m
# + 1 m overhang); stopping the rear axle 5 m before the line leaves ~1 m of the 2 m window.
DEFAULT_STOP_MARGIN_M = 5.0
DEFAULT_STOP_DECEL_MPS2 = 1.5  # comfortable: 40 km/h to rest in 41 m, inside the 70 m gate
MIN_RAMP_SPEED_MPS = 1.0  # the original loader's "zero below 1 m/s"


@dataclass(frozen=True)
class TrackWaypoints:
    """The base waypoints: a closed polyline in driving order with a target speed each.

    Attributes:
        x, y: (n,) m, waypoint positions.
        yaw: (n,) rad, direction of the segment from each waypoint to the next.
        s: (n,) m, polyline length from waypoint 0 (strictly increasing, < ``length``).
        speed: (n,) m/s, target speed at each waypoint.
        length: m, the closed polyline's length (the seam segment included).
    """

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    yaw: NDArray[np.float64]
    s: NDArray[np.float64]
    speed: NDArray[np.float64]
    length: float

    def __len__(self) -> int:
        return len(self.x)

    @property
    def xy(self) -> NDArray[np.float64]:
        """(n, 2) positions, m."""
        return np.column_stack([self.x, self.y])

    def distance_ahead(self, from_index: int, to_index: int) -> float:
        """m along the loop from waypoint ``from_index`` forward to ``to_index``, in
        ``[0, length)`` (wraps at the seam)."""
        return float((self.s[to_index] - self.s[from_index]) % self.length)

    def closest(self, x: float, y: float) -> int:
        """Index of the waypoint closest to ``(x, y)`` (a full search)."""
        return int(np.argmin((self.x - x) ** 2 + (self.y - y) ** 2))


def _read_only(array: NDArray[np.float64]) -> NDArray[np.float64]:
    array.flags.writeable = False
    return array


def load_waypoints(
    track: TrackMap,
    speed_limit_mps: float | None = None,
    *,
    seam_ramp: bool = False,
) -> TrackWaypoints:
    """The waypoint loader: ``track``'s waypoints with target speed = the limit everywhere.

    ``speed_limit_mps`` defaults to the track's (40 km/h sim, 10 km/h site). The waypoints
    are the track's file points cleaned like its reference line (repeats and a retraced
    tail dropped, see :func:`~sdc_gym.road.track_map.loop_points`), so the loop closes
    without a cusp. ``seam_ramp`` reproduces the original loader's slow-down towards the
    end of the list (see the module docstring): a quirk on a loop, off by default.
    """
    limit = track.speed_limit_mps if speed_limit_mps is None else float(speed_limit_mps)
    if not (math.isfinite(limit) and limit > 0.0):
        raise ValueError(f"load_waypoints: speed_limit_mps must be a finite number > 0 m/s, "
                         f"got {speed_limit_mps!r}")
    xy = loop_points(track.waypoints[:, :2])
    step = np.roll(xy, -1, axis=0) - xy  # segment i: waypoint i -> i + 1 (last: the seam)
    segment = np.hypot(step[:, 0], step[:, 1])
    s = np.concatenate([[0.0], np.cumsum(segment[:-1])])
    length = float(segment.sum())
    speed = np.full(len(xy), limit)
    if seam_ramp:
        to_end = s[-1] - s  # the original measured to the last waypoint of the list
        speed = np.minimum(speed, np.sqrt(2.0 * SEAM_RAMP_DECEL_MPS2 * to_end))
        speed[speed < SEAM_RAMP_MIN_SPEED_MPS] = 0.0
    return TrackWaypoints(
        x=_read_only(xy[:, 0].copy()), y=_read_only(xy[:, 1].copy()),
        yaw=_read_only(exact_math.atan2(step[:, 1], step[:, 0])), s=_read_only(s),
        speed=_read_only(speed), length=length)


def nearest_waypoints(waypoints: TrackWaypoints, points: ArrayLike) -> NDArray[np.int64]:
    """(k,) index of the waypoint closest to each of the (k, 2) ``points``."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    squared = ((waypoints.x[None, :] - points[:, :1]) ** 2
               + (waypoints.y[None, :] - points[:, 1:]) ** 2)
    return np.argmin(squared, axis=1).astype(np.int64)


def stop_line_waypoints(track: TrackMap, waypoints: TrackWaypoints) -> NDArray[np.int64]:
    """(k,) index of the waypoint closest to each stop line (the original's stop-line
    waypoint, what the traffic light detector publishes), in the track's stop-line order."""
    return nearest_waypoints(waypoints, track.stop_lines_xy)


@dataclass(frozen=True)
class UpdaterParameters:
    """Waypoint updater settings (defaults: the spec's and this stack's stop geometry).

    Attributes:
        count: final waypoints published (at most the loop's waypoint count).
        search_behind, search_ahead: the windowed search around the previous index.
        full_search_distance_m: search the whole list when the window's closest waypoint
            is farther than this.
        stop_margin_m: the pose (rear axle) comes to rest this far before the stop line.
        stop_decel_mps2: deceleration of the square-root speed ramp before a stop.
        min_ramp_speed_mps: ramp speeds below this become 0.
        watchdog_s: pose or light information older than this -> zero speeds.
    """

    count: int = DEFAULT_FINAL_COUNT
    search_behind: int = SEARCH_BEHIND
    search_ahead: int = SEARCH_AHEAD
    full_search_distance_m: float = FULL_SEARCH_DISTANCE_M
    stop_margin_m: float = DEFAULT_STOP_MARGIN_M
    stop_decel_mps2: float = DEFAULT_STOP_DECEL_MPS2
    min_ramp_speed_mps: float = MIN_RAMP_SPEED_MPS
    watchdog_s: float = WATCHDOG_S

    def __post_init__(self) -> None:
        checks = {
            "count": self.count >= 2,
            "search_behind": self.search_behind >= 0,
            "search_ahead": self.search_ahead >= 1,
            "full_search_distance_m": self.full_search_distance_m > 0,
            "stop_margin_m": self.stop_margin_m >= 0,
            "stop_decel_mps2": self.stop_decel_mps2 > 0,
            "min_ramp_speed_mps": self.min_ramp_speed_mps >= 0,
            "watchdog_s": self.watchdog_s > 0,
        }
        for key, ok in checks.items():
            if not ok:
                raise ValueError(f"UpdaterParameters: {key} out of range, got "
                                 f"{getattr(self, key)!r} (counts >= 1 or 2, distances, "
                                 f"rates and times > 0)")


@dataclass(frozen=True)
class FinalWaypoints:
    """The updater's output: the next waypoints ahead of the car with target speeds.

    Attributes:
        indices: (m,) base waypoint indices, consecutive modulo the loop.
        x, y: (m,) m, positions.
        speed: (m,) m/s, target speeds.
        time_s: when they were computed (agent clock).
        emergency: True when the watchdog zeroed the speeds.
    """

    indices: NDArray[np.int64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    speed: NDArray[np.float64]
    time_s: float
    emergency: bool = False

    def __len__(self) -> int:
        return len(self.indices)

    @property
    def xy(self) -> NDArray[np.float64]:
        """(m, 2) positions, m (e.g. for the env's ``set_debug_path``)."""
        return np.column_stack([self.x, self.y])


class WaypointUpdater:
    """The waypoint updater node; see the module docstring. Its arithmetic is
    :func:`~sdc_gym.stack.track.node_kernels.update_waypoints` (the kernel the batched stack
    runs for every env); this class is its batch of one.

    Usage (every updater tick)::

        final = updater.update(now, x, y, yaw, pose_time, stop_waypoint, light_time,
                               speed_cap)
    """

    def __init__(self, waypoints: TrackWaypoints, params: UpdaterParameters | None = None,
                 stop_lines_xy: ArrayLike | None = None) -> None:
        self.waypoints = waypoints
        self.params = params or UpdaterParameters()
        self.count = min(self.params.count, len(waypoints))
        # Stop lines lie up to half a waypoint spacing from their waypoint: given their
        # positions, a stop at a stop-line waypoint is measured to the line itself.
        self.stop_line_offsets: dict[int, float] = {}
        if stop_lines_xy is not None:
            lines = np.asarray(stop_lines_xy, dtype=np.float64).reshape(-1, 2)
            for index, (x, y) in zip(nearest_waypoints(waypoints, lines), lines, strict=True):
                yaw = waypoints.yaw[index]
                self.stop_line_offsets[int(index)] = float(
                    (x - waypoints.x[index]) * math.cos(yaw)
                    + (y - waypoints.y[index]) * math.sin(yaw))
        offsets = np.zeros(len(waypoints))
        for index, offset in self.stop_line_offsets.items():
            offsets[index] = offset
        p = self.params
        self.constants = UpdaterConstants(
            _floats(waypoints.x), _floats(waypoints.y), _floats(waypoints.s),
            _floats(waypoints.speed), float(waypoints.length), int(self.count),
            int(p.search_behind), int(p.search_ahead), float(p.full_search_distance_m ** 2),
            offsets, float(p.stop_margin_m), float(2.0 * p.stop_decel_mps2),
            float(p.min_ramp_speed_mps), float(p.watchdog_s))
        self.state = updater_state(1)
        self._update = TypedCall(update_waypoints)
        self.reset()

    def reset(self) -> None:
        """Forget the previous index: the next search covers the whole list."""
        self.state.previous_index[0] = -1
        self.state.full_searches[0] = 0

    @property
    def previous_index(self) -> int:
        return int(self.state.previous_index[0])

    @property
    def full_searches(self) -> int:
        return int(self.state.full_searches[0])

    def next_waypoint(self, x: float, y: float, yaw: float) -> int:
        """Index of the next waypoint ahead of the pose (windowed search, see the module).

        The closest waypoint is taken; if it lies behind the car (its direction from the
        car makes more than 90 degrees with the heading) its successor is the next one.
        """
        return int(next_waypoint(self.constants, self.state, 0, float(x), float(y),
                                 float(yaw)))

    def speeds_for_stop(self, indices: NDArray[np.int64], stop_waypoint: int,
                        speeds: NDArray[np.float64]) -> NDArray[np.float64]:
        """``speeds`` at ``indices`` (consecutive from ``indices[0]``, as the updater
        publishes them) lowered to stop ``stop_margin_m`` before the stop line at waypoint
        ``stop_waypoint``: zero from the stop point on, a square-root ramp before it. A
        stop line behind the first index (the car is past it) changes nothing.
        """
        lowered = np.array(speeds, dtype=np.float64)
        lower_for_stop(self.constants, int(indices[0]), int(stop_waypoint), lowered)
        return lowered

    def update(
        self,
        now_s: float,
        x: float,
        y: float,
        yaw: float,
        pose_time_s: float,
        stop_waypoint: int = -1,
        light_time_s: float | None = None,
        speed_cap_mps: float | None = None,
    ) -> FinalWaypoints:
        """The final waypoints for the pose ``(x, y, yaw)``.

        Args:
            now_s: current time; pose_time_s, light_time_s: when the pose and the light
                information (the behavior decision's basis) arrived. ``light_time_s=None``
                means light information is not watched (a track without lights).
            stop_waypoint: base index of the stop line to stop at, -1 for none.
            speed_cap_mps: the behavior layer's target speed (None: the base speeds).
        """
        n = len(self.waypoints)
        if stop_waypoint >= n:
            raise ValueError(f"WaypointUpdater.update: stop_waypoint must be -1 or a "
                             f"waypoint index in [0, {n}), got {stop_waypoint}")
        count = self.count
        x_out, y_out, speed = np.empty(count), np.empty(count), np.empty(count)
        first, stale = self._update(
            self.constants, self.state, 0, float(now_s), float(x), float(y), float(yaw),
            float(pose_time_s), int(stop_waypoint), light_time_s is not None,
            0.0 if light_time_s is None else float(light_time_s), speed_cap_mps is not None,
            0.0 if speed_cap_mps is None else float(speed_cap_mps), x_out, y_out, speed)
        indices = (first + np.arange(count)) % n
        return FinalWaypoints(indices=indices, x=x_out, y=y_out, speed=speed, time_s=now_s,
                              emergency=bool(stale))


def _floats(values: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.ascontiguousarray(values, dtype=np.float64)
