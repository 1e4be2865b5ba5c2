"""``processes``: a batch split over worker processes gives the bits of one batch.

The same seeds and actions through ``make_vec(..., processes=P)`` and through the one-process
batch: every observation, reward, flag and info (``full_info``, by its bytes) must be equal,
for blocks of equal and unequal size, both autoreset modes, dict observations (the path
level), the track, and resets with masks, seed lists and scenarios. Shield off and rogue
traffic on, so that episodes end within the run. Then the errors, and the workers' lives:
they end at ``close()`` and when their owner is killed.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError
from sdc_gym.envs.highway_vector import HighwayLoopVectorEnv
from sdc_gym.envs.split_vector import SplitVectorEnv, block_bounds, merge_infos
from tests.exact_bytes import feed_bytes
from tests.processes import all_gone

BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
BUSY = {"safety_shield": False,
        "highway": {"max_duration": 12.0, "traffic": {"rogue": True, "rogue_rate": 30.0}}}


def make(env_id: str, envs: int, processes: int, **kwargs: Any) -> gym.vector.VectorEnv:
    return gym.make_vec(env_id, num_envs=envs, vectorization_mode="vector_entry_point",
                        processes=processes, **kwargs)


def behavior_run(envs: int, processes: int, steps: int, **kwargs: Any) -> tuple[bytes, int]:
    vector = make(BEHAVIOR, envs, processes, config=BUSY, **kwargs)
    assert isinstance(vector, SplitVectorEnv) == (processes > 1)
    record: list[bytes] = []
    feed_bytes(record, vector.reset(seed=21))
    rng = np.random.default_rng(5)
    endings = 0
    for _ in range(steps):
        actions = np.where(rng.random(envs) < 0.6, 3, rng.integers(9, size=envs))
        result = vector.step(actions)
        feed_bytes(record, result)
        endings += int(result[2].sum() + result[3].sum())
    vector.close()
    return b"".join(record), endings


@pytest.mark.parametrize(("envs", "processes", "kwargs"), [
    (7, 2, {"full_info": True}),                       # blocks of 4 and 3, every info key
    (5, 3, {"autoreset_mode": "SameStep"}),            # final_obs / final_info merged
])
def test_split_batch_gives_the_bits_of_one_batch(envs: int, processes: int,
                                                 kwargs: dict[str, Any]) -> None:
    one, endings = behavior_run(envs, 1, 70, **kwargs)
    split, _ = behavior_run(envs, processes, 70, **kwargs)
    assert endings >= 2  # episodes ended and were reset within the run
    assert one == split


def test_split_path_level_and_track_batches() -> None:
    world = HighwayLoopVectorEnv(1, {"max_duration": 6.0}).world
    start, points = world.start_xy, world.path_points
    for env_id, config, steps in [("sdc_gym/HighwayLoop-v0", {"max_duration": 6.0}, 30),
                                  ("sdc_gym/TrackLoopBehavior-v0", None, 25)]:
        runs = []
        for processes in (1, 2):
            vector = make(env_id, 3, processes, config=config, full_info=True)
            record: list[bytes] = []
            feed_bytes(record, vector.reset(seed=40))
            rng = np.random.default_rng(9)
            for _ in range(steps):
                if env_id.endswith("Behavior-v0"):
                    actions = rng.integers(vector.single_action_space.n, size=3)
                else:  # paths ahead of the start, then noise: incidents, ends, resets
                    actions = start + np.cumsum(rng.normal(0.4, 0.1, (3, points, 2)), axis=1)
                feed_bytes(record, vector.step(actions))
            vector.close()
            runs.append(b"".join(record))
        assert runs[0] == runs[1], env_id


def test_split_resets_by_mask_seed_list_and_scenario() -> None:
    scenario = {"cars": [{"lane": 1, "gap": 25.0, "speed": 20.0}]}
    records = []
    for processes in (1, 2):
        vector = make(BEHAVIOR, 4, processes, config=BUSY, full_info=True)
        record: list[bytes] = []
        feed_bytes(record, vector.reset(seed=[3, 7, 8, 9]))
        for step in range(30):
            feed_bytes(record, vector.step(np.full(4, 3 if step % 2 else 6)))
        feed_bytes(record, vector.reset(seed=[50, 51, 52, 53], options={
            "reset_mask": np.array([False, True, True, False]),
            "scenario": [None, scenario, None, scenario]}))
        for _ in range(10):
            feed_bytes(record, vector.step(np.full(4, 3)))
        vector.close()
        records.append(b"".join(record))
    assert records[0] == records[1]


def test_block_bounds_and_info_merge_known_answers() -> None:
    assert block_bounds(7, 2) == [(0, 4), (4, 7)]
    assert block_bounds(6, 3) == [(0, 2), (2, 4), (4, 6)]
    # A key only the second block has: 0 / None / False for the first block's envs.
    first = {"time": np.array([1.5, 2.5]), "_time": np.array([True, True])}
    second = {"time": np.array([3.5]), "_time": np.array([True]),
              "reason": np.array(["done"], dtype=object), "_reason": np.array([True]),
              "summary": {"laps": np.array([2]), "_laps": np.array([True])}}
    merged = merge_infos([first, second], [(0, 2), (2, 3)], 3)
    assert list(merged) == ["time", "_time", "reason", "_reason", "summary"]
    np.testing.assert_array_equal(merged["time"], [1.5, 2.5, 3.5])
    assert merged["reason"].tolist() == [None, None, "done"]
    assert merged["_reason"].tolist() == [False, False, True]
    assert merged["summary"]["laps"].tolist() == [0, 0, 2]
    assert merged["summary"]["laps"].dtype == np.array([2]).dtype


@pytest.fixture(scope="module")
def split() -> SplitVectorEnv:
    vector = make(BEHAVIOR, 4, 2)
    vector.reset(seed=0)
    yield vector
    vector.close()


@pytest.mark.parametrize("bad", [0, -1, 5, 1.5, "2", True, None])
def test_bad_processes_are_refused_naming_the_argument(bad: Any) -> None:
    with pytest.raises(ValueError, match=r"processes must be an int in \[1, num_envs = 4\]"):
        make(BEHAVIOR, 4, bad)


def test_errors_of_the_workers_come_back_naming_the_block(split: SplitVectorEnv) -> None:
    with pytest.raises(ValueError, match=r"action 9 of env 1 out of range; valid: 0\.\.8.*"
                                         r"block of envs 2\.\.3"):
        split.step(np.array([3, 3, 3, 9]))
    with pytest.raises(ValueError, match=r"one action per env \(num_envs = 4\)"):
        split.step(np.array([3, 3, 3]))
    with pytest.raises(ValueError, match=r"takes an int, None or 4 seeds"):
        split.reset(seed=[1, 2])
    with pytest.raises(ValueError, match=r"options\['reset_mask'\] must be 4 bools"):
        split.reset(options={"reset_mask": [True, False]})
    with pytest.raises(ValueError, match=r"unknown reset option 'scenrio'"):
        split.reset(options={"scenrio": None})
    # After the errors the batch goes on.
    obs, reward, *_ = split.step(np.full(4, 3))
    assert obs.shape == (4, 25) and reward.shape == (4,)


def test_a_config_error_in_the_workers_is_the_one_process_error() -> None:
    bad = {"highway": {"traffic": {"car_cont": 3}}}
    with pytest.raises(ConfigError) as one:
        make(BEHAVIOR, 2, 1, config=bad)
    with pytest.raises(ConfigError) as split:
        make(BEHAVIOR, 2, 2, config=bad)
    assert str(split.value) == str(one.value)


def test_workers_end_at_close_and_with_their_killed_owner() -> None:
    vector = make(BEHAVIOR, 2, 2)
    pids = vector.worker_pids
    vector.close()
    assert all_gone(pids, wait_s=10.0) == []
    with pytest.raises(RuntimeError, match="closed"):
        vector.step(np.full(2, 3))
    owner = textwrap.dedent("""
        import os, signal, sys
        import gymnasium as gym, sdc_gym
        vector = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=2,
                              vectorization_mode="vector_entry_point", processes=2)
        print(*vector.worker_pids, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    done = subprocess.run([sys.executable, "-c", owner], capture_output=True, text=True,
                          timeout=300, cwd=os.getcwd())
    assert done.returncode == -signal.SIGKILL, done.stderr
    pids = [int(pid) for pid in done.stdout.split()]
    assert len(pids) == 2
    assert all_gone(pids, wait_s=10.0) == []
