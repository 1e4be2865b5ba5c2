"""What a hostile file can cost at most: the time and peak memory of the worst cases each
bound admits (docs/guarantees.md records the figures).

    .venv/bin/python benchmarks/hostile_costs.py

Cases: a 10^9-leaf alias bomb (refused), a flat list at the node bound (the most nodes per
byte), a 256 KiB flat list (refused at the node bound), aliases past the expansion bound,
and the largest map file (2 MiB of a circle's rows, 72,000 points).
"""

from __future__ import annotations

import math
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


def main() -> None:
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
