"""Where a split batch's step goes: one process against two, and the parent's share.

    python benchmarks/profile_split.py [--envs 256 1024] [--env-steps 40000] [--rounds 2]

Per E and round, a ``HighwayLoopBehavior-v0`` batch made with ``processes=1`` and then one
with ``processes=2`` (:mod:`sdc_gym.envs.split_vector`), each stepped ``--env-steps`` env
steps with random discrete actions after 10 warm-up steps: env steps/s, wall ms per step,
and the CPU the owning process spent per step (``time.process_time``: with one process
that is the whole step; split, it is the parent's part, sending actions and merging the
blocks' arrays, while the workers step). The peer and the target's judgement are in
``bench_kernel_threads.py`` and ``speed_report.py``; this script says what is left of a
split step beyond the blocks' own work.
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401

BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"


def measure(envs: int, processes: int, env_steps: int) -> tuple[float, float, float]:
    """(env steps/s, wall ms per step, owner CPU ms per step)."""
    vector = gym.make_vec(BEHAVIOR, num_envs=envs, vectorization_mode="vector_entry_point",
                          processes=processes)
    vector.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = [rng.integers(9, size=envs) for _ in range(max(env_steps // envs, 3) + 10)]
    for action in actions[:10]:
        vector.step(action)
    wall, cpu = time.perf_counter(), time.process_time()
    for action in actions[10:]:
        vector.step(action)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    vector.close()
    steps = len(actions) - 10
    return steps * envs / wall, 1e3 * wall / steps, 1e3 * cpu / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[256, 1024])
    parser.add_argument("--env-steps", type=int, default=40_000)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    print("| E | round | processes | env steps/s | wall ms / step | owner CPU ms / step |")
    print("|---:|---:|---:|---:|---:|---:|")
    for envs in args.envs:
        for round_ in range(args.rounds):
            rates = {}
            for processes in (1, 2):
                rate, wall, cpu = measure(envs, processes, args.env_steps)
                rates[processes] = rate
                print(f"| {envs} | {round_ + 1} | {processes} | {rate:,.0f} | {wall:.2f} | "
                      f"{cpu:.2f} |", flush=True)
            print(f"| {envs} | {round_ + 1} | 2 / 1 | {rates[2] / rates[1]:.2f}x | | |")


if __name__ == "__main__":
    main()
