"""``sdc_gym/TrackLoopBehavior-v0``: the track loop at the level of go / stop decisions."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, require, resolve_config
from sdc_gym.envs.track_loop import TrackLoopEnv
from sdc_gym.stack.track.dbw_stack import dbw_stack_for_env
from sdc_gym.stack.track.decisions import (
    TRACK_ACTION_NAMES,
    TrackDecisionBehavior,
    TrackFeatures,
    action_decision,
)
from sdc_gym.stack.track.detector import GroundTruthLightSource
from sdc_gym.validation.env_configs import check_track_behavior_config
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT

ACTION_TYPES = ("discrete", "continuous")


class TrackLoopBehaviorEnv(gym.Env):
    """
    ## Description

    ``sdc_gym/TrackLoop-v0`` driven by the drive-by-wire reference stack
    (:mod:`sdc_gym.stack.track`: light detector, waypoint updater, pure pursuit, twist
    controller, each at its node rate), with the agent in the place of its behavior layer:
    the decision, once per ``decision_period_s``, of the cruise speed and whether to stop
    at the next stop line, given its distance and the light state the detector reports
    (the env's ground truth, debounced as the detector does). The rule-based
    ``StopAtRedLights`` is the baseline to beat: it never runs a red light and cruises at
    the limit.

    ## Action Space

    ``action: "discrete"`` (default): ``Discrete(4)``: go (at the limit), go at 75 %,
    go at 50 %, stop at the next stop line
    (:data:`~sdc_gym.stack.track.decisions.TRACK_ACTION_NAMES`). ``"continuous"``:
    ``Box(-1, 1, (2,))``: cruise speed (-1: 0, 1: the limit) and stop (> 0). Invalid
    actions raise ``ValueError``.

    ## Observation Space

    ``Box(float32, (12,))``: speed over the limit, distance to the next stop line and to
    where the car would stop, the light state one-hot, how long that state has been seen,
    the comfortable braking distance, whether full / comfortable braking can still stop
    before the line, and whether the car is stopping (table in
    :class:`~sdc_gym.stack.track.decisions.TrackFeatures`).

    ## Rewards

    The track env's reward summed over the decision's steps: progress along the path
    (``track.reward_progress`` defaults to 1 / steps per decision here, so about 1 per
    decision at the limit), plus incident penalties: red-light violation -5, collision
    and off-road -10, acceleration, jerk, speed -1 (``track.reward_incident``).

    ## Starting State, Episode End

    As ``TrackLoop-v0`` (``track.laps``, ``track.max_duration``); ``info`` has its keys
    (``summary`` with red-light violations, stops and overshoot at the end) plus
    ``behavior`` (the decision's name).

    ## Arguments

    ``gym.make("sdc_gym/TrackLoopBehavior-v0", config={...})``: ``track`` (any
    ``TrackLoop-v0`` key; ``observe_light_states`` is always on), ``decision_period_s``
    (a multiple of the track env's step), ``action``. Unknown keys raise ``ConfigError``.

    ## Version History

    * v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"],
                                          "render_fps": 1}
    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = {
        "track": {},                  # TrackLoop-v0 config
        "decision_period_s": 1.0,     # s between decisions
        "action": "discrete",         # "discrete" (Discrete(4)) or "continuous" (Box(2))
    }

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        owner = "TrackLoopBehavior-v0"
        self.config = cfg = resolve_config(self.DEFAULT_CONFIG, config, owner=owner)
        require(isinstance(cfg["track"], dict), owner, "track",
                "a mapping of TrackLoop-v0 config keys", cfg["track"])
        require(cfg["action"] in ACTION_TYPES, owner, "action", f"one of {ACTION_TYPES}",
                cfg["action"])
        check_track_behavior_config(cfg, owner)  # the track's step first: it is used here
        step_s = PHYSICS_DT * cfg["track"].get("steps_per_action", 1)
        ticks = cfg["decision_period_s"] / step_s
        if not (cfg["decision_period_s"] > 0 and round(ticks) >= 1
                and abs(ticks - round(ticks)) < 1e-9):
            raise ConfigError(f"{owner}: decision_period_s must be a positive multiple of "
                              f"the track env's step ({step_s:g} s), got "
                              f"{cfg['decision_period_s']!r}")
        self.ticks_per_decision = round(ticks)
        # Progress worth about 1 per decision at the limit (the track env's is 1 per step),
        # incident penalties unscaled.
        track_config = {"reward_progress": 1.0 / self.ticks_per_decision, **cfg["track"],
                        "observe_light_states": True}
        self.inner = TrackLoopEnv(track_config, render_mode=render_mode)
        self.render_mode = render_mode
        self.continuous = cfg["action"] == "continuous"
        self.features = TrackFeatures(abs(self.inner.params.decel_limit))
        self.behavior = TrackDecisionBehavior(self.features, continuous=self.continuous)
        self.stack = dbw_stack_for_env(self.inner, GroundTruthLightSource(),
                                       name="behavior_env_stack", behavior=self.behavior)
        self.observation_space = self.features.space
        self.action_space: spaces.Space[Any] = (
            spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32) if self.continuous
            else spaces.Discrete(len(TRACK_ACTION_NAMES)))
        self.feature_names = list(TrackFeatures.names)
        self._inner_obs: dict[str, Any] | None = None

    @property
    def track(self) -> Any:
        return self.inner.track

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32],
                                                              dict[str, Any]]:
        super().reset(seed=seed)
        self._inner_obs, info = self.inner.reset(seed=seed, options=options)
        self.stack.reset()
        info["behavior"] = {"decision": ""}
        return self.behavior.observe(self.stack.situation(self._inner_obs)), info

    def step(self, action: Any) -> tuple[NDArray[np.float32], float, bool, bool,
                                         dict[str, Any]]:
        if self._inner_obs is None:
            raise RuntimeError("call reset() before step()")
        # Validate now, not at the next updater cycle.
        action_decision(action, self.stack.situation(self._inner_obs), self.continuous)
        self.behavior.action = action
        total = 0.0
        terminated = truncated = False
        info: dict[str, Any] = {}
        for _ in range(self.ticks_per_decision):
            command = self.stack.act(self._inner_obs)
            self._inner_obs, reward, terminated, truncated, info = self.inner.step(command)
            total += reward
            if terminated or truncated:
                break
        decision = self.behavior.decision
        info["behavior"] = {"decision": decision.mode if decision else ""}
        observation = self.behavior.observe(self.stack.situation(self._inner_obs))
        return observation, total, terminated, truncated, info

    def render(self) -> NDArray[np.uint8] | None:
        return self.inner.render()

    def close(self) -> None:
        self.inner.close()
