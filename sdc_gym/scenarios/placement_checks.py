"""A scenario's placements checked against the road and each other when an env starts it:
the ego on the road, no two vehicles on the same spot of a lane, every lane a scenario
names (an action's target, a success condition's) a lane of the map.

Each error is a :class:`~sdc_gym.config.ConfigError` naming the scenario file, the line
and the key path. A car "overlaps" another when both are in the same lane and their
centres are closer than the sum of their half lengths (bumper to bumper or worse): a car
at ``gap: 0`` or ``gap: 2`` in the ego's lane, two cars at the same ``s``. A replay (its
cars' recorded states) is not checked for overlap: it starts from what an episode held.
"""

from __future__ import annotations

from typing import Any

from sdc_gym.config import ConfigError
from sdc_gym.scenarios.model import Scenario
from sdc_gym.traffic.vehicle_types import KIND_INDEX, VEHICLE_TYPES

LANE_ACTIONS = ("cut_in", "lane_change")
"""The scripted actions whose ``lane`` is a target lane of the map."""


def _lane_error(scenario: Scenario, path: str, lane: int, lanes: int) -> ConfigError:
    return ConfigError(f"{scenario.at(path)}: scenario key {path!r} must be a lane of the "
                       f"map, 0 to {lanes - 1}, got {lane}")


def check_lanes(scenario: Scenario, lanes: int) -> None:
    """Every lane the scenario's actions and success conditions name is on the map."""
    for index, action in enumerate(scenario.actions):
        if action.do in LANE_ACTIONS and action.lane is not None and not (
                0 <= action.lane < lanes):
            raise _lane_error(scenario, f"actions[{index}].lane", action.lane, lanes)
    success = scenario.success
    for key, lane in (("reach_lane", success.reach_lane and success.reach_lane[0]),
                      ("keep_lane", success.keep_lane and success.keep_lane[0]),
                      ("end_lane", success.end_lane)):
        if lane is not None and lane is not False and not 0 <= lane < lanes:
            raise _lane_error(scenario, f"success.{key}", int(lane), lanes)


def check_ego_on_road(scenario: Scenario, d: float, road_width: float) -> None:
    """The ego's ``d`` within the road, [0, lanes x lane width]."""
    if scenario.ego.d is not None and not 0.0 <= d <= road_width:
        raise ConfigError(f"{scenario.at('ego.d')}: scenario key 'ego.d' must be on the "
                          f"road, in [0, {road_width:g}] m right of the centre line, got {d:g}")


def check_overlaps(scenario: Scenario, ego_s: float, ego_lane: int, ego_length: float,
                   loop: float) -> None:
    """No car on the ego's spot or on another car's, in the same lane."""
    if scenario.replay is not None:
        return
    placed: list[tuple[str, int, float, float]] = [("the ego", ego_lane, ego_s,
                                                    0.5 * ego_length)]
    for index, car in enumerate(scenario.cars):
        s = (ego_s + car.gap if car.gap is not None else float(car.s or 0.0)) % loop
        half = 0.5 * VEHICLE_TYPES[KIND_INDEX[car.kind]].length
        path = f"cars[{index}]"
        for name, lane, other_s, other_half in placed:
            apart = abs((s - other_s + 0.5 * loop) % loop - 0.5 * loop)
            if lane == car.lane and apart < half + other_half:
                key = f"{path}.gap" if car.gap is not None else f"{path}.s"
                raise ConfigError(
                    f"{scenario.at(key)}: scenario car {path} ({car.name!r}, a {car.kind} in "
                    f"lane {car.lane} at s {s:.1f} m) overlaps {name} (s {other_s:.1f} m): "
                    f"their centres are {apart:.1f} m apart, less than the sum of their "
                    f"half lengths, {half + other_half:.1f} m")
        placed.append((f"cars[{index}] ({car.name!r})", car.lane, s, half))


def check_placements(scenario: Scenario, road: Any, ego_s: float, ego_d: float,
                     ego_length: float) -> None:
    """All of the above for a start at (``ego_s``, ``ego_d``) on ``road`` (a
    :class:`~sdc_gym.road.highway_map.HighwayMap`)."""
    check_lanes(scenario, road.lane_count)
    check_ego_on_road(scenario, ego_d, road.road_width)
    ego_lane = min(max(int(ego_d // road.lane_width), 0), road.lane_count - 1)
    for index, car in enumerate(scenario.cars):  # the lanes first: overlaps are by lane
        if not 0 <= car.lane < road.lane_count:
            raise _lane_error(scenario, f"cars[{index}].lane", car.lane, road.lane_count)
    check_overlaps(scenario, ego_s, ego_lane, ego_length, road.length)
