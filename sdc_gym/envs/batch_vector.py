"""The base of the natively batched vector envs (the highway's and the track's):
``gymnasium.vector.VectorEnv`` over one batch of arrays whose envs reset one at a time.

Env ``i`` is exactly the single env with the same seed and actions (``reset(seed=s)``
seeds env ``i`` with ``s + i``, as Gymnasium's ``SyncVectorEnv`` does; a list seeds each
env).

Autoreset (``autoreset_mode``): ``NEXT_STEP`` (Gymnasium 1.x's default) returns an ended
episode's last observation and resets that env on the following ``step()``, whose action
for it is ignored (reward 0, not terminated); ``SAME_STEP`` resets it within the step and
returns the new episode's first observation, the last one in ``info["final_obs"]`` and its
info in ``info["final_info"]``; ``DISABLED`` leaves resetting to the caller
(``reset(options={"reset_mask": mask})``).

``info`` follows the vector API: a dict of arrays, each key with a boolean mask ``_key``
naming the envs that have it. By default it is slim: at an episode's end ``summary``
(the single env's, a nested dict of arrays as the vector API lays dicts out;
:func:`env_info` gives back one env's plain dict), ``is_success`` and
``termination_reason``, and nothing in between. ``full_info=True`` adds the single
env's per-step values every step (``time``, ``distance``, ``speed``, the incident
counts, ...; for the behavior env also ``behavior``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from sdc_gym.config import excerpt
from sdc_gym.scenarios.options import (
    CONFIG,
    RESET_MASK,
    batch_scenarios,
    check_reset_options,
    reset_mask,
)
from sdc_gym.validation.bounds import check_env_count

_MODES = {mode.value: mode for mode in AutoresetMode}


def _autoreset_mode(value: AutoresetMode | str) -> AutoresetMode:
    if isinstance(value, AutoresetMode):
        return value
    if value not in _MODES:
        raise ValueError(f"autoreset_mode {value!r} is not one of {list(_MODES)}")
    return _MODES[value]


class BatchVectorEnv(VectorEnv):
    """Seeding, autoreset and info assembly over a batch whose envs reset one at a time."""

    reset_option_keys: tuple[str, ...] = ()
    """The ``reset(options=...)`` keys besides ``reset_mask`` (the highway's: ``scenario``)."""

    def __init__(self, num_envs: int, autoreset_mode: AutoresetMode | str,
                 full_info: bool, render_mode: str | None, max_episode_steps: int | None,
                 duration_key: str) -> None:
        num_envs = check_env_count(num_envs)
        if not isinstance(full_info, bool | np.bool_):
            raise ValueError(f"full_info must be True or False, got {excerpt(full_info)} "
                             f"({type(full_info).__name__})")
        if render_mode is not None:
            raise ValueError("the batched env does not render; render one env with gym.make")
        if max_episode_steps is not None:
            raise ValueError(f"set the episode length with config {duration_key}")
        self.num_envs = num_envs
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": []}
        self.render_mode = None
        self.full_info = bool(full_info)
        self._generators: list[np.random.Generator | None] = [None] * num_envs
        # Each env's scenario (the config's until reset options give one; kept through
        # autoresets): sdc_gym.scenarios.options.
        self._scenarios: list[Any] = [CONFIG] * num_envs
        self._needs_reset = np.zeros(num_envs, dtype=bool)
        self._ready = False

    def _set_spaces(self, action_space: gym.Space, observation_space: gym.Space) -> None:
        self.single_action_space = action_space
        self.single_observation_space = observation_space
        self.action_space = batch_space(action_space, self.num_envs)
        self.observation_space = batch_space(observation_space, self.num_envs)

    # ------------------------------------------------------------------ to implement
    def _reset_env(self, env: int, rng: np.random.Generator) -> None:
        """Reset env ``env`` (with its scenario, ``self._scenarios[env]``)."""
        raise NotImplementedError

    def _observations(self) -> Any:
        raise NotImplementedError

    def _observation_of(self, env: int) -> Any:
        raise NotImplementedError

    def _step_batch(self, actions: Any) -> tuple[NDArray, NDArray, NDArray, list[Any]]:
        raise NotImplementedError

    def _env_info(self, env: int, incidents: Any, final: bool, action: Any) -> dict[str, Any]:
        raise NotImplementedError

    def _summary(self, env: int) -> dict[str, Any]:
        raise NotImplementedError

    def _done_reason(self, env: int) -> str:
        raise NotImplementedError

    def _is_success(self, env: int) -> bool:
        raise NotImplementedError

    # ------------------------------------------------------------------ Gymnasium API
    def _seed_generators(self, seed: int | list[int | None] | None,
                         rows: list[int]) -> None:
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset(seed=...) takes an int or {self.num_envs} seeds, "
                                 f"got {len(seeds)}")
        for env in rows:
            if seeds[env] is not None or self._generators[env] is None:
                self._generators[env], _ = seeding.np_random(seeds[env])

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        check_reset_options(options, type(self).__name__,
                            (*self.reset_option_keys, RESET_MASK))
        mask = reset_mask(options, self.num_envs)
        if mask is not None:
            if not self._ready and not mask.all():
                raise RuntimeError("the first reset() must reset every env")
        rows = list(range(self.num_envs)) if mask is None else np.flatnonzero(mask).tolist()
        scenarios = batch_scenarios(options, self.num_envs)
        if scenarios is not None:
            for env in rows:
                self._scenarios[env] = scenarios[env]
        self._seed_generators(seed, rows)
        for env in rows:
            self._reset_env(env, self._generators[env])  # type: ignore[arg-type]
        self._needs_reset[rows] = False
        self._ready = True
        return self._observations(), {}

    def step(self, actions: Any) -> tuple[Any, NDArray[np.float64], NDArray[np.bool_],
                                          NDArray[np.bool_], dict[str, Any]]:
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        restart = np.flatnonzero(self._needs_reset) if (
            self.autoreset_mode == AutoresetMode.NEXT_STEP) else np.zeros(0, dtype=np.int64)
        if self.autoreset_mode == AutoresetMode.DISABLED and self._needs_reset.any():
            raise RuntimeError(f"envs {np.flatnonzero(self._needs_reset).tolist()} ended: reset "
                               "them (reset(options={'reset_mask': mask})) before step()")
        # NEXT_STEP: an env whose episode ended last step is reset now, its action ignored.
        # The batch still steps it; its generator is put back to where the episode left
        # it, so the reset draws exactly what a single env's reset would.
        saved = [self._generators[env].bit_generator.state  # type: ignore[union-attr]
                 for env in restart.tolist()]
        reward, terminated, truncated, incidents = self._step_batch(actions)
        for env, state in zip(restart.tolist(), saved, strict=True):
            self._generators[env].bit_generator.state = state  # type: ignore[union-attr]
        infos: dict[str, Any] = {}
        done = terminated | truncated
        for env in restart.tolist():
            self._reset_env(env, self._generators[env])  # type: ignore[arg-type]
            done[env] = terminated[env] = truncated[env] = False
            reward[env] = 0.0
            incidents[env] = ()
        if self.full_info:
            for env in range(self.num_envs):
                self._add(infos, env, self._env_info(env, incidents[env], bool(done[env]),
                                                     _index(actions, env)))
        else:
            for env in np.flatnonzero(done).tolist():
                self._add(infos, env, {"summary": self._summary(env),
                                       "is_success": self._is_success(env),
                                       "termination_reason": self._done_reason(env)})
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_info: dict[str, Any] = {}
            for env in np.flatnonzero(done).tolist():
                final_obs[env] = self._observation_of(env)
                final_info = self._add(final_info, env, env_info(infos, env))
                self._reset_env(env, self._generators[env])  # type: ignore[arg-type]
            infos = {"final_obs": final_obs, "_final_obs": done.copy(),
                     "final_info": final_info, "_final_info": done.copy()}
        else:
            self._needs_reset = done.copy()
        return self._observations(), reward, terminated, truncated, infos

    def _add(self, infos: dict[str, Any], env: int, info: dict[str, Any]) -> dict[str, Any]:
        return self._add_info(infos, info, env)

    def close_extras(self, **kwargs: Any) -> None:
        pass


def _index(actions: Any, env: int) -> Any:
    return actions[env]


def env_info(infos: dict[str, Any], env: int) -> dict[str, Any]:
    """Env ``env``'s entries of a vector ``info`` dict (those its masks mark), as the
    single env's ``info`` holds them (nested dicts, such as ``summary``, included)."""
    single = {}
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        mask = infos.get(f"_{key}")
        if isinstance(value, dict):
            single[key] = env_info(value, env)
        elif mask is not None and mask[env]:
            item = value[env]
            single[key] = item.item() if isinstance(item, np.generic) else item
    return single


