"""Train a stable-baselines3 policy on an sdc-gym env; every run gets its own folder.

    python train.py --config configs/train_highway_behavior.yaml --output runs/dqn_highway
    python train.py --config configs/train_highway_behavior.yaml --algo dqn --output runs/dqn
    python train.py --config ... --output runs/x --hp learning_rate=1e-4 --hp n_steps=256
    python train.py --output runs/dqn_highway --resume    # continue after an interruption

The run config (``--config``, YAML) names the ``env`` id, its ``config``, and optionally
``algo``, ``timesteps``, ``n_envs``, ``seed``, ``checkpoint_every`` and ``eval``
(``every`` steps, ``episodes``, ``seed``: the first held-out seed). Hyperparameters come from
``configs/hyperparams/<algo>.yaml``, keyed by env id (as in rl-baselines3-zoo), and
``--hp key=value`` overrides them: the value is parsed as YAML (numbers, lists, mappings;
never evaluated as Python), dotted keys reach into mappings (``policy_kwargs.net_arch=[64]``).

The run folder holds ``config.yaml`` (everything above, resolved, with the seed),
``command.txt`` (each exact command, one per line), ``checkpoints/`` (model and, for
off-policy algorithms, the replay buffer, every ``--checkpoint-every`` steps),
``best_model.zip`` (best mean evaluation reward so far), ``evaluations.npz``,
``replay_buffer.pkl`` (DQN, SAC: the final buffer),
``tensorboard/`` (SB3's curves plus ``driving/``: incidents per episode by kind and in
all, success, mean speed and distance per episode, and lap time from the episodes that
complete a lap, which training episodes shorter than a lap never do) and ``model.zip`` at
the end. With ``--resume`` the newest checkpoint is loaded and training continues to the
same total of timesteps, checkpointing at the run's ``checkpoint_every``.
Envs with a native batch (``sdc_gym/HighwayLoopBehavior-v0``, ``sdc_gym/HighwayLoop-v0``)
run as one batch of ``n_envs`` envs in this process (``sdc_gym.envs.sb3.SB3VecEnv``: no
subprocesses, one batched policy forward pass per step; env ``i`` is the env seeded
``seed + i``, as SB3's own vec envs seed it); others, or ``--vectorize subprocess``, in
``n_envs`` subprocesses (default: one per CPU core).
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

import sdc_gym  # noqa: F401  (registers the env ids)
from agents import checkpoints as ckpt
from evaluation.files import atomic_write_text
from sdc_gym.config import ConfigError
from sdc_gym.validation.run_config import (
    ALGORITHMS,
    EVAL_DEFAULTS,
    check_hyperparams,
    check_run_config,
)
from sdc_gym.validation.text_files import parse_yaml
from sdc_gym.validation.text_files import read_yaml as read_yaml_file

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "configs" / "hyperparams"
RUN_KEYS = {"env", "config", "algo", "timesteps", "n_envs", "seed", "eval", "checkpoint_every"}
CHECKPOINT_EVERY = 10_000
DEFAULT_TIMESTEPS = 100_000
DEFAULT_ENV = "sdc_gym/HighwayLoopBehavior-v0"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", type=Path, default=None, help="run config YAML")
    parser.add_argument("--env", default=None, help="env id (overrides the config's)")
    parser.add_argument("--algo", default=None, choices=ALGORITHMS)
    parser.add_argument("--timesteps", type=int, default=None, help="total env steps")
    parser.add_argument("--n-envs", type=int, default=None, help="parallel envs (processes)")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--hp", action="append", default=[], metavar="KEY=VALUE",
                        help="hyperparameter override (YAML value; repeatable)")
    parser.add_argument("--output", type=Path, required=True, help="run folder")
    parser.add_argument("--checkpoint-every", type=int, default=None,
                        help=f"env steps between checkpoints (default {CHECKPOINT_EVERY:,}; "
                             "kept in the run's config.yaml, so a resumed run goes on at the "
                             "same interval)")
    parser.add_argument("--eval-every", type=int, default=None,
                        help="env steps between evaluations (0: none)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --output from its newest intact checkpoint")
    parser.add_argument("--resume-without-buffer", action="store_true",
                        help="with --resume of DQN or SAC: go on from the newest intact model "
                             "even if its replay buffer is missing or torn (an empty buffer; "
                             "without this flag that is refused)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--vectorize", choices=("batch", "subprocess"), default="batch",
                        help="batch: the env's native batch in this process (where it has "
                             "one); subprocess: one process per env")
    parser.add_argument("--torch-threads", type=int, default=1,
                        help="torch threads in the learner (small MLPs: 1 is fastest, and "
                             "the env processes keep the other cores)")
    args = parser.parse_args(argv)
    for name in ("timesteps", "n_envs", "checkpoint_every"):
        value = getattr(args, name)
        if value is not None and value < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    if args.resume_without_buffer and not args.resume:
        parser.error("--resume-without-buffer goes with --resume")
    return args


def parse_override(text: str) -> tuple[list[str], Any]:
    """``"a.b=value"`` -> (["a", "b"], value parsed as YAML); a clear error otherwise."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip() or any(not part for part in key.strip().split(".")):
        raise SystemExit(f"--hp {text!r}: expected KEY=VALUE, e.g. learning_rate=3e-4")
    try:
        value = parse_yaml(raw)
    except yaml.YAMLError as error:
        raise SystemExit(f"--hp {text!r}: the value is not valid YAML: {error}") from None
    return key.strip().split("."), value


