"""Scenario files: errors naming the file, line and key; the library's known outcomes for
the FSM styles; per-episode scenarios through reset options, single and batched;
``stop_at_incident``; ``evaluate.py --scenario``."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

from sdc_agents.registry import make_agent
from sdc_gym.config import ConfigError
from sdc_gym.scenarios import library_path, library_scenarios, load_scenario
from tests.planners.no_reaction import NoReaction, drive

HIGHWAY = "sdc_gym/HighwayLoop-v0"


# --------------------------------------------------------------------------- the format
def write(tmp_path, text: str):
    path = tmp_path / "case.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("text, message", [
    # An unknown key: its line, a close match, the valid keys.
    ("name: x\nego:\n  lane: 1\n  sped: 20\n",
     r"case.yaml:4: unknown scenario key 'ego.sped' \(did you mean 'speed'\?\); valid keys "
     r"of ego: s, lane, d, speed"),
    # A value out of range: line, key, the rule, the value.
    ("cars:\n  - {lane: 1, gap: 30, speed: 20}\n  - {lane: 0, gap: 10,\n     speed: -3}\n",
     r"case.yaml:4: scenario key 'cars\[1\]\.speed' must be a finite number in \[0, 100\] "
     r"\(m/s\), got -3"),
    # A choice: the valid ones listed.
    ("cars:\n  - {lane: 1, gap: 30, speed: 20, kind: tank}\n",
     r"case.yaml:2: scenario key 'cars\[0\]\.kind' must be one of \['car', 'suv', 'truck', "
     r"'motorcycle', 'bus', 'van', 'semi'\], got 'tank'"),
    # A required key.
    ("cars:\n  - {lane: 1, gap: 30}\n", r"case.yaml:2: scenario key 'cars\[0\]\.speed' is "
     r"required"),
    # An action for a car that is not there.
    ("cars:\n  - {name: a, lane: 1, gap: 30, speed: 20}\nactions:\n"
     "  - {car: b, when: {time: 1}, do: brake, decel: 5, duration: 1}\n",
     r"case.yaml:4: scenario key 'actions\[0\]\.car' must be a car's name or index "
     r"\(cars: \['a'\]\), got 'b'"),
    # A trigger kind.
    ("cars:\n  - {lane: 1, gap: 30, speed: 20}\nactions:\n"
     "  - {car: 0, when: {distance: 1}, do: stop}\n",
     r"case.yaml:4: unknown scenario key 'actions\[0\]\.when\.distance'.*time, gap_below, "
     r"gap_above, ego_distance"),
    # YAML itself broken: the line of the problem.
    ("ego:\n  lane: [1\nduration: 3\n", r"case.yaml:3: the scenario file is not valid YAML"),
    # A success condition's incident kind.
    ("success:\n  no_incidents: [crash]\n", r"case.yaml:2: scenario key "
     r"'success.no_incidents' must be a list of incident kinds of \['collision'"),
])
def test_bad_scenario_files_name_the_line_key_value_and_choices(tmp_path, text, message):
    with pytest.raises(ConfigError, match=message):
        load_scenario(write(tmp_path, text))


def test_what_depends_on_the_road_is_checked_with_the_line_when_an_env_takes_it(tmp_path):
    path = write(tmp_path, "ego: {lane: 1, speed: 20}\ncars:\n  - {lane: 3, gap: 30, "
                           "speed: 20}\n")
    load_scenario(path)  # a lane 3 is fine on a map of four lanes
    with pytest.raises(ConfigError, match=r"case.yaml:3: scenario key 'cars\[0\]\.lane' must "
                                          r"be a lane of the map, 0 to 2, got 3"):
        gym.make(HIGHWAY, config={"scenario": str(path)})
    env = gym.make(HIGHWAY)
    with pytest.raises(ConfigError, match=r"has 13 cars; the env has traffic.car_count = 12"):
        env.reset(options={"scenario": {"cars": [{"lane": 0, "gap": 20 * k + 10,
                                                   "speed": 10} for k in range(13)]}})


def test_bad_env_config_keys_of_the_issue():
    with pytest.raises(ConfigError, match=r"stop_at_incident.*list of incident kinds"):
        gym.make(HIGHWAY, config={"stop_at_incident": ["crash"]})
    with pytest.raises(ConfigError, match=r"road_events.object_slots' must be >= 1"):
        gym.make(HIGHWAY, config={"road_events": {"cargo_per_km": 1.0}})
    with pytest.raises(ConfigError, match=r"vehicle_mix.*kind names"):
        gym.make(HIGHWAY, config={"traffic": {"vehicle_mix": {"tank": 1.0}}})
    with pytest.raises(ConfigError, match=r"config key 'scenario'.*scenario file"):
        gym.make(HIGHWAY, config={"scenario": "/no/such/scenario.yaml"})


def test_every_library_file_is_valid_and_named_after_its_file():
    names = [path.stem for path in library_scenarios()]
    assert {"a_early_lane_change", "j_pocket_double_lane_change", "stress_cut_in_10m",
            "stress_stop_and_go", "stress_stalled_in_bend"} <= set(names)
    assert sum(name[0] in "abcdefghij" and name[1] == "_" for name in names) == 10
    for path in library_scenarios():
        scenario = load_scenario(path)
        assert scenario.name == path.stem and scenario.description
    with pytest.raises(KeyError, match="a_early_lane_change"):
        library_path("no_such_scenario")


# --------------------------------------------------------------------------- outcomes
# The FSM styles on every library scenario (seed 0): (Conservative, Bold) passed. Where a
# style fails, the reason says why, and docs/scenarios.md explains it.
LIBRARY_OUTCOMES = {
    "a_early_lane_change": (True, True),
    "b_matched_speed_clear_lanes": (True, True),
    "c_open_ahead_behind_no_threat": (True, True),
    "d_threat_from_behind": (True, True),
    "e_faster_next_lane_behind_no_threat": (True, True),
    "f_return_to_middle_lane": (True, True),
    "g_pocket_patience": (True, True),
    "h_faster_next_lane_clear_behind": (True, True),
    "i_faster_next_lane_not_clear_behind": (True, True),
    # Conservative's 15 s cool-down outlasts the straight a double change needs.
    "j_pocket_double_lane_change": (False, True),
    # Conservative's ghosting brakes for the car beside before it is in the lane; Bold's
    # 30 m braking range is too short for the cut-in and for a car standing in a bend.
    "stress_cut_in_10m": (True, False),
    "stress_stalled_in_bend": (True, False),
    "stress_stop_and_go": (True, True),
    "stress_hard_braking_lead": (True, True),
    "event_closed_lane": (True, True),
    "event_fallen_cargo": (True, True),
    "event_animal_crossing": (True, True),
    "traffic_buses_and_semis": (True, True),
}
FAIL_REASONS = {
    ("j_pocket_double_lane_change", "fsm_conservative"): "not in lane 0 within 25 s",
    ("stress_cut_in_10m", "fsm_bold"): "collision with car at",
    ("stress_stalled_in_bend", "fsm_bold"): "collision with car at",
}


def test_the_library_is_the_table():
    assert set(LIBRARY_OUTCOMES) == {path.stem for path in library_scenarios()}


@pytest.mark.parametrize("name", sorted(LIBRARY_OUTCOMES))
def test_fsm_styles_on_the_library(name):
    path = library_path(name)
    for style, expected in zip(("fsm_conservative", "fsm_bold"), LIBRARY_OUTCOMES[name],
                               strict=True):
        env = gym.make(HIGHWAY, config={"scenario": str(path)})
        info = drive(env, make_agent(style, env))
        verdict = info["summary"]["scenario"]
        assert verdict["name"] == name and verdict["source"] == str(path)
        assert verdict["passed"] is expected, (style, verdict["reason"])
        assert info["is_success"] is expected
        if expected:
            assert verdict["reason"].startswith("passed: ")
            assert info["termination_reason"] == "scenario_end"
        else:
            assert verdict["reason"].startswith(FAIL_REASONS[name, style]), verdict["reason"]


@pytest.mark.parametrize("name, kind", [("stress_cut_in_10m", "car"),
                                        ("stress_stalled_in_bend", "car"),
                                        ("event_closed_lane", "barrier"),
                                        ("event_fallen_cargo", "cargo"),
                                        ("event_animal_crossing", "animal")])
def test_a_driver_that_does_not_react_hits_what_the_scenario_puts_in_its_way(name, kind):
    path = library_path(name)
    env = gym.make(HIGHWAY, config={"scenario": str(path)})
    info = drive(env, NoReaction(env, load_scenario(path).ego.speed))
    assert info["termination_reason"] == "collision"
    assert info["summary"]["scenario"]["reason"].startswith(f"collision with {kind} at ")
    assert info["summary"]["incidents"]["collision"] == 1


def test_b_lane_change_waits_for_each_styles_cool_down():
    """Seed scenario B: the lane change comes after the tactical cool-down (15 s
    Conservative, 4.6 s Bold), counted from the episode's start, and not long after."""
    path = library_path("b_matched_speed_clear_lanes")
    for style, (low, high) in (("fsm_conservative", (15.0, 20.0)), ("fsm_bold", (4.6, 8.0))):
        env = gym.make(HIGHWAY, config={"scenario": str(path)})
        reason = drive(env, make_agent(style, env))["summary"]["scenario"]["reason"]
        at = float(reason.split("lane 1 at ")[1].split(" s")[0])
        assert low < at < high, (style, reason)


