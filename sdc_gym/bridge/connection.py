"""The simulator side of one websocket connection to an external planner.

:meth:`PlannerConnection.connect` plays the original simulator's Socket.IO client: it
connects to ``ws://127.0.0.1:<port>/socket.io/?EIO=4&transport=websocket``, retrying while
the planner starts up, and sends nothing on connect. :meth:`PlannerConnection.exchange`
is one lock-step round: send ``42["telemetry",{...}]``, wait for the one reply, return
its path. Time-outs are wall clock and only detect a stuck planner; what the car does is
decided in simulated frames by the env (its ``latency_steps``), so a slow planner gives
the same episode as a fast one.

Uses the synchronous client of the ``websockets`` library over a socket opened here (no
proxy lookup, ``TCP_NODELAY`` so that small frames are not held back), without
compression or keep-alive pings, which the original does not use either.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray
from websockets.exceptions import ConnectionClosed, WebSocketException
from websockets.sync.client import ClientConnection
from websockets.sync.client import connect as websocket_connect

from sdc_gym.bridge.errors import (
    MalformedReply,
    PlannerDisconnected,
    PlannerNotListening,
    ReplyTimeout,
)
from sdc_gym.bridge.protocol import (
    MANUAL_TELEMETRY,
    SOCKET_PATH,
    decode_reply,
    encode_telemetry,
    parse_event,
)

LOCALHOST: Final = "127.0.0.1"
RETRY_INTERVAL_S: Final = 0.05  # between connection attempts while the planner starts
MAX_MESSAGE_BYTES: Final = 16 * 2**20  # a reply of 100,000 points still fits
CLOSE_TIMEOUT_S: Final = 1.0  # wait for the planner's closing handshake, then drop the socket


@dataclass
class ExchangeStats:
    """Counters of a connection: exchanges done and wall time spent in them.

    ``wait_time`` runs from sending the telemetry to having the reply text (the planner's
    thinking plus the transport); ``codec_time`` is encoding and decoding here.
    """

    exchanges: int = 0
    wait_time: float = 0.0
    codec_time: float = 0.0


class PlannerConnection:
    """One websocket connection to a planner; see the module docstring.

    Use :meth:`connect` to open one; close it with :meth:`close` (or a ``with`` block).
    """

    def __init__(self, websocket: ClientConnection, uri: str, reply_timeout: float) -> None:
        self._websocket = websocket
        self.uri = uri
        self.reply_timeout = reply_timeout
        self.stats = ExchangeStats()

    @classmethod
    def connect(cls, port: int, startup_timeout: float = 10.0, reply_timeout: float = 5.0,
                check_alive: Callable[[], None] | None = None, *, host: str = LOCALHOST,
                path: str = SOCKET_PATH) -> PlannerConnection:
        """Connect to the planner on ``port``, retrying until ``startup_timeout`` seconds.

        ``check_alive`` is called before every attempt and should raise when the planner's
        process has exited (see :meth:`sdc_gym.bridge.process.PlannerProcess.check_alive`),
        so that a crash at start-up is reported as such rather than as a time-out.
        Raises :class:`~sdc_gym.bridge.errors.PlannerNotListening` when nothing accepted a
        websocket connection in time.
        """
        if not 0 < port < 65536:
            raise ValueError(f"port must be in 1..65535, got {port}")
        uri = f"ws://{host}:{port}{path}"
        deadline = time.monotonic() + startup_timeout
        last_error: Exception | None = None
        while True:
            if check_alive is not None:
                check_alive()
            remaining = max(deadline - time.monotonic(), 0.01)
            try:
                sock = socket.create_connection((host, port), timeout=min(remaining, 1.0))
            except OSError as error:
                last_error = error
            else:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                try:
                    # Entered as a context manager, the way websockets wants its sync
                    # client used (websockets >= 17.1 warns otherwise).
                    websocket = websocket_connect(
                        uri, sock=sock, compression=None, ping_interval=None,
                        open_timeout=remaining, close_timeout=CLOSE_TIMEOUT_S,
                        max_size=MAX_MESSAGE_BYTES).__enter__()
                    return cls(websocket, uri, reply_timeout)
                except (OSError, WebSocketException) as error:  # TimeoutError is an OSError
                    sock.close()
                    last_error = error
            if time.monotonic() >= deadline:
                raise PlannerNotListening(
                    f"nothing accepted a websocket connection on {uri} within "
                    f"{startup_timeout:g} s (last error: {last_error}); is the planner "
                    "listening on that port?")
            time.sleep(RETRY_INTERVAL_S)

    def exchange(self, telemetry: Mapping[str, Any]) -> NDArray[np.float64]:
        """Send one telemetry message and return the reply's path, ``(m, 2)`` map points.

        Raises a :class:`~sdc_gym.bridge.errors.BridgeError`: the reply's faults (see
        :func:`~sdc_gym.bridge.protocol.decode_reply`),
        :class:`~sdc_gym.bridge.errors.ReplyTimeout` or
        :class:`~sdc_gym.bridge.errors.PlannerDisconnected`.
        """
        stats = self.stats
        started = time.perf_counter()
        message = encode_telemetry(telemetry)
        sent = time.perf_counter()
        reply = self._round_trip(message)
        received = time.perf_counter()
        stats.exchanges += 1
        try:
            return decode_reply(reply)
        finally:
            stats.wait_time += received - sent
            stats.codec_time += (sent - started) + (time.perf_counter() - received)

    def probe_manual(self) -> None:
        """Send manual-mode telemetry (``42["telemetry",null]``) and expect
        ``42["manual",{}]`` back: checks that the planner speaks the protocol."""
        reply = self._round_trip(MANUAL_TELEMETRY)
        try:
            parse_event(reply, expected="manual")
        except MalformedReply as error:
            raise MalformedReply(f'manual-mode telemetry must be answered with 42["manual",'
                                 f"{{}}]: {error}") from None

    def _round_trip(self, message: str) -> str | bytes:
        number = self.stats.exchanges + 1
        try:
            self._websocket.send(message)
            return self._websocket.recv(timeout=self.reply_timeout)
        except TimeoutError:
            raise ReplyTimeout(f"no reply to telemetry message {number} within "
                               f"{self.reply_timeout:g} s") from None
        except ConnectionClosed as error:
            raise PlannerDisconnected(f"the planner closed the connection at telemetry "
                                      f"message {number} ({error})") from None

    def close(self) -> None:
        """Close the connection (safe to call twice)."""
        self._websocket.close()

    def __enter__(self) -> PlannerConnection:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
