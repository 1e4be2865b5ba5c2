"""What the first use of each env costs on a fresh clone: numba compiling its kernels.

    python benchmarks/cold_start.py [--rounds 3] [--steps 500] [--cases highway behavior ...]
        [--tree TREE] [--before TREE] [--profile] [--warm]

Every case runs in a fresh subprocess with ``NUMBA_CACHE_DIR`` set to an empty temporary
folder (so nothing is cached: what a fresh clone or CI pays), and with ``--warm`` once
more on the same, now filled, folder. The child times each phase (CPU = user + sys of the
process, and wall): ``import`` (gymnasium, numba, sdc_gym), ``make``, ``reset``, the
``first step``, then an ``episode`` of ``--steps`` more steps (resetting when one ends), so
that a kernel compiled mid-episode (car recycling, a second signature) shows as CPU there.
The parent adds the child's whole CPU from ``resource.getrusage(RUSAGE_CHILDREN)``.

The child also listens to numba's compile events (a cache hit emits none): how many of
this package's functions compiled in each phase, how many signatures each, and with
``--profile`` the kernels that cost the most CPU of their own (a kernel's compile time
less the time of the kernels it compiled on the way).

``--tree TREE`` measures another tree's sdc_gym as "now" (a snapshot, so that editing
this checkout during a run changes nothing); ``--before TREE`` runs the same cases from
another tree (e.g. ``git archive <commit> | tar -x -C /tmp/before``) with this venv, side
by side in each round, and prints the ratio.
Other jobs on the machine skew wall times; CPU seconds are steadier.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PHASES = ("import", "make", "reset", "first step", "episode")

# name: (env id, vector env size or 0 for gym.make, config)
CASES: dict[str, tuple[str, int, dict[str, Any]]] = {
    "highway": ("sdc_gym/HighwayLoop-v0", 0, {}),
    "behavior": ("sdc_gym/HighwayLoopBehavior-v0", 0, {}),
    "track": ("sdc_gym/TrackLoop-v0", 0, {}),
    "track_behavior": ("sdc_gym/TrackLoopBehavior-v0", 0, {}),
    "bosch": ("sdc_gym/HighwayLoop-v0", 0, {"config_file": "highway_bosch_challenge.yaml"}),
    "highway_vec": ("sdc_gym/HighwayLoop-v0", 4, {}),
    "behavior_vec": ("sdc_gym/HighwayLoopBehavior-v0", 4, {}),
    "track_vec": ("sdc_gym/TrackLoop-v0", 4, {}),
    "track_behavior_vec": ("sdc_gym/TrackLoopBehavior-v0", 4, {}),
}


# ------------------------------------------------------------------------ the child
def _listener() -> Any:
    """A :class:`_Compiles` (numba's ``event.Listener``, imported in the child only)."""
    from numba.core import event

    class Compiles(_Compiles, event.Listener):
        pass

    return Compiles()


class _Compiles:
    """numba's compile events of this package's functions, each with its CPU seconds
    (own: less the kernels compiled inside it) and the phase it happened in."""

    def __init__(self) -> None:
        self.phase = "import"
        self.stack: list[list[Any]] = []
        self.done: list[dict[str, Any]] = []

    def on_start(self, happening: Any) -> None:
        data = getattr(happening, "data", None) or {}
        dispatcher = data.get("dispatcher")
        function = getattr(dispatcher, "py_func", None)
        module = getattr(function, "__module__", "") or ""
        name = f"{module.removeprefix('sdc_gym.')}.{getattr(function, '__name__', '?')}"
        self.stack.append([name, time.process_time(), 0.0, module.startswith("sdc_gym"),
                           str(data.get("args", ""))])

    def on_end(self, happening: Any) -> None:
        name, started, inner, ours, args = self.stack.pop()
        total = time.process_time() - started
        if self.stack:
            self.stack[-1][2] += total
        if ours:
            self.done.append({"name": name, "own_s": total - inner, "total_s": total,
                              "top": not self.stack, "phase": self.phase, "args": args})


def _cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def child(case: str, steps: int) -> dict[str, Any]:
    """The phases of ``case`` in this (fresh) process; returns their CPU and wall."""
    env_id, num_envs, config = CASES[case]
    times: dict[str, dict[str, float]] = {}
    cpu, wall = _cpu(), time.perf_counter()

    def mark(phase: str, next_phase: str | None) -> None:
        nonlocal cpu, wall
        now_cpu, now_wall = _cpu(), time.perf_counter()
        times[phase] = {"cpu": now_cpu - cpu, "wall": now_wall - wall}
        cpu, wall = now_cpu, now_wall
        if next_phase:
            compiles.phase = next_phase

    from numba.core import event

    compiles = _listener()
    event.register("numba:compile", compiles)
    import gymnasium as gym
    import numpy as np

    import sdc_gym  # noqa: F401  (registers the ids)

    if "config_file" in config:
        import yaml

        config = yaml.safe_load((ROOT / "configs" / config["config_file"]).read_text())["config"]
        # The preset's map is relative to the checkout's root (../shared/...): this one's.
        config["map"] = str((ROOT / config["map"]).resolve())
    mark("import", "make")
    if num_envs:
        env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                           config=config)
    else:
        env = gym.make(env_id, config=config)
    mark("make", "reset")
    env.reset(seed=0)
    env.action_space.seed(0)
    mark("reset", "first step")
    env.step(env.action_space.sample())
    mark("first step", "episode")
    resets = 0
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if not num_envs and (terminated or truncated):
            env.reset()
            resets += 1
        elif num_envs:
            resets += int(np.count_nonzero(np.logical_or(terminated, truncated)))
    mark("episode", None)
    event.unregister("numba:compile", compiles)
    return {"times": times, "compiles": compiles.done, "resets": resets}


