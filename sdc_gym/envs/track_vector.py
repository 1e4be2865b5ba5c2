"""Natively batched vector envs of the track loop: ``gymnasium.vector.VectorEnv`` shells over
one batch of arrays.

``gym.make_vec("sdc_gym/TrackLoopBehavior-v0", num_envs=E,
vectorization_mode="vector_entry_point")`` returns :class:`TrackLoopBehaviorVectorEnv`:
``E`` envs whose decisions (every env's drive-by-wire stack and physics frames) run in one
compiled call, not ``E`` env objects (and ``"sdc_gym/TrackLoop-v0"``
:class:`TrackLoopVectorEnv`, the drive-by-wire level). Env ``i`` is exactly the single
env with the same seed and actions (``reset(seed=s)`` seeds env ``i`` with ``s + i``, as
Gymnasium's ``SyncVectorEnv`` does; a list seeds each env).

Autoreset (``autoreset_mode``), seeding and ``info`` are those of the highway's vector
envs (:mod:`sdc_gym.envs.batch_vector`, the same base class): ``NEXT_STEP`` (Gymnasium
1.x's default) returns an ended episode's last observation and resets that env on the
following ``step()``, whose action for it is ignored (reward 0, not terminated);
``SAME_STEP`` resets it within the step (the last observation in ``info["final_obs"]``,
its info in ``info["final_info"]``: what SB3 expects); ``DISABLED`` leaves resetting to
the caller (``reset(options={"reset_mask": mask})``). ``info`` is slim by default (at an
episode's end ``summary``, ``is_success``, ``termination_reason``); ``full_info=True``
adds the single env's per-step info (and ``behavior``) every step.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from sdc_gym.envs.batch_vector import BatchVectorEnv
from sdc_gym.envs.split_vector import vector_entry_point
from sdc_gym.envs.track_behavior_world import TrackBehaviorWorld
from sdc_gym.envs.track_world import TrackWorld
from sdc_gym.validation.actions import real_array


class TrackLoopBehaviorVectorEnv(BatchVectorEnv):
    """``num_envs`` ``sdc_gym/TrackLoopBehavior-v0`` envs as one batch (see the module
    docstring). ``config`` is the single env's; actions are ``(num_envs,)`` ints
    (discrete) or ``(num_envs, 2)`` floats (continuous)."""

    def __init__(self, num_envs: int = 1, config: dict[str, Any] | None = None, *,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 full_info: bool = False, render_mode: str | None = None,
                 max_episode_steps: int | None = None) -> None:
        super().__init__(num_envs, autoreset_mode, full_info, render_mode, max_episode_steps,
                         "track.max_duration")
        self.batch = TrackBehaviorWorld(config, envs=num_envs)
        self._set_spaces(self.batch.action_space, self.batch.observation_space)

    def _reset_env(self, env: int, rng: np.random.Generator) -> None:
        self.batch.reset_at(env, rng)

    def _observations(self) -> NDArray[np.float32]:
        return self.batch.observations.copy()

    def _observation_of(self, env: int) -> NDArray[np.float32]:
        return self.batch.observations[env].copy()

    def _step_batch(self, actions: Any) -> tuple[NDArray, NDArray, NDArray, list[Any]]:
        active = ~self._needs_reset  # NEXT_STEP: an env reset by this step does not run
        self.batch.set_batch_actions(actions, active)  # the whole batch checked first
        reward, incidents = self.batch.step(active)
        state = self.batch.world.state
        return reward, state.terminated & active, state.truncated & active, incidents

    def _env_info(self, env: int, incidents: Any, final: bool, action: Any) -> dict[str, Any]:
        return _vector_info(self.batch.info(env, incidents, final=final))

    def _summary(self, env: int) -> dict[str, Any]:
        return self.batch.world.summary(env)

    def _done_reason(self, env: int) -> str:
        return self.batch.world.done_reason[env]

    def _is_success(self, env: int) -> bool:
        return self.batch.world.is_success(env)


class TrackLoopVectorEnv(BatchVectorEnv):
    """``num_envs`` ``sdc_gym/TrackLoop-v0`` envs as one batch (see the module docstring).
    Actions are ``(num_envs, 3)``: throttle, brake torque, steering-wheel angle per env;
    observations the single env's dict, each key stacked over the envs."""

    def __init__(self, num_envs: int = 1, config: dict[str, Any] | None = None, *,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 full_info: bool = False, render_mode: str | None = None,
                 max_episode_steps: int | None = None) -> None:
        super().__init__(num_envs, autoreset_mode, full_info, render_mode, max_episode_steps,
                         "max_duration")
        self.world = TrackWorld(config, envs=num_envs)
        self._set_spaces(self.world.setup.action_space, self.world.setup.observation_space)

    def _reset_env(self, env: int, rng: np.random.Generator) -> None:
        self.world.reset_at(env, rng)

    def _observations(self) -> dict[str, Any]:
        return self.world.observations()

    def _observation_of(self, env: int) -> dict[str, Any]:
        return self.world.observation(env)

    def _step_batch(self, actions: Any) -> tuple[NDArray, NDArray, NDArray, list[Any]]:
        world = self.world
        actions = real_array(actions, (self.num_envs, 3), "actions", "one [throttle, "
                             "brake_torque, steering_wheel_angle] per env")
        active = ~self._needs_reset  # NEXT_STEP: an env reset by this step does not run
        rows = np.flatnonzero(active).tolist()
        # Every env's action checked, an ended env's too (its action is ignored, but a NaN
        # batch is a caller's bug the other vector envs refuse as well).
        commands = [world.setup.read_action(actions[env]) for env in range(self.num_envs)]
        commands = [commands[env] for env in rows]
        for env, command in zip(rows, commands, strict=True):
            world.state.command[env] = command
        reward, incidents = world.step(active)
        state = world.state
        return reward, state.terminated & active, state.truncated & active, incidents

    def _env_info(self, env: int, incidents: Any, final: bool, action: Any) -> dict[str, Any]:
        return _vector_info(self.world.info(env, incidents, final=final))

    def _summary(self, env: int) -> dict[str, Any]:
        return self.world.summary(env)

    def _done_reason(self, env: int) -> str:
        return self.world.done_reason[env]

    def _is_success(self, env: int) -> bool:
        return self.world.is_success(env)


def _vector_info(info: dict[str, Any]) -> dict[str, Any]:
    """The single env's info as the vector API holds it: ``summary`` only at the end (its
    mask says which envs have one)."""
    if info["summary"] is None:
        del info["summary"]
    return info


make_track_behavior_vector_env = vector_entry_point(
    "sdc_gym/TrackLoopBehavior-v0", TrackLoopBehaviorVectorEnv)
make_track_vector_env = vector_entry_point(
    "sdc_gym/TrackLoop-v0", TrackLoopVectorEnv)
