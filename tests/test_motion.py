"""The seed planner's motion layer driving the real env with scripted behavior decisions.

Every test drives ``HighwayLoop-v0`` without traffic and checks a known answer: the rates
the decisions ask for, the lane centre, the env's incident counters, the path queue.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_gym.metrics import INCIDENT_KINDS
from sdc_gym.stack.highway.behavior import (
    GENTLE_ACCELERATION,
    LAUNCH_ACCELERATION,
    MAX_BRAKING,
    NORMAL_ACCELERATION,
    STEP,
    BehaviorDecision,
)
from sdc_gym.stack.highway.motion import MotionParameters, SeedMotionPlanner

MPH = 0.44704
SPEED_LIMIT = 50 * MPH
CRUISE = 49 * MPH
LAUNCH_END = 40 * MPH

Script = Callable[[float, SeedMotionPlanner], BehaviorDecision]


@dataclass
class Drive:
    """What a scripted drive recorded, one row per env step."""

    env: gym.Env
    planner: SeedMotionPlanner
    time: list[float] = field(default_factory=list)
    s: list[float] = field(default_factory=list)
    d: list[float] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    acceleration: list[float] = field(default_factory=list)
    info: dict = field(default_factory=dict)

    def column(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name))

    @property
    def metrics(self):
        return self.env.unwrapped.metrics

    def assert_no_incident(self) -> None:
        counts = {kind: self.info[f"incidents_{kind}"] for kind in INCIDENT_KINDS}
        assert not any(counts.values()), (counts, self.info.get("summary"))


def make_env(**config) -> gym.Env:
    return gym.make("sdc_gym/HighwayLoop-v0", config={"traffic": {"car_count": 0}, **config})


def drive(script: Script, seconds: float, **config) -> Drive:
    env = make_env(**config)
    obs, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road, MotionParameters.for_env(env))
    run = Drive(env, planner)
    t = 0.0
    while t < seconds:
        path = planner.plan(obs, script(t, planner))
        obs, _, terminated, truncated, info = env.step(path)
        t = info["time"]
        run.time.append(t)
        run.s.append(float(obs["ego"][2]))
        run.d.append(float(obs["ego"][3]))
        run.speed.append(info["speed"])
        run.acceleration.append(info["acceleration"])
        run.info = info
        if terminated or truncated:
            break
    return run


def launch_then(lane: int, later: Script | None = None, until: float = math.inf) -> Script:
    """The FSM's start: Launch (muted steering) to 40 mph, then 49 mph at the normal rate;
    after ``until`` seconds, ``later`` decides."""

    def script(t: float, planner: SeedMotionPlanner) -> BehaviorDecision:
        if t >= until and later is not None:
            return later(t, planner)
        if t < 3.0 and planner.speed < LAUNCH_END:
            return BehaviorDecision(lane, CRUISE, LAUNCH_ACCELERATION, steering=False)
        return BehaviorDecision(lane, CRUISE, NORMAL_ACCELERATION)

    return script


def slope(time: np.ndarray, value: np.ndarray, where: np.ndarray) -> float:
    return float(np.polyfit(time[where], value[where], 1)[0])


# ---------------------------------------------------------------------- (1) launch
def test_launch_from_rest_to_49_mph_at_the_asked_rates_on_the_lane_centre():
    run = drive(launch_then(1), 12.0)
    t, v, d = run.column("time"), run.column("speed"), run.column("d")
    # The launch rate until the easing into the goal begins, at dv = a^2 / (2 J) short of
    # it (measured on the speeds the env reports, away from the switch points).
    jerk = MotionParameters().arrival_jerk
    easing_starts = CRUISE - LAUNCH_ACCELERATION**2 / (2 * jerk)
    launch = (v > 2.0) & (v < easing_starts - 0.5)
    assert slope(t, v, launch) == pytest.approx(LAUNCH_ACCELERATION, rel=0.01)
    # Then the acceleration eases: a <= sqrt(2 J dv) (block means, so a little slack),
    # and after the switch at 40 mph it never exceeds the normal rate.
    blocks = run.column("acceleration")
    assert np.max(blocks[launch]) == pytest.approx(LAUNCH_ACCELERATION, abs=0.1)
    rate = np.diff(v) / np.diff(t)  # per env step, from the speeds the env reports
    middle = 0.5 * (v[1:] + v[:-1])
    easing = middle > easing_starts + 0.5
    bound = np.sqrt(2 * jerk * np.maximum(CRUISE - middle[easing], 0.0))
    assert np.all(rate[easing] <= bound + 0.3)
    assert np.all(rate[middle > LAUNCH_END + 0.3] <= NORMAL_ACCELERATION + 1e-6)
    assert run.metrics.max_acceleration < 10.0
    assert run.metrics.max_jerk <= 5.0
    # Cruise at 49 mph, under the limit, centred once settled.
    assert v[-1] == pytest.approx(CRUISE, abs=1e-3)
    assert CRUISE - 0.01 < run.metrics.max_speed < SPEED_LIMIT
    assert np.all(np.abs(d[t > 4.0] - 6.0) < 0.25)
    run.assert_no_incident()


# ---------------------------------------------------------------------- (2) lane changes
@pytest.mark.parametrize(("start_lane", "target_lane", "within"), [(1, 0, 6.0), (2, 0, 8.0)])
def test_lane_change_at_cruise_on_a_straight(start_lane, target_lane, within):
    change_at = 10.0

    def script(t: float, planner: SeedMotionPlanner) -> BehaviorDecision:
        # A gentle start keeps the start's own jerk well below the lane change's.
        return BehaviorDecision(start_lane if t < change_at else target_lane, CRUISE,
                                GENTLE_ACCELERATION)

    run = drive(script, change_at + within + 2.0, start_d=2.0 + 4.0 * start_lane)
    t, d, s = run.column("time"), run.column("d"), run.column("s")
    centre = 2.0 + 4.0 * target_lane
    off = np.abs(d - centre) >= 0.25
    done = t[np.flatnonzero(off)[-1] + 1]  # from here on, within 0.25 m
    assert done - change_at < within
    changing = (t > change_at) & (t < done)
    curvature = run.env.unwrapped.road.reference.curvature(s[changing])
    assert np.all(np.abs(curvature) < 1e-4), "on the default map's first straight"
    assert d[t > change_at].min() > centre - 0.05, "settles without crossing the centre"
    assert run.metrics.max_jerk <= 5.0
    assert run.metrics.max_acceleration < 5.0
    run.assert_no_incident()


def test_lane_change_flag_follows_the_queue_end():
    def script(t: float, planner: SeedMotionPlanner) -> BehaviorDecision:
        return BehaviorDecision(1 if t < 6.0 else 0, CRUISE, NORMAL_ACCELERATION)

    flags = []
    run = drive(lambda t, planner: (flags.append((t, planner.lane_change_in_progress))
                                    or script(t, planner)), 14.0)
    times = np.array([t for t, _ in flags])
    flag = np.array([f for _, f in flags])
    first = np.flatnonzero(times >= 6.0)[0]
    assert not flag[:first].any()
    assert flag[first + 1]  # flagged from the first plan with the new target lane
    assert not flag[-1]
    assert run.planner.end_state.d == pytest.approx(2.0, abs=0.05)


# ---------------------------------------------------------------------- (3) braking
def test_braking_at_max_rate_from_cruise_to_20_mph():
    brake_at = 7.0
    target = 20 * MPH
    first = []

    def later(t: float, planner: SeedMotionPlanner) -> BehaviorDecision:
        first.append(t)
        return BehaviorDecision(1, target, MAX_BRAKING, replan=len(first) == 1)

    run = drive(launch_then(1, later, until=brake_at), 12.0)
    t, v = run.column("time"), run.column("speed")
    # The seed's maximum braking until the easing into the goal speed begins.
    easing = MAX_BRAKING**2 / (2 * MotionParameters().arrival_jerk)
    braking = (t > brake_at) & (v < CRUISE - 1.0) & (v > target + easing + 0.5)
    assert slope(t, v, braking) == pytest.approx(-MAX_BRAKING, rel=0.01)
    assert v[-1] == pytest.approx(target, abs=1e-3)
    # A replan: the car slows within a few frames, not after the 1 s queue.
    assert t[np.argmax(v < CRUISE - 0.1)] - brake_at < 0.3
    assert run.info["incidents_acceleration"] == 0
    run.assert_no_incident()


# ---------------------------------------------------------------------- (4) replan
def test_replan_keeps_only_the_first_replan_keep_points():
    env = make_env()
    obs, _ = env.reset(seed=0)
    params = MotionParameters.for_env(env)
    planner = SeedMotionPlanner(env.unwrapped.road, params)
    cruise = BehaviorDecision(1, CRUISE, NORMAL_ACCELERATION)
    for _ in range(100):
        obs, *_ = env.step(planner.plan(obs, cruise))
    before = planner.queue
    path = planner.plan(obs, BehaviorDecision(1, 20 * MPH, MAX_BRAKING, replan=True))
    start = planner.consumed  # the old plan's point where this path starts (the car's next)
    # The seed keeps the first 4 points on a replan; here counted from where the path will
    # be when it arrives, after the `lead` points consumed in flight.
    keep = planner.lead + 4
    assert len(path) == params.path_length
    np.testing.assert_array_equal(path[:keep], before[start:start + keep, :2])
    assert np.hypot(*(path[keep] - before[start + keep, :2])) > 1e-3
    # After the kept points the speed falls at the braking rate from the first new point.
    increments = planner.queue[:, 5]
    assert increments[keep - 1] == pytest.approx(CRUISE * STEP, abs=1e-9)
    np.testing.assert_allclose(np.diff(increments[keep - 1:keep + 10]),
                               -MAX_BRAKING * STEP**2, rtol=1e-9)


def test_without_replan_a_new_decision_only_changes_new_points():
    env = make_env()
    obs, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road, MotionParameters.for_env(env))
    for _ in range(100):
        previous = planner.plan(obs, BehaviorDecision(1, CRUISE, NORMAL_ACCELERATION))
        obs, *_ = env.step(previous)
    path = planner.plan(obs, BehaviorDecision(0, 20 * MPH, MAX_BRAKING))
    kept = len(previous) - planner.consumed
    np.testing.assert_array_equal(path[:kept], previous[planner.consumed:])


# ---------------------------------------------------------------------- (5) continuity
def scripted_decisions(t: float, planner: SeedMotionPlanner) -> BehaviorDecision:
    """Speed and lane changes, so that continuity is checked while the plan changes."""
    if t < 4.0:
        return launch_then(1)(t, planner)
    return BehaviorDecision(0 if t < 8.0 else 2, 35 * MPH if t < 6.0 else CRUISE,
                            NORMAL_ACCELERATION)


def assert_continues(path: np.ndarray, previous: np.ndarray, previous_increments: np.ndarray,
                     planner: SeedMotionPlanner, resumed: bool) -> None:
    """The path starts with the rest of the previous one, unchanged; except in the cycle
    where steering comes back after the launch: then only ``lead + 4`` points are kept and
    the rest of the unsteered states are planned again, steered, at the same increments."""
    consumed = planner.consumed
    rest = len(previous) - consumed
    if not resumed:
        np.testing.assert_array_equal(path[:rest], previous[consumed:])
        return
    keep = planner.lead + 4
    np.testing.assert_array_equal(path[:keep], previous[consumed:consumed + keep])
    np.testing.assert_array_equal(planner.queue[:rest, 5], previous_increments[consumed:])
    assert not np.array_equal(path[keep:rest], previous[consumed + keep:])


def test_path_continues_the_echoed_previous_path_exactly_without_latency():
    env = make_env(latency_steps=0)
    obs, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road, MotionParameters.for_env(env))
    ego = obs["ego"].astype(np.float64)
    previous = planner.plan(obs, scripted_decisions(0.0, planner))
    # The first path starts from the ego's observed pose and speed (at rest: the seed's
    # start increment along the yaw).
    expected = ego[:2] + 0.009 * np.array([math.cos(ego[4]), math.sin(ego[4])])
    np.testing.assert_allclose(previous[0], expected, atol=1e-9)
    increments, steered, resumptions = planner.queue[:, 5], False, 0
    for _ in range(250):
        obs, _, _, _, info = env.step(previous)
        count = int(obs["previous_path_count"])
        decision = scripted_decisions(info["time"], planner)
        path = planner.plan(obs, decision)
        assert count == len(previous) - 3 == len(previous) - planner.consumed
        resumed = decision.steering and not steered
        resumptions += resumed
        assert_continues(path, previous, increments, planner, resumed)
        np.testing.assert_allclose(obs["previous_path"][:planner.lead + 4],
                                   path[:planner.lead + 4], atol=2e-3)
        previous, increments, steered = path, planner.queue[:, 5], decision.steering
    assert resumptions == 1  # the launch's end


def test_path_continues_exactly_with_the_default_latency():
    env = make_env()
    obs, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road, MotionParameters.for_env(env))
    previous, increments, steered = None, None, False
    for cycle in range(250):
        decision = scripted_decisions(env.unwrapped.metrics.time, planner)
        path = planner.plan(obs, decision)
        if previous is not None:
            # The car consumed some points since (3 per cycle once the first path has
            # arrived): the path starts with the rest of the previous one.
            assert planner.consumed == 3 or cycle == 1
            assert_continues(path, previous, increments, planner,
                             decision.steering and not steered)
        previous, increments, steered = path, planner.queue[:, 5], decision.steering
        obs, *_ = env.step(path)
    assert env.unwrapped.metrics.max_raw_acceleration < 25.0  # no stalled or skipped frame


def test_queue_states_carry_exact_frenet_coordinates():
    env = make_env(map="oval")
    obs, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road, MotionParameters.for_env(env))
    reference = env.unwrapped.road.reference
    for step in range(700):
        obs, *_ = env.step(planner.plan(obs, scripted_decisions(step * 0.06, planner)))
    queue = planner.queue
    s, d = reference.to_frenet(queue[:, :2], s_guess=queue[:, 2])
    np.testing.assert_allclose(reference.s_difference(s, queue[:, 2]), 0.0, atol=1e-6)
    np.testing.assert_allclose(d, queue[:, 3], atol=1e-6)


# ---------------------------------------------------------------------- (6) latency
def test_a_lap_of_the_oval_with_160_ms_latency():
    run = drive(launch_then(1), 120.0, map="oval", latency_steps=8, steps_per_action=3)
    assert run.planner.params.latency_frames == 8
    assert run.info["is_success"], run.info["termination_reason"]
    run.assert_no_incident()
    t, v, d = run.column("time"), run.column("speed"), run.column("d")
    # Never a stalled frame (a path arriving mid-step must not make the car repeat its
    # point) nor a skipped one: cruise speed on every reported frame.
    assert np.all(np.abs(v[t > 4.0] - CRUISE) < 1e-3)
    assert run.metrics.max_raw_acceleration < 25.0
    # Centred through both 150 m bends.
    assert np.all(np.abs(d[t > 4.0] - 6.0) < 0.25)


def test_parameters_are_checked():
    with pytest.raises(ValueError):
        MotionParameters(steering_gate_lane_change=0.01)
    with pytest.raises(ValueError):
        MotionParameters(frames_per_cycle=0)


# ---------------------------------------------------------------------- (7) cost-saving paths
@pytest.mark.parametrize("map_name", ["default", "oval"])
def test_geometry_agrees_with_the_reference_lines_vectorized_evaluation(map_name):
    road = make_env(map=map_name).unwrapped.road
    reference = road.reference
    planner = SeedMotionPlanner(road)
    rng = np.random.default_rng(0)
    for _ in range(500):
        k = int(rng.integers(1, 6))
        start = float(rng.uniform(-5.0, reference.length + 5.0))  # across the seam too
        s_pred = [start + 0.4 * j + float(rng.normal(0.0, 0.01)) for j in range(k)]
        distance = float(rng.uniform(12.5, 40.0))
        aim_d = float(rng.choice([2.0, 6.0, 10.0])) + float(rng.normal(0.0, 0.3))
        xy, curvature = reference.to_xy_and_curvature(
            np.array(s_pred + s_pred + [s + distance for s in s_pred]),
            np.array([0.0] * k + [1.0] * k + [aim_d] * k))
        frames, aims, aim_curvature = planner._geometry(s_pred, distance, aim_d)
        expected = np.column_stack([xy[:k], xy[k:2 * k] - xy[:k], curvature[:k]])
        np.testing.assert_allclose(np.array(frames), expected, rtol=0, atol=1e-9)
        np.testing.assert_allclose([(a.real, a.imag) for a in aims], xy[2 * k:], atol=1e-9)
        assert aim_curvature == pytest.approx(curvature[-1], abs=1e-12)


def test_a_queue_longer_than_its_buffer_grows_it():
    env = make_env(path_points=1500)
    obs, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road,
                                MotionParameters.for_env(env, path_length=1500))
    previous = None
    for _ in range(5):
        path = planner.plan(obs, BehaviorDecision(1, CRUISE, NORMAL_ACCELERATION))
        assert path.shape == (1500, 2)
        np.testing.assert_array_equal(planner.queue[:, :2], path)
        if previous is not None:  # the path continues the previous one exactly
            np.testing.assert_array_equal(path[:len(previous) - planner.consumed],
                                          previous[planner.consumed:])
        previous = path
        obs, *_ = env.step(path)


# ---------------------------------------------------------------------- (7) queue length
@pytest.mark.parametrize("path_points", [25, 120])
def test_the_fsm_sends_the_envs_path_points_as_its_queue(path_points):
    """The queue is the env's ``path_points`` (the seed's "queue length of 50" is the
    default), not a fixed 50: after the first cycle every path the FSM sends holds exactly
    ``path_points`` points, and it drives a clean 40 s with them."""
    from sdc_agents.registry import make_agent

    env = gym.make("sdc_gym/HighwayLoop-v0",
                   config={"traffic": {"car_count": 6}, "path_points": path_points})
    agent = make_agent("fsm_bold", env)
    assert MotionParameters.for_env(env).path_length == path_points
    obs, _ = env.reset(seed=3)
    agent.reset()
    lengths = []
    info: dict = {}
    while not info or info["time"] < 40.0:
        path = agent.act(obs)
        lengths.append(len(path))
        obs, _, terminated, truncated, info = env.step(path)
        assert not (terminated or truncated), info.get("summary")
    assert set(lengths[1:]) == {path_points}
    assert not any(info[f"incidents_{kind}"] for kind in INCIDENT_KINDS)
    assert info["distance"] > 400.0  # ~40 s near 47 mph less the launch
