"""The drive-by-wire stack of a batch of envs, one tick per env step, as a numba kernel.

:func:`stack_tick` is one tick of :class:`~sdc_gym.stack.track.dbw_stack.DBWStackAgent`
for env ``env`` of a batch: the nodes due at the tick (detector, behavior + waypoint
updater, pure pursuit, twist controller, at their rates) run in data-flow order on the
node kernels of :mod:`sdc_gym.stack.track.node_kernels`, with every node's state in
arrays over the env axis. The light source is the env's ground truth (the observation's
light states) and the behavior layer the RL decision executor
(:class:`~sdc_gym.stack.track.decisions.TrackDecisionBehavior`, its action set between
decisions, with its red-light shield when on): the stack of
``sdc_gym/TrackLoopBehavior-v0``. Its parameters are those of the agent that
:func:`~sdc_gym.stack.track.dbw_stack.dbw_stack_for_env` builds for the env
(:func:`stack_constants` reads them off it), so the batch drives exactly as that agent.

The stack sees what the agent sees in the env's observation: float32 pose, speed and
stop-line distance; its commands reach the car as float32 values, as an action does.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.kernel_compiler import kernel
from sdc_gym.lights.traffic_lights import UNKNOWN
from sdc_gym.stack.track.behavior import SQUARE
from sdc_gym.stack.track.control_kernels import (
    FollowerConstants,
    FollowerState,
    TwistParameters,
    TwistState,
    follow,
    follower_state,
    twist_control,
    twist_reset,
    twist_state,
)
from sdc_gym.stack.track.dbw_stack import DBWStackAgent
from sdc_gym.stack.track.follower import PurePursuit
from sdc_gym.stack.track.node_kernels import (
    DetectorConstants,
    DetectorState,
    UpdaterConstants,
    UpdaterState,
    action_decision,
    detect,
    detector_reset,
    detector_state,
    encode_features,
    in_gate,
    node_due,
    state_time,
    stop_at_red,
    update_waypoints,
    updater_state,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

DETECTOR, UPDATER, FOLLOWER, DBW = range(4)  # RateScheduler's node order (rates.NODES)


class StackConstants(NamedTuple):
    """The stack's parameters (shared by every env)."""

    runs: IntArray  # (4,) node rates as runs / per_ticks per tick
    per_ticks: IntArray
    loop_period: float
    detector: DetectorConstants
    updater: UpdaterConstants
    follower: FollowerConstants
    twist: TwistParameters
    speed_limit: float
    stop_margin: float
    watch_lights: bool  # the track has lights: the updater's watchdog watches them
    continuous: bool  # RL actions are (speed, stop) pairs rather than indices
    speed_margin: float
    max_decel: float  # features
    comfortable_decel: float
    red_light_shield: bool  # the rule's stops override the RL action's go
    square: float  # 2.0, the stopping test's exponent at run time (behavior.SQUARE)


class StackState(NamedTuple):
    """Every env's stack: the scheduler's ticks, each node's state and last output, the
    RL action in force and how long the detector has reported its state."""

    ticks: IntArray
    detector: DetectorState
    updater: UpdaterState
    follower: FollowerState
    twist: TwistState
    has_decision: BoolArray
    decision_speed: FloatArray
    decision_waypoint: IntArray
    decision_mode: IntArray
    has_final: BoolArray
    final_x: FloatArray  # (envs, count)
    final_y: FloatArray
    final_speed: FloatArray
    has_twist: BoolArray
    twist_linear: FloatArray
    twist_angular: FloatArray
    twist_time: FloatArray
    action_index: IntArray
    action_speed: FloatArray
    action_stop: FloatArray
    key_line: IntArray
    key_state: IntArray
    state_since: FloatArray
    shield_for: IntArray  # the line the shield's rule is committed to stop at (-1: none)


