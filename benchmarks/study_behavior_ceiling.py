"""How fast can a lap go under the shield? A clairvoyant rollout planner's lap speed.

    python benchmarks/study_behavior_ceiling.py --seed 2000 --episodes 10 \
        [--horizon 8.0] [--replan 4] [--hold 4] [--workers 2] [--output ceiling.csv]

Issue 28 asks a learned behavior layer to beat ``fsm_bold`` by a clear margin on 40 seeds.
How much room is there? This planner sees the future exactly: at every ``--replan``
decisions it copies the env (``copy.deepcopy``: the copy goes on exactly as the env would,
traffic's reactions and random draws included, ``tests/test_env_copy.py``) once per
candidate, drives each candidate for ``--horizon`` s, and executes the best candidate's
first ``--replan`` decisions. A candidate is one of the nine decisions held for ``--hold``
decisions, then ``keep/cruise`` (follow the lane, the shield capping the speed behind the
lead) for the rest of the horizon; its score is the distance driven by the end of the
horizon (an incident of any kind disqualifies it; a lap finished earlier scores by the
time it finished). Ties keep ``keep/cruise``, so it changes lanes only for a gain.

The env is ``HighwayLoopBehavior-v0`` with the shield on and the config train.py trains
with (``configs/train_highway_behavior.yaml``), one lap per seed as the validation laps
drive it (``sdc_training.validation_laps.lap_config``): the same layers, rules and lap as
a policy's, with foresight no policy has. Its mean mph is a *lower bound* on what the
decision interface allows (a deeper search finds more); ``fsm_bold`` on the same seeds
(``evaluate.py --agents fsm_bold --seeds ...``) is the bar. Prints one line per lap and
the mean with its 95 % t interval; ``--output`` writes the per-seed table as CSV.
"""

from __future__ import annotations

import argparse
import copy
import csv
import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

import sdc_gym  # noqa: F401
from sdc_evaluation.statistics import mean_interval
from sdc_gym.stack.highway.decisions import ACTION_NAMES
from sdc_training.validation_laps import lap_config

ENV_ID = "sdc_gym/HighwayLoopBehavior-v0"
TRAIN_CONFIG = Path(__file__).resolve().parents[1] / "configs" / "train_highway_behavior.yaml"
KEEP_CRUISE = ACTION_NAMES.index("keep/cruise")
MAX_LAP_S = 600.0


