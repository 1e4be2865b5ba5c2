"""One lap per validation seed, as one batch: model selection apart from the held-out seeds.

Issue 28 keeps three seed ranges apart: training seeds (the run's ``seed`` and its
continuations), validation seeds (2000-, model selection) and held-out seeds (1000-1039,
the reported comparison, ``evaluate.py``). Here a policy drives a native batch of
behavior envs (:data:`LAP_SECTIONS`) deterministically, env ``i`` seeded ``seed + i``, each
for exactly one lap (the env config's lap section gets ``laps: 1`` and a time limit), with
one forward pass per decision for the whole batch: about 35 s for 40 highway laps, an
order of magnitude faster than ``evaluate.py`` on the path-level env, whose policy agent
drives the same layered stack (so a ranking made here carries over).

- :func:`drive_laps` runs the batch and returns each env's episode summary;
- :func:`score_laps` turns them into the figure that ranks models: mean mph on the
  highway (higher is better), mean lap time on the track (lower is better); a model with an
  incident of any kind (a collision, a red light, a jerk or speed violation...) or, on the
  track, an unfinished lap is not eligible to be the best, as issue 28's bar asks (no more
  incidents than the rule-based agents, which have none on these seeds);
- :func:`validation_callback` does both during ``train.py`` runs (run config key
  ``validation``), logs ``validation/*`` to TensorBoard, keeps every result in
  ``validations.csv`` and the best eligible model in ``best_validation_model.zip``, each
  written atomically, and carries the best so far across ``--resume``.

``benchmarks/validate_policies.py`` and ``benchmarks/validate_track_policies.py`` score
saved checkpoints with the same functions.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import gymnasium as gym
import numpy as np

from sdc_evaluation.statistics import mean_interval

LAP_SECTIONS: Final = {"sdc_gym/HighwayLoopBehavior-v0": "highway",
                       "sdc_gym/TrackLoopBehavior-v0": "track"}
"""The behavior envs validated here, and the key of their path-level env's config (where
``laps`` and ``max_duration`` live)."""
MAX_DURATION_S: Final = {"highway": 600.0, "track": 1200.0}
"""Default time limit of a validation lap (the default laps take ~330 s and ~665 s)."""
CSV_NAME: Final = "validations.csv"
BEST_NAME: Final = "best_validation_model.zip"


@dataclass(frozen=True)
class LapBatch:
    """The outcome of :func:`drive_laps`: each env's episode summary (env order) and how
    often each discrete action was chosen while its episode ran (empty for Box actions)."""

    summaries: list[dict[str, Any]]
    action_counts: np.ndarray


@dataclass(frozen=True)
class LapScore:
    """A validation result: ``value`` (mean mph, or mean lap time in s), its 95 % Student t
    interval, whether higher is better, the incident counts, and ``eligible`` (no incident
    of any kind; on the track also every lap finished)."""

    value: float
    low: float
    high: float
    higher_is_better: bool
    eligible: bool
    counts: dict[str, int]

    def beats(self, other: LapScore | None) -> bool:
        """Eligible and better than ``other`` (None: nothing yet)."""
        if not self.eligible:
            return False
        if other is None or not other.eligible:
            return True
        return (self.value > other.value if self.higher_is_better
                else self.value < other.value)


def lap_config(env_id: str, config: Mapping[str, Any],
               max_duration: float | None = None) -> dict[str, Any]:
    """``config`` with its lap section set to one lap of at most ``max_duration`` s."""
    section = lap_section(env_id)
    limit = MAX_DURATION_S[section] if max_duration is None else float(max_duration)
    lapped = dict(config)
    lapped[section] = {**dict(lapped.get(section) or {}), "laps": 1, "max_duration": limit}
    return lapped


def lap_section(env_id: str) -> str:
    """The config key holding ``laps`` for ``env_id``; ValueError naming the valid ids."""
    if env_id not in LAP_SECTIONS:
        raise ValueError(f"validation laps run on {sorted(LAP_SECTIONS)}, not {env_id!r}")
    return LAP_SECTIONS[env_id]


def make_lap_envs(env_id: str, config: Mapping[str, Any], episodes: int,
                  max_duration: float | None = None, full_info: bool = False) -> Any:
    """The native batch of ``episodes`` one-lap envs (reusable: :func:`drive_laps` resets
    it with the seed each time); ``full_info`` gives every step's ``info`` (the vector
    env's option), for an ``on_step`` observer of :func:`drive_laps`."""
    return gym.make_vec(env_id, num_envs=episodes,
                        config=lap_config(env_id, config, max_duration),
                        vectorization_mode="vector_entry_point", full_info=full_info)


