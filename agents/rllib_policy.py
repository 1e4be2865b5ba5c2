"""RLlib policies (new API stack: an ``RLModule``) with the interface of an SB3 model.

``evaluate.py --agents rllib:runs/ppo/model`` drives the path-level envs with an RLlib
policy trained on a behavior-level env (``train.py --framework rllib``), exactly where an
SB3 policy sits (:mod:`sdc_agents.policy_agent`): the layered agent only calls
``predict(observation, deterministic=True)`` and reads ``observation_space``.

``PATH`` is an RLlib checkpoint folder: a whole algorithm's (``Algorithm.save_to_path``:
the run folder's ``model/``, ``best_model/``, ``checkpoints/<algo>_<steps>_steps/``) or
one RLModule's. The module is loaded on the CPU without starting Ray, and a decision is
one ``forward_inference`` (no exploration): the actions the module returns (DQN: the
arg-max of its Q-values), else its action distribution's deterministic action (PPO: the
arg-max for ``Discrete``; the mean for ``Box``), clipped to a ``Box`` as RLlib's
module-to-env connector clips.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

MODULE_FILES = ("module_state.pkl", "class_and_ctor_args.pkl")
"""What an RLModule checkpoint folder holds (``RLModule.save_to_path``)."""


def rl_module_folder(path: str | Path) -> Path:
    """The RLModule checkpoint inside ``path`` (an algorithm checkpoint: the learner's
    module of the default policy) or ``path`` itself; ``ValueError`` for anything else."""
    from ray.rllib.core import (
        COMPONENT_LEARNER,
        COMPONENT_LEARNER_GROUP,
        COMPONENT_RL_MODULE,
        DEFAULT_MODULE_ID,
    )

    folder = Path(path)
    if not folder.is_dir():
        raise ValueError(f"rllib: no checkpoint folder at {folder}")
    candidates = (folder, folder / COMPONENT_LEARNER_GROUP / COMPONENT_LEARNER
                  / COMPONENT_RL_MODULE / DEFAULT_MODULE_ID)
    for candidate in candidates:
        if all((candidate / name).is_file() for name in MODULE_FILES):
            return candidate
    raise ValueError(f"rllib: {folder} is neither an RLlib algorithm checkpoint (with "
                     f"{candidates[1].relative_to(folder)}/) nor an RLModule checkpoint "
                     f"(with {' and '.join(MODULE_FILES)})")


class RLlibPolicy:
    """An RLModule behind SB3's ``predict``: one observation (or a batch) in, actions out.

    Deterministic only: an evaluation policy (stochastic sampling is RLlib's env runners'
    job during training).
    """

    def __init__(self, module: Any) -> None:
        import torch

        self.module = module
        self.observation_space: gym.Space = module.observation_space
        self.action_space: gym.Space = module.action_space
        self._torch = torch
        module.eval()

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """The deterministic action for ``observation`` (shape of the observation space,
        or a batch of them); ``state`` and ``episode_start`` are SB3's, unused (no
        recurrent modules)."""
        if not deterministic:
            raise ValueError("RLlibPolicy.predict is deterministic only")
        obs = np.asarray(observation, dtype=np.float32)
        single = obs.shape == self.observation_space.shape
        batch = obs[None] if single else obs
        with self._torch.no_grad():
            output = self.module.forward_inference({"obs": self._torch.from_numpy(batch)})
            if "actions" in output:  # the module chose (DQN)
                actions = output["actions"].numpy()
            else:
                distribution = self.module.get_inference_action_dist_cls()
                actions = distribution.from_logits(
                    output["action_dist_inputs"]).to_deterministic().sample().numpy()
        if isinstance(self.action_space, gym.spaces.Box):
            actions = np.clip(actions, self.action_space.low, self.action_space.high)
        return (actions[0] if single else actions), None


def load_rllib_policy(path: str | Path) -> RLlibPolicy:
    """The policy of the RLlib checkpoint at ``path`` (see the module doc), on the CPU."""
    from ray.rllib.core.rl_module.rl_module import RLModule

    # An absolute path: RLlib (pyarrow) takes a relative one for a URI without a scheme.
    return RLlibPolicy(RLModule.from_checkpoint(rl_module_folder(path).absolute()))
