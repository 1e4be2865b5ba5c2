"""The behavior-level envs: API checks, vector envs, determinism, the shield in the loop,
and a trained policy driving the path-level env exactly as in its behavior env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import check_env

import sdc_gym  # noqa: F401
from sdc_agents.registry import make_agent
from sdc_gym.config import ConfigError
from sdc_gym.lights import RED

HIGHWAY = "sdc_gym/HighwayLoopBehavior-v0"
TRACK = "sdc_gym/TrackLoopBehavior-v0"
KEEP_CRUISE = 3
FIRST_LINE_S = 230.0  # the default track's first stop line
SIM_FRONT_OFFSET_M = 4.0


def highway(**config):
    return gym.make(HIGHWAY, config=config)


@pytest.mark.parametrize("env_id,config", [
    (HIGHWAY, {}), (HIGHWAY, {"action": "continuous", "safety_shield": False}),
    (TRACK, {"track": {"max_duration": 20.0}}), (TRACK, {"action": "continuous"})])
def test_check_env_gymnasium_and_sb3(env_id, config):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(env_id, config=config)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)


def test_bad_config_and_actions_raise_clear_errors():
    with pytest.raises(ConfigError, match="decision_frames"):
        highway(highway={"steps_per_action": 3})
    with pytest.raises(ConfigError, match="action"):
        highway(action="multi")
    with pytest.raises(ConfigError, match=r"observation.*'nearest', 'extended'.*'second'"):
        highway(observation="second")
    with pytest.raises(ConfigError, match="Valid keys"):
        highway(shield_on=True)
    with pytest.raises(ConfigError, match="multiple of"):
        gym.make(TRACK, config={"decision_period_s": 0.03})
    env = highway()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="out of range"):
        env.step(9)
    env = highway(action="continuous")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))


def rollout(env, actions, seed):
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    for action in actions:
        obs, reward, terminated, truncated, _ = env.step(action)
        trace.append(np.append(obs, reward))
        if terminated or truncated:
            break
    return np.concatenate(trace)


def test_same_seed_same_actions_same_episode():
    actions = np.random.default_rng(3).integers(0, 9, 150)
    first = rollout(highway(), actions, seed=5)
    assert np.array_equal(first, rollout(highway(), actions, seed=5))
    assert not np.array_equal(first, rollout(highway(), actions, seed=6))


def test_shield_keeps_a_reckless_policy_safe_and_without_it_collisions_are_seen():
    # "keep lane, cruise" drives into the first slower car unless the shield caps the speed.
    for shield, must_collide in ((True, False), (False, True)):
        env = highway(safety_shield=shield, highway={"max_duration": 120.0})
        env.reset(seed=1)
        for _ in range(500):
            _, _, terminated, truncated, info = env.step(KEEP_CRUISE)
            if terminated or truncated:
                break
        assert info["summary"]["collided"] is must_collide
    # Random decisions with the shield: lane changes happen, none into a car.
    env = highway(highway={"max_duration": 120.0})
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    for _ in range(500):
        _, _, terminated, truncated, info = env.step(int(rng.integers(9)))
        if terminated or truncated:
            break
    assert not info["summary"]["collided"]
    assert info["behavior"]["lane_changes"] > 3 and info["behavior"]["refused"] > 0


def test_vector_envs_gymnasium_and_sb3_subprocesses():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    envs = gym.make_vec(HIGHWAY, num_envs=2, vectorization_mode="sync")
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (2, 25)
    obs, rewards, *_ = envs.step(np.array([KEEP_CRUISE, 0]))
    assert obs.shape == (2, 25) and rewards.shape == (2,)
    envs.close()
    for env_id in (HIGHWAY, TRACK):
        # "module:id" makes each subprocess import sdc_gym (which registers the ids).
        vec = make_vec_env(f"sdc_gym:{env_id}", n_envs=2, seed=0, vec_env_cls=SubprocVecEnv)
        obs = vec.reset()
        obs, _, _, infos = vec.step(np.array([0, 0]))
        assert obs.shape[0] == 2 and len(infos) == 2
        vec.close()


def test_track_stop_decision_stops_before_a_red_line_and_go_runs_it():
    config = {"track": {"start_s": FIRST_LINE_S - 80.0, "max_duration": 40.0,
                        "lights": {"script": [RED] + [None] * 7}}}
    results = {}
    for action in (3, 0):  # stop, go
        env = gym.make(TRACK, config=config)
        obs, info = env.reset(seed=0)
        assert obs[3] == 1.0 or obs[6] == 1.0  # red (in range) or unknown
        for _ in range(40):
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        results[action] = (info["summary"], info["s"], info["speed"])
    stop_summary, stop_s, stop_speed = results[3]
    assert stop_summary["incidents"]["red_light"] == 0 and stop_speed == 0.0
    assert 0.0 < FIRST_LINE_S - (stop_s + SIM_FRONT_OFFSET_M) < 2.0  # the stack's stop gap
    assert results[0][0]["incidents"]["red_light"] == 1


@pytest.mark.parametrize("tracking", [False, True])
def test_extended_observation_of_the_batch_is_that_of_its_world_models(tracking):
    """The batch's extended entries (one kernel over the perceived car arrays, or the
    Kalman tracks) equal BehaviorFeatures.encode of each env's world model with its cars,
    step after step in traffic; the second car is seen."""
    import dataclasses

    from sdc_gym.envs.highway_vector import HighwayLoopBehaviorVectorEnv

    vec = HighwayLoopBehaviorVectorEnv(3, config={"observation": "extended",
                                                  "kalman_tracking": tracking,
                                                  "highway": {"max_duration": 40.0}})
    assert vec.single_observation_space.shape == (34,)
    obs, _ = vec.reset(seed=7)
    batch = vec.batch
    rng = np.random.default_rng(0)
    seen_second = 0
    for _ in range(60):
        obs, *_ = vec.step(rng.integers(0, 9, size=3))
        for env in range(3):
            model = dataclasses.replace(batch.world_model(env), cars=batch.sensed.cars(env))
            np.testing.assert_array_equal(
                obs[env], batch.features.encode(model, batch.executor[env]))
        seen_second += int((obs[:, 25::3] < 1.0).sum())
    assert seen_second > 0


@pytest.mark.parametrize("observation", ["nearest", "extended"])
def test_trained_policy_drives_the_path_level_env_as_in_its_behavior_env(tmp_path,
                                                                          observation):
    """The ppo: agent on HighwayLoop-v0 (12 frames per step) repeats the behavior env's
    episode exactly: same perception, executor, features and motion layer."""
    from stable_baselines3 import PPO

    config = {"highway": {"max_duration": 30.0}, "observation": observation}
    model = PPO("MlpPolicy", highway(**config), n_steps=64, batch_size=64, n_epochs=1, seed=0)
    model.learn(64)
    path = tmp_path / "policy.zip"
    model.save(path)
    (tmp_path / "policy.yaml").write_text(yaml.safe_dump({"env": HIGHWAY, "config": config}))

    env = highway(**config)
    obs, _ = env.reset(seed=4)
    done = False
    while not done:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    expected = info["summary"]

    path_env = gym.make("sdc_gym/HighwayLoop-v0",
                        config={"steps_per_action": 12, "max_duration": 30.0})
    agent = make_agent(f"ppo:{path}", path_env)
    observation, _ = path_env.reset(seed=4)
    agent.reset()
    done = False
    while not done:
        observation, _, terminated, truncated, info = path_env.step(agent.act(observation))
        done = terminated or truncated
    assert info["summary"]["distance"] == expected["distance"] > 20.0
    assert info["summary"]["incidents"] == expected["incidents"]
    # At 3 frames per step the same policy decides every 4 planning cycles.
    make_agent(f"ppo:{path}", gym.make("sdc_gym/HighwayLoop-v0"))
    with pytest.raises(ValueError, match="multiple"):
        make_agent(f"ppo:{path}", gym.make("sdc_gym/HighwayLoop-v0",
                                           config={"steps_per_action": 5}))


@pytest.mark.parametrize("spec", ["dqn:agents/highway/policies/dqn_highway.zip",
                                  "dqn_nstep_highway", "dqn_swa_highway"])
def test_committed_policy_drives_a_held_out_seed_cleanly_and_changes_lanes(spec):
    """The committed DQN policies (by file, and by name) on a seed they never saw: no
    incident, lap pace near the limit, and lane changes (not keep-lane policies)."""
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"max_duration": 120.0})
    agent = make_agent(spec, env)
    observation, _ = env.reset(seed=1003)
    agent.reset()
    done = False
    while not done:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        done = terminated or truncated
    summary = info["summary"]
    assert summary["incident_total"] == 0 and summary["termination_reason"] == "max_duration"
    assert summary["mean_speed_mph"] > 40.0
    assert agent.behavior.executor.lane_changes >= 1


def test_the_behavior_envs_are_exported_and_documented():
    import pydoc

    import sdc_gym.envs

    for name in ("HighwayLoopBehaviorEnv", "TrackLoopBehaviorEnv"):
        assert name in sdc_gym.envs.__all__
        page = pydoc.render_doc(f"sdc_gym.envs.{name}", renderer=pydoc.plaintext)
        assert "Observation" in page or "observation" in page
