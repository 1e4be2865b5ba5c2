"""What a highway world keeps per env for scenarios, road events and ``stop_at_incident``.

:class:`EpisodeSettings` is the world's one object for them (``world.episodes``): it reads
the config keys ``scenario``, ``road_events`` and ``stop_at_incident``, sizes the traffic's
object slots, and per env holds the episode's scenario, its judge, its length and whether
it stopped at an incident. The world calls it at a few points only:

* :meth:`EpisodeSettings.reset` at each reset (``True``: a scenario started the env; else
  the world lays out random traffic and calls :meth:`EpisodeSettings.random_started`);
* :meth:`EpisodeSettings.record` after each step's incidents (the judges follow the
  episode; returns the envs that stop at an incident);
* :meth:`EpisodeSettings.reason`, :meth:`EpisodeSettings.is_success` and
  :meth:`EpisodeSettings.summary` at the episode's end.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.config import ConfigError
from sdc_gym.scenarios import episode as scenario_episode
from sdc_gym.scenarios.model import Scenario
from sdc_gym.scenarios.runtime import ScenarioJudge
from sdc_gym.traffic.road_events import RoadEventRates, RoadEvents
from sdc_gym.traffic.vehicle_types import KINDS
from sdc_gym.validation.env_configs import stop_kinds
from sdc_gym.validation.scenarios import load_scenario

CONFIG = scenario_episode.CONFIG


class EpisodeSettings:
    """Per env: scenario, judge, length, stop at incident (see the module docstring)."""

    def __init__(self, cfg: dict[str, Any], owner: str, road: Any, car_count: int,
                 envs: int, as_tuple: Any = tuple) -> None:
        self.config_map = cfg["map"]
        self.road = road
        self.car_count = car_count
        self.default_duration = float(cfg["max_duration"])
        try:
            self.rates = RoadEventRates(**{k: as_tuple(v)
                                           for k, v in cfg["road_events"].items()})
            self.scenario: Scenario | None = (load_scenario(cfg["scenario"])
                                              if cfg["scenario"] is not None else None)
        except (TypeError, ValueError) as error:
            raise ConfigError(f"{owner}: config key 'scenario': {error}") from None
        # A scenario of the config sizes the object slots (never the car slots: those are
        # the traffic's car_count, which random episodes fill).
        self.object_slots = self.rates.object_slots
        if self.scenario is not None:
            self.object_slots = max(self.object_slots, self.scenario.objects_needed)
            scenario_episode.check_fits(self.scenario, car_count, self.object_slots, road,
                                        self.config_map)
        self.stop_kinds = stop_kinds(cfg["stop_at_incident"])
        self.max_duration = np.full(envs, self.default_duration)
        self.scenarios: list[Scenario | None] = [None] * envs
        self.judges: list[ScenarioJudge | None] = [None] * envs
        self.stopped = np.zeros(envs, dtype=bool)
        self.collided_with: list[str | None] = [None] * envs
        self._judged: set[int] = set()  # the envs running a scenario

    # ------------------------------------------------------------------ resets
    def reset(self, world: Any, env: int, rng: np.random.Generator, scenario: Any) -> bool:
        """Env ``env``'s reset with ``scenario`` (:data:`CONFIG`: the config's; ``None``:
        random traffic; a path, mapping or :class:`Scenario`); ``True`` when a scenario
        started it (the world then skips its random layout)."""
        if scenario is CONFIG:
            scenario = self.scenario
        elif scenario is not None:
            scenario = load_scenario(scenario)
            scenario_episode.check_fits(scenario, self.car_count, world.traffic.object_slots,
                                        self.road, self.config_map)
        self.scenarios[env] = scenario
        self.judges[env] = None
        self.stopped[env] = False
        self.collided_with[env] = None
        self.max_duration[env] = self.default_duration
        self._judged.discard(env)
        if scenario is None:
            return False
        world.rngs[env] = rng
        scenario_episode.start(world, env, rng, scenario, self.rates)
        self.judges[env] = ScenarioJudge(scenario, self.road.lane_width, self.road.lane_count)
        self.max_duration[env] = scenario.duration
        self._judged.add(env)
        return True

    def random_started(self, world: Any, env: int, rng: np.random.Generator) -> None:
        """After a random layout: the random road events (or none) in the object slots."""
        if world.traffic.object_slots:
            world.traffic.controllers[env] = RoadEvents(self.rates, rng)

    # ------------------------------------------------------------------ steps
    def record(self, world: Any, incidents: list[Any], d: NDArray[np.float64]
               ) -> NDArray[np.bool_]:
        """One step's incidents per env (``d``: the ego's d at the step's end): what each
        collision hit, the judges, the stops; the envs stopped at an incident. Random
        traffic without ``stop_at_incident`` costs one test."""
        if not self._judged and not self.stop_kinds:
            return self.stopped
        time = world.metrics.time()
        for env, new in enumerate(incidents):
            if not new and env not in self._judged:
                continue
            for incident in new:
                if incident.kind == "collision" and self.collided_with[env] is None:
                    self.collided_with[env] = self.kind_of(world, env, int(incident.value))
                if incident.kind in self.stop_kinds:
                    self.stopped[env] = True
            judge = self.judges[env]
            if judge is not None:
                judge.update(float(time[env]), float(d[env]), new, self.collided_with[env])
        return self.stopped

    def kind_of(self, world: Any, env: int, slot: int) -> str:
        """The kind (``"car"``, ``"bus"``, ``"cargo"``, ...) in traffic slot ``slot``."""
        if not 0 <= slot < world.traffic.state.cars:
            return "unknown"
        return KINDS[int(world.traffic.state.type_index[env, slot])].name

    # ------------------------------------------------------------------ endings
    def reason(self, env: int) -> str | None:
        """The end's reason of a stop or a scenario (``None``: the world's own)."""
        if self.stopped[env]:
            return "stop_at_incident"
        if self.scenarios[env] is not None:
            return "scenario_end"
        return None

    def is_success(self, world: Any, env: int) -> bool | None:
        """A scenario's verdict (``None``: no scenario, the world's laps rule)."""
        judge = self.judges[env]
        if judge is None:
            return None
        return judge.verdict(float(world.metrics.distance[env])).passed

    def summary(self, world: Any, env: int) -> dict[str, Any] | None:
        """``summary["scenario"]``: name, source, passed and the reason (or ``None``)."""
        judge, scenario = self.judges[env], self.scenarios[env]
        if judge is None or scenario is None:
            return None
        return judge.verdict(float(world.metrics.distance[env])).as_dict(scenario)

    def road_events(self, world: Any, env: int) -> list[dict[str, Any]]:
        """The road events on env ``env``'s road (``info["road_events"]``)."""
        controller = world.traffic.controllers[env]
        if not isinstance(controller, RoadEvents):
            return []
        return controller.records(self.road.length)
