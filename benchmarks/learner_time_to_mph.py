"""Wall time to a fixed mean mph on validation laps, per PPO learner, side by side (issue 27).

    nice -n 10 python benchmarks/learner_time_to_mph.py                  # sb3, rllib, ...
    nice -n 10 python benchmarks/learner_time_to_mph.py --learners sb3 --budget-s 600 \\
        --target-mph 44.5 --check-every 65536 --laps 8 --seed 1

Each learner trains PPO on ``HighwayLoopBehavior-v0`` the way ``train.py`` builds it, from
``configs/train_highway_behavior.yaml`` (its env config: the reward shaping, 240 s training
episodes) with ``--algo ppo``:

* ``sb3``: stable-baselines3 PPO on :class:`sdc_gym.envs.sb3.SB3VecEnv` (a native batch of
  ``--envs`` envs) with ``configs/hyperparams/ppo.yaml``, ``n_steps`` rescaled so that a
  rollout still holds the project's 2,048 samples (``bench_learners.py``'s settings; built
  by ``train.run_config`` and ``train.make_vec_env``, as ``train.py --n-envs E --hp
  n_steps=...`` would);
* ``sb3-large``: the same at throughput settings (``learner_settings.LARGE``: 1,024 envs split over
  two worker processes, rollouts of 8,192, minibatches of 2,048, torch on 2 threads in the
  update; ``--envs`` does not apply);
* ``rllib``: RLlib PPO as ``train.py --framework rllib --n-envs 1`` builds it
  (``configs/hyperparams/rllib_ppo.yaml``: the same rollout, minibatches and epochs; one
  env sampled in the learner's process, on a local Ray cluster started for the race);
* ``torchrl``, ``pufferlib``: ``bench_learners.py``'s other learners; skipped here with their
  install line when they do not import (neither is a project dependency), and with a note
  when they do (their samples/s: ``bench_learners.py --cases torchrl,pufferlib``; their
  race is not written).

Every ``--check-every`` samples (and once before the first), the current policy drives
``--laps`` validation laps deterministically (one lap per seed from 2000, all in one
native batch: :mod:`sdc_training.validation_laps`, the functions ``train.py``'s validation
uses) and the race stops when their mean mph reaches ``--target-mph`` or when the
``--budget-s`` wall budget (training and scoring) has run out (checked after each score,
so a race can overrun it by one chunk and one score; every race trains at least one
chunk). Printed per learner: samples/s
(samples over the training wall, scoring left out), the training wall to the target (or
"not reached in B s, best X mph") and the mph curve.

**The default target, 44.0 mph**, was chosen from a measured SB3 race (2026-12-04, this
2-core machine at load 2.1 at the start and 2.6 at the end, another engineer's DQN training
on one core; ``--learners sb3 --target-mph 99 --budget-s 240 --check-every 16384 --laps
4``): the untrained policy drove its 4 laps at 39.9 mph; SB3 PPO reached 43.1 mph after
16,384 samples, 44.0 (43.97) at 49,152, then held 43.1 (one policy, the same laps) from
0.11 M to 0.41 M samples, dipped to 41.1 and reached 44.5 at 0.48 M samples (131 s of
training, 3,633 samples/s, 241 s of wall with the scoring). PPO plateaus at 43-45 mph on
validation laps after millions of samples and the lane-keeping baseline drives 41-42, so
43 mph is reached within seconds by almost any policy that keeps up with the traffic:
44.0 mph is 80 % of the way from the untrained policy (39.9) to the plateau's top (45),
what SB3 reached within a few minutes here, not at every check. A random initial policy
can already be fast by luck (one RLlib initialisation drove 2 laps at 43.8 mph before any
update), so a race's time is one sample of a noisy quantity: compare learners over seeds
(``--seed``) before concluding.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

ENV_ID = "sdc_gym/HighwayLoopBehavior-v0"
RUN_CONFIG = ROOT / "configs" / "train_highway_behavior.yaml"
VALIDATION_SEED = 2000
DEFAULT_TARGET_MPH = 44.0
DEFAULT_BUDGET_S = 240.0
DEFAULT_CHECK_EVERY = 32_768
DEFAULT_LAPS = 4
LEARNERS = ("sb3", "sb3-large", "rllib", "torchrl", "pufferlib")
OPTIONAL = {"torchrl": "pip install --no-deps torchrl==0.14.1 tensordict==0.15.3 pyvers",
            "pufferlib": "pip install --no-deps pufferlib-core==3.0.23 psutil pyro-ppl "
                         "pyro-api opt_einsum rich_argparse"}
"""The learners that are no project dependency, and their install lines (docs/rl.md)."""


class Learner(Protocol):
    """What a race needs of a learner."""

    def train(self, samples: int) -> int:
        """Train on at least ``samples`` more samples; the samples trained on so far."""

    def policy(self) -> Any:
        """The current policy: anything with SB3's ``predict(obs, deterministic=True)``."""

    def close(self) -> None:
        """Free the learner's envs (and cluster)."""


