"""Replays: an env's snapshot restores the traffic exactly; a recorded incident, replayed
from a few seconds before it, happens again with the same agent and not with another."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import yaml

from sdc_agents.registry import make_agent
from sdc_evaluation.episodes import EpisodeSpec, run_episode
from sdc_gym.scenarios.replay import incident_scenario
from tests.planners.no_reaction import drive

HIGHWAY = "sdc_gym/HighwayLoop-v0"
# Rogue traffic (cut-ins, hard braking) in which the lane keeper hits a car at 9.40 s.
ROGUE = {"traffic": {"rogue": True, "rogue_rate": 30.0}, "max_duration": 12.0,
         "terminate_on_collision": False}
SEED = 11


@pytest.fixture(scope="module")
def report():
    episode = run_episode(EpisodeSpec("lane_keeping", HIGHWAY, SEED, ROGUE))
    first = episode["incident_reports"][0]
    assert first["kind"] == "collision" and first["time"] == pytest.approx(9.40, abs=1e-6)
    return {"agent": "lane_keeping", "seed": SEED, **first}


def test_a_snapshot_continues_the_traffic_bit_for_bit():
    """Snapshot an episode after 6 s; an env started from the snapshot and given the same
    paths has the same ego and the same sensor fusion as the original, step for step
    (respawns and rogue moments included: the generator's state is restored)."""
    env = gym.make(HIGHWAY, config=ROGUE)
    agent = make_agent("lane_keeping", env)
    observation, _ = env.reset(seed=SEED)
    agent.reset()
    for _ in range(100):
        observation, *_ = env.step(agent.act(observation))
    snapshot = env.unwrapped.scenario_snapshot()
    snapshot = yaml.safe_load(yaml.safe_dump(json.loads(json.dumps(snapshot))))  # as files
    replay = gym.make(HIGHWAY, config={**ROGUE, "scenario": snapshot})
    replayed, _ = replay.reset(seed=1234)  # the seed does not matter: the state is restored
    assert np.array_equal(replayed["sensor_fusion"], observation["sensor_fusion"])
    for _ in range(90):
        action = agent.act(observation)
        observation, *_ = env.step(action)
        replayed, *_ = replay.step(action)
        assert np.array_equal(replayed["ego"], observation["ego"])
        assert np.array_equal(replayed["sensor_fusion"], observation["sensor_fusion"])
        assert np.array_equal(replayed["previous_path"], observation["previous_path"])


def test_the_report_starts_its_replay_a_few_seconds_before_the_incident(report):
    start = report["replay"]["replay"]["source"]["time"]
    assert 3.0 <= report["time"] - start <= 4.1  # a snapshot every second, >= 3 s before
    scenario = incident_scenario(report)
    assert scenario["duration"] == pytest.approx(report["time"] - start + 5.0)
    assert scenario["success"] == {"no_collision": True}
    assert scenario["replay"]["source"]["incident_time"] == report["time"]


def test_the_same_agent_repeats_the_incident_and_another_avoids_it(report):
    scenario = incident_scenario(report)
    start = report["replay"]["replay"]["source"]["time"]
    env = gym.make(HIGHWAY, config={**ROGUE, "scenario": scenario})
    again = drive(env, make_agent("lane_keeping", env))["summary"]
    collision = again["incident_log"][0]
    assert collision["kind"] == "collision" and collision["value"] == report["value"]
    assert start + collision["time"] == pytest.approx(report["time"], abs=0.3)
    assert again["scenario"]["passed"] is False
    assert drive(env, make_agent("lane_keeping", env))["summary"] == again  # repeatable
    fsm = drive(env, make_agent("fsm_conservative", env))["summary"]
    assert fsm["scenario"]["passed"] is True and fsm["incidents"]["collision"] == 0


def test_evaluate_replays_the_incidents_of_a_run(report, tmp_path):
    import evaluate

    incidents = tmp_path / "incidents.json"
    incidents.write_text(json.dumps([report]), encoding="utf-8")
    result = evaluate.main(["--scenario", str(incidents), "--agents", "lane_keeping",
                            "fsm_conservative", "--output", str(tmp_path / "run"),
                            "--workers", "1", "--no-progress"])
    verdicts = {row["agent"]: row["passed"] for row in result["rows"]}
    assert verdicts == {"lane_keeping": False, "fsm_conservative": True}
    with pytest.raises(ValueError, match="no 'replay' snapshot"):
        incident_scenario({"kind": "collision", "time": 3.0})
