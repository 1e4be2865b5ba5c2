"""The committed light classifiers in closed loop: laps, and every frame checked.

    python benchmarks/study_light_sources.py                       # seeds 0-9, cnn and crop
    python benchmarks/study_light_sources.py --seeds 0 1 --sources crop --workers 2

Each row drives one lap per seed of ``configs/track_loop.yaml`` (the default track, the
200 x 150 camera, ground-truth light states in the observation too) with the reference
stack reading its lights from a classifier (``cnn``: the whole-image CNN, ``crop``: the crop
of the projected light box; ``agents/track/light_classifier.py``) and compares every frame
the detector classified with the truth: the light of the next stop line as the stack sees
it (RED and YELLOW as themselves, GREEN and no light as UNKNOWN, the classifiers' three
classes). Printed: laps and lap time, red-light violations, frames classified, and misreads
by kind (a red or yellow light read as something else; a green or no light read as red or
yellow).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sdc_gym  # noqa: E402,F401  (registers the env ids)
from sdc_agents.track.dbw_agent import dbw_agent, light_source_for  # noqa: E402
from sdc_gym.lights.traffic_lights import RED, UNKNOWN, YELLOW  # noqa: E402
from tests.planners.capstone_twist_controllers import drive_episode  # noqa: E402

CONFIG = ROOT / "configs" / "track_loop.yaml"


class CheckedSource:
    """A light source that also compares each answer with the observation's truth."""

    def __init__(self, source: Any) -> None:
        self.source = source
        self.misreads: Counter[str] = Counter()
        self.frames = 0

    def classify(self, observation: Mapping[str, Any]) -> int:
        state = int(self.source.classify(observation))
        line = round(float(observation["next_stop_line"][0]))
        truth = int(observation["light_states"][line]) if line >= 0 else UNKNOWN
        truth = truth if truth in (RED, YELLOW) else UNKNOWN
        self.frames += 1
        if state != truth:
            kind = "red/yellow missed" if truth in (RED, YELLOW) else "false red/yellow"
            self.misreads[kind] += 1
        return state


def run(job: tuple[str, int]) -> dict:
    import torch  # the classifiers' library; one thread per worker (the workers fill the cores)

    torch.set_num_threads(1)
    name, seed = job
    spec = yaml.safe_load(CONFIG.read_text())
    env = gym.make(spec["env"], config=spec["config"])
    source = CheckedSource(light_source_for(env, name))
    info = drive_episode(env, dbw_agent(env, source, name=f"dbw_{name}"), seed)
    env.close()
    summary = info["summary"]
    return {"laps": summary["lap_times"], "red": summary["red_light_violations"],
            "frames": source.frames, "misreads": dict(source.misreads)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(10)))
    parser.add_argument("--sources", nargs="+", choices=("cnn", "crop"),
                        default=["cnn", "crop"])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [(name, seed) for name in args.sources for seed in args.seeds]
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(run, jobs))
    print(f"configs/track_loop.yaml, seeds {args.seeds}, one lap each")
    print(f"{'source':6s} {'laps':>4s} {'lap s':>6s} {'red viol.':>9s} {'frames':>7s} "
          f"{'misreads':>30s}")
    for name in args.sources:
        rows = [r for (n, _), r in zip(jobs, results, strict=True) if n == name]
        laps = [t for r in rows for t in r["laps"]]
        misreads: Counter[str] = Counter()
        for r in rows:
            misreads.update(r["misreads"])
        text = ", ".join(f"{k} {v}" for k, v in sorted(misreads.items())) or "none"
        lap = f"{np.mean(laps):.1f}" if laps else "-"
        print(f"{name:6s} {len(laps):4d} {lap:>6s} {sum(r['red'] for r in rows):9d} "
              f"{sum(r['frames'] for r in rows):7d} {text:>30s}")


if __name__ == "__main__":
    main()
