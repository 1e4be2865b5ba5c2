"""Go / stop decisions a learned policy takes on the track, their features and execution.

The track stack's behavior layer (:mod:`sdc_gym.stack.track.behavior`) decides, at each
waypoint-updater cycle, the cruise speed and whether to stop at the next stop line. A
learned policy chooses one of :data:`TRACK_ACTION_NAMES` per decision period:

=========  ====================================================================
``go``     cruise at the limit (less the rule-based policy's 0.15 m/s margin)
``go_75``  cruise at 75 % of it
``go_50``  cruise at 50 % of it
``stop``   stop at the next stop line (the updater's ramp, ~1 m before the line);
           with no stop line ahead, the same as ``go``
=========  ====================================================================

As a continuous ``Box(-1, 1, (2,))`` action: the cruise speed from 0 (-1) to the limit
(1), and stop at the next line when the second component is positive.

:class:`TrackFeatures` is the observation (table in its docstring) and
:class:`TrackDecisionBehavior` the :class:`~sdc_gym.stack.track.behavior.TrackBehaviorPolicy`
that executes the current action. The behavior-level env sets the action between its
steps; a trained policy running on the path-level env gives it a ``chooser`` instead.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.stack.track.behavior import (
    DEFAULT_COMFORTABLE_DECEL_MPS2,
    DEFAULT_SPEED_MARGIN_MPS,
    FEASIBILITY_SLACK_M,
    TrackBehaviorDecision,
    TrackSituation,
)
from sdc_gym.validation.actions import discrete_index, real_array

TRACK_ACTION_NAMES = ("go", "go_75", "go_50", "stop")
SPEED_FRACTIONS = (1.0, 0.75, 0.5, 1.0)
DISTANCE_SCALE_M = 100.0
STATE_TIME_SCALE_S = 10.0
LIGHT_ORDER = (RED, YELLOW, GREEN, UNKNOWN)


def action_decision(action: Any, situation: TrackSituation, continuous: bool
                    ) -> TrackBehaviorDecision:
    """The behavior decision an action stands for in ``situation``."""
    cruise = max(situation.speed_limit_mps - DEFAULT_SPEED_MARGIN_MPS, 0.0)
    if continuous:
        values = real_array(action, (2,), "a continuous track decision", "(speed, stop)")
        if not np.all(np.isfinite(values)) or np.any(np.abs(values) > 1.0 + 1e-6):
            raise ValueError(f"a continuous track decision is 2 finite numbers in [-1, 1] "
                             f"(speed, stop), got {np.asarray(action).tolist()!r}")
        speed = 0.5 * (float(values[0]) + 1.0) * cruise
        stop = float(values[1]) > 0.0
        name = "stop" if stop else "go"
    else:
        action = discrete_index(action, len(TRACK_ACTION_NAMES), TRACK_ACTION_NAMES)
        name = TRACK_ACTION_NAMES[action]
        speed = SPEED_FRACTIONS[int(action)] * cruise
        stop = name == "stop"
    waypoint = situation.stop_waypoint if stop else -1
    return TrackBehaviorDecision(speed, waypoint, name if waypoint >= 0 or not stop else "go")


class TrackFeatures:
    """The observation of a track decision, ``Box(float32, (12,))``:

    ==================  ========================================================  =======
    entry               meaning                                                   range
    ==================  ========================================================  =======
    speed               speed / limit                                             [0, 1.5]
    line_distance       distance to the next stop line / 100 m (1: none or far)   [0, 1]
    room                distance to where the car would stop / 100 m              [-1, 1]
    red .. unknown      the detector's light state of that line, one-hot (4)      {0, 1}
    state_time          time the state has been reported / 10 s                   [0, 1]
    braking_distance    comfortable (3.05 m/s^2) stopping distance / 100 m        [0, 1]
    can_stop            1 when the vehicle's full braking stops before the line   {0, 1}
    can_stop_gently     1 when comfortable braking does                           {0, 1}
    stopping            1 when the current decision is to stop                    {0, 1}
    ==================  ========================================================  =======
    """

    size = 12
    names = ("speed", "line_distance", "room", "red", "yellow", "green", "unknown",
             "state_time", "braking_distance", "can_stop", "can_stop_gently", "stopping")

    def __init__(self, max_decel_mps2: float,
                 comfortable_decel_mps2: float = DEFAULT_COMFORTABLE_DECEL_MPS2) -> None:
        if not (max_decel_mps2 > 0 and comfortable_decel_mps2 > 0):
            raise ValueError("decelerations must be > 0 m/s^2")
        self.max_decel = max_decel_mps2
        self.comfortable_decel = comfortable_decel_mps2
        low = np.zeros(self.size, dtype=np.float32)
        high = np.ones(self.size, dtype=np.float32)
        high[0] = 1.5
        low[2] = -1.0
        self.space = spaces.Box(low, high, dtype=np.float32)

    def encode(self, situation: TrackSituation, state_time_s: float,
               stopping: bool) -> NDArray[np.float32]:
        v = situation.speed_mps
        limit = max(situation.speed_limit_mps, 1e-6)
        room = situation.room_m
        has_line = situation.stop_line >= 0 and math.isfinite(situation.stop_line_distance_m)
        values = [0.0] * self.size
        values[0] = min(v / limit, 1.5)
        values[1] = min(situation.stop_line_distance_m / DISTANCE_SCALE_M, 1.0) \
            if has_line else 1.0
        values[2] = min(max(room / DISTANCE_SCALE_M, -1.0), 1.0) if has_line else 1.0
        values[3 + LIGHT_ORDER.index(situation.light_state
                                     if situation.light_state in LIGHT_ORDER else UNKNOWN)] = 1.0
        values[7] = min(state_time_s / STATE_TIME_SCALE_S, 1.0)
        values[8] = min(v * v / (2.0 * self.comfortable_decel) / DISTANCE_SCALE_M, 1.0)
        slack_room = max(room + FEASIBILITY_SLACK_M, 0.0)
        values[9] = float(has_line and v * v <= 2.0 * self.max_decel * slack_room)
        values[10] = float(has_line and v * v <= 2.0 * self.comfortable_decel * slack_room)
        values[11] = float(stopping)
        return np.asarray(values, dtype=np.float32)


class TrackDecisionBehavior:
    """Executes the current action at every updater cycle (see the module docstring).

    Args:
        features: the observation encoder.
        continuous: actions are ``Box(2)`` vectors rather than indices.
        chooser: when given, called with the observation to pick a new action every
            ``decision_period_s`` (a trained policy on the path-level env); otherwise the
            owner sets :attr:`action`.
    """

    def __init__(self, features: TrackFeatures, *, continuous: bool = False,
                 chooser: Callable[[NDArray[np.float32]], Any] | None = None,
                 decision_period_s: float = 1.0) -> None:
        self.features = features
        self.continuous = continuous
        self.chooser = chooser
        self.decision_period_s = decision_period_s
        self.reset()

    def reset(self) -> None:
        self.action: Any = np.array([1.0, -1.0], np.float32) if self.continuous else 0
        self.situation: TrackSituation | None = None
        self.decision: TrackBehaviorDecision | None = None
        self._state_key: tuple[int, int] = (-2, -2)
        self._state_since = 0.0
        self._next_choice = 0.0

    def state_time(self, situation: TrackSituation) -> float:
        """How long the detector has reported this line's current state (s)."""
        key = (situation.stop_line, situation.light_state)
        if key != self._state_key:
            self._state_key, self._state_since = key, situation.time_s
        return situation.time_s - self._state_since

    def observe(self, situation: TrackSituation) -> NDArray[np.float32]:
        stopping = self.decision is not None and self.decision.stop_waypoint >= 0
        return self.features.encode(situation, self.state_time(situation), stopping)

    def decide(self, situation: TrackSituation) -> TrackBehaviorDecision:
        self.situation = situation
        if self.chooser is not None and situation.time_s >= self._next_choice - 1e-9:
            self.action = self.chooser(self.observe(situation))
            self._next_choice = situation.time_s + self.decision_period_s
        else:
            self.state_time(situation)
        self.decision = action_decision(self.action, situation, self.continuous)
        return self.decision
