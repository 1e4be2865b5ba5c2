"""Scenarios: explicit starts, scripted traffic, road events and success conditions for the
highway envs, from YAML files (``docs/scenarios.md``), plus the library of the seed's
lane-change scenarios and stress cases, and replays of recorded incidents.

* :mod:`~sdc_gym.scenarios.model`: a scenario as data;
* :func:`load_scenario` (:mod:`sdc_gym.validation.scenarios`): a file or mapping, checked,
  with errors naming the line and key;
* :mod:`~sdc_gym.scenarios.runtime` and :mod:`~sdc_gym.scenarios.episode`: a scenario
  while it runs in an env (its start, its script, its verdict);
* :mod:`~sdc_gym.scenarios.library`: the packaged scenario files;
* :mod:`~sdc_gym.scenarios.replay`: an env's state as a scenario, an incident report as a
  scenario file.

Select one with ``gym.make(id, config={"scenario": PATH})`` or per episode with
``env.reset(options={"scenario": PATH_OR_MAPPING})``.
"""

from typing import Any

from sdc_gym.scenarios.library import LIBRARY, library_path, library_scenarios
from sdc_gym.scenarios.model import Scenario

_CHECKS = ("check_scenario", "load_scenario")


def __getattr__(name: str) -> Any:
    """``check_scenario`` and ``load_scenario`` from :mod:`sdc_gym.validation.scenarios`,
    imported on first use: that module imports :mod:`sdc_gym.scenarios.model` (and so this
    package), and an eager import here made ``import sdc_gym.validation.scenarios`` a
    circular ImportError when it was the first to be imported."""
    if name in _CHECKS:
        from sdc_gym.validation import scenarios

        return getattr(scenarios, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["LIBRARY", "Scenario", "check_scenario", "library_path", "library_scenarios",
           "load_scenario"]
