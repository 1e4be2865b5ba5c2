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
* each ``*-noop`` case: the same learner on a no-op env of the same spaces (zeros for
  observations, no episode end): the learner's own cost, its ceiling on this machine.

The rate printed is min/median/max over ``--rounds`` rounds (rounds interleave the cases, so
the shared machine's load hits them alike), with the ratio of medians to ``sb3``.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import train

ENV_ID = "sdc_gym/HighwayLoopBehavior-v0"


OVERRIDES: dict[str, Any] = {}
"""``--batch-size`` and ``--n-steps`` from the command line, over the project's values."""


def ppo_settings(n_envs: int) -> dict[str, Any]:
    """The project's PPO hyperparameters, ``n_steps`` rescaled so a rollout holds as many
    samples as the project's (n_envs x n_steps of the config)."""
    hyper = train.load_hyperparams("ppo", ENV_ID, "sb3")
    rollout = int(hyper.pop("n_envs")) * int(hyper["n_steps"])
    hyper.pop("timesteps", None)
    hyper["n_steps"] = max(1, rollout // n_envs)
    hyper.update(OVERRIDES)
    return hyper


class NoopVecEnv:
    """A stand-in batch with the env's spaces: zero observations, zero rewards, no ends."""

    def __init__(self, num_envs: int) -> None:
        from sdc_gym.envs.highway_vector import HighwayLoopBehaviorVectorEnv

        probe = HighwayLoopBehaviorVectorEnv(1)
        self.single_observation_space = probe.single_observation_space
        self.single_action_space = probe.single_action_space
        probe.close()
        self.num_envs = num_envs
        self._obs = np.zeros((num_envs, *self.single_observation_space.shape), np.float32)
        self._zeros = np.zeros(num_envs, np.float64)
        self._false = np.zeros(num_envs, bool)

    def reset(self, seed: Any = None) -> tuple[np.ndarray, dict]:
        return self._obs, {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        return self._obs, self._zeros, self._false, self._false, {}

    def close(self) -> None:
        pass


def sb3_rate(n_envs: int, samples: int, noop: bool, threads: int) -> float:
    import torch
    from stable_baselines3 import PPO

    from sdc_gym.envs.sb3 import SB3VecEnv

    torch.set_num_threads(threads)
    if noop:
        from bench_batched import NullVecEnv  # SB3's own cost: bench_batched's ceiling

        vec = NullVecEnv(n_envs)
    else:
        vec = SB3VecEnv(ENV_ID, n_envs)
    hyper = ppo_settings(n_envs)
    model = PPO("MlpPolicy", vec, seed=0, verbose=0, device="cpu", **hyper)
    rollout = n_envs * hyper["n_steps"]
    model.learn(rollout)  # warm-up rollout and update
    started = time.perf_counter()
    model.learn(samples, reset_num_timesteps=False)
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
        layers: list[nn.Module] = []
        size = n_obs
        for w in width:
            layers += [nn.Linear(size, w), nn.Tanh()]
            size = w
        return nn.Sequential(*layers, nn.Linear(size, out))

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


CASES = {
    "sb3": (sb3_rate, False), "sb3-noop": (sb3_rate, True),
    "torchrl": (torchrl_rate, False), "torchrl-noop": (torchrl_rate, True),
    "rllib": (rllib_rate, False),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, default=64, help="envs in the batch (E)")
    parser.add_argument("--samples", type=int, default=65_536, help="samples timed per case")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1, help="torch threads per case")
    parser.add_argument("--cases", default=None,
                        help=f"comma-separated, of {', '.join(CASES)} (default: sb3, "
                             "sb3-noop, and torchrl, torchrl-noop when torchrl imports)")
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
        args.cases = "sb3,sb3-noop" + (",torchrl,torchrl-noop" if have_torchrl else "")
        if not have_torchrl:
            print("torchrl is not installed (not a project dependency): its cases are left "
                  "out; see --cases")
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    for case in cases:
        if case not in CASES:
            parser.error(f"--cases: unknown case {case!r}; choices: {', '.join(CASES)}")
    missing = [case for case in cases if case.startswith("torchrl")] \
        if not have_torchrl else []
    if missing:  # not among the project's dependencies: a benchmark-only comparison
        parser.error(f"--cases {','.join(missing)}: needs torchrl, which the project does "
                     "not install (pip install --no-deps torchrl==0.14.1 tensordict==0.15.3 "
                     "pyvers, into a separate --target on PYTHONPATH, keeps torch 2.13.0), "
                     "or leave them out: --cases sb3,sb3-noop,rllib")
    warnings.filterwarnings("ignore")
    hyper = ppo_settings(args.envs)
    print(f"{ENV_ID}, E={args.envs}, PPO: n_steps={hyper['n_steps']} per env "
          f"({hyper['n_steps'] * args.envs} per rollout), batch_size={hyper['batch_size']}, "
          f"n_epochs={hyper['n_epochs']}, net_arch={hyper['policy_kwargs']['net_arch']}; "
          f"{args.samples:,} samples per case, torch threads {args.threads}")
    rates: dict[str, list[float]] = {case: [] for case in cases}
    for round_ in range(args.rounds):
        for case in cases:
            fn, noop = CASES[case]
            rates[case].append(fn(args.envs, args.samples, noop, args.threads))
            print(f"  round {round_ + 1} {case}: {rates[case][-1]:,.0f} samples/s", flush=True)
    base = statistics.median(rates["sb3"]) if "sb3" in rates else None
    print(f"\n{'learner':<14}{'min':>10}{'median':>10}{'max':>10}{'x sb3':>8}")
    for case, values in rates.items():
        med = statistics.median(values)
        ratio = f"{med / base:.2f}" if base else "-"
        print(f"{case:<14}{min(values):>10,.0f}{med:>10,.0f}{max(values):>10,.0f}{ratio:>8}")


if __name__ == "__main__":
    main()