# --------------------------------------------------------------------------- selection
CUT_IN = {"name": "cut_in", "duration": 6.0, "ego": {"lane": 1, "speed": 20.0},
          "cars": [{"name": "cutter", "lane": 0, "gap": 10.0, "speed": 20.0}],
          "actions": [{"car": "cutter", "when": {"time": 1.0}, "do": "cut_in"},
                      {"car": "cutter", "when": {"time": 1.5}, "do": "brake", "decel": 6.0,
                       "to_speed": 8.0}]}


def test_reset_options_select_a_scenario_per_episode_and_it_stays_until_replaced():
    env = gym.make(HIGHWAY, config={"terminate_on_collision": False})
    agent = NoReaction(env, 20.0)
    info = drive(env, agent, options={"scenario": CUT_IN})
    assert info["termination_reason"] == "scenario_end"
    assert info["summary"]["scenario"]["reason"].startswith("collision with car at ")
    assert info["time"] == pytest.approx(6.0, abs=0.07)
    again = drive(env, agent)  # the same scenario again, the same episode
    assert again["summary"] == info["summary"]
    observation, info = env.reset(seed=0, options={"scenario": None})  # random traffic
    assert "scenario" not in env.unwrapped.summary()
    assert observation["sensor_fusion_mask"].sum() == 12


