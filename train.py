"""Train a policy on an sdc-gym env (stable-baselines3, or RLlib and Ray Tune); every run
gets its own folder.

    python train.py --config configs/train_highway_behavior.yaml --output runs/dqn_highway
    python train.py --config configs/train_highway_behavior.yaml --algo dqn --output runs/dqn
    python train.py --config ... --output runs/x --hp learning_rate=1e-4 --hp n_steps=256
    python train.py --output runs/dqn_highway --resume    # continue after an interruption
    python train.py --framework rllib --config ... --algo ppo --output runs/ppo_rllib
    python train.py --tune configs/tune/highway_ppo.yaml --config ... --output runs/sweep

``--framework rllib`` trains with RLlib on a Ray cluster (``--ray ADDRESS``, default a
local one for the run; :mod:`sdc_training.rllib_trainer`), hyperparameters from
``configs/hyperparams/rllib_<algo>.yaml``; ``--tune SWEEP.yaml`` sweeps them with Ray Tune
(:mod:`sdc_training.tune_sweep`). Both need the extra ``pip install -e ".[ray]"``.

The run config (``--config``, YAML) names the ``env`` id, its ``config``, and optionally
``algo``, ``timesteps``, ``n_envs``, ``seed``, ``checkpoint_every`` and ``eval``
(``every`` steps, ``episodes``, ``seed``: the first held-out seed) and ``validation``
(``every`` steps, 0 by default, ``episodes``, ``seed``: one lap per validation seed, from
2000, for model selection: ``sdc_training.validation_laps``). Hyperparameters come from
``configs/hyperparams/<algo>.yaml``, keyed by env id (as in rl-baselines3-zoo), and
``--hp key=value`` overrides them: the value is parsed as YAML (numbers, lists, mappings;
never evaluated as Python), dotted keys reach into mappings (``policy_kwargs.net_arch=[64]``).

The run folder holds ``config.yaml`` (everything above, resolved, with the seed),
``command.txt`` (each exact command, one per line), ``checkpoints/`` (model and, for
off-policy algorithms, the replay buffer, every ``--checkpoint-every`` steps),
``best_model.zip`` (best mean evaluation reward so far), ``evaluations.npz``,
``validations.csv`` and ``best_validation_model.zip`` (with ``validation``: each result, and
the model with the best eligible one: the highest mean mph, or the shortest mean lap, of
the results without any incident), ``averaged_model.zip`` (with ``averaging``: the policy's
weights averaged from ``start`` env steps on, a sample every ``every``, uniformly or with
``decay``: :mod:`sdc_training.weight_averaging`; also validated when validation is on),
``replay_buffer.pkl`` (DQN, SAC: the final buffer),
``tensorboard/`` (SB3's curves plus ``driving/``: incidents per episode by kind and in
all, success, mean speed and distance per episode, and lap time from the episodes that
complete a lap, which training episodes shorter than a lap never do) and ``model.zip`` at
the end. With ``--resume`` the newest checkpoint is loaded and training continues to the
same total of timesteps, checkpointing at the run's ``checkpoint_every``.
Envs with a native batch (``sdc_gym/HighwayLoopBehavior-v0``, ``sdc_gym/HighwayLoop-v0``,
``sdc_gym/TrackLoopBehavior-v0``, ``sdc_gym/TrackLoop-v0``) run as one batch of ``n_envs``
envs in this process (``sdc_gym.envs.sb3.SB3VecEnv``: no subprocesses, one batched policy
forward pass per step; env ``i`` is the env seeded
``seed + i``, as SB3's own vec envs seed it); ``--vectorize split`` splits that batch over
two worker processes (the same samples, both cores stepping the envs); other envs, or
``--vectorize subprocess``, run in ``n_envs`` subprocesses (default: one per CPU core).
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
from sdc_agents import checkpoints as ckpt
from sdc_agents.policy_agent import algorithm_class
from sdc_configs import config_path
from sdc_configs import packaged as packaged_config
from sdc_evaluation.files import atomic_write_text
from sdc_evaluation.run_folders import remove_stale_temporaries
from sdc_gym.config import ConfigError
from sdc_gym.validation.rules import Choice
from sdc_gym.validation.run_config import (
    ALGORITHMS,
    AVERAGING_DEFAULTS,
    EVAL_DEFAULTS,
    OFF_POLICY_ALGORITHMS,
    VALIDATION_DEFAULTS,
    check_algorithm_space,
    check_hyperparams,
    check_run_config,
    resolved_policy_kwargs,
)
from sdc_gym.validation.yaml_files import parse_yaml
from sdc_training.driving_metrics import driving_metrics
from sdc_training.yaml_files import read_yaml

RLLIB_ALGORITHMS = ("ppo", "dqn")
"""RLlib's (``--framework rllib``; ``sdc_training.rllib_config.ALGORITHMS``); ``ALGORITHMS``
are stable-baselines3's (``--framework sb3``, the default)."""
FRAMEWORKS = ("sb3", "rllib")
HYPERPARAMS_DIR = packaged_config("hyperparams")  # configs/hyperparams, installed too
RUN_KEYS = {"env", "config", "algo", "timesteps", "n_envs", "seed", "eval", "checkpoint_every",
            "framework", "validation", "averaging"}
