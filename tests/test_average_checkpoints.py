"""benchmarks/average_checkpoints.py: the element-wise mean of checkpoints' policy weights."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import average_checkpoints


def small_dqn(fill: float, width: int = 4):
    from stable_baselines3 import DQN

    model = DQN("MlpPolicy", "CartPole-v1", policy_kwargs={"net_arch": [width]},
                learning_starts=0, buffer_size=100, seed=0)
    with torch.no_grad():
        for parameter in model.policy.parameters():
            parameter.fill_(fill)
    return model


def test_weights_are_averaged_and_the_averaged_model_is_saved(tmp_path):
    from stable_baselines3 import DQN

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.yaml").write_text("env: CartPole-v1\n")
    paths = []
    for index, fill in enumerate((1.0, 2.0, 6.0)):
        path = run / "checkpoints" / f"dqn_{index + 1}00_steps.zip"
        small_dqn(fill).save(path)
        paths.append(path)
    output = tmp_path / "elsewhere" / "averaged.zip"
    average_checkpoints.main([*map(str, paths), "--algo", "dqn", "--output", str(output)])
    averaged = DQN.load(output)
    for parameter in averaged.policy.q_net.parameters():
        assert torch.all(parameter == 3.0)  # (1 + 2 + 6) / 3
    # The online and target networks are both policy parameters: both averaged.
    assert all(torch.all(p == 3.0) for p in averaged.policy.q_net_target.parameters())
    assert (output.parent / "config.yaml").read_text() == "env: CartPole-v1\n"


def test_different_networks_and_bad_paths_are_clear_errors(tmp_path):
    with pytest.raises(ValueError, match="different networks"):
        average_checkpoints.average_models([small_dqn(1.0, 4), small_dqn(1.0, 8)])
    with pytest.raises(SystemExit):
        average_checkpoints.main([str(tmp_path / "none.zip"), "--algo", "dqn",
                                  "--output", str(tmp_path / "x.zip")])
