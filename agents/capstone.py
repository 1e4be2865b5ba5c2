"""Capstone stacks as agents: ``evaluate.py --agents "capstone:roslaunch launch/styx.launch"``.

A capstone team's whole ROS stack, which talks to the original track simulator through
its styx server, drives ``sdc_gym/TrackLoop-v0`` unchanged: sdc-gym plays the simulator
(:mod:`sdc_gym.capstone`). :class:`CapstoneStackAgent` is an ordinary agent for
:func:`sdc_evaluation.episodes.run_episode`: at its first action it starts the command in its
working directory (``--stack-cwd``) under the planner bridge's process machinery and
connects to the server; every action is one step's messages (telemetry, control,
traffic lights, camera) and the stack's latest commands back; at the end of the episode
the stack's whole process tree (roscore, roslaunch, every node) is ended. Its faults end
the episode with their reason (``stack_never_connected``, ``protocol_mismatch``,
``stack_disconnected``, ``malformed_command``, ``stack_stalled``, ``planner_died``,
``log_flooded``) and ``abort_message``; the metrics up to that moment are kept.

Options (keyword arguments of :func:`capstone_agent`: the fields of
:class:`~sdc_gym.capstone.CapstoneOptions`; ``evaluate.py``'s ``--stack-*`` flags).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import re
from pathlib import Path
from typing import Any, Final

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from sdc_agents.protocol import EpisodeAborted
from sdc_gym.bridge.errors import BridgeError
from sdc_gym.capstone.session import CapstoneOptions, CapstoneSession
from sdc_gym.capstone.sim_clock import DBW_COMMAND_TOPICS, DEFAULT_ROS_PYTHON
from sdc_gym.envs.track_loop import TrackLoopEnv

CAPSTONE_KIND: Final = "capstone"
LOG_FOLDER: Final = "stack_logs"
"""Folder of the run's output where each episode's stack output is captured."""


class CapstoneStackAgent:
    """A capstone stack driven through the styx protocol; one instance per episode."""

    wants_info = True  # act() builds the telemetry from the step's info

    def __init__(self, command: str, env: gym.Env, options: CapstoneOptions | None = None,
                 *, name: str | None = None) -> None:
        if not isinstance(env.unwrapped, TrackLoopEnv):
            raise ValueError(f"capstone stacks drive sdc_gym/TrackLoop-v0, not "
                             f"{type(env.unwrapped).__name__}")
        self.name = name or f"{CAPSTONE_KIND}:{command}"
        self.command = command
        self.options = options or CapstoneOptions()
        self.env = env
        self.session: CapstoneSession | None = None

    def reset(self) -> None:
        """Stop the previous episode's stack; the next action starts a fresh one."""
        self.close()
        self.session = None

    def act(self, observation: Any, info: dict[str, Any]) -> NDArray[np.float32]:
        try:
            if self.session is None:
                self.session = CapstoneSession(self.env, self.command, self.options)
                self.session.start()
            return self.session.action(info)
        except BridgeError as error:
            raise EpisodeAborted(error.reason, str(error)) from error

    def episode_extras(self) -> dict[str, Any]:
        return {} if self.session is None else self.session.extras()

    def close(self) -> None:
        """End the stack's process tree and the connection (safe to repeat)."""
        if self.session is not None:
            self.session.close()


_OPTION_NAMES = tuple(field.name for field in dataclasses.fields(CapstoneOptions))


def capstone_agent(command: str, env: gym.Env, **options: Any) -> CapstoneStackAgent:
    """The factory of agent specs ``capstone:COMMAND``; ``options`` are
    :class:`~sdc_gym.capstone.CapstoneOptions` fields."""
    unknown = sorted(set(options) - set(_OPTION_NAMES))
    if unknown:
        raise ValueError(f"unknown capstone stack option(s) {unknown}; valid: "
                         f"{', '.join(_OPTION_NAMES)}")
    return CapstoneStackAgent(command, env, CapstoneOptions(**options))


