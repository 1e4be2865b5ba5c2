"""The FSM agent driving the env itself (not hand-built world models)."""

from __future__ import annotations

import gymnasium as gym

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_agents.highway.fsm import DrivingStyle
from sdc_agents.highway.fsm_agent import fsm_agent
from tests.conftest import HIGHWAY_MAP_FILE


def test_launch_into_the_original_maps_first_bend_stays_in_lane():
    """The original start (s = 124.9 m) is 25 m before a left bend. Launch drives straight,
    steering muted; if the path queued during the launch were kept as it is, the car would
    go on straight for another path length and drift 2.8 m to the right, into the next lane
    (seed 2: Bold hit the car there after 3 s). When steering comes back, the motion layer
    plans those queued states again, steered, at the same speeds."""
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"map": str(HIGHWAY_MAP_FILE)})
    agent = fsm_agent(env, DrivingStyle.BOLD)
    observation, _ = env.reset(seed=2)
    agent.reset()
    start_d = env.unwrapped.road.start_d
    offsets = []
    for _ in range(200):  # 12 s at 3 frames per step
        observation, _, terminated, truncated, _ = env.step(agent.act(observation))
        assert not (terminated or truncated)
        if agent.behavior.lane_change_in_progress:
            break
        offsets.append(abs(agent.world.ego_d - start_d))
    assert len(offsets) > 100  # past the launch and into the bend
    assert max(offsets) < 0.75
    assert env.unwrapped.summary()["incident_total"] == 0
    env.close()
