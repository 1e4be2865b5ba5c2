"""PufferLib's PPO trainer (``PuffeRL``, pufferlib-core 3.0.23) as a case of
``bench_learners.py``: the native batch wrapped as one ``PufferEnv``, the advantage kernel
PufferLib's CPU build lacks here ported to numba, and the import's side effects undone.

Kept apart from ``bench_learners.py`` (which imports it lazily) so that the common cases do
not carry PufferLib's plumbing; pufferlib is not a project dependency.
"""

from __future__ import annotations

import importlib.util
import logging
import signal
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from learner_settings import ENV_ID, NoopVecEnv, ppo_settings, tanh_mlp


def puff_advantage(values: np.ndarray, rewards: np.ndarray, dones: np.ndarray,
                   importance: np.ndarray, advantages: np.ndarray, gamma: float,
                   lam: float, rho_clip: float, c_clip: float) -> None:
    """PufferLib's advantage (GAE with V-trace clipping of the importance ratio), in place,
    over ``[segments, horizon]`` float32 arrays: the C++ CPU kernel
    ``compute_puff_advantage_cpu`` of pufferlib-core 3.0.23 (``extensions/pufferlib.cpp``),
    whose compiled form needs CUDA. Per row, backwards from ``horizon - 2``:
    ``delta = rho_t (r[t+1] + gamma v[t+1] (1 - d[t+1]) - v[t])`` and
    ``a[t] = delta + gamma lam c_t a[t+1] (1 - d[t+1])`` with ``rho_t = min(w[t], rho_clip)``,
    ``c_t = min(w[t], c_clip)``; the last column is left as given. float32 throughout, as
    the C++."""
    _puff_advantage_kernel()(values, rewards, dones, importance, advantages,
                             np.float32(gamma), np.float32(lam), np.float32(rho_clip),
                             np.float32(c_clip))


_KERNEL: list[Any] = []


def _puff_advantage_kernel() -> Any:
    if not _KERNEL:
        import numba

        @numba.njit(cache=False)
        def kernel(values, rewards, dones, importance, advantages, gamma, lam, rho_clip,
                   c_clip):  # pragma: no cover - compiled
            one = np.float32(1.0)
            for row in range(values.shape[0]):
                last = np.float32(0.0)
                for t in range(values.shape[1] - 2, -1, -1):
                    nonterminal = one - dones[row, t + 1]
                    rho = min(importance[row, t], rho_clip)
                    c = min(importance[row, t], c_clip)
                    delta = rho * (rewards[row, t + 1] + gamma * values[row, t + 1]
                                   * nonterminal - values[row, t])
                    last = delta + gamma * lam * c * last * nonterminal
                    advantages[row, t] = last

        _KERNEL.append(kernel)
    return _KERNEL[0]


_PUFFER_LIBRARY: list[Any] = []

COLLECTION_SHARE: dict[tuple[bool, int, int], list[float]] = {}
"""PuffeRL's ``evaluate()`` (env, policy forward, copies) as a share of the timed wall, per
(noop, workers, kernel_threads) and round; the rest is ``train()``, the update."""


def import_pufferl() -> Any:
    """``pufferlib.pufferl`` with its PPO advantage op available on CPU (see the module
    docstring), and the process settings its import changes put back: it turns every
    RuntimeWarning into an error and makes Ctrl-C exit the process on the spot."""
    import torch

    handler = signal.getsignal(signal.SIGINT)
    log = logging.getLogger("pufferlib")
    level = log.level
    log.setLevel(logging.ERROR)  # its "no _C: a pure-PyTorch fallback" is the op below
    with warnings.catch_warnings():
        import pufferlib.pufferl as pufferl
    signal.signal(signal.SIGINT, handler)
    log.setLevel(level)
    if not pufferl._C_AVAILABLE and not _PUFFER_LIBRARY:
        library = torch.library.Library("pufferlib", "DEF")
        library.define("compute_puff_advantage(Tensor(a!) values, Tensor(b!) rewards, "
                       "Tensor(c!) dones, Tensor(d!) importance, Tensor(e!) advantages, "
                       "float gamma, float lambda, float rho_clip, float c_clip) -> ()")

        def compute(values, rewards, dones, importance, advantages, gamma, lam, rho_clip,
                    c_clip) -> None:
            # detach: PuffeRL passes the live ratio (the C++ reads its data pointer alike)
            puff_advantage(*(t.detach().numpy() for t in (values, rewards, dones,
                                                          importance, advantages)),
                           gamma, lam, rho_clip, c_clip)

        library.impl("compute_puff_advantage", compute, "CPU")
        _PUFFER_LIBRARY.append(library)  # the registration lives as long as the object
    pufferl._C_AVAILABLE = True
    return pufferl


def puffer_env(n_envs: int, noop: bool, buf: Any = None, seed: int = 0,
               kernel_threads: int = 1) -> Any:
    """The batch as one native ``PufferEnv`` of ``n_envs`` agents: the env writes each
    step's arrays into PufferLib's buffers (shared memory in a worker process), ends reset
    within the step (SAME_STEP: the next episode's first observation, the ended one's
    reward and flag), no infos (PuffeRL only averages them into its dashboard)."""
    import pufferlib
    from gymnasium.vector import AutoresetMode

    from sdc_gym.envs.highway_vector import HighwayLoopBehaviorVectorEnv

    class HighwayPufferEnv(pufferlib.PufferEnv):
        def __init__(self) -> None:
            config = {"highway": {"kernel_threads": kernel_threads}} \
                if kernel_threads > 1 else None
            self.vector = NoopVecEnv(n_envs) if noop else HighwayLoopBehaviorVectorEnv(
                n_envs, config, autoreset_mode=AutoresetMode.SAME_STEP)
            self.single_observation_space = self.vector.single_observation_space
            self.single_action_space = self.vector.single_action_space
            self.num_agents = n_envs
            super().__init__(buf)

        def reset(self, seed: Any = None) -> tuple[np.ndarray, list]:
            obs, _ = self.vector.reset(seed=seed)
            self.observations[:] = obs
            return self.observations, []

        def step(self, actions: Any) -> tuple[np.ndarray, ...]:
            obs, reward, terminated, truncated, _ = self.vector.step(actions)
            self.observations[:] = obs
            self.rewards[:] = reward
            self.terminals[:] = terminated
            self.truncations[:] = truncated
            return self.observations, self.rewards, self.terminals, self.truncations, []

        def close(self) -> None:
            self.vector.close()

    return HighwayPufferEnv()


