"""The drive-by-wire stack's nodes as numba kernels: one implementation, single or batched.

The planning nodes of :mod:`sdc_gym.stack.track` (detector, behavior, waypoint updater,
node rates) compute here, on plain numbers and arrays; the control nodes (pure pursuit,
twist controller) in :mod:`sdc_gym.stack.track.control_kernels`, by the same rules. The node classes
(:class:`~sdc_gym.stack.track.controllers.TwistController`,
:class:`~sdc_gym.stack.track.follower.PurePursuit`, ...) are thin shells that call these
functions for one car; the batched stack (:mod:`sdc_gym.stack.track.stack_batch`) calls
them for every env of a batch inside one compiled loop. The node modules' docstrings
explain what each node does and why; the functions below follow the arithmetic of the
scalar code they replaced operation for operation (Python's ``min``/``max``, CPython's
``hypot`` and ``remainder``, ``x ** 2`` as the C library's ``pow`` with the exponent
passed at run time, numpy's ``minimum``/``maximum`` where arrays were used), so the stack
drives exactly as before, bit for bit.

State that a node keeps between calls lives in per-env arrays (NamedTuples of arrays
with a leading env axis); a function updates entry ``env`` in place.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import (
    np_maximum,
    np_minimum,
    py_max,
    py_min,
    py_mod,
)
from sdc_gym.kernel_compiler import kernel
from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

FEASIBILITY_SLACK_M = 1.0
"""Stopping stays "feasible" with this much slack over the exact braking distance (m)."""

# --- behavior decision labels (TrackBehaviorDecision.mode) by code ---------------------------
MODE_NAMES = ("", "go", "go_75", "go_50", "stop", "cruise", "stop_red", "stop_yellow",
              "go_yellow", "run_red")
MODE_NONE, MODE_GO = 0, 1
MODE_CRUISE, MODE_STOP_RED, MODE_STOP_YELLOW, MODE_GO_YELLOW, MODE_RUN_RED = 5, 6, 7, 8, 9
MODE_CODES = {name: code for code, name in enumerate(MODE_NAMES)}
STOP_ACTION = 3  # the discrete "stop" action; 0..2 go at SPEED_FRACTIONS
SPEED_FRACTIONS = np.array([1.0, 0.75, 0.5, 1.0])
DISTANCE_SCALE_M = 100.0
STATE_TIME_SCALE_S = 10.0


# ============================================================================ waypoint updater
class UpdaterConstants(NamedTuple):
    """The base waypoints and the updater's settings (``UpdaterParameters``)."""

    x: FloatArray
    y: FloatArray
    s: FloatArray
    speed: FloatArray
    length: float
    count: int  # final waypoints published
    search_behind: int
    search_ahead: int
    full_search_sq: float  # full_search_distance_m ** 2 (Python's)
    stop_line_offset: FloatArray  # (n,) m from a stop-line waypoint to its line (0: none)
    stop_margin: float
    ramp_decel2: float  # 2.0 * stop_decel_mps2
    min_ramp_speed: float
    watchdog: float


class UpdaterState(NamedTuple):
    """Per env: the previous closest waypoint and the count of full searches."""

    previous_index: IntArray
    full_searches: IntArray


def updater_state(envs: int) -> UpdaterState:
    return UpdaterState(np.full(envs, -1, dtype=np.int64), np.zeros(envs, dtype=np.int64))


@kernel
def closest_waypoint(uc: UpdaterConstants, x: float, y: float) -> int:
    """Index of the waypoint closest to (x, y) (a full search; first of equals)."""
    best, best_sq = 0, np.inf
    for k in range(uc.x.size):
        dx = uc.x[k] - x
        dy = uc.y[k] - y
        squared = dx * dx + dy * dy
        if squared < best_sq:
            best, best_sq = k, squared
    return best


@kernel
def next_waypoint(uc: UpdaterConstants, st: UpdaterState, env: int, x: float, y: float,
                  yaw: float) -> int:
    """Index of the next waypoint ahead of the pose: the closest in a window around the
    previous one (a full search when none is within reach), or its successor when it lies
    behind the car."""
    n = uc.x.size
    closest = -1
    previous = st.previous_index[env]
    if previous >= 0:
        best, best_sq = -1, np.inf
        for offset in range(-uc.search_behind, uc.search_ahead + 1):
            k = (previous + offset) % n
            dx = uc.x[k] - x
            dy = uc.y[k] - y
            squared = dx * dx + dy * dy
            if squared < best_sq:
                best, best_sq = k, squared
        if best_sq <= uc.full_search_sq:
            closest = best
    if closest < 0:
        closest = closest_waypoint(uc, x, y)
        st.full_searches[env] += 1
    st.previous_index[env] = closest
    ahead = (uc.x[closest] - x) * math.cos(yaw) + (uc.y[closest] - y) * math.sin(yaw)
    return closest if ahead > 0.0 else (closest + 1) % n


