"""The track loop's metrics for a batch of envs: stop lines, stops, cross-track error and
lateral acceleration as a numba kernel, the shared driving metrics as
:class:`~sdc_gym.metrics.batch.DrivingMetricsBatch`.

The rules are :mod:`sdc_gym.metrics.track_metrics`' (its module docstring); this module
is their only implementation: :class:`~sdc_gym.metrics.track_metrics.TrackMetrics` is the
batch of one, and the track world's frame kernel calls :func:`stop_line_frame` for every
env's physics frames, then hands the frames to the driving metrics in one chunk.

Per env, the running state is one entry of each array of :class:`StopLineState`; rare
events (red-light crossings, finished stops) leave the kernel as rows of event buffers
(:class:`StopLineEvents`) that :class:`TrackMetricsBatch` turns into incidents and
:class:`~sdc_gym.metrics.track_metrics.StopRecord` lists.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import py_min, py_mod
from sdc_gym.kernel_compiler import kernel
from sdc_gym.lights.traffic_lights import GREEN, RED, YELLOW
from sdc_gym.metrics.batch import DrivingMetricsBatch
from sdc_gym.metrics.incidents import INCIDENT_KINDS, Incident, IncidentRules
from sdc_gym.road.track_map import TrackMap

RED_LIGHT = "red_light"
TRACK_INCIDENT_KINDS: tuple[str, ...] = (*INCIDENT_KINDS, RED_LIGHT)
"""Every incident kind of the track loop, in report order."""

STOP_SPEED_MPS = 0.1
"""Below this speed the car counts as stopped (the vehicle model reaches exactly 0 when the
brakes stop it; this also catches a car held against its idle creep)."""
STOP_LINE_RANGE_M = 10.0
"""A stop belongs to a stop line when the front bumper rests within this distance of it."""

CROSSING_NAMES = ("red", "yellow", "green", "unknown")
"""``stop_line_crossings`` keys, in order (the kernel counts into these columns)."""


@dataclass(frozen=True)
class StopRecord:
    """The car came to rest near a stop line.

    Attributes:
        line: index of the stop line (its light has the same index).
        time: s, when the stop began (speed fell below :data:`STOP_SPEED_MPS`).
        offset_m: where the front bumper came to rest, m past the line (negative: short of
            it); the final value once the car moved off again (or the episode ended).
        light_state: that light's state code when the stop began.
    """

    line: int
    time: float
    offset_m: float
    light_state: int

    @property
    def overshoot_m(self) -> float:
        """m the front bumper came to rest past the line (0 when it stopped before it)."""
        return max(self.offset_m, 0.0)

    def as_dict(self) -> dict[str, Any]:
        """Plain-Python dict, ready for JSON (with ``overshoot_m``)."""
        return {**asdict(self), "overshoot_m": self.overshoot_m}


class StopLines(NamedTuple):
    """A track's stop lines as the kernel needs them (shared by every env)."""

    line_order: NDArray[np.int64]  # (k,) line indices sorted by s
    gap_to_next: NDArray[np.float64]  # (k,) m from each sorted line to the next (wraps)
    front_offset: float  # m, rear axle to front bumper
    length: float  # m, the loop
    dt: float  # s per physics frame


class StopLineState(NamedTuple):
    """Per env (arrays over the env axis): progress, the stop-line pointer, the current
    stop, crossing counts and the cross-track / lateral statistics."""

    progress: NDArray[np.float64]
    s_last: NDArray[np.float64]
    steps: NDArray[np.int64]
    next_position: NDArray[np.int64]  # position in line_order of the next line to cross
    next_cross: NDArray[np.float64]  # its unwrapped arc length
    last_line: NDArray[np.int64]
    last_cross: NDArray[np.float64]
    moving: NDArray[np.bool_]
    stopped_at_line: NDArray[np.bool_]  # a stop near a line is in progress
    stop_line: NDArray[np.int64]
    stop_time: NDArray[np.float64]
    stop_line_at: NDArray[np.float64]
    stop_state: NDArray[np.int64]
    stop_offset: NDArray[np.float64]
    crossings: NDArray[np.int64]  # (envs, 4): CROSSING_NAMES
    sum_d2: NDArray[np.float64]
    samples: NDArray[np.int64]
    max_abs_d: NDArray[np.float64]
    last_d: NDArray[np.float64]
    max_lat: NDArray[np.float64]
    last_lat: NDArray[np.float64]


