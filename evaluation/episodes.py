"""One episode of one agent on a fresh env: what to run and what comes back.

An episode is one (agent, seed) pair. :func:`run_episode` builds the env and the agent (by
name, through :mod:`sdc_agents.registry`), drives it to the end and returns the env's
end-of-episode ``summary`` plus identification and wall time, with the per-step trace
(:class:`EpisodeTrace`, for the plots) and the incident reports kept aside under their own
keys (they go to their own files, not into the JSON rows). The runner
(:mod:`sdc_evaluation.runner`) runs many of these, in this process or in workers.
"""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import sdc_gym  # noqa: F401  (registers the env ids)
from sdc_agents.registry import EpisodeAborted, make_agent
from sdc_evaluation.incident_reports import DEFAULT_HISTORY_S, IncidentRecorder


@dataclass(frozen=True)
class EpisodeSpec:
    """What to run: agent name (or ``kind:argument`` spec), env id and config overrides, seed.

    ``trace_points`` caps the per-step trace kept for plots (0: no trace); longer episodes
    keep every 2nd, 4th, ... step so that the trace stays within the cap.
    ``agent_options`` are options per agent kind (``{"external": {"cwd": ...}}``, see
    ``sdc_agents.registry.make_agent``). ``incident_history`` is the seconds of history in each
    incident report (0: no reports, see :mod:`sdc_evaluation.incident_reports`);
    ``stop_at_incident`` ends the episode at its first incident (termination reason
    ``stop_at_incident``). ``name`` is the agent's name in the results (default: the spec
    ``agent``): one external planner run from two folders is two agents with one spec.
    """

    agent: str
    env_id: str
    seed: int
    env_config: dict[str, Any] = field(default_factory=dict)
    trace_points: int = 250_000
    agent_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    incident_history: float = DEFAULT_HISTORY_S
    stop_at_incident: bool = False
    name: str | None = None

    @property
    def agent_name(self) -> str:
        """The agent's name in the results and tables."""
        return self.name or self.agent


TRACE_FIELDS: tuple[str, ...] = ("time", "distance", "speed", "acceleration", "jerk")
"""Per-step trace columns, read from the env's ``info``: s, m, m/s, m/s^2 (the latest
0.2 s block's total), m/s^3 (the latest 1 s window's signed jerk)."""
LIGHT_FIELD = "light_state_near"
"""Also traced where the env's ``info`` has the light ahead (the track loop): the state
code of the next stop line's light (RED 0, YELLOW 1, GREEN 2) while that line is within
:data:`LIGHT_NEAR_M` ahead, else UNKNOWN (4): the light the car is driving up to, for the
profiles' light strips."""
LIGHT_NEAR_M = 100.0
_UNKNOWN_LIGHT = 4.0  # sdc_gym.lights.UNKNOWN

TRACE_KEY = "trace"
"""Key of the :class:`EpisodeTrace` in :func:`run_episode`'s result (never written to JSON)."""
REPORTS_KEY = "incident_reports"
"""Key of the incident reports in :func:`run_episode`'s result (they go to their own file,
``incidents.json``)."""


@dataclass(frozen=True)
class EpisodeTrace:
    """One episode's per-step trace (the reset state first), one array per field."""

    time: NDArray[np.float64]
    distance: NDArray[np.float64]
    speed: NDArray[np.float64]
    acceleration: NDArray[np.float64]
    jerk: NDArray[np.float64]
    light_state_near: NDArray[np.float64] | None = None  # track loop only

    def __len__(self) -> int:
        return len(self.distance)

    def columns(self) -> dict[str, NDArray[np.float64]]:
        """The trace's arrays by name (``light_state_near`` only when traced)."""
        columns = {name: getattr(self, name) for name in TRACE_FIELDS}
        if self.light_state_near is not None:
            columns[LIGHT_FIELD] = self.light_state_near
        return columns


class TraceRecorder:
    """Appends the trace fields of every step's ``info`` as Python floats (cheap).

    Keeps at most ``max_points`` samples: when full it drops every other sample and
    records only every 2nd (then 4th, ...) step from then on, so the kept samples stay
    evenly spaced. :meth:`finish` always keeps the final step. The light ahead
    (:data:`LIGHT_FIELD`) is traced when the first ``info`` has it.
    """

    def __init__(self, max_points: int) -> None:
        if max_points < 2:
            raise ValueError(f"max_points must be >= 2, got {max_points}")
        self.max_points = max_points
        self._fields: tuple[str, ...] | None = None
        self._columns: list[array[float]] = []
        self._stride = 1
        self._seen = 0
        self._last: tuple[float, ...] | None = None

    def add(self, info: dict[str, Any]) -> None:
        if self._fields is None:
            lights = "light_state_ahead" in info and "stop_line_distance" in info
            self._fields = TRACE_FIELDS + ((LIGHT_FIELD,) if lights else ())
            self._columns = [array("d") for _ in self._fields]
        values = (info["time"], info["distance"], info["speed"], info["acceleration"],
                  info["jerk"])
        if len(self._fields) > len(TRACE_FIELDS):
            near = info["stop_line_distance"] < LIGHT_NEAR_M
            values += (float(info["light_state_ahead"]) if near else _UNKNOWN_LIGHT,)
        if self._seen % self._stride == 0:
            for column, value in zip(self._columns, values, strict=True):
                column.append(value)
            self._last = None
            if len(self._columns[0]) >= self.max_points:
                self._columns = [column[::2] for column in self._columns]
                self._stride *= 2
        else:
            self._last = values
        self._seen += 1

    def finish(self) -> EpisodeTrace:
        columns = [np.array(column, dtype=np.float64) for column in self._columns]
        if self._last is not None:  # the final step was skipped by the stride: keep it
            columns = [np.append(column, value)
                       for column, value in zip(columns, self._last, strict=True)]
        if self._fields is None:  # nothing recorded
            return EpisodeTrace(*(np.zeros(0) for _ in TRACE_FIELDS))
        return EpisodeTrace(**dict(zip(self._fields, columns, strict=True)))