@dataclass(frozen=True)
class Settings:
    """The planner's search (see the module docstring)."""

    horizon_s: float = 8.0
    replan: int = 4
    hold: int = 4

    def __post_init__(self) -> None:
        for name in ("replan", "hold"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.horizon_s > 0:
            raise ValueError(f"horizon_s must be > 0, got {self.horizon_s}")


@dataclass(frozen=True)
class LapResult:
    """One seed's lap driven by the planner."""

    seed: int
    mean_mph: float
    lap_s: float | None
    incidents: int
    lane_changes: int
    decisions: int
    wall_s: float


def make_env(config: dict[str, Any] | None = None) -> Any:
    """The unwrapped one-lap behavior env the planner drives and copies."""
    if config is None:
        config = yaml.safe_load(TRAIN_CONFIG.read_text())["config"]
    return gym.make(ENV_ID, config=lap_config(ENV_ID, config, MAX_LAP_S)).unwrapped


def rollout_score(env: Any, first: int, settings: Settings, steps: int,
                  incidents: int) -> float:
    """The distance a copy of ``env`` drives with ``first`` held for ``settings.hold``
    decisions then ``keep/cruise``, over ``steps`` decisions (-inf on an incident beyond
    the ``incidents`` the env has had; a lap finished earlier scores more, the sooner the
    better)."""
    trial = copy.deepcopy(env)
    for k in range(steps):
        _, _, terminated, truncated, info = trial.step(first if k < settings.hold
                                                       else KEEP_CRUISE)
        if info["incidents"] > incidents:  # a new one
            return -math.inf
        if terminated or truncated:
            summary = info["summary"] or {}
            if summary.get("laps", 0) >= 1:  # finished: ahead of any unfinished candidate
                return 1e9 - k
            return float(info["distance"])
    return float(info["distance"])


def plan(env: Any, settings: Settings, incidents: int) -> int:
    """The candidate decision with the best rollout (``keep/cruise`` on ties)."""
    steps = max(1, round(settings.horizon_s / env.decision_period_s))
    best, best_score = KEEP_CRUISE, rollout_score(env, KEEP_CRUISE, settings, steps,
                                                    incidents)
    for action in range(len(ACTION_NAMES)):
        if action == KEEP_CRUISE:
            continue
        score = rollout_score(env, action, settings, steps, incidents)
        if score > best_score:
            best, best_score = action, score
    return best


def drive_lap(seed: int, settings: Settings, config: dict[str, Any] | None = None) -> LapResult:
    """One lap of seed ``seed`` with the planner deciding."""
    started = time.perf_counter()
    env = make_env(config)
    env.reset(seed=seed)
    decisions, action, incidents = 0, KEEP_CRUISE, 0
    while True:
        if decisions % settings.replan == 0:
            action = plan(env, settings, incidents)
        _, _, terminated, truncated, info = env.step(action)
        decisions += 1
        incidents = int(info["incidents"])
        if terminated or truncated:
            break
    summary = info["summary"]
    lap_times = summary.get("lap_times") or []
    return LapResult(seed=seed, mean_mph=float(summary["mean_speed_mph"]),
                     lap_s=float(lap_times[0]) if lap_times else None,
                     incidents=int(summary["incident_total"]),
                     lane_changes=int(info["behavior"]["lane_changes"]),
                     decisions=decisions, wall_s=time.perf_counter() - started)


def drive_laps(seeds: list[int], settings: Settings, workers: int = 1) -> list[LapResult]:
    """Every seed's lap, in ``workers`` processes, in seed order."""
    if workers == 1:
        return [drive_lap(seed, settings) for seed in seeds]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(drive_lap, seeds, [settings] * len(seeds)))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=2000, help="the first seed")
    parser.add_argument("--episodes", type=int, default=10, help="laps (seeds from --seed on)")
    parser.add_argument("--horizon", type=float, default=Settings.horizon_s,
                        help="rollout length, s")
    parser.add_argument("--replan", type=int, default=Settings.replan,
                        help="decisions between plans")
    parser.add_argument("--hold", type=int, default=Settings.hold,
                        help="decisions a candidate holds before keep/cruise")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--output", type=Path, default=None, help="per-seed CSV")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.workers < 1:
        parser.error(f"--episodes and --workers must be >= 1, got {args.episodes} and "
                     f"{args.workers}")
    try:
        settings = Settings(args.horizon, args.replan, args.hold)
    except ValueError as error:
        parser.error(str(error))
    seeds = list(range(args.seed, args.seed + args.episodes))
    results = drive_laps(seeds, settings, args.workers)
    for r in results:
        print(f"seed {r.seed}: {r.mean_mph:6.2f} mph, lap {r.lap_s} s, {r.lane_changes} lane "
              f"changes, {r.incidents} incidents, {r.decisions} decisions, {r.wall_s:.0f} s")
    interval = mean_interval(np.array([r.mean_mph for r in results]))
    bounds = ("" if interval.low is None
              else f" [{interval.low:.2f}, {interval.high:.2f}]")  # one lap: no interval
    print(f"planner ({settings}): {interval.value:.2f} mph{bounds} over {len(results)} "
          f"laps, {sum(r.incidents for r in results)} incidents")
    if args.output is not None:
        temporary = args.output.with_suffix(args.output.suffix + ".tmp")
        with temporary.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(asdict(results[0])))
            writer.writeheader()
            writer.writerows(asdict(r) for r in results)
        temporary.replace(args.output)


if __name__ == "__main__":
    main()