def apply_overrides(params: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    params = dict(params)
    for text in overrides:
        path, value = parse_override(text)
        node = params
        for part in path[:-1]:
            child = node.get(part)
            node[part] = dict(child) if isinstance(child, dict) else {}
            node = node[part]
        node[path[-1]] = value
    return params


def load_hyperparams(algo: str, env_id: str) -> dict[str, Any]:
    """The hyperparameters for ``env_id`` in ``configs/hyperparams/<algo>.yaml`` ({} if the
    file has no entry for it: SB3's defaults); every offered algorithm has its file."""
    path = HYPERPARAMS_DIR / f"{algo}.yaml"
    if not path.is_file():
        raise SystemExit(f"{path}: no hyperparameter file for --algo {algo}")
    table = read_yaml(path)
    entry = table.get(env_id) or {}
    if not isinstance(entry, dict):
        raise SystemExit(f"{path}: the entry for {env_id} must be a mapping of "
                         f"hyperparameters, got {entry!r}")
    return dict(entry)


def read_yaml(path: Path) -> dict[str, Any]:
    """A YAML mapping (UTF-8, YAML 1.2 numbers), or SystemExit saying what is wrong."""
    data = read_yaml_file(path, "YAML file", SystemExit) or {}
    if not isinstance(data, dict):
        raise SystemExit(f"{path}: expected a mapping, got {type(data).__name__}")
    return data


def first_given(*values: Any) -> Any:
    """The first value that is not None (0 is a given value, to be validated)."""
    return next((value for value in values if value is not None), None)


def run_config(args: argparse.Namespace) -> dict[str, Any]:
    """The run's resolved configuration (a resumed run reads it back from its folder).

    Each value comes from the command line, else the run config (``--config``), else the
    hyperparameter file's entry for the env (``timesteps``, ``n_envs``), else the default;
    then every value is checked (:mod:`sdc_gym.validation.run_config`) and SystemExit
    names the key, the value and what is valid.
    """
    saved = args.output / "config.yaml"
    if args.resume:
        if not saved.is_file():
            raise SystemExit(f"--resume: no run to resume in {args.output} (no config.yaml)")
        config = read_yaml(saved)
        config.setdefault("checkpoint_every", CHECKPOINT_EVERY)  # runs from before it was kept
        if args.checkpoint_every is not None:
            config["checkpoint_every"] = args.checkpoint_every
        validate(config, str(saved))
        return config
    if saved.is_file():
        raise SystemExit(f"{args.output} already holds a run; use --resume or another --output")
    source = str(args.config) if args.config is not None else "train.py"
    data = read_yaml(args.config) if args.config is not None else {}
    unknown = set(data) - RUN_KEYS
    if unknown:
        raise SystemExit(f"{args.config}: unknown keys {sorted(unknown)}; valid: "
                         f"{sorted(RUN_KEYS)}")
    env_id = first_given(args.env, data.get("env"), DEFAULT_ENV)
    algo = first_given(args.algo, data.get("algo"), "ppo")
    if algo not in ALGORITHMS:
        raise SystemExit(f"{source}: config key 'algo' must be one of {list(ALGORITHMS)}, "
                         f"got {algo!r}")
    if not isinstance(env_id, str):
        raise SystemExit(f"{source}: config key 'env' must be an env id, got {env_id!r}")
    hyper = apply_overrides(load_hyperparams(algo, env_id), args.hp)
    hyper_n_envs, hyper_timesteps = hyper.pop("n_envs", None), hyper.pop("timesteps", None)
    evaluation = data.get("eval")
    evaluation = ({**EVAL_DEFAULTS, **evaluation} if isinstance(evaluation, dict)
                  else EVAL_DEFAULTS if evaluation is None else evaluation)
    if args.eval_every is not None and isinstance(evaluation, dict):
        evaluation["every"] = args.eval_every
    config = {
        "env": env_id,
        "config": first_given(data.get("config"), {}),
        "algo": algo,
        "seed": first_given(args.seed, data.get("seed"), 0),
        "timesteps": first_given(args.timesteps, data.get("timesteps"), hyper_timesteps,
                                 DEFAULT_TIMESTEPS),
        "n_envs": first_given(args.n_envs, data.get("n_envs"), hyper_n_envs,
                              os.cpu_count() or 1),
        "hyperparams": hyper,
        "eval": evaluation,
        "checkpoint_every": first_given(args.checkpoint_every, data.get("checkpoint_every"),
                                        CHECKPOINT_EVERY),
    }
    validate(config, source)
    return config


def validate(config: dict[str, Any], source: str) -> None:
    """Every value of the run config, its hyperparameters against the algorithm, and the
    env config by making the env once here, before any env process starts (a bad key is
    one clear error, not a worker's ConnectionResetError)."""
    try:
        check_run_config(config, source, registered=lambda env_id: env_id in gym.registry)
        check_hyperparams(algorithm_class(config["algo"]), config["hyperparams"],
                          f"{source} (hyperparameters)")
        env = gym.make(config["env"], config=config["config"])
        env.close()
    except (ConfigError, gym.error.Error) as error:
        raise SystemExit(str(error)) from None
    except (ValueError, TypeError) as error:  # an env's own check outside ConfigError
        raise SystemExit(f"{source}: cannot make {config['env']} with config "
                         f"{config['config']}: {error}") from None


def algorithm_class(name: str) -> type:
    import stable_baselines3

    return getattr(stable_baselines3, name.upper())


def make_vec_env(config: dict[str, Any], n_envs: int, seed: int,
                 vectorize: str = "batch") -> Any:
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    from sdc_gym.envs.sb3 import VECTOR_ENVS, SB3VecEnv

    env_id = config["env"]
    if vectorize == "batch" and env_id in VECTOR_ENVS:
        batch = SB3VecEnv(env_id, n_envs, config["config"])
        batch.seed(seed)
        return VecMonitor(batch)
    if env_id.startswith("sdc_gym/"):  # subprocesses import the package that registers it
        env_id = f"sdc_gym:{env_id}"
    return sb3_make_vec_env(env_id, n_envs=n_envs, seed=seed,
                            env_kwargs={"config": config["config"]},
                            vec_env_cls=SubprocVecEnv if n_envs > 1 else DummyVecEnv)


def driving_callback() -> Any:
    """Logs each finished episode's driving summary to TensorBoard (``driving/``)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class DrivingMetricsCallback(BaseCallback):
        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
                summary = info.get("summary") if done else None
                if not summary:
                    continue
                incidents = summary.get("incidents", {})
                for kind, count in incidents.items():
                    self.logger.record_mean(f"driving/{kind}_per_episode", count)
                self.logger.record_mean("driving/incidents_per_episode",
                                        sum(incidents.values()))
                self.logger.record_mean("driving/success", float(summary.get("is_success",
                                                                             False)))
                # Only episodes that complete a lap have lap times (the committed config's
                # 240 s episodes never do); every episode has its distance.
                for lap in summary.get("lap_times") or ():
                    self.logger.record_mean("driving/lap_time_s", lap)
                if summary.get("distance") is not None:
                    self.logger.record_mean("driving/distance_m", summary["distance"])
                if summary.get("mean_speed_mph") is not None:
                    self.logger.record_mean("driving/mean_speed_mph",
                                            summary["mean_speed_mph"])
            return True

    return DrivingMetricsCallback()


def main(argv: list[str] | None = None) -> Path:
    import torch
    from stable_baselines3.common.callbacks import CallbackList, ProgressBarCallback

    args = parse_args(argv)
    torch.set_num_threads(max(args.torch_threads, 1))
    config = run_config(args)  # every value checked, the env config too, before any process
    args.output.mkdir(parents=True, exist_ok=True)
    if not args.resume:
        atomic_write_text(args.output / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    with (args.output / "command.txt").open("a", encoding="utf-8") as handle:
        handle.write(shlex.join([sys.executable, *(sys.argv if argv is None else
                                                   ["train.py", *argv])]) + "\n")

    algo = algorithm_class(config["algo"])
    checkpoints = args.output / "checkpoints"
    off_policy = config["algo"] in ("dqn", "sac")
    point = None
    if args.resume:
        try:
            point = ckpt.resume_point(checkpoints, config["algo"], off_policy,
                                      without_buffer=args.resume_without_buffer)
        except ValueError as error:
            raise SystemExit(f"--resume: {error}") from None
    vec_env = make_vec_env(config, config["n_envs"], config["seed"], args.vectorize)
    if point is not None:
        for note in point.notes:
            print(f"--resume: {note}")
        print(f"--resume: from {point.model} ({point.steps} steps"
              + (f", replay buffer {point.replay_buffer.name})" if point.replay_buffer
                 else ")"))
        model = algo.load(point.model, env=vec_env,
                          tensorboard_log=str(args.output / "tensorboard"))
        if point.replay_buffer is not None:
            model.load_replay_buffer(point.replay_buffer)
    else:
        hyper = dict(config["hyperparams"])
        policy = hyper.pop("policy", "MultiInputPolicy" if isinstance(
            vec_env.observation_space, gym.spaces.Dict) else "MlpPolicy")
        model = algo(policy, vec_env, seed=config["seed"], verbose=0,
                     tensorboard_log=str(args.output / "tensorboard"), **hyper)
    every = max(int(config["checkpoint_every"]) // config["n_envs"], 1)
    callbacks = [ckpt.checkpoint_callback(every, checkpoints, config["algo"], off_policy),
                 driving_callback()]
    evaluation = config["eval"]
    if evaluation["every"]:
        # Evaluation runs in this process; SB3 warns that its vec env class differs.
        warnings.filterwarnings("ignore", message="Training and eval env are not of the same")
        eval_env = make_vec_env(config, 1, int(evaluation["seed"]), args.vectorize)
        callbacks.append(ckpt.eval_callback(
            eval_env, args.output, n_eval_episodes=int(evaluation["episodes"]),
            eval_freq=max(int(evaluation["every"]) // config["n_envs"], 1),
            deterministic=True, verbose=0))
    if not args.no_progress:
        callbacks.append(ProgressBarCallback())
    remaining = config["timesteps"] - model.num_timesteps
    if remaining > 0:
        model.learn(remaining, callback=CallbackList(callbacks),
                    reset_num_timesteps=point is None, tb_log_name=config["algo"])
    final = args.output / "model.zip"
    if off_policy:  # with the final model, so that a longer run can continue from here
        ckpt.save_replay_buffer(model, args.output / "replay_buffer.pkl")
    ckpt.save_model(model, final)
    vec_env.close()
    print(f"trained {model.num_timesteps} steps; model: {final}")
    return final


if __name__ == "__main__":
    main()
