"""The FSM's options from the seed's further work: straight-line maximum braking, crash
rerouting and quintic in-out easing of the steering target between lane splines (their
rules: :mod:`sdc_agents.highway.fsm_mode_parameters`; each off by default).

:class:`FSMOptions` keeps what the options remember between cycles (the deceleration
commanded last, the easing under way) and answers the FSM's questions at three points of
its cycle: the braking rate, the lanes a crash closes, and the steering target's ``d``.
"""

from __future__ import annotations

import math

from sdc_agents.highway.fsm_parameters import FSMParameters
from sdc_gym.stack.highway.world_model import WorldModel


def quintic_in_out(u: float) -> float:
    """The quintic in-out easing ``e(u)``: 0 at 0, 1/2 at 1/2, 1 at 1, flat at both ends
    (first and second derivatives 0), ``16 u^5`` then ``1 - (2 - 2u)^5 / 2``; clipped
    to [0, 1] outside."""
    if u <= 0.0:
        return 0.0
    if u >= 1.0:
        return 1.0
    if u < 0.5:
        return 16.0 * u * u * u * u * u
    w = 2.0 - 2.0 * u
    return 1.0 - 0.5 * w * w * w * w * w


class FSMOptions:
    """The options' state for one FSM (see the module docstring)."""

    def __init__(self, params: FSMParameters) -> None:
        self._p = params
        self.reset()

    def reset(self) -> None:
        self._brake = 0.0  # the hard-braking deceleration commanded last (0: none)
        self._brake_time = 0.0
        self._lane = -1  # the lane the steering target eases to
        self._ease: tuple[float, float, float, float] | None = None  # t0, d0, d1, T

    # ----------------------------------------------------------------------- braking
    def braking(self, accel: float, hard: bool, world: WorldModel) -> float:
        """The rate for this cycle: under hard braking, the seed's 8.42 m/s^2 at first,
        then ``jerk_mps3`` more per second up to what the limit leaves beside the bend's
        lateral acceleration (never less than the seed's figure)."""
        b = self._p.straight_braking
        if not hard:
            self._brake = 0.0
            return accel
        v = world.ego_speed
        radius = world.road_radius
        lateral = v * v / radius if radius > 0.0 and radius != math.inf else 0.0
        room = b.decel_limit_mps2 * b.decel_limit_mps2 - lateral * lateral
        limit = max(math.sqrt(room) if room > 0.0 else 0.0, self._p.max_braking_mps2)
        if self._brake == 0.0:
            command = self._p.max_braking_mps2
        else:
            command = min(limit, self._brake + b.jerk_mps3 * (world.time - self._brake_time))
        command = max(command, self._p.max_braking_mps2)
        self._brake = command
        self._brake_time = world.time
        return command

    # --------------------------------------------------------------------- rerouting
    def closed_lanes(self, world: WorldModel) -> frozenset[int]:
        """The lanes with a standing car or object within the reroute range ahead."""
        r = self._p.reroute
        return frozenset(lane.lane for lane in world.lanes
                         if lane.has_ahead and lane.ahead_gap < r.range_m
                         and lane.ahead_speed < r.standing_mps)

    # ------------------------------------------------------------------------ easing
    def target_d(self, world: WorldModel, lane: int) -> float | None:
        """The steering target's ``d`` while easing to ``lane`` (``None``: its centre)."""
        width = world.lane_width
        now = world.time
        centre = (lane + 0.5) * width
        if self._lane < 0:
            self._lane = lane  # the first cycle: the ego starts in its lane
            return None
        if lane != self._lane:
            d0 = self._eased(now)
            if d0 is None:
                d0 = (self._lane + 0.5) * width
            duration = self._p.easing.seconds_per_lane * abs(centre - d0) / width
            self._ease = (now, d0, centre, duration) if duration > 0.0 else None
            self._lane = lane
        return self._eased(now)

    def snap(self, lane: int) -> None:
        """Aim at ``lane``'s centre at once (an aborted lane change goes back without
        easing: the seed's return, as quickly as the steering allows)."""
        self._lane = lane
        self._ease = None

    def _eased(self, now: float) -> float | None:
        if self._ease is None:
            return None
        t0, d0, d1, duration = self._ease
        u = (now - t0) / duration
        if u >= 1.0:
            self._ease = None
            return None
        return d0 + (d1 - d0) * quintic_in_out(u)
