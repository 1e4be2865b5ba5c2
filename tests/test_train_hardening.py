"""train.py hardened: the precedence CLI > run config > hyperparameter file > defaults,
every value checked before any env process starts, resume after a torn checkpoint and a
missing replay buffer, and checkpoints that survive a ``kill -9`` mid-run."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

import train
from sdc_agents import checkpoints as ckpt

ROOT = Path(__file__).resolve().parents[1]
SHORT = {"highway": {"max_duration": 20.0}}
BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"


def run_yaml(tmp_path: Path, **content) -> Path:
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({"env": BEHAVIOR, "config": SHORT, **content}))
    return path


def resolved(tmp_path: Path, *cli: str, **content) -> dict:
    args = train.parse_args(["--config", str(run_yaml(tmp_path, **content)),
                             "--output", str(tmp_path / "run"), *cli])
    return train.run_config(args)


def test_precedence_is_cli_then_run_config_then_hyperparameter_file_then_defaults(tmp_path):
    # dqn.yaml's entry for the env says n_envs 2, timesteps 600,000.
    assert resolved(tmp_path, algo="dqn")["timesteps"] == 600_000
    config = resolved(tmp_path, algo="dqn", timesteps=700, n_envs=1, checkpoint_every=70)
    assert (config["timesteps"], config["n_envs"], config["checkpoint_every"]) == (700, 1, 70)
    config = resolved(tmp_path, "--timesteps", "900", "--n-envs", "2", "--seed", "7",
                      algo="dqn", timesteps=700, n_envs=1, seed=3)
    assert (config["timesteps"], config["n_envs"], config["seed"]) == (900, 2, 7)
    # a2c.yaml has no entry for the path-level track env: the default.
    assert resolved(tmp_path, algo="a2c", env="sdc_gym/TrackLoop-v0", config={})[
        "timesteps"] == train.DEFAULT_TIMESTEPS
    # YAML 1.2 numbers: 1e-4 is a float, not the string "1e-4".
    assert resolved(tmp_path, "--hp", "learning_rate=1e-4")["hyperparams"][
        "learning_rate"] == pytest.approx(1e-4)


@pytest.mark.parametrize("content, cli, message", [
    ({"timesteps": -5}, [], "config key 'timesteps' must be an int in [1, "),
    ({"timesteps": 0}, [], "got 0"),
    ({"n_envs": 2.5}, [], "config key 'n_envs' must be an int"),
    ({"config": "dense"}, [], "config key 'config' must be a mapping"),
    ({"eval": "x"}, [], "config key 'eval' must be a mapping with keys of"),
    ({"eval": {"every": -1}}, [], "config key 'eval.every' must be an int in [0, "),
    ({"eval": {"often": 1}}, [], "'eval' must be a mapping with keys of"),
    ({"seed": "x"}, [], "config key 'seed' must be an int in [0, 4294967295], got 'x'"),
    ({"seed": -1}, [], "'seed' must be an int in [0, 4294967295], got -1"),
    ({"env": "sdc_gym/Nope-v0"}, [], "'env' must be a registered env id"),
    ({"algo": "ddpg"}, [],
     "config key 'algo' must be one of ['ppo', 'dqn', 'qrdqn', 'sac', 'a2c']"),
    ({}, ["--hp", "learning_rate=abc"],
     "hyperparameter 'learning_rate' of PPO must be float | Schedule, got 'abc' (str)"),
    ({}, ["--hp", "learning_rate=-0.1"], "'learning_rate' must be a finite number in (0, 1]"),
    ({}, ["--hp", "gamma=.nan"], "'gamma' must be a finite number in [0, 1], got nan"),
    ({}, ["--hp", "n_steps=[1]"], "hyperparameter 'n_steps' of PPO must be int"),
    ({}, ["--hp", "learnin_rate=0.1"], "unknown hyperparameter 'learnin_rate' for PPO"),
    ({}, ["--hp", "policy_kwargs=5"], "'policy_kwargs' of PPO must be dict"),
    # The env config is checked here, in the main process, before any env process.
    ({"config": {"highway": {"traffic": {"car_count": -1}}}}, ["--n-envs", "2"],
     "config key 'traffic.car_count' must be an int in [0, "),
    ({"config": {"decision_frames": 0}}, [], "'decision_frames' must be an int in [1, "),
])
def test_every_bad_run_value_is_a_clear_error_naming_the_key(tmp_path, content, cli, message):
    with pytest.raises(SystemExit) as raised:
        resolved(tmp_path, *cli, **content)
    assert message in str(raised.value)
    assert not (tmp_path / "run").exists()  # nothing started, nothing written


def train_short(tmp_path: Path, algo: str, *extra: str) -> Path:
    output = tmp_path / algo
    options = {"dqn": ["--hp", "learning_starts=50", "--hp", "buffer_size=1000"],
               "ppo": ["--hp", "n_steps=64", "--hp", "batch_size=32"]}[algo]
    train.main(["--config", str(run_yaml(tmp_path, eval={"every": 0})), "--algo", algo,
                "--output", str(output), "--n-envs", "1", "--timesteps", "256",
                "--checkpoint-every", "128", "--no-progress", *options, *extra])
    return output


def test_resume_after_a_torn_newest_checkpoint_uses_the_newest_intact_one(tmp_path, capsys):
    from stable_baselines3 import PPO

    output = train_short(tmp_path, "ppo")
    newest = output / "checkpoints" / "ppo_256_steps.zip"
    data = newest.read_bytes()
    newest.write_bytes(data[: len(data) // 2])  # a save cut short
    (output / "model.zip").unlink()
    capsys.readouterr()
    train.main(["--output", str(output), "--resume", "--no-progress"])
    out = capsys.readouterr().out
    assert "skipped ppo_256_steps.zip: not a whole SB3 model zip" in out
    assert "from " + str(output / "checkpoints" / "ppo_128_steps.zip") + " (128 steps)" in out
    assert PPO.load(output / "model.zip").num_timesteps == 256
    assert ckpt.model_problem(newest) is None  # rewritten whole by the resumed run


def test_a_missing_replay_buffer_is_refused_unless_asked_and_a_torn_one_falls_back(
        tmp_path, capsys):
    from stable_baselines3 import DQN

    output = train_short(tmp_path, "dqn")
    folder = output / "checkpoints"
    # A torn newest buffer: the older complete pair is used.
    buffer_256 = folder / "dqn_replay_buffer_256_steps.pkl"
    buffer_256.write_bytes(buffer_256.read_bytes()[:1000])
    point = ckpt.resume_point(folder, "dqn", off_policy=True)
    assert point.steps == 128 and point.replay_buffer == folder / "dqn_replay_buffer_128_steps.pkl"
    assert "dqn_256_steps.zip: its replay buffer dqn_replay_buffer_256_steps.pkl is torn" in \
        point.notes[0]
    # No buffer at all: refused, naming the flag.
    buffer_256.unlink()
    (folder / "dqn_replay_buffer_128_steps.pkl").unlink()
    (output / "model.zip").unlink()
    with pytest.raises(SystemExit, match="pass --resume-without-buffer to do that anyway"):
        train.main(["--output", str(output), "--resume", "--no-progress"])
    capsys.readouterr()
    train.main(["--output", str(output), "--resume", "--resume-without-buffer",
                "--no-progress"])
    out = capsys.readouterr().out
    assert "dqn_256_steps.zip: its replay buffer dqn_replay_buffer_256_steps.pkl is missing; " \
           "resuming with an empty replay buffer" in out
    assert DQN.load(output / "model.zip").num_timesteps == 256


def test_an_atomic_write_that_fails_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "model.zip"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), ckpt.atomic_file(target) as handle:
        handle.write(b"half of the new")
        raise RuntimeError("killed mid-save")
    assert target.read_bytes() == b"old" and sorted(tmp_path.iterdir()) == [target]


def test_kill_9_mid_training_loses_no_checkpoint_and_the_run_resumes(tmp_path):
    """A DQN run killed without warning while it trains (and checkpoints every 64 steps):
    every checkpoint and buffer on disk loads, no temporary file is taken for one, and
    ``--resume`` finishes the run from the newest."""
    from stable_baselines3 import DQN

    output = tmp_path / "run"
    command = [sys.executable, "train.py", "--config", str(run_yaml(tmp_path, eval={
        "every": 0})), "--algo", "dqn", "--output", str(output), "--n-envs", "1",
        "--timesteps", "100000", "--checkpoint-every", "64", "--hp", "learning_starts=32",
        "--hp", "buffer_size=5000", "--no-progress"]
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    try:
        folder = output / "checkpoints"
        deadline = time.monotonic() + 120.0
        while len(list(folder.glob("dqn_*_steps.zip"))) < 3:
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.05)
        time.sleep(0.3)  # somewhere in the middle of the next save or rollout
    finally:
        process.kill()
        process.wait()
    models = sorted(folder.glob("dqn_*_steps.zip"), key=ckpt.checkpoint_steps)
    for model in models:
        assert ckpt.model_problem(model) is None
        buffer = ckpt.buffer_path(folder, "dqn", ckpt.checkpoint_steps(model))
        assert ckpt.buffer_problem(buffer) is None  # written before its model
    newest = ckpt.checkpoint_steps(models[-1])
    config = yaml.safe_load((output / "config.yaml").read_text())
    config["timesteps"] = newest + 64
    (output / "config.yaml").write_text(yaml.safe_dump(config))
    train.main(["--output", str(output), "--resume", "--no-progress"])
    assert DQN.load(output / "model.zip").num_timesteps >= newest + 64
