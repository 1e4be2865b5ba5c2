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
import typing
from typing import Any

from sdc_gym.config import ConfigError
from sdc_gym.validation.rules import Number, Rule, check_finite, check_value, is_real
from sdc_gym.validation.run_config import matches

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


RULES: dict[str, Rule] = {
    "lr": Number(0.0, 1.0, low_open=True),
    "gamma": Number(0.0, 1.0),
    "lambda_": Number(0.0, 1.0),
    "tau": Number(0.0, 1.0),
    "clip_param": Number(0.0, low_open=True),
    "vf_clip_param": Number(0.0, low_open=True),
    "vf_loss_coeff": Number(0.0),
    "entropy_coeff": Number(0.0),
    "kl_coeff": Number(0.0),
    "grad_clip": Number(0.0, low_open=True, optional=True),
    "train_batch_size_per_learner": Number(1, 10**7, integer=True),
    "train_batch_size": Number(1, 10**7, integer=True),
    "minibatch_size": Number(1, 10**7, integer=True),
    "num_epochs": Number(1, 10**4, integer=True),
    "target_network_update_freq": Number(0, integer=True),
    "num_steps_sampled_before_learning_starts": Number(0, integer=True),
    "training_intensity": Number(0.0, low_open=True, optional=True),
    "n_step": Number(1, 10**4, integer=True),
    "env_runners.num_envs_per_env_runner": Number(1, 1024, integer=True),
    "env_runners.rollout_fragment_length": Number(1, 10**7, integer=True),
    "reporting.min_sample_timesteps_per_iteration": Number(0, integer=True),
    "reporting.metrics_num_episodes_for_smoothing": Number(1, integer=True),
}
"""Ranges of the common hyperparameters (a learning rate as a schedule is a list: its
type is RLlib's annotation's, its values RLlib's ``validate()``'s)."""

DEPRECATED = -1
"""The default RLlib gives the deprecated arguments of its config methods."""


def _keyword_hints(cls: type, method: str) -> dict[str, list[Any]]:
    """The keyword arguments of ``cls.method`` and of the methods it passes ``**kwargs``
    on to (the same method of its base classes), less the deprecated ones, each with its
    annotations (one per class that declares it: DQN's ``grad_clip`` says ``int``, the
    base class's ``float``)."""
    hints: dict[str, list[Any]] = {}
    for klass in cls.__mro__:
        if method in vars(klass):
            for name, parameter in inspect.signature(vars(klass)[method]).parameters.items():
                if (parameter.kind is inspect.Parameter.KEYWORD_ONLY
                        and not (isinstance(parameter.default, int)
                                 and parameter.default == DEPRECATED)):
                    hints.setdefault(name, []).append(
                        Any if parameter.annotation is inspect.Parameter.empty
                        else parameter.annotation)
    return hints


def valid_keys(algo: str) -> dict[str, dict[str, list[Any]]]:
    """The keys a hyperparameter entry of ``algo`` may have, each with its annotations:
    ``"training"`` (top level) and those of each of :data:`SECTIONS`."""
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    cls = config_class(algo)
    model_hints = typing.get_type_hints(DefaultModelConfig)
    runners = _keyword_hints(cls, "env_runners")
    runners.pop("num_env_runners", None)  # train.py's n_envs
    return {"training": _keyword_hints(cls, "training"),
            "model": {field.name: [model_hints.get(field.name, Any)]
                      for field in dataclasses.fields(DefaultModelConfig)},
            "env_runners": runners,
            "reporting": _keyword_hints(cls, "reporting")}


def _describe(hints: list[Any]) -> str:
    return " or ".join(str(hint).replace("typing.", "").replace("<class '", "")
                       .replace("'>", "") for hint in hints)


def _check_value(algo: str, key: str, value: Any, hints: list[Any], where: str) -> None:
    """``value`` of the annotated type (of one of ``hints``) and in :data:`RULES`."""
    if not any(matches(value, hint) for hint in hints):
        raise ConfigError(f"{where}: hyperparameter {key!r} of rllib {algo} must be "
                          f"{_describe(hints)}, got {value!r} ({type(value).__name__})")
    if key in RULES and (is_real(value) or value is None):
        check_value(RULES[key], value, where, key)