def test_stop_at_incident_ends_the_episode_at_the_first_incident_of_its_kinds():
    env = gym.make(HIGHWAY, config={"scenario": CUT_IN, "terminate_on_collision": False,
                                    "stop_at_incident": ["collision"]})
    info = drive(env, NoReaction(env, 20.0))
    assert info["termination_reason"] == "stop_at_incident"
    assert info["new_incidents"] == ["collision"] and info["time"] < 4.0
    env = gym.make(HIGHWAY, config={"scenario": CUT_IN, "terminate_on_collision": False,
                                    "stop_at_incident": ["speed"]})
    assert drive(env, NoReaction(env, 20.0))["termination_reason"] == "scenario_end"


def test_batched_scenarios_equal_single_envs_per_env():
    """A scenario per env through reset options (and none for env 1): each env of the batch
    is the single env with that scenario, step for step, bit for bit."""
    options = [CUT_IN, None, library_path("event_closed_lane")]
    config = {"terminate_on_collision": False, "road_events": {"object_slots": 20}}
    vec = gym.make_vec(HIGHWAY, num_envs=3, vectorization_mode="vector_entry_point",
                       config=config)
    singles = [gym.make(HIGHWAY, config=config) for _ in options]
    drivers = [NoReaction(env, 20.0) for env in singles]
    batch_obs, _ = vec.reset(seed=[0, 1, 2], options={"scenario": options})
    single_obs = [env.reset(seed=i, options={"scenario": scenario})[0]
                  for i, (env, scenario) in enumerate(zip(singles, options, strict=True))]
    for _ in range(95):  # CUT_IN lasts 6 s, 100 steps of 0.06 s
        actions = [driver.act(obs) for driver, obs in zip(drivers, single_obs, strict=True)]
        for i, obs in enumerate(single_obs):
            rows = batch_obs["sensor_fusion"][i]
            assert np.array_equal(rows, obs["sensor_fusion"])
            assert np.array_equal(batch_obs["ego"][i], obs["ego"])
        batch_obs, _, _, _, _ = vec.step(np.stack(actions))  # full paths, no padding
        single_obs = [env.step(action)[0] for env, action in zip(singles, actions, strict=True)]
    vec.close()


