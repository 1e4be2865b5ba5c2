"""The drive-by-wire reference stack (sdc_agents.track): each node against known answers, then
the wired agent driving the site track in closed loop."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.road.builtin_tracks import get_track_map
from sdc_gym.road.track_map import TrackMap
from sdc_gym.stack.track.behavior import StopAtRedLights, StopAtRedParameters, TrackSituation
from sdc_gym.stack.track.controllers import (
    PID,
    LowPassFilter,
    TwistController,
    TwistControllerParameters,
    YawController,
)
from sdc_gym.stack.track.detector import (
    DetectorParameters,
    GroundTruthLightSource,
    LightStateSource,
    TrafficLightDetector,
)
from sdc_gym.stack.track.follower import PurePursuit, curvature_to_point
from sdc_gym.stack.track.rates import RateScheduler, node_rates
from sdc_gym.stack.track.waypoints import (
    FinalWaypoints,
    UpdaterParameters,
    WaypointUpdater,
    load_waypoints,
    stop_line_waypoints,
)
from sdc_gym.vehicle.dbw_vehicle import DBWVehicle, vehicle_parameters

SIM = vehicle_parameters("sim")
SITE = vehicle_parameters("site")
DT = 0.02


def circle_track(count: int = 400, radius: float = 400 / (2 * math.pi),
                 stop_angles: tuple[float, ...] = ()) -> TrackMap:
    """A counter-clockwise circle of ``count`` waypoints (about 1 m apart by default)."""
    angles = np.arange(count) * 2 * math.pi / count
    xy = radius * np.column_stack([np.cos(angles), np.sin(angles)])
    waypoints = np.column_stack([xy, np.zeros(count), angles + math.pi / 2])
    stops = [[radius * math.cos(a), radius * math.sin(a)] for a in stop_angles]
    return TrackMap.from_waypoints("circle", waypoints, stops)


# ------------------------------------------------------------------------------ controllers
def test_pid_clamps_and_keeps_the_integral_only_while_not_clamped():
    pid = PID(0.8, 0.25, 0.1, -5.0, 1.0)
    # No derivative on the first sample: 0.8 * 0.5 + 0.25 * 0.01.
    assert pid.step(0.5, DT) == pytest.approx(0.4025)
    assert pid.integral == pytest.approx(0.01)
    # Saturated high (8 + 47.5 kick, then 8.05): the integral does not grow.
    assert pid.step(10.0, DT) == 1.0
    assert pid.step(10.0, DT) == 1.0
    assert pid.integral == pytest.approx(0.01)
    # The derivative (0.2 - 10) / 0.02 = -490 saturates low: still no integration.
    assert pid.step(0.2, DT) == -5.0
    assert pid.integral == pytest.approx(0.01)
    # Unclamped again: integrates from 0.01 (a wound-up integral would hold 0.41 here).
    assert pid.step(0.2, DT) == pytest.approx(0.16 + 0.25 * 0.014)
    assert pid.integral == pytest.approx(0.014)
    pid.reset()
    assert pid.integral == 0.0 and pid.step(1.0, DT) == pytest.approx(0.8 + 0.25 * DT)


def test_low_pass_step_response_is_one_minus_one_minus_a_to_the_n():
    lpf = LowPassFilter(tau_s=0.1, ts_s=DT)
    assert lpf.a == pytest.approx(1 / 6)
    for n in range(1, 11):
        assert lpf.filt(1.0) == pytest.approx(1 - (5 / 6) ** n)
    assert LowPassFilter(0.0, DT).filt(0.7) == 0.7  # tau 0: no filtering


def test_yaw_controller_steers_the_bicycle_angle_of_a_known_radius():
    yaw = YawController(wheel_base=3.0, steer_ratio=14.8, min_speed=0.1, max_lat_accel=3.0,
                        max_steer_angle=8.0)
    expected = 14.8 * math.atan(3.0 / 50.0)  # R = 50 m
    assert yaw.steering(10.0, 10.0 / 50.0, 10.0) == pytest.approx(expected)
    # Same path curvature at half the current speed: w' = v_current w / v_target.
    assert yaw.steering(10.0, 10.0 / 50.0, 5.0) == pytest.approx(expected)
    assert yaw.steering(10.0, -10.0 / 50.0, 10.0) == pytest.approx(-expected)
    assert yaw.steering(0.0, 0.3, 5.0) == 0.0  # no target speed: straight


def test_yaw_controller_limits_lateral_acceleration_and_steering_angle():
    yaw = YawController(3.0, 14.8, 0.1, 3.0, 8.0)
    # R = 20 m at 10 m/s would be 5 m/s^2: the yaw rate is limited to 3 / 10 rad/s.
    assert yaw.steering(10.0, 0.5, 10.0) == pytest.approx(14.8 * math.atan(3.0 * 0.3 / 10.0))
    # A 2 m radius at 1 m/s needs 14.8 atan(1.5) = 14.5 rad at the wheel: clamped to 8.
    assert yaw.steering(1.0, 0.5, 1.0) == 8.0
    assert yaw.steering(1.0, -0.5, 1.0) == -8.0


def test_brake_torque_is_mass_times_deceleration_times_wheel_radius_beyond_the_deadband():
    controller = TwistController(SIM, DT)
    assert controller.longitudinal(-2.0) == (0.0, pytest.approx(1080.0 * 2.0 * 0.335))
    assert controller.longitudinal(-0.15) == (0.0, 0.0)  # inside the 0.2 deadband: coast
    assert controller.longitudinal(0.5) == (0.5, 0.0)
    site = TwistController(SITE, DT)
    total = 1736.35 + 13.5 * 2.858  # fuel counts
    assert site.longitudinal(-0.5) == (0.0, pytest.approx(total * 0.5 * 0.2413))
    assert site.longitudinal(-0.05) == (0.0, 0.0)  # site deadband 0.1


# A sim car creeping at idle, held by 400 N m (the sim preset before issue 19).
CREEPING_SIM = SIM.replace(creep_hold_torque=400.0, rolling_resistance=0.015)


@pytest.mark.parametrize(("params", "hold"), [(CREEPING_SIM, 500.0), (SITE, 875.0)])
def test_holding_torque_at_standstill_beats_the_idle_creep(params, hold):
    controller = TwistController(params, DT)
    command = controller.control(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, True)
    assert controller.holding and command.throttle == 0.0
    assert command.brake_torque == pytest.approx(hold)  # 1.25 x 400 / 700 N m
    car = DBWVehicle(params)
    car.reset(0.0, 0.0, 0.0, brake_torque=command.brake_torque)  # parked, brake applied
    for _ in range(100):
        car.step(0.0, command.brake_torque, 0.0)
    assert car.state.speed == 0.0 and car.state.x == 0.0
    car.reset(0.0, 0.0, 0.0, brake_torque=0.9 * params.creep_hold_torque)
    for _ in range(100):  # 90 % of the creep's torque does not hold
        car.step(0.0, 0.9 * params.creep_hold_torque, 0.0)
    assert car.state.x > 0.0


def test_the_sim_car_needs_no_holding_torque_and_stays_at_its_stop():
    """The original's car does not creep: at a standstill the controller brakes only as
    the PID asks (nothing once at rest) and the car stays where it stopped."""
    controller = TwistController(SIM, DT)
    assert controller.hold_torque == 0.0
    car = DBWVehicle(SIM)
    car.reset(0.0, 0.0, 0.0, speed=1.0)
    for step in range(500):  # 10 s with a stop target from 1 m/s
        command = controller.control(step * DT, 0.0, 0.0, step * DT, car.state.speed,
                                     step * DT, True)
        assert command.throttle == 0.0
        car.step(command.throttle, command.brake_torque, command.steering)
    assert controller.holding and car.state.speed == 0.0
    stopped_at = car.state.x
    assert 0.0 < stopped_at < 1.0  # braked from 1 m/s, then parked
    for step in range(500, 1000):
        command = controller.control(step * DT, 0.0, 0.0, step * DT, 0.0, step * DT, True)
        car.step(command.throttle, command.brake_torque, command.steering)
    assert car.state.x == stopped_at


def test_manual_mode_resets_so_that_resuming_has_no_throttle_jump():
    controller = TwistController(SIM, DT)
    for step in range(200):  # a long speed error winds the integral up to its clamp
        controller.control(step * DT, 11.0, 0.0, step * DT, 10.5, step * DT, True)
    assert controller.pid_integral > 1.0
    assert controller.control(4.0, 11.0, 0.0, 4.0, 10.5, 4.0, False) == (
        controller.control(4.02, 11.0, 0.0, 4.02, 10.5, 4.02, False))
    command = controller.control(4.04, 11.0, 0.0, 4.04, 10.5, 4.04, False)
    assert (command.throttle, command.brake_torque, command.steering) == (0.0, 0.0, 0.0)
    assert controller.pid_integral == 0.0 and controller.filter_value == 0.0
    resumed = controller.control(4.06, 11.0, 0.0, 4.06, 10.5, 4.06, True)
    # Fresh PID (no integral, no derivative kick), the filter rising from 0.
    a = controller.filter_gain
    assert resumed.throttle == pytest.approx(a * (0.8 * 0.5 + 0.25 * 0.5 * DT))


def test_twist_controller_watchdog_stops_on_a_stale_twist_or_velocity():
    fresh = TwistController(SIM, DT).control(1.0, 10.0, 0.1, 1.0, 10.0, 1.0, True)
    assert fresh.brake_torque == 0.0
    for twist_time, velocity_time in ((0.4, 1.0), (1.0, 0.4)):
        controller = TwistController(SIM, DT)
        stale = controller.control(1.0, 10.0, 0.1, twist_time, 10.0, velocity_time, True)
        assert controller.stale and stale.throttle == 0.0 and stale.brake_torque > 0.0
        assert stale.steering == 0.0  # target speed 0: the yaw controller steers straight


def test_controller_parameters_are_validated():
    with pytest.raises(ValueError, match="hold_torque_margin must be > 1"):
        TwistControllerParameters(hold_torque_margin=1.0)
    with pytest.raises(ValueError, match="min_output must be < max_output"):
        PID(1, 0, 0, 1.0, -1.0)
    with pytest.raises(ValueError, match="dt must be > 0"):
        PID(1, 0, 0).step(1.0, 0.0)


# ------------------------------------------------------------------------------ follower
def test_pure_pursuit_curvature_of_a_point_on_a_known_circle_is_one_over_r():
    radius = 20.0
    for theta in (0.1, 0.5, 1.0):  # points on the circle through the car, tangent to +x
        x, y = radius * math.sin(theta), radius - radius * math.cos(theta)
        assert 2 * y / (x * x + y * y) == pytest.approx(1 / radius)
        assert curvature_to_point(0.0, 0.0, 0.0, x, y) == pytest.approx(1 / radius)
        # The same geometry rotated and moved: the car's frame is what counts.
        c, s = math.cos(2.0), math.sin(2.0)
        assert curvature_to_point(5.0, -3.0, 2.0, 5.0 + c * x - s * y, -3.0 + s * x + c * y) \
            == pytest.approx(1 / radius)


def final_on_circle(radius: float, speed: float, spacing: float = 0.5,
                    count: int = 100) -> FinalWaypoints:
    theta = np.arange(count) * spacing / radius
    x, y = radius * np.sin(theta), radius - radius * np.cos(theta)
    return FinalWaypoints(np.arange(count), x, y, np.full(count, speed), 0.0)


def test_pure_pursuit_follows_a_circle_and_keeps_its_command_while_on_the_path():
    follower = PurePursuit()
    assert follower.lookahead_distance(2.0) == 6.0 and follower.lookahead_distance(10.0) == 20.0
    final = final_on_circle(40.0, speed=7.0)
    # On the path and aligned: "following", the previous angular velocity (0) is kept.
    twist = follower.follow(0.0, 0.0, 0.0, 5.0, final)
    assert not follower.recomputed and twist.angular_radps == 0.0 and twist.linear_mps == 7.0
    # 0.3 m off the path: recomputed; the look-ahead point lies on the circle at L = 10 m.
    twist = follower.follow(0.0, -0.3, 0.0, 5.0, final)
    assert follower.recomputed
    assert math.dist((0.0, -0.3), follower.target) == pytest.approx(10.0)
    # Heading 10 degrees off (on the path): recomputed, curvature 1/R from the car on it.
    twist = follower.follow(0.0, 0.0, math.radians(10.0), 5.0, final)
    assert follower.recomputed
    x, y = follower.target
    assert math.hypot(x, y - 40.0) == pytest.approx(40.0, abs=1e-3)  # chord interpolation
    assert curvature_to_point(0.0, 0.0, 0.0, x, y) == pytest.approx(1 / 40.0, rel=1e-3)
    assert twist.angular_radps == pytest.approx(5.0 * follower.curvature)


# ------------------------------------------------------------------------------ waypoints
def test_loader_sets_the_limit_everywhere_without_a_slow_down_at_the_seam():
    track = get_track_map("site")
    waypoints = load_waypoints(track)
    assert np.all(waypoints.speed == track.speed_limit_mps)
    assert waypoints.length == pytest.approx(track.length, rel=2e-3)
    quirk = load_waypoints(track, 5.0, seam_ramp=True)  # the original's end-of-list ramp
    assert quirk.speed[-1] == 0.0 and quirk.speed[0] == 5.0
    to_end = quirk.s[-1] - quirk.s
    ramped = np.sqrt(2.0 * to_end) < 5.0
    assert np.allclose(quirk.speed[ramped & (quirk.speed > 0)],
                       np.sqrt(2.0 * to_end[ramped & (quirk.speed > 0)]))
    with pytest.raises(ValueError, match="speed_limit_mps must be a finite number > 0"):
        load_waypoints(track, 0.0)


def test_updater_window_wraps_at_the_seam_and_searches_fully_when_far():
    waypoints = load_waypoints(circle_track(count=400))
    n = len(waypoints)
    updater = WaypointUpdater(waypoints, UpdaterParameters(count=50))
    # Standing exactly on a waypoint: it is not ahead, its successor is.
    assert updater.next_waypoint(*waypoints.xy[n - 2], waypoints.yaw[n - 2]) == n - 1
    assert updater.full_searches == 1
    # Standing just behind waypoint n - 2: it is the next one (ahead of the car).
    x, y = waypoints.xy[n - 2] - 0.3 * np.array([math.cos(waypoints.yaw[n - 2]),
                                                 math.sin(waypoints.yaw[n - 2])])
    assert updater.next_waypoint(x, y, waypoints.yaw[n - 2]) == n - 2
    # Across the seam: 3 waypoints on, found in the window (no new full search).
    x, y = waypoints.xy[1] + 0.2 * np.array([math.cos(waypoints.yaw[1]),
                                             math.sin(waypoints.yaw[1])])
    assert updater.next_waypoint(x, y, waypoints.yaw[1]) == 2
    assert updater.full_searches == 1 and updater.previous_index == 1
    # Far from the window (half a lap on): full search again. Waypoint 200 is at (-R, 0),
    # the car 0.1 m past it heading -y: the next one is 201.
    assert updater.next_waypoint(*(waypoints.xy[200] - [0.0, 0.1]), waypoints.yaw[200]) == 201
    assert updater.full_searches == 2
    final = updater.update(10.0, *waypoints.xy[n - 10], waypoints.yaw[n - 10], 10.0)
    assert len(final) == 50 and final.indices[0] == n - 9
    assert list(final.indices[8:10]) == [n - 1, 0]  # consecutive across the seam
    assert final.indices[-1] == 40


def test_stop_ramp_zero_from_the_margin_and_a_monotone_ramp_before_it():
    track = circle_track(count=400, stop_angles=(math.pi,))  # a stop line half a lap on
    waypoints = load_waypoints(track, 10.0)
    line = int(stop_line_waypoints(track, waypoints)[0])
    params = UpdaterParameters(count=200, stop_margin_m=5.0, stop_decel_mps2=1.5)
    updater = WaypointUpdater(waypoints, params, track.stop_lines_xy)
    start = line - 120
    final = updater.update(0.0, *waypoints.xy[start], waypoints.yaw[start], 0.0, line, 0.0)
    along = (waypoints.s[final.indices] - waypoints.s[final.indices[0]]) % waypoints.length
    (position,) = np.flatnonzero(final.indices == line)
    line_at = along[position] + updater.stop_line_offsets[line]
    to_stop = line_at - 5.0 - along
    assert np.all(final.speed[to_stop <= 0] == 0.0)  # the stop point on, past the line too
    assert np.all(final.speed[to_stop > 10.0] > 0.0)
    assert np.all(np.diff(final.speed) <= 0.0)  # monotone down to the stop
    ramp = (to_stop > 0) & (final.speed < 10.0) & (final.speed > 0)
    assert np.allclose(final.speed[ramp], np.sqrt(3.0 * to_stop[ramp]))
    assert ramp.sum() > 20 and np.all(final.speed[(to_stop > 0) & ~ramp & (final.speed > 0)]
                                      == 10.0)
    # A target speed caps every waypoint; no stop: the base speeds.
    capped = updater.update(0.0, *waypoints.xy[start], waypoints.yaw[start], 0.0, -1, 0.0, 4.0)
    assert np.all(capped.speed == 4.0) and not capped.emergency


def test_updater_watchdog_zeroes_speeds_on_stale_pose_or_light():
    waypoints = load_waypoints(circle_track())
    updater = WaypointUpdater(waypoints)
    pose = (*waypoints.xy[10], waypoints.yaw[10])
    assert np.all(updater.update(1.0, *pose, 0.6, -1, 0.6).speed > 0)  # 0.4 s old: fine
    for pose_time, light_time in ((0.4, 1.0), (1.0, 0.4)):
        final = updater.update(1.0, *pose, pose_time, -1, light_time)
        assert final.emergency and np.all(final.speed == 0.0)


# ------------------------------------------------------------------------------ detector
class Scripted:
    """A light state source returning the given states in turn (counts its calls)."""

    def __init__(self, *states: int) -> None:
        self.states = list(states)

    def classify(self, observation) -> int:
        return self.states.pop(0)


def test_detector_needs_three_identical_states_and_publishes_the_red_line_waypoint():
    detector = TrafficLightDetector([123, 456])
    reports = [detector.process(i * DT, 1, 50.0, lambda s=s: s)
               for i, s in enumerate([RED, RED, RED, GREEN, RED, GREEN, GREEN, GREEN])]
    assert [r.state for r in reports] == [UNKNOWN, UNKNOWN, RED, RED, RED, RED, RED, GREEN]
    assert [r.red_light_waypoint for r in reports] == [-1, -1, 456, 456, 456, 456, 456, -1]
    assert reports[2].stop_waypoint == 456 and reports[2].time_s == pytest.approx(2 * DT)


def test_detector_looks_only_within_70_m_and_forgets_a_passed_line():
    source = Scripted(*[RED] * 10)
    detector = TrafficLightDetector([7, 8], source)
    observation = {"next_stop_line": np.array([0.0, 70.5], dtype=np.float32)}
    for i in range(3):
        assert detector.detect(observation, i * DT).state == UNKNOWN
    assert detector.classifications == 0 and len(source.states) == 10
    observation["next_stop_line"][1] = 69.5
    states = [detector.detect(observation, 0.1 + i * DT).state for i in range(3)]
    assert states == [UNKNOWN, UNKNOWN, RED] and detector.classifications == 3
    # The next line: the old state does not carry over.
    assert detector.process(1.0, 1, 60.0, lambda: RED).state == UNKNOWN
    assert detector.process(1.0, -1, math.inf, lambda: RED).stop_waypoint == -1


def test_light_sources_follow_the_protocol_and_read_the_ground_truth():
    source = GroundTruthLightSource()
    assert isinstance(source, LightStateSource) and isinstance(Scripted(), LightStateSource)
    observation = {"next_stop_line": np.array([2.0, 40.0]),
                   "light_states": np.array([GREEN, GREEN, YELLOW], dtype=np.int8)}
    assert source.classify(observation) == YELLOW
    assert source.classify({"next_stop_line": np.array([-1.0, 9.0])}) == UNKNOWN
    with pytest.raises(KeyError, match="observe_light_states"):
        source.classify({"next_stop_line": np.array([0.0, 9.0])})
    with pytest.raises(ValueError, match="valid codes"):
        TrafficLightDetector([0]).process(0.0, 0, 10.0, lambda: 3)
    with pytest.raises(ValueError, match="debounce_frames"):
        DetectorParameters(debounce_frames=0)


# ------------------------------------------------------------------------------ behavior
def situation(speed: float, distance: float, state: int) -> TrackSituation:
    return TrackSituation(time_s=0.0, speed_mps=speed, speed_limit_mps=11.0, stop_line=3,
                          stop_waypoint=99, stop_line_distance_m=distance, light_state=state,
                          stop_margin_m=5.6)


def test_behavior_stops_for_red_and_stoppable_yellow_and_commits_to_a_stop():
    policy = StopAtRedLights(StopAtRedParameters(max_decel_mps2=5.0))
    assert policy.decide(situation(11.0, 60.0, GREEN)).stop_waypoint == -1
    assert policy.decide(situation(11.0, 60.0, GREEN)).target_speed_mps == pytest.approx(10.85)
    assert policy.decide(situation(11.0, 60.0, RED)).mode == "stop_red"
    # Committed: crawling the last centimetres with no room left, it keeps stopping.
    assert policy.decide(situation(0.2, 5.0, RED)).stop_waypoint == 99
    assert policy.decide(situation(0.0, 5.0, GREEN)).mode == "cruise"
    # Red at 10 m doing 11 m/s needs 11^2 / (2 x 5.4 m) = 11.2 m/s^2: run, not brake.
    policy.reset()
    assert policy.decide(situation(11.0, 10.0, RED)).mode == "run_red"
    # Yellow: stop when 3.05 m/s^2 suffices (v^2 <= 2 a (room + 1 m)), else go.
    assert policy.decide(situation(11.0, 24.0, YELLOW)).mode == "go_yellow"  # 19.4 m room
    assert policy.decide(situation(11.0, 25.0, YELLOW)).mode == "stop_yellow"  # 121 / 6.1
    # = 19.8 m needed, 20.4 m room
    assert policy.decide(situation(11.0, 30.0, UNKNOWN)).mode == "cruise"
    no_yellow = StopAtRedLights(StopAtRedParameters(stop_on_yellow=False))
    assert no_yellow.decide(situation(11.0, 60.0, YELLOW)).mode == "go_yellow"


# ------------------------------------------------------------------------------ rates
def test_rate_scheduler_fires_each_node_at_its_rate_over_one_second():
    for preset, expected in (("original", {"detector": 50, "updater": 10, "follower": 30,
                                           "dbw": 50}),
                             ("seed", {"detector": 50, "updater": 2, "follower": 5,
                                       "dbw": 15})):
        scheduler = RateScheduler(DT, node_rates(preset).as_mapping())
        counts = dict.fromkeys(scheduler.names, 0)
        for _ in range(50):
            for name in scheduler.tick():
                counts[name] += 1
        assert counts == expected
        assert scheduler.time_s == pytest.approx(1.0)
    scheduler = RateScheduler(0.1, {"fast": 50.0, "slow": 4.0})  # a 10 Hz loop
    assert scheduler.rate("fast") == 10.0 and scheduler.rate("slow") == 4.0
    ticks = [i for i in range(10) if "slow" in scheduler.tick()]
    assert ticks == [0, 3, 5, 8]  # floor(0.4 k) grows: 4 runs, gaps of 2 or 3 ticks
    with pytest.raises(ValueError, match="rate of 'x' must be > 0 Hz"):
        RateScheduler(DT, {"x": 0.0})
    with pytest.raises(ValueError, match="unknown rate preset 'fast'"):
        node_rates("fast")


# ------------------------------------------------------------------------------ closed loop
def run_site(config: dict, *, laps: int = 1):
    from sdc_agents.track.dbw_agent import dbw_agent

    env = gym.make("sdc_gym/TrackLoop-v0", config={
        "track": "site", "observe_light_states": True, "laps": laps, "max_duration": 120.0,
        **config})
    agent = dbw_agent(env)
    observation, info = env.reset(seed=3)
    agent.reset()
    trace = []
    while True:
        action = agent.act(observation)
        observation, _, terminated, truncated, info = env.step(action)
        trace.append((info["time"], info["dbw_enabled"], float(action[0])))
        if terminated or truncated:
            return info["summary"], trace


def test_the_stack_drives_a_site_lap_stopping_at_the_red_light():
    # The one light is red for the first 25 s: the car must wait at its line, then go.
    summary, _ = run_site({"lights": {"script": [[[0, RED], [25.0, GREEN]]]}})
    assert summary["is_success"] and summary["red_light_violations"] == 0
    (stop,) = summary["stops"]
    assert stop["light_state"] == RED and -2.0 <= stop["offset_m"] <= 0.0
    assert summary["rms_cross_track_error"] < 0.35 and summary["max_cross_track_error"] < 1.0
    assert summary["max_lateral_acceleration"] <= 3.0
    assert sum(summary["incidents"].values()) == 0


def test_the_stack_resumes_after_manual_override_without_a_throttle_jump():
    summary, trace = run_site({"lights": {"script": [GREEN]},
                               "manual": {"mode": "scripted", "periods": [[8.0, 12.0]]}})
    # The manual driver may speed a little; the stack itself has no incident.
    assert summary["is_success"]
    assert all(8.0 <= incident["time"] <= 12.0 for incident in summary["incident_log"])
    resumed = next(i for i, (t, enabled, _) in enumerate(trace) if t > 12.0 and enabled)
    a = 1.0 / (0.1 / DT + 1.0)  # the filter's gain: the first command is at most a
    assert 0.0 <= trace[resumed][2] <= a
