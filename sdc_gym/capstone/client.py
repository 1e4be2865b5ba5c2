"""The simulator's Socket.IO connection to a stack's styx server.

:class:`StyxClient` is python-socketio's own client (4.x: Engine.IO protocol 3, the Unity
client's; 5.x: protocol 4), connected over a websocket as the Unity client was. The
server's messages (``steer``, ``throttle``, ``brake``, ``drawline``) arrive on the
client's thread and are kept as the *latest value of each* (the original's car holds its
last command until the next one); the simulator's loop reads them with
:meth:`StyxClient.commands`. A message that cannot be read is kept as a fault and raised
in the simulator's thread at its next call, so the episode ends with its reason.

Two ways to talk:

* real time (the original's only mode): :meth:`StyxClient.emit` sends and returns at
  once; the stack answers whenever its nodes publish.
* lock-step: :meth:`StyxClient.exchange` sends telemetry with a Socket.IO
  acknowledgement and waits for it. ``server.py`` handles ``telemetry`` by emitting the
  commands its nodes queued, and python-socketio sends the acknowledgement after the
  handler returns, on the same websocket, so when it arrives every command of that
  exchange has arrived before it. The stack's code is unchanged: the acknowledgement is
  part of the protocol its server library already speaks.

Latency: the styx server's socket (``eventlet.listen``) keeps Nagle's algorithm, so its
second small message of an exchange waits for our TCP acknowledgement, which Linux
delays by up to 40 ms. The client acknowledges every message at once (``TCP_QUICKACK``
after each one, ``TCP_NODELAY`` for ours): 3-4 ms per exchange instead of 45 ms.
"""

from __future__ import annotations

import socket
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from sdc_gym.bridge.errors import BridgeError
from sdc_gym.capstone.errors import (
    MalformedCommand,
    StackDisconnected,
    StackNeverConnected,
    StackStalled,
)
from sdc_gym.capstone.protocol import (
    BRAKE,
    COMMAND_EVENTS,
    DRAWLINE,
    STEER,
    TELEMETRY,
    THROTTLE,
    command_value,
    drawline_points,
)
from sdc_gym.capstone.versions import check_protocol

RETRY_INTERVAL_S: Final = 0.05  # between connection attempts while the stack starts


def _socketio() -> Any:
    """The ``socketio`` module; python-socketio 4.x imports eventlet's zmq module when
    eventlet is installed, which warns that eventlet is deprecated: not our concern."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import socketio
    return socketio


@dataclass
class ClientStats:
    """Counts of the connection, for the episode's extras and the benchmarks."""

    sent: int = 0  # messages to the stack
    received: dict[str, int] = field(default_factory=lambda: dict.fromkeys(
        (*COMMAND_EVENTS, DRAWLINE), 0))
    exchanges: int = 0  # lock-step round trips
    wait_time: float = 0.0  # s spent waiting for them