@dataclass(frozen=True)
class Point:
    """One score of the race: after ``samples`` samples and ``train_s`` s of training."""

    samples: int
    train_s: float
    mph: float
    incidents: int


@dataclass
class Race:
    """A learner's race: its curve, the training wall at the target (None: not reached)
    and the whole wall (training and scoring)."""

    learner: str
    target_mph: float
    budget_s: float
    curve: list[Point] = field(default_factory=list)
    reached_s: float | None = None
    wall_s: float = 0.0

    @property
    def samples(self) -> int:
        return self.curve[-1].samples if self.curve else 0

    @property
    def train_s(self) -> float:
        return self.curve[-1].train_s if self.curve else 0.0

    @property
    def samples_per_s(self) -> float:
        """Samples over the training wall (the scoring left out); NaN before any."""
        return self.samples / self.train_s if self.train_s > 0 else float("nan")

    @property
    def best_mph(self) -> float:
        return max((point.mph for point in self.curve), default=float("nan"))

    def outcome(self) -> str:
        """``"131 s (0.48 M samples)"`` or ``"not reached in 300 s, best 40.4 mph"``."""
        if self.reached_s is not None:
            samples = next(p.samples for p in self.curve if p.mph >= self.target_mph)
            return f"{self.reached_s:.0f} s ({samples / 1e6:.2f} M samples)"
        return f"not reached in {self.budget_s:.0f} s, best {self.best_mph:.1f} mph"


def race(name: str, learner: Learner, score: Callable[[Any], Any], target_mph: float,
         check_every: int, budget_s: float,
         clock: Callable[[], float] = time.perf_counter,
         report: Callable[[str], None] | None = None) -> Race:
    """Score, train ``check_every`` samples, score again... until a score's mean mph
    (``score(policy).value``, a :class:`~sdc_training.validation_laps.LapScore`) reaches
    ``target_mph`` or the wall since the start (``clock``) reaches ``budget_s`` after at
    least one chunk of training (so that even a tiny budget measures samples/s)."""
    result = Race(name, target_mph, budget_s)
    started = clock()
    samples, train_s = 0, 0.0
    while True:
        lap_score = score(learner.policy())
        point = Point(samples, train_s, float(lap_score.value),
                      int(lap_score.counts.get("incidents", 0)))
        result.curve.append(point)
        result.wall_s = clock() - started
        if report is not None:
            report(f"  {name}: {samples:>9,} samples, {train_s:7.1f} s training, "
                   f"{point.mph:5.2f} mph, {point.incidents} incidents "
                   f"(wall {result.wall_s:.0f} s)")
        if point.mph >= target_mph:
            result.reached_s = train_s
            return result
        if result.wall_s >= budget_s and samples:  # a race trains at least one chunk
            return result
        before = clock()
        samples = learner.train(check_every)
        train_s += clock() - before


# ------------------------------------------------------------------ the learners
def run_config(framework: str, n_envs: int, seed: int, extra: Sequence[str] = ()) -> dict:
    """train.py's resolved run config for PPO from :data:`RUN_CONFIG` (its checks too)."""
    import train

    with tempfile.TemporaryDirectory(prefix="time-to-mph-") as folder:
        args = train.parse_args(["--config", str(RUN_CONFIG), "--framework", framework,
                                 "--algo", "ppo", "--n-envs", str(n_envs), "--seed",
                                 str(seed), "--eval-every", "0", "--output", folder, *extra])
        return train.run_config(args)


