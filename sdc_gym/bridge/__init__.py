"""Drive planners written for the original highway simulator through its wire protocol.

Hundreds of public planners for Udacity's highway simulator are websocket servers
(uWebSockets, port 4567) that wait for the simulator to connect, then answer every
``42["telemetry",{...}]`` message with ``42["control",{"next_x":[...],"next_y":[...]}]``.
This package plays the simulator's side for ``sdc_gym/HighwayLoop-v0``, so such a program
drives our env unchanged, faster than real time:

* :mod:`~sdc_gym.bridge.protocol`: the frames, with the original's float formatting;
* :mod:`~sdc_gym.bridge.connection`: the websocket client, one lock-step exchange per
  env step;
* :mod:`~sdc_gym.bridge.process`: one planner process per episode under a watchdog
  (:mod:`~sdc_gym.bridge.reaper`) that ends its whole process tree, output to a log file
  of bounded size (:mod:`~sdc_gym.bridge.planner_log`);
* :mod:`~sdc_gym.bridge.session`: the three together, faults named by their cause;
* :mod:`~sdc_gym.bridge.map_file`: any of our maps as the original ``highway_map.csv``
  (command line: ``python -m sdc_gym.bridge.export_map``).

Timing is simulated, not measured: the env sends telemetry after each step, the reply is
the next step's action, and it takes effect ``latency_steps`` physics frames after the
telemetry (the original's "the car keeps consuming the old path meanwhile"). The
original's lock-step has the next telemetry go out when the reply arrives, i.e.
``steps_per_action == latency_steps`` (the env's default; :func:`lockstep_config`). Wall
time only bounds how long we wait for a stuck planner, so results are reproducible.
"""

from typing import Any

from sdc_gym.bridge.connection import ExchangeStats, PlannerConnection
from sdc_gym.bridge.errors import (
    FAULT_REASONS,
    BridgeError,
    EmptyPath,
    InvalidPath,
    MalformedReply,
    ManualReply,
    NonFinitePoint,
    PlannerDied,
    PlannerDisconnected,
    PlannerLogFlooded,
    PlannerNotFound,
    PlannerNotListening,
    PortInUse,
    ReplyTimeout,
)
from sdc_gym.bridge.map_file import PlannerMap, export_highway_map
from sdc_gym.bridge.planner_log import DEFAULT_LOG_LIMIT_BYTES
from sdc_gym.bridge.process import PlannerProcess
from sdc_gym.bridge.protocol import DEFAULT_PORT, decode_reply, encode_telemetry
from sdc_gym.bridge.session import PlannerOptions, PlannerSession


def lockstep_config(reply_latency_frames: int) -> dict[str, Any]:
    """Env config overrides for the original's lock-step with a reply latency of
    ``reply_latency_frames`` physics frames (0.02 s each): one telemetry message per
    env step of that many frames, the reply taking effect at its end."""
    if not (isinstance(reply_latency_frames, int) and reply_latency_frames >= 1):
        raise ValueError(f"the reply latency must be an int >= 1 frame, got "
                         f"{reply_latency_frames!r}")
    return {"steps_per_action": reply_latency_frames, "latency_steps": reply_latency_frames}


__all__ = [
    "DEFAULT_LOG_LIMIT_BYTES", "DEFAULT_PORT", "FAULT_REASONS", "BridgeError", "EmptyPath",
    "ExchangeStats", "InvalidPath",
    "MalformedReply", "ManualReply", "NonFinitePoint", "PlannerConnection", "PlannerDied",
    "PlannerDisconnected", "PlannerLogFlooded", "PlannerMap", "PlannerNotFound",
    "PlannerNotListening", "PlannerOptions", "PlannerProcess", "PlannerSession", "PortInUse",
    "ReplyTimeout", "decode_reply",
    "encode_telemetry", "export_highway_map", "lockstep_config",
]
