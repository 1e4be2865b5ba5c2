"""What can go wrong between sdc-gym's simulator side and a capstone stack's styx server.

Each fault is a :class:`~sdc_gym.bridge.errors.BridgeError` (the planner bridge's base: one
process machinery, one kind of fault) with a ``reason``, the episode's
``termination_reason`` when an evaluation ends on it. The stack's process faults are the
planner bridge's own classes (``planner_not_found``, ``planner_died``, ``log_flooded``).
"""

from __future__ import annotations

from sdc_gym.bridge.errors import BridgeError, PlannerDied, PlannerLogFlooded, PlannerNotFound


class StackNeverConnected(BridgeError):
    """No styx server accepted the simulator's connection within the start-up wait."""

    reason = "stack_never_connected"


class ProtocolMismatch(BridgeError):
    """The styx server speaks another Engine.IO protocol than the installed client."""

    reason = "protocol_mismatch"


class StackDisconnected(BridgeError):
    """The styx server closed the connection during the episode."""

    reason = "stack_disconnected"


class MalformedCommand(BridgeError):
    """A ``steer``/``throttle``/``brake``/``drawline`` message the simulator cannot read."""

    reason = "malformed_command"


class StackStalled(BridgeError):
    """In lock-step, the styx server did not answer a telemetry message in time."""

    reason = "stack_stalled"


class RosClockFailed(BridgeError):
    """Sim time: sdc-gym's ``/clock`` node could not run on the stack's master (no rospy,
    no master, ``/use_sim_time`` not true) or ended."""

    reason = "ros_clock_failed"


CAPSTONE_FAULT_REASONS: tuple[str, ...] = tuple(
    cls.reason for cls in (PlannerNotFound, PlannerDied, PlannerLogFlooded, StackNeverConnected,
                           ProtocolMismatch, StackDisconnected, MalformedCommand, StackStalled,
                           RosClockFailed))
"""Every reason a capstone episode can end on besides the env's own."""
