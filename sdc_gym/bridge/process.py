"""Launching an external planner, capturing its output, and ending it with all its children.

The original's planners keep state across reconnections and many crash when the
simulator disconnects, so each episode gets a fresh process. It runs in the planner's
working directory, the way ``cd DIR && COMMAND`` would (they read their map from a path
relative to it), in its own session. Its standard output and error go through a pipe to
one log file of bounded size (:mod:`sdc_gym.bridge.planner_log`): a planner that prints
more than the limit has *flooded*, is ended, and its episode ends with the reason
``log_flooded``.

The planner is started by a small watchdog process, :mod:`sdc_gym.bridge.reaper`, which
is a child subreaper: every process of the planner's tree, even a ``setsid`` grandchild
that outlives the planner, stays below it. :meth:`PlannerProcess.stop` asks it to end the
whole tree (SIGTERM, a grace period, SIGKILL); it does the same by itself if the process
that started the planner is killed before it can call ``stop()``.

The port: a command containing ``{port}`` (e.g. ``python planner.py --port {port}``) gets
a free port picked here, so episodes can run in parallel; otherwise the planner listens
on its own hard-wired port, 4567 for the original's template (``port=`` overrides it).
"""

from __future__ import annotations

import os
import select
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

from sdc_gym.bridge.errors import PlannerDied, PlannerNotFound, PortInUse
from sdc_gym.bridge.planner_log import DEFAULT_LOG_LIMIT_BYTES, CappedLog
from sdc_gym.bridge.protocol import DEFAULT_PORT

PORT_PLACEHOLDER: Final = "{port}"
STOP_GRACE_S: Final = 2.0  # between SIGTERM to the tree and SIGKILL (the reaper's GRACE_S)
REAPER_EXIT_S: Final = 3.0  # beyond the grace: the reaper's SIGKILL sweep and its own exit
STARTUP_WAIT_S: Final = 30.0  # for the reaper (a Python start-up) to start the planner
LOG_TAIL_LINES: Final = 12  # lines of the planner's output quoted in fault messages
REAPER_SCRIPT: Final = Path(__file__).with_name("reaper.py")  # run as a script: stdlib only


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port nothing listens on right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return int(probe.getsockname()[1])


