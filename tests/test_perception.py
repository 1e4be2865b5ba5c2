"""Perception (sdc_gym.stack.highway.perception): known answers from hand-built observations."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_agents.lane_keeping import LaneKeepingDriver
from sdc_gym.road.builtin_highways import get_highway_map
from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.stack.highway.perception import Perception, PerceptionParameters
from sdc_gym.stack.highway.world_model import NO_CAR, TrackedCar, WorldModel

ROAD = get_highway_map("default")
L = ROAD.length
CYCLE = 0.06  # s: one env step of 3 frames


def observation(road: HighwayMap, ego_s: float, ego_d: float, cars=(), *,
                ego_speed: float = 20.0, mask=None) -> dict:
    """An env-like observation (float32 arrays). ``cars``: (id, s, d, speed[, d_rate]),
    speed along the lane tangent (m/s), d_rate along the right normal (m/s)."""
    reference = road.reference
    fusion = np.zeros((len(cars), 7))
    for row, car in enumerate(cars):
        car_id, s, d, speed = car[:4]
        d_rate = car[4] if len(car) > 4 else 0.0
        velocity = speed * reference.tangent(s) + d_rate * reference.normal(s)
        fusion[row] = [car_id, *reference.to_xy(s, d), *velocity, s % road.length, d]
    ego_xy = reference.to_xy(ego_s, ego_d)
    ego = [*ego_xy, ego_s % road.length, ego_d, float(reference.heading(ego_s)), ego_speed]
    mask = np.ones(len(cars)) if mask is None else np.asarray(mask)
    return {
        "ego": np.array(ego, dtype=np.float32),
        "previous_path": np.zeros((50, 2), dtype=np.float32),
        "previous_path_count": 0,
        "end_path": np.zeros(2, dtype=np.float32),
        "sensor_fusion": fusion.astype(np.float32),
        "sensor_fusion_mask": mask.astype(np.int8),
    }


def circle_map(radius: float, points: int = 360) -> HighwayMap:
    angle = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)  # counter-clockwise
    return HighwayMap.from_waypoints("circle", radius * np.column_stack(
        [np.cos(angle), np.sin(angle)]))


def lane_speed(s: float, d: float, s_rate: float, road: HighwayMap = ROAD) -> float:
    """Speed along a lane at offset d of a car whose s grows at ``s_rate``."""
    return s_rate * (1.0 + float(road.reference.curvature(s)) * d)


def car(world: WorldModel, car_id: int) -> TrackedCar:
    (found,) = [c for c in world.cars if c.id == car_id]
    return found


# ---------------------------------------------------------------------- lanes and gaps
def test_nearest_ahead_and_behind_per_lane_across_the_seam():
    ego_s = L - 10.0
    cars = [
        (1, 15.0, 6.0, 21.0),          # lane 1, 25 m ahead across the seam
        (2, 100.0, 6.2, 25.0),         # lane 1, further ahead: not the nearest
        (3, L - 40.0, 5.8, 19.0),      # lane 1, 30 m behind
        (4, L - 5.0, 2.0, 17.0),       # lane 0, 5 m ahead
        (5, L - 12.0, 1.5, 16.0),      # lane 0, 2 m behind
        (6, L - 300.0, 2.0, 16.0),     # lane 0, beyond the 200 m sensing range
        (7, 300.0, 10.0, 23.0),        # lane 2, beyond the sensing range
        (8, 5.0, 10.0, 23.0),          # lane 2, but a dropout (masked)
    ]
    world = Perception(ROAD).perceive(
        observation(ROAD, ego_s, 6.0, cars, mask=[1, 1, 1, 1, 1, 1, 1, 0]), 1.5)

    assert (world.time, world.ego_lane, world.lane_count, world.lane_width) == (1.5, 1, 3, 4.0)
    assert world.ego_s == pytest.approx(ego_s, abs=1e-3)
    middle, left, right = world.lanes[1], world.lanes[0], world.lanes[2]
    assert (middle.ahead_id, middle.behind_id) == (1, 3)
    assert middle.ahead_gap == pytest.approx(25.0, abs=1e-2)
    assert middle.behind_gap == pytest.approx(30.0, abs=1e-2)
    assert middle.ahead_speed == pytest.approx(21.0, abs=1e-3)
    assert middle.behind_speed == pytest.approx(19.0, abs=1e-3)
    assert (left.ahead_id, left.behind_id) == (4, 5)
    assert left.ahead_gap == pytest.approx(5.0, abs=1e-2)
    assert left.behind_gap == pytest.approx(2.0, abs=1e-2)
    assert (left.ahead_speed, left.behind_speed) == pytest.approx((17.0, 16.0), abs=1e-3)
    # Nobody within range in lane 2: inf gaps, speed 0, no id.
    assert not right.has_ahead and not right.has_behind
    assert (right.ahead_gap, right.behind_gap) == (math.inf, math.inf)
    assert (right.ahead_speed, right.behind_speed, right.ahead_id) == (0.0, 0.0, NO_CAR)
    # Every sensed car is listed (range only limits the lane views); the dropout is not.
    assert sorted(c.id for c in world.cars) == [1, 2, 3, 4, 5, 6, 7]
    assert car(world, 1).gap == pytest.approx(25.0, abs=1e-2)
    assert car(world, 3).gap == pytest.approx(-30.0, abs=1e-2)
    assert car(world, 6).gap == pytest.approx(-290.0, abs=1e-2)
    assert [car(world, i).lane for i in (1, 4, 7)] == [1, 0, 2]


def test_speed_is_projected_on_the_road_and_d_rate_points_right():
    cars = [(1, 500.0, 6.0, 18.0, 1.5), (2, 520.0, 9.5, 22.0, -0.8)]
    world = Perception(ROAD).perceive(observation(ROAD, 480.0, 6.0, cars), 0.0)
    assert (car(world, 1).speed, car(world, 1).d_rate) == pytest.approx((18.0, 1.5), abs=1e-3)
    assert (car(world, 2).speed, car(world, 2).d_rate) == pytest.approx((22.0, -0.8), abs=1e-3)
    assert world.lanes[1].ahead_speed == pytest.approx(18.0, abs=1e-3)


def test_off_road_cars_fill_no_lane_and_empty_observations_work():
    cars = [(1, 510.0, 12.5, 20.0), (2, 490.0, -0.5, 20.0)]
    perception = Perception(ROAD)
    world = perception.perceive(observation(ROAD, 500.0, 6.0, cars), 0.0)
    assert all(not view.has_ahead and not view.has_behind for view in world.lanes)
    assert (car(world, 1).lane, car(world, 2).lane) == (3, -1)
    for empty in (observation(ROAD, 500.0, 6.0, cars, mask=[0, 0]),
                  observation(ROAD, 500.0, 6.0, ())):
        world = perception.perceive(empty, 0.0)
        assert world.cars == ()
        assert all(view.ahead_gap == math.inf for view in world.lanes)
        assert world.preferred_lane == 1


@pytest.mark.parametrize(
    ("ego_d", "cars", "preferred"),
    [
        (6.0, [(1, 530.0, 2.0, 20.0), (2, 550.0, 6.0, 20.0), (3, 580.0, 10.0, 20.0)], 2),
        (6.0, [(1, 590.0, 2.0, 20.0), (2, 550.0, 6.0, 20.0), (3, 580.0, 10.0, 20.0)], 0),
        (2.0, [], 1),                                                   # all empty: middle
        (10.0, [(1, 520.0, 6.0, 20.0)], 2),                              # tie 0/2: ego's
        (2.0, [(1, 520.0, 6.0, 20.0)], 0),
        (10.0, [(1, 520.0, 2.0, 20.0)], 1),                              # tie 1/2: middle
        (6.0, [(1, 520.0, 6.0, 20.0), (2, 400.0, 2.0, 20.0)], 0),       # behind ignored
    ],
)
def test_preferred_lane_is_the_furthest_ahead_with_middle_then_ego_ties(ego_d, cars,
                                                                         preferred):
    world = Perception(ROAD).perceive(observation(ROAD, 500.0, ego_d, cars), 0.0)
    assert world.preferred_lane == preferred


# ---------------------------------------------------------------------- ghosting
@pytest.mark.parametrize(
    ("s_offset", "d", "ghosted"),
    [
        (15.0, 8.9, True),    # ahead within 20 m, 2.9 m sideways
        (-5.0, 3.2, True),    # behind within 10 m, left lane
        (0.0, 9.0, True),     # alongside
        (25.0, 8.9, False),   # too far ahead
        (-12.0, 8.9, False),  # too far behind
        (15.0, 9.5, False),   # 3.5 m sideways
    ],
)
def test_ghosting_puts_drifting_adjacent_cars_ahead_in_the_ego_lane(s_offset, d, ghosted):
    ego_s = L - 5.0  # across the seam for positive offsets
    obs = observation(ROAD, ego_s, 6.0, [(9, ego_s + s_offset, d, 17.0)])
    plain = Perception(ROAD).perceive(obs, 0.0)
    ghosting = Perception(ROAD, PerceptionParameters(ghosting=True)).perceive(obs, 0.0)
    own_lane = int(ROAD.lane_of(d))
    assert not plain.lanes[1].has_ahead
    assert plain.lanes[own_lane] == ghosting.lanes[own_lane]  # stays in its own lane too
    view = ghosting.lanes[1]
    if ghosted:
        assert view.ahead_id == 9
        assert view.ahead_gap == pytest.approx(abs(s_offset), abs=1e-2)
        assert view.ahead_speed == pytest.approx(17.0, abs=1e-3)
    else:
        assert not view.has_ahead


def test_ghost_only_replaces_a_farther_car_ahead():
    cars = [(1, 508.0, 6.0, 15.0), (2, 515.0, 8.8, 20.0)]
    params = PerceptionParameters(ghosting=True)
    world = Perception(ROAD, params).perceive(observation(ROAD, 500.0, 6.0, cars), 0.0)
    assert world.lanes[1].ahead_id == 1
    cars = [(1, 530.0, 6.0, 15.0), (2, 515.0, 8.8, 20.0)]
    world = Perception(ROAD, params).perceive(observation(ROAD, 500.0, 6.0, cars), 0.0)
    assert (world.lanes[1].ahead_id, world.lanes[1].ahead_gap) == (2, pytest.approx(15.0,
                                                                                    abs=1e-2))


# ---------------------------------------------------------------------- faulty sensor
def test_faulty_sd_rows_are_recomputed_from_xy():
    true_s, true_d = L - 3.0, 2.0
    obs = observation(ROAD, L - 20.0, 2.0, [(4, true_s, true_d, 20.0),
                                            (5, 40.0, 6.0, 21.0),
                                            (6, 60.0, 10.0, 22.0)])
    obs["sensor_fusion"][0, 5:7] = 0.0            # the original's quirk: s = d = 0
    obs["sensor_fusion"][1, 5] += 50.0            # s inconsistent with x, y by 50 m
    obs["sensor_fusion"][2, 5:7] += [1.0, 0.5]    # within tolerance: kept as reported
    world = Perception(ROAD).perceive(obs, 0.0)

    faulty = car(world, 4)
    assert faulty.s == pytest.approx(true_s, abs=1e-2)
    assert faulty.d == pytest.approx(true_d, abs=1e-2)
    assert faulty.speed == pytest.approx(20.0, abs=1e-3)
    assert world.lanes[0].ahead_id == 4
    assert world.lanes[0].ahead_gap == pytest.approx(17.0, abs=1e-2)  # 20 m if s read 0
    assert car(world, 5).s == pytest.approx(40.0, abs=1e-2)
    assert (car(world, 6).s, car(world, 6).d) == pytest.approx((61.0, 10.5), abs=1e-3)


# ---------------------------------------------------------------------- road radius
@pytest.mark.parametrize("radius", [300.0, 1000.0])
def test_road_radius_on_a_circle_is_radius_plus_lane_offset(radius):
    road = circle_map(radius)
    perception = Perception(road)
    for lane in range(3):
        d = float(road.lane_center(lane))
        for s in (0.0, 123.4, road.length - 30.0):
            world = perception.perceive(observation(road, s, d), 0.0)
            assert world.ego_lane == lane
            assert world.road_radius == pytest.approx(radius + d, rel=1e-3)


def test_road_radius_on_the_oval_straight_and_bend():
    oval = get_highway_map("oval")  # 230 m straights from s = 0, then a 150 m half circle
    perception = Perception(oval)
    straight = perception.perceive(observation(oval, 55.0, 6.0), 0.0).road_radius
    bend = perception.perceive(observation(oval, 400.0, 6.0), 0.0).road_radius
    assert bend == pytest.approx(156.0, rel=2e-2)
    assert straight > 5000.0
    spaced = Perception(oval, PerceptionParameters(radius_spacing=30.0))
    assert spaced.road_radius(100.0, 1) > 5000.0
    assert spaced.road_radius(420.0, 2) == pytest.approx(160.0, rel=2e-2)


# ---------------------------------------------------------------------- tracking
def test_tracking_beats_raw_measurements_under_noise_across_the_seam():
    rng = np.random.default_rng(7)
    reference = ROAD.reference
    car_rate, ego_rate, d = 21.0, 20.0, 6.0   # s rates (m/s): a constant-speed drive
    car_s0, ego_s0 = L - 150.0, L - 170.0
    raw = Perception(ROAD)
    tracked = Perception(ROAD, PerceptionParameters(tracking=True))
    errors = {"raw": [], "tracked": []}
    crossed_filter = None
    for step in range(400):
        t = step * CYCLE
        s, ego_s = (car_s0 + car_rate * t) % L, (ego_s0 + ego_rate * t) % L
        speed = lane_speed(s, d, car_rate)
        obs = observation(ROAD, ego_s, 6.0, [(7, s, d, speed)])
        fusion = obs["sensor_fusion"].astype(np.float64)
        fusion[:, [1, 2, 5, 6]] += rng.normal(0.0, 1.0, (1, 4))
        fusion[:, [3, 4]] += rng.normal(0.0, 1.0, (1, 2))
        fusion[:, 5] %= L
        obs["sensor_fusion"] = fusion.astype(np.float32)
        true_gap = float(reference.s_difference(s, ego_s))
        for name, perception in (("raw", raw), ("tracked", tracked)):
            seen = car(perception.perceive(obs, t), 7)
            errors[name].append((seen.gap - true_gap, seen.speed - speed))
        if step == 150:
            crossed_filter = tracked._filters[7]
    # One track all along: the car crossed the seam at t ~ 7 s without a restart.
    assert tracked.tracked_ids == (7,)
    assert tracked._filters[7] is crossed_filter
    raw_rms = np.sqrt(np.mean(np.square(errors["raw"][50:]), axis=0))
    tracked_rms = np.sqrt(np.mean(np.square(errors["tracked"][50:]), axis=0))
    assert raw_rms == pytest.approx([1.0, 1.0], rel=0.25)  # the noise we added
    assert tracked_rms[0] < 0.6 * raw_rms[0]                # gap
    assert tracked_rms[1] < 0.4 * raw_rms[1]                # speed
    seam = slice(int(140 / (car_rate * CYCLE)) - 5, int(150 / (car_rate * CYCLE)) + 20)
    assert np.max(np.abs(np.array(errors["tracked"])[seam, 0])) < 2.0


def test_tracking_predicts_through_dropouts_and_drops_stale_tracks():
    params = PerceptionParameters(tracking=True, track_timeout=0.5)
    perception = Perception(ROAD, params)
    s0, speed = 600.0, 20.0

    def obs_at(step, mask):  # both cars at an s rate of ``speed``
        s = s0 + speed * step * CYCLE
        return observation(ROAD, 580.0 + speed * step * CYCLE, 6.0,
                           [(3, s, 6.0, lane_speed(s, 6.0, speed)),
                            (4, s + 30.0, 10.0, lane_speed(s + 30.0, 10.0, speed))], mask=mask)

    for step in range(20):
        perception.perceive(obs_at(step, [1, 1]), step * CYCLE)
    for step in range(20, 25):  # car 3 missing: predicted at constant speed
        world = perception.perceive(obs_at(step, [0, 1]), step * CYCLE)
        assert car(world, 3).s == pytest.approx(s0 + speed * step * CYCLE, abs=0.05)
        assert world.lanes[1].ahead_id == 3
        assert world.lanes[1].ahead_gap == pytest.approx(20.0, abs=0.05)
    assert perception.tracked_ids == (3, 4)
    for step in range(25, 40):  # gone for over 0.5 s: dropped
        world = perception.perceive(obs_at(step, [0, 1]), step * CYCLE)
    assert perception.tracked_ids == (4,)
    assert [c.id for c in world.cars] == [4]
    assert not world.lanes[1].has_ahead
    # A recycled car (new id, far away) starts a new track; an earlier time starts afresh.
    world = perception.perceive(observation(ROAD, 580.0, 6.0, [(11, 700.0, 2.0, 15.0)]),
                                40 * CYCLE)
    assert perception.tracked_ids == (4, 11)
    perception.perceive(observation(ROAD, 580.0, 6.0, [(12, 700.0, 2.0, 15.0)]), 0.0)
    assert perception.tracked_ids == (12,)
    perception.reset()
    assert perception.tracked_ids == ()


def test_tracked_cars_are_ordinary_frozen_dataclasses():
    world = Perception(ROAD).perceive(observation(ROAD, 500.0, 6.0,
                                                  [(1, 510.0, 6.0, 20.0)]), 0.0)
    (tracked,) = world.cars
    rebuilt = TrackedCar(**dataclasses.asdict(tracked))
    assert tracked == rebuilt and hash(tracked) == hash(rebuilt)
    assert repr(tracked) == repr(rebuilt)
    with pytest.raises(dataclasses.FrozenInstanceError):
        tracked.s = 0.0  # type: ignore[misc]


# ---------------------------------------------------------------------- the real env
def nearest_by_lane(road, ego_s, s, d, ids, reach=200.0):
    """Brute-force nearest ahead/behind per lane from ground truth: {lane: (ahead, behind)}."""
    gaps = road.reference.s_difference(s, ego_s)
    lanes = road.lane_of(d)
    answer = {}
    for lane in range(road.lane_count):
        ahead = [(g, i) for g, i, k in zip(gaps, ids, lanes, strict=True)
                 if k == lane and 0 <= g <= reach]
        behind = [(-g, i) for g, i, k in zip(gaps, ids, lanes, strict=True)
                  if k == lane and -reach <= g < 0]
        answer[lane] = (min(ahead, default=(math.inf, NO_CAR)),
                        min(behind, default=(math.inf, NO_CAR)))
    return answer


def check_against_traffic(env, world):
    base = env.unwrapped
    traffic, road = base.traffic, base.road
    assert world.ego_s == pytest.approx(base._s, abs=2e-3)
    for car_id, s, d, speed in zip(traffic.ids.tolist(), traffic.s, traffic.d, traffic.speed,
                                   strict=True):
        seen = car(world, car_id)
        assert road.reference.s_difference(seen.s, s) == pytest.approx(0.0, abs=5e-3)
        assert seen.d == pytest.approx(d, abs=5e-3)
        assert seen.speed == pytest.approx(speed, abs=1e-2)
    truth = nearest_by_lane(road, world.ego_s, traffic.s, traffic.d, traffic.ids.tolist())
    for view in world.lanes:
        (ahead_gap, ahead_id), (behind_gap, behind_id) = truth[view.lane]
        assert (view.ahead_id, view.behind_id) == (ahead_id, behind_id)
        assert view.ahead_gap == pytest.approx(ahead_gap, abs=5e-3)
        assert view.behind_gap == pytest.approx(behind_gap, abs=5e-3)


def test_world_model_matches_the_env_ground_truth():
    env = gym.make("sdc_gym/HighwayLoop-v0")
    obs, _ = env.reset(seed=0)
    road = env.unwrapped.road
    driver = LaneKeepingDriver(road)
    perception = Perception(road)
    tracker = Perception(road, PerceptionParameters(tracking=True))
    steps = env.unwrapped.config["steps_per_action"]
    for step in range(1, 41):
        obs, *_ = env.step(driver.act(obs))
        time = step * steps * 0.02
        world = perception.perceive(obs, time)
        check_against_traffic(env, world)
        tracked = tracker.perceive(obs, time)
        traffic = env.unwrapped.traffic
        for car_id, s, speed in zip(traffic.ids.tolist(), traffic.s, traffic.speed,
                                    strict=True):
            # Perfect sensors: the filter sits on the truth (within a car's acceleration lag).
            seen = car(tracked, car_id)
            assert road.reference.s_difference(seen.s, s) == pytest.approx(0.0, abs=0.25)
            assert seen.speed == pytest.approx(speed, abs=1.0)
    env.close()


def test_tracking_beats_raw_in_the_env_with_noisy_sensors_and_dropouts():
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"sensors": {
        "position_noise": 1.0, "velocity_noise": 1.0, "dropout_probability": 0.05}})
    obs, _ = env.reset(seed=1)
    road = env.unwrapped.road
    driver = LaneKeepingDriver(road)
    raw = Perception(road)
    tracked = Perception(road, PerceptionParameters(tracking=True))
    errors = {"raw": [], "tracked": []}
    for step in range(1, 201):
        obs, *_ = env.step(driver.act(obs))
        traffic = env.unwrapped.traffic
        for name, perception in (("raw", raw), ("tracked", tracked)):
            seen = {c.id: c for c in perception.perceive(obs, step * CYCLE).cars}
            for car_id, s, speed in zip(traffic.ids.tolist(), traffic.s, traffic.speed,
                                        strict=True):
                if car_id in seen and step > 20:
                    errors[name].append((road.reference.s_difference(seen[car_id].s, s),
                                         seen[car_id].speed - speed))
    raw_rms = np.sqrt(np.mean(np.square(errors["raw"]), axis=0))
    tracked_rms = np.sqrt(np.mean(np.square(errors["tracked"]), axis=0))
    assert raw_rms == pytest.approx([1.0, 1.0], rel=0.15)
    assert tracked_rms[0] < 0.5 * raw_rms[0]
    assert tracked_rms[1] < 0.6 * raw_rms[1]
    # Dropouts are predicted through: the tracker reports (nearly) every car every cycle.
    assert len(errors["tracked"]) > len(errors["raw"])
    env.close()


def test_env_faulty_sensor_rows_near_the_seam_are_repaired():
    env = gym.make("sdc_gym/HighwayLoop-v0", config={
        "start_s": float(get_highway_map("default").length - 150.0),
        "sensors": {"zero_sd_probability": 1.0}})
    obs, _ = env.reset(seed=3)
    driver = LaneKeepingDriver(env.unwrapped.road)
    perception = Perception(env.unwrapped.road)
    faults = 0
    for step in range(1, 31):
        obs, *_ = env.step(driver.act(obs))
        rows = obs["sensor_fusion"][obs["sensor_fusion_mask"] == 1]
        faults += int(np.sum((rows[:, 5] == 0) & (rows[:, 6] == 0)))
        check_against_traffic(env, perception.perceive(obs, step * 0.06))
    assert faults > 20  # the quirk really happened
    env.close()


def test_lane_views_and_world_models_are_ordinary_frozen_dataclasses():
    world = Perception(ROAD, PerceptionParameters(ghosting=True)).perceive(
        observation(ROAD, 500.0, 6.0, [(1, 510.0, 6.0, 20.0), (2, 490.0, 2.0, 18.0)]), 0.0)
    rebuilt = WorldModel(**{f.name: getattr(world, f.name) for f in dataclasses.fields(world)})
    assert world == rebuilt and hash(world) == hash(rebuilt) and repr(world) == repr(rebuilt)
    for view in world.lanes:
        again = type(view)(**dataclasses.asdict(view))
        assert view == again and hash(view) == hash(again) and repr(view) == repr(again)
    assert world.lanes[1].ahead_id == 1 and world.lanes[0].behind_id == 2
    with pytest.raises(dataclasses.FrozenInstanceError):
        world.ego_s = 0.0  # type: ignore[misc]


def test_fast_constructors_fall_back_to_the_class_when_it_has_its_own_init_logic():
    from sdc_gym.stack.highway.perception import _fast_constructor

    @dataclasses.dataclass(frozen=True)
    class Checked:
        value: float

        def __post_init__(self) -> None:
            if self.value < 0:
                raise ValueError("negative")

    assert _fast_constructor(Checked) is Checked
    make = _fast_constructor(TrackedCar)
    car = make(1, 2.0, 3.0, 4.0, 5.0, 0, 6.0)
    assert car == TrackedCar(1, 2.0, 3.0, 4.0, 5.0, 0, 6.0) and type(car) is TrackedCar



def test_road_tables_are_built_once_per_road_and_shared_read_only():
    """A batch's Perceptions share one set of road tables (the audit's 4.9 MB per env was a
    copy each): the same arrays, not writeable, rebuilt for another radius spacing; and a
    batch of 64 behavior envs grows the tables' memory by nothing per env."""
    import tracemalloc

    from sdc_gym.stack.highway.perception import road_tables

    first, second = Perception(ROAD), Perception(ROAD)
    assert first._geometry is second._geometry
    assert first._geometry_xy_rows is second._geometry_xy_rows
    assert first._circle_curvature is second._circle_curvature
    with pytest.raises(ValueError, match="read-only"):
        first._geometry_xy_rows[0, 0] = 1.0
    other = Perception(ROAD, PerceptionParameters(radius_spacing=30.0))
    assert np.array_equal(other._geometry, first._geometry)
    assert other._circle_curvature is not first._circle_curvature
    assert road_tables(ROAD, 60.0) is road_tables(ROAD, 60.0)
    # The real-valued rows are the complex table's parts (what the per-car Python path reads).
    tables = road_tables(ROAD, 60.0)
    assert np.array_equal(tables.geometry_xy_rows[:, 0], tables.geometry[0].real)
    assert np.array_equal(tables.geometry_xy_rows[:, 8], tables.geometry[4].imag)
    tracemalloc.start()
    envs = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=64,
                        vectorization_mode="vector_entry_point")
    held, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    envs.close()
    assert held / 64 < 1.0e6, f"{held / 64 / 1e6:.2f} MB per env"  # was ~5.1 MB
