"""A behavior policy trained on ``sdc_gym/HighwayLoopBehavior-v0`` driving highway-env.

highway-env (``highway-v0``, ``highway-fast-v0``) is the peer project: a straight
multi-lane highway with IDM/MOBIL traffic, driven through five *meta-actions*
(``DiscreteMetaAction``: LANE_LEFT 0, IDLE 1, LANE_RIGHT 2, FASTER 3, SLOWER 4). This module
runs one of our behavior policies there, to see how it transfers:

    highway-env state --world_model_from_highway_env--> WorldModel
        --BehaviorFeatures--> observation --model.predict--> HighwayDecision
        --DecisionExecutor (+ SafetyShield)--> BehaviorDecision --meta_action--> 0..4

The policy meets the same features and the same executor (lane-change state, the shield's
following cap and lane-change rules) as in training; only the motion layer differs:
highway-env's own ``MDPVehicle`` controllers execute the meta-action.

**The world model.** highway-env's lane 0 is the leftmost, as ours, and its lanes are 4 m
wide, so a car in lane ``k`` at lateral offset ``y`` (m, + to the right) from its lane's
centre has ``d = (k + 0.5) x 4 + y``. ``s`` is the longitudinal coordinate along the
ego's lane; gaps are centre to centre (as our perception gives them) to the nearest car
ahead and behind in each lane within the sensing range (200 m); speeds are
``vehicle.speed`` projected on the lane direction. The road is straight: ``road_radius``
is ``inf``. ``time`` is highway-env's clock (``env.unwrapped.time``).

**The mapping** (:func:`meta_action`), one meta-action per highway-env step:

1. the executor's target lane differs from the lane highway-env is steering to
   (``vehicle.target_lane_index``): a change was started (or aborted, which sends it back)
   -> LANE_LEFT / LANE_RIGHT toward it. The comparison is with highway-env's *target* lane,
   not the lane the ego is in: its lane commands are relative to its target lane, so
   repeating LANE_LEFT while the ego is still crossing over would aim one lane further;
2. otherwise the executed target speed ``u`` against highway-env's ``vehicle.target_speed``
   ``w``: ``u < w - step / 2`` -> SLOWER, ``u > w + step / 2`` -> FASTER, else IDLE, with
   ``step`` the spacing of its target speeds.

**Limits of the mapping** (why a transferred policy is not the same driver):

* highway-env's target speeds are discrete, 20 / 25 / 30 m/s by default: our cruise speed
  (22.275 m/s, the seed's 49.83 mph) rounds to 20 m/s, ``slow`` (2 m/s below the current
  speed) is less than half a step and becomes IDLE, and the ego cannot drive slower than
  20 m/s behind a slower lead: the shield's following cap then only asks for SLOWER,
  which is already the floor. Its FASTER / SLOWER move one step from the speed the car
  *has* (not the one it aims at).
* One meta-action per step: a step that starts a lane change leaves the speed set-point as
  it was; and highway-env decides once per policy period (1 s on highway-fast-v0) where
  the policy was trained to decide every 0.24 s, so the shield's checks are 4 x rarer.
* highway-env's controllers change lanes in their own time (about 1 s to cross); our
  executor judges "lane change complete" from the world model's ``ego_d`` (within 0.5 m of
  the target lane's centre), so its "change under way" flag follows highway-env's car.
* highway-env's MDPVehicle has no collision avoidance of its own: whatever the mapping
  asks is executed, and what it cannot ask (braking below 20 m/s) is not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from sdc_agents.policy_agent import load_model, training_config
from sdc_gym.config import resolve_config
from sdc_gym.envs.highway_behavior import HighwayLoopBehaviorEnv
from sdc_gym.stack.highway.behavior import BehaviorDecision
from sdc_gym.stack.highway.decisions import DecisionExecutor, HighwayDecision
from sdc_gym.stack.highway.features import OBSERVATION_TYPES, BehaviorFeatures
from sdc_gym.stack.highway.shield import SafetyShield, ShieldParameters
from sdc_gym.stack.highway.world_model import LaneView, TrackedCar, WorldModel

LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = 0, 1, 2, 3, 4
"""highway-env's ``DiscreteMetaAction`` indices (lateral and longitudinal actions on)."""
META_ACTION_NAMES = ("LANE_LEFT", "IDLE", "LANE_RIGHT", "FASTER", "SLOWER")
SENSING_RANGE_M = 200.0
"""Cars further than this (centre to centre, along the road) are not in the lane views
(our perception's default range)."""
BEHAVIOR_ENV_ID = "sdc_gym/HighwayLoopBehavior-v0"


class Predictor(Protocol):
    """Anything with SB3's ``predict``: a loaded model, or a stub in tests."""

    def predict(self, observation: np.ndarray, deterministic: bool = ...) -> tuple[Any, Any]:
        ...


def _unwrapped(env: Any) -> Any:
    unwrapped = getattr(env, "unwrapped", env)
    if getattr(unwrapped, "vehicle", None) is None or getattr(unwrapped, "road", None) is None:
        raise ValueError("expected a highway-env env after reset() (with .vehicle and .road), "
                         f"got {type(unwrapped).__name__}")
    return unwrapped


