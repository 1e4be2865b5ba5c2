"""The original highway simulator's wire format: telemetry out, control in.

The planners written for Udacity's highway simulator are uWebSockets servers built from
one template. The simulator is the websocket client; no Engine.IO / Socket.IO handshake
is exchanged, but every message is a Socket.IO event frame, the text ``42`` followed by a
JSON array ``[event, payload]``:

* simulator -> planner: ``42["telemetry",{...}]``, a FLAT object (see
  :data:`TELEMETRY_FIELDS`). The template finds the payload with ``hasData``: the text
  from the first ``[`` to the first ``}`` (plus one character), and any ``null`` in the
  message means manual mode. So a nested object, a ``null`` (a NaN printed by a JSON
  library) or a missing field breaks those planners; :func:`encode_telemetry` never
  produces one. Numbers are 32-bit floats printed with 7 significant digits, as C#'s
  ``float.ToString()`` prints them in the original (``%.7g`` with the exponent written
  ``1E-05`` and a negative zero written ``0``), car ids integers.
* in manual mode the simulator sends ``42["telemetry",null]`` (:data:`MANUAL_TELEMETRY`)
  and the planner answers ``42["manual",{}]`` (:data:`MANUAL_REPLY`).
* planner -> simulator: ``42["control",{"next_x":[...],"next_y":[...]}]``, one reply per
  telemetry message; :func:`decode_reply` turns it into an ``(m, 2)`` array of map points
  or raises the :mod:`sdc_gym.bridge.errors` class naming what is wrong with it.
"""

from __future__ import annotations

import functools
import json
import re
from collections.abc import Mapping
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from sdc_gym.bridge.errors import EmptyPath, MalformedReply, ManualReply, NonFinitePoint

DEFAULT_PORT: Final = 4567
"""The port every planner built from the template listens on."""
SOCKET_PATH: Final = "/socket.io/?EIO=4&transport=websocket"
"""The request path the original's Socket.IO client uses (the planners accept any path)."""
EVENT_PREFIX: Final = "42"
MANUAL_TELEMETRY: Final = '42["telemetry",null]'
MANUAL_REPLY: Final = '42["manual",{}]'
TELEMETRY_FIELDS: Final = (
    "x", "y", "yaw", "speed", "s", "d", "previous_path_x", "previous_path_y",
    "end_path_s", "end_path_d", "sensor_fusion")
"""The telemetry object's fields, in the original's order (units: m, degrees, mph)."""
_SCALARS: Final = ("x", "y", "yaw", "speed", "s", "d")
_EXCERPT_CHARS: Final = 160

_NUMBER: Final = "%.7g"  # the original's 32-bit floats, printed with 7 significant digits
# C# writes the exponent of small numbers as "1E-05" where %g writes "1e-05" (no field name
# holds "e-" or "e+", so the test below only finds numbers).
_LOWER_EXPONENT: Final = re.compile(r"(?<=\d)e(?=[-+])")
# ... and prints a negative zero as "0" (Mono, like the .NET Framework).
_NEGATIVE_ZERO: Final = re.compile(r"(?<=[,:\[])-0(?=[,\]}])")


@functools.lru_cache(maxsize=256)
def _telemetry_template(path_points: int, cars: int) -> str:
    """A ``%`` template of the telemetry frame for this many path points and cars.

    Formatting every number with one ``%`` call is about twice as fast as one call per
    number; there are only a few shapes per episode.
    """
    path = ",".join([_NUMBER] * path_points)
    car = "[%d," + ",".join([_NUMBER] * 6) + "]"
    scalars = ",".join(f'"{name}":{_NUMBER}' for name in _SCALARS)
    return (f'{EVENT_PREFIX}["telemetry",{{{scalars},"previous_path_x":[{path}],'
            f'"previous_path_y":[{path}],"end_path_s":{_NUMBER},"end_path_d":{_NUMBER},'
            f'"sensor_fusion":[{",".join([car] * cars)}]}}]')


def encode_telemetry(telemetry: Mapping[str, Any]) -> str:
    """The ``42["telemetry",{...}]`` frame for the env's telemetry object.

    ``telemetry`` is ``info["telemetry"]`` of ``sdc_gym/HighwayLoop-v0`` (or any mapping
    with :data:`TELEMETRY_FIELDS`). Raises ``ValueError`` naming a missing field or a
    non-finite number, which the planners could not read.
    """
    missing = [name for name in TELEMETRY_FIELDS if name not in telemetry]
    if missing:
        raise ValueError(f"telemetry lacks the field(s) {missing}; it needs {TELEMETRY_FIELDS}")
    t = telemetry
    path_x, path_y, rows = t["previous_path_x"], t["previous_path_y"], t["sensor_fusion"]
    if len(path_x) != len(path_y):
        raise ValueError(f"telemetry has {len(path_x)} previous_path_x but {len(path_y)} "
                         "previous_path_y numbers")
    values = [t["x"], t["y"], t["yaw"], t["speed"], t["s"], t["d"], *path_x, *path_y,
              t["end_path_s"], t["end_path_d"]]
    for row in rows:
        values.extend(row)
    try:
        text = _telemetry_template(len(path_x), len(rows)) % tuple(values)
    except (TypeError, ValueError):  # a sensor row of the wrong length, a NaN car id
        _raise_non_finite(telemetry)
        raise ValueError("telemetry sensor_fusion rows must be [id, x, y, vx, vy, s, d]"
                         ) from None
    # %.7g prints NaN and inf as "nan" and "inf", which no field name contains.
    if "nan" in text or "inf" in text:
        _raise_non_finite(telemetry)
    if "e-" in text or "e+" in text:
        text = _LOWER_EXPONENT.sub("E", text)
    if "-0," in text or "-0]" in text or "-0}" in text:
        text = _NEGATIVE_ZERO.sub("0", text)
    return text


