"""Wall time of one full lap with the FSM planning at every env step, split planner / env.

    python benchmarks/bench_fsm_lap.py [--seeds 3] [--frames 3 5]

For each style and env step size (physics frames per step), drives one lap of the default
highway at default traffic and reports the wall time, how it splits between the planner
(perception + behavior + motion) and the simulation (env.step), and the speedup against
the original simulator, which runs at 1 x real time (a lap is the simulated lap time).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym

import sdc_gym  # noqa: F401
from sdc_agents.registry import make_agent


def lap(agent_name: str, frames: int, seed: int) -> tuple[float, float, float, bool]:
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"steps_per_action": frames})
    agent = make_agent(agent_name, env)
    agent.reset()
    observation, _ = env.reset(seed=seed)
    planner = simulator = 0.0
    while True:
        started = time.perf_counter()
        path = agent.act(observation)
        middle = time.perf_counter()
        observation, _, terminated, truncated, info = env.step(path)
        simulator += time.perf_counter() - middle
        planner += middle - started
        if terminated or truncated:
            break
    env.close()
    summary = info["summary"]
    clean = summary["incident_total"] == 0 and summary["laps"] == 1
    return planner, simulator, summary["time"], clean


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--frames", type=int, nargs="+", default=[3, 5])
    args = parser.parse_args()
    print(f"{'agent':18} {'frames/step':>11} {'wall s':>7} {'planner s':>9} {'env s':>6} "
          f"{'sim lap s':>9} {'x real time':>11} {'clean laps':>10}")
    for name in ("fsm_conservative", "fsm_bold"):
        for frames in args.frames:
            runs = [lap(name, frames, seed) for seed in range(args.seeds)]
            planner = sum(r[0] for r in runs) / len(runs)
            simulator = sum(r[1] for r in runs) / len(runs)
            simulated = sum(r[2] for r in runs) / len(runs)
            clean = sum(r[3] for r in runs)
            wall = planner + simulator
            print(f"{name:18} {frames:>11} {wall:>7.2f} {planner:>9.2f} {simulator:>6.2f} "
                  f"{simulated:>9.1f} {simulated / wall:>11.0f} {clean:>7}/{len(runs)}")


if __name__ == "__main__":
    main()
