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

from sdc_gym.stack.highway import behavior_kernel as kernel
from sdc_gym.stack.highway.behavior import MAX_BRAKING, NORMAL_ACCELERATION, BehaviorDecision
from sdc_gym.stack.highway.shield import SafetyShield, ShieldParameters, shield_array, views_of
from sdc_gym.stack.highway.world_model import WorldModel
from sdc_gym.validation.actions import discrete_index, real_array

LANE_MOVES = ("left", "keep", "right")
SPEED_MOVES = ("cruise", "hold", "slow")
ACTION_NAMES = tuple(f"{lane}/{speed}" for lane in LANE_MOVES for speed in SPEED_MOVES)
CRUISE_SPEED_MPS = 0.4455 / 0.02
"""22.275 m/s (49.83 mph): the seed's largest distance increment per 0.02 s, under the
50 mph limit."""
LANE_CHANGE_DONE_M = kernel.LANE_CHANGE_DONE_M
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
    turned down, ``aborted`` changes it sent back. The rules are compiled
    (:func:`~sdc_gym.stack.highway.behavior_kernel.execute`); the executors of a batch
    of envs share their state arrays (:class:`ExecutorBatch`), of which this one is a
    row (``view``) or the only row.
    """

    def __init__(self, shield: SafetyShield | None = None, *, slow_step_mps: float = 2.0,
                 cruise_speed_mps: float = CRUISE_SPEED_MPS) -> None:
        self._attach(ExecutorBatch(shield, 1, slow_step_mps=slow_step_mps,
                                   cruise_speed_mps=cruise_speed_mps), 0)

    @classmethod
    def view(cls, batch: ExecutorBatch, env: int) -> DecisionExecutor:
        """Env ``env``'s executor of ``batch``."""
        made = object.__new__(cls)
        made._attach(batch, env)
        return made

    def _attach(self, batch: ExecutorBatch, env: int) -> None:
        self.batch = batch
        self.env = env
        self.shield = batch.shield
        self.slow_step_mps = batch.slow_step_mps
        self.cruise_speed_mps = batch.cruise_speed_mps

    def reset(self) -> None:
        self.batch.reset_at(self.env)

    target_lane = property(lambda self: int(self.batch.ints[self.env, kernel.TARGET]))
    origin_lane = property(lambda self: int(self.batch.ints[self.env, kernel.ORIGIN]))
    changing = property(lambda self: bool(self.batch.ints[self.env, kernel.CHANGING]))
    lane_changes = property(lambda self: int(self.batch.ints[self.env, kernel.LANE_CHANGES]))
    refused = property(lambda self: int(self.batch.ints[self.env, kernel.REFUSED]))
    aborted = property(lambda self: int(self.batch.ints[self.env, kernel.ABORTED]))
    last_change_time = property(lambda self: float(self.batch.last_change[self.env]))

    def time_since_lane_change(self, now: float) -> float:
        return now - self.last_change_time

    def allowed_moves(self, world: WorldModel) -> tuple[bool, bool]:
        """Whether a ``left`` and a ``right`` move would start a change now."""
        return kernel.allowed_moves(self.shield is not None, self.batch.shield_array,
                                    views_of(world), world.ego_lane, world.ego_speed,
                                    world.road_radius, self.changing)

    def execute(self, world: WorldModel, decision: HighwayDecision) -> BehaviorDecision:
        """The motion layer's instruction for ``decision`` in ``world``."""
        lane_move, speed_move, target_speed = decision_codes(decision)
        lane, speed, acceleration, replan = kernel.execute(
            self.shield is not None, self.batch.shield_array, self.batch.constants,
            views_of(world), world.ego_lane, world.ego_d, world.ego_speed, world.lane_width,
            world.road_radius, world.time, lane_move, speed_move, target_speed,
            self.batch.ints, self.batch.last_change, self.env)
        return BehaviorDecision(target_lane=lane, target_speed=speed, acceleration=acceleration,
                                replan=replan, mode="changing" if self.changing else "lane")


class ExecutorBatch:
    """The decision executors of ``envs`` envs: their lane-change state and counters as
    arrays (``ints`` ``(envs, 6)``: target lane, origin lane, changing, lane changes,
    refused, aborted; ``last_change`` ``(envs,)`` s), the shield and constants shared."""

    def __init__(self, shield: SafetyShield | None, envs: int, *, slow_step_mps: float = 2.0,
                 cruise_speed_mps: float = CRUISE_SPEED_MPS) -> None:
        if not slow_step_mps > 0.0 or not cruise_speed_mps > 0.0:
            raise ValueError("slow_step_mps and cruise_speed_mps must be > 0")
        self.shield = shield
        self.slow_step_mps = float(slow_step_mps)
        self.cruise_speed_mps = float(cruise_speed_mps)
        self.shield_array = (shield.array if shield is not None
                             else shield_array(ShieldParameters()))
        self.constants = np.array([self.slow_step_mps, self.cruise_speed_mps,
                                   NORMAL_ACCELERATION, MAX_BRAKING])
        self.ints = np.zeros((envs, 6), dtype=np.int64)
        self.last_change = np.zeros(envs)
        for env in range(envs):
            self.reset_at(env)

    def reset_at(self, env: int) -> None:
        """Env ``env``'s executor afresh (the target lane is set from its first world)."""
        self.ints[env] = 0
        self.ints[env, kernel.TARGET] = self.ints[env, kernel.ORIGIN] = -1
        self.last_change[env] = 0.0


def decision_codes(decision: HighwayDecision) -> tuple[int, int, float]:
    """A decision as the kernel takes it: lane move, speed move code, target speed."""
    if decision.lane_move not in (-1, 0, 1):
        raise ValueError(f"lane_move must be -1, 0 or 1, got {decision.lane_move!r}")
    code = _SPEED_CODES.get(decision.speed_move)
    if code is None or (code == kernel.TARGET_SPEED and decision.target_speed is None):
        raise ValueError(f"unknown speed move {decision.speed_move!r}; valid: "
                         f"{[*SPEED_MOVES, 'target']}")
    target = decision.target_speed if code == kernel.TARGET_SPEED else 0.0
    return int(decision.lane_move), code, float(target)  # type: ignore[arg-type]


_SPEED_CODES = {"cruise": kernel.CRUISE, "hold": kernel.HOLD, "slow": kernel.SLOW,
                "target": kernel.TARGET_SPEED}
