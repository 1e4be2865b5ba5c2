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

The red-light shield (``red_light_shield``, off by default): the rule-based
:class:`~sdc_gym.stack.track.behavior.StopAtRedLights` runs beside the policy, and whenever
it stops (a red light it can stop for, a yellow one it can stop for comfortably, a stop it
has committed to) while the action goes, the rule's stop is executed at the action's
speed. The policy keeps the speed and may stop where the rule would not; it cannot run a
light the rule stops for, so it can never run a red the rule would not (the rule runs none
on the default track). What is left to learn is the approach: how fast to drive toward a
light (shielded RL, as the highway's safety shield).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.stack.track.behavior import (
    DEFAULT_COMFORTABLE_DECEL_MPS2,
    DEFAULT_SPEED_MARGIN_MPS,
    StopAtRedLights,
    StopAtRedParameters,
    TrackBehaviorDecision,
    TrackSituation,
)
from sdc_gym.stack.track.node_kernels import (
    DISTANCE_SCALE_M,
    MODE_NAMES,
    SPEED_FRACTIONS,
    STATE_TIME_SCALE_S,
    encode_features,
)
from sdc_gym.stack.track.node_kernels import action_decision as _action_decision
from sdc_gym.stack.track.node_kernels import state_time as _state_time
from sdc_gym.validation.actions import discrete_index, discrete_indices, real_array

TRACK_ACTION_NAMES = ("go", "go_75", "go_50", "stop")
LIGHT_ORDER = (RED, YELLOW, GREEN, UNKNOWN)
__all__ = ["DISTANCE_SCALE_M", "LIGHT_ORDER", "SPEED_FRACTIONS", "STATE_TIME_SCALE_S",
           "TRACK_ACTION_NAMES", "TrackDecisionBehavior", "TrackFeatures", "action_decision",
           "action_values", "batch_action_values"]


def action_values(action: Any, continuous: bool) -> tuple[int, float, float]:
    """A valid action as the kernels take it: (index, speed value, stop value); a
    ``ValueError`` for an invalid one."""
    if continuous:
        values = real_array(action, (2,), "a continuous track decision", "(speed, stop)")
        if not np.all(np.isfinite(values)) or np.any(np.abs(values) > 1.0 + 1e-6):
            raise ValueError(f"a continuous track decision is 2 finite numbers in [-1, 1] "
                             f"(speed, stop), got {np.asarray(action).tolist()!r}")
        return 0, float(values[0]), float(values[1])
    return discrete_index(action, len(TRACK_ACTION_NAMES), TRACK_ACTION_NAMES), 0.0, 0.0



def batch_action_values(actions: Any, envs: int, continuous: bool
                        ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """A batch's actions as the kernels take them, checked as a whole before any is used:
    ``(envs,)`` int indices (discrete) or ``(envs, 2)`` real numbers in [-1, 1]
    (continuous), as (index, speed value, stop value) arrays; a ``ValueError`` names the
    expected shape and dtype, or the first env whose action is out of range."""
    zeros = np.zeros(envs)
    if not continuous:
        return discrete_indices(actions, envs, TRACK_ACTION_NAMES), zeros, zeros
    values = real_array(actions, (envs, 2), "actions",
                        "one (speed, stop) decision in [-1, 1] per env")
    bad = np.flatnonzero(~(np.abs(values) <= 1.0 + 1e-6).all(axis=1))  # NaN is bad too
    if len(bad):
        env = int(bad[0])
        raise ValueError(f"the continuous track decision of env {env} must be 2 finite "
                         f"numbers in [-1, 1] (speed, stop), got {values[env].tolist()!r}")
    return np.zeros(envs, dtype=np.int64), values[:, 0].copy(), values[:, 1].copy()

def action_decision(action: Any, situation: TrackSituation, continuous: bool
                    ) -> TrackBehaviorDecision:
    """The behavior decision an action stands for in ``situation``
    (:func:`~sdc_gym.stack.track.node_kernels.action_decision`)."""
    index, speed_value, stop_value = action_values(action, continuous)
    speed, waypoint, mode = _action_decision(
        continuous, index, speed_value, stop_value, float(situation.speed_limit_mps),
        DEFAULT_SPEED_MARGIN_MPS, int(situation.stop_waypoint))
    return TrackBehaviorDecision(speed, waypoint, MODE_NAMES[mode])


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
        values = np.empty(self.size, dtype=np.float32)
        encode_features(float(self.max_decel), float(self.comfortable_decel),
                        float(situation.speed_mps), float(situation.speed_limit_mps),
                        int(situation.stop_line), float(situation.stop_line_distance_m),
                        float(situation.room_m), int(situation.light_state),
                        float(state_time_s), bool(stopping), values)
        return values


class TrackDecisionBehavior:
    """Executes the current action at every updater cycle (see the module docstring).

    Args:
        features: the observation encoder.
        continuous: actions are ``Box(2)`` vectors rather than indices.
        chooser: when given, called with the observation to pick a new action every
            ``decision_period_s`` (a trained policy on the path-level env); otherwise the
            owner sets :attr:`action`.
        red_light_shield: the rule's stops override the action's go (module docstring).
    """

    def __init__(self, features: TrackFeatures, *, continuous: bool = False,
                 chooser: Callable[[NDArray[np.float32]], Any] | None = None,
                 decision_period_s: float = 1.0, red_light_shield: bool = False) -> None:
        self.features = features
        self.continuous = continuous
        self.chooser = chooser
        self.decision_period_s = decision_period_s
        self.shield = StopAtRedLights(StopAtRedParameters(
            max_decel_mps2=features.max_decel,
            comfortable_decel_mps2=features.comfortable_decel)) if red_light_shield else None
        self.reset()

    def reset(self) -> None:
        if self.shield is not None:
            self.shield.reset()
        self.action: Any = np.array([1.0, -1.0], np.float32) if self.continuous else 0
        self.situation: TrackSituation | None = None
        self.decision: TrackBehaviorDecision | None = None
        self._state_key: tuple[int, int] = (-2, -2)
        self._state_since = 0.0
        self._next_choice = 0.0

    def state_time(self, situation: TrackSituation) -> float:
        """How long the detector has reported this line's current state (s)."""
        line, state, self._state_since, seconds = _state_time(
            self._state_key[0], self._state_key[1], self._state_since,
            int(situation.stop_line), int(situation.light_state), float(situation.time_s))
        self._state_key = (line, state)
        return seconds

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
        decision = action_decision(self.action, situation, self.continuous)
        if self.shield is not None:
            rule = self.shield.decide(situation)  # every cycle: it keeps its commitment
            if rule.stop_waypoint >= 0 and decision.stop_waypoint < 0:
                decision = TrackBehaviorDecision(decision.target_speed_mps,
                                                 rule.stop_waypoint, rule.mode)
        self.decision = decision
        return decision
