"""Tuning the drive-by-wire stack's gains: Twiddle (the seed team's suggestion) and Optuna.

The seed team (seed 000) tuned its speed PID by hand (kp 0.8, ki 0.25, kd 0.1) and listed
"auto-tuning algorithms such as the Twiddle algorithm" as further work. The gains tuned
here: the speed PID's ``kp``, ``ki``, ``kd`` and the steering side's, pure pursuit's
look-ahead (``lookahead_min_m``, ``lookahead_gain_s``: the stack steers through pure
pursuit and the yaw controller, which has no gain of its own).

The objective (:func:`tuning_cost`, lower is better) drives one short scripted episode
(:data:`TUNING_CONFIG`: the default track, 200 s, the first light red for its first 40 s
and every other light green, so every candidate meets the same stop) and adds

* the cross-track error's RMS over 0.05 m (the seed stack's is ~0.2 m on a lap),
* the stop's distance from the 1 m gap before the line (the middle of the 0..2 m window)
  over 0.25 m; a missing stop costs 10,
* 10 per incident (red-light violations, acceleration, jerk, off road...).

:func:`twiddle` is Thrun's coordinate search (Udacity's AI for Robotics): for each gain,
try ``+dp``; if no better, ``-dp``; a success grows ``dp`` by 1.1, a failure shrinks it by
0.9. :func:`optuna_tune` runs Optuna's TPE sampler (seeded: the same trials every run)
over ranges around the seed's gains. ``python -m sdc_agents.track.tuning`` runs both and
writes the winners to :data:`TUNED_GAINS` (committed; the agents ``dbw_twiddle`` and
``dbw_optuna`` load them with :func:`tuned_parameters`).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

from sdc_agents.track.dbw_agent import dbw_agent
from sdc_gym.lights.traffic_lights import GREEN, RED
from sdc_gym.stack.track.controllers import TwistControllerParameters
from sdc_gym.stack.track.dbw_stack import DBWStackAgent
from sdc_gym.stack.track.follower import CONTINUOUS_FOLLOWER, FollowerParameters
from sdc_gym.validation.yaml_files import read_yaml

GAIN_NAMES = ("kp", "ki", "kd", "lookahead_min_m", "lookahead_gain_s")
"""The tuned gains, in this order (speed PID, then pure pursuit's look-ahead)."""
SEED_GAINS: dict[str, float] = {"kp": 0.8, "ki": 0.25, "kd": 0.1,
                                "lookahead_min_m": CONTINUOUS_FOLLOWER.lookahead_min_m,
                                "lookahead_gain_s": CONTINUOUS_FOLLOWER.lookahead_gain_s}
LOWER_BOUNDS: dict[str, float] = {"kp": 0.05, "ki": 0.0, "kd": 0.0, "lookahead_min_m": 1.0,
                                  "lookahead_gain_s": 0.0}
"""Twiddle's floor per gain: a look-ahead under 1 m or a negative gain is no candidate."""
TUNED_GAINS = Path(__file__).with_name("tuned_gains.yaml")
STOP_GAP_TARGET_M = -1.0  # stop offset (front bumper, + past the line): 1 m before it
FIRST_RED_S = 40.0
TUNING_CONFIG: dict[str, Any] = {
    "track": "default", "laps": 1, "observe_light_states": True, "max_duration": 200.0,
    "lights": {"script": [[[0.0, RED], [FIRST_RED_S, GREEN]]] + [GREEN] * 7},
}


@dataclass(frozen=True)
class TuningResult:
    """A tuner's best gains, their cost and the number of episodes it drove."""

    gains: dict[str, float]
    cost: float
    evaluations: int


def stack_parameters(gains: Mapping[str, float]
                     ) -> tuple[TwistControllerParameters, FollowerParameters]:
    """The twist controller's and pure pursuit's settings with ``gains`` (keys
    :data:`GAIN_NAMES`; a missing key keeps the seed's, an unknown one is an error)."""
    unknown = sorted(set(gains) - set(GAIN_NAMES))
    if unknown:
        raise ValueError(f"unknown gains {unknown}; valid: {list(GAIN_NAMES)}")
    g = {**SEED_GAINS, **{k: float(v) for k, v in gains.items()}}
    controller = TwistControllerParameters(kp=g["kp"], ki=g["ki"], kd=g["kd"])
    follower = replace(CONTINUOUS_FOLLOWER, lookahead_min_m=g["lookahead_min_m"],
                       lookahead_gain_s=g["lookahead_gain_s"])
    return controller, follower


def episode_summary(gains: Mapping[str, float], seed: int = 0,
                    config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The summary of the episode :func:`tuning_cost` drives, with ``gains``."""
    controller, follower = stack_parameters(gains)
    env = gym.make("sdc_gym/TrackLoop-v0", config=dict(config or TUNING_CONFIG))
    agent = dbw_agent(env, "ground_truth", follower=follower, controller=controller,
                      name="tuning")
    agent.reset()
    observation, _ = env.reset(seed=seed)
    while True:
        observation, _, terminated, truncated, info = env.step(agent.act(observation))
        if terminated or truncated:
            break
    env.close()
    return info["summary"]


def summary_cost(summary: Mapping[str, Any]) -> float:
    """The objective of one episode's summary (see the module docstring)."""
    cost = summary["rms_cross_track_error"] / 0.05 + 10.0 * summary["incident_total"]
    stops = summary["stops"]
    if not stops:
        return cost + 10.0
    return cost + abs(stops[0]["offset_m"] - STOP_GAP_TARGET_M) / 0.25


def tuning_cost(gains: Mapping[str, float], seed: int = 0,
                config: Mapping[str, Any] | None = None) -> float:
    """The objective of ``gains`` (lower is better): one scripted episode (``config``,
    default :data:`TUNING_CONFIG`)."""
    return summary_cost(episode_summary(gains, seed, config))


def twiddle(cost: Callable[[Mapping[str, float]], float], start: Mapping[str, float],
            steps: Mapping[str, float], *, max_evaluations: int = 40,
            tolerance: float = 1e-3,
            lower: Mapping[str, float] | None = None) -> TuningResult:
    """Thrun's Twiddle from ``start`` with initial steps ``steps`` until the steps sum
    below ``tolerance`` (relative to the start's magnitudes) or ``max_evaluations``.
    A candidate below its ``lower`` bound is clamped to it."""
    names = list(start)
    if set(steps) != set(names):
        raise ValueError(f"twiddle: steps must name the same gains as start {names}, "
                         f"got {sorted(steps)}")
    if max_evaluations < 1:
        raise ValueError(f"twiddle: max_evaluations must be >= 1, got {max_evaluations}")
    floor = dict(lower or {})
    p = {k: float(start[k]) for k in names}
    dp = {k: float(steps[k]) for k in names}
    best = cost(p)
    evaluations = 1

    def trial(name: str, value: float) -> float:
        nonlocal evaluations
        candidate = {**p, name: max(value, floor.get(name, -math.inf))}
        evaluations += 1
        return cost(candidate)

    while sum(dp.values()) > tolerance and evaluations < max_evaluations:
        for name in names:
            if evaluations >= max_evaluations:
                break
            original = p[name]
            up = trial(name, original + dp[name])
            if up < best:
                best, p[name] = up, max(original + dp[name], floor.get(name, -math.inf))
                dp[name] *= 1.1
                continue
            if evaluations >= max_evaluations:
                break
            down = trial(name, original - dp[name])
            if down < best:
                best, p[name] = down, max(original - dp[name], floor.get(name, -math.inf))
                dp[name] *= 1.1
            else:
                dp[name] *= 0.9
    return TuningResult(p, best, evaluations)


def optuna_tune(cost: Callable[[Mapping[str, float]], float],
                ranges: Mapping[str, tuple[float, float]], *, trials: int = 40,
                seed: int = 0, start: Mapping[str, float] | None = None) -> TuningResult:
    """Optuna's TPE sampler (seeded) over ``ranges``, ``trials`` episodes; ``start`` (the
    seed's gains by default) is the first trial, so the result is never worse."""
    import optuna  # the "tuning" extra

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=seed))
    first = dict(start or {k: SEED_GAINS[k] for k in ranges})
    study.enqueue_trial(first)
    study.optimize(lambda t: cost({k: t.suggest_float(k, lo, hi)
                                   for k, (lo, hi) in ranges.items()}), n_trials=trials)
    return TuningResult(dict(study.best_params), float(study.best_value), trials)


