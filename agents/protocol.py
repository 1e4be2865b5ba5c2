"""What an agent is, and how it may end an episode early (the contract with the runner).

An agent has ``name``, ``reset()`` (start of an episode) and ``act(observation)`` (the
action for ``env.step``); optional parts the evaluation runner uses when present:
``wants_info = True`` (called as ``act(observation, info)``), ``episode_extras()`` (figures
added to the episode's result) and ``close()``. Any ``act`` may raise
:class:`EpisodeAborted` to end the episode now with a reason (an external planner's fault).

This module imports nothing from the project, so that agents (which raise) and the
evaluation package (which catches) both depend on it and never on each other.
"""

from __future__ import annotations

from typing import Any, Protocol


class Agent(Protocol):
    name: str

    def reset(self) -> None: ...

    def act(self, observation: Any) -> Any: ...


class EpisodeAborted(Exception):
    """Raised by an agent's ``act`` to end the episode now, e.g. an external planner's
    fault: ``reason`` becomes the episode's ``termination_reason``, the message its
    ``abort_message``."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason
