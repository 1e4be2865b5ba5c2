"""Batched behavior env steps/s on one core and on two (``kernel_threads`` 2, or the batch
split over 2 worker processes), side by side in one run.

    python benchmarks/bench_kernel_threads.py [--envs 64 256 1024] [--rounds 5]
        [--env-steps 20000] [--peer-steps 100]
    NUMBA_THREADING_LAYER=omp OMP_WAIT_POLICY=passive python benchmarks/bench_kernel_threads.py

``HighwayLoopBehavior-v0`` batches (``gym.make_vec(..., vectorization_mode=
"vector_entry_point")``, random discrete actions, the default config), one per E (a batch
of 1024 behavior envs holds ~130 MB: the perceptions share the road tables), made
with ``highway.kernel_threads = 2`` and warmed up (the parallel twins compile at the
first step), then timed in rounds: each round steps the batch for ``--env-steps`` env
steps with its kernels on 1 thread and as many on 2 (``KernelThreads.set``: the same
bits either way, so both continue the same episodes) and highway-env's
``highway-fast-v0`` (the peer, one env, ``bench_behavior.env_steps_per_second``) for
``--peer-steps``, in that order, so that the three see the same load. A second batch of
each E, made with ``processes=2`` (:mod:`sdc_gym.envs.split_vector`: envs ``0..E/2-1`` and
``E/2..E-1`` in two worker processes, kernels on one thread each, the same bits), is
stepped as many env steps in each round after the threads. Prints per row min/median/max
env steps/s over the rounds, the median ratios to one thread and each median / the peer's
median (all rounds of every E), with the load average at each round and the threading
layer numba ran (workqueue unless ``NUMBA_THREADING_LAYER`` says otherwise:
:mod:`sdc_gym.kernel_threads`).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
import warnings

import gymnasium as gym
import numba
import numpy as np
from bench_behavior import env_steps_per_second

import sdc_gym  # noqa: F401

BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
PEER = "highway-fast-v0"
THREADS = (1, 2)
SPLIT = "2 processes"
"""The rates' key of the batch split over two worker processes (``(E, SPLIT)``)."""


def load() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def make(envs: int, threads: int,
         seed: int = 0) -> tuple[gym.vector.VectorEnv, np.random.Generator]:
    vector = gym.make_vec(BEHAVIOR, num_envs=envs, vectorization_mode="vector_entry_point",
                          config={"highway": {"kernel_threads": threads}})
    vector.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for warm in (threads, 1):  # warm-up: the parallel twins compile, the kernels load
        vector.unwrapped.batch.world.kernel_threads.set(warm)
        for _ in range(3):
            vector.step(rng.integers(9, size=envs))
    return vector, rng


CORE_PROBE = """
import time
import numpy as np
started = time.perf_counter()
total = 0
for i in range(4_000_000):
    total += i * i % 7
values = np.random.default_rng(0).random((256, 256))
for _ in range(150):
    values = np.sin(values) * np.cos(values) + values
print(time.perf_counter() - started)
"""
"""A fixed CPU-bound job (a Python loop, then numpy ufuncs: the two kinds of work of a
batch step), printing its wall seconds."""


def core_scaling(rounds: int = 3) -> list[float]:
    """Per round, how much work two independent CPU-bound processes get done at once
    against one alone: ``2 x alone / together`` (2.0: two full cores; about 1.6 on a
    machine whose two cores slow each other, e.g. shared execution units or clocks). No
    split of one batch over two cores can beat it."""
    def run(copies: int) -> float:
        children = [subprocess.Popen([sys.executable, "-c", CORE_PROBE],
                                     stdout=subprocess.PIPE, text=True)
                    for _ in range(copies)]
        return statistics.mean(float(child.communicate()[0]) for child in children)

    return [2.0 * run(1) / run(2) for _ in range(rounds)]


