"""A styx server spoken by hand, frame by frame, to pin the simulator's wire format.

:class:`RawStyxServer` is a websocket server (the ``websockets`` library) that speaks
Engine.IO protocol 3 and Socket.IO protocol 4 without any Socket.IO library, exactly as
python-engineio 3 / python-socketio 4 frame them on a websocket: it opens with
``0{"sid":...,"upgrades":[],"pingInterval":...,"pingTimeout":...}`` and ``40`` (the
default namespace connected), takes ``42[event,data]`` frames (``42N[...]`` with an
acknowledgement id N, answered ``43N[]``), and records every text frame it receives,
byte for byte. It answers the long-polling handshake ``GET /socket.io/?EIO=3&...`` as a
protocol-3 server does; ``protocol=4`` makes it answer like python-engineio 4 instead
(protocol 3 rejected with HTTP 400 and its message, protocol 4 accepted), to test the
version check. ``replies`` are frames sent after each ``telemetry`` frame.
"""

from __future__ import annotations

import re
import threading
from http import HTTPStatus
from typing import Any

from websockets.sync.server import ServerConnection, serve

OPEN = '0{"sid":"standin","upgrades":[],"pingInterval":25000,"pingTimeout":60000}'
UNSUPPORTED = "The client is using an unsupported version of the Socket.IO or Engine.IO " \
              "protocols"
_ACK = re.compile(r"^42(\d+)\[")


class RawStyxServer:
    """See the module docstring; use as a context manager, ``port`` is the OS's choice."""

    def __init__(self, protocol: int = 3, replies: list[str] | None = None) -> None:
        self.protocol = protocol
        self.replies = list(replies or [])
        self.frames: list[str] = []
        self.polls: list[str] = []
        self.telemetry_seen = threading.Event()
        self._server = serve(self._handle, "127.0.0.1", 0, process_request=self._http,
                             compression=None)
        self.port = int(self._server.socket.getsockname()[1])
        self._thread = threading.Thread(target=self._server.serve_forever, daemon=True)

    def __enter__(self) -> RawStyxServer:
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._server.shutdown()
        self._thread.join(5)

    def _http(self, connection: ServerConnection, request: Any) -> Any:
        if "transport=websocket" in request.path:
            return None  # the websocket handshake proceeds
        self.polls.append(request.path)
        asked = 3 if "EIO=3" in request.path else 4
        if asked != self.protocol and self.protocol == 4:
            return connection.respond(HTTPStatus.BAD_REQUEST, UNSUPPORTED)
        body = f"{len(OPEN)}:{OPEN}" if self.protocol == 3 else OPEN
        return connection.respond(HTTPStatus.OK, body)

    def _handle(self, websocket: ServerConnection) -> None:
        websocket.send(OPEN)
        websocket.send("40")
        for frame in websocket:
            if not isinstance(frame, str):
                continue
            if frame == "2":  # a protocol-3 client's ping
                websocket.send("3")
                continue
            self.frames.append(frame)
            if frame.startswith("42") and '["telemetry"' in frame[:20]:
                for reply in self.replies:
                    websocket.send(reply)
                if match := _ACK.match(frame):
                    websocket.send(f"43{match.group(1)}[]")
                self.telemetry_seen.set()
