"""Issue 26's remainder: a batch's sizes bounded as products (num_envs times each per-env
size) before any allocation, and every agent kind checked against the env before any
episode (named agents, ``external:``, ``capstone:``, and trained policies by their file
and spaces), each with its exact message."""

from __future__ import annotations

import shutil
from pathlib import Path

import gymnasium as gym
import pytest
import yaml

import sdc_gym  # noqa: F401
from sdc_agents.registry import check_agent_builds, check_agent_env
from sdc_gym.config import ConfigError
from sdc_gym.validation import bounds
from sdc_gym.validation.bounds import check_batch_sizes

ROOT = Path(__file__).resolve().parents[1]
HIGHWAY = "sdc_gym/HighwayLoop-v0"
TRACK = "sdc_gym/TrackLoop-v0"
DQN = "agents/highway/policies/dqn_highway.zip"


# ------------------------------------------------------------------------ batch products
@pytest.mark.parametrize("env_id, num_envs, config, message", [
    (HIGHWAY, 4096, {"map": "oval", "path_points": 10_000},
     "HighwayLoop-v0: num_envs x path_points must be at most 4,194,304 (points of the "
     "batch's paths), got 4,096 x 10,000 = 40,960,000; lower num_envs to at most 419 or "
     "path_points to at most 1,024"),
    (HIGHWAY, 4096, {"map": "oval", "traffic": {"car_count": 65, "spawn_range": 1000.0}},
     "HighwayLoop-v0: num_envs x traffic.car_count must be at most 262,144 (cars of the "
     "batch), got 4,096 x 65 = 266,240; lower num_envs to at most 4,032 or "
     "traffic.car_count to at most 64"),
    ("sdc_gym/HighwayLoopBehavior-v0", 4096,
     {"decision_frames": 50_000, "highway": {"map": "oval", "max_duration": 1000.0}},
     "HighwayLoopBehavior-v0: num_envs x decision_frames must be at most 1,048,576 "
     "(physics frames of one batch step: its per-frame buffers), got 4,096 x 50,000 = "
     "204,800,000; lower num_envs to at most 20 or decision_frames to at most 256"),
    (HIGHWAY, 512, {"map": "oval", "steps_per_action": 1000, "max_duration": 30.0,
                     "traffic": {"car_count": 40}},
     "HighwayLoop-v0: num_envs x traffic.car_count x steps_per_action must be at most "
     "16,777,216 (car updates of one step: its time), got 512 x 40 x 1,000 = 20,480,000; "
     "lower one of them"),
    (TRACK, 70, {"track": "site", "camera": {"enabled": True}},  # the original's 800 x 600
     "TrackLoop-v0: num_envs x camera.width x height must be at most 33,177,600 (camera "
     "pixels of one batch observation), got 70 x 480,000 = 33,600,000; lower num_envs to "
     "at most 69 or camera.width x height to at most 473,965"),
    ("sdc_gym/TrackLoopBehavior-v0", 4096, {"decision_period_s": 1000.0},
     "TrackLoopBehavior-v0: num_envs x frames per decision (decision_period_s / 0.02 s) "
     "must be at most 1,048,576 (physics frames of one batch step: its per-frame buffers), "
     "got 4,096 x 50,000 = 204,800,000; lower num_envs to at most 20 or frames per decision "
     "(decision_period_s / 0.02 s) to at most 256"),
])
def test_a_batchs_products_are_refused_before_any_allocation(env_id, num_envs, config,
                                                               message):
    with pytest.raises(ConfigError) as raised:
        gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                     config=config)
    assert str(raised.value) == message


def test_the_products_admit_their_bounds_and_every_single_env():
    check_batch_sizes("x", 4096, frames_per_step=256, path_points=1024, cars=16,
                      camera_pixels=8100)  # each product at its bound (16 x 256 x 4,096)
    with pytest.raises(ConfigError, match=r"num_envs x path_points .* got 4,096 x 1,025"):
        check_batch_sizes("x", 4096, frames_per_step=1, path_points=1025)
    # The batch of one at every single-env bound, but for its car updates.
    check_batch_sizes("x", 1, frames_per_step=bounds.MAX_STEP_FRAMES,
                      path_points=bounds.MAX_PATH_POINTS, cars=16,
                      camera_pixels=bounds.MAX_CAMERA_PIXELS)
    with pytest.raises(ConfigError, match=r"got 1 x 1,000 x 50,000 = 50,000,000"):
        check_batch_sizes("x", 1, frames_per_step=bounds.MAX_STEP_FRAMES,
                          cars=bounds.MAX_CAR_COUNT)
    assert bounds.MAX_BATCH_CAMERA_PIXELS == 33_177_600


def test_an_sb3_vec_env_is_bounded_by_the_same_products():
    from sdc_gym.envs.sb3 import SB3VecEnv

    with pytest.raises(ConfigError, match=r"^HighwayLoopBehavior-v0: num_envs x "
                       r"decision_frames must be at most 1,048,576"):
        SB3VecEnv("sdc_gym/HighwayLoopBehavior-v0", 4096,
                  {"decision_frames": 2000, "highway": {"map": "oval"}})