CHECKPOINT_EVERY = 10_000
SPLIT_PROCESSES = 2
"""``--vectorize split``: worker processes the batch is split over (this machine's 2 cores)."""
DEFAULT_TIMESTEPS = 100_000
DEFAULT_ENV = "sdc_gym/HighwayLoopBehavior-v0"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", type=config_path, default=None,
                        help="run config YAML: a path, or a packaged name "
                             "(train_highway_behavior)")
    parser.add_argument("--env", default=None, help="env id (overrides the config's)")
    parser.add_argument("--algo", default=None,
                        choices=sorted(set(ALGORITHMS) | set(RLLIB_ALGORITHMS)),
                        help=f"sb3: {', '.join(ALGORITHMS)}; rllib: "
                             f"{', '.join(RLLIB_ALGORITHMS)} (default: the config's, else ppo)")
    parser.add_argument("--framework", default=None, choices=FRAMEWORKS,
                        help="sb3 (stable-baselines3, default) or rllib (RLlib on Ray)")
    parser.add_argument("--tune", type=config_path, default=None, metavar="SWEEP_YAML",
                        help="a Ray Tune sweep (search space, scheduler), e.g. "
                             "configs/tune/highway_ppo.yaml (RLlib)")
    parser.add_argument("--ray", default=None, metavar="ADDRESS",
                        help="the Ray cluster of an RLlib run: 'auto' or HOST:PORT (default: "
                             "a local cluster started for the run)")
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
    parser.add_argument("--validate-every", type=int, default=None,
                        help="env steps between validations: one lap per validation seed "
                             "(the run config's 'validation': seeds from 2000, 40 laps), "
                             "best_validation_model.zip and validations.csv (0: none)")
    parser.add_argument("--average-every", type=int, default=None,
                        help="env steps between samples of the weight average (the run "
                             "config's 'averaging'; 0: none): averaged_model.zip at the end, "
                             "scored by the validation laps too")
    parser.add_argument("--average-start", type=int, default=None,
                        help="env steps before the first sample of the weight average")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --output from its newest intact checkpoint")
    parser.add_argument("--resume-without-buffer", action="store_true",
                        help="with --resume of DQN or SAC: go on from the newest intact model "
                             "even if its replay buffer is missing or torn (an empty buffer; "
                             "without this flag that is refused)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--vectorize", choices=("batch", "split", "subprocess"),
                        default="batch",
                        help="batch: the env's native batch in this process (where it has "
                             "one); split: that batch split over two worker processes, the "
                             "same samples bit for bit (both cores step the envs while the "
                             "learner waits); subprocess: one process per env")
    parser.add_argument("--torch-threads", type=int, default=1,
                        help="torch threads in the learner's update (small MLPs: 1 is "
                             "fastest, and the env processes keep the other cores; large "
                             "minibatches gain from 2). With more than 1, SB3 collects on 1 "
                             "thread (torch's idle threads would spin on the envs' cores)")
    args = parser.parse_args(argv)
    for name in ("timesteps", "n_envs", "checkpoint_every", "torch_threads"):
        value = getattr(args, name)
        if value is not None and value < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    if args.tune is not None and args.framework == "sb3":
        parser.error("--tune sweeps with Ray Tune over RLlib runs: drop --framework sb3")
    if args.ray is not None and args.framework == "sb3":
        parser.error("--ray is for RLlib runs (--framework rllib); SB3 runs on this machine")
    if args.resume_without_buffer and not args.resume:
        parser.error("--resume-without-buffer goes with --resume")
    if args.resume and (args.average_every is not None or args.average_start is not None):
        parser.error("--average-every and --average-start are set when a run starts "
                     "(its config.yaml keeps them): drop them with --resume")
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


