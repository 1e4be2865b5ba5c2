"""Model selection on validation seeds: every checkpoint of a run, one lap per seed, batched.

    python benchmarks/validate_policies.py runs/dqn_a/checkpoints/*.zip runs/dqn_a/model.zip \
        --algo dqn --seeds 2000 --episodes 20

Runs each model deterministically on a batch of ``HighwayLoopBehavior-v0`` envs with the
model's own training config (the run folder's ``config.yaml``), env ``i`` seeded
``seed + i``, each for one lap (``highway.laps: 1``, up to ``--max-duration`` s), and prints
per model the mean mph with its 95 % Student t interval, collisions and incidents. One
batch and one forward pass per decision for all seeds make this about an order of magnitude
faster than ``evaluate.py`` on the path-level env, which remains the judge: the policy agent
there drives the same behavior env's layered stack, so a ranking made here carries over, but
report final figures from ``evaluate.py``. Keep validation seeds (2000-) apart from the
held-out seeds (1000-1039) and train.py's evaluation seeds (10000-).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import sdc_gym  # noqa: F401
from sdc_agents.policy_agent import SB3_KINDS, load_model, training_config
from sdc_training.validation_laps import CSV_NAME, append_row, make_lap_envs, validate_model

DEFAULT_ENV = "sdc_gym/HighwayLoopBehavior-v0"


def validate(model_path: Path, algo: str, seed: int, episodes: int,
             max_duration: float, record: Path | None = None) -> dict[str, float]:
    """One lap per seed of ``model_path``; the batch's mean mph, interval and incidents.
    With ``record`` (a run folder), the result is also appended to its ``validations.csv``
    at the model's timesteps, as train.py's ``validation`` key writes it."""
    env_id, trained = training_config(model_path)
    env_id = env_id or DEFAULT_ENV
    model = load_model(algo, model_path)
    envs = make_lap_envs(env_id, trained, episodes, max_duration)
    try:
        score, _ = validate_model(model, envs, env_id, seed)
    finally:
        envs.close()
    if record is not None:
        append_row(record, int(model.num_timesteps), score)
    return {"mph": score.value, "low": score.low, "high": score.high, **score.counts}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("models", nargs="+", type=Path)
    parser.add_argument("--algo", required=True, choices=SB3_KINDS)
    parser.add_argument("--seeds", type=int, default=2000, help="the first validation seed")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--max-duration", type=float, default=600.0)
    parser.add_argument("--record", type=Path, default=None, metavar="RUN",
                        help=f"append each result to RUN/{CSV_NAME} (a run trained without "
                             "the validation key gets the same curve file)")
    args = parser.parse_args(argv)
    print(f"{'model':<48} {'mph [95% CI]':>22} {'laps':>5} {'coll':>5} {'inc':>5}")
    for model in args.models:
        row = validate(model, args.algo, args.seeds, args.episodes, args.max_duration,
                       args.record)
        print(f"{model!s:<48} {row['mph']:6.2f} [{row['low']:.2f}, {row['high']:.2f}]"
              f" {row['laps']:>5} {row['collisions']:>5} {row['incidents']:>5}", flush=True)


if __name__ == "__main__":
    main()