def _lane_frame(vehicle: Any) -> tuple[float, float, float, float]:
    """``s`` along the vehicle's lane, lateral offset (+ right), speed along the lane and
    its lateral rate (+ right)."""
    lane = vehicle.lane
    s, lateral = lane.local_coordinates(vehicle.position)
    relative_heading = vehicle.heading - lane.heading_at(s)
    return (float(s), float(lateral), float(vehicle.speed * math.cos(relative_heading)),
            float(vehicle.speed * math.sin(relative_heading)))


def _preferred_lane(views: list[LaneView], ego_lane: int) -> int:
    """The lane whose car ahead is furthest; ties: the middle lane, then the ego's
    (the rule of our perception)."""
    gaps = [view.ahead_gap for view in views]
    best = max(gaps)
    middle = len(views) // 2
    if gaps[middle] == best:
        return middle
    if gaps[ego_lane] == best:
        return ego_lane
    return gaps.index(best)


def world_model_from_highway_env(env: Any, time_s: float,
                                 sensing_range_m: float = SENSING_RANGE_M) -> WorldModel:
    """The ego and the other vehicles of highway-env's straight road as our world model.

    Args:
        env: a highway-env env (wrapped or not) after ``reset()``.
        time_s: the world model's clock (s; ``env.unwrapped.time`` for the agent).
        sensing_range_m: lane views hold cars within this distance (centre to centre).

    Vehicles on another road segment than the ego's (none on highway-env's straight
    highway) are left out. Car ids are indices in ``road.vehicles``.
    """
    unwrapped = _unwrapped(env)
    ego = unwrapped.vehicle
    origin, destination, ego_lane = ego.lane_index
    lanes = unwrapped.road.network.graph[origin][destination]
    lane_count = len(lanes)
    width = float(lanes[ego_lane].width)
    if any(not math.isclose(float(lane.width), width) for lane in lanes):
        raise ValueError("the adapter needs lanes of one width; this road has "
                         f"{[float(lane.width) for lane in lanes]}")
    ego_s, ego_lateral, ego_speed, _ = _lane_frame(ego)
    ego_d = (ego_lane + 0.5) * width + ego_lateral

    best = [math.inf] * (2 * lane_count)  # ahead rows 0..n-1, behind rows n..2n-1
    nearest: list[TrackedCar | None] = [None] * (2 * lane_count)
    cars = []
    for index, vehicle in enumerate(unwrapped.road.vehicles):
        if vehicle is ego:
            continue
        car_origin, car_destination, lane = vehicle.lane_index
        if (car_origin, car_destination) != (origin, destination):
            continue
        s, lateral, speed, d_rate = _lane_frame(vehicle)
        gap = s - ego_s
        car = TrackedCar(index, s, (lane + 0.5) * width + lateral, speed, d_rate, lane, gap)
        cars.append(car)
        row = lane if gap >= 0.0 else lane + lane_count
        if abs(gap) < best[row]:
            best[row], nearest[row] = abs(gap), car

    views = []
    for lane in range(lane_count):
        ahead, behind = nearest[lane], nearest[lane + lane_count]
        view = {"lane": lane}
        if ahead is not None and best[lane] <= sensing_range_m:
            view.update(ahead_gap=best[lane], ahead_speed=ahead.speed, ahead_id=ahead.id)
        if behind is not None and best[lane + lane_count] <= sensing_range_m:
            view.update(behind_gap=best[lane + lane_count], behind_speed=behind.speed,
                        behind_id=behind.id)
        views.append(LaneView(**view))
    return WorldModel(time=float(time_s), ego_s=ego_s, ego_d=ego_d, ego_speed=ego_speed,
                      ego_lane=ego_lane, lane_count=lane_count, lane_width=width,
                      lanes=tuple(views), cars=tuple(cars),
                      preferred_lane=_preferred_lane(views, ego_lane), road_radius=math.inf)


def target_speed_step(target_speeds: Any) -> float:
    """The spacing of highway-env's target speeds (``inf`` with a single speed)."""
    speeds = np.sort(np.asarray(target_speeds, dtype=np.float64).reshape(-1))
    if speeds.size == 0:
        raise ValueError("highway-env's target_speeds is empty")
    return float(np.min(np.diff(speeds))) if speeds.size > 1 else math.inf


def meta_action(plan: BehaviorDecision, steering_lane: int, target_speed: float,
                speed_step: float) -> int:
    """highway-env's meta-action for an executed decision (see the module docstring).

    Args:
        plan: the executor's instruction.
        steering_lane: the lane highway-env steers to (``vehicle.target_lane_index[2]``).
        target_speed: highway-env's current set-point (``vehicle.target_speed``, m/s).
        speed_step: the spacing of its target speeds (m/s).
    """
    if plan.target_lane != steering_lane:
        return LANE_LEFT if plan.target_lane < steering_lane else LANE_RIGHT
    if plan.target_speed < target_speed - 0.5 * speed_step:
        return SLOWER
    if plan.target_speed > target_speed + 0.5 * speed_step:
        return FASTER
    return IDLE