class StopLineEvents(NamedTuple):
    """Event rows written by the kernel: red-light crossings ``(env, chunk frame, line)``
    and finished stops ``(env, line, state)`` with ``(time, offset)``; ``counts`` holds
    how many rows of each are filled."""

    red: NDArray[np.int64]  # (rows, 3)
    stop_ids: NDArray[np.int64]  # (rows, 3)
    stop_values: NDArray[np.float64]  # (rows, 2)
    counts: NDArray[np.int64]  # (2,): red rows, stop rows


def stop_line_state(envs: int) -> StopLineState:
    """Zeroed state for ``envs`` envs (reset each with :meth:`TrackMetricsBatch.reset_at`)."""
    floats = np.zeros
    ints = lambda: np.zeros(envs, dtype=np.int64)  # noqa: E731
    bools = lambda: np.zeros(envs, dtype=bool)  # noqa: E731
    return StopLineState(floats(envs), floats(envs), ints(), ints(), floats(envs), ints(),
                         floats(envs), bools(), bools(), ints(), floats(envs), floats(envs),
                         ints(), floats(envs), np.zeros((envs, 4), dtype=np.int64),
                         floats(envs), ints(), floats(envs), floats(envs), floats(envs),
                         floats(envs))


def stop_line_events(rows: int) -> StopLineEvents:
    """Empty event buffers with room for ``rows`` events of each kind."""
    return StopLineEvents(np.zeros((rows, 3), dtype=np.int64),
                          np.zeros((rows, 3), dtype=np.int64), np.zeros((rows, 2)),
                          np.zeros(2, dtype=np.int64))


@kernel
def _crossing_column(state: int) -> int:
    if state == RED:
        return 0
    if state == YELLOW:
        return 1
    if state == GREEN:
        return 2
    return 3


@kernel
def stop_line_frame(lines: StopLines, st: StopLineState, env: int, frame: int, s: float,
                    d: float, speed: float, lateral: float, states: NDArray[np.int8],
                    events: StopLineEvents) -> None:
    """Add one physics frame of env ``env`` (``frame``: its index in the chunk the driving
    metrics will get; ``states``: the lights' states at that frame)."""
    length = lines.length
    half = 0.5 * length
    progress = st.progress[env] + (py_mod((s - st.s_last[env]) + half, length) - half)
    st.progress[env] = progress
    st.s_last[env] = s
    step = st.steps[env] + 1
    st.steps[env] = step
    front = progress + lines.front_offset
    count = lines.line_order.size
    if count:
        while front > st.next_cross[env]:
            # The front bumper passes the next line.
            position = st.next_position[env]
            line = lines.line_order[position]
            state = states[line]
            st.crossings[env, _crossing_column(state)] += 1
            if state == RED:
                row = events.counts[0]
                events.red[row, 0] = env
                events.red[row, 1] = frame
                events.red[row, 2] = line
                events.counts[0] = row + 1
            st.last_line[env] = line
            st.last_cross[env] = st.next_cross[env]
            st.next_cross[env] += lines.gap_to_next[position]
            st.next_position[env] = (position + 1) % count
        if speed < STOP_SPEED_MPS:
            if st.moving[env]:
                # The car just stopped: attach the stop to the nearest line within range.
                short_of_next = st.next_cross[env] - front
                past_last = front - st.last_cross[env]
                if short_of_next <= past_last:
                    line, line_at = lines.line_order[st.next_position[env]], st.next_cross[env]
                else:
                    line, line_at = st.last_line[env], st.last_cross[env]
                if py_min(short_of_next, past_last) > STOP_LINE_RANGE_M:
                    st.stopped_at_line[env] = False
                else:
                    st.stopped_at_line[env] = True
                    st.stop_line[env] = line
                    st.stop_time[env] = step * lines.dt
                    st.stop_line_at[env] = line_at
                    st.stop_state[env] = states[line]
                    st.stop_offset[env] = front - line_at
            elif st.stopped_at_line[env]:
                st.stop_offset[env] = front - st.stop_line_at[env]
            st.moving[env] = False
        elif not st.moving[env]:
            if st.stopped_at_line[env]:
                row = events.counts[1]
                events.stop_ids[row, 0] = env
                events.stop_ids[row, 1] = st.stop_line[env]
                events.stop_ids[row, 2] = st.stop_state[env]
                events.stop_values[row, 0] = st.stop_time[env]
                events.stop_values[row, 1] = st.stop_offset[env]
                events.counts[1] = row + 1
                st.stopped_at_line[env] = False
            st.moving[env] = True
    st.sum_d2[env] += d * d
    if abs(d) > st.max_abs_d[env]:
        st.max_abs_d[env] = abs(d)
    if abs(lateral) > st.max_lat[env]:
        st.max_lat[env] = abs(lateral)
    st.samples[env] += 1
    st.last_d[env] = d
    st.last_lat[env] = lateral


