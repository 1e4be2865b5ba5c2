"""The drive-by-wire car against closed-form answers, and the manual driver on an oval."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from sdc_gym.geometry.reference_line import ReferenceLine
from sdc_gym.vehicle import (
    PHYSICS_DT,
    SIM_VEHICLE,
    SITE_VEHICLE,
    DBWVehicle,
    DriverStyle,
    ManualDriver,
    VehicleParameters,
    vehicle_parameters,
)
from sdc_gym.vehicle.manual_driver import braking_distance

# Physics off: no drag, rolling resistance, creep or coming to rest (closed-form kinematics).
NO_RESISTANCE = {"drag_coefficient": 0.0, "rolling_resistance": 0.0, "creep_hold_torque": 0.0,
                 "linear_drag": 0.0, "rest_speed": 0.0}
# An automatic creeping at idle, held by 400 N m (the sim preset before issue 19).
CREEPING = {"creep_hold_torque": 400.0, "rolling_resistance": 0.015, "drag_coefficient": 0.40,
            "linear_drag": 0.0, "rest_speed": 0.0}


def run(car: DBWVehicle, seconds: float, throttle: float, brake: float, steer: float):
    states = []
    for _ in range(round(seconds / PHYSICS_DT)):
        states.append(car.step(throttle, brake, steer).copy())
    return states


# ---------------------------------------------------------------------- parameters
def test_presets_match_the_spec_table():
    table = {
        "vehicle_mass": (1080.0, 1736.35), "fuel_capacity": (0.0, 13.5),
        "brake_deadband": (0.2, 0.1), "decel_limit": (-5.0, -1.0), "accel_limit": (1.0, 1.0),
        "wheel_radius": (0.335, 0.2413), "wheel_base": (3.0, 2.8498),
        "steer_ratio": (14.8, 14.8), "max_lat_accel": (3.0, 3.0), "max_steer_angle": (8.0, 8.0),
    }
    for field, (sim, site) in table.items():
        assert getattr(vehicle_parameters("sim"), field) == sim, field
        assert getattr(vehicle_parameters("site"), field) == site, field
    assert SIM_VEHICLE.total_mass == 1080.0
    assert SITE_VEHICLE.total_mass == pytest.approx(1736.35 + 13.5 * 2.858)
    assert SITE_VEHICLE.total_mass == pytest.approx(1774.933)


def test_unknown_preset_and_bad_field_are_clear_errors():
    with pytest.raises(ValueError, match=r"'moon'.*\['sim', 'site'\]"):
        vehicle_parameters("moon")
    with pytest.raises(ValueError, match="vehicle_mass"):
        SIM_VEHICLE.replace(vehicle_mass=-1.0)
    with pytest.raises(ValueError, match="decel_limit"):
        dataclasses.replace(SIM_VEHICLE, decel_limit=2.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        SIM_VEHICLE.vehicle_mass = 1.0  # type: ignore[misc]


def test_creep_is_derived_from_the_holding_torque():
    for params, hold in ((SITE_VEHICLE, 700.0), (SIM_VEHICLE.replace(**CREEPING), 400.0)):
        net_at_rest = params.creep_force_at_rest - params.rolling_force
        assert net_at_rest * params.wheel_radius == pytest.approx(hold)
    # A holding torque of 0 is no creep at all, not a creep that only cancels rolling.
    no_creep = SITE_VEHICLE.replace(creep_hold_torque=0.0)
    assert no_creep.creep_force_at_rest == 0.0 and no_creep.creep_force(0.5) == 0.0


def test_sim_preset_is_the_original_unity_car():
    """Known answers from the original's Car.prefab (docs/track_vehicle.md): 2000 N m over
    four wheels of 0.335 / 0.37 m, rigid-body drag 0.1 /s on 1000 kg plus wheel damping
    0.25 N m s/rad, no creep; the steering ratio and lock the original reports."""
    p = SIM_VEHICLE
    assert p.max_drive_force == pytest.approx(500.0 * (2 / 0.335 + 2 / 0.37)) == (
        pytest.approx(5687.78, abs=0.01))
    assert math.isinf(p.max_drive_power) and p.engine_force(50.0) == p.max_drive_force
    assert p.linear_drag == pytest.approx(100.0 + 0.25 * (2 / 0.335**2 + 2 / 0.37**2))
    assert p.linear_drag == pytest.approx(108.108, abs=1e-3)
    assert (p.drag_coefficient, p.rolling_resistance, p.creep_hold_torque) == (0.0, 0.0, 0.0)
    assert p.resistance_force(11.0) == pytest.approx(11.0 * 108.108, abs=0.01)
    assert p.road_wheel_ratio == pytest.approx(18.3345, abs=2e-4)  # 8.2 / 0.447241
    assert p.steering_wheel_lock == 8.2
    assert p.max_road_wheel_angle == pytest.approx(0.447241, abs=1e-9)
    # The controllers are still told the launch file's figures.
    assert (p.steer_ratio, p.max_steer_angle) == (14.8, 8.0)
    assert (SITE_VEHICLE.road_wheel_ratio, SITE_VEHICLE.steering_wheel_lock) == (14.8, 8.0)


# ---------------------------------------------------------------------- longitudinal
def test_constant_throttle_terminal_speed_force_limited():
    """Site, throttle 0.08 below the power crossover: 0.08 F_max = c v^2 + F_roll."""
    p = SITE_VEHICLE
    car = DBWVehicle(p)
    car.reset(0.0, 0.0, 0.0)
    expected = math.sqrt((0.08 * p.max_drive_force - p.rolling_force) / p.drag_coefficient)
    assert expected < p.max_drive_power / p.max_drive_force  # really the force-limited regime
    state = run(car, 600.0, 0.08, 0.0, 0.0)[-1]
    assert state.speed == pytest.approx(expected, rel=5e-3)
    assert abs(state.acceleration) < 1e-3


def test_linear_drag_speed_is_the_exact_euler_recursion_to_u_f_over_c():
    """Sim, constant throttle u: v_{n+1} = v_n (1 - c dt / m) + u F dt / m from rest, so
    v_n = (u F / c) (1 - (1 - c dt / m)^n): terminal speed u F / c (11.05 m/s at 0.21)."""
    p = SIM_VEHICLE
    u, m, c, force = 0.21, p.total_mass, p.linear_drag, p.max_drive_force
    car = DBWVehicle(p)
    car.reset(0.0, 0.0, 0.0)
    states = run(car, 120.0, u, 0.0, 0.0)
    terminal = u * force / c
    assert terminal == pytest.approx(11.049, abs=1e-3)
    for n in (1, 10, 500, 6000):
        expected = terminal * (1.0 - (1.0 - c * PHYSICS_DT / m) ** n)
        assert states[n - 1].speed == pytest.approx(expected, rel=1e-9)
    assert states[-1].speed == pytest.approx(terminal, rel=1e-4)


def test_sim_car_coasts_on_linear_drag_and_comes_to_rest_below_rest_speed():
    """No pedals from 5 m/s: v_n = 5 (1 - c dt / m)^n while at or above 0.1 m/s, then at
    rest for good (no creep pushes it on); the first step below 0.1 m/s ends at 0."""
    p = SIM_VEHICLE
    keep = 1.0 - p.linear_drag * PHYSICS_DT / p.total_mass
    car = DBWVehicle(p)
    car.reset(0.0, 0.0, 0.0, speed=5.0)
    states = run(car, 60.0, 0.0, 0.0, 0.0)
    n_rest = math.ceil(math.log(0.1 / 5.0) / math.log(keep))  # first step below 0.1
    assert states[n_rest - 2].speed == pytest.approx(5.0 * keep ** (n_rest - 1), rel=1e-9)
    assert states[n_rest - 2].speed >= 0.1 and states[n_rest - 1].speed == 0.0
    assert all(s.speed == 0.0 for s in states[n_rest - 1:])
    assert states[-1].x == states[n_rest - 1].x  # parked, with no brake at all
    # Coasting distance: the geometric series of the trapezoid steps (the last one to
    # the speed it would have had), about m (5 - 0.1) / c = 49 m.
    expected = 0.5 * PHYSICS_DT * 5.0 * (1.0 + keep) * (1.0 - keep**n_rest) / (1.0 - keep)
    assert states[-1].x == pytest.approx(expected, rel=1e-9)
    assert expected == pytest.approx(4.9 * p.total_mass / p.linear_drag, rel=1e-3)
    # With any drive force the car keeps rolling below rest_speed.
    car.reset(0.0, 0.0, 0.0, speed=0.05)
    assert car.step(0.001, 0.0, 0.0).speed > 0.0


def test_full_throttle_terminal_speed_power_limited():
    """Site, full throttle: P / v = c v^2 + F_roll, i.e. the root of c v^3 + F v - P."""
    p = SITE_VEHICLE
    roots = np.roots([p.drag_coefficient, 0.0, p.rolling_force, -p.max_drive_power])
    expected = float(roots[np.abs(roots.imag) < 1e-9].real.max())
    car = DBWVehicle(p)
    car.reset(0.0, 0.0, 0.0)
    state = run(car, 300.0, 1.0, 0.0, 0.0)[-1]
    assert state.speed == pytest.approx(expected, rel=5e-3)


def test_braking_distance_matches_v_squared_over_2a():
    params = SIM_VEHICLE.replace(**NO_RESISTANCE)
    brake = 1809.0  # N m: the reference stack's mass * 5 m/s^2 * wheel_radius
    decel = brake / params.wheel_radius / params.total_mass
    car = DBWVehicle(params)
    car.reset(10.0, -2.0, 0.0, speed=20.0)
    states = run(car, 6.0, 0.0, brake, 0.0)
    assert states[-1].speed == 0.0
    assert states[-1].x - 10.0 == pytest.approx(20.0**2 / (2.0 * decel), rel=1e-2)
    assert states[-1].y == pytest.approx(-2.0)
    assert states[0].acceleration == pytest.approx(-decel)


def test_brake_never_reverses_the_car():
    params = SIM_VEHICLE.replace(**NO_RESISTANCE)
    car = DBWVehicle(params)
    car.reset(0.0, 0.0, 0.0, speed=3.0)
    states = run(car, 3.0, 0.0, 1e9, 0.0)
    xs = [s.x for s in states]
    assert all(s.speed >= 0.0 for s in states)
    assert all(b >= a for a, b in itertools.pairwise(xs))
    # The brake force is capped by tyre friction: stops in v^2 / (2 mu g).
    decel = params.max_brake_force / params.total_mass
    assert decel == pytest.approx(1.0 * 9.81)
    assert xs[-1] == pytest.approx(3.0**2 / (2.0 * decel), rel=1e-9)
    assert states[-1].speed == 0.0


@pytest.mark.parametrize(("params", "hold"), [(SIM_VEHICLE.replace(**CREEPING), 400.0),
                                             (SITE_VEHICLE, 700.0)])
def test_brake_at_the_holding_torque_holds_and_less_creeps(params, hold):
    car = DBWVehicle(params)
    car.reset(5.0, 5.0, 1.0, brake_torque=hold)
    held = run(car, 5.0, 0.0, hold, 0.0)
    assert all(s.speed == 0.0 and s.x == 5.0 and s.y == 5.0 for s in held)
    car.reset(5.0, 5.0, 0.0, brake_torque=hold - 100.0)
    crept = run(car, 20.0, 0.0, hold - 100.0, 0.0)
    assert crept[-1].speed > 0.1
    assert crept[-1].x > 6.0


def test_the_sim_car_stays_at_rest_without_any_pedal():
    """The original's car has no idle creep: zero throttle and zero brake hold it."""
    car = DBWVehicle(SIM_VEHICLE)
    car.reset(5.0, 5.0, 1.0)
    assert all(s.speed == 0.0 and (s.x, s.y) == (5.0, 5.0)
               for s in run(car, 60.0, 0.0, 0.0, 0.0))
    # Any throttle pulls away at once: u F / m in the first step (no static friction).
    assert car.step(0.1, 0.0, 0.0).speed == pytest.approx(
        0.1 * SIM_VEHICLE.max_drive_force / 1080.0 * PHYSICS_DT)


