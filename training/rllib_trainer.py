"""``train.py --framework rllib``: an RLlib run with the run folder of an SB3 run.

    python train.py --framework rllib --config configs/train_highway_behavior.yaml \
        --algo ppo --output runs/ppo_rllib
    python train.py --output runs/ppo_rllib --resume          # after an interruption
    python train.py --framework rllib ... --ray auto           # on a running cluster
    python evaluate.py --agents rllib:runs/ppo_rllib/model fsm_bold

RLlib's new API stack (RLModule and Learner, EnvRunner actors), configured by
:mod:`sdc_training.rllib_config` from the same run config YAML and
``configs/hyperparams/rllib_<algo>.yaml``. The envs are found in every worker through
:func:`sdc_gym.ray.register_envs`. The run folder holds what an SB3 run's does, with
checkpoint folders in place of ``.zip`` files (``Algorithm.save_to_path``, each written
to a temporary folder and renamed, so a checkpoint is whole or absent):

* ``config.yaml``, ``command.txt`` (train.py writes them);
* ``checkpoints/<algo>_<steps>_steps/`` every ``checkpoint_every`` env steps (for DQN with
  its replay buffer, ``replay_buffer.pkl``, which RLlib's own checkpoints leave out);
* ``best_model/`` (best mean reward of the periodic evaluation: ``eval.episodes``
  deterministic episodes in the driver from the held-out ``eval.seed``, with SB3's
  ``evaluate_policy`` on the same env sequence as an SB3 run's ``EvalCallback``) and
  ``evaluations.npz`` (``timesteps``, ``results``, ``ep_lengths``, as SB3's);
* ``tensorboard/rllib_<algo>_<n>/``: ``rollout/ep_rew_mean``, ``rollout/ep_len_mean``,
  ``time/fps``, the learner's ``train/`` figures, ``eval/`` and the ``driving/`` metrics,
  against env steps (SB3's names, so both show in one TensorBoard);
* ``model/`` at the end (with the replay buffer, so a longer run can go on from it):
  ``evaluate.py --agents rllib:RUN/model``.

``--resume`` restores the newest checkpoint (weights, optimizer, counters, connector
state, replay buffer) and trains on to the same total of env steps. A local cluster started for the
run is shut down at its end, also on Ctrl-C.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

from sdc_agents import checkpoints as ckpt
from sdc_gym.ray import LOCAL, ray_session
from sdc_training.driving_metrics import PREFIX as DRIVING_PREFIX
from sdc_training.rllib_config import algorithm_config

MODEL_FOLDER = "model"
BEST_FOLDER = "best_model"
CHECKPOINTS_FOLDER = "checkpoints"
EVALUATIONS_FILE = "evaluations.npz"
REPLAY_BUFFER_FILE = "replay_buffer.pkl"
RLLIB_METADATA = "rllib_checkpoint.json"
OFF_POLICY = ("dqn",)
"""Algorithms with a replay buffer: kept in the run's checkpoints and final model."""
STEPS_KEY = "num_env_steps_sampled_lifetime"
"""The result's count of env steps sampled since the run began (restored on resume)."""


def checkpoint_name(algo: str, steps: int) -> str:
    return f"{algo}_{steps}_steps"


def rllib_checkpoints(folder: Path, algo: str) -> list[tuple[int, Path]]:
    """``(steps, path)`` of the checkpoint folders ``<algo>_<steps>_steps``, newest first
    (a half-written one never has its final name: :func:`save_checkpoint`)."""
    found = []
    for path in folder.glob(f"{algo}_*_steps") if folder.is_dir() else ():
        steps = path.name[len(algo) + 1:-len("_steps")]
        if path.is_dir() and steps.isdigit():
            found.append((int(steps), path))
    return sorted(found, reverse=True)


