"""A safety shield between a learned behavior layer and the motion layer.

A behavior policy proposes a lane and a speed; the shield disposes, with the seed planner's
own safety rules (``seeds/004``), so that a policy in training explores lap time and lane
choice rather than rediscovering how not to hit a car in front (shielded RL: Alshiekh et
al., "Safe Reinforcement Learning via Shielding", AAAI 2018). Turn it off in the
behavior-level env (``safety_shield: False``) to learn everything from the rewards.

Rules (gaps centre to centre, as the world model gives them):

* **Following.** Behind a lead car (the nearest car ahead in the ego lane, and while
  changing lanes also in the target lane) at gap ``g`` with speed ``u``, the speed is
  capped by the seed's braking curve ``p(g) / 100 x u`` inside ``brake_range_m`` (30 m, the
  seed's active range), and beyond it by ``p(range) x u + approach_gain_per_s x (g -
  range)``, which meets the curve at its edge (the FSM's following law). Below
  ``hard_braking_fraction`` of the lead's speed the path is replanned and the car brakes at
  the seed's maximum rate.
* **Lane changes** start only when no change is in progress, the road's circumradius ahead
  exceeds ``min_change_radius_m`` (the seed's "lower visibility in bends" rule), the target
  lane's car behind is beyond the seed's safety gap ``max(11, 3 s x (v_behind - v) + 11)``,
  its car ahead is beyond ``min_ahead_m + 3 s x (v - v_ahead)``, and (merging towards a
  lane with another lane beyond it) no car of that far lane is within
  ``far_lane_watch_m`` either way: traffic merges into lanes clear by +-20 m, so both could
  move into the same gap at once.
* **Abort.** While the ego is still within ``abort_window_m`` of the lane it is leaving, a
  car that appears in the target lane inside ``abort_gap_m`` ahead, or behind closer than
  its safety gap, sends it back.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from sdc_gym.stack.highway import behavior_kernel as kernel
from sdc_gym.stack.highway.behavior import (
    BRAKE_CURVE_DECAY_PER_M,
    BRAKE_CURVE_GAIN_PCT_PER_M,
    BRAKE_CURVE_OFFSET_PCT,
    MAX_BRAKING,
    NORMAL_ACCELERATION,
    SAFETY_GAP_MIN_M,
    SAFETY_HORIZON_S,
)
from sdc_gym.stack.highway.world_model import LaneView, WorldModel


@dataclass(frozen=True)
class ShieldParameters:
    """The shield's constants (the seed's values; Bold's active profile for the ranges)."""

    brake_range_m: float = 30.0
    approach_gain_per_s: float = 1.0
    hard_braking_fraction: float = 0.8
    brake_curve_gain_pct_per_m: float = BRAKE_CURVE_GAIN_PCT_PER_M
    brake_curve_decay_per_m: float = BRAKE_CURVE_DECAY_PER_M
    brake_curve_offset_pct: float = BRAKE_CURVE_OFFSET_PCT
    safety_gap_min_m: float = SAFETY_GAP_MIN_M
    safety_horizon_s: float = SAFETY_HORIZON_S
    min_ahead_m: float = 20.0
    min_change_radius_m: float = 500.0
    far_lane_watch_m: float = 20.0
    abort_gap_m: float = 8.0
    abort_window_m: float = 2.0

    def __post_init__(self) -> None:
        for name in ("brake_range_m", "brake_curve_decay_per_m", "safety_horizon_s"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"shield {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("approach_gain_per_s", "safety_gap_min_m", "min_ahead_m",
                     "min_change_radius_m", "far_lane_watch_m", "abort_gap_m",
                     "abort_window_m"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"shield {name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.hard_braking_fraction <= 1.0:
            raise ValueError("shield hard_braking_fraction must be in [0, 1]")


@dataclass(frozen=True)
class SpeedLimit:
    """What following allows: at most ``speed`` m/s; ``hard`` asks for a replan and the
    maximum braking rate (``acceleration``)."""

    speed: float
    acceleration: float = NORMAL_ACCELERATION
    hard: bool = False


class SafetyShield:
    """The rules of the module docstring, as pure functions of a world model (compiled:
    :mod:`sdc_gym.stack.highway.behavior_kernel`, the implementation the batched
    behavior env runs too)."""

    def __init__(self, params: ShieldParameters | None = None) -> None:
        self.params = params or ShieldParameters()
        self.array = shield_array(self.params)

    def braking_fraction(self, gap_m: float) -> float:
        """p(gap) / 100: the fraction of the lead's speed to drive at, ``gap_m`` behind it."""
        return kernel.braking_fraction(self.array, float(gap_m))

    def lead(self, world: WorldModel, target_lane: int) -> tuple[float, float]:
        """Gap and speed of the nearest car ahead in the lanes from the ego's to the target."""
        return kernel.lead(views_of(world), world.ego_lane, int(target_lane))

    def speed_limit(self, world: WorldModel, target_lane: int) -> SpeedLimit:
        """The following cap behind the lead (``inf`` speed when there is none)."""
        speed, acceleration, hard = kernel.speed_limit(
            self.array, views_of(world), world.ego_lane, int(target_lane), MAX_BRAKING,
            NORMAL_ACCELERATION)
        return SpeedLimit(speed, acceleration, hard)

    def safe_behind(self, view: LaneView, ego_speed: float) -> bool:
        """The lane's car behind is beyond the seed's safety gap."""
        return kernel.safe_behind(self.array, view.behind_gap, view.behind_speed,
                                  float(ego_speed))

    def safe_ahead(self, view: LaneView, ego_speed: float) -> bool:
        """The lane's car ahead leaves room for the change at the current speeds."""
        return kernel.safe_ahead(self.array, view.ahead_gap, view.ahead_speed, float(ego_speed))

    def lane_change_allowed(self, world: WorldModel, target_lane: int) -> bool:
        """Whether a change from the ego lane to the adjacent ``target_lane`` may start now."""
        return kernel.lane_change_allowed(self.array, views_of(world), world.ego_lane,
                                          world.ego_speed, world.road_radius,
                                          int(target_lane))

    def must_abort(self, world: WorldModel, origin_lane: int, target_lane: int) -> bool:
        """A lane change under way should go back: see "Abort" in the module docstring."""
        return kernel.must_abort(self.array, views_of(world), world.ego_d, world.ego_speed,
                                 world.lane_width, int(origin_lane), int(target_lane))


def shield_array(params: ShieldParameters) -> NDArray[np.float64]:
    """The parameters as the kernels take them (in field order)."""
    return np.array([getattr(params, field.name) for field in fields(params)],
                    dtype=np.float64)


def views_of(world: WorldModel) -> NDArray[np.float64]:
    """A world model's lane views as the kernels take them: ``(lanes, 6)`` rows ahead gap,
    ahead speed, ahead id, behind gap, behind speed, behind id."""
    return np.array([(view.ahead_gap, view.ahead_speed, view.ahead_id, view.behind_gap,
                      view.behind_speed, view.behind_id) for view in world.lanes],
                    dtype=np.float64).reshape(-1, 6)