@kernel
def stop_lines_record(lines: StopLines, st: StopLineState, env: int, s: NDArray[np.float64],
                      d: NDArray[np.float64], speed: NDArray[np.float64],
                      lateral: NDArray[np.float64], states: NDArray[np.int8],
                      events: StopLineEvents) -> None:
    """:func:`stop_line_frame` for ``k`` frames of one env (``states``: (k, lights))."""
    for i in range(s.size):
        stop_line_frame(lines, st, env, i, s[i], d[i], speed[i], lateral[i], states[i], events)


class TrackMetricsBatch:
    """Driving metrics, stop lines, cross-track error and lateral acceleration of ``envs``
    cars (one per env); see the module docstring.

    Args:
        track: the track (its stop lines and loop length).
        rules: the incident rules (the env gives the track's speed limit and road edges).
        front_offset_m: m from the reference point (rear axle) to the front bumper.
        envs: number of envs.
    """

    def __init__(self, track: TrackMap, rules: IncidentRules, front_offset_m: float,
                 envs: int = 1) -> None:
        if not (math.isfinite(front_offset_m) and front_offset_m >= 0.0):
            raise ValueError(f"front_offset_m must be a finite number >= 0 m, "
                             f"got {front_offset_m!r}")
        self.track = track
        self.envs = envs
        self.front_offset_m = float(front_offset_m)
        self.driving = DrivingMetricsBatch(rules, track.length, envs, extra_kinds=(RED_LIGHT,))
        length = track.length
        order = np.argsort(track.stop_line_s, kind="stable")
        sorted_s = [float(track.stop_line_s[i]) for i in order]
        count = len(sorted_s)
        # Gap from each line (in sorted order) to the next one; the last wraps the loop end.
        # Lines at the same s have a gap of 0 (each is crossed, in the same step); the gaps
        # always add up to one loop.
        gaps = [sorted_s[k + 1] - sorted_s[k] for k in range(count - 1)]
        if count:
            gaps.append(sorted_s[0] + length - sorted_s[-1])
        self.lines = StopLines(np.asarray(order, dtype=np.int64),
                               np.asarray(gaps, dtype=np.float64), self.front_offset_m,
                               float(length), float(rules.dt))
        self._sorted_position = {int(line): k for k, line in enumerate(order)}
        self.state = stop_line_state(envs)
        self.stops_done: list[list[StopRecord]] = [[] for _ in range(envs)]

    # ------------------------------------------------------------------ episode control
    def reset_at(self, env: int, x: float, y: float, s: float, d: float,
                 speed: float = 0.0) -> None:
        """Start env ``env``'s episode with the reference point at (x, y) / (s, d)."""
        self.driving.reset_at(env, x, y, s, d, speed)
        st = self.state
        for array in st:
            array[env] = 0
        st.s_last[env] = float(s)
        st.last_d[env] = float(d)
        lines = self.lines
        count = len(lines.line_order)
        if count:
            # The line ahead of the reference point, skipping any under the car (the same
            # query as the env's observation, so both name the same line).
            line, ahead = self.track.next_stop_line(s)
            position = self._sorted_position[line]
            for _ in range(count):
                if ahead >= self.front_offset_m:
                    break
                ahead += float(lines.gap_to_next[position])
                position = (position + 1) % count
            st.next_position[env] = position
            st.next_cross[env] = ahead
            previous = (position - 1) % count
            st.last_line[env] = lines.line_order[previous]
            st.last_cross[env] = ahead - float(lines.gap_to_next[previous])
        st.moving[env] = speed >= STOP_SPEED_MPS
        self.stops_done[env] = []

    # ------------------------------------------------------------------ recording
    def collect(self, events: StopLineEvents, frames: int
                ) -> list[list[tuple[int, str, float]]] | None:
        """Take the kernel's events: finished stops into :attr:`stops_done`, red-light
        crossings returned as each env's ``extra_incidents`` for the driving metrics
        (``frames``: the chunk's length), or None without any. Empties the buffers."""
        red_rows, stop_rows = events.counts.tolist()
        for row, (env, line, state) in enumerate(events.stop_ids[:stop_rows].tolist()):
            time, offset = events.stop_values[row].tolist()
            self.stops_done[env].append(StopRecord(line, time, offset, state))
        extra: list[list[tuple[int, str, float]]] | None = None
        if red_rows:
            extra = [[] for _ in range(self.envs)]
            for env, frame, line in events.red[:red_rows].tolist():
                extra[env].append((frame, RED_LIGHT, float(line)))
        events.counts[:] = 0
        return extra

    # ------------------------------------------------------------------ results
    def next_stop_line(self, env: int) -> tuple[int, float]:
        """(index, m from the front bumper along the path) of the next stop line env
        ``env``'s front bumper will cross; ``(-1, inf)`` on a track without lines."""
        if not len(self.lines.line_order):
            return -1, math.inf
        st = self.state
        return (int(self.lines.line_order[st.next_position[env]]),
                float(st.next_cross[env] - st.progress[env] - self.front_offset_m))

    def stops(self, env: int) -> list[StopRecord]:
        """Env ``env``'s stops at stop lines so far, the current one (if stopped) included."""
        stops = list(self.stops_done[env])
        st = self.state
        if st.stopped_at_line[env]:
            stops.append(StopRecord(int(st.stop_line[env]), float(st.stop_time[env]),
                                    float(st.stop_offset[env]), int(st.stop_state[env])))
        return stops

    def red_light_violations(self, env: int) -> int:
        return int(self.driving.counts[env, self.driving.kind_order[RED_LIGHT]])

    def rms_cross_track_error(self, env: int) -> float:
        """m, root mean square of ``d`` over the recorded steps (0 before any)."""
        samples = int(self.state.samples[env])
        return math.sqrt(float(self.state.sum_d2[env]) / samples) if samples else 0.0

    def step_info(self, env: int) -> dict[str, Any]:
        """The driving metrics' step info plus the latest cross-track error and lateral
        acceleration; the same keys every call."""
        info: dict[str, Any] = self.driving.step_info(env)
        info["cross_track_error"] = float(self.state.last_d[env])
        info["lateral_acceleration"] = float(self.state.last_lat[env])
        return info

    def summary(self, env: int) -> dict[str, Any]:
        """The driving metrics' summary plus (plain Python, JSON-ready):

        ``red_light_violations``; ``stop_line_crossings`` (crossings by the light's state:
        red, yellow, green, unknown); ``stops`` (each :class:`StopRecord` as a dict) and
        ``max_overshoot`` (m, 0 without a stop past a line); ``max_cross_track_error``,
        ``rms_cross_track_error`` (m); ``max_lateral_acceleration`` (m/s^2).
        """
        summary = self.driving.summary(env)
        stops = self.stops(env)
        st = self.state
        summary.update({
            "red_light_violations": self.red_light_violations(env),
            "stop_line_crossings": dict(zip(CROSSING_NAMES, st.crossings[env].tolist(),
                                            strict=True)),
            "stops": [stop.as_dict() for stop in stops],
            "max_overshoot": max((stop.overshoot_m for stop in stops), default=0.0),
            "max_cross_track_error": float(st.max_abs_d[env]),
            "rms_cross_track_error": self.rms_cross_track_error(env),
            "max_lateral_acceleration": float(st.max_lat[env]),
        })
        return summary


__all__ = ["CROSSING_NAMES", "RED_LIGHT", "STOP_LINE_RANGE_M", "STOP_SPEED_MPS",
           "TRACK_INCIDENT_KINDS", "Incident", "StopRecord", "TrackMetricsBatch"]
