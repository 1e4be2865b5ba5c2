"""``python -m sdc_gym.capstone``: play the original track simulator for a capstone stack.

Start the stack as usual (``roslaunch launch/styx.launch``: its styx server listens on
4567), then::

    python -m sdc_gym.capstone --track ros/src/waypoint_loader/../../data/wp_yaw_const.csv \\
        --light-config ros/src/tl_detector/sim_traffic_light_config.yaml

or let sdc-gym start and end it: ``--stack "roslaunch launch/styx.launch" --stack-cwd ros``.
The episode's summary is printed as JSON at the end (``--output FILE`` writes it too).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

from sdc_gym.capstone.protocol import DEFAULT_HOST, IMAGE_FORMATS
from sdc_gym.capstone.session import CapstoneOptions, CapstoneSession, run_episode
from sdc_gym.capstone.sim_clock import DBW_COMMAND_TOPICS, DEFAULT_ROS_PYTHON


def parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels."""
    width, sep, height = text.lower().partition("x")
    if not sep or not width.isdigit() or not height.isdigit() or not int(width) or \
            not int(height):
        raise argparse.ArgumentTypeError(f"--image-size must be WIDTHxHEIGHT, e.g. 800x600, "
                                         f"got {text!r}")
    return int(width), int(height)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m sdc_gym.capstone",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--host", default=DEFAULT_HOST, help="the styx server's host")
    parser.add_argument("--port", type=int, default=None,
                        help="its port (default 4567, or a free one for a {port} argument "
                             "of --stack)")
    parser.add_argument("--stack", default=None, metavar="COMMAND",
                        help="start this command as the stack, end its whole process tree "
                             "with the episode (default: connect to a running one)")
    parser.add_argument("--stack-cwd", default=None, metavar="DIR",
                        help="the stack's working directory")
    parser.add_argument("--stack-log", default=None, metavar="FILE",
                        help="the stack's output (default: a file in the temp folder)")
    parser.add_argument("--lockstep", action="store_true",
                        help="wait for the server to handle each telemetry message and run "
                             "as fast as the stack keeps up (default: real time)")
    parser.add_argument("--sim-time", action="store_true",
                        help="own the stack's /clock (a stack launched with /use_sim_time "
                             "true): each step ticks it and waits for the DBW node's "
                             "commands, then exchanges telemetry in lock-step")
    parser.add_argument("--ros-master-uri", default=None, metavar="URI",
                        help="sim time: the stack's master (default: a free port for a "
                             "{master_port} argument of --stack, else $ROS_MASTER_URI, "
                             "else http://127.0.0.1:11311)")
    parser.add_argument("--ros-python", default=DEFAULT_ROS_PYTHON, metavar="PYTHON",
                        help="sim time: the Python with rospy that runs the clock node")
    parser.add_argument("--clock-topics", nargs="+", default=list(DBW_COMMAND_TOPICS),
                        metavar="TOPIC", help="sim time: the topics that answer a tick")
    parser.add_argument("--tick-timeout", type=float, default=1.0, metavar="S",
                        help="sim time: wall seconds before an unanswered tick is missed")
    parser.add_argument("--track", default=None, help="waypoint CSV (default: sdc-gym's "
                                                      "own loop); the stack's own file")
    parser.add_argument("--light-config", default=None, help="traffic-light YAML")
    parser.add_argument("--laps", type=int, default=1)
    parser.add_argument("--max-duration", type=float, default=1200.0, metavar="S",
                        help="simulated seconds before the episode is truncated")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--telemetry-frames", type=int, default=1, metavar="N",
                        help="physics frames (0.02 s) per step and telemetry message")
    parser.add_argument("--report-every", type=int, default=1, metavar="STEPS",
                        help="steps between control, trafficlights and obstacle messages")
    parser.add_argument("--image-every", type=int, default=0, metavar="STEPS",
                        help="steps between camera images (0: camera off, the default)")
    parser.add_argument("--image-size", type=parse_size, default=(800, 600))
    parser.add_argument("--image-format", choices=IMAGE_FORMATS, default="jpeg")
    parser.add_argument("--startup-timeout", type=float, default=60.0, metavar="S")
    parser.add_argument("--reply-timeout", type=float, default=5.0, metavar="S")
    parser.add_argument("--render", action="store_true", help="show the top-down window")
    parser.add_argument("--output", type=Path, default=None, help="write the summary here")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    import gymnasium as gym

    import sdc_gym  # noqa: F401  (registers the envs)

    config: dict[str, Any] = {"laps": args.laps, "max_duration": args.max_duration,
                              "steps_per_action": args.telemetry_frames}
    if args.track is not None:
        config["track"] = args.track
    if args.light_config is not None:
        config["light_config"] = args.light_config
    try:
        options = CapstoneOptions(
            host=args.host, port=args.port, cwd=args.stack_cwd, log_path=args.stack_log,
            startup_timeout=args.startup_timeout, reply_timeout=args.reply_timeout,
            lockstep=args.lockstep, sim_time=args.sim_time,
            ros_master_uri=args.ros_master_uri, ros_python=args.ros_python,
            clock_topics=tuple(args.clock_topics), tick_timeout=args.tick_timeout,
            report_every=args.report_every,
            image_every=args.image_every, image_width=args.image_size[0],
            image_height=args.image_size[1], image_format=args.image_format)
        env = gym.make("sdc_gym/TrackLoop-v0", config=config,
                       render_mode="human" if args.render else None)
    except (ValueError, TypeError) as error:
        parser.error(str(error))
    try:
        session = CapstoneSession(env, args.stack, options)
    except ValueError as error:
        parser.error(str(error))
    summary = run_episode(env, session, seed=args.seed)
    env.close()
    text = json.dumps(summary, indent=2, default=str)
    print(text)
    if args.output is not None:
        write_atomically(args.output, text + "\n")
    return 1 if "abort_reason" in summary else 0


def write_atomically(path: Path, text: str) -> None:
    """``text`` into ``path`` through a temporary file in its folder and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(handle, "w") as stream:
        stream.write(text)
    os.replace(name, path)


if __name__ == "__main__":
    sys.exit(main())
