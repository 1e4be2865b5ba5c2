"""train.py --framework rllib and --tune on a real local Ray cluster (2 CPUs, one for the
module): RLlib PPO with remote env runners, its run folder and resume, DQN on the track,
an RLlib policy driving the path-level env exactly as in its behavior env (through
evaluate.py and the agent registry), and a Ray Tune sweep with ASHA."""

from __future__ import annotations

import csv
import pickle
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import evaluate
import train

ray = pytest.importorskip("ray")

HIGHWAY = "sdc_gym/HighwayLoopBehavior-v0"
TRACK = "sdc_gym/TrackLoopBehavior-v0"
SHORT = {"highway": {"max_duration": 20.0}}
TINY_PPO = ["--hp", "train_batch_size_per_learner=256", "--hp", "minibatch_size=64",
            "--hp", "num_epochs=1", "--hp", "model.fcnet_hiddens=[16]"]
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of 2 CPUs for the module (train.py finds it running)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def run_config(tmp_path: Path, env: str = HIGHWAY, config: dict | None = None,
               **extra) -> Path:
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({"env": env, "config": SHORT if config is None else config,
                                    **extra}))
    return path


@pytest.fixture(scope="module")
def ppo_run(cluster, tmp_path_factory):
    """A tiny RLlib PPO run on the highway behavior env, two remote env runners."""
    tmp_path = tmp_path_factory.mktemp("ppo")
    output = tmp_path / "run"
    args = ["--framework", "rllib", "--config",
            str(run_config(tmp_path, eval={"every": 256, "episodes": 2, "seed": 10_000})),
            "--output", str(output), "--n-envs", "2", "--timesteps", "512",
            "--checkpoint-every", "256", *TINY_PPO, "--no-progress"]
    model = train.main(args)
    return output, model, args


def test_rllib_ppo_run_folder_and_resume_after_an_interruption(ppo_run):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    output, model, args = ppo_run
    assert model == output / "model"
    config = yaml.safe_load((output / "config.yaml").read_text())
    assert config["framework"] == "rllib" and config["algo"] == "ppo"
    assert config["n_envs"] == 2 and config["timesteps"] == 512
    # rllib_ppo.yaml's entry for the env, with the overrides applied (dotted into model).
    hyper = config["hyperparams"]
    assert hyper["gamma"] == 0.99 and hyper["train_batch_size_per_learner"] == 256
    assert hyper["model"] == {"fcnet_hiddens": [16], "fcnet_activation": "tanh",
                              "vf_share_layers": False}
    assert sorted(p.name for p in (output / "checkpoints").iterdir()) == [
        "ppo_256_steps", "ppo_512_steps"]
    evaluations = np.load(output / "evaluations.npz")
    assert list(evaluations["timesteps"]) == [256, 512]
    assert evaluations["results"].shape == (2, 2)
    assert (evaluations["ep_lengths"] == 84).all()  # 20 s of 0.24 s decisions
    assert (output / "best_model" / "rllib_checkpoint.json").is_file()
    [board] = (output / "tensorboard").iterdir()
    assert board.name == "rllib_ppo_1"
    events = EventAccumulator(str(board))
    events.Reload()
    tags = set(events.Tags()["scalars"])
    assert {"rollout/ep_rew_mean", "rollout/ep_len_mean", "time/fps", "eval/mean_reward",
            "driving/distance_m", "driving/collision_per_episode",
            "train/policy_loss"} <= tags
    assert [event.step for event in events.Scalars("eval/mean_reward")] == [256, 512]
    assert events.Scalars("eval/mean_reward")[-1].value == pytest.approx(
        evaluations["results"][-1].mean())

    # Interrupted after the first checkpoint: only it survives; resume to the same total.
    for name in ("checkpoints/ppo_512_steps", "model"):
        shutil.rmtree(output / name)
    train.main(["--output", str(output), "--resume", "--no-progress"])
    assert (output / "checkpoints" / "ppo_512_steps").is_dir() and (output / "model").is_dir()
    assert len((output / "command.txt").read_text().splitlines()) == 2
    assert list(np.load(output / "evaluations.npz")["timesteps"]) == [256, 512]
    assert sorted(p.name for p in (output / "tensorboard").iterdir()) == [
        "rllib_ppo_1", "rllib_ppo_2"]
    with pytest.raises(SystemExit, match="already holds a run"):
        train.main(args)


