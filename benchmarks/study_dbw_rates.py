"""The drive-by-wire stack's node rates against lap time and violations (issue 5's study).

    python benchmarks/study_dbw_rates.py                 # seeds 0-3, all rate settings
    python benchmarks/study_dbw_rates.py --seeds 0 1 2 3 4 5 6 7 8 9 --workers 2
    python benchmarks/study_dbw_rates.py --speed-kmh 40 70    # also at a higher limit

The seed team lowered the rates of the waypoint updater, pure pursuit and DBW nodes from
the original's (updater 10 Hz here, follower 30 Hz, DBW 50 Hz) to 2 / 5 / 15 Hz to save
compute, and wrote that lower rates limit the top speed. Each row drives the default track
(one lap per seed, ground-truth lights, the sim car at the 40 km/h limit or the limits
given) with one rate setting and prints lap time, red-light violations, how stops landed
relative to their lines, cross-track error and incidents. ``next wp speed`` rows take the
commanded speed from the next final waypoint ahead of the car instead of the first one (at
2 Hz the first one can be metres behind the car, so the car brakes late for a red light).
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401  (registers the env ids)
from sdc_agents.track.dbw_agent import dbw_agent
from sdc_gym.stack.track.follower import CONTINUOUS_FOLLOWER
from sdc_gym.stack.track.rates import ORIGINAL_RATES, SEED_RATES, NodeRates
from sdc_gym.units import KMH_TO_MPS


@dataclass(frozen=True)
class Setting:
    """One row of the study: node rates and where the follower reads its speed."""

    label: str
    rates: NodeRates
    next_waypoint_speed: bool = False


SETTINGS: tuple[Setting, ...] = (
    Setting("original (10 / 30 / 50 Hz)", ORIGINAL_RATES),
    Setting("halved (5 / 15 / 25 Hz)", NodeRates(updater_hz=5.0, follower_hz=15.0,
                                                 dbw_hz=25.0)),
    Setting("seed team (2 / 5 / 15 Hz)", SEED_RATES),
    Setting("seed team + next wp speed", SEED_RATES, next_waypoint_speed=True),
    Setting("1 / 2 / 10 Hz + next wp speed", NodeRates(updater_hz=1.0, follower_hz=2.0,
                                                       dbw_hz=10.0), True),
)
ENV_CONFIG = {"track": "default", "laps": 1, "observe_light_states": True,
              "max_duration": 1500.0}


def run(job: tuple[int, float, int]) -> dict:
    """One lap with setting ``job[0]``, speed limit ``job[1]`` km/h and seed ``job[2]``."""
    index, kmh, seed = job
    setting = SETTINGS[index]
    env = gym.make("sdc_gym/TrackLoop-v0",
                   config={**ENV_CONFIG, "speed_limit": kmh * KMH_TO_MPS})
    follower = replace(CONTINUOUS_FOLLOWER,
                       speed_from_next_waypoint=setting.next_waypoint_speed)
    agent = dbw_agent(env, "ground_truth", rates=setting.rates, follower=follower)
    agent.reset()
    observation, _ = env.reset(seed=seed)
    while True:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        if terminated or truncated:
            break
    env.close()
    return info["summary"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--speed-kmh", type=float, nargs="+", default=[40.0],
                        help="speed limits to drive at, km/h (default: the track's 40)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [(i, kmh, seed) for kmh in args.speed_kmh for i in range(len(SETTINGS))
            for seed in args.seeds]
    with ProcessPoolExecutor(args.workers) as pool:
        summaries = list(pool.map(run, jobs))
    print(f"default track, sim car, ground-truth lights, seeds {args.seeds}")
    header = (f"{'km/h':>4s} {'setting':32s} {'lap s':>7s} {'red lights':>10s} {'stops':>5s} "
              f"{'stop offset m (min..max)':>25s} {'CTE rms m':>9s} {'other incidents':>15s}")
    print(header)
    for kmh, i in ((kmh, i) for kmh in args.speed_kmh for i in range(len(SETTINGS))):
        setting = SETTINGS[i]
        rows = [s for (j, k, _), s in zip(jobs, summaries, strict=True) if j == i and k == kmh]
        laps = [t for s in rows for t in s["lap_times"]]
        offsets = [stop["offset_m"] for s in rows for stop in s["stops"]]
        others = sum(s["incident_total"] - s["red_light_violations"] for s in rows)
        lap = f"{np.mean(laps):.1f}" if len(laps) == len(rows) else f"{len(laps)} laps"
        spread = f"{min(offsets):+.2f}..{max(offsets):+.2f}" if offsets else "-"
        red = sum(s["red_light_violations"] for s in rows)
        print(f"{kmh:4.0f} {setting.label:32s} {lap:>7s} {red:10d} "
              f"{len(offsets):5d} {spread:>25s} "
              f"{max(s['rms_cross_track_error'] for s in rows):9.3f} {others:15d}")


if __name__ == "__main__":
    main()
