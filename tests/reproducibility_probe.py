"""Print fingerprints of everything on the simulation's path that once went through
processor-dependent kernels: the roads' geometry, a Kalman track, short episodes of the
highway and track envs. Run by tests/test_reproducibility.py in processes with other
BLAS cores and numpy kernels; every line must be the same as in the default process."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sdc_gym  # noqa: E402, F401
from sdc_gym.road.builtin_highways import get_highway_map  # noqa: E402
from sdc_gym.road.builtin_tracks import get_track_map  # noqa: E402
from sdc_gym.stack.highway.kalman import FixedOrderKalmanFilter  # noqa: E402

ORIGINAL_MAP = ROOT.parent / "shared" / "data" / "udacity" / "path_planning" / "highway_map.csv"


def _hash(*arrays: np.ndarray) -> str:
    digest = hashlib.blake2b(digest_size=8)
    for array in arrays:
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def _episode(env_id: str, config: dict, seed: int, steps: int) -> str:
    env = gym.make(env_id, config=config)
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    parts = [obs]
    for _ in range(steps):
        action = int(rng.integers(env.action_space.n))
        obs, reward, terminated, truncated, _ = env.step(action)
        parts += [obs, np.float64(reward)]
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return _hash(*parts)


def fingerprints() -> dict[str, str]:
    out = {}
    for name in ("default", "oval", str(ORIGINAL_MAP)):
        ref = get_highway_map(name).reference
        out[f"highway {Path(name).name}"] = f"{ref.length.hex()} {_hash(ref._coef_xy)}"
    for name in ("default", "site"):
        track = get_track_map(name)
        out[f"track {name}"] = _hash(track.reference._coef_xy, track.light_yaw)
    kf = FixedOrderKalmanFilter(4, 4)
    kf.x = np.array([[10.0], [6.0], [20.0], [0.1]])
    kf.P = np.diag([0.25, 0.25, 0.5, 0.5])
    kf.R = kf.P.copy()
    kf.H = np.eye(4)
    transition = np.eye(4)
    transition[0, 2] = transition[1, 3] = 0.02
    rng = np.random.default_rng(5)
    states = []
    for _ in range(50):
        kf.predict(F=transition, Q=np.diag([1e-4, 1e-4, 0.04, 0.04]))
        kf.update(kf.x + rng.normal(size=(4, 1)) * 0.3)
        states.append(kf.x.copy())
    out["kalman"] = _hash(*states)
    out["highway behavior episode"] = _episode(
        "sdc_gym/HighwayLoopBehavior-v0",
        {"kalman_tracking": True, "highway": {"sensors": {"position_noise": 0.3}}}, 3, 150)
    out["track behavior episode"] = _episode("sdc_gym/TrackLoopBehavior-v0", {}, 4, 60)
    return out


if __name__ == "__main__":
    print(json.dumps(fingerprints(), indent=1, sort_keys=True))