# ---------------------------------------------------------------- evaluate.py's options
def add_capstone_arguments(parser: argparse.ArgumentParser) -> None:
    """The command-line options of capstone stacks (``--agents 'capstone:COMMAND'``)."""
    group = parser.add_argument_group(
        "capstone stacks (--agents 'capstone:COMMAND', a whole stack for the original "
        "track simulator; {port} in COMMAND gets a free port)")
    group.add_argument("--stack-cwd", default=None, metavar="DIR",
                       help="the stack's working directory (default: the current one)")
    group.add_argument("--stack-port", type=int, default=None, metavar="PORT",
                       help="its styx server's port (default: a free one for a {port} "
                            "argument, else 4567 like the original)")
    group.add_argument("--stack-lockstep", action="store_true",
                       help="run as fast as the stack keeps up (it must run on sim time "
                            "or tick per telemetry) instead of in real time")
    group.add_argument("--stack-sim-time", action="store_true",
                       help="own the stack's /clock (launched with /use_sim_time true): "
                            "each step ticks it, waits for the DBW node's commands, then "
                            "exchanges telemetry in lock-step")
    group.add_argument("--stack-ros-master", default=None, metavar="URI",
                       help="sim time: the stack's ROS master (default: a free port for a "
                            "{master_port} argument, else $ROS_MASTER_URI)")
    group.add_argument("--stack-ros-python", default=DEFAULT_ROS_PYTHON, metavar="PYTHON",
                       help="sim time: the Python with rospy for sdc-gym's clock node")
    group.add_argument("--stack-clock-topics", nargs="+", default=list(DBW_COMMAND_TOPICS),
                       metavar="TOPIC", help="sim time: the topics that answer a tick")
    group.add_argument("--stack-tick-timeout", type=float, default=1.0, metavar="S",
                       help="sim time: wall seconds before an unanswered tick is missed")
    group.add_argument("--stack-startup", type=float, default=60.0, metavar="S",
                       help="wall seconds for its server to accept the connection")
    group.add_argument("--stack-timeout", type=float, default=5.0, metavar="S",
                       help="wall seconds of silence (real time) or per exchange "
                            "(lock-step) before the episode ends 'stack_stalled'")
    group.add_argument("--stack-image-every", type=int, default=0, metavar="STEPS",
                       help="steps between camera images (default 0: none)")


def check_capstone_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Reject bad capstone options (exits through ``parser.error``)."""
    if args.stack_cwd is not None and not Path(args.stack_cwd).expanduser().is_dir():
        parser.error(f"--stack-cwd {args.stack_cwd}: no such folder")
    try:
        capstone_options_of(args)
    except ValueError as error:
        parser.error(str(error).replace("CapstoneOptions.", "--stack option "))


def is_capstone(agent: str) -> bool:
    return agent.startswith(CAPSTONE_KIND + ":")


def capstone_options_of(args: argparse.Namespace) -> CapstoneOptions:
    return CapstoneOptions(
        port=args.stack_port, cwd=(str(Path(args.stack_cwd).expanduser())
                                   if args.stack_cwd else None),
        startup_timeout=args.stack_startup, reply_timeout=args.stack_timeout,
        lockstep=args.stack_lockstep, image_every=args.stack_image_every,
        sim_time=args.stack_sim_time, ros_master_uri=args.stack_ros_master,
        ros_python=args.stack_ros_python, clock_topics=tuple(args.stack_clock_topics),
        tick_timeout=args.stack_tick_timeout)


def capstone_options(args: argparse.Namespace, agent: str, seed: int) -> dict[str, Any]:
    """The ``capstone`` options of one episode: the flags, and its log in the run folder."""
    options = dataclasses.asdict(capstone_options_of(args))
    words = " ".join(Path(word).name or word for word in agent.partition(":")[2].split())
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", words).strip("_.")[:60]
    key = f"{agent}\n{options['cwd']}".encode()  # one command may run in two folders
    slug = f"{slug}_{hashlib.sha1(key).hexdigest()[:8]}"
    options["log_path"] = str(args.output / LOG_FOLDER / f"{slug}_seed{seed}.log")
    return options


def fixed_port(args: argparse.Namespace, agents: list[str]) -> bool:
    """Whether capstone stacks share one fixed port (episodes must then run one at a time):
    the styx server's, or in sim time the ROS master's (no ``{master_port}``)."""
    return any(is_capstone(agent) and (
        "{port}" not in agent or args.stack_port is not None
        or (args.stack_sim_time and "{master_port}" not in agent)) for agent in agents)
