"""The seed team's further work against the seed's stack, on the same seeds (issue 29).

    python benchmarks/study_track_variants.py                  # seeds 0-2, every variant
    python benchmarks/study_track_variants.py --seeds 0 1 2 3 4 5 --workers 2
    python benchmarks/study_track_variants.py --variants dbw_ground_truth dbw_mpc

Each variant is an agent by name (``evaluate.py --agents NAME``) of the drive-by-wire stack
with ground-truth lights: ``dbw_ground_truth`` (the seed's: pure pursuit, PID 0.8 / 0.25 /
0.1, throttle low-pass 0.1 s), ``dbw_mpc`` (the MPC follower), ``dbw_steering_lowpass``
(0.1 s on the steering), ``dbw_no_throttle_lowpass``, ``dbw_twiddle`` and ``dbw_optuna``
(the committed tuned gains). Every variant drives one lap of the default track per seed
(the lights drawn by the seed: the same phases for every variant), and the table gives:
cross-track error RMS (over all seeds' steps: the RMS of the per-lap RMS) and max, mean
lap time, the stops' distance before the line (front bumper; min..max), max acceleration
and jerk (the env's 0.2 s block and 1 s window values), max lateral acceleration,
red-light violations, other incidents, and the stack's compute per env step (wall time of
``agent.act`` only, in this run, side by side: the ratio against the seed's is what to
read; absolute times move with the machine's load).
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401  (registers the env ids)
from sdc_agents.registry import make_agent

VARIANTS = ("dbw_ground_truth", "dbw_mpc", "dbw_steering_lowpass",
            "dbw_no_throttle_lowpass", "dbw_twiddle", "dbw_optuna")
ENV_CONFIG = {"track": "default", "laps": 1, "observe_light_states": True,
              "max_duration": 1500.0}


def run(job: tuple[str, int]) -> dict:
    """One lap of agent ``job[0]`` with seed ``job[1]``: its summary and the act time."""
    name, seed = job
    env = gym.make("sdc_gym/TrackLoop-v0", config=ENV_CONFIG)
    agent = make_agent(name, env)
    agent.reset()
    observation, _ = env.reset(seed=seed)
    agent.act(observation)  # warm-up: compiled kernels load, the solver's first setup
    agent.reset()
    observation, _ = env.reset(seed=seed)
    acting = 0.0
    steps = 0
    while True:
        started = time.perf_counter()
        action = agent.act(observation)
        acting += time.perf_counter() - started
        steps += 1
        observation, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    env.close()
    return {**info["summary"], "act_ms_per_step": 1000.0 * acting / steps}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [(name, seed) for name in args.variants for seed in args.seeds]
    with ProcessPoolExecutor(args.workers) as pool:
        summaries = list(pool.map(run, jobs))
    print(f"default track, sim car, ground-truth lights, one lap per seed, seeds {args.seeds}")
    print("| variant | CTE RMS m | CTE max m | lap s | stop gap m (before the line) | "
          "max accel m/s^2 | max jerk m/s^3 | max lateral m/s^2 | red-light violations | "
          "other incidents | act ms/step | x seed's |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    seed_ms = None
    for name in args.variants:
        rows = [s for (n, _), s in zip(jobs, summaries, strict=True) if n == name]
        laps = [t for s in rows for t in s["lap_times"]]
        gaps = [-stop["offset_m"] for s in rows for stop in s["stops"]]
        rms = math.sqrt(float(np.mean([s["rms_cross_track_error"] ** 2 for s in rows])))
        red = sum(s["red_light_violations"] for s in rows)
        others = sum(s["incident_total"] - s["red_light_violations"] for s in rows)
        ms = float(np.mean([s["act_ms_per_step"] for s in rows]))
        seed_ms = ms if name == "dbw_ground_truth" else seed_ms
        lap = f"{np.mean(laps):.1f}" if len(laps) == len(rows) else f"{len(laps)} laps"
        gap = f"{min(gaps):.2f}..{max(gaps):.2f} ({len(gaps)})" if gaps else "-"
        ratio = f"{ms / seed_ms:.1f}" if seed_ms else "-"
        print(f"| {name} | {rms:.3f} | {max(s['max_cross_track_error'] for s in rows):.3f} "
              f"| {lap} | {gap} | {max(s['max_acceleration'] for s in rows):.2f} "
              f"| {max(s['max_jerk'] for s in rows):.2f} "
              f"| {max(s['max_lateral_acceleration'] for s in rows):.2f} | {red} | {others} "
              f"| {ms:.3f} "
              f"| {ratio} |")


if __name__ == "__main__":
    main()