def checkpoint_problem(path: Path) -> str | None:
    """Why an RLlib checkpoint folder cannot be restored (None: it looks whole): RLlib
    writes ``rllib_checkpoint.json`` (its metadata, JSON) into every checkpoint."""
    metadata = path / RLLIB_METADATA
    try:
        json.loads(metadata.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return f"not a whole RLlib checkpoint (no {RLLIB_METADATA})"
    except (OSError, ValueError) as error:
        return f"not a whole RLlib checkpoint ({RLLIB_METADATA}: {error})"
    return None


def resume_point(checkpoints: Path, algo: str, without_buffer: bool) -> ckpt.ResumePoint | None:
    """The newest checkpoint to resume from, as for an SB3 run
    (:func:`sdc_agents.checkpoints.resume_point`): a torn one is skipped with a note; for DQN
    its replay buffer must load, unless ``without_buffer`` (``--resume-without-buffer``).
    ``SystemExit`` when checkpoints exist but none can be resumed."""
    try:
        return ckpt.resume_point(checkpoints, algo, algo in OFF_POLICY,
                                 without_buffer=without_buffer,
                                 found=rllib_checkpoints(checkpoints, algo),
                                 check_model=checkpoint_problem,
                                 buffer_of=lambda path, _: path / REPLAY_BUFFER_FILE)
    except ValueError as error:
        raise SystemExit(f"--resume: {error}") from None


def replace_folder(source: Path, target: Path) -> None:
    """Put the finished folder ``source`` at ``target``: an old ``target`` is renamed
    aside first and removed after, so ``target`` is the old or the new whole folder (or,
    between the two renames, absent), never a mix of both."""
    old = target.with_name(f".{target.name}.old")
    if old.exists():
        shutil.rmtree(old)
    if target.exists():
        os.replace(target, old)
    os.replace(source, target)
    if old.exists():
        shutil.rmtree(old)


def save_checkpoint(algo: Any, target: Path, replay_buffer: bool = False) -> Path:
    """``algo.save_to_path`` into a temporary sibling of ``target``, flushed to disk, then
    renamed; with ``replay_buffer``, the off-policy algorithm's buffer too
    (:data:`REPLAY_BUFFER_FILE`: RLlib's new API stack leaves it out of its checkpoints)."""
    temporary = target.with_name(f".{target.name}.tmp")
    if temporary.exists():
        shutil.rmtree(temporary)
    target.parent.mkdir(parents=True, exist_ok=True)
    algo.save_to_path(str(temporary.resolve()))
    buffer = getattr(algo, "local_replay_buffer", None)
    if replay_buffer and buffer is not None:
        with ckpt.atomic_file(temporary / REPLAY_BUFFER_FILE) as handle:
            pickle.dump(buffer.get_state(), handle, protocol=pickle.HIGHEST_PROTOCOL)
    ckpt.sync_folder(temporary)
    replace_folder(temporary, target)
    return target


def restore_checkpoint(algo: Any, source: Path, replay_buffer: Path | None = None) -> None:
    """The algorithm's state from ``source``, and its replay buffer from ``replay_buffer``
    (None: the buffer stays empty)."""
    algo.restore_from_path(str(source.resolve()))
    buffer = getattr(algo, "local_replay_buffer", None)
    if replay_buffer is not None and buffer is not None:
        with replay_buffer.open("rb") as handle:
            buffer.set_state(pickle.load(handle))


def tensorboard_folder(root: Path, algo: str) -> Path:
    """``root/rllib_<algo>_<n>`` with the first free n (a resumed run gets the next)."""
    index = 1
    while (root / f"rllib_{algo}_{index}").exists():
        index += 1
    return root / f"rllib_{algo}_{index}"


def result_scalars(result: dict[str, Any]) -> dict[str, float]:
    """The figures of one ``algo.train()`` result worth a curve, by SB3's names."""
    runners = result.get("env_runners", {})
    scalars: dict[str, float] = {}
    for source, name in (("episode_return_mean", "rollout/ep_rew_mean"),
                         ("episode_len_mean", "rollout/ep_len_mean")):
        if runners.get(source) is not None:
            scalars[name] = float(runners[source])
    scalars.update({key: float(value) for key, value in runners.items()
                    if key.startswith(DRIVING_PREFIX) and np.isscalar(value)})
    learner = result.get("learners", {}).get("default_policy", {})
    scalars.update({f"train/{key}": float(value) for key, value in learner.items()
                    if np.isscalar(value) and not isinstance(value, str)
                    and np.isfinite(value)})
    return scalars


class Evaluation:
    """The periodic evaluation: deterministic episodes on held-out seeds, the best model
    kept, ``evaluations.npz`` in SB3's format."""

    def __init__(self, config: dict[str, Any], output: Path, resumed_at: int = 0) -> None:
        from stable_baselines3.common.env_util import make_vec_env
        from stable_baselines3.common.vec_env import DummyVecEnv

        settings = config["eval"]
        self.every = int(settings["every"])
        self.episodes = int(settings["episodes"])
        self.output = output
        env_id = config["env"]
        if env_id.startswith("sdc_gym/"):
            env_id = f"sdc_gym:{env_id}"
        self.env = make_vec_env(env_id, n_envs=1, seed=int(settings["seed"]),
                                env_kwargs={"config": config["config"]},
                                vec_env_cls=DummyVecEnv) if self.every else None
        self.timesteps: list[int] = []
        self.results: list[list[float]] = []
        self.lengths: list[list[int]] = []
        self.best = -np.inf
        previous = output / EVALUATIONS_FILE
        if self.every and resumed_at and previous.is_file():
            # A resumed run goes on with the history up to its checkpoint; best_model/ is
            # the best evaluated so far, so the bar to beat is over all of it.
            with np.load(previous) as data:
                kept = data["timesteps"] <= resumed_at
                self.timesteps = [int(t) for t in data["timesteps"][kept]]
                self.results = data["results"][kept].tolist()
                self.lengths = data["ep_lengths"][kept].tolist()
                self.best = float(np.max(np.mean(data["results"], axis=1), initial=-np.inf))

    def due(self, before: int, after: int) -> bool:
        return bool(self.every) and after // self.every > before // self.every

    def __call__(self, algo: Any, steps: int) -> float:
        """Evaluate the current policy (from a checkpoint, as an agent loads it); keep it
        as ``best_model/`` when its mean reward is the best so far."""
        from stable_baselines3.common.evaluation import evaluate_policy

        from sdc_agents.rllib_policy import load_rllib_policy

        candidate = save_checkpoint(algo, self.output / ".evaluated")
        rewards, lengths = evaluate_policy(load_rllib_policy(candidate), self.env,
                                           n_eval_episodes=self.episodes,
                                           deterministic=True, return_episode_rewards=True)
        mean = float(np.mean(rewards))
        self.timesteps.append(steps)
        self.results.append([float(r) for r in rewards])
        self.lengths.append([int(n) for n in lengths])
        with ckpt.atomic_file(self.output / EVALUATIONS_FILE) as handle:
            np.savez(handle, timesteps=np.array(self.timesteps),
                     results=np.array(self.results), ep_lengths=np.array(self.lengths))
        if mean > self.best:
            self.best = mean
            replace_folder(candidate, self.output / BEST_FOLDER)
        else:
            shutil.rmtree(candidate)
        return mean

    def close(self) -> None:
        if self.env is not None:
            self.env.close()


def train_rllib(config: dict[str, Any], args: argparse.Namespace) -> Path:
    """Train (or resume) the run of ``config`` in ``args.output``; the final model folder.

    ``args``: ``output``, ``resume``, ``no_progress`` and ``ray`` (the cluster: None or
    :data:`sdc_gym.ray.LOCAL` for a local one, ``"auto"``, ``HOST:PORT``).
    """
    from torch.utils.tensorboard import SummaryWriter

    output: Path = args.output
    checkpoints = output / CHECKPOINTS_FOLDER
    point = (resume_point(checkpoints, config["algo"], args.resume_without_buffer)
             if args.resume else None)
    if point is not None:
        print("\n".join(point.report()))
    total = int(config["timesteps"])
    every = int(config["checkpoint_every"])
    buffered = config["algo"] in OFF_POLICY
    with ray_session(args.ray or LOCAL):
        algo = algorithm_config(config).build_algo()
        evaluation = writer = None
        try:
            steps = 0
            if point is not None:
                restore_checkpoint(algo, point.model, point.replay_buffer)
                steps = point.steps
            evaluation = Evaluation(config, output, resumed_at=steps)
            writer = SummaryWriter(str(tensorboard_folder(output / "tensorboard",
                                                          config["algo"])))
            started, start_steps = time.perf_counter(), steps
            with _StepProgress(total, steps, not args.no_progress) as advance:
                while steps < total:
                    result = algo.train()
                    before, steps = steps, int(result[STEPS_KEY])
                    scalars = result_scalars(result)
                    scalars["time/fps"] = (steps - start_steps) / (time.perf_counter()
                                                                   - started)
                    if evaluation.due(before, steps):
                        scalars["eval/mean_reward"] = evaluation(algo, steps)
                        scalars["eval/mean_ep_length"] = float(np.mean(evaluation.lengths[-1]))
                    for name, value in scalars.items():
                        writer.add_scalar(name, value, steps)
                    if steps // every > before // every or steps >= total:
                        save_checkpoint(algo, checkpoints / checkpoint_name(config["algo"],
                                                                            steps), buffered)
                    advance(steps)
            final = save_checkpoint(algo, output / MODEL_FOLDER, buffered)
        finally:
            if writer is not None:
                writer.close()
            if evaluation is not None:
                evaluation.close()
            logdir = Path(algo.logdir)
            algo.stop()
            _remove_if_empty(logdir)
    print(f"trained {steps} steps; model: {final}")
    return final


def _remove_if_empty(folder: Path) -> None:
    """An Algorithm built outside Tune makes an (unused) folder in ~/ray_results."""
    try:
        folder.rmdir()
    except OSError:
        pass


class _StepProgress:
    """A rich progress bar of env steps (or nothing); ``advance(steps)`` moves it."""

    def __init__(self, total: int, done: int, enabled: bool) -> None:
        from rich.progress import Progress

        self.bar = Progress(disable=not enabled, transient=True)
        self.task = self.bar.add_task("env steps", total=total, completed=done)

    def __enter__(self) -> Any:
        self.bar.__enter__()
        return lambda steps: self.bar.update(self.task, completed=steps)

    def __exit__(self, *exc: object) -> None:
        self.bar.__exit__(*exc)
