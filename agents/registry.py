"""Agents by name, so that scripts can say ``--agents lane_keeping`` and build one per env.

An agent has ``name``, ``reset()`` (start of an episode) and ``act(observation)`` (the
action for ``env.step``). A factory takes the (unwrapped) env it will drive, so it can read
the map and the env's configuration.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import gymnasium as gym

from agents.highway.fsm import DrivingStyle
from agents.highway.fsm_agent import fsm_agent
from agents.lane_keeping import LaneKeepingDriver
from agents.track.dbw_agent import dbw_agent
from sdc_gym.stack.track.follower import FollowerParameters


class Agent(Protocol):
    name: str

    def reset(self) -> None: ...

    def act(self, observation: Any) -> Any: ...


AgentFactory = Callable[[gym.Env], Agent]

AGENTS: dict[str, AgentFactory] = {
    "lane_keeping": lambda env: LaneKeepingDriver(env.unwrapped.road),
    "fsm_conservative": lambda env: fsm_agent(env, DrivingStyle.CONSERVATIVE),
    "fsm_bold": lambda env: fsm_agent(env, DrivingStyle.BOLD),
    # With Kalman tracking of every car (for the env's sensor noise).
    "fsm_conservative_kf": lambda env: fsm_agent(env, DrivingStyle.CONSERVATIVE, tracking=True),
    "fsm_bold_kf": lambda env: fsm_agent(env, DrivingStyle.BOLD, tracking=True),
    # The track loop's drive-by-wire stack, by traffic light source: the env's ground truth
    # (config observe_light_states), or the committed classifiers on the camera image
    # (config camera: {enabled: true, preset: training}).
    "dbw_ground_truth": lambda env: dbw_agent(env, "ground_truth", name="dbw_ground_truth"),
    "dbw_cnn": lambda env: dbw_agent(env, "cnn", name="dbw_cnn"),
    "dbw_crop": lambda env: dbw_agent(env, "crop", name="dbw_crop"),
    # Node rates and follower variants, for the rates study (ground-truth lights).
    "dbw_seed_rates": lambda env: dbw_agent(env, "ground_truth", rates="seed",
                                            name="dbw_seed_rates"),
    "dbw_original_follower": lambda env: dbw_agent(env, "ground_truth",
                                                   follower=FollowerParameters(),
                                                   name="dbw_original_follower"),
}


def make_agent(name: str, env: gym.Env) -> Agent:
    """Build the agent called ``name`` for ``env``; unknown names list the valid ones."""
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}; valid agents: {', '.join(sorted(AGENTS))}")
    return AGENTS[name](env)
