"""``copy.deepcopy(env)`` is an independent env that goes on exactly as the original.

Lookahead planners (highway-env's MCTS agents, a clairvoyant rollout) copy the env and
try actions on the copy. The batch state keeps its fields as views of packed blocks
(:mod:`sdc_gym.packed_rows`); a plain deep copy used to detach them, so the copy's
distance, metrics and traffic froze at the moment of the copy.
"""

from __future__ import annotations

import copy
import gc
import pickle
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.metrics.batch import DrivingMetricsBatch
from sdc_gym.traffic.state import TrafficState

ENV_IDS = ("sdc_gym/HighwayLoop-v0", "sdc_gym/HighwayLoopBehavior-v0",
           "sdc_gym/TrackLoop-v0", "sdc_gym/TrackLoopBehavior-v0")
BEFORE, AFTER = 30, 40  # steps before the copy, steps compared after it


def actions(space: gym.Space[Any], count: int, seed: int) -> list[Any]:
    space.seed(seed)
    return [space.sample() for _ in range(count)]


def drive(env: gym.Env[Any, Any], plan: list[Any]) -> list[tuple[Any, ...]]:
    """``(observation, reward, terminated, truncated, distance)`` after each action."""
    steps = []
    for action in plan:
        observation, reward, terminated, truncated, info = env.step(action)
        flat = gym.spaces.flatten(env.observation_space, observation)  # the dict ones too
        steps.append((flat.copy(), float(reward), terminated, truncated,
                      info.get("distance")))
        if terminated or truncated:
            break
    return steps


def assert_same(first: list[tuple[Any, ...]], second: list[tuple[Any, ...]]) -> None:
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_copy_goes_on_as_the_original_and_leaves_it_alone(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=7)
    plan = actions(env.action_space, BEFORE + AFTER, seed=1)
    drive(env, plan[:BEFORE])
    duplicate = copy.deepcopy(env)
    # The copy, given the original's next actions, drives the same steps bit for bit.
    from_copy = drive(duplicate, plan[BEFORE:])
    # Trying other actions on the copy does not touch the original ...
    drive(duplicate, actions(env.action_space, AFTER, seed=2))
    from_original = drive(env, plan[BEFORE:])
    assert_same(from_copy, from_original)
    # ... which is also what a fresh env drives with the whole plan.
    reference = gym.make(env_id)
    reference.reset(seed=7)
    drive(reference, plan[:BEFORE])
    assert_same(drive(reference, plan[BEFORE:]), from_original)
    # And the copy really moved on from where it was copied.
    distances = [step[4] for step in from_copy]
    if distances[0] is not None:
        assert distances[-1] > distances[0]


def test_a_vector_env_copy_is_independent_too() -> None:
    envs = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=3,
                        vectorization_mode="vector_entry_point")
    envs.reset(seed=11)
    rng = np.random.default_rng(0)
    plan = [rng.integers(0, 9, size=3) for _ in range(BEFORE + AFTER)]
    for action in plan[:BEFORE]:
        envs.step(action)
    duplicate = copy.deepcopy(envs)
    from_copy = [duplicate.step(action)[:4] for action in plan[BEFORE:]]
    for _ in range(AFTER):
        duplicate.step(rng.integers(0, 9, size=3))
    from_original = [envs.step(action)[:4] for action in plan[BEFORE:]]
    for a, b in zip(from_copy, from_original, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


def test_the_copys_named_fields_are_views_of_its_own_blocks() -> None:
    state = TrafficState(envs=2, cars=3)
    state.speed[:] = 4.0
    duplicate = copy.deepcopy(state)
    for name in (*TrafficState.CAR_FLOATS, *TrafficState.CAR_INTS, *TrafficState.ENV_INTS,
                 *TrafficState.ENV_FLOATS):
        assert np.shares_memory(getattr(duplicate, name), duplicate.blocks[0]) or any(
            np.shares_memory(getattr(duplicate, name), block) for block in duplicate.blocks)
        assert not any(np.shares_memory(getattr(duplicate, name), block)
                       for block in state.blocks)
    # A kernel writes the block; the named field must show it (and not the original).
    duplicate.car_floats[TrafficState.CAR_FLOATS.index("speed")] = 9.0
    assert duplicate.speed.tolist() == [[9.0] * 3] * 2
    assert state.speed.tolist() == [[4.0] * 3] * 2


def test_a_copied_metrics_batch_counts_on_in_its_named_rows() -> None:
    env = gym.make("sdc_gym/HighwayLoop-v0").unwrapped
    env.reset(seed=0)
    metrics = env.world.metrics
    assert isinstance(metrics, DrivingMetricsBatch)
    duplicate = copy.deepcopy(metrics)
    row = DrivingMetricsBatch.FLOATS.index("distance")
    duplicate._floats[row] = 123.0
    assert duplicate.distance.tolist() == [123.0]
    assert metrics.distance.tolist() != [123.0]


def test_a_copy_draws_from_its_own_generator_after_the_original_is_gone() -> None:
    # The traffic's kernels draw through raw addresses of each env's generator
    # (sdc_gym.generator_kernel); a copy must point at its own, or it would advance the
    # original's, or read freed memory once the original is collected.
    env = gym.make("sdc_gym/HighwayLoopBehavior-v0", config={"highway": {
        "traffic": {"car_count": 30}}})
    env.reset(seed=5)
    plan = actions(env.action_space, 300, seed=3)
    drive(env, plan[:BEFORE])
    duplicate = copy.deepcopy(env)
    traffic, copied = env.unwrapped.batch.world.traffic, duplicate.unwrapped.batch.world.traffic
    assert not np.array_equal(traffic.rng_pointers, copied.rng_pointers)
    del env, traffic
    gc.collect()
    reference = gym.make("sdc_gym/HighwayLoopBehavior-v0", config={"highway": {
        "traffic": {"car_count": 30}}})
    reference.reset(seed=5)
    drive(reference, plan[:BEFORE])
    assert_same(drive(duplicate, plan[BEFORE:]), drive(reference, plan[BEFORE:]))


def test_an_env_pickles_and_goes_on_as_the_original() -> None:
    env = gym.make("sdc_gym/HighwayLoopBehavior-v0").unwrapped
    env.reset(seed=9)
    plan = actions(env.action_space, BEFORE + AFTER, seed=4)
    drive(env, plan[:BEFORE])
    restored = pickle.loads(pickle.dumps(env))
    assert_same(drive(restored, plan[BEFORE:]), drive(env, plan[BEFORE:]))