def greedy_behavior_episode(policy, config: dict, seed: int) -> dict:
    env = gym.make(HIGHWAY, config=config)
    observation, _ = env.reset(seed=seed)
    while True:
        action, _ = policy.predict(observation, deterministic=True)
        observation, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            return info["summary"]


def test_rllib_policy_drives_the_path_level_env_as_in_its_behavior_env(ppo_run, tmp_path):
    """``evaluate.py --agents rllib:RUN/model`` on HighwayLoop-v0 (12 frames per step)
    repeats the behavior env's episode of the same policy exactly."""
    from sdc_agents.rllib_policy import load_rllib_policy

    output, model, _ = ppo_run
    policy = load_rllib_policy(model)
    assert policy.observation_space.shape == (25,) and policy.action_space.n == 9
    observation = gym.make(HIGHWAY, config=SHORT).reset(seed=4)[0]
    action, _ = policy.predict(observation)
    batch, _ = policy.predict(np.stack([observation, observation]))
    assert int(action) == batch[0] == batch[1] and 0 <= int(action) < 9
    expected = greedy_behavior_episode(policy, SHORT, seed=4)

    config = tmp_path / "path.yaml"
    config.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoop-v0", "config": {
        "steps_per_action": 12, "max_duration": 20.0}}))
    result = evaluate.main(["--agents", f"rllib:{model}", "--seeds", "4", "--config",
                            str(config), "--workers", "1", "--no-plots", "--no-progress",
                            "--output", str(tmp_path / "eval")])
    [episode] = result["episodes"]
    assert episode["agent"] == f"rllib:{model}" and not result["failures"]
    assert episode["distance"] == expected["distance"] > 20.0
    assert episode["incidents"] == expected["incidents"]
    # A checkpoint in the run's checkpoints/ finds the run's config.yaml one folder up.
    from sdc_agents.policy_agent import training_config

    assert training_config(output / "checkpoints" / "ppo_256_steps")[1] == SHORT


def test_rllib_dqn_trains_on_the_track_behavior_env(cluster, tmp_path, capsys):
    from sdc_agents.registry import make_agent

    output = tmp_path / "dqn"
    config = {"track": {"max_duration": 30.0}}
    train.main(["--framework", "rllib", "--algo", "dqn", "--config",
                str(run_config(tmp_path, TRACK, config, eval={"every": 0})),
                "--output", str(output), "--n-envs", "1", "--timesteps", "150",
                "--checkpoint-every", "100",
                "--hp", "reporting.min_sample_timesteps_per_iteration=100",
                "--hp", "env_runners.rollout_fragment_length=100",
                "--hp", "num_steps_sampled_before_learning_starts=50",
                "--hp", "training_intensity=4", "--hp", "replay_buffer_config.capacity=1000",
                "--hp", "model.fcnet_hiddens=[16]", "--no-progress"])
    saved = yaml.safe_load((output / "config.yaml").read_text())
    assert saved["algo"] == "dqn" and saved["hyperparams"]["target_network_update_freq"]
    # Iterations of 100 env steps (reporting section): checkpoints at 100 and 200 (the end).
    assert sorted(p.name for p in (output / "checkpoints").iterdir()) == [
        "dqn_100_steps", "dqn_200_steps"]
    assert not (output / "evaluations.npz").exists()  # eval every 0: none

    def buffered(folder: Path) -> int:
        return pickle.loads((folder / "replay_buffer.pkl").read_bytes())["_num_timesteps"]

    assert buffered(output / "checkpoints" / "dqn_100_steps") == 100
    # Interrupted after the first checkpoint: the resumed run starts from its buffer, so
    # the final buffer holds both parts (a fresh buffer would hold 100).
    for name in ("checkpoints/dqn_200_steps", "model"):
        shutil.rmtree(output / name)
    # A torn newest checkpoint (no RLlib metadata) is skipped; a checkpoint whose replay
    # buffer is gone is refused (before any cluster work) unless --resume-without-buffer.
    torn = output / "checkpoints" / "dqn_300_steps"
    torn.mkdir()
    (torn / "algorithm_state.pkl").write_bytes(b"cut short")
    buffer = output / "checkpoints" / "dqn_100_steps" / "replay_buffer.pkl"
    buffer.rename(tmp_path / "aside.pkl")
    with pytest.raises(SystemExit, match=r"--resume: no checkpoint .* can be resumed with its "
                                         r"replay buffer .*skipped dqn_300_steps: not a whole "
                                         r"RLlib checkpoint .*--resume-without-buffer"):
        train.main(["--output", str(output), "--resume", "--no-progress"])
    (tmp_path / "aside.pkl").rename(buffer)
    model = train.main(["--output", str(output), "--resume", "--no-progress"])
    assert "--resume: skipped dqn_300_steps: not a whole RLlib checkpoint (no rllib_checkpoint" \
           ".json)" in capsys.readouterr().out
    assert buffered(model) == 200
    # The track policy sits in the drive-by-wire stack of TrackLoop-v0.
    env = gym.make("sdc_gym/TrackLoop-v0", config={"observe_light_states": True,
                                                   "max_duration": 5.0})
    agent = make_agent(f"rllib:{model}", env)
    observation, _ = env.reset(seed=0)
    agent.reset()
    for _ in range(250):
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        if terminated or truncated:
            break
    assert info["distance"] > 0.0


