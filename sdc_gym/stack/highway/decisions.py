"""Behavior decisions a policy can take on the highway, and their execution.

A learned behavior layer chooses, once per decision period, a **lane** move and a
**speed** move:

=========  ==============================================================================
lane       ``left`` / ``keep`` / ``right``: start a change to the adjacent lane (ignored
           while a change is under way: ``keep`` lets it finish), or stay on target
speed      ``cruise``: drive at the cruise speed (49.83 mph, the seed's top increment);
           ``hold``: keep the current speed; ``slow``: ``slow_step_mps`` below the current
           speed (to let a car pass before merging behind it)
=========  ==============================================================================

As a ``Discrete(9)`` action (for PPO and DQN) the index is ``3 x lane + speed`` with
lanes in the order above (left 0, keep 1, right 2) and speeds cruise 0, hold 1, slow 2;
:data:`ACTION_NAMES` lists them. As a continuous ``Box(-1, 1, (2,))`` action (SAC, TD3)
the first component picks the lane move (below -1/3 left, above 1/3 right) and the second
the target speed, linearly from 0 (at -1) to the cruise speed (at 1).

:class:`DecisionExecutor` turns a :class:`HighwayDecision` into the
:class:`~sdc_gym.stack.highway.behavior.BehaviorDecision` the motion layer executes; it
owns the lane-change state (target lane, change under way, time of the last change), and
with a :class:`~sdc_gym.stack.highway.shield.SafetyShield` it caps the speed behind the
lead, refuses unsafe lane changes and aborts changes that become unsafe. The
behavior-level env and the agent that runs a trained policy on the path-level env share
it, so a policy meets the same execution in training and evaluation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from sdc_gym.stack.highway.behavior import NORMAL_ACCELERATION, BehaviorDecision
from sdc_gym.stack.highway.shield import SafetyShield
from sdc_gym.stack.highway.world_model import WorldModel
from sdc_gym.validation.actions import discrete_index, real_array

LANE_MOVES = ("left", "keep", "right")
SPEED_MOVES = ("cruise", "hold", "slow")
ACTION_NAMES = tuple(f"{lane}/{speed}" for lane in LANE_MOVES for speed in SPEED_MOVES)
CRUISE_SPEED_MPS = 0.4455 / 0.02
"""22.275 m/s (49.83 mph): the seed's largest distance increment per 0.02 s, under the
50 mph limit."""
LANE_CHANGE_DONE_M = 0.5
"""A lane change is complete within this of the target lane's centre (the seed's)."""


@dataclass(frozen=True)
class HighwayDecision:
    """One behavior decision: ``lane_move`` -1 (left), 0, +1 (right); ``speed_move`` one of
    :data:`SPEED_MOVES`, or ``target_speed`` (m/s) for a continuous policy."""

    lane_move: int
    speed_move: str = "cruise"
    target_speed: float | None = None

    @classmethod
    def from_index(cls, index: int) -> HighwayDecision:
        """Decode a ``Discrete(9)`` action (see the module docstring)."""
        index = discrete_index(index, len(ACTION_NAMES), ACTION_NAMES)
        lane, speed = divmod(index, len(SPEED_MOVES))
        return cls(lane - 1, SPEED_MOVES[speed])

    @classmethod
    def from_vector(cls, vector: ArrayLike, cruise_speed: float = CRUISE_SPEED_MPS
                    ) -> HighwayDecision:
        """Decode a continuous ``Box(-1, 1, (2,))`` action (see the module docstring)."""
        values = real_array(vector, (2,), "a continuous highway decision", "(lane, speed)")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"a continuous highway decision is 2 finite numbers in [-1, 1] "
                             f"(lane, speed), got {np.asarray(vector).tolist()!r}")
        if np.any(np.abs(values) > 1.0 + 1e-6):
            raise ValueError(f"continuous decision {values.tolist()} outside [-1, 1]")
        lane_value, speed_value = (float(v) for v in values)
        lane = -1 if lane_value < -1.0 / 3.0 else (1 if lane_value > 1.0 / 3.0 else 0)
        return cls(lane, "target", 0.5 * (min(max(speed_value, -1.0), 1.0) + 1.0) * cruise_speed)


class DecisionExecutor:
    """Executes decisions: lane-change state, the speed move, and the shield (optional).

    Args:
        shield: the safety shield, or ``None`` to execute decisions as they come (a lane
            move into a car is carried out; the speed is not capped behind a lead).
        slow_step_mps: how far below the current speed ``slow`` aims.
        cruise_speed_mps: the ``cruise`` target (and the top of the continuous range).

    Counters (per episode): ``lane_changes`` started, ``refused`` lane moves the shield
    turned down, ``aborted`` changes it sent back.
    """

    def __init__(self, shield: SafetyShield | None = None, *, slow_step_mps: float = 2.0,
                 cruise_speed_mps: float = CRUISE_SPEED_MPS) -> None:
        if not slow_step_mps > 0.0 or not cruise_speed_mps > 0.0:
            raise ValueError("slow_step_mps and cruise_speed_mps must be > 0")
        self.shield = shield
        self.slow_step_mps = slow_step_mps
        self.cruise_speed_mps = cruise_speed_mps
        self.reset()

    def reset(self) -> None:
        self.target_lane = -1  # set from the first world model
        self.origin_lane = -1
        self.changing = False
        self.last_change_time = 0.0
        self.lane_changes = 0
        self.refused = 0
        self.aborted = 0

    def time_since_lane_change(self, now: float) -> float:
        return now - self.last_change_time

    def allowed_moves(self, world: WorldModel) -> tuple[bool, bool]:
        """Whether a ``left`` and a ``right`` move would start a change now."""
        if self.changing:
            return False, False
        ego = world.ego_lane
        if self.shield is None:
            return ego > 0, ego < world.lane_count - 1
        return (self.shield.lane_change_allowed(world, ego - 1),
                self.shield.lane_change_allowed(world, ego + 1))

    def _update_lane_state(self, world: WorldModel) -> None:
        if self.target_lane < 0:
            self.target_lane = world.ego_lane
        if self.changing and abs(world.ego_d - world.lane_center(self.target_lane)) \
                <= LANE_CHANGE_DONE_M:
            self.changing = False
        if (self.changing and self.shield is not None
                and self.shield.must_abort(world, self.origin_lane, self.target_lane)):
            self.target_lane, self.origin_lane = self.origin_lane, self.target_lane
            self.aborted += 1

    def execute(self, world: WorldModel, decision: HighwayDecision) -> BehaviorDecision:
        """The motion layer's instruction for ``decision`` in ``world``."""
        self._update_lane_state(world)
        v = world.ego_speed
        if decision.speed_move == "cruise":
            goal = self.cruise_speed_mps
        elif decision.speed_move == "hold":
            goal = v
        elif decision.speed_move == "slow":
            goal = max(v - self.slow_step_mps, 0.0)
        elif decision.speed_move == "target" and decision.target_speed is not None:
            goal = decision.target_speed
        else:
            raise ValueError(f"unknown speed move {decision.speed_move!r}; valid: "
                             f"{[*SPEED_MOVES, 'target']}")
        goal = min(goal, self.cruise_speed_mps)
        accel, replan = NORMAL_ACCELERATION, False
        limit = self.shield.speed_limit(world, self.target_lane) if self.shield else None
        if limit is not None and limit.speed < goal:
            goal, accel, replan = limit.speed, limit.acceleration, limit.hard

        if decision.lane_move not in (-1, 0, 1):
            raise ValueError(f"lane_move must be -1, 0 or 1, got {decision.lane_move!r}")
        if decision.lane_move and not self.changing:
            new = world.ego_lane + decision.lane_move
            ok = 0 <= new < world.lane_count
            if ok and self.shield is not None:
                ok = not replan and self.shield.lane_change_allowed(world, new)
            if ok:
                self.origin_lane, self.target_lane = self.target_lane, new
                self.changing = True
                self.last_change_time = world.time
                self.lane_changes += 1
            else:
                self.refused += 1
        return BehaviorDecision(target_lane=self.target_lane, target_speed=max(goal, 0.0),
                                acceleration=accel, replan=replan,
                                mode="changing" if self.changing else "lane")

