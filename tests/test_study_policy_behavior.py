"""The policy-behavior study (``benchmarks/study_policy_behavior.py``): its counts are the
single env's own for the same actions, and a fresh PPO policy's entropy is the uniform
distribution's ln 9."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import study_policy_behavior as study

from sdc_gym.stack.highway.decisions import ACTION_NAMES
from sdc_training.validation_laps import lap_config

DURATION_S = 40.0
SEED = 2000


class Constant:
    """A model that always picks one action (the SB3 ``predict`` interface)."""

    def __init__(self, action: int) -> None:
        self.action = action

    def predict(self, observations, deterministic=True):
        return np.full(len(observations), self.action), None


def _single_env_drive(action: int, seed: int) -> tuple[dict, dict]:
    """The single env driven with one action to its end: (summary, behavior counters)."""
    env = gym.make(study.ENV_ID, config=lap_config(study.ENV_ID, {}, DURATION_S))
    env.reset(seed=seed)
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    env.close()
    return info["summary"], info["behavior"]


@pytest.mark.parametrize("name", ["keep/cruise", "left/cruise"])
def test_the_counts_are_the_single_envs_for_the_same_actions(name):
    """Two seeds, one constant action: the study's mph, counters and shares equal what the
    single env reports for each seed driven alone."""
    action = ACTION_NAMES.index(name)
    row = study.study(name, Constant(action), {}, SEED, 2, slow_mph=45.0,
                      max_duration=DURATION_S)
    singles = [_single_env_drive(action, SEED + i) for i in range(2)]
    assert row.mph == pytest.approx(np.mean([s["mean_speed_mph"] for s, _ in singles]),
                                    abs=1e-9)
    for key in study.COUNTERS:
        assert row.per_lap[key] == pytest.approx(np.mean([b[key] for _, b in singles]))
    lane = name.split("/")[0]
    assert row.lane_shares()[lane] == 1.0 and row.speed_shares()["cruise"] == 1.0
    assert row.action_counts.sum() == row.action_counts[action] > 0
    assert row.entropy is None
    if lane == "keep":
        assert row.per_lap["lane_changes"] == row.per_lap["refused"] == 0
    else:  # asking left every decision: the shield refuses most asks, some are taken
        assert row.per_lap["refused"] > 0 and row.per_lap["lane_changes"] >= 1


def test_a_fresh_ppo_policy_is_uniform_over_the_nine_actions():
    """SB3 initialises PPO's action head with gain 0.01, so before training its entropy
    is ln 9 = 2.197 nats on every observation."""
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", gym.make(study.ENV_ID), seed=0, device="cpu")
    row = study.study("fresh", model, {}, SEED, 2, slow_mph=45.0, max_duration=10.0)
    assert row.entropy == pytest.approx(math.log(len(ACTION_NAMES)), abs=0.01)


def test_a_model_spec_names_its_kind():
    assert study.parse_spec("dqn:runs/x/model.zip") == ("dqn", "runs/x/model.zip")
    with pytest.raises(ValueError, match=r"'bogus:x.zip'.*KIND one of \['ppo'"):
        study.parse_spec("bogus:x.zip")
    with pytest.raises(ValueError, match="expected KIND:PATH"):
        study.parse_spec("model.zip")
