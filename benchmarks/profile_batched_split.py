"""Where a batched ``HighwayLoopBehavior-v0`` step spends its time: numba kernels, Python, copies.

    python benchmarks/profile_batched_split.py [--envs 256] [--steps 200]

Times ``--steps`` random-action steps of the batch (after a warm-up), then profiles the same
number with cProfile and splits the profiled time into numba kernels (sdc_gym functions
whose own time is their whole time: a dispatcher call), numpy calls and copies, and the
rest (Python between the kernels, which threads over the env axis cannot speed up).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import time

import gymnasium as gym

import sdc_gym  # noqa: F401


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args()
    env = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=args.envs,
                       vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(50)]
    for action in actions[:20]:
        env.step(action)
    start = time.perf_counter()
    for i in range(args.steps):
        env.step(actions[i % 50])
    rate = args.steps * args.envs / (time.perf_counter() - start)
    print(f"load {' '.join(f'{v:.2f}' for v in os.getloadavg())}  E={args.envs}  "
          f"{rate:,.0f} env steps/s")
    profile = cProfile.Profile()
    profile.enable()
    for i in range(args.steps):
        env.step(actions[i % 50])
    profile.disable()
    stats = pstats.Stats(profile)
    kernels = python = copies = 0.0
    for (file, _line, name), (_cc, _nc, own, cumulative, _callers) in stats.stats.items():
        if "sdc_gym" in file and own > 0 and abs(own - cumulative) < 1e-9:
            kernels += own
        elif "numpy" in file or name.startswith("<method 'astype'") or "ascontiguous" in name:
            copies += own
        else:
            python += own
    total = kernels + python + copies
    print(f"kernels {kernels / total:.0%}  python {python / total:.0%}  "
          f"numpy/copies {copies / total:.0%}  (of {total:.2f} s profiled)")
    stats.sort_stats("tottime").print_stats(12)


if __name__ == "__main__":
    main()