# ------------------------------------------------------------------------ the parent
def run_child(tree: Path, case: str, steps: int, cache: str) -> dict[str, Any]:
    """``child(case)`` in a fresh interpreter importing ``tree``'s sdc_gym."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--child", case, "--steps", str(steps)],
        cwd=tree, capture_output=True, text=True, check=False,
        env={**os.environ, "PYTHONPATH": str(tree), "NUMBA_CACHE_DIR": cache})
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise RuntimeError(f"{case} in {tree} failed:\n{done.stderr[-3000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["process_cpu"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    result["process_wall"] = time.perf_counter() - started
    return result


def spread(values: list[float]) -> str:
    """min / median / max, one decimal."""
    if len(values) == 1:
        return f"{values[0]:.1f}"
    return f"{min(values):.1f} / {statistics.median(values):.1f} / {max(values):.1f}"


def summary(results: list[dict[str, Any]], steps: int) -> list[str]:
    """The table cells of one case in one tree and cache state, over the rounds."""
    cells = []
    for phase in ("import", "make", "reset", "first step"):
        cells.append(spread([r["times"][phase]["cpu"] for r in results]))
    cells.append(spread([sum(r["times"][p]["cpu"] for p in PHASES[1:4]) for r in results]))
    cells.append(spread([r["times"]["episode"]["cpu"] for r in results]))
    cells.append(spread([r["process_cpu"] for r in results]))
    cells.append(spread([r["process_wall"] for r in results]))
    counts = [sum(1 for c in r["compiles"] if c["top"]) for r in results]
    mid = [sum(1 for c in r["compiles"] if c["top"] and c["phase"] == "episode")
           for r in results]
    cells.append(f"{max(counts)}")
    cells.append(f"{max(mid)}")
    return cells


HEADER = ("case", "tree", "cache", "import", "make", "reset", "1st step", "make..1st step",
          "episode", "process CPU", "process wall", "compiles", "mid-episode")


def print_table(rows: list[list[str]]) -> None:
    widths = [max(len(str(row[i])) for row in [list(HEADER), *rows]) for i in range(len(HEADER))]
    for row in [list(HEADER), ["-" * w for w in widths], *rows]:
        print("  ".join(str(cell).ljust(width) for cell, width in zip(row, widths, strict=True)))


def print_profile(case: str, tree: str, results: list[dict[str, Any]]) -> None:
    """Per kernel: signatures compiled and own CPU (median over rounds), costliest first."""
    own: dict[str, list[float]] = {}
    signatures: dict[str, set[str]] = {}
    phases: dict[str, set[str]] = {}
    for r in results:
        per_round: dict[str, float] = {}
        for c in r["compiles"]:
            per_round[c["name"]] = per_round.get(c["name"], 0.0) + c["own_s"]
            signatures.setdefault(c["name"], set()).add(c["args"])
            phases.setdefault(c["name"], set()).add(c["phase"])
        for name, seconds in per_round.items():
            own.setdefault(name, []).append(seconds)
    total = sum(statistics.median(v) for v in own.values())
    print(f"\n{case} ({tree}): {len(own)} functions compiled, {total:.1f} s CPU of their own")
    ranked = sorted(own.items(), key=lambda item: -statistics.median(item[1]))
    for name, seconds in ranked[:25]:
        print(f"  {statistics.median(seconds):6.2f} s  {len(signatures[name])} sig  "
              f"{','.join(sorted(phases[name])):18}  {name}")
    multi = [name for name, sigs in signatures.items() if len(sigs) > 1]
    for name in multi:
        print(f"  {name}: {len(signatures[name])} signatures:")
        for sig in sorted(signatures[name]):
            print(f"      {sig[:300]}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    parser.add_argument("--tree", type=Path, default=ROOT,
                        help="the tree measured as 'now' (default: this checkout)")
    parser.add_argument("--before", type=Path, default=None,
                        help="another tree to run side by side (its sdc_gym, this venv)")
    parser.add_argument("--warm", action="store_true",
                        help="also each case on the cache its cold run filled")
    parser.add_argument("--profile", action="store_true",
                        help="per kernel: signatures and own compile CPU")
    parser.add_argument("--child", choices=list(CASES), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args.child, args.steps)))
        return
    trees = {"now": args.tree.resolve()}
    if args.before:
        trees["before"] = args.before.resolve()
    print(f"cold start, {args.rounds} round(s), {args.steps}-step episode part, load "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}; CPU seconds (user + sys) "
          f"min / median / max")
    results: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for _ in range(args.rounds):
        for case in args.cases:
            for tree_name, tree in trees.items():
                with tempfile.TemporaryDirectory(prefix="numba-cold-") as cache:
                    states = ("cold", "warm") if args.warm else ("cold",)
                    for state in states:
                        result = run_child(tree, case, args.steps, cache)
                        results.setdefault((case, tree_name, state), []).append(result)
                        first = sum(result["times"][p]["cpu"] for p in PHASES[1:4])
                        mid = sum(1 for c in result["compiles"]
                                  if c["top"] and c["phase"] == "episode")
                        print(f"  {case:20} {tree_name:6} {state}: "
                              f"{result['process_cpu']:5.1f} s CPU, "
                              f"{result['process_wall']:5.1f} s wall, make..first step "
                              f"{first:5.1f} s CPU, {mid} compiled mid-episode", flush=True)
    rows = [[case, tree, state, *summary(found, args.steps)]
            for (case, tree, state), found in results.items()]
    print()
    print_table(rows)
    if args.before:
        print("\nCPU of make..first step, now / before (median):")
        for case in args.cases:
            now = statistics.median(sum(r["times"][p]["cpu"] for p in PHASES[1:4])
                                    for r in results[(case, "now", "cold")])
            old = statistics.median(sum(r["times"][p]["cpu"] for p in PHASES[1:4])
                                    for r in results[(case, "before", "cold")])
            print(f"  {case:20} {now:5.1f} s / {old:5.1f} s = {now / old:.2f}")
    if args.profile:
        for (case, tree, state), found in results.items():
            if state == "cold":
                print_profile(case, tree, found)
    print(f"\nload average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
