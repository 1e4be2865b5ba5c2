"""Open roads: the reference line, the telemetry's polyline rule, maps, traffic, episode ends.

Known answers: constructed roads (a straight, a circular arc) with exact s, d, lengths and
curvature; the Udacity-Bosch Challenge's maps (``../shared/data/udacity/bosch``), whose s
column is the sum of chord lengths the original's telemetry rule adds up.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_gym.config import ConfigError
from sdc_gym.geometry.open_line import open_period
from sdc_gym.geometry.reference_line import ReferenceLine, ReferenceLineError
from sdc_gym.road.highway_map import (
    OPEN_START_S,
    HighwayMap,
    MapFormatError,
    load_highway_map,
    write_highway_map,
)
from sdc_gym.traffic import TrafficConfig
from sdc_gym.traffic.batch import TrafficBatch
from tests.conftest import HIGHWAY_MAP_FILE, UDACITY

BOSCH1 = UDACITY / "bosch" / "highway_map_bosch1.csv"
BOSCH_FINAL = UDACITY / "bosch" / "highway_map_bosch1_final.csv"


def _straight(length: float = 1000.0, step: float = 50.0) -> np.ndarray:
    x = np.arange(0.0, length + 0.5 * step, step)
    return np.column_stack([x + 100.0, np.full_like(x, 500.0)])


def _arc(radius: float, degrees: float, step: float = 20.0) -> np.ndarray:
    count = int(radius * math.radians(degrees) / step) + 1
    angle = np.linspace(0.0, math.radians(degrees), count)
    # Counter-clockwise from the bottom of the circle: heading +x at the start.
    return np.column_stack([1000.0 + radius * np.sin(angle),
                            1000.0 + radius * (1.0 - np.cos(angle))])


# ---------------------------------------------------------------------- reference line
def test_open_straight_line_has_s_from_the_first_point_and_no_wrap() -> None:
    line = ReferenceLine(_straight(), closed=False)
    assert not line.closed
    assert line.end_s == pytest.approx(1000.0, abs=1e-9)
    assert line.length == open_period(line.end_s) == 4096.0
    np.testing.assert_allclose(line.position([0.0, 250.0, 1000.0]),
                               [[100.0, 500.0], [350.0, 500.0], [1100.0, 500.0]], atol=1e-9)
    # d grows to the right of travel (+x): towards -y.
    s, d = line.to_frenet(np.array([[600.0, 497.0], [1099.0, 503.0]]))
    np.testing.assert_allclose(s, [500.0, 999.0], atol=1e-9)
    np.testing.assert_allclose(d, [3.0, -3.0], atol=1e-9)
    # No wrap: the far end is 980 m ahead of the start's neighbourhood, not 20 m behind.
    assert float(line.s_difference(990.0, 10.0)) == pytest.approx(980.0, abs=1e-9)
    assert float(line.s_difference(10.0, 990.0)) == pytest.approx(-980.0, abs=1e-9)


def test_open_line_clamps_at_its_start_and_runs_out_straight_past_its_end() -> None:
    line = ReferenceLine(_arc(600.0, 60.0), closed=False)
    end_heading = float(line.heading(line.end_s))
    # A natural end (zero curvature) turns a little less than the arc: 0.6 degrees here.
    assert end_heading == pytest.approx(math.radians(60.0), abs=math.radians(0.7))
    # Past the end: a straight run-out along the end tangent, zero curvature.
    past = line.position(line.end_s + 100.0) - line.position(line.end_s)
    np.testing.assert_allclose(past, 100.0 * np.array([math.cos(end_heading),
                                                       math.sin(end_heading)]), atol=1e-6)
    assert float(line.curvature(line.end_s + 50.0)) == 0.0
    # 60 m down the run-out, 2 m right of it: s = end + 60, d = 2.
    end_xy = line.position(line.end_s)
    right = np.array([math.sin(end_heading), -math.cos(end_heading)])
    x, y = end_xy + 60.0 * np.array([math.cos(end_heading), math.sin(end_heading)]) + 2 * right
    s, d = line.project(np.array([x]), np.array([y]), np.array([line.end_s]))
    assert s[0] == pytest.approx(line.end_s + 60.0, abs=1e-6)
    assert d[0] == pytest.approx(2.0, abs=1e-6)
    # Behind the start: the projection clamps at s = 0 (it would wrap on a loop), d is
    # the offset along the start's right normal.
    s, d = line.project(np.array([990.0]), np.array([997.0]), np.array([1.0]))
    offset = np.array([990.0, 997.0]) - line.position(0.0)
    assert s[0] == 0.0 and d[0] == pytest.approx(float(offset @ line.normal(0.0)), abs=1e-9)
    s, d = line.to_frenet(np.array([[990.0, 997.0]] * 30))  # the array path agrees
    np.testing.assert_array_equal(s, 0.0)


def test_open_arc_length_and_curvature_are_the_circle_s() -> None:
    line = ReferenceLine(_arc(500.0, 90.0, step=10.0), closed=False)
    assert line.end_s == pytest.approx(500.0 * math.pi / 2.0, abs=0.05)
    middle = np.linspace(0.2, 0.8, 7) * line.end_s
    np.testing.assert_allclose(line.curvature(middle), 1.0 / 500.0, rtol=2e-3)


def test_open_line_refuses_too_few_or_repeated_points() -> None:
    with pytest.raises(ReferenceLineError, match="at least 3 waypoints; got 2"):
        ReferenceLine([[0.0, 0.0], [100.0, 0.0]], closed=False)
    with pytest.raises(ReferenceLineError, match="waypoints 1 and 2 coincide"):
        ReferenceLine([[0.0, 0.0], [100.0, 0.0], [100.0, 0.0], [200.0, 0.0]], closed=False)


# ---------------------------------------------------------------------- the Bosch maps
@pytest.mark.parametrize("path, rows, last_s", [(BOSCH1, 133, 5104.62105369568),
                                                (BOSCH_FINAL, 251, 5128.30712127686)])
def test_bosch_maps_load_as_open_roads_by_the_ends_rule(path, rows, last_s) -> None:
    road = load_highway_map(path)
    assert not road.closed and len(road.waypoints) == rows
    assert road.waypoints[-1, 2] == last_s
    # The smooth line is a little longer than the chords it rounds.
    assert last_s < road.end_s < last_s + 2.0
    assert road.length > 2.0 * road.end_s  # the period: nothing comes around
    assert (road.start_s, road.start_d) == (OPEN_START_S, 6.0)
    assert road.start_heading() == pytest.approx(float(road.reference.heading(OPEN_START_S)))
    # The file's first and last rows say (dx, dy) = (1, 0); the road's normal there is
    # what the rows next to them say (about 0, -1 at the start).
    raw = np.loadtxt(path)
    assert raw[0, 3:].tolist() == raw[-1, 3:].tolist() == [1.0, 0.0]
    for row, neighbour in ((0, 1), (-1, -2)):
        assert road.waypoints[row, 3:] @ raw[neighbour, 3:] > math.cos(math.radians(10.0))
    np.testing.assert_array_equal(road.waypoints[1:-1], raw[1:-1])  # the rest as read


def test_bosch_telemetry_rule_s_at_both_ends_and_no_wrap() -> None:
    road = load_highway_map(BOSCH1)
    frenet = road.original_frenet
    w = road.waypoints
    assert frenet.loop_length == w[-1, 2]  # no closing chord
    # Every waypoint reads the file's own s (the sum of chords, which the file has in
    # 32-bit floats of the unrounded points: within 1 mm) and d = 0.
    s, d = frenet.convert(w[:, :2])
    np.testing.assert_allclose(s, w[:, 2], atol=1e-3)
    np.testing.assert_allclose(d, 0.0, atol=1e-9)
    # 10 m past the last waypoint along the last chord: s runs on, it does not wrap to 0.
    # (The rule adds to the previous waypoint's s: the last chord's start, s[-2].)
    last_chord = np.hypot(*(w[-1, :2] - w[-2, :2]))
    chord = (w[-1, :2] - w[-2, :2]) / last_chord
    s, d = frenet.convert(w[-1, :2] + 10.0 * chord)
    assert s[0] == pytest.approx(w[-2, 2] + last_chord + 10.0, abs=1e-9)
    assert abs(d[0]) < 1e-9
    # 6 m right of the first chord, 5 m along it: s = 5, d = 6.
    first = (w[1, :2] - w[0, :2]) / np.hypot(*(w[1, :2] - w[0, :2]))
    right = np.array([first[1], -first[0]])
    s, d = frenet.convert(w[0, :2] + 5.0 * first + 6.0 * right)
    assert s[0] == pytest.approx(5.0, abs=1e-9) and d[0] == pytest.approx(6.0, abs=1e-9)
    # 3 m behind the first waypoint: the original's |projection| (s never negative).
    s, _ = frenet.convert(w[0, :2] - 3.0 * first)
    assert s[0] == pytest.approx(3.0, abs=1e-9)


# ---------------------------------------------------------------------- bad open maps
def _write(tmp_path, name: str, xy: np.ndarray) -> str:
    road = HighwayMap.from_waypoints(name, xy, closed=False)
    path = tmp_path / f"{name}.csv"
    write_highway_map(road, path)
    return str(path)


def test_bad_open_maps_are_clear_errors(tmp_path) -> None:
    with pytest.raises(MapFormatError, match="at least 3 waypoints, got 2"):
        path = tmp_path / "two.csv"
        path.write_text("0 0 0 0 -1\n600 0 600 0 -1\n")
        load_highway_map(path, road="open")
    short = _write(tmp_path, "short", _straight(300.0))
    with pytest.raises(MapFormatError, match=r"the open road is 300 m long; it must be in "
                                             r"\[500, 100000\] m"):
        load_highway_map(short)
    # 1.3 turns of a circle: the ends do not meet, but the road runs over itself.
    angle = np.linspace(0.0, 1.3 * 2 * math.pi, 130)
    spiral = np.column_stack([1000 + 300 * np.sin(angle), 1000 + 300 * (1 - np.cos(angle))])
    path = tmp_path / "spiral.csv"
    np.savetxt(path, np.column_stack([spiral, np.arange(130.0), np.zeros(130),
                                      -np.ones(130)]))
    with pytest.raises(MapFormatError, match=r"crosses itself.*must not run over itself"):
        load_highway_map(path)
    with pytest.raises(MapFormatError, match="a loop given as an open road"):
        load_highway_map(HIGHWAY_MAP_FILE, road="open")
    with pytest.raises(MapFormatError, match=r"not a closed loop.*say road: open"):
        load_highway_map(BOSCH1, road="loop")
    with pytest.raises(ConfigError, match=r"config key 'road'.*one of"):
        gym.make("sdc_gym/HighwayLoop-v0", config={"road": "sideways"})
    with pytest.raises(ConfigError, match=r"'distance_target'.*the map is a loop"):
        gym.make("sdc_gym/HighwayLoop-v0", config={"map": "oval", "distance_target": 100.0})
    with pytest.raises(ConfigError, match="the road ends after"):
        gym.make("sdc_gym/HighwayLoop-v0", config={"map": str(BOSCH1),
                                                   "distance_target": 6000.0})


# ---------------------------------------------------------------------- traffic
def test_traffic_spawns_on_the_open_road_and_leaves_at_its_end() -> None:
    road = load_highway_map(BOSCH1)
    batch = TrafficBatch(road, TrafficConfig(car_count=12), envs=2)
    batch.reset_at(0, np.random.default_rng(1), OPEN_START_S, 6.0)
    end = road.end_s - 30.0
    batch.reset_at(1, np.random.default_rng(2), end, 6.0)
    st = batch.state
    # At the start nobody is behind s = 0 (a loop would put half the cars at its far end).
    assert np.all((st.s[0] > 0.0) & (st.s[0] < OPEN_START_S + batch.range))
    assert np.all(st.s[1] <= road.end_s) and np.all(st.s[1] > end - batch.range)
    # The ego stands; 60 s later the cars that drove past the end have left (respawned
    # behind the ego, on the road) and none has wrapped to the road's beginning.
    frames = 50
    for _ in range(60):
        ego_s = np.array([[OPEN_START_S] * frames, [end] * frames])
        batch.advance(frames, ego_s, np.full((2, frames), 6.0), np.zeros((2, frames)))
        assert np.all(st.s[1] > end - batch.range)
        assert np.all(st.s[0] >= 0.0) and np.all(st.s[0] < road.end_s)
    assert np.all(st.s[1] < road.end_s + 60.0)
    assert (st.s[1] < end).sum() >= 6  # they respawned behind the standing ego


# ---------------------------------------------------------------------- the env
def _lane_path(road: HighwayMap, s0: float, speed: float, count: int) -> np.ndarray:
    s = s0 + speed * 0.02 * np.arange(1, count + 1)
    return road.reference.to_xy(s, np.full(count, 6.0))


def test_env_starts_at_rest_in_the_middle_lane_and_ends_at_the_distance_target() -> None:
    env = gym.make("sdc_gym/HighwayLoop-v0", config={
        "map": str(BOSCH1), "distance_target": 30.0, "traffic": {"car_count": 0},
        "path_points": 50, "incident_rules": {"max_acceleration": math.inf,
                                              "max_jerk": math.inf}})
    observation, info = env.reset(seed=0)
    road = env.unwrapped.road
    _, _, s, d, yaw, speed = observation["ego"].tolist()
    assert (s, d, speed) == (OPEN_START_S, 6.0, 0.0)
    assert yaw == pytest.approx(float(road.reference.heading(OPEN_START_S)), abs=1e-6)
    assert info["telemetry"]["s"] == pytest.approx(5.02, abs=0.01)  # the polyline's
    assert info["telemetry"]["d"] == pytest.approx(5.98, abs=0.01)
    # 10 m/s along the lane: 0.2 m a frame; 30 m driven at frame 150.
    path = _lane_path(road, OPEN_START_S, 10.0, 50)
    while True:
        observation, _, terminated, truncated, info = env.step(path)
        if terminated or truncated:
            break
        path = _lane_path(road, float(observation["ego"][2]), 10.0, 50)
    summary = info["summary"]
    assert terminated and summary["termination_reason"] == "distance_target"
    assert summary["is_success"]
    assert summary["goal"]["reached"] and summary["goal"]["distance_target"] == 30.0
    # The first path arrives after the first step's 3 frames (the latency), then 150
    # frames of 0.2 m (in the lane, the bends make it a frame more or less).
    assert summary["goal"]["time"] == pytest.approx((3 + 150) * 0.02, abs=0.025)
    assert summary["goal"]["driven"] >= 30.0


def test_env_ends_at_the_road_end() -> None:
    road = load_highway_map(BOSCH_FINAL)
    start = road.end_s - 20.0
    env = gym.make("sdc_gym/HighwayLoop-v0", config={
        "map": str(BOSCH_FINAL), "start_s": start, "traffic": {"car_count": 4},
        "incident_rules": {"max_acceleration": math.inf, "max_jerk": math.inf}})
    observation, _ = env.reset(seed=3)
    for _ in range(100):
        path = _lane_path(road, float(observation["ego"][2]), 10.0, 50)
        observation, _, terminated, truncated, info = env.step(path)
        if terminated or truncated:
            break
    assert info["summary"]["termination_reason"] == "road_end"
    assert info["summary"]["goal"]["end_s"] == road.end_s
    assert info["summary"]["is_success"]
    # The telemetry's s past the file's last s: no wrap to 0.
    assert info["telemetry"]["s"] > road.waypoints[-1, 2] - 1.0


def test_the_final_preset_places_the_same_traffic_whatever_the_seed() -> None:
    import yaml

    from tests.test_batched import ROOT

    preset = yaml.safe_load((ROOT / "configs" / "highway_bosch_final.yaml").read_text())
    config = {**preset["config"], "map": str(BOSCH_FINAL),
              "scenario": str(ROOT / preset["config"]["scenario"])}
    env = gym.make(preset["env"], config=config)
    first, _ = env.reset(seed=0)
    again, _ = env.reset(seed=123)
    for key, value in first.items():
        np.testing.assert_array_equal(value, again[key])
    scenario = yaml.safe_load(Path(config["scenario"]).read_text())
    np.testing.assert_array_equal(np.sort(first["sensor_fusion"][:, 5]),
                                  np.sort([float(car["s"]) for car in scenario["cars"]]))
    assert first["ego"][2:4].tolist() == [OPEN_START_S, 6.0]
