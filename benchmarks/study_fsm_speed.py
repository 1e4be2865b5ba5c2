"""Where the seed's FSM loses time on the highway, and how much its rules cost (issue 3).

    python benchmarks/study_fsm_speed.py                       # seeds 0-19, both styles
    python benchmarks/study_fsm_speed.py --seeds 0 1 2 3 --workers 2
    python benchmarks/study_fsm_speed.py --map ../shared/data/udacity/path_planning/highway_map.csv

Part 1 drives one lap per seed with each style's own rules and books every planning cycle's
lost time, ``dt x (1 - v / v_cruise)`` (what the cycle costs against driving at the 49.83 mph
cruise speed), to the first situation that applies:

    launch          the launch from rest
    lane change     a lane change in progress
    cruising        at the cruise speed (nothing to lose)
    open road       nobody within 150 m ahead (accelerating back to the cruise speed)
    boxed in        no adjacent lane has 20 m more room ahead than the ego's lane
    bend            the seed's circumradius rule forbids lane changes here
    cool-down       the tactical cool-down since the last lane change runs
    car behind      the roomier lane's car behind is inside the seed's safety gap
    other rules     the rest (thresholds on room ahead, far-lane checks, ...)

It also reports how fast the traffic itself flows: the mean desired and actual speed of the
traffic cars over the lap.

Part 2 drives the same laps with variants of the rules, each lifting restrictions on lane
changes (the seed's bend rule, this project's far-lane merge watch, the cool-downs) and
prints mean speed and incidents: how much each rule costs, and the speed a planner of this
family reaches with none of them.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401  (registers the env ids)
from sdc_agents.highway.fsm import DrivingStyle, FSMParameters, Mode
from sdc_agents.highway.fsm_agent import fsm_agent
from sdc_gym.units import MPH_TO_MPS

CRUISE = FSMParameters().cruise_speed_mps
OPEN_ROAD_M = 150.0  # nobody this close ahead: the road is open
MORE_ROOM_M = 20.0  # an adjacent lane "has room" with this much more room ahead
CATEGORIES = ("launch", "lane change", "cruising", "open road", "boxed in", "bend",
              "cool-down", "car behind", "other rules")


def _short_cooldowns(style: DrivingStyle) -> FSMParameters:
    base = FSMParameters.for_style(style)
    fast = dict(tactical_cooldown_s=2.0, strategic_cooldown_s=2.0)
    return replace(base, calm=replace(base.calm, **fast), active=replace(base.active, **fast))


def _no_bend_rule(style: DrivingStyle) -> FSMParameters:
    return FSMParameters.for_style(style, single_change_radius_m=0.0, double_change_radius_m=0.0)


def _no_merge_watch(style: DrivingStyle) -> FSMParameters:
    return FSMParameters.for_style(style, far_lane_merge_watch_m=0.0)


def _none_of_them(style: DrivingStyle) -> FSMParameters:
    return replace(_short_cooldowns(style), single_change_radius_m=0.0,
                   double_change_radius_m=0.0, far_lane_merge_watch_m=0.0)


VARIANTS: dict[str, Callable[[DrivingStyle], FSMParameters]] = {
    "the seed's rules": FSMParameters.for_style,
    "no bend rule (circumradius)": _no_bend_rule,
    "no far-lane merge watch": _no_merge_watch,
    "cool-downs 2 s": _short_cooldowns,
    "none of the three": _none_of_them,
}


def _situation(agent, params: FSMParameters) -> str:
    """The first situation of :data:`CATEGORIES` that applies to the last cycle."""
    fsm = agent.behavior
    world = agent.world
    v = world.ego_speed
    lanes = world.lanes
    own = lanes[world.ego_lane]
    if fsm.mode is Mode.LAUNCH:
        return "launch"
    if fsm.lane_change_in_progress:
        return "lane change"
    if v >= 0.985 * CRUISE:
        return "cruising"
    if own.ahead_gap > OPEN_ROAD_M:
        return "open road"
    roomier = [lanes[t] for t in (world.ego_lane - 1, world.ego_lane + 1)
               if 0 <= t < world.lane_count and lanes[t].ahead_gap > own.ahead_gap + MORE_ROOM_M]
    if not roomier:
        return "boxed in"
    if world.road_radius <= params.single_change_radius_m:
        return "bend"
    if fsm.time_since_lane_change <= fsm.profile.tactical_cooldown_s:
        return "cool-down"
    if all(lane.behind_gap <= params.safety_gap_m(lane.behind_speed, v) for lane in roomier):
        return "car behind"
    return "other rules"


def drive(job: tuple[str, str, int, str, bool]) -> dict:
    """One lap: ``(variant, style, seed, map, book the lost time)``."""
    variant, style_name, seed, map_name, book = job
    style = DrivingStyle(style_name)
    params = VARIANTS[variant](style)
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"map": map_name})
    agent = fsm_agent(env, style, params=params)
    observation, _ = env.reset(seed=seed)
    agent.reset()
    traffic = env.unwrapped.traffic
    dt = agent.motion.params.frames_per_cycle * 0.02
    lost: dict[str, float] = defaultdict(float)
    desired: list[float] = []
    actual: list[float] = []
    steps = 0
    while True:
        action = agent.act(observation)
        if book:
            lost[_situation(agent, params)] += dt * (1.0 - agent.world.ego_speed / CRUISE)
            if steps % 50 == 0:
                desired.append(float(np.mean(traffic.desired_speed)))
                actual.append(float(np.mean(traffic.speed)))
        observation, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            break
    summary = env.unwrapped.summary()
    env.close()
    return {"variant": variant, "style": style_name, "seed": seed,
            "mph": summary["mean_speed_mph"], "incidents": summary["incident_total"],
            "lost": dict(lost), "desired": float(np.mean(desired)) if desired else 0.0,
            "actual": float(np.mean(actual)) if actual else 0.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(20)))
    parser.add_argument("--map", default="default", help="map name or original-format file")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS),
                        choices=list(VARIANTS), metavar="VARIANT",
                        help=f"rule variants, of: {', '.join(VARIANTS)}")
    args = parser.parse_args()
    if not args.seeds:
        parser.error("--seeds needs at least one seed")
    styles = [s.value for s in DrivingStyle]
    jobs = [(variant, style, seed, args.map, variant == "the seed's rules")
            for variant in args.variants for style in styles for seed in args.seeds]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        results = list(pool.map(drive, jobs))
    n = len(args.seeds)

    booked = [r for r in results if r["variant"] == "the seed's rules"]
    if booked:
        print(f"Where the time goes ({args.map}, seeds {args.seeds[0]}..{args.seeds[-1]}, "
              f"{n} laps per style): s lost per lap against the cruise speed")
        print(f"| situation | {' | '.join(styles)} |\n|---|{'---:|' * len(styles)}")
        for category in CATEGORIES:
            cells = [sum(r["lost"].get(category, 0.0) for r in booked if r["style"] == s) / n
                     for s in styles]
            print(f"| {category} | {' | '.join(f'{c:.1f}' for c in cells)} |")
        totals = [sum(sum(r["lost"].values()) for r in booked if r["style"] == s) / n
                  for s in styles]
        print(f"| total | {' | '.join(f'{t:.1f}' for t in totals)} |")
        desired = np.mean([r["desired"] for r in booked]) / MPH_TO_MPS
        actual = np.mean([r["actual"] for r in booked]) / MPH_TO_MPS
        print(f"traffic speed over the laps: desired {desired:.1f} mph, actual {actual:.1f} mph\n")

    print("| rules | " + " | ".join(f"{s} mph | {s} incidents" for s in styles) + " |")
    print("|---|" + "---:|---:|" * len(styles))
    for variant in args.variants:
        cells = []
        for style in styles:
            rows = [r for r in results if r["variant"] == variant and r["style"] == style]
            cells += [f"{np.mean([r['mph'] for r in rows]):.2f}",
                      str(sum(r["incidents"] for r in rows))]
        print(f"| {variant} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
