"""Run agents on an env over seeds and summarise lap time and violations.

Used by ``evaluate.py``. One episode = one (agent, seed) pair on a fresh env; episodes can
run in parallel worker processes, with a rich progress bar counting laps (and a line per
running episode that moves during the episode, for long endurance runs). Results: one row
per episode (the env's end-of-episode ``summary`` plus wall time), aggregated per agent,
written atomically as CSV and JSON; each episode's per-step trace (time, distance, speed,
acceleration, jerk) stays out of those and goes to a compressed ``traces.npz``.
"""

from __future__ import annotations

import csv
import io
import json
import multiprocessing
import os
import time
from array import array
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from queue import Empty
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import sdc_gym  # noqa: F401  (registers the env ids)
from agents.incident_reports import DEFAULT_HISTORY_S, IncidentRecorder
from agents.registry import make_agent
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.units import METERS_PER_MILE


@dataclass(frozen=True)
class EpisodeSpec:
    """What to run: agent name (or ``kind:argument`` spec), env id and config overrides, seed.

    ``trace_points`` caps the per-step trace kept for plots (0: no trace); longer episodes
    keep every 2nd, 4th, ... step so that the trace stays within the cap.
    ``agent_options`` are options per agent kind (``{"external": {"cwd": ...}}``, see
    ``agents.registry.make_agent``). ``incident_history`` is the seconds of history in each
    incident report (0: no reports, see :mod:`agents.incident_reports`);
    ``stop_at_incident`` ends the episode at its first incident (termination reason
    ``stop_at_incident``).
    """

    agent: str
    env_id: str
    seed: int
    env_config: dict[str, Any] = field(default_factory=dict)
    trace_points: int = 250_000
    agent_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    incident_history: float = DEFAULT_HISTORY_S
    stop_at_incident: bool = False


class EpisodeAborted(Exception):
    """Raised by an agent's ``act`` to end the episode now, e.g. an external planner's
    fault: ``reason`` becomes the episode's ``termination_reason``, the message its
    ``abort_message``."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


TRACE_FIELDS: tuple[str, ...] = ("time", "distance", "speed", "acceleration", "jerk")
"""Per-step trace columns, read from the env's ``info``: s, m, m/s, m/s^2 (the latest
0.2 s block's total), m/s^3 (the latest 1 s window's signed jerk)."""


TRACE_KEY = "trace"
"""Key of the :class:`EpisodeTrace` in :func:`run_episode`'s result (never written to JSON)."""
REPORTS_KEY = "incident_reports"
"""Key of the incident reports in :func:`run_episode`'s result (they go to their own file,
see :func:`write_incident_reports`)."""


@dataclass(frozen=True)
class EpisodeTrace:
    """One episode's per-step trace (the reset state first), one array per field."""

    time: NDArray[np.float64]
    distance: NDArray[np.float64]
    speed: NDArray[np.float64]
    acceleration: NDArray[np.float64]
    jerk: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.distance)

    def columns(self) -> dict[str, NDArray[np.float64]]:
        return {name: getattr(self, name) for name in TRACE_FIELDS}


class TraceRecorder:
    """Appends the trace fields of every step's ``info`` as Python floats (cheap).

    Keeps at most ``max_points`` samples: when full it drops every other sample and
    records only every 2nd (then 4th, ...) step from then on, so the kept samples stay
    evenly spaced. :meth:`finish` always keeps the final step.
    """

    def __init__(self, max_points: int) -> None:
        if max_points < 2:
            raise ValueError(f"max_points must be >= 2, got {max_points}")
        self.max_points = max_points
        self._columns = [array("d") for _ in TRACE_FIELDS]
        self._stride = 1
        self._seen = 0
        self._last: tuple[float, ...] | None = None

    def add(self, info: dict[str, Any]) -> None:
        values = (info["time"], info["distance"], info["speed"], info["acceleration"],
                  info["jerk"])
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
        return EpisodeTrace(*columns)


ProgressCallback = Callable[[float, dict[str, Any]], None]
"""``callback(laps_done, info)``: laps as a float (fraction of the loop), the step's info."""

PROGRESS_EVERY_STEPS = 100
"""Env steps between progress reports of a running episode (6 simulated s by default)."""


