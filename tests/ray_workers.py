"""Functions the Ray tests run in Ray workers: a fault-injecting episode and probes of
env registration in a fresh worker process.

The tests send this module by value (``cloudpickle.register_pickle_by_value``), so a
worker unpickling a probe imports only what the probe itself names: a probe that names
nothing of sdc_gym finds the package not imported, as in RLlib's env runners.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import gymnasium as gym

from sdc_evaluation.episodes import EpisodeSpec, ProgressCallback, run_episode

BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
PROBE_CONFIG = {"highway": {"max_duration": 5.0}}
PROBE_SEED = 7

DIES_ON_SEED = 1
"""The seed whose worker process exits in the middle of its episode."""


def die_on_seed(spec: EpisodeSpec, progress: ProgressCallback) -> dict[str, Any]:
    """:func:`run_episode`, except that the worker of seed :data:`DIES_ON_SEED` exits
    (``os._exit``: no exception, no clean-up, as a killed process) after its first
    progress report."""
    if spec.seed != DIES_ON_SEED:
        return run_episode(spec, progress)

    def report_then_die(laps: float, info: dict[str, Any]) -> None:
        progress(laps, info)
        os._exit(3)

    return run_episode(spec, report_then_die)


def plain_id() -> tuple[bool, str]:
    """Whether sdc_gym was imported, and what ``gym.make`` of the plain id does."""
    had_package = "sdc_gym" in sys.modules
    try:
        gym.make(BEHAVIOR)
    except gym.error.NamespaceNotFound as error:
        return had_package, f"NamespaceNotFound: {error}"
    return had_package, "made"


def prefixed_id() -> Any:
    """The first observation of the env made by the ``"sdc_gym:"``-prefixed id."""
    env = gym.make(f"sdc_gym:{BEHAVIOR}", config=PROBE_CONFIG)
    return env.reset(seed=PROBE_SEED)[0]


def registered_creator() -> tuple[bool, Any]:
    """Whether sdc_gym was imported, and the first observation of the env that Ray's
    registry creates (what RLlib's env runners call)."""
    from ray.tune.registry import ENV_CREATOR, _global_registry

    had_package = "sdc_gym" in sys.modules
    env = _global_registry.get(ENV_CREATOR, BEHAVIOR)(PROBE_CONFIG)
    return had_package, env.reset(seed=PROBE_SEED)[0]