@kernel
def lower_for_stop(uc: UpdaterConstants, first: int, stop_waypoint: int,
                   speeds: FloatArray) -> None:
    """``speeds`` (of the waypoints from ``first`` on) lowered in place to stop
    ``stop_margin`` before the line at ``stop_waypoint``: zero from the stop point on, a
    square-root ramp before it."""
    n = uc.x.size
    length = uc.length
    s0 = uc.s[first]
    line_at = py_mod(py_mod(uc.s[stop_waypoint] - s0, length)
                     + uc.stop_line_offset[stop_waypoint], length)
    stop_at = line_at - uc.stop_margin
    for j in range(speeds.size):
        along = py_mod(uc.s[(first + j) % n] - s0, length)
        ramp = math.sqrt(uc.ramp_decel2 * np_maximum(stop_at - along, 0.0))
        if ramp < uc.min_ramp_speed:
            ramp = 0.0
        speeds[j] = np_minimum(speeds[j], ramp)


@kernel
def update_waypoints(uc: UpdaterConstants, st: UpdaterState, env: int, now: float, x: float,
                     y: float, yaw: float, pose_time: float, stop_waypoint: int,
                     watch_light: bool, light_time: float, has_cap: bool, speed_cap: float,
                     out_x: FloatArray, out_y: FloatArray, out_speed: FloatArray
                     ) -> tuple[int, bool]:
    """The final waypoints for the pose into ``out_*`` (``uc.count`` each): returns the
    first index and whether the watchdog zeroed the speeds."""
    n = uc.x.size
    first = next_waypoint(uc, st, env, x, y, yaw)
    cap = py_max(speed_cap, 0.0)
    for j in range(uc.count):
        k = (first + j) % n
        out_x[j] = uc.x[k]
        out_y[j] = uc.y[k]
        out_speed[j] = np_minimum(uc.speed[k], cap) if has_cap else uc.speed[k]
    if stop_waypoint >= 0:
        lower_for_stop(uc, first, stop_waypoint, out_speed)
    stale = now - pose_time > uc.watchdog or (watch_light and now - light_time > uc.watchdog)
    if stale:
        out_speed[:] = 0.0
    return first, stale


# ============================================================================ light detector
class DetectorConstants(NamedTuple):
    """The stop lines' waypoints and the detector's settings."""

    stop_waypoints: IntArray
    gate: float
    debounce: int


class DetectorState(NamedTuple):
    """Per env: the debouncing (line, candidate, count, published state) and the report
    (line, waypoint, state, distance, time)."""

    line: IntArray
    candidate: IntArray
    count: IntArray
    state: IntArray
    report_line: IntArray
    report_waypoint: IntArray
    report_state: IntArray
    report_distance: FloatArray
    report_time: FloatArray
    classifications: IntArray


def detector_state(envs: int) -> DetectorState:
    i = lambda: np.zeros(envs, dtype=np.int64)  # noqa: E731
    return DetectorState(i(), i(), i(), i(), i(), i(), i(), np.zeros(envs), np.zeros(envs), i())


@kernel
def detector_reset(st: DetectorState, env: int) -> None:
    st.line[env] = -1
    st.candidate[env] = UNKNOWN
    st.count[env] = 0
    st.state[env] = UNKNOWN
    st.report_line[env] = -1
    st.report_waypoint[env] = -1
    st.report_state[env] = UNKNOWN
    st.report_distance[env] = np.inf
    st.report_time[env] = -np.inf


@kernel
def in_gate(dc: DetectorConstants, stop_line: int, distance: float) -> bool:
    """Whether the detector looks at the light (a next line within the gate)."""
    return stop_line >= 0 and distance <= dc.gate


@kernel
def detect(dc: DetectorConstants, st: DetectorState, env: int, time_s: float, stop_line: int,
           distance: float, frame_state: int) -> None:
    """One frame: ``frame_state`` is the source's state (inside the gate) or UNKNOWN;
    debounce it and publish the report."""
    if stop_line != st.line[env]:
        st.line[env] = stop_line
        st.candidate[env] = UNKNOWN
        st.count[env] = 0
        st.state[env] = UNKNOWN
    if frame_state == st.candidate[env]:
        st.count[env] += 1
    else:
        st.candidate[env] = frame_state
        st.count[env] = 1
    if st.count[env] >= dc.debounce:
        st.state[env] = st.candidate[env]
    st.report_line[env] = stop_line
    st.report_waypoint[env] = dc.stop_waypoints[stop_line] if stop_line >= 0 else -1
    st.report_state[env] = st.state[env]
    st.report_distance[env] = distance
    st.report_time[env] = time_s


