"""Throughput of the batched track envs against the single envs, before and now, in one run.

    python benchmarks/bench_track_batched.py [--before /work/ref_pre15 ...] [--steps 3000]
        [--envs 1 8 64 256] [--lap-seed 1] [--skip-compile]

Every measurement runs in a fresh subprocess (so that one cannot warm or slow another),
the ``--before`` tree's with that tree's own ``.venv`` (a checkout of the code before the
track batch, e.g. ``git worktree add /tmp/before <commit>`` with ``make test`` run once):

* ``TrackLoopBehavior-v0`` env steps/s with random discrete actions (one decision, 1 s,
  per step): the single env before and now, and the batch now
  (``gym.make_vec(..., vectorization_mode="vector_entry_point")``) at each E;
* ``TrackLoop-v0``, the single env: env steps/s under the small pure-pursuit driver of
  ``bench_track.py`` (driver time included), before and now;
* the reference stack (``dbw_ground_truth``: detector, waypoint updater, pure pursuit,
  twist controller) driving one lap of the default track (seed ``--lap-seed``): its wall
  time before and now, and that both drove the same lap (same steps and distance);
* the cost of compiling: a fresh process's first ``reset`` + ``step`` of both track envs
  with an empty numba cache (what a fresh CI clone pays once) and with the cache filled.

The machine's load is printed: other jobs skew absolute numbers; ratios measured side by
side in the same run stay meaningful.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BEHAVIOR = "sdc_gym/TrackLoopBehavior-v0"
TRACK = "sdc_gym/TrackLoop-v0"


# ---------------------------------------------------------------- measurements (in workers)
def behavior_single(steps: int, seed: int = 0) -> dict[str, Any]:
    import gymnasium as gym
    import numpy as np

    env = gym.make(BEHAVIOR)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = rng.integers(4, size=steps).tolist()
    env.step(0)  # warm-up: the compiled kernels load
    started = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return {"steps_per_s": steps / (time.perf_counter() - started)}


def behavior_batch(steps: int, envs: int, seed: int = 0) -> dict[str, Any]:
    import gymnasium as gym
    import numpy as np

    vector = gym.make_vec(BEHAVIOR, num_envs=envs, vectorization_mode="vector_entry_point")
    vector.reset(seed=seed)
    rng = np.random.default_rng(seed)
    batches = max(steps // envs, 3)
    actions = [rng.integers(4, size=envs) for _ in range(batches)]
    vector.step(actions[0])
    started = time.perf_counter()
    for action in actions:
        vector.step(action)
    return {"steps_per_s": batches * envs / (time.perf_counter() - started)}


def track_single(steps: int, seed: int = 0) -> dict[str, Any]:
    import gymnasium as gym
    from bench_track import PursuitController

    env = gym.make(TRACK)
    controller = PursuitController(env, 0.95 * env.unwrapped.speed_limit)
    obs, _ = env.reset(seed=seed)
    obs, *_ = env.step(controller.act(obs))
    started = time.perf_counter()
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(controller.act(obs))
        if terminated or truncated:
            obs, _ = env.reset()
    return {"steps_per_s": steps / (time.perf_counter() - started)}


def reference_lap(seed: int) -> dict[str, Any]:
    import gymnasium as gym

    try:
        from sdc_agents.registry import make_agent
    except ImportError:  # a reference tree from before issue 23's names (the installed
        # sdc_agents then maps to this checkout's agents/, which the old sdc_gym cannot serve)
        from agents.registry import make_agent  # the old import name

    env = gym.make(TRACK, config={"observe_light_states": True})
    agent = make_agent("dbw_ground_truth", env)
    obs, _ = env.reset(seed=seed)
    agent.reset()
    steps = 0
    started = time.perf_counter()
    while True:
        obs, _, terminated, truncated, info = env.step(agent.act(obs))
        steps += 1
        if terminated or truncated:
            break
    wall = time.perf_counter() - started
    summary = info["summary"]
    return {"wall_s": wall, "steps": steps, "reason": info["termination_reason"],
            "distance": summary.get("distance"), "laps": summary.get("laps")}


def first_step() -> dict[str, Any]:
    started = time.perf_counter()
    import gymnasium as gym

    import sdc_gym  # noqa: F401

    imported = time.perf_counter()
    for env_id in (TRACK, BEHAVIOR):
        env = gym.make(env_id)
        env.reset(seed=0)
        env.step(env.action_space.sample())
    return {"import_s": imported - started, "first_steps_s": time.perf_counter() - imported}


WORKERS = {"behavior_single": behavior_single, "behavior_batch": behavior_batch,
           "track_single": track_single, "reference_lap": reference_lap,
           "first_step": first_step}


# ---------------------------------------------------------------- the driver
def load() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def run_worker(tree: Path, name: str, env: dict[str, str] | None = None,
               **kwargs: Any) -> dict[str, Any]:
    """``name(**kwargs)`` in a fresh process of ``tree``'s venv, with ``tree`` importable."""
    python = tree / ".venv" / "bin" / "python"
    if not python.exists():  # a tree without its own venv (e.g. ``git archive``): ours
        python = ROOT / ".venv" / "bin" / "python"
    command = [str(python), str(Path(__file__).resolve()), "--worker", name,
               "--kwargs", json.dumps(kwargs), "--tree", str(tree)]
    done = subprocess.run(command, cwd=tree, capture_output=True, text=True, check=False,
                          env={**os.environ, "PYTHONPATH": str(tree), **(env or {})})
    if done.returncode:
        raise RuntimeError(f"{name} in {tree} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _ratios(rates: dict[str, float], label: str) -> str:
    """``label``'s rate as multiples of the others' (the trees measured so far)."""
    return "  ".join(f"{rates[label] / rate:6.2f} x {other}" for other, rate in rates.items()
                     if other != label)


def commit_of(tree: Path) -> str:
    done = subprocess.run(["git", "-C", str(tree), "log", "-1", "--format=%h %s"],
                          capture_output=True, text=True, check=False)
    return done.stdout.strip()[:70] or "?"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--before", type=Path, nargs="*", default=[Path("/work/ref_pre15")],
                        help="checkouts of earlier code (each with its own .venv, or run "
                             "with this tree's), labelled by their folder names")
    parser.add_argument("--steps", type=int, default=3000,
                        help="TrackLoopBehavior-v0 env steps per measurement (single "
                             "envs: a tenth)")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 8, 64, 256])
    parser.add_argument("--lap-seed", type=int, default=1)
    parser.add_argument("--skip-compile", action="store_true")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--kwargs", default="{}", help=argparse.SUPPRESS)
    parser.add_argument("--tree", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        sys.path.insert(0, str(args.tree))  # that tree's sdc_gym and agents
        if args.worker != "first_step":
            import sdc_gym  # noqa: F401  (registers the ids)
        print(json.dumps(WORKERS[args.worker](**json.loads(args.kwargs))))
        return

    now = ROOT
    trees = [(tree.name, tree) for tree in args.before if (tree / "sdc_gym").is_dir()]
    trees.append(("now", now))
    for label, tree in trees:
        print(f"{label:6}: {tree} ({commit_of(tree)})")
    print(f"load average at start: {load()}\n")

    single_steps = max(args.steps // 10, 50)
    print(f"{BEHAVIOR}, random discrete actions (1 decision = 50 physics frames)")
    single: dict[str, float] = {}
    for label, tree in trees:
        single[label] = run_worker(tree, "behavior_single", steps=single_steps)["steps_per_s"]
        print(f"  single env, {label:14} {single[label]:9.1f} env steps/s   "
              f"{_ratios(single, label)}")
    for envs in args.envs:
        rate = run_worker(now, "behavior_batch", steps=args.steps, envs=envs)["steps_per_s"]
        print(f"  batch now, E = {envs:<10} {rate:9.1f} env steps/s   "
              f"{_ratios({**single, 'batch': rate}, 'batch')}")

    print(f"\n{TRACK}, single env with the pursuit driver of bench_track.py")
    track: dict[str, float] = {}
    for label, tree in trees:
        track[label] = run_worker(tree, "track_single", steps=args.steps)["steps_per_s"]
        print(f"  {label:26} {track[label]:9.0f} env steps/s   {_ratios(track, label)}")

    print(f"\nreference stack (dbw_ground_truth), one lap of the default track, seed "
          f"{args.lap_seed}")
    laps: dict[str, dict[str, Any]] = {}
    for label, tree in trees:
        laps[label] = lap = run_worker(tree, "reference_lap", seed=args.lap_seed)
        same = all(lap[key] == laps[trees[0][0]][key]
                   for key in ("steps", "distance", "laps", "reason"))
        rates = {name: 1.0 / result["wall_s"] for name, result in laps.items()}
        print(f"  {label:14} wall {lap['wall_s']:7.2f} s   {lap['steps']} steps "
              f"({lap['reason']}), {lap['distance']:.1f} m, laps {lap['laps']}, same lap as "
              f"{trees[0][0]}: {same}   speed {_ratios(rates, label)}")

    if not args.skip_compile:
        print("\nfirst reset + step of both track envs in a fresh process")
        with tempfile.TemporaryDirectory() as cache:
            for state in ("empty numba cache", "cache filled"):
                first = run_worker(now, "first_step", env={"NUMBA_CACHE_DIR": cache})
                print(f"  now, {state:18}  import {first['import_s']:5.2f} s, first steps "
                      f"{first['first_steps_s']:6.2f} s")
    print(f"\nload average at end: {load()}")


if __name__ == "__main__":
    main()