@pytest.mark.parametrize("algo, env_id, config, options", [
    ("ppo", TRACK, {"track": {"max_duration": 30.0}}, TINY_PPO),
    ("dqn", HIGHWAY, SHORT, ["--hp", "reporting.min_sample_timesteps_per_iteration=128",
                             "--hp", "num_steps_sampled_before_learning_starts=64",
                             "--hp", "training_intensity=4",
                             "--hp", "replay_buffer_config.capacity=1000",
                             "--hp", "model.fcnet_hiddens=[16]"]),
], ids=["ppo_track", "dqn_highway"])
def test_rllib_trains_the_other_pairs_of_algorithm_and_behavior_env(cluster, tmp_path, algo,
                                                                    env_id, config, options):
    """The other two pairs (PPO on the track, DQN on the highway) train from the committed
    hyperparameter entries and give a policy that acts in the env's action space."""
    from sdc_agents.rllib_policy import load_rllib_policy

    output = tmp_path / "run"
    model = train.main(["--framework", "rllib", "--algo", algo, "--config",
                        str(run_config(tmp_path, env_id, config, eval={"every": 0})),
                        "--output", str(output), "--n-envs", "1", "--timesteps", "256",
                        *options, "--no-progress"])
    saved = yaml.safe_load((output / "config.yaml").read_text())
    assert (saved["framework"], saved["algo"], saved["env"]) == ("rllib", algo, env_id)
    assert saved["hyperparams"]["gamma"] == 0.99  # rllib_<algo>.yaml's entry for the env
    [checkpoint] = (output / "checkpoints").iterdir()
    assert int(checkpoint.name.split("_")[1]) >= 256
    env = gym.make(env_id, config=config)
    policy = load_rllib_policy(model)
    observation, _ = env.reset(seed=3)
    action, _ = policy.predict(observation, deterministic=True)
    assert env.action_space.contains(np.int64(action))
    env.step(action)