def test_creep_speed_against_a_brake_has_a_closed_form():
    """Moving: creep0 (1 - v / v_c) = brake / r + F_roll (drag off)."""
    params = SITE_VEHICLE.replace(drag_coefficient=0.0)
    brake = 300.0
    expected = params.creep_speed * (
        1.0 - (brake / params.wheel_radius + params.rolling_force) / params.creep_force_at_rest)
    car = DBWVehicle(params)
    car.reset(0.0, 0.0, 0.0)
    assert run(car, 30.0, 0.0, brake, 0.0)[-1].speed == pytest.approx(expected, rel=1e-3)


def test_throttle_lag_is_the_exact_first_order_response():
    car = DBWVehicle(SITE_VEHICLE)
    car.reset(0.0, 0.0, 0.0)
    tau = SITE_VEHICLE.throttle_time_constant
    states = run(car, 0.5, 1.0, 0.0, 0.0)
    assert states[0].throttle == pytest.approx(1.0 - math.exp(-PHYSICS_DT / tau))
    assert states[-1].throttle == pytest.approx(1.0 - math.exp(-0.5 / tau))
    # No lag in the sim preset: the command applies at once (and is clamped to [0, 1]).
    sim = DBWVehicle(SIM_VEHICLE)
    sim.reset(0.0, 0.0, 0.0)
    assert sim.step(2.0, -5.0, 0.0).throttle == 1.0
    assert sim.state.brake_torque == 0.0


