"""Throughput of the natively batched envs against the single env, measured in one run.

    python benchmarks/bench_batched.py [--steps 2000] [--envs 1 8 64 256 1024] [--ppo-steps 16384]
    python benchmarks/bench_batched.py --reference /work/ref_pre15 --rounds 3 --only-single

Prints, with the machine's load (other jobs skew absolute numbers; ratios measured side
by side in the same run stay meaningful):

* with ``--reference TREE`` (another code tree with its own ``.venv``, e.g. the code before
  the batch work): the single env's rates of ``single_env_rates.py`` (random behavior
  steps, lane keeping, an FSM lap) in this tree and in ``TREE``, each in a fresh process,
  the two trees alternating for ``--rounds`` rounds, best of the rounds, and their ratio;

* ``HighwayLoopBehavior-v0`` env steps/s with random actions: the single env
  (``gym.make``) and the batch (``gym.make_vec(..., vectorization_mode=
  "vector_entry_point")``) at each E, and the ratio batch / single;
* PPO samples/s (``bench_behavior.py``'s settings: MLP 64x64, 2048 samples per rollout,
  5 epochs of minibatches of 256), torch on 1 and 2 threads: the batch through
  ``SB3VecEnv`` with the share of the time in PPO's update, the same PPO on a free env
  (:class:`NullVecEnv`: SB3's own cost, the ceiling of any env), and two single envs in
  subprocesses (the previous default of train.py);
* ``HighwayLoop-v0`` with the lane-keeping driver: simulated s per wall s against the
  number of cars, and the traffic's decision kernel alone (leaders by one sort per lane:
  the ratio 500 cars / 100 cars);
* ``TrackLoopBehavior-v0`` env steps/s (single env).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import single_env_rates
from bench_behavior import PPO_SETTINGS, ppo_samples_per_second
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

import sdc_gym  # noqa: F401
from sdc_gym.envs.sb3 import SB3VecEnv

BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
HERE = Path(__file__).resolve().parent
SINGLE_TASKS = {"behavior": 3000, "lane_keeping": 3000, "fsm_lap": 1}


def load() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def single_steps_per_second(env_id: str, steps: int, seed: int = 0) -> float:
    env = gym.make(env_id)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    space = env.action_space
    actions = [int(rng.integers(space.n)) if isinstance(space, gym.spaces.Discrete)
               else space.sample() for _ in range(steps)]
    env.step(actions[0])  # warm-up (compiled kernels load)
    started = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    wall = time.perf_counter() - started
    env.close()
    return steps / wall


def batch_steps_per_second(envs: int, env_steps: int, seed: int = 0) -> float:
    vector = gym.make_vec(BEHAVIOR, num_envs=envs, vectorization_mode="vector_entry_point")
    vector.reset(seed=seed)
    rng = np.random.default_rng(seed)
    vector.step(rng.integers(9, size=envs))
    batches = max(env_steps // envs, 3)
    started = time.perf_counter()
    for _ in range(batches):
        vector.step(rng.integers(9, size=envs))
    wall = time.perf_counter() - started
    vector.close()
    return batches * envs / wall


class NullVecEnv(VecEnv):
    """SB3 ``VecEnv`` of ``envs`` envs with the behavior batch's spaces whose step costs
    nothing (fixed random observations, reward 0, no episode ends): PPO on it is SB3's
    own cost per sample, the ceiling of any env's samples/s with the same settings."""

    def __init__(self, envs: int) -> None:
        template = SB3VecEnv(BEHAVIOR, 1)
        super().__init__(envs, template.observation_space, template.action_space)
        template.close()
        shape = self.observation_space.shape or ()
        self._obs = np.random.default_rng(0).random((envs, *shape)).astype(np.float32)

    def reset(self) -> np.ndarray:
        return self._obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        pass

    def step_wait(self) -> tuple:
        envs = self.num_envs
        return (self._obs.copy(), np.zeros(envs, dtype=np.float32), np.zeros(envs, dtype=bool),
                [{} for _ in range(envs)])

    def close(self) -> None:
        pass

    def get_attr(self, attr_name: str, indices: object = None) -> list:
        return [None] * self.num_envs

    def set_attr(self, attr_name: str, value: object, indices: object = None) -> None:
        pass

    def env_method(self, method_name: str, *args: object, indices: object = None,
                   **kwargs: object) -> list:
        return [None] * self.num_envs

    def env_is_wrapped(self, wrapper_class: type, indices: object = None) -> list:
        return [False] * self.num_envs