def hyperparams_name(framework: str, algo: str) -> str:
    """The hyperparameter file's name: ``<algo>`` (SB3) or ``rllib_<algo>``."""
    return algo if framework == "sb3" else f"{framework}_{algo}"


def load_hyperparams(algo: str, env_id: str, framework: str = "sb3") -> dict[str, Any]:
    """The hyperparameters for ``env_id`` in ``configs/hyperparams/<algo>.yaml`` (RLlib:
    ``rllib_<algo>.yaml``; {} if the file has no entry for it: the library's defaults);
    every offered algorithm has its file."""
    path = HYPERPARAMS_DIR / f"{hyperparams_name(framework, algo)}.yaml"
    if not path.is_file():
        raise SystemExit(f"{path}: no hyperparameter file for --algo {algo} "
                         f"(--framework {framework})")
    table = read_yaml(path)
    entry = table.get(env_id) or {}
    if not isinstance(entry, dict):
        raise SystemExit(f"{path}: the entry for {env_id} must be a mapping of "
                         f"hyperparameters, got {entry!r}")
    return dict(entry)


def first_given(*values: Any) -> Any:
    """The first value that is not None (0 is a given value, to be validated)."""
    return next((value for value in values if value is not None), None)


def run_config(args: argparse.Namespace) -> dict[str, Any]:
    """The run's resolved configuration (a resumed run reads it back from its folder).

    Each value comes from the command line, else the run config (``--config``), else the
    hyperparameter file's entry for the env (``timesteps``, ``n_envs``), else the default;
    for ``--framework rllib`` and ``--tune`` too (the algorithm: ``--algo``, else the
    sweep file's, else the run config's). Then every value is checked
    (:mod:`sdc_gym.validation.run_config`; RLlib's hyperparameters by
    :mod:`sdc_training.rllib_config`) and SystemExit names the key, the value and what is valid.
    """
    saved = args.output / "config.yaml"
    if args.resume:
        if not saved.is_file():
            raise SystemExit(f"--resume: no run to resume in {args.output} (no config.yaml)")
        config = read_yaml(saved)
        config.setdefault("checkpoint_every", CHECKPOINT_EVERY)  # runs from before it was kept
        config.setdefault("framework", "sb3")
        if args.tune is not None:
            raise SystemExit(f"--resume: the run in {args.output} keeps its own settings "
                             f"(a sweep's in its config.yaml): drop --tune")
        if args.framework is not None and args.framework != config["framework"]:
            raise SystemExit(f"--resume: the run in {args.output} is a --framework "
                             f"{config['framework']} run, not {args.framework}")
        if args.checkpoint_every is not None:
            config["checkpoint_every"] = args.checkpoint_every
        if args.validate_every is not None:  # validation can start in a resumed run
            config["validation"] = {**VALIDATION_DEFAULTS, **(config.get("validation") or {}),
                                    "every": args.validate_every}
        validate(config, str(saved))
        return config
    if saved.is_file():
        raise SystemExit(f"{args.output} already holds a run; use --resume or another --output")
    source = str(args.config) if args.config is not None else "train.py"
    data = read_yaml(args.config) if args.config is not None else {}
    if args.config is not None and not data:
        raise SystemExit(f"{args.config}: the run config is empty; give the keys to set "
                         f"(valid: {sorted(RUN_KEYS)}), or drop --config to train the "
                         f"defaults ({DEFAULT_ENV}, ppo)")
    unknown = set(data) - RUN_KEYS
    if unknown:
        raise SystemExit(f"{args.config}: unknown keys {sorted(unknown)}; valid: "
                         f"{sorted(RUN_KEYS)}")
    env_id = first_given(args.env, data.get("env"), DEFAULT_ENV)
    framework = first_given(args.framework, data.get("framework"),
                            "rllib" if args.tune is not None else "sb3")
    _check_choice(Choice(FRAMEWORKS), framework, source, "framework")
    if args.tune is not None and framework != "rllib":
        raise SystemExit(f"{source}: --tune sweeps RLlib runs; config key 'framework' "
                         f"must be 'rllib' with it, got {framework!r}")
    sweep = None
    if args.tune is not None:
        from sdc_training.tune_sweep import read_sweep

        sweep = read_sweep(args.tune)
    algo = first_given(args.algo, (sweep or {}).get("algo"), data.get("algo"), "ppo")
    _check_choice(Choice(framework_algorithms(framework)), algo, source, "algo",
                  f" for framework {framework}")
    if not isinstance(env_id, str):
        raise SystemExit(f"{source}: config key 'env' must be an env id, got {env_id!r}")
    hyper = apply_overrides(load_hyperparams(algo, env_id, framework), args.hp)
    hyper_n_envs, hyper_timesteps = hyper.pop("n_envs", None), hyper.pop("timesteps", None)
    evaluation = data.get("eval")
    evaluation = ({**EVAL_DEFAULTS, **evaluation} if isinstance(evaluation, dict)
                  else EVAL_DEFAULTS if evaluation is None else evaluation)
    if args.eval_every is not None and isinstance(evaluation, dict):
        evaluation["every"] = args.eval_every
    validation = data.get("validation")
    validation = ({**VALIDATION_DEFAULTS, **validation} if isinstance(validation, dict)
                  else dict(VALIDATION_DEFAULTS) if validation is None else validation)
    if args.validate_every is not None and isinstance(validation, dict):
        validation["every"] = args.validate_every
    averaging = data.get("averaging")
    averaging = ({**AVERAGING_DEFAULTS, **averaging} if isinstance(averaging, dict)
                 else dict(AVERAGING_DEFAULTS) if averaging is None else averaging)
    for key in ("every", "start"):
        if getattr(args, f"average_{key}") is not None and isinstance(averaging, dict):
            averaging[key] = getattr(args, f"average_{key}")
    config = {
        "env": env_id,
        "config": first_given(data.get("config"), {}),
        "framework": framework,
        "algo": algo,
        "seed": first_given(args.seed, data.get("seed"), 0),
        "timesteps": first_given(args.timesteps, data.get("timesteps"), hyper_timesteps,
                                 DEFAULT_TIMESTEPS),
        "n_envs": first_given(args.n_envs, data.get("n_envs"), hyper_n_envs,
                              os.cpu_count() or 1),
        "hyperparams": hyper,
        "eval": evaluation,
        "validation": validation,
        "averaging": averaging,
        "checkpoint_every": first_given(args.checkpoint_every, data.get("checkpoint_every"),
                                        CHECKPOINT_EVERY),
    }
    if sweep is not None:
        config["tune"] = sweep
    validate(config, source)
    return config


