"""Run agents on an env over seeds and summarise lap time and violations.

Used by ``evaluate.py``. One episode = one (agent, seed) pair on a fresh env; episodes can
run in parallel worker processes. Results: one row per episode (the env's end-of-episode
``summary`` plus wall time), aggregated per agent, written atomically as CSV and JSON.
"""

from __future__ import annotations

import csv
import io
import json
import os
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401  (registers the env ids)
from agents.registry import make_agent
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.units import METERS_PER_MILE


@dataclass(frozen=True)
class EpisodeSpec:
    """What to run: agent name, env id and config overrides, seed."""

    agent: str
    env_id: str
    seed: int
    env_config: dict[str, Any] = field(default_factory=dict)


def run_episode(spec: EpisodeSpec) -> dict[str, Any]:
    """Drive one episode to its end; returns the env's summary plus identification."""
    env = gym.make(spec.env_id, config=spec.env_config)
    try:
        agent = make_agent(spec.agent, env)
        agent.reset()
        observation, info = env.reset(seed=spec.seed)
        started = time.perf_counter()
        steps = 0
        while True:
            observation, _, terminated, truncated, info = env.step(agent.act(observation))
            steps += 1
            if terminated or truncated:
                break
        wall = time.perf_counter() - started
    finally:
        env.close()
    summary = dict(info["summary"])
    summary.update(agent=spec.agent, env_id=spec.env_id, seed=spec.seed, env_steps=steps,
                   wall_time=wall)
    return summary


def run_episodes(specs: Sequence[EpisodeSpec], workers: int = 1,
                 progress: bool = True) -> list[dict[str, Any]]:
    """Run every spec (in ``workers`` processes when > 1); results in the specs' order."""
    from rich.progress import Progress

    results: list[dict[str, Any] | None] = [None] * len(specs)
    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task("episodes", total=len(specs))
        if workers <= 1:
            for index, spec in enumerate(specs):
                results[index] = run_episode(spec)
                bar.advance(task)
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                futures = {pool.submit(run_episode, spec): i for i, spec in enumerate(specs)}
                for future in as_completed(futures):
                    results[futures[future]] = future.result()
                    bar.advance(task)
    return [result for result in results if result is not None]


def aggregate(episodes: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per agent: laps, lap times, speed, distance without incident, incidents."""
    by_agent: dict[str, list[dict[str, Any]]] = {}
    for episode in episodes:
        by_agent.setdefault(episode["agent"], []).append(episode)
    rows = []
    for agent, runs in by_agent.items():
        lap_times = [t for run in runs for t in run["lap_times"]]
        rows.append({
            "agent": agent,
            "episodes": len(runs),
            "laps": sum(run["laps"] for run in runs),
            "mean_lap_time": float(np.mean(lap_times)) if lap_times else None,
            "best_lap_time": float(np.min(lap_times)) if lap_times else None,
            "mean_speed_mph": float(np.mean([run["mean_speed_mph"] for run in runs])),
            "longest_miles_without_incident": max(
                run["longest_distance_without_incident"] for run in runs) / METERS_PER_MILE,
            "incidents": {kind: sum(run["incidents"][kind] for run in runs)
                          for kind in INCIDENT_KINDS},
            "max_acceleration": max(run["max_acceleration"] for run in runs),
            "max_jerk": max(run["max_jerk"] for run in runs),
            "success_rate": float(np.mean([run["is_success"] for run in runs])),
            "wall_time": sum(run["wall_time"] for run in runs),
        })
    return rows


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and rename: never a half file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def write_results(output: Path, episodes: list[dict[str, Any]],
                  rows: list[dict[str, Any]]) -> None:
    """``episodes.csv`` (one row per episode) and ``summary.json`` (episodes + per agent)."""
    columns = ["agent", "env_id", "seed", "laps", "lap_times", "mean_lap_time", "distance",
               "time", "mean_speed_mph", "longest_distance_without_incident",
               *[f"incidents_{kind}" for kind in INCIDENT_KINDS], "max_acceleration",
               "max_jerk", "max_raw_acceleration", "max_raw_jerk", "is_success",
               "termination_reason", "env_steps", "wall_time"]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, extrasaction="ignore")
    writer.writeheader()
    for episode in episodes:
        flat = dict(episode)
        flat["lap_times"] = " ".join(f"{t:.3f}" for t in episode["lap_times"])
        for kind in INCIDENT_KINDS:
            flat[f"incidents_{kind}"] = episode["incidents"][kind]
        writer.writerow(flat)
    atomic_write_text(output / "episodes.csv", buffer.getvalue())
    atomic_write_text(output / "summary.json",
                      json.dumps({"agents": rows, "episodes": episodes}, indent=2))


def results_table(rows: list[dict[str, Any]], title: str) -> Any:
    """A rich Table of the per-agent rows (printed by evaluate.py)."""
    from rich.table import Table

    table = Table(title=title)
    for header in ("agent", "laps", "mean lap s", "best lap s", "mean mph",
                   "miles no incident", *INCIDENT_KINDS, "max acc", "max jerk"):
        table.add_column(header, justify="left" if header == "agent" else "right")

    def seconds(value: float | None) -> str:
        return "-" if value is None else f"{value:.1f}"

    for row in rows:
        table.add_row(
            row["agent"], str(row["laps"]), seconds(row["mean_lap_time"]),
            seconds(row["best_lap_time"]), f"{row['mean_speed_mph']:.2f}",
            f"{row['longest_miles_without_incident']:.2f}",
            *[str(row["incidents"][kind]) for kind in INCIDENT_KINDS],
            f"{row['max_acceleration']:.2f}", f"{row['max_jerk']:.2f}")
    return table
