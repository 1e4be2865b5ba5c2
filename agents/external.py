"""External planners as agents: ``evaluate.py --agent "external:./path_planning"``.

A planner written for the original highway simulator (a uWebSockets server on port 4567,
usually C++) drives ``sdc_gym/HighwayLoop-v0`` unchanged through the original's wire
protocol (:mod:`sdc_gym.bridge`). :class:`ExternalPlannerAgent` is an ordinary agent for
:func:`sdc_evaluation.episodes.run_episode`: at its first action it exports the map (if asked),
starts the planner command in its working directory, connects; every action is one
exchange (the step's ``info["telemetry"]`` out, the path back); at the end of the episode
the planner is stopped with its whole process group. Its faults end the episode with
their reason (``termination_reason`` ``planner_died``, ``reply_timeout``,
``malformed_reply``, ``empty_path``, ``non_finite_point``, ...) and a message saying what
happened (``abort_message``); the metrics up to that moment are kept.

Options (keyword arguments of :func:`external_agent`, ``evaluate.py`` flags):
``cwd`` (``--planner-cwd``), ``port`` (``--planner-port``), ``map_export``
(``--planner-map``), ``startup_timeout`` / ``reply_timeout`` (``--planner-startup`` /
``--planner-timeout``), ``log_path`` (evaluate puts it in the run folder:
``planner_logs/<agent>_seed<seed>.log``), ``log_limit`` (``--planner-log-limit`` MiB: the
log's largest size; more output ends the episode ``log_flooded``), ``manual_probe``. The
reply latency is the env's: ``--reply-latency N`` sets ``steps_per_action = latency_steps =
N`` frames.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from sdc_agents.protocol import EpisodeAborted
from sdc_gym.bridge import (
    DEFAULT_LOG_LIMIT_BYTES,
    BridgeError,
    InvalidPath,
    PlannerMap,
    PlannerOptions,
    PlannerSession,
    lockstep_config,
)
from sdc_gym.envs import HighwayLoopEnv

EXTERNAL_KIND: Final = "external"
MIB: Final = 1024 * 1024
MIN_LOG_LIMIT_BYTES: Final = 1024
LOG_FOLDER: Final = "planner_logs"
"""Folder of the run's output where each episode's planner output is captured."""


class ExternalPlannerAgent:
    """An external planner process driven through the original's protocol; see the module
    docstring. One instance per episode (``run_episode`` builds one per episode)."""

    wants_info = True  # act() needs the step's info["telemetry"]

    def __init__(self, command: str, env: gym.Env, options: PlannerOptions | None = None,
                 *, name: str | None = None) -> None:
        unwrapped = env.unwrapped
        if not isinstance(unwrapped, HighwayLoopEnv):
            raise ValueError(f"external planners drive sdc_gym/HighwayLoop-v0 (path level), "
                             f"not {type(unwrapped).__name__}")
        if not unwrapped.config["telemetry_info"]:
            raise ValueError("external planners need the env's telemetry: set the config key "
                             "telemetry_info: true")
        self.name = name or f"{EXTERNAL_KIND}:{command}"
        self.command = command
        self.options = options or PlannerOptions()
        self._road = unwrapped.road
        self._max_points = unwrapped.path_points
        self._low = env.action_space.low[0].astype(np.float64)
        self._high = env.action_space.high[0].astype(np.float64)
        self.session: PlannerSession | None = None

    def reset(self) -> None:
        """Stop the previous episode's planner; the next action starts a fresh one."""
        self.close()
        self.session = None

    def act(self, observation: Any, info: dict[str, Any]) -> NDArray[np.float64]:
        """The planner's reply to this step's telemetry (raises
        :class:`~sdc_agents.protocol.EpisodeAborted` on a fault)."""
        try:
            if self.session is None:
                self.session = PlannerSession(self.command, self.options, road=self._road)
                self.session.start()
            path = self.session.exchange(info["telemetry"])
            self._check(path)
        except BridgeError as error:
            raise EpisodeAborted(error.reason, str(error)) from error
        return path

    def _check(self, path: NDArray[np.float64]) -> None:
        """Faults the env would raise as ValueError, named as the planner's."""
        if len(path) > self._max_points:
            raise InvalidPath(f"the planner sent {len(path)} points; the env takes at most "
                              f"path_points = {self._max_points} (raise the env config key "
                              "path_points)")
        outside = ((path < self._low) | (path > self._high)).any(axis=1)
        if outside.any():
            index = int(np.flatnonzero(outside)[0])
            raise InvalidPath(
                f"path point {index} {path[index].tolist()} lies outside the map's area "
                f"(x {self._low[0]:.0f}..{self._high[0]:.0f}, y {self._low[1]:.0f}.."
                f"{self._high[1]:.0f} m): does the planner load this env's map? (export it "
                "with --planner-map)")

    def episode_extras(self) -> dict[str, Any]:
        """Figures of the exchange for the episode's result."""
        session = self.session
        if session is None:
            return {"planner_exchanges": 0}
        stats = session.stats
        return {"planner_exchanges": stats.exchanges,
                "planner_wait_time": stats.wait_time,
                "planner_pid": session.process.pid,
                "planner_log": str(session.process.log_path)}

    def close(self) -> None:
        """Stop the planner process group and close the connection (safe to repeat)."""
        if self.session is not None:
            self.session.close()


