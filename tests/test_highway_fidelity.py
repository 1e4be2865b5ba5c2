"""The highway env as the original simulator's planners see it: every telemetry field and
path rule pinned with a known answer on the original map (``../shared``), from the Unity
source (``CarAIControl.getFrenetFrame``, ``perfect_controller``, ``CommandServer``,
``CarTraffic.example_sensor_fusion``; see docs/highway_fidelity.md)."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the ids)
from sdc_gym.bridge import encode_telemetry, lockstep_config
from sdc_gym.config import ConfigError
from sdc_gym.geometry.original_frenet import OriginalFrenet
from sdc_gym.sensors.highway_sensors import telemetry_message
from sdc_gym.traffic import HighwayTraffic, TrafficConfig
from sdc_gym.units import MPS_TO_MPH
from tests.conftest import HIGHWAY_MAP_FILE
from tests.planners.map_helpers import MapFile
from tests.planners.walkthrough_planner import Walkthrough

ORIGINAL = str(HIGHWAY_MAP_FILE)
ORIGINAL_LOOP = 6945.554  # the file's polyline: last s 6914.149 + the closing chord 31.405


def make(**config):
    return gym.make("sdc_gym/HighwayLoop-v0", config={"map": ORIGINAL, **config})


def telemetry_of(info):
    """The telemetry as a planner parses it from the wire."""
    return json.loads(encode_telemetry(info["telemetry"])[len('42["telemetry",'):-1])


def test_first_telemetry_on_the_original_map_is_the_originals_start():
    env = make(traffic={"car_count": 0})
    _, info = env.reset(seed=0)
    assert encode_telemetry(info["telemetry"]) == (
        '42["telemetry",{"x":909.48,"y":1128.67,"yaw":0,"speed":0,"s":124.8337,'
        '"d":6.164966,"previous_path_x":[],"previous_path_y":[],"end_path_s":0,'
        '"end_path_d":0,"sensor_fusion":[]}]')


def test_the_start_with_traffic_is_within_the_issues_tolerance_and_the_observation_exact():
    env = make()
    obs, info = env.reset(seed=3)
    t = telemetry_of(info)
    assert t["yaw"] == 0.0 and t["speed"] == 0.0
    assert t["s"] == pytest.approx(124.8336, abs=0.001)
    assert t["d"] == pytest.approx(6.164833, abs=0.001)
    assert [row[0] for row in t["sensor_fusion"]] == list(range(12))
    # The Dict observation keeps the env's exact frame (our agents read it).
    assert obs["ego"][2] == pytest.approx(124.9356, abs=1e-3)
    assert obs["ego"][3] == pytest.approx(6.0984, abs=1e-3)
    assert obs["ego"][4] == 0.0  # the car faces +x, like the original's, ...
    exact = make(frenet="exact")
    _, info = exact.reset(seed=3)
    assert telemetry_of(info)["s"] == pytest.approx(124.9356, abs=1e-3)  # ... on request


def test_yaw_stays_0_until_a_path_turns_the_car_and_our_maps_start_along_the_road():
    env = make(traffic={"car_count": 0}, **lockstep_config(1))
    _, info = env.reset(seed=0)
    # A path heading 10 degrees left. In the lock-step it arrives as the step ends: the
    # car has not moved and still faces +x. The next frame puts it on point 0 (ahead of
    # the car, so kept) facing point 1.
    heading = math.radians(10.0)
    path = [(909.48 + 0.3 * k * math.cos(heading), 1128.67 + 0.3 * k * math.sin(heading))
            for k in range(1, 20)]
    _, _, _, _, info = env.step(path)
    assert telemetry_of(info)["yaw"] == 0
    _, _, _, _, info = env.step(path)
    assert telemetry_of(info)["yaw"] == pytest.approx(10.0, abs=1e-4)
    builtin = gym.make("sdc_gym/HighwayLoop-v0")
    obs, info = builtin.reset(seed=0)
    road = builtin.unwrapped.road
    assert obs["ego"][4] == pytest.approx(float(road.reference.heading(road.start_s)), abs=1e-6)


def test_the_fixed_sign_point_lies_left_of_every_chord_of_the_original_map():
    """The original's d is negative when the point is nearer (1000, 2000) than its
    projection; on its map that is "left of the chord", which OriginalFrenet tests."""
    w = np.loadtxt(HIGHWAY_MAP_FILE)
    chord = np.roll(w[:, :2], -1, axis=0) - w[:, :2]
    to_point = np.array([1000.0, 2000.0]) - w[:, :2]
    cross = chord[:, 0] * to_point[:, 1] - chord[:, 1] * to_point[:, 0]
    assert (cross / np.hypot(*chord.T) > 750.0).all()  # left, and far: |d| < 1500 agrees


def test_end_path_is_extrapolated_along_the_chord_under_the_ego_car():
    """The ego car's script converts the path's end from its own closest waypoint: an end
    beyond the next waypoint is projected on the ego's chord, extended."""
    w = np.loadtxt(HIGHWAY_MAP_FILE)
    frenet = OriginalFrenet(w)
    ego = w[4, :2] + 0.25 * (w[5, :2] - w[4, :2])  # a quarter along chord 4 -> 5
    end = w[6, :2] + np.array([0.0, -6.0])          # past waypoint 5, right of the road
    s, d = frenet.convert(end, ego)
    chord = w[5, :2] - w[4, :2]
    along = np.dot(end - w[4, :2], chord) / np.dot(chord, chord)
    assert along > 1.0  # beyond the next waypoint
    assert s[0] == pytest.approx(w[4, 2] + along * np.hypot(*chord), abs=1e-9)
    # Its own closest waypoint would give the polyline's s, a few cm less here.
    own_s, _ = frenet.convert(end)
    assert own_s[0] == pytest.approx(w[5, 2] + np.dot(end - w[5, :2], w[6, :2] - w[5, :2])
                                     / np.hypot(*(w[6, :2] - w[5, :2])), abs=1e-9)
    offset = end - w[4, :2]
    cross = chord[0] * offset[1] - chord[1] * offset[0]
    assert d[0] == pytest.approx(abs(cross) / np.hypot(*chord)) and cross < 0  # right: d > 0


