"""Per-agent rows of an evaluation: counts, extremes and interval estimates.

:func:`aggregate` turns the episodes' results (one dict per episode, as
:func:`sdc_evaluation.episodes.run_episode` returns them or ``summary.json`` holds them) into
one row per agent. Every mean comes with its 95 % interval (see
:mod:`sdc_evaluation.statistics`), the episode being the unit:

* ``mean_speed_mph`` (with ``_ci``): the mean of the episodes' mean speeds (distance over
  time), and ``iqm_speed_mph`` (with ``_ci``) their interquartile mean;
* ``mean_lap_time`` (with ``_ci``), ``iqm_lap_time``: the same over the episodes' mean lap
  times (episodes without a lap left out); with one lap per episode, or the same number in
  each, this is the mean over all laps; ``best_lap_time`` is the best lap of all;
* ``incidents_per_100_miles`` (with ``_ci``): all incidents over all miles driven, with
  Garwood's exact Poisson interval, and per kind in ``incident_rates``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sdc_agents.registry import agent_label
from sdc_evaluation import challenge, statistics
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.units import METERS_PER_MILE


def incident_kinds(episodes: Iterable[dict[str, Any]]) -> tuple[str, ...]:
    """The shared incident kinds, then any env-specific ones the episodes report (the track
    loop's ``red_light``), in the order first seen."""
    kinds = dict.fromkeys(INCIDENT_KINDS)
    for episode in episodes:
        kinds.update(dict.fromkeys(episode["incidents"]))
    return tuple(kinds)


def has_stop_lines(runs: Sequence[dict[str, Any]]) -> bool:
    return any("stops" in run for run in runs)


@dataclass(frozen=True)
class AgentSamples:
    """One agent's episodes as samples: one value per episode, in the episodes' order."""

    agent: str
    label: str
    seeds: tuple[int, ...]
    speed_mph: np.ndarray
    lap_time: np.ndarray  # the episodes' mean lap times (episodes with a lap)
    miles: float
    incidents: dict[str, int]

    @property
    def incident_total(self) -> int:
        return sum(self.incidents.values())


def group_by_agent(episodes: Iterable[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Episodes by agent, agents in the order first seen."""
    by_agent: dict[str, list[dict[str, Any]]] = {}
    for episode in episodes:
        by_agent.setdefault(episode["agent"], []).append(episode)
    return by_agent


def unique_labels(agents: Sequence[str]) -> dict[str, str]:
    """Short labels (:func:`sdc_agents.registry.agent_label`) unless two would be equal: those
    keep their full spec."""
    labels = {agent: agent_label(agent) for agent in agents}
    counts: dict[str, int] = {}
    for label in labels.values():
        counts[label] = counts.get(label, 0) + 1
    return {agent: label if counts[label] == 1 else agent for agent, label in labels.items()}


def agent_samples(episodes: Iterable[dict[str, Any]],
                  labels: dict[str, str] | None = None) -> list[AgentSamples]:
    """Each agent's per-episode samples (``labels``: display names, default
    :func:`unique_labels`)."""
    episodes = list(episodes)
    kinds = incident_kinds(episodes)
    by_agent = group_by_agent(episodes)
    labels = labels or unique_labels(list(by_agent))
    result = []
    for agent, runs in by_agent.items():
        result.append(AgentSamples(
            agent=agent, label=labels.get(agent, agent),
            seeds=tuple(int(run["seed"]) for run in runs),
            speed_mph=np.array([run["mean_speed_mph"] for run in runs], dtype=np.float64),
            lap_time=np.array([float(np.mean(run["lap_times"])) for run in runs
                               if run["lap_times"]], dtype=np.float64),
            miles=sum(run["distance"] for run in runs) / METERS_PER_MILE,
            incidents={kind: sum(run["incidents"].get(kind, 0) for run in runs)
                       for kind in kinds}))
    return result


def _track_columns(runs: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Stop-line and tracking figures of track episodes (see TrackLoop-v0's summary).

    ``stop_short_max_m`` is the largest distance a stop ended *before* its line (the
    stack should stop within 2 m), ``max_overshoot`` the largest past it.
    """
    stops = [stop for run in runs for stop in run.get("stops", [])]
    return {
        "red_light_violations": sum(run.get("red_light_violations", 0) for run in runs),
        "stops": len(stops),
        "stop_short_max_m": max((-stop["offset_m"] for stop in stops), default=None),
        "max_overshoot": max((run.get("max_overshoot", 0.0) for run in runs), default=0.0),
        "rms_cross_track_error": max(run.get("rms_cross_track_error", 0.0) for run in runs),
        "max_cross_track_error": max(run.get("max_cross_track_error", 0.0) for run in runs),
        "max_lateral_acceleration": max(run.get("max_lateral_acceleration", 0.0)
                                        for run in runs),
    }


def _estimate(prefix: str, interval: statistics.Interval) -> dict[str, Any]:
    return {prefix: interval.value, f"{prefix}_ci": interval.ci()}


def aggregate(episodes: Iterable[dict[str, Any]],
              settings: statistics.Settings = statistics.DEFAULT_SETTINGS,
              labels: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """One row per agent (see the module docstring); on a track with stop lines also red
    lights, stops and tracking (:func:`_track_columns`, the worst episode's value for the
    RMS cross-track error)."""
    episodes = list(episodes)
    by_agent = group_by_agent(episodes)
    rows = []
    for samples in agent_samples(episodes, labels):
        runs = by_agent[samples.agent]
        lap_times = [t for run in runs for t in run["lap_times"]]
        row: dict[str, Any] = {
            "agent": samples.agent,
            "label": samples.label,
            "episodes": len(runs),
            "seeds": list(samples.seeds),
            "laps": sum(run["laps"] for run in runs),
            **_estimate("mean_lap_time", statistics.mean_interval(
                samples.lap_time, "lap_time", settings)),
            **_estimate("iqm_lap_time", statistics.iqm_interval(
                samples.lap_time, "lap_time", settings)),
            "best_lap_time": float(np.min(lap_times)) if lap_times else None,
            **_estimate("mean_speed_mph", statistics.mean_interval(
                samples.speed_mph, "speed_mph", settings)),
            **_estimate("iqm_speed_mph", statistics.iqm_interval(
                samples.speed_mph, "speed_mph", settings)),
            "miles": samples.miles,
            "longest_miles_without_incident": max(
                run["longest_distance_without_incident"] for run in runs) / METERS_PER_MILE,
            "incidents": dict(samples.incidents),
            "incident_total": samples.incident_total,
            **_estimate("incidents_per_100_miles", statistics.poisson_rate(
                samples.incident_total, samples.miles, confidence=settings.confidence)),
            "incident_rates": {
                kind: _estimate("per_100_miles", statistics.poisson_rate(
                    count, samples.miles, confidence=settings.confidence))
                for kind, count in samples.incidents.items()},
            "max_acceleration": max(run["max_acceleration"] for run in runs),
            "max_jerk": max(run["max_jerk"] for run in runs),
            "success_rate": float(np.mean([run["is_success"] for run in runs])),
            "wall_time": sum(run["wall_time"] for run in runs),
        }
        if has_stop_lines(runs):
            row.update(_track_columns(runs))
        if any(challenge.is_timed(run) for run in runs):  # open roads' timed runs
            row.update(challenge.columns([run for run in runs if challenge.is_timed(run)],
                                         settings))
        rows.append(row)
    return rows
