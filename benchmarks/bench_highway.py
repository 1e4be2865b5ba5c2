"""Simulated seconds per wall second: sdc-gym's highway loop against highway-env, one run.

    python benchmarks/bench_highway.py [--seconds 60] [--repeats 3]

sdc-gym: ``sdc_gym/HighwayLoop-v0`` driven by the lane-keeping driver (agent time
included), one env step = 1 and = 5 physics frames of 0.02 s, at 12 and 50 traffic cars.
highway-env: ``highway-v0`` (15 Hz simulation, 1 Hz policy) and ``highway-fast-v0`` (5 Hz
simulation) with the IDLE meta-action, at the same car counts, rendering off. Each
configuration runs ``--seconds`` simulated seconds (episodes restarted as they end, resets
not timed); the best of ``--repeats`` runs is reported, and the ratio of sdc-gym to
highway-v0 at the same car count is printed.
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym

import sdc_gym  # noqa: F401
from sdc_agents.lane_keeping import LaneKeepingDriver


def time_sdc_gym(cars: int, frames: int, seconds: float, seed: int = 0) -> float:
    env = gym.make("sdc_gym/HighwayLoop-v0", config={
        "steps_per_action": frames, "traffic": {"car_count": cars},
        "terminate_on_collision": False, "laps": 100})
    driver = LaneKeepingDriver(env.unwrapped.road)
    observation, _ = env.reset(seed=seed)
    driver.reset()
    steps = round(seconds / (0.02 * frames))
    started = time.perf_counter()
    for _ in range(steps):
        observation, _, terminated, truncated, _ = env.step(driver.act(observation))
        if terminated or truncated:  # not expected within the budget; keep timing honest
            observation, _ = env.reset()
            driver.reset()
    wall = time.perf_counter() - started
    env.close()
    return steps * 0.02 * frames / wall


def time_highway_env(env_id: str, cars: int, seconds: float, seed: int = 0) -> float:
    import highway_env  # noqa: F401

    env = gym.make(env_id, config={"vehicles_count": cars})
    env.reset(seed=seed)
    policy_period = 1.0 / env.unwrapped.config["policy_frequency"]
    steps = round(seconds / policy_period)
    wall = 0.0
    for _ in range(steps):
        started = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(1)  # IDLE
        wall += time.perf_counter() - started
        if terminated or truncated:
            env.reset()
    env.close()
    return steps * policy_period / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated s per run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    rows = []
    peer: dict[int, float] = {}
    for cars in (12, 50):
        for env_id in ("highway-v0", "highway-fast-v0"):
            rate = max(time_highway_env(env_id, cars, args.seconds, seed)
                       for seed in range(args.repeats))
            rows.append((f"highway-env {env_id}", cars, "-", rate))
            if env_id == "highway-v0":
                peer[cars] = rate
        for frames in (1, 5):
            rate = max(time_sdc_gym(cars, frames, args.seconds, seed)
                       for seed in range(args.repeats))
            rows.append(("sdc-gym HighwayLoop-v0 + lane keeping", cars, frames, rate))
    print(f"{'environment':40} {'cars':>4} {'frames/step':>11} {'sim s / wall s':>15} "
          f"{'x highway-v0':>13}")
    for name, cars, frames, rate in rows:
        print(f"{name:40} {cars:>4} {frames!s:>11} {rate:>15.1f} {rate / peer[cars]:>13.1f}")


if __name__ == "__main__":
    main()
