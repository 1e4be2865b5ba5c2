"""Launching an external planner, capturing its output, and ending it with all its children.

The original's planners keep state across reconnections and many crash when the
simulator disconnects, so each episode gets a fresh process. It runs in its own session
(process group) in the planner's working directory, the way ``cd DIR && COMMAND`` would
(they read their map from a path relative to it). Its standard output and error go to one
log file. :meth:`PlannerProcess.stop` signals the whole group, so a planner started
through a shell script or one that forks leaves nothing behind; and a small watchdog
(:mod:`sdc_gym.bridge.reaper`) does the same if the process that started the planner is
killed before it can call ``stop()``.

The port: a command containing ``{port}`` (e.g. ``python planner.py --port {port}``) gets
a free port picked here, so episodes can run in parallel; otherwise the planner listens
on its own hard-wired port, 4567 for the original's template (``port=`` overrides it).
"""

from __future__ import annotations

import os
import shlex
import signal
import socket
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Final

from sdc_gym.bridge.errors import PlannerDied, PlannerNotFound, PortInUse
from sdc_gym.bridge.protocol import DEFAULT_PORT

PORT_PLACEHOLDER: Final = "{port}"
STOP_GRACE_S: Final = 2.0  # between SIGTERM to the group and SIGKILL
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
    """

    def __init__(self, command: str | Sequence[str], *, cwd: str | os.PathLike[str] | None = None,
                 port: int | None = None, log_path: str | os.PathLike[str] | None = None) -> None:
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
        self._popen: subprocess.Popen[bytes] | None = None
        self._reaper: subprocess.Popen[bytes] | None = None
        self._log: IO[bytes] | None = None
        self._stopped = False

    @property
    def pid(self) -> int | None:
        """The planner's process id (also its process group id), once started."""
        return self._popen.pid if self._popen is not None else None

    @property
    def command_line(self) -> str:
        return shlex.join(self.arguments)

    def start(self) -> None:
        """Launch the planner. Raises :class:`~sdc_gym.bridge.errors.PortInUse` when
        something already listens on the port (we would talk to it instead) and
        :class:`~sdc_gym.bridge.errors.PlannerNotFound` when the command cannot run."""
        if self._popen is not None:
            raise RuntimeError("the planner process was already started")
        if not self.cwd.is_dir():
            raise PlannerNotFound(f"the planner's working directory does not exist: {self.cwd}")
        if port_is_open(self.port):
            raise PortInUse(
                f"port {self.port} is already in use before the planner started (another "
                "planner still running?); stop that process, or give the command a {port} "
                "argument so that a free port is chosen")
        if self.log_path is None:
            handle, name = tempfile.mkstemp(prefix="sdc_gym_planner_", suffix=".log")
            os.close(handle)
            self.log_path = Path(name)
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self._log = self.log_path.open("wb")
        try:
            self._popen = subprocess.Popen(
                self.arguments, cwd=self.cwd, stdin=subprocess.DEVNULL, stdout=self._log,
                stderr=subprocess.STDOUT, start_new_session=True)
        except OSError as error:  # FileNotFoundError, PermissionError, ...
            self._close_log()
            raise PlannerNotFound(
                f"cannot start the planner {self.command_line!r} in {self.cwd}: "
                f"{error.strerror or error}") from None
        self._reaper = subprocess.Popen(
            [sys.executable, str(REAPER_SCRIPT), str(self._popen.pid), str(os.getpid())],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)

    def exit_code(self) -> int | None:
        """The planner's exit status once it has exited (negative: killed by that signal)."""
        return self._popen.poll() if self._popen is not None else None

    def check_alive(self) -> None:
        """Raise :class:`~sdc_gym.bridge.errors.PlannerDied` if the planner has exited."""
        code = self.exit_code()
        if code is not None:
            raise PlannerDied(f"the planner exited with {_status(code)}{self._tail()}")

    def wait_exit(self, timeout: float) -> int | None:
        """Wait up to ``timeout`` s for the planner to exit; its exit status or ``None``."""
        if self._popen is None:
            return None
        try:
            return self._popen.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def log_tail(self, lines: int = LOG_TAIL_LINES) -> str:
        """The last ``lines`` lines of the planner's output so far."""
        if self.log_path is None or not self.log_path.is_file():
            return ""
        if self._log is not None:
            self._log.flush()
        with self.log_path.open("rb") as handle:
            handle.seek(0, os.SEEK_END)
            handle.seek(max(handle.tell() - 8192, 0))
            text = handle.read().decode("utf-8", "replace")
        return "\n".join(text.splitlines()[-lines:])

    def _tail(self) -> str:
        tail = self.log_tail()
        where = f"; its output is in {self.log_path}"
        return f"{where}, ending:\n{tail}" if tail else f"{where} (empty)"

    def stop(self) -> None:
        """End the planner and every process of its group (safe to call twice).

        SIGTERM to the group, up to :data:`STOP_GRACE_S` for the planner to exit, then
        SIGKILL to whatever of the group is left.
        """
        popen = self._popen
        if popen is not None and not self._stopped:
            self._stopped = True  # never signal the group id again: it could be reused
            group = popen.pid  # start_new_session: the planner leads its own group
            _signal_group(group, signal.SIGTERM)
            try:
                popen.wait(STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                pass
            _signal_group(group, signal.SIGKILL)  # children that outlived their parent
            popen.wait()
        reaper, self._reaper = self._reaper, None
        if reaper is not None:  # its planner is gone: nothing left to watch
            reaper.terminate()
            reaper.wait()
        self._close_log()

    def _close_log(self) -> None:
        if self._log is not None:
            self._log.close()
            self._log = None

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
