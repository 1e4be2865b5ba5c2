"""Drivers and helpers for the scenario tests: a driver that does not react, and episodes
driven to their end."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym

from sdc_gym.scenarios.runtime import ego_path

LANE_WIDTH = 4.0


class NoReaction:
    """Keeps its lane's centre at a constant speed whatever happens ahead (the driver that
    does not react): each step a fresh path along its lane from where it is."""

    name = "no_reaction"

    def __init__(self, env: gym.Env, speed: float) -> None:
        self.reference = env.unwrapped.road.reference
        self.points = env.unwrapped.path_points
        self.speed = speed

    def reset(self) -> None:
        pass

    def act(self, observation: dict[str, Any]) -> Any:
        s, d = float(observation["ego"][2]), float(observation["ego"][3])
        lane_d = (math.floor(d / LANE_WIDTH) + 0.5) * LANE_WIDTH
        return ego_path(self.reference, s, lane_d, self.speed, self.points, 0.02)


def drive(env: gym.Env, agent: Any, seed: int = 0,
          options: dict[str, Any] | None = None) -> dict[str, Any]:
    """One episode to its end; the final info."""
    observation, info = env.reset(seed=seed, options=options)
    agent.reset()
    while True:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        if terminated or truncated:
            return info
