"""Waypoint follower: pure pursuit from the final waypoints to a twist command.

The original course's follower (Autoware's pure pursuit, spec "The nodes"):

* look-ahead distance ``L = max(6.0, 2.0 * v)`` m at the current speed ``v`` m/s;
* the target is the point of the final-waypoint polyline at distance ``L`` from the car:
  the first waypoint farther than ``L``, moved back along its segment onto the circle of
  radius ``L`` (the last waypoint when none is that far);
* in the car's frame (x forward, y to the left) the circular arc through the car, tangent
  to its heading, that reaches the target ``(x_t, y_t)`` has curvature
  ``kappa = 2 y_t / (x_t^2 + y_t^2) = 2 y_t / L^2`` (positive: turn left);
* twist command: linear velocity = the *first* final waypoint's speed, angular velocity
  = ``v * kappa`` with the *current* speed ``v`` (as in the original);
* the angular velocity is recomputed only when the car is off the path: its distance to
  the line through the first two final waypoints is at least 0.2 m or its heading differs
  from that line's by at least 5 degrees; otherwise the previous one is kept (this
  damps the steering on straights and in steady curves). Thresholds of 0
  (:data:`CONTINUOUS_FOLLOWER`) recompute every cycle. The hold has a cost: the car
  drifts up to the threshold and back, weaving about +-0.25 m on straights, and at the
  onset of a curve it holds the straight's angular velocity until 0.2 m off, then asks
  for a large correction at once.

Units: m, rad, m/s, rad/s; the pose is the rear axle (where the kinematic bicycle's
velocity points along the body, so the arc geometry above is exact for it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sdc_gym.kernel_compiler import TypedCall
from sdc_gym.stack.track.control_kernels import FollowerConstants, follower_state
from sdc_gym.stack.track.control_kernels import command_speed as _command_speed
from sdc_gym.stack.track.control_kernels import curvature_to_point as _curvature_to_point
from sdc_gym.stack.track.control_kernels import follow as _follow
from sdc_gym.stack.track.control_kernels import is_following as _is_following
from sdc_gym.stack.track.control_kernels import target_point as _target_point
from sdc_gym.stack.track.waypoints import FinalWaypoints

LOOKAHEAD_MIN_M = 6.0
LOOKAHEAD_GAIN_S = 2.0  # look-ahead per m/s of speed
DISPLACEMENT_THRESHOLD_M = 0.2
ANGLE_THRESHOLD_RAD = math.radians(5.0)


@dataclass(frozen=True)
class FollowerParameters:
    """Pure pursuit settings (the original's defaults).

    Attributes:
        lookahead_min_m: shortest look-ahead distance.
        lookahead_gain_s: look-ahead distance per m/s of speed.
        displacement_threshold_m, angle_threshold_rad: the "off the path" test.
        speed_from_next_waypoint: take the command speed from the first final waypoint
            still ahead of the car instead of the list's first (the original's). They
            differ when the list is older than the follower's cycle: a 2 Hz updater's
            first waypoint may lie 5 m behind a car at 40 km/h, whose speed is then
            commanded too late (stops overshoot).
    """

    lookahead_min_m: float = LOOKAHEAD_MIN_M
    lookahead_gain_s: float = LOOKAHEAD_GAIN_S
    displacement_threshold_m: float = DISPLACEMENT_THRESHOLD_M
    angle_threshold_rad: float = ANGLE_THRESHOLD_RAD
    speed_from_next_waypoint: bool = False

    def __post_init__(self) -> None:
        if not self.lookahead_min_m > 0:
            raise ValueError(f"FollowerParameters: lookahead_min_m must be > 0 m, "
                             f"got {self.lookahead_min_m!r}")
        for key in ("lookahead_gain_s", "displacement_threshold_m", "angle_threshold_rad"):
            if not getattr(self, key) >= 0:
                raise ValueError(f"FollowerParameters: {key} must be >= 0, "
                                 f"got {getattr(self, key)!r}")


CONTINUOUS_FOLLOWER = FollowerParameters(displacement_threshold_m=0.0, angle_threshold_rad=0.0)
"""Recompute the angular velocity every cycle (never keep the previous one): no weaving on
straights (the original's hysteresis lets the car drift to 0.2 m before correcting)."""


@dataclass(frozen=True)
class TwistCommand:
    """A target twist: forward speed (m/s) and yaw rate (rad/s, positive to the left)."""

    linear_mps: float
    angular_radps: float


def curvature_to_point(x: float, y: float, yaw: float, target_x: float,
                       target_y: float) -> float:
    """1/m, curvature of the arc from the pose ``(x, y, yaw)`` (tangent to the heading)
    through ``(target_x, target_y)``: ``2 y_local / (x_local^2 + y_local^2)``."""
    return _curvature_to_point(float(x), float(y), float(yaw), float(target_x),
                               float(target_y))


class PurePursuit:
    """The waypoint follower node; see the module docstring. Its arithmetic is
    :func:`~sdc_gym.stack.track.node_kernels.follow` (the kernel the batched stack runs for
    every env); this class is its batch of one.

    Attributes after :meth:`follow`: ``target`` (the look-ahead point), ``lookahead_m``,
    ``curvature`` (of the last recomputation), ``recomputed`` (False: kept).
    """

    def __init__(self, params: FollowerParameters | None = None) -> None:
        self.params = params or FollowerParameters()
        p = self.params
        self.constants = FollowerConstants(
            float(p.lookahead_min_m), float(p.lookahead_gain_s),
            float(p.displacement_threshold_m), float(p.angle_threshold_rad),
            bool(p.speed_from_next_waypoint))
        self.state = follower_state(1)
        self._follow = TypedCall(_follow)
        self.reset()

    def reset(self) -> None:
        for array in self.state:
            array[0] = 0
        self.state.lookahead[0] = self.params.lookahead_min_m
        self.target: tuple[float, float] | None = None

    @property
    def lookahead_m(self) -> float:
        return float(self.state.lookahead[0])

    @property
    def curvature(self) -> float:
        return float(self.state.curvature[0])

    @property
    def recomputed(self) -> bool:
        return bool(self.state.recomputed[0])

    def lookahead_distance(self, speed_mps: float) -> float:
        """m, ``max(lookahead_min, lookahead_gain * speed)``."""
        return max(self.params.lookahead_min_m, self.params.lookahead_gain_s * speed_mps)

    @staticmethod
    def target_point(x: float, y: float, final: FinalWaypoints,
                     lookahead_m: float) -> tuple[float, float]:
        """The polyline's point at ``lookahead_m`` from ``(x, y)`` (see the module)."""
        return _target_point(float(x), float(y), _floats(final.x), _floats(final.y),
                             float(lookahead_m))

    def is_following(self, x: float, y: float, yaw: float, final: FinalWaypoints) -> bool:
        """True when the pose is on the path: closer than the displacement threshold to
        the line through the first two final waypoints and within the angle threshold of
        its direction."""
        return _is_following(self.constants, float(x), float(y), float(yaw),
                             _floats(final.x), _floats(final.y))

    def follow(self, x: float, y: float, yaw: float, speed_mps: float,
               final: FinalWaypoints) -> TwistCommand:
        """The twist command for the pose and speed along ``final``."""
        if len(final) == 0:
            raise ValueError("PurePursuit.follow: final waypoints are empty")
        linear, angular = self._follow(self.constants, self.state, 0, float(x), float(y),
                                  float(yaw), float(speed_mps), _floats(final.x),
                                  _floats(final.y), _floats(final.speed))
        self.target = (float(self.state.target_x[0]), float(self.state.target_y[0]))
        return TwistCommand(linear_mps=linear, angular_radps=angular)

    def command_speed(self, x: float, y: float, yaw: float, final: FinalWaypoints) -> float:
        """m/s, the first final waypoint's speed (or the next one ahead of the car's, see
        :attr:`FollowerParameters.speed_from_next_waypoint`)."""
        return _command_speed(self.constants, float(x), float(y), float(yaw),
                              _floats(final.x), _floats(final.y), _floats(final.speed))


def _floats(values: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.ascontiguousarray(values, dtype=np.float64)
