"""What playing the capstone simulator for a stack through its styx server costs.

    python benchmarks/bench_capstone.py [--seconds 60] [--frames 1 5] [--images 20]
    python benchmarks/bench_capstone.py --ros [--seconds 60]   # sim time, the ROS graph

Four figures, each printed with the command's own numbers:

* ``exchanges/s`` and ``latency/exchange``: lock-step telemetry round trips (telemetry
  sent with an acknowledgement, every queued command back before it) against the stand-in
  styx server (``tests/stacks/styx_standin.py``: python-socketio on eventlet like the
  original ``server.py``, sdc-gym's DBW stack ticking once per telemetry), with each
  step's ``control`` and ``trafficlights`` messages, for ``--seconds`` simulated seconds
  of the original track at each ``--frames`` (physics frames per telemetry message).
* ``env step`` and ``stack wait``: where one step's wall time goes.
* ``real-time factor`` (lock-step): simulated seconds per wall second; the original
  simulator runs at 1.
* ``--ros``: the real-time factor of the tests' ROS 1 graph (tests/ros: roscore, the styx
  node, sdc-gym's stack as a rospy node at ``rospy.Rate(50)``) in sim-time mode
  (``/use_sim_time`` true, sdc-gym's ``/clock``), telemetry every frame, from the stack's
  first command on; with where a step's wall time goes (the tick: clock out, the DBW
  node's three commands back; the telemetry exchange; the env step).
* ``camera cost/frame``: rendering the 800 x 600 camera, encoding it (JPEG quality 75,
  PNG) and base64, ``--images`` frames, best of three, and as a fraction of the
  original's 50 Hz frame budget (20 ms).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym

import sdc_gym  # noqa: F401  (registers the ids)
from sdc_gym.capstone import CapstoneOptions, CapstoneSession
from sdc_gym.capstone.protocol import encode_image
from sdc_gym.capstone.sim_clock import TickAnswer
from sdc_gym.sensors.track_camera import CameraConfig, TrackCamera

ROOT = Path(__file__).resolve().parents[1]
STANDIN = ROOT / "tests" / "stacks" / "styx_standin.py"
CAPSTONE = ROOT.parent / "shared" / "data" / "udacity" / "capstone"
TRACK = str(CAPSTONE / "wp_yaw_const.csv")
LIGHTS = str(CAPSTONE / "sim_traffic_light_config.yaml")


def exchanges(seconds: float, frames: int) -> None:
    env = gym.make("sdc_gym/TrackLoop-v0", config={
        "track": TRACK, "light_config": LIGHTS, "steps_per_action": frames,
        "max_duration": seconds})
    command = shlex.join([sys.executable, str(STANDIN), "--port", "{port}", "--track", TRACK,
                          "--lights", LIGHTS, "--telemetry-frames", str(frames)])
    with tempfile.TemporaryDirectory() as folder:
        session = CapstoneSession(env, command, CapstoneOptions(
            lockstep=True, log_path=str(Path(folder) / "stack.log")))
        _, info = env.reset(seed=0)
        session.start()
        steps, step_time = 0, 0.0
        start = time.perf_counter()
        try:
            while True:
                action = session.action(info)
                before = time.perf_counter()
                _, _, terminated, truncated, info = env.step(action)
                step_time += time.perf_counter() - before
                steps += 1
                if terminated or truncated:
                    break
        finally:
            session.close()
    wall = time.perf_counter() - start
    stats = session.client.stats
    print(f"telemetry every {frames} frame(s) ({50 / frames:g} Hz), {info['time']:g} "
          f"simulated s, {stats.exchanges} exchanges, {stats.sent} messages sent, "
          f"{sum(stats.received.values())} received:")
    print(f"  exchanges/s       {stats.exchanges / wall:8.1f}")
    print(f"  latency/exchange  {1e3 * stats.wait_time / stats.exchanges:8.2f} ms "
          "(telemetry out, commands and acknowledgement back)")
    print(f"  env step          {1e3 * step_time / steps:8.3f} ms")
    print(f"  real-time factor  {info['time'] / wall:8.2f} x (lock-step; the original: 1 x)")
    print(f"  distance          {info['distance']:8.1f} m, red-light violations "
          f"{info['summary']['red_light_violations']}")
    env.close()


def ros_sim_time(seconds: float) -> None:
    import os

    from tests.ros.workspace import build_workspace
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        (root / "ws").mkdir()
        os.environ["SDC_GYM_ROS_DEVEL"] = str(build_workspace(root / "ws"))
        env = gym.make("sdc_gym/TrackLoop-v0", config={
            "track": TRACK, "light_config": LIGHTS, "max_duration": seconds})
        command = shlex.join([sys.executable, str(ROOT / "tests" / "ros" / "launch_graph.py"),
                              "--port", "{port}", "--track", TRACK, "--lights", LIGHTS,
                              "--master-port", "{master_port}", "--use-sim-time"])
        session = CapstoneSession(env, command, CapstoneOptions(
            sim_time=True, cwd=folder, log_path=str(root / "graph.log"),
            startup_timeout=120.0))
        _, info = env.reset(seed=0)
        session.start()
        clock = session.clock
        assert clock is not None
        tick_of_clock = clock.tick
        timings = {"tick": 0.0, "exchange": 0.0, "env": 0.0}

        def timed_tick(nanoseconds: int, wait: float) -> TickAnswer:
            before = time.perf_counter()
            answer = tick_of_clock(nanoseconds, wait)
            timings["tick"] += time.perf_counter() - before
            return answer

        clock.tick = timed_tick  # type: ignore[method-assign]
        steps, start = 0, None
        try:
            while True:
                action = session.action(info)
                if start is None:  # the start-up (until the first command) is behind us
                    start = time.perf_counter()
                    for key in timings:
                        timings[key] = 0.0
                    exchange_before = session.client.stats.wait_time
                before = time.perf_counter()
                _, _, terminated, truncated, info = env.step(action)
                timings["env"] += time.perf_counter() - before
                steps += 1
                if terminated or truncated:
                    break
        finally:
            session.close()
        wall = time.perf_counter() - start
        timings["exchange"] = session.client.stats.wait_time - exchange_before
    extras = session.extras()
    print(f"ROS graph on sim time, telemetry every frame (50 Hz), {info['time']:g} simulated "
          f"s, {steps} steps, start-up {extras['stack_startup_wall']:.1f} wall s "
          f"({extras['stack_clock_offset']:g} s of ROS time):")
    print(f"  real-time factor  {info['time'] / wall:8.2f} x (from the first command)")
    print(f"  steps/s           {steps / wall:8.1f}")
    for key, total in timings.items():
        print(f"  {key:17s} {1e3 * total / steps:8.2f} ms/step")
    print(f"  missed ticks      {extras['stack_missed_ticks']:8d}, late steps "
          f"{extras['stack_late_steps']}, red-light violations "
          f"{info['summary']['red_light_violations']}, distance {info['distance']:.0f} m")
    env.close()


def camera(frames: int) -> None:
    env = gym.make("sdc_gym/TrackLoop-v0", config={"track": TRACK, "light_config": LIGHTS})
    env.reset(seed=0)
    track = env.unwrapped.track
    states = env.unwrapped.world.state.light_states[0]
    # At the first stop line's approach: the light is in view, drawn at its largest.
    s = float(track.stop_line_s[0]) - 30.0
    x, y = (float(v) for v in track.reference.position(s))
    yaw = float(track.reference.heading(s))
    cam = TrackCamera(CameraConfig(variation=False))
    timings: dict[str, float] = {}
    sizes: dict[str, int] = {}
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(frames):
            frame = cam.render(x, y, yaw, track.light_positions, track.light_yaw, states)
        timings["render"] = min(timings.get("render", 1e9), (time.perf_counter() - start)
                                / frames)
        for image_format in ("jpeg", "png"):
            start = time.perf_counter()
            for _ in range(frames):
                text = encode_image(frame, image_format)
            key = f"encode {image_format} + base64"
            timings[key] = min(timings.get(key, 1e9), (time.perf_counter() - start) / frames)
            sizes[key] = len(text)
    print(f"camera 800 x 600, {frames} frames, best of 3:")
    for key, seconds in timings.items():
        size = f", {sizes[key] / 1024:.0f} KiB of base64" if key in sizes else ""
        print(f"  {key:24s} {1e3 * seconds:7.2f} ms/frame ({seconds / 0.02:5.2f} of a 50 Hz "
              f"frame){size}")
    env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--frames", type=int, nargs="+", default=[1, 5])
    parser.add_argument("--images", type=int, default=20)
    parser.add_argument("--ros", action="store_true",
                        help="only the ROS graph's sim-time real-time factor")
    args = parser.parse_args()
    if args.ros:
        ros_sim_time(args.seconds)
        return
    for frames in args.frames:
        exchanges(args.seconds, frames)
    camera(args.images)


if __name__ == "__main__":
    main()