def pufferlib_rate(n_envs: int, samples: int, noop: bool, threads: int,
                   workers: int = 0, kernel_threads: int = 1) -> float:
    """PufferLib's PPO trainer (``PuffeRL``: ``evaluate()`` fills ``batch_size`` samples,
    ``train()`` runs ``update_epochs x batch_size / minibatch_size`` minibatch steps) with
    the project's hyperparameters, the policy SB3's MlpPolicy's shape (separate 64 x 64
    tanh actor and critic). ``workers`` 0: the batch in this process (PufferLib's native
    vectorization); 2: ``pufferlib.vector.Multiprocessing``, two processes of E / 2 envs,
    the trainer taking one worker's half while the other steps. ``kernel_threads``: the
    env's (in this process only)."""
    import tempfile

    import pufferlib.vector
    import torch
    from torch import nn

    pufferl = import_pufferl()
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    hyper = ppo_settings(n_envs)
    if workers:
        if n_envs % workers:
            raise SystemExit(f"pufferlib-pool: E = {n_envs} must divide into {workers} workers")
        vecenv = pufferlib.vector.make(
            lambda buf=None, seed=0: puffer_env(n_envs // workers, noop, buf, seed),
            backend=pufferlib.vector.Multiprocessing, num_envs=workers,
            num_workers=workers, batch_size=1)
    else:
        vecenv = pufferlib.vector.make(
            lambda: puffer_env(n_envs, noop, kernel_threads=kernel_threads))
    width = hyper["policy_kwargs"]["net_arch"]
    n_obs = int(np.prod(vecenv.single_observation_space.shape))
    n_act = int(vecenv.single_action_space.n)

    def mlp(out: int) -> nn.Sequential:
        return tanh_mlp(n_obs, width, out)

    class Policy(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.actor, self.critic = mlp(n_act), mlp(1)

        def forward_eval(self, obs: Any, state: Any = None) -> tuple[Any, Any]:
            obs = obs.float()
            return self.actor(obs), self.critic(obs)

        forward = forward_eval

    class Trainer(pufferl.PuffeRL):
        def print_dashboard(self, *args: Any, **kwargs: Any) -> None:
            pass  # a full-screen rich dashboard, redrawn every update

    rollout = n_envs * hyper["n_steps"]
    config = {
        "env": ENV_ID, "seed": 0, "torch_deterministic": False, "device": "cpu",
        "cpu_offload": False, "use_rnn": False, "compile": False, "compile_mode": None,
        "compile_fullgraph": False, "precision": "float32", "optimizer": "adam",
        "batch_size": rollout, "bptt_horizon": hyper["n_steps"],
        "minibatch_size": hyper["batch_size"], "max_minibatch_size": hyper["batch_size"],
        "update_epochs": hyper["n_epochs"], "learning_rate": hyper["learning_rate"],
        "adam_beta1": 0.9, "adam_beta2": 0.999, "adam_eps": 1e-5, "anneal_lr": False,
        "gamma": hyper["gamma"], "gae_lambda": hyper["gae_lambda"],
        "clip_coef": hyper["clip_range"], "vf_clip_coef": 1e9, "vf_coef": 0.5,
        "ent_coef": hyper["ent_coef"], "max_grad_norm": 0.5,
        "prio_alpha": 0.0, "prio_beta0": 1.0,  # uniform minibatches, as SB3's
        "vtrace_rho_clip": 1.0, "vtrace_c_clip": 1.0,
        "total_timesteps": 1 << 40, "checkpoint_interval": 1 << 30,
        "data_dir": tempfile.gettempdir(),
    }
    trainer = Trainer(config, vecenv, Policy())
    try:
        trainer.evaluate()  # warm-up rollout and update
        trainer.train()
        started = time.perf_counter()
        done_samples = 0
        collecting = 0.0
        while done_samples < samples:
            tick = time.perf_counter()
            trainer.evaluate()
            collecting += time.perf_counter() - tick
            trainer.train()
            done_samples += rollout
        wall = time.perf_counter() - started
        COLLECTION_SHARE.setdefault((noop, workers, kernel_threads), []).append(
            collecting / wall)
    finally:
        trainer.utilization.stop()
        vecenv.close()
    return done_samples / wall


def puffer_importable() -> bool:
    """Whether PufferLib's trainer imports; if not, the reason in ``.reason``."""
    if importlib.util.find_spec("pufferlib") is None:
        puffer_importable.reason = ("pufferlib is not installed (not a project dependency; "
                                    "pip install --no-deps pufferlib-core==3.0.23 psutil "
                                    "pyro-ppl pyro-api opt_einsum rich_argparse)")
        return False
    try:
        import_pufferl()
    except ImportError as error:
        puffer_importable.reason = f"pufferlib.pufferl does not import: {error}"
        return False
    return True


puffer_importable.reason = ""
