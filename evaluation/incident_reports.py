"""Incident reports: each incident's kind, time and place, with the seconds that led to it.

The env's summary logs every incident (kind, time, physics step, x, y, s, d, value). A
report adds the history a reader needs to see *why*: the last ``history_s`` seconds of
the ego car (x, y, s, d, yaw, speed) and of every traffic car that came within
``radius_m`` of it meanwhile (x, y, vx, vy, s, d, from the sensor fusion rows), one sample
per env step, the incident's step last. :class:`IncidentRecorder` keeps references to the
last observations (no copies, a few microseconds per step) and builds the reports only
when incidents happen; ``evaluate.py`` writes them to ``incidents.json``.

Replays: given the env's ``scenario_snapshot`` (the highway envs have one), the recorder
also snapshots the env's whole state every :data:`SNAPSHOT_EVERY_S` s and attaches to each
report, under ``replay``, the newest one from at least ``history_s`` before the incident:
:func:`sdc_gym.scenarios.replay.incident_scenario` makes a scenario of it that starts
there, with the same traffic state (``docs/scenarios.md``).

It works on any env whose ``info`` has ``time`` and ``new_incidents`` (every sdc-gym
env): the ego comes from the observation's ``ego`` row (highway loop) or from ``info``'s
pose (track loop, which has no traffic to report).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any, Final

import numpy as np

DEFAULT_HISTORY_S: Final = 3.0
"""Seconds of history before each incident."""
NEARBY_RADIUS_M: Final = 60.0
"""Traffic cars that come this close to the ego during the history are in the report."""
EGO_FIELDS: Final = ("x", "y", "s", "d", "yaw", "speed")
CAR_FIELDS: Final = ("x", "y", "vx", "vy", "s", "d")
SNAPSHOT_EVERY_S: Final = 1.0
"""Simulated seconds between the recorder's snapshots of the env (for replays)."""
MAX_REPORTS: Final = 1000
"""Reports kept per episode (a long endurance run with a bad planner counts the rest only)."""
_DIGITS: Final = 4  # decimals kept in reports (0.1 mm, 0.1 mrad): readable JSON


class IncidentRecorder:
    """Records the recent past and snapshots it at every incident; see the module docstring.

    Call :meth:`add` with the reset's and every step's ``(observation, info)``, then
    :meth:`reports` with the summary's ``incident_log`` at the end.
    """

    def __init__(self, history_s: float = DEFAULT_HISTORY_S,
                 radius_m: float = NEARBY_RADIUS_M,
                 snapshot: Callable[[], dict[str, Any]] | None = None) -> None:
        if not history_s > 0:
            raise ValueError(f"history_s must be > 0 s, got {history_s!r}")
        self.history_s = float(history_s)
        self.radius_m = float(radius_m)
        self.snapshot = snapshot
        self._samples: deque[tuple[float, Any, dict[str, Any]]] = deque()
        self._snapshots: list[tuple[str, tuple[tuple[float, Any, dict[str, Any]], ...]]] = []
        self._states: deque[tuple[float, dict[str, Any]]] = deque()  # (time, env snapshot)
        self._replays: list[dict[str, Any] | None] = []
        self._next_state_at = 0.0

    def add(self, observation: Any, info: dict[str, Any]) -> None:
        """One env step (or the reset): keep it, forget what is older than the history."""
        now = float(info["time"])
        samples = self._samples
        samples.append((now, observation, info))
        oldest = now - self.history_s - 1e-9
        while samples[0][0] < oldest:
            samples.popleft()
        kinds = info.get("new_incidents")
        if kinds and len(self._snapshots) < MAX_REPORTS:
            history = tuple(samples)
            self._snapshots.extend((kind, history) for kind in kinds)
            replay = self._replay_for(now)
            self._replays.extend(replay for _ in kinds)
        if self.snapshot is not None and now >= self._next_state_at - 1e-9:
            states = self._states
            states.append((now, self.snapshot()))
            self._next_state_at = now + SNAPSHOT_EVERY_S
            # Keep the newest one old enough for any incident to come, and those after it.
            while len(states) > 1 and states[1][0] <= now - self.history_s + 1e-9:
                states.popleft()

    def _replay_for(self, now: float) -> dict[str, Any] | None:
        """The newest snapshot from at least ``history_s`` before ``now`` (the oldest one
        early in an episode), or ``None`` without snapshots."""
        chosen = None
        for time, state in self._states:
            if chosen is None or time <= now - self.history_s + 1e-9:
                chosen = state
        return chosen

    def reports(self, incident_log: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """One report per incident: the log's entry plus ``history`` (JSON-ready).

        ``incident_log`` is the env summary's, in the same order as the steps'
        ``new_incidents`` (an incident missing from it keeps its kind only).
        """
        reports = []
        for index, (kind, history) in enumerate(self._snapshots):
            entry = incident_log[index] if index < len(incident_log) else {}
            if entry.get("kind", kind) != kind:
                entry = {}  # out of step with the log: do not attach the wrong details
            report = {"kind": kind, **{key: value for key, value in entry.items()
                                       if key != "kind"}}
            report["history"] = self._history(history)
            if index < len(self._replays) and self._replays[index] is not None:
                report["replay"] = self._replays[index]
            reports.append(report)
        return reports

    def _history(self, history: tuple[tuple[float, Any, dict[str, Any]], ...]
                 ) -> dict[str, Any]:
        times = [round(sample[0], _DIGITS) for sample in history]
        ego = np.array([_ego_row(observation, info) for _, observation, info in history])
        result: dict[str, Any] = {
            "time": times,
            "ego": {name: np.round(ego[:, i], _DIGITS).tolist()
                    for i, name in enumerate(EGO_FIELDS)},
            "cars": [],
        }
        fusion = [_cars(observation) for _, observation, _ in history]
        if all(rows is None for rows in fusion):
            return result
        tracks: dict[int, list[tuple[float, Any]]] = {}
        near: set[int] = set()
        for time, rows, (x, y) in zip(times, fusion, ego[:, :2].tolist(), strict=True):
            if rows is None:
                continue
            for row in rows:
                car = int(row[0])
                tracks.setdefault(car, []).append((time, row))
                if (row[1] - x) ** 2 + (row[2] - y) ** 2 <= self.radius_m**2:
                    near.add(car)
        for car in sorted(near):
            samples = tracks[car]
            rows = np.round(np.array([row[1:7] for _, row in samples], dtype=np.float64),
                            _DIGITS)
            entry: dict[str, Any] = {"id": car, "time": [time for time, _ in samples]}
            entry.update({name: rows[:, i].tolist() for i, name in enumerate(CAR_FIELDS)})
            result["cars"].append(entry)
        return result


def _ego_row(observation: Any, info: dict[str, Any]) -> list[float]:
    if isinstance(observation, dict) and "ego" in observation:  # highway: x y s d yaw speed
        return [float(value) for value in observation["ego"][:6]]
    return [float(info.get(name, np.nan)) for name in EGO_FIELDS]


def _cars(observation: Any) -> Any:
    """The present sensor fusion rows ``[id, x, y, vx, vy, s, d]``, or ``None``."""
    if not (isinstance(observation, dict) and "sensor_fusion" in observation):
        return None
    rows = np.asarray(observation["sensor_fusion"], dtype=np.float64)
    mask = observation.get("sensor_fusion_mask")
    return rows[np.asarray(mask) > 0] if mask is not None else rows