StepObserver = Callable[[np.ndarray, dict[str, Any], np.ndarray, np.ndarray], None]
"""``on_step(observations, infos, live, ended)`` of :func:`drive_laps`, after each step:
the observations the actions were chosen on, the step's vector ``info``, the envs whose
lap the step advanced and those whose lap it ended (boolean masks)."""


def drive_laps(envs: Any, act: Callable[[np.ndarray], np.ndarray], seed: int,
               on_step: StepObserver | None = None) -> LapBatch:
    """Reset ``envs`` with ``seed`` (env ``i``: ``seed + i``) and step them with
    ``act(observations)`` until every env's episode has ended once; ``on_step`` sees
    every step (:data:`StepObserver`)."""
    from sdc_gym.envs.batch_vector import env_info

    episodes = envs.num_envs
    space = envs.single_action_space
    counts = np.zeros(int(space.n) if isinstance(space, gym.spaces.Discrete) else 0,
                      dtype=np.int64)
    summaries: list[dict[str, Any] | None] = [None] * episodes
    done = np.zeros(episodes, dtype=bool)
    observations, _ = envs.reset(seed=seed)
    while not done.all():
        actions = act(observations)
        live = ~done
        if counts.size:
            counts += np.bincount(np.asarray(actions)[live], minlength=counts.size)
        chosen_on = observations
        observations, _, terminated, truncated, infos = envs.step(actions)
        ended = (terminated | truncated) & live
        for env in np.flatnonzero(ended):
            summaries[env] = env_info(infos, env)["summary"]
        if on_step is not None:
            on_step(chosen_on, infos, live, ended)
        done |= ended
    return LapBatch([summary for summary in summaries if summary is not None], counts)


def score_laps(env_id: str, summaries: list[dict[str, Any]]) -> LapScore:
    """The ranking figure of one batch of laps (see the module docstring)."""
    collisions = sum(s["incidents"].get("collision", 0) for s in summaries)
    incidents = sum(s["incident_total"] for s in summaries)
    if lap_section(env_id) == "highway":
        speeds = [s["mean_speed_mph"] for s in summaries]
        laps = sum(s["laps"] >= 1 for s in summaries)
        return LapScore(*_interval(speeds), True, incidents == 0,
                        {"laps": laps, "collisions": collisions, "incidents": incidents})
    red = sum(s["red_light_violations"] for s in summaries)
    times = [s["lap_times"][0] for s in summaries if s["lap_times"]]
    unfinished = len(summaries) - len(times)
    return LapScore(*_interval(times), False, incidents == 0 and not unfinished,
                    {"unfinished": unfinished, "red_lights": red, "collisions": collisions,
                     "incidents": incidents,
                     "stops": sum(len(s["stops"]) for s in summaries)})


def _interval(values: list[float]) -> tuple[float, float, float]:
    """Mean and 95 % Student t interval; NaN where there are too few values."""
    interval = mean_interval(np.asarray(values, dtype=float))
    return tuple(float("nan") if x is None else float(x)  # type: ignore[return-value]
                 for x in (interval.value, interval.low, interval.high))


def validate_model(model: Any, envs: Any, env_id: str,
                   seed: int) -> tuple[LapScore, LapBatch]:
    """``model`` (an SB3 model or anything with its ``predict``) greedily on ``envs`` (a
    batch of ``env_id``, :func:`make_lap_envs`)."""
    batch = drive_laps(envs, lambda obs: model.predict(obs, deterministic=True)[0], seed)
    return score_laps(env_id, batch.summaries), batch


