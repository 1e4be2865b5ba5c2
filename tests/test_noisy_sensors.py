"""configs/highway_noisy_sensors.yaml: Kalman tracking repairs what the noisy sensors break.

Under that config the unfiltered FSM planner collides in about half of the 1-lap episodes
(mostly lane changes into a neighbour missing from one frame's sensor fusion), the tracked
one in none (``evaluate.py --config configs/highway_noisy_sensors.yaml``, seeds 0-9; too
slow for a test). This test drives the tracked planner for 60 simulated seconds on two
seeds, runs an untracked perception on the same observations, and compares both world
models with the env's ground truth (``env.unwrapped.traffic``) for the cars within 60 m.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import sdc_gym  # noqa: F401
from sdc_agents.registry import make_agent
from sdc_gym.stack.highway.perception import Perception

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "highway_noisy_sensors.yaml"
NEAR = 60.0  # m: the cars the planner brakes and changes lanes for
SECONDS = 60.0


def world_model_errors(agent_name: str, seed: int) -> tuple[dict[str, dict], dict]:
    """Per perception ("raw", "tracked"): gap and speed errors of the near cars, how many
    near cars were missing and how many were put in the wrong lane; and the summary."""
    data = yaml.safe_load(CONFIG.read_text(encoding="utf-8"))
    env = gym.make(data["env"], config=dict(data["config"], max_duration=SECONDS))
    unwrapped = env.unwrapped
    length, width = unwrapped.road.length, unwrapped.road.lane_width
    agent = make_agent(agent_name, env)
    agent.reset()
    assert agent.perception.params.tracking
    raw = Perception(unwrapped.road,
                     dataclasses.replace(agent.perception.params, tracking=False))
    stats = {name: {"gap": [], "speed": [], "missing": 0, "wrong_lane": 0, "count": 0}
             for name in ("raw", "tracked")}
    observation, _ = env.reset(seed=seed)
    step = 0
    while True:
        action = agent.act(observation)
        worlds = {"tracked": agent.world, "raw": raw.perceive(observation, agent.world.time)}
        traffic = unwrapped.traffic
        if step >= 20:  # let the tracks settle (1.2 s)
            gap = (traffic.s - agent.world.ego_s + 0.5 * length) % length - 0.5 * length
            near = np.abs(gap) < NEAR
            truth = list(zip(traffic.ids[near].tolist(), gap[near].tolist(),
                             traffic.speed[near].tolist(), traffic.d[near].tolist(),
                             strict=True))
            for name, world in worlds.items():
                seen = {car.id: car for car in world.cars}
                st = stats[name]
                for car_id, true_gap, true_speed, true_d in truth:
                    st["count"] += 1
                    car = seen.get(car_id)
                    if car is None:
                        st["missing"] += 1
                        continue
                    st["gap"].append(car.gap - true_gap)
                    st["speed"].append(car.speed - true_speed)
                    st["wrong_lane"] += math.floor(car.d / width) != math.floor(true_d / width)
        observation, _, terminated, truncated, info = env.step(action)
        step += 1
        if terminated or truncated:
            break
    env.close()
    return stats, info["summary"]


def rms(values: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


@pytest.mark.parametrize(("agent_name", "seed"), [("fsm_bold_kf", 0),
                                                  ("fsm_conservative_kf", 1)])
def test_tracking_fixes_gaps_speeds_dropouts_and_lanes_under_noisy_sensors(agent_name, seed):
    stats, summary = world_model_errors(agent_name, seed)
    raw, tracked = stats["raw"], stats["tracked"]
    assert raw["count"] == tracked["count"] > 2000
    # The config's noise reaches the raw world model unfiltered ...
    assert rms(raw["gap"]) == pytest.approx(1.0, rel=0.15)
    assert rms(raw["speed"]) == pytest.approx(1.0, rel=0.15)
    assert raw["missing"] / raw["count"] > 0.01  # 2 % dropouts
    assert raw["wrong_lane"] / raw["count"] > 0.02  # 1 m of d noise crosses lane lines
    # ... and the Kalman filter removes most of it.
    assert rms(tracked["gap"]) < 0.4 * rms(raw["gap"])
    assert rms(tracked["speed"]) < 0.5 * rms(raw["speed"])
    assert max(map(abs, tracked["gap"])) < 2.0 < max(map(abs, raw["gap"]))
    assert tracked["missing"] / tracked["count"] < 0.002  # dropouts are predicted through
    assert tracked["wrong_lane"] < 0.1 * raw["wrong_lane"]
    # The tracked planner drives the minute without incident.
    assert summary["termination_reason"] == "max_duration"
    assert not any(summary["incidents"].values()), summary["incidents"]
