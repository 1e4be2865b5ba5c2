"""End-to-end PPO samples per second (collection + update, wall) per learner, side by side.

    nice -n 10 python benchmarks/bench_learners.py                      # E=64, 3 rounds
    nice -n 10 python benchmarks/bench_learners.py --envs 64 --samples 131072 --rounds 3

Every case trains PPO with the project's hyperparameters (``configs/hyperparams/ppo.yaml``
for ``HighwayLoopBehavior-v0``: samples per rollout, minibatch size, epochs, 64 x 64 MLP;
printed at the start) on the env's native batch of ``--envs`` envs, for ``--samples``
samples after a warm-up rollout:

* ``sb3``: stable-baselines3 PPO over :class:`sdc_gym.envs.sb3.SB3VecEnv` (as train.py runs it);
* ``torchrl``: torchrl's ``ClipPPOLoss`` and ``GAE`` in a plain loop over the batched env
  (no collector: the env already is a batch of numpy arrays);
* ``rllib``: RLlib PPO as ``training/`` builds it (``benchmarks/bench_ray.py``'s case);
* ``pufferlib``: PufferLib's own PPO trainer (``pufferlib.pufferl.PuffeRL``, pufferlib-core
  3.0.23) over the batch as one native ``PufferEnv`` of E agents (no per-env Python);
  ``pufferlib-pool``: the same trainer over PufferLib's ``Multiprocessing`` vector env,
  two worker processes of E / 2 envs each and a batch of one worker, so one half of the
  batch steps while the trainer runs the policy on the other (its env pool: collection
  overlapped with inference; PuffeRL still alternates collection and update);
  ``pufferlib-kt2``: ``pufferlib`` with the env's kernels on two threads (the learner
  idles while the env steps, so the second core is free for them);
* each ``*-noop`` case: the same learner on a no-op env of the same spaces (zeros for
  observations, no episode end): the learner's own cost, its ceiling on this machine;
* ``env``, ``env-kt2``: the env alone, random actions on the native batch, its kernels on
  one thread and on two (the behavior env's ``highway.kernel_threads: 2``);
* ``env-split``, ``sb3-split``: the batch split over two worker processes
  (``train.py --vectorize split``), alone and under SB3's PPO;
* ``env-large``, ``sb3-large``, ``sb3-large-noop``: SB3's PPO at throughput settings
  (``learner_settings.LARGE``: 1,024 envs split over two processes, rollouts of 8,192,
  minibatches of 2,048, torch on 2 threads in the update), whatever ``--envs`` says.

The rate printed is min/median/max over ``--rounds`` rounds (rounds interleave the cases, so
the shared machine's load hits them alike), with the ratio of medians to ``sb3``. Then the
bounds, from the medians: a learner that alternates collection and update spends
1/env + 1/learner seconds per sample, so it cannot beat 1 / (1/env + 1/learner) (the
*sequential bound*); one that overlaps them on two cores is bounded by min(env, learner).

PufferLib is not a project dependency; its cases are skipped with the reason printed when
it does not import. pufferlib-core 3.0.23's wheel needs torch 2.9.0 and CUDA for its
compiled ``_C`` (the PPO advantage kernel), so install it with ``--no-deps`` (plus
``psutil pyro-ppl pyro-api opt_einsum rich_argparse``, also ``--no-deps``, keeping torch
2.13.0 CPU); :func:`puff_advantage` here is that kernel's C++ CPU loop ported to numba and
registered under the same op name, so PuffeRL runs unchanged.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


from learner_settings import (
    ENV_ID,
    LARGE,
    LARGE_SAMPLES,
    OVERRIDES,
    NoopVecEnv,
    ppo_settings,
    tanh_mlp,
)
from learners_pufferlib import COLLECTION_SHARE, puffer_importable
from speed_targets import sequential_bound


def env_rate(n_envs: int, samples: int, kernel_threads: int, processes: int = 1) -> float:
    """The env alone: random discrete actions on the native batch (SAME_STEP autoreset, as
    :class:`~sdc_gym.envs.sb3.SB3VecEnv` runs it; ``processes`` 2: split over two worker
    processes), after a warm-up of 64 steps."""
    from gymnasium.vector import AutoresetMode

    from sdc_gym.envs.highway_vector import make_behavior_vector_env

    config = {"highway": {"kernel_threads": kernel_threads}} if kernel_threads > 1 else None
    env = make_behavior_vector_env(n_envs, processes, config=config,
                                   autoreset_mode=AutoresetMode.SAME_STEP)
    steps = max(1, samples // n_envs)
    actions = np.random.default_rng(0).integers(0, env.single_action_space.n,
                                                (steps + 64, n_envs))
    env.reset(seed=0)
    for t in range(64):
        env.step(actions[t])
    started = time.perf_counter()
    for t in range(64, steps + 64):
        env.step(actions[t])
    wall = time.perf_counter() - started
    env.close()
    return steps * n_envs / wall


def sb3_rate(n_envs: int, samples: int, noop: bool, threads: int,
             processes: int = 1, large: bool = False) -> float:
    """SB3's PPO (``large``: at :data:`learner_settings.LARGE`, E and threads ignored)."""
    import torch
    from stable_baselines3 import PPO

    from sdc_gym.envs.sb3 import SB3VecEnv
    from sdc_training.torch_threads import phase_threads_callback

    if large:
        n_envs, threads, processes = LARGE["n_envs"], LARGE["threads"], LARGE["processes"]
        samples = max(samples, LARGE_SAMPLES)
    torch.set_num_threads(threads)
    if noop:
        from bench_batched import NullVecEnv  # SB3's own cost: bench_batched's ceiling

        vec = NullVecEnv(n_envs)
    else:
        vec = SB3VecEnv(ENV_ID, n_envs, processes=processes)
    hyper = ppo_settings(n_envs)
    if large:
        hyper.update(n_steps=LARGE["n_steps"], batch_size=LARGE["batch_size"])
    callback = phase_threads_callback(threads) if threads > 1 else None
    model = PPO("MlpPolicy", vec, seed=0, verbose=0, device="cpu", **hyper)
    rollout = n_envs * hyper["n_steps"]
    model.learn(rollout, callback=callback)  # warm-up rollout and update
    started = time.perf_counter()
    model.learn(samples, reset_num_timesteps=False, callback=callback)
    wall = time.perf_counter() - started
    vec.close()
    return samples / wall


