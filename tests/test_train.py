"""train.py: real short runs write their run folder, resume after an interruption, take
hyperparameters from YAML by env id with command-line overrides, and log driving metrics."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import train

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
SHORT = {"highway": {"max_duration": 20.0}}


def write_config(tmp_path: Path, **extra) -> Path:
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoopBehavior-v0", "config": SHORT,
                                    "eval": {"every": 0}, **extra}))
    return path


def test_ppo_run_folder_and_resume_after_an_interruption(tmp_path, capsys):
    from stable_baselines3 import PPO

    output = tmp_path / "run"
    args = ["--config", str(write_config(tmp_path)), "--output", str(output), "--n-envs", "2",
            "--timesteps", "512", "--checkpoint-every", "256", "--hp", "n_steps=128",
            "--hp", "batch_size=64", "--hp", "policy_kwargs.net_arch=[16]",
            "--eval-every", "256", "--no-progress"]
    model = train.main(args)
    config = yaml.safe_load((output / "config.yaml").read_text())
    assert config["algo"] == "ppo" and config["seed"] == 0 and config["n_envs"] == 2
    # ppo.yaml's entry for the env, with the overrides applied (parsed as YAML, not eval).
    assert config["hyperparams"]["n_steps"] == 128 and config["hyperparams"]["gamma"] == 0.99
    assert config["hyperparams"]["policy_kwargs"] == {"net_arch": [16]}
    loaded = PPO.load(model)
    assert loaded.num_timesteps == 512 and loaded.n_steps == 128
    assert (output / "best_model.zip").is_file() and (output / "evaluations.npz").is_file()
    checkpoints = sorted((output / "checkpoints").glob("*.zip"))
    assert [p.name for p in checkpoints] == ["ppo_256_steps.zip", "ppo_512_steps.zip"]
    events = list((output / "tensorboard").rglob("events.out.tfevents.*"))
    assert events
    # Each evaluation prints SB3's verbose=1 lines and ours: return, mean mph, incidents,
    # the same returns as evaluations.npz holds.
    out = capsys.readouterr().out
    evaluations = np.load(output / "evaluations.npz")
    assert list(evaluations["timesteps"]) == [256, 512]
    lines = re.findall(r"^Eval num_timesteps=(\d+): (\d+) episode\(s\), return (\S+) \+/- "
                       r"\S+, mean speed (\S+) mph, incidents (\S+) per episode", out, re.M)
    assert [int(line[0]) for line in lines] == [256, 512]
    for line, returns in zip(lines, evaluations["results"], strict=True):
        assert int(line[1]) == len(returns)
        assert float(line[2]) == pytest.approx(np.mean(returns), abs=0.006)
        assert 0.0 <= float(line[3]) < 80.0 and float(line[4]) >= 0.0  # (an untrained
        # policy may keep the car standing: 0.00 mph)
    assert "Eval num_timesteps=256, episode_reward=" in out  # SB3's own line
    # Interrupted after the first checkpoint: only it survives.
    checkpoints[1].unlink()
    model.unlink()
    train.main(["--output", str(output), "--resume", "--no-progress"])
    assert PPO.load(model).num_timesteps == 512  # 256 restored + two 128 x 2 rollouts... capped
    assert len((output / "command.txt").read_text().splitlines()) == 2
    # The resumed run checkpoints at the run's interval (kept in config.yaml), not the
    # default 10,000 steps: the 512-step checkpoint is written again.
    assert config["checkpoint_every"] == 256
    assert (output / "checkpoints" / "ppo_512_steps.zip").is_file()
    with pytest.raises(SystemExit, match="already holds a run"):
        train.main(args)


@pytest.mark.parametrize("algo", ["dqn", "qrdqn"])
def test_value_based_runs_resume_with_their_replay_buffer(tmp_path, algo):
    """DQN and sb3-contrib's QR-DQN: checkpoints with the buffer, resume, and the model
    drives the path-level env as the agent ``<algo>:model.zip``."""
    import gymnasium as gym
    from stable_baselines3.common.save_util import load_from_pkl

    from sdc_agents.policy_agent import algorithm_class
    from sdc_agents.registry import make_agent

    output = tmp_path / algo
    train.main(["--config", str(write_config(tmp_path)), "--algo", algo, "--output",
                str(output), "--n-envs", "1", "--timesteps", "300", "--checkpoint-every",
                "150", "--hp", "learning_starts=50", "--hp", "buffer_size=1000",
                "--eval-every", "0", "--no-progress"])
    names = sorted(p.name for p in (output / "checkpoints").iterdir())
    assert names == [f"{algo}_150_steps.zip", f"{algo}_300_steps.zip",
                     f"{algo}_replay_buffer_150_steps.pkl", f"{algo}_replay_buffer_300_steps.pkl"]
    (output / "checkpoints" / f"{algo}_300_steps.zip").unlink()
    (output / "checkpoints" / f"{algo}_replay_buffer_300_steps.pkl").unlink()
    train.main(["--output", str(output), "--resume", "--no-progress"])
    model = algorithm_class(algo).load(output / "model.zip")
    assert type(model).__name__ == {"dqn": "DQN", "qrdqn": "QRDQN"}[algo]
    assert 300 <= model.num_timesteps < 310
    # The resumed run started from the 150-step buffer: its final buffer holds both parts.
    assert load_from_pkl(output / "replay_buffer").size() >= 300
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"steps_per_action": 12,
                                                     "max_duration": 5.0})
    agent = make_agent(f"{algo}:{output / 'model.zip'}", env)
    observation, _ = env.reset(seed=0)
    agent.reset()
    env.step(agent.act(observation))


def test_bad_overrides_and_configs_are_clear_errors(tmp_path):
    with pytest.raises(SystemExit, match="KEY=VALUE"):
        train.parse_override("learning_rate")
    assert train.parse_override("policy_kwargs.net_arch=[64, 64]") == (
        ["policy_kwargs", "net_arch"], [64, 64])
    # A value is data: "__import__('os')" stays a string, never code.
    assert train.parse_override("x=__import__('os')")[1] == "__import__('os')"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoopBehavior-v0", "algos": "ppo"}))
    with pytest.raises(SystemExit, match="unknown keys"):
        train.main(["--config", str(bad), "--output", str(tmp_path / "x")])
    with pytest.raises(SystemExit, match="no run to resume"):
        train.main(["--output", str(tmp_path / "nothing"), "--resume"])


def test_committed_training_config_resolves():
    args = train.parse_args(["--config", str(CONFIGS / "train_highway_behavior.yaml"),
                             "--output", "/nonexistent/run"])
    config = train.run_config(args)
    assert config["env"] == "sdc_gym/HighwayLoopBehavior-v0" and config["algo"] == "dqn"
    assert config["timesteps"] == 600_000 and config["hyperparams"]["buffer_size"] > 0
    # The committed policy's recorded config is this one.
    recorded = yaml.safe_load((CONFIGS.parent / "agents" / "highway" / "policies"
                               / "dqn_highway.yaml").read_text())
    assert recorded["config"] == config["config"]
    assert recorded["hyperparams"] == config["hyperparams"]


def test_sac_trains_the_continuous_variant(tmp_path):
    from stable_baselines3 import SAC

    output = tmp_path / "sac"
    config = tmp_path / "sac.yaml"
    config.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoopBehavior-v0", "algo": "sac",
                                      "config": {**SHORT, "action": "continuous"},
                                      "eval": {"every": 0}}))
    model = train.main(["--config", str(config), "--output", str(output), "--n-envs", "1",
                        "--timesteps", "200", "--hp", "learning_starts=100",
                        "--hp", "batch_size=32", "--no-progress"])
    sac = SAC.load(model)
    assert sac.num_timesteps == 200 and sac.action_space.shape == (2,)
    assert (output / "replay_buffer.pkl").is_file()


def test_every_offered_algorithm_has_hyperparameters_for_the_behavior_envs():
    import inspect

    for algo in train.ALGORITHMS:
        path = train.HYPERPARAMS_DIR / f"{algo}.yaml"
        assert path.is_file(), f"--algo {algo} is offered without {path}"
        accepted = set(inspect.signature(train.algorithm_class(algo)).parameters)
        for env_id in ("sdc_gym/HighwayLoopBehavior-v0", "sdc_gym/TrackLoopBehavior-v0"):
            params = train.load_hyperparams(algo, env_id)
            assert params, f"{path} has no entry for {env_id}"
            unknown = set(params) - accepted - {"n_envs", "timesteps"}
            assert not unknown, f"{path} [{env_id}]: not {algo.upper()} arguments: {unknown}"


def test_a2c_trains_with_its_hyperparameters(tmp_path):
    from stable_baselines3 import A2C

    model = train.main(["--config", str(write_config(tmp_path)), "--algo", "a2c",
                        "--output", str(tmp_path / "a2c"), "--n-envs", "1",
                        "--timesteps", "64", "--no-progress"])
    a2c = A2C.load(model)
    assert a2c.num_timesteps == 64 and a2c.n_steps == 32  # from a2c.yaml


def test_driving_metrics_log_distance_always_and_lap_time_only_with_laps():
    from types import SimpleNamespace

    logged: dict[str, list[float]] = {}
    callback = train.driving_callback()
    callback.model = SimpleNamespace(logger=SimpleNamespace(
        record_mean=lambda key, value: logged.setdefault(key, []).append(value)))
    short = {"incidents": {"collision": 1, "lane": 0}, "is_success": False, "lap_times": [],
             "distance": 4200.0, "mean_speed_mph": 39.1}
    lap = {**short, "incidents": {}, "lap_times": [330.5], "distance": 6950.0}
    callback.locals = {"infos": [{"summary": short}, {"summary": lap}, {}],
                       "dones": [True, True, False]}
    assert callback._on_step()
    assert logged["driving/distance_m"] == [4200.0, 6950.0]
    assert logged["driving/lap_time_s"] == [330.5]  # from the episode with a lap only
    assert logged["driving/collision_per_episode"] == [1]
    assert logged["driving/incidents_per_episode"] == [1, 0]


def test_the_track_behavior_env_trains_as_one_native_batch(tmp_path):
    """train.py's default --vectorize batch: the track's decisions of all n_envs envs in one
    SB3VecEnv (no subprocesses), env i seeded seed + i; PPO reads its rollouts."""
    from stable_baselines3 import PPO

    from sdc_gym.envs.sb3 import SB3VecEnv

    config = {"env": "sdc_gym/TrackLoopBehavior-v0", "config": {"track": {"max_duration": 20.0}},
              "seed": 3}
    vec = train.make_vec_env(config, 4, 3)
    assert isinstance(vec.venv, SB3VecEnv) and vec.num_envs == 4
    vec.close()
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({**config, "algo": "ppo", "eval": {"every": 0}}))
    model = PPO.load(train.main(["--config", str(path), "--output", str(tmp_path / "ppo"),
                                 "--n-envs", "4", "--timesteps", "64", "--hp", "n_steps=16",
                                 "--hp", "batch_size=32", "--no-progress"]))
    assert model.num_timesteps == 64 and model.n_envs == 4


def test_vectorize_split_trains_the_same_model_as_one_batch(tmp_path):
    """--vectorize split: the batch in two worker processes gives PPO the same samples, so
    the same seed trains the same weights, bit for bit."""
    from stable_baselines3 import PPO

    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoopBehavior-v0", "algo": "ppo",
                                    "seed": 4, "eval": {"every": 0},
                                    "config": {"highway": {"max_duration": 8.0}}}))
    weights = []
    for vectorize in ("batch", "split"):
        model = PPO.load(train.main(["--config", str(path), "--output", str(tmp_path / vectorize),
                                     "--n-envs", "5", "--timesteps", "160", "--hp", "n_steps=32",
                                     "--hp", "batch_size=40", "--vectorize", vectorize,
                                     "--no-progress"]))
        assert model.num_timesteps == 160
        weights.append(model.policy.state_dict())
    assert weights[0].keys() == weights[1].keys()
    for key, value in weights[0].items():
        assert value.equal(weights[1][key]), key


def test_torch_threads_by_phase_one_while_collecting_all_while_updating():
    """--torch-threads N > 1: torch runs 1 thread while the envs step and N in the update
    (train.py adds the callback); 0 is refused, not coerced."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList

    from sdc_gym.envs.sb3 import SB3VecEnv
    from sdc_training.torch_threads import phase_threads_callback

    seen: dict[str, set[int]] = {"collect": set(), "update": set()}

    class Probe(BaseCallback):
        def _on_step(self) -> bool:
            seen["collect"].add(torch.get_num_threads())
            return True

        def _on_rollout_end(self) -> None:  # after PhaseThreads' own (it comes first)
            seen["update"].add(torch.get_num_threads())

    before = torch.get_num_threads()
    try:
        vec = SB3VecEnv("sdc_gym/HighwayLoopBehavior-v0", 2, {"highway": {"max_duration": 8.0}})
        model = PPO("MlpPolicy", vec, n_steps=16, batch_size=32, n_epochs=1, seed=0,
                    device="cpu")
        model.learn(64, callback=CallbackList([phase_threads_callback(2), Probe()]))
        vec.close()
        assert seen == {"collect": {1}, "update": {2}}
        assert torch.get_num_threads() == 2  # left at the update's count
    finally:
        torch.set_num_threads(before)
    with pytest.raises(SystemExit):
        train.parse_args(["--torch-threads", "0"])


@pytest.mark.parametrize("flags", [["--vectorize", "split"], ["--torch-threads", "2"]])
def test_sb3_only_flags_are_refused_for_an_rllib_run_before_anything_is_written(tmp_path,
                                                                                flags):
    with pytest.raises(SystemExit, match="a --framework rllib run samples with RLlib's env "
                                         "runners and takes neither: drop them"):
        train.main(["--framework", "rllib", "--output", str(tmp_path / "run"), *flags])
    assert not (tmp_path / "run").exists()
