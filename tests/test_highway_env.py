"""HighwayLoop-v0: API conformance, the original's ego semantics, validation, determinism."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_agents.lane_keeping import LaneKeepingDriver
from sdc_gym.config import ConfigError
from sdc_gym.units import MPS_TO_MPH

from .conftest import HIGHWAY_MAP_FILE

ENV_ID = "sdc_gym/HighwayLoop-v0"


def make(**config):
    return gym.make(ENV_ID, config=config)


def straight_path(env, speed: float, count: int, start_s: float | None = None,
                  d: float = 6.0) -> np.ndarray:
    """Points every speed * 0.02 m along the lane at offset d, starting one step ahead."""
    base = env.unwrapped
    s0 = base._s if start_s is None else start_s
    s = s0 + speed * 0.02 * np.arange(1, count + 1)
    return base.road.reference.to_xy(s, np.full(count, d))


def test_gymnasium_and_sb3_check_env():
    from gymnasium.utils.env_checker import check_env as gym_check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = make(traffic={"car_count": 6})
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)


def test_unknown_config_key_lists_valid_keys():
    with pytest.raises(ConfigError, match=r"unknown config key 'lapz'.*Valid keys: .*laps"):
        make(lapz=2)
    with pytest.raises(ConfigError, match=r"traffic: unknown config key 'cars'"):
        make(traffic={"cars": 3})


@pytest.mark.parametrize(
    ("action", "message"),
    [
        ([[np.nan, 1.0]], "not finite"),
        ([[1e9, 1e9]], "outside the action bounds"),
        ([["a", "b"]], "a real dtype"),
        (np.zeros((3, 3)), "shape"),
        (np.full((51, 2), 500.0), "at most path_points = 50"),
    ],
)
def test_bad_paths_are_rejected_with_clear_errors(action, message):
    env = make(traffic={"car_count": 2})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


def test_ego_is_placed_on_each_point_facing_the_next():
    env = make(steps_per_action=3, latency_steps=0, traffic={"car_count": 0})
    env.reset(seed=0)
    path = straight_path(env, 20.0, 10)
    obs, *_ = env.step(path)
    assert np.allclose(obs["ego"][:2], path[2], atol=1e-3)
    expected_yaw = np.arctan2(*(path[3] - path[2])[::-1])
    assert obs["ego"][4] == pytest.approx(expected_yaw, abs=1e-5)
    assert obs["ego"][5] == pytest.approx(20.0, rel=1e-4)
    assert obs["previous_path_count"] == 7
    assert np.allclose(obs["previous_path"][:7], path[3:], atol=1e-3)


def test_latency_keeps_the_old_path_until_the_new_one_arrives():
    env = make(steps_per_action=3, latency_steps=4, traffic={"car_count": 0})
    obs, _ = env.reset(seed=0)
    start = obs["ego"][:2].copy()
    path = straight_path(env, 10.0, 20)
    obs, *_ = env.step(path)
    assert np.allclose(obs["ego"][:2], start)  # 3 frames, path not arrived yet
    obs, *_ = env.step(path[3:])  # arrives after frame 4: frames 5 and 6 consume 2 points
    assert np.allclose(obs["ego"][:2], path[1], atol=1e-3)


def test_new_path_drops_points_behind_the_car_and_the_one_it_stands_on():
    env = make(steps_per_action=3, latency_steps=0, traffic={"car_count": 0})
    env.reset(seed=0)
    path = straight_path(env, 15.0, 20)
    env.step(path)  # the car is on path[2]
    # Resend the whole path: path[0..2] are dropped (the car stands on path[2]), so the
    # car moves on to path[3..5] at full speed, with no frame standing still.
    obs, *_ = env.step(path)
    assert np.allclose(obs["ego"][:2], path[5], atol=1e-3)
    assert obs["ego"][5] == pytest.approx(15.0, rel=0.01)


def test_lock_step_observation_shows_the_path_just_applied():
    env = make(steps_per_action=3, traffic={"car_count": 0})  # latency = 3 frames
    env.reset(seed=0)
    path = straight_path(env, 15.0, 20)
    obs, *_ = env.step(path)  # arrives after the 3 frames, before the observation
    assert obs["previous_path_count"] == 20
    obs, *_ = env.step(path)  # frames 4-6 consume path[0..2]; the resend drops them
    assert np.allclose(obs["ego"][:2], path[2], atol=1e-3)
    assert obs["previous_path_count"] == 17


def test_padding_by_repeating_the_last_point_and_short_paths():
    env = make(latency_steps=0, traffic={"car_count": 0})
    env.reset(seed=0)
    path = straight_path(env, 10.0, 8)
    padded = np.vstack([path, np.repeat(path[-1:], 42, axis=0)])
    obs, *_ = env.step(padded)
    assert obs["previous_path_count"] == 5
    env2 = make(latency_steps=0, traffic={"car_count": 0})
    env2.reset(seed=0)
    obs2, *_ = env2.step(path.tolist())
    assert obs2["previous_path_count"] == 5
    assert np.array_equal(obs["ego"], obs2["ego"])


def test_running_out_of_path_stops_dead_and_is_an_acceleration_incident():
    env = make(latency_steps=0, traffic={"car_count": 0})
    env.reset(seed=0)
    speed = 0.0
    # Accelerate gently to 20 m/s, then send nothing more.
    s = env.unwrapped._s
    points = []
    for _ in range(1200):
        speed = min(speed + 2.0 * 0.02, 20.0)
        s += speed * 0.02
        points.append(s)
    lane = env.unwrapped.road.reference.to_xy(np.array(points), np.full(len(points), 6.0))
    index = 0
    info = {}
    while index + 50 <= len(lane):
        count = int(env.unwrapped._remaining_path().shape[0])
        send = lane[index - count:index + 50 - count] if index >= count else lane[:50]
        obs, _, _, _, info = env.step(send)
        index += 3
        if obs["ego"][5] > 19.9:
            break
    assert info["incidents_acceleration"] == 0
    for _ in range(40):
        obs, _, _, _, info = env.step(np.zeros((0, 2)))
    assert obs["ego"][5] == 0.0
    assert info["incidents_acceleration"] >= 1


def test_collision_is_seen_and_terminates():
    env = make(latency_steps=0)
    obs, _ = env.reset(seed=1)
    reference = env.unwrapped.road.reference
    gaps = reference.s_difference(obs["sensor_fusion"][:, 5], obs["ego"][2])
    assert (gaps > 0).any()
    car = obs["sensor_fusion"][int(np.argmax(np.where(gaps > 0, -gaps, -np.inf)))]
    # Jump onto the nearest car ahead and ride with it (a teleport, but the contact must
    # be seen; points ahead of the ego are all kept by the nearest-point rule).
    times = 0.02 * np.arange(1, 11)
    path = np.column_stack([car[1] + car[3] * times, car[2] + car[4] * times])
    obs, reward, terminated, truncated, info = env.step(path)
    assert terminated and not truncated
    assert info["incidents_collision"] == 1
    assert info["termination_reason"] == "collision"
    assert info["summary"]["incidents"]["collision"] == 1
    # Reward = progress / (speed limit * step duration) + the penalty of each new incident.
    penalties = {"collision": -10.0, "acceleration": -1.0, "jerk": -1.0, "speed": -1.0,
                 "lane": -1.0, "off_road": -1.0}
    assert "collision" in info["new_incidents"]
    expected = info["progress"] / (22.352 * 0.06) + sum(
        penalties[kind] for kind in info["new_incidents"])
    assert reward == pytest.approx(expected, rel=1e-9)


def test_telemetry_matches_the_original_fields_and_units():
    env = make(latency_steps=0)
    env.reset(seed=2)
    obs, *_, info = env.step(straight_path(env, 20.0, 30))
    telemetry = info["telemetry"]
    assert list(telemetry) == ["x", "y", "yaw", "speed", "s", "d", "previous_path_x",
                               "previous_path_y", "end_path_s", "end_path_d", "sensor_fusion"]
    assert telemetry["speed"] == pytest.approx(obs["ego"][5] * MPS_TO_MPH, rel=1e-6)
    assert telemetry["speed"] == pytest.approx(20.0 * MPS_TO_MPH, rel=0.01)
    assert telemetry["yaw"] == pytest.approx(np.degrees(obs["ego"][4]) % 360, abs=1e-3)
    assert len(telemetry["previous_path_x"]) == obs["previous_path_count"]
    assert len(telemetry["sensor_fusion"]) == 12
    row = telemetry["sensor_fusion"][0]
    assert isinstance(row[0], int) and len(row) == 7
    assert np.allclose(row[1:], obs["sensor_fusion"][0][1:], rtol=1e-6, atol=1e-3)
    # 7 significant digits, like the original's float printing.
    assert telemetry["x"] == float(f"{telemetry['x']:.7g}")
    # Built lazily, but a plain dict for json and for pickling (vector envs).
    import json
    import pickle

    assert json.loads(json.dumps(dict(telemetry))) == dict(telemetry)
    assert pickle.loads(pickle.dumps(telemetry)) == dict(telemetry)


def test_same_seed_same_actions_same_episode_bit_for_bit():
    def run(seed):
        env = make()
        driver = LaneKeepingDriver(env.unwrapped.road)
        obs, _ = env.reset(seed=seed)
        frames = []
        for _ in range(200):
            obs, reward, *_ = env.step(driver.act(obs))
            frames.append((obs["ego"].tobytes(), obs["sensor_fusion"].tobytes(), reward))
        return frames

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_info_has_the_same_keys_every_step():
    env = make(max_duration=1.0)
    driver = LaneKeepingDriver(env.unwrapped.road)
    obs, info = env.reset(seed=0)
    keys = set(info)
    while True:
        obs, _, terminated, truncated, info = env.step(driver.act(obs))
        assert set(info) == keys
        if terminated or truncated:
            break
    assert truncated and info["termination_reason"] == "max_duration"
    assert info["summary"]["time"] == pytest.approx(1.02, abs=0.07)


def test_original_map_from_a_path_starts_at_the_original_state():
    env = make(map=str(HIGHWAY_MAP_FILE))
    obs, _ = env.reset(seed=0)
    assert env.unwrapped.road.length == pytest.approx(6945.554, rel=1e-3)
    # The original's start point is x = 909.48, y = 1128.67 (coarse s, d = 124.8336,
    # 6.164833); on the exact reference line that point is s = 124.935, d = 6.098.
    assert obs["ego"][0] == pytest.approx(909.48, abs=0.01)
    assert obs["ego"][1] == pytest.approx(1128.67, abs=0.01)
    assert obs["ego"][2] == pytest.approx(124.935, abs=1e-3)
    assert obs["ego"][3] == pytest.approx(6.098, abs=1e-3)


def test_lane_keeping_driver_completes_a_lap_without_incident():
    env = make()
    driver = LaneKeepingDriver(env.unwrapped.road)
    obs, _ = env.reset(seed=0)
    while True:
        obs, _, terminated, truncated, info = env.step(driver.act(obs))
        if terminated or truncated:
            break
    summary = info["summary"]
    assert info["is_success"] and summary["laps"] == 1
    assert summary["incident_total"] == 0, summary["incidents"]
    length = env.unwrapped.road.length
    # Laps count from the start line: a lap is one loop length of progress.
    assert summary["lap_times"][0] == pytest.approx(summary["time"], abs=0.1)
    assert length / summary["lap_times"][0] > 15.0  # a real lap, not a shortcut


def test_rgb_render_and_record_video(tmp_path):
    from gymnasium.wrappers import RecordVideo

    env = gym.make(ENV_ID, config={"max_duration": 1.0}, render_mode="rgb_array")
    env = RecordVideo(env, str(tmp_path), episode_trigger=lambda episode: True,
                      disable_logger=True)
    driver = LaneKeepingDriver(env.unwrapped.road)
    obs, _ = env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (600, 600, 3) and frame.dtype == np.uint8
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(driver.act(obs))
        done = terminated or truncated
    env.close()
    assert list(tmp_path.glob("*.mp4"))


def test_human_render_mode_runs_headless(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = gym.make(ENV_ID, config={"max_duration": 0.3}, render_mode="human")
    driver = LaneKeepingDriver(env.unwrapped.road)
    obs, _ = env.reset(seed=0)
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(driver.act(obs))
        done = terminated or truncated
    assert env.render() is None
    env.close()
    env.close()  # safe twice
