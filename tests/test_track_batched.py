"""Natively batched track envs: env i of a batch is exactly the single env with seed s + i.

Known answers: the single envs (batches of one) reproduce the episodes recorded from the
scalar implementation before batching (``tests/data/recorded_track_digests.json``: digests
of every step's observation, reward, flags and whole info, recorded by
``benchmarks/record_episodes.py`` from main's scalar code: the DBW stack agents with
manual override, the site car, obstacles; scripted drivers provoking red-light, speed,
acceleration, jerk, off-road and collision incidents; the behavior env with random and
scripted decisions); E envs in one batch reproduce E single envs step for step, with
their resets in between; the kernels' math equals Python's on random inputs.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import sdc_gym  # noqa: F401
from sdc_gym.envs.batch_vector import env_info
from sdc_gym.envs.track_vector import TrackLoopBehaviorVectorEnv, TrackLoopVectorEnv

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import record_episodes  # noqa: E402

RECORDED = ROOT / "tests" / "data" / "recorded_track_digests.json"
BEHAVIOR = "sdc_gym/TrackLoopBehavior-v0"
# The site lot: laps end episodes at different decisions (random speeds), and a short
# duration truncates the slow ones.
SITE = {"track": {"track": "site", "laps": 1, "max_duration": 33.0}}


def _equal(a, b) -> bool:
    """Exactly equal, recursively (floats by value and sign, arrays by dtype and bits); a
    None of ``b`` may be a NaN in ``a`` (the vector info's float arrays hold a missing
    value, e.g. a ``mean_lap_time`` without laps, as NaN)."""
    if b is None and isinstance(a, float):
        return a != a
    if isinstance(a, dict):
        return isinstance(b, dict) and set(a) == set(b) and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray):
        return a.dtype == np.asarray(b).dtype and np.array_equal(a, b)
    if isinstance(a, float):
        return (a == b and math.copysign(1, a) == math.copysign(1, b)) or (a != a and b != b)
    return a == b


def _same_info(infos: dict, env: int, single: dict) -> bool:
    """Env ``env``'s entries of a vector ``info`` are the single env's info (whose
    ``summary`` is None before the end, where the vector info has none for the env)."""
    got = env_info(infos, env)
    if single["summary"] is None:  # env_info leaves the other envs' summaries' shells
        got.pop("summary", None)
    return _equal(got, {key: value for key, value in single.items()
                        if not (key == "summary" and value is None)})


def _singles(env_id: str, seeds: list[int], config: dict) -> tuple[list[gym.Env], list]:
    envs = [gym.make(env_id, config=config) for _ in seeds]
    first = [env.reset(seed=seed)[0] for env, seed in zip(envs, seeds, strict=True)]
    return envs, first


def test_behavior_batch_equals_single_envs_with_resets_next_step() -> None:
    seeds = [3, 4, 5, 6]
    vector = gym.make_vec(BEHAVIOR, num_envs=len(seeds), vectorization_mode="vector_entry_point",
                          config=SITE, full_info=True)
    assert isinstance(vector, TrackLoopBehaviorVectorEnv)
    obs, _ = vector.reset(seed=seeds[0])
    singles, first = _singles(BEHAVIOR, seeds, SITE)
    np.testing.assert_array_equal(obs, np.stack(first))
    rng = np.random.default_rng(0)
    restart = [False] * len(seeds)
    endings: dict[str, int] = {}
    for _ in range(110):
        # Mostly "go", so that some laps end before the duration and some do not.
        actions = np.where(rng.random(len(seeds)) < 0.5, 0, rng.integers(4, size=len(seeds)))
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
                assert _same_info(info, i, single_info)  # every key
                if te or tr:
                    restart[i] = True
                    reason = single_info["termination_reason"]
                    endings[reason] = endings.get(reason, 0) + 1
            np.testing.assert_array_equal(obs[i], expected)
    # Laps and truncations, at different decisions of the envs.
    assert endings.get("laps_completed", 0) >= 2 and endings.get("max_duration", 0) >= 1


def test_same_step_autoreset_continuous_actions_manual_override_and_frames() -> None:
    config = {"action": "continuous", "decision_period_s": 0.6,
              "track": {"steps_per_action": 3, "max_duration": 30.0,
                        "manual": {"mode": "random", "interval_s": [5.0, 12.0],
                                   "duration_s": [2.0, 5.0]}}}
    seeds = [21, 22, 23]
    vector = TrackLoopBehaviorVectorEnv(len(seeds), config,
                                        autoreset_mode=AutoresetMode.SAME_STEP)
    vector.reset(seed=seeds)
    singles, _ = _singles(BEHAVIOR, seeds, config)
    rng = np.random.default_rng(1)
    ended, manual_s = 0, 0.0
    for _ in range(60):
        actions = rng.uniform(-1.0, 1.0, size=(len(seeds), 2)).astype(np.float32)
        obs, reward, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            expected, r, te, tr, single_info = env.step(actions[i])
            assert reward[i] == r and (terminated[i], truncated[i]) == (te, tr)
            if te or tr:
                ended += 1
                manual_s += single_info["summary"]["manual_time"]
                np.testing.assert_array_equal(info["final_obs"][i], expected)
                assert _equal(env_info(info["final_info"], i)["summary"],
                              single_info["summary"])
                expected, _ = env.reset()
            np.testing.assert_array_equal(obs[i], expected)
    assert ended == 3 and manual_s > 5.0  # every env was reset, and the human drove


def test_dbw_level_batch_equals_single_envs_driven_by_the_stack() -> None:
    from sdc_agents.registry import make_agent

    config = {"observe_light_states": True, "max_duration": 40.0,
              "obstacles": {"count": 3, "max_offset_d": 1.0}, "start_speed": 9.0}
    seeds = [7, 8]
    vector = gym.make_vec("sdc_gym/TrackLoop-v0", num_envs=2,
                          vectorization_mode="vector_entry_point", config=config,
                          full_info=True)
    assert isinstance(vector, TrackLoopVectorEnv)
    obs, _ = vector.reset(seed=seeds[0])
    singles, single_obs = _singles("sdc_gym/TrackLoop-v0", seeds, config)
    agents = [make_agent("dbw_ground_truth", env) for env in singles]
    for agent in agents:
        agent.reset()
    for key, value in single_obs[1].items():
        np.testing.assert_array_equal(obs[key][1], value)
    for _ in range(400):
        actions = np.stack([agent.act(o) for agent, o in zip(agents, single_obs, strict=True)])
        obs, reward, terminated, truncated, info = vector.step(actions)
        for i, env in enumerate(singles):
            single_obs[i], r, te, tr, single_info = env.step(actions[i])
            assert reward[i] == r and (terminated[i], truncated[i]) == (te, tr)
            for key, value in single_obs[i].items():
                np.testing.assert_array_equal(obs[key][i], value)
            assert _same_info(info, i, single_info)
    with pytest.raises(ValueError, match=r"action\[0\] throttle = 2.0 is outside"):
        vector.step(np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))


def test_sb3_vec_env_matches_dummy_vec_env_and_trains() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from sdc_gym.envs.sb3 import SB3VecEnv

    config = {"track": {"track": "site", "max_duration": 12.0}}
    ours = SB3VecEnv(BEHAVIOR, 3, config)
    theirs = DummyVecEnv([lambda: gym.make(BEHAVIOR, config=config) for _ in range(3)])
    ours.seed(21)
    theirs.seed(21)
    np.testing.assert_array_equal(ours.reset(), theirs.reset())
    rng = np.random.default_rng(2)
    done_seen = False
    for _ in range(30):
        actions = rng.integers(4, size=3)
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
                assert _equal(a["summary"], b["summary"])
    assert done_seen
    model = PPO("MlpPolicy", ours, n_steps=16, batch_size=24, n_epochs=1, seed=0, verbose=0)
    model.learn(48)
    assert model.num_timesteps >= 48


def test_bad_actions_and_a_stack_command_outside_the_action_box_raise() -> None:
    vector = TrackLoopBehaviorVectorEnv(2, {"track": {"max_duration": 5.0}})
    vector.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must be an int array of shape \(2,\)"):
        vector.step(np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match=r"action 7 of env 1 out of range; valid: 0..3"):
        vector.step(np.array([0, 7]))
    # Tyres that lock at 355 N m, less than the controller's braking from 11 m/s to 5.5 m/s
    # asks: the env rejects the stack's brake torque as it rejects such an action (the
    # scalar code raised this very message).
    env = gym.make(BEHAVIOR, config={"track": {"start_speed": 11.0, "vehicle_overrides": {
        "tire_friction": 0.1}}})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action\[1\] brake_torque = 479.9616394042969 is "
                                         r"outside its valid range \[0, 354.926\] N m"):
        env.step(2)


@pytest.mark.parametrize("name", sorted(json.loads(RECORDED.read_text())))
def test_single_envs_reproduce_the_recorded_scalar_episodes(name: str) -> None:
    recorded = json.loads(RECORDED.read_text())[name]
    scenario = next(s for s in record_episodes.scenarios() if s["name"] == name)
    result = record_episodes.run({**scenario, "steps": recorded["steps"]})
    assert len(result["steps"]) == recorded["entries"]
    assert record_episodes.chain(result["steps"]) == recorded["digest"]


def test_kernel_math_is_pythons() -> None:
    """The exact-math kernels (``sdc_gym.geometry.exact_math``) give Python's bits: on
    random pairs over twelve orders of magnitude, signed zeros and a half-way case."""
    from numba import njit

    from sdc_gym.geometry.exact_math import py_hypot, py_max, py_min, py_mod, py_remainder

    @njit
    def apply(a, b, out):
        for i in range(a.size):
            out[0, i] = py_hypot(a[i], b[i])
            out[1, i] = py_remainder(a[i], b[i])
            out[2, i] = py_max(a[i], b[i])
            out[3, i] = py_min(a[i], b[i])
            out[4, i] = py_mod(a[i], abs(b[i]))  # the kernels' divisors are > 0

    rng = np.random.default_rng(5)
    a = rng.normal(size=100_000) * 10.0 ** rng.uniform(-6, 6, 100_000)
    b = rng.normal(size=100_000) * 10.0 ** rng.uniform(-6, 6, 100_000)
    a[:4], b[:4] = [0.0, -0.0, 2.5, 3.0], [0.0, 0.0, 1.0, 2.0]  # signed zeros, half-way
    a[4:8], b[4:8] = [0.5, -0.0, 1.0, 3.0], [1.0, 1.0, 1.0, 1.0]  # in range, -0.0, edges
    b = np.where(b == 0.0, 1.0, b)
    out = np.empty((5, a.size))
    apply(a, b, out)
    pairs = list(zip(a.tolist(), b.tolist(), strict=True))
    for row, function in enumerate((math.hypot, math.remainder, max, min,
                                    lambda x, y: x % abs(y))):
        expected = np.array([function(x, y) for x, y in pairs])
        assert np.array_equal(out[row].view(np.int64), expected.view(np.int64)), row


def test_a_pickled_batch_continues_exactly_as_the_original() -> None:
    """The bound kernel calls (machine code entry points) are dropped when pickling and
    bound again to the copy's own arrays."""
    import pickle

    vector = TrackLoopBehaviorVectorEnv(3, {"track": {"max_duration": 30.0}})
    vector.reset(seed=4)
    for _ in range(3):
        vector.step(np.array([0, 1, 3]))
    clone = pickle.loads(pickle.dumps(vector))
    for actions in ([1, 0, 2], [3, 3, 0], [2, 1, 1]):
        ours, theirs = vector.step(np.array(actions)), clone.step(np.array(actions))
        for a, b in zip(ours[:4], theirs[:4], strict=True):
            np.testing.assert_array_equal(a, b)
    assert not np.shares_memory(vector.batch.observations, clone.batch.observations)