def torchrl_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    """PPO from torchrl's parts (ClipPPOLoss, GAE) over the batched env, numpy <-> torch
    at the env boundary only; the update is torchrl's loss on shuffled minibatches."""
    import torch
    from tensordict import TensorDict
    from tensordict.nn import TensorDictModule
    from torch import nn
    from torchrl.modules import ProbabilisticActor, ValueOperator
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    from sdc_gym.envs.highway_vector import HighwayLoopBehaviorVectorEnv

    torch.set_num_threads(threads)
    torch.manual_seed(0)
    env = NoopVecEnv(n_envs) if noop else HighwayLoopBehaviorVectorEnv(n_envs)
    hyper = ppo_settings(n_envs)
    width = hyper["policy_kwargs"]["net_arch"]
    n_obs = int(np.prod(env.single_observation_space.shape))
    n_act = int(env.single_action_space.n)

    def mlp(out: int) -> nn.Sequential:
        return tanh_mlp(n_obs, width, out)

    actor = ProbabilisticActor(TensorDictModule(mlp(n_act), ["observation"], ["logits"]),
                               in_keys=["logits"],
                               distribution_class=torch.distributions.Categorical,
                               return_log_prob=True)
    critic = ValueOperator(mlp(1), in_keys=["observation"])
    loss = ClipPPOLoss(actor, critic, clip_epsilon=hyper["clip_range"],
                       entropy_coeff=hyper["ent_coef"], normalize_advantage=True)
    gae = GAE(gamma=hyper["gamma"], lmbda=hyper["gae_lambda"], value_network=critic,
              average_gae=False)
    optim = torch.optim.Adam(loss.parameters(), lr=hyper["learning_rate"])
    n_steps, batch, epochs = hyper["n_steps"], hyper["batch_size"], hyper["n_epochs"]
    obs, _ = env.reset(seed=list(range(n_envs)))

    def iteration() -> None:
        nonlocal obs
        obs_buf = torch.empty(n_steps, n_envs, n_obs)
        next_buf = torch.empty(n_steps, n_envs, n_obs)
        act_buf = torch.empty(n_steps, n_envs, dtype=torch.long)
        logp_buf = torch.empty(n_steps, n_envs)
        rew_buf = torch.empty(n_steps, n_envs, 1)
        term_buf = torch.empty(n_steps, n_envs, 1, dtype=torch.bool)
        done_buf = torch.empty(n_steps, n_envs, 1, dtype=torch.bool)
        with torch.no_grad():
            for t in range(n_steps):
                o = torch.from_numpy(np.asarray(obs, np.float32).reshape(n_envs, n_obs))
                td = actor(TensorDict({"observation": o}, [n_envs]))
                action = td["action"]
                nxt, reward, terminated, truncated, info = env.step(action.numpy())
                done = np.logical_or(terminated, truncated)
                final = np.asarray(nxt, np.float32).reshape(n_envs, n_obs)
                if done.any() and "final_obs" in info:
                    final = final.copy()
                    for i in np.flatnonzero(done):
                        final[i] = np.asarray(info["final_obs"][i], np.float32).reshape(n_obs)
                obs_buf[t], act_buf[t], logp_buf[t] = o, action, td["action_log_prob"]
                next_buf[t] = torch.from_numpy(final)
                rew_buf[t, :, 0] = torch.from_numpy(np.asarray(reward, np.float32))
                term_buf[t, :, 0] = torch.from_numpy(np.asarray(terminated))
                done_buf[t, :, 0] = torch.from_numpy(done)
                obs = nxt
        data = TensorDict({
            "observation": obs_buf, "action": act_buf, "action_log_prob": logp_buf,
            "next": {"observation": next_buf, "reward": rew_buf, "terminated": term_buf,
                     "done": done_buf}}, [n_steps, n_envs]).transpose(0, 1)  # env, time
        with torch.no_grad():
            gae(data)
        flat = data.reshape(-1)
        for _ in range(epochs):
            for idx in torch.randperm(flat.shape[0]).split(batch):
                out = loss(flat[idx])
                total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
                optim.zero_grad()
                total.backward()
                nn.utils.clip_grad_norm_(loss.parameters(), 0.5)
                optim.step()

    iteration()  # warm-up
    rollout = n_envs * n_steps
    started = time.perf_counter()
    done_samples = 0
    while done_samples < samples:
        iteration()
        done_samples += rollout
    wall = time.perf_counter() - started
    env.close()
    return done_samples / wall


