"""The FSM's options from the seed's further work, each with a known answer: the quintic
in-out easing curve and the eased steering target, straight-line maximum braking's
deceleration (the seed's step, then the jerk limit up to the deceleration limit less the
bend's share), crash rerouting's lane."""

from __future__ import annotations

import dataclasses
import itertools
import math

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_agents.highway.fsm import DrivingStyle, FSMBehavior, FSMParameters
from sdc_agents.highway.fsm_options import quintic_in_out
from sdc_gym.stack.highway.behavior import MAX_BRAKING, BehaviorDecision
from sdc_gym.stack.highway.motion import MotionParameters, SeedMotionPlanner
from tests.test_fsm_scenarios import Scene, decide_at, warm_up


def bold_with(**options: bool) -> FSMBehavior:
    base = FSMParameters.for_style(DrivingStyle.BOLD)
    params = dataclasses.replace(base, **{name: dataclasses.replace(getattr(base, name),
                                                                    enabled=on)
                                          for name, on in options.items()})
    fsm = FSMBehavior(DrivingStyle.BOLD, params)
    warm_up(fsm)
    return fsm


@pytest.mark.parametrize(("u", "value"), [(-0.5, 0.0), (0.0, 0.0), (0.25, 16 / 4**5),
                                          (0.5, 0.5), (0.75, 1 - 0.5 * 0.5**5), (1.0, 1.0),
                                          (2.0, 1.0)])
def test_the_quintic_in_out_curve_at_known_points(u, value):
    assert quintic_in_out(u) == value


def test_the_quintic_curve_is_symmetric_and_flat_at_both_ends():
    for u in np.linspace(0.0, 1.0, 41):
        assert quintic_in_out(u) + quintic_in_out(1.0 - u) == pytest.approx(1.0, abs=1e-15)
    h = 1e-4  # slope ~ 5 * 16 h^4 at the ends: flat
    assert quintic_in_out(h) < 1e-18 and 1.0 - quintic_in_out(1.0 - h) < 1e-18


def test_an_eased_lane_change_aims_along_the_quintic_between_the_lane_centres():
    """Bold behind a slow car in the middle lane, lane 0 open: the change begins at
    t = 10 s and the target's d goes 6 m -> 2 m over 3 s (one lane) along the curve."""
    fsm = bold_with(easing=True)
    scene = Scene(ego_lane=1, ego_speed=20.0).add(1, 30.0, 15.0)
    start = decide_at(fsm, scene, 10.0)
    assert start.target_lane == 0 and start.target_d == 6.0  # e(0) = 0: the old centre
    expected = {10.75: 6.0 - 4.0 * 16 / 4**5, 11.5: 4.0, 12.25: 2.0 + 4.0 * 0.5**6}
    for t, d in expected.items():
        assert decide_at(fsm, scene, t).target_d == pytest.approx(d, abs=1e-12)
    assert decide_at(fsm, scene, 13.0).target_d is None  # arrived: the lane's centre
    # Without the option the decision names the lane only (the seed's jump to its spline).
    plain = bold_with()
    assert decide_at(plain, Scene(ego_lane=1, ego_speed=20.0).add(1, 30.0, 15.0),
                     10.0).target_d is None


def test_an_aborted_eased_lane_change_goes_back_at_once():
    """A car appears beside the ego in the target lane while the ego is still on its side
    of the line: the FSM returns to its lane (the seed's abort) without easing back."""
    fsm = bold_with(easing=True)
    scene = Scene(ego_lane=1, ego_speed=20.0).add(1, 30.0, 15.0)
    assert decide_at(fsm, scene, 10.0).target_lane == 0
    scene.ego_d = 5.0  # 1 m toward lane 0, inside the 2 m abort window
    scene.add(0, 1.0, 20.0)
    back = decide_at(fsm, scene, 10.3)
    assert back.target_lane == 1 and back.replan and back.target_d is None


def test_the_motion_layer_steers_at_the_decisions_target_d():
    env = gym.make("sdc_gym/HighwayLoop-v0")
    observation, _ = env.reset(seed=0)
    planner = SeedMotionPlanner(env.unwrapped.road, MotionParameters.for_env(env))
    planner.plan(observation, BehaviorDecision(target_lane=1, target_speed=10.0))
    assert planner.batch.floats[0, 4] == 6.0  # lane 1's centre
    planner.plan(observation, BehaviorDecision(target_lane=1, target_speed=10.0,
                                               target_d=4.75))
    assert planner.batch.floats[0, 4] == 4.75
    env.close()


def braking_rates(fsm: FSMBehavior, radius: float) -> list[float]:
    """The rates asked for behind a car standing 15 m ahead (hard braking) at 20 m/s,
    one cycle every 0.06 s."""
    rates = []
    for k in range(5):
        scene = Scene(ego_lane=1, ego_speed=20.0, road_radius=radius).add(1, 15.0, 0.0)
        decision = decide_at(fsm, scene, 1.0 + 0.06 * k)
        assert decision.replan
        rates.append(decision.acceleration)
    return rates


def test_straight_line_max_braking_reaches_the_limit_at_the_jerk_limit():
    # The seed: 8.42 m/s^2 at once and no more.
    assert braking_rates(bold_with(), math.inf) == [MAX_BRAKING] * 5
    # The option on a straight: the seed's step, then +10 m/s^3 x 0.06 s per cycle up to
    # the 9.5 m/s^2 limit, and not beyond.
    rates = braking_rates(bold_with(straight_braking=True), math.inf)
    assert rates[:2] == [MAX_BRAKING, pytest.approx(MAX_BRAKING + 0.6)]
    assert rates[2:] == [9.5, 9.5, 9.5]
    assert all(b - a <= 0.6 + 1e-12 for a, b in itertools.pairwise(rates))
    # In a bend of 100 m at 20 m/s the lateral 4 m/s^2 leaves sqrt(9.5^2 - 4^2).
    rates = braking_rates(bold_with(straight_braking=True), 100.0)
    assert rates == [MAX_BRAKING] + [pytest.approx(math.sqrt(9.5**2 - 16.0))] * 4


def test_crash_rerouting_leaves_a_lane_a_crash_closes_and_never_enters_one():
    """Wrecks standing 150 m ahead in lanes 1 and 0, lane 2 clear: Bold keeps its lane
    (the wreck is beyond its 50 m early-change horizon); with rerouting it moves to
    lane 2, not lane 0."""
    def scene() -> Scene:
        return Scene(ego_lane=1, ego_speed=20.0).add(1, 150.0, 0.0).add(0, 160.0, 0.0)

    assert decide_at(bold_with(), scene(), 1.0).target_lane == 1
    rerouted = decide_at(bold_with(reroute=True), scene(), 1.0)
    assert rerouted.target_lane == 2 and rerouted.replan
    # Blocked in lane 1 by a slow car, lane 0 roomier but closed by a wreck at 120 m:
    # Bold's tactical rule would take lane 0; rerouting refuses it.
    def boxed() -> Scene:
        return (Scene(ego_lane=1, ego_speed=15.0).add(1, 25.0, 12.0).add(0, 120.0, 0.0)
                .add(2, 28.0, 12.0))

    assert decide_at(bold_with(), boxed(), 10.0).target_lane == 0
    assert decide_at(bold_with(reroute=True), boxed(), 10.0).target_lane == 1
