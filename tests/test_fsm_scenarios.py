"""The FSM planner on hand-built world models: the seed's lane-change scenarios A to J and
the rules and modes of ``spec/fsm_planner.md``.

Lanes are 0, 1, 2 from the yellow line outward (d = 2, 6, 10 m); cars are placed by lane,
signed centre-to-centre gap (m, > 0 ahead) and speed (m/s).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import pytest

from sdc_agents.highway.fsm import (
    MAX_SPEED_MPS,
    DrivingStyle,
    FSMBehavior,
    FSMParameters,
    Mode,
)
from sdc_gym.stack.highway.behavior import (
    GENTLE_ACCELERATION,
    LAUNCH_ACCELERATION,
    MAX_BRAKING,
    NORMAL_ACCELERATION,
    BehaviorDecision,
)
from sdc_gym.stack.highway.world_model import LaneView, TrackedCar, WorldModel

WIDTH = 4.0
LANES = 3
MPH = 0.44704


@dataclass
class Scene:
    """An ego and cars on a straight 3-lane road; ``advance`` moves them at constant speed."""

    ego_lane: int = 1
    ego_speed: float = 20.0
    cars: list[list[float]] = field(default_factory=list)  # [lane, gap, speed, d_rate]
    time: float = 0.0
    ego_d: float | None = None  # None: the ego lane's centre
    road_radius: float = math.inf

    def add(self, lane: int, gap: float, speed: float, d_rate: float = 0.0) -> Scene:
        self.cars.append([lane, gap, speed, d_rate])
        return self

    def advance(self, dt: float) -> None:
        for car in self.cars:
            car[1] += (car[2] - self.ego_speed) * dt
        self.time += dt

    def world(self) -> WorldModel:
        ego_d = (self.ego_lane + 0.5) * WIDTH if self.ego_d is None else self.ego_d
        ego_lane = min(LANES - 1, max(0, int(ego_d // WIDTH)))
        tracked = []
        views = []
        for lane in range(LANES):
            ahead = (math.inf, 0.0, -1)
            behind = (math.inf, 0.0, -1)
            for i, (car_lane, gap, speed, *_) in enumerate(self.cars):
                if car_lane != lane:
                    continue
                if gap > 0 and gap < ahead[0]:
                    ahead = (gap, speed, i)
                elif gap <= 0 and -gap < behind[0]:
                    behind = (-gap, speed, i)
            views.append(
                LaneView(lane, ahead[0], ahead[1], ahead[2], behind[0], behind[1], behind[2])
            )
        for i, (car_lane, gap, speed, *rest) in enumerate(self.cars):
            d_rate = rest[0] if rest else 0.0  # cars may be given as [lane, gap, speed]
            d = (car_lane + 0.5) * WIDTH
            tracked.append(TrackedCar(i, 1000.0 + gap, d, speed, d_rate, int(car_lane), gap))
        gaps = [v.ahead_gap for v in views]
        best = max(gaps)
        preferred = (
            1 if gaps[1] == best else (ego_lane if gaps[ego_lane] == best else gaps.index(best))
        )
        return WorldModel(
            time=self.time,
            ego_s=1000.0,
            ego_d=ego_d,
            ego_speed=self.ego_speed,
            ego_lane=ego_lane,
            lane_count=LANES,
            lane_width=WIDTH,
            lanes=tuple(views),
            cars=tuple(tracked),
            preferred_lane=preferred,
            road_radius=self.road_radius,
        )


def warm_up(fsm: FSMBehavior, lane: int = 1) -> None:
    """Launch -> Adapt -> Cruise on an empty road at t = 0: cool-downs count from t = 0."""
    scene = Scene(ego_lane=lane, ego_speed=22.0)
    fsm.decide(scene.world())
    scene.time = 0.02
    fsm.decide(scene.world())
    assert fsm.mode is Mode.CRUISE


def cruising(style: DrivingStyle = DrivingStyle.CONSERVATIVE, lane: int = 1) -> FSMBehavior:
    fsm = FSMBehavior(style)
    warm_up(fsm, lane)
    return fsm


def decide_at(fsm: FSMBehavior, scene: Scene, t: float) -> BehaviorDecision:
    scene.time = t
    return fsm.decide(scene.world())


# --------------------------------------------------------------------------- A to J
def test_a_early_lane_change_at_long_range():
    # Cruise in the middle lane; a slow car 85 m ahead; lane 0 open, lane 2 not.
    def scene() -> Scene:
        return Scene(ego_lane=1, ego_speed=22.0).add(1, 85.0, 15.0).add(2, 60.0, 20.0)

    fsm = cruising()
    before = decide_at(fsm, scene(), 10.0)  # strategic cool-down (20 s) not over
    assert before.target_lane == 1
    fsm = cruising()
    d = decide_at(fsm, scene(), 25.0)
    assert fsm.mode is Mode.CRUISE  # the car is still beyond the braking range
    assert d.target_lane == 0 and not d.replan  # strategic: no replan needed
    assert d.target_speed == pytest.approx(MAX_SPEED_MPS)
    # The same car further than the early-change horizon (90 m): no change yet.
    fsm = cruising()
    far = Scene(ego_lane=1, ego_speed=22.0).add(1, 95.0, 15.0).add(2, 60.0, 20.0)
    assert decide_at(fsm, far, 25.0).target_lane == 1


def test_b_matched_velocity_clear_lanes_after_cooldown():
    # Adapt behind a car at matched speed in lane 0; lanes 1 and 2 clear.
    fsm = cruising(lane=0)
    scene = Scene(ego_lane=0, ego_speed=18.0).add(0, 30.0, 18.0)
    changed_at = None
    t = 5.0
    while t < 18.0:
        d = decide_at(fsm, scene, t)
        if t == 5.0:
            assert fsm.mode is Mode.ADAPT  # car detected ahead
        if d.target_lane != 0:
            changed_at = t
            break
        assert d.target_speed == pytest.approx(fsm.params.braking_percent(30.0) / 100 * 18.0)
        t = round(t + 0.1, 6)
    assert changed_at is not None and 15.0 < changed_at <= 15.1 + 1e-9
    assert d.target_lane == 1 and d.replan
    assert fsm.mode is Mode.ADAPT and fsm.lane_change_in_progress


def test_c_open_ahead_vehicle_behind_not_a_threat():
    fsm = cruising(lane=0)
    # Slow car 40 m ahead; lane 1 open ahead, its car behind 15 m back and slower.
    scene = Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 16.0).add(1, -15.0, 19.0)
    d = decide_at(fsm, scene, 30.0)
    assert fsm.mode is Mode.ADAPT
    assert d.target_lane == 1 and d.replan


def test_d_collision_threat_from_behind():
    fsm = cruising(lane=0)
    # The car behind in lane 1 closes at 8 m/s: it needs 3 * 8 + 11 = 35 m, has 25 m.
    scene = Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 16.0).add(1, -25.0, 28.0)
    d = decide_at(fsm, scene, 30.0)
    assert d.target_lane == 0
    # The same gap with a car that is not closing: change.
    fsm = cruising(lane=0)
    calm = Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 16.0).add(1, -25.0, 20.0)
    assert decide_at(fsm, calm, 30.0).target_lane == 1


def test_e_higher_velocity_next_lane_vehicle_behind_not_a_threat():
    fsm = cruising(lane=0)
    # Lane 1 flows faster (its car ahead at 24 m/s, 90 m away); its car behind closes at
    # 4 m/s from 30 m: 3 * 4 + 11 = 23 m needed.
    scene = (
        Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 16.0).add(1, 90.0, 24.0).add(1, -30.0, 24.0)
    )
    d = decide_at(fsm, scene, 30.0)
    assert d.target_lane == 1


def test_f_return_to_open_middle_lane():
    def scene() -> Scene:
        # Cruise in lane 2 with no car ahead; lane 1 open (its car behind 40 m back at the
        # same speed); lane 0 clear for 50 m both ways.
        return (
            Scene(ego_lane=2, ego_speed=22.0)
            .add(1, -40.0, 22.0)
            .add(0, 70.0, 22.0)
            .add(0, -60.0, 22.0)
        )

    fsm = cruising(lane=2)
    assert decide_at(fsm, scene(), 10.0).target_lane == 2  # strategic cool-down
    fsm = cruising(lane=2)
    d = decide_at(fsm, scene(), 25.0)
    assert fsm.mode is Mode.CRUISE
    assert d.target_lane == 1 and not d.replan
    # Not when the middle lane has a car ahead (not open).
    fsm = cruising(lane=2)
    busy = scene().add(1, 150.0, 22.0)
    assert decide_at(fsm, busy, 25.0).target_lane == 2


def test_g_matched_velocity_in_a_pocket_patience_then_advance():
    fsm = cruising(lane=1)
    # Boxed in: a car 35 m ahead, one alongside ahead in lane 0, one just behind in lane 2,
    # all at the ego's speed.
    scene = (
        Scene(ego_lane=1, ego_speed=18.0).add(1, 35.0, 18.0).add(0, 5.0, 18.0).add(2, -3.0, 18.0)
    )
    scene.time = 5.0
    d = fsm.decide(scene.world())
    assert fsm.mode is Mode.ADAPT
    for _ in range(149):  # to t = 19.9 s
        scene.advance(0.1)
        d = fsm.decide(scene.world())
        assert d.target_lane == 1
        assert fsm.mode is Mode.ADAPT
    assert fsm.blocked_time == pytest.approx(15.0, abs=0.11)
    for _ in range(3):
        scene.advance(0.1)
        d = fsm.decide(scene.world())
    assert fsm.mode is Mode.ADVANCE and d.mode == "advance"
    assert d.target_lane == 1
    # Advance closes in: 1.05 x the lead's speed (35 m is beyond the active 30 m braking
    # range) at the gentle rate.
    assert d.target_speed == pytest.approx(1.05 * 18.0)
    assert d.acceleration == pytest.approx(GENTLE_ACCELERATION)


def test_h_higher_velocity_next_lane_clear_behind():
    fsm = cruising(lane=0)
    scene = Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 16.0).add(1, 80.0, 24.0)
    d = decide_at(fsm, scene, 30.0)
    assert d.target_lane == 1 and d.replan


def test_i_higher_velocity_next_lane_not_clear_behind():
    fsm = cruising(lane=0)
    # A car 9 m behind in lane 1 (under the 11 m minimum), dropping back at 3 m/s.
    scene = (
        Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 20.0).add(1, 80.0, 24.0).add(1, -9.0, 17.0)
    )
    scene.time = 30.0
    d = fsm.decide(scene.world())
    assert d.target_lane == 0
    changed = None
    for _ in range(20):
        scene.advance(0.1)
        d = fsm.decide(scene.world())
        if d.target_lane == 1:
            changed = -scene.world().lanes[1].behind_gap
            break
    assert changed is not None and changed < -11.0  # only once it is 11 m back


def test_j_pocket_avoidance_double_lane_change():
    def scene(radius: float) -> Scene:
        # Lane 2: slow car 30 m ahead. Lane 1: a car 60 m ahead (too close to merge into,
        # > 45 m: passable). Lane 0 open.
        return (
            Scene(ego_lane=2, ego_speed=20.0, road_radius=radius)
            .add(2, 30.0, 16.0)
            .add(1, 60.0, 16.0)
        )

    fsm = cruising(lane=2)
    d = decide_at(fsm, scene(math.inf), 30.0)
    assert d.target_lane == 0 and d.replan
    for radius in (2900.0, 3000.0):  # a double change needs more than 3000 m
        fsm = cruising(lane=2)
        assert decide_at(fsm, scene(radius), 30.0).target_lane == 2
    fsm = cruising(lane=2)
    assert decide_at(fsm, scene(3001.0), 30.0).target_lane == 0


def test_no_double_change_through_a_car_inside_the_hard_braking_gap():
    """Bold asks 20 m of room in the lane a double change crosses, but while changing that
    lane's car is a lead: at 21 m the braking curve would demand an emergency stop (below
    80 % of its speed under 22.7 m), so the change waits; at 24 m it goes."""
    assert FSMParameters().hard_braking_gap_m == pytest.approx(22.7, abs=0.01)
    for middle_gap, lane in ((21.0, 2), (24.0, 0)):
        scene = Scene(ego_lane=2, ego_speed=20.0).add(2, 30.0, 16.0).add(1, middle_gap, 21.0)
        decision = decide_at(cruising(DrivingStyle.BOLD, lane=2), scene, 30.0)
        assert decision.target_lane == lane, middle_gap
        assert decision.acceleration < MAX_BRAKING  # no emergency either way


# ------------------------------------------------------------------ rules and modes
def test_braking_curve_anchors():
    p = FSMParameters()
    assert p.braking_percent(5.0) == pytest.approx(0.0, abs=0.3)
    assert p.braking_percent(4.0) == 0.0
    assert p.braking_percent(22.7) == pytest.approx(80.0, abs=0.05)
    assert p.braking_percent(49.8) == pytest.approx(100.0, abs=0.05)
    assert p.braking_percent(80.0) == 100.0


def test_hard_braking_replans_below_80_percent():
    fsm = cruising(lane=1)
    scene = Scene(ego_lane=1, ego_speed=20.0).add(1, 15.0, 16.0)
    d = decide_at(fsm, scene, 1.0)
    frac = fsm.params.braking_percent(15.0) / 100
    assert frac < 0.8
    assert d.replan and d.acceleration == pytest.approx(MAX_BRAKING)
    assert d.target_speed == pytest.approx(frac * 16.0)
    # At 30 m: 90 %, a normal deceleration without replan.
    fsm = cruising(lane=1)
    d = decide_at(fsm, Scene(ego_lane=1, ego_speed=20.0).add(1, 30.0, 16.0), 1.0)
    assert not d.replan and d.acceleration == pytest.approx(NORMAL_ACCELERATION)
    assert d.target_speed == pytest.approx(fsm.params.braking_percent(30.0) / 100 * 16.0)


def test_hard_braking_inhibits_lane_change():
    fsm = cruising(lane=0)
    # Scenario C's open lane 1, but the car ahead is only 15 m away.
    scene = Scene(ego_lane=0, ego_speed=20.0).add(0, 15.0, 16.0)
    d = decide_at(fsm, scene, 30.0)
    assert d.replan and d.target_lane == 0


def test_launch_then_adapt_above_40_mph():
    fsm = FSMBehavior()
    scene = Scene(ego_lane=1, ego_speed=0.0)
    for speed in (0.0, 5.0, 10.0, 17.8):
        scene.ego_speed = speed
        d = fsm.decide(scene.world())
        assert fsm.mode is Mode.LAUNCH and d.mode == "launch"
        assert not d.steering
        assert d.acceleration == pytest.approx(LAUNCH_ACCELERATION)
        assert d.target_lane == 1
        scene.time += 0.5
    scene.ego_speed = 40.1 * MPH
    d = fsm.decide(scene.world())
    assert fsm.mode is Mode.ADAPT and d.steering and not d.replan
    fsm.reset()
    assert fsm.mode is Mode.LAUNCH and fsm.target_lane == -1


def test_launch_ignores_open_lanes():
    """Launching (slow, lead beyond the braking range) the ego keeps its lane, steering muted."""
    fsm = FSMBehavior()
    scene = Scene(ego_lane=0, ego_speed=10.0, time=40.0).add(0, 60.0, 10.0)
    d = fsm.decide(scene.world())
    scene.time = 80.0
    d = fsm.decide(scene.world())
    assert fsm.mode is Mode.LAUNCH and d.target_lane == 0 and not d.steering


def test_launch_ends_behind_a_lead_in_braking_range():
    """Behind a car slower than 40 mph the seed's launch would never end (and never steer):
    a lead inside the braking range hands over to Adapt, which steers and follows it."""
    fsm = FSMBehavior()
    scene = Scene(ego_lane=1, ego_speed=10.0).add(1, 40.0, 15.0)
    d = fsm.decide(scene.world())
    assert fsm.mode is Mode.ADAPT and d.steering
    assert d.target_speed == pytest.approx(fsm.params.braking_percent(40.0) / 100.0 * 15.0)


def test_adapt_to_cruise_needs_centred_and_clear_100_m():
    fsm = FSMBehavior()
    scene = Scene(ego_lane=1, ego_speed=20.0).add(1, 90.0, 20.0)
    fsm.decide(scene.world())
    assert fsm.mode is Mode.ADAPT
    decide_at(fsm, scene, 0.1)
    assert fsm.mode is Mode.ADAPT  # blocked within 100 m
    scene.cars.clear()
    scene.ego_d = 6.3  # 0.3 m off centre
    decide_at(fsm, scene, 0.2)
    assert fsm.mode is Mode.ADAPT
    scene.ego_d = 6.2
    decide_at(fsm, scene, 0.3)
    assert fsm.mode is Mode.CRUISE


def test_cruise_to_adapt_below_40_mph():
    fsm = cruising()
    decide_at(fsm, Scene(ego_lane=1, ego_speed=17.0), 1.0)
    assert fsm.mode is Mode.ADAPT


def test_lane_change_inhibited_on_bends():
    def scene(radius: float) -> Scene:
        return (
            Scene(ego_lane=0, ego_speed=20.0, road_radius=radius)
            .add(0, 40.0, 16.0)
            .add(1, -15.0, 19.0)
        )

    for radius in (300.0, 500.0):
        fsm = cruising(lane=0)
        assert decide_at(fsm, scene(radius), 30.0).target_lane == 0
    fsm = cruising(lane=0)
    assert decide_at(fsm, scene(501.0), 30.0).target_lane == 1


def test_bold_brakes_later_than_conservative():
    def scene() -> Scene:
        return Scene(ego_lane=1, ego_speed=22.0).add(1, 40.0, 18.0).add(0, 5, 22).add(2, 5, 22)

    cons = cruising(DrivingStyle.CONSERVATIVE)
    d = decide_at(cons, scene(), 1.0)
    assert d.target_speed == pytest.approx(cons.params.braking_percent(40.0) / 100 * 18.0)
    assert cons.mode is Mode.ADAPT
    bold = cruising(DrivingStyle.BOLD)
    d = decide_at(bold, scene(), 1.0)
    assert d.target_speed == pytest.approx(MAX_SPEED_MPS)  # 40 m: outside 30 m
    assert bold.mode is Mode.CRUISE
    d = decide_at(bold, Scene(ego_lane=1, ego_speed=22.0).add(1, 29.0, 18.0), 1.1)
    assert d.target_speed < 18.0 and bold.mode is Mode.ADAPT


def test_bold_cooldowns_are_shorter():
    def scene() -> Scene:
        return Scene(ego_lane=0, ego_speed=20.0).add(0, 25.0, 18.0).add(1, 40.0, 20.0)

    # At t = 5 s: Bold changes (4.6 s cool-down, 25 m of room needed ahead in lane 1),
    # Conservative does not (15 s, and 76 m needed).
    bold = cruising(DrivingStyle.BOLD, lane=0)
    assert decide_at(bold, scene(), 5.0).target_lane == 1
    cons = cruising(DrivingStyle.CONSERVATIVE, lane=0)
    assert decide_at(cons, scene(), 5.0).target_lane == 0
    bold = cruising(DrivingStyle.BOLD, lane=0)
    assert decide_at(bold, scene(), 4.5).target_lane == 0


def test_conservative_checks_far_lane_behind_before_merging_into_middle():
    def scene() -> Scene:
        # Lane 0 -> 1 with a fast car closing in lane 2 (could merge into lane 1): 25 m
        # behind, needing 3 x (26 - 20) + 11 = 29 m by the projection.
        return Scene(ego_lane=0, ego_speed=20.0).add(0, 40.0, 16.0).add(2, -25.0, 26.0)

    cons = cruising(DrivingStyle.CONSERVATIVE, lane=0)
    assert decide_at(cons, scene(), 30.0).target_lane == 0
    bold = cruising(DrivingStyle.BOLD, lane=0)
    assert decide_at(bold, scene(), 30.0).target_lane == 1


def test_conservative_advance_returns_to_adapt_after_lane_change():
    fsm = cruising(lane=0)
    scene = Scene(ego_lane=0, ego_speed=18.0).add(0, 33.0, 18.0).add(1, 5.0, 18.0)
    decide_at(fsm, scene, 1.0)
    assert fsm.mode is Mode.ADAPT
    decide_at(fsm, scene, 16.5)
    assert fsm.mode is Mode.ADVANCE
    # Lane 1 clears; the active profile needs 25 m of room there, lead within 35 m.
    scene.cars = [[0, 33.0, 18.0]]
    d = decide_at(fsm, scene, 17.0)
    assert d.target_lane == 1 and fsm.lane_change_in_progress
    scene.ego_d = 4.2  # halfway: not complete, still Advance, no new change
    d = decide_at(fsm, scene, 18.0)
    assert fsm.mode is Mode.ADVANCE and d.target_lane == 1
    scene.ego_d = 5.6  # within 0.5 m of lane 1's centre: complete
    decide_at(fsm, scene, 19.0)
    assert not fsm.lane_change_in_progress
    assert fsm.mode is Mode.ADAPT


def test_bold_advance_stays_in_advance_after_lane_change():
    fsm = cruising(DrivingStyle.BOLD, lane=0)
    scene = Scene(ego_lane=0, ego_speed=18.0).add(0, 25.0, 18.0).add(1, 5.0, 18.0)
    decide_at(fsm, scene, 1.0)
    decide_at(fsm, scene, 16.5)
    assert fsm.mode is Mode.ADVANCE
    scene.cars = [[0, 25.0, 18.0], [1, 60.0, 18.0]]
    assert decide_at(fsm, scene, 17.0).target_lane == 1
    scene.ego_d = 6.0
    decide_at(fsm, scene, 19.0)
    assert fsm.mode is Mode.ADVANCE


def test_advance_to_cruise_when_open_centred_fast():
    fsm = cruising(lane=1)
    scene = Scene(ego_lane=1, ego_speed=18.0).add(1, 40.0, 18.0).add(0, 5, 18).add(2, -3, 18)
    decide_at(fsm, scene, 1.0)
    decide_at(fsm, scene, 16.5)
    assert fsm.mode is Mode.ADVANCE
    scene.cars = []
    d = decide_at(fsm, scene, 17.0)
    assert fsm.mode is Mode.ADVANCE  # 18 m/s < 49 mph
    assert d.target_speed == pytest.approx(MAX_SPEED_MPS)
    scene.ego_speed = 21.95
    decide_at(fsm, scene, 18.0)
    assert fsm.mode is Mode.CRUISE


def test_push_from_behind_conservative_only():
    def scene(lead_gap: float) -> Scene:
        # A car 8 m behind at 22 m/s; the lead at 18 m/s.
        return Scene(ego_lane=1, ego_speed=18.0).add(1, lead_gap, 18.0).add(1, -8.0, 22.0)

    # Conservative speeds up from p(40 m) = 97.9 % of the lead's speed to the mean of the
    # two cars' speeds, capped at the lead's speed inside the braking range.
    cons = cruising()
    d = decide_at(cons, scene(40.0), 1.0)
    assert d.replan and d.target_speed == pytest.approx(18.0)
    assert d.acceleration == pytest.approx(MAX_BRAKING)
    # Not under hard braking (p(20 m) < 80 %).
    cons = cruising()
    d = decide_at(cons, scene(20.0), 1.0)
    assert d.target_speed == pytest.approx(cons.params.braking_percent(20.0) / 100 * 18.0)
    bold = cruising(DrivingStyle.BOLD)
    d = decide_at(bold, scene(25.0), 1.0)
    assert not d.replan
    assert d.target_speed == pytest.approx(bold.params.braking_percent(25.0) / 100 * 18.0)


def test_never_commands_above_49_83_mph():
    cap = 0.4455 / 0.02
    rng = random.Random(7)
    for style in DrivingStyle:
        fsm = FSMBehavior(style)
        scene = Scene(ego_lane=1, ego_speed=0.0)
        for _ in range(3000):
            scene.ego_speed = rng.uniform(0.0, 22.3)
            scene.cars = [
                [rng.randrange(3), rng.uniform(-80, 150), rng.uniform(10.0, 27.0)]
                for _ in range(rng.randrange(7))
            ]
            scene.ego_lane = fsm.target_lane if fsm.target_lane >= 0 else 1
            scene.time += rng.uniform(0.02, 2.0)
            d = fsm.decide(scene.world())
            assert 0.0 <= d.target_speed <= cap
            assert 0 <= d.target_lane < 3
        assert cap / MPH < 49.83


def test_no_merge_into_middle_beside_a_far_lane_car_that_may_merge_either_style():
    """The seed checks the far lane for "potential lane-changing vehicles" before merging
    into the middle lane. Traffic merges when the lane is clear by +-20 m, so a far-lane car
    within 20 m either way that may move over makes both styles wait: one held up by a car
    close ahead in its own lane that is no faster, or one already moving toward the middle.
    One with open road ahead has no reason to move over, and one 21 m away is not beside."""
    def scene() -> Scene:  # the ego in lane 0 behind a slow car, the middle lane empty
        return Scene(ego_lane=0, ego_speed=20.0).add(0, 30.0, 16.0)

    for style in DrivingStyle:
        for far_gap in (-12.0, 15.0):
            held_up = scene().add(2, far_gap, 20.0).add(2, far_gap + 30.0, 18.0)
            moving_over = scene().add(2, far_gap, 20.0, d_rate=-0.5)
            open_road = scene().add(2, far_gap, 20.0)
            for label, case, lane in (("held up", held_up, 0), ("moving", moving_over, 0),
                                      ("open road", open_road, 1)):
                decision = decide_at(cruising(style, lane=0), case, 30.0)
                assert decision.target_lane == lane, (style, far_gap, label)
        alongside = scene().add(2, 0.5, 20.0)  # the seed's own rule: far car ahead < 13 m
        assert decide_at(cruising(style, lane=0), alongside, 30.0).target_lane == 0, style
        not_beside = scene().add(2, -21.0, 20.0).add(2, 25.0, 18.0)  # held up, 21 m back
        assert decide_at(cruising(style, lane=0), not_beside, 30.0).target_lane == 1, style


def test_lane_change_aborted_when_a_car_enters_the_target_lane_beside():
    fsm = cruising(DrivingStyle.BOLD, lane=0)
    scene = Scene(ego_lane=0, ego_speed=20.0).add(0, 30.0, 16.0)
    assert decide_at(fsm, scene, 30.0).target_lane == 1
    # Half-way to the line, a car from lane 2 is now in lane 1, 3 m ahead: go back.
    scene.ego_d = 3.0
    scene.add(1, 3.0, 20.0)
    decision = decide_at(fsm, scene, 30.5)
    assert decision.target_lane == 0 and decision.replan  # the queued move is dropped
    assert fsm.lane_change_in_progress


def test_lane_change_not_aborted_past_the_lane_line():
    fsm = cruising(DrivingStyle.BOLD, lane=0)
    scene = Scene(ego_lane=0, ego_speed=20.0).add(0, 30.0, 16.0)
    assert decide_at(fsm, scene, 30.0).target_lane == 1
    scene.ego_d = 4.5  # 2.5 m from lane 0's centre: committed
    scene.add(1, 12.0, 20.0)
    assert decide_at(fsm, scene, 30.5).target_lane == 1


def test_following_speed_is_continuous_at_the_braking_range_and_settles_outside():
    """Beyond the braking range the goal is p(range) x u + gain x (gap - range): equal to
    the braking curve's value at the edge, and equal to the lead's speed at
    range + u (1 - p(range)) / gain (the gap the ego settles at)."""
    fsm = FSMBehavior(DrivingStyle.BOLD)
    p = fsm.params
    u = 18.0
    edge = p.active.brake_range_m
    inside = p.braking_percent(edge - 1e-6) / 100.0 * u
    settle = edge + u * (1.0 - p.braking_percent(edge) / 100.0) / p.approach_gain_per_s
    for gap, expected in ((edge + 1e-6, inside), (settle, u)):
        fsm = FSMBehavior(DrivingStyle.BOLD)
        warm_up(fsm, lane=1)
        scene = Scene(ego_lane=1, ego_speed=u).add(1, gap, u).add(0, 5.0, u).add(2, 5.0, u)
        goal = decide_at(fsm, scene, 0.1).target_speed
        assert goal == pytest.approx(expected, abs=1e-4), gap
