"""What can go wrong between the simulator side and an external planner, one class per fault.

Every fault is a :class:`BridgeError` with a short machine-readable ``reason`` (the episode's
``termination_reason`` when an evaluation ends on it) and a message that says what happened
and what to check. The classes exist so that callers and tests can catch one fault exactly.
"""

from __future__ import annotations


class BridgeError(RuntimeError):
    """A fault of the external planner or of its connection; ``reason`` names the kind."""

    reason = "bridge_error"


class PlannerNotFound(BridgeError):
    """The planner command cannot be started (missing file, not executable, bad cwd)."""

    reason = "planner_not_found"


class PortInUse(BridgeError):
    """Something already listens on the planner's port before the planner was started."""

    reason = "port_in_use"


class PlannerNotListening(BridgeError):
    """The planner runs but accepted no websocket connection within the start-up wait."""

    reason = "planner_not_listening"


class PlannerDied(BridgeError):
    """The planner process exited (before listening, or during the episode)."""

    reason = "planner_died"


class PlannerDisconnected(BridgeError):
    """The planner closed the connection but its process is still running."""

    reason = "planner_disconnected"


class ReplyTimeout(BridgeError):
    """No reply to a telemetry message within the reply time-out (wall clock)."""

    reason = "reply_timeout"


class MalformedReply(BridgeError):
    """A reply that is not ``42["control",{"next_x":[...],"next_y":[...]}]``."""

    reason = "malformed_reply"


class ManualReply(BridgeError):
    """The planner answered telemetry with ``42["manual",{}]``: it found no data in it."""

    reason = "manual_reply"


class EmptyPath(BridgeError):
    """A control message with no points (the original would stop the car dead)."""

    reason = "empty_path"


class NonFinitePoint(BridgeError):
    """A path point that is NaN or infinite (``null``, ``NaN`` or ``Infinity`` in the JSON)."""

    reason = "non_finite_point"


class InvalidPath(BridgeError):
    """Finite points the env cannot take: too many of them, or outside the map's bounds."""

    reason = "invalid_path"


class PlannerLogFlooded(BridgeError):
    """The planner printed more than its log's limit (it is ended; the log keeps its
    beginning and its last part)."""

    reason = "log_flooded"


FAULT_REASONS: tuple[str, ...] = tuple(
    cls.reason for cls in (
        PlannerNotFound, PortInUse, PlannerNotListening, PlannerDied, PlannerDisconnected,
        ReplyTimeout, MalformedReply, ManualReply, EmptyPath, NonFinitePoint, InvalidPath,
        PlannerLogFlooded))
"""Every fault reason, as found in an episode's ``termination_reason``."""
