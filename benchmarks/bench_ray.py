"""Ray against the local machinery, in one run: evaluation episodes per minute and PPO
training samples per second.

    python benchmarks/bench_ray.py [--seeds 6] [--workers 2] [--ppo-steps 8192] [--repeats 3]

* Evaluation: the same episodes (``--agents`` x ``--seeds`` on the default highway, one lap
  each) through the local process pool (``evaluate.py --workers N``) and as Ray tasks on
  a local cluster of N CPUs (``evaluate.py --ray``), started before the clock runs (its
  start-up is reported on its own line). Each backend runs the episodes twice: the first
  time its workers start (a forked pool inherits the imported project; a Ray worker is a
  new process that imports it), the second time Ray's workers are up (the pool forks
  anew). The results are checked to be the same, episode for episode.
* Training: PPO samples per second on ``HighwayLoopBehavior-v0`` with N env processes,
  stable-baselines3 (``configs/hyperparams/ppo.yaml``'s settings, as
  ``benchmarks/bench_behavior.py`` measures it) against RLlib (the run config
  ``train.py --framework rllib`` builds from ``configs/hyperparams/rllib_ppo.yaml``: the
  same 2048 samples per update, minibatches of 256, 5 epochs, 64 x 64 MLP), each after a
  warm-up update, the learner on one torch thread.

The four measurements are interleaved, ``--repeats`` rounds of pool, Ray, SB3, RLlib, and
the best of each is reported, so that a burst of load from other jobs on the machine
weighs on both sides of a ratio alike; the Ray workers' first run (start-up) is measured
once, before the rounds. The machine's load average is printed with the figures.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from bench_behavior import ppo_samples_per_second  # noqa: E402

import train  # noqa: E402
from sdc_evaluation.episodes import EpisodeSpec  # noqa: E402
from sdc_evaluation.runner import ProcessPoolBackend, run_episodes  # noqa: E402

ENV = "sdc_gym/HighwayLoop-v0"
BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
COMPARED = ("distance", "time", "lap_times", "incidents", "max_jerk")


def episodes_per_minute(backend, specs) -> tuple[float, list[dict]]:
    started = time.perf_counter()
    runs = run_episodes(specs, progress=False, backend=backend)
    wall = time.perf_counter() - started
    if runs.failures:
        raise SystemExit(f"episodes failed: {runs.failures}")
    return 60.0 * len(specs) / wall, runs.results


RLLIB_TIMERS = {"env_step_timer": "env step",
                "rlmodule_inference_timer": "RLModule forward",
                "env_to_module_connector/connector_pipeline_timer": "env-to-module connectors",
                "module_to_env_connector/connector_pipeline_timer": "module-to-env connectors"}
"""RLlib's own per-step timers of its env runners (seconds, means over the iteration)."""
LAST_TIMERS: dict[str, float] = {}


def _nested(result: dict, path: str) -> float | None:
    node = result
    for part in path.split("/"):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return float(node)


def rllib_samples_per_second(samples: int, n_envs: int) -> float:
    import torch

    from sdc_training.rllib_config import algorithm_config

    torch.set_num_threads(1)
    hyper = train.load_hyperparams("ppo", BEHAVIOR, "rllib")
    hyper.pop("timesteps", None)
    hyper.pop("n_envs", None)
    config = {"env": BEHAVIOR, "config": {}, "algo": "ppo", "seed": 0, "n_envs": n_envs,
              "hyperparams": hyper}
    algo = algorithm_config(config).build_algo()
    try:
        first = int(algo.train()["num_env_steps_sampled_lifetime"])  # warm-up update
        started = time.perf_counter()
        steps = first
        while steps - first < samples:
            result = algo.train()
            steps = int(result["num_env_steps_sampled_lifetime"])
        wall = time.perf_counter() - started
        LAST_TIMERS.update({name: value * 1000 for key, name in RLLIB_TIMERS.items()
                            if (value := _nested(result["env_runners"], key)) is not None})
    finally:
        algo.stop()
    return (steps - first) / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agents", nargs="+", default=["fsm_bold", "lane_keeping"])
    parser.add_argument("--seeds", type=int, default=6, help="seeds per agent")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="pool workers = local cluster CPUs = env processes")
    parser.add_argument("--ppo-steps", type=int, default=8192, help="PPO samples timed")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved rounds")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    import ray

    from sdc_evaluation.ray_backend import RayBackend
    from sdc_gym.ray import ray_session

    specs = [EpisodeSpec(agent, ENV, seed, {"laps": 1, "max_duration": 1000.0})
             for agent in args.agents for seed in range(args.seeds)]
    load = os.getloadavg()
    pool = ProcessPoolBackend(args.workers)
    started = time.perf_counter()
    with ray_session(num_cpus=args.workers):
        start_up = time.perf_counter() - started
        ray_first, ray_results = episodes_per_minute(RayBackend(), specs)
        rates: dict[str, list[float]] = {"pool": [], "ray": [], "sb3": [], "rllib": []}
        same = True
        for _ in range(args.repeats):
            rate, pool_results = episodes_per_minute(pool, specs)
            rates["pool"].append(rate)
            rate, again = episodes_per_minute(RayBackend(), specs)
            rates["ray"].append(rate)
            same &= all(all(a[key] == b[key] == c[key] for key in COMPARED)
                        for a, b, c in zip(pool_results, ray_results, again, strict=True))
            rates["sb3"].append(ppo_samples_per_second(BEHAVIOR, args.ppo_steps,
                                                       args.workers))
            rates["rllib"].append(rllib_samples_per_second(args.ppo_steps, args.workers))
    assert not ray.is_initialized()
    load_after = os.getloadavg()
    best = {name: max(values) for name, values in rates.items()}

    rows = [
        (f"evaluation, local pool of {args.workers}: episodes/min", best["pool"]),
        (f"evaluation, Ray tasks, local cluster of {args.workers} CPUs: episodes/min",
         best["ray"]),
        ("    the same, the Ray workers' first run (they start)", ray_first),
        ("local cluster start-up (s), not in the rates above", start_up),
        (f"PPO samples/s, {args.workers} env processes: stable-baselines3", best["sb3"]),
        (f"PPO samples/s, {args.workers} env runners: RLlib", best["rllib"]),
    ]
    width = max(len(name) for name, _ in rows)
    print(f"{len(specs)} episodes ({' '.join(args.agents)} x seeds 0-{args.seeds - 1}, one "
          f"lap of {ENV}); results identical on both: {same}; best of {args.repeats} "
          f"interleaved rounds")
    for name, value in rows:
        print(f"{name:<{width}}  {value:8.1f}")
    print(f"ratio episodes/min (Ray / pool): {best['ray'] / best['pool']:.2f}")
    print(f"ratio PPO samples/s (RLlib / SB3): {best['rllib'] / best['sb3']:.2f}")
    print("RLlib's env runner timers per step, last iteration (ms): " + ", ".join(
        f"{name} {value:.2f}" for name, value in LAST_TIMERS.items()))
    print("every round: " + "; ".join(f"{name} " + " ".join(f"{v:.1f}" for v in values)
                                      for name, values in rates.items()))
    print(f"load average (1, 5, 15 min) before {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}, "
          f"after {load_after[0]:.1f} {load_after[1]:.1f} {load_after[2]:.1f}; "
          f"cores: {os.cpu_count()}")
    if not same:
        raise SystemExit("the Ray backend's results differ from the pool's")


if __name__ == "__main__":
    main()