@dataclass(frozen=True)
class AdapterStep:
    """What the agent saw and did in one highway-env step (for tests and debugging)."""

    world: WorldModel
    decision: HighwayDecision
    plan: BehaviorDecision
    action: int


class HighwayEnvPolicyAgent:
    """A behavior policy driving highway-env through meta-actions (module docstring).

    Args:
        model: a loaded SB3 model, or anything with ``predict(obs, deterministic)``
            returning ``(action, state)``; its ``observation_space`` (when it has one) must
            match the features' shape.
        shield: the safety shield the policy was trained with, or ``None``.
        slow_step_mps: the ``slow`` move's step (the training config's).
        action: ``"discrete"`` (``Discrete(9)`` decisions) or ``"continuous"``.
        lane_count: lanes of the highway-env road (the policy's observation depends on it).
        sensing_range_m: the world model's range.
        name: for tables.

    Call :meth:`reset` after each ``env.reset()`` and :meth:`act` with the env before
    each ``env.step``.
    """

    def __init__(self, model: Predictor, *, shield: SafetyShield | None = None,
                 slow_step_mps: float = 2.0, action: str = "discrete", lane_count: int = 3,
                 sensing_range_m: float = SENSING_RANGE_M, name: str = "policy",
                 observation: str = "nearest") -> None:
        if action not in ("discrete", "continuous"):
            raise ValueError(f"unknown action type {action!r}; valid: ['discrete', "
                             "'continuous']")
        if observation not in OBSERVATION_TYPES:
            raise ValueError(f"unknown observation type {observation!r}; valid: "
                             f"{list(OBSERVATION_TYPES)}")
        self.features = BehaviorFeatures(lane_count, sensing_range_m,
                                         extended=observation == "extended")
        space = getattr(model, "observation_space", None)
        if space is not None and space.shape != self.features.space.shape:
            raise ValueError(f"the policy expects observations of shape {space.shape}; a "
                             f"{lane_count}-lane road gives {self.features.space.shape} "
                             "(set highway-env's lanes_count to the policy's lane count)")
        self.model = model
        self.executor = DecisionExecutor(shield, slow_step_mps=slow_step_mps)
        self.action = action
        self.sensing_range_m = sensing_range_m
        self.name = name
        self.last: AdapterStep | None = None

    def reset(self) -> None:
        """Forget the lane-change state (start of an episode)."""
        self.executor.reset()
        self.last = None

    def decide(self, observation: np.ndarray) -> HighwayDecision:
        action, _ = self.model.predict(observation, deterministic=True)
        if self.action == "discrete":
            return HighwayDecision.from_index(int(np.asarray(action).reshape(())))
        return HighwayDecision.from_vector(action, self.executor.cruise_speed_mps)

    def act(self, env: Any) -> int:
        """The meta-action for highway-env's current state."""
        unwrapped = _unwrapped(env)
        vehicle = unwrapped.vehicle
        speeds = getattr(vehicle, "target_speeds", None)
        if speeds is None or not hasattr(vehicle, "target_lane_index"):
            raise ValueError("the adapter drives highway-env's DiscreteMetaAction (an "
                             f"MDPVehicle ego); this ego is a {type(vehicle).__name__}")
        world = world_model_from_highway_env(unwrapped, float(unwrapped.time),
                                             self.sensing_range_m)
        observation = self.features.encode(world, self.executor)
        decision = self.decide(observation)
        plan = self.executor.execute(world, decision)
        action = meta_action(plan, int(vehicle.target_lane_index[2]),
                             float(vehicle.target_speed), target_speed_step(speeds))
        self.last = AdapterStep(world, decision, plan, action)
        return action


def highway_env_policy_agent(kind: str, path: str | Path, *, lane_count: int = 3,
                             name: str | None = None) -> HighwayEnvPolicyAgent:
    """The policy of algorithm ``kind`` saved at ``path`` as a highway-env agent, with the
    shield, ``slow`` step and action type of its training config (the behavior env's
    defaults when none is found: the shield on)."""
    env_id, trained = training_config(path)
    if env_id is not None and env_id != BEHAVIOR_ENV_ID:
        raise ValueError(f"{path} was trained on {env_id}; the highway-env adapter runs "
                         f"policies of {BEHAVIOR_ENV_ID}")
    cfg = resolve_config(HighwayLoopBehaviorEnv.DEFAULT_CONFIG, trained,
                         owner="HighwayLoopBehavior-v0 (policy's training config)")
    shield = SafetyShield(ShieldParameters(**cfg["shield"])) if cfg["safety_shield"] else None
    return HighwayEnvPolicyAgent(load_model(kind, path), shield=shield,
                                 slow_step_mps=float(cfg["slow_step_mps"]),
                                 action=cfg["action"], lane_count=lane_count,
                                 observation=cfg["observation"],
                                 name=name or f"{kind}:{Path(path).stem}")
