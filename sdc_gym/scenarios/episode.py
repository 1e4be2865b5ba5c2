"""Starting an env of a highway world from a scenario (the world's ``reset_at`` with one).

:func:`start` puts the ego where the scenario says (on the path it would be driving if it
moves: :func:`~sdc_gym.scenarios.runtime.ego_path`, or a replay's recorded path and paths
in flight), lays out the traffic slots (:func:`~sdc_gym.scenarios.runtime.scenario_slots`),
hands the traffic the scenario's script as the env's controller, and restarts the metrics
at the ego's speed (:mod:`sdc_gym.scenarios.world_episodes` sets the episode's length and
judge). A replay's recorded traffic clock
and generator state are restored, so that the traffic continues as it did.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Final

import numpy as np

from sdc_gym.config import ConfigError
from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.scenarios.model import Scenario
from sdc_gym.scenarios.placement_checks import check_lanes, check_placements
from sdc_gym.scenarios.runtime import ScenarioScript, ego_path, scenario_slots
from sdc_gym.traffic.road_events import RoadEventRates


class _ConfigScenario:
    """The type of :data:`CONFIG`: one instance, which copies and pickles as itself (an
    ``object()`` sentinel would not: a deep-copied env would hold a stranger that its own
    reset no longer recognises)."""

    def __reduce__(self) -> str:
        return "CONFIG"  # copy and pickle: the module's global of that name

    def __repr__(self) -> str:
        return "CONFIG"


CONFIG: Final = _ConfigScenario()
"""``reset_at``'s default scenario: the one of the env's config (or none)."""


def same_map(scenario_map: str, config_map: str) -> bool:
    """Whether a scenario's ``map`` names the env's map (a built-in name, or a file:
    the same file)."""
    if scenario_map == config_map:
        return True
    first, second = Path(scenario_map), Path(config_map)
    return first.is_file() and second.is_file() and first.resolve() == second.resolve()


def check_fits(scenario: Scenario, car_slots: int, object_slots: int, road: HighwayMap,
               config_map: str) -> None:
    """The scenario is for this env's map and fits its slots (else a ConfigError naming
    the file, the line and the config key to change)."""
    if scenario.map is not None and not same_map(scenario.map, config_map):
        raise ConfigError(f"{scenario.at('map')}: scenario {scenario.name!r} is for map "
                          f"{scenario.map!r}; the env has map {config_map!r} (set the "
                          "env's 'map' config key)")
    check_lanes(scenario, road.lane_count)
    scenario_slots(scenario, car_slots, object_slots, 0.0, road.lane_count, road.lane_width,
                   road.length, 0.02)


def start(world: Any, env: int, rng: np.random.Generator, scenario: Scenario,
          rates: RoadEventRates) -> None:
    """Start env ``env`` of ``world`` (a :class:`~sdc_gym.envs.highway_world.HighwayWorld`)
    from ``scenario``; the env's randomness from ``rng``, random road events at ``rates``
    on top of the scenario's."""
    road: HighwayMap = world.road
    reference = road.reference
    replay = scenario.replay
    if replay is not None and replay.generator_state is not None:
        _restore_generator(rng, replay.generator_state, scenario)
    ego = scenario.ego
    s = float(reference.wrap_s(ego.s if ego.s is not None else world.start_s))
    if ego.lane is not None:
        d = float(road.lane_center(ego.lane))
        if not 0 <= ego.lane < road.lane_count:
            raise ConfigError(f"{scenario.at('ego.lane')}: scenario key 'ego.lane' must be a "
                              f"lane of the map, 0 to {road.lane_count - 1}, got {ego.lane}")
    else:
        d = float(ego.d if ego.d is not None else world.start_d)
    speed = float(ego.speed)
    check_placements(scenario, road, s, d, world.ego_length)  # before any state changes
    if ego.x is not None:
        xy = np.array([ego.x, ego.y], dtype=np.float64)
        yaw = float(ego.yaw)  # type: ignore[arg-type]
    else:
        xy = reference.to_xy(s, d).astype(np.float64).reshape(2)
        yaw = float(reference.heading(s))
    follower = world.ego
    follower.reset_at(env, xy, yaw)
    path = (np.asarray(ego.path, dtype=np.float64).reshape(-1, 2) if ego.path is not None
            else ego_path(reference, s, d, speed, world.path_points, world.traffic.dt))
    count = min(len(path), world.path_points)
    follower.path[env, :count] = path[:count]
    follower.path_length[env] = count
    follower.path_start[env] = 0
    for due, points in ego.in_flight:  # a replay's paths sent but not yet arrived
        sent = np.asarray(points, dtype=np.float64).reshape(-1, 2)[:world.path_points]
        slot = (follower.queue_head[env] + follower.queue_count[env]) % follower.queue.shape[1]
        follower.queue[env, slot, :len(sent)] = sent
        follower.queue_length[env, slot] = len(sent)
        follower.queue_due[env, slot] = follower.frame[env] + due
        follower.queue_count[env] += 1
    world.s[env], world.d[env], world.speed[env] = s, d, speed
    world.end_sd[env] = _end_of_path(reference, path[:count], s)
    start_step = replay.traffic_step if replay is not None else 0
    specs, events = scenario_slots(scenario, world.car_count, world.traffic.object_slots, s,
                                   road.lane_count, road.lane_width, road.length,
                                   world.traffic.dt)
    script = ScenarioScript(scenario, events, rates, rng, start_step)
    world.traffic.reset_slots_at(
        env, rng, s, d, speed, specs, step=start_step,
        respawn_blocked_steps=replay.respawn_blocked_steps if replay is not None else 0,
        controller=script)
    world.sensors.reset_at(env)
    world.metrics.reset_at(env, float(xy[0]), float(xy[1]), s, d, speed)
    world.collided[env] = False
    world.done_reason[env] = ""
    world.read_sensors(np.array([env]))


def _end_of_path(reference: Any, path: np.ndarray, s: float) -> np.ndarray:
    """Frenet s, d of a path's last point (0, 0 for no path), as the observation has it."""
    if not len(path):
        return np.zeros(2)
    last = path[-1]
    guess = s + float(np.hypot(*(path[-1] - path[0]))) + 1.0
    end_s, end_d = reference.project(np.array([last[0]]), np.array([last[1]]),
                                     np.array([guess]))
    return np.array([float(end_s[0]), float(end_d[0])])


def _restore_generator(rng: np.random.Generator, state: dict[str, Any],
                       scenario: Scenario) -> None:
    """A replay continues the recorded random stream (respawns, rogue moments)."""
    expected = type(rng.bit_generator).__name__
    if state.get("bit_generator") != expected:
        raise ConfigError(f"{scenario.at('replay.generator_state')}: scenario key "
                          f"'replay.generator_state' is a {state.get('bit_generator')!r} "
                          f"state; the env's generator is a {expected}")
    try:
        rng.bit_generator.state = state
    except (TypeError, ValueError, KeyError) as error:
        raise ConfigError(f"{scenario.at('replay.generator_state')}: scenario key "
                          f"'replay.generator_state' is not a valid {expected} state "
                          f"({error})") from None