def framework_algorithms(framework: str) -> tuple[str, ...]:
    """The algorithms train.py offers with ``framework``."""
    return ALGORITHMS if framework == "sb3" else RLLIB_ALGORITHMS


def _check_choice(rule: Choice, value: Any, source: str, key: str, context: str = "") -> None:
    """SystemExit naming the run config's ``key``, ``value`` and the valid choices."""
    expectation = rule.problem(value)
    if expectation is not None:
        raise SystemExit(f"{source}: config key {key!r} must be {expectation}{context}, "
                         f"got {value!r}")


def validate(config: dict[str, Any], source: str) -> None:
    """Every value of the run config, its hyperparameters against the algorithm (SB3's
    constructor, or RLlib's config methods), and the env config by making the env once
    here, before any env process or Ray cluster starts (a bad key is one clear error, not
    a worker's ConnectionResetError)."""
    framework = config.get("framework", "sb3")
    _check_choice(Choice(FRAMEWORKS), framework, source, "framework")
    _check_choice(Choice(framework_algorithms(framework)), config.get("algo"), source, "algo",
                  f" for framework {framework}")
    try:
        check_run_config(config, source, registered=lambda env_id: env_id in gym.registry)
        check_validation(config, source)
        check_averaging(config, source)
        if framework == "rllib":
            check_rllib_config(config, source)
        else:
            check_hyperparams(algorithm_class(config["algo"]), config["hyperparams"],
                              f"{source} (hyperparameters)")
        env = gym.make(config["env"], config=config["config"])
        env.close()
        check_algorithm_space(config["algo"], env.action_space, config["env"], source)
    except (ConfigError, gym.error.Error) as error:
        raise SystemExit(str(error)) from None
    except (ValueError, TypeError) as error:  # an env's own check outside ConfigError
        raise SystemExit(f"{source}: cannot make {config['env']} with config "
                         f"{config['config']}: {error}") from None