def test_a_lap_of_telemetry_keeps_s_below_the_files_loop_and_ids_in_their_slots():
    env = make(**lockstep_config(3))
    _, info = env.reset(seed=1)
    planner = Walkthrough(MapFile.load(ORIGINAL))
    ego_s, end_s, car_s, ids, ends_near_seam = [], [], [], set(), 0
    while True:
        t = telemetry_of(info)
        ego_s.append(t["s"])
        if t["previous_path_x"]:
            end_s.append(t["end_path_s"])
            ends_near_seam += t["end_path_s"] >= ORIGINAL_LOOP
        car_s += [row[5] for row in t["sensor_fusion"]]
        ids |= {row[0] for row in t["sensor_fusion"]}
        _, _, terminated, truncated, info = env.step(np.column_stack(planner.plan(t)))
        if terminated or truncated:
            break
    assert info["summary"]["laps"] == 1
    assert 0.0 <= min(ego_s) and max(ego_s) < ORIGINAL_LOOP
    # A car right of the centre line just before the seam, nearest the first waypoint
    # but projected on the closing chord, can read a few cm past the loop (the rule).
    assert 0.0 <= min(car_s) and max(car_s) < ORIGINAL_LOOP + 0.2
    assert ids == set(range(12))
    # end_path_s passes the file's loop only in the few messages whose path ends past
    # the seam while the ego is still nearest the last waypoint (the original's rule).
    assert max(end_s) < ORIGINAL_LOOP + 25.0 and ends_near_seam < 20


def test_sensor_fusion_ids_stay_in_their_slots_over_ten_laps_of_recycling(original_highway):
    road = original_highway
    traffic = HighwayTraffic(road, TrafficConfig(), dt=0.02)
    rng = np.random.default_rng(0)
    traffic.reset(rng, road.start_s, road.start_d, 22.0)
    frames, ego_s, speed = 250, road.start_s, 22.0  # 5 s chunks at 22 m/s
    for _ in range(int(10 * road.length / (speed * frames * 0.02)) + 1):
        s = ego_s + speed * 0.02 * np.arange(1, frames + 1)
        traffic.advance(frames, s, np.full(frames, road.start_d), np.full(frames, speed))
        ego_s = float(s[-1])
        assert np.array_equal(traffic.ids, np.arange(12))
    assert ego_s - road.start_s > 10 * road.length
    assert traffic.spawn_count.sum() > 100  # the cars were recycled, their ids reused


def test_numbers_are_32_bit_floats_printed_with_7_digits():
    # 904.09745 prints 904.0974 from a double but 904.0975 from the float the original
    # keeps (904.0974731...f rounds up).
    message = telemetry_message(904.09745, 1.0, 0.0, 0.0, 1.0, 1.0, np.zeros((0, 2)), 0.0,
                                0.0, np.zeros((0, 7)))
    assert message["x"] == 904.0975
    assert f"{904.09745:.7g}" == "904.0974"


