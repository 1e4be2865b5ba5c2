"""The layered highway agent: perception -> behavior -> motion, one cycle per env step.

Any :class:`~sdc_gym.stack.highway.behavior.BehaviorPolicy` can sit in the middle: the seed's
finite state machine (:func:`fsm_agent`) or, later, a trained RL policy. The agent's clock
counts planning cycles: each is ``frames_per_cycle`` frames of 0.02 s (the env's
``steps_per_action``, read by :meth:`MotionParameters.for_env`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.stack.highway.behavior import STEP, BehaviorDecision, BehaviorPolicy
from sdc_gym.stack.highway.motion import SeedMotionPlanner
from sdc_gym.stack.highway.perception import Perception
from sdc_gym.stack.highway.world_model import WorldModel


class LayeredHighwayAgent:
    """Drives ``HighwayLoop-v0`` through the three layers; see the module docstring.

    Attributes after each :meth:`act`: ``world`` (the last world model) and ``decision``
    (the last behavior decision), for logging and tests.
    """

    def __init__(self, name: str, road: HighwayMap, behavior: BehaviorPolicy,
                 perception: Perception | None = None,
                 motion: SeedMotionPlanner | None = None) -> None:
        self.name = name
        self.road = road
        self.behavior = behavior
        self.perception = perception or Perception(road)
        self.motion = motion or SeedMotionPlanner(road)
        self.reset()

    def reset(self) -> None:
        self.behavior.reset()
        self.perception.reset()
        self.motion.reset()
        self._cycles = 0
        self.world: WorldModel | None = None
        self.decision: BehaviorDecision | None = None

    def act(self, observation: dict[str, Any]) -> NDArray[np.float64]:
        """The path for this step: perceive, decide, plan."""
        clock = self._cycles * self.motion.params.frames_per_cycle * STEP
        self._cycles += 1
        self.world = self.perception.perceive(observation, clock)
        self.decision = self.behavior.decide(self.world)
        return self.motion.plan(observation, self.decision)