def check_validation(config: dict[str, Any], source: str) -> None:
    """Validation laps (run config key ``validation``) need an SB3 run of a behavior env
    with a lap (:data:`sdc_training.validation_laps.LAP_SECTIONS`)."""
    from sdc_training.validation_laps import LAP_SECTIONS

    every = (config.get("validation") or {}).get("every", 0)
    if not every:
        return
    if config.get("framework", "sb3") != "sb3":
        raise ConfigError(f"{source}: config key 'validation.every' must be 0 with framework "
                          f"{config['framework']} (validation laps run in SB3 runs), "
                          f"got {every}")
    if config["env"] not in LAP_SECTIONS:
        raise ConfigError(f"{source}: config key 'validation.every' must be 0 for env "
                          f"{config['env']}: validation laps run on {sorted(LAP_SECTIONS)}, "
                          f"got {every}")


def check_averaging(config: dict[str, Any], source: str) -> None:
    """Weight averaging (run config key ``averaging``) runs in SB3 runs."""
    every = (config.get("averaging") or {}).get("every", 0)
    if every and config.get("framework", "sb3") != "sb3":
        raise ConfigError(f"{source}: config key 'averaging.every' must be 0 with framework "
                          f"{config['framework']} (weight averaging runs in SB3 runs), "
                          f"got {every}")


def make_vec_env(config: dict[str, Any], n_envs: int, seed: int,
                 vectorize: str = "batch") -> Any:
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    from sdc_gym.envs.sb3 import VECTOR_ENVS, SB3VecEnv

    env_id = config["env"]
    if vectorize in ("batch", "split") and env_id in VECTOR_ENVS:
        processes = min(SPLIT_PROCESSES, n_envs) if vectorize == "split" else 1
        batch = SB3VecEnv(env_id, n_envs, config["config"], processes=processes)
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
                for name, value in driving_metrics(summary or {}) if summary else ():
                    self.logger.record_mean(name, value)
            return True

    return DrivingMetricsCallback()