def test_units_yaw_degrees_counter_clockwise_speed_mph_velocities_mps():
    env = make(latency_steps=0, traffic={"car_count": 1})
    env.reset(seed=0)
    heading = math.radians(120.0)  # any direction: yaw is the heading in [0, 360)
    path = [(909.48 + 0.4 * k * math.cos(heading), 1128.67 + 0.4 * k * math.sin(heading))
            for k in range(1, 30)]
    obs, _, _, _, info = env.step(path)
    t = telemetry_of(info)
    assert t["yaw"] == pytest.approx(120.0, abs=1e-4)
    assert t["speed"] == pytest.approx(0.4 / 0.02 * MPS_TO_MPH, rel=1e-6)  # 44.74 mph
    _, _, _, vx, vy, _, _ = t["sensor_fusion"][0]
    assert math.hypot(vx, vy) == pytest.approx(float(np.hypot(*obs["sensor_fusion"][0][3:5])),
                                               rel=1e-5)


class TestPathRules:
    """``perfect_controller``: adopting a path, consuming it, its last point."""

    @staticmethod
    def env():
        env = make(traffic={"car_count": 0}, steps_per_action=1, latency_steps=0)
        env.reset(seed=0)
        return env

    @staticmethod
    def line(count, start=0.0, step=0.4):
        return np.array([(909.48 + start + step * k, 1128.67) for k in range(count)])

    def test_a_first_point_ahead_of_the_car_is_driven_to(self):
        env = self.env()
        path = self.line(10, start=0.5)
        obs, *_ = env.step(path)
        assert obs["ego"][0] == pytest.approx(path[0, 0], abs=1e-4)  # behind the path: kept
        assert obs["previous_path_count"] == 9

    def test_a_first_point_exactly_under_the_car_is_dropped(self):
        env = self.env()
        obs, *_ = env.step(self.line(10))  # point 0 is the car's position, exactly
        assert obs["ego"][0] == pytest.approx(909.48 + 0.4, abs=1e-4)
        assert obs["previous_path_count"] == 8

    def test_the_nearest_point_is_dropped_when_it_is_not_the_first(self):
        env = self.env()
        path = self.line(10, start=-1.5, step=1.0)  # nearest: point 1 (0.5 m ahead) or 2
        obs, *_ = env.step(path)
        # Points 0..1 go (1 is the nearest, 0.5 m behind... dropped although not under
        # the car); the car steps on point 2.
        assert obs["ego"][0] == pytest.approx(path[2, 0], abs=1e-4)
        assert obs["previous_path_count"] == 7

    def test_the_last_point_is_removed_without_moving_the_car(self):
        env = self.env()
        path = self.line(3, start=0.4)
        # Resent each frame: onto point 0 (ahead, kept), then point 1 (point 0 under the
        # car is dropped), then the nearest, point 1, is dropped and one point is left.
        for _ in range(2):
            obs, _, _, _, info = env.step(path)
        assert obs["previous_path_count"] == 1 and obs["ego"][0] == pytest.approx(path[1, 0])
        obs, _, _, _, info = env.step(path)
        t = telemetry_of(info)
        assert obs["previous_path_count"] == 0 and t["previous_path_x"] == []
        assert t["end_path_s"] == 0 and t["end_path_d"] == 0 and t["speed"] == 0
        assert obs["ego"][0] == pytest.approx(path[1, 0])  # never reached point 2

    def test_with_a_path_end_path_is_its_last_points_frenet(self):
        env = self.env()
        path = self.line(30, start=0.4)
        obs, _, _, _, info = env.step(path)
        t = telemetry_of(info)
        frenet = env.unwrapped.road.original_frenet
        s, d = frenet.convert(path[-1], obs["ego"][:2].astype(np.float64))
        assert t["end_path_s"] == pytest.approx(float(s[0]), abs=1e-3)
        assert t["end_path_d"] == pytest.approx(float(d[0]), abs=1e-4)
        assert t["previous_path_x"] == pytest.approx(path[1:, 0].tolist(), abs=1e-3)


def test_frenet_setting_is_checked():
    with pytest.raises(ConfigError, match=r"frenet.*'original', 'exact'"):
        make(frenet="polyline")


def test_the_walkthrough_drives_off_its_lane_if_the_first_yaw_were_359_55():
    """With the original's yaw 0 the walkthrough's degrees-as-radians anchor is harmless;
    with the 359.55 degrees of the road's heading there, its first spline points the car
    north across the lanes (the failure the real planners showed)."""

    def leaves_lane(first_yaw):
        env = make(traffic={"car_count": 0}, **lockstep_config(3))
        obs, info = env.reset(seed=0)
        planner = Walkthrough(MapFile.load(ORIGINAL))
        lowest = highest = obs["ego"][3]
        for step in range(150):
            t = telemetry_of(info)
            if step == 0:
                t["yaw"] = first_yaw
            obs, _, _, _, info = env.step(np.column_stack(planner.plan(t)))
            lowest, highest = min(lowest, obs["ego"][3]), max(highest, obs["ego"][3])
        return lowest < 4.0 or highest > 8.0, info

    left, info = leaves_lane(359.5473)
    assert left
    stayed, info = leaves_lane(0.0)
    assert not stayed and info["incidents"] == 0
