"""Sim time for a capstone stack run with ``use_sim_time``: sdc-gym owns its ``/clock``.

:class:`RosClock` starts :mod:`sdc_gym.capstone.clock_node` (a rospy node; see there for
the pipe's lines) on the Python that has rospy, with the stack's ``ROS_MASTER_URI``, and
asks it once per env step to publish the step's time and wait for the stack's answer:

1. ``/clock`` is set to the env's time (``info["time"]``, in ns; a stack's stamps and
   ``rospy.get_time()`` are the env's seconds). Every node of the stack that runs with
   ``/use_sim_time`` true sees time only there: a ``rospy.Rate(50)`` loop wakes once per
   20 ms tick, however long the wall takes.
2. The node then waits until each *watched topic* (by default the DBW node's three
   commands, ``/vehicle/throttle_cmd``, ``/vehicle/brake_cmd``,
   ``/vehicle/steering_cmd``) has had a message since the tick, at most ``wait`` wall
   seconds. The answer names the topics that had none.

The caller (:class:`~sdc_gym.capstone.session.CapstoneSession`) then sends the step's
telemetry in lock-step; see ``docs/capstone.md``, "Time", for when a step is handled.
The node is sdc-gym's child, not the stack's: it ends when its pipe closes (sdc-gym
closing or dying) and :meth:`RosClock.close` ends it in any case.
"""

from __future__ import annotations

import os
import queue
import subprocess
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Final

from sdc_gym.capstone.errors import RosClockFailed

CLOCK_NODE: Final = Path(__file__).resolve().parent / "clock_node.py"
DEFAULT_ROS_PYTHON: Final = "/usr/bin/python3"  # Debian's python3-rospy is for it
DEFAULT_MASTER_URI: Final = "http://127.0.0.1:11311"  # roscore's default
DBW_COMMAND_TOPICS: Final = ("/vehicle/throttle_cmd", "/vehicle/brake_cmd",
                             "/vehicle/steering_cmd")
"""What the original's ``dbw_node.py`` publishes every loop while DBW is on."""
STOP_WAIT_S: Final = 2.0
LOG_EXCERPT: Final = 1500  # characters of the node's log quoted in an error


def master_uri(uri: str | None = None) -> str:
    """``uri``, else ``$ROS_MASTER_URI``, else roscore's default."""
    return uri or os.environ.get("ROS_MASTER_URI") or DEFAULT_MASTER_URI


@dataclass(frozen=True)
class TickAnswer:
    """What the clock node saw after one tick: the watched topics without a message within
    the wait (empty: the stack answered) and the wall seconds it waited."""

    missing: tuple[str, ...]
    waited: float


