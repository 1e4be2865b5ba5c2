"""The highway behavior layer's decisions, shield and features on constructed worlds."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sdc_gym.stack.highway.behavior import MAX_BRAKING, NORMAL_ACCELERATION
from sdc_gym.stack.highway.decisions import (
    ACTION_NAMES,
    CRUISE_SPEED_MPS,
    DecisionExecutor,
    HighwayDecision,
)
from sdc_gym.stack.highway.features import BehaviorFeatures
from sdc_gym.stack.highway.shield import SafetyShield
from sdc_gym.stack.highway.world_model import LaneView, TrackedCar, WorldModel

WIDTH = 4.0


def world(lanes: dict[int, dict[str, float]] | None = None, *, ego_lane: int = 1,
          speed: float = 20.0, radius: float = math.inf, d: float | None = None,
          time: float = 10.0) -> WorldModel:
    """A three-lane world; ``lanes`` gives LaneView fields per lane (ids made up)."""
    views = []
    for lane in range(3):
        fields = dict((lanes or {}).get(lane, {}))
        if "ahead_gap" in fields:
            fields.setdefault("ahead_id", 10 + lane)
        if "behind_gap" in fields:
            fields.setdefault("behind_id", 20 + lane)
        views.append(LaneView(lane, **fields))
    ego_d = (ego_lane + 0.5) * WIDTH if d is None else d
    return WorldModel(time=time, ego_s=500.0, ego_d=ego_d, ego_speed=speed, ego_lane=ego_lane,
                      lane_count=3, lane_width=WIDTH, lanes=tuple(views), cars=(),
                      preferred_lane=1, road_radius=radius)


def seed_curve_percent(gap: float) -> float:
    """p(d) of the seed, written out: (13.67303 / 0.08660915)(1 - e^(-0.08660915 d)) - 55.76378."""
    return (13.67303 / 0.08660915) * (1.0 - math.exp(-0.08660915 * gap)) - 55.76378


def test_discrete_actions_decode_as_documented():
    assert ACTION_NAMES[3] == "keep/cruise" and len(ACTION_NAMES) == 9
    assert HighwayDecision.from_index(0) == HighwayDecision(-1, "cruise")
    assert HighwayDecision.from_index(8) == HighwayDecision(1, "slow")
    assert HighwayDecision.from_index(np.int64(4)) == HighwayDecision(0, "hold")
    for bad in (9, -1, 2.0, True, "3"):
        with pytest.raises(ValueError, match=r"Discrete\(9\) action|out of range"):
            HighwayDecision.from_index(bad)


def test_continuous_actions_decode_lane_thirds_and_speed_range():
    assert HighwayDecision.from_vector([-0.5, 1.0]).lane_move == -1
    assert HighwayDecision.from_vector([0.3, 1.0]).lane_move == 0
    assert HighwayDecision.from_vector([0.4, -1.0]) == HighwayDecision(1, "target", 0.0)
    assert HighwayDecision.from_vector([0.0, 0.0]).target_speed == pytest.approx(
        0.5 * CRUISE_SPEED_MPS)
    for bad in ([np.nan, 0.0], [0.0, 1.5], [0.0]):
        with pytest.raises(ValueError):
            HighwayDecision.from_vector(bad)


def test_following_caps_speed_by_the_seed_braking_curve():
    shield = SafetyShield()
    # Inside the 30 m range: p(d) x lead speed; p(20 m) = 74.2 % < 80 %: hard braking.
    limit = shield.speed_limit(world({1: {"ahead_gap": 20.0, "ahead_speed": 18.0}}), 1)
    assert limit.speed == pytest.approx(seed_curve_percent(20.0) / 100 * 18.0)
    assert seed_curve_percent(20.0) == pytest.approx(74.18, abs=0.01)
    assert limit.hard and limit.acceleration == MAX_BRAKING
    # Beyond it: p(30) u + 1/s x (gap - 30), continuous at the edge, no hard braking.
    limit = shield.speed_limit(world({1: {"ahead_gap": 60.0, "ahead_speed": 15.0}}), 1)
    assert limit.speed == pytest.approx(seed_curve_percent(30.0) / 100 * 15.0 + 30.0)
    assert not limit.hard and limit.acceleration == NORMAL_ACCELERATION
    assert math.isinf(shield.speed_limit(world(), 1).speed)
    # While changing to lane 2, a nearer car ahead there is the lead.
    both = world({1: {"ahead_gap": 80.0, "ahead_speed": 20.0},
                  2: {"ahead_gap": 35.0, "ahead_speed": 10.0}})
    assert shield.lead(both, 2) == (35.0, 10.0) and shield.lead(both, 1) == (80.0, 20.0)


def test_lane_change_rules_known_cases():
    shield = SafetyShield()
    assert shield.lane_change_allowed(world(), 0) and shield.lane_change_allowed(world(), 2)
    assert not shield.lane_change_allowed(world(ego_lane=0), -1)
    # Behind in the target lane: 11 m minimum; a car 5 m/s faster needs 3 x 5 + 11 = 26 m.
    assert not shield.lane_change_allowed(world({0: {"behind_gap": 10.0,
                                                     "behind_speed": 20.0}}), 0)
    assert not shield.lane_change_allowed(world({0: {"behind_gap": 25.0,
                                                     "behind_speed": 25.0}}), 0)
    assert shield.lane_change_allowed(world({0: {"behind_gap": 27.0, "behind_speed": 25.0}}), 0)
    # Ahead: 20 m plus 3 s of closing speed (ego 20 m/s on a car at 15: 35 m).
    assert not shield.lane_change_allowed(world({2: {"ahead_gap": 34.0,
                                                     "ahead_speed": 15.0}}), 2)
    assert shield.lane_change_allowed(world({2: {"ahead_gap": 36.0, "ahead_speed": 15.0}}), 2)
    # The seed's bend rule, and a far-lane car within 20 m when merging to the middle.
    assert not shield.lane_change_allowed(world(radius=400.0), 0)
    assert shield.lane_change_allowed(world(radius=600.0), 0)
    assert not shield.lane_change_allowed(world({2: {"ahead_gap": 15.0, "ahead_speed": 20.0}},
                                                ego_lane=0), 1)


def test_executor_refuses_unsafe_moves_and_aborts_when_the_gap_closes():
    executor = DecisionExecutor(SafetyShield())
    blocked = world({0: {"behind_gap": 8.0, "behind_speed": 20.0}})
    plan = executor.execute(blocked, HighwayDecision(-1))
    assert plan.target_lane == 1 and executor.refused == 1 and not executor.changing
    plan = executor.execute(world(), HighwayDecision(-1))
    assert plan.target_lane == 0 and executor.changing and executor.lane_changes == 1
    # A second move is ignored while the change is under way.
    assert executor.execute(world(d=5.0), HighwayDecision(1)).target_lane == 0
    # A car appears 5 m ahead in the target lane while the ego is still near its lane.
    plan = executor.execute(world({0: {"ahead_gap": 5.0, "ahead_speed": 20.0}}, d=5.5),
                            HighwayDecision(0))
    assert plan.target_lane == 1 and executor.aborted == 1
    # Back within 0.5 m of the middle lane's centre: the change is over.
    executor.execute(world(d=6.2), HighwayDecision(0))
    assert not executor.changing


def test_executor_speed_moves_and_no_shield():
    executor = DecisionExecutor(None, slow_step_mps=2.0)
    lead = world({1: {"ahead_gap": 10.0, "ahead_speed": 5.0}})
    assert executor.execute(lead, HighwayDecision(0, "cruise")).target_speed == CRUISE_SPEED_MPS
    assert executor.execute(lead, HighwayDecision(0, "hold")).target_speed == 20.0
    assert executor.execute(lead, HighwayDecision(0, "slow")).target_speed == 18.0
    # Without a shield a move into an occupied lane is carried out.
    plan = executor.execute(world({0: {"behind_gap": 2.0, "behind_speed": 20.0}}),
                            HighwayDecision(-1))
    assert plan.target_lane == 0 and executor.refused == 0
    # With it, the cruise target is capped behind the slow lead.
    shielded = DecisionExecutor(SafetyShield())
    assert shielded.execute(lead, HighwayDecision(0, "cruise")).target_speed < 5.0


def test_features_of_a_constructed_world():
    features = BehaviorFeatures(3, sensing_range_m=200.0)
    executor = DecisionExecutor(SafetyShield())
    model = world({0: {"ahead_gap": 50.0, "ahead_speed": 25.0},
                   2: {"behind_gap": 8.0, "behind_speed": 22.0}}, radius=250.0, speed=11.1375)
    executor.execute(model, HighwayDecision(0))
    x = features.encode(model, executor)
    names = features.names()
    assert x.shape == (25,) == features.space.shape and features.space.contains(x)
    value = dict(zip(names, x.tolist(), strict=True))
    assert value["speed"] == pytest.approx(0.5)
    assert value["ego_lane_1"] == 1.0 and value["target_lane_1"] == 1.0
    assert value["curvature"] == pytest.approx(1.0)  # 500 / 250, clipped
    assert value["lane_0_ahead_gap"] == pytest.approx(0.25)
    assert value["lane_0_ahead_speed"] == pytest.approx((25.0 - 11.1375) / CRUISE_SPEED_MPS)
    assert value["lane_1_ahead_gap"] == 1.0 and value["lane_1_ahead_speed"] == 0.0
    assert value["lane_2_behind_gap"] == pytest.approx(0.04)
    # The bend forbids lane changes: neither move is allowed.
    assert value["allowed_left"] == 0.0 and value["allowed_right"] == 0.0
    assert value["since_change"] == 1.0  # 10 s since the start, clipped


def test_extended_features_see_the_second_car_and_the_lead_s_intent():
    """observation "extended": per lane the second car ahead (gap and relative speed) and
    the lateral rate of the lane's car ahead, computed from the world model's cars."""
    features = BehaviorFeatures(3, sensing_range_m=200.0, extended=True)
    executor = DecisionExecutor(SafetyShield())
    base = world({0: {"ahead_gap": 50.0, "ahead_speed": 25.0},
                  1: {"ahead_gap": 30.0, "ahead_speed": 18.0},
                  2: {"behind_gap": 8.0, "behind_speed": 22.0}}, speed=20.0)
    cars = (
        TrackedCar(10, 550.0, 2.0, 25.0, 1.0, 0, 50.0),     # lane 0's car ahead, moving right
        TrackedCar(11, 620.0, 2.0, 15.0, 0.0, 0, 120.0),    # lane 0's second car
        TrackedCar(12, 900.0, 2.0, 30.0, 0.0, 0, 400.0),    # beyond the sensing range
        TrackedCar(13, 480.0, 2.0, 30.0, 0.0, 0, -20.0),    # behind: never "ahead"
        TrackedCar(14, 530.0, 6.0, 18.0, -3.0, 1, 30.0),    # lane 1's car ahead, moving left
        TrackedCar(22, 492.0, 10.0, 22.0, 0.0, 2, -8.0),    # lane 2's car behind
    )
    model = dataclasses.replace(base, cars=cars, lanes=(
        dataclasses.replace(base.lanes[0], ahead_id=10),
        dataclasses.replace(base.lanes[1], ahead_id=14), base.lanes[2]))
    executor.execute(model, HighwayDecision(0))
    x = features.encode(model, executor)
    names = features.names()
    assert x.shape == (34,) == features.space.shape and features.space.contains(x)
    value = dict(zip(names, x.tolist(), strict=True))
    assert value["lane_0_second_gap"] == pytest.approx(120.0 / 200.0)
    assert value["lane_0_second_speed"] == pytest.approx((15.0 - 20.0) / CRUISE_SPEED_MPS)
    assert value["lane_0_ahead_lateral"] == pytest.approx(0.5)
    # Lane 1: one car ahead, none beyond it; its lead moves left at 3 m/s (clipped to -1).
    assert value["lane_1_second_gap"] == 1.0 and value["lane_1_second_speed"] == 0.0
    assert value["lane_1_ahead_lateral"] == -1.0
    # Lane 2: nobody ahead at all.
    assert (value["lane_2_second_gap"], value["lane_2_ahead_lateral"]) == (1.0, 0.0)
    # The first 25 entries are the nearest observation's, unchanged.
    nearest = BehaviorFeatures(3, sensing_range_m=200.0).encode(model, executor)
    np.testing.assert_array_equal(x[:25], nearest)