def _raise_non_finite(telemetry: Mapping[str, Any]) -> None:
    for name in TELEMETRY_FIELDS:
        values = np.asarray(telemetry[name], dtype=np.float64)
        if values.size and not np.isfinite(values).all():
            raise ValueError(f"telemetry field {name!r} holds a non-finite number; the "
                             "original's planners cannot read NaN or inf")


def _excerpt(text: str) -> str:
    return repr(text if len(text) <= _EXCERPT_CHARS else text[:_EXCERPT_CHARS] + "...")


def decode_reply(message: str | bytes) -> NDArray[np.float64]:
    """The path of a ``42["control",{"next_x":[...],"next_y":[...]}]`` reply, ``(m, 2)``.

    Raises :class:`~sdc_gym.bridge.errors.ManualReply` for ``42["manual",{}]``,
    :class:`~sdc_gym.bridge.errors.EmptyPath` for a path without points,
    :class:`~sdc_gym.bridge.errors.NonFinitePoint` for ``null`` / ``NaN`` / ``Infinity``
    coordinates and :class:`~sdc_gym.bridge.errors.MalformedReply` for anything else that
    is not a control message; each message quotes the start of the reply.
    """
    payload = parse_event(message, expected="control")
    if not isinstance(payload, dict):
        raise MalformedReply(f"the control payload must be an object with next_x and next_y, "
                             f"got {type(payload).__name__}: {_excerpt(str(message))}")
    missing = [key for key in ("next_x", "next_y") if key not in payload]
    if missing:
        raise MalformedReply(f"the control message lacks {missing} (it has "
                             f"{sorted(payload)}): {_excerpt(str(message))}")
    xs, ys = payload["next_x"], payload["next_y"]
    if not isinstance(xs, list) or not isinstance(ys, list):
        raise MalformedReply("next_x and next_y must be JSON arrays of numbers: "
                             f"{_excerpt(str(message))}")
    if len(xs) != len(ys):
        raise MalformedReply(f"next_x has {len(xs)} numbers but next_y has {len(ys)}")
    if not xs:
        raise EmptyPath("the planner sent an empty path (next_x and next_y are []); the "
                        "original simulator would stop the car dead")
    for name, values in (("next_x", xs), ("next_y", ys)):
        # type() checks exclude bool (an int subclass) and strings, which numpy would coerce.
        if not all(type(value) is float or type(value) is int for value in values):
            _raise_bad_number(name, values)
    path = np.array([xs, ys], dtype=np.float64).T
    if not np.isfinite(path).all():
        row, column = np.argwhere(~np.isfinite(path))[0]
        name = ("next_x", "next_y")[column]
        raise NonFinitePoint(f"point {row} of the path is not finite: {name}[{row}] = "
                             f"{path[row, column]} (NaN/inf in the planner's arithmetic)")
    return path


def _raise_bad_number(name: str, values: list[Any]) -> None:
    index, value = next((i, v) for i, v in enumerate(values)
                        if not (type(v) is float or type(v) is int))
    if value is None:
        raise NonFinitePoint(
            f"point {index} of the path is null: {name}[{index}] = null (JSON libraries such "
            "as nlohmann::json print NaN and inf as null)")
    raise MalformedReply(f"{name}[{index}] is not a number: {value!r}")


def parse_event(message: str | bytes, *, expected: str) -> Any:
    """The payload of a ``42[event, payload]`` frame whose event is ``expected``.

    ``42["manual",{}]`` raises :class:`~sdc_gym.bridge.errors.ManualReply` unless
    ``expected`` is ``"manual"``; any other event, a binary frame, a frame without the
    ``42`` prefix or text that is not JSON raises
    :class:`~sdc_gym.bridge.errors.MalformedReply`.
    """
    if not isinstance(message, str):
        raise MalformedReply(f"the planner sent a binary frame ({len(message)} bytes); the "
                             "protocol uses text frames")
    if not message.startswith(EVENT_PREFIX):
        raise MalformedReply("the reply is not a Socket.IO event frame (it must start with "
                             f'42, as in 42["control",{{...}}]): {_excerpt(message)}')
    try:
        event = json.loads(message[len(EVENT_PREFIX):])
    except json.JSONDecodeError as error:
        raise MalformedReply(f"the reply is not valid JSON ({error.msg} at character "
                             f"{error.pos + len(EVENT_PREFIX)}): {_excerpt(message)}") from None
    if not (isinstance(event, list) and len(event) == 2 and isinstance(event[0], str)):
        raise MalformedReply(f'the reply must be ["event", payload]: {_excerpt(message)}')
    name, payload = event
    if name != expected:
        if name == "manual":
            raise ManualReply(
                'the planner answered 42["manual",{}]: it found no telemetry in the message '
                "(its hasData() treats any 'null' as manual mode)")
        raise MalformedReply(f"unexpected event {name!r}; expected {expected!r}: "
                             f"{_excerpt(message)}")
    return payload
