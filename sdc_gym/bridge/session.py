"""One episode's external planner: export the map, start the process, connect, exchange, stop.

:class:`PlannerSession` ties :mod:`~sdc_gym.bridge.process` and
:mod:`~sdc_gym.bridge.connection` together and turns low-level symptoms into the fault
that caused them: a closed connection or a missing reply from a process that has exited
is :class:`~sdc_gym.bridge.errors.PlannerDied` (with the exit status and the end of the
planner's output), not a network error. Drive an env with it::

    env = gym.make("sdc_gym/HighwayLoop-v0")
    with PlannerSession("./path_planning", PlannerOptions(cwd="build"),
                        road=env.unwrapped.road) as planner:
        observation, info = env.reset(seed=0)
        while True:
            path = planner.exchange(info["telemetry"])
            observation, reward, terminated, truncated, info = env.step(path)
            if terminated or truncated:
                break
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from sdc_gym.bridge.connection import ExchangeStats, PlannerConnection
from sdc_gym.bridge.errors import (
    BridgeError,
    PlannerDied,
    PlannerDisconnected,
    PlannerLogFlooded,
    ReplyTimeout,
)
from sdc_gym.bridge.map_file import PlannerMap
from sdc_gym.bridge.planner_log import DEFAULT_LOG_LIMIT_BYTES
from sdc_gym.bridge.process import PlannerProcess
from sdc_gym.road.highway_map import HighwayMap

EXIT_WAIT_S: Final = 1.0  # after a disconnection: time for the process to finish exiting


@dataclass(frozen=True)
class PlannerOptions:
    """How to run an external planner. Times are wall-clock seconds.

    Attributes:
        cwd: the planner's working directory (default: the current one).
        port: the port it listens on; ``None``: a free one when the command has ``{port}``,
            else 4567 (the original's).
        map_export: where to put the env's map in the original format before starting,
            relative to ``cwd`` (the template reads ``../data/highway_map.csv``); ``None``:
            leave the planner's own map (it must then be the env's map). The planner's own
            file is rewritten only when its numbers differ, and put back when the session
            closes (:class:`~sdc_gym.bridge.map_file.PlannerMap`).
        startup_timeout: how long to retry connecting while the planner starts.
        reply_timeout: how long to wait for each reply before giving up on the planner.
        log_path: file for the planner's output (default: a temporary file).
        log_limit: bytes; the log file never grows past this (it keeps its beginning and
            its end), and a planner printing more has flooded it: it is ended and the
            episode ends with the reason ``log_flooded``.
        manual_probe: send one manual-mode message (``42["telemetry",null]``) after
            connecting and require ``42["manual",{}]`` back, as a protocol check. The
            original sends those only in manual mode, so this is off by default.
    """

    cwd: str | None = None
    port: int | None = None
    map_export: str | None = None
    startup_timeout: float = 10.0
    reply_timeout: float = 5.0
    log_path: str | None = None
    log_limit: int = DEFAULT_LOG_LIMIT_BYTES
    manual_probe: bool = False

    def __post_init__(self) -> None:
        for name in ("startup_timeout", "reply_timeout"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0 s, got {getattr(self, name)!r}")
        if self.port is not None and not 0 < self.port < 65536:
            raise ValueError(f"port must be in 1..65535 (or None), got {self.port!r}")
        if isinstance(self.log_limit, bool) or not isinstance(self.log_limit, int) \
                or self.log_limit < 1024:
            raise ValueError(f"log_limit must be an int >= 1024 bytes, got {self.log_limit!r}")


class PlannerSession:
    """An external planner for one episode; see the module docstring.

    Args:
        command: the planner's command line (``{port}`` is replaced by the port).
        options: :class:`PlannerOptions`.
        road: the env's map, needed when ``options.map_export`` is set.
    """

    def __init__(self, command: str | Sequence[str], options: PlannerOptions | None = None,
                 *, road: HighwayMap | None = None) -> None:
        self.options = options or PlannerOptions()
        if self.options.map_export is not None and road is None:
            raise ValueError("map_export needs the road to export (pass road=env.unwrapped.road)")
        self.road = road
        self.process = PlannerProcess(command, cwd=self.options.cwd, port=self.options.port,
                                      log_path=self.options.log_path,
                                      log_limit=self.options.log_limit)
        self.connection: PlannerConnection | None = None
        self.map_file: Path | None = None
        self._planner_map: PlannerMap | None = None

    @property
    def stats(self) -> ExchangeStats:
        """Exchanges so far and the wall time they took (zeros before connecting)."""
        return self.connection.stats if self.connection is not None else ExchangeStats()

    def start(self) -> None:
        """Export the map (if asked), start the planner and connect to it.

        Raises a :class:`~sdc_gym.bridge.errors.BridgeError` (the process is stopped then).
        """
        options = self.options
        if options.map_export is not None:
            assert self.road is not None
            target = self.process.cwd / os.path.expanduser(options.map_export)
            self._planner_map = PlannerMap(self.road, target)
            self.map_file = self._planner_map.__enter__()
        try:
            self.process.start()
        except BaseException:
            self.close()
            raise
        try:
            self.connection = self._explained(
                PlannerConnection.connect, self.process.port, options.startup_timeout,
                options.reply_timeout, self.process.check_alive)
            if options.manual_probe:
                self._explained(self.connection.probe_manual)
        except BaseException:
            self.close()
            raise

    def exchange(self, telemetry: Mapping[str, Any]) -> NDArray[np.float64]:
        """One lock-step round: the planner's path for this telemetry, ``(m, 2)``."""
        if self.connection is None:
            raise RuntimeError("call start() before exchange()")
        return self._explained(self.connection.exchange, telemetry)

    def _explained(self, call: Any, *args: Any) -> Any:
        """Run ``call``; on a fault, name the real cause and where the planner's output is."""
        self._check_log()
        try:
            result = self._named(call, *args)
        except BridgeError:
            self._check_log()  # a flood ends the planner: that is the cause of the rest
            raise
        self._check_log()
        return result

    def _check_log(self) -> None:
        """Raise :class:`~sdc_gym.bridge.errors.PlannerLogFlooded` once the log flooded."""
        process = self.process
        if process.log_flooded:
            raise PlannerLogFlooded(
                f"the planner printed more than its log limit of {process.log_limit} bytes "
                f"and was stopped (after {self.stats.exchanges} exchanges); its log "
                f"{process.log_path} keeps the beginning and the last part") from None

    def _named(self, call: Any, *args: Any) -> Any:
        """Run ``call``; a connection's symptom becomes its cause (the process died)."""
        try:
            return call(*args)
        except (PlannerDisconnected, ReplyTimeout) as error:
            # The connection's symptom; the cause is often that the process died.
            code = self.process.wait_exit(EXIT_WAIT_S if isinstance(
                error, PlannerDisconnected) else 0.0)
            if code is not None:
                try:
                    self.process.check_alive()
                except PlannerDied as died:
                    raise PlannerDied(f"{died} (after {self.stats.exchanges} exchanges; "
                                      f"{error})") from None
            raise type(error)(f"{error}; the planner's output is in "
                              f"{self.process.log_path}") from None
        except PlannerDied:
            raise  # its message quotes the planner's output already
        except BridgeError as error:
            count = self.stats.exchanges
            where = f" (reply to telemetry message {count})" if count else ""
            raise type(error)(f"{error}{where}; the planner's output is in "
                              f"{self.process.log_path}") from None

    def close(self) -> None:
        """Stop the planner with its whole process group, then close the connection (in
        that order: closing first would wait for the handshake of a stuck planner)."""
        self.process.stop()
        if self.connection is not None:
            self.connection.close()
        if self._planner_map is not None:
            self._planner_map.restore()

    def __enter__(self) -> PlannerSession:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
