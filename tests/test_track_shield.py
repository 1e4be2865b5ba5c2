"""The track behavior env's red-light shield (``red_light_shield``): the rule's stops
override a go, in the batched kernel and in the executor a trained policy drives
``TrackLoop-v0`` with, and both drive alike."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError
from sdc_gym.lights import GREEN, RED
from sdc_gym.stack.track.dbw_stack import dbw_stack_for_env
from sdc_gym.stack.track.decisions import TrackDecisionBehavior, TrackFeatures
from sdc_gym.stack.track.detector import GroundTruthLightSource

TRACK = "sdc_gym/TrackLoopBehavior-v0"
FIRST_LINE_S = 230.0  # the default track's first stop line
SIM_FRONT_OFFSET_M = 4.0
GO, GO_50 = 0, 2
# The first light red for 12 s, then green; the car starts 80 m before its line.
RED_THEN_GREEN = {"start_s": FIRST_LINE_S - 80.0,
                  "lights": {"script": [[[0.0, RED], [12.0, GREEN]]] + [None] * 7}}


def test_go_under_the_shield_stops_at_a_red_line_and_without_it_runs_the_light():
    config = {"start_s": FIRST_LINE_S - 80.0, "max_duration": 30.0,
              "lights": {"script": [RED] + [None] * 7}}
    ends = {}
    for shield in (True, False):
        env = gym.make(TRACK, config={"track": config, "red_light_shield": shield})
        env.reset(seed=0)
        modes = set()
        for _ in range(30):
            info = env.step(GO)[-1]
            modes.add(info["behavior"]["decision"])
        ends[shield] = info
        assert ("stop_red" in modes) == shield  # the rule's stop, executed by the shield
    stopped = ends[True]
    assert stopped["incidents_red_light"] == 0 and stopped["speed"] == 0.0
    assert 0.0 < FIRST_LINE_S - (stopped["s"] + SIM_FRONT_OFFSET_M) < 2.0  # the stack's gap
    assert ends[False]["incidents_red_light"] == 1 and ends[False]["s"] > FIRST_LINE_S


def test_the_shield_keeps_the_actions_speed_and_releases_at_green():
    env = gym.make(TRACK, config={"track": {**RED_THEN_GREEN, "max_duration": 40.0},
                                  "red_light_shield": True})
    env.reset(seed=0)
    speeds, decisions = [], []
    for _ in range(40):
        _, _, _, _, info = env.step(GO_50)
        speeds.append(info["speed"])
        decisions.append(info["behavior"]["decision"])
    assert "stop_red" in decisions and decisions[-1] == "go_50"  # shielded, then released
    assert info["incidents_red_light"] == 0 and info["s"] > FIRST_LINE_S
    assert max(speeds) < 0.5 * 11.11 + 0.3  # never above go_50's cruise speed


def test_policy_executor_on_the_track_env_drives_as_the_behavior_env_under_the_shield():
    """A fixed action sequence through ``TrackDecisionBehavior`` (what ``evaluate.py``'s
    policy agent runs) on ``TrackLoop-v0`` and through the batched kernel of
    ``TrackLoopBehavior-v0`` gives the same drive."""
    actions = [GO] * 3 + [GO_50] * 4 + [GO] * 30
    track = {**RED_THEN_GREEN, "max_duration": 60.0}
    behavior = gym.make(TRACK, config={"track": track, "red_light_shield": True})
    behavior.reset(seed=3)
    path = gym.make("sdc_gym/TrackLoop-v0", config={**track, "observe_light_states": True})
    obs, _ = path.reset(seed=3)
    queue = iter(actions)
    executor = TrackDecisionBehavior(
        TrackFeatures(abs(path.unwrapped.params.decel_limit)),
        chooser=lambda _: next(queue), red_light_shield=True)
    agent = dbw_stack_for_env(path, GroundTruthLightSource(), behavior=executor,
                              name="shielded_executor")
    agent.reset()
    for action in actions[:-1]:
        _, _, _, _, expected = behavior.step(action)
        for _ in range(50):  # one decision: 50 steps of 0.02 s
            obs, _, _, _, info = path.step(agent.act(obs))
        assert info["s"] == pytest.approx(expected["s"], abs=1e-6)
        assert info["speed"] == pytest.approx(expected["speed"], abs=1e-6)
    assert info["incidents_red_light"] == 0 and info["s"] > FIRST_LINE_S


def test_the_shield_flag_must_be_a_bool():
    with pytest.raises(ConfigError, match="red_light_shield"):
        gym.make(TRACK, config={"red_light_shield": "yes"})
    obs, _ = gym.make(TRACK, config={"red_light_shield": True}).reset(seed=0)
    assert np.asarray(obs).shape == (12,)