class SB3Learner:
    """SB3 PPO as train.py builds it, on a native batch of ``n_envs`` envs (``large``: the
    ``learner_settings.LARGE`` settings instead, ``n_envs`` ignored)."""

    def __init__(self, n_envs: int, seed: int, threads: int = 1, large: bool = False) -> None:
        import torch
        from learner_settings import LARGE, ppo_settings

        import train
        from sdc_agents.policy_agent import algorithm_class
        from sdc_gym.validation.run_config import resolved_policy_kwargs
        from sdc_training.torch_threads import phase_threads_callback

        if large:
            n_envs, threads = LARGE["n_envs"], LARGE["threads"]
            extra = ["--hp", f"n_steps={LARGE['n_steps']}",
                     "--hp", f"batch_size={LARGE['batch_size']}"]
        else:  # the project's rollout size over E
            extra = ["--hp", f"n_steps={ppo_settings(n_envs)['n_steps']}"]
        torch.set_num_threads(threads)
        self.config = run_config("sb3", n_envs, seed, extra)
        self.vec = train.make_vec_env(self.config, n_envs, seed,
                                      "split" if large else "batch")  # LARGE: 2 processes
        self.callback = phase_threads_callback(threads) if threads > 1 else None
        hyper = dict(self.config["hyperparams"])
        policy = hyper.pop("policy", "MlpPolicy")
        self.model = algorithm_class("ppo")(policy, self.vec, seed=seed, verbose=0,
                                            device="cpu", **resolved_policy_kwargs(hyper))

    def train(self, samples: int) -> int:
        self.model.learn(samples, reset_num_timesteps=False, callback=self.callback)
        return int(self.model.num_timesteps)

    def policy(self) -> Any:
        return self.model

    def close(self) -> None:
        self.vec.close()


class RLlibLearner:
    """RLlib PPO as ``train.py --framework rllib --n-envs 1`` builds it, on a local
    cluster that lives as long as the learner."""

    def __init__(self, seed: int, threads: int = 1) -> None:
        import torch

        from sdc_gym.ray import LOCAL, ray_session
        from sdc_training.rllib_config import algorithm_config

        torch.set_num_threads(threads)
        self.config = run_config("rllib", 1, seed)
        self.session = ray_session(LOCAL)
        self.session.__enter__()
        try:
            self.algo = algorithm_config(self.config).build_algo()
        except BaseException:
            self.session.__exit__(*sys.exc_info())
            raise
        self.steps = 0

    def train(self, samples: int) -> int:
        from sdc_training.rllib_trainer import STEPS_KEY

        goal = self.steps + samples
        while self.steps < goal:
            self.steps = int(self.algo.train()[STEPS_KEY])
        return self.steps

    def policy(self) -> Any:
        from sdc_agents.rllib_policy import RLlibPolicy

        module = self.algo.get_module()  # the env runner's, synced after each update
        policy = RLlibPolicy(module)  # puts it in eval mode: back in train mode after
        return _Restoring(policy, module)

    def close(self) -> None:
        try:
            self.algo.stop()
        finally:
            self.session.__exit__(None, None, None)


class _Restoring:
    """An RLlib policy that puts its module back in train mode once scored."""

    def __init__(self, policy: Any, module: Any) -> None:
        self.policy, self.module = policy, module

    def predict(self, *args: Any, **kwargs: Any) -> Any:
        return self.policy.predict(*args, **kwargs)

    def done(self) -> None:
        self.module.train()


def make_learner(name: str, n_envs: int, seed: int, threads: int) -> Learner:
    if name == "sb3":
        return SB3Learner(n_envs, seed, threads)
    if name == "sb3-large":
        return SB3Learner(n_envs, seed, large=True)
    if name == "rllib":
        return RLlibLearner(seed, threads)
    raise ValueError(f"no race for learner {name!r}; valid: sb3, sb3-large, rllib")


def skip_reason(name: str) -> str | None:
    """Why ``name`` is not raced here (None: it is)."""
    if name in OPTIONAL:
        if importlib.util.find_spec(name) is None:
            return f"{name} is not installed (not a project dependency; {OPTIONAL[name]})"
        return (f"{name} imports, but its time-to-mph race is not written (its samples/s: "
                f"benchmarks/bench_learners.py --cases {name},{name}-noop)")
    if name == "rllib" and importlib.util.find_spec("ray") is None:
        return 'Ray is not installed (pip install -e ".[ray]")'
    return None


