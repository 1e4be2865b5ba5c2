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

Implementation: the stop-line rules are the numba kernel of
:mod:`sdc_gym.metrics.track_metrics_batch` (over a batch of envs: the track world runs it
for every env's frames); :class:`TrackMetrics` is its batch of one.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.metrics.driving_metrics import DrivingMetrics, Incident, IncidentRules
from sdc_gym.metrics.track_metrics_batch import (
    RED_LIGHT,
    STOP_LINE_RANGE_M,
    STOP_SPEED_MPS,
    TRACK_INCIDENT_KINDS,
    StopRecord,
    TrackMetricsBatch,
    stop_line_events,
    stop_lines_record,
)
from sdc_gym.road.track_map import TrackMap

__all__ = ["RED_LIGHT", "STOP_LINE_RANGE_M", "STOP_SPEED_MPS", "TRACK_INCIDENT_KINDS",
           "StopRecord", "TrackMetrics"]


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
        self._attach(TrackMetricsBatch(track, rules, front_offset_m, envs=1), 0)
        self._ready = False

    @classmethod
    def view(cls, batch: TrackMetricsBatch, env: int) -> TrackMetrics:
        """Env ``env`` of an existing batch, with this class's API (read it; the batch
        records)."""
        made = object.__new__(cls)
        made._attach(batch, env)
        made._ready = True
        return made

    def _attach(self, batch: TrackMetricsBatch, env: int) -> None:
        self.batch = batch
        self.env = env
        self.track = batch.track
        self.front_offset_m = batch.front_offset_m
        self.driving = DrivingMetrics.view(batch.driving, env)

    # ------------------------------------------------------------------ episode control
    def reset(self, x: float, y: float, s: float, d: float, speed: float = 0.0) -> None:
        """Start an episode with the reference point at ``(x, y)`` / ``(s, d)``."""
        self.batch.reset_at(0, x, y, s, d, speed)
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
            light_states: per step, the lights' states (k arrays); may be ``None`` only
                when the track has no stop lines.
            collision_ids: per step, the obstacle touched or -1; ``None``: no contact.
        """
        if not self._ready:
            raise RuntimeError("call reset() before record()")
        batch = self.batch
        if batch.envs != 1:
            raise RuntimeError("record() of one env of a batch: record the batch")
        lights = len(batch.lines.line_order)
        if lights and light_states is None:
            raise ValueError("TrackMetrics.record: the track has stop lines, so light_states "
                             "(the lights' states per step) is required")
        s = np.asarray(s, dtype=np.float64).reshape(-1)
        k = len(s)
        states = (np.asarray(light_states, dtype=np.int8).reshape(k, lights) if lights
                  else np.zeros((k, 0), dtype=np.int8))
        events = stop_line_events(k * max(lights, 1))
        stop_lines_record(batch.lines, batch.state, 0, s,
                          np.asarray(d, dtype=np.float64).reshape(-1),
                          np.asarray(speed, dtype=np.float64).reshape(-1),
                          np.asarray(lateral_acceleration, dtype=np.float64).reshape(-1),
                          states, events)
        extra = batch.collect(events, k)
        return self.driving.record(xy, s, d, speed, collision_ids, extra[0] if extra else None)

    # ------------------------------------------------------------------ results
    @property
    def incident_counts(self) -> dict[str, int]:
        """Incidents by kind, every kind of :data:`TRACK_INCIDENT_KINDS` present."""
        return self.driving.incident_counts

    @property
    def next_stop_line(self) -> tuple[int, float]:
        """(index, m from the front bumper along the path) of the next stop line the front
        bumper will cross; ``(-1, inf)`` on a track without lines."""
        return self.batch.next_stop_line(self.env)

    @property
    def red_light_violations(self) -> int:
        return self.batch.red_light_violations(self.env)

    @property
    def stops(self) -> list[StopRecord]:
        """Stops at stop lines so far, the current one (if stopped) included."""
        return self.batch.stops(self.env)

    @property
    def rms_cross_track_error(self) -> float:
        """m, root mean square of ``d`` over the recorded steps (0 before any)."""
        return self.batch.rms_cross_track_error(self.env)

    @property
    def max_cross_track_error(self) -> float:
        """m, largest ``|d|`` so far."""
        return float(self.batch.state.max_abs_d[self.env])

    @property
    def max_lateral_acceleration(self) -> float:
        """m/s^2, largest ``|a_lat|`` so far."""
        return float(self.batch.state.max_lat[self.env])

    def step_info(self) -> dict[str, Any]:
        """The driving metrics' step info plus the latest cross-track error and lateral
        acceleration; the same keys every call."""
        return self.batch.step_info(self.env)

    def summary(self) -> dict[str, Any]:
        """The driving metrics' summary plus (plain Python, JSON-ready):

        ``red_light_violations``; ``stop_line_crossings`` (crossings by the light's state:
        red, yellow, green, unknown); ``stops`` (each :class:`StopRecord` as a dict) and
        ``max_overshoot`` (m, 0 without a stop past a line); ``max_cross_track_error``,
        ``rms_cross_track_error`` (m); ``max_lateral_acceleration`` (m/s^2).
        """
        return self.batch.summary(self.env)
