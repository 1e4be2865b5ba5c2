"""Natively batched vector envs of the highway: ``gymnasium.vector.VectorEnv`` shells over
one batch of arrays.

``gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=E,
vectorization_mode="vector_entry_point")`` returns :class:`HighwayLoopBehaviorVectorEnv`
(and ``"sdc_gym/HighwayLoop-v0"`` :class:`HighwayLoopVectorEnv`): ``E`` envs stepped by
every numpy call at once, not ``E`` env objects. Env ``i`` is exactly the single env with
the same seed and actions (``reset(seed=s)`` seeds env ``i`` with ``s + i``, as
Gymnasium's ``SyncVectorEnv`` does; a list seeds each env).

Autoreset, seeding and ``info``: :mod:`sdc_gym.envs.batch_vector` (the base shared with
the track's batches).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from sdc_gym.envs.batch_vector import BatchVectorEnv, env_info
from sdc_gym.envs.highway_behavior import behavior_spaces
from sdc_gym.envs.highway_behavior_world import HighwayBehaviorWorld
from sdc_gym.envs.highway_loop import highway_spaces
from sdc_gym.envs.highway_world import HighwayWorld
from sdc_gym.envs.split_vector import vector_entry_point
from sdc_gym.scenarios.options import OPTION
from sdc_gym.stack.highway.decisions import ACTION_NAMES
from sdc_gym.validation.actions import discrete_indices, real_array

__all__ = ["HighwayLoopBehaviorVectorEnv", "HighwayLoopVectorEnv", "env_info",
           "make_behavior_vector_env", "make_highway_vector_env"]


class HighwayLoopBehaviorVectorEnv(BatchVectorEnv):
    """``num_envs`` ``sdc_gym/HighwayLoopBehavior-v0`` envs as one batch (see the module
    docstring). ``config`` is the single env's; actions are ``(num_envs,)`` ints
    (discrete) or ``(num_envs, 2)`` floats (continuous)."""

    reset_option_keys = (OPTION,)

    def __init__(self, num_envs: int = 1, config: dict[str, Any] | None = None, *,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 full_info: bool = False, render_mode: str | None = None,
                 max_episode_steps: int | None = None) -> None:
        super().__init__(num_envs, autoreset_mode, full_info, render_mode, max_episode_steps,
                         "highway.max_duration")
        self.batch = HighwayBehaviorWorld(config, envs=num_envs)
        self._set_spaces(*behavior_spaces(self.batch))

    def _reset_env(self, env: int, rng: np.random.Generator) -> None:
        self.batch.reset_at(env, rng, self._scenarios[env])

    def _observations(self) -> NDArray[np.float32]:
        return self.batch.observations.copy()

    def _observation_of(self, env: int) -> NDArray[np.float32]:
        return self.batch.observations[env].copy()

    def _step_batch(self, actions: Any) -> tuple[NDArray, NDArray, NDArray, list[Any]]:
        if self.batch.discrete:
            actions = discrete_indices(actions, self.num_envs, ACTION_NAMES)
        else:
            actions = real_array(actions, (self.num_envs, 2), "actions",
                                 "one (lane, speed) decision in [-1, 1] per env")
        reward, terminated, truncated, incidents = self.batch.step(actions)
        return reward, terminated.copy(), truncated.copy(), list(incidents)

    def _env_info(self, env: int, incidents: Any, final: bool, action: Any) -> dict[str, Any]:
        info = self.batch.info(env, incidents, final=final, action=action)
        if info.get("summary") is None:
            # Only at an episode's end, as the path-level batch's: a None for one env and
            # a dict for another under one key is more than the vector info's arrays hold
            # (Gymnasium's _add_info failed at the first end of an env after the first).
            info.pop("summary", None)
        return info

    def _summary(self, env: int) -> dict[str, Any]:
        return self.batch.world.summary(env)

    def _done_reason(self, env: int) -> str:
        return self.batch.world.done_reason[env]

    def _is_success(self, env: int) -> bool:
        return self.batch.world.is_success(env)


class HighwayLoopVectorEnv(BatchVectorEnv):
    """``num_envs`` ``sdc_gym/HighwayLoop-v0`` envs as one batch (see the module docstring).
    Actions are ``(num_envs, path_points, 2)`` paths: fewer points by repeating the last
    real one (trailing repeats are padding, as for the single env)."""

    reset_option_keys = (OPTION,)

    def __init__(self, num_envs: int = 1, config: dict[str, Any] | None = None, *,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 full_info: bool = False, render_mode: str | None = None,
                 max_episode_steps: int | None = None) -> None:
        super().__init__(num_envs, autoreset_mode, full_info, render_mode, max_episode_steps,
                         "max_duration")
        self.world = HighwayWorld(config, envs=num_envs)
        self._set_spaces(*highway_spaces(self.world))
        self._lengths = np.full(num_envs, self.world.path_points, dtype=np.int64)

    def _reset_env(self, env: int, rng: np.random.Generator) -> None:
        self.world.reset_at(env, rng, self._scenarios[env])

    def _observations(self) -> dict[str, NDArray]:
        return self.world.observations()

    def _observation_of(self, env: int) -> dict[str, Any]:
        return self.world.observation(env)

    def _step_batch(self, actions: Any) -> tuple[NDArray, NDArray, NDArray, list[Any]]:
        paths = real_array(actions, (self.num_envs, self.world.path_points, 2), "actions",
                           "one path of (x, y) map points per env (repeat the last point "
                           "to send fewer)")
        lengths = self.world.check_paths(paths, self._lengths)
        result = self.world.step(paths, lengths)
        return (result.reward, result.terminated.copy(), result.truncated.copy(),
                list(result.incidents))

    def _env_info(self, env: int, incidents: Any, final: bool, action: Any) -> dict[str, Any]:
        world = self.world
        info: dict[str, Any] = world.metrics.step_info(env)
        info["lane"] = world.lane(env)
        info["is_success"] = world.is_success(env)
        info["termination_reason"] = world.done_reason[env] if final else ""
        if final:
            info["summary"] = world.summary(env)
        return info

    def _summary(self, env: int) -> dict[str, Any]:
        return self.world.summary(env)

    def _done_reason(self, env: int) -> str:
        return self.world.done_reason[env]

    def _is_success(self, env: int) -> bool:
        return self.world.is_success(env)


make_behavior_vector_env = vector_entry_point(
    "sdc_gym/HighwayLoopBehavior-v0", HighwayLoopBehaviorVectorEnv)
make_highway_vector_env = vector_entry_point(
    "sdc_gym/HighwayLoop-v0", HighwayLoopVectorEnv)