def lap_scorer(config: dict[str, Any], laps: int, seed: int = VALIDATION_SEED) -> Any:
    """``score(policy)``: the policy's :class:`LapScore` on ``laps`` one-lap envs (seeds
    ``seed``...), one native batch made once; ``score.close()`` frees it."""
    from sdc_training.validation_laps import make_lap_envs, validate_model

    envs = make_lap_envs(ENV_ID, config, laps)

    def score(policy: Any) -> Any:
        try:
            return validate_model(policy, envs, ENV_ID, seed)[0]
        finally:
            if hasattr(policy, "done"):
                policy.done()

    score.close = envs.close  # type: ignore[attr-defined]
    return score


def run_race(name: str, target_mph: float, budget_s: float, check_every: int, laps: int,
             n_envs: int = 64, seed: int = 0, threads: int = 1,
             report: Callable[[str], None] | None = print) -> Race:
    """One learner's race, built, run and closed."""
    learner = make_learner(name, n_envs, seed, threads)
    score = lap_scorer(learner.config["config"], laps)  # type: ignore[attr-defined]
    try:
        return race(name, learner, score, target_mph, check_every, budget_s, report=report)
    finally:
        score.close()
        learner.close()


# ------------------------------------------------------------------ the report
def race_table(races: Sequence[Race]) -> list[str]:
    """The side-by-side lines: samples/s, time to the target, and each curve."""
    if not races:
        return ["(no learner raced)"]
    target = races[0].target_mph
    lines = [f"| learner | samples/s | training wall to {target:.1f} mph | samples | "
             "wall with scoring (s) |", "|---|---:|---|---:|---:|"]
    for entry in races:
        lines.append(f"| {entry.learner} | {entry.samples_per_s:,.0f} | {entry.outcome()} | "
                     f"{entry.samples:,} | {entry.wall_s:.0f} |")
    for entry in races:
        lines.append(f"{entry.learner} mph curve (M samples: mph): " + ", ".join(
            f"{p.samples / 1e6:.2f}: {p.mph:.1f}" for p in entry.curve))
    return lines


def positive(kind: type) -> Callable[[str], Any]:
    """An argparse type: a positive ``kind``, with a message naming the value."""
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a {kind.__name__}") from None
        if value <= 0:
            raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
        return value
    return parse


def parse_learners(text: str) -> list[str]:
    names = [name.strip() for name in text.split(",") if name.strip()]
    for name in names:
        if name not in LEARNERS:
            raise argparse.ArgumentTypeError(f"unknown learner {name!r}; choices: "
                                             f"{', '.join(LEARNERS)}")
    if not names:
        raise argparse.ArgumentTypeError(f"no learner given; choices: {', '.join(LEARNERS)}")
    return names


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--learners", type=parse_learners, default=list(LEARNERS),
                        help=f"comma-separated, of {', '.join(LEARNERS)} (default: all)")
    parser.add_argument("--target-mph", type=positive(float), default=DEFAULT_TARGET_MPH)
    parser.add_argument("--budget-s", type=positive(float), default=DEFAULT_BUDGET_S,
                        help="wall budget per learner, training and scoring (s)")
    parser.add_argument("--check-every", type=positive(int), default=DEFAULT_CHECK_EVERY,
                        help="samples between scores")
    parser.add_argument("--laps", type=positive(int), default=DEFAULT_LAPS,
                        help="validation laps per score (seeds from 2000, one batch)")
    parser.add_argument("--envs", type=positive(int), default=64,
                        help="SB3's batch of envs (E)")
    parser.add_argument("--seed", type=int, default=0)


def run_races(args: argparse.Namespace,
              report: Callable[[str], None] = print) -> tuple[list[Race], list[str]]:
    """The races of ``args.learners`` and the skip notes of those not raced."""
    races, notes = [], []
    for name in args.learners:
        reason = skip_reason(name)
        if reason is not None:
            notes.append(f"skipping {name}: {reason}")
            report(notes[-1])
            continue
        races.append(run_race(name, args.target_mph, args.budget_s, args.check_every,
                              args.laps, args.envs, args.seed, report=report))
    return races, notes


def main(argv: list[str] | None = None) -> None:
    import os

    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore")
    print(f"PPO on {ENV_ID} to {args.target_mph} mph on {args.laps} validation laps (seeds "
          f"from {VALIDATION_SEED}), scored every {args.check_every:,} samples, budget "
          f"{args.budget_s:.0f} s per learner; load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}", flush=True)
    races, _ = run_races(args, lambda line: print(line, flush=True))
    print()
    print("\n".join(race_table(races)))
    print(f"load average at the end: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