_OPTION_NAMES = tuple(field.name for field in dataclasses.fields(PlannerOptions))


def external_agent(command: str, env: gym.Env, **options: Any) -> ExternalPlannerAgent:
    """The factory of agent specs ``external:COMMAND``; ``options`` are
    :class:`~sdc_gym.bridge.PlannerOptions` fields."""
    unknown = sorted(set(options) - set(_OPTION_NAMES))
    if unknown:
        raise ValueError(f"unknown external planner option(s) {unknown}; valid: "
                         f"{', '.join(_OPTION_NAMES)}")
    return ExternalPlannerAgent(command, env, PlannerOptions(**options))


# ---------------------------------------------------------------- evaluate.py's options
def add_external_arguments(parser: argparse.ArgumentParser) -> None:
    """The command-line options of external planners (``--agent external:COMMAND``)."""
    group = parser.add_argument_group(
        "external planners (--agent 'external:COMMAND', a planner for the original "
        "simulator; {port} in COMMAND gets a free port)")
    group.add_argument("--planner-cwd", nargs="+", default=None, metavar="DIR",
                       help="the planner's working directory (default: the current one); "
                            "one for every external agent, or one per external agent in "
                            "the order of --agents")
    group.add_argument("--planner-port", type=int, default=None, metavar="PORT",
                       help="the port it listens on (default: a free one for a {port} "
                            "argument, else 4567 like the original)")
    group.add_argument("--planner-map", default=None, metavar="PATH",
                       help="put the env's map in the original format at PATH, relative "
                            "to the working directory, for the run (e.g. "
                            "../data/highway_map.csv); the planner's own file is rewritten "
                            "only if its numbers differ, and restored after the run")
    group.add_argument("--reply-latency", type=int, default=None, metavar="FRAMES",
                       help="the planner's reply takes effect FRAMES physics frames (0.02 s) "
                            "after its telemetry, which goes out every FRAMES frames (the "
                            "original's lock-step; sets steps_per_action and latency_steps "
                            "for every agent; default: the config's, 3)")
    group.add_argument("--planner-timeout", type=float, default=5.0, metavar="S",
                       help="wall seconds to wait for each reply (default 5)")
    group.add_argument("--planner-startup", type=float, default=10.0, metavar="S",
                       help="wall seconds to wait for the planner to listen (default 10)")
    group.add_argument("--planner-log-limit", type=float,
                       default=DEFAULT_LOG_LIMIT_BYTES / MIB, metavar="MIB",
                       help="largest planner log, MiB (default "
                            f"{DEFAULT_LOG_LIMIT_BYTES / MIB:g}): a planner printing more "
                            "is stopped, its episode ends 'log_flooded', and its log keeps "
                            "the beginning and the last part")


def check_external_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Reject bad external planner options (exits through ``parser.error``)."""
    if args.reply_latency is not None and args.reply_latency < 1:
        parser.error(f"--reply-latency must be >= 1 frame, got {args.reply_latency}")
    for flag in ("planner_timeout", "planner_startup"):
        if not getattr(args, flag) > 0:
            parser.error(f"--{flag.replace('_', '-')} must be > 0 s, got {getattr(args, flag)}")
    if not args.planner_log_limit * MIB >= MIN_LOG_LIMIT_BYTES:
        parser.error(f"--planner-log-limit must be >= {MIN_LOG_LIMIT_BYTES / MIB:g} MiB, got "
                     f"{args.planner_log_limit}")
    if args.planner_port is not None and not 0 < args.planner_port < 65536:
        parser.error(f"--planner-port must be in 1..65535, got {args.planner_port}")
    for folder in args.planner_cwd or ():
        if not Path(folder).expanduser().is_dir():
            parser.error(f"--planner-cwd {folder}: no such folder")
    try:  # the folders' count, and repeated agents named apart or refused
        agent_runs(args.agents or [], args.planner_cwd)
    except ValueError as error:
        parser.error(str(error))


def is_external(agent: str) -> bool:
    return agent.startswith(EXTERNAL_KIND + ":")


FOLDER_SEPARATOR: Final = "@"
"""Between an external agent's spec and its folder in its name: ``external:./planner@a``."""


@dataclass(frozen=True)
class AgentRun:
    """One agent of an evaluation: its ``name`` in the results and tables, the ``spec``
    that builds it, and for an external planner its working folder ``cwd`` (as given to
    ``--planner-cwd``; ``None``: the current one)."""

    name: str
    spec: str
    cwd: str | None = None