# ============================================================================ behavior
@kernel
def can_stop(speed: float, room: float, decel: float, two: float) -> bool:
    """Braking at ``decel`` stops before the line (with the slack): ``v^2 <= 2 a room``
    (``v ** two``: Python's float power, the C library's ``pow``)."""
    return math.pow(speed, two) <= 2.0 * decel * py_max(room + FEASIBILITY_SLACK_M, 0.0)


@kernel
def stop_at_red(max_decel: float, comfortable_decel: float, stop_on_yellow: bool,
                speed_margin: float, two: float, stopping_for: int, speed: float,
                speed_limit: float, line: int, waypoint: int, room: float, state: int
                ) -> tuple[float, int, int, int]:
    """The rule-based decision (``StopAtRedLights``): (target speed, stop waypoint, mode
    code, the line it is now committed to stop at)."""
    cruise = py_max(speed_limit - speed_margin, 0.0)
    if line < 0 or waypoint < 0 or (state != RED and state != YELLOW):
        return cruise, -1, MODE_CRUISE, -1  # green or unknown: not red, drive on
    committed = stopping_for == line
    if state == RED:
        if committed or can_stop(speed, room, max_decel, two):
            return cruise, waypoint, MODE_STOP_RED, line
        return cruise, -1, MODE_RUN_RED, stopping_for
    if committed or (stop_on_yellow and can_stop(speed, room, comfortable_decel, two)):
        return cruise, waypoint, MODE_STOP_YELLOW, line
    return cruise, -1, MODE_GO_YELLOW, stopping_for


@kernel
def action_decision(continuous: bool, index: int, speed_value: float, stop_value: float,
                    speed_limit: float, speed_margin: float, waypoint: int
                    ) -> tuple[float, int, int]:
    """The decision an RL action stands for: (target speed, stop waypoint, mode code).
    Discrete ``index`` (0..3); continuous ``(speed_value, stop_value)`` in [-1, 1]."""
    cruise = py_max(speed_limit - speed_margin, 0.0)
    if continuous:
        speed = 0.5 * (speed_value + 1.0) * cruise
        stop = stop_value > 0.0
        mode = 4 if stop else MODE_GO
    else:
        speed = SPEED_FRACTIONS[index] * cruise
        stop = index == STOP_ACTION
        mode = 1 + index
    stop_at = waypoint if stop else -1
    if stop and stop_at < 0:
        mode = MODE_GO  # nothing to stop at: the same as go
    return speed, stop_at, mode


@kernel
def state_time(key_line: int, key_state: int, since: float, line: int, state: int,
               time_s: float) -> tuple[int, int, float, float]:
    """How long the detector has reported this line's state: (key line, key state, since,
    seconds)."""
    if line != key_line or state != key_state:
        key_line, key_state, since = line, state, time_s
    return key_line, key_state, since, time_s - since


@kernel
def encode_features(max_decel: float, comfortable_decel: float, speed: float,
                    speed_limit: float, line: int, distance: float, room: float, state: int,
                    state_seconds: float, stopping: bool, out: NDArray[np.float32]) -> None:
    """The decision's observation (``TrackFeatures``) into ``out`` (12,) float32."""
    v = speed
    limit = py_max(speed_limit, 1e-6)
    has_line = line >= 0 and math.isfinite(distance)
    out[:] = 0.0
    out[0] = py_min(v / limit, 1.5)
    out[1] = py_min(distance / DISTANCE_SCALE_M, 1.0) if has_line else 1.0
    out[2] = py_min(py_max(room / DISTANCE_SCALE_M, -1.0), 1.0) if has_line else 1.0
    if state == RED:
        out[3] = 1.0
    elif state == YELLOW:
        out[4] = 1.0
    elif state == GREEN:
        out[5] = 1.0
    else:
        out[6] = 1.0
    out[7] = py_min(state_seconds / STATE_TIME_SCALE_S, 1.0)
    out[8] = py_min(v * v / (2.0 * comfortable_decel) / DISTANCE_SCALE_M, 1.0)
    slack_room = py_max(room + FEASIBILITY_SLACK_M, 0.0)
    out[9] = 1.0 if has_line and v * v <= 2.0 * max_decel * slack_room else 0.0
    out[10] = 1.0 if has_line and v * v <= 2.0 * comfortable_decel * slack_room else 0.0
    out[11] = 1.0 if stopping else 0.0


# ============================================================================ node rates
@kernel
def node_due(runs: int, ticks: int, tick: int) -> bool:
    """Whether a node running ``runs`` times every ``ticks`` loop ticks (a reduced
    fraction; 1/1: every tick) runs at ``tick``: at tick 0, and whenever
    ``floor(tick * runs / ticks)`` grew (exact integer arithmetic)."""
    return tick == 0 or (tick * runs) // ticks > ((tick - 1) * runs) // ticks
