"""The behavior-level highway of ``envs`` envs at once: decisions in, features out.

:class:`HighwayBehaviorWorld` runs the shared driving stack (perception, the decision
executor with its safety shield, the seed's motion layer, the features) over a
:class:`~sdc_gym.envs.highway_world.HighwayWorld`: the simulation behind
``sdc_gym/HighwayLoopBehavior-v0`` (the batch of one) and its vector env. Env ``i`` of a
batch is exactly a single env with the same generator and actions.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.highway_world import HighwayWorld, incident_kinds
from sdc_gym.scenarios.episode import CONFIG
from sdc_gym.stack.highway.decisions import ACTION_NAMES, DecisionExecutor, HighwayDecision
from sdc_gym.stack.highway.features import BehaviorFeatures
from sdc_gym.stack.highway.motion import MotionBatch, MotionParameters, SeedMotionPlanner
from sdc_gym.stack.highway.perception import Perception, PerceptionParameters, perceive_all
from sdc_gym.stack.highway.shield import SafetyShield, ShieldParameters
from sdc_gym.stack.highway.world_model import WorldModel
from sdc_gym.validation.env_configs import check_highway_behavior_config
from sdc_gym.vehicle.path_follower import PHYSICS_DT

FloatArray = NDArray[np.float64]

ACTION_TYPES = ("discrete", "continuous")

BEHAVIOR_DEFAULTS: dict[str, Any] = {
    "highway": {},                 # HighwayLoop-v0 config (not steps_per_action)
    "decision_frames": 12,         # 0.02 s frames per decision (0.24 s)
    "action": "discrete",          # "discrete" (Discrete(9)) or "continuous" (Box(2))
    "safety_shield": True,
    "shield": dataclasses.asdict(ShieldParameters()),
    "slow_step_mps": 2.0,          # m/s below the current speed for "slow"
    "kalman_tracking": False,      # perception tracks cars with Kalman filters
    "reward_lane_change": -0.05,   # per lane change started
    "reward_refused": -0.02,       # per lane move the shield refused
    "reward_room_ahead": 0.0,      # weight of the room-ahead shaping potential
    "shaping_gamma": 0.99,         # the shaping's discount: the algorithm's gamma
}
"""``HighwayLoopBehavior-v0``'s config keys with their defaults."""


