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

from sdc_gym.scenarios.library import LIBRARY, library_path, library_scenarios
from sdc_gym.scenarios.model import Scenario
from sdc_gym.validation.scenarios import check_scenario, load_scenario

__all__ = ["LIBRARY", "Scenario", "check_scenario", "library_path", "library_scenarios",
           "load_scenario"]
