"""Simulated seconds per wall second of the track loop, and camera frames per second through it.

    python benchmarks/bench_track.py [--seconds 120] [--camera-steps 500] [--repeats 3]

Without camera: ``sdc_gym/TrackLoop-v0`` on the default ~7 km track, driven by a small
pure-pursuit + proportional-speed controller written here (agent time included, like
``bench_highway.py``), one env step = 1 physics frame (50 Hz, the DBW rate) and = 5
frames; then the same action sequences replayed with no controller (env alone; the env is
deterministic, so the replay drives the same trajectory). Each run drives ``--seconds``
simulated seconds from the start (lights cycling, so the car crosses some lights).

With camera: env steps per wall second with ``camera.enabled`` at the track's full 800 x
600 and at the training 200 x 150 size, one camera frame per env step (1 physics frame),
brightness jitter and noise on (the defaults), the car driving from 150 m before the first
light so that lights are in view. The best of ``--repeats`` runs is reported.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401

ENV_ID = "sdc_gym/TrackLoop-v0"
PHYSICS_DT = 0.02
LOOKAHEAD_MIN_M = 6.0  # m; look-ahead max(6 m, 1 s of travel)
SPEED_GAIN = 0.5  # throttle per m/s of speed error
BRAKE_GAIN = 300.0  # N m per m/s of overspeed
MAX_BRAKE_NM = 1000.0
FIRST_LIGHT_S = 230.0  # the default track's first stop line


class PursuitController:
    """Pure pursuit on the track's path and a proportional speed loop, in scalar Python."""

    def __init__(self, env: Any, target_speed: float) -> None:
        base = env.unwrapped
        self.line, self.car, self.target = base.track.reference, base.params, target_speed
        self.s: float | None = None

    def act(self, obs: dict[str, Any]) -> np.ndarray:
        x, y, yaw = obs["pose"].tolist()
        speed = float(obs["velocity"][0])
        guess = self.s if self.s is not None else float(self.line.to_frenet(np.array([x, y]))[0])
        (self.s,), _ = self.line.project_few([[x, y]], [guess])
        tx, ty, *_ = self.line.line_frames_few([self.s + max(LOOKAHEAD_MIN_M, speed)])[0]
        dx, dy = tx - x, ty - y
        lateral = -math.sin(yaw) * dx + math.cos(yaw) * dy
        wheel = math.atan(self.car.wheel_base * 2.0 * lateral / (dx * dx + dy * dy))
        limit = self.car.max_steer_angle
        steering = min(max(self.car.steer_ratio * wheel, -limit), limit)
        error = self.target - speed
        throttle = min(max(SPEED_GAIN * error, 0.0), 1.0)
        brake = min(max(-BRAKE_GAIN * error, 0.0), MAX_BRAKE_NM)
        return np.array([throttle, brake, steering], dtype=np.float32)


def drive(frames: int, seconds: float, seed: int) -> tuple[float, list[np.ndarray]]:
    """Simulated s per wall s of env + controller, and the actions it sent."""
    env = gym.make(ENV_ID, config={"steps_per_action": frames})
    controller = PursuitController(env, 0.95 * env.unwrapped.speed_limit)
    obs, _ = env.reset(seed=seed)
    steps = round(seconds / (PHYSICS_DT * frames))
    actions = []
    started = time.perf_counter()
    for _ in range(steps):
        action = controller.act(obs)
        actions.append(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            raise RuntimeError("the benchmark drive ended early; shorten --seconds")
    wall = time.perf_counter() - started
    env.close()
    return steps * PHYSICS_DT * frames / wall, actions


def replay(frames: int, actions: list[np.ndarray], seed: int) -> float:
    """Simulated s per wall s of the env alone, replaying recorded actions."""
    env = gym.make(ENV_ID, config={"steps_per_action": frames})
    env.reset(seed=seed)
    started = time.perf_counter()
    for action in actions:
        env.step(action)
    wall = time.perf_counter() - started
    env.close()
    return len(actions) * PHYSICS_DT * frames / wall


def camera_rate(preset: str, steps: int, seed: int) -> float:
    """Env steps (= camera frames) per wall second with the camera on."""
    env = gym.make(ENV_ID, config={"camera": {"enabled": True, "preset": preset},
                                   "start_s": FIRST_LIGHT_S - 150.0})
    controller = PursuitController(env, 0.95 * env.unwrapped.speed_limit)
    obs, _ = env.reset(seed=seed)
    actions = []
    for _ in range(steps):  # drive once to record the actions, then time a replay
        actions.append(controller.act(obs))
        obs, *_ = env.step(actions[-1])
    env.reset(seed=seed)
    started = time.perf_counter()
    for action in actions:
        env.step(action)
    wall = time.perf_counter() - started
    env.close()
    return steps / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=120.0, help="simulated s per run")
    parser.add_argument("--camera-steps", type=int, default=500, help="env steps per run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"{'TrackLoop-v0, no camera':42} {'frames/step':>11} {'sim s / wall s':>15}")
    for frames in (1, 5):
        runs = [drive(frames, args.seconds, seed) for seed in range(args.repeats)]
        print(f"{'env + pursuit controller':42} {frames:>11} "
              f"{max(rate for rate, _ in runs):>15.0f}")
        alone = max(replay(frames, actions, seed) for seed, (_, actions) in enumerate(runs))
        print(f"{'env alone (replayed actions)':42} {frames:>11} {alone:>15.0f}")
    print()
    print(f"{'TrackLoop-v0, camera on (1 frame/step)':42} {'size':>11} {'frames/s':>15}")
    for preset, size in (("full", "800x600"), ("training", "200x150")):
        rate = max(camera_rate(preset, args.camera_steps, seed) for seed in range(args.repeats))
        print(f"{'env + camera, ' + preset:42} {size:>11} {rate:>15.0f}")


if __name__ == "__main__":
    main()
