"""Natively batched envs: env i of a batch is exactly the single env with seed s + i.

Known answers: the single env (a batch of one) reproduces the episodes recorded from the
scalar implementation before batching (``tests/data/recorded_digests.json``: digests of
every step's observation, reward, flags and info, recorded by
``benchmarks/record_episodes.py`` from main's scalar code), and E envs in one batch
reproduce E single envs step for step, with their resets in between.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import sdc_gym  # noqa: F401
from sdc_agents.lane_keeping import LaneKeepingDriver
from sdc_gym.envs.highway_vector import (
    HighwayLoopBehaviorVectorEnv,
    HighwayLoopVectorEnv,
    env_info,
)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import record_episodes  # noqa: E402

RECORDED = ROOT / "tests" / "data" / "recorded_digests.json"
SHORT = {"safety_shield": False, "highway": {"max_duration": 20.0}}


def _singles(seeds: list[int], config: dict) -> list[gym.Env]:
    envs = [gym.make("sdc_gym/HighwayLoopBehavior-v0", config=config) for _ in seeds]
    for env, seed in zip(envs, seeds, strict=True):
        env.reset(seed=seed)
    return envs


def _actions(rng: np.random.Generator, count: int) -> np.ndarray:
    # Mostly "keep / cruise" so that shield-less episodes end in collisions at different
    # steps, with random moves in between.
    return np.where(rng.random(count) < 0.7, 3, rng.integers(9, size=count))


def test_batch_equals_single_envs_step_for_step_with_resets_next_step() -> None:
    seeds = [11, 12, 13, 14, 15]
    vector = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=len(seeds),
                          vectorization_mode="vector_entry_point", config=SHORT)
    assert isinstance(vector, HighwayLoopBehaviorVectorEnv)
    obs, _ = vector.reset(seed=seeds[0])
    singles = _singles(seeds, SHORT)
    first = [env.reset(seed=seed)[0] for env, seed in zip(singles, seeds, strict=True)]
    np.testing.assert_array_equal(obs, np.stack(first))
    rng = np.random.default_rng(0)
    restart = [False] * len(seeds)
    endings = 0
    for _ in range(160):
        actions = _actions(rng, len(seeds))
        obs, reward, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            if restart[i]:  # NEXT_STEP: this step resets the env, its action ignored
                expected, _ = env.reset()
                assert reward[i] == 0.0 and not terminated[i] and not truncated[i]
                restart[i] = False
            else:
                expected, r, te, tr, single_info = env.step(int(actions[i]))
                assert reward[i] == r  # bit for bit
                assert (terminated[i], truncated[i]) == (te, tr)
                if te or tr:
                    restart[i] = True
                    endings += 1
                    ended = env_info(info, i)
                    assert ended["summary"] == single_info["summary"]
                    assert ended["termination_reason"] == single_info["termination_reason"]
            np.testing.assert_array_equal(obs[i], expected)
    assert endings >= 6  # collisions and truncations at different steps of the envs


def test_same_step_autoreset_returns_the_new_episode_and_the_final_observation() -> None:
    seeds = [3, 4, 5]
    vector = HighwayLoopBehaviorVectorEnv(len(seeds), SHORT,
                                          autoreset_mode=AutoresetMode.SAME_STEP)
    vector.reset(seed=[3, 4, 5])
    singles = _singles(seeds, SHORT)
    rng = np.random.default_rng(1)
    ended = 0
    for _ in range(120):
        actions = _actions(rng, len(seeds))
        obs, reward, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            expected, r, te, tr, single_info = env.step(int(actions[i]))
            assert reward[i] == r and (terminated[i], truncated[i]) == (te, tr)
            if te or tr:
                ended += 1
                np.testing.assert_array_equal(info["final_obs"][i], expected)
                assert env_info(info["final_info"], i)["summary"] == single_info["summary"]
                expected, _ = env.reset()
            np.testing.assert_array_equal(obs[i], expected)
    assert ended >= 3


def test_path_level_batch_equals_single_envs() -> None:
    config = {"traffic": {"car_count": 20}, "max_duration": 30.0}
    seeds = [7, 8]
    vector = gym.make_vec("sdc_gym/HighwayLoop-v0", num_envs=2,
                          vectorization_mode="vector_entry_point", config=config,
                          full_info=True)
    assert isinstance(vector, HighwayLoopVectorEnv)
    obs, _ = vector.reset(seed=seeds[0])
    singles = [gym.make("sdc_gym/HighwayLoop-v0", config=config) for _ in seeds]
    single_obs = [env.reset(seed=seed)[0] for env, seed in zip(singles, seeds, strict=True)]
    drivers = [LaneKeepingDriver(env.unwrapped.road) for env in singles]
    points = vector.unwrapped.world.path_points
    for _ in range(300):
        actions = np.zeros((2, points, 2))
        paths = [driver.act(single_obs[i]) for i, driver in enumerate(drivers)]
        for i, path in enumerate(paths):
            actions[i, :len(path)] = path
            actions[i, len(path):] = path[-1]  # padding: repeats of the last point
        obs, reward, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            single_obs[i], r, te, tr, single_info = env.step(paths[i])
            assert reward[i] == r and (terminated[i], truncated[i]) == (te, tr)
            for key, value in single_obs[i].items():
                np.testing.assert_array_equal(obs[key][i], value)
            assert info["distance"][i] == single_info["distance"]
            assert info["incidents"][i] == single_info["incidents"]
        if terminated.any() or truncated.any():
            break


def test_seeding_and_bad_arguments() -> None:
    vector = HighwayLoopBehaviorVectorEnv(2, {"highway": {"max_duration": 5.0}})
    a, _ = vector.reset(seed=[4, 9])
    b, _ = HighwayLoopBehaviorVectorEnv(2, {"highway": {"max_duration": 5.0}}).reset(seed=[4, 9])
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"actions must be an int array of shape \(2,\)"):
        vector.step(np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match="num_envs"):
        HighwayLoopBehaviorVectorEnv(0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        HighwayLoopBehaviorVectorEnv(2, autoreset_mode="Sometimes")
    with pytest.raises(ValueError, match="2 seeds"):
        vector.reset(seed=[1, 2, 3])


def test_sb3_vec_env_matches_dummy_vec_env_and_trains() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from sdc_gym.envs.sb3 import SB3VecEnv

    config = {"highway": {"max_duration": 10.0}}
    ours = SB3VecEnv("sdc_gym/HighwayLoopBehavior-v0", 3, config)
    theirs = DummyVecEnv([lambda: gym.make("sdc_gym/HighwayLoopBehavior-v0", config=config)
                          for _ in range(3)])
    ours.seed(21)
    theirs.seed(21)
    np.testing.assert_array_equal(ours.reset(), theirs.reset())
    rng = np.random.default_rng(2)
    done_seen = False
    for _ in range(60):
        actions = rng.integers(9, size=3)
        o1, r1, d1, i1 = ours.step(actions)
        o2, r2, d2, i2 = theirs.step(actions)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(d1, d2)
        for a, b, done in zip(i1, i2, d1, strict=True):
            if done:
                done_seen = True
                np.testing.assert_array_equal(a["terminal_observation"],
                                              b["terminal_observation"])
                assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
                assert a["summary"] == b["summary"]
    assert done_seen
    model = PPO("MlpPolicy", ours, n_steps=32, batch_size=32, n_epochs=1, seed=0, verbose=0)
    model.learn(96)
    assert model.num_timesteps >= 96


@pytest.mark.parametrize("name", ["behavior_random_discrete_s1", "behavior_no_shield_random_s4",
                                  "fsm_bold_s0", "fsm_conservative_s3",
                                  "scripted_off_road_straddle_s11"])
def test_single_env_reproduces_the_recorded_scalar_episodes(name: str) -> None:
    recorded = json.loads(RECORDED.read_text())[name]
    scenario = next(s for s in record_episodes.scenarios() if s["name"] == name)
    scenario = {**scenario, "steps": recorded["steps"]}
    result = record_episodes.run(scenario)
    assert record_episodes.chain(result["steps"]) == recorded["digest"]


BOSCH1 = ROOT.parent / "shared" / "data" / "udacity" / "bosch" / "highway_map_bosch1.csv"


def test_open_road_path_level_batch_equals_single_envs() -> None:
    """The Bosch Challenge's open road, as the loop's test above: env i of a batch is the
    single env with seed i, observation for observation, with the challenge's stop at the
    first incident and its timed goal (a 150 m target, reached by both envs)."""
    config = {"map": str(BOSCH1), "traffic": {"car_count": 12}, "max_duration": 30.0,
              "distance_target": 150.0, "stop_at_incident": True}
    seeds = [7, 8]
    vector = gym.make_vec("sdc_gym/HighwayLoop-v0", num_envs=2,
                          vectorization_mode="vector_entry_point", config=config,
                          full_info=True)
    obs, _ = vector.reset(seed=seeds[0])
    singles = [gym.make("sdc_gym/HighwayLoop-v0", config=config) for _ in seeds]
    single_obs = [env.reset(seed=seed)[0] for env, seed in zip(singles, seeds, strict=True)]
    for key, value in single_obs[1].items():
        np.testing.assert_array_equal(obs[key][1], value)
    drivers = [LaneKeepingDriver(env.unwrapped.road) for env in singles]
    points = vector.unwrapped.world.path_points
    ended = [False, False]
    for _ in range(600):
        actions = np.zeros((2, points, 2))
        paths = [driver.act(single_obs[i]) for i, driver in enumerate(drivers)]
        for i, path in enumerate(paths):
            actions[i, :len(path)] = path
            actions[i, len(path):] = path[-1]
        obs, reward, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            single_obs[i], r, te, tr, single_info = env.step(paths[i])
            assert reward[i] == r and (terminated[i], truncated[i]) == (te, tr)
            for key, value in single_obs[i].items():
                np.testing.assert_array_equal(obs[key][i], value)
            if te or tr:
                ended[i] = True
                assert env_info(info, i)["summary"] == single_info["summary"]
                assert single_info["summary"]["termination_reason"] in (
                    "distance_target", "stop_at_incident")
        if terminated.any() or truncated.any():
            break
    assert any(ended)


def test_open_road_behavior_batch_equals_single_envs() -> None:
    config = {"highway": {"map": str(BOSCH1), "max_duration": 20.0}}
    seeds = [5, 6, 7]
    vector = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=len(seeds),
                          vectorization_mode="vector_entry_point", config=config)
    obs, _ = vector.reset(seed=seeds[0])
    singles = _singles(seeds, config)
    first = [env.reset(seed=seed)[0] for env, seed in zip(singles, seeds, strict=True)]
    np.testing.assert_array_equal(obs, np.stack(first))
    rng = np.random.default_rng(3)
    for _ in range(80):
        actions = _actions(rng, len(seeds))
        obs, reward, terminated, truncated, _ = vector.step(actions)
        for i, env in enumerate(singles):
            expected, r, te, tr, _ = env.step(int(actions[i]))
            assert reward[i] == r and (terminated[i], truncated[i]) == (te, tr)
            np.testing.assert_array_equal(obs[i], expected)
        if terminated.any() or truncated.any():
            break
    # The open road's s, not a loop's: every ego still near the start of 5.1 km.
    assert all(0.0 < env.unwrapped.batch.world.s[0] < 1000.0 for env in singles)
