"""A stable-baselines3 ``VecEnv`` over a natively batched env: no subprocesses.

:class:`SB3VecEnv` hands SB3's algorithms (PPO, DQN, A2C, SAC) the batch of
:class:`~sdc_gym.envs.highway_vector.HighwayLoopBehaviorVectorEnv` (or of the path-level
:class:`~sdc_gym.envs.highway_vector.HighwayLoopVectorEnv`, or the track's
:class:`~sdc_gym.envs.track_vector.TrackLoopBehaviorVectorEnv` and
:class:`~sdc_gym.envs.track_vector.TrackLoopVectorEnv`) with SB3's conventions: an
ended episode is reset within the step (Gymnasium's ``SAME_STEP`` autoreset), its last
observation in ``infos[i]["terminal_observation"]``, ``infos[i]["TimeLimit.truncated"]``
for truncations, ``dones`` = terminated or truncated, and the single env's ``summary`` and
``is_success`` in the final ``info`` (for ``EvalCallback`` and the driving callback).
Seeds work as for SB3's own vec envs: ``seed(s)`` gives env ``i`` the seed ``s + i`` at the
next ``reset()``. Policy inference is batched by SB3 itself: one forward pass for every
env per step.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from sdc_gym.envs.highway_vector import (
    HighwayLoopBehaviorVectorEnv,
    HighwayLoopVectorEnv,
    env_info,
)
from sdc_gym.envs.split_vector import split_or_batch
from sdc_gym.envs.track_vector import TrackLoopBehaviorVectorEnv, TrackLoopVectorEnv

VECTOR_ENVS = {
    "sdc_gym/HighwayLoopBehavior-v0": HighwayLoopBehaviorVectorEnv,
    "sdc_gym/HighwayLoop-v0": HighwayLoopVectorEnv,
    "sdc_gym/TrackLoopBehavior-v0": TrackLoopBehaviorVectorEnv,
    "sdc_gym/TrackLoop-v0": TrackLoopVectorEnv,
}
"""The env ids with a native batch, and its class."""


class SB3VecEnv(VecEnv):
    """``num_envs`` envs of ``env_id`` as one SB3 ``VecEnv`` (see the module docstring).

    Args:
        env_id: one of :data:`VECTOR_ENVS`.
        num_envs: envs in the batch.
        config: the single env's config.
        processes: worker processes the batch is split over (1: this process;
            :mod:`sdc_gym.envs.split_vector`), bit for bit the same samples.
    """

    def __init__(self, env_id: str, num_envs: int, config: dict[str, Any] | None = None,
                 processes: int = 1) -> None:
        if env_id not in VECTOR_ENVS:
            raise ValueError(f"{env_id!r} has no native batch; valid: {sorted(VECTOR_ENVS)}")
        self.vector = split_or_batch(env_id, VECTOR_ENVS[env_id], num_envs, processes,
                                     {"config": config,
                                      "autoreset_mode": AutoresetMode.SAME_STEP})
        self.env_id = env_id
        super().__init__(num_envs, self.vector.single_observation_space,
                         self.vector.single_action_space)
        self._actions: Any = None

    def reset(self) -> Any:
        seeds = self._seeds if any(seed is not None for seed in self._seeds) else None
        obs, _ = self.vector.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> Any:
        obs, reward, terminated, truncated, info = self.vector.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if dones.any():
            final_obs = info["final_obs"]
            final = info["final_info"]
            for env in np.flatnonzero(dones).tolist():
                entry = infos[env]
                entry["terminal_observation"] = final_obs[env]
                entry["TimeLimit.truncated"] = bool(truncated[env] and not terminated[env])
                entry.update(env_info(final, env))
        return obs, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        self.vector.close()

    # ------------------------------------------------------------------ attributes
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self.vector, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self.vector, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        method = getattr(self.vector, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper],
                       indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def _get_indices(self, indices: VecEnvIndices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return list(indices)