OPTUNA_RANGES: dict[str, tuple[float, float]] = {
    "kp": (0.1, 3.0), "ki": (0.0, 1.0), "kd": (0.0, 0.5), "lookahead_min_m": (1.0, 10.0),
    "lookahead_gain_s": (0.0, 3.0)}
TWIDDLE_STEPS: dict[str, float] = {"kp": 0.2, "ki": 0.1, "kd": 0.05, "lookahead_min_m": 1.0,
                                   "lookahead_gain_s": 0.5}


def tuned_parameters(tuner: str, path: Path = TUNED_GAINS
                     ) -> tuple[TwistControllerParameters, FollowerParameters]:
    """The committed gains of ``tuner`` (``"twiddle"`` or ``"optuna"``) as stack settings."""
    data = read_yaml(path, "tuned gains")
    if not isinstance(data, dict) or tuner not in data:
        raise ValueError(f"{path}: no gains for tuner {tuner!r}; it has "
                         f"{sorted(data) if isinstance(data, dict) else type(data).__name__}")
    gains = data[tuner].get("gains") if isinstance(data[tuner], dict) else None
    if not isinstance(gains, dict):
        raise ValueError(f"{path}: {tuner}.gains must be a mapping of {list(GAIN_NAMES)}")
    return stack_parameters(gains)


