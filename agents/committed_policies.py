"""The committed trained policies as named agents: ``--agents dqn_highway ppo_highway``.

Every ``<name>.zip`` under ``agents/highway/policies/`` and ``agents/track/policies/`` that
has its training config ``<name>.yaml`` beside it is the agent ``<name>``. The YAML (the run
folder's ``config.yaml``, which ``train.py`` writes, with a comment block on how it was
made) gives the algorithm (``algo``: the SB3 class that loads the zip) and the behavior env
it was trained on, and with it the path-level env the agent drives: a policy trained on
``HighwayLoopBehavior-v0`` drives ``HighwayLoop-v0`` through the layered agent, one trained
on ``TrackLoopBehavior-v0`` drives ``TrackLoop-v0`` inside the drive-by-wire stack
(:mod:`sdc_agents.policy_agent`). The spec ``dqn:agents/highway/policies/dqn_highway.zip``
still names the same model by its file.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

import gymnasium as gym

from sdc_agents.policy_agent import DRIVEN_ENV, SB3_KINDS, policy_agent
from sdc_gym.validation.yaml_files import read_yaml

POLICY_FOLDERS: Final = (Path(__file__).resolve().parent / "highway" / "policies",
                         Path(__file__).resolve().parent / "track" / "policies")
"""Where committed policies live (inside the package, so an installed wheel has them)."""



class CommittedPolicy:
    """One committed policy: its name, model file, algorithm and the env it drives."""

    def __init__(self, model: Path) -> None:
        config_file = model.with_suffix(".yaml")
        config = read_yaml(config_file, "committed policy's training config")
        if not isinstance(config, dict):
            raise ValueError(f"{config_file}: a committed policy's config must be a mapping "
                             "with 'algo' and 'env'")
        algo, trained_on = config.get("algo"), config.get("env")
        if algo not in SB3_KINDS:
            raise ValueError(f"{config_file}: algo {algo!r}; valid: {list(SB3_KINDS)}")
        if trained_on not in DRIVEN_ENV:
            raise ValueError(f"{config_file}: env {trained_on!r}; valid: {sorted(DRIVEN_ENV)}")
        self.name = model.stem
        self.model = model
        self.algo: str = algo
        self.env_id: str = DRIVEN_ENV[trained_on]

    def agent(self, env: gym.Env) -> Any:
        return policy_agent(env, self.algo, self.model, name=self.name)


def committed_policies() -> dict[str, CommittedPolicy]:
    """Every committed policy by name (a zip without its YAML beside it is not one)."""
    found: dict[str, CommittedPolicy] = {}
    for folder in POLICY_FOLDERS:
        for model in sorted(folder.glob("*.zip")):
            if model.with_suffix(".yaml").is_file():
                found[model.stem] = CommittedPolicy(model)
    return found


def committed_policy_agents() -> tuple[dict[str, Callable[[gym.Env], Any]], dict[str, str]]:
    """``(factories, envs)``: the agent factory and the driven env id of each policy."""
    policies = committed_policies()
    return ({name: policy.agent for name, policy in policies.items()},
            {name: policy.env_id for name, policy in policies.items()})
