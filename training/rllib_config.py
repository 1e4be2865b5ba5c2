"""An RLlib ``AlgorithmConfig`` from train.py's run config (RLlib's new API stack).

The hyperparameters come from ``configs/hyperparams/rllib_<algo>.yaml`` keyed by env id,
as the SB3 ones do, with the same ``--hp key=value`` overrides. An entry's keys are:

* arguments of the algorithm's ``AlgorithmConfig.training()`` (``lr``, ``gamma``,
  ``train_batch_size_per_learner``, ``minibatch_size``, ``num_epochs``, ...);
* ``model``: the RLModule's model config (``DefaultModelConfig`` fields:
  ``fcnet_hiddens``, ``fcnet_activation``, ``vf_share_layers``, ...);
* ``env_runners``: arguments of ``AlgorithmConfig.env_runners()``
  (``num_envs_per_env_runner``, ``rollout_fragment_length``, ...);
* ``reporting``: arguments of ``AlgorithmConfig.reporting()``
  (``min_sample_timesteps_per_iteration``: DQN's iterations sample at least 1000 env steps
  by default, and checkpoints and evaluations fall between iterations;
  ``metrics_num_episodes_for_smoothing``, ...);
* ``n_envs`` and ``timesteps``, the run's defaults (train.py pops them).

``n_envs`` is the number of env processes, as for SB3: 1 samples in the learner's own
process (``num_env_runners=0``), N > 1 in N EnvRunner actors (one CPU each), anywhere on
the cluster. The learner runs in the driver (``num_learners=0``). An unknown key is an
error naming it and the valid ones.
"""

from __future__ import annotations

import dataclasses
import inspect
from typing import Any

ALGORITHMS = ("ppo", "dqn")
"""RLlib algorithms offered by ``train.py --framework rllib``."""
SECTIONS = ("model", "env_runners", "reporting")
"""Keys of a hyperparameter entry that are mappings for other parts of the config."""


def config_class(algo: str) -> type:
    """The ``AlgorithmConfig`` class of ``algo``."""
    if algo == "ppo":
        from ray.rllib.algorithms.ppo import PPOConfig

        return PPOConfig
    if algo == "dqn":
        from ray.rllib.algorithms.dqn import DQNConfig

        return DQNConfig
    raise ValueError(f"unknown RLlib algorithm {algo!r}; valid: {list(ALGORITHMS)}")


DEPRECATED = -1
"""The default RLlib gives the deprecated arguments of its config methods."""


def _keyword_names(cls: type, method: str) -> set[str]:
    """The keyword arguments of ``cls.method`` and of the methods it passes ``**kwargs``
    on to (the same method of its base classes), less the deprecated ones."""
    names: set[str] = set()
    for klass in cls.__mro__:
        if method in vars(klass):
            names |= {name for name, parameter in
                      inspect.signature(vars(klass)[method]).parameters.items()
                      if parameter.kind is inspect.Parameter.KEYWORD_ONLY
                      and not (isinstance(parameter.default, int)
                               and parameter.default == DEPRECATED)}
    return names


def valid_keys(algo: str) -> dict[str, set[str]]:
    """The keys a hyperparameter entry of ``algo`` may have: ``"training"`` (top level)
    and those of each of :data:`SECTIONS`."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    cls = config_class(algo)
    return {"training": _keyword_names(cls, "training"),
            "model": {field.name for field in dataclasses.fields(DefaultModelConfig)},
            "env_runners": _keyword_names(cls, "env_runners") - {"num_env_runners"},
            "reporting": _keyword_names(cls, "reporting")}


def check_hyperparams(algo: str, hyper: dict[str, Any], where: str) -> None:
    """``ValueError`` naming the first unknown key of ``hyper`` and the valid ones."""
    keys = valid_keys(algo)
    for name, value in hyper.items():
        if name in SECTIONS:
            if not isinstance(value, dict):
                raise ValueError(f"{where}: {name} must be a mapping, got {value!r}")
            unknown = set(value) - keys[name]
            if unknown:
                raise ValueError(f"{where}: unknown {name} keys {sorted(unknown)}; valid: "
                                 f"{sorted(keys[name])}")
        elif name not in keys["training"]:
            raise ValueError(f"{where}: {name!r} is not an argument of "
                             f"{config_class(algo).__name__}.training(); valid: "
                             f"{sorted(keys['training'])}, or the sections {list(SECTIONS)}")


def algorithm_config(config: dict[str, Any], hyper: dict[str, Any] | None = None) -> Any:
    """The ``AlgorithmConfig`` of a resolved run config (train.py's ``config.yaml``).

    ``hyper`` replaces ``config["hyperparams"]`` (a Tune sweep puts its search space there:
    the values may be Tune domains). The driving metrics are logged by
    :class:`training.rllib_callbacks.DrivingMetricsCallback`.
    """
    from training.rllib_callbacks import DrivingMetricsCallback

    hyper = dict(config["hyperparams"] if hyper is None else hyper)
    model = dict(hyper.pop("model", None) or {})
    runners = dict(hyper.pop("env_runners", None) or {})
    reporting = dict(hyper.pop("reporting", None) or {})
    n_envs = int(config["n_envs"])
    return (config_class(config["algo"])()
            .environment(config["env"], env_config=dict(config["config"]))
            .framework("torch")
            .env_runners(num_env_runners=0 if n_envs == 1 else n_envs, **runners)
            .learners(num_learners=0)
            .rl_module(model_config=model)
            .training(**hyper)
            .reporting(**reporting)
            .callbacks(DrivingMetricsCallback)
            .debugging(seed=int(config["seed"])))


def with_keys(hyper: dict[str, Any], keys: Any, value: Any = None) -> dict[str, Any]:
    """``hyper`` with each (dotted: ``model.fcnet_hiddens``) key of ``keys`` set to
    ``value`` (a Tune sweep's search space: placeholders for the checks, domains for Tune)."""
    hyper = {name: (dict(item) if isinstance(item, dict) else item)
             for name, item in hyper.items()}
    for key in keys:
        *parents, last = key.split(".")
        node = hyper
        for part in parents:
            node[part] = dict(node.get(part) or {})
            node = node[part]
        node[last] = value(key) if callable(value) else value
    return hyper


def check_run_config(config: dict[str, Any]) -> None:
    """``ValueError`` for an unknown hyperparameter of the run (or of its sweep's search
    space), before any cluster starts."""
    hyper = config["hyperparams"]
    where = f"hyperparameters of rllib {config['algo']} for {config['env']}"
    if config.get("tune"):
        hyper = with_keys(hyper, config["tune"]["search_space"])
        where = f"{where} (with the sweep's search space)"
    check_hyperparams(config["algo"], hyper, where)