def check_hyperparams(algo: str, hyper: dict[str, Any], where: str,
                      placeholders: frozenset[str] = frozenset()) -> None:
    """:class:`~sdc_gym.config.ConfigError` naming the first unknown key of ``hyper`` and
    the valid ones, or the first value of the wrong type (against RLlib's annotations), out
    of :data:`RULES`' range, or not finite. Dotted ``placeholders`` (a sweep's searched
    keys) are checked by name only."""
    keys = valid_keys(algo)
    for name, value in hyper.items():
        if name in SECTIONS:
            if not isinstance(value, dict):
                raise ConfigError(f"{where}: {name} must be a mapping, got {value!r}")
            unknown = set(value) - set(keys[name])
            if unknown:
                raise ConfigError(f"{where}: unknown {name} keys {sorted(unknown)}; valid: "
                                  f"{sorted(keys[name])}")
            for key, item in value.items():
                if f"{name}.{key}" not in placeholders:
                    _check_value(algo, f"{name}.{key}", item, keys[name][key], where)
        elif name not in keys["training"]:
            raise ConfigError(f"{where}: {name!r} is not an argument of "
                              f"{config_class(algo).__name__}.training(); valid: "
                              f"{sorted(keys['training'])}, or the sections {list(SECTIONS)}")
        elif name not in placeholders:
            _check_value(algo, name, value, keys["training"][name], where)
    check_finite(hyper, where)


def algorithm_config(config: dict[str, Any], hyper: dict[str, Any] | None = None) -> Any:
    """The ``AlgorithmConfig`` of a resolved run config (train.py's ``config.yaml``).

    ``hyper`` replaces ``config["hyperparams"]`` (a Tune sweep puts its search space there:
    the values may be Tune domains). The driving metrics are logged by
    :class:`sdc_training.rllib_callbacks.DrivingMetricsCallback`.
    """
    from sdc_training.rllib_callbacks import DrivingMetricsCallback

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


def search_candidates(distribution: dict[str, list[Any]]) -> list[Any]:
    """Values a sweep's distribution gives, to check before any trial: every value of a
    ``choice`` or ``grid_search``, the bounds of the others."""
    (name, arguments), = distribution.items()
    if name in ("choice", "grid_search"):
        return list(arguments)
    if name == "randint" and len(arguments) >= 2 and isinstance(arguments[1], int):
        return [arguments[0], arguments[1] - 1]  # Tune's randint excludes its upper bound
    return list(arguments[:2])


def check_run_config(config: dict[str, Any], where: str = "") -> None:
    """:class:`~sdc_gym.config.ConfigError` for an unknown or bad hyperparameter of the
    run (every value its sweep's search space can give too), and for what RLlib's own
    ``AlgorithmConfig.validate()`` refuses (``minibatch_size`` above the train batch, a
    malformed schedule, ...), before any cluster starts."""
    hyper = config["hyperparams"]
    where = f"{where}{' ' if where else ''}(hyperparameters of rllib {config['algo']} for " \
            f"{config['env']})"
    space = (config.get("tune") or {}).get("search_space") or {}
    keys = frozenset(space)
    check_hyperparams(config["algo"], with_keys(hyper, keys), where, placeholders=keys)
    for key, distribution in space.items():
        for value in search_candidates(distribution):
            check_hyperparams(config["algo"], with_keys(hyper, [key], value),
                              f"{where} (the sweep's search_space.{key})",
                              placeholders=keys - {key})
    sample = with_keys(hyper, keys, lambda key: search_candidates(space[key])[0])
    try:
        algorithm_config(config, sample).validate()
    except ValueError as error:
        raise ConfigError(f"{where}: RLlib refuses the config: "
                          f"{str(error).strip().splitlines()[0]}") from None
