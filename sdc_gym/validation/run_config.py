"""train.py's run config: every value checked, hyperparameters against the algorithm.

A run config (YAML, ``train.py --config``) has the keys of :data:`RUN_RULES` plus ``env``
(a registered id) and ``config`` (its env config, a mapping); ``eval`` is a mapping with
the keys of :data:`EVAL_DEFAULTS`, ``validation`` and ``averaging`` (optional) ones with
the keys of :data:`VALIDATION_DEFAULTS` and :data:`AVERAGING_DEFAULTS`. Hyperparameters
(``configs/hyperparams/<algo>.yaml`` and ``--hp KEY=VALUE``) must be parameters of the
stable-baselines3 algorithm's constructor, of the type its annotation says (a float where
it takes ``float | Schedule``: YAML cannot give a function), finite, and in range for the
common ones (:data:`HYPERPARAM_RULES`). Errors are :class:`~sdc_gym.config.ConfigError` naming the
key, the value and what is valid.
"""

from __future__ import annotations

import collections.abc
import inspect
import sys
import types
import typing
from collections.abc import Mapping
from typing import Any, Final

from sdc_gym.config import ConfigError, excerpt
from sdc_gym.validation.rules import Choice, Number, Rule, check_finite, check_value, is_real

ALGORITHMS: Final = ("ppo", "dqn", "qrdqn", "sac", "a2c")
OFF_POLICY_ALGORITHMS: Final = ("dqn", "qrdqn", "sac")
"""The algorithms with a replay buffer (checkpointed beside the model)."""
EVAL_DEFAULTS: Final = {"every": 50_000, "episodes": 4, "seed": 10_000}
VALIDATION_DEFAULTS: Final = {"every": 0, "episodes": 40, "seed": 2000}
"""One lap per validation seed every ``every`` env steps (0: never), as one batch
(``sdc_training.validation_laps``): model selection apart from the held-out seeds."""
AVERAGING_DEFAULTS: Final = {"every": 0, "start": 0, "decay": None}
"""A running average of the policy's weights, a sample every ``every`` env steps (0: no
averaging) from ``start`` on; ``decay`` None: their uniform mean (SWA), else an
exponential one (``sdc_training.weight_averaging``)."""
SEED_LIMIT: Final = 2**32 - 1  # numpy's and SB3's seeds are 32-bit
MAX_N_ENVS: Final = 1024  # processes or a batch; memory and time bound it long before
MAX_TIMESTEPS: Final = 10**12
RUN_RULES: Final[dict[str, Rule]] = {
    "algo": Choice(ALGORITHMS),
    "timesteps": Number(1, MAX_TIMESTEPS, integer=True, unit="env steps"),
    "n_envs": Number(1, MAX_N_ENVS, integer=True, unit="parallel envs"),
    "seed": Number(0, SEED_LIMIT, integer=True),
    "checkpoint_every": Number(1, MAX_TIMESTEPS, integer=True, unit="env steps"),
    "eval.every": Number(0, MAX_TIMESTEPS, integer=True, unit="env steps; 0: no evaluation"),
    "eval.episodes": Number(1, 10_000, integer=True),
    "eval.seed": Number(0, SEED_LIMIT, integer=True, unit="the first held-out seed"),
    "validation.every": Number(0, MAX_TIMESTEPS, integer=True,
                               unit="env steps; 0: no validation"),
    "validation.episodes": Number(2, MAX_N_ENVS, integer=True,
                                  unit="laps, one batch; 2 at least for an interval"),
    "validation.seed": Number(0, SEED_LIMIT, integer=True, unit="the first validation seed"),
    "averaging.every": Number(0, MAX_TIMESTEPS, integer=True,
                              unit="env steps between samples; 0: no averaging"),
    "averaging.start": Number(0, MAX_TIMESTEPS, integer=True, unit="env steps"),
    "averaging.decay": Number(0.0, 1.0, low_open=True, high_open=True, optional=True,
                              unit="None: the uniform mean"),
}
HYPERPARAM_RULES: Final[dict[str, Rule]] = {
    "learning_rate": Number(0.0, 1.0, low_open=True),
    "gamma": Number(0.0, 1.0),
    "gae_lambda": Number(0.0, 1.0),
    "tau": Number(0.0, 1.0),
    "batch_size": Number(1, 10**7, integer=True),
    "n_steps": Number(1, 10**7, integer=True),
    "n_epochs": Number(1, 10**4, integer=True),
    "buffer_size": Number(1, 10**8, integer=True, why="the replay buffer is held in memory"),
    "learning_starts": Number(0, integer=True),
    "exploration_fraction": Number(0.0, 1.0),
    "exploration_initial_eps": Number(0.0, 1.0),
    "exploration_final_eps": Number(0.0, 1.0),
    "target_update_interval": Number(1, integer=True),
    "gradient_steps": Number(-1, integer=True, why="-1: as many as env steps"),
    "clip_range": Number(0.0, low_open=True),
    "vf_coef": Number(0.0),
    "max_grad_norm": Number(0.0, low_open=True),
}
NOT_HYPERPARAMETERS: Final = ("self", "env", "tensorboard_log", "seed", "verbose",
                              "_init_setup_model")