@pytest.mark.parametrize("action, shield, passed", [
    ("keep/cruise", True, False), ("keep/cruise", False, False),  # drives into it
    ("keep/hold", True, True), ("keep/hold", False, False),  # the shield brakes in time
    ("keep/slow", False, True)])
def test_behavior_env_runs_scenarios_too(action, shield, passed):
    """The cut-in at the behavior level, one decision held throughout: holding the speed
    hits the car unless the safety shield brakes for it; slowing down misses it."""
    from sdc_gym.stack.highway.decisions import ACTION_NAMES

    env = gym.make("sdc_gym/HighwayLoopBehavior-v0", config={
        "highway": {"scenario": str(library_path("stress_cut_in_10m"))},
        "safety_shield": shield})
    env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = env.step(ACTION_NAMES.index(action))
        if terminated or truncated:
            break
    verdict = info["summary"]["scenario"]
    assert verdict["passed"] is passed, verdict["reason"]
    assert info["termination_reason"] == ("scenario_end" if passed else "collision")


# --------------------------------------------------------------------------- evaluate.py
def test_evaluate_scenario_prints_and_writes_pass_or_fail_with_the_reason(tmp_path):
    import evaluate

    result = evaluate.main(["--scenario", str(library_path("stress_cut_in_10m")),
                            "--agents", "lane_keeping", "fsm_conservative",
                            "--output", str(tmp_path / "run"), "--workers", "1",
                            "--no-progress"])
    rows = {row["agent"]: row for row in result["rows"]}
    assert rows["lane_keeping"]["passed"] is False
    assert rows["lane_keeping"]["reason"].startswith("collision with car at ")
    assert rows["fsm_conservative"]["passed"] is True
    text = (tmp_path / "run" / "scenarios.csv").read_text()
    assert "stress_cut_in_10m,fsm_conservative,0,True,passed: no collision" in text
    with pytest.raises(SystemExit, match="no such file or folder"):
        evaluate.main(["--scenario", str(tmp_path / "none.yaml"), "--output",
                       str(tmp_path / "other"), "--no-progress"])


def test_the_readmes_chain_replays_the_incidents_of_the_latest_run(tmp_path, monkeypatch):
    """README: ``--scenario LIBRARY`` then ``--scenario results/latest/incidents.json``. A
    scenario run writes its incidents too, so the chain replays them (the same collision
    again); a run without incidents writes ``[]`` and the replay says there is nothing."""
    import evaluate

    monkeypatch.chdir(tmp_path)  # results/ and results/latest here
    quick = ["--workers", "1", "--no-progress"]
    first = evaluate.main(["--scenario", str(library_path("stress_cut_in_10m")),
                           "--agents", "lane_keeping", *quick])
    latest = tmp_path / "results" / "latest"
    assert latest.resolve() == first["output"].resolve()
    reports = json.loads((latest / "incidents.json").read_text())
    assert [report["kind"] for report in reports] == ["collision"]
    replay = evaluate.main(["--scenario", "results/latest/incidents.json",
                            "--agents", "lane_keeping", *quick])
    [row] = replay["rows"]
    assert row["scenario"].startswith("0_") and row["passed"] is False
    assert row["reason"].startswith("collision with car at ")
    clean = evaluate.main(["--scenario", str(library_path("stress_cut_in_10m")),
                           "--agents", "fsm_conservative", *quick])
    assert clean["rows"][0]["passed"] is True
    assert (latest / "incidents.json").read_text() == "[]\n"
    with pytest.raises(SystemExit, match="no incidents to replay"):
        evaluate.main(["--scenario", "results/latest/incidents.json", *quick])
