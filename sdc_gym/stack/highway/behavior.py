"""The behavior layer's interface: a decision per planning cycle, from a world model.

The seed's finite state machine is one :class:`BehaviorPolicy`; an RL policy is another.
The motion layer executes a :class:`BehaviorDecision`: it steers toward ``target_lane``
and changes speed toward ``target_speed`` at no more than ``acceleration``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from sdc_gym.stack.highway.world_model import WorldModel

# The seed's speed-change rates, converted from metres per step per step (0.02 s steps).
STEP = 0.02  # s
NORMAL_ACCELERATION = 0.002 / STEP**2     # 5.0 m/s^2
LAUNCH_ACCELERATION = 0.0039 / STEP**2    # 9.75 m/s^2, steering muted
MAX_BRAKING = 0.003368 / STEP**2          # 8.42 m/s^2
GENTLE_ACCELERATION = 0.001 / STEP**2     # 2.5 m/s^2


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
    """

    target_lane: int
    target_speed: float
    acceleration: float = NORMAL_ACCELERATION
    replan: bool = False
    steering: bool = True
    mode: str = ""


class BehaviorPolicy(Protocol):
    """Anything that decides target lane and speed from a world model."""

    def reset(self) -> None:
        """Forget all state (start of an episode)."""

    def decide(self, world: WorldModel) -> BehaviorDecision:
        """The decision for this planning cycle."""