def ppo_samples_per_second_on(vec: object, samples: int, envs: int, threads: int,
                              seed: int = 0) -> tuple[float, float]:
    """PPO (bench_behavior's settings) on ``vec``: samples/s and the share of the time in
    PPO's update (``train``)."""
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(threads)
    model = PPO("MlpPolicy", vec, seed=seed, verbose=0,
                **{**PPO_SETTINGS, "n_steps": PPO_SETTINGS["n_steps"] * 2 // envs})
    spent = {"train": 0.0}
    train = model.train

    def timed_train() -> None:
        started = time.perf_counter()
        train()
        spent["train"] += time.perf_counter() - started

    model.train = timed_train  # type: ignore[method-assign]
    model.learn(2048)  # warm-up: the first rollout and update
    spent["train"] = 0.0
    started = time.perf_counter()
    model.learn(samples, reset_num_timesteps=False)
    wall = time.perf_counter() - started
    return samples / wall, spent["train"] / wall


def highway_sim_seconds_per_wall_second(cars: int, seconds: float, seed: int = 0) -> float:
    """Lane keeping on ``HighwayLoop-v0`` with ``cars`` cars (single_env_rates.py's)."""
    return single_env_rates.lane_keeping(round(seconds / 0.1), seed, cars)[0]


def decision_kernel_ms(cars: int, repeats: int = 30) -> float:
    from sdc_gym.road.builtin_highways import get_highway_map
    from sdc_gym.traffic import TrafficConfig
    from sdc_gym.traffic.batch import TrafficBatch
    from sdc_gym.traffic.decisions import decide

    road = get_highway_map("default")
    batch = TrafficBatch(road, TrafficConfig(car_count=cars, spawn_range=3000.0), envs=1)
    batch.reset_at(0, np.random.default_rng(0), road.start_s, road.start_d)
    # A decision at the window's frame 0 (the ego's state is the one at reset).
    rows, frame = np.ones(1, dtype=bool), np.zeros(1, dtype=np.int64)
    step0, ego = batch.state.step.copy(), np.zeros((1, 1))

    def once() -> None:
        decide(batch, rows, frame, step0, ego, ego, ego)

    once()
    started = time.perf_counter()
    for _ in range(repeats):
        once()
    return (time.perf_counter() - started) / repeats * 1e3


def single_rate(tree: Path, task: str, size: int) -> dict[str, float]:
    """``single_env_rates.py TASK`` run by ``tree``'s own interpreter (its ``agents``)."""
    python = tree / ".venv" / "bin" / "python"
    if not python.exists():
        raise SystemExit(f"--reference {tree}: no interpreter at {python}")
    done = subprocess.run([str(python), str(HERE / "single_env_rates.py"), task,
                           "--size", str(size), "--root", str(tree)], cwd=tree,
                          capture_output=True, text=True, check=False)
    if done.returncode:
        raise SystemExit(f"single_env_rates.py {task} in {tree} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def compare_single(reference: Path, rounds: int, scale: float) -> None:
    """This tree's single env against ``reference``'s, alternating, best of ``rounds``."""
    ours_tree = HERE.parent
    print(f"single env, this tree ({ours_tree}) against {reference}; best of {rounds} "
          f"rounds, trees alternating")
    for task, size in SINGLE_TASKS.items():
        size = max(1, round(size * scale))
        ours: list[dict[str, float]] = []
        theirs: list[dict[str, float]] = []
        for index in range(rounds):
            order = [(ours_tree, ours), (reference, theirs)]
            for tree, results in order if index % 2 == 0 else order[::-1]:
                results.append(single_rate(tree, task, size))
        lower_is_better = task == "fsm_lap"
        pick = min if lower_is_better else max
        mine, old = pick(r["rate"] for r in ours), pick(r["rate"] for r in theirs)
        ratio = old / mine if lower_is_better else mine / old
        print(f"  {task:13s} ours {mine:9.2f}  reference {old:9.2f}  {ours[0]['unit']:22s} "
              f"speed ratio {ratio:5.2f}x   first step after start: ours "
              f"{min(r['warm_s'] for r in ours):.2f} s, reference "
              f"{min(r['warm_s'] for r in theirs):.2f} s   load {load()}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=2000, help="single-env steps timed")
    parser.add_argument("--batch-steps", type=int, default=20000,
                        help="env steps timed per batch size")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 8, 64, 256, 1024])
    parser.add_argument("--ppo-steps", type=int, default=16384)
    parser.add_argument("--ppo-envs", type=int, nargs="+", default=[64, 256],
                        help="envs of the batched PPO")
    parser.add_argument("--cars", type=int, nargs="+", default=[12, 100, 200, 500])
    parser.add_argument("--sim-seconds", type=float, default=60.0)
    parser.add_argument("--skip-ppo", action="store_true")
    parser.add_argument("--reference", type=Path, default=None,
                        help="another code tree (with .venv) to compare the single env with")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of --reference")
    parser.add_argument("--single-scale", type=float, default=1.0,
                        help="scales the steps / laps of the --reference comparison")
    parser.add_argument("--only-single", action="store_true",
                        help="only the --reference comparison")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    print(f"load average at start: {load()} (cores: {os.cpu_count()}, numpy {np.__version__})")
    if args.reference is not None:
        compare_single(args.reference.resolve(), args.rounds, args.single_scale)
    if args.only_single:
        return

    single = single_steps_per_second(BEHAVIOR, args.steps)
    print(f"HighwayLoopBehavior-v0 single env:        {single:9.0f} env steps/s")
    for envs in args.envs:
        rate = batch_steps_per_second(envs, max(args.batch_steps, 3 * envs))
        print(f"HighwayLoopBehavior-v0 batch E = {envs:<5d}:  {rate:9.0f} env steps/s  "
              f"({rate / single:5.1f}x the single env)   load {load()}")
    if not args.skip_ppo:
        for envs in args.ppo_envs:
            for threads in (1, 2):
                vec = VecMonitor(SB3VecEnv(BEHAVIOR, envs))
                vec.seed(0)
                ours, share = ppo_samples_per_second_on(vec, args.ppo_steps, envs, threads)
                vec.close()
                ceiling, null_share = ppo_samples_per_second_on(NullVecEnv(envs),
                                                                args.ppo_steps, envs, threads)
                print(f"PPO samples/s, batch of {envs:4d} (SB3VecEnv), torch threads "
                      f"{threads}: {ours:7.0f} ({share:4.0%} in PPO's update); SB3 alone on a "
                      f"free env: {ceiling:7.0f} ({null_share:4.0%} update)   load {load()}",
                      flush=True)
        theirs = ppo_samples_per_second(BEHAVIOR, args.ppo_steps, 2)
        print(f"PPO samples/s, 2 single envs in subprocesses (the previous default): "
              f"{theirs:7.0f}   load {load()}")
    for cars in args.cars:
        rate = highway_sim_seconds_per_wall_second(cars, args.sim_seconds)
        print(f"HighwayLoop-v0 + lane keeping, {cars:4d} cars: {rate:8.1f} simulated s / wall s")
    small, large = decision_kernel_ms(100), decision_kernel_ms(500)
    print(f"traffic decision kernel: 100 cars {small:.2f} ms, 500 cars {large:.2f} ms "
          f"(ratio {large / small:.2f})")
    track = single_steps_per_second("sdc_gym/TrackLoopBehavior-v0", max(args.steps // 20, 50))
    print(f"TrackLoopBehavior-v0 single env:         {track:9.1f} env steps/s")
    print(f"load average at the end: {load()}")


if __name__ == "__main__":
    main()
