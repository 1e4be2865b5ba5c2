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
from sdc_gym.stack.highway import behavior_kernel
from sdc_gym.stack.highway.decisions import (
    ACTION_NAMES,
    DecisionExecutor,
    ExecutorBatch,
    HighwayDecision,
    decision_codes,
)
from sdc_gym.stack.highway.features import (
    LATERAL_SCALE_MPS,
    OBSERVATION_TYPES,
    BehaviorFeatures,
)
from sdc_gym.stack.highway.motion import MotionBatch, MotionParameters, SeedMotionPlanner
from sdc_gym.stack.highway.perception import (
    Perception,
    PerceptionParameters,
    SensedBatch,
    sense_batch,
    world_model_of,
)
from sdc_gym.stack.highway.shield import SafetyShield, ShieldParameters
from sdc_gym.stack.highway.world_model import WorldModel
from sdc_gym.validation.actions import discrete_index
from sdc_gym.validation.env_configs import check_highway_behavior_config
from sdc_gym.vehicle.path_follower import PHYSICS_DT

FloatArray = NDArray[np.float64]

ACTION_TYPES = ("discrete", "continuous")

BEHAVIOR_DEFAULTS: dict[str, Any] = {
    "highway": {},                 # HighwayLoop-v0 config (not steps_per_action)
    "decision_frames": 12,         # 0.02 s frames per decision (0.24 s)
    "action": "discrete",          # "discrete" (Discrete(9)) or "continuous" (Box(2))
    "observation": "nearest",      # "nearest" (Box(25)) or "extended" (+ 3 per lane)
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
        require(cfg["observation"] in OBSERVATION_TYPES, owner, "observation",
                f"one of {OBSERVATION_TYPES}", cfg["observation"])
        require(cfg["slow_step_mps"] > 0, owner, "slow_step_mps", "> 0 m/s",
                cfg["slow_step_mps"])
        highway_config = {"telemetry_info": False, **cfg["highway"],
                          "steps_per_action": cfg["decision_frames"]}
        self.world = HighwayWorld(highway_config, envs=envs,
                                  batch_names=(owner, "decision_frames"))
        self.envs = envs
        road = self.world.road
        self.road = road
        try:
            self.shield = SafetyShield(ShieldParameters(**cfg["shield"])) \
                if cfg["safety_shield"] else None
        except ValueError as error:
            raise ConfigError(f"{owner}: {error}") from None
        self.perception_params = PerceptionParameters(tracking=bool(cfg["kalman_tracking"]))
        self.motion_params = MotionParameters.for_env(self.world)
        self.perception = [Perception(road, self.perception_params) for _ in range(envs)]
        self.motion_batch = MotionBatch(road, self.motion_params, envs,
                                        kernel_threads=self.world.kernel_threads)
        self.motion = [SeedMotionPlanner.view(self.motion_batch, env) for env in range(envs)]
        self.executors = ExecutorBatch(self.shield, envs,
                                       slow_step_mps=float(cfg["slow_step_mps"]))
        self.executor = [DecisionExecutor.view(self.executors, env) for env in range(envs)]
        self.features = BehaviorFeatures(road.lane_count, self.perception_params.sensing_range,
                                         extended=cfg["observation"] == "extended")
        self.discrete = cfg["action"] == "discrete"
        self.decision_period_s = PHYSICS_DT * cfg["decision_frames"]
        self.lane_change_reward = float(cfg["reward_lane_change"])
        self.refused_reward = float(cfg["reward_refused"])
        self.room_weight = float(cfg["reward_room_ahead"])
        self.shaping_gamma = float(cfg["shaping_gamma"])
        require(0.0 <= self.shaping_gamma <= 1.0, owner, "shaping_gamma", "in [0, 1]",
                cfg["shaping_gamma"])
        self.decisions = np.zeros(envs, dtype=np.int64)
        self.sensed: SensedBatch | None = None
        self.observations = np.zeros((envs, self.features.size), dtype=np.float32)
        self._paths = np.zeros((envs, self.world.path_points, 2))
        self._all = np.ones(envs, dtype=bool)
        self._steering = np.ones(envs, dtype=bool)
        # The plan of each env's last decision: target lane and speed.
        self.plan_lane = np.full(envs, -1, dtype=np.int64)
        self.plan_speed = np.zeros(envs)
        self._planned = np.zeros(envs, dtype=bool)

    # ------------------------------------------------------------------ episodes
    def reset_at(self, env: int, rng: np.random.Generator, scenario: Any = CONFIG) -> None:
        """Start env ``env``'s episode; all its randomness comes from ``rng``; ``scenario``
        as :meth:`HighwayWorld.reset_at` takes it."""
        self.world.reset_at(env, rng, scenario)
        self.perception[env].reset()
        self.motion[env].reset()
        self.executors.reset_at(env)
        self.decisions[env] = 0
        self._planned[env] = False
        rows = np.zeros(self.envs, dtype=bool)
        rows[env] = True
        self._perceive(np.zeros(self.envs), rows)

    # ------------------------------------------------------------------ decisions
    def decode(self, action: Any, env: int = 0) -> HighwayDecision:
        """The decision an action stands for (``ValueError`` for an invalid one)."""
        if self.discrete:
            # an int, a NumPy int or an int array of shape () or (1,); not an object array
            return HighwayDecision.from_index(discrete_index(action, len(ACTION_NAMES),
                                                             ACTION_NAMES))
        return HighwayDecision.from_vector(action, self.executors.cruise_speed_mps)

    def decode_batch(self, actions: Any) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                                  FloatArray]:
        """Every env's action as lane moves, speed move codes and target speeds: the
        kernel's form of :meth:`decode` (whose ``ValueError`` an invalid one raises)."""
        envs = self.envs
        values = np.asarray(actions)
        if self.discrete and values.shape == (envs,) and values.dtype.kind in "iu":
            index = values.astype(np.int64)
            if ((index >= 0) & (index < len(ACTION_NAMES))).all():
                lane, speed = np.divmod(index, 3)
                return lane - 1, speed, np.zeros(envs)
        elif not self.discrete and values.shape == (envs, 2) and values.dtype.kind == "f":
            vector = values.astype(np.float64)
            if np.isfinite(vector).all() and not (np.abs(vector) > 1.0 + 1e-6).any():
                lane = np.where(vector[:, 0] < -1.0 / 3.0, -1,
                                np.where(vector[:, 0] > 1.0 / 3.0, 1, 0))
                target = 0.5 * (np.minimum(np.maximum(vector[:, 1], -1.0), 1.0) + 1.0) * (
                    self.executors.cruise_speed_mps)
                return lane, np.full(envs, behavior_kernel.TARGET_SPEED), target
        # Anything else: one at a time (the single env's decoding and its errors).
        codes = [decision_codes(self.decode(actions[env], env)) for env in range(envs)]
        lane_move, speed_move, target = (np.array(column) for column in zip(*codes, strict=True))
        return lane_move.astype(np.int64), speed_move.astype(np.int64), target.astype(float)

    def step(self, actions: Any) -> tuple[FloatArray, NDArray[np.bool_], NDArray[np.bool_],
                                          list[Any]]:
        """Every env takes its decision (``actions[i]``) for ``decision_frames`` frames:
        rewards, terminated, truncated, and the incidents each env's step began."""
        if self.sensed is None or not self._all_reset():
            raise RuntimeError("call reset() before step()")
        sensed = self.sensed
        executors = self.executors
        lane_move, speed_move, target_speed = self.decode_batch(actions)
        potentials = self._potentials(sensed)
        before = executors.ints[:, [behavior_kernel.LANE_CHANGES,
                                    behavior_kernel.REFUSED]].copy()
        envs = self.envs
        accel, replan = np.empty(envs), np.empty(envs, dtype=bool)
        behavior_kernel.execute_batch(
            self.shield is not None, executors.shield_array, executors.constants, sensed.views,
            sensed.ego_lane, sensed.ego_d, sensed.ego_speed, self.world.road.lane_width,
            sensed.road_radius, self.times, lane_move, speed_move, target_speed,
            executors.ints, executors.last_change, self.plan_lane, self.plan_speed, accel,
            replan)
        self._planned[:] = True
        # The motion layer plans from the ego as observed (float32, like the single env's).
        ego = self.world.ego_array().astype(np.float32)
        paths, lengths = self.motion_batch.plan(ego, self.plan_lane, self.plan_speed, accel,
                                                replan, self._steering)
        self._paths[:, :paths.shape[1]] = paths
        lengths = self.world.check_paths(self._paths, lengths)
        result = self.world.step(self._paths, lengths)
        self.decisions += 1
        sensed = self._perceive(self.decisions * self.decision_period_s, self._all)
        reward = result.reward
        if self.room_weight:
            after = self._potentials(sensed)
            after[result.terminated] = 0.0
            reward += self.shaping_gamma * after - potentials
        changes = executors.ints[:, [behavior_kernel.LANE_CHANGES,
                                     behavior_kernel.REFUSED]] - before
        reward += self.lane_change_reward * changes[:, 0]
        reward += self.refused_reward * changes[:, 1]
        return reward, result.terminated, result.truncated, result.incidents

    def _all_reset(self) -> bool:
        return self.world._all_reset or all(rng is not None for rng in self.world.rngs)

    @property
    def times(self) -> FloatArray:
        """Each env's perception clock: decisions taken x the decision period (s)."""
        return self.decisions * self.decision_period_s

    def _perceive(self, times: FloatArray, rows: NDArray[np.bool_]) -> SensedBatch:
        """Perceive every env (from the observation as the single env gives it, float32)
        and encode the observations of ``rows``."""
        world = self.world
        ego = world.ego_array().astype(np.float32)
        fusion = world.fusion.astype(np.float32)
        if rows.all():
            sensed = sense_batch(self.perception, ego, fusion, world.fusion_mask, times)
        else:  # only these envs moved on: the others keep what they perceived
            which = np.flatnonzero(rows)
            part = sense_batch([self.perception[env] for env in which.tolist()], ego[which],
                               fusion[which], world.fusion_mask[which], times[which])
            sensed = self.sensed if self.sensed is not None else SensedBatch(
                self.envs, fusion.shape[1], self.road.lane_count)
            sensed.put(which, part)
        self.sensed = sensed
        executors = self.executors
        behavior_kernel.encode_batch(
            self.shield is not None, executors.shield_array, sensed.views, sensed.ego_lane,
            sensed.ego_d, sensed.ego_speed, world.road.lane_width, sensed.road_radius, times,
            executors.ints, executors.last_change, self.features.scales, rows,
            self.observations)
        if self.features.extended:
            self._encode_traffic(sensed, rows)
        return sensed

    def _encode_traffic(self, sensed: SensedBatch, rows: NDArray[np.bool_]) -> None:
        """The extended observation's traffic entries of ``rows`` (tracked envs, whose
        cars are their Kalman tracks, one at a time)."""
        features = self.features
        plain = rows.copy()
        for env in sensed.tracked:
            plain[env] = False
        behavior_kernel.encode_traffic_batch(
            sensed.views, sensed.ids, sensed.car_lane, sensed.car_gap, sensed.speed,
            sensed.d_rate, sensed.count, sensed.ego_speed, features.scales,
            LATERAL_SCALE_MPS, plain, self.observations, features.base_size)
        for env, columns in sensed.tracked.items():
            if rows[env]:
                ids, _, _, speed, d_rate, car_lane, car_gap = columns
                behavior_kernel.encode_traffic(
                    sensed.views[env], np.asarray(ids, dtype=np.int64), car_lane, car_gap,
                    speed, d_rate, len(ids), sensed.ego_speed[env], features.scales,
                    LATERAL_SCALE_MPS, self.observations[env], features.base_size)

    def _potentials(self, sensed: SensedBatch) -> FloatArray:
        """The shaping potential of every env (0 without shaping)."""
        out = np.zeros(self.envs)
        if self.room_weight:
            behavior_kernel.room_batch(sensed.views, sensed.ego_lane, self.executors.ints,
                                       self.room_weight, self.perception_params.sensing_range,
                                       out)
        return out

    def room_potential(self, env: int) -> float:
        """The shaping potential: weight x room ahead in the target lane / sensing range."""
        if not self.room_weight or self.sensed is None:
            return 0.0
        return float(self._potentials(self.sensed)[env])

    def world_model(self, env: int) -> WorldModel:
        """Env ``env``'s world model as perception last saw it (the lane views, the ego
        and the road; no cars)."""
        assert self.sensed is not None
        return world_model_of(self.sensed, env, float(self.times[env]), self.perception[env])

    def behavior_info(self, env: int, action: Any) -> dict[str, Any]:
        """Env ``env``'s ``info["behavior"]``: the decision executed and the counters."""
        executor = self.executor[env]
        info: dict[str, Any] = {"lane_changes": executor.lane_changes,
                                "refused": executor.refused, "aborted": executor.aborted}
        if self._planned[env]:
            name = (ACTION_NAMES[int(np.asarray(action).reshape(()))]
                    if self.discrete else "continuous")
            info.update(action_name=name, target_lane=int(self.plan_lane[env]),
                        target_speed=float(self.plan_speed[env]))
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


