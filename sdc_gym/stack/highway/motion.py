"""The motion layer of the seed planner: a queue of states extended by gated pursuit steering.

The seed (``seeds/004``, "Motion control (path management)") keeps a queue of about 50
planned states ``{x, y, s, heading, distance increment}``. Every planning cycle it drops the
states the simulator consumed, keeps the rest (only the first few when a replan is
flagged), and appends new states one 0.02 s step at a time:

1. steer toward the point ``look_ahead`` (12.5 m) ahead on the target lane's centre line:
   the steering change is the bearing to that point in the car's frame, gated to
   +-0.005 rad per step (+-0.00245 during a lane change); no steering when the behavior
   mutes it (Launch) or below 0.05 m per step;
2. heading += steering; next point = previous point + increment along the new heading;
3. the increment (the speed, metres per step) moves toward ``target_speed * 0.02`` by at
   most ``acceleration * 0.02**2`` per step and never exceeds 0.4455 m (49.83 mph).

The lane centre lines are the road's reference line offset by ``d = (lane + 0.5) * width``
(:meth:`ReferenceLine.to_xy`, the same geometry the env uses).

Where this implementation goes beyond the seed's prose, and why
---------------------------------------------------------------
* **Damping (no overshoot).** Steering at a point 12.5 m ahead with a rate-limited heading
  overshoots a lane change: pointing straight at the look-ahead point asks for a heading of
  about ``e / 12.5`` rad (e = lateral error, 4 m per lane), far more than the gate lets
  the car take back before it reaches the new lane (at 0.00245 rad per step a heading psi
  unwinds over ``v * psi**2 / (2 * 0.1225 rad/s)`` metres of error). Measured in the env
  at 49 mph with the narrow gate held to the centre: 0.11 m past the centre for one lane,
  1.85 m (off the road) for a double change. The seed calls its law "semi-PD" and tuned it
  empirically. Here the look-ahead distance is stretched while the error is large:
  ``L = max(12.5, sqrt(unwind_margin * |e| * increment / gate))``. The heading then asked
  for, ``e / L = sqrt(|e| * gate / (unwind_margin * increment))``, is one the gate can
  always unwind (with ``unwind_margin = 2``: at half the gate rate) before the error
  reaches zero, so the car settles on the lane centre without crossing it (2 to 3 mm);
  near the centre (|e| < ~0.4 m at 49 mph) it is the seed's 12.5 m pursuit unchanged. The
  term acts like a derivative term: it cuts the heading (the rate of change of e) in
  proportion to how fast the car would close on the lane.
* **Centring in bends.** Pure pursuit of a point on a circle of radius R settles on a
  smaller concentric circle, ``L**2 / (2 R)`` inside the lane (0.5 m for R = 156 m): the
  aimed point is therefore moved out by that sagitta (the lane's curvature times
  ``L**2 / 2``), which puts the steady-state circle on the lane centre.
* **The lane-change gate is centred on the lane's own turn** (``curvature * increment``
  per step) and stays within +-``steering_gate``: on a straight road this is the seed's
  +-0.00245 rad; in a bend it keeps the narrow gate from stopping the car from following
  the road (0.00245 rad per step is a 180 m radius at 49 mph).
* **Latency.** The seed trims ``len(queue) - previous_path_count`` states. Here the car is
  located exactly in the queue instead (its observed x, y is one of our points to float32
  rounding), which stays right however many frames a path spends in flight: with
  ``latency_frames`` larger than ``frames_per_cycle`` the echoed count belongs to an older
  path. The path sent starts at the car's next point; the env drops the points the car
  consumes while the path is in flight (its nearest-point rule). ``lead`` (the points
  consumed in flight, ``latency_frames``) matters for a replan: the queue keeps
  ``lead + replan_keep`` points so that the new plan joins the path the car is actually
  on. :meth:`MotionParameters.for_env` reads the env's timing. If the car is ever found
  off the queue (the env moved it) the planner starts afresh from the observed pose.
* **Steering resumes on the queued states.** States planned while the behavior muted
  the steering (the seed's Launch) run straight for a path's length after the launch
  ends (about 20 m at 40 mph): where the road bends there, as 25 m after the original
  map's start, the car would drift across the lane line. When steering comes back, the
  queue beyond ``lead + replan_keep`` points is planned again with the same increments
  (the speed profile, and so the acceleration, unchanged) and steering on.
* Each state also carries its Frenet ``d`` (exact, like ``s``, from one projection per
  batch of new points), so the lane error and the lane-change flag are exact.

Cost: a cycle that adds 3 points (one env step) takes ~25 microseconds (was ~40): per
batch of up to ``batch_points`` new states one evaluation of the reference line's spline
(:meth:`SeedMotionPlanner._geometry`, the numbers of
:meth:`ReferenceLine.to_xy_and_curvature` bit for bit, on Python complex numbers plus one
small numpy batch) gives the look-ahead points and the line at the states' predicted s
(from which one Newton step gives their exact s, d); everything per point runs on Python
floats. The queue is a window of a preallocated array (no concatenation per cycle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.stack.highway.behavior import STEP, BehaviorDecision

# Columns of the queue: one row per planned state.
_X, _Y, _S, _D, _HEADING, _INCREMENT = range(6)
_COLUMNS = 6
# A queued point and the car's observed (float32) position agree to ~2e-4 m; distinct
# points are at least the start increment (0.009 m) apart.
_MATCH_TOLERANCE_M = 2e-3
# Rows of the queue's buffer: the queue is a window of it that new states extend at the
# back and the car's progress trims at the front (moved back to the start when full).
_BUFFER_ROWS = 1024


@dataclass(frozen=True)
class MotionParameters:
    """Every constant of the seed's motion controller, plus this implementation's own.

    Increments are metres per 0.02 s step (speed = increment / 0.02 s), angles radians.
    """

    path_length: int = 50                   # points sent each cycle (the seed: 40-50); the
                                            # queue holds `lead` more (see module doc)
    replan_keep: int = 4                    # points of the sent path kept on a replan
    look_ahead: float = 12.5                # m along the target lane
    steering_gate: float = 0.005            # rad per step
    steering_gate_lane_change: float = 0.00245  # rad per step while changing lanes
    min_steering_increment: float = 0.05    # m per step: no steering below (2.5 m/s)
    start_increment: float = 0.009          # m per step: first increment from rest
    max_increment: float = 0.4455           # m per step (49.83 mph); 0.44704 = 50 mph
    arrival_jerk: float = 4.0               # m/s^3: easing of the acceleration into a goal
    lane_change_tolerance: float = 0.5      # m: |d - target lane centre| ending a change
    unwind_margin: float = 2.0              # look-ahead stretch factor (see module doc)
    frames_per_cycle: int = 3               # env frames per planning cycle (steps_per_action)
    latency_frames: int = 3                 # frames before a sent path takes effect
    batch_points: int = 5                   # new points per geometry call

    def __post_init__(self) -> None:
        if self.path_length < 2 or self.replan_keep < 1 or self.batch_points < 1:
            raise ValueError("path_length >= 2, replan_keep >= 1, batch_points >= 1")
        if self.frames_per_cycle < 1 or self.latency_frames < 0:
            raise ValueError("frames_per_cycle >= 1 and latency_frames >= 0")
        if not 0.0 < self.steering_gate_lane_change <= self.steering_gate:
            raise ValueError("0 < steering_gate_lane_change <= steering_gate")
        if not (self.look_ahead > 0.0 and self.max_increment > 0.0
                and self.unwind_margin > 0.0):
            raise ValueError("look_ahead, max_increment and unwind_margin must be > 0")

    @classmethod
    def for_env(cls, env: Any, **changes: Any) -> MotionParameters:
        """Parameters matching a ``HighwayLoop-v0`` env's timing and path capacity."""
        unwrapped = env.unwrapped
        values: dict[str, Any] = {
            "frames_per_cycle": int(unwrapped.steps_per_action),
            "latency_frames": int(unwrapped.latency_steps),
            "path_length": min(cls.path_length, int(unwrapped.path_points)),
        }
        values.update(changes)
        return replace(cls(), **values)


