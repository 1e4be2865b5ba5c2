"""train.py: a short real PPO run writes its run folder and resumes from a checkpoint."""

from __future__ import annotations

from pathlib import Path

import yaml

import train

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def test_train_writes_the_run_folder_and_resumes_after_an_interruption(tmp_path):
    from stable_baselines3 import PPO

    output = tmp_path / "run"
    model = train.main(["--config", str(CONFIGS / "highway_oval.yaml"), "--output",
                        str(output), "--checkpoint-every", "1024", "--timesteps", "2048"])
    config = yaml.safe_load((output / "config.yaml").read_text())
    assert config["env"] == "sdc_gym/HighwayLoop-v0" and config["config"]["map"] == "oval"
    assert PPO.load(model).num_timesteps == 2048  # one PPO rollout of 2048 steps
    checkpoints = sorted((output / "checkpoints").glob("*.zip"))
    assert [p.name for p in checkpoints] == ["ppo_1024_steps.zip", "ppo_2048_steps.zip"]
    # Interrupted after the first checkpoint: only it survives.
    checkpoints[1].unlink()
    model.unlink()
    train.main(["--output", str(output), "--resume"])
    resumed = PPO.load(model)
    assert resumed.num_timesteps > 2048  # 1024 restored + one more 2048-step rollout
    assert len((output / "command.txt").read_text().splitlines()) == 2