# ---------------------------------------------------------------------- lateral
def fit_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares circle (Kasa): x^2 + y^2 = 2 a x + 2 b y + c."""
    design = np.column_stack([2.0 * x, 2.0 * y, np.ones_like(x)])
    (a, b, c), *_ = np.linalg.lstsq(design, x**2 + y**2, rcond=None)
    return float(a), float(b), math.sqrt(c + a * a + b * b)


@pytest.mark.parametrize("steering", [2.0, -5.5])
def test_fixed_wheel_angle_drives_a_circle_of_wheel_base_over_tan_delta(steering):
    car = DBWVehicle(SIM_VEHICLE)
    car.reset(0.0, 0.0, 0.3, speed=6.0)
    states = run(car, 20.0, 0.2, 0.0, steering)
    x = np.array([s.x for s in states])
    y = np.array([s.y for s in states])
    _, _, radius = fit_circle(x, y)
    expected = SIM_VEHICLE.wheel_base / math.tan(abs(steering) / SIM_VEHICLE.road_wheel_ratio)
    assert radius == pytest.approx(expected, rel=5e-3)
    last = states[-1]
    assert abs(last.yaw_rate) == pytest.approx(last.speed / expected, rel=5e-3)
    assert math.copysign(1.0, last.yaw_rate) == math.copysign(1.0, steering)
    assert last.lateral_acceleration == pytest.approx(last.speed * last.yaw_rate)


def test_steering_answers_as_the_original_reports_and_is_clamped_at_its_lock():
    """CarND-Capstone issues #110/#111: the original's steering report is the command
    divided by ~18.33, at most 0.447241 rad (reached at 8.2 rad)."""
    car = DBWVehicle(SIM_VEHICLE)
    car.reset(0.0, 0.0, 0.0, speed=5.0)
    for command in (0.5, 2.0, -4.0, 8.0):
        wheel = car.step(0.0, 0.0, command).road_wheel_angle
        assert command / wheel == pytest.approx(18.3345, abs=2e-4)
    assert car.step(0.0, 0.0, 100.0).steering_wheel_angle == 8.2
    assert car.state.road_wheel_angle == pytest.approx(0.447241, abs=1e-9)
    assert car.step(0.0, 0.0, -math.inf).steering_wheel_angle == -8.2
    site = DBWVehicle(SITE_VEHICLE.replace(steering_time_constant=0.0))
    site.reset(0.0, 0.0, 0.0, speed=5.0)
    assert site.step(0.0, 0.0, 100.0).steering_wheel_angle == 8.0
    with pytest.raises(ValueError, match="NaN"):
        car.step(math.nan, 0.0, 0.0)


def test_straight_driving_and_body_points():
    car = DBWVehicle(SIM_VEHICLE.replace(**NO_RESISTANCE))
    car.reset(1.0, 2.0, math.pi / 2, speed=10.0)
    state = run(car, 1.0, 0.0, 0.0, 0.0)[-1]
    assert (state.x, state.y) == pytest.approx((1.0, 12.0))
    assert state.odometer == pytest.approx(10.0)
    assert car.front_axle_xy() == pytest.approx((1.0, 15.0))
    assert car.center_xy() == pytest.approx((1.0, 13.5))


def test_same_commands_give_identical_runs():
    commands = np.random.default_rng(7).uniform([0, 0, -8], [1, 2000, 8], size=(500, 3))
    finals = []
    for _ in range(2):
        car = DBWVehicle(SITE_VEHICLE)
        car.reset(0.0, 0.0, 0.0, speed=3.0)
        for throttle, brake, steer in commands.tolist():
            car.step(throttle, brake, steer)
        finals.append(dataclasses.astuple(car.state))
    assert finals[0] == finals[1]


# ---------------------------------------------------------------------- manual driver
OVAL_RADIUS_M = 40.0
OVAL_STRAIGHT_M = 80.0
TARGET_SPEED = 8.0  # m/s: below sqrt(comfort_lat_accel * radius) = 8.9 m/s


@pytest.fixture(scope="module")
def oval() -> ReferenceLine:
    """A counter-clockwise stadium: two 80 m straights joined by 40 m half circles."""
    r, length = OVAL_RADIUS_M, OVAL_STRAIGHT_M
    straight = np.arange(0.0, length, 1.0)
    arc = np.linspace(-math.pi / 2, math.pi / 2, 126, endpoint=False)
    points = np.concatenate([
        np.column_stack([straight, np.full_like(straight, -r)]),
        np.column_stack([length + r * np.cos(arc), r * np.sin(arc)]),
        np.column_stack([length - straight, np.full_like(straight, r)]),
        np.column_stack([-r * np.cos(arc), -r * np.sin(arc)]),
    ])
    return ReferenceLine(points)


def drive(oval, params, seed, seconds, stop_line_s=None, speed=TARGET_SPEED):
    car = DBWVehicle(params)
    x, y = oval.position(0.0)
    car.reset(float(x), float(y), float(oval.heading(0.0)), speed=speed)
    driver = ManualDriver(params, np.random.default_rng(seed))
    s_prev, log = 0.0, []
    for _ in range(round(seconds / PHYSICS_DT)):
        (s,), (d,) = oval.project_few([[car.state.x, car.state.y]], [s_prev])
        s = s_prev + float(oval.s_difference(s, s_prev))  # unwrapped arc length
        s_prev = s
        stop = None if stop_line_s is None else stop_line_s - s
        state = car.step(*driver.act(car.state, oval, TARGET_SPEED, stop))
        log.append((s, d, state.speed))
    return driver, np.array(log)


@pytest.mark.parametrize("params", [SIM_VEHICLE, SITE_VEHICLE])
def test_manual_driver_keeps_the_lane_at_its_preferred_speed(oval, params):
    driver, log = drive(oval, params, seed=1, seconds=60.0)
    assert log[-1, 0] > oval.length  # a full lap and more
    assert np.abs(log[:, 1]).max() < 0.5
    preferred = TARGET_SPEED * driver.speed_factor
    assert 0.92 <= driver.speed_factor <= 1.08
    assert np.all(np.abs(log[250:, 2] - preferred) < 0.1 * preferred)


def test_manual_driver_stops_before_a_red_line(oval):
    stop_line = 150.0
    driver, log = drive(oval, SIM_VEHICLE, seed=2, seconds=40.0, stop_line_s=stop_line)
    front_axle_s = log[:, 0] + SIM_VEHICLE.wheel_base
    assert front_axle_s.max() < stop_line  # never past it
    assert np.all(log[-250:, 2] == 0.0)  # at rest for the last 5 s
    rest_gap = stop_line - log[-1, 0]
    expected = SIM_VEHICLE.wheel_base + DriverStyle().front_overhang + driver.stop_gap
    assert rest_gap == pytest.approx(expected, abs=1.0)


def test_manual_driver_runs_a_yellow_it_cannot_stop_for(oval):
    # Appears 10 m ahead at 8 m/s: stopping needs 64 / (2 * 6) = 5.3 m/s^2 > 3.5.
    _, log = drive(oval, SIM_VEHICLE, seed=3, seconds=5.0, stop_line_s=10.0)
    assert log[-1, 0] > 30.0
    assert log[:, 2].min() > 0.9 * TARGET_SPEED * 0.92


@pytest.mark.parametrize(("speed", "accel", "decel", "jerk", "lag"), [
    (11.0, 0.0, 3.5, 3.0, 0.0),   # the ramp ends before rest
    (11.0, 1.2, 3.5, 3.0, 0.1),   # from accelerating, with brake lag
    (2.0, 0.0, 3.5, 3.0, 0.0),    # at rest during the ramp
    (8.0, -2.0, 2.0, 3.0, 0.0),   # already braking at decel: no ramp
])
def test_braking_distance_matches_integrating_the_jerk_limited_pedal(speed, accel, decel,
                                                                     jerk, lag):
    # Hand case 1: T = 3.5 / 3 = 1.167 s, speed at its end 11 - 3 T^2 / 2 = 8.958 m/s,
    # distance 11 T - 3 T^3 / 6 + 8.958^2 / 7 = 12.833 - 0.794 + 11.465 = 23.50 m, where
    # the constant 3.5 m/s^2 alone would say 121 / 7 = 17.29 m.
    dt, x, v, a, t = 1e-4, 0.0, speed, accel, 0.0
    while v > 0.0:
        if t >= lag:
            a = max(a - jerk * dt, -decel)
        x += v * dt + 0.5 * a * dt * dt
        v += a * dt
        t += dt
    assert braking_distance(speed, accel, decel, jerk, lag) == pytest.approx(x, abs=1e-3)
    if (speed, accel, lag) == (11.0, 0.0, 0.0):
        assert x == pytest.approx(23.50, abs=0.01)
    assert braking_distance(speed, 0.0, decel, 0.0) == pytest.approx(speed**2 / (2 * decel))


def test_manual_driver_stops_for_a_line_only_when_it_can_and_then_before_it(oval):
    # The line appears at 8 m/s, pedal at rest. The old rule (v^2 / 2 d <= 3.5 m/s^2 to
    # the line) said "stop" from 13.1 m on but could not deliver it: the jerk-limited ramp
    # adds ~4 m. Now the driver stops iff the jerk-limited distance at 3.5 m/s^2 fits
    # before its rest point, and then rests before the line; otherwise it drives through.
    style, car = DriverStyle(), SIM_VEHICLE
    needed = braking_distance(TARGET_SPEED, 0.0, style.dilemma_decel, style.pedal_jerk)
    outcomes = set()
    for line_s in np.arange(12.0, 24.0, 0.5):
        driver, log = drive(oval, car, seed=2, seconds=8.0, stop_line_s=float(line_s))
        to_rest = line_s - car.wheel_base - style.front_overhang - driver.stop_gap
        front = log[:, 0] + car.wheel_base + style.front_overhang
        if needed <= to_rest:
            assert front.max() < line_s and log[-1, 2] == 0.0, line_s
            outcomes.add("stop")
        else:
            assert front.max() > line_s + 10.0, line_s
            outcomes.add("go")
    assert outcomes == {"stop", "go"}


def test_manual_driver_is_deterministic_per_seed(oval):
    _, first = drive(oval, SITE_VEHICLE, seed=5, seconds=4.0)
    _, second = drive(oval, SITE_VEHICLE, seed=5, seconds=4.0)
    _, other = drive(oval, SITE_VEHICLE, seed=6, seconds=4.0)
    np.testing.assert_array_equal(first, second)
    assert not np.array_equal(first, other)


def test_manual_driver_rejects_a_global_rng():
    with pytest.raises(TypeError, match="Generator"):
        ManualDriver(SIM_VEHICLE, np.random)  # type: ignore[arg-type]


def test_parameters_are_a_frozen_dataclass_with_replace():
    changed = SIM_VEHICLE.replace(wheel_base=2.5)
    assert isinstance(changed, VehicleParameters)
    assert changed.wheel_base == 2.5 and SIM_VEHICLE.wheel_base == 3.0
    plain = SIM_VEHICLE.replace(response_steer_ratio=None, steering_lock=None)
    assert (plain.road_wheel_ratio, plain.steering_wheel_lock) == (14.8, 8.0)


@pytest.mark.parametrize(("field", "value", "message"), [
    ("response_steer_ratio", 0.0, "response_steer_ratio must be None or a finite number > 0"),
    ("steering_lock", math.inf, "steering_lock must be None or a finite number > 0"),
    ("linear_drag", -1.0, "linear_drag must be a finite number >= 0"),
    ("rest_speed", True, "rest_speed must be a finite number >= 0"),
    ("max_drive_power", 0.0, "max_drive_power must be a number > 0"),
    ("max_drive_force", "4000", "max_drive_force must be a finite number > 0"),
])
def test_new_fields_are_validated(field, value, message):
    with pytest.raises(ValueError, match=message):
        SIM_VEHICLE.replace(**{field: value})