def test_tune_sweep_keeps_a_table_of_trials_and_the_best_checkpoint(cluster, tmp_path):
    from sdc_agents.rllib_policy import load_rllib_policy

    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({
        "num_samples": 1, "timesteps": 256, "n_envs": 1,
        "scheduler": {"type": "asha", "grace_period": 128, "reduction_factor": 2},
        "search_space": {"lr": {"grid_search": [1.0e-4, 1.0e-3]},
                         "model.fcnet_hiddens": {"choice": [[8], [16]]}}}))
    output = tmp_path / "sweep"
    best = train.main(["--tune", str(sweep), "--config", str(run_config(tmp_path)),
                       "--output", str(output), "--hp", "train_batch_size_per_learner=128",
                       "--hp", "minibatch_size=64", "--hp", "num_epochs=1", "--no-progress"])
    assert best == output.resolve() / "best_model"
    with (output / "trials.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert sorted(float(row["lr"]) for row in rows) == [1.0e-4, 1.0e-3]
    assert all(row["model.fcnet_hiddens"] in ("[8]", "[16]") and not row["error"]
               for row in rows)
    # ASHA may stop the lagging trial at its 128-step rung; a trial that ran on has 256.
    assert max(int(row["env_steps"]) for row in rows) == 256
    assert all(row["stopped_early"] == str(int(row["env_steps"]) < 256) for row in rows)
    winner = max(rows, key=lambda row: float(row["best"]))
    resolved = yaml.safe_load((output / "best_model.yaml").read_text())
    assert resolved["hyperparams"]["lr"] == float(winner["lr"])
    assert str(resolved["hyperparams"]["model"]["fcnet_hiddens"]) == winner[
        "model.fcnet_hiddens"]
    policy = load_rllib_policy(best)  # the best checkpoint, an rllib: agent's model
    hidden = resolved["hyperparams"]["model"]["fcnet_hiddens"][0]
    weights = [p.shape for p in policy.module.parameters()]
    assert (hidden, 25) in weights
    config = yaml.safe_load((output / "config.yaml").read_text())
    assert config["tune"]["search_space"]["lr"] == {"grid_search": [1.0e-4, 1.0e-3]}


def test_bad_rllib_settings_are_clear_errors_before_any_cluster(tmp_path, capsys):
    config = str(run_config(tmp_path))
    with pytest.raises(SystemExit, match=r"'learning_rate' is not an argument of "
                                         r"PPOConfig.training\(\); valid: .*'lr'"):
        train.main(["--framework", "rllib", "--config", config, "--output",
                    str(tmp_path / "a"), "--hp", "learning_rate=1e-3", "--no-progress"])
    with pytest.raises(SystemExit, match=r"unknown model keys \['hidden'\]; valid: .*"
                                         r"fcnet_hiddens"):
        train.main(["--framework", "rllib", "--config", config, "--output",
                    str(tmp_path / "b"), "--hp", "model.hidden=[8]", "--no-progress"])
    # Values: RLlib's annotations, the common ranges, finiteness, RLlib's own validate();
    # the run config's precedence and checks as for SB3.
    for index, (options, message) in enumerate([
            (["--hp", "lr=abc"],
             r"hyperparameter 'lr' of rllib ppo must be Union\[float, .*got 'abc' \(str\)"),
            (["--hp", "gamma=1.5"],
             r"config key 'gamma' must be a finite number in \[0, 1\], got 1.5"),
            (["--hp", "entropy_coeff=.nan"], r"'entropy_coeff' must be a finite number"),
            (["--hp", "model.fcnet_hiddens=64"], r"'model.fcnet_hiddens' of rllib ppo must "
                                                 r"be List\[int\], got 64"),
            (["--hp", "env_runners.rollout_fragment_length=0"],
             r"'env_runners.rollout_fragment_length' must be an int in \[1, "),
            (["--hp", "minibatch_size=4096"], r"RLlib refuses the config: `minibatch_size` "
                                              r"\(4096\) must be <= "),
            (["--seed", "-1"], r"config key 'seed' must be an int in \[0, 4294967295\]"),
            (["--hp", "model.fcnet_hiddens=[8]", "--config", str(run_config(
                tmp_path, config={"highway": {"traffic": {"car_count": -1}}}))],
             r"config key 'traffic.car_count' must be an int in \[0, ")]):
        with pytest.raises(SystemExit, match=message):
            train.main(["--framework", "rllib", "--config", config, "--output",
                        str(tmp_path / f"v{index}"), *options, "--no-progress"])
        assert not (tmp_path / f"v{index}").exists()
    with pytest.raises(SystemExit, match=r"config key 'algo' must be one of \['ppo', 'dqn'\] "
                                         r"for framework rllib, got 'sac'"):
        train.main(["--framework", "rllib", "--algo", "sac", "--config", config,
                    "--output", str(tmp_path / "c")])
    with pytest.raises(SystemExit):
        train.main(["--framework", "sb3", "--tune", "tune/highway_ppo", "--output",
                    str(tmp_path)])
    assert "--tune sweeps with Ray Tune over RLlib runs" in capsys.readouterr().err
    bad = tmp_path / "bad_sweep.yaml"
    for content, message in [
            ({"search_space": {"lr": {"uniformly": [0, 1]}}},
             r"config key 'search_space.lr' must be one of \['uniform', "),
            ({"search_space": {"lr": {"choice": [1e-3]}}, "mode": "maximum"},
             r"config key 'mode' must be one of \['max', 'min'\], got 'maximum'"),
            ({"search_space": {"lr": {"choice": [1e-3]}}, "schedulers": {}},
             r"unknown keys \['schedulers'\]"),
            ({"search_space": {"lr": {"choice": [1e-3]}}, "scheduler": {"type": "pbt"}},
             r"config key 'scheduler.type' must be one of \['asha', 'none'\], got 'pbt'"),
            ({"search_space": {"lr": {"choice": [1e-3]}},
              "scheduler": {"type": "asha", "grace_period": 0}},
             r"config key 'scheduler.grace_period' must be None or an int in \[1, "),
            ({"search_space": {"lr": {"loguniform": [0.0, 1e-3]}}},
             r"config key 'search_space.lr' must be arguments Tune takes"),
            ({"search_space": {"lr": {"choice": [1e-3, 5.0]}}},
             r"search_space.lr\).*config key 'lr' must be a finite number in \(0, 1\], "
             r"got 5.0"),
            ({"search_space": {"num_epochs": {"choice": [2, 2.5]}}},
             r"hyperparameter 'num_epochs' of rllib ppo must be .*int.*got 2.5"),
            ({"search_space": {"lr": {"choice": [1e-3]}}, "algo": "sac"},
             r"config key 'algo' must be one of \['ppo', 'dqn'\], got 'sac'")]:
        bad.write_text(yaml.safe_dump(content))
        with pytest.raises(SystemExit, match=message):
            train.main(["--tune", str(bad), "--config", config, "--output",
                        str(tmp_path / "d")])
    for path in ("a", "b", "c", "d"):  # refused before anything is written
        assert not (tmp_path / path).exists()


def test_committed_rllib_hyperparameters_and_sweeps_are_valid():
    from sdc_training.rllib_config import check_run_config
    from sdc_training.tune_sweep import read_sweep

    sweeps = sorted((ROOT / "configs" / "tune").glob("*.yaml"))
    assert sweeps
    for algo in train.RLLIB_ALGORITHMS:
        for env_id in (HIGHWAY, TRACK):
            params = train.load_hyperparams(algo, env_id, "rllib")
            assert params, f"rllib_{algo}.yaml has no entry for {env_id}"
            hyper = {k: v for k, v in params.items() if k not in ("n_envs", "timesteps")}
            run = {"algo": algo, "env": env_id, "hyperparams": hyper, "config": {},
                   "n_envs": params["n_envs"], "seed": 0}
            check_run_config(run)
            for path in sweeps:
                sweep = read_sweep(path)
                if sweep.get("algo", "ppo") == algo:
                    check_run_config({**run, "tune": sweep})


def test_an_rllib_agent_with_a_relative_path_as_the_docs_write_it(ppo_run, monkeypatch):
    """``evaluate.py --agents rllib:runs/ppo_rllib/model`` (docs/ray.md, README): a path
    relative to the working folder drives as the absolute one (RLlib alone reads a relative
    path as a URI: ``ArrowInvalid: URI has empty scheme``)."""
    from sdc_agents.registry import make_agent

    output, model, _ = ppo_run
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"steps_per_action": 12})
    absolute = make_agent(f"rllib:{model}", env)
    monkeypatch.chdir(output.parent)
    relative = make_agent(f"rllib:{Path(output.name) / model.name}", env)
    observation, _ = env.reset(seed=4)
    absolute.reset()
    relative.reset()
    for _ in range(3):
        action = relative.act(observation)
        np.testing.assert_array_equal(action, absolute.act(observation))
        observation, *_ = env.step(action)
