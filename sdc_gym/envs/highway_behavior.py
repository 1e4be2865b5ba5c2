"""``sdc_gym/HighwayLoopBehavior-v0``: the highway loop at the level of behavior decisions."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.highway_loop import PHYSICS_DT, HighwayLoopEnv
from sdc_gym.stack.highway.decisions import ACTION_NAMES, DecisionExecutor, HighwayDecision
from sdc_gym.stack.highway.features import BehaviorFeatures
from sdc_gym.stack.highway.motion import MotionParameters, SeedMotionPlanner
from sdc_gym.stack.highway.perception import Perception, PerceptionParameters
from sdc_gym.stack.highway.shield import SafetyShield, ShieldParameters
from sdc_gym.stack.highway.world_model import WorldModel
from sdc_gym.validation.env_configs import check_highway_behavior_config

ACTION_TYPES = ("discrete", "continuous")


class HighwayLoopBehaviorEnv(gym.Env):
    """
    ## Description

    ``sdc_gym/HighwayLoop-v0`` driven through the shared driving stack, with the agent in
    the place of the seed planner's behavior layer. Each step is one decision: a lane move
    and a speed move, which the motion layer (:mod:`sdc_gym.stack.highway.motion`, the one
    the FSM agent uses) executes for ``decision_frames`` physics frames (12 = 0.24 s by
    default), while perception (:mod:`sdc_gym.stack.highway.perception`) turns the
    telemetry into the world model the observation is made from. A policy trained here
    drives the path-level env unchanged through the same layers
    (``evaluate.py --agents ppo:model.zip``), next to the rule-based FSM.

    By default a safety shield (:mod:`sdc_gym.stack.highway.shield`) sits between the
    decision and the motion layer, with the seed's own safety rules: the speed is capped
    behind the lead by the seed's braking curve, unsafe lane changes are refused and
    changes that become unsafe are aborted. The policy then learns lane choice and
    tactics, not how to avoid the car in front. ``safety_shield: False`` executes
    decisions as they come (``cruise`` drives into the car ahead): everything is then
    learned from the incident penalties.

    ## Action Space

    ``action: "discrete"`` (default): ``Discrete(9)``, index ``3 x lane + speed`` with lane
    moves left 0 / keep 1 / right 2 and speed moves cruise 0 / hold 1 / slow 2
    (:data:`~sdc_gym.stack.highway.decisions.ACTION_NAMES`; semantics in
    :mod:`sdc_gym.stack.highway.decisions`). ``action: "continuous"``:
    ``Box(-1, 1, (2,), float32)``, lane (below -1/3 left, above 1/3 right) and target speed
    (-1 = 0, 1 = 49.83 mph). An out-of-range or non-finite action raises ``ValueError``.

    ## Observation Space

    ``Box(float32, (7 + 6 n,))`` for ``n`` lanes (25 on the default highway): ego speed,
    ego and target lane one-hot, offset from the target lane's centre, lane change under
    way, time since the last change, curvature ahead, whether a left / right move would
    start a change now, and per lane the gap and relative speed of the nearest car ahead
    and behind, normalised. The table is in :mod:`sdc_gym.stack.highway.features`;
    ``env.unwrapped.feature_names`` names each entry.

    ## Rewards

    The path-level env's reward for the frames of the decision (progress along the road,
    about 1 per decision at the 50 mph limit, plus each incident's penalty: collision -10,
    acceleration, jerk, speed, lane, off-road -1; ``highway.reward_incident``), plus
    ``reward_lane_change`` per lane change started and ``reward_refused`` per lane move
    the shield refused (so a policy learns to ask only for what it gets, which matters
    without the shield), plus optional potential-based shaping (Ng, Harada and Russell,
    1999), which leaves the optimal policy unchanged: with ``reward_room_ahead = w``,
    ``shaping_gamma x phi(next) - phi(now)`` where ``phi = w x`` the room ahead in the
    target lane over the sensing range (0 after the end). It pays a lane change into an
    open lane at once rather than through the speed it brings seconds later. A collision
    ends the episode, so it also forfeits the progress still to come: lap time and
    violations are what evaluation scores.

    ## Starting State

    As ``HighwayLoop-v0``: standing in the middle lane at the original's start, traffic
    from the seed.

    ## Episode End

    As ``HighwayLoop-v0`` (terminated on a collision or after ``highway.laps`` laps,
    truncated after ``highway.max_duration`` s). ``info`` has the path-level env's keys
    (``summary`` and ``is_success`` at the end) plus ``behavior``: the decision executed
    (``action_name``, ``target_lane``, ``target_speed``) and the episode's counts of lane
    changes started, refused and aborted.

    ## Arguments

    ``gym.make("sdc_gym/HighwayLoopBehavior-v0", config={...}, render_mode=None)``:

    * ``highway``: the path-level env's config (any ``HighwayLoop-v0`` key but
      ``steps_per_action``), e.g. ``{"traffic": {"car_count": 20}, "max_duration": 200}``.
    * ``decision_frames``: physics frames per decision (the path-level env's
      ``steps_per_action``).
    * ``action``: ``"discrete"`` or ``"continuous"``.
    * ``safety_shield`` and ``shield`` (its :class:`ShieldParameters`), ``slow_step_mps``,
      ``kalman_tracking`` (perception filters every car, for noisy sensors),
      ``reward_lane_change``, ``reward_refused``, ``reward_room_ahead``,
      ``shaping_gamma``.

    Unknown keys raise ``ConfigError`` listing the valid ones.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"],
                                          "render_fps": 25}
    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = {
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

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        owner = "HighwayLoopBehavior-v0"
        self.config = cfg = resolve_config(self.DEFAULT_CONFIG, config, owner=owner)
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
        self.highway = HighwayLoopEnv(highway_config, render_mode=render_mode)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.highway.metadata["render_fps"]}
        road = self.highway.road
        try:
            shield = SafetyShield(ShieldParameters(**cfg["shield"])) if cfg["safety_shield"] \
                else None
        except ValueError as error:
            raise ConfigError(f"{owner}: {error}") from None
        self.perception = Perception(road, PerceptionParameters(
            tracking=bool(cfg["kalman_tracking"])))
        self.motion = SeedMotionPlanner(road, MotionParameters.for_env(self.highway))
        self.executor = DecisionExecutor(shield, slow_step_mps=float(cfg["slow_step_mps"]))
        self.features = BehaviorFeatures(road.lane_count,
                                         self.perception.params.sensing_range)
        self.feature_names = self.features.names()
        self.observation_space = self.features.space
        self.action_space: spaces.Space[Any] = (
            spaces.Discrete(len(ACTION_NAMES)) if cfg["action"] == "discrete"
            else spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32))
        self.decision_period_s = PHYSICS_DT * cfg["decision_frames"]
        self._lane_change_reward = float(cfg["reward_lane_change"])
        self._refused_reward = float(cfg["reward_refused"])
        self._room_weight = float(cfg["reward_room_ahead"])
        self._shaping_gamma = float(cfg["shaping_gamma"])
        require(0.0 <= self._shaping_gamma <= 1.0, owner, "shaping_gamma", "in [0, 1]",
                cfg["shaping_gamma"])
        self._world: WorldModel | None = None
        self._highway_obs: dict[str, Any] = {}
        self._decisions = 0

    @property
    def road(self) -> Any:
        return self.highway.road

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32],
                                                              dict[str, Any]]:
        super().reset(seed=seed)
        self._highway_obs, info = self.highway.reset(seed=seed, options=options)
        self.perception.reset()
        self.motion.reset()
        self.executor.reset()
        self._decisions = 0
        self._world = self.perception.perceive(self._highway_obs, 0.0)
        info["behavior"] = self._behavior_info(None, None)
        return self.features.encode(self._world, self.executor), info

    def decode(self, action: Any) -> HighwayDecision:
        """The decision an action stands for (``ValueError`` for an invalid one)."""
        if self.config["action"] == "discrete":
            if isinstance(action, np.ndarray) and action.shape in ((), (1,)):
                action = action.reshape(()).item()
            return HighwayDecision.from_index(action)
        return HighwayDecision.from_vector(action, self.executor.cruise_speed_mps)

    def step(self, action: Any) -> tuple[NDArray[np.float32], float, bool, bool,
                                         dict[str, Any]]:
        if self._world is None:
            raise RuntimeError("call reset() before step()")
        decision = self.decode(action)
        potential = self._room_potential()  # phi of the state the decision is taken in
        changes, refused = self.executor.lane_changes, self.executor.refused
        plan = self.executor.execute(self._world, decision)
        path = self.motion.plan(self._highway_obs, plan)
        self._highway_obs, reward, terminated, truncated, info = self.highway.step(path)
        self._decisions += 1
        self._world = self.perception.perceive(self._highway_obs,
                                               self._decisions * self.decision_period_s)
        if self._room_weight:
            after = 0.0 if terminated else self._room_potential()
            reward += self._shaping_gamma * after - potential
        reward += self._lane_change_reward * (self.executor.lane_changes - changes)
        reward += self._refused_reward * (self.executor.refused - refused)
        info["behavior"] = self._behavior_info(action, plan)
        observation = self.features.encode(self._world, self.executor)
        return observation, float(reward), terminated, truncated, info

    def _room_potential(self) -> float:
        """The shaping potential: weight x room ahead in the target lane / sensing range."""
        if not self._room_weight or self._world is None:
            return 0.0
        lane = self.executor.target_lane if self.executor.target_lane >= 0 \
            else self._world.ego_lane
        rng = self.perception.params.sensing_range
        return self._room_weight * min(self._world.lanes[lane].ahead_gap, rng) / rng

    def _behavior_info(self, action: Any, plan: Any) -> dict[str, Any]:
        executor = self.executor
        info: dict[str, Any] = {"lane_changes": executor.lane_changes,
                                "refused": executor.refused, "aborted": executor.aborted}
        if plan is not None:
            name = (ACTION_NAMES[int(np.asarray(action).reshape(()))]
                    if self.config["action"] == "discrete" else "continuous")
            info.update(action_name=name, target_lane=plan.target_lane,
                        target_speed=plan.target_speed)
        return info

    def render(self) -> NDArray[np.uint8] | None:
        return self.highway.render()

    def close(self) -> None:
        self.highway.close()
