"""The capstone simulator's wire format, pinned byte for byte against a styx server spoken
by hand (tests/stacks/raw_engineio.py): field names, units, strings, message order, and
the Engine.IO version check."""

from __future__ import annotations

import json
import math
import time

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.capstone import (
    CapstoneOptions,
    CapstoneSession,
    MalformedCommand,
    ProtocolMismatch,
    StyxClient,
    check_protocol,
    server_protocol,
)
from sdc_gym.capstone.protocol import (
    CarReport,
    command_value,
    control_fields,
    drawline_points,
    obstacle_fields,
    telemetry_fields,
)
from tests.conftest import UDACITY
from tests.stacks.raw_engineio import RawStyxServer

CAPSTONE = UDACITY / "capstone"
# 10 m/s is 10 / 0.44704 mph (bridge.py turns it back with * 0.44704); yaw pi/2 is 90 degrees.
CAR = CarReport(x=1.5, y=-2.25, yaw=math.pi / 2, speed=10.0, dbw_enabled=True, throttle=0.25,
                brake_torque=400.0, road_wheel_angle=math.radians(-5.0))


def wait_frames(server: RawStyxServer, count: int, timeout: float = 10.0) -> list[str]:
    deadline = time.monotonic() + timeout
    while len(server.frames) < count and time.monotonic() < deadline:
        time.sleep(0.005)
    return list(server.frames)


def test_the_telemetry_and_control_frames_byte_for_byte():
    with RawStyxServer() as server:
        client = StyxClient("127.0.0.1", server.port)
        client.connect(10.0)
        try:
            client.emit("telemetry", telemetry_fields(CAR))
            client.emit("control", control_fields(CAR))
            # bridge.publish_obstacles reads obs[0], obs[1], obs[2] of data['obstacles'].
            client.emit("obstacle", obstacle_fields(np.array([[1.5, -2.25], [-10.0, 20.125]])))
            frames = wait_frames(server, 3)
        finally:
            client.close()
    assert frames[0] == ('42["telemetry",{"x":1.5,"y":-2.25,"z":0.0,"yaw":90.0,'
                         '"velocity":22.369362920544024,"dbw_enable":true}]')
    assert frames[1] == '42["control",{"steering_angle":-5.0,"throttle":0.25,"brake":400.0}]'
    assert frames[2] == '42["obstacle",{"obstacles":[[1.5,-2.25,0.0],[-10.0,20.125,0.0]]}]'
    assert client.protocol == 3
    assert any("EIO=3&transport=polling" in poll for poll in server.polls)


def test_commands_arrive_as_strings_and_the_latest_of_each_is_held():
    replies = ['42["steer",{"steering_angle":"0.75"}]', '42["throttle",{"throttle":"0.3"}]',
               '42["brake",{"brake":"0.0"}]', '42["steer",{"steering_angle":"-1.5"}]',
               '42["drawline",{"next_x":[1.0,2.0],"next_y":[3.0,4.0],"next_z":[0.5,0.5]}]']
    with RawStyxServer(replies=replies) as server:
        client = StyxClient("127.0.0.1", server.port)
        client.connect(10.0)
        try:
            client.exchange(telemetry_fields(CAR), timeout=10.0)  # 421[...] answered 431[]
            commands = client.commands()
            path = client.take_drawline()
        finally:
            client.close()
    assert server.frames[0].startswith('421["telemetry",{"x":1.5,')
    assert commands == {"steer": -1.5, "throttle": 0.3, "brake": 0.0}
    assert path.tolist() == [[1.0, 3.0], [2.0, 4.0]]
    assert client.stats.received == {"steer": 2, "throttle": 1, "brake": 1, "drawline": 1}


