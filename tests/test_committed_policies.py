"""The committed policies are agents by name, the same models as their ``kind:path`` specs."""

from __future__ import annotations

import shutil

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_agents.committed_policies import POLICY_FOLDERS, CommittedPolicy, committed_policies
from sdc_agents.registry import AGENT_ENVS, AGENTS, check_agent_env, make_agent

COMMITTED = POLICY_FOLDERS[0] / "dqn_highway.zip"


def _drive(agent, seed: int, steps: int) -> list[np.ndarray]:
    env = gym.make("sdc_gym/HighwayLoop-v0")
    observation, _ = env.reset(seed=seed)
    agent.reset()
    paths = []
    for _ in range(steps):
        action = agent.act(observation)
        paths.append(np.asarray(action, dtype=float).copy())
        observation, *_ = env.step(action)
    return paths


def test_every_committed_zip_with_its_config_is_a_named_agent_on_its_env():
    policies = committed_policies()
    assert "dqn_highway" in policies
    for name, policy in policies.items():
        assert name in AGENTS
        assert AGENT_ENVS[name] == (policy.env_id,)
    assert policies["dqn_highway"].algo == "dqn"
    assert policies["dqn_highway"].env_id == "sdc_gym/HighwayLoop-v0"


def test_the_name_and_the_file_spec_drive_the_same_paths():
    env = gym.make("sdc_gym/HighwayLoop-v0")
    by_name = make_agent("dqn_highway", env)
    by_file = make_agent(f"dqn:{COMMITTED}", env)
    assert by_name.name == "dqn_highway"
    for a, b in zip(_drive(by_name, 5, 60), _drive(by_file, 5, 60), strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_highway_policy_is_refused_on_the_track_before_any_episode():
    with pytest.raises(ValueError, match="agent 'dqn_highway' drives sdc_gym/HighwayLoop-v0, "
                                         "not sdc_gym/TrackLoop-v0"):
        check_agent_env("dqn_highway", "sdc_gym/TrackLoop-v0")


@pytest.mark.parametrize(("text", "message"), [
    ("env: sdc_gym/HighwayLoopBehavior-v0\n", "algo None; valid: \\['ppo', 'dqn'"),
    ("algo: dqn\nenv: sdc_gym/HighwayLoop-v0\n", "env 'sdc_gym/HighwayLoop-v0'; valid: "),
    ("- algo\n", "must be a mapping with 'algo' and 'env'"),
])
def test_a_broken_policy_config_names_the_file_and_the_key(tmp_path, text, message):
    model = tmp_path / "broken.zip"
    shutil.copyfile(COMMITTED, model)
    model.with_suffix(".yaml").write_text(text)
    with pytest.raises(ValueError, match=message) as raised:
        CommittedPolicy(model)
    assert str(model.with_suffix(".yaml")) in str(raised.value)
