"""The capstone simulator's side of the styx protocol: sdc-gym plays the original track
simulator (a Socket.IO client) for a capstone team's whole ROS stack, unchanged.

``python -m sdc_gym.capstone`` (or ``sdc-gym-capstone``) connects to a running stack's
styx server and drives ``sdc_gym/TrackLoop-v0`` for it; ``evaluate.py --agents
"capstone:COMMAND"`` starts the stack too and scores it beside every other agent. See
``docs/capstone.md``.
"""

from sdc_gym.capstone.client import StyxClient
from sdc_gym.capstone.errors import (
    CAPSTONE_FAULT_REASONS,
    MalformedCommand,
    ProtocolMismatch,
    StackDisconnected,
    StackNeverConnected,
    StackStalled,
)
from sdc_gym.capstone.session import CapstoneOptions, CapstoneSession, run_episode
from sdc_gym.capstone.versions import check_protocol, client_protocol, server_protocol

__all__ = [
    "CAPSTONE_FAULT_REASONS",
    "CapstoneOptions",
    "CapstoneSession",
    "MalformedCommand",
    "ProtocolMismatch",
    "StackDisconnected",
    "StackNeverConnected",
    "StackStalled",
    "StyxClient",
    "check_protocol",
    "client_protocol",
    "run_episode",
    "server_protocol",
]
