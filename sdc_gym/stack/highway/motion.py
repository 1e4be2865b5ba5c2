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
  An episode that starts with the car moving (a scenario or a replay: the car is on a
  path of the env's) plans its first states from where the car will be when the first
  plan arrives, ``latency_frames`` increments along its heading.
* **Steering resumes on the queued states.** States planned while the behavior muted
  the steering (the seed's Launch) run straight for a path's length after the launch
  ends (about 20 m at 40 mph): where the road bends there, as 25 m after the original
  map's start, the car would drift across the lane line. When steering comes back, the
  queue beyond ``lead + replan_keep`` points is planned again with the same increments
  (the speed profile, and so the acceleration, unchanged) and steering on.
* Each state also carries its Frenet ``d`` (exact, like ``s``, from one projection per
  batch of new points), so the lane error and the lane-change flag are exact.

Implementation: :class:`MotionBatch` holds the states of a batch of planners as arrays
and plans all of them in one numba-compiled call
(:func:`~sdc_gym.stack.highway.motion_kernel.plan_batch`: per batch of up to
``batch_points`` new states, the reference line at their predicted s and at the
look-ahead points, then one Newton step per state for its exact s, d); the arithmetic is
the per-point arithmetic on floats the layer was defined with, bit for bit.
:class:`SeedMotionPlanner` is the planner of one env (a batch of one). The queue is a
window of a preallocated array (no concatenation per cycle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.kernel_threads import SERIAL, KernelThreads
from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.stack.highway.behavior import STEP, BehaviorDecision
from sdc_gym.stack.highway.motion_kernel import line_frame, plan_batch

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
        """Parameters matching a ``HighwayLoop-v0`` env's (or its world's) timing and path
        capacity: the queue (``path_length``) is the env's ``path_points``, 50 by default
        (the seed's queue of about 50), so a config's ``path_points`` sets the planner's
        queue length (``benchmarks/study_fsm_latency.py``)."""
        unwrapped = getattr(env, "unwrapped", env)
        values: dict[str, Any] = {
            "frames_per_cycle": int(unwrapped.steps_per_action),
            "latency_frames": int(unwrapped.latency_steps),
            "path_length": int(unwrapped.path_points),
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


class MotionBatch:
    """The motion layer of ``envs`` planners, their states as arrays (see the module
    docstring); :func:`~sdc_gym.stack.highway.motion_kernel.plan_batch` plans every env
    of a cycle in one compiled call (on ``kernel_threads``' threads:
    :mod:`sdc_gym.kernel_threads`)."""

    def __init__(self, road: HighwayMap, params: MotionParameters | None = None,
                 envs: int = 1, kernel_threads: KernelThreads = SERIAL) -> None:
        self.road = road
        self.kernel_threads = kernel_threads
        self.reference = road.reference
        self.params = p = params or MotionParameters()
        self.envs = envs
        reference = road.reference
        self._kernel_params = np.array([
            p.path_length, p.replan_keep, p.look_ahead, p.steering_gate,
            p.steering_gate_lane_change, p.min_steering_increment, p.start_increment,
            p.max_increment, math.sqrt(2.0 * p.arrival_jerk / STEP) * STEP * STEP,
            p.lane_change_tolerance, p.unwind_margin, p.frames_per_cycle, p.latency_frames,
            p.batch_points, _MATCH_TOLERANCE_M**2, STEP, road.lane_count, road.lane_width],
            dtype=np.float64)
        self._coef = reference._coef_xy
        self._line = np.array([reference._knot_step, reference._inverse_step,
                               reference._segments, reference._param_scale,
                               reference.length])
        # Room for the longest queue (a path, the points in flight, a cycle's consumption)
        # twice over: the kernel moves a queue back to the start when it reaches the end.
        rows = max(_BUFFER_ROWS, 2 * (p.path_length + p.latency_frames
                                      + 2 * p.frames_per_cycle + p.batch_points + 8))
        self.buffer = np.zeros((envs, rows, _COLUMNS))
        self.start = np.zeros(envs, dtype=np.int64)  # queue: buffer[start:stop]
        self.stop = np.zeros(envs, dtype=np.int64)
        self.end_row = np.zeros((envs, _COLUMNS))  # the queue's last row ...
        self.has_end = np.zeros(envs, dtype=bool)  # ... if it has one
        self.last_row = np.zeros((envs, _COLUMNS))  # the car's state when the queue emptied
        self.has_last = np.zeros(envs, dtype=bool)
        self.counters = np.zeros((envs, 3), dtype=np.int64)  # cycles, consumed, lead
        # ds_ratio, curvature_target, anchor x, anchor y, target_d
        self.floats = np.zeros((envs, 5))
        self.flags = np.zeros((envs, 2), dtype=bool)  # lane_changing, queued_muted
        self.paths = np.zeros((envs, p.path_length, 2))
        self.lengths = np.zeros(envs, dtype=np.int64)
        self._all = np.ones(envs, dtype=bool)
        self._lane_centres = np.full(envs, math.nan)  # target_d: each target lane's centre
        for env in range(envs):
            self.reset_at(env)

    def reset_at(self, env: int) -> None:
        """Forget env ``env``'s queue (start of an episode)."""
        self.start[env] = self.stop[env] = 0
        self.has_end[env] = self.has_last[env] = False
        self.counters[env] = 0
        self.floats[env] = (1.0, 0.0, math.nan, math.nan, math.nan)
        self.flags[env] = False

    def plan(self, ego: NDArray[np.float64], target_lane: NDArray, target_speed: NDArray,
             acceleration: NDArray, replan: NDArray[np.bool_], steering: NDArray[np.bool_],
             active: NDArray[np.bool_] | None = None,
             target_d: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64],
                                                                   NDArray[np.int64]]:
        """One cycle of every (``active``) env: ``ego`` ``(envs, 6)`` as observed (x, y,
        s, d, yaw, speed; the observation's float32 values), the decisions as arrays
        (``target_d``: where to aim across the road, NaN or ``None`` for the target lane's
        centre). Returns the paths ``(envs, path_length, 2)`` (the first ``lengths``
        points)."""
        if target_d is None:
            target_d = self._lane_centres
        self.kernel_threads.pick(plan_batch)(
            self._kernel_params, self._coef, self._line, self.buffer, self.start,
            self.stop, self.end_row, self.has_end, self.last_row, self.has_last,
            self.counters, self.floats, self.flags,
            np.ascontiguousarray(ego, dtype=np.float64),
            np.asarray(target_lane, dtype=np.int64),
            np.asarray(target_speed, dtype=np.float64),
            np.asarray(acceleration, dtype=np.float64), np.asarray(replan, dtype=bool),
            np.asarray(steering, dtype=bool), self._all if active is None else active,
            np.asarray(target_d, dtype=np.float64), self.paths, self.lengths, 2.0, 3.0)
        return self.paths, self.lengths

    def end_of(self, env: int) -> NDArray[np.float64]:
        if self.has_end[env]:
            return self.end_row[env]
        if self.has_last[env]:
            return self.last_row[env]
        raise RuntimeError("no state yet: call plan() first")


class SeedMotionPlanner:
    """Turns behavior decisions into paths for ``HighwayLoop-v0``; see the module docstring.

    Call :meth:`reset` at the start of every episode and :meth:`plan` once per env step.
    The planner of one env: a :class:`MotionBatch` of one (or env ``env`` of a batch).
    """

    def __init__(self, road: HighwayMap, params: MotionParameters | None = None) -> None:
        self._attach(MotionBatch(road, params, 1), 0)

    @classmethod
    def view(cls, batch: MotionBatch, env: int) -> SeedMotionPlanner:
        made = object.__new__(cls)
        made._attach(batch, env)
        return made

    def _attach(self, batch: MotionBatch, env: int) -> None:
        self.batch = batch
        self.env = env
        self.road = batch.road
        self.reference = batch.reference
        self.params = batch.params

    # ------------------------------------------------------------------ public API
    def reset(self) -> None:
        """Forget the queue (start of an episode)."""
        self.batch.reset_at(self.env)

    def plan(self, observation: dict[str, Any], decision: BehaviorDecision) -> NDArray[np.float64]:
        """The path to send this cycle, shape ``(m, 2)``, ``m <= path_length``.

        Args:
            observation: the env's observation (only ``ego`` is used: the car's x, y locate
                it in the queue; see the module docstring on ``previous_path_count``).
            decision: what to do: target lane and speed, rate, replan, steering.
        """
        batch = self.batch
        if batch.envs != 1:
            raise RuntimeError("plan() of one env of a batch: plan the batch")
        ego = np.asarray(observation["ego"]).astype(np.float64).reshape(1, 6)
        aim = math.nan if decision.target_d is None else decision.target_d
        paths, lengths = batch.plan(ego, (decision.target_lane,), (decision.target_speed,),
                                    (decision.acceleration,), (decision.replan,),
                                    (decision.steering,), target_d=(aim,))
        return paths[0, :int(lengths[0])].copy()

    def _end_row(self) -> list[float]:
        return self.batch.end_of(self.env).tolist()

    def _geometry(self, s_pred: list[float], distance: float, aim_d: float,
                  ) -> tuple[list[tuple[float, ...]], list[complex], float]:
        """The kernel's road geometry for a batch of predicted s: the line's ``(x, y, nx,
        ny, curvature)`` at each, the aim points ``distance`` further at ``aim_d``, and the
        curvature at the last aim point (for tests of the kernel's arithmetic)."""
        batch = self.batch
        frame = [line_frame(batch._coef, *batch._line[:2], int(batch._line[2]),
                            *batch._line[3:], s, 3.0)
                 for s in [*s_pred, *(sp + distance for sp in s_pred)]]
        k = len(s_pred)
        aims = [complex(x + aim_d * nx, y + aim_d * ny) for x, y, nx, ny, _ in frame[k:]]
        return frame[:k], aims, frame[-1][4]

    @property
    def end_state(self) -> MotionState:
        """The last planned state (where the next new point will continue from)."""
        x, y, s, d, heading, increment = self._end_row()
        return MotionState(x, y, s, d, math.remainder(heading, math.tau), increment / STEP)

    @property
    def speed(self) -> float:
        """m/s at the end of the queue (0 before the first :meth:`plan`)."""
        env = self.env
        if not self.batch.has_end[env] and not self.batch.has_last[env]:
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
        return bool(self.batch.flags[self.env, 0])

    @property
    def consumed(self) -> int:
        """Points the car consumed between the previous cycle and this one (0.02 s each)."""
        return int(self.batch.counters[self.env, 1])

    @property
    def lead(self) -> int:
        """Queued points the car consumes while the last path sent is in flight."""
        return int(self.batch.counters[self.env, 2])

    @property
    def queue(self) -> NDArray[np.float64]:
        """A copy of the queue: rows x, y, s, d, heading, increment (the car's next point
        first)."""
        env = self.env
        return self.batch.buffer[env, self.batch.start[env]:self.batch.stop[env]].copy()
