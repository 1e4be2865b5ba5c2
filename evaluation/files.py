"""The files of a run folder, each written atomically (a temporary file, then a rename).

``episodes.csv`` (one row per episode), ``agents.csv`` (one row per agent, with the
intervals), ``comparisons.csv`` (one row per agent pair), ``summary.json`` (all of it plus
each episode's incident log), ``traces.npz`` (per-step traces, :func:`load_traces` reads
them back) and ``incidents.json`` (the incident reports, a JSON array with one report per
line).
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_evaluation import challenge
from sdc_evaluation.episodes import REPORTS_KEY, TRACE_KEY, EpisodeTrace
from sdc_evaluation.summary import has_stop_lines, incident_kinds


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


def incident_reports(episodes: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every episode's incident reports, each led by its agent and seed, in run order."""
    return [{"agent": episode["agent"], "seed": episode["seed"], **report}
            for episode in episodes for report in episode.get(REPORTS_KEY, ())]


def write_incident_reports(path: Path, episodes: Iterable[dict[str, Any]]) -> int:
    """Every episode's incident reports as one JSON array (atomically), one report per
    line; returns how many. Written also without incidents (``[]``), so that a chain such
    as ``--scenario results/latest/incidents.json`` always finds its file."""
    reports = incident_reports(episodes)
    # One report per line: its history's long number lists stay compact.
    atomic_write_text(path, "[\n" + ",\n".join(map(json.dumps, reports)) + "\n]\n"
                      if reports else "[]\n")
    return len(reports)


EPISODES_FILE = "episodes.csv"
AGENTS_FILE = "agents.csv"
COMPARISONS_FILE = "comparisons.csv"
SUMMARY_FILE = "summary.json"
TRACES_FILE = "traces.npz"
INCIDENTS_FILE = "incidents.json"


def csv_text(rows: Iterable[dict[str, Any]], columns: list[str]) -> str:
    """``rows`` as CSV text with a header of ``columns`` (other keys of a row left out)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, extrasaction="ignore")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def _flat_intervals(row: dict[str, Any]) -> dict[str, Any]:
    """``key_ci: [low, high]`` as ``key_ci_low`` and ``key_ci_high`` (CSV columns)."""
    flat = {}
    for key, value in row.items():
        if key.endswith("_ci"):
            low, high = value if value is not None else (None, None)
            flat[f"{key}_low"], flat[f"{key}_high"] = low, high
        else:
            flat[key] = value
    return flat


def agent_rows_csv(rows: list[dict[str, Any]]) -> str:
    """The per-agent rows with their intervals as ``_ci_low`` / ``_ci_high`` columns, and
    incident counts and rates per kind."""
    kinds = list(dict.fromkeys(kind for row in rows for kind in row["incidents"]))
    flat_rows = []
    for row in rows:
        flat = _flat_intervals({key: value for key, value in row.items()
                                if key not in ("incidents", "incident_rates",
                                               "challenge_verdicts")})
        flat["seeds"] = " ".join(map(str, row["seeds"]))
        for kind in kinds:
            flat[f"incidents_{kind}"] = row["incidents"].get(kind, 0)
            rate = row["incident_rates"].get(kind) or {}
            flat.update(_flat_intervals({f"{kind}_per_100_miles": rate.get("per_100_miles"),
                                         f"{kind}_per_100_miles_ci": rate.get(
                                             "per_100_miles_ci")}))
        flat_rows.append(flat)
    columns = list(dict.fromkeys(key for flat in flat_rows for key in flat))
    return csv_text(flat_rows, columns)


def write_results(output: Path, episodes: list[dict[str, Any]], rows: list[dict[str, Any]],
                  comparisons: list[dict[str, Any]] | None = None,
                  run: dict[str, Any] | None = None) -> list[Path]:
    """``episodes.csv`` (one row per episode), ``agents.csv`` (one per agent, with the
    intervals), ``comparisons.csv`` (one per agent pair) and ``summary.json`` (``run``:
    the run's settings; ``agents``; ``comparisons``; ``episodes``); their paths.

    Traces are left out (see :func:`write_traces`); ``incident_log`` is in the JSON only.
    """
    kinds = incident_kinds(episodes)
    columns = ["agent", "env_id", "seed", "laps", "lap_times", "mean_lap_time", "distance",
               "time", "mean_speed_mph", "longest_distance_without_incident",
               *[f"incidents_{kind}" for kind in kinds], "max_acceleration",
               "max_jerk", "max_raw_acceleration", "max_raw_jerk", "is_success",
               "termination_reason", "env_steps", "wall_time"]
    if any(challenge.is_timed(episode) for episode in episodes):
        columns += ["challenge_time", "challenge_verdict"]
    if has_stop_lines(episodes):
        columns += ["red_light_violations", "stop_count", "max_overshoot",
                    "rms_cross_track_error", "max_cross_track_error", "max_lateral_acceleration"]
    flat_episodes = []
    for episode in episodes:
        flat = dict(episode)
        flat["lap_times"] = " ".join(f"{t:.3f}" for t in episode["lap_times"])
        for kind in kinds:
            flat[f"incidents_{kind}"] = episode["incidents"].get(kind, 0)
        if "stops" in episode:
            flat["stop_count"] = len(episode["stops"])
        if challenge.is_timed(episode):
            flat["challenge_time"] = episode["goal"]["time"] if challenge.finished(
                episode) else ""
            flat["challenge_verdict"] = challenge.verdict(episode)
        flat_episodes.append(flat)
    comparisons = comparisons or []
    written = [output / EPISODES_FILE, output / AGENTS_FILE]
    atomic_write_text(written[0], csv_text(flat_episodes, columns))
    atomic_write_text(written[1], agent_rows_csv(rows))
    if comparisons:
        written.append(output / COMPARISONS_FILE)
        flat = [_flat_intervals(comparison) for comparison in comparisons]
        atomic_write_text(written[-1], csv_text(flat, list(flat[0])))
    written.append(output / SUMMARY_FILE)
    atomic_write_text(written[-1], json.dumps(
        {"run": run or {}, "agents": rows, "comparisons": comparisons,
         "episodes": without_traces(episodes)}, indent=2))
    return written


def load_summary(folder: Path) -> dict[str, Any]:
    """A run folder's ``summary.json``; a ``SystemExit`` naming the folder when it has
    none or it cannot be read."""
    path = Path(folder) / SUMMARY_FILE
    if not path.is_file():
        raise SystemExit(f"{folder}: not a run folder (no {SUMMARY_FILE})")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise SystemExit(f"{path}: cannot be read: {error}") from None
    if not isinstance(data, dict) or not isinstance(data.get("episodes"), list):
        raise SystemExit(f"{path}: no 'episodes' list (written by another version?)")
    return data


def trace_key(agent: str, seed: int, name: str) -> str:
    """Array name in ``traces.npz``: ``agent/seed/field``."""
    return f"{agent}/{seed}/{name}"


def write_traces(path: Path, episodes: Iterable[dict[str, Any]]) -> int:
    """The episodes' traces as one compressed ``.npz`` (atomically); returns how many.

    Arrays are named ``agent/seed/field`` (see :func:`load_traces`); time and distance are
    float64, the rest float32.
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