class StyxClient:
    """The connection; see the module docstring. ``host``/``port``: the styx server's."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, int(port)
        self.protocol: int | None = None
        self.stats = ClientStats()
        self._lock = threading.Lock()
        self._commands: dict[str, float] = {}
        self._drawline: NDArray[np.float64] | None = None
        self._fault: BridgeError | None = None
        self._connected = False
        self._last_message = time.monotonic()
        self._acked = threading.Event()
        self._socket: socket.socket | None = None
        self._sio: Any = None

    # ------------------------------------------------------------------ connection
    def connect(self, timeout: float, alive: Callable[[], None] | None = None) -> None:
        """Connect within ``timeout`` wall seconds, retrying while the stack starts;
        ``alive()`` is called between attempts (it raises when the stack's process died).
        Raises :class:`StackNeverConnected` or
        :class:`~sdc_gym.capstone.errors.ProtocolMismatch`."""
        deadline = time.monotonic() + timeout
        last_error: Exception | None = None
        while True:
            if alive is not None:
                alive()
            try:
                self.protocol = check_protocol(self.host, self.port)
                self._open()
                return
            except OSError as error:  # nothing listens yet
                last_error = error
            except BridgeError:
                raise
            except Exception as error:  # socketio's ConnectionError: the handshake failed
                last_error = error
                self._close_client()
            if time.monotonic() > deadline:
                raise StackNeverConnected(
                    f"no styx server accepted a connection at {self.host}:{self.port} within "
                    f"{timeout:g} s (last error: {last_error}); does the stack's server.py "
                    "listen on that port?")
            time.sleep(RETRY_INTERVAL_S)

    def _open(self) -> None:
        socketio = _socketio()
        sio = socketio.Client(reconnection=False)
        for event in (*COMMAND_EVENTS, DRAWLINE):
            sio.on(event, self._handler(event))
        sio.on("disconnect", self._on_disconnect)
        self._sio = sio
        sio.connect(f"http://{self.host}:{self.port}", transports=["websocket"])
        websocket = getattr(sio.eio, "ws", None)
        self._socket = getattr(websocket, "sock", None)
        if self._socket is not None:
            self._socket.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._connected = True
        self._last_message = time.monotonic()

    def _quick_ack(self) -> None:
        sock = self._socket
        if sock is not None and hasattr(socket, "TCP_QUICKACK"):
            try:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_QUICKACK, 1)
            except OSError:
                pass  # closed meanwhile

    def _handler(self, event: str) -> Callable[..., None]:
        def handle(data: Any = None, *_: Any) -> None:
            self._quick_ack()
            try:
                value: Any = (drawline_points(data) if event == DRAWLINE
                              else command_value(event, data))
            except MalformedCommand as error:
                with self._lock:
                    self._fault = self._fault or error
                return
            with self._lock:
                self._last_message = time.monotonic()
                self.stats.received[event] += 1
                if event == DRAWLINE:
                    self._drawline = value
                else:
                    self._commands[event] = value
        return handle

    def _on_disconnect(self, *_: Any) -> None:
        with self._lock:
            if self._connected:
                self._connected = False
                self._fault = self._fault or StackDisconnected(
                    f"the styx server at {self.host}:{self.port} closed the connection")
        self._acked.set()

    def check(self) -> None:
        """Raise the first fault seen on the client's thread (malformed, disconnected)."""
        with self._lock:
            fault = self._fault
        if fault is not None:
            raise fault

    # ------------------------------------------------------------------ messages
    def emit(self, event: str, data: dict[str, Any]) -> None:
        """Send one message now (real time)."""
        self.check()
        self._sio.emit(event, data)
        self.stats.sent += 1

    def exchange(self, telemetry: dict[str, Any], timeout: float) -> None:
        """Lock-step: send ``telemetry`` and wait until the server has handled it (its
        commands have then arrived). Raises :class:`StackStalled` after ``timeout`` s."""
        self.check()
        self._acked.clear()
        start = time.perf_counter()
        self._sio.emit(TELEMETRY, telemetry, callback=self._on_ack)
        self.stats.sent += 1
        if not self._acked.wait(timeout):
            self.check()
            raise StackStalled(f"the styx server did not handle telemetry message "
                               f"{self.stats.exchanges + 1} within {timeout:g} s")
        self.stats.exchanges += 1
        self.stats.wait_time += time.perf_counter() - start
        self.check()

    def _on_ack(self, *_: Any) -> None:
        self._quick_ack()
        self._acked.set()

    def commands(self) -> dict[str, float]:
        """The latest value of each command event received so far (``steer``,
        ``throttle``, ``brake``; absent until the first)."""
        self.check()
        with self._lock:
            return dict(self._commands)

    def take_drawline(self) -> NDArray[np.float64] | None:
        """The points of the latest ``drawline`` since the last call (``None``: none)."""
        with self._lock:
            points, self._drawline = self._drawline, None
        return points

    def silent_for(self) -> float:
        """Wall seconds since the server's last message (or since connecting)."""
        with self._lock:
            return time.monotonic() - self._last_message

    def close(self) -> None:
        """Disconnect (safe to repeat)."""
        with self._lock:
            self._connected = False
        self._close_client()

    def _close_client(self) -> None:
        sio, self._sio = self._sio, None
        if sio is not None:
            try:
                sio.disconnect()
            except Exception:
                pass


__all__ = ["BRAKE", "STEER", "THROTTLE", "ClientStats", "StyxClient"]
