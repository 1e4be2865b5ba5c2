"""``kernel_threads``: the batched highway's kernels on 2 threads give the bits of 1.

The same seeds and actions, batched steps at ``kernel_threads`` 1 and 2: every
observation, reward, flag and info (``full_info``, every key, by its bytes) must be equal,
for an even and an odd number of envs (numba's static split gives the threads blocks of
unequal size then). Shield off and rogue traffic on, so that the episodes end (collisions,
resets in between) and the decision kernel draws from each env's generator.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError
from sdc_gym.envs.highway_vector import HighwayLoopBehaviorVectorEnv, HighwayLoopVectorEnv
from sdc_gym.kernel_threads import KernelThreads, max_kernel_threads, parallel_twin
from sdc_gym.traffic.kinematics import segments
from tests.exact_bytes import feed_bytes

BUSY = {"safety_shield": False,
        "highway": {"max_duration": 12.0, "traffic": {"rogue": True, "rogue_rate": 30.0}}}

needs_two = pytest.mark.skipif(max_kernel_threads() < 2, reason="NUMBA_NUM_THREADS < 2")


def _behavior_run(envs: int, threads: int, steps: int) -> tuple[bytes, int]:
    config = {**BUSY, "highway": {**BUSY["highway"], "kernel_threads": threads}}
    vector = HighwayLoopBehaviorVectorEnv(envs, config, full_info=True)
    record: list[bytes] = []
    obs, info = vector.reset(seed=21)
    feed_bytes(record, [obs, info])
    rng = np.random.default_rng(5)
    endings = 0
    for _ in range(steps):
        actions = np.where(rng.random(envs) < 0.6, 3, rng.integers(9, size=envs))
        obs, reward, terminated, truncated, info = vector.step(actions)
        feed_bytes(record, [obs, reward, terminated, truncated, info])
        endings += int(terminated.sum() + truncated.sum())
    # The 2-thread batch ran the parallel twins, numba's threads on: not the serial code.
    picked = vector.batch.world.kernel_threads._picked
    assert len(picked) == (0 if threads == 1 else 5)
    if threads > 1:
        assert numba.threading_layer() in ("workqueue", "omp", "tbb")
    vector.close()
    return b"".join(record), endings


@needs_two
@pytest.mark.parametrize("envs", [4, 7])
def test_two_kernel_threads_give_the_bits_of_one(envs: int) -> None:
    one, endings = _behavior_run(envs, 1, 80)
    two, _ = _behavior_run(envs, 2, 80)
    assert endings >= 2  # episodes ended and were reset within the run
    assert len(one) == len(two)
    assert one == two


@needs_two
def test_two_kernel_threads_path_level_batch() -> None:
    runs: list[Any] = []
    for threads in (1, 2):
        config = {"traffic": {"car_count": 30}, "max_duration": 6.0, "kernel_threads": threads}
        vector = HighwayLoopVectorEnv(3, config, full_info=True)
        record: list[bytes] = []
        feed_bytes(record, vector.reset(seed=40))
        points = vector.world.path_points
        rng = np.random.default_rng(9)
        start = vector.world.start_xy
        for _ in range(40):
            # Paths straight ahead of the start, then noise: incidents, ends, resets.
            actions = start + np.cumsum(rng.normal(0.4, 0.1, (3, points, 2)), axis=1)
            feed_bytes(record, vector.step(actions))
        runs.append(b"".join(record))
    assert runs[0] == runs[1]


def test_the_parallel_twin_is_the_same_function_under_its_own_name() -> None:
    twin = parallel_twin(segments)
    assert twin.py_func.__code__ is segments.py_func.__code__  # one body
    assert twin.py_func.__qualname__ == "segments__parallel"
    assert twin.targetoptions["parallel"] is True
    assert parallel_twin(segments) is twin
    assert KernelThreads(1).pick(segments) is segments  # the default calls the kernel


@pytest.mark.parametrize("bad", [0, -1, max_kernel_threads() + 1, 1.5, "2", True, None])
def test_bad_kernel_threads_are_config_errors(bad: Any) -> None:
    with pytest.raises(ConfigError) as caught:
        HighwayLoopBehaviorVectorEnv(2, {"highway": {"kernel_threads": bad}})
    message = str(caught.value)
    assert "'kernel_threads'" in message
    top = numba.config.NUMBA_NUM_THREADS
    if isinstance(bad, int) and not isinstance(bad, bool):  # the range, the pool size
        assert f"must be an int in [1, {top}]" in message
        assert f"NUMBA_NUM_THREADS = {top}" in message and message.endswith(f"got {bad}")
    else:  # the type check of every config key
        assert f"expects int, got {type(bad).__name__} ({bad!r})" in message