ProgressCallback = Callable[[float, dict[str, Any]], None]
"""``callback(laps_done, info)``: laps as a float (fraction of the loop), the step's info."""

PROGRESS_EVERY_STEPS = 100
"""Env steps between progress reports of a running episode (6 simulated s by default)."""


def run_episode(spec: EpisodeSpec, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Drive one episode to its end; returns the env's summary plus identification.

    With ``spec.trace_points`` > 0 the result has a ``"trace"`` (:class:`EpisodeTrace`),
    which the result files leave out of the JSON and CSV (see
    :func:`sdc_evaluation.files.write_traces`); likewise ``"incident_reports"``
    (:func:`sdc_evaluation.files.write_incident_reports`).
    ``progress`` is called every :data:`PROGRESS_EVERY_STEPS` env steps.

    Agents with ``wants_info = True`` are called as ``act(observation, info)`` (an
    external planner needs ``info["telemetry"]``); an agent with ``close()`` is closed at
    the end; one with ``episode_extras()`` adds its figures to the result. An agent may
    end the episode early by raising :class:`EpisodeAborted`, and ``spec.stop_at_incident``
    ends it at the first incident; the summary is then the env's at that moment.
    """
    env = gym.make(spec.env_id, config=spec.env_config)
    agent = None
    try:
        agent = make_agent(spec.agent, env, spec.agent_options)
        agent.reset()
        with_info = bool(getattr(agent, "wants_info", False))
        road = getattr(env.unwrapped, "road", None)
        loop_length = float(road.length) if road is not None else 0.0
        recorder = TraceRecorder(spec.trace_points) if spec.trace_points > 0 else None
        incidents = (IncidentRecorder(spec.incident_history,
                                      snapshot=getattr(env.unwrapped, "scenario_snapshot",
                                                       None))
                     if spec.incident_history > 0 else None)
        observation, info = env.reset(seed=spec.seed)
        if recorder is not None:
            recorder.add(info)
        if incidents is not None:
            incidents.add(observation, info)
        started = time.perf_counter()
        steps = 0
        stopped: EpisodeAborted | None = None
        while True:
            try:
                action = agent.act(observation, info) if with_info else agent.act(observation)
            except EpisodeAborted as abort:
                stopped = abort
                break
            observation, _, terminated, truncated, info = env.step(action)
            steps += 1
            if recorder is not None:
                recorder.add(info)
            if incidents is not None:
                incidents.add(observation, info)
            if terminated or truncated:
                break
            if spec.stop_at_incident and info["new_incidents"]:
                stopped = EpisodeAborted("stop_at_incident", "stopped at the first incident: "
                                         + ", ".join(info["new_incidents"]))
                break
            if progress is not None and steps % PROGRESS_EVERY_STEPS == 0:
                progress(_laps_done(info, loop_length), info)
        wall = time.perf_counter() - started
        summary = dict(info["summary"]) if stopped is None else _summary_now(env, stopped)
        extras = getattr(agent, "episode_extras", None)
        if extras is not None:
            summary.update(extras())
    finally:
        close = getattr(agent, "close", None)
        if close is not None:
            close()
        env.close()
    summary.update(agent=spec.agent_name, env_id=spec.env_id, seed=spec.seed, env_steps=steps,
                   wall_time=wall)
    if recorder is not None:
        summary[TRACE_KEY] = recorder.finish()
    if incidents is not None:
        summary[REPORTS_KEY] = incidents.reports(summary.get("incident_log", []))
    return summary


def _summary_now(env: gym.Env, stopped: EpisodeAborted) -> dict[str, Any]:
    """The env's end-of-episode summary for an episode ended early by ``stopped``.

    The envs put it in ``info`` only on their final step; their ``summary()`` gives it at
    any time, and the reason is set here.
    """
    summary = dict(env.unwrapped.summary())
    summary.update(termination_reason=stopped.reason, abort_message=str(stopped))
    return summary


def _laps_done(info: dict[str, Any], loop_length: float) -> float:
    if loop_length > 0.0:
        return max(float(info["progress"]) / loop_length, 0.0)
    return float(info.get("laps", 0))