def tuned_dbw_agent(env: gym.Env, tuner: str) -> DBWStackAgent:
    """The stack with the committed gains of ``tuner`` (``"twiddle"`` or ``"optuna"``):
    speed PID and pure pursuit's look-ahead, ground-truth lights."""
    controller, follower = tuned_parameters(tuner)
    return dbw_agent(env, "ground_truth", follower=follower, controller=controller,
                     name=f"dbw_{tuner}")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tuners", nargs="+", choices=("twiddle", "optuna"),
                        default=["twiddle", "optuna"])
    parser.add_argument("--evaluations", type=int, default=40,
                        help="episodes per tuner (default 40)")
    parser.add_argument("--seed", type=int, default=0, help="the episode's seed")
    parser.add_argument("--output", type=Path, default=TUNED_GAINS)
    args = parser.parse_args(argv)
    data = read_yaml(args.output, "tuned gains") if args.output.exists() else {}

    def cost(gains: Mapping[str, float]) -> float:
        return tuning_cost(gains, args.seed)

    seed_cost = cost(SEED_GAINS)
    print(f"seed's gains {SEED_GAINS}: cost {seed_cost:.4f}")
    for tuner in args.tuners:
        if tuner == "twiddle":
            result = twiddle(cost, SEED_GAINS, TWIDDLE_STEPS, lower=LOWER_BOUNDS,
                             max_evaluations=args.evaluations)
        else:
            result = optuna_tune(cost, OPTUNA_RANGES, trials=args.evaluations,
                                 seed=args.seed)
        print(f"{tuner}: {result.gains} cost {result.cost:.4f} "
              f"({result.evaluations} episodes)")
        data[tuner] = {"gains": {k: round(float(v), 6) for k, v in result.gains.items()},
                       "cost": round(result.cost, 6), "seed_cost": round(seed_cost, 6),
                       "episodes": result.evaluations, "episode_seed": args.seed,
                       "command": f"python -m sdc_agents.track.tuning --tuners {tuner} "
                                  f"--evaluations {args.evaluations} --seed {args.seed}"}
    args.output.write_text("# Tuned gains of the track stack (agents/track/tuning.py).\n"
                           + yaml.safe_dump(data, sort_keys=True))


if __name__ == "__main__":
    main()