# ------------------------------------------------------------------------ agent kinds
@pytest.mark.parametrize("spec, env_id, message", [
    ("external:./path_planning", TRACK,
     "agent 'external:./path_planning' is an external planner (the original highway's path "
     "protocol): it drives sdc_gym/HighwayLoop-v0, not sdc_gym/TrackLoop-v0; the kinds for "
     "sdc_gym/TrackLoop-v0: a2c:, capstone:, dqn:, ppo:, qrdqn:, rllib:, sac:"),
    ("capstone:roslaunch launch/styx.launch", HIGHWAY,
     "agent 'capstone:roslaunch launch/styx.launch' is a capstone stack (the original "
     "track's styx server): it drives sdc_gym/TrackLoop-v0, not sdc_gym/HighwayLoop-v0; the "
     "kinds for sdc_gym/HighwayLoop-v0: a2c:, dqn:, external:, fsm:, ppo:, qrdqn:, rllib:, sac:"),
    (f"dqn:{DQN}", TRACK,
     f"policy 'dqn:{DQN}' was trained on sdc_gym/HighwayLoopBehavior-v0: it drives "
     "sdc_gym/HighwayLoop-v0, not sdc_gym/TrackLoop-v0"),
    (f"dqn:{DQN}", "sdc_gym/HighwayLoopBehavior-v0",
     f"agent 'dqn:{DQN}' is a trained policy (its behavior layer under the rule-based "
     "stack): it drives sdc_gym/HighwayLoop-v0, sdc_gym/TrackLoop-v0, not "
     "sdc_gym/HighwayLoopBehavior-v0; the kinds for sdc_gym/HighwayLoopBehavior-v0: none "
     "(a behavior env is driven by its policy: train.py evaluates it there)"),
    (f"ppo:{DQN}", HIGHWAY,
     f"policy 'ppo:{DQN}': dqn_highway.zip holds a policy of 'stable_baselines3.dqn.policies' "
     f"(an SB3 DQN model), not of PPO: give it as dqn:{DQN}"),
    ("dqn:/nonexistent.zip", HIGHWAY, "policy 'dqn:/nonexistent.zip': no model file at "
                                      "/nonexistent.zip"),
    ("rllib:/nonexistent", HIGHWAY, "policy 'rllib:/nonexistent': no RLlib checkpoint folder "
                                    "at /nonexistent"),
    ("dqn:pyproject.toml", HIGHWAY,
     f"policy 'dqn:pyproject.toml': {ROOT / 'pyproject.toml'} is not a stable-baselines3 "
     "model file (BadZipFile: 'File is not a zip file')"),
])
def test_every_agent_kind_is_checked_against_the_env(spec, env_id, message, monkeypatch):
    monkeypatch.chdir(ROOT)
    with pytest.raises(ValueError) as raised:
        check_agent_env(spec, env_id)
    assert str(raised.value) == message


def test_a_policy_whose_spaces_do_not_fit_is_refused_when_built(tmp_path):
    """The committed DQN (Discrete(9)) under a training config of continuous actions."""
    model = tmp_path / "dqn_highway.zip"
    shutil.copy(ROOT / DQN, model)
    config = yaml.safe_load((ROOT / DQN).with_suffix(".yaml").read_text())
    config["config"]["action"] = "continuous"
    model.with_suffix(".yaml").write_text(yaml.safe_dump(config))
    check_agent_env(f"dqn:{model}", HIGHWAY)  # the file and its env fit
    env = gym.make(HIGHWAY, config={"max_duration": 5.0})
    with pytest.raises(ValueError) as raised:
        check_agent_builds(f"dqn:{model}", env)
    assert str(raised.value) == (
        "the policy's action space is Discrete(9); HighwayLoopBehavior-v0 on this road with "
        "action 'continuous' has Box(-1.0, 1.0, (2,), float32) (was it trained on another "
        "env or config?)")
    check_agent_builds(f"dqn:{ROOT / DQN}", env)  # the committed one fits
    env.close()


def test_evaluate_refuses_a_policy_of_another_env_before_any_episode(tmp_path):
    import evaluate

    with pytest.raises(SystemExit) as raised:
        evaluate.main(["--agents", "external:./path_planning", "--env", TRACK, "--output",
                       str(tmp_path / "run"), "--episodes", "1", "--workers", "1",
                       "--no-progress"])
    assert str(raised.value).startswith("--agents: agent 'external:./path_planning' is an "
                                        "external planner")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("algorithm", ["ppo", "a2c"])
def test_ppo_and_a2c_share_a_policy_module_and_are_told_apart(tmp_path, algorithm):
    """PPO and A2C both save stable_baselines3.common.policies' ActorCriticPolicy: a PPO
    zip was refused as "an SB3 COMMON model" before PPO's clip_range told them apart."""
    import stable_baselines3

    behavior = gym.make("sdc_gym/HighwayLoopBehavior-v0")
    model = getattr(stable_baselines3, algorithm.upper())("MlpPolicy", behavior, n_steps=8,
                                                          device="cpu")
    path = tmp_path / f"{algorithm}_policy.zip"
    model.save(path)
    behavior.close()
    path.with_suffix(".yaml").write_text("env: sdc_gym/HighwayLoopBehavior-v0\nconfig: {}\n")
    check_agent_env(f"{algorithm}:{path}", HIGHWAY)
    other = "a2c" if algorithm == "ppo" else "ppo"
    with pytest.raises(ValueError) as raised:
        check_agent_env(f"{other}:{path}", HIGHWAY)
    assert str(raised.value) == (
        f"policy '{other}:{path}': {path.name} holds a policy of "
        f"'stable_baselines3.common.policies' (an SB3 {algorithm.upper()} model), not of "
        f"{other.upper()}: give it as {algorithm}:{path}")
