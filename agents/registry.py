"""Agents by name, so that scripts can say ``--agents lane_keeping`` and build one per env.

An agent has ``name``, ``reset()`` (start of an episode) and ``act(observation)`` (the
action for ``env.step``). A factory takes the (unwrapped) env it will drive, so it can read
the map and the env's configuration.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import gymnasium as gym

from agents.lane_keeping import LaneKeepingDriver


class Agent(Protocol):
    name: str

    def reset(self) -> None: ...

    def act(self, observation: Any) -> Any: ...


AgentFactory = Callable[[gym.Env], Agent]

AGENTS: dict[str, AgentFactory] = {
    "lane_keeping": lambda env: LaneKeepingDriver(env.unwrapped.road),
}


def make_agent(name: str, env: gym.Env) -> Agent:
    """Build the agent called ``name`` for ``env``; unknown names list the valid ones."""
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}; valid agents: {', '.join(sorted(AGENTS))}")
    return AGENTS[name](env)
