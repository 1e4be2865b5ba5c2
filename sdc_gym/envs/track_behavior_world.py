"""The track loop at the behavior level for a batch of envs: the world plus the stack.

:class:`TrackBehaviorWorld` is ``envs`` episodes of ``sdc_gym/TrackLoopBehavior-v0``: a
:class:`~sdc_gym.envs.track_world.TrackWorld` (the ``TrackLoop-v0`` world, its ``track``
config) and the drive-by-wire stack of every env
(:mod:`sdc_gym.stack.track.stack_batch`), run together by the kernel of
:mod:`sdc_gym.envs.track_behavior_kernel`: one call steps every env through its whole
decision (``decision_period_s``: one stack tick and one env step per tick). The single
env (:class:`~sdc_gym.envs.track_behavior.TrackLoopBehaviorEnv`) is the batch of one; the
vector env (:class:`~sdc_gym.envs.track_vector.TrackLoopBehaviorVectorEnv`) the batch.

A decision's reward is the sum of its env steps' rewards in step order (each step's: its
progress, plus the penalties of the incidents that began in it on frames the agent
drove), as the single env always summed them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.track_behavior_kernel import BAD_COMMAND, observe_envs, run_decisions
from sdc_gym.envs.track_world import TrackWorld
from sdc_gym.kernel_compiler import bind
from sdc_gym.stack.track.behavior import DEFAULT_SPEED_MARGIN_MPS
from sdc_gym.stack.track.dbw_stack import dbw_stack_for_env
from sdc_gym.stack.track.decisions import (
    TRACK_ACTION_NAMES,
    TrackDecisionBehavior,
    TrackFeatures,
    action_values,
    batch_action_values,
)
from sdc_gym.stack.track.detector import GroundTruthLightSource
from sdc_gym.stack.track.node_kernels import MODE_NAMES
from sdc_gym.stack.track.stack_batch import reset_stack, stack_constants, stack_state
from sdc_gym.validation.env_configs import check_track_behavior_config
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT

ACTION_TYPES = ("discrete", "continuous")
BEHAVIOR_DEFAULTS: dict[str, Any] = {
    "track": {},                  # TrackLoop-v0 config
    "decision_period_s": 1.0,     # s between decisions
    "action": "discrete",         # "discrete" (Discrete(4)) or "continuous" (Box(2))
    "red_light_shield": False,    # the rule's stops override a go (TrackDecisionBehavior)
}


class TrackBehaviorWorld:
    """``envs`` episodes of ``TrackLoopBehavior-v0``; see the module docstring.

    Args:
        config: the behavior env's config (:data:`BEHAVIOR_DEFAULTS` keys).
        envs: number of envs.
    """

    OWNER: ClassVar[str] = "TrackLoopBehavior-v0"

    def __init__(self, config: Mapping[str, Any] | None = None, *, envs: int = 1) -> None:
        owner = self.OWNER
        self.config = cfg = resolve_config(BEHAVIOR_DEFAULTS, config, owner=owner)
        require(isinstance(cfg["track"], dict), owner, "track",
                "a mapping of TrackLoop-v0 config keys", cfg["track"])
        require(cfg["action"] in ACTION_TYPES, owner, "action", f"one of {ACTION_TYPES}",
                cfg["action"])
        require(isinstance(cfg["red_light_shield"], bool), owner, "red_light_shield",
                "true or false", cfg["red_light_shield"])
        check_track_behavior_config(cfg, owner)  # the track's step first: it is used here
        step_s = PHYSICS_DT * cfg["track"].get("steps_per_action", 1)
        ticks = cfg["decision_period_s"] / step_s
        if not (cfg["decision_period_s"] > 0 and round(ticks) >= 1
                and abs(ticks - round(ticks)) < 1e-9):
            raise ConfigError(f"{owner}: decision_period_s must be a positive multiple of "
                              f"the track env's step ({step_s:g} s), got "
                              f"{cfg['decision_period_s']!r}")
        self.ticks_per_decision = round(ticks)
        # Progress worth about 1 per decision at the limit (the track env's is 1 per step),
        # incident penalties unscaled.
        track_config = {"reward_progress": 1.0 / self.ticks_per_decision, **cfg["track"],
                        "observe_light_states": True}
        self.world = world = TrackWorld(
            track_config, envs=envs,
            batch_names=(owner, "frames per decision (decision_period_s / 0.02 s)"),
            frames_per_step=self.ticks_per_decision * int(cfg["track"].get("steps_per_action", 1)))
        self.envs = envs
        self.setup = setup = world.setup
        self.continuous = cfg["action"] == "continuous"
        self.features = TrackFeatures(abs(setup.params.decel_limit))
        # The agent dbw_stack_for_env builds for the env: the batch runs its nodes.
        shield = cfg["red_light_shield"]
        behavior = TrackDecisionBehavior(self.features, continuous=self.continuous,
                                         red_light_shield=shield)
        self.agent = dbw_stack_for_env(setup, GroundTruthLightSource(),
                                       name="behavior_env_stack", behavior=behavior)
        self.stack_constants = stack_constants(
            self.agent, continuous=self.continuous, speed_margin=DEFAULT_SPEED_MARGIN_MPS,
            max_decel=self.features.max_decel,
            comfortable_decel=self.features.comfortable_decel, red_light_shield=shield)
        self.stack = stack_state(envs, self.agent.updater.count)
        self.observation_space = self.features.space
        self.action_space: spaces.Space[Any] = (
            spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32) if self.continuous
            else spaces.Discrete(len(TRACK_ACTION_NAMES)))
        self.observations = np.zeros((envs, self.features.size), dtype=np.float32)
        self._steps_left = np.zeros(envs, dtype=np.int64)
        self._bad = np.zeros(1, dtype=np.int64)
        self._chosen = np.zeros(envs, dtype=bool)  # the envs to observe
        self._observer: tuple[int, Any] = (-1, None)
        self._max_brake = float(setup.max_brake_torque)
        self._max_steer = float(setup.max_steering_angle)

    # ------------------------------------------------------------------ episodes
    def reset_at(self, env: int, rng: np.random.Generator) -> None:
        """Start env ``env``'s episode (see :meth:`TrackWorld.reset_at`)."""
        self.world.reset_at(env, rng)
        reset_stack(self.stack_constants, self.stack, env)
        self._chosen[:] = False
        self._chosen[env] = True
        self._observe()

    # ------------------------------------------------------------------ stepping
    def set_actions(self, actions: Any, rows: list[int] | NDArray[np.int64]) -> None:
        """The actions of envs ``rows`` (one per row) for their next decision, checked
        (a ``ValueError`` names an invalid one, before any is set)."""
        values = [action_values(action, self.continuous) for action in actions]
        stack = self.stack
        for env, (index, speed, stop) in zip(rows, values, strict=True):
            stack.action_index[env] = index
            stack.action_speed[env] = speed
            stack.action_stop[env] = stop

    def set_batch_actions(self, actions: Any, active: NDArray[np.bool_]) -> None:
        """Every env's action (``(envs,)`` ints or ``(envs, 2)`` floats, checked as a
        whole: :func:`~sdc_gym.stack.track.decisions.batch_action_values`) for the next
        decision of the ``active`` envs."""
        index, speed, stop = batch_action_values(actions, self.envs, self.continuous)
        stack = self.stack
        stack.action_index[active] = index[active]
        stack.action_speed[active] = speed[active]
        stack.action_stop[active] = stop[active]

    def step(self, active: NDArray[np.bool_]) -> tuple[NDArray[np.float64], list[Any]]:
        """One decision of the ``active`` envs (their actions set with
        :meth:`set_actions`): each env's reward (0 for the others) and the incidents of its
        last env step."""
        world = self.world
        steps = self.ticks_per_decision
        self._steps_left[:] = np.where(active, steps, 0)
        incidents = world.advance(steps, self._run)
        totals = np.zeros(self.envs)
        last: list[Any] = [()] * self.envs
        out = world.outputs
        # Each decision's reward: its steps' rewards summed in step order, from 0.0.
        rewards = np.zeros((self.envs, steps + 1))
        rewards[:, 1:] = out.reward[:, :steps] * (np.arange(steps) < out.steps[:, None])
        totals = np.add.accumulate(rewards, axis=1)[:, -1]
        for env, items in enumerate(incidents):
            done = int(out.steps[env])
            if items and done:
                total = 0.0
                for reward in world.rewards(env, items):
                    total += reward
                totals[env] = total
                last[env] = world.step_incidents(env, items, done - 1)
        self._chosen[:] = active
        self._observe()
        return totals, last

    def _run(self) -> bool:
        world = self.world
        status = world.kernel_call(run_decisions, self.stack_constants, self.stack,
                                   self._steps_left, self._max_brake, self._max_steer,
                                   self._bad)()
        if status == BAD_COMMAND:
            env = int(self._bad[0])
            # The env's own check of an action, which the stack's command failed.
            self.setup.raise_bad_action(world.state.command[env].tolist())
        return bool(status)

    def _observe(self) -> None:
        """The observations of the ``_chosen`` envs (a call bound to the arrays; see
        :meth:`TrackWorld.kernel_call`)."""
        generation, call = self._observer
        if call is None or generation != self.world.generation:
            call = bind(observe_envs, self.world.state, self.stack_constants, self.stack,
                        self._chosen, self.observations)
            self._observer = (self.world.generation, call)
        call()

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_observer"] = (-1, None)  # machine code: bound again after unpickling
        return state

    # ------------------------------------------------------------------ reading one env
    def decision_name(self, env: int) -> str:
        """The mode of env ``env``'s current behavior decision ("" before the first)."""
        if not self.stack.has_decision[env]:
            return ""
        return MODE_NAMES[int(self.stack.decision_mode[env])]

    def info(self, env: int, incidents: Any, *, final: bool) -> dict[str, Any]:
        """Env ``env``'s info after a decision: its last env step's, plus ``behavior``."""
        info = self.world.info(env, incidents, final=final)
        info["behavior"] = {"decision": self.decision_name(env)}
        return info
