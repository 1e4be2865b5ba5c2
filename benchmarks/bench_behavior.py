"""Behavior-level env steps per second and PPO samples per second, against highway-env.

    python benchmarks/bench_behavior.py [--steps 3000] [--ppo-steps 8192] [--repeats 3]

Measured in one run, on this machine:

* env steps/s in one process (random actions, resets not timed): sdc-gym's
  ``HighwayLoopBehavior-v0`` (one decision = 12 frames = 0.24 s, perception + shield +
  motion layer + the path-level simulation included) and ``TrackLoopBehavior-v0`` (one
  decision = 1 s = 50 ticks of the drive-by-wire stack), and highway-env's
  ``highway-fast-v0`` (one decision = 1 s);
* PPO samples/s (stable-baselines3, MLP 64x64, 2048 samples per rollout, 5 epochs of
  minibatches of 256), one env per CPU core in subprocesses, torch on one thread per
  process: sdc-gym's highway behavior env against ``highway-fast-v0`` with the same PPO
  settings and its default kinematics observation.

The best of ``--repeats`` runs is reported with the ratio sdc-gym / highway-env.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401

PPO_SETTINGS = {"n_steps": 1024, "batch_size": 256, "n_epochs": 5,
                "policy_kwargs": {"net_arch": [64, 64]}}


def env_steps_per_second(env_id: str, steps: int, config: dict | None = None,
                         seed: int = 0) -> float:
    if env_id.startswith("highway"):
        import highway_env  # noqa: F401

    env = gym.make(env_id, **({"config": config} if config is not None else {}))
    env.reset(seed=seed)
    env.action_space.seed(seed)
    wall = 0.0
    for _ in range(steps):
        action = env.action_space.sample()
        started = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        wall += time.perf_counter() - started
        if terminated or truncated:
            env.reset()
    env.close()
    return steps / wall


def ppo_samples_per_second(env_id: str, samples: int, n_envs: int, seed: int = 0) -> float:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    torch.set_num_threads(1)
    module = "sdc_gym" if env_id.startswith("sdc_gym/") else "highway_env"
    vec = make_vec_env(f"{module}:{env_id}", n_envs=n_envs, seed=seed,
                       vec_env_cls=SubprocVecEnv)
    model = PPO("MlpPolicy", vec, seed=seed, verbose=0,
                **{**PPO_SETTINGS, "n_steps": PPO_SETTINGS["n_steps"] * 2 // n_envs})
    model.learn(2048)  # warm-up: processes, first rollout
    started = time.perf_counter()
    model.learn(samples, reset_num_timesteps=False)
    wall = time.perf_counter() - started
    vec.close()
    return samples / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=3000, help="env steps per measurement")
    parser.add_argument("--ppo-steps", type=int, default=8192, help="PPO samples timed")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--n-envs", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")

    def best(fn, *fn_args) -> float:
        return max(fn(*fn_args) for _ in range(args.repeats))

    track_steps = max(args.steps // 20, 50)
    rows = [
        ("HighwayLoopBehavior-v0 env steps/s", best(env_steps_per_second,
                                                    "sdc_gym/HighwayLoopBehavior-v0",
                                                    args.steps)),
        ("TrackLoopBehavior-v0 env steps/s", best(env_steps_per_second,
                                                  "sdc_gym/TrackLoopBehavior-v0", track_steps)),
        ("highway-fast-v0 env steps/s", best(env_steps_per_second, "highway-fast-v0",
                                             max(args.steps // 10, 100))),
    ]
    ppo_ours = best(ppo_samples_per_second, "sdc_gym/HighwayLoopBehavior-v0", args.ppo_steps,
                    args.n_envs)
    ppo_theirs = best(ppo_samples_per_second, "highway-fast-v0",
                      max(args.ppo_steps // 8, 1024), args.n_envs)
    rows += [(f"PPO samples/s, {args.n_envs} envs: HighwayLoopBehavior-v0", ppo_ours),
             (f"PPO samples/s, {args.n_envs} envs: highway-fast-v0", ppo_theirs)]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value:10.1f}")
    print(f"ratio env steps/s (sdc-gym highway behavior / highway-fast-v0): "
          f"{rows[0][1] / rows[2][1]:.1f}x")
    print(f"ratio PPO samples/s (sdc-gym / highway-fast-v0): {ppo_ours / ppo_theirs:.1f}x")
    print(f"(cores: {os.cpu_count()}, numpy {np.__version__})")


if __name__ == "__main__":
    main()
