"""A stand-in for a capstone stack's styx server, written from the protocol, for the tests.

It is built like the original's ``ros/src/styx/server.py``: a python-socketio ``Server``
served by eventlet's WSGI server, a ``msgs`` dict holding the latest message per topic
that the nodes published, and a ``telemetry`` handler that publishes the odometry and then
sends every queued message (so commands follow telemetry, one exchange late, as in the
original). Behind it, instead of a ROS graph, sdc-gym's own reference stack
(:class:`~sdc_gym.stack.track.dbw_stack.DBWStackAgent`: detector, updater, pure pursuit,
twist controller) runs one tick per telemetry message, fed the way the original's
``bridge.py`` feeds the ROS topics: the pose from x, y, yaw (degrees), the speed from
``velocity * 0.44704`` (mph), the light states from ``trafficlights``, ``dbw_enable``.
It loads its own track from the original's waypoint CSV and light YAML, as a team's
waypoint loader does. Its commands leave as strings, as the bridge's ``str(...)``.

    python styx_standin.py --port {port} --track wp_yaw_const.csv --lights sim.yaml

``--fault KIND --after N`` misbehaves after N telemetry messages: ``die`` (exit code 3),
``garbage`` (a ``steer`` message whose angle is not a number), ``stall`` (the telemetry
handler never returns), ``disconnect`` (the server drops the client), ``mute`` (the
server answers telemetry, the nodes publish nothing); ``never_listen``
runs without ever listening. ``--spawn`` starts a child in a session of its own first
(as roscore is) and prints ``spawned PID``.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import warnings
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's sdc_gym

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    import eventlet
    import eventlet.wsgi
    import socketio

import numpy as np

from sdc_gym.road.track_map import load_track
from sdc_gym.stack.track.dbw_stack import DBWStackAgent
from sdc_gym.stack.track.detector import GroundTruthLightSource
from sdc_gym.stack.track.follower import CONTINUOUS_FOLLOWER
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT, vehicle_parameters

MPH_TO_MPS = 0.44704  # bridge.py's factor


class StackBridge:
    """The bridge's role: telemetry into the stack's inputs, its outputs to ``send``."""

    def __init__(self, args: argparse.Namespace, send: Any) -> None:
        self.send = send
        self.track = load_track(args.track, args.lights)
        self.stack = DBWStackAgent(
            "standin", self.track, vehicle_parameters("sim"), GroundTruthLightSource(),
            loop_period_s=PHYSICS_DT * args.telemetry_frames, front_offset_m=args.front_offset,
            follower_params=CONTINUOUS_FOLLOWER)
        self.light_states = np.full(self.track.light_count, 4, dtype=np.int8)  # UNKNOWN
        self.dbw_enabled = False
        self.pose = (0.0, 0.0, 0.0)
        self.speed = 0.0
        self.s_guess: float | None = None
        self.last_path: Any = None

    def publish_dbw_status(self, enabled: bool) -> None:
        self.dbw_enabled = bool(enabled)

    def publish_odometry(self, data: dict[str, Any]) -> None:
        self.pose = (float(data["x"]), float(data["y"]), math.radians(float(data["yaw"])))
        self.speed = float(data["velocity"]) * MPH_TO_MPS

    def publish_traffic(self, data: dict[str, Any]) -> None:
        self.light_states = np.asarray(data["light_state"], dtype=np.int8)

    def spin(self) -> None:
        """One tick of the nodes on the latest inputs; their outputs go to ``send``."""
        x, y, yaw = self.pose
        reference = self.track.reference
        s, _ = reference.to_frenet(np.array([x, y]), self.s_guess)
        self.s_guess = float(s)
        line, distance = self.track.next_stop_line(float(s))
        observation = {
            "pose": np.array([x, y, yaw], dtype=np.float32),
            "velocity": np.array([self.speed], dtype=np.float32),
            "dbw_enabled": int(self.dbw_enabled),
            "next_stop_line": np.array([line, distance], dtype=np.float32),
            "light_states": self.light_states,
        }
        throttle, brake, steer = (float(v) for v in self.stack.act(observation))
        if not self.dbw_enabled:
            return  # the DBW node publishes nothing in manual mode
        self.send("steer", {"steering_angle": str(steer)})
        self.send("throttle", {"throttle": str(throttle)})
        self.send("brake", {"brake": str(brake)})
        path = self.stack.final_waypoints
        if path is not None and path is not self.last_path:
            self.last_path = path
            xs = [float(v) for v in path.x]
            ys = [float(v) for v in path.y]
            self.send("drawline", {"next_x": xs, "next_y": ys,
                                   "next_z": [0.5] * len(xs)})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--track", required=True)
    parser.add_argument("--lights", required=True)
    parser.add_argument("--front-offset", type=float, default=2.5,
                        help="m from the reported pose (the body's centre) to the bumper")
    parser.add_argument("--telemetry-frames", type=int, default=1,
                        help="physics frames between telemetry messages")
    parser.add_argument("--fault", default="none",
                        choices=["none", "die", "garbage", "stall", "disconnect", "mute",
                                 "never_listen"])
    parser.add_argument("--after", type=int, default=0)
    parser.add_argument("--spawn", action="store_true")
    args = parser.parse_args()
    if args.spawn:
        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                                 start_new_session=True)
        print(f"spawned {child.pid}", flush=True)
    if args.fault == "never_listen":
        eventlet.sleep(600)
        return

    sio = socketio.Server()
    msgs: dict[str, Any] = {}
    state = {"dbw_enable": False, "telemetry": 0}

    def send(topic: str, data: Any) -> None:
        msgs[topic] = data

    bridge = StackBridge(args, send)

    @sio.on("connect")
    def connect(sid: str, environ: Any) -> None:
        print("connect ", sid, flush=True)

    @sio.on("telemetry")
    def telemetry(sid: str, data: dict[str, Any]) -> None:
        state["telemetry"] += 1
        if args.fault != "none" and state["telemetry"] > args.after:
            if args.fault == "die":
                os._exit(3)
            if args.fault == "garbage":
                sio.emit("steer", data={"steering_angle": "not a number"}, skip_sid=True)
            if args.fault == "stall":
                eventlet.sleep(600)
            if args.fault == "disconnect":
                sio.disconnect(sid)
                return
            if args.fault == "mute":  # the server answers, its nodes publish nothing
                return
        if data["dbw_enable"] != state["dbw_enable"]:
            state["dbw_enable"] = data["dbw_enable"]
            bridge.publish_dbw_status(data["dbw_enable"])
        bridge.publish_odometry(data)
        for _ in range(len(msgs)):
            topic, message = msgs.popitem()
            sio.emit(topic, data=message, skip_sid=True)
        bridge.spin()  # the nodes react; what they publish goes out with the next telemetry

    @sio.on("trafficlights")
    def trafficlights(sid: str, data: dict[str, Any]) -> None:
        bridge.publish_traffic(data)

    @sio.on("control")
    def control(sid: str, data: dict[str, Any]) -> None:
        pass  # reports the stack does not use

    @sio.on("image")
    def image(sid: str, data: dict[str, Any]) -> None:
        pass

    app = socketio.WSGIApp(sio)
    listener = eventlet.listen(("127.0.0.1", args.port))
    print(f"listening on {args.port}", flush=True)
    eventlet.wsgi.server(listener, app, log_output=False)


if __name__ == "__main__":
    main()
