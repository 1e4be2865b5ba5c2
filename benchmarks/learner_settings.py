"""What every case of ``bench_learners.py`` shares: the env, the project's PPO settings (with
the command line's overrides) and the no-op batch of the same spaces."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import train

ENV_ID = "sdc_gym/HighwayLoopBehavior-v0"
LARGE = {"n_envs": 1024, "n_steps": 8, "batch_size": 2048, "threads": 2, "processes": 2}
"""SB3 PPO at throughput settings (the ``*-large`` cases and ``sb3-large`` race; docs/speed.md):
1,024 envs split over two worker processes (``train.py --vectorize split``), 8 steps per env
per rollout (8,192 samples), minibatches of 2,048, torch on 2 threads in the update (1
while collecting: ``sdc_training.torch_threads``)."""
LARGE_SAMPLES = 65_536
"""Samples timed per ``*-large`` case at least (8 rollouts)."""


OVERRIDES: dict[str, Any] = {}
"""``--batch-size`` and ``--n-steps`` from the command line, over the project's values."""


def ppo_settings(n_envs: int) -> dict[str, Any]:
    """The project's PPO hyperparameters, ``n_steps`` rescaled so a rollout holds as many
    samples as the project's (n_envs x n_steps of the config)."""
    hyper = train.load_hyperparams("ppo", ENV_ID, "sb3")
    rollout = int(hyper.pop("n_envs")) * int(hyper["n_steps"])
    hyper.pop("timesteps", None)
    hyper["n_steps"] = max(1, rollout // n_envs)
    hyper.update(OVERRIDES)
    return hyper


class NoopVecEnv:
    """A stand-in batch with the env's spaces: zero observations, zero rewards, no ends."""

    def __init__(self, num_envs: int) -> None:
        from sdc_gym.envs.highway_vector import HighwayLoopBehaviorVectorEnv

        probe = HighwayLoopBehaviorVectorEnv(1)
        self.single_observation_space = probe.single_observation_space
        self.single_action_space = probe.single_action_space
        probe.close()
        self.num_envs = num_envs
        self._obs = np.zeros((num_envs, *self.single_observation_space.shape), np.float32)
        self._zeros = np.zeros(num_envs, np.float64)
        self._false = np.zeros(num_envs, bool)

    def reset(self, seed: Any = None) -> tuple[np.ndarray, dict]:
        return self._obs, {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        return self._obs, self._zeros, self._false, self._false, {}

    def close(self) -> None:
        pass


def tanh_mlp(inputs: int, width: list[int], outputs: int) -> Any:
    """SB3's default MLP shape for PPO's actor or critic: ``Linear`` + ``Tanh`` per hidden
    width, then a linear head (the same network in every learner's case)."""
    from torch import nn

    layers: list[nn.Module] = []
    size = inputs
    for hidden in width:
        layers += [nn.Linear(size, hidden), nn.Tanh()]
        size = hidden
    return nn.Sequential(*layers, nn.Linear(size, outputs))
