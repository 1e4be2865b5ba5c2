"""What a highway policy does on its validation laps: its choices, its lane changes, its pace.

    python benchmarks/study_policy_behavior.py ppo:runs/ppo/model.zip \
        dqn:agents/highway/policies/dqn_swa_highway.zip --seed 2000 --episodes 40

Issue 28 asks, where a policy-gradient method does not beat ``fsm_bold``, for the reason
shown with measurements of what the policy does rather than a guess. This drives each
model greedily (as ``evaluate.py`` and the validation laps do) on one native batch of
``HighwayLoopBehavior-v0`` laps, env ``i`` seeded ``seed + i``, with the model's own
training config, and reports per model:

* the mean mph over the laps and its 95 % interval (the validation figure);
* the share of decisions per lane move (left / keep / right) and per speed move
  (cruise / hold / slow) of :data:`~sdc_gym.stack.highway.decisions.ACTION_NAMES`;
* per lap, the lane changes started, the lane moves the safety shield refused and the
  changes it aborted (the executor's counters, ``info["behavior"]``);
* the share of decisions driven below ``--slow-mph`` (default 45 mph, 5 under the
  cruise speed): time spent following a slower car or slowing on purpose;
* for a stochastic policy (PPO, A2C), the mean entropy of its action distribution over
  the greedy laps' decisions (nats; ln 9 = 2.20 is uniform): how far the policy that
  collected its training data is from the greedy one measured here.

A policy faster than another on the same seeds differs in these (more lane changes into
room, less time below the slow line); one that keeps its lane, or asks for moves the
shield refuses, shows it here.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Any

import numpy as np

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_agents.policy_agent import POLICY_KINDS, load_model, training_config
from sdc_gym.envs.batch_vector import env_info
from sdc_gym.stack.highway.decisions import LANE_MOVES, SPEED_MOVES
from sdc_gym.units import MPS_TO_MPH
from sdc_training.validation_laps import drive_laps, make_lap_envs, score_laps

ENV_ID = "sdc_gym/HighwayLoopBehavior-v0"
COUNTERS = ("lane_changes", "refused", "aborted")


@dataclass(frozen=True)
class PolicyBehavior:
    """One model's laps, summarised (see the module docstring)."""

    name: str
    mph: float
    mph_low: float
    mph_high: float
    action_counts: np.ndarray          # per ACTION_NAMES entry, over every lap's decisions
    per_lap: dict[str, float]          # COUNTERS, mean per lap
    slow_share: float                  # decisions below the slow line / decisions
    entropy: float | None              # mean nats over the decisions (None: greedy-only)
    collisions: int
    incidents: int

    def lane_shares(self) -> dict[str, float]:
        counts = self.action_counts.reshape(len(LANE_MOVES), len(SPEED_MOVES)).sum(axis=1)
        return dict(zip(LANE_MOVES, counts / max(1, counts.sum()), strict=True))

    def speed_shares(self) -> dict[str, float]:
        counts = self.action_counts.reshape(len(LANE_MOVES), len(SPEED_MOVES)).sum(axis=0)
        return dict(zip(SPEED_MOVES, counts / max(1, counts.sum()), strict=True))


def parse_spec(spec: str) -> tuple[str, str]:
    """``kind:path`` into its two parts; ValueError naming the valid kinds."""
    kind, sep, path = spec.partition(":")
    if not sep or kind not in POLICY_KINDS or not path:
        raise ValueError(f"model {spec!r}: expected KIND:PATH with KIND one of "
                         f"{list(POLICY_KINDS)}")
    return kind, path


def action_entropy(model: Any, observations: np.ndarray) -> np.ndarray | None:
    """Per observation, the entropy of ``model``'s action distribution (None: a model
    without one, such as DQN's greedy Q-network)."""
    policy = getattr(model, "policy", None)
    if policy is None or not hasattr(policy, "get_distribution"):
        return None
    import torch

    with torch.no_grad():
        tensor, _ = policy.obs_to_tensor(observations)
        return policy.get_distribution(tensor).entropy().cpu().numpy()


