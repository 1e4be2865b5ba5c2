"""Capstone teams' twist controllers on the original track: do they stop as they did there?

    python benchmarks/study_capstone_controllers.py                    # seeds 0-2, both cars
    python benchmarks/study_capstone_controllers.py --seeds 0 1 2 3 4 --workers 2
    python benchmarks/study_capstone_controllers.py --cars sim        # the sim preset only

Each row drives full laps of the original simulator's track (``wp_yaw_const.csv`` with its
8 stop lines, ground-truth light states, lights cycling 10 s green / 3 s yellow / 10 s red
with seeded offsets, 40 km/h) with sdc-gym's waypoint updater and pure pursuit and one
twist controller: sdc-gym's own, or one of the two stand-ins written from public
descriptions of capstone teams' controllers (``tests/planners/capstone_twist_controllers.py``:
the course walkthrough's, with a 400 N m holding torque; a proportional braker with no
brake below 0.1 m/s). ``--cars``: ``sim`` is the sim preset (the original's car as
docs/track_vehicle.md describes it: no idle creep); ``creeping`` is the sim preset before
issue 19 (idle creep held by 400 N m, 4 kN / 90 kW, aero drag and rolling resistance,
steer ratio 14.8), for the before/after comparison.

Printed per controller and car: laps, mean lap time, red-light violations, stops at red
lights and where the front bumper came to rest relative to the line (negative: before
it), the largest overshoot, the worst lap's cross-track error RMS and other incidents.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import gymnasium as gym
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sdc_gym  # noqa: E402,F401  (registers the env ids)
from sdc_gym.lights.traffic_lights import RED  # noqa: E402
from tests.planners.capstone_twist_controllers import (  # noqa: E402
    CARS,
    drive_episode,
    original_track_config,
    with_controller,
)

CONTROLLERS = ("sdc_gym", "walkthrough", "proportional_brake")


def run(job: tuple[str, str, int, int]) -> dict:
    """``laps`` laps with controller ``job[0]`` on car ``job[1]``, seed ``job[2]``."""
    controller, car, seed, laps = job
    env = gym.make("sdc_gym/TrackLoop-v0", config=original_track_config(
        laps=laps, max_duration=900.0 * laps, vehicle_overrides=CARS[car]))
    info = drive_episode(env, with_controller(env, controller), seed)
    env.close()
    return info["summary"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--laps", type=int, default=1)
    parser.add_argument("--cars", nargs="+", choices=sorted(CARS), default=["sim", "creeping"])
    parser.add_argument("--controllers", nargs="+", choices=CONTROLLERS,
                        default=list(CONTROLLERS))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [(c, car, seed, args.laps) for car in args.cars for c in args.controllers
            for seed in args.seeds]
    with ProcessPoolExecutor(args.workers) as pool:
        summaries = list(pool.map(run, jobs))
    print(f"original track (wp_yaw_const.csv, 8 lights cycling), 40 km/h, ground-truth "
          f"lights, seeds {args.seeds}, {args.laps} lap(s) each")
    print(f"{'car':9s} {'controller':19s} {'laps':>4s} {'lap s':>6s} {'red viol.':>9s} "
          f"{'red stops':>9s} {'red stop offset m':>18s} {'overshoot m':>11s} "
          f"{'CTE rms m':>9s} {'other incidents':>15s}")
    for car in args.cars:
        for controller in args.controllers:
            rows = [s for (c, k, _, _), s in zip(jobs, summaries, strict=True)
                    if c == controller and k == car]
            laps = [t for s in rows for t in s["lap_times"]]
            red_stops = [stop["offset_m"] for s in rows for stop in s["stops"]
                         if stop["light_state"] == RED]
            spread = (f"{min(red_stops):+.2f}..{max(red_stops):+.2f}" if red_stops else "-")
            others = Counter()
            for s in rows:
                others.update({kind: n for kind, n in s["incidents"].items()
                               if n and kind != "red_light"})
            other = " ".join(f"{kind} {n}" for kind, n in sorted(others.items())) or "0"
            lap = f"{np.mean(laps):.1f}" if laps else "-"
            print(f"{car:9s} {controller:19s} {len(laps):4d} {lap:>6s} "
                  f"{sum(s['red_light_violations'] for s in rows):9d} {len(red_stops):9d} "
                  f"{spread:>18s} {max(s['max_overshoot'] for s in rows):11.2f} "
                  f"{max(s['rms_cross_track_error'] for s in rows):9.3f} {other:>15s}")


if __name__ == "__main__":
    main()
