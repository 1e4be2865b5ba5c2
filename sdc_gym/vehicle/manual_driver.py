"""The built-in human driver who has the wheel while drive-by-wire is off.

The original track simulator has a "manual" toggle: with ``dbw_enabled`` false a person
drives, and the stack must stay silent and reset its controllers. The env reproduces
those periods with this driver. It is deliberately **not** the reference drive-by-wire
stack (which lives in ``agents/`` and which ``sdc_gym`` never imports): it is a simpler,
human-like model, so that a stack under test sees a car handed back to it in a slightly
different state than its own controllers would have left.

What the driver does each call (``act``)
----------------------------------------
Steering (a pursuit driver)
    Projects the rear axle on the reference line, looks ``max(min_lookahead,
    lookahead_time * v)`` metres ahead *along the line* and steers onto the circular arc
    through that point (pure-pursuit curvature ``2 * lateral / distance^2``, road-wheel
    angle ``atan(wheel_base * curvature)``). The hands follow with a first-order lag
    (``steering_response_time``) and a small, slowly wandering error (an AR(1) process of
    standard deviation ``steering_noise_std`` road-wheel rad and correlation time
    ``steering_noise_time``).
Speed
    Eases onto a preferred speed: the target speed times a personal factor drawn at
    :meth:`ManualDriver.reset` (``1 + N(0, preferred_speed_spread)``, clipped), lowered
    ahead of curves so that lateral acceleration stays below ``comfort_lat_accel`` (it
    plans to be at the curve speed by the time it reaches each sampled curve, braking at
    ``comfort_decel``). The wanted acceleration ``speed_gain * (v_pref - v)`` is limited
    to ``[-comfort_decel, comfort_accel]``, and the pedal moves at most ``pedal_jerk``
    m/s^3 (no jerky feet).
Stop lines
    Given the distance to the next stop line whose light is red or yellow, the driver
    decides once, when the line first appears, whether it can come to rest at its rest
    point (the front bumper ``stop_gap`` metres, drawn per reset, before the line) without
    braking harder than ``dilemma_decel`` (a human at a yellow light); if not, it drives
    on and ignores that line. Otherwise it follows a braking curve down to the rest point
    and holds the brake there. Both the decision and the curve use the
    **jerk-limited braking distance** (:func:`braking_distance`): the pedal cannot jump
    from the current acceleration ``a0`` to ``-D`` but ramps at ``pedal_jerk``, taking
    ``T = (a0 + D) / pedal_jerk`` s, and the brakes answer after the car's brake lag
    ``brake_time_constant``. At 11 m/s from cruising (``a0 = 0``) the ramp to 3.5 m/s^2
    adds about ``v T / 2`` = 6 m to ``v^2 / 2D`` = 17 m; ignoring it left the car 2.3 m past
    a line it had decided to stop for. The curve is the speed ``v`` from which braking at
    ``comfort_decel`` (ramp included) ends exactly at the rest point; above it the driver
    brakes harder, up to ``max_decel``, which is more than ``dilemma_decel``. Measured over
    1,688 decided stops (sim and site cars, 3 to 13 m/s, lines appearing 3 to 60 m ahead,
    4 seeds) the front bumper came to rest within 0.5 m of its rest point, never past the
    line (at least 0.47 m before it).
Pedals
    The wanted acceleration becomes throttle or brake torque through the car's own force
    balance (the driver "knows the feel" of the car): ``F = m a + resistance - creep``;
    positive ``F`` is throttle ``F / F_engine(v)``, negative is brake torque
    ``-F * wheel_radius``. At a standstill with no wish to move it holds
    ``hold_brake_factor`` times the car's holding torque (:func:`holding_torque`: the
    torque that balances the idle creep, or for a car that does not creep the torque of
    a ``comfort_decel`` stop). The wheel turns the car's own steering ratio and lock
    (``road_wheel_ratio``, ``steering_wheel_lock``): the driver steers by feel, not by the
    figures the controllers are given.

Distances
---------
``stop_distance`` is measured along the path from the car's reference point (the rear
axle, :class:`~sdc_gym.vehicle.dbw_vehicle.DBWVehicle`'s ``x, y``) to the stop line; the
driver keeps ``wheel_base + front_overhang + stop_gap`` metres of it. A caller measuring
from a point further forward makes the driver stop earlier, never later.

Randomness comes only from the ``numpy.random.Generator`` given to the constructor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sdc_gym.geometry.reference_line import ReferenceLine
from sdc_gym.vehicle.dbw_vehicle import PHYSICS_DT, VehicleParameters, VehicleState

# Curvature is sampled at this many look-ahead distances (0, 1, 2, 3 x look-ahead) to
# plan the speed for curves ahead.
_CURVE_SAMPLES = 4
# A stop distance this much larger than the last one is a new stop line (m).
_NEW_LINE_JUMP_M = 5.0
# Guards against dividing by zero distances (m) and curvatures (1/m).
_MIN_DISTANCE_M = 0.1
_MIN_CURVATURE = 1e-6


def braking_distance(speed: float, accel: float, decel: float, jerk: float,
                     dead_time: float = 0.0) -> float:
    """m travelled to rest when braking at ``decel`` with a jerk-limited pedal.

    The car moves at ``speed`` m/s with acceleration ``accel`` m/s^2 (the pedal now). It
    keeps that acceleration for ``dead_time`` s (actuator lag), then the acceleration
    ramps linearly at ``jerk`` m/s^3 to ``-decel`` (``decel > 0``) and stays there until
    the car is at rest; the car may also come to rest during the ramp. ``jerk = 0`` means
    no ramp (an instant pedal). An ``accel`` already below ``-decel`` is taken as
    ``-decel`` (an overestimate). Closed form: piecewise constant jerk.
    """
    if speed <= 0.0:
        return 0.0
    if decel <= 0.0:
        return math.inf
    accel = max(accel, -decel)
    travelled = 0.0
    if dead_time > 0.0:
        after = speed + accel * dead_time
        if after <= 0.0:  # at rest before the brakes answer (accel < 0 here)
            return speed * speed / (-2.0 * accel)
        travelled = speed * dead_time + 0.5 * accel * dead_time * dead_time
        speed = after
    ramp = (accel + decel) / jerk if jerk > 0.0 else 0.0
    at_ramp_end = speed + accel * ramp - 0.5 * jerk * ramp * ramp
    if at_ramp_end > 0.0:
        return (travelled + speed * ramp + 0.5 * accel * ramp * ramp - jerk * ramp**3 / 6.0
                + at_ramp_end * at_ramp_end / (2.0 * decel))
    # At rest during the ramp (jerk > 0 here): speed + accel t - jerk t^2 / 2 = 0.
    t = (accel + math.sqrt(accel * accel + 2.0 * jerk * speed)) / jerk
    return travelled + speed * t + 0.5 * accel * t * t - jerk * t**3 / 6.0


def holding_torque(params: VehicleParameters, style: DriverStyle) -> float:
    """N m a driver's foot holds a stopped car with (before ``hold_brake_factor``): the
    torque that balances the idle creep, or, for a car that does not creep, the torque of
    a stop at ``style.comfort_decel`` (the pedal stays where the stop left it)."""
    if params.creep_hold_torque > 0.0:
        return params.creep_hold_torque
    return params.total_mass * style.comfort_decel * params.wheel_radius


@dataclass(frozen=True)
class DriverStyle:
    """How the human drives; defaults describe a calm, attentive driver.

    Attributes:
        lookahead_time: s, look-ahead distance per unit speed.
        min_lookahead: m, look-ahead at low speed.
        steering_response_time: s, first-order lag of the hands on the wheel.
        steering_noise_std: rad (road wheel), standard deviation of the steering error.
        steering_noise_time: s, correlation time of the steering error.
        speed_gain: 1/s, wanted acceleration per m/s of speed error.
        comfort_accel: m/s^2, largest acceleration the driver asks for.
        comfort_decel: m/s^2 (positive), planned braking for speed changes and stops.
        max_decel: m/s^2 (positive), hardest braking the driver uses at all.
        pedal_jerk: m/s^3, how fast the wanted acceleration may change.
        comfort_lat_accel: m/s^2, lateral acceleration the driver accepts in curves.
        preferred_speed_spread: standard deviation of the personal speed factor.
        preferred_speed_clip: the personal speed factor stays within 1 +- this.
        stop_gap_range: m, (low, high) of the uniform front-bumper gap to a stop line.
        front_overhang: m, front axle to front bumper.
        dilemma_decel: m/s^2, a red/yellow line needing harder braking when first seen is
            driven through.
        stop_gain: 1/s, how firmly the driver follows the braking curve to a stop line.
        hold_gap: m, within this distance of the rest point at walking pace it stops.
        standstill_speed: m/s, below this (and not wanting to move) the brake is held.
        hold_brake_factor: held brake torque / the car's holding torque.
    """

    lookahead_time: float = 1.0
    min_lookahead: float = 6.0
    steering_response_time: float = 0.15
    steering_noise_std: float = 0.002
    steering_noise_time: float = 1.0
    speed_gain: float = 0.6
    comfort_accel: float = 1.2
    comfort_decel: float = 2.0
    max_decel: float = 5.0
    pedal_jerk: float = 3.0
    comfort_lat_accel: float = 2.0
    preferred_speed_spread: float = 0.04
    preferred_speed_clip: float = 0.08
    stop_gap_range: tuple[float, float] = (0.5, 2.0)
    front_overhang: float = 1.0
    dilemma_decel: float = 3.5
    stop_gain: float = 1.0
    hold_gap: float = 0.5
    standstill_speed: float = 0.3
    hold_brake_factor: float = 1.5

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            values = value if isinstance(value, tuple) else (value,)
            if not all(math.isfinite(v) and v >= 0.0 for v in values):
                raise ValueError(f"DriverStyle: {name} must be finite and >= 0, got {value!r}")
        low, high = self.stop_gap_range
        if low > high:
            raise ValueError(f"DriverStyle: stop_gap_range must be (low, high) with "
                             f"low <= high, got {self.stop_gap_range!r}")


class ManualDriver:
    """A human-like driver for manual-override periods; see the module docstring.

    Args:
        params: the car being driven (for the wheel base, steering and pedal feel).
        rng: the only source of randomness (personal traits and steering error).
        style: how the human drives.
    """

    def __init__(
        self,
        params: VehicleParameters,
        rng: np.random.Generator,
        style: DriverStyle | None = None,
    ) -> None:
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        self.params = params
        self.rng = rng
        self.style = style if style is not None else DriverStyle()
        self.speed_factor = 1.0
        self.stop_gap = 0.0
        self.reset()

    def reset(self, state: VehicleState | None = None) -> None:
        """Start a new stint at the wheel: draw the personal traits, forget the past.

        With ``state`` the hands and feet start where the car's actuators are (a smooth
        take-over from the automation); otherwise from centred wheel and no pedal.
        """
        style = self.style
        spread = style.preferred_speed_spread * float(self.rng.standard_normal())
        self.speed_factor = 1.0 + min(max(spread, -style.preferred_speed_clip),
                                      style.preferred_speed_clip)
        self.stop_gap = float(self.rng.uniform(*style.stop_gap_range))
        self._s: float | None = None
        self._noise = 0.0
        self._steering = state.steering_wheel_angle if state is not None else 0.0
        self._accel = state.acceleration if state is not None else 0.0
        self._last_stop_distance: float | None = None
        self._stopping = False

    # ------------------------------------------------------------------ one decision
    def act(
        self,
        state: VehicleState,
        line: ReferenceLine,
        target_speed: float,
        stop_distance: float | None = None,
        dt: float = PHYSICS_DT,
    ) -> tuple[float, float, float]:
        """Pedals and wheel for the next ``dt`` s: (throttle, brake torque N m, steering-
        wheel angle rad).

        Args:
            state: the car now.
            line: the path to follow (the lane centre).
            target_speed: m/s, the speed the road asks for.
            stop_distance: m along the path from the rear axle to the next stop line whose
                light is red or yellow, or ``None``.
            dt: s until the next call (the smoothing and noise are per unit time).
        """
        if not (dt > 0.0 and math.isfinite(dt)):
            raise ValueError(f"ManualDriver.act: dt must be a finite number > 0 s, got {dt!r}")
        if not (math.isfinite(target_speed) and target_speed >= 0.0):
            raise ValueError(f"ManualDriver.act: target_speed must be finite and >= 0 m/s, "
                             f"got {target_speed!r}")
        style, params = self.style, self.params
        speed = state.speed
        lookahead = max(style.min_lookahead, style.lookahead_time * speed)
        s = self._project(state, line)
        frames = line.line_frames_few([s + k * lookahead for k in range(_CURVE_SAMPLES)])
        steering = self._steer(state, frames[1], dt)
        accel, hold = self._wanted_acceleration(speed, target_speed, stop_distance, frames,
                                                lookahead, dt)
        if hold:
            return 0.0, style.hold_brake_factor * holding_torque(params, style), steering
        throttle, brake = self._pedals(speed, accel)
        return throttle, brake, steering

    def _project(self, state: VehicleState, line: ReferenceLine) -> float:
        """Arc length of the rear axle, warm-started from the last call."""
        if self._s is None:
            s, _ = line.to_frenet(np.array([state.x, state.y]))
            self._s = float(s)
        else:
            (self._s,), _ = line.project_few([[state.x, state.y]], [self._s])
        return self._s

    def _steer(self, state: VehicleState, target: tuple[float, ...], dt: float) -> float:
        """Pursuit steering toward the look-ahead point, smoothed and a little noisy."""
        style, params = self.style, self.params
        dx, dy = target[0] - state.x, target[1] - state.y
        lateral = -math.sin(state.yaw) * dx + math.cos(state.yaw) * dy  # left of the car
        distance_sq = max(dx * dx + dy * dy, _MIN_DISTANCE_M**2)
        road_wheel = math.atan(params.wheel_base * 2.0 * lateral / distance_sq)
        if style.steering_noise_std > 0.0:
            keep = math.exp(-dt / style.steering_noise_time) if style.steering_noise_time else 0.0
            self._noise = keep * self._noise + math.sqrt(1.0 - keep * keep) * (
                style.steering_noise_std * float(self.rng.standard_normal()))
        lock = params.steering_wheel_lock
        wanted = min(max(params.road_wheel_ratio * (road_wheel + self._noise), -lock), lock)
        follow = -math.expm1(-dt / style.steering_response_time) if (
            style.steering_response_time > 0.0) else 1.0
        self._steering += follow * (wanted - self._steering)
        return self._steering

    def _wanted_acceleration(
        self,
        speed: float,
        target_speed: float,
        stop_distance: float | None,
        frames: list[tuple[float, float, float, float, float]],
        lookahead: float,
        dt: float,
    ) -> tuple[float, bool]:
        """The pedal-smoothed acceleration to ask for, and whether to hold at rest."""
        style = self.style
        preferred = target_speed * self.speed_factor
        for k, frame in enumerate(frames):
            curve_speed_sq = style.comfort_lat_accel / max(abs(frame[4]), _MIN_CURVATURE)
            reachable = math.sqrt(curve_speed_sq + 2.0 * style.comfort_decel * k * lookahead)
            preferred = min(preferred, reachable)
        wanted = min(max(style.speed_gain * (preferred - speed), -style.comfort_decel),
                     style.comfort_accel)

        gap = self._stop_gap_left(speed, stop_distance)
        if gap is not None:
            if gap < style.hold_gap and speed < style.standstill_speed:
                self._accel = 0.0
                return 0.0, True
            # The braking curve: the speed whose comfortable stop, pedal ramp and brake lag
            # included, ends at the rest point. v^2 / 2D plus the ramp's extra distance
            # equals the gap exactly when the speed is on the curve.
            decel = style.comfort_decel
            ramp_extra = self._braking_distance(speed, decel) - speed * speed / (2.0 * decel)
            on_curve = math.sqrt(2.0 * decel * max(gap - ramp_extra, 0.0))
            wanted = min(wanted, -decel + style.stop_gain * (on_curve - speed))
        wanted = max(wanted, -style.max_decel)

        step = style.pedal_jerk * dt
        self._accel += min(max(wanted - self._accel, -step), step)
        if self._accel <= 0.0 and speed < style.standstill_speed and preferred <= speed:
            return 0.0, True
        return self._accel, False

    def _stop_gap_left(self, speed: float, stop_distance: float | None) -> float | None:
        """Metres to this driver's rest point before a red/yellow line, or ``None`` when
        there is no line to stop for (none given, already past it, or deciding to go)."""
        if stop_distance is None or stop_distance < 0.0:
            self._last_stop_distance = None
            return None
        to_rest_point = (stop_distance - self.params.wheel_base - self.style.front_overhang
                         - self.stop_gap)
        last = self._last_stop_distance
        if last is None or stop_distance > last + _NEW_LINE_JUMP_M:
            # A new red/yellow line: can I stop at my rest point without braking harder
            # than dilemma_decel, given how fast my foot and the brakes can move?
            needed = self._braking_distance(speed, self.style.dilemma_decel)
            self._stopping = to_rest_point > 0.0 and needed <= to_rest_point
        self._last_stop_distance = stop_distance
        if not self._stopping:
            return None
        return to_rest_point

    def _braking_distance(self, speed: float, decel: float) -> float:
        """m to rest braking at ``decel`` from now: pedal ramp and brake lag included."""
        return braking_distance(speed, self._accel, decel, self.style.pedal_jerk,
                                self.params.brake_time_constant)

    def _pedals(self, speed: float, accel: float) -> tuple[float, float]:
        """Throttle and brake torque giving ``accel`` m/s^2, from the car's force balance."""
        params = self.params
        resistance = params.resistance_force(speed)
        force = params.total_mass * accel + resistance - params.creep_force(speed)
        if force > 0.0:
            return min(force / params.engine_force(speed), 1.0), 0.0
        return 0.0, -force * params.wheel_radius
