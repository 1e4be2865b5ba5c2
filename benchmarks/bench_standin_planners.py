"""The stand-ins for the public planners on the original map, through the socket.

    python benchmarks/bench_standin_planners.py [--seeds 0 1 ... 9] [--laps 1]
        [--workers 2] [--telemetry-laps 10]

Each stand-in (``tests/planners/walkthrough_planner.py``: the course walkthrough's pattern;
``tests/planners/frenet_planner.py``: its own map-file s and quintic paths) runs as its own
process in a folder laid out like a planner's checkout (``build/`` runs it, it reads
``../data/highway_map.csv``), driven by ``evaluate.py``'s episode runner as
``external:COMMAND`` with the original's lock-step (3 frames per exchange) and its rules
(a collision is counted and the car drives on). Printed per planner: laps, lap time,
mean mph, incidents by kind over all seeds, max acceleration and jerk, and the wall time
per exchange (``wait``: telemetry sent to reply read, the planner's thinking plus the
socket; ``step``: the whole episode's wall time per exchange, env included).

``--telemetry-laps N`` then drives the walkthrough for N laps in this process on the
encoded telemetry text (seed 0) and prints the range of every s the telemetry carried
(ego, end of path, sensor fusion) and the sensor fusion ids seen.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401  (registers the ids)
from sdc_agents.external import external_env_config
from sdc_evaluation.episodes import EpisodeSpec
from sdc_evaluation.runner import run_episodes
from sdc_gym.bridge import encode_telemetry, lockstep_config

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.planners.map_helpers import MapFile  # noqa: E402
from tests.planners.walkthrough_planner import Walkthrough  # noqa: E402

MAP = ROOT.parent / "shared" / "data" / "udacity" / "path_planning" / "highway_map.csv"
HIGHWAY = "sdc_gym/HighwayLoop-v0"
PLANNERS = {"walkthrough": "walkthrough_planner.py", "frenet": "frenet_planner.py"}
FRAMES_PER_EXCHANGE = 3
SECONDS_PER_LAP = 420.0
MPS_PER_MPH = 0.44704


def specs(planner: str, seeds: list[int], laps: int, folder: Path) -> list[EpisodeSpec]:
    build = folder / planner / "build"
    build.mkdir(parents=True)
    command = shlex.join([sys.executable, str(ROOT / "tests" / "planners" / PLANNERS[planner]),
                          "--port", "{port}", "--map", "../data/highway_map.csv"])
    config = external_env_config({"map": str(MAP), "laps": laps,
                                  "max_duration": SECONDS_PER_LAP * laps,
                                  **lockstep_config(FRAMES_PER_EXCHANGE)})
    return [EpisodeSpec(f"external:{command}", HIGHWAY, seed, config, trace_points=0,
                        incident_history=0.0,
                        agent_options={"external": {
                            "cwd": str(build), "map_export": "../data/highway_map.csv",
                            "log_path": str(folder / planner / f"seed{seed}.log")}})
            for seed in seeds]


def table(planner: str, results: list[dict[str, Any]]) -> dict[str, Any]:
    incidents: Counter[str] = Counter()
    for result in results:
        incidents.update({kind: count for kind, count in result["incidents"].items() if count})
    lap_times = [t for result in results for t in result["lap_times"]]
    distance = sum(result["distance"] for result in results)
    sim_time = sum(result["time"] for result in results)
    exchanges = sum(result.get("planner_exchanges", 0) for result in results)
    return {
        "planner": planner,
        "episodes": len(results),
        "laps": sum(result["laps"] for result in results),
        "ended": dict(Counter(result["termination_reason"] for result in results)),
        "mean_lap_s": float(np.mean(lap_times)) if lap_times else float("nan"),
        "best_lap_s": float(np.min(lap_times)) if lap_times else float("nan"),
        "mean_mph": distance / sim_time / MPS_PER_MPH,
        "incidents": dict(incidents),
        "max_acceleration": max(result["max_acceleration"] for result in results),
        "max_jerk": max(result["max_jerk"] for result in results),
        "wait_ms_per_exchange": 1e3 * sum(result.get("planner_wait_time", 0.0)
                                          for result in results) / max(exchanges, 1),
        "step_ms_per_exchange": 1e3 * sum(result["wall_time"] for result in results)
        / max(exchanges, 1),
    }


def telemetry_ranges(laps: int, seed: int = 0) -> dict[str, Any]:
    """Every s the telemetry carries over ``laps`` laps of the walkthrough, and the ids."""
    env = gym.make(HIGHWAY, config={"map": str(MAP), "laps": laps,
                                    "max_duration": SECONDS_PER_LAP * laps,
                                    "terminate_on_collision": False,
                                    **lockstep_config(FRAMES_PER_EXCHANGE)})
    _, info = env.reset(seed=seed)
    planner = Walkthrough(MapFile.load(str(MAP)))
    ego, end, cars, ids = [], [], [], set()
    first = encode_telemetry(info["telemetry"])
    while True:
        text = encode_telemetry(info["telemetry"])
        t = json.loads(text[len('42["telemetry",'):-1])
        ego.append(t["s"])
        if t["previous_path_x"]:
            end.append(t["end_path_s"])
        cars += [row[5] for row in t["sensor_fusion"]]
        ids |= {row[0] for row in t["sensor_fusion"]}
        _, _, terminated, truncated, info = env.step(np.column_stack(planner.plan(t)))
        if terminated or truncated:
            break
    loop = MapFile.load(str(MAP)).max_s
    summary = info["summary"]
    return {
        "laps": summary["laps"], "incidents": {k: v for k, v in summary["incidents"].items()
                                               if v},
        "first_message": first[:200] + ("..." if len(first) > 200 else ""),
        "ego_s": [min(ego), max(ego)], "end_path_s": [min(end), max(end)],
        "end_path_s_past_loop": int(sum(s >= loop for s in end)), "messages": len(ego),
        "sensor_fusion_s": [min(cars), max(cars)],
        "sensor_fusion_s_past_loop": int(sum(s >= loop for s in cars)),
        "ids": sorted(ids), "loop": loop,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(10)))
    parser.add_argument("--laps", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--planners", nargs="+", choices=list(PLANNERS),
                        default=list(PLANNERS))
    parser.add_argument("--telemetry-laps", type=int, default=0,
                        help="laps of the walkthrough for the telemetry ranges (0: skip)")
    args = parser.parse_args()
    if not MAP.is_file():
        raise SystemExit(f"the original map is expected at {MAP}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="standin_planners_") as folder:
        for planner in args.planners:
            started = time.perf_counter()
            results = run_episodes(specs(planner, args.seeds, args.laps, Path(folder)),
                                   workers=args.workers, progress=False)
            row = table(planner, results)
            row["wall_s"] = time.perf_counter() - started
            rows.append(row)
            print(json.dumps(row))
    print()
    print(f"{'planner':<12} {'episodes':>8} {'laps':>5} {'mean lap s':>10} {'mean mph':>9} "
          f"{'incidents':<28} {'max acc':>7} {'max jerk':>8} {'wait ms/x':>9} "
          f"{'step ms/x':>9}")
    for row in rows:
        incidents = ", ".join(f"{k} {v}" for k, v in row["incidents"].items()) or "none"
        print(f"{row['planner']:<12} {row['episodes']:>8} {row['laps']:>5} "
              f"{row['mean_lap_s']:>10.1f} {row['mean_mph']:>9.2f} {incidents:<28} "
              f"{row['max_acceleration']:>7.2f} {row['max_jerk']:>8.2f} "
              f"{row['wait_ms_per_exchange']:>9.3f} {row['step_ms_per_exchange']:>9.3f}")
    if args.telemetry_laps:
        print()
        print(json.dumps(telemetry_ranges(args.telemetry_laps), indent=1))


if __name__ == "__main__":
    main()