def run_episode(spec: EpisodeSpec, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Drive one episode to its end; returns the env's summary plus identification.

    With ``spec.trace_points`` > 0 the result has a ``"trace"`` (:class:`EpisodeTrace`),
    which :func:`write_results` leaves out of the JSON and CSV (see :func:`write_traces`);
    likewise ``"incident_reports"`` (:func:`write_incident_reports`).
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
        incidents = (IncidentRecorder(spec.incident_history) if spec.incident_history > 0
                     else None)
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
    summary.update(agent=spec.agent, env_id=spec.env_id, seed=spec.seed, env_steps=steps,
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


_WORKER_QUEUE: Any = None  # a worker process's progress queue, set by _init_worker


WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
"""Thread counts pinned to 1 in worker processes (unless set): the workers already fill the
cores, and a torch model (the light classifiers) using every core in every worker ran
~10 x slower than single-threaded."""


def _init_worker(queue: Any) -> None:
    global _WORKER_QUEUE  # per-process state of the pool's workers
    _WORKER_QUEUE = queue
    for variable in WORKER_THREAD_VARIABLES:  # read by torch when a worker imports it
        os.environ.setdefault(variable, "1")


def _run_in_worker(index: int, spec: EpisodeSpec) -> dict[str, Any]:
    queue = _WORKER_QUEUE

    def report(laps: float, info: dict[str, Any]) -> None:
        queue.put((index, laps, _progress_fields(info)))

    return run_episode(spec, report if queue is not None else None)


def _progress_fields(info: dict[str, Any]) -> dict[str, float]:
    return {"distance": float(info["distance"]),
            "clean": float(info["distance_without_incident"]),
            "incidents": float(info["incidents"])}


class _ProgressDisplay:
    """A rich progress bar: laps of all episodes, plus one line per running episode."""

    def __init__(self, specs: Sequence[EpisodeSpec], enabled: bool) -> None:
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.specs = specs
        self.laps = [float(spec.env_config.get("laps", 1)) for spec in specs]
        self.done = [0.0] * len(specs)
        self.finished = 0
        self.bar = Progress(
            TextColumn("{task.description}"), BarColumn(bar_width=20),
            TextColumn("{task.completed:.1f}/{task.total:g} laps"), TimeElapsedColumn(),
            TimeRemainingColumn(), TextColumn("{task.fields[status]}"),
            disable=not enabled, transient=True)
        self.total = self.bar.add_task(self._overall(), total=sum(self.laps), status="")
        self.tasks: dict[int, Any] = {}

    def _overall(self) -> str:
        return f"episodes {self.finished}/{len(self.specs)}"

    def __enter__(self) -> _ProgressDisplay:
        self.bar.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.__exit__(*exc)

    def start(self, index: int) -> None:
        if index not in self.tasks:
            spec = self.specs[index]
            self.tasks[index] = self.bar.add_task(
                f"  {spec.agent} seed {spec.seed}", total=self.laps[index], status="")

    def update(self, index: int, laps: float, fields: dict[str, float]) -> None:
        self.start(index)
        laps = min(laps, self.laps[index])
        status = (f"{fields['distance'] / METERS_PER_MILE:.1f} mi, "
                  f"{fields['clean'] / METERS_PER_MILE:.1f} without incident, "
                  f"{fields['incidents']:.0f} incidents")
        self.bar.update(self.tasks[index], completed=laps, status=status)
        self._set(index, laps)

    def finish(self, index: int) -> None:
        if index in self.tasks:
            self.bar.remove_task(self.tasks.pop(index))
        self.finished += 1
        self._set(index, self.laps[index])

    def _set(self, index: int, laps: float) -> None:
        self.done[index] = laps
        self.bar.update(self.total, completed=sum(self.done), description=self._overall())


def run_episodes(specs: Sequence[EpisodeSpec], workers: int = 1,
                 progress: bool = True) -> list[dict[str, Any]]:
    """Run every spec (in ``workers`` processes when > 1); results in the specs' order.

    ``progress`` shows a rich bar counting laps, with a line per running episode that
    advances during the episode (useful for a single long endurance episode).
    """
    results: list[dict[str, Any] | None] = [None] * len(specs)
    with _ProgressDisplay(specs, progress) as display:
        if workers <= 1 or len(specs) <= 1:
            for index, spec in enumerate(specs):
                display.start(index)

                def report(laps: float, info: dict[str, Any], index: int = index) -> None:
                    display.update(index, laps, _progress_fields(info))

                results[index] = run_episode(spec, report if progress else None)
                display.finish(index)
        else:
            _run_parallel(specs, workers, display if progress else None, results)
    return [result for result in results if result is not None]


def _run_parallel(specs: Sequence[EpisodeSpec], workers: int, display: _ProgressDisplay | None,
                  results: list[dict[str, Any] | None]) -> None:
    context = multiprocessing.get_context()
    queue = context.Queue() if display is not None else None

    def drain() -> None:
        while queue is not None and display is not None:
            try:
                index, laps, fields = queue.get_nowait()
            except Empty:
                return
            if results[index] is None:
                display.update(index, laps, fields)

    with ProcessPoolExecutor(max_workers=min(workers, len(specs)), mp_context=context,
                             initializer=_init_worker, initargs=(queue,)) as pool:
        futures = {pool.submit(_run_in_worker, i, spec): i for i, spec in enumerate(specs)}
        pending = set(futures)
        try:
            while pending:
                done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                drain()
                for future in done:
                    index = futures[future]
                    results[index] = future.result()
                    if display is not None:
                        display.finish(index)
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    if queue is not None:
        queue.close()


def incident_kinds(episodes: Iterable[dict[str, Any]]) -> tuple[str, ...]:
    """The shared incident kinds, then any env-specific ones the episodes report (the track
    loop's ``red_light``), in the order first seen."""
    kinds = dict.fromkeys(INCIDENT_KINDS)
    for episode in episodes:
        kinds.update(dict.fromkeys(episode["incidents"]))
    return tuple(kinds)


def _has_stop_lines(runs: Sequence[dict[str, Any]]) -> bool:
    return any("stops" in run for run in runs)


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


def aggregate(episodes: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per agent: laps, lap times, speed, distance without incident, incidents;
    on a track with stop lines also red lights, stops and tracking (:func:`_track_columns`,
    the worst episode's value for the RMS cross-track error)."""
    episodes = list(episodes)
    kinds = incident_kinds(episodes)
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
            "incidents": {kind: sum(run["incidents"].get(kind, 0) for run in runs)
                          for kind in kinds},
            "max_acceleration": max(run["max_acceleration"] for run in runs),
            "max_jerk": max(run["max_jerk"] for run in runs),
            "success_rate": float(np.mean([run["is_success"] for run in runs])),
            "wall_time": sum(run["wall_time"] for run in runs),
        })
        if _has_stop_lines(runs):
            rows[-1].update(_track_columns(runs))
    return rows


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file and rename: never a half file."""
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same folder and rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def without_traces(episodes: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """The episodes without their :class:`EpisodeTrace` and incident reports (what goes
    into JSON and CSV)."""
    return [{key: value for key, value in episode.items() if key not in (TRACE_KEY, REPORTS_KEY)}
            for episode in episodes]


def write_incident_reports(path: Path, episodes: Iterable[dict[str, Any]]) -> int:
    """Every episode's incident reports as one JSON list (atomically), each report led by
    its agent and seed; returns how many (no file when there are none)."""
    reports = [{"agent": episode["agent"], "seed": episode["seed"], **report}
               for episode in episodes for report in episode.get(REPORTS_KEY, ())]
    if reports:
        # One report per line: its history's long number lists stay compact.
        atomic_write_text(path, "[\n" + ",\n".join(map(json.dumps, reports)) + "\n]\n")
    return len(reports)


def write_results(output: Path, episodes: list[dict[str, Any]],
                  rows: list[dict[str, Any]]) -> None:
    """``episodes.csv`` (one row per episode) and ``summary.json`` (episodes + per agent).

    Traces are left out (see :func:`write_traces`); ``incident_log`` is in the JSON only.
    """
    kinds = incident_kinds(episodes)
    columns = ["agent", "env_id", "seed", "laps", "lap_times", "mean_lap_time", "distance",
               "time", "mean_speed_mph", "longest_distance_without_incident",
               *[f"incidents_{kind}" for kind in kinds], "max_acceleration",
               "max_jerk", "max_raw_acceleration", "max_raw_jerk", "is_success",
               "termination_reason", "env_steps", "wall_time"]
    if _has_stop_lines(episodes):
        columns += ["red_light_violations", "stop_count", "max_overshoot",
                    "rms_cross_track_error", "max_cross_track_error", "max_lateral_acceleration"]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, extrasaction="ignore")
    writer.writeheader()
    for episode in episodes:
        flat = dict(episode)
        flat["lap_times"] = " ".join(f"{t:.3f}" for t in episode["lap_times"])
        for kind in kinds:
            flat[f"incidents_{kind}"] = episode["incidents"].get(kind, 0)
        if "stops" in episode:
            flat["stop_count"] = len(episode["stops"])
        writer.writerow(flat)
    atomic_write_text(output / "episodes.csv", buffer.getvalue())
    atomic_write_text(output / "summary.json",
                      json.dumps({"agents": rows, "episodes": without_traces(episodes)},
                                 indent=2))


def trace_key(agent: str, seed: int, name: str) -> str:
    """Array name in ``traces.npz``: ``agent/seed/field``."""
    return f"{agent}/{seed}/{name}"


def write_traces(path: Path, episodes: Iterable[dict[str, Any]]) -> int:
    """The episodes' traces as one compressed ``.npz`` (atomically); returns how many.

    Arrays are named ``agent/seed/field`` (see :func:`load_traces`); time and distance are
    float64, speed, acceleration and jerk float32.
    """
    arrays: dict[str, NDArray[Any]] = {}
    count = 0
    for episode in episodes:
        trace = episode.get(TRACE_KEY)
        if trace is None:
            continue
        count += 1
        for name, column in trace.columns().items():
            dtype = np.float64 if name in ("time", "distance") else np.float32
            arrays[trace_key(episode["agent"], episode["seed"], name)] = column.astype(dtype)
    if count:
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)
        atomic_write_bytes(path, buffer.getvalue())
    return count


def load_traces(path: Path) -> dict[tuple[str, int], EpisodeTrace]:
    """Read :func:`write_traces`' file back: ``{(agent, seed): EpisodeTrace}``."""
    columns: dict[tuple[str, int], dict[str, NDArray[np.float64]]] = {}
    with np.load(path) as data:
        for key in data.files:
            agent, seed, name = key.rsplit("/", 2)
            columns.setdefault((agent, int(seed)), {})[name] = data[key].astype(np.float64)
    return {key: EpisodeTrace(**value) for key, value in columns.items()}


def results_table(rows: list[dict[str, Any]], title: str) -> Any:
    """A rich Table of the per-agent rows (printed by evaluate.py)."""
    from rich.table import Table

    table = Table(title=title)
    kinds = list(dict.fromkeys(kind for row in rows for kind in row["incidents"]))
    track = any("stops" in row for row in rows)
    extra = ("stops", "short of line m", "overshoot m", "CTE rms m", "max lat acc") if track \
        else ()
    for header in ("agent", "laps", "mean lap s", "best lap s", "mean mph",
                   "miles no incident", *kinds, "max acc", "max jerk", *extra):
        table.add_column(header, justify="left" if header == "agent" else "right")

    def number(value: float | None, digits: int) -> str:
        return "-" if value is None else f"{value:.{digits}f}"

    for row in rows:
        cells = [
            row["agent"], str(row["laps"]), number(row["mean_lap_time"], 1),
            number(row["best_lap_time"], 1), f"{row['mean_speed_mph']:.2f}",
            f"{row['longest_miles_without_incident']:.2f}",
            *[str(row["incidents"].get(kind, 0)) for kind in kinds],
            f"{row['max_acceleration']:.2f}", f"{row['max_jerk']:.2f}"]
        if track:
            cells += [str(row.get("stops", "-")), number(row.get("stop_short_max_m"), 2),
                      number(row.get("max_overshoot"), 2),
                      number(row.get("rms_cross_track_error"), 3),
                      number(row.get("max_lateral_acceleration"), 2)]
        table.add_row(*cells)
    return table


SEED_RECORD_MILES = 276.53
"""Distance without incident of the seed's rule-based planner, miles (to beat)."""


def endurance_table(episodes: list[dict[str, Any]], title: str) -> Any:
    """A rich Table of endurance episodes: distance without incident (miles), wall time."""
    from rich.table import Table

    table = Table(title=title, caption=f"seed planner's record: {SEED_RECORD_MILES:.2f} "
                                       "miles without incident")
    for header in ("agent", "seed", "laps", "miles", "longest miles no incident",
                   "miles no incident at end", "incidents", "vs record", "sim time",
                   "wall time", "end"):
        table.add_column(header, justify="left" if header in ("agent", "end") else "right")
    for episode in episodes:
        longest = episode["longest_distance_without_incident"] / METERS_PER_MILE
        table.add_row(
            episode["agent"], str(episode["seed"]), str(episode["laps"]),
            f"{episode['distance'] / METERS_PER_MILE:.2f}", f"{longest:.2f}",
            f"{episode['distance_without_incident'] / METERS_PER_MILE:.2f}",
            str(episode["incident_total"]), f"{100.0 * longest / SEED_RECORD_MILES:.1f} %",
            _duration(episode["time"]), _duration(episode["wall_time"]),
            episode["termination_reason"])
    return table


def _duration(seconds: float) -> str:
    if seconds < 60.0:
        return f"{seconds:.1f} s"
    minutes, rest = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{rest:02d}" if hours else f"{minutes}:{rest:02d}"
