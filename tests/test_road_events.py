"""Road events and vehicle kinds: traffic reacts to closed lanes, cargo and animals; the
sensors report them; the renderer draws closed lanes; random events come at seeded rates;
with object slots and no events the random traffic is the default one, to the bit."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from sdc_gym.render.highway_renderer import CONE_COLOR, ZONE_COLOR
from sdc_gym.traffic.vehicle_types import KIND_INDEX, KINDS
from tests.planners.no_reaction import NoReaction

HIGHWAY = "sdc_gym/HighwayLoop-v0"


def run(env: gym.Env, driver: NoReaction, steps: int, seed: int = 0,
        options: dict | None = None) -> list[tuple[dict, dict]]:
    observation, info = env.reset(seed=seed, options=options)
    frames = [(observation, info)]
    for _ in range(steps):
        observation, _, terminated, truncated, info = env.step(driver.act(observation))
        frames.append((observation, info))
        if terminated or truncated:
            break
    return frames


def test_object_slots_without_events_leave_the_random_traffic_as_it_was():
    plain = gym.make(HIGHWAY)
    slotted = gym.make(HIGHWAY, config={"road_events": {"object_slots": 6}})
    a = run(plain, NoReaction(plain, 15.0), 150, seed=3)
    b = run(slotted, NoReaction(slotted, 15.0), 150, seed=3)
    for (first, _), (second, info) in zip(a, b, strict=True):
        assert np.array_equal(second["sensor_fusion"][:12], first["sensor_fusion"])
        assert not second["sensor_fusion_mask"][12:].any()  # parked: not sensed
        assert np.array_equal(second["ego"], first["ego"])
        assert info["road_events"] == []


def test_random_road_events_come_at_seeded_rates_and_are_sensed():
    config = {"road_events": {"object_slots": 40, "closed_lane_per_km": 1.5,
                              "cargo_per_km": 3.0, "animal_per_km": 3.0},
              "terminate_on_collision": False}
    env = gym.make(HIGHWAY, config=config)
    frames = run(env, NoReaction(env, 22.0), 700, seed=5)
    seen = {}
    for observation, info in frames:
        for event in info["road_events"]:
            seen.setdefault((event["kind"], round(event["s_start"], 6)), event)
            rows = observation["sensor_fusion"]
            sensed = rows[observation["sensor_fusion_mask"] > 0, 0].astype(int).tolist()
            assert set(event["ids"]) <= set(sensed)  # every object a sensor-fusion row
            assert min(event["ids"]) >= 12  # after the cars' ids
    kinds = {kind for kind, _ in seen}
    assert kinds == {"closed_lane", "cargo", "animal"}, kinds
    # Events appear beyond the sensors' reach ahead of the ego (260-340 m by default).
    assert len(seen) >= 4
    again = run(gym.make(HIGHWAY, config=config), NoReaction(env, 22.0), 700, seed=5)
    assert [info["road_events"] for _, info in again] == [info["road_events"]
                                                          for _, info in frames]
    other = run(gym.make(HIGHWAY, config=config), NoReaction(env, 22.0), 700, seed=6)
    assert [info["road_events"] for _, info in other] != [info["road_events"]
                                                          for _, info in frames]


def test_cargo_is_a_standing_row_and_traffic_stops_behind_it():
    scenario = {"duration": 20.0, "ego": {"lane": 0, "speed": 10.0},
                "cars": [{"name": "follower", "lane": 2, "gap": 20, "speed": 15}],
                "road_events": [{"kind": "cargo", "lane": 2, "gap": 150, "offset": -0.5}]}
    env = gym.make(HIGHWAY, config={"scenario": scenario})
    frames = run(env, NoReaction(env, 10.0), 330)
    observation, info = frames[-1]
    event = info["road_events"][0]
    assert event["kind"] == "cargo" and event["lane"] == 2 and event["size"] == [1.4, 1.2]
    cargo = observation["sensor_fusion"][event["ids"][0]]
    follower = observation["sensor_fusion"][0]
    assert cargo[3] == 0.0 and cargo[4] == 0.0  # vx, vy: it stands
    assert cargo[6] == pytest.approx(9.5, abs=1e-4)  # 0.5 m left of lane 2's centre
    assert np.hypot(follower[3], follower[4]) < 0.3  # the car stopped behind it
    gap = cargo[5] - follower[5]  # centre to centre
    assert 0.5 * 1.4 + 0.5 * KINDS[0].length < gap < 15.0


def test_traffic_merges_out_of_a_closed_lane_and_passes_it():
    scenario = {"duration": 30.0, "ego": {"lane": 0, "speed": 12.0},
                "cars": [{"name": "merging", "lane": 1, "gap": 30, "speed": 16,
                          "lane_changes": True}],
                "road_events": [{"kind": "closed_lane", "lane": 1, "gap": 150,
                                 "length": 100}]}
    env = gym.make(HIGHWAY, config={"scenario": scenario})
    frames = run(env, NoReaction(env, 12.0), 480)
    zone = frames[0][1]["road_events"][0]
    assert zone["kind"] == "closed_lane" and len(zone["ids"]) == 13  # 8 m pieces
    for observation, _ in frames:
        car = observation["sensor_fusion"][0]
        inside = zone["s_start"] - 3.0 < car[5] < zone["s_end"] + 3.0
        assert not (inside and 4.0 < car[6] < 8.0), car  # never in the closed stretch
    assert frames[-1][0]["sensor_fusion"][0][5] > zone["s_end"]  # merged and went past


def test_an_animal_walks_across_the_lanes():
    scenario = {"duration": 20.0, "ego": {"lane": 0, "speed": 5.0},
                "road_events": [{"kind": "animal", "gap": 120, "speed": 2.0,
                                 "from_d": -1.0, "to_d": 13.0, "when": {"time": 1.0}}]}
    env = gym.make(HIGHWAY, config={"scenario": scenario, "terminate_on_collision": False})
    frames = run(env, NoReaction(env, 5.0), 200)
    ids = frames[0][1]["road_events"][0]["ids"]
    d = [observation["sensor_fusion"][ids[0], 6] for observation, _ in frames]
    t = [info["time"] for _, info in frames]
    walked = [(time, value) for time, value in zip(t, d, strict=True) if 1.3 < time < 7.0]
    for time, value in walked:  # 2 m/s from d = -1 once the decision at 1.0 s starts it
        assert value == pytest.approx(-1.0 + 2.0 * (time - 1.0), abs=2.0 * 0.2 + 1e-6)
    assert d[0] == pytest.approx(-1.0) and max(d) == pytest.approx(13.0)


def test_closed_lanes_are_drawn_with_cones():
    scenario = {"duration": 5.0, "ego": {"lane": 0, "speed": 10.0},
                "road_events": [{"kind": "closed_lane", "lane": 1, "gap": 15,
                                 "length": 60}]}
    env = gym.make(HIGHWAY, render_mode="rgb_array", config={"scenario": scenario})
    env.reset(seed=0)
    image = env.render()
    plain = gym.make(HIGHWAY, render_mode="rgb_array")
    plain.reset(seed=0)
    for color, least in ((CONE_COLOR, 20), (ZONE_COLOR, 200)):
        assert np.all(image == color, axis=-1).sum() >= least
        assert np.all(plain.render() == color, axis=-1).sum() == 0


def test_buses_come_by_vehicle_mix_and_not_by_default():
    env = gym.make(HIGHWAY, config={"traffic": {"vehicle_mix": {"bus": 1.0}}})
    env.reset(seed=0)
    types = env.unwrapped.traffic.type_index
    assert np.all(types == KIND_INDEX["bus"])
    assert np.all(env.unwrapped.traffic.length == KINDS[KIND_INDEX["bus"]].length)
    default = gym.make(HIGHWAY)
    counts = set()
    for seed in range(10):
        default.reset(seed=seed)
        counts |= set(default.unwrapped.traffic.type_index.tolist())
    assert KIND_INDEX["bus"] not in counts and KIND_INDEX["semi"] not in counts
