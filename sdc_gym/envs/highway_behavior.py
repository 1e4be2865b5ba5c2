"""``sdc_gym/HighwayLoopBehavior-v0``: the highway loop at the level of behavior decisions."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.envs.highway_behavior_world import (
    ACTION_TYPES,
    BEHAVIOR_DEFAULTS,
    HighwayBehaviorWorld,
)
from sdc_gym.envs.highway_loop import HighwayLoopEnv
from sdc_gym.scenarios.options import CONFIG, OPTION, check_reset_options, scenario_option
from sdc_gym.stack.highway.decisions import ACTION_NAMES, HighwayDecision

__all__ = ["ACTION_TYPES", "HighwayLoopBehaviorEnv", "behavior_spaces"]


def behavior_spaces(world: HighwayBehaviorWorld) -> tuple[spaces.Space[Any], spaces.Box]:
    """The action and observation spaces of one env of ``world``."""
    action_space: spaces.Space[Any] = (
        spaces.Discrete(len(ACTION_NAMES)) if world.discrete
        else spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32))
    return action_space, world.features.space


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
    ``env.unwrapped.feature_names`` names each entry. ``observation: "extended"`` adds
    ``3 n`` entries (34 on the default highway): per lane the gap and relative speed of the
    second car ahead (a lane open beyond its first car, or a queue) and the lateral rate of
    the car ahead (its lane-change intent).

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
      ``steps_per_action``), e.g. ``{"traffic": {"car_count": 20}, "max_duration": 200}``;
      its ``kernel_threads`` (default 1; an int in 1..``NUMBA_NUM_THREADS``) runs the
      batch's heaviest kernels, the motion plan included, on that many threads with the
      same bits (``HighwayLoop-v0``'s Arguments; docs/batched.md, "Two kernel threads").
    * ``decision_frames``: physics frames per decision (the path-level env's
      ``steps_per_action``).
    * ``action``: ``"discrete"`` or ``"continuous"``.
    * ``observation``: ``"nearest"`` (the nearest car ahead and behind per lane) or
      ``"extended"`` (also the second car ahead and the lead's lateral rate per lane).
    * ``safety_shield`` and ``shield`` (its :class:`ShieldParameters`), ``slow_step_mps``,
      ``kalman_tracking`` (perception filters every car, for noisy sensors),
      ``reward_lane_change``, ``reward_refused``, ``reward_room_ahead``,
      ``shaping_gamma``.

    Unknown keys raise ``ConfigError`` listing the valid ones.

    ## Vectorized

    ``gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=E,
    vectorization_mode="vector_entry_point")`` gives
    :class:`~sdc_gym.envs.highway_vector.HighwayLoopBehaviorVectorEnv`: ``E`` of these envs
    as one batch (:class:`~sdc_gym.envs.highway_behavior_world.HighwayBehaviorWorld`, of
    which this env is the batch of one), env ``i`` exactly this env with the same seed and
    actions; ``sdc_gym.envs.sb3.SB3VecEnv`` gives stable-baselines3 the same batch.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"],
                                          "render_fps": 25}
    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = BEHAVIOR_DEFAULTS

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        self.batch = HighwayBehaviorWorld(config, envs=1)
        self.config = self.batch.config
        # The path-level env of this batch of one: its road, metrics, traffic and renderer.
        self.highway = HighwayLoopEnv.__new__(HighwayLoopEnv)
        self.highway._attach(self.batch.world, render_mode)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.highway.metadata["render_fps"]}
        self.perception = self.batch.perception[0]
        self.motion = self.batch.motion[0]
        self.executor = self.batch.executor[0]
        self.features = self.batch.features
        self.feature_names = self.features.names()
        self.action_space, self.observation_space = behavior_spaces(self.batch)
        self.decision_period_s = self.batch.decision_period_s
        self._ready = False
        self._scenario: Any = CONFIG  # the last reset option's, kept as a batch env's

    @property
    def road(self) -> Any:
        return self.batch.road

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32],
                                                              dict[str, Any]]:
        check_reset_options(options, type(self).__name__, (OPTION,))
        super().reset(seed=seed)
        self._scenario = scenario_option(options, self._scenario)
        self.batch.reset_at(0, self.np_random, self._scenario)
        self.highway._state_ready = self._ready = True
        info = self.batch.info(0, (), final=False)
        info["behavior"] = {"lane_changes": 0, "refused": 0, "aborted": 0}
        return self.batch.observations[0].copy(), info

    def decode(self, action: Any) -> HighwayDecision:
        """The decision an action stands for (``ValueError`` for an invalid one)."""
        return self.batch.decode(action)

    def step(self, action: Any) -> tuple[NDArray[np.float32], float, bool, bool,
                                         dict[str, Any]]:
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        reward, terminated, truncated, incidents = self.batch.step([action])
        done_t, done_f = bool(terminated[0]), bool(truncated[0])
        if self.render_mode == "human":
            self.render()
        info = self.batch.info(0, incidents[0], final=done_t or done_f, action=action)
        return self.batch.observations[0].copy(), float(reward[0]), done_t, done_f, info

    def scenario_snapshot(self) -> dict[str, Any]:
        """The env's state now as a scenario mapping (see
        :meth:`HighwayLoopEnv.scenario_snapshot`; the behavior stack's own state, its
        queue and executor, starts afresh in a replay)."""
        return self.highway.scenario_snapshot()

    def render(self) -> NDArray[np.uint8] | None:
        return self.highway.render()

    def close(self) -> None:
        self.highway.close()