def agent_runs(agents: Sequence[str], cwds: Sequence[str] | None = None) -> list[AgentRun]:
    """The agents of ``--agents`` with their folders of ``--planner-cwd`` (none, one for
    every external agent, or one per external agent in order), each named apart.

    An agent given once is named by its spec. An external spec given more than once is run
    once per folder, each named ``SPEC@FOLDER`` (``external:./planner@build_a``), so the
    tables keep them apart. Repeats that cannot be told apart are refused with a
    ``ValueError``: the same agent twice (not an external planner, or one in the same
    folder twice) would be one agent run twice under one name.
    """
    cwds = list(cwds or [])
    externals = sum(is_external(agent) for agent in agents)
    if len(cwds) > 1 and len(cwds) != externals:
        raise ValueError(f"--planner-cwd got {len(cwds)} folders for {externals} external "
                         "agent(s): give one for all, or one per external agent in the "
                         "order of --agents")
    folders = iter(cwds if len(cwds) > 1 else [])
    counts = {agent: list(agents).count(agent) for agent in agents}
    runs, seen = [], set()
    for agent in agents:
        cwd = None
        if is_external(agent):
            cwd = next(folders) if len(cwds) > 1 else (cwds[0] if cwds else None)
        elif counts[agent] > 1:
            raise ValueError(f"--agents names {agent!r} {counts[agent]} times: each agent "
                             "runs once (only an external planner may repeat, once per "
                             "--planner-cwd folder); drop the repeats")
        key = (agent, str(Path(cwd).expanduser().resolve()) if cwd is not None else None)
        if key in seen:
            where = f"the folder {cwd}" if cwd is not None else "the current folder"
            raise ValueError(f"--agents names {agent!r} {counts[agent]} times, and two of "
                             f"them would run in {where}: that is one planner run twice; "
                             "give each its own folder (--planner-cwd A B, in the order of "
                             "the external agents) or drop the repeat")
        seen.add(key)
        name = agent if counts[agent] == 1 else f"{agent}{FOLDER_SEPARATOR}{cwd}"
        runs.append(AgentRun(name, agent, cwd))
    return runs


def apply_reply_latency(args: argparse.Namespace, env_config: dict[str, Any]) -> None:
    """``--reply-latency N`` into the env config (the original's lock-step)."""
    if args.reply_latency is not None:
        env_config.update(lockstep_config(args.reply_latency))


def planner_cwd(run: AgentRun) -> str | None:
    """The working directory of an external agent's run (``~`` expanded)."""
    return None if run.cwd is None else str(Path(run.cwd).expanduser())


def external_options(args: argparse.Namespace, run: AgentRun, seed: int) -> dict[str, Any]:
    """The ``external`` options of one episode: the flags, and its log in the run folder."""
    cwd, agent = planner_cwd(run), run.spec
    # A readable file name from the command's words without their folders, made unique
    # by the hash of the spec and its folder (commands can be long and differ only in
    # their folders; one command may run in two folders).
    words = " ".join(Path(word).name or word for word in agent.partition(":")[2].split())
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", words).strip("_.")[:60]
    key = f"{agent}\n{cwd}".encode()
    slug = f"{slug}_{hashlib.sha1(key).hexdigest()[:8]}"
    return {
        "cwd": cwd,
        "port": args.planner_port,
        "map_export": args.planner_map,
        "startup_timeout": args.planner_startup,
        "reply_timeout": args.planner_timeout,
        "log_limit": round(args.planner_log_limit * MIB),
        "log_path": str(args.output / LOG_FOLDER / f"{slug}_seed{seed}.log"),
    }


def fixed_port_workers(args: argparse.Namespace, agents: list[str], workers: int) -> int:
    """Workers for the run: 1 when external planners share a fixed port (they would
    collide), else ``workers``."""
    fixed = [agent for agent in agents if is_external(agent)
             and ("{port}" not in agent or args.planner_port is not None)]
    return 1 if fixed and workers > 1 else workers


EXTERNAL_PATH_POINTS: Final = 500
"""Points an external planner may send (10 s of path): the original takes paths of any
length, and some planners send more than the env's default of 50."""


def external_env_config(env_config: dict[str, Any]) -> dict[str, Any]:
    """The env config for an external planner, where the config does not say otherwise:
    like the original, a collision is counted and the car drives on
    (``terminate_on_collision`` off), and paths of up to :data:`EXTERNAL_PATH_POINTS`
    points are taken."""
    return {"terminate_on_collision": False, "path_points": EXTERNAL_PATH_POINTS,
            **env_config}


def planner_maps(args: argparse.Namespace, runs: Sequence[AgentRun],
                 road: Any) -> contextlib.ExitStack:
    """The env's map in every external agent's ``--planner-map`` file for the whole run,
    each planner's own file put back at the end (:class:`~sdc_gym.bridge.PlannerMap`)."""
    stack = contextlib.ExitStack()
    if args.planner_map is None or road is None:
        return stack
    folders = {planner_cwd(run) or "." for run in runs if is_external(run.spec)}
    try:
        for folder in sorted(folders):
            stack.enter_context(PlannerMap(road, Path(folder) / Path(args.planner_map)
                                           .expanduser()))
    except BaseException:
        stack.close()
        raise
    return stack
