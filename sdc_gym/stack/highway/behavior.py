"""The behavior layer's interface: a decision per planning cycle, from a world model.

The seed's finite state machine is one :class:`BehaviorPolicy`; an RL policy is another.
The motion layer executes a :class:`BehaviorDecision`: it steers toward ``target_lane``
and changes speed toward ``target_speed`` at no more than ``acceleration``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from sdc_gym.stack.highway import behavior_kernel as kernel
from sdc_gym.stack.highway.world_model import WorldModel

# The seed's speed-change rates, converted from metres per step per step (0.02 s steps).
STEP = 0.02  # s
NORMAL_ACCELERATION = 0.002 / STEP**2     # 5.0 m/s^2
LAUNCH_ACCELERATION = 0.0039 / STEP**2    # 9.75 m/s^2, steering muted
MAX_BRAKING = 0.003368 / STEP**2          # 8.42 m/s^2
GENTLE_ACCELERATION = 0.001 / STEP**2     # 2.5 m/s^2

# The seed's short-range braking curve p(d) = (gain / decay) (1 - exp(-decay d)) - offset, in
# % of the lead car's speed: 0 at 5 m, 80 at 22.7 m, 100 at 49.8 m (centre-to-centre gaps).
BRAKE_CURVE_GAIN_PCT_PER_M = 13.67303
BRAKE_CURVE_DECAY_PER_M = 0.08660915
BRAKE_CURVE_OFFSET_PCT = 55.76378
# The seed's safety gap to a car behind in a target lane: its 3 s projection plus 11 m.
SAFETY_GAP_MIN_M = 11.0
SAFETY_HORIZON_S = 3.0


def braking_percent(gap_m: float, gain_pct_per_m: float = BRAKE_CURVE_GAIN_PCT_PER_M,
                    decay_per_m: float = BRAKE_CURVE_DECAY_PER_M,
                    offset_pct: float = BRAKE_CURVE_OFFSET_PCT) -> float:
    """p(d): the % of the lead car's speed to drive at, ``gap_m`` behind it, in [0, 100].

    The seed fitted this curve to a train-braking profile: the closer the lead, the larger
    the share of its speed to give up, so the gap opens again before it closes. (The
    compiled rule of :mod:`sdc_gym.stack.highway.behavior_kernel`, shared with the
    shield.)"""
    return kernel.braking_percent(float(gap_m), gain_pct_per_m, decay_per_m, offset_pct)


def safety_gap_m(behind_speed_mps: float, ego_speed_mps: float,
                 min_gap_m: float = SAFETY_GAP_MIN_M,
                 horizon_s: float = SAFETY_HORIZON_S) -> float:
    """The gap a car behind in a target lane needs: where it will be after ``horizon_s`` at
    constant speeds, plus ``min_gap_m`` (never less than ``min_gap_m``)."""
    return kernel.safety_gap_m(float(behind_speed_mps), float(ego_speed_mps), min_gap_m,
                               horizon_s)


@dataclass(frozen=True)
class BehaviorDecision:
    """What the motion layer should do until the next cycle.

    Attributes:
        target_lane: lane index to drive in (a lane change when different from the
            current one; two lanes away is a double lane change).
        target_speed: m/s to reach.
        acceleration: m/s^2, largest speed change per second used to reach it (the seed's
            rates: NORMAL_ACCELERATION, LAUNCH_ACCELERATION, MAX_BRAKING,
            GENTLE_ACCELERATION).
        replan: drop the queued path beyond its first few points and plan afresh (an
            emergency: the queued points would carry the car on too fast).
        steering: False mutes steering (the seed's Launch).
        mode: the policy's state name, for logs and the renderer.
        target_d: where to aim across the road (m) instead of ``target_lane``'s centre
            (an eased lane change); ``None``: the lane's centre.
    """

    target_lane: int
    target_speed: float
    acceleration: float = NORMAL_ACCELERATION
    replan: bool = False
    steering: bool = True
    mode: str = ""
    target_d: float | None = None


class BehaviorPolicy(Protocol):
    """Anything that decides target lane and speed from a world model."""

    def reset(self) -> None:
        """Forget all state (start of an episode)."""

    def decide(self, world: WorldModel) -> BehaviorDecision:
        """The decision for this planning cycle."""
