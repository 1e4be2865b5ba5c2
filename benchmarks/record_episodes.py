"""Record episodes as digests, or check that the code still reproduces recorded ones.

    python benchmarks/record_episodes.py --output /tmp/episodes.json   # record
    python benchmarks/record_episodes.py --compare /tmp/episodes.json  # check, bit for bit
    python benchmarks/record_episodes.py --only track_ \
        --compare tests/data/recorded_track_digests.json  # the tests' compact digests

Each scenario (env id, config, seed, agent) is run for up to ``max_steps`` env steps over
one or two episodes (the second starts with ``reset()`` without a seed, so it continues the
env's random stream, as an autoreset does). Per step the digest covers the observation's
bytes, the reward's and the flags' bits and the info fields the scenario names; at each
episode end the summary (its JSON with exact float reprs) too. ``--compare`` reports, per
scenario, whether every step matches and the first step that does not.

The scenarios cover the FSM agent's styles (with and without Kalman tracking and sensor
noise), lane keeping, random behavior actions (discrete and continuous, shield on and off,
rogue and dense traffic, latency, the oval and the original map) and scripted paths that
provoke every incident kind of the highway (collision, acceleration, jerk, speed, lane,
off-road), and the track loop (:func:`track_scenarios`): the DBW stack agents with manual
override, the site car, obstacles and the camera, scripted DBW drivers provoking every
track incident kind (red light included), and the behavior env with random and scripted
decisions.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401  (registers the ids)

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

ORIGINAL_MAP = ROOT.parent / "shared" / "data" / "udacity" / "path_planning" / "highway_map.csv"
HIGHWAY = "sdc_gym/HighwayLoop-v0"
BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
TRACK_BEHAVIOR = "sdc_gym/TrackLoopBehavior-v0"
TRACK = "sdc_gym/TrackLoop-v0"
ALL_INFO = ("*",)  # digest every info key (sorted)
PATH_INFO = ("time", "distance", "progress", "laps", "speed", "acceleration", "jerk",
             "raw_acceleration", "raw_jerk", "distance_without_incident", "incidents",
             "lane", "new_incidents", "is_success", "termination_reason")


def _update(digest: Any, value: Any) -> None:
    """Feed ``value`` into ``digest`` exactly (arrays by their bytes, floats by bits)."""
    if isinstance(value, np.ndarray):
        digest.update(str(value.dtype).encode())
        digest.update(str(value.shape).encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, dict):
        for key in sorted(value):
            digest.update(str(key).encode())
            _update(digest, value[key])
    elif isinstance(value, (list, tuple)):
        digest.update(b"[")
        for item in value:
            _update(digest, item)
        digest.update(b"]")
    elif isinstance(value, (bool, np.bool_)):
        digest.update(b"T" if value else b"F")
    elif isinstance(value, (int, np.integer)):
        digest.update(str(int(value)).encode())
    elif isinstance(value, (float, np.floating)):
        digest.update(struct.pack("<d", float(value)))
    elif value is None:
        digest.update(b"None")
    else:
        digest.update(str(value).encode())


def _step_digest(obs: Any, reward: float, terminated: bool, truncated: bool,
                 info: dict[str, Any], keys: tuple[str, ...]) -> str:
    digest = hashlib.blake2b(digest_size=8)
    _update(digest, obs)
    _update(digest, float(reward))
    _update(digest, bool(terminated))
    _update(digest, bool(truncated))
    if keys == ALL_INFO:
        _update(digest, info)
        return digest.hexdigest()
    for key in keys:
        _update(digest, info.get(key))
    if "behavior" in info:
        _update(digest, info["behavior"])
    return digest.hexdigest()


# ---------------------------------------------------------------- scripted agents
class RandomActions:
    """Actions from a generator of their own (independent of the env's seeding)."""

    def __init__(self, space: gym.Space, seed: int, fixed: Any = None) -> None:
        self.space = space
        self.rng = np.random.default_rng(seed)
        self.fixed = fixed

    def reset(self) -> None:
        pass

    def act(self, _observation: Any) -> Any:
        if self.fixed is not None:
            return self.fixed
        if isinstance(self.space, gym.spaces.Discrete):
            return int(self.rng.integers(self.space.n))
        return self.rng.uniform(-1.0, 1.0, size=self.space.shape).astype(np.float32)


class ScriptedPath:
    """A path-level driver that follows a lane offset profile at a speed profile: used to
    provoke incidents (stop dead, speeding, off-road, straddling a lane line)."""

    def __init__(self, env: gym.Env, speed: Callable[[float], float],
                 offset: Callable[[float], float], stop_after_s: float | None = None) -> None:
        self.road = env.unwrapped.road
        self.speed = speed
        self.offset = offset
        self.stop_after_s = stop_after_s
        self.reset()

    def reset(self) -> None:
        self.t = 0.0
        self.s: float | None = None

    def act(self, observation: dict[str, Any]) -> np.ndarray:
        ego = observation["ego"].astype(np.float64)
        count = int(observation["previous_path_count"])
        previous = observation["previous_path"][:count].astype(np.float64)
        if self.s is None:
            self.s = float(ego[2])
        if self.stop_after_s is not None and self.t >= self.stop_after_s:
            return np.zeros((0, 2))
        new = []
        for _ in range(50 - count):
            self.t += 0.02
            self.s += self.speed(self.t) * 0.02
            new.append(self.road.reference.to_xy(self.s, self.offset(self.t)))
        return np.vstack([previous, *new]) if new else previous


class SequenceActions:
    """A fixed cycle of actions (scripted decisions)."""

    def __init__(self, actions: list[Any]) -> None:
        self.actions = actions
        self.reset()

    def reset(self) -> None:
        self.index = 0

    def act(self, _observation: Any) -> Any:
        action = self.actions[self.index % len(self.actions)]
        self.index += 1
        return np.asarray(action, dtype=np.float32) if isinstance(action, list) else action


class TrackPursuit:
    """A DBW-level track driver: pure pursuit on the track's path at a lateral offset and a
    speed loop (proportional throttle, brake torque), both profiles of time; ``pump``
    alternates full throttle and hard braking (acceleration and jerk incidents)."""

    def __init__(self, env: gym.Env, speed: Callable[[float], float],
                 offset: Callable[[float], float], pump: bool = False) -> None:
        base = env.unwrapped
        self.line, self.car = base.track.reference, base.params
        self.dt = 0.02 * base.steps_per_action
        self.max_brake = float(env.action_space.high[1])
        self.speed, self.offset, self.pump = speed, offset, pump
        self.reset()

    def reset(self) -> None:
        self.t = 0.0
        self.s: float | None = None

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        import math

        x, y, yaw = obs["pose"].astype(np.float64).tolist()
        speed = float(obs["velocity"][0])
        guess = self.s if self.s is not None else float(self.line.to_frenet(np.array([x, y]))[0])
        (self.s,), _ = self.line.project_few([[x, y]], [guess])
        target = self.line.to_xy(self.s + max(6.0, speed), self.offset(self.t)).tolist()
        dx, dy = target[0] - x, target[1] - y
        lateral = -math.sin(yaw) * dx + math.cos(yaw) * dy
        wheel = math.atan(self.car.wheel_base * 2.0 * lateral / (dx * dx + dy * dy))
        limit = self.car.steering_wheel_lock
        steering = min(max(self.car.road_wheel_ratio * wheel, -limit), limit)
        error = self.speed(self.t) - speed
        throttle = min(max(0.5 * error, 0.0), 1.0)
        brake = min(max(-300.0 * error, 0.0), 1000.0)
        if self.pump and int(self.t / 2.0) % 2:
            throttle, brake = 0.0, self.max_brake
        self.t += self.dt
        return np.array([throttle, brake, steering], dtype=np.float32)


# ---------------------------------------------------------------- scenarios
def chain(digests: list[str]) -> str:
    """One digest of a sequence of step digests."""
    return hashlib.blake2b("".join(digests).encode(), digest_size=16).hexdigest()


def scenarios() -> list[dict[str, Any]]:
    """Every recorded scenario: name, env id, config, seed, agent spec, max steps."""
    items: list[dict[str, Any]] = []

    def add(name: str, env_id: str, agent: Any, seed: int, steps: int,
            config: dict[str, Any] | None = None, episodes: int = 1) -> None:
        items.append({"name": name, "env": env_id, "config": config or {}, "agent": agent,
                      "seed": seed, "steps": steps, "episodes": episodes})

    for seed in (0, 1, 7):
        add(f"behavior_random_discrete_s{seed}", BEHAVIOR, ("random", None), seed, 2600,
            episodes=2)
    add("behavior_random_discrete_short_s3", BEHAVIOR, ("random", None), 3, 900,
        {"highway": {"max_duration": 60.0}}, episodes=3)
    add("behavior_random_continuous_s2", BEHAVIOR, ("random", None), 2, 1500,
        {"action": "continuous"})
    add("behavior_no_shield_random_s4", BEHAVIOR, ("random", None), 4, 1500,
        {"safety_shield": False}, episodes=3)
    add("behavior_no_shield_cruise_s5", BEHAVIOR, ("fixed", 3), 5, 1500,
        {"safety_shield": False}, episodes=3)
    add("behavior_rogue_dense_s6", BEHAVIOR, ("random", None), 6, 1500,
        {"highway": {"traffic": {"car_count": 40, "rogue": True, "density": 2.0}}},
        episodes=2)
    add("behavior_shaping_s8", BEHAVIOR, ("random", None), 8, 800,
        {"reward_room_ahead": 4.0, "reward_lane_change": -0.01, "reward_refused": 0.0})
    add("behavior_oval_s9", BEHAVIOR, ("random", None), 9, 800, {"highway": {"map": "oval"}})
    add("behavior_kalman_noise_s10", BEHAVIOR, ("random", None), 10, 500,
        {"kalman_tracking": True, "highway": {"sensors": {
            "position_noise": 0.3, "velocity_noise": 0.3, "dropout_probability": 0.05,
            "zero_sd_probability": 0.02}}})
    add("behavior_frames6_s11", BEHAVIOR, ("random", None), 11, 800, {"decision_frames": 6})
    if ORIGINAL_MAP.is_file():
        add("behavior_original_map_s12", BEHAVIOR, ("random", None), 12, 800,
            {"highway": {"map": str(ORIGINAL_MAP)}})

    for agent in ("fsm_bold", "fsm_conservative"):
        for seed in (0, 3):
            add(f"{agent}_s{seed}", HIGHWAY, ("agent", agent), seed, 6000)
    add("fsm_bold_frames5_s1", HIGHWAY, ("agent", "fsm_bold"), 1, 3000,
        {"steps_per_action": 5})
    add("fsm_bold_latency_s2", HIGHWAY, ("agent", "fsm_bold"), 2, 3000,
        {"steps_per_action": 3, "latency_steps": 9})
    add("fsm_bold_kf_noise_s4", HIGHWAY, ("agent", "fsm_bold_kf"), 4, 1500,
        {"sensors": {"position_noise": 0.5, "velocity_noise": 0.5,
                     "dropout_probability": 0.05, "zero_sd_probability": 0.02}})
    add("fsm_conservative_dense_s5", HIGHWAY, ("agent", "fsm_conservative"), 5, 2000,
        {"traffic": {"car_count": 50}})
    add("lane_keeping_s6", HIGHWAY, ("agent", "lane_keeping"), 6, 2000)
    add("lane_keeping_500cars_s7", HIGHWAY, ("agent", "lane_keeping"), 7, 300,
        {"traffic": {"car_count": 500, "spawn_range": 3000.0}, "steps_per_action": 5})
    add("lane_keeping_rogue_s8", HIGHWAY, ("agent", "lane_keeping"), 8, 2000,
        {"traffic": {"rogue": True, "rogue_rate": 4.0, "car_count": 30},
         "terminate_on_collision": False})
    add("scripted_stop_dead_s9", HIGHWAY, ("stop_dead", None), 9, 400)
    add("scripted_speeding_s10", HIGHWAY, ("speeding", None), 10, 400)
    add("scripted_off_road_straddle_s11", HIGHWAY, ("off_road", None), 11, 700)
    add("track_behavior_random_s0", TRACK_BEHAVIOR, ("random", None), 0, 200, episodes=2)
    add("track_behavior_random_s1", TRACK_BEHAVIOR, ("random", None), 1, 150,
        {"action": "continuous"})
    items.extend(track_scenarios())
    return items


def track_scenarios() -> list[dict[str, Any]]:
    """The track loop: the DBW stack agents (light sources, rates, followers, manual
    override, the site car, obstacles), scripted DBW drivers provoking every incident kind
    (red light, speed, acceleration, jerk, off-road, collision), and the behavior env
    with random and scripted decisions. Every info key is digested."""
    items: list[dict[str, Any]] = []

    def add(name: str, env_id: str, agent: Any, seed: int, steps: int,
            config: dict[str, Any] | None = None, episodes: int = 1) -> None:
        items.append({"name": name, "env": env_id, "config": config or {}, "agent": agent,
                      "seed": seed, "steps": steps, "episodes": episodes,
                      "info_keys": ALL_INFO})

    lights = {"observe_light_states": True}
    add("track_dbw_ground_truth_s0", TRACK, ("agent", "dbw_ground_truth"), 0, 9000, lights)
    add("track_dbw_lap_s1", TRACK, ("agent", "dbw_ground_truth"), 1, 40000, lights)
    add("track_dbw_manual_random_s2", TRACK, ("agent", "dbw_ground_truth"), 2, 8000,
        {**lights, "manual": {"mode": "random", "interval_s": [8.0, 25.0],
                              "duration_s": [3.0, 9.0]}}, episodes=2)
    add("track_dbw_manual_scripted_s3", TRACK, ("agent", "dbw_ground_truth"), 3, 5000,
        {**lights, "steps_per_action": 2,
         "manual": {"mode": "scripted", "periods": [[0.0, 2.5], [20.0, 31.3], [60.01, 70.0]]}})
    add("track_dbw_site_s4", TRACK, ("agent", "dbw_ground_truth"), 4, 12000,
        {**lights, "track": "site", "laps": 2}, episodes=2)
    add("track_dbw_seed_rates_s5", TRACK, ("agent", "dbw_seed_rates"), 5, 4000,
        {**lights, "steps_per_action": 5})
    add("track_dbw_original_follower_s6", TRACK, ("agent", "dbw_original_follower"), 6, 6000,
        lights)
    add("track_dbw_obstacle_s7", TRACK, ("agent", "dbw_ground_truth"), 7, 3000,
        {**lights, "obstacles": {"positions": [[150.0, 0.5]]}}, episodes=2)
    add("track_dbw_random_obstacles_s8", TRACK, ("agent", "dbw_ground_truth"), 8, 3000,
        {**lights, "obstacles": {"count": 4, "max_offset_d": 2.0},
         "lights": {"green_s": 5.0, "yellow_s": 2.0, "red_s": 12.0}})
    add("track_dbw_cnn_camera_s9", TRACK, ("agent", "dbw_cnn"), 9, 400,
        {"start_s": 180.0, "camera": {"enabled": True, "preset": "training"}})
    add("track_dbw_short_duration_s10", TRACK, ("agent", "dbw_ground_truth"), 10, 3000,
        {**lights, "max_duration": 25.0, "start_speed": 8.0}, episodes=3)
    add("track_script_red_speed_s11", TRACK, ("track_speeding", None), 11, 6000,
        {"max_duration": 100.0})
    add("track_script_pump_s12", TRACK, ("track_pump", None), 12, 3000,
        {"incident_rules": {"max_acceleration": 4.0, "max_jerk": 3.0}})
    add("track_script_off_road_s13", TRACK, ("track_off_road", None), 13, 3000,
        episodes=2)
    add("track_script_site_car_s14", TRACK, ("track_pump", None), 14, 2000,
        {"vehicle": "site", "steps_per_action": 3, "obstacles": {"count": 2}})
    behavior = TRACK_BEHAVIOR
    add("track_behavior_random_long_s20", behavior, ("random", None), 20, 1500, episodes=2)
    add("track_behavior_go_s21", behavior, ("fixed", 0), 21, 700)
    add("track_behavior_stop_s22", behavior, ("fixed", 3), 22, 300)
    add("track_behavior_sequence_s23", behavior, ("sequence", [0, 0, 3, 3, 3, 1, 2, 3, 0]),
        23, 800)
    add("track_behavior_continuous_s24", behavior, ("random", None), 24, 600,
        {"action": "continuous", "decision_period_s": 0.5})
    add("track_behavior_manual_s25", behavior, ("random", None), 25, 700,
        {"track": {"manual": {"mode": "random", "interval_s": [10.0, 40.0],
                              "duration_s": [3.0, 8.0]}}})
    add("track_behavior_frames_s26", behavior, ("random", None), 26, 900,
        {"decision_period_s": 0.6, "track": {"steps_per_action": 3, "max_duration": 120.0}},
        episodes=3)
    add("track_behavior_site_s27", behavior, ("sequence", [0, 0, 0, 3, 1]), 27, 600,
        {"track": {"track": "site", "laps": 3}}, episodes=2)
    return items


def make_agent(spec: tuple[str, Any], env: gym.Env, seed: int) -> Any:
    kind, argument = spec
    if kind == "random":
        return RandomActions(env.action_space, 1000 + seed)
    if kind == "fixed":
        return RandomActions(env.action_space, 0, fixed=argument)
    if kind == "agent":
        from sdc_agents.registry import make_agent as registry_agent

        return registry_agent(argument, env)
    mph = 0.44704
    if kind == "stop_dead":
        return ScriptedPath(env, lambda t: min(8.0 * t, 20.0), lambda t: 6.0, stop_after_s=4.0)
    if kind == "speeding":
        return ScriptedPath(env, lambda t: min(3.0 * t, 55.0 * mph), lambda t: 6.0)
    if kind == "off_road":
        return ScriptedPath(env, lambda t: min(3.0 * t, 15.0),
                            lambda t: 6.0 if t < 3.0 else (4.0 if t < 10.0 else 12.5))
    if kind == "sequence":
        return SequenceActions(argument)
    if kind == "track_speeding":
        return TrackPursuit(env, lambda t: 16.0, lambda t: 0.0)
    if kind == "track_pump":
        return TrackPursuit(env, lambda t: 9.0, lambda t: 0.0, pump=True)
    if kind == "track_off_road":
        return TrackPursuit(env, lambda t: min(2.0 * t, 10.0),
                            lambda t: 0.0 if t < 8.0 else 0.4 * (t - 8.0))
    raise ValueError(f"unknown agent spec {spec!r}")


def run(scenario: dict[str, Any]) -> dict[str, Any]:
    env = gym.make(scenario["env"], config=scenario["config"])
    agent = make_agent(tuple(scenario["agent"]), env, scenario["seed"])
    keys = scenario.get("info_keys") or (
        PATH_INFO if scenario["env"] == HIGHWAY or scenario["env"] == BEHAVIOR else (
            "time", "distance", "progress", "incidents", "is_success", "termination_reason"))
    steps: list[str] = []
    summaries: list[str] = []
    obs, info = env.reset(seed=scenario["seed"])
    agent.reset()
    steps.append(_step_digest(obs, 0.0, False, False, info, keys))
    episodes = 1
    started = time.perf_counter()
    for _ in range(scenario["steps"]):
        obs, reward, terminated, truncated, info = env.step(agent.act(obs))
        steps.append(_step_digest(obs, reward, terminated, truncated, info, keys))
        if terminated or truncated:
            summaries.append(json.dumps(info["summary"], sort_keys=True))
            if episodes >= scenario["episodes"]:
                break
            episodes += 1
            obs, info = env.reset()
            agent.reset()
            steps.append(_step_digest(obs, 0.0, False, False, info, keys))
    else:
        inner = env.unwrapped
        inner = getattr(inner, "highway", None) or getattr(inner, "inner", None) or inner
        summary = inner.summary()
        summaries.append(json.dumps(summary, sort_keys=True))
    wall = time.perf_counter() - started
    env.close()
    incidents: dict[str, int] = {}
    for text in summaries:
        for kind, count in json.loads(text).get("incidents", {}).items():
            incidents[kind] = incidents.get(kind, 0) + count
    return {"steps": steps, "summaries": summaries, "wall_s": wall, "incidents": incidents}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--output", type=Path, help="record into this JSON file")
    group.add_argument("--compare", type=Path, help="check against this recording")
    parser.add_argument("--only", nargs="*", default=None, help="scenario names (substrings)")
    args = parser.parse_args()
    chosen = [s for s in scenarios()
              if not args.only or any(part in s["name"] for part in args.only)]
    recorded = json.loads(args.compare.read_text()) if args.compare else {}
    results: dict[str, Any] = {}
    failures = 0
    for scenario in chosen:
        name = scenario["name"]
        compact = recorded.get(name, {}).get("digest") is not None  # tests/data's form
        if compact:  # recorded as one digest of its first `steps` steps
            scenario = {**scenario, "steps": recorded[name]["steps"]}
        result = run(scenario)
        results[name] = result
        line = (f"{name:<38} steps {len(result['steps']):5d}  wall {result['wall_s']:6.2f} s  "
                f"incidents {result['incidents']}")
        if args.compare:
            old = recorded.get(name)
            if old is None:
                line += "  (not recorded)"
            elif compact:
                if (len(result["steps"]) == old["entries"]
                        and chain(result["steps"]) == old["digest"]):
                    line += "  IDENTICAL"
                else:
                    failures += 1
                    line += "  DIFFERS (the digest of the steps differs)"
            else:
                first = next((i for i, (a, b) in enumerate(
                    zip(old["steps"], result["steps"], strict=False)) if a != b), None)
                same_len = len(old["steps"]) == len(result["steps"])
                same_summary = old["summaries"] == result["summaries"]
                if first is None and same_len and same_summary:
                    line += "  IDENTICAL"
                else:
                    failures += 1
                    line += (f"  DIFFERS (first step {first}, lengths {len(old['steps'])}/"
                             f"{len(result['steps'])}, summaries "
                             f"{'same' if same_summary else 'differ'})")
        print(line, flush=True)
    if args.output:
        args.output.write_text(json.dumps(results))
        print(f"recorded {len(results)} scenarios into {args.output}")
    else:
        print(f"{len(chosen) - failures} of {len(chosen)} scenarios identical")
        if failures:
            raise SystemExit(1)


if __name__ == "__main__":
    main()