"""Constructor parameters train.py sets itself."""


def check_run_config(config: Mapping[str, Any], owner: str, registered: Any) -> None:
    """Check a resolved run config; ``registered(env_id)`` tells whether an id exists."""
    env_id = config.get("env")
    if not isinstance(env_id, str) or not registered(env_id):
        raise ConfigError(f"{owner}: config key 'env' must be a registered env id (e.g. "
                          f"sdc_gym/HighwayLoopBehavior-v0), got {excerpt(env_id)}")
    if not isinstance(config.get("config"), Mapping):
        raise ConfigError(f"{owner}: config key 'config' must be a mapping of {env_id} "
                          f"config keys, got {excerpt(config.get('config'))}")
    evaluation = config.get("eval")
    if not isinstance(evaluation, Mapping) or set(evaluation) - set(EVAL_DEFAULTS):
        raise ConfigError(f"{owner}: config key 'eval' must be a mapping with keys of "
                          f"{sorted(EVAL_DEFAULTS)}, got {excerpt(evaluation)}")
    validation = config.get("validation", VALIDATION_DEFAULTS)
    if not isinstance(validation, Mapping) or set(validation) - set(VALIDATION_DEFAULTS):
        raise ConfigError(f"{owner}: config key 'validation' must be a mapping with keys of "
                          f"{sorted(VALIDATION_DEFAULTS)}, got {excerpt(validation)}")
    averaging = config.get("averaging", AVERAGING_DEFAULTS)
    if not isinstance(averaging, Mapping) or set(averaging) - set(AVERAGING_DEFAULTS):
        raise ConfigError(f"{owner}: config key 'averaging' must be a mapping with keys of "
                          f"{sorted(AVERAGING_DEFAULTS)}, got {excerpt(averaging)}")
    for key, rule in RUN_RULES.items():
        section = key.partition(".")[0]
        if section in ("validation", "averaging") and section not in config:
            continue  # a run from before the key existed
        node: Any = config
        for part in key.split("."):
            node = node.get(part) if isinstance(node, Mapping) else None
        check_value(rule, node, owner, key)


def _hint(algorithm: type, name: str) -> Any:
    """The annotation of ``algorithm.__init__``'s parameter ``name`` (``Any`` if unknown)."""
    annotation = inspect.signature(algorithm.__init__).parameters[name].annotation
    if annotation is inspect.Parameter.empty:
        return Any
    if isinstance(annotation, str):  # postponed annotations: evaluate in SB3's module
        try:
            # SB3's own annotation text (never user input), in SB3's module namespace.
            return eval(annotation, vars(sys.modules[algorithm.__module__]))
        except Exception:  # a name only imported for type checking
            return Any
    return annotation


def matches(value: Any, hint: Any) -> bool:
    """Whether a YAML value (None, bool, int, float, str, list, dict) fits ``hint``."""
    origin = typing.get_origin(hint)
    if hint is Any:
        return True
    if origin in (typing.Union, types.UnionType):
        return any(matches(value, arg) for arg in typing.get_args(hint))
    if hint is None or hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return is_real(value)
    if hint is str:
        return isinstance(value, str)
    if origin is type or origin is collections.abc.Callable or hint is type:
        return False  # YAML gives no classes and no functions
    if origin is tuple:
        args = typing.get_args(hint)
        return (isinstance(value, list | tuple) and len(value) == len(args)
                and all(matches(item, arg) for item, arg in zip(value, args, strict=True)))
    if origin in (list, collections.abc.Sequence) or hint is list:
        return isinstance(value, list)
    if origin in (dict, collections.abc.Mapping) or hint is dict:
        return isinstance(value, dict)
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True  # a form we cannot judge: the algorithm checks it


def _describe(hint: Any) -> str:
    text = str(hint).replace("typing.", "").replace("collections.abc.Callable[[float], float]",
                                                      "Schedule")
    return text.replace("<class '", "").replace("'>", "")


def check_hyperparams(algorithm: type, hyperparams: Mapping[str, Any], owner: str) -> None:
    """Every hyperparameter a constructor parameter of ``algorithm``, of its annotated type,
    finite, and in :data:`HYPERPARAM_RULES`'s range."""
    parameters = [name for name in inspect.signature(algorithm.__init__).parameters
                  if name not in NOT_HYPERPARAMETERS]
    for key, value in hyperparams.items():
        if key not in parameters:
            raise ConfigError(f"{owner}: unknown hyperparameter {key!r} for "
                              f"{algorithm.__name__}; valid: {', '.join(parameters)}")
        hint = _hint(algorithm, key)
        if not matches(value, hint):
            raise ConfigError(f"{owner}: hyperparameter {key!r} of {algorithm.__name__} must "
                              f"be {_describe(hint)}, got {excerpt(value)} "
                              f"({type(value).__name__})")
        if key in HYPERPARAM_RULES and is_real(value):
            check_value(HYPERPARAM_RULES[key], value, owner, key)
    check_finite(dict(hyperparams), owner)
    if "policy_kwargs" in hyperparams and hyperparams["policy_kwargs"] is not None:
        check_policy_kwargs(hyperparams["policy_kwargs"], owner)