def rllib_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    from bench_ray import rllib_samples_per_second

    return rllib_samples_per_second(samples, 1)


def pufferlib_rate(n_envs: int, samples: int, noop: bool, threads: int, **kwargs: Any) -> float:
    from learners_pufferlib import pufferlib_rate as rate

    return rate(n_envs, samples, noop, threads, **kwargs)


def pufferlib_pool_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    return pufferlib_rate(n_envs, samples, noop, threads, workers=2)


def pufferlib_kt2_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    return pufferlib_rate(n_envs, samples, noop, threads, kernel_threads=2)


def env_alone_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    return env_rate(n_envs, samples, 1)


def env_kt2_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    return env_rate(n_envs, samples, 2)


def env_split_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    return env_rate(n_envs, samples, 1, processes=2)


def env_large_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    return env_rate(LARGE["n_envs"], max(samples, LARGE_SAMPLES), 1,
                    processes=LARGE["processes"])


def sb3_large_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    """SB3's PPO at throughput settings (:data:`learner_settings.LARGE`)."""
    return sb3_rate(n_envs, samples, noop, threads, large=True)


def sb3_split_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    """SB3's PPO collecting from the batch split over two worker processes
    (``train.py --vectorize split``): both cores step the envs while the learner waits."""
    return sb3_rate(n_envs, samples, noop, threads, processes=2)


CASES = {
    "env": (env_alone_rate, False), "env-kt2": (env_kt2_rate, False),
    "env-split": (env_split_rate, False),
    "sb3": (sb3_rate, False), "sb3-noop": (sb3_rate, True),
    "sb3-split": (sb3_split_rate, False),
    "env-large": (env_large_rate, False),
    "sb3-large": (sb3_large_rate, False), "sb3-large-noop": (sb3_large_rate, True),
    "torchrl": (torchrl_rate, False), "torchrl-noop": (torchrl_rate, True),
    "pufferlib": (pufferlib_rate, False), "pufferlib-noop": (pufferlib_rate, True),
    "pufferlib-kt2": (pufferlib_kt2_rate, False),
    "pufferlib-pool": (pufferlib_pool_rate, False),
    "pufferlib-pool-noop": (pufferlib_pool_rate, True),
    "rllib": (rllib_rate, False),
}
OPTIONAL = {"torchrl": "torchrl", "pufferlib": "pufferlib"}
"""Case prefix -> the module it needs (none is a project dependency)."""
BOUNDS = {
    "sb3": ("sb3-noop", ("env",)),
    "sb3-split": ("sb3-noop", ("env-split",)),
    "sb3-large": ("sb3-large-noop", ("env-large",)),
    "torchrl": ("torchrl-noop", ("env",)),
    "pufferlib": ("pufferlib-noop", ("env", "env-kt2")),
    "pufferlib-kt2": ("pufferlib-noop", ("env-kt2",)),
    "pufferlib-pool": ("pufferlib-pool-noop", ("env",)),
}
"""Learner case -> (its no-op case, the env cases its bounds are printed against)."""


