"""The track loop's physics frames for a batch of envs, as one numba kernel.

One env step of ``sdc_gym/TrackLoop-v0`` is ``steps_per_action`` physics frames of: the
manual-override schedule, the car (:func:`~sdc_gym.vehicle.dbw_kernel.step_vehicle`), the
lights (:func:`~sdc_gym.lights.light_kernel.step_lights`), the projection onto the path
(:func:`~sdc_gym.geometry.projection_kernel.project_point`), the stop-line metrics
(:func:`~sdc_gym.metrics.track_metrics_batch.stop_line_frame`) and the end tests
(obstacle contact, off-road); then the step's reward from progress, the laps and the
episode's end. :func:`run_steps` runs that for every env of a batch, each env as many
steps as asked; the behavior world's kernel
(:mod:`sdc_gym.envs.track_behavior_kernel`) runs the same frames with the drive-by-wire
stack in the loop. The single env is the batch of one.

Three things a kernel does not do are left to Python, which the kernel hands them to by
*pausing* an env at that point (``stage``) and resuming it where it stopped:

* a frame the human drives (manual override): the built-in driver
  (:class:`~sdc_gym.vehicle.manual_driver.ManualDriver`, with its own random stream) gives
  the commands (:data:`NEED_MANUAL`);
* a projection whose Newton iteration ended more than 25 m away (the car is not where the
  guess said): the global search over the path (:data:`NEED_PROJECTION`);
* the body near an obstacle: the exact box test (:data:`NEED_CONTACT`).

Everything else, and so nearly every frame, stays compiled. Each frame's samples go to
:class:`FrameBuffers` for the driving metrics, which take the call's frames in one chunk.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.geometry.projection_kernel import LineGeometry, project_point
from sdc_gym.kernel_compiler import kernel
from sdc_gym.lights.light_kernel import LightSchedule, step_lights
from sdc_gym.metrics.track_metrics_batch import (
    StopLineEvents,
    StopLines,
    StopLineState,
    stop_line_frame,
)
from sdc_gym.road.stop_line_kernel import next_stop_line
from sdc_gym.vehicle.dbw_kernel import (
    LATERAL_ACCELERATION,
    SPEED,
    STATE_SIZE,
    YAW,
    X,
    Y,
    step_vehicle,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

# --- where an env stands within its step (TrackState.stage) ---------------------------------
RUN = 0  # about to start a frame
NEED_MANUAL = 1  # paused: the human drives this frame, Python gives the commands (forced)
HAVE_MANUAL = 2  # resume: drive the frame with the forced commands
NEED_PROJECTION = 3  # paused: the projection is lost, Python projects globally (fix_s, fix_d)
HAVE_PROJECTION = 4  # resume with the fixed projection
NEED_CONTACT = 5  # paused: the body is near an obstacle, Python runs the exact test
HAVE_CONTACT = 6  # resume with contact (the obstacle's index or -1)

# --- why an episode ended (TrackState.reason), the env's termination_reason ---------------
REASONS = ("", "collision", "off_road", "laps_completed", "max_duration")
NO_END, COLLISION, OFF_ROAD, LAPS_COMPLETED, MAX_DURATION = range(5)

LOCAL_SEARCH_TRUST_M = 25.0
"""A projection that lands further than this from the point, or moves s by more than this,
is redone globally (:meth:`ReferenceLine.project`'s rule)."""
# The kernel pauses for Python's exact obstacle test when the body's centre is within the
# reach plus this relative margin: never later than Python's own broad phase would.
_REACH_MARGIN = 1e-9


class TrackConstants(NamedTuple):
    """What every env of a world shares (see :class:`~sdc_gym.envs.track_setup.TrackSetup`)."""

    vehicle: FloatArray  # dbw_kernel.vehicle_constants
    gains: FloatArray  # the actuator lags' gains for one frame
    line: LineGeometry
    stop_s: FloatArray  # stop lines sorted by s (the observation's next line)
    stop_index: IntArray
    lines: StopLines  # the stop-line metrics
    lights: LightSchedule
    dt: float
    frames_per_step: int
    half_width: float
    centre_offset: float
    reach_sq: float  # broad phase of the obstacle test (slightly widened)
    progress_scale: float
    laps: int
    max_frames: int
    length: float


class TrackState(NamedTuple):
    """Every env's state (arrays over the env axis)."""

    vehicle: FloatArray  # (envs, STATE_SIZE): dbw_kernel's columns
    s: FloatArray
    d: FloatArray
    frame: IntArray  # physics frames since reset
    dbw_enabled: BoolArray
    take_over: BoolArray  # the human takes the wheel: Python resets the driver first
    manual_periods: IntArray  # (envs, periods, 2) [start, end) frames
    manual_count: IntArray
    manual_index: IntArray
    manual_frames_total: IntArray
    step_manual_frames: IntArray
    obstacles: FloatArray  # (envs, obstacles, 2) centres
    light_offsets: FloatArray  # (envs, lights)
    light_clock: FloatArray
    light_next_change: FloatArray
    light_states: NDArray[np.int8]  # (envs, lights)
    next_line: IntArray  # the observation's next stop line (from the rear axle)
    line_distance: FloatArray
    laps: IntArray  # laps as the driving metrics count them after each step
    lap_mark: FloatArray
    contact: IntArray  # the obstacle touched at the step's last frame, or -1
    command: FloatArray  # (envs, 3): the agent's commands for the step
    forced: FloatArray  # (envs, 3): the human's commands for a paused frame
    stage: IntArray
    in_step: BoolArray
    frame_in_step: IntArray
    frame_manual: BoolArray  # the human drives the current frame
    s_start: FloatArray
    progress_before: FloatArray
    guess: FloatArray  # the current frame's projection guess (for Python's global search)
    fix_s: FloatArray
    fix_d: FloatArray
    terminated: BoolArray  # of the last step
    truncated: BoolArray
    reason: IntArray
    metrics: StopLineState


class FrameBuffers(NamedTuple):
    """One call's physics frames per env, for the driving metrics."""

    xy: FloatArray  # (envs, frames, 2)
    s: FloatArray  # (envs, frames)
    d: FloatArray
    speed: FloatArray
    progress: FloatArray
    manual: BoolArray
    count: IntArray  # (envs,) frames filled


class StepOutputs(NamedTuple):
    """One call's env steps per env: the progress part of each step's reward and where
    its frames are."""

    reward: FloatArray  # (envs, steps)
    first_frame: IntArray  # physics frame count before the step
    frames: IntArray  # frames the step ran
    buffer_start: IntArray  # its first frame's index in the FrameBuffers
    manual_frames: IntArray  # of those, frames the human drove
    steps: IntArray  # (envs,) steps done


def frame_buffers(envs: int, frames: int) -> FrameBuffers:
    return FrameBuffers(np.zeros((envs, frames, 2)), np.zeros((envs, frames)),
                        np.zeros((envs, frames)), np.zeros((envs, frames)),
                        np.zeros((envs, frames)), np.zeros((envs, frames), dtype=bool),
                        np.zeros(envs, dtype=np.int64))


def step_outputs(envs: int, steps: int) -> StepOutputs:
    ints = lambda: np.zeros((envs, steps), dtype=np.int64)  # noqa: E731
    return StepOutputs(np.zeros((envs, steps)), ints(), ints(), ints(), ints(),
                       np.zeros(envs, dtype=np.int64))


def track_state(envs: int, lights: int, obstacles: int, metrics: StopLineState) -> TrackState:
    """A zeroed state for ``envs`` envs (reset each before use)."""
    f = lambda: np.zeros(envs)  # noqa: E731
    i = lambda: np.zeros(envs, dtype=np.int64)  # noqa: E731
    b = lambda: np.zeros(envs, dtype=bool)  # noqa: E731
    return TrackState(
        np.zeros((envs, STATE_SIZE)), f(), f(), i(), b(), b(),
        np.zeros((envs, 1, 2), dtype=np.int64), i(), i(), i(), i(),
        np.zeros((envs, obstacles, 2)), np.zeros((envs, lights)), f(), f(),
        np.zeros((envs, lights), dtype=np.int8), i(), f(), i(), f(), i(),
        np.zeros((envs, 3)), np.zeros((envs, 3)), i(), b(), i(), b(), f(), f(), f(), f(), f(),
        b(), b(), i(), metrics)


# ============================================================================ frames
@kernel
def manual_at(st: TrackState, env: int, frame: int) -> bool:
    """Whether the frame starting at ``frame`` is in a manual period (the index moves
    forward only)."""
    periods = st.manual_periods[env]
    count = st.manual_count[env]
    index = st.manual_index[env]
    while index < count and frame >= periods[index, 1]:
        index += 1
    st.manual_index[env] = index
    return index < count and periods[index, 0] <= frame


@kernel
def update_mode(st: TrackState, env: int) -> None:
    """``dbw_enabled`` for the frame about to run; a take-over when the human starts."""
    manual = manual_at(st, env, st.frame[env])
    if manual and st.dbw_enabled[env]:
        st.take_over[env] = True
    st.dbw_enabled[env] = not manual


@kernel
def update_stop_line(c: TrackConstants, st: TrackState, env: int) -> None:
    """The observation's next stop line ahead of the rear axle (the loop length: none)."""
    line, distance = next_stop_line(c.stop_s, c.stop_index, c.length, st.s[env])
    if line < 0:
        distance = c.length
    st.next_line[env] = line
    st.line_distance[env] = distance


@kernel
def _near_obstacle(c: TrackConstants, st: TrackState, env: int) -> bool:
    car = st.vehicle[env]
    cx = car[X] + c.centre_offset * math.cos(car[YAW])
    cy = car[Y] + c.centre_offset * math.sin(car[YAW])
    obstacles = st.obstacles[env]
    for k in range(obstacles.shape[0]):
        dx = obstacles[k, 0] - cx
        dy = obstacles[k, 1] - cy
        if dx * dx + dy * dy <= c.reach_sq:
            return True
    return False


@kernel
def begin_step(st: TrackState, buffers: FrameBuffers, out: StepOutputs, env: int) -> None:
    """Start an env step: the frames' bookkeeping from here on belongs to it."""
    st.contact[env] = -1
    st.step_manual_frames[env] = 0
    st.frame_in_step[env] = 0
    st.stage[env] = RUN
    st.s_start[env] = st.s[env]
    st.progress_before[env] = st.metrics.progress[env]
    step = out.steps[env]
    out.first_frame[env, step] = st.frame[env]
    out.buffer_start[env, step] = buffers.count[env]
    st.in_step[env] = True


@kernel
def run_frames(c: TrackConstants, st: TrackState, buffers: FrameBuffers,
               events: StopLineEvents, env: int) -> bool:
    """The frames of env ``env``'s current step, from where it stands; True when it paused
    for Python (see the module), False when the step's frames are done."""
    car = st.vehicle[env]
    while True:
        stage = st.stage[env]
        if stage == RUN or stage == HAVE_MANUAL:
            if stage == RUN:
                if st.manual_count[env]:
                    update_mode(st, env)
                if not st.dbw_enabled[env]:
                    st.stage[env] = NEED_MANUAL
                    return True
                command = st.command[env]
                st.frame_manual[env] = False
            else:
                command = st.forced[env]
                st.frame_manual[env] = True
                st.step_manual_frames[env] += 1
            step_vehicle(c.vehicle, c.gains, st.vehicle, env, command[0], command[1],
                         command[2], c.dt)
            st.frame[env] += 1
            step_lights(c.lights, st.light_offsets, st.light_clock, st.light_next_change,
                        st.light_states, env, c.dt)
            guess = st.s[env] + car[SPEED] * c.dt
            s, d, moved = project_point(c.line, car[X], car[Y], guess)
            if abs(moved) > LOCAL_SEARCH_TRUST_M or abs(d) > LOCAL_SEARCH_TRUST_M:
                st.guess[env] = guess
                st.stage[env] = NEED_PROJECTION
                return True
        elif stage == HAVE_PROJECTION:
            s, d = st.fix_s[env], st.fix_d[env]
        else:  # HAVE_CONTACT: the frame's bookkeeping is done
            s, d = st.s[env], st.d[env]
        if stage != HAVE_CONTACT:
            n = buffers.count[env]
            buffers.xy[env, n, 0] = car[X]
            buffers.xy[env, n, 1] = car[Y]
            buffers.s[env, n] = s
            buffers.d[env, n] = d
            buffers.speed[env, n] = car[SPEED]
            buffers.manual[env, n] = st.frame_manual[env]
            stop_line_frame(c.lines, st.metrics, env, n, s, d, car[SPEED],
                            car[LATERAL_ACCELERATION], st.light_states[env], events)
            buffers.progress[env, n] = st.metrics.progress[env]
            buffers.count[env] = n + 1
            st.s[env] = s
            st.d[env] = d
            if st.obstacles.shape[1] and _near_obstacle(c, st, env):
                st.stage[env] = NEED_CONTACT
                return True
        st.stage[env] = RUN
        st.frame_in_step[env] += 1
        if st.contact[env] >= 0 or abs(d) > c.half_width:
            return False  # the episode ends inside the step
        if st.frame_in_step[env] >= c.frames_per_step:
            if st.manual_count[env]:
                update_mode(st, env)  # the observation tells whether the next action counts
            return False


@kernel
def end_step(c: TrackConstants, st: TrackState, buffers: FrameBuffers, out: StepOutputs,
             env: int) -> None:
    """Close env ``env``'s step: the progress reward, the laps and the episode's end."""
    step = out.steps[env]
    start = out.buffer_start[env, step]
    frames = buffers.count[env] - start
    out.frames[env, step] = frames
    manual_frames = st.step_manual_frames[env]
    out.manual_frames[env, step] = manual_frames
    st.manual_frames_total[env] += manual_frames
    progress = st.metrics.progress[env]
    if manual_frames == 0:
        gained = progress - st.progress_before[env]
    else:
        # Only the frames the agent drove (the metrics' wrapped-difference formula).
        length = c.length
        half = 0.5 * length
        gained, s_before = 0.0, st.s_start[env]
        for i in range(start, start + frames):
            if not buffers.manual[env, i]:
                gained += py_mod(buffers.s[env, i] - s_before + half, length) - half
            s_before = buffers.s[env, i]
    out.reward[env, step] = c.progress_scale * gained
    # Laps as the driving metrics count them for a chunk of these frames.
    if progress >= st.lap_mark[env]:
        for i in range(start, start + frames):
            while buffers.progress[env, i] >= st.lap_mark[env]:
                st.laps[env] += 1
                st.lap_mark[env] = (st.laps[env] + 1) * c.length
    st.terminated[env] = False
    st.truncated[env] = False
    st.reason[env] = NO_END
    if st.contact[env] >= 0:
        st.terminated[env], st.reason[env] = True, COLLISION
    elif abs(st.d[env]) > c.half_width:
        st.terminated[env], st.reason[env] = True, OFF_ROAD
    elif st.laps[env] >= c.laps:
        st.terminated[env], st.reason[env] = True, LAPS_COMPLETED
    elif st.frame[env] >= c.max_frames:
        st.truncated[env], st.reason[env] = True, MAX_DURATION
    update_stop_line(c, st, env)
    out.steps[env] = step + 1
    st.in_step[env] = False


@kernel
def run_steps(c: TrackConstants, st: TrackState, buffers: FrameBuffers, out: StepOutputs,
              events: StopLineEvents, steps_left: IntArray) -> bool:
    """Every env's next ``steps_left[env]`` steps with its ``st.command``; True when some
    env paused for Python (call again once served: each env resumes where it stopped)."""
    paused = False
    for env in range(steps_left.size):
        while True:
            if not st.in_step[env]:
                if steps_left[env] <= 0:
                    break
                begin_step(st, buffers, out, env)
            if run_frames(c, st, buffers, events, env):
                paused = True
                break
            end_step(c, st, buffers, out, env)
            steps_left[env] -= 1
    return paused


__all__ = ["COLLISION", "HAVE_CONTACT", "HAVE_MANUAL", "HAVE_PROJECTION", "LAPS_COMPLETED",
           "MAX_DURATION", "NEED_CONTACT", "NEED_MANUAL", "NEED_PROJECTION", "NO_END",
           "OFF_ROAD", "REASONS", "RUN", "FrameBuffers", "StepOutputs",
           "TrackConstants", "TrackState", "begin_step", "end_step", "frame_buffers",
           "manual_at", "run_frames", "run_steps", "step_outputs", "track_state",
           "update_stop_line"]