class HighwayBehaviorWorld:
    """``envs`` behavior-level highway envs (see the module docstring).

    Args:
        config: ``HighwayLoopBehavior-v0`` config overrides (see :data:`BEHAVIOR_DEFAULTS`).
        envs: number of envs.
    """

    OWNER: ClassVar[str] = "HighwayLoopBehavior-v0"

    def __init__(self, config: dict[str, Any] | None = None, envs: int = 1) -> None:
        owner = self.OWNER
        self.config = cfg = resolve_config(BEHAVIOR_DEFAULTS, config, owner=owner)
        require(isinstance(cfg["highway"], dict), owner, "highway", "a mapping of "
                "HighwayLoop-v0 config keys", cfg["highway"])
        if "steps_per_action" in cfg["highway"]:
            raise ConfigError(f"{owner}: set the decision period with 'decision_frames', "
                              "not highway.steps_per_action")
        check_highway_behavior_config(cfg, owner)  # sdc_gym.validation
        require(cfg["action"] in ACTION_TYPES, owner, "action", f"one of {ACTION_TYPES}",
                cfg["action"])
        require(cfg["slow_step_mps"] > 0, owner, "slow_step_mps", "> 0 m/s",
                cfg["slow_step_mps"])
        highway_config = {"telemetry_info": False, **cfg["highway"],
                          "steps_per_action": cfg["decision_frames"]}
        self.world = HighwayWorld(highway_config, envs=envs)
        self.envs = envs
        road = self.world.road
        self.road = road
        try:
            self.shield = SafetyShield(ShieldParameters(**cfg["shield"])) \
                if cfg["safety_shield"] else None
        except ValueError as error:
            raise ConfigError(f"{owner}: {error}") from None
        self.perception_params = PerceptionParameters(tracking=bool(cfg["kalman_tracking"]))
        self.motion_params = MotionParameters(
            frames_per_cycle=self.world.steps_per_action,
            latency_frames=self.world.latency_steps,
            path_length=min(MotionParameters.path_length, self.world.path_points))
        self.perception = [Perception(road, self.perception_params) for _ in range(envs)]
        self.motion_batch = MotionBatch(road, self.motion_params, envs)
        self.motion = [SeedMotionPlanner.view(self.motion_batch, env) for env in range(envs)]
        self.executor = [DecisionExecutor(self.shield, slow_step_mps=float(cfg["slow_step_mps"]))
                         for _ in range(envs)]
        self.features = BehaviorFeatures(road.lane_count, self.perception_params.sensing_range)
        self.discrete = cfg["action"] == "discrete"
        self.decision_period_s = PHYSICS_DT * cfg["decision_frames"]
        self.lane_change_reward = float(cfg["reward_lane_change"])
        self.refused_reward = float(cfg["reward_refused"])
        self.room_weight = float(cfg["reward_room_ahead"])
        self.shaping_gamma = float(cfg["shaping_gamma"])
        require(0.0 <= self.shaping_gamma <= 1.0, owner, "shaping_gamma", "in [0, 1]",
                cfg["shaping_gamma"])
        self.decisions = np.zeros(envs, dtype=np.int64)
        self.world_models: list[WorldModel | None] = [None] * envs
        self.observations = np.zeros((envs, self.features.size), dtype=np.float32)
        self._paths = np.zeros((envs, self.world.path_points, 2))
        self._lengths = np.zeros(envs, dtype=np.int64)
        self.last_plans: list[Any] = [None] * envs

    # ------------------------------------------------------------------ episodes
    def reset_at(self, env: int, rng: np.random.Generator, scenario: Any = CONFIG) -> None:
        """Start env ``env``'s episode; all its randomness comes from ``rng``; ``scenario``
        as :meth:`HighwayWorld.reset_at` takes it."""
        self.world.reset_at(env, rng, scenario)
        self.perception[env].reset()
        self.motion[env].reset()
        self.executor[env].reset()
        self.decisions[env] = 0
        self.last_plans[env] = None
        world = self._perceive(np.zeros(self.envs), [env])[0]
        self.world_models[env] = world
        self.observations[env] = self.features.encode(world, self.executor[env])

    # ------------------------------------------------------------------ decisions
    def decode(self, action: Any, env: int = 0) -> HighwayDecision:
        """The decision an action stands for (``ValueError`` for an invalid one)."""
        if self.discrete:
            if isinstance(action, np.ndarray) and action.shape in ((), (1,)):
                action = action.reshape(()).item()
            return HighwayDecision.from_index(action)
        return HighwayDecision.from_vector(action, self.executor[env].cruise_speed_mps)

    def step(self, actions: Any) -> tuple[FloatArray, NDArray[np.bool_], NDArray[np.bool_],
                                          list[Any]]:
        """Every env takes its decision (``actions[i]``) for ``decision_frames`` frames:
        rewards, terminated, truncated, and the incidents each env's step began."""
        if any(model is None for model in self.world_models):
            raise RuntimeError("call reset() before step()")
        envs = self.envs
        decisions = [self.decode(actions[env], env) for env in range(envs)]
        potentials = np.array([self.room_potential(env) for env in range(envs)])
        before = [(ex.lane_changes, ex.refused) for ex in self.executor]
        plans = []
        for env in range(envs):
            world = self.world_models[env]
            assert world is not None
            plans.append(self.executor[env].execute(world, decisions[env]))
        self.last_plans = plans
        # The motion layer plans from the ego as observed (float32, like the single env's).
        ego = self.world.ego_array().astype(np.float32)
        paths, lengths = self.motion_batch.plan(
            ego, [plan.target_lane for plan in plans], [plan.target_speed for plan in plans],
            [plan.acceleration for plan in plans], [plan.replan for plan in plans],
            [plan.steering for plan in plans])
        self._paths[:, :paths.shape[1]] = paths
        lengths = self.world.check_paths(self._paths, lengths)
        result = self.world.step(self._paths, lengths)
        self.decisions += 1
        reward = result.reward
        models = self._perceive(self.decisions * self.decision_period_s)
        for env in range(envs):
            world = models[env]
            self.world_models[env] = world
            executor = self.executor[env]
            value = float(reward[env])
            if self.room_weight:
                after = 0.0 if result.terminated[env] else self.room_potential(env)
                value += self.shaping_gamma * after - float(potentials[env])
            value += self.lane_change_reward * (executor.lane_changes - before[env][0])
            value += self.refused_reward * (executor.refused - before[env][1])
            reward[env] = value
            self.observations[env] = self.features.encode(world, executor)
        return reward, result.terminated, result.truncated, result.incidents

    def _perceive(self, times: FloatArray, rows: list[int] | None = None) -> list[WorldModel]:
        """The world models of every env (or of ``rows``), from the observation as the
        single env gives it (float32)."""
        world = self.world
        ego = world.ego_array().astype(np.float32)
        fusion = world.fusion.astype(np.float32)
        present = world.fusion_mask
        if rows is not None:
            ego, fusion, present, times = ego[rows], fusion[rows], present[rows], times[rows]
        perceptions = self.perception if rows is None else [self.perception[e] for e in rows]
        return perceive_all(perceptions, ego, fusion, present, times, with_cars=False)

    def room_potential(self, env: int) -> float:
        """The shaping potential: weight x room ahead in the target lane / sensing range."""
        world = self.world_models[env]
        if not self.room_weight or world is None:
            return 0.0
        executor = self.executor[env]
        lane = executor.target_lane if executor.target_lane >= 0 else world.ego_lane
        rng = self.perception_params.sensing_range
        return self.room_weight * min(world.lanes[lane].ahead_gap, rng) / rng

    def behavior_info(self, env: int, action: Any) -> dict[str, Any]:
        """Env ``env``'s ``info["behavior"]``: the decision executed and the counters."""
        executor = self.executor[env]
        info: dict[str, Any] = {"lane_changes": executor.lane_changes,
                                "refused": executor.refused, "aborted": executor.aborted}
        plan = self.last_plans[env]
        if plan is not None:
            name = (ACTION_NAMES[int(np.asarray(action).reshape(()))]
                    if self.discrete else "continuous")
            info.update(action_name=name, target_lane=plan.target_lane,
                        target_speed=plan.target_speed)
        return info

    def info(self, env: int, incidents: Any, *, final: bool, action: Any = None
             ) -> dict[str, Any]:
        """Env ``env``'s ``info`` dict as the single env gives it."""
        world = self.world
        info: dict[str, Any] = world.metrics.step_info(env)
        info["lane"] = world.lane(env)
        info["new_incidents"] = incident_kinds(incidents)
        info["is_success"] = world.is_success(env)
        info["termination_reason"] = world.done_reason[env] if final else ""
        info["summary"] = world.summary(env) if final else None
        info["behavior"] = self.behavior_info(env, action)
        if world.traffic.object_slots:
            info["road_events"] = world.road_events(env)
        return info
