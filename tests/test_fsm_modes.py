"""The FSM's optional modes (Alert, Caution, Reverse, Hyper): each entered in a scenario
built to trigger it, none on an empty road, and the seed's styles never entering one."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import pytest
import yaml

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_agents.registry import make_agent

HIGHWAY = "sdc_gym/HighwayLoop-v0"
START = {"s": 150, "lane": 1, "speed": 20}  # the default loop's straight, middle lane

SCENARIOS = {
    # A car level 10 m ahead in the next lane cuts in (a 1 s lane change: swerving) and
    # brakes at 6 m/s^2 (stress_cut_in_10m, which Bold fails).
    "alert": {"name": "rogue_cut_in", "duration": 15, "ego": START,
              "cars": [{"name": "cutter", "lane": 0, "gap": 10, "speed": 20}],
              "actions": [{"car": "cutter", "when": {"time": 2}, "do": "cut_in"},
                          {"car": "cutter", "when": {"time": 3}, "do": "brake", "decel": 6,
                           "to_speed": 8}]},
    # A car at 8 m/s in the next lane 60 m ahead.
    "caution": {"name": "slow_beside", "duration": 15, "ego": START,
                "cars": [{"name": "slow", "lane": 0, "gap": 60, "speed": 8}]},
    # A wreck standing in the ego's lane 90 m ahead.
    "reverse": {"name": "blockage", "duration": 30, "ego": START,
                "cars": [{"name": "wreck", "lane": 1, "gap": 90, "stalled": True}]},
    # Boxed in behind a car at its own speed, lane 0 open ahead but with a car beside,
    # lane 2 open.
    "hyper": {"name": "boxed_in", "duration": 20, "ego": {"s": 150, "lane": 1, "speed": 15},
              "cars": [{"name": "slow", "lane": 1, "gap": 25, "speed": 15},
                       {"name": "beside", "lane": 0, "gap": -6, "speed": 17}]},
}
EMPTY = {"name": "empty_road", "duration": 30, "ego": START}


def run(agent_name: str, scenario: dict) -> tuple[dict, list[tuple[float, str, float, int]],
                                                   frozenset[str]]:
    """One scenario episode: the final info, (time, mode, speed, lane) per cycle, and the
    optional modes the agent's FSM says it entered."""
    env = gym.make(HIGHWAY)
    agent = make_agent(agent_name, env)
    observation, info = env.reset(seed=0, options={"scenario": scenario})
    agent.reset()
    log = []
    while True:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        world = agent.world
        log.append((world.time, agent.decision.mode, world.ego_speed, world.ego_lane))
        if terminated or truncated:
            break
    env.close()
    return info, log, agent.behavior.modes_entered


@pytest.mark.parametrize("mode", sorted(SCENARIOS))
def test_each_mode_is_entered_in_its_scenario_and_never_on_an_empty_road(mode):
    info, log, entered = run(f"fsm_{mode}", SCENARIOS[mode])
    assert entered == {mode}
    assert any(step[1] == mode for step in log)  # the decision carries the mode's name
    assert info["summary"]["scenario"]["passed"], info["summary"]["scenario"]["reason"]
    _, log, entered = run(f"fsm_{mode}", EMPTY)
    assert entered == frozenset()
    assert {step[1] for step in log} <= {"launch", "adapt", "advance", "cruise"}


def test_the_seeds_bold_style_enters_none_and_alert_saves_the_cut_in():
    info, log, entered = run("fsm_bold", SCENARIOS["alert"])
    assert entered == frozenset() and {step[1] for step in log} <= {"adapt", "cruise"}
    assert info["summary"]["scenario"]["reason"].startswith("collision with car at")
    info, log, _ = run("fsm_alert", SCENARIOS["alert"])
    # Alert from the swerve (the cut-in starts at 2 s), held for 3 s after the last
    # sighting: the brake at 3 s is seen as a jolt too.
    first = next(t for t, mode, _, _ in log if mode == "alert")
    assert 2.0 < first < 2.5


def test_caution_passes_the_slow_car_at_most_its_speed_plus_the_margin():
    _, log, _ = run("fsm_caution", SCENARIOS["caution"])
    cautious = [speed for _, mode, speed, _ in log if mode == "caution"]
    assert cautious
    # 8 m/s + 4.5 m/s, once the ego has slowed from its start at 20 m/s (at 5 m/s^2,
    # easing into the goal at the motion layer's bounded jerk).
    assert max(cautious[int(3.0 / 0.06):]) < 8.0 + 4.5 + 0.01
    assert min(cautious[int(3.0 / 0.06):]) > 8.0 + 4.5 - 0.01


def test_reverse_stops_short_of_a_blockage_when_it_cannot_leave_the_lane():
    """A wreck across all three lanes (an accident): no lane to leave into, so the ego
    stops on its straight-line profile 30 m (centre to centre) behind it and waits."""
    scenario = {"name": "road_blocked", "duration": 20, "ego": START,
                "cars": [{"name": f"wreck{lane}", "lane": lane, "gap": 90, "stalled": True}
                         for lane in range(3)]}
    info, _, entered = run("fsm_reverse", scenario)
    assert entered == {"reverse"}
    assert info["summary"]["scenario"]["passed"], info["summary"]["scenario"]["reason"]
    env = gym.make(HIGHWAY)
    agent = make_agent("fsm_reverse", env)
    observation, _ = env.reset(seed=0, options={"scenario": scenario})
    agent.reset()
    for _ in range(int(15 / 0.06)):
        observation, *_ = env.step(agent.act(observation))
    own = agent.world.lanes[1]
    assert agent.world.ego_speed < 0.5 and agent.world.ego_lane == 1
    assert own.ahead_gap == pytest.approx(30.0, abs=3.0)
    assert math.isfinite(own.ahead_gap) and agent.behavior.mode.value == "reverse"
    env.close()


def test_hyper_leaves_only_past_the_mid_range_plus_its_margin(tmp_path):
    """The library's hard-braking lead with a car beside: Hyper slows for the gap beside,
    the lead draws away to the mid range (35 m) just before it brakes at 8 m/s^2. Without
    the exit margin Hyper ends there, the approach rule plans a second of acceleration and
    the ego hits the lead at 6.46 s; with the margin (10 m) it stays in Hyper and stops."""
    library = Path(__file__).resolve().parents[1] / "sdc_gym" / "scenarios" / "library"
    scenario = yaml.safe_load((library / "stress_hard_braking_lead.yaml").read_text())
    info, log, entered = run("fsm_hyper", scenario)
    assert entered == {"hyper"}
    assert info["summary"]["scenario"]["passed"], info["summary"]["scenario"]["reason"]
    # Hyper held through the lead's 35-45 m (no exit at the mid range) until it braked.
    assert {mode for t, mode, _, _ in log if 2.5 < t < 4.0} == {"hyper"}
    rules = tmp_path / "hyper_no_margin.yaml"
    rules.write_text("style: bold\nhyper: {enabled: true, exit_margin_m: 0.0}\n")
    info, _, _ = run(f"fsm:{rules}", scenario)
    assert info["summary"]["scenario"]["reason"] == "collision with car at 6.46 s"