def port_is_open(port: int, host: str = "127.0.0.1") -> bool:
    """Whether something accepts TCP connections on ``host:port``."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.settimeout(1.0)
        return probe.connect_ex((host, port)) == 0


def program_problem(program: str, cwd: Path) -> str | None:
    """Why ``program`` cannot be started from ``cwd`` (``None``: it can), looked up as
    ``execvp`` does after ``cd cwd``: a path with a slash relative to ``cwd``, a bare name
    on ``PATH``."""
    if os.sep not in program:
        return None if shutil.which(program) else f"no program {program!r} on PATH"
    path = cwd / os.path.expanduser(program)
    if not path.exists():
        return f"no such file: {path}"
    if path.is_dir():
        return f"{path} is a folder, not a program"
    if not os.access(path, os.X_OK):
        return f"{path} is not executable (chmod +x {program})"
    return None


def port_holder(port: int) -> str | None:
    """The process listening on TCP ``port``, as ``pid N (command)``, when Linux's
    ``/proc`` tells (only processes of this user are visible); else ``None``."""
    inodes = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()  # local address HEX_IP:HEX_PORT, state 0A = LISTEN
            if len(fields) > 9 and fields[3] == "0A" \
                    and int(fields[1].rpartition(":")[2], 16) == port:
                inodes.add(f"socket:[{fields[9]}]")
    if not inodes:
        return None
    for fd_folder in Path("/proc").glob("[0-9]*/fd"):
        try:
            if any(os.readlink(fd) in inodes for fd in fd_folder.iterdir()):
                pid = fd_folder.parent.name
                words = (fd_folder.parent / "cmdline").read_bytes().split(b"\0")
                command = " ".join(word.decode(errors="replace") for word in words if word)
                return f"pid {pid} ({command[:120]})"
        except OSError:  # gone, or another user's
            continue
    return None


class PlannerProcess:
    """One run of an external planner command; see the module docstring.

    Args:
        command: the command line (split like a POSIX shell does, no shell features) or
            its argument list; ``{port}`` in an argument is replaced by :attr:`port`.
        cwd: working directory (default: the current one). A relative program path such
            as ``./path_planning`` is found relative to it, as after ``cd``.
        port: the port the planner will listen on; ``None``: a free port when the command
            has ``{port}``, else :data:`~sdc_gym.bridge.protocol.DEFAULT_PORT`.
        log_path: file for the planner's output (created with its folder, overwritten);
            ``None``: a new file in the system's temporary folder.
        log_limit: the log file's largest size in bytes; more output floods it
            (:attr:`log_flooded`) and ends the planner.
        env: variables set for the planner on top of this process's environment (e.g.
            a ROS stack's ``ROS_MASTER_URI``).
    """

    def __init__(self, command: str | Sequence[str], *, cwd: str | os.PathLike[str] | None = None,
                 port: int | None = None, log_path: str | os.PathLike[str] | None = None,
                 log_limit: int = DEFAULT_LOG_LIMIT_BYTES,
                 env: Mapping[str, str] | None = None) -> None:
        arguments = shlex.split(command) if isinstance(command, str) else list(command)
        if not arguments:
            raise PlannerNotFound("the planner command is empty")
        takes_port = any(PORT_PLACEHOLDER in argument for argument in arguments)
        if port is None:
            port = free_port() if takes_port else DEFAULT_PORT
        self.port = int(port)
        self.arguments = [argument.replace(PORT_PLACEHOLDER, str(self.port))
                          for argument in arguments]
        self.cwd = Path(cwd) if cwd is not None else Path.cwd()
        self.log_path = Path(log_path) if log_path is not None else None
        self.log_limit = int(log_limit)
        self.env = dict(env or {})
        self._reaper: subprocess.Popen[bytes] | None = None
        self._log: CappedLog | None = None
        self._control: int | None = None  # our end of the reaper's stdin: closing it = stop
        self._control_lock = threading.Lock()
        self._status: int | None = None  # the reaper's status pipe
        self._status_buffer = b""
        self._pid: int | None = None
        self._exit_code: int | None = None
        self._stopped = False

    @property
    def pid(self) -> int | None:
        """The planner's process id (also its process group id), once started."""
        return self._pid

    @property
    def reaper_pid(self) -> int | None:
        """The process id of the watchdog that is the planner's parent."""
        return self._reaper.pid if self._reaper is not None else None

    @property
    def command_line(self) -> str:
        return shlex.join(self.arguments)

    @property
    def log_flooded(self) -> bool:
        """Whether the planner printed more than :attr:`log_limit` bytes."""
        return self._log is not None and self._log.flooded

    def start(self) -> None:
        """Launch the planner. Raises :class:`~sdc_gym.bridge.errors.PortInUse` when
        something already listens on the port (we would talk to it instead) and
        :class:`~sdc_gym.bridge.errors.PlannerNotFound` when the command cannot run."""
        if self._reaper is not None:
            raise RuntimeError("the planner process was already started")
        if not self.cwd.is_dir():
            raise PlannerNotFound(f"the planner's working directory does not exist: {self.cwd}")
        # The command first: a missing planner is the fault to report, whoever holds the port.
        problem = program_problem(self.arguments[0], self.cwd)
        if problem is not None:
            raise PlannerNotFound(f"cannot start the planner {self.command_line!r} in "
                                  f"{self.cwd}: {problem}")
        if port_is_open(self.port):
            holder = port_holder(self.port)
            raise PortInUse(
                f"port {self.port} is already in use before the planner started"
                f"{f', by {holder}' if holder else ''} (another planner still running?); "
                "stop that process, or give the command a {port} argument so that a free "
                "port is chosen")
        if self.log_path is None:
            handle, name = tempfile.mkstemp(prefix="sdc_gym_planner_", suffix=".log")
            os.close(handle)
            self.log_path = Path(name)
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        log_read, log_write = os.pipe()
        try:
            self._log = CappedLog(log_read, self.log_path, self.log_limit,
                                  on_flood=self._end_tree)
        except BaseException:
            os.close(log_read)
            os.close(log_write)
            raise
        status_read, status_write = os.pipe()
        control_read, control_write = os.pipe()
        try:
            self._reaper = subprocess.Popen(
                [sys.executable, str(REAPER_SCRIPT), str(os.getpid()), str(status_write),
                 "--", *self.arguments],
                cwd=self.cwd, stdin=control_read, stdout=log_write, stderr=log_write,
                pass_fds=(status_write,), start_new_session=True,
                env={**os.environ, **self.env} if self.env else None)
        except BaseException:
            os.close(status_read)
            os.close(control_write)
            raise
        finally:  # the log's reader sees its end of file once every writer is gone
            for fd in (log_write, status_write, control_read):
                os.close(fd)
        self._control, self._status = control_write, status_read
        line = self._status_line(STARTUP_WAIT_S)
        if line is not None and line.startswith("started "):
            self._pid = int(line.split()[1])
            return
        self.stop()
        reason = (line.split(maxsplit=2)[2] if line is not None and line.startswith("error ")
                  else f"its watchdog did not start it within {STARTUP_WAIT_S:g} s"
                  f"{self._tail()}")
        raise PlannerNotFound(f"cannot start the planner {self.command_line!r} in "
                              f"{self.cwd}: {reason}")

    def _status_line(self, timeout: float) -> str | None:
        """The reaper's next status line within ``timeout`` s (``None``: none came)."""
        deadline = time.monotonic() + timeout
        while b"\n" not in self._status_buffer:
            if self._status is None:
                return None
            left = deadline - time.monotonic()
            readable, _, _ = select.select([self._status], [], [], max(left, 0.0))
            if not readable:
                return None
            chunk = os.read(self._status, 4096)
            if not chunk:  # the reaper exited
                os.close(self._status)
                self._status = None
                return None
            self._status_buffer += chunk
        line, _, self._status_buffer = self._status_buffer.partition(b"\n")
        return line.decode()

    def _poll_status(self, timeout: float = 0.0) -> None:
        """Read the reaper's status lines until the planner's exit or ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while self._exit_code is None:
            line = self._status_line(max(deadline - time.monotonic(), 0.0))
            if line is None:
                return
            if line.startswith("exit "):
                self._exit_code = int(line.split()[1])

    def exit_code(self) -> int | None:
        """The planner's exit status once it has exited (negative: killed by that signal)."""
        self._poll_status()
        return self._exit_code

    def check_alive(self) -> None:
        """Raise :class:`~sdc_gym.bridge.errors.PlannerDied` if the planner has exited."""
        code = self.exit_code()
        if code is not None:
            raise PlannerDied(f"the planner exited with {_status(code)}{self._tail()}")

    def wait_exit(self, timeout: float) -> int | None:
        """Wait up to ``timeout`` s for the planner to exit; its exit status or ``None``."""
        if self._reaper is None:
            return None
        self._poll_status(timeout)
        return self._exit_code

    def log_tail(self, lines: int = LOG_TAIL_LINES) -> str:
        """The last ``lines`` lines of the planner's output so far."""
        return self._log.tail_text(lines) if self._log is not None else ""

    def _tail(self) -> str:
        tail = self.log_tail()
        where = f"; its output is in {self.log_path}"
        return f"{where}, ending:\n{tail}" if tail else f"{where} (empty)"

    def _end_tree(self) -> None:
        """Ask the reaper to end the planner's tree (any thread; safe to repeat)."""
        with self._control_lock:
            if self._control is not None:
                os.close(self._control)
                self._control = None

    def stop(self) -> None:
        """End the planner and every process of its tree (safe to call twice).

        The reaper sends SIGTERM to the tree, waits up to :data:`STOP_GRACE_S` for it to
        exit, then SIGKILLs whatever is left, and exits; the log file is then finished.
        """
        reaper = self._reaper
        if reaper is not None and not self._stopped:
            self._stopped = True
            self._end_tree()
            try:
                reaper.wait(STOP_GRACE_S + REAPER_EXIT_S)
            except subprocess.TimeoutExpired:  # cannot happen unless the reaper hangs
                if self._pid is not None:
                    _signal_group(self._pid, signal.SIGKILL)
                reaper.kill()
                reaper.wait()
            self._poll_status()
            if self._status is not None:
                os.close(self._status)
                self._status = None
        if self._log is not None:
            self._log.close()

    def __enter__(self) -> PlannerProcess:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _signal_group(group: int, signum: signal.Signals) -> None:
    try:
        os.killpg(group, signum)
    except (ProcessLookupError, PermissionError):
        pass  # the group is gone already


def _status(code: int) -> str:
    if code < 0:
        try:
            return f"signal {signal.Signals(-code).name}"
        except ValueError:
            return f"signal {-code}"
    return f"exit code {code}"
