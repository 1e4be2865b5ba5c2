"""Single-env rates, timed in whichever code tree's interpreter runs this file.

    python benchmarks/single_env_rates.py TASK [--size N] [--seed S]

Prints one JSON line ``{"task", "rate", "unit", "warm_s"}``. Only the public API that the
pre-batch code had too is used (``gym.make``, ``sdc_agents.registry.make_agent``,
``sdc_agents.lane_keeping.LaneKeepingDriver``), so ``bench_batched.py --reference TREE`` can run
the same measurement with another tree's ``.venv/bin/python`` (``TREE`` first on
``sys.path``, for its ``agents``) and print the ratio, interleaving the two trees.

Tasks (``--size``: how much is timed, after one warm-up step that loads compiled kernels;
``warm_s`` is the time from the start of the process to the end of that step):

* ``behavior``: ``HighwayLoopBehavior-v0`` random discrete actions, env steps / s;
* ``lane_keeping``: ``HighwayLoop-v0`` with 12 cars, 5 frames per step, driven by the
  lane-keeping driver (its planning included), simulated s / wall s;
* ``fsm_lap``: one lap of ``HighwayLoop-v0`` (3 frames per step) with ``fsm_bold``
  planning at every step, wall s per lap (lower is better; ``--size`` laps, seeds
  ``seed, seed + 1, ...``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

STARTED = time.perf_counter()

TASKS = ("behavior", "lane_keeping", "fsm_lap")


def behavior(steps: int, seed: int) -> tuple[float, float, str]:
    """Env steps per wall second of random discrete actions (the time to the warm step)."""
    import gymnasium as gym
    import numpy as np

    env = gym.make("sdc_gym/HighwayLoopBehavior-v0")
    env.reset(seed=seed)
    actions = np.random.default_rng(seed).integers(env.action_space.n, size=steps + 1)
    env.step(int(actions[0]))
    warm = time.perf_counter() - STARTED
    started = time.perf_counter()
    for action in actions[1:]:
        _, _, terminated, truncated, _ = env.step(int(action))
        if terminated or truncated:
            env.reset()
    wall = time.perf_counter() - started
    env.close()
    return steps / wall, warm, "env steps / s"


def lane_keeping(steps: int, seed: int, cars: int | None = None) -> tuple[float, float, str]:
    """Simulated s per wall s of the lane-keeping driver, 5 frames per step; ``cars``
    traffic cars (spread over 3 km above 50), or the default 12."""
    import gymnasium as gym

    try:
        from sdc_agents.lane_keeping import LaneKeepingDriver
    except ModuleNotFoundError:  # a reference tree from before issue 23's names
        from agents.lane_keeping import LaneKeepingDriver  # the old import name

    config = {"steps_per_action": 5, "terminate_on_collision": False, "laps": 100}
    if cars is not None:
        config["traffic"] = {"car_count": cars, "spawn_range": 200.0 if cars <= 50 else 3000.0}
    env = gym.make("sdc_gym/HighwayLoop-v0", config=config)
    driver = LaneKeepingDriver(env.unwrapped.road)
    observation, _ = env.reset(seed=seed)
    driver.reset()
    observation, *_ = env.step(driver.act(observation))
    warm = time.perf_counter() - STARTED
    started = time.perf_counter()
    for _ in range(steps):
        observation, _, terminated, truncated, _ = env.step(driver.act(observation))
        if terminated or truncated:
            observation, _ = env.reset()
            driver.reset()
    wall = time.perf_counter() - started
    env.close()
    return steps * 5 * 0.02 / wall, warm, "simulated s / wall s"


def fsm_lap(laps: int, seed: int) -> tuple[float, float, str]:
    """Wall s per lap of the bold FSM at 3 frames per step (mean over ``laps`` seeds)."""
    import gymnasium as gym

    try:
        from sdc_agents.registry import make_agent
    except ModuleNotFoundError:  # a reference tree from before issue 23's names
        from agents.registry import make_agent  # the old import name

    warm = 0.0
    total = 0.0
    for lap in range(laps + 1):  # lap 0 warms the kernels up and is not timed
        env = gym.make("sdc_gym/HighwayLoop-v0", config={"steps_per_action": 3})
        agent = make_agent("fsm_bold", env)
        agent.reset()
        observation, _ = env.reset(seed=seed + lap)
        started = time.perf_counter()
        while True:
            observation, _, terminated, truncated, _ = env.step(agent.act(observation))
            if not lap and not warm:
                warm = time.perf_counter() - STARTED
            if terminated or truncated:
                break
        if lap:
            total += time.perf_counter() - started
        env.close()
    return total / laps, warm, "wall s / lap"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("task", choices=TASKS)
    parser.add_argument("--size", type=int, default=None,
                        help="steps (behavior, lane_keeping) or laps (fsm_lap) timed")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--root", default=None, help="code tree put first on sys.path")
    args = parser.parse_args()
    if args.root:
        sys.path.insert(0, args.root)
    import warnings

    warnings.filterwarnings("ignore")
    import sdc_gym  # noqa: F401  (registers the ids)

    default = {"behavior": 3000, "lane_keeping": 3000, "fsm_lap": 1}[args.task]
    size = args.size if args.size is not None else default
    if size < 1:
        parser.error(f"--size must be >= 1; got {size}")
    rate, warm, unit = {"behavior": behavior, "lane_keeping": lane_keeping,
                        "fsm_lap": fsm_lap}[args.task](size, args.seed)
    print(json.dumps({"task": args.task, "rate": rate, "unit": unit, "warm_s": warm}))


if __name__ == "__main__":
    main()
