"""Train a stable-baselines3 policy on an sdc-gym env; every run gets its own folder.

    python train.py --env sdc_gym/HighwayLoop-v0 --timesteps 100000 --output runs/ppo_highway
    python train.py --output runs/ppo_highway --resume      # continue from the last checkpoint

The run folder holds ``config.yaml`` (env id, env config, algorithm, seed), ``command.txt``
(the exact command), ``checkpoints/`` (saved every ``--checkpoint-every`` steps), the
TensorBoard log, and ``model.zip`` at the end. With ``--resume`` the newest checkpoint is
loaded and training continues to the same total number of timesteps.

Until the behavior-level environments arrive (their actions are lane and speed decisions),
the only registered env is the path-level highway, whose (N, 2) path action is hard to
learn from scratch: this script trains on it honestly, but expect a poor driver.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

import sdc_gym  # noqa: F401  (registers the env ids)

ALGORITHMS = ("ppo",)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="sdc_gym/HighwayLoop-v0", help="registered env id")
    parser.add_argument("--config", type=Path, default=None,
                        help="YAML with 'env' and/or 'config' (env overrides), as for evaluate.py")
    parser.add_argument("--algo", default="ppo", choices=ALGORITHMS)
    parser.add_argument("--timesteps", type=int, default=100_000, help="total env steps")
    parser.add_argument("--n-envs", type=int, default=1, help="parallel envs (subprocesses)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output", type=Path, required=True, help="run folder")
    parser.add_argument("--checkpoint-every", type=int, default=10_000, help="env steps")
    parser.add_argument("--resume", action="store_true", help="continue the run in --output")
    args = parser.parse_args(argv)
    if args.timesteps < 1 or args.n_envs < 1 or args.checkpoint_every < 1:
        parser.error("--timesteps, --n-envs and --checkpoint-every must be >= 1")
    return args


def run_config(args: argparse.Namespace) -> dict[str, Any]:
    """The run's recorded configuration (a resumed run reads it back from its folder)."""
    saved = args.output / "config.yaml"
    if args.resume:
        if not saved.is_file():
            raise SystemExit(f"--resume: no run to resume in {args.output} (no config.yaml)")
        return yaml.safe_load(saved.read_text(encoding="utf-8"))
    env_id, env_config = args.env, {}
    if args.config is not None:
        data = yaml.safe_load(args.config.read_text(encoding="utf-8")) or {}
        env_id, env_config = data.get("env", env_id), dict(data.get("config") or {})
    return {"env": env_id, "config": env_config, "algo": args.algo, "seed": args.seed,
            "timesteps": args.timesteps, "n_envs": args.n_envs}


def main(argv: list[str] | None = None) -> Path:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CheckpointCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    args = parse_args(argv)
    config = run_config(args)
    args.output.mkdir(parents=True, exist_ok=True)
    if not args.resume:
        (args.output / "config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    with (args.output / "command.txt").open("a", encoding="utf-8") as handle:
        handle.write(shlex.join([sys.executable, *sys.argv]) + "\n")

    gym.spec(config["env"])  # a clear error for an unknown id before any process starts
    vec_env = make_vec_env(
        config["env"], n_envs=config["n_envs"], seed=config["seed"],
        env_kwargs={"config": config["config"]},
        vec_env_cls=SubprocVecEnv if config["n_envs"] > 1 else None)
    checkpoints = args.output / "checkpoints"
    latest = max(checkpoints.glob("*.zip"), key=lambda p: p.stat().st_mtime, default=None)
    if args.resume and latest is not None:
        model = PPO.load(latest, env=vec_env)
    else:
        model = PPO("MultiInputPolicy" if isinstance(vec_env.observation_space, gym.spaces.Dict)
                    else "MlpPolicy", vec_env, seed=config["seed"], verbose=0,
                    tensorboard_log=str(args.output / "tensorboard"))
    callback = CheckpointCallback(max(args.checkpoint_every // config["n_envs"], 1),
                                  str(checkpoints), name_prefix=config["algo"])
    remaining = config["timesteps"] - model.num_timesteps
    if remaining > 0:
        model.learn(remaining, callback=callback, reset_num_timesteps=not args.resume,
                    progress_bar=False)
    model.save(args.output / "model")
    vec_env.close()
    print(f"trained {model.num_timesteps} steps; model: {args.output / 'model.zip'}")
    return args.output / "model.zip"


if __name__ == "__main__":
    main()