def make_split(envs: int, seed: int = 0) -> tuple[gym.vector.VectorEnv, np.random.Generator]:
    """A batch of ``envs`` split over 2 worker processes, reset and warmed up."""
    vector = gym.make_vec(BEHAVIOR, num_envs=envs, vectorization_mode="vector_entry_point",
                          processes=2)
    vector.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        vector.step(rng.integers(9, size=envs))
    return vector, rng


def steps_per_second(vector: gym.vector.VectorEnv, rng: np.random.Generator,
                     env_steps: int) -> float:
    envs = vector.num_envs
    batches = max(env_steps // envs, 3)
    actions = [rng.integers(9, size=envs) for _ in range(batches)]
    started = time.perf_counter()
    for action in actions:
        vector.step(action)
    return batches * envs / (time.perf_counter() - started)


def cells(values: list[float]) -> str:
    return " / ".join(f"{value:,.0f}" for value in (min(values), statistics.median(values),
                                                    max(values)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[64, 256, 1024])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--env-steps", type=int, default=20000,
                        help="env steps per batch and round")
    parser.add_argument("--peer-steps", type=int, default=100,
                        help=f"{PEER} steps per round")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    print(f"numba {numba.__version__}, NUMBA_NUM_THREADS {numba.config.NUMBA_NUM_THREADS}, "
          f"OMP_WAIT_POLICY {os.environ.get('OMP_WAIT_POLICY', '(unset)')}, load {load()}")
    rates: dict[object, list[float]] = {PEER: []}
    for envs in args.envs:
        vector, rng = make(envs, max(THREADS))
        split, split_rng = make_split(envs)
        threads_of = vector.unwrapped.batch.world.kernel_threads  # shared by every layer
        print(f"E = {envs}: made and warmed up (threading layer "
              f"{numba.threading_layer()}), load {load()}", flush=True)
        for mode in (*THREADS, SPLIT):
            rates[(envs, mode)] = []
        for round_ in range(args.rounds):
            for threads in THREADS:
                threads_of.set(threads)
                rates[(envs, threads)].append(steps_per_second(vector, rng, args.env_steps))
            rates[(envs, SPLIT)].append(steps_per_second(split, split_rng, args.env_steps))
            rates[PEER].append(env_steps_per_second(PEER, args.peer_steps, seed=round_))
            print(f"  round {round_ + 1}/{args.rounds}: "
                  + ", ".join(f"{t} thread(s) {rates[(envs, t)][-1]:,.0f}" for t in THREADS)
                  + f", {SPLIT} {rates[(envs, SPLIT)][-1]:,.0f}, {PEER} "
                  f"{rates[PEER][-1]:,.1f}; load {load()}", flush=True)
        vector.close()
        split.close()
        del vector, split
    peer = statistics.median(rates[PEER])
    print(f"\nload at the end {load()}; env steps/s, min / median / max of {args.rounds} "
          "rounds\n")
    print(f"| E | kernel_threads 1 | kernel_threads 2 | {SPLIT} | 2 threads / 1 | "
          f"{SPLIT} / 1 | 1 thread / {PEER} | {SPLIT} / {PEER} |")
    print("|---:|---|---|---|---:|---:|---:|---:|")
    for envs in args.envs:
        one, two, split = rates[(envs, 1)], rates[(envs, 2)], rates[(envs, SPLIT)]
        m1, m2, ms = (statistics.median(values) for values in (one, two, split))
        print(f"| {envs} | {cells(one)} | {cells(two)} | {cells(split)} | {m2 / m1:.2f}x | "
              f"{ms / m1:.2f}x | {m1 / peer:,.0f}x | {ms / peer:,.0f}x |")
    print(f"\n{PEER} (one env, the peer, every round of every E): {cells(rates[PEER])} "
          "env steps/s")
    scaling = core_scaling(args.rounds)
    print(f"this machine's two cores: two independent CPU-bound processes at once do "
          f"{' / '.join(f'{value:.2f}' for value in sorted(scaling))}x the work of one alone "
          "(min / median / max; the ceiling of any 2-way split)")


if __name__ == "__main__":
    main()