def test_one_env_step_sends_control_lights_then_telemetry_of_the_original_track():
    env = gym.make("sdc_gym/TrackLoop-v0", config={
        "track": str(CAPSTONE / "wp_yaw_const.csv"),
        "light_config": str(CAPSTONE / "sim_traffic_light_config.yaml")})
    _, info = env.reset(seed=0)
    replies = ['42["steer",{"steering_angle":"100.0"}]', '42["throttle",{"throttle":"2"}]',
               '42["brake",{"brake":"-5"}]']
    with RawStyxServer(replies=replies) as server:
        session = CapstoneSession(env, None, CapstoneOptions(port=server.port, lockstep=True))
        try:
            session.start()
            session.action(info)
            action = session.action(info)
        finally:
            session.close()
    events = [frame.split('"')[1] for frame in server.frames[:3]]
    assert events == ["control", "trafficlights", "telemetry"]
    # No obstacles configured: no obstacle event at all (nor lidar: sdc-gym has none).
    frame_events = {frame.split('"')[1] for frame in server.frames if '"' in frame}
    assert not frame_events & {"obstacle", "lidar"}
    _, lights = json.loads(server.frames[1][2:])
    # One entry per light (eight, in the YAML's order), each light facing back along the
    # road (a unit vector dx, dy), its state as the env has it (RED 0, YELLOW 1, GREEN 2).
    assert list(lights) == ["light_pos_x", "light_pos_y", "light_pos_z", "light_pos_dx",
                            "light_pos_dy", "light_state"]
    assert all(len(values) == 8 for values in lights.values())
    assert [math.hypot(dx, dy) for dx, dy in zip(lights["light_pos_dx"],
                                                 lights["light_pos_dy"], strict=True)] == \
        pytest.approx([1.0] * 8)
    assert lights["light_state"] == env.unwrapped.world.state.light_states[0].tolist()
    # The car stands still at the start with the pedals released and dbw on.
    assert '"velocity":0.0,"dbw_enable":true}]' in server.frames[2]
    # Out-of-range commands are clamped to the car's ranges, as the original car does.
    unwrapped = env.unwrapped
    assert action.tolist() == pytest.approx([1.0, 0.0, unwrapped.max_steering_angle])
    env.close()


def test_obstacles_are_sent_at_their_world_positions_with_the_lights():
    # Obstacles at s = 0 (the track's first waypoint, 909.48, 1128.67, heading ~+x) on
    # the centre line and 2 m to its right (-y); the car starts 60 m on.
    env = gym.make("sdc_gym/TrackLoop-v0", config={
        "track": str(CAPSTONE / "wp_yaw_const.csv"),
        "light_config": str(CAPSTONE / "sim_traffic_light_config.yaml"), "start_s": 60.0,
        "obstacles": {"positions": [[0.0, 0.0], [0.0, 2.0]]}})
    observation, info = env.reset(seed=0)
    with RawStyxServer() as server:
        options = CapstoneOptions(port=server.port, lockstep=True, report_every=2)
        session = CapstoneSession(env, None, options)
        try:
            session.start()
            for _ in range(3):
                session.action(info)
        finally:
            session.close()
    messages = [frame for frame in server.frames if frame.startswith("42")]  # not pings
    events = [frame.split('"')[1] for frame in messages]
    assert events == ["control", "trafficlights", "obstacle", "telemetry", "telemetry",
                      "control", "trafficlights", "obstacle", "telemetry"]
    frame = messages[2]
    assert frame.startswith('42["obstacle",{"obstacles":[[909.48,1128.67,0.0],[')
    _, data = json.loads(frame[2:])
    assert data["obstacles"][1] == pytest.approx([909.48, 1126.67, 0.0], abs=0.01)
    # The same centres the env observes and collides with.
    assert [xyz[:2] for xyz in data["obstacles"]] == \
        env.unwrapped.world.state.obstacles[0].tolist()
    assert observation["obstacles"].tolist() == \
        np.float32(data["obstacles"])[:, :2].tolist()
    env.close()


def test_obstacle_centres_must_be_x_y_pairs():
    with pytest.raises(ValueError, match=r"\(n, 2\).*shape \(3,\)"):
        obstacle_fields(np.zeros(3))


