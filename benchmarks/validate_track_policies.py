"""Model selection on validation seeds for track policies: every checkpoint, one lap per seed.

    python benchmarks/validate_track_policies.py runs/dqn_track/checkpoints/*.zip \
        runs/dqn_track/model.zip --algo dqn --seeds 2000 --episodes 20

The track counterpart of ``validate_policies.py``: each model drives a batch of
``TrackLoopBehavior-v0`` envs deterministically with its own training config (the run
folder's ``config.yaml``), env ``i`` seeded ``seed + i``, one lap each (``track.laps: 1``, up
to ``--max-duration`` s), and the script prints per model the mean lap time with its 95 %
Student t interval, red-light violations, other incidents and stops, and how often each
decision was taken. Lap times of seeds that did not finish a lap are left out (counted in
``unfinished``). One batch and one forward pass per decision make it much faster than
``evaluate.py`` on ``TrackLoop-v0``, which remains the judge (the policy agent there runs
the same stack); keep validation seeds (2000-) apart from the held-out seeds (1000-1039).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401
from sdc_agents.policy_agent import load_model, training_config
from sdc_evaluation.statistics import mean_interval
from sdc_gym.envs.batch_vector import env_info
from sdc_gym.stack.track.decisions import TRACK_ACTION_NAMES


def validate(model_path: Path, algo: str, seed: int, episodes: int,
             max_duration: float) -> dict[str, float]:
    """One lap per seed of ``model_path``: mean lap time, interval, incidents, decisions."""
    env_id, trained = training_config(model_path)
    config = dict(trained)
    config["track"] = {**dict(config.get("track") or {}), "laps": 1,
                       "max_duration": max_duration}
    envs = gym.make_vec(env_id or "sdc_gym/TrackLoopBehavior-v0", num_envs=episodes,
                        config=config, vectorization_mode="vector_entry_point")
    model = load_model(algo, model_path)
    observations, _ = envs.reset(seed=seed)
    laps = np.full(episodes, np.nan)
    red = np.zeros(episodes, dtype=int)
    other = np.zeros(episodes, dtype=int)
    stops = np.zeros(episodes, dtype=int)
    done = np.zeros(episodes, dtype=bool)
    chosen = np.zeros(len(TRACK_ACTION_NAMES), dtype=int)
    while not done.all():
        actions, _ = model.predict(observations, deterministic=True)
        chosen += np.bincount(np.asarray(actions)[~done], minlength=len(chosen))
        observations, _, terminated, truncated, infos = envs.step(actions)
        for env in np.flatnonzero((terminated | truncated) & ~done):
            summary = env_info(infos, env)["summary"]
            if summary["lap_times"]:
                laps[env] = summary["lap_times"][0]
            red[env] = summary["red_light_violations"]
            other[env] = summary["incident_total"] - summary["incidents"].get("red_light", 0)
            stops[env] = len(summary["stops"])
            done[env] = True
    envs.close()
    finished = laps[np.isfinite(laps)]
    interval = mean_interval(finished) if len(finished) > 1 else None
    share = chosen / max(chosen.sum(), 1)
    return {"lap": interval.value if interval else float("nan"),
            "low": interval.low if interval else float("nan"),
            "high": interval.high if interval else float("nan"),
            "red": int(red.sum()), "other": int(other.sum()), "stops": int(stops.sum()),
            "unfinished": int(episodes - len(finished)),
            **{name: float(s) for name, s in zip(TRACK_ACTION_NAMES, share, strict=True)}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("models", nargs="+", type=Path)
    parser.add_argument("--algo", default="dqn")
    parser.add_argument("--seeds", type=int, default=2000, help="first validation seed")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--max-duration", type=float, default=1200.0)
    args = parser.parse_args()
    print("| model | mean lap s [95 % CI] | unfinished | red lights | other incidents | stops "
          "| go / go_75 / go_50 / stop |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for path in args.models:
        r = validate(path, args.algo, args.seeds, args.episodes, args.max_duration)
        print(f"| {path} | {r['lap']:.1f} [{r['low']:.1f}, {r['high']:.1f}] | "
              f"{r['unfinished']} | {r['red']} | {r['other']} | {r['stops']} | "
              f"{r['go']:.2f} / {r['go_75']:.2f} / {r['go_50']:.2f} / {r['stop']:.2f} |",
              flush=True)


if __name__ == "__main__":
    main()