def read_best(folder: Path) -> LapScore | None:
    """The best eligible result in ``folder``'s ``validations.csv`` (None: none yet)."""
    path = folder / CSV_NAME
    if not path.is_file():
        return None
    best = None
    with path.open(encoding="utf-8", newline="") as handle:
        for row in csv.DictReader(handle):
            score = LapScore(float(row["value"]), float(row["low"]), float(row["high"]),
                             row["higher_is_better"] == "True", row["eligible"] == "True", {})
            best = score if score.beats(best) else best
    return best


def append_row(folder: Path, timesteps: int, score: LapScore,
               weights: str = "online") -> None:
    """Add one result to ``validations.csv``, rewriting it atomically; ``weights`` names
    the model scored: ``online`` (the trained weights) or ``averaged``
    (:mod:`sdc_training.weight_averaging`)."""
    from sdc_evaluation.files import atomic_write_text

    path = folder / CSV_NAME
    rows = []
    if path.is_file():
        with path.open(encoding="utf-8", newline="") as handle:
            rows = list(csv.DictReader(handle))
    rows.append({"timesteps": timesteps, "weights": weights, "value": score.value,
                 "low": score.low, "high": score.high,
                 "higher_is_better": score.higher_is_better, "eligible": score.eligible,
                 **score.counts})
    fields = list(dict.fromkeys(key for row in rows for key in row))  # old files lack some
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=fields, lineterminator="\n", restval="")
    writer.writeheader()
    for row in rows:
        writer.writerow({"weights": "online", **row} if not row.get("weights") else row)
    atomic_write_text(path, out.getvalue())


def read_rows(folder: Path, weights: str = "online") -> list[dict[str, str]]:
    """The rows of ``folder``'s ``validations.csv`` that scored ``weights`` (files from
    before the column hold only ``online`` rows)."""
    with (folder / CSV_NAME).open(encoding="utf-8", newline="") as handle:
        return [row for row in csv.DictReader(handle)
                if row.get("weights", "online") == weights]


def validation_callback(env_id: str, config: Mapping[str, Any], folder: Path, every: int,
                        episodes: int, seed: int, verbose: bool = True,
                        average: Any = None) -> Any:
    """An SB3 callback validating the model every ``every`` callback calls (batch steps).

    With ``average`` (a :class:`sdc_training.weight_averaging.WeightAverage` of the
    policy) its averaged weights are scored too, once they hold a sample, and either kind
    of weights can become ``best_validation_model.zip``."""
    from stable_baselines3.common.callbacks import BaseCallback

    from sdc_agents.checkpoints import save_model

    lap_section(env_id)  # a clear error before training starts

    class ValidationLapsCallback(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.envs: Any = None
            self.best = read_best(folder)

        def _on_step(self) -> bool:
            if self.n_calls % every:
                return True
            if self.envs is None:
                self.envs = make_lap_envs(env_id, config, episodes)
            self.score("online")
            if average is not None and average.count:
                with average.applied(self.model.policy):
                    self.score("averaged")
            return True

        def score(self, weights: str) -> None:
            score, _ = validate_model(self.model, self.envs, env_id, seed)
            prefix = "validation" if weights == "online" else f"validation_{weights}"
            self.logger.record(f"{prefix}/value", score.value)
            for name, count in score.counts.items():
                self.logger.record(f"{prefix}/{name}", count)
            append_row(folder, self.num_timesteps, score, weights)
            if score.beats(self.best):
                self.best = score
                save_model(self.model, folder / BEST_NAME)
            if verbose:
                unit = "mph" if score.higher_is_better else "s per lap"
                print(f"Validation num_timesteps={self.num_timesteps} ({weights} weights): "
                      f"{episodes} laps from seed {seed}, {score.value:.2f} {unit} "
                      f"[{score.low:.2f}, {score.high:.2f}], {score.counts}"
                      f"{' (best so far)' if self.best is score else ''}", flush=True)

        def _on_training_end(self) -> None:
            if self.envs is not None:
                self.envs.close()
                self.envs = None

    return ValidationLapsCallback()
