"""Which Engine.IO protocol a styx server speaks, and whether the installed client does.

The original simulator's Unity client speaks Engine.IO protocol 3 (Socket.IO protocol 4)
over a websocket (it asks for ``/socket.io/?EIO=4&transport=websocket`` but frames and
pings as protocol 3). The stacks' ``server.py`` runs on python-socketio and
python-engineio: the course's first requirements pinned python-socketio 1.6.1 with
eventlet (python-engineio 1.x/2.x), later ones python-socketio 4.4.0 (python-engineio
3.x): every python-engineio before 4.0 speaks protocol 3, 4.x speaks protocol 4 only and
rejects a protocol-3 client (HTTP 400, "The client is using an unsupported version of the
Socket.IO or Engine.IO protocols"). A stack ported to python-socketio 5 therefore needs a
protocol-4 client.

sdc-gym's simulator side is python-socketio's own client: 4.x (with python-engineio 3.x:
protocol 3, the Unity client's) or 5.x (protocol 4); the installed one decides.
:func:`server_protocol` asks the server with one HTTP long-polling handshake (the
request every Engine.IO client may open with) and :func:`check_protocol` raises
:class:`~sdc_gym.capstone.errors.ProtocolMismatch` naming both versions and the fix when
they differ, instead of the silent hang the original showed in that case.
"""

from __future__ import annotations

import http.client
import re
from typing import Final

from sdc_gym.capstone.errors import ProtocolMismatch

SOCKET_PATH: Final = "/socket.io/"
PROBE_TIMEOUT_S: Final = 2.0
CLIENTS: Final = {3: "python-socketio>=4,<5 with python-engineio>=3.13,<4",
                  4: "python-socketio>=5,<6 (python-engineio 4)"}
SERVERS: Final = {3: "python-engineio < 4 (python-socketio 1.x-4.x, as the course pinned)",
                  4: "python-engineio 4.x (python-socketio 5.x)"}
_SID = re.compile(r'"sid"\s*:\s*"([^"]+)"')


def client_protocol() -> int:
    """The Engine.IO protocol of the installed python-engineio (3 before 4.0, else 4)."""
    import engineio

    major = int(str(engineio.__version__).split(".")[0])
    return 3 if major < 4 else 4


def _handshake(host: str, port: int, eio: int) -> tuple[int, str]:
    """One polling handshake ``EIO=eio``: the status and body; the session it opened is
    closed again at once (its open packet names it)."""
    query = f"{SOCKET_PATH}?EIO={eio}&transport=polling&t=sdcgym" + ("&b64=1" if eio == 3 else "")
    connection = http.client.HTTPConnection(host, port, timeout=PROBE_TIMEOUT_S)
    try:
        connection.request("GET", query)
        response = connection.getresponse()
        body = response.read().decode("utf-8", "replace")
        if response.status == 200 and (sid := _SID.search(body)):
            close = "1:1" if eio == 3 else "1"  # a close packet (protocol 3 frames its length)
            try:  # best effort: an unclosed probe session only times out on the server
                connection.request("POST", f"{query}&sid={sid.group(1)}", body=close,
                                   headers={"Content-Type": "text/plain;charset=UTF-8"})
                connection.getresponse().read()
            except (OSError, http.client.HTTPException):
                pass
        return response.status, body
    finally:
        connection.close()


def server_protocol(host: str, port: int) -> int | None:
    """The Engine.IO protocol the server at ``host:port`` accepts (3 or 4), ``None`` if it
    accepts neither handshake (not an Engine.IO server at ``/socket.io/``). Raises
    ``OSError`` when nothing accepts the connection."""
    for eio in (3, 4):
        status, _ = _handshake(host, port, eio)
        if status == 200:
            return eio
    return None


def check_protocol(host: str, port: int) -> int:
    """The server's protocol if the installed client speaks it; else
    :class:`~sdc_gym.capstone.errors.ProtocolMismatch` naming both and the fix."""
    ours = client_protocol()
    theirs = server_protocol(host, port)
    if theirs is None:
        raise ProtocolMismatch(
            f"the server at {host}:{port} answers but accepts no Engine.IO handshake at "
            f"{SOCKET_PATH} (protocol 3 or 4): is it a styx server (server.py)?")
    if theirs != ours:
        import engineio

        raise ProtocolMismatch(
            f"the stack's styx server at {host}:{port} speaks Engine.IO protocol {theirs} "
            f"({SERVERS[theirs]}), the installed client python-engineio "
            f"{engineio.__version__} speaks protocol {ours}: install {CLIENTS[theirs]} into "
            "sdc-gym's environment (pip install 'sdc-gym[capstone]' pins the protocol-3 "
            "client of the original stacks)")
    return theirs
