"""The highway-env adapter: world models of placed vehicles, the decision -> meta-action
mapping in constructed situations, and a whole highway-fast-v0 episode."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
import yaml
from highway_env.vehicle.behavior import IDMVehicle

from sdc_agents.highway_env_adapter import (
    FASTER,
    IDLE,
    LANE_LEFT,
    LANE_RIGHT,
    SLOWER,
    HighwayEnvPolicyAgent,
    highway_env_policy_agent,
    meta_action,
    world_model_from_highway_env,
)
from sdc_gym.stack.highway.behavior import BehaviorDecision
from sdc_gym.stack.highway.decisions import ACTION_NAMES
from sdc_gym.stack.highway.features import BehaviorFeatures
from sdc_gym.stack.highway.shield import SafetyShield

EGO_X = 100.0
LEFT_HOLD = ACTION_NAMES.index("left/hold")
KEEP_HOLD = ACTION_NAMES.index("keep/hold")
KEEP_CRUISE = ACTION_NAMES.index("keep/cruise")


class FixedPolicy:
    """A stand-in for an SB3 model: always the same ``Discrete(9)`` decision."""

    def __init__(self, index: int) -> None:
        self.index = index
        self.observations: list[np.ndarray] = []

    def predict(self, observation: np.ndarray, deterministic: bool = True):
        self.observations.append(observation)
        return np.int64(self.index), None


@pytest.fixture()
def env():
    import highway_env  # noqa: F401

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        environment = gym.make("highway-fast-v0", config={"lanes_count": 3,
                                                          "vehicles_count": 3,
                                                          "duration": 8})
        environment.reset(seed=0)
    yield environment
    environment.close()


def place(env, ego_lane: int, ego_speed: float, others, ego_lateral: float = 0.0):
    """Replace highway-env's scene: the ego at ``EGO_X`` in ``ego_lane`` and ``others``
    as ``(lane, x, speed[, heading])`` IDM cars."""
    unwrapped = env.unwrapped
    road = unwrapped.road
    lane = road.network.get_lane(("0", "1", ego_lane))
    ego = unwrapped.action_type.vehicle_class(road, lane.position(EGO_X, ego_lateral), 0.0,
                                              ego_speed)
    unwrapped.vehicle = ego
    road.vehicles = [ego]
    for lane_id, x, speed, *heading in others:
        position = road.network.get_lane(("0", "1", lane_id)).position(x, 0.0)
        road.vehicles.append(IDMVehicle(road, position, heading[0] if heading else 0.0, speed))
    return ego


def test_world_model_of_placed_vehicles(env):
    place(env, 1, 25.0, [
        (1, 130.0, 20.0),       # 1: lead, 30 m ahead
        (1, 160.0, 22.0),       # 2: further ahead, hidden by the lead
        (1, 60.0, 24.0),        # 3: 40 m behind
        (0, 100.0, 21.0),       # 4: alongside on the left: gap 0 counts as ahead
        (2, 350.0, 23.0),       # 5: 250 m ahead: beyond the 200 m range
        (2, 80.0, 30.0, 0.1),   # 6: 20 m behind, heading 0.1 rad to the right
    ], ego_lateral=0.5)
    world = world_model_from_highway_env(env, 3.0)
    assert (world.time, world.lane_count, world.lane_width) == (3.0, 3, 4.0)
    assert (world.ego_lane, world.ego_s, world.ego_d, world.ego_speed) == (1, 100.0, 6.5, 25.0)
    assert world.ego_offset == pytest.approx(0.5)
    assert math.isinf(world.road_radius)
    left, middle, right = world.lanes
    assert (left.ahead_gap, left.ahead_speed, left.ahead_id) == (0.0, 21.0, 4)
    assert not left.has_behind and math.isinf(left.behind_gap)
    assert (middle.ahead_gap, middle.ahead_speed, middle.ahead_id) == (30.0, 20.0, 1)
    assert (middle.behind_gap, middle.behind_speed, middle.behind_id) == (40.0, 24.0, 3)
    assert not right.has_ahead and math.isinf(right.ahead_gap)
    assert right.behind_id == 6 and right.behind_gap == pytest.approx(20.0)
    assert right.behind_speed == pytest.approx(30.0 * math.cos(0.1), rel=1e-12)
    assert world.preferred_lane == 2  # the only lane with nobody ahead in range
    assert [car.id for car in world.cars] == [1, 2, 3, 4, 5, 6]
    far, slanted = world.cars[4], world.cars[5]
    assert (far.lane, far.gap, far.d) == (2, 250.0, 10.0)
    assert slanted.d_rate == pytest.approx(30.0 * math.sin(0.1), rel=1e-12)


def test_preferred_lane_ties_go_to_the_middle_then_the_ego(env):
    place(env, 2, 25.0, [(0, 150.0, 20.0)])
    assert world_model_from_highway_env(env, 0.0).preferred_lane == 1  # lanes 1, 2 empty
    place(env, 2, 25.0, [(1, 150.0, 20.0)])
    assert world_model_from_highway_env(env, 0.0).preferred_lane == 2  # lanes 0, 2 empty


def agent_for(index: int) -> HighwayEnvPolicyAgent:
    return HighwayEnvPolicyAgent(FixedPolicy(index), shield=SafetyShield(), lane_count=3)


# The ego starts at 20 m/s (highway-env's lowest set-point): our speed moves are capped at
# the 22.3 m/s cruise speed, so from its 25 m/s start every one of them asks for SLOWER.


def test_left_move_into_a_clear_lane_is_lane_left(env):
    place(env, 1, 20.0, [(1, 200.0, 20.0)])
    agent = agent_for(LEFT_HOLD)
    assert agent.act(env) == LANE_LEFT
    assert agent.last.plan.target_lane == 0 and agent.executor.changing
    # highway-env now steers to lane 0; the change under way is not commanded again
    # (a second LANE_LEFT would aim at the lane beyond).
    env.unwrapped.vehicle.target_lane_index = ("0", "1", 0)
    agent.model.index = KEEP_HOLD
    assert agent.act(env) == IDLE


def test_shield_refuses_a_left_move_with_a_car_alongside(env):
    place(env, 1, 20.0, [(0, 102.0, 20.0)])
    agent = agent_for(LEFT_HOLD)
    action = agent.act(env)
    assert action != LANE_LEFT and action == IDLE  # hold: 20 m/s is the set-point
    assert agent.executor.refused == 1 and agent.last.plan.target_lane == 1
    unshielded = HighwayEnvPolicyAgent(FixedPolicy(LEFT_HOLD), shield=None, lane_count=3)
    assert unshielded.act(env) == LANE_LEFT  # without the shield it goes


def test_slow_lead_close_ahead_is_slower(env):
    place(env, 1, 25.0, [(1, 115.0, 15.0)])
    agent = agent_for(KEEP_HOLD)
    assert agent.act(env) == SLOWER
    assert agent.last.plan.target_speed < 25.0 - 2.5 and agent.last.plan.replan
    place(env, 1, 25.0, [(1, 190.0, 25.0)])  # far ahead and as fast: hold, capped at cruise
    agent = agent_for(KEEP_HOLD)
    assert agent.act(env) == SLOWER and agent.last.plan.target_speed == pytest.approx(22.275)
    place(env, 1, 20.0, [(1, 190.0, 25.0)])
    agent = agent_for(KEEP_HOLD)
    assert agent.act(env) == IDLE


def test_meta_action_table():
    def plan(lane: int, speed: float) -> BehaviorDecision:
        return BehaviorDecision(target_lane=lane, target_speed=speed)

    assert meta_action(plan(0, 25.0), 1, 25.0, 5.0) == LANE_LEFT
    assert meta_action(plan(2, 25.0), 1, 25.0, 5.0) == LANE_RIGHT
    assert meta_action(plan(1, 25.0), 0, 25.0, 5.0) == LANE_RIGHT  # an abort goes back
    assert meta_action(plan(1, 22.275), 1, 25.0, 5.0) == SLOWER    # cruise rounds to 20
    assert meta_action(plan(1, 22.275), 1, 20.0, 5.0) == IDLE
    assert meta_action(plan(1, 22.6), 1, 25.0, 5.0) == IDLE        # within half a step
    assert meta_action(plan(1, 22.275), 1, 15.0, 5.0) == FASTER


def test_observation_shape_mismatch_is_a_clear_error():
    model = FixedPolicy(KEEP_CRUISE)
    model.observation_space = BehaviorFeatures(3).space
    with pytest.raises(ValueError, match="lanes_count"):
        HighwayEnvPolicyAgent(model, lane_count=4)


def test_episode_end_to_end_is_deterministic(env):
    def episode() -> tuple[list[int], bool]:
        agent = agent_for(KEEP_CRUISE)
        env.reset(seed=3)
        actions, done = [], False
        while not done:
            actions.append(agent.act(env))
            _, _, terminated, truncated, _ = env.step(actions[-1])
            done = terminated or truncated
        assert agent.executor.lane_changes == 0
        return actions, terminated

    actions, terminated = episode()
    assert 1 <= len(actions) <= 8  # duration 8 s, one meta-action per second
    assert set(actions) <= {IDLE, FASTER, SLOWER}  # keep never asks for a lane
    assert actions[0] == SLOWER  # cruise (22.3 m/s) from the 25 m/s start: down to 20
    assert episode() == (actions, terminated)


def test_factory_reads_the_training_config(tmp_path, monkeypatch):
    loaded = []

    def fake_load(kind, path):  # SB3's loading is policy_agent's (tested with evaluate.py)
        loaded.append((kind, path))
        return FixedPolicy(KEEP_CRUISE)

    monkeypatch.setattr("sdc_agents.highway_env_adapter.load_model", fake_load)
    model_path = tmp_path / "policy.zip"
    agent = highway_env_policy_agent("ppo", model_path)  # no YAML: the env's defaults
    assert agent.executor.shield is not None and agent.name == "ppo:policy"
    assert loaded == [("ppo", model_path)]
    (tmp_path / "policy.yaml").write_text(yaml.safe_dump({
        "env": "sdc_gym/HighwayLoopBehavior-v0",
        "config": {"safety_shield": False, "slow_step_mps": 3.0, "action": "continuous"}}))
    agent = highway_env_policy_agent("ppo", model_path)
    assert agent.executor.shield is None and agent.executor.slow_step_mps == 3.0
    assert agent.action == "continuous"
    (tmp_path / "policy.yaml").write_text(yaml.safe_dump({"env": "sdc_gym/TrackLoop-v0"}))
    with pytest.raises(ValueError, match="HighwayLoopBehavior-v0"):
        highway_env_policy_agent("ppo", model_path)
