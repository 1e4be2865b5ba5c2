"""A planner for the original highway simulator, in Python, for the bridge's tests.

It is a websocket server speaking the protocol exactly as the template's C++ planners do
(uWebSockets, ``main.cpp``): it listens on a port, prints ``Listening to port N``, and
for every text frame starting with ``42`` cuts the payload out with the template's
``hasData`` (the text from the first ``[`` to the first ``}``, plus one character; any
``null`` means manual mode), answers ``42["manual",{}]`` in manual mode and
``42["control",{"next_x":[...],"next_y":[...]}]`` to telemetry. Like the template it
reads its map from a path relative to its working directory.

    python protocol_planner.py --port 4567 --map highway_map.csv              # lane keeping
    python protocol_planner.py --port {port} --brain straight --fault die --after 5

Brains: ``lane_keeping`` (``sdc_agents.lane_keeping.LaneKeepingDriver`` fed from the
telemetry) and ``straight`` (a few points ahead along the heading; no map, quick to
start). ``--fault`` makes it misbehave after ``--after`` good replies: ``die`` (exit with
code 3), ``malformed`` (broken JSON), ``empty`` (no points), ``nan`` (a ``NaN`` literal),
``null`` (a ``null`` point, as nlohmann::json prints NaN), ``stall`` (never answers),
``manual`` (answers telemetry with ``42["manual",{}]``), ``flood`` (prints random bytes
as fast as it can, never answering); ``never_listen`` runs (with a child process) without
ever listening, ``crash_at_start`` exits with code 2 at once. ``--spawn`` starts a process
that escapes the planner's process group before serving: ``setsid`` (a child in a session
of its own) or ``daemon`` (a grandchild whose parent, in a new session, exits at once: an
orphan, as a daemonizing planner leaves); it prints ``spawned PID``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from typing import Any

FAULTS = ("none", "die", "malformed", "empty", "nan", "null", "stall", "manual",
          "flood", "never_listen", "crash_at_start")
SPAWNS = ("none", "setsid", "daemon")
SLEEPER = "import time; time.sleep(3600)"
MANUAL_REPLY = '42["manual",{}]'
STRAIGHT_SPEED_MPS = 10.0
DT = 0.02


def has_data(message: str) -> str:
    """The template's hasData(): the event array, or "" when there is none (manual)."""
    if "null" in message:
        return ""
    start, end = message.find("["), message.find("}")
    if start != -1 and end != -1:
        return message[start:end + 2]
    return ""


def control_message(next_x: list[float], next_y: list[float]) -> str:
    body = json.dumps({"next_x": next_x, "next_y": next_y}, separators=(",", ":"))
    return f'42["control",{body}]'


class TelemetryLaneKeeper:
    """``LaneKeepingDriver`` on the telemetry object (degrees and mph, as sent)."""

    def __init__(self, map_path: str, target_mph: float | None = None) -> None:
        from sdc_agents.lane_keeping import LaneKeepingDriver, LaneKeepingParameters
        from sdc_gym.road.highway_map import load_highway_map

        params = (LaneKeepingParameters() if target_mph is None
                  else LaneKeepingParameters(target_speed_mph=target_mph))
        self.driver = LaneKeepingDriver(load_highway_map(map_path), params)

    def plan(self, telemetry: dict[str, Any]) -> tuple[list[float], list[float]]:
        path = self.driver.act(observation_from_telemetry(telemetry))
        return path[:, 0].tolist(), path[:, 1].tolist()


def observation_from_telemetry(telemetry: dict[str, Any]) -> dict[str, Any]:
    """The env's observation layout rebuilt from a telemetry object."""
    import numpy as np

    from sdc_gym.units import MPH_TO_MPS

    t = telemetry
    previous = np.column_stack([t["previous_path_x"], t["previous_path_y"]]).reshape(-1, 2)
    fusion = np.array(t["sensor_fusion"], dtype=np.float64).reshape(-1, 7)
    return {
        "ego": np.array([t["x"], t["y"], t["s"], t["d"], math.radians(t["yaw"]),
                         t["speed"] * MPH_TO_MPS]),
        "previous_path": previous,
        "previous_path_count": len(previous),
        "end_path": np.array([t["end_path_s"], t["end_path_d"]]),
        "sensor_fusion": fusion,
        "sensor_fusion_mask": np.ones(len(fusion), dtype=np.int8),
    }