def study(name: str, model: Any, config: dict[str, Any], seed: int, episodes: int,
          slow_mph: float, max_duration: float = 600.0) -> PolicyBehavior:
    """Drive ``model`` greedily for one lap on each of ``episodes`` seeds from ``seed``
    (the validation laps' own loop, with an observer of every step)."""
    counters = dict.fromkeys(COUNTERS, 0)
    entropies: list[np.ndarray] = []
    slow = decisions = 0

    def observe(observations: np.ndarray, infos: dict[str, Any], live: np.ndarray,
                ended: np.ndarray) -> None:
        nonlocal slow, decisions
        entropy = action_entropy(model, observations)
        if entropy is not None:
            entropies.append(entropy[live])
        speeds = np.asarray(infos["speed"], dtype=float) * MPS_TO_MPH
        slow += int(np.count_nonzero(speeds[live] < slow_mph))
        decisions += int(live.sum())
        for env in np.flatnonzero(ended):
            behavior = env_info(infos, env)["behavior"]
            for key in COUNTERS:
                counters[key] += int(behavior[key])

    envs = make_lap_envs(ENV_ID, config, episodes, max_duration, full_info=True)
    try:
        batch = drive_laps(envs, lambda obs: model.predict(obs, deterministic=True)[0],
                           seed, on_step=observe)
    finally:
        envs.close()
    score = score_laps(ENV_ID, batch.summaries)
    return PolicyBehavior(
        name=name, mph=score.value, mph_low=score.low, mph_high=score.high,
        action_counts=batch.action_counts,
        per_lap={key: value / episodes for key, value in counters.items()},
        slow_share=slow / max(1, decisions),
        entropy=float(np.concatenate(entropies).mean()) if entropies else None,
        collisions=score.counts["collisions"], incidents=score.counts["incidents"])


def table(rows: list[PolicyBehavior], slow_mph: float) -> str:
    """The results as a Markdown table (as docs/rl.md shows them)."""
    lanes = " / ".join(LANE_MOVES)
    speeds = " / ".join(SPEED_MOVES)
    lines = [f"| model | mph [95 % CI] | {lanes} | {speeds} | lane changes / lap | "
             f"refused / lap | aborted / lap | below {slow_mph:g} mph | entropy (nats) | "
             "collisions | incidents |",
             "|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        lane = " / ".join(f"{v:.2f}" for v in row.lane_shares().values())
        speed = " / ".join(f"{v:.2f}" for v in row.speed_shares().values())
        entropy = "-" if row.entropy is None else f"{row.entropy:.2f}"
        lines.append(
            f"| {row.name} | {row.mph:.2f} [{row.mph_low:.2f}, {row.mph_high:.2f}] | {lane} | "
            f"{speed} | {row.per_lap['lane_changes']:.1f} | {row.per_lap['refused']:.1f} | "
            f"{row.per_lap['aborted']:.2f} | {row.slow_share:.1%} | {entropy} | "
            f"{row.collisions} | {row.incidents} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("models", nargs="+", metavar="KIND:PATH",
                        help=f"models to study, KIND one of {list(POLICY_KINDS)}")
    parser.add_argument("--seed", type=int, default=2000, help="the first validation seed")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--slow-mph", type=float, default=45.0)
    args = parser.parse_args(argv)
    if args.episodes < 2:
        parser.error(f"--episodes: {args.episodes}; at least 2 (an interval needs two laps)")
    rows = []
    for spec in args.models:
        try:
            kind, path = parse_spec(spec)
        except ValueError as error:
            parser.error(str(error))
        env_id, config = training_config(path)
        if env_id not in (None, ENV_ID):
            parser.error(f"model {spec!r} was trained on {env_id}, not {ENV_ID}")
        rows.append(study(spec, load_model(kind, path), config, args.seed, args.episodes,
                          args.slow_mph))
        print(table(rows[-1:], args.slow_mph), flush=True)
    print()
    print(table(rows, args.slow_mph))


if __name__ == "__main__":
    main()