@dataclass(frozen=True)
class MotionState:
    """One planned state (the end of the queue is what behavior plans from).

    ``speed`` is the increment that led to the point divided by 0.02 s (m/s).
    """

    x: float
    y: float
    s: float
    d: float
    heading: float
    speed: float


class SeedMotionPlanner:
    """Turns behavior decisions into paths for ``HighwayLoop-v0``; see the module docstring.

    Call :meth:`reset` at the start of every episode and :meth:`plan` once per env step.
    """

    def __init__(self, road: HighwayMap, params: MotionParameters | None = None) -> None:
        self.road = road
        self.reference = road.reference
        self.params = params or MotionParameters()
        self.reset()

    # ------------------------------------------------------------------ public API
    def reset(self) -> None:
        """Forget the queue (start of an episode)."""
        self._buffer: NDArray[np.float64] = np.zeros((_BUFFER_ROWS, _COLUMNS))
        self._start = self._stop = 0  # the queue is self._buffer[self._start:self._stop]
        self._end: list[float] | None = None  # the queue's last row (None when empty)
        self._last_row: list[float] | None = None  # the car's state when the queue empties
        self._cycles = 0             # paths sent since reset
        self._consumed = 0           # points the car consumed since the previous cycle
        self._lead = 0               # queue points the car consumes before the path arrives
        self._ds_ratio = 1.0         # metres of s per metre driven, from the last batch
        self._curvature_target = 0.0  # reference curvature at the last look-ahead point
        self._anchor = [math.nan, math.nan]  # the point before the queue's first one
        self._target_d = math.nan
        self._lane_changing = False
        self._queued_muted = False   # the queue's newest states were planned unsteered

    def plan(self, observation: dict[str, Any], decision: BehaviorDecision) -> NDArray[np.float64]:
        """The path to send this cycle, shape ``(m, 2)``, ``m <= path_length``.

        Args:
            observation: the env's observation (only ``ego`` is used: the car's x, y locate
                it in the queue; see the module docstring on ``previous_path_count``).
            decision: what to do: target lane and speed, rate, replan, steering.
        """
        p = self.params
        ego = observation["ego"]
        self._locate_car(ego)
        if self._end is None and self._last_row is None:
            x, y, s, d, yaw, speed = (float(v) for v in ego)
            self._last_row = [x, y, s, d, yaw, speed * STEP]
            self._anchor = [x, y]
        # The car consumes `lead` more queued points from the paths already sent before
        # this one arrives; none while it is still waiting for its first path.
        self._lead = min(p.latency_frames, self._cycles * p.frames_per_cycle)
        replay: list[float] = []  # increments of unsteered states to plan again, steered
        if decision.replan:
            self._truncate(self._lead + p.replan_keep)
        elif decision.steering and self._queued_muted:
            keep = self._start + self._lead + p.replan_keep
            replay = self._buffer[keep:self._stop, _INCREMENT].tolist()
            self._truncate(self._lead + p.replan_keep)
        self._queued_muted = not decision.steering
        lane = min(max(int(decision.target_lane), 0), self.road.lane_count - 1)
        self._target_d = (lane + 0.5) * self.road.lane_width
        missing = p.path_length - (self._stop - self._start)
        if missing > 0:
            self._extend(missing, decision, replay)  # (may move the queue in its buffer)
        self._cycles += 1
        end = self._end_row()
        self._lane_changing = abs(end[_D] - self._target_d) > p.lane_change_tolerance
        start = self._start
        return self._buffer[start:min(start + p.path_length, self._stop), :2].copy()

    @property
    def end_state(self) -> MotionState:
        """The last planned state (where the next new point will continue from)."""
        x, y, s, d, heading, increment = self._end_row()
        return MotionState(x, y, s, d, math.remainder(heading, math.tau), increment / STEP)

    @property
    def speed(self) -> float:
        """m/s at the end of the queue (0 before the first :meth:`plan`)."""
        if self._end is None and self._last_row is None:
            return 0.0
        return self._end_row()[_INCREMENT] / STEP

    @property
    def heading(self) -> float:
        """Heading at the end of the queue, rad in (-pi, pi]."""
        return math.remainder(self._end_row()[_HEADING], math.tau)

    @property
    def lane_change_in_progress(self) -> bool:
        """True while the queue's end is more than ``lane_change_tolerance`` from the
        target lane's centre (as of the last :meth:`plan`)."""
        return self._lane_changing

    @property
    def consumed(self) -> int:
        """Points the car consumed between the previous cycle and this one (0.02 s each)."""
        return self._consumed

    @property
    def lead(self) -> int:
        """Queued points the car consumes while the last path sent is in flight."""
        return self._lead

    @property
    def queue(self) -> NDArray[np.float64]:
        """A copy of the queue: rows x, y, s, d, heading, increment (the car's next point
        first)."""
        return self._buffer[self._start:self._stop].copy()

    # ------------------------------------------------------------------ queue
    def _end_row(self) -> list[float]:
        """The last queued state (not to be modified), else the car's when it is empty."""
        if self._end is not None:
            return self._end
        if self._last_row is None:
            raise RuntimeError("no state yet: call plan() first")
        return list(self._last_row)

    def _truncate(self, keep: int) -> None:
        if self._stop - self._start > keep:
            self._stop = self._start + keep
            self._end = self._buffer[self._stop - 1].tolist() if keep > 0 else None

    def _append(self, rows: list[tuple[float, ...]]) -> None:
        """Add states at the back of the queue."""
        count = len(rows)
        start, stop = self._start, self._stop
        if stop + count > len(self._buffer):
            # Move the queue back to the buffer's start (a larger buffer if need be).
            size = stop - start
            if size + count > len(self._buffer):
                buffer = np.zeros((max(2 * len(self._buffer), size + count), _COLUMNS))
            else:
                buffer = self._buffer
            buffer[:size] = self._buffer[start:stop]  # numpy copes with the overlap
            self._buffer, self._start, start, stop = buffer, 0, 0, size
        self._buffer[stop:stop + count] = rows
        self._stop = stop + count
        self._end = list(rows[-1])

    def _locate_car(self, ego: NDArray[np.float32]) -> None:
        """Drop the queued points the car has consumed: it stands on one of them, or still
        on the point before the queue (the anchor) when it has not moved."""
        start, stop = self._start, self._stop
        self._consumed = 0
        if start == stop:
            return
        cx, cy = float(ego[0]), float(ego[1])
        # Search the points the car can have reached since the last cycle, the likeliest
        # first: one cycle's frames. (Points that coincide, a car at rest, match there
        # too, which keeps the count in step with the env's.)
        reach = min(stop - start, self._lead + 2 * self.params.frames_per_cycle + 2)
        expected = min(self.params.frames_per_cycle, reach) - 1
        tolerance2 = _MATCH_TOLERANCE_M**2
        px, py = self._buffer[start + expected, :2].tolist()
        if (px - cx) ** 2 + (py - cy) ** 2 <= tolerance2:
            self._consumed = expected + 1
        else:
            points = self._buffer[start:start + reach, :2].tolist()
            for index, (px, py) in enumerate(points):
                if (px - cx) ** 2 + (py - cy) ** 2 <= tolerance2:
                    self._consumed = index + 1
                    break
        if not self._consumed:
            if (self._anchor[0] - cx) ** 2 + (self._anchor[1] - cy) ** 2 > tolerance2:
                # Lost (the env moved the car off our points): plan afresh from the car.
                self._restart()
            return  # else not moved (e.g. waiting for the first path to arrive)
        if self._consumed >= stop - start:
            # The path ran out under the car: continue from the car as observed.
            self._restart()
            return
        self._anchor = [px, py]  # the point the car stands on
        self._start = start + self._consumed

    def _restart(self) -> None:
        self._start = self._stop = 0
        self._end = None
        self._last_row = None
        self._cycles = 0

    # ------------------------------------------------------------------ planning
    def _geometry(self, s_pred: list[float], distance: float, aim_d: float,
                  ) -> tuple[list[tuple[float, ...]], list[complex], float]:
        """The reference line at the predicted s, and the aim points ``distance`` further.

        Returns, per predicted s, the line's ``(x, y, nx, ny, curvature)`` (n the unit
        normal to the right); the aim points (x + iy) at d = ``aim_d``; the reference
        curvature at the last aim point. One :meth:`ReferenceLine.line_frames_few` call:
        a handful of points per batch, where plain Python beats numpy's per-call cost.
        """
        k = len(s_pred)
        frames = self.reference.line_frames_few(s_pred + [sp + distance for sp in s_pred])
        aims = [complex(x + aim_d * nx, y + aim_d * ny) for x, y, nx, ny, _ in frames[k:]]
        return frames[:k], aims, frames[-1][4]

    def _extend(self, count: int, decision: BehaviorDecision,
                replay: list[float] | None = None) -> None:
        """Append ``count`` states to the queue (the seed's steps 2 to 6); the first ones
        take their increments from ``replay`` (states planned again) instead of the
        decision's speed.

        Per batch of up to ``batch_points`` new states, one geometry evaluation gives
        the aim points and the reference line (point, normal, curvature) at each new
        state's predicted s; the states themselves are stepped on Python floats and then
        projected onto the line by one Newton step from the prediction (exact to ~1e-9 m:
        the prediction is off by millimetres).
        """
        p = self.params
        length = self.road.length
        x, y, s, d, heading, increment = self._end_row()
        target_d = self._target_d
        goal = min(max(decision.target_speed * STEP, 0.0), p.max_increment)
        change = max(decision.acceleration, 0.0) * STEP * STEP
        # sqrt(2 J dv) in m/s^2 as a change of increment per step, dv = gap / STEP.
        arrival = math.sqrt(2.0 * p.arrival_jerk / STEP) * STEP * STEP
        steering = decision.steering
        min_increment = p.min_steering_increment
        look_ahead, margin = p.look_ahead, p.unwind_margin
        cos, sin, atan2, sqrt = math.cos, math.sin, math.atan2, math.sqrt
        rows: list[tuple[float, ...]] = []
        start_increment, max_increment = p.start_increment, p.max_increment
        # cos, sin of the heading: worked out again only when the heading changes.
        c, sn = cos(heading), sin(heading)
        while count > 0:
            k = count if count < p.batch_points else p.batch_points
            count -= k
            # Speeds first: they do not depend on the steering. (Below, `b if b < a
            # else a` is min(a, b) and `b if b > a else a` max(a, b), without the calls.)
            increments = []
            for _ in range(k):
                if replay:
                    increment = replay.pop(0)
                    increments.append(increment)
                    continue
                # Arrive at the goal speed with the acceleration easing to zero at a
                # bounded jerk, a <= sqrt(2 J |dv|): an abrupt end of the seed's rate
                # shows as jerk in the original's 1 s windows. The seed's rate applies
                # until dv <= rate^2 / (2 J) (12 m/s for the launch, 3 m/s normally).
                gap = goal - increment
                step_change = arrival * sqrt(abs(gap))
                if not step_change < change:
                    step_change = change
                if gap > 0.0:
                    increment += step_change
                    if goal < increment:
                        increment = goal
                    if increment < start_increment:
                        increment = goal if goal < start_increment else start_increment
                else:
                    increment -= step_change
                    if goal > increment:
                        increment = goal
                increments.append(max_increment if max_increment < increment else increment)
            # Lane error, gate and stretched look-ahead for this batch.
            error = d - target_d
            changing = abs(error) > p.lane_change_tolerance
            gate = p.steering_gate_lane_change if changing else p.steering_gate
            speed_step = max(increments[-1], min_increment)
            distance = max(look_ahead, sqrt(margin * abs(error) * speed_step / gate))
            # Aim point on the target lane, moved out by the pursuit's sagitta in bends.
            lane_curvature = self._curvature_target / (1.0 + self._curvature_target * target_d)
            aim_d = target_d + 0.5 * lane_curvature * distance * distance
            s_pred = []
            s_start = s
            travelled = 0.0
            ratio = self._ds_ratio
            for step in increments:
                travelled += step
                s_pred.append(s + ratio * travelled)
            # The line at each predicted s (its point, unit normal and curvature), then
            # the aim points: one geometry evaluation.
            frames, aims, self._curvature_target = self._geometry(s_pred, distance, aim_d)
            if changing:
                # The narrow gate, centred on the lane's own turn, inside the normal gate.
                car_curvature = frames[0][4]
                turn = car_curvature / (1.0 + car_curvature * d) * speed_step
                low = max(turn - gate, -p.steering_gate)
                high = min(turn + gate, p.steering_gate)
            else:
                low, high = -gate, gate
            for i, step in enumerate(increments):
                if steering and step >= min_increment:
                    aim = aims[i]
                    dx, dy = aim.real - x, aim.imag - y
                    bearing = atan2(dy * c - dx * sn, dx * c + dy * sn)
                    if low > bearing:
                        bearing = low
                    heading += high if high < bearing else bearing
                    c, sn = cos(heading), sin(heading)
                x += step * c
                y += step * sn
                # Frenet s, d: one Newton step from the predicted s (normal n = (nx, ny),
                # tangent (-ny, nx); an offset d to the right runs 1 + curvature * d
                # times faster than s).
                rx, ry, nx, ny, bend = frames[i]
                ox, oy = x - rx, y - ry
                d = ox * nx + oy * ny
                s = s_pred[i] + (oy * nx - ox * ny) / (1.0 + bend * d)
                rows.append((x, y, s % length, d, heading, step))
            if travelled > 1e-6:
                self._ds_ratio = min(max((s - s_start) / travelled, 0.5), 2.0)
            s %= length
        self._append(rows)