class Straight:
    """Keeps 10 points ahead along the car's heading at 10 m/s (no map needed)."""

    def plan(self, telemetry: dict[str, Any]) -> tuple[list[float], list[float]]:
        xs, ys = list(telemetry["previous_path_x"]), list(telemetry["previous_path_y"])
        if not xs:
            xs, ys = [telemetry["x"]], [telemetry["y"]]
        yaw = math.radians(telemetry["yaw"])
        while len(xs) < 10:
            xs.append(xs[-1] + STRAIGHT_SPEED_MPS * DT * math.cos(yaw))
            ys.append(ys[-1] + STRAIGHT_SPEED_MPS * DT * math.sin(yaw))
        return xs, ys


class Planner:
    """The template's onMessage, with an optional fault after ``after`` good replies."""

    def __init__(self, brain: Any, fault: str, after: int) -> None:
        self.brain = brain
        self.fault = fault
        self.after = after
        self.replies = 0

    def on_message(self, data: str) -> str | None:
        if not (len(data) > 2 and data[0] == "4" and data[1] == "2"):
            return None
        payload = has_data(data)
        if not payload:
            return MANUAL_REPLY
        event = json.loads(payload)
        if event[0] != "telemetry":
            return None
        next_x, next_y = self.brain.plan(event[1])
        self.replies += 1
        if self.fault != "none" and self.replies > self.after:
            return self.misbehave(next_x, next_y)
        return control_message(next_x, next_y)

    def misbehave(self, next_x: list[float], next_y: list[float]) -> str | None:
        fault = self.fault
        if fault == "die":
            print(f"dying after {self.after} replies", flush=True)
            os._exit(3)
        if fault == "stall":
            time.sleep(3600)
        if fault == "malformed":
            return control_message(next_x, next_y)[:40]
        if fault == "empty":
            return control_message([], [])
        if fault == "nan":
            return control_message([*next_x[:3], math.nan, *next_x[4:]], next_y)
        if fault == "null":
            return control_message(next_x, [*next_y[:2], None, *next_y[3:]])  # null
        if fault == "manual":
            return MANUAL_REPLY
        if fault == "flood":
            garbage = os.urandom(1 << 16)
            while True:
                sys.stdout.buffer.write(garbage)
        raise ValueError(fault)


def spawn_escaping_process(kind: str) -> int:
    """A process outside the planner's process group (see the module docstring); its pid."""
    if kind == "setsid":
        return subprocess.Popen([sys.executable, "-c", SLEEPER], start_new_session=True).pid
    # daemon: the middle process starts the sleeper, prints its pid, and exits.
    middle = subprocess.run(
        [sys.executable, "-c", "import subprocess, sys; print(subprocess.Popen("
         f"[sys.executable, '-c', {SLEEPER!r}], start_new_session=True, "
         "stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).pid)"],
        capture_output=True, text=True, check=True, start_new_session=True)
    return int(middle.stdout)


def serve(planner: Planner, port: int) -> None:
    from websockets.sync.server import serve as websocket_serve

    def handler(websocket: Any) -> None:
        print("Connected!!!", flush=True)
        for message in websocket:
            reply = planner.on_message(message)
            if reply is not None:
                websocket.send(reply)
        print("Disconnected", flush=True)

    with websocket_serve(handler, "127.0.0.1", port, compression=None,
                         ping_interval=None) as server:
        print(f"Listening to port {port}", flush=True)
        server.serve_forever()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--port", type=int, default=4567)
    parser.add_argument("--map", default="highway_map.csv", help="relative to the cwd")
    parser.add_argument("--brain", choices=("lane_keeping", "straight"),
                        default="lane_keeping")
    parser.add_argument("--target-mph", type=float, default=None)
    parser.add_argument("--fault", choices=FAULTS, default="none")
    parser.add_argument("--after", type=int, default=0)
    parser.add_argument("--spawn", choices=SPAWNS, default="none")
    args = parser.parse_args()
    if args.spawn != "none":
        print(f"spawned {spawn_escaping_process(args.spawn)}", flush=True)
    if args.fault == "crash_at_start":
        print("terminate called after throwing an instance of 'std::runtime_error'",
              flush=True)
        sys.exit(2)
    if args.fault == "never_listen":
        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(3600)"])
        print(f"child {child.pid}", flush=True)
        time.sleep(3600)
    brain = (TelemetryLaneKeeper(args.map, args.target_mph) if args.brain == "lane_keeping"
             else Straight())
    serve(Planner(brain, args.fault, args.after), args.port)


if __name__ == "__main__":
    main()