def stack_constants(agent: DBWStackAgent, *, continuous: bool, speed_margin: float,
                    max_decel: float, comfortable_decel: float,
                    red_light_shield: bool = False) -> StackConstants:
    """The constants of ``agent``'s nodes (built by ``dbw_stack_for_env`` for the env);
    ``red_light_shield``: the executor's shield (``TrackDecisionBehavior``).
    The batch runs pure pursuit only: the MPC follower solves a QP with OSQP at every
    follower tick, which cannot run inside the compiled loop."""
    if not isinstance(agent.follower, PurePursuit):
        raise ValueError(f"the batched stack runs follower 'pure_pursuit' only, got "
                         f"{getattr(agent, 'follower_kind', type(agent.follower).__name__)!r} "
                         f"(the MPC solves a QP with OSQP per step, outside the compiled "
                         f"batch; drive it with the single-env stack, DBWStackAgent)")
    scheduler = agent.scheduler
    return StackConstants(
        scheduler.runs.copy(), scheduler.per_ticks.copy(), float(scheduler.loop_period_s),
        agent.detector.constants, agent.updater.constants, agent.follower.constants,
        agent.controller.constants, float(agent.speed_limit_mps), float(agent.stop_margin_m),
        bool(agent.track.light_count), bool(continuous), float(speed_margin),
        float(max_decel), float(comfortable_decel), bool(red_light_shield), SQUARE)


def stack_state(envs: int, final_count: int) -> StackState:
    """A stack state for ``envs`` envs (reset each with :func:`reset_stack`)."""
    f = lambda: np.zeros(envs)  # noqa: E731
    i = lambda: np.zeros(envs, dtype=np.int64)  # noqa: E731
    b = lambda: np.zeros(envs, dtype=bool)  # noqa: E731
    return StackState(i(), detector_state(envs), updater_state(envs), follower_state(envs),
                      twist_state(envs), b(), f(), i(), i(), b(),
                      np.zeros((envs, final_count)), np.zeros((envs, final_count)),
                      np.zeros((envs, final_count)), b(), f(), f(), f(), i(), f(), f(), i(),
                      i(), f(), i())


@kernel
def reset_stack(c: StackConstants, st: StackState, env: int) -> None:
    """A new episode: every node of env ``env`` forgets its state."""
    st.ticks[env] = 0
    detector_reset(st.detector, env)
    st.updater.previous_index[env] = -1
    st.updater.full_searches[env] = 0
    fs = st.follower
    fs.angular[env] = 0.0
    fs.target_x[env] = 0.0
    fs.target_y[env] = 0.0
    fs.lookahead[env] = c.follower.lookahead_min
    fs.curvature[env] = 0.0
    fs.recomputed[env] = False
    twist_reset(st.twist, env)
    st.twist.command[env, :] = 0.0
    st.has_decision[env] = False
    st.has_final[env] = False
    st.has_twist[env] = False
    st.twist_time[env] = -np.inf
    # The executor's initial action (go at the limit) and its state-time key.
    st.action_index[env] = 0
    st.action_speed[env] = 1.0
    st.action_stop[env] = -1.0
    st.key_line[env] = -2
    st.key_state[env] = -2
    st.state_since[env] = 0.0
    st.shield_for[env] = -1


@kernel
def observed_stop_line(line: int, distance: float) -> tuple[int, float]:
    """The next stop line as ``detector.next_stop_line`` reads it from the observation's
    float32 ``next_stop_line`` (index -1: none, distance inf)."""
    index = np.float64(np.float32(line))
    if index >= 0:
        return int(index), np.float64(np.float32(distance))  # index: an exact integer
    return -1, np.inf