@pytest.mark.parametrize(("data", "message"), [
    ({"steering_angle": "abc"}, "not a number"),
    ({"steering_angle": "nan"}, "finite"),
    ({"steering_angle": None}, "string of a number"),
    ({"angle": "0.1"}, "field 'steering_angle'"),
])
def test_a_command_that_is_not_a_number_is_malformed(data, message):
    with pytest.raises(MalformedCommand, match=message):
        command_value("steer", data)


def test_a_drawline_with_uneven_lists_is_malformed():
    with pytest.raises(MalformedCommand, match="one length"):
        drawline_points({"next_x": [1.0], "next_y": []})


def test_a_garbage_command_on_the_wire_ends_the_next_call():
    with RawStyxServer(replies=['42["throttle",{"throttle":"full"}]']) as server:
        client = StyxClient("127.0.0.1", server.port)
        client.connect(10.0)
        try:
            with pytest.raises(MalformedCommand, match=r"throttle\.throttle is not a number"):
                client.exchange(telemetry_fields(CAR), timeout=10.0)
        finally:
            client.close()


def test_a_protocol_4_server_is_named_as_a_version_mismatch():
    """python-engineio 4 answers a protocol-3 handshake with HTTP 400; the client (4.x,
    protocol 3) says which versions differ and what to install, instead of hanging."""
    with RawStyxServer(protocol=4) as server:
        assert server_protocol("127.0.0.1", server.port) == 4
        with pytest.raises(ProtocolMismatch, match=r"speaks Engine.IO protocol 4 .*"
                                                   r"python-engineio 3\.\d+\.\d+ speaks "
                                                   r"protocol 3: install python-socketio>=5"):
            check_protocol("127.0.0.1", server.port)


def test_the_image_is_a_base64_jpeg_of_the_configured_size():
    """The camera at the original's 800 x 600 by default, and at a size asked for, as
    base64 of a JPEG that bridge.py's ``PIL.Image.open(BytesIO(b64decode(...)))`` reads."""
    import base64
    import io

    from PIL import Image

    env = gym.make("sdc_gym/TrackLoop-v0", config={
        "track": str(CAPSTONE / "wp_yaw_const.csv"),
        "light_config": str(CAPSTONE / "sim_traffic_light_config.yaml")})
    _, info = env.reset(seed=0)
    with RawStyxServer() as server:
        sizes = []
        for width, height in ((800, 600), (400, 300)):
            session = CapstoneSession(env, None, CapstoneOptions(
                port=server.port, lockstep=True, image_every=1, image_width=width,
                image_height=height))
            try:
                session.start()
                session.action(info)
            finally:
                session.close()
            frame = next(frame for frame in server.frames if frame.startswith('42["image"'))
            server.frames.clear()
            _, data = json.loads(frame[2:])
            image = Image.open(io.BytesIO(base64.b64decode(data["image"])))
            sizes.append((image.format, image.mode, image.size))
    assert sizes == [("JPEG", "RGB", (800, 600)), ("JPEG", "RGB", (400, 300))]
    env.close()


def test_the_command_line_drives_a_running_server_and_writes_its_summary(tmp_path):
    """``python -m sdc_gym.capstone`` against a server that answers every telemetry with
    full throttle: the car drives off, the summary is written, exit status 0."""
    from sdc_gym.capstone.__main__ import main

    replies = ['42["throttle",{"throttle":"1.0"}]', '42["brake",{"brake":"0"}]',
               '42["steer",{"steering_angle":"0.0"}]']
    with RawStyxServer(replies=replies) as server:
        status = main(["--port", str(server.port), "--lockstep", "--track",
                       str(CAPSTONE / "wp_yaw_const.csv"), "--light-config",
                       str(CAPSTONE / "sim_traffic_light_config.yaml"), "--max-duration", "2",
                       "--telemetry-frames", "5", "--output", str(tmp_path / "summary.json")])
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert status == 0
    assert summary["termination_reason"] == "max_duration"
    assert summary["stack_exchanges"] == 20 and summary["distance"] > 0.5
