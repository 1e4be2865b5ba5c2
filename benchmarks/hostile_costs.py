"""What a hostile file can cost at most: the time and peak memory of the worst cases each
bound admits (docs/guarantees.md records the figures).

    .venv/bin/python benchmarks/hostile_costs.py

    .venv/bin/python benchmarks/hostile_costs.py --batches   # the batch bounds only

Cases: a 10^9-leaf alias bomb (refused), a flat list at the node bound (the most nodes per
byte), a 256 KiB flat list (refused at the node bound), aliases past the expansion bound,
and the largest map file (2 MiB of a circle's rows, 72,000 points). With ``--batches``,
the largest batches each product bound of ``sdc_gym.validation.bounds`` admits, each in a
process of its own (its peak resident memory, the time to make it, reset it and step it).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sdc_gym.road.track_map import load_track
from sdc_gym.validation.text_files import MAX_TEXT_BYTES
from sdc_gym.validation.yaml_files import MAX_YAML_BYTES, MAX_YAML_NODES, parse_yaml_lines


def measured(name: str, work: Any) -> None:
    start = time.perf_counter()
    try:
        work()
        outcome = "read"
    except (yaml.YAMLError, ValueError) as error:
        outcome = f"refused ({str(error)[:60]}...)"
    seconds = time.perf_counter() - start  # untraced: tracemalloc slows PyYAML 10x
    tracemalloc.start()
    try:
        work()
    except (yaml.YAMLError, ValueError):
        pass
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    print(f"{name:48s} {seconds:7.2f} s  {peak / 1e6:8.1f} MB peak  {outcome}")


def alias_bomb() -> str:
    names = "abcdefghi"
    lines = ["a: &a [" + ", ".join(["x"] * 10) + "]"]
    lines += [f"{names[i]}: &{names[i]} [" + ", ".join([f"*{names[i - 1]}"] * 10) + "]"
              for i in range(1, 9)]
    return "\n".join(lines) + "\n"


BATCH_RUN = """
import json, resource, sys, time
import numpy as np, gymnasium as gym, sdc_gym
env_id, envs, config, steps = json.loads(sys.argv[1])
start = time.perf_counter()
batch = gym.make_vec(env_id, num_envs=envs, vectorization_mode="vector_entry_point",
                     config=config)
made = time.perf_counter()
batch.reset(seed=0)
reset = time.perf_counter()
action = np.zeros(batch.action_space.shape, dtype=batch.action_space.dtype)
for _ in range(steps):
    batch.step(action)
stepped = time.perf_counter()
print(json.dumps([made - start, reset - made, (stepped - reset) / steps,
                  resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024]))
"""
"""One batch made, reset and stepped, in a fresh process (its peak RSS is the batch's)."""

BATCHES = [
    ("num_envs x path_points: 4,096 x 1,024", "sdc_gym/HighwayLoop-v0", 4096,
     {"path_points": 1024}),
    ("num_envs x car_count: 4,096 x 64", "sdc_gym/HighwayLoop-v0", 4096,
     {"traffic": {"car_count": 64, "spawn_range": 1000.0}}),
    ("num_envs x steps_per_action: 4,096 x 256, 16 cars (car updates 1.7e7)",
     "sdc_gym/HighwayLoop-v0", 4096, {"steps_per_action": 256, "traffic": {"car_count": 16}}),
    ("num_envs x decision frames: 4,096 x 256 (TrackLoopBehavior, 5.12 s)",
     "sdc_gym/TrackLoopBehavior-v0", 4096, {"decision_period_s": 5.12}),
    ("num_envs x camera pixels: 4 x 3,840 x 2,160", "sdc_gym/TrackLoop-v0", 4,
     {"camera": {"enabled": True, "width": 3840, "height": 2160}}),
    ("num_envs x camera pixels: 69 x 800 x 600", "sdc_gym/TrackLoop-v0", 69,
     {"camera": {"enabled": True}}),
]
"""The largest batch each product bound admits (the others at their defaults)."""


def batch_costs(steps: int = 2, only: str | None = None) -> None:
    print(f"{'batch at its bound':72s} {'make':>7s} {'reset':>7s} {'step':>7s} {'peak RSS':>9s}")
    for name, env_id, envs, config in BATCHES:
        if only is not None and only not in name:
            continue
        done = subprocess.run([sys.executable, "-c", BATCH_RUN,
                               json.dumps([env_id, envs, config, steps])],
                              capture_output=True, text=True, check=True)
        made, reset, step, rss = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"{name:72s} {made:6.1f}s {reset:6.1f}s {step:6.2f}s {rss:6.0f} MB", flush=True)


def main() -> None:
    if "--batches" in sys.argv[1:]:  # --batches [TEXT]: the batches whose name has TEXT
        rest = sys.argv[sys.argv.index("--batches") + 1:]
        batch_costs(only=rest[0] if rest else None)
        return
    measured("alias bomb, 10^9 leaves (413 bytes)", lambda: parse_yaml_lines(alias_bomb()))
    flat = "[" + "1," * (MAX_YAML_NODES - 2) + "1]"
    measured(f"flat list at the node bound, {len(flat):,} bytes",
             lambda: parse_yaml_lines(flat))
    over = "[" + "1," * ((MAX_YAML_BYTES - 2) // 2 - 1) + "1]"
    measured(f"flat list at the size bound, {len(over):,} bytes",
             lambda: parse_yaml_lines(over))
    aliased = "a: &a [" + ", ".join(["x"] * 999) + "]\nb: [" + ", ".join(["*a"] * 199) + "]\n"
    measured("199 aliases of a 1,000-node list", lambda: parse_yaml_lines(aliased))
    count = MAX_TEXT_BYTES // 29
    t = np.linspace(0.0, 2 * math.pi, count, endpoint=False)
    xy = 2000.0 * np.column_stack([np.cos(t), np.sin(t)]) + 3000.0
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "track.csv"
        path.write_text("".join(f"{x:.6f},{y:.6f},0,0\n" for x, y in xy))
        measured(f"track file, {path.stat().st_size:,} bytes ({count:,} rows)",
                 lambda: load_track(path))


if __name__ == "__main__":
    main()
