"""Traffic light phases as numba kernels over a batch of light sets.

The model is :mod:`sdc_gym.lights.traffic_lights`' (a light's state is a pure function of
its phase ``(t + offset) mod cycle``, or of its script); these functions are its only
implementation: :class:`~sdc_gym.lights.traffic_lights.TrafficLights` is the batch of
one, and the track world advances every env's lights with :func:`step_lights`.

A :class:`LightSchedule` holds what all envs of a track share (the phase boundaries of
each light and the scripts, padded to one length); each env has its own offsets (k,),
clock, cached next-change time and states (k,) int8.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.kernel_compiler import kernel

CHANGE_GUARD_S = 1e-9
"""The cached "next change" time is set this far early so that rounding of (t + offset) mod
cycle can never make the states differ from the pure function near a phase boundary."""


class LightSchedule(NamedTuple):
    """Per light: green end, yellow end and cycle (s, phase), and the script, if any
    (``script_length`` 0: the light cycles; else its first entries of ``script_times`` /
    ``script_states``)."""

    green_end: NDArray[np.float64]
    yellow_end: NDArray[np.float64]
    cycle: NDArray[np.float64]
    script_length: NDArray[np.int64]
    script_times: NDArray[np.float64]
    script_states: NDArray[np.int8]


@kernel
def _script_row(times: NDArray[np.float64], length: int, time_s: float) -> int:
    """The last entry at or before ``time_s`` (``searchsorted(..., "right") - 1``, >= 0)."""
    row = 0
    for k in range(1, length):
        if times[k] <= time_s:
            row = k
        else:
            break
    return row


@kernel
def states_at(schedule: LightSchedule, offsets: NDArray[np.float64], time_s: float,
              out: NDArray[np.int8]) -> None:
    """Each light's state at ``time_s`` (s since reset) into ``out`` (k,)."""
    for light in range(offsets.size):
        phase = py_mod(time_s + offsets[light], schedule.cycle[light])
        # GREEN = 2, YELLOW = 1, RED = 0: count the boundaries still ahead in the cycle.
        out[light] = (1 if phase < schedule.green_end[light] else 0) + (
            1 if phase < schedule.yellow_end[light] else 0)
        length = schedule.script_length[light]
        if length:
            row = _script_row(schedule.script_times[light], length, time_s)
            out[light] = schedule.script_states[light, row]


@kernel
def time_to_change(schedule: LightSchedule, offsets: NDArray[np.float64], light: int,
                   time_s: float) -> float:
    """s from ``time_s`` until light ``light``'s state next changes (inf: never)."""
    phase = py_mod(time_s + offsets[light], schedule.cycle[light])
    if phase < schedule.green_end[light]:
        boundary = schedule.green_end[light]
    elif phase < schedule.yellow_end[light]:
        boundary = schedule.yellow_end[light]
    else:
        boundary = schedule.cycle[light]
    remaining = boundary - phase
    length = schedule.script_length[light]
    if length:
        times = schedule.script_times[light]
        states = schedule.script_states[light]
        row = _script_row(times, length, time_s)
        # The next entry that changes the state (a repeated state is no change).
        remaining = np.inf
        for k in range(length):
            if times[k] > time_s and states[k] != states[row]:
                remaining = times[k] - time_s
                break
    return remaining


@kernel
def times_to_change(schedule: LightSchedule, offsets: NDArray[np.float64], time_s: float,
                    out: NDArray[np.float64]) -> None:
    """s from ``time_s`` until each light's state next changes (inf: never) into ``out``."""
    for light in range(offsets.size):
        out[light] = time_to_change(schedule, offsets, light, time_s)


@kernel
def refresh_lights(schedule: LightSchedule, offsets: NDArray[np.float64], time_s: float,
                   states: NDArray[np.int8]) -> float:
    """The states at ``time_s`` into ``states``; returns the next change's cached time."""
    states_at(schedule, offsets, time_s, states)
    soonest = np.inf
    for light in range(offsets.size):
        value = time_to_change(schedule, offsets, light, time_s)
        if value < soonest:  # np.min(initial=inf); NaN never occurs (finite phases)
            soonest = value
    return time_s + soonest - CHANGE_GUARD_S


@kernel
def step_lights(schedule: LightSchedule, offsets: NDArray[np.float64],
                clock: NDArray[np.float64], next_change: NDArray[np.float64],
                states: NDArray[np.int8], env: int, dt: float) -> bool:
    """Advance env ``env``'s light clock by ``dt`` s; True when its states changed."""
    clock[env] += dt
    if clock[env] >= next_change[env]:
        next_change[env] = refresh_lights(schedule, offsets[env], clock[env], states[env])
        return True
    return False
