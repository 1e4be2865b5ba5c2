"""How a behavior policy transfers to highway-env: crash rate next to its default agents.

    python benchmarks/transfer_highway_env.py [--policy dqn:agents/highway/policies/dqn_highway.zip]
        [--episodes 20] [--output transfer.json] [--target-speeds 20,25,30]

Runs ``--episodes`` episodes (seeds 0..N-1, the same for every agent) of highway-env's
``highway-fast-v0`` with ``lanes_count: 3`` (our policies see 3 lanes) and otherwise its
defaults (20 cars, 5 Hz simulation, one meta-action per second, 30 s episodes), for:

* the policy (``--policy kind:path``; default the committed DQN policy when the file
  exists), through :mod:`sdc_agents.highway_env_adapter` (our world model, features, decision
  executor and safety shield; decisions mapped onto highway-env's meta-actions);
* highway-env's default agents: always ``IDLE`` (the action its docs and benchmarks use by
  default) and uniformly random meta-actions (seeded per episode);
* a reference: always ``SLOWER``, which holds its lowest set-point (20 m/s by default),
  the speed our cruise decision rounds to: whatever the policy beats beyond this row is
  lane choice and timing, not just driving slowly.

Columns: crash rate (% of episodes ending with ``info["crashed"]``), mean episode length
(steps; 30 is the full episode), mean speed (m/s, the mean of ``info["speed"]`` over an
episode's steps, averaged over episodes), lane changes per episode (changes of the lane
highway-env steers to, so a refused or no-op LANE_LEFT at the edge does not count), the
agent's decision time (ms per step) and wall time. Also printed: highway-fast-v0's own env
steps per second in this run (time inside ``env.step`` only, every agent's steps), the
figure behind the issue's "60 to 75 PPO samples/s on highway-fast-v0".
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from sdc_agents.highway_env_adapter import (
    IDLE,
    META_ACTION_NAMES,
    SLOWER,
    highway_env_policy_agent,
)
from sdc_agents.policy_agent import POLICY_KINDS
from sdc_evaluation.files import atomic_write_text

ENV_ID = "highway-fast-v0"
LANES = 3
DEFAULT_POLICY = Path("agents/highway/policies/dqn_highway.zip")

Chooser = Callable[[Any], int]
"""Given the env (after reset / the last step), the meta-action to take."""


def make_env(target_speeds: list[float] | None) -> gym.Env:
    import highway_env  # noqa: F401  (registers highway-fast-v0)

    config: dict[str, Any] = {"lanes_count": LANES}
    if target_speeds is not None:
        config["action"] = {"type": "DiscreteMetaAction", "target_speeds": target_speeds}
    return gym.make(ENV_ID, config=config)


def run_episode(env: gym.Env, choose: Chooser, seed: int) -> dict[str, Any]:
    """One episode from ``seed``; what the table is made of."""
    env.reset(seed=seed)
    vehicle = env.unwrapped.vehicle
    speeds: list[float] = []
    lane_changes = 0
    env_time = agent_time = 0.0
    crashed = False
    while True:
        steering = vehicle.target_lane_index[2]
        started = time.perf_counter()
        action = choose(env)
        agent_time += time.perf_counter() - started
        started = time.perf_counter()
        _, _, terminated, truncated, info = env.step(action)
        env_time += time.perf_counter() - started
        lane_changes += int(vehicle.target_lane_index[2] != steering)
        speeds.append(float(info["speed"]))
        crashed = bool(info["crashed"])
        if terminated or truncated:
            break
    return {"seed": seed, "crashed": crashed, "steps": len(speeds),
            "mean_speed": float(np.mean(speeds)), "lane_changes": lane_changes,
            "env_time": env_time, "agent_time": agent_time}


def run_agent(name: str, make_chooser: Callable[[int], Chooser], env: gym.Env,
              seeds: list[int]) -> dict[str, Any]:
    """Every seed with a fresh chooser per episode; one table row."""
    started = time.perf_counter()
    episodes = [run_episode(env, make_chooser(seed), seed) for seed in seeds]
    steps = sum(episode["steps"] for episode in episodes)
    env_time = sum(episode["env_time"] for episode in episodes)
    return {
        "agent": name,
        "episodes": len(episodes),
        "crash_rate_pct": 100.0 * float(np.mean([e["crashed"] for e in episodes])),
        "mean_steps": float(np.mean([e["steps"] for e in episodes])),
        "mean_speed_mps": float(np.mean([e["mean_speed"] for e in episodes])),
        "lane_changes_per_episode": float(np.mean([e["lane_changes"] for e in episodes])),
        "agent_ms_per_step": 1000.0 * sum(e["agent_time"] for e in episodes) / steps,
        "env_steps": steps,
        "env_time_s": env_time,
        "wall_time_s": time.perf_counter() - started,
        "per_episode": episodes,
    }


def parse_policy(spec: str) -> tuple[str, Path]:
    kind, sep, path = spec.partition(":")
    if not sep or kind not in POLICY_KINDS or not path:
        raise SystemExit(f"--policy must be <kind>:<path to model.zip> with kind one of "
                         f"{list(POLICY_KINDS)}, got {spec!r}")
    return kind, Path(path)


def parse_speeds(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        speeds = sorted(float(value) for value in text.split(","))
    except ValueError:
        raise SystemExit(f"--target-speeds must be comma-separated m/s, got {text!r}") from None
    if len(speeds) < 2 or speeds[0] < 0.0:
        raise SystemExit("--target-speeds needs at least two speeds >= 0 m/s")
    if not np.allclose(np.diff(speeds), speeds[1] - speeds[0]) or speeds[1] == speeds[0]:
        raise SystemExit("--target-speeds must be evenly spaced (highway-env's MDPVehicle "
                         f"rounds speeds on a uniform grid), got {speeds}")
    return speeds


def print_table(rows: list[dict[str, Any]], title: str) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    table.add_column("agent", no_wrap=True)
    for column in ("crash %", "steps", "m/s", "lane ch", "ms/step", "wall s"):
        table.add_column(column, justify="right", no_wrap=True)
    for row in rows:
        table.add_row(row["agent"], f"{row['crash_rate_pct']:.0f}", f"{row['mean_steps']:.1f}",
                      f"{row['mean_speed_mps']:.2f}", f"{row['lane_changes_per_episode']:.2f}",
                      f"{row['agent_ms_per_step']:.2f}", f"{row['wall_time_s']:.1f}")
    Console().print(table)
    print("crash %: episodes ending in a crash; steps: mean episode length (1 s each); m/s: "
          "mean speed; lane ch: lane changes per episode; ms/step: the agent's decision time")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default=None,
                        help=f"kind:path of the policy (default dqn:{DEFAULT_POLICY} when it "
                             "exists; without it only the default agents run)")
    parser.add_argument("--episodes", type=int, default=20, help="episodes (seeds 0..N-1)")
    parser.add_argument("--output", type=Path, default=None, help="write the results as JSON")
    parser.add_argument("--target-speeds", default=None,
                        help="highway-env's DiscreteMetaAction target speeds, comma-separated "
                             "m/s, evenly spaced (default its own: 20,25,30)")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        raise SystemExit("--episodes must be >= 1")
    warnings.filterwarnings("ignore")
    speeds = parse_speeds(args.target_speeds)
    spec = args.policy or (f"dqn:{DEFAULT_POLICY}" if DEFAULT_POLICY.is_file() else None)

    env = make_env(speeds)
    seeds = list(range(args.episodes))
    started = time.perf_counter()
    rows = []
    if spec is not None:
        kind, path = parse_policy(spec)
        agent = highway_env_policy_agent(kind, path, lane_count=LANES)

        def policy_chooser(_: int) -> Chooser:
            agent.reset()
            return agent.act

        rows.append(run_agent(agent.name, policy_chooser, env, seeds))
    else:
        print(f"no policy: {DEFAULT_POLICY} does not exist and --policy was not given")
    rows.append(run_agent("highway-env IDLE", lambda _: lambda _env: IDLE, env, seeds))

    def random_chooser(seed: int) -> Chooser:
        rng = np.random.default_rng(seed)
        return lambda _env: int(rng.integers(len(META_ACTION_NAMES)))

    rows.append(run_agent("highway-env random", random_chooser, env, seeds))
    rows.append(run_agent("always SLOWER", lambda _: lambda _env: SLOWER, env, seeds))
    wall = time.perf_counter() - started
    env_rate = sum(r["env_steps"] for r in rows) / sum(r["env_time_s"] for r in rows)
    target = env.unwrapped.action_type.target_speeds
    env.close()

    print_table(rows, f"{ENV_ID}, {LANES} lanes, {args.episodes} episodes (seeds 0.."
                      f"{args.episodes - 1}), target speeds {np.asarray(target).tolist()} m/s")
    print(f"{ENV_ID} env steps/s in this run: {env_rate:.1f} (time inside env.step; the "
          "issue quotes 60-75 PPO samples/s on it)")
    print(f"wall time: {wall:.1f} s")
    if args.output is not None:
        result = {"env_id": ENV_ID, "config": {"lanes_count": LANES,
                                              "target_speeds": np.asarray(target).tolist()},
                  "episodes": args.episodes, "seeds": seeds, "policy": spec,
                  "env_steps_per_s": env_rate, "wall_time_s": wall, "rows": rows,
                  "command": shlex.join([sys.executable, *sys.argv])}
        atomic_write_text(args.output, json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