def print_bounds(medians: dict[str, float]) -> None:
    """Each learner's end to end rate against its bounds (module docstring), from medians."""
    rows = [(learner, noop, env) for learner, (noop, envs) in BOUNDS.items() for env in envs
            if learner in medians and noop in medians and env in medians]
    if not rows:
        return
    print(f"\n{'learner':<16}{'env':>9}{'env':>9}{'learner':>9}{'sequential':>12}"
          f"{'overlap':>9}{'end to end':>12}{'/ seq.':>8}")
    print(f"{'':<16}{'case':>9}{'alone':>9}{'alone':>9}{'bound':>12}{'bound':>9}")
    for learner, noop, env in rows:
        alone, own = medians[env], medians[noop]
        bound = sequential_bound(alone, own)
        print(f"{learner:<16}{env:>9}{alone:>9,.0f}{own:>9,.0f}{bound:>12,.0f}"
              f"{min(alone, own):>9,.0f}{medians[learner]:>12,.0f}"
              f"{medians[learner] / bound:>8.2f}")




def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, default=64, help="envs in the batch (E)")
    parser.add_argument("--samples", type=int, default=65_536, help="samples timed per case")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1, help="torch threads per case")
    parser.add_argument("--cases", default=None,
                        help=f"comma-separated, of {', '.join(CASES)} (default: env, "
                             "env-kt2, sb3, sb3-noop, torchrl, torchrl-noop, pufferlib, "
                             "pufferlib-noop; the torchrl and pufferlib ones skipped, with "
                             "the reason printed, when they do not import)")
    parser.add_argument("--batch-size", type=int, default=None,
                        help="PPO minibatch (default: the project's)")
    parser.add_argument("--n-steps", type=int, default=None,
                        help="PPO steps per env per rollout (default: the project's rollout "
                             "size / E)")
    args = parser.parse_args()
    for name in ("batch_size", "n_steps"):
        value = getattr(args, name)
        if value is not None:
            if value < 1:
                parser.error(f"--{name.replace('_', '-')} must be >= 1, got {value}")
            OVERRIDES[name] = value
    have_torchrl = importlib.util.find_spec("torchrl") is not None
    if args.cases is None:
        args.cases = "env,env-kt2,sb3,sb3-noop,torchrl,torchrl-noop,pufferlib,pufferlib-noop"
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    for case in cases:
        if case not in CASES:
            parser.error(f"--cases: unknown case {case!r}; choices: {', '.join(CASES)}")
    if "torchrl" in args.cases and not have_torchrl:
        print("skipping the torchrl cases: torchrl is not installed (not a project "
              "dependency; pip install --no-deps torchrl==0.14.1 tensordict==0.15.3 pyvers, "
              "into a separate --target on PYTHONPATH, keeps torch 2.13.0)")
    if "pufferlib" in args.cases and not puffer_importable():
        print(f"skipping the pufferlib cases: {puffer_importable.reason}")
    cases = [case for case in cases
             if not (case.startswith("torchrl") and not have_torchrl)
             and not (case.startswith("pufferlib") and not puffer_importable())]
    warnings.filterwarnings("ignore")
    hyper = ppo_settings(args.envs)
    print(f"{ENV_ID}, E={args.envs}, PPO: n_steps={hyper['n_steps']} per env "
          f"({hyper['n_steps'] * args.envs} per rollout), batch_size={hyper['batch_size']}, "
          f"n_epochs={hyper['n_epochs']}, net_arch={hyper['policy_kwargs']['net_arch']}; "
          f"{args.samples:,} samples per case, torch threads {args.threads}; load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    rates: dict[str, list[float]] = {case: [] for case in cases}
    for round_ in range(args.rounds):
        for case in cases:
            fn, noop = CASES[case]
            rates[case].append(fn(args.envs, args.samples, noop, args.threads))
            print(f"  round {round_ + 1} {case}: {rates[case][-1]:,.0f} samples/s", flush=True)
    base = statistics.median(rates["sb3"]) if "sb3" in rates else None
    print(f"\n{'case':<20}{'min':>10}{'median':>10}{'max':>10}{'x sb3':>8}")
    for case, values in rates.items():
        med = statistics.median(values)
        ratio = f"{med / base:.2f}" if base else "-"
        print(f"{case:<20}{min(values):>10,.0f}{med:>10,.0f}{max(values):>10,.0f}{ratio:>8}")
    print_bounds({case: statistics.median(values) for case, values in rates.items()})
    for (noop, workers, threads), shares in COLLECTION_SHARE.items():
        name = f"pufferlib{'-pool' if workers else ''}{'-kt2' if threads > 1 else ''}" \
               f"{'-noop' if noop else ''}"
        print(f"{name}: collection (evaluate) {statistics.median(shares):.0%} of the wall, "
              f"the update (train) the rest (median of {len(shares)} rounds)")
    print(f"load average at the end: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