def main(argv: list[str] | None = None) -> Path:
    import torch
    from stable_baselines3.common.callbacks import CallbackList, ProgressBarCallback

    args = parse_args(argv)
    torch.set_num_threads(args.torch_threads)
    config = run_config(args)  # every value checked, the env config too, before any process
    if config["framework"] == "rllib" and (args.vectorize != "batch" or args.torch_threads != 1):
        raise SystemExit(f"--vectorize {args.vectorize} and --torch-threads {args.torch_threads}"
                         " set SB3's envs and learner; a --framework rllib run samples with "
                         "RLlib's env runners and takes neither: drop them")
    args.output.mkdir(parents=True, exist_ok=True)
    for stale in remove_stale_temporaries(args.output):  # a killed run's half files
        print(f"removed {stale} (a temporary file of a run that was killed)")
    if not args.resume:
        atomic_write_text(args.output / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    with (args.output / "command.txt").open("a", encoding="utf-8") as handle:
        handle.write(shlex.join([sys.executable, *(sys.argv if argv is None else
                                                   ["train.py", *argv])]) + "\n")
    if config["framework"] == "rllib":
        return train_with_ray(config, args)

    algo = algorithm_class(config["algo"])
    checkpoints = args.output / "checkpoints"
    off_policy = config["algo"] in OFF_POLICY_ALGORITHMS
    point = None
    if args.resume:
        try:
            point = ckpt.resume_point(checkpoints, config["algo"], off_policy,
                                      without_buffer=args.resume_without_buffer)
        except ValueError as error:
            raise SystemExit(f"--resume: {error}") from None
    vec_env = make_vec_env(config, config["n_envs"], config["seed"], args.vectorize)
    if point is not None:
        print("\n".join(point.report()))
        model = algo.load(point.model, env=vec_env,
                          tensorboard_log=str(args.output / "tensorboard"))
        if point.replay_buffer is not None:
            model.load_replay_buffer(point.replay_buffer)
    else:
        hyper = dict(config["hyperparams"])
        policy = hyper.pop("policy", "MultiInputPolicy" if isinstance(
            vec_env.observation_space, gym.spaces.Dict) else "MlpPolicy")
        model = algo(policy, vec_env, seed=config["seed"], verbose=0,
                     tensorboard_log=str(args.output / "tensorboard"),
                     **resolved_policy_kwargs(hyper))
    every = max(int(config["checkpoint_every"]) // config["n_envs"], 1)
    callbacks = [ckpt.checkpoint_callback(every, checkpoints, config["algo"], off_policy),
                 driving_callback()]
    averaging = config.get("averaging") or AVERAGING_DEFAULTS
    average = None
    if averaging["every"]:
        from sdc_training.weight_averaging import averaging_callback

        callbacks.append(averaging_callback(
            model, checkpoints, every=int(averaging["every"]), start=int(averaging["start"]),
            decay=averaging["decay"], checkpoint_every=every,
            resume_steps=None if point is None else point.steps))
        average = callbacks[-1].average
    evaluation = config["eval"]
    if evaluation["every"]:
        # Evaluation runs in this process; SB3 warns that its vec env class differs.
        warnings.filterwarnings("ignore", message="Training and eval env are not of the same")
        eval_env = make_vec_env(config, 1, int(evaluation["seed"]), args.vectorize)
        callbacks.append(ckpt.eval_callback(
            eval_env, args.output, n_eval_episodes=int(evaluation["episodes"]),
            eval_freq=max(int(evaluation["every"]) // config["n_envs"], 1),
            deterministic=True, verbose=1))  # prints return, mph, incidents per evaluation
    validation = config.get("validation") or VALIDATION_DEFAULTS
    if validation["every"]:
        from sdc_training.validation_laps import validation_callback

        callbacks.append(validation_callback(
            config["env"], config["config"], args.output,
            every=max(int(validation["every"]) // config["n_envs"], 1),
            episodes=int(validation["episodes"]), seed=int(validation["seed"]),
            average=average))
    if args.torch_threads > 1:
        from sdc_training.torch_threads import phase_threads_callback

        callbacks.append(phase_threads_callback(args.torch_threads))
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
    if average is not None and average.count:
        from sdc_training.weight_averaging import AVERAGED_NAME, save_averaged_model

        save_averaged_model(model, average, args.output / AVERAGED_NAME)
        print(f"weight average of {average.count} samples: {args.output / AVERAGED_NAME}")
    vec_env.close()
    print(f"trained {model.num_timesteps} steps; model: {final}")
    return final


def check_rllib_config(config: dict[str, Any], source: str) -> None:
    """RLlib's hyperparameters checked (:func:`sdc_training.rllib_config.check_run_config`):
    ConfigError naming the key; SystemExit when Ray is not installed."""
    try:
        from sdc_training.rllib_config import check_run_config as check_rllib_run
    except ImportError as error:
        raise SystemExit(f"--framework rllib needs Ray: pip install -e \".[ray]\" "
                         f"({error})") from None
    check_rllib_run(config, source)


def train_with_ray(config: dict[str, Any], args: argparse.Namespace) -> Path:
    """An RLlib run, or a Tune sweep of RLlib runs (:mod:`sdc_training`)."""
    from sdc_training.rllib_trainer import train_rllib
    from sdc_training.tune_sweep import sweep

    try:
        return sweep(config, args) if config.get("tune") else train_rllib(config, args)
    except ConnectionError as error:  # --ray ADDRESS with no cluster there
        raise SystemExit(f"--ray {args.ray}: {error}") from None


if __name__ == "__main__":
    main()
