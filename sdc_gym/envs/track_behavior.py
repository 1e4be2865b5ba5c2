"""``sdc_gym/TrackLoopBehavior-v0``: the track loop at the level of go / stop decisions."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from sdc_gym.envs.track_behavior_world import ACTION_TYPES, BEHAVIOR_DEFAULTS, TrackBehaviorWorld
from sdc_gym.envs.track_loop import TrackLoopEnv
from sdc_gym.scenarios.options import check_reset_options

__all__ = ["ACTION_TYPES", "TrackLoopBehaviorEnv"]


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
    (a multiple of the track env's step), ``action``, ``red_light_shield`` (default
    false: the rule's stops override a go, so that the policy learns the approach only;
    :mod:`~sdc_gym.stack.track.decisions`). Unknown keys raise ``ConfigError``.

    ## Version History

    * v0: initial version.

    ``gym.make_vec("sdc_gym/TrackLoopBehavior-v0", num_envs=E,
    vectorization_mode="vector_entry_point")`` runs E of these as one batch
    (:class:`~sdc_gym.envs.track_vector.TrackLoopBehaviorVectorEnv`); this env is its batch
    of one (:class:`~sdc_gym.envs.track_behavior_world.TrackBehaviorWorld`).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"],
                                          "render_fps": 1}
    DEFAULT_CONFIG: ClassVar[dict[str, Any]] = BEHAVIOR_DEFAULTS

    def __init__(self, config: dict[str, Any] | None = None,
                 render_mode: str | None = None) -> None:
        self.batch = TrackBehaviorWorld(config, envs=1)
        self.config = self.batch.config
        self.ticks_per_decision = self.batch.ticks_per_decision
        # The TrackLoop-v0 view of the same world (its attributes, summary and render).
        self.inner = TrackLoopEnv.over(self.batch.world, render_mode=render_mode)
        self.render_mode = render_mode
        self.continuous = self.batch.continuous
        self.features = self.batch.features
        self.observation_space = self.batch.observation_space
        self.action_space = self.batch.action_space
        self.feature_names = list(self.features.names)
        self._active = np.ones(1, dtype=bool)
        self._ready = False

    @property
    def track(self) -> Any:
        return self.inner.track

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32],
                                                              dict[str, Any]]:
        check_reset_options(options, type(self).__name__, ())  # no scenarios on a track
        super().reset(seed=seed)
        batch = self.batch
        batch.reset_at(0, self.np_random)
        self._ready = True
        info = batch.world.info(0, [], final=False)
        info["behavior"] = {"decision": ""}
        return batch.observations[0].copy(), info

    def step(self, action: Any) -> tuple[NDArray[np.float32], float, bool, bool,
                                         dict[str, Any]]:
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        batch = self.batch
        batch.set_actions((action,), (0,))  # checked now, not at the next updater cycle
        rewards, incidents = batch.step(self._active)
        terminated = bool(batch.world.state.terminated[0])
        truncated = bool(batch.world.state.truncated[0])
        if self.render_mode == "human":
            self.inner.render()
        info = batch.info(0, incidents[0], final=terminated or truncated)
        return batch.observations[0].copy(), float(rewards[0]), terminated, truncated, info

    def summary(self) -> dict[str, Any]:
        """The episode's summary so far (``info["summary"]`` at its end)."""
        return self.batch.world.summary(0)

    def render(self) -> NDArray[np.uint8] | None:
        return self.inner.render()

    def close(self) -> None:
        self.inner.close()
