"""The original's wire format (sdc_gym.bridge.protocol) and map export, without processes."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the ids)
from sdc_agents.lane_keeping import LaneKeepingDriver
from sdc_gym.bridge import (
    EmptyPath,
    MalformedReply,
    ManualReply,
    NonFinitePoint,
    decode_reply,
    encode_telemetry,
    export_highway_map,
    lockstep_config,
)
from sdc_gym.bridge.export_map import main as export_main
from sdc_gym.bridge.protocol import MANUAL_REPLY, MANUAL_TELEMETRY, TELEMETRY_FIELDS
from sdc_gym.road.builtin_highways import get_highway_map
from sdc_gym.road.highway_map import load_highway_map
from tests.conftest import HIGHWAY_MAP_FILE
from tests.planners.protocol_planner import Planner, Straight, has_data

START = {"x": 909.48, "y": 1128.67, "yaw": 0.0, "speed": 0.0, "s": 124.8336,
         "d": 6.164833, "previous_path_x": [], "previous_path_y": [], "end_path_s": 0.0,
         "end_path_d": 0.0, "sensor_fusion": [[0, 1000.5, 1128.7, 10.25, -0.0, 200.1234567, 6.0]]}


def test_telemetry_frame_is_the_originals_flat_object_with_7_significant_digits():
    assert encode_telemetry(START) == (
        '42["telemetry",{"x":909.48,"y":1128.67,"yaw":0,"speed":0,"s":124.8336,'
        '"d":6.164833,"previous_path_x":[],"previous_path_y":[],"end_path_s":0,'
        '"end_path_d":0,"sensor_fusion":[[0,1000.5,1128.7,10.25,0,200.1235,6]]}]')
    message = dict(START, previous_path_x=[1.0 / 3.0, 1234567.89],
                   previous_path_y=[2e-7, -5.5])
    text = encode_telemetry(message)
    # C#'s float.ToString(): an upper-case exponent, no sign on a zero.
    assert '"previous_path_x":[0.3333333,1234568],"previous_path_y":[2E-07,-5.5]' in text


def test_env_telemetry_survives_the_templates_hasData_and_json():
    env = gym.make("sdc_gym/HighwayLoop-v0")
    driver = LaneKeepingDriver(env.unwrapped.road)
    observation, info = env.reset(seed=3)
    for _ in range(40):
        observation, _, _, _, info = env.step(driver.act(observation))
    telemetry = dict(info["telemetry"])
    text = encode_telemetry(telemetry)
    assert "null" not in text and text.count("}") == 1  # flat: hasData cuts at the first }
    event, payload = json.loads(has_data(text))
    assert event == "telemetry" and list(payload) == list(TELEMETRY_FIELDS)
    assert len(payload["previous_path_x"]) == len(telemetry["previous_path_x"]) > 0
    assert len(payload["sensor_fusion"]) == 12
    flat_sent = np.concatenate([np.ravel(payload[name]) for name in TELEMETRY_FIELDS])
    flat_env = np.concatenate([np.ravel(telemetry[name]) for name in TELEMETRY_FIELDS])
    np.testing.assert_allclose(flat_sent, flat_env, rtol=6e-7, atol=1e-12)
    assert all(isinstance(row[0], int) for row in payload["sensor_fusion"])


def test_telemetry_that_the_planners_could_not_read_is_refused():
    with pytest.raises(ValueError, match="'speed' holds a non-finite"):
        encode_telemetry(dict(START, speed=math.nan))
    with pytest.raises(ValueError, match="lacks the field"):
        encode_telemetry({key: value for key, value in START.items() if key != "end_path_d"})


def test_template_planner_answers_manual_telemetry_with_manual():
    planner = Planner(Straight(), "none", 0)
    assert planner.on_message(MANUAL_TELEMETRY) == MANUAL_REPLY
    path = decode_reply(planner.on_message(encode_telemetry(START)))
    # 10 points east along yaw 0 at 10 m/s, starting on the car.
    np.testing.assert_allclose(path[:, 0], 909.48 + 0.2 * np.arange(10))
    np.testing.assert_allclose(path[:, 1], 1128.67)


def test_control_reply_gives_the_path_as_float64_points():
    path = decode_reply('42["control",{"next_x":[1.5,2,3.25],"next_y":[4,5.5,6]}]')
    assert path.dtype == np.float64
    np.testing.assert_array_equal(path, [[1.5, 4.0], [2.0, 5.5], [3.25, 6.0]])


@pytest.mark.parametrize("reply, error, message", [
    ('42["control",{"next_x":[1,2', MalformedReply, "not valid JSON"),
    ('{"next_x":[1],"next_y":[2]}', MalformedReply, "Socket.IO event frame"),
    (b'42["control",{}]', MalformedReply, "binary frame"),
    ('42["steer",{"angle":0}]', MalformedReply, "unexpected event 'steer'"),
    ('42["control",[1,2]]', MalformedReply, "must be an object"),
    ('42["control"]', MalformedReply, '["event", payload]'),
    ('42["control",{"next_x":[1,2]}]', MalformedReply, "lacks ['next_y']"),
    ('42["control",{"next_x":[1,2],"next_y":[1]}]', MalformedReply,
     "next_x has 2 numbers but next_y has 1"),
    ('42["control",{"next_x":[1,"2"],"next_y":[1,2]}]', MalformedReply, "next_x[1]"),
    ('42["control",{"next_x":[1,2],"next_y":[true,2]}]', MalformedReply, "next_y[0]"),
    (MANUAL_REPLY, ManualReply, "found no telemetry"),
    ('42["control",{"next_x":[],"next_y":[]}]', EmptyPath, "empty path"),
    ('42["control",{"next_x":[1,NaN,3],"next_y":[1,2,3]}]', NonFinitePoint,
     "point 1 of the path is not finite"),
    ('42["control",{"next_x":[1,2,3],"next_y":[1,2,Infinity]}]', NonFinitePoint,
     "next_y[2] = inf"),
    ('42["control",{"next_x":[1,2,3],"next_y":[1,null,3]}]', NonFinitePoint,
     "next_y[1] = null"),
])
def test_each_bad_reply_names_its_fault(reply, error, message):
    with pytest.raises(error, match=message.replace("[", r"\[").replace("(", r"\(")):
        decode_reply(reply)


def test_lockstep_config_sets_one_exchange_per_latency():
    assert lockstep_config(4) == {"steps_per_action": 4, "latency_steps": 4}
    env = gym.make("sdc_gym/HighwayLoop-v0", config=lockstep_config(4))
    assert env.unwrapped.latency_steps == env.unwrapped.steps_per_action == 4
    with pytest.raises(ValueError, match="int >= 1"):
        lockstep_config(0)


@pytest.mark.parametrize("name", ["default", "oval"])
def test_exported_builtin_map_loads_back_as_the_same_road(name, tmp_path):
    road = get_highway_map(name)
    path = export_highway_map(name, tmp_path)
    assert path == tmp_path / "highway_map.csv"
    loaded = load_highway_map(path)
    np.testing.assert_allclose(loaded.waypoints, road.waypoints, rtol=5e-7, atol=5e-7)
    assert loaded.length == pytest.approx(road.length, abs=1e-3)
    s = np.linspace(0.0, road.length, 200, endpoint=False)
    for d in (2.0, 6.0, 10.0):  # lane centres: the same place on both lines
        gap = np.hypot(*(loaded.reference.to_xy(s, d) - road.reference.to_xy(s, d)).T)
        assert gap.max() < 2e-3


def test_exporting_the_original_map_reproduces_its_file(tmp_path):
    path = export_highway_map(str(HIGHWAY_MAP_FILE), tmp_path / "copy.csv")
    original = np.loadtxt(HIGHWAY_MAP_FILE)
    exported = np.loadtxt(path)
    np.testing.assert_array_equal(exported[:, [0, 1, 3, 4]], original[:, [0, 1, 3, 4]])
    np.testing.assert_allclose(exported[:, 2], original[:, 2], rtol=1e-11)


def test_export_command_keeps_a_planners_own_map_and_skips_identical_writes(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    own = data / "highway_map.csv"
    own.write_text("784.6001 1135.571 0 -0.02359831 -0.9997216\n")
    export_highway_map("oval", data, keep_original=True)
    assert (data / "highway_map.csv.orig").read_text().startswith("784.6001")
    stamp = own.stat().st_mtime_ns
    assert export_main(["--map", "oval", "--output", str(data)]) == own
    assert own.stat().st_mtime_ns == stamp  # already this map: not rewritten
    assert "wrote" in capsys.readouterr().out
    assert sorted(p.name for p in data.iterdir()) == ["highway_map.csv", "highway_map.csv.orig"]
    with pytest.raises(SystemExit):
        export_main(["--map", "nowhere", "--output", str(data)])
    assert "neither a built-in" in capsys.readouterr().err


def test_planner_map_leaves_the_planners_file_as_it_found_it(tmp_path):
    from sdc_gym.bridge import PlannerMap

    oval = get_highway_map("oval")
    target = tmp_path / "data" / "highway_map.csv"
    with PlannerMap(oval, target) as path:  # no file: written, then removed
        assert load_highway_map(path).waypoints.shape == oval.waypoints.shape
    assert not target.exists()
    own = "784.6001 1135.571 0 -0.02359831 -0.9997216\n" * 4
    target.write_text(own)
    with PlannerMap(oval, target):  # another map: replaced for the block, then restored
        assert target.read_text() != own
    assert target.read_text() == own
    same = "\n".join(" ".join(f"{value:.9e}" for value in row) for row in oval.waypoints)
    target.write_text(same)
    stamp = target.stat().st_mtime_ns
    with PlannerMap(oval, target):  # the same numbers, printed otherwise: untouched
        pass
    assert target.read_text() == same and target.stat().st_mtime_ns == stamp
