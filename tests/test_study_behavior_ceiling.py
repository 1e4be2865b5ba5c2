"""The ceiling study's clairvoyant planner (``benchmarks/study_behavior_ceiling.py``):
its look-ahead leaves the env untouched, scores a rollout by the distance a direct drive
gets, and with foresight avoids a collision that lane keeping has."""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import study_behavior_ceiling as ceiling

from sdc_gym.scenarios.library import library_path

CUT_IN = {"highway": {"scenario": str(library_path("stress_cut_in_10m"))},
          "safety_shield": False}


def _env(config=None):
    return gym.make(ceiling.ENV_ID, config=config or {}).unwrapped


def test_planning_leaves_the_env_as_it_was():
    """Two envs of one seed; one plans (nine rollouts of copies), then both take the same
    decisions: their observations stay bit for bit equal."""
    planned, untouched = _env(), _env()
    planned.reset(seed=7)
    untouched.reset(seed=7)
    ceiling.plan(planned, ceiling.Settings(horizon_s=1.0, replan=1, hold=2), incidents=0)
    for action in (3, 0, 4, 3, 3, 6, 5, 3):
        a = planned.step(action)[0]
        b = untouched.step(action)[0]
        np.testing.assert_array_equal(a, b)


def test_rollout_score_is_the_distance_of_the_same_drive():
    """keep/cruise held for 6 decisions scores the distance a same-seed env reports after
    6 keep/cruise steps of its own."""
    env, direct = _env(), _env()
    env.reset(seed=3)
    direct.reset(seed=3)
    score = ceiling.rollout_score(env, ceiling.KEEP_CRUISE,
                                  ceiling.Settings(hold=2), steps=6, incidents=0)
    for _ in range(6):
        info = direct.step(ceiling.KEEP_CRUISE)[4]
    assert score == float(info["distance"])
    assert score > 0.0


def _drive(env, choose, steps: int = 200) -> tuple[dict, int]:
    """Step until the episode ends; the last info and the number of decisions taken."""
    incidents = 0
    for k in range(steps):
        _, _, terminated, truncated, info = env.step(choose(env, k, incidents))
        incidents = int(info["incidents"])
        if terminated or truncated:
            return info, k + 1
    raise AssertionError(f"the scenario did not end in {steps} decisions")


def test_foresight_avoids_the_cut_in_that_lane_keeping_hits():
    """Shield off, a car cuts in 10 m ahead and brakes hard: keep/cruise collides within
    3 s; the planner (6 s horizon) sees it coming and ends the scenario without one."""
    keeping = _env(CUT_IN)
    keeping.reset(seed=0)
    info, decisions = _drive(keeping, lambda env, k, incidents: ceiling.KEEP_CRUISE)
    assert info["incidents"] >= 1
    assert decisions * keeping.decision_period_s < 3.5

    settings = ceiling.Settings(horizon_s=6.0, replan=2, hold=4)
    planning = _env(CUT_IN)
    planning.reset(seed=0)
    chosen: list[int] = []

    def choose(env, k, incidents):
        if k % settings.replan == 0:
            chosen.append(ceiling.plan(env, settings, incidents))
        return chosen[-1]

    info, decisions = _drive(planning, choose)
    assert info["incidents"] == 0
    assert decisions * planning.decision_period_s >= 14.0  # ran the scenario's 15 s out
    assert any(action != ceiling.KEEP_CRUISE for action in chosen)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("replan", 0, "replan must be >= 1, got 0"),
    ("hold", -2, "hold must be >= 1, got -2"),
    ("horizon_s", 0.0, "horizon_s must be > 0, got 0.0"),
])
def test_settings_errors_name_the_field(field, value, message):
    with pytest.raises(ValueError, match=message):
        ceiling.Settings(**{field: value})