ACTIVATIONS: Final = {"relu": "ReLU", "tanh": "Tanh", "elu": "ELU", "leaky_relu": "LeakyReLU",
                      "selu": "SELU", "silu": "SiLU", "gelu": "GELU", "sigmoid": "Sigmoid"}
"""``policy_kwargs.activation_fn`` by name (``relu``, ``ReLU``, ``nn.ReLU`` or
``torch.nn.ReLU``: YAML gives a string, SB3 wants the ``torch.nn`` class)."""
MAX_LAYER_WIDTH: Final = 4_096
MAX_LAYERS: Final = 16
NET_ARCH_HEADS: Final = ("pi", "vf", "qf")


def activation_name(value: Any) -> str | None:
    """The ``torch.nn`` class name ``value`` names (see :data:`ACTIVATIONS`), or None."""
    if not isinstance(value, str):
        return None
    name = value.removeprefix("torch.").removeprefix("nn.")
    by_class = {cls.lower(): cls for cls in ACTIVATIONS.values()}
    return ACTIVATIONS.get(name.lower()) or by_class.get(name.lower())


def _layers_problem(value: Any) -> bool:
    return not (isinstance(value, list) and len(value) <= MAX_LAYERS and all(
        isinstance(width, int) and not isinstance(width, bool)
        and 1 <= width <= MAX_LAYER_WIDTH for width in value))


def check_policy_kwargs(policy_kwargs: Any, owner: str) -> None:
    """``activation_fn`` a name of :data:`ACTIVATIONS`; ``net_arch`` a list of at most
    :data:`MAX_LAYERS` layer widths in [1, :data:`MAX_LAYER_WIDTH`] (``[0]`` trained a
    zero-width layer) or a mapping of ``pi``/``vf``/``qf`` to such lists."""
    if not isinstance(policy_kwargs, Mapping):
        raise ConfigError(f"{owner}: hyperparameter 'policy_kwargs' must be a mapping, got "
                          f"{excerpt(policy_kwargs)}")
    if "activation_fn" in policy_kwargs and activation_name(
            policy_kwargs["activation_fn"]) is None:
        raise ConfigError(f"{owner}: hyperparameter 'policy_kwargs.activation_fn' must be one "
                          f"of {sorted(ACTIVATIONS)} (or the torch.nn class name, e.g. "
                          f"'torch.nn.ReLU'), got {excerpt(policy_kwargs['activation_fn'])}")
    if "net_arch" in policy_kwargs:
        arch = policy_kwargs["net_arch"]
        bad = (any(key not in NET_ARCH_HEADS or _layers_problem(layers)
                   for key, layers in arch.items()) if isinstance(arch, Mapping)
               else _layers_problem(arch))
        if bad:
            raise ConfigError(f"{owner}: hyperparameter 'policy_kwargs.net_arch' must be a "
                              f"list of at most {MAX_LAYERS} layer widths, each an int in "
                              f"[1, {MAX_LAYER_WIDTH}], or a mapping of {list(NET_ARCH_HEADS)}"
                              f" to such lists, got {excerpt(arch)}")


def resolved_policy_kwargs(hyperparams: Mapping[str, Any]) -> dict[str, Any]:
    """``hyperparams`` (checked) with ``policy_kwargs.activation_fn`` the ``torch.nn``
    class it names, as SB3 takes it (the run's config.yaml keeps the name)."""
    out = dict(hyperparams)
    kwargs = out.get("policy_kwargs")
    if isinstance(kwargs, Mapping) and "activation_fn" in kwargs:
        from torch import nn

        out["policy_kwargs"] = {**kwargs, "activation_fn": getattr(
            nn, activation_name(kwargs["activation_fn"]) or "")}
    return out


ACTION_SPACES: Final = {"ppo": ("Box", "Discrete", "MultiDiscrete", "MultiBinary"),
                        "a2c": ("Box", "Discrete", "MultiDiscrete", "MultiBinary"),
                        "dqn": ("Discrete",), "qrdqn": ("Discrete",), "sac": ("Box",)}
"""The action spaces each algorithm learns (stable-baselines3's and RLlib's alike)."""


def check_algorithm_space(algo: str, action_space: Any, env_id: str, owner: str) -> None:
    """``algo`` can learn ``env_id``'s ``action_space`` (``sac`` on a Discrete env raised
    SB3's AssertionError after the envs had started)."""
    kinds = ACTION_SPACES.get(algo)
    kind = type(action_space).__name__
    if kinds is not None and kind not in kinds:
        fits = [name for name, spaces in ACTION_SPACES.items() if kind in spaces]
        raise ConfigError(f"{owner}: algo {algo!r} learns {' or '.join(kinds)} actions; "
                          f"{env_id} has {kind} actions ({action_space}): use one of {fits}"
                          " (the behavior envs take config action: discrete or continuous)")
