"""Model selection on validation seeds for track policies: every checkpoint, one lap per seed.

    python benchmarks/validate_track_policies.py runs/dqn_track/checkpoints/*.zip \
        runs/dqn_track/model.zip rule --algo dqn --seeds 2000 --episodes 20

The track counterpart of ``validate_policies.py``: each model drives a batch of
``TrackLoopBehavior-v0`` envs deterministically with its own training config (the run
folder's ``config.yaml``), env ``i`` seeded ``seed + i``, one lap each (``track.laps: 1``, up
to ``--max-duration`` s), and the script prints per model the mean lap time with its 95 %
Student t interval, red-light violations, other incidents and stops, and how often each
decision was taken. The name ``rule`` stands for the stack's own stop-at-red rule (``go``
at every decision with the red-light shield on), driven with the first model's config: the
baseline in the same batch. Lap times of seeds that did not finish a lap are left out (counted in
``unfinished``). One batch and one forward pass per decision make it much faster than
``evaluate.py`` on ``TrackLoop-v0``, which remains the judge (the policy agent there runs
the same stack); keep validation seeds (2000-) apart from the held-out seeds (1000-1039).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import sdc_gym  # noqa: F401
from sdc_agents.policy_agent import load_model, training_config
from sdc_gym.stack.track.decisions import TRACK_ACTION_NAMES
from sdc_training.validation_laps import drive_laps, make_lap_envs, score_laps

DEFAULT_ENV = "sdc_gym/TrackLoopBehavior-v0"
RULE = "rule"
"""The model name that drives ``go`` at every decision with the red-light shield on: the
DBW stack's stop-at-red rule itself, in the same batch (the baseline of the table)."""


def validate(model_path: Path, algo: str, seed: int, episodes: int, max_duration: float,
             rule_config: Path | None = None) -> dict[str, float]:
    """One lap per seed of ``model_path`` (or of the rule, :data:`RULE`, with the config of
    the model ``rule_config``): mean lap time, interval, incidents, decisions."""
    env_id, trained = training_config(rule_config if str(model_path) == RULE else model_path)
    env_id = env_id or DEFAULT_ENV
    model = None if str(model_path) == RULE else load_model(algo, model_path)
    if model is None:
        trained = {**trained, "red_light_shield": True}

    def act(observations: np.ndarray) -> np.ndarray:
        if model is None:  # go everywhere: the shield executes the rule's stops
            return np.zeros(len(observations), dtype=np.int64)
        return model.predict(observations, deterministic=True)[0]

    envs = make_lap_envs(env_id, trained, episodes, max_duration)
    try:
        batch = drive_laps(envs, act, seed)
    finally:
        envs.close()
    score = score_laps(env_id, batch.summaries)
    share = batch.action_counts / max(int(batch.action_counts.sum()), 1)
    return {"lap": score.value, "low": score.low, "high": score.high,
            "red": score.counts["red_lights"], "stops": score.counts["stops"],
            "other": score.counts["incidents"] - score.counts["red_lights"],
            "unfinished": score.counts["unfinished"],
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
    if all(str(path) == RULE for path in args.models):
        parser.error(f"{RULE!r} takes its env config from a model: give at least one model")
    config_source = next(path for path in args.models if str(path) != RULE)
    for path in args.models:
        r = validate(path, args.algo, args.seeds, args.episodes, args.max_duration,
                     config_source)
        print(f"| {path} | {r['lap']:.1f} [{r['low']:.1f}, {r['high']:.1f}] | "
              f"{r['unfinished']} | {r['red']} | {r['other']} | {r['stops']} | "
              f"{r['go']:.2f} / {r['go_75']:.2f} / {r['go_50']:.2f} / {r['stop']:.2f} |",
              flush=True)


if __name__ == "__main__":
    main()
