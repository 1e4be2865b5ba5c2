"""Metrics of the track loop: the shared driving metrics plus stop lines, cross-track error
and lateral acceleration.

:class:`TrackMetrics` owns a :class:`~sdc_gym.metrics.driving_metrics.DrivingMetrics` (lap
times, distance, acceleration / jerk / speed / off-road / collision incidents) and adds
what a traffic-light track asks for. It counts one more incident kind, ``"red_light"``
(:data:`TRACK_INCIDENT_KINDS`), through the driving metrics' ``extra_kinds``, so red-light
violations are counted, logged and ordered, and restart the distance without incident,
exactly like the shared kinds.

Conventions
-----------
* The car's reference point is the centre of the rear axle (the vehicle model's ``x, y``);
  ``s, d`` are its Frenet coordinates on the track's path, and ``d`` is the
  **cross-track error** (m, positive to the right of travel).
* The **front bumper** is ``front_offset_m`` ahead of the reference point *along the
  path*: its arc length is ``s + front_offset_m``. That is exact while the car is aligned
  with a straight path, where the stop lines are, and a few centimetres off in a bend.
* Positions along the loop are *unwrapped* (progress since reset, like
  :attr:`DrivingMetrics.progress`), so a line is met again one lap later.

Stop lines
----------
Crossing
    The front bumper crosses a stop line at the first physics step at which its unwrapped
    arc length is strictly beyond the line's. Each pass over a line counts once: the
    pointer to the next line only moves forward, so the small backward motion of ``s``
    that steering can cause never counts a line twice. Lines at the same ``s`` are
    separate lines: a pass counts each of them (in the same step).
Next line
    At :meth:`TrackMetrics.reset` the next line is the first one at least
    ``front_offset_m`` ahead of the reference point, i.e. not yet under the car (a line
    between the rear axle and the front bumper counts as passed);
    :attr:`TrackMetrics.next_stop_line` reports it with its distance from the front
    bumper. The env starts the car where no line lies under it, so the observation (the
    next line ahead of the rear axle) and the metrics agree at every reset.
Red-light violation
    A crossing at a step when that line's light (light ``i`` belongs to stop line ``i``)
    is RED; a ``"red_light"`` incident with the line's index as its value. Crossing on
    yellow is allowed (it is counted in ``stop_line_crossings``).
Stop and overshoot
    The car *stops* when its speed falls below :data:`STOP_SPEED_MPS` having been above
    it, and stays stopped until it is above it again. A stop belongs to the stop line
    nearest the front bumper (the next one ahead or the last one passed) if that is within
    :data:`STOP_LINE_RANGE_M`; its ``offset_m`` is where the front bumper came to rest
    relative to the line (positive: past the line), updated while the car creeps. The
    **overshoot** of a stop is ``max(offset_m, 0)``; the summary reports every stop and
    the largest overshoot.

Cross-track error and lateral acceleration are sampled every physics step: the maximum of
``|d|``, its root mean square, and the maximum ``|a_lat|`` (the vehicle's
``speed * yaw_rate``). Lap times come from the driving metrics.

Cost: :meth:`TrackMetrics.record` adds a scalar loop over the chunk's few steps to the
driving metrics' own; without lights the stop-line work is skipped.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.metrics.driving_metrics import INCIDENT_KINDS, DrivingMetrics, Incident, IncidentRules
from sdc_gym.road.track_map import TrackMap

RED_LIGHT = "red_light"
TRACK_INCIDENT_KINDS: tuple[str, ...] = (*INCIDENT_KINDS, RED_LIGHT)
"""Every incident kind of the track loop, in report order."""

STOP_SPEED_MPS = 0.1
"""Below this speed the car counts as stopped (the vehicle model reaches exactly 0 when the
brakes stop it; this also catches a car held against its idle creep)."""
STOP_LINE_RANGE_M = 10.0
"""A stop belongs to a stop line when the front bumper rests within this distance of it."""

_STATE_NAMES = {RED: "red", YELLOW: "yellow", GREEN: "green", UNKNOWN: "unknown"}


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


class TrackMetrics:
    """Driving metrics, stop lines, cross-track error and lateral acceleration of one car.

    Call :meth:`reset` at the start of every episode and :meth:`record` with the physics
    steps of each env step; read :meth:`step_info` and :meth:`summary`, or the shared
    metrics through :attr:`driving`.

    Args:
        track: the track (its stop lines and loop length).
        rules: the incident rules (the env gives the track's speed limit and road edges).
        front_offset_m: m from the reference point (rear axle) to the front bumper.
    """

    def __init__(self, track: TrackMap, rules: IncidentRules, front_offset_m: float) -> None:
        if not (math.isfinite(front_offset_m) and front_offset_m >= 0.0):
            raise ValueError(f"front_offset_m must be a finite number >= 0 m, "
                             f"got {front_offset_m!r}")
        self.track = track
        self.front_offset_m = float(front_offset_m)
        self.driving = DrivingMetrics(rules, track.length, extra_kinds=(RED_LIGHT,))
        self._length = track.length
        order = np.argsort(track.stop_line_s, kind="stable")
        self._line_order = [int(i) for i in order]
        sorted_s = [float(track.stop_line_s[i]) for i in order]
        count = len(sorted_s)
        # Gap from each line (in sorted order) to the next one; the last wraps the loop end.
        # Lines at the same s have a gap of 0 (each is crossed, in the same step); the gaps
        # always add up to one loop.
        self._gap_to_next = [sorted_s[k + 1] - sorted_s[k] for k in range(count - 1)]
        if count:
            self._gap_to_next.append(sorted_s[0] + self._length - sorted_s[-1])
        self._sorted_position = {line: k for k, line in enumerate(self._line_order)}
        self._ready = False

    # ------------------------------------------------------------------ episode control
    def reset(self, x: float, y: float, s: float, d: float, speed: float = 0.0) -> None:
        """Start an episode with the reference point at ``(x, y)`` / ``(s, d)``."""
        self.driving.reset(x, y, s, d, speed)
        self._s_last = float(s)
        self._progress = 0.0
        self._steps = 0
        offset = self.front_offset_m
        if self._line_order:
            # The line ahead of the reference point, skipping any under the car (the same
            # query as the env's observation, so both name the same line).
            line, ahead = self.track.next_stop_line(s)
            position = self._sorted_position[line]
            for _ in range(len(self._line_order)):
                if ahead >= offset:
                    break
                ahead += self._gap_to_next[position]
                position = (position + 1) % len(self._line_order)
            self._next_position = position
            self._next_cross = ahead
            previous = (position - 1) % len(self._line_order)
            self._last_line = self._line_order[previous]
            self._last_cross = self._next_cross - self._gap_to_next[previous]
        self._moving = speed >= STOP_SPEED_MPS
        self._stop: list[Any] | None = None  # [line, time, line position, state, offset]
        self._stops: list[StopRecord] = []
        self._crossings = dict.fromkeys(_STATE_NAMES.values(), 0)
        self._sum_d2 = 0.0
        self._samples = 0
        self._max_abs_d = 0.0
        self._last_d = float(d)
        self._max_lat = 0.0
        self._last_lat = 0.0
        self._ready = True

    def record(
        self,
        xy: NDArray[np.float64],
        s: NDArray[np.float64],
        d: NDArray[np.float64],
        speed: NDArray[np.float64],
        lateral_acceleration: Sequence[float],
        light_states: Sequence[NDArray[np.int8]] | None = None,
        collision_ids: NDArray[np.int64] | None = None,
    ) -> list[Incident]:
        """Add ``k >= 1`` physics steps; returns the incidents they began, in step order.

        Args:
            xy, s, d, speed: as :meth:`DrivingMetrics.record` (arrays of ``k`` steps).
            lateral_acceleration: ``k`` values, m/s^2.
            light_states: per step, the lights' states (k references to state arrays,
                only read); may be ``None`` only when the track has no stop lines.
            collision_ids: per step, the obstacle touched or -1; ``None``: no contact.
        """
        if not self._ready:
            raise RuntimeError("call reset() before record()")
        s_l = s.tolist()
        d_l = d.tolist()
        speed_l = speed.tolist()
        dt = self.driving.rules.dt
        length, half = self._length, 0.5 * self._length
        offset = self.front_offset_m
        has_lines = bool(self._line_order)
        if has_lines and light_states is None:
            raise ValueError("TrackMetrics.record: the track has stop lines, so light_states "
                             "(the lights' states per step) is required")
        extra: list[tuple[int, str, float]] = []
        progress, s_last, step = self._progress, self._s_last, self._steps
        max_abs_d, max_lat, sum_d2 = self._max_abs_d, self._max_lat, self._sum_d2
        for i, s_i in enumerate(s_l):
            progress += (s_i - s_last + half) % length - half
            s_last = s_i
            step += 1
            front = progress + offset
            if has_lines:
                while front > self._next_cross:
                    self._cross(i, light_states[i], extra)  # type: ignore[index]
                v = speed_l[i]
                if v < STOP_SPEED_MPS:
                    if self._moving:
                        self._begin_stop(front, step * dt, light_states[i])  # type: ignore[index]
                    elif self._stop is not None:
                        self._stop[4] = front - self._stop[2]
                    self._moving = False
                elif not self._moving:
                    self._end_stop()
                    self._moving = True
            dd = d_l[i]
            sum_d2 += dd * dd
            if abs(dd) > max_abs_d:
                max_abs_d = abs(dd)
            lat = abs(lateral_acceleration[i])
            if lat > max_lat:
                max_lat = lat
        self._progress, self._s_last, self._steps = progress, s_last, step
        self._max_abs_d, self._max_lat, self._sum_d2 = max_abs_d, max_lat, sum_d2
        self._samples += len(s_l)
        self._last_d = d_l[-1]
        self._last_lat = lateral_acceleration[-1]
        return self.driving.record(xy, s, d, speed, collision_ids, extra or None)

    # ------------------------------------------------------------------ stop lines
    def _cross(self, i: int, states: NDArray[np.int8],
               extra: list[tuple[int, str, float]]) -> None:
        """The front bumper passed the next line at chunk step ``i``."""
        position = self._next_position
        line = self._line_order[position]
        state = int(states[line])
        self._crossings[_STATE_NAMES.get(state, "unknown")] += 1
        if state == RED:
            extra.append((i, RED_LIGHT, float(line)))
        self._last_line, self._last_cross = line, self._next_cross
        self._next_cross += self._gap_to_next[position]
        self._next_position = (position + 1) % len(self._line_order)

    def _begin_stop(self, front: float, time: float, states: NDArray[np.int8]) -> None:
        """The car just stopped: attach the stop to the nearest line within range."""
        short_of_next = self._next_cross - front
        past_last = front - self._last_cross
        if short_of_next <= past_last:
            line, line_at = self._line_order[self._next_position], self._next_cross
        else:
            line, line_at = self._last_line, self._last_cross
        if min(short_of_next, past_last) > STOP_LINE_RANGE_M:
            self._stop = None
            return
        self._stop = [line, time, line_at, int(states[line]), front - line_at]

    def _end_stop(self) -> None:
        if self._stop is not None:
            line, time, _, state, offset = self._stop
            self._stops.append(StopRecord(line, time, offset, state))
            self._stop = None

    # ------------------------------------------------------------------ results
    @property
    def incident_counts(self) -> dict[str, int]:
        """Incidents by kind, every kind of :data:`TRACK_INCIDENT_KINDS` present."""
        return self.driving.incident_counts

    @property
    def next_stop_line(self) -> tuple[int, float]:
        """(index, m from the front bumper along the path) of the next stop line the front
        bumper will cross; ``(-1, inf)`` on a track without lines."""
        if not self._line_order:
            return -1, math.inf
        return (self._line_order[self._next_position],
                self._next_cross - self._progress - self.front_offset_m)

    @property
    def red_light_violations(self) -> int:
        return self.driving.incident_counts[RED_LIGHT]

    @property
    def stops(self) -> list[StopRecord]:
        """Stops at stop lines so far, the current one (if stopped) included."""
        stops = list(self._stops)
        if self._stop is not None:
            line, time, _, state, offset = self._stop
            stops.append(StopRecord(line, time, offset, state))
        return stops

    @property
    def rms_cross_track_error(self) -> float:
        """m, root mean square of ``d`` over the recorded steps (0 before any)."""
        return math.sqrt(self._sum_d2 / self._samples) if self._samples else 0.0

    @property
    def max_cross_track_error(self) -> float:
        """m, largest ``|d|`` so far."""
        return self._max_abs_d

    @property
    def max_lateral_acceleration(self) -> float:
        """m/s^2, largest ``|a_lat|`` so far."""
        return self._max_lat

    def step_info(self) -> dict[str, Any]:
        """The driving metrics' step info plus the latest cross-track error and lateral
        acceleration; the same keys every call."""
        info: dict[str, Any] = self.driving.step_info()
        info["cross_track_error"] = self._last_d
        info["lateral_acceleration"] = self._last_lat
        return info

    def summary(self) -> dict[str, Any]:
        """The driving metrics' summary plus (plain Python, JSON-ready):

        ``red_light_violations``; ``stop_line_crossings`` (crossings by the light's state:
        red, yellow, green, unknown); ``stops`` (each :class:`StopRecord` as a dict) and
        ``max_overshoot`` (m, 0 without a stop past a line); ``max_cross_track_error``,
        ``rms_cross_track_error`` (m); ``max_lateral_acceleration`` (m/s^2).
        """
        summary = self.driving.summary()
        stops = self.stops
        summary.update({
            "red_light_violations": self.red_light_violations,
            "stop_line_crossings": dict(self._crossings),
            "stops": [stop.as_dict() for stop in stops],
            "max_overshoot": max((stop.overshoot_m for stop in stops), default=0.0),
            "max_cross_track_error": self._max_abs_d,
            "rms_cross_track_error": self.rms_cross_track_error,
            "max_lateral_acceleration": self._max_lat,
        })
        return summary
