"""The track loop at the behavior level for a batch of envs: the drive-by-wire stack and the
physics frames in one numba kernel.

:func:`run_decisions` runs, for every env, its decision's env steps: before each step one
tick of the stack (:func:`~sdc_gym.stack.track.stack_batch.stack_tick`, on what the env's
observation shows: float32 pose, speed and stop line, the ground-truth light states),
then the step's frames (:mod:`sdc_gym.envs.track_kernel`) with the stack's command as the
action (float32, checked against the action box as an action is). An env stops at the
end of its episode. Pauses for Python are the frame kernel's (see there).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sdc_gym.envs.track_kernel import (
    FrameBuffers,
    StepOutputs,
    TrackConstants,
    TrackState,
    begin_step,
    end_step,
    run_frames,
)
from sdc_gym.kernel_compiler import kernel
from sdc_gym.metrics.track_metrics_batch import StopLineEvents
from sdc_gym.stack.track.stack_batch import (
    StackConstants,
    StackState,
    observe,
    observed_stop_line,
    stack_tick,
)
from sdc_gym.vehicle.dbw_kernel import SPEED, YAW, X, Y

DONE, PAUSED, BAD_COMMAND = range(3)


@kernel
def _f32(value: float) -> float:
    return np.float64(np.float32(value))  # float() would keep a float32 in numba


@kernel
def run_decisions(c: TrackConstants, st: TrackState, buffers: FrameBuffers, out: StepOutputs,
                  events: StopLineEvents, sc: StackConstants, ss: StackState,
                  steps_left: NDArray[np.int64], max_brake: float, max_steer: float,
                  bad_env: NDArray[np.int64]) -> int:
    """Every env's next ``steps_left[env]`` steps under its stack (see the module):
    :data:`DONE`, :data:`PAUSED` (call again once Python served the pauses) or
    :data:`BAD_COMMAND` (the stack's command of env ``bad_env[0]``, in ``st.command``, is
    outside the action box: the env would reject it)."""
    status = DONE
    for env in range(steps_left.size):
        while True:
            if not st.in_step[env]:
                if steps_left[env] <= 0:
                    break
                car = st.vehicle[env]
                line, distance = observed_stop_line(st.next_line[env], st.line_distance[env])
                stack_tick(sc, ss, env, _f32(car[X]), _f32(car[Y]), _f32(car[YAW]),
                           _f32(car[SPEED]), st.dbw_enabled[env], line, distance,
                           st.light_states[env])
                command = ss.twist.command[env]
                throttle, brake, steer = _f32(command[0]), _f32(command[1]), _f32(command[2])
                st.command[env, 0] = throttle
                st.command[env, 1] = brake
                st.command[env, 2] = steer
                if not (0.0 <= throttle <= 1.0 and 0.0 <= brake <= max_brake
                        and -max_steer <= steer <= max_steer):
                    bad_env[0] = env
                    return BAD_COMMAND
                begin_step(st, buffers, out, env)
            if run_frames(c, st, buffers, events, env):
                status = PAUSED
                break
            end_step(c, st, buffers, out, env)
            steps_left[env] -= 1
            if st.terminated[env] or st.truncated[env]:
                steps_left[env] = 0
    return status


@kernel
def observe_envs(st: TrackState, sc: StackConstants, ss: StackState,
                 chosen: NDArray[np.bool_], out: NDArray[np.float32]) -> None:
    """The decision observations of the ``chosen`` envs into their rows of ``out`` (see
    :func:`~sdc_gym.stack.track.stack_batch.observe`)."""
    for env in range(chosen.size):
        if not chosen[env]:
            continue
        line, distance = observed_stop_line(st.next_line[env], st.line_distance[env])
        observe(sc, ss, env, _f32(st.vehicle[env, SPEED]), line, distance, out[env])