class RosClock:
    """The ``/clock`` of a stack's master; see the module docstring.

    Args:
        uri: the stack's ``ROS_MASTER_URI`` (``None``: the environment's, else
            ``http://127.0.0.1:11311``).
        topics: the watched topics (at least one).
        python: the interpreter with rospy and rosgraph_msgs.
        log_path: the node's standard error (``None``: a file in the temp folder).
    """

    def __init__(self, uri: str | None = None, topics: tuple[str, ...] = DBW_COMMAND_TOPICS,
                 python: str = DEFAULT_ROS_PYTHON, log_path: str | None = None) -> None:
        if not topics or any(not t.startswith("/") or " " in t for t in topics):
            raise ValueError(f"RosClock topics must be absolute ROS names (at least one, no "
                             f"spaces), got {list(topics)!r}")
        self.uri = master_uri(uri)
        self.topics = tuple(topics)
        self.python = python
        self.log_path = log_path  # None: a new temporary file at start()
        self.pid: int | None = None
        self.ticks = 0
        self._process: subprocess.Popen[str] | None = None
        self._log: IO[str] | None = None
        self._lines: queue.Queue[str] = queue.Queue()

    def start(self, timeout: float) -> None:
        """Start the node and wait (``timeout`` wall s) until it is on the master with
        ``/use_sim_time`` true. Raises :class:`RosClockFailed` naming what is missing."""
        if not Path(self.python).is_file():
            raise RosClockFailed(f"sim time needs rospy, but the ROS Python {self.python!r} "
                                 "does not exist (Debian: apt-get install python3-rospy "
                                 "python3-rosgraph-msgs)")
        if self.log_path is None:
            handle, self.log_path = tempfile.mkstemp(prefix="sdc_gym_clock_", suffix=".log")
            os.close(handle)
        Path(self.log_path).parent.mkdir(parents=True, exist_ok=True)
        self._log = open(self.log_path, "w")  # closed in close()
        env = {**os.environ, "ROS_MASTER_URI": self.uri}
        env.setdefault("ROS_HOSTNAME", "127.0.0.1")
        self._process = subprocess.Popen(
            [self.python, str(CLOCK_NODE), *self.topics], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=self._log, text=True, bufsize=1, env=env)
        self.pid = self._process.pid
        threading.Thread(target=self._read_lines, args=(self._process.stdout,),
                         daemon=True).start()
        words = self._read_line(timeout, "start").split()
        if words[0] != "ready":
            raise RosClockFailed(f"the clock node could not start: {' '.join(words[1:])}")
        if words[1] != "use_sim_time=1":
            raise RosClockFailed(
                f"the stack's master at {self.uri} has /use_sim_time unset or false, so its "
                "nodes run on the wall clock and would ignore /clock; launch the stack with "
                "<param name=\"/use_sim_time\" value=\"true\"/> (or `rosparam set "
                "/use_sim_time true` before its nodes start)")

    def tick(self, nanoseconds: int, wait: float) -> TickAnswer:
        """Publish ``/clock`` = ``nanoseconds`` and wait up to ``wait`` wall s for every
        watched topic (see the module docstring)."""
        process = self._process
        if process is None or process.stdin is None:
            raise RosClockFailed("the clock node is not running (start() first)")
        try:
            process.stdin.write(f"tick {int(nanoseconds)} {wait:.6f}\n")
            process.stdin.flush()
        except (BrokenPipeError, ValueError):
            raise RosClockFailed(self._death("tick")) from None
        words = self._read_line(wait + 10.0, "tick").split()
        if words[0] != "done":
            raise RosClockFailed(f"the clock node answered {' '.join(words)[:200]!r}")
        self.ticks += 1
        count = int(words[1])
        return TickAnswer(missing=tuple(words[2:2 + count]), waited=float(words[-1]))

    def _read_lines(self, stream: IO[str]) -> None:
        """The reader thread: every line of the node, then "" at its end (pipes have no
        timeout of their own)."""
        for line in stream:
            self._lines.put(line)
        self._lines.put("")

    def _read_line(self, timeout: float, what: str) -> str:
        """The node's next line within ``timeout`` wall s."""
        try:
            line = self._lines.get(timeout=timeout)
        except queue.Empty:
            raise RosClockFailed(f"the clock node did not answer {what} within {timeout:g} "
                                 f"s; its log: {self._log_excerpt()}") from None
        if not line.strip():
            self._lines.put("")  # the end stays the end
            raise RosClockFailed(self._death(what))
        return line

    def _death(self, what: str) -> str:
        process = self._process
        code = None if process is None else process.poll()
        if process is not None and code is None:
            try:
                code = process.wait(STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                code = None
        return (f"the clock node ({self.python} {CLOCK_NODE.name}) ended during {what} "
                f"(exit status {code}); its log: {self._log_excerpt()}")

    def _log_excerpt(self) -> str:
        if self._log is not None:
            self._log.flush()
        if self.log_path is None:
            return "(none)"
        try:
            text = Path(self.log_path).read_text(errors="replace")
        except OSError:
            return "(none)"
        return text[-LOG_EXCERPT:].strip() or "(empty)"

    def close(self) -> None:
        """End the node (safe to repeat): ``quit``, then a signal if it lingers."""
        process, self._process = self._process, None
        if process is not None:
            try:
                if process.stdin is not None:
                    process.stdin.write("quit\n")
                    process.stdin.close()
            except (BrokenPipeError, ValueError, OSError):
                pass
            try:
                process.wait(STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
            if process.stdout is not None:
                process.stdout.close()
        if self._log is not None:
            self._log.close()
            self._log = None


def ros_available(python: str = DEFAULT_ROS_PYTHON) -> bool:
    """Whether ``python`` exists and can import rospy and rosgraph_msgs."""
    if not Path(python).is_file():
        return False
    check = subprocess.run([python, "-c", "import rospy, rosgraph_msgs.msg"],
                           capture_output=True, timeout=60, check=False)
    return check.returncode == 0


__all__ = ["DBW_COMMAND_TOPICS", "RosClock", "TickAnswer", "master_uri", "ros_available"]
