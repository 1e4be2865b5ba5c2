"""TrackLoop-v0: API conformance, determinism, validation, stop lines, episode ends, manual
override, a lap on the site track, the original data, rendering."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError
from sdc_gym.lights import GREEN, RED, YELLOW
from sdc_gym.metrics.track_metrics import TRACK_INCIDENT_KINDS

from .conftest import UDACITY

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

ENV_ID = "sdc_gym/TrackLoop-v0"
DT = 0.02
FIRST_LINE_S = 230.0  # the default track's first stop line (layout: 230 m into straight 0)
SIM_FRONT_OFFSET_M = 4.0  # sim car: wheel base 3 m + front overhang 1 m


def make(render_mode=None, **config):
    return gym.make(ENV_ID, config=config, render_mode=render_mode)


def act(throttle=0.0, brake=0.0, steering=0.0):
    return np.array([throttle, brake, steering], dtype=np.float32)


class PursuitController:
    """Pure pursuit on the track's path and a proportional speed loop: the test's driver."""

    def __init__(self, env, target_speed: float) -> None:
        base = env.unwrapped
        self.line, self.car, self.target = base.track.reference, base.params, target_speed
        self.s: float | None = None

    def act(self, obs) -> np.ndarray:
        x, y, yaw = obs["pose"].tolist()
        speed = float(obs["velocity"][0])
        guess = self.s if self.s is not None else float(self.line.to_frenet(np.array([x, y]))[0])
        (self.s,), _ = self.line.project_few([[x, y]], [guess])
        tx, ty, *_ = self.line.line_frames_few([self.s + max(6.0, speed)])[0]
        dx, dy = tx - x, ty - y
        lateral = -math.sin(yaw) * dx + math.cos(yaw) * dy  # left of the car
        wheel = math.atan(self.car.wheel_base * 2.0 * lateral / (dx * dx + dy * dy))
        limit = self.car.max_steer_angle
        steering = min(max(self.car.steer_ratio * wheel, -limit), limit)
        error = self.target - speed
        return act(min(max(0.5 * error, 0.0), 1.0), min(max(-300.0 * error, 0.0), 1000.0),
                   steering)


def run_until_done(env, policy, max_steps: int):
    obs, info = env.reset(seed=0)
    for _ in range(max_steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            return obs, info, terminated, truncated
    raise AssertionError(f"episode did not end within {max_steps} steps")


# ------------------------------------------------------------------ API conformance
# Physical units (throttle, N m, rad) by design, not the normalised Box the checker suggests.
@pytest.mark.filterwarnings("ignore:.*symmetric and normalized space")
@pytest.mark.parametrize("config", [
    {},
    {"camera": {"enabled": True, "preset": "training"}, "observe_light_states": True,
     "obstacles": {"count": 2}, "manual": {"mode": "random"}},
])
def test_gymnasium_and_sb3_check_env(config):
    from gymnasium.utils.env_checker import check_env as gym_check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = make(**config)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    if config:
        obs, _ = env.reset(seed=0)
        assert obs["camera"].shape == (150, 200, 3) and obs["camera"].dtype == np.uint8
        assert obs["light_states"].shape == (8,) and obs["obstacles"].shape == (2, 2)


def test_spaces_bounds_and_vehicle_preset_follow_the_track():
    sim, site = make().unwrapped, make(track="site").unwrapped
    assert (sim.params.name, site.params.name) == ("sim", "site")
    # Tyre-locking brake torque: friction 1.0 * mass * g * wheel radius.
    assert sim.action_space.high[1] == pytest.approx(1080.0 * 9.81 * 0.335, rel=1e-6)
    assert site.action_space.high[1] == pytest.approx(
        (1736.35 + 13.5 * 2.858) * 9.81 * 0.2413, rel=1e-6)
    # Steering: the car's lock (8.2 rad for the original's car, 8 rad for the site car).
    assert sim.action_space.high[2] == np.float32(8.2) and sim.action_space.low[2] == (
        np.float32(-8.2))
    assert site.action_space.high[2] == 8.0 and site.action_space.low[2] == -8.0
    assert all(space.dtype in (np.float32, np.int64) for space in sim.observation_space.values())
    lagless = make(track="site", vehicle="sim", vehicle_overrides={"drag_coefficient": 0.0})
    assert lagless.unwrapped.params.drag_coefficient == 0.0
    assert lagless.unwrapped.params.wheel_base == 3.0


def test_same_seed_same_actions_same_episode_bit_for_bit():
    config = {"camera": {"enabled": True, "preset": "training"}, "observe_light_states": True,
              "obstacles": {"count": 3, "max_offset_d": 5.0},
              "manual": {"mode": "random", "interval_s": [0.5, 1.0], "duration_s": [0.3, 0.6]},
              "steps_per_action": 2}
    rng = np.random.default_rng(7)
    actions = [act(*row) for row in rng.uniform([0, 0, -0.3], [0.6, 200, 0.3], (120, 3))]

    def episode(seed, **changes):
        env = make(**{**config, **changes})
        trace = [env.reset(seed=seed)[0]]
        rewards = []
        for action in actions:
            obs, reward, *_ = env.step(action)
            trace.append(obs)
            rewards.append(reward)
        return trace, rewards

    first, again, other = episode(3), episode(3), episode(4)
    for a, b in zip(first[0], again[0], strict=True):
        assert a.keys() == b.keys()
        for key in a:
            assert np.array_equal(a[key], b[key]), key
    assert first[1] == again[1]
    assert not np.array_equal(first[0][0]["obstacles"], other[0][0]["obstacles"])
    assert {obs["dbw_enabled"] for obs in first[0]} == {0, 1}
    # One random stream per component: without the camera the drive is the same.
    blind = episode(3, camera={"enabled": False})
    assert all(np.array_equal(a["pose"], b["pose"]) for a, b in zip(first[0], blind[0],
                                                                     strict=True))


# ------------------------------------------------------------------ validation
def test_config_errors_name_the_key_and_the_valid_choices():
    with pytest.raises(ConfigError, match=r"unknown config key 'lapz'.*Valid keys: .*laps"):
        make(lapz=2)
    with pytest.raises(ConfigError, match=r"lights: unknown config key 'green'.*green_s"):
        make(lights={"green": 5.0})
    with pytest.raises(ConfigError, match=r"'manual.mode' must be one of \('off', 'random', "):
        make(manual={"mode": "sometimes"})
    with pytest.raises(ConfigError, match=r"'manual.periods' must be non-empty"):
        make(manual={"mode": "scripted"})
    with pytest.raises(ConfigError, match=r"'manual.periods' must be sorted"):
        make(manual={"mode": "scripted", "periods": [[5, 9], [1, 6]]})
    with pytest.raises(ConfigError, match=r"'vehicle' must be None or one of \['sim', 'site'\]"):
        make(vehicle="truck")
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['mass'\].*vehicle_mass"):
        make(vehicle_overrides={"mass": 900.0})
    with pytest.raises(ConfigError, match=r"preset' must be one of \('full', 'training'\)"):
        make(camera={"enabled": True, "preset": "tiny"})
    with pytest.raises(ConfigError, match=r"track.*neither a built-in \(default, site\)"):
        make(track="oval")
    with pytest.raises(ConfigError, match=r"script of light 0"):
        make(lights={"script": [7] + [None] * 7})


@pytest.mark.parametrize(("action", "message"), [
    (act(float("nan")), r"action\[0\] throttle = nan is outside its valid range \[0, 1\]"),
    (act(0.0, 5000.0), r"action\[1\] brake_torque = 5000.0 .*\[0, 3549.\d+\] N m"),
    (act(0.0, 0.0, -9.0), r"action\[2\] steering_wheel_angle = -9.0 .*\[-8.2, 8.2\] rad"),
    ([0.1, 0.0], r"shape \(3,\)"),
    (["a", 0.0, 0.0], r"shape \(3,\) with a real dtype .*; got dtype <U"),
])
def test_bad_actions_are_rejected_with_clear_errors(action, message):
    env = make()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


# ------------------------------------------------------------------ reward, info
def test_reward_is_normalised_progress_and_info_keys_never_change():
    env = make(steps_per_action=5)
    _, info = env.reset(seed=0)
    keys = set(info)
    assert {f"incidents_{kind}" for kind in TRACK_INCIDENT_KINDS} <= keys
    progress = info["progress"]
    for _ in range(20):
        _, reward, _, _, info = env.step(act(0.3))
        assert set(info) == keys and not info["new_incidents"]
        # 40 km/h limit: reward = metres gained / (11.11 m/s * 0.1 s).
        assert reward == pytest.approx((info["progress"] - progress) / (40 / 3.6 * 0.1))
        progress = info["progress"]
    assert reward > 0.2


# ------------------------------------------------------------------ stop lines
def drive_through_first_line(script):
    """Constant throttle from 30 m before the first stop line until 5 m past it."""
    env = make(start_s=FIRST_LINE_S - 30.0, lights={"script": [script] + [None] * 7})
    env.reset(seed=0)
    crossing = None
    for _ in range(600):
        info = env.step(act(0.5))[4]
        if crossing is None and info["s"] + SIM_FRONT_OFFSET_M > FIRST_LINE_S:
            crossing = info
        if info["s"] + SIM_FRONT_OFFSET_M > FIRST_LINE_S + 5.0:
            return env.unwrapped, crossing
    raise AssertionError("never reached the line")


def test_crossing_a_red_line_is_a_violation_at_the_crossing_step():
    env, crossing = drive_through_first_line(RED)
    assert crossing["new_incidents"] == ["red_light"]
    summary = env.metrics.summary()
    assert summary["red_light_violations"] == 1 == summary["incidents"]["red_light"]
    assert summary["stop_line_crossings"] == {"red": 1, "yellow": 0, "green": 0, "unknown": 0}
    incident = env.metrics.driving.incidents[-1]
    assert incident.kind == "red_light" and incident.value == 0.0
    # The front bumper passed the line during that 0.02 s step.
    assert 0.0 < incident.s + SIM_FRONT_OFFSET_M - FIRST_LINE_S < crossing["speed"] * DT + 1e-6


def test_crossing_on_green_is_not_a_violation():
    env, crossing = drive_through_first_line(GREEN)
    assert crossing["new_incidents"] == []
    summary = env.metrics.summary()
    assert summary["red_light_violations"] == 0
    assert summary["stop_line_crossings"]["green"] == 1


def stop_near_first_line(script, brake_at_front_m: float):
    """Approach the first line at ~8 m/s; brake at 2000 N m once the front bumper is at
    ``brake_at_front_m`` (relative to the line) and hold the brake until 1 s after rest."""
    env = make(start_s=FIRST_LINE_S - 60.0, lights={"script": [script] + [None] * 7})
    controller = PursuitController(env, 8.0)
    obs, info = env.reset(seed=0)
    braking, rest_steps = False, 0
    for _ in range(1500):
        front = info["s"] + SIM_FRONT_OFFSET_M - FIRST_LINE_S
        braking = braking or front >= brake_at_front_m
        action = controller.act(obs)
        obs, _, _, _, info = env.step(act(0.0, 2000.0, action[2]) if braking else action)
        rest_steps += info["speed"] == 0.0
        if rest_steps == 50:
            return env.unwrapped, info
    raise AssertionError("never stopped")


def test_stop_before_a_red_line_no_violation_and_measured_offset():
    env, info = stop_near_first_line(RED, brake_at_front_m=-12.0)
    stops = env.metrics.stops
    assert env.metrics.red_light_violations == 0 and len(stops) == 1
    stop = stops[0]
    rest_front = info["s"] + SIM_FRONT_OFFSET_M - FIRST_LINE_S
    assert stop.line == 0 and stop.light_state == RED
    assert stop.offset_m == pytest.approx(rest_front, abs=1e-9)
    # From ~8 m/s at 2000 N m (about 5.7 m/s^2 with rolling resistance): ~5.6 m to rest.
    assert -8.0 < stop.offset_m < -5.0 and stop.overshoot_m == 0.0
    assert env.metrics.summary()["max_overshoot"] == 0.0


def test_stop_past_the_line_is_an_overshoot():
    env, info = stop_near_first_line(GREEN, brake_at_front_m=-2.0)
    summary = env.metrics.summary()
    assert summary["red_light_violations"] == 0
    [stop] = summary["stops"]
    rest_front = info["s"] + SIM_FRONT_OFFSET_M - FIRST_LINE_S
    assert stop["offset_m"] == pytest.approx(rest_front, abs=1e-9)
    assert 2.0 < stop["overshoot_m"] == summary["max_overshoot"] < 5.0


# ------------------------------------------------------------------ episode ends
def test_leaving_the_road_terminates_with_its_reason():
    env = make()
    _, info, terminated, truncated = run_until_done(env, lambda obs: act(0.4, 0.0, 8.0), 1000)
    assert terminated and not truncated
    assert info["termination_reason"] == "off_road" == info["summary"]["termination_reason"]
    assert info["d"] < -6.0  # full lock left: d grows to the right, so it leaves on the left
    assert info["summary"]["incidents"]["off_road"] == 1 and not info["is_success"]


def test_hitting_an_obstacle_terminates_and_obstacles_are_reported():
    env = make(obstacles={"positions": [[40.0, 0.0], [60.0, 4.0]]})
    obs, _ = env.reset(seed=0)
    expected = env.unwrapped.track.reference.to_xy(np.array([40.0, 60.0]), np.array([0.0, 4.0]))
    np.testing.assert_allclose(obs["obstacles"], expected, rtol=1e-6)
    obs, info, terminated, _ = run_until_done(env, lambda obs: act(0.4), 2000)
    assert terminated and info["termination_reason"] == "collision"
    assert info["summary"]["incident_log"][-1]["kind"] == "collision"
    assert info["summary"]["incident_log"][-1]["value"] == 0.0  # the obstacle's index
    # The front bumper reached the obstacle's rear (40 - 4.5 / 2 m) in this step.
    front = info["s"] + SIM_FRONT_OFFSET_M
    assert 37.75 <= front < 37.75 + info["speed"] * DT + 0.05


def test_manual_override_ignores_the_agent_and_says_so():
    env = make(manual={"mode": "scripted", "periods": [[1.0, 3.0]]})
    obs, _ = env.reset(seed=0)
    assert obs["dbw_enabled"] == 1
    hold = act(0.0, 1000.0)  # the agent brakes all the time
    trace = []
    for _ in range(225):
        obs, _, _, _, info = env.step(hold)
        trace.append((obs["dbw_enabled"], info["dbw_enabled"], info["speed"]))
    modes = [mode for mode, _, _ in trace]
    # Observation after step n (time 0.02 n) tells whether frame n + 1 is manual:
    # frames starting at 1.00 s .. 2.98 s are.
    assert modes[48] == 1 and modes[49] == 0 and modes[148] == 0 and modes[149] == 1
    assert all(bool(mode) == flag for mode, flag, _ in trace)
    assert all(speed == 0.0 for _, _, speed in trace[:50])
    assert trace[149][2] > 1.0  # the human drove off although the agent braked
    assert trace[-1][2] == 0.0  # the agent's brake is back in charge
    assert env.unwrapped.summary()["manual_time"] == pytest.approx(2.0)


def test_random_manual_periods_respect_their_intervals_and_durations():
    env = make(manual={"mode": "random", "interval_s": [0.4, 0.6], "duration_s": [0.2, 0.3]})
    env.reset(seed=5)
    modes = [env.step(act(0.0, 500.0))[0]["dbw_enabled"] for _ in range(400)]
    runs: list[list[int]] = []
    for mode in modes:
        if runs and runs[-1][0] == mode:
            runs[-1][1] += 1
        else:
            runs.append([mode, 1])
    manual = [length for mode, length in runs[:-1] if mode == 0]
    auto = [length for mode, length in runs[1:-1] if mode == 1]
    assert len(manual) >= 5
    # 0.2-0.3 s and 0.4-0.6 s in 0.02 s frames; each end is rounded to a frame (+-1).
    assert all(9 <= length <= 16 for length in manual)
    assert all(19 <= length <= 31 for length in auto)


def test_lap_of_the_site_track_with_a_pure_pursuit_controller():
    env = make(track="site", steps_per_action=5, lights={"script": [GREEN]})
    track = env.unwrapped.track
    controller = PursuitController(env, 0.9 * track.speed_limit_mps)
    _, info, terminated, _ = run_until_done(env, controller.act, 1000)
    summary = info["summary"]
    assert terminated and info["is_success"] and summary["termination_reason"] == "laps_completed"
    [lap] = summary["lap_times"]
    cruise = track.length / (0.9 * track.speed_limit_mps)  # 30.6 s at 2.5 m/s
    assert cruise < lap < cruise + 5.0
    assert summary["incidents"]["off_road"] == summary["incidents"]["red_light"] == 0
    assert summary["max_cross_track_error"] < 1.0  # the 6 m look-ahead cuts the 6.5 m corners
    assert 0.5 < summary["max_lateral_acceleration"] < 2.0  # ~2.5^2 / 6.5 m in the corners


def test_original_track_files_load_and_step():
    capstone = UDACITY / "capstone"
    env = make(track=str(capstone / "wp_yaw_const.csv"),
               light_config=str(capstone / "sim_traffic_light_config.yaml"),
               observe_light_states=True)
    obs, _ = env.reset(seed=0)
    assert env.unwrapped.track.light_count == 8 and obs["light_states"].shape == (8,)
    assert obs["next_stop_line"][0] == 0.0
    assert obs["next_stop_line"][1] == pytest.approx(247.7, abs=0.5)  # spec: s = 247.7 m
    for _ in range(50):
        obs, _, terminated, truncated, info = env.step(act(0.3))
    assert not (terminated or truncated) and info["speed"] > 0.5


# ------------------------------------------------------------------ sensors, rendering
def test_camera_sees_the_red_light_ahead():
    env = make(start_s=FIRST_LINE_S - 10.0, lights={"script": [RED] + [None] * 7},
               camera={"enabled": True, "preset": "training", "variation": False})
    obs, _ = env.reset(seed=0)
    image = obs["camera"].astype(int)
    red = (image[..., 0] > 200) & (image[..., 1] < 80) & (image[..., 2] < 80)
    assert red.sum() >= 4  # the lit red lamp of light 0, 24 m past its line


def test_rgb_array_and_human_render(monkeypatch):
    env = make(render_mode="rgb_array", render_width=320, render_height=240,
               obstacles={"positions": [[30.0, 0.0]]})
    env.reset(seed=0)
    env.unwrapped.set_debug_path([[980.0, 100.0], [990.0, 100.0]])
    env.step(act(0.2))
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # something is drawn
    with pytest.raises(ValueError, match="debug path"):
        env.unwrapped.set_debug_path([[1.0, np.nan]])
    env.close()
    env.close()
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    human = make(render_mode="human", track="site")
    human.reset(seed=0)
    human.step(act(0.2))
    human.close()
    human.close()


@pytest.mark.parametrize("name", ["track_loop.yaml", "track_site.yaml"])
def test_yaml_configs_build_the_env(name):
    data = yaml.safe_load((CONFIGS / name).read_text(encoding="utf-8"))
    env = gym.make(data["env"], config=data["config"])
    obs, _ = env.reset(seed=0)
    assert obs["light_states"].shape == (env.unwrapped.track.light_count,)
    assert env.step(act(0.1))[0]["velocity"][0] > 0.0


def test_track_metrics_count_every_pass_of_a_line_across_the_loop_end_in_any_chunking():
    from sdc_gym.metrics.driving_metrics import IncidentRules
    from sdc_gym.metrics.track_metrics import TrackMetrics
    from sdc_gym.road.builtin_tracks import get_track_map

    track = get_track_map("site")  # one stop line, 41.0 m along a 76.5 m loop
    line_s = float(track.stop_line_s[0])
    s = np.arange(0, 2.5 * track.length, 0.05)  # 2.5 laps at 2.5 m/s, on the path
    xy = track.reference.to_xy(s, np.zeros_like(s))
    speed = np.full(len(s), 2.5)
    red = np.array([RED], dtype=np.int8)
    rules = IncidentRules(speed_limit=10.0, road_d_min=-3.0, road_d_max=3.0, straddle_bands=())

    def run(chunk):
        metrics = TrackMetrics(track, rules, front_offset_m=4.0)
        metrics.reset(*xy[0], 0.0, 0.0, 2.5)
        for start in range(1, len(s), chunk):
            part = slice(start, min(start + chunk, len(s)))
            n = part.stop - part.start
            metrics.record(xy[part], track.reference.wrap_s(s[part]), np.zeros(n),
                           speed[part], [0.0] * n, [red] * n)
        return metrics.driving

    # The front bumper (s + 4 m) passes the line at 41.0, 41.0 + L and 41.0 + 2 L m.
    expected = [line_s - 4.0 + lap * track.length for lap in range(3)]
    driving = run(1)
    single = driving.incidents
    assert single == run(7).incidents
    # Red-light incidents restart the distance without incident like the shared kinds.
    assert driving.longest_distance_without_incident == pytest.approx(track.length, abs=0.1)
    assert [incident.kind for incident in single] == ["red_light"] * 3
    for incident, rear_s in zip(single, expected, strict=True):
        assert 0.0 < incident.time * 2.5 - rear_s <= 0.05 + 1e-9  # the first step past it


# ------------------------------------------------------------------ review fixes
def test_velocity_bound_is_the_cars_top_speed_and_start_speed_is_checked():
    from sdc_gym.envs.track_loop import top_speed
    from sdc_gym.vehicle import SITE_VEHICLE

    # Sim car at full throttle: constant force against linear drag, F / c.
    force = 500.0 * (2 / 0.335 + 2 / 0.37)
    drag = 100.0 + 0.25 * (2 / 0.335**2 + 2 / 0.37**2)
    expected = force / drag
    assert expected == pytest.approx(52.61, abs=0.01)
    # Site car, power limited: 140 kW / v = 0.43 v^2 + 0.015 * m * 9.81.
    roots = np.roots([0.43, 0.0, 0.015 * SITE_VEHICLE.total_mass * 9.81, -140_000.0])
    assert top_speed(SITE_VEHICLE) == pytest.approx(
        float(max(roots.real[np.abs(roots.imag) < 1e-9])), abs=1e-9)
    env = make(start_speed=52.6, steps_per_action=25,
               incident_rules={"road_half_width": 1e4}).unwrapped
    assert env.top_speed == pytest.approx(expected, abs=1e-9)
    # Top speed + one frame of launch (5688 / 1080 m/s^2, no creep) + 5 %.
    bound = 1.05 * (expected + 0.02 * force / 1080.0)
    assert env.observation_space["velocity"].high[0] == pytest.approx(bound, rel=1e-6)
    obs, _ = env.reset(seed=0)
    for _ in range(100):
        assert env.observation_space.contains(obs)
        obs = env.step(act(1.0))[0]
    with pytest.raises(ConfigError, match=r"'start_speed' must be in \[0, 52.61\] m/s"):
        make(start_speed=150.0)
    with pytest.raises(ConfigError, match="top speed is unbounded"):
        make(vehicle_overrides={"linear_drag": 0.0})


def test_velocity_stays_in_its_box_when_a_light_car_overshoots_its_top_speed():
    # A creeping car of 5 kg and 20 kN: the first frame from rest gains
    # (20000 + 400 / 0.335) / 5 * 0.02 = 84.8 m/s, beyond the 60.8 m/s top speed (4 kN /
    # 90 kW against aero drag and rolling): the launch term of the bound covers it.
    env = make(vehicle_overrides={"vehicle_mass": 5.0, "max_drive_force": 20_000.0,
                                  "max_drive_power": 90_000.0, "creep_hold_torque": 400.0,
                                  "drag_coefficient": 0.40, "rolling_resistance": 0.015,
                                  "linear_drag": 0.0, "rest_speed": 0.0},
               incident_rules={"road_half_width": 1e4}).unwrapped
    obs, _ = env.reset(seed=0)
    speeds = []
    for _ in range(50):
        obs = env.step(act(1.0))[0]
        assert env.observation_space.contains(obs)
        speeds.append(float(obs["velocity"][0]))
    assert speeds[0] == pytest.approx((20_000.0 + 400.0 / 0.335) / 5.0 * 0.02, rel=1e-6)
    assert speeds[0] > env.top_speed == pytest.approx(60.81, abs=0.01)
    assert speeds[-1] == pytest.approx(env.top_speed, abs=0.01)


def test_manual_frames_earn_no_reward_and_no_penalty():
    # The human drives the first 4 s and pulls away at ~1.2 m/s^2, above the 0.5 m/s^2
    # acceleration limit: incidents the metrics count but the agent is not charged for.
    env = make(manual={"mode": "scripted", "periods": [[0.0, 4.0]]}, steps_per_action=10,
               incident_rules={"max_acceleration": 0.5})
    _, info = env.reset(seed=0)
    assert info["manual_frames"] == 0
    human_incidents = []
    for _ in range(20):  # 20 x 0.2 s, all driven by the human
        _, reward, _, _, info = env.step(act(0.0, 1000.0))
        assert reward == 0.0 and info["manual_frames"] == 10
        human_incidents += info["new_incidents"]
    assert "acceleration" in human_incidents and info["speed"] > 2.0
    progress = info["progress"]
    rewards = []
    for _ in range(10):  # the agent's full throttle: an acceleration incident of its own
        _, reward, _, _, info = env.step(act(1.0))
        assert info["manual_frames"] == 0
        gained = (info["progress"] - progress) / (40 / 3.6 * 0.2)
        penalty = -1.0 * len(info["new_incidents"])  # -1 each by default
        assert set(info["new_incidents"]) <= {"acceleration", "jerk", "speed"}
        assert reward == pytest.approx(gained + penalty)
        rewards.append(penalty)
        progress = info["progress"]
    assert min(rewards) == -1.0


def test_a_manual_period_inside_a_step_counts_only_the_agents_frames():
    # Manual frames 5..14 (0.1 s .. 0.3 s): 5 in step 1, 5 in step 2 of 10 frames each.
    # The same drive one frame per step rewards agent frames only; its sum / 10 is the
    # 10-frame step's reward.
    def rewards(frames):
        env = make(manual={"mode": "scripted", "periods": [[0.1, 0.3]]},
                   steps_per_action=frames, start_speed=5.0)
        env.reset(seed=0)
        out = [env.step(act(0.5))[1:5:3] for _ in range(30 // frames)]
        return [reward for reward, _ in out], [info["manual_frames"] for _, info in out]

    coarse, manual = rewards(10)
    fine, fine_manual = rewards(1)
    assert manual == [5, 5, 0] and sum(fine_manual) == 10
    assert all(reward == 0.0 for reward, flag in zip(fine, fine_manual, strict=True) if flag)
    for step in range(3):
        assert coarse[step] == pytest.approx(sum(fine[10 * step:10 * step + 10]) / 10)
    # Step 1: the agent's 5 frames at ~5 m/s, 0.5 m / (11.1 m/s * 0.2 s) = 0.225.
    assert coarse[0] == pytest.approx(0.225, abs=0.01)


def test_keys_that_would_be_ignored_and_wrong_types_are_config_errors():
    cases = [
        ({"manual": {"mode": "random", "periods": [[1, 2]]}},
         r"'manual.periods' must be empty unless manual.mode is 'scripted'"),
        ({"manual": {"periods": [[1, 2]]}}, r"'manual.periods' must be empty unless"),
        ({"manual": {"mode": "scripted", "periods": [[1, 2]], "interval_s": [1.0, 2.0]}},
         r"'manual.interval_s' must be left out unless manual.mode is 'random'"),
        ({"camera": {"enabled": False, "preset": "tiny"}}, r"'preset' must be one of"),
        ({"camera": {"enabled": False, "width": -5}}, r"CameraConfig\.width must be an int"),
        ({"obstacles": {"positions": [[100.0, 0.0]], "max_offset_d": 3.0}},
         r"'obstacles.max_offset_d' must be 0 unless obstacles are random"),
        ({"obstacles": {"count": 2, "max_offset_d": 7.0}},
         r"'obstacles.max_offset_d' must be in \[0, 6\] m"),
        ({"obstacles": {"positions": [[100.0, 50.0]]}},
         r"'obstacles.positions' must be \[s, d\] pairs on the road, d in \[-6, 6\] m"),
        ({"speed_limit": "fast"},
         r"'speed_limit' must be None or a finite number in \(0, 100\] \(m/s\)"),
        ({"start_s": "x"}, r"'start_s' must be None or a finite number"),
        ({"start_d": 50.0}, r"'start_d' must be in \[-6, 6\] m \(on the road\), got 50.0"),
        ({"vehicle": ["sim"]}, r"'vehicle' must be None or one of \['sim', 'site'\]"),
        ({"track": str(UDACITY / "capstone" / "wp_yaw_const.csv"), "light_config": 5},
         r"'light_config' must be None or the path \(str\)"),
        ({"incident_rules": {"road_half_width": "wide"}}, r"'incident_rules.road_half_width'"),
    ]
    for config, message in cases:
        with pytest.raises(ConfigError, match=message):
            make(**config)


def test_stop_lines_at_the_same_s_are_each_counted():
    from sdc_gym.metrics.driving_metrics import IncidentRules
    from sdc_gym.metrics.track_metrics import TrackMetrics
    from sdc_gym.road.track_map import TrackMap

    radius = 200.0  # a circle; lines at s = 100, 100 and 500 m
    angle = np.linspace(0.0, 2 * np.pi, 2000, endpoint=False)
    waypoints = np.column_stack([radius * np.cos(angle), radius * np.sin(angle),
                                 np.zeros_like(angle), angle + np.pi / 2])
    lines = [[radius * np.cos(s / radius), radius * np.sin(s / radius)]
             for s in (100.0, 100.0, 500.0)]
    track = TrackMap.from_waypoints("circle", waypoints, lines)
    rules = IncidentRules(speed_limit=100.0, road_d_min=-6.0, road_d_max=6.0,
                          straddle_bands=())
    metrics = TrackMetrics(track, rules, front_offset_m=4.0)
    s = np.arange(0.0, 0.9 * track.length, 0.2)
    xy = track.reference.to_xy(s, np.zeros_like(s))
    metrics.reset(*xy[0], 0.0, 0.0, 10.0)
    red = np.full(3, RED, dtype=np.int8)
    for start in range(1, len(s), 10):
        part = slice(start, min(start + 10, len(s)))
        n = part.stop - part.start
        metrics.record(xy[part], s[part], np.zeros(n), np.full(n, 10.0), [0.0] * n, [red] * n)
    assert metrics.red_light_violations == 3
    assert [incident.value for incident in metrics.driving.incidents] == [0.0, 1.0, 2.0]
    # Both lines at 100 m were crossed at the same step.
    assert metrics.driving.incidents[0].step == metrics.driving.incidents[1].step


def test_the_car_never_starts_with_a_stop_line_under_it():
    capstone = UDACITY / "capstone"
    env = make(track=str(capstone / "churchlot_with_cars.csv"),
               light_config=str(capstone / "site_traffic_light_config.yaml"))
    base = env.unwrapped
    front = base.params.wheel_base + 1.0  # 3.85 m for the site car
    [line_s] = base.track.stop_line_s  # 1.98 m from the first waypoint
    # The front bumper starts 2 m behind the line (not across it, as from s = 0).
    assert base.start_s == pytest.approx(line_s - front - 2.0 + base.track.length)
    obs, info = env.reset(seed=0)
    assert obs["next_stop_line"][0] == 0 == info["next_stop_line_front"]
    assert obs["next_stop_line"][1] == pytest.approx(front + 2.0, abs=1e-4)
    assert info["stop_line_distance_front"] == pytest.approx(2.0, abs=1e-9)
    with pytest.raises(ConfigError, match=r"stop line 0 at s = 1.98 m lies between the rear "
                                          r"axle and the front bumper"):
        make(track=str(capstone / "churchlot_with_cars.csv"),
             light_config=str(capstone / "site_traffic_light_config.yaml"), start_s=0.0)
    # Driving on: the observation's line (ahead of the rear axle) is the metrics' line
    # (ahead of the bumper) whenever it is not under the car.
    controller = PursuitController(env, 2.5)
    under_car = 0
    for _ in range(2000):
        obs, _, terminated, _, info = env.step(controller.act(obs))
        line, distance = obs["next_stop_line"]
        if distance >= front:
            assert info["next_stop_line_front"] == line
            assert info["stop_line_distance_front"] == pytest.approx(distance - front, abs=1e-3)
        else:
            under_car += 1
        if terminated:
            break
    assert info["termination_reason"] == "laps_completed"
    assert sum(info["summary"]["stop_line_crossings"].values()) == 1 and under_car > 0


def test_per_light_timings():
    env = make(lights={"timings": [[2.0, 1.0, 3.0]] + [[10.0, 3.0, 10.0]] * 7,
                       "offsets_s": [0.0] * 8}, observe_light_states=True, steps_per_action=25)
    lights = env.unwrapped.lights
    assert lights.timings[0].cycle_s == 6.0 and lights.timings[1].cycle_s == 23.0
    env.reset(seed=0)
    states = [env.step(act(0.0, 1000.0))[0]["light_states"][:2].tolist() for _ in range(14)]
    states = states[::2]  # at 0.5, 1.5, ..., 6.5 s (0.5 s per step), away from the changes
    # Light 0: green 0-2 s, yellow 2-3 s, red 3-6 s, green again; light 1 green 0-10 s.
    assert [row[0] for row in states] == [GREEN, GREEN, YELLOW, RED, RED, RED, GREEN]
    assert all(row[1] == GREEN for row in states)
    with pytest.raises(ConfigError, match=r"'lights.timings' must be None or 8 \[green_s, "):
        make(lights={"timings": [[2.0, 1.0, 3.0]]})
    with pytest.raises(ConfigError, match=r"'lights.timings' must be given without "
                                          r"\['green_s'\]"):
        make(lights={"timings": [[2.0, 1.0, 3.0]] * 8, "green_s": 5.0})
    with pytest.raises(ConfigError, match=r"LightTiming.red_s must be a finite number > 0"):
        make(lights={"timings": [[2.0, 1.0, -3.0]] * 8})