@kernel
def stack_tick(c: StackConstants, st: StackState, env: int, x: float, y: float, yaw: float,
               speed: float, dbw_enabled: bool, line: int, distance: float,
               light_states: NDArray[np.int8]) -> None:
    """One tick of env ``env``'s stack on its observation (float32 values as floats; the
    stop line as the observation gives it); the command lands in ``st.twist.command``."""
    tick = st.ticks[env]
    now = tick * c.loop_period
    st.ticks[env] = tick + 1
    if node_due(c.runs[DETECTOR], c.per_ticks[DETECTOR], tick):
        frame_state = UNKNOWN
        if in_gate(c.detector, line, distance):
            frame_state = light_states[line]  # the ground truth source
            st.detector.classifications[env] += 1
        detect(c.detector, st.detector, env, now, line, distance, frame_state)
    if node_due(c.runs[UPDATER], c.per_ticks[UPDATER], tick):
        ds = st.detector
        state = ds.report_state[env] if ds.report_line[env] == line else UNKNOWN
        waypoint = c.detector.stop_waypoints[line] if line >= 0 else -1
        # The executor: how long this state has been seen, then the action's decision.
        key_line, key_state, since, _ = state_time(st.key_line[env], st.key_state[env],
                                                   st.state_since[env], line, state, now)
        st.key_line[env], st.key_state[env], st.state_since[env] = key_line, key_state, since
        target, stop_waypoint, mode = action_decision(
            c.continuous, st.action_index[env], st.action_speed[env], st.action_stop[env],
            c.speed_limit, c.speed_margin, waypoint)
        if c.red_light_shield:
            # The rule's stop (StopAtRedLights, its commitment kept per env) overrides a go.
            _, rule_waypoint, rule_mode, st.shield_for[env] = stop_at_red(
                c.max_decel, c.comfortable_decel, True, c.speed_margin, c.square,
                st.shield_for[env], speed, c.speed_limit, line, waypoint,
                distance - c.stop_margin, state)
            if rule_waypoint >= 0 and stop_waypoint < 0:
                stop_waypoint, mode = rule_waypoint, rule_mode
        st.has_decision[env] = True
        st.decision_speed[env] = target
        st.decision_waypoint[env] = stop_waypoint
        st.decision_mode[env] = mode
        update_waypoints(c.updater, st.updater, env, now, x, y, yaw, now, stop_waypoint,
                         c.watch_lights, ds.report_time[env], True, target, st.final_x[env],
                         st.final_y[env], st.final_speed[env])
        st.has_final[env] = True
    if node_due(c.runs[FOLLOWER], c.per_ticks[FOLLOWER], tick) and st.has_final[env]:
        linear, angular = follow(c.follower, st.follower, env, x, y, yaw, speed,
                                 st.final_x[env], st.final_y[env], st.final_speed[env])
        st.has_twist[env] = True
        st.twist_linear[env] = linear
        st.twist_angular[env] = angular
        st.twist_time[env] = now
    if node_due(c.runs[DBW], c.per_ticks[DBW], tick):
        linear = st.twist_linear[env] if st.has_twist[env] else 0.0
        angular = st.twist_angular[env] if st.has_twist[env] else 0.0
        twist_control(c.twist, st.twist, env, now, linear, angular, st.twist_time[env], speed,
                      now, dbw_enabled)


@kernel
def observe(c: StackConstants, st: StackState, env: int, speed: float, line: int,
            distance: float, out: NDArray[np.float32]) -> None:
    """The decision's observation (``TrackDecisionBehavior.observe``) of env ``env`` at
    its next tick, into ``out`` (12,) float32."""
    now = st.ticks[env] * c.loop_period
    ds = st.detector
    state = ds.report_state[env] if ds.report_line[env] == line else UNKNOWN
    key_line, key_state, since, seconds = state_time(st.key_line[env], st.key_state[env],
                                                     st.state_since[env], line, state, now)
    st.key_line[env], st.key_state[env], st.state_since[env] = key_line, key_state, since
    stopping = st.has_decision[env] and st.decision_waypoint[env] >= 0
    encode_features(c.max_decel, c.comfortable_decel, speed, c.speed_limit, line, distance,
                    distance - c.stop_margin, state, seconds, stopping, out)
