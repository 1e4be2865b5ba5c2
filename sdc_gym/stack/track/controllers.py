"""Drive-by-wire controllers: PID, low-pass filter, yaw controller and the twist controller.

The last node of the reference stack (spec "The nodes") turns a twist command (target
speed and yaw rate) and the current speed into the car's three commands: throttle in
``[0, 1]``, brake torque in N m and steering-wheel angle in rad.

Longitudinal
    A :class:`PID` on the speed error (target - current, m/s) gives an *acceleration
    command* ``u`` in ``[decel_limit, accel_limit]`` (m/s^2; kp 0.8, ki 0.25, kd 0.1). Anti
    windup: the integral is kept only while the output is not clamped. A first-order
    :class:`LowPassFilter` ``y = a u + (1 - a) y_prev``, ``a = 1 / (tau / ts + 1)``,
    smooths ``u`` (``throttle_tau_s``; 0 removes it, the seed's "improve or remove the
    low pass filter"). Then, like the seed team:

    * ``y > 0``: throttle = ``y`` (the seed team feeds the acceleration command, limited
      to ``accel_limit`` = 1, straight to the throttle pedal), no brake;
    * ``y < -brake_deadband``: brake torque = ``total_mass * |y| * wheel_radius`` (the
      torque that decelerates the car by ``|y|``), no throttle;
    * in between: coast.
    * Standstill: target speed ~0 and speed below ``standstill_speed_mps``: no throttle,
      and at least the holding torque, ``hold_torque_margin`` times the vehicle's
      ``creep_hold_torque`` (700 N m site: the torque that exactly balances the idle
      creep, so a margin is needed to hold rather than tie; 0 for the sim car, which
      does not creep and stays where it stops). The PID keeps braking harder if it asks
      for more (the last metre of a stop, against the creep); when the target speed
      rises again, the PID and the filter start afresh.

Lateral (:class:`YawController`, the original's)
    ``w' = v_current * w_target / v_target`` (the same path curvature at the current
    speed), limited to ``+-max_lat_accel / |v_current|`` (the twist controller passes
    ``lateral_limit_fraction`` = 95 % of the vehicle's limit: the speed changes within the
    step, so a limit commanded exactly ends a hair above it), then the steering-wheel angle of
    the kinematic bicycle ``steer_ratio * atan(wheel_base * w' / max(v_current,
    min_speed))``, clamped to ``+-max_steer_angle``. Optionally (``steering_tau_s`` > 0; 0,
    the seed's, is off) the same first-order low-pass smooths the steering-wheel angle:
    the seed's "low pass filter for the steering command if real tests show too much
    lateral accelerations".

Manual mode and watchdog (:class:`TwistController`)
    When ``dbw_enabled`` is false the human drives: the controller outputs nothing and
    resets the PID and the filter, so that resuming starts from a clean state (no
    integral from before, no derivative kick, the throttle rising through the filter
    from 0: no jump). When the velocity or the twist command is older than
    ``watchdog_s``, the target speed becomes 0 (a smooth stop by the PID).

Departures from the original's small helpers, on purpose: the PID's first sample after a
reset has no derivative term (the original's ``(error - 0) / dt`` kicks by ``kd * error /
dt``, 5 x the error at 50 Hz), and the filter starts from 0 instead of passing its first
sample through (so that the step response after ``n`` samples is ``1 - (1 - a)^n``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sdc_gym.kernel_compiler import TypedCall
from sdc_gym.stack.track.control_kernels import (
    TwistParameters,
    longitudinal,
    low_pass,
    pid_update,
    twist_control,
    twist_reset,
    twist_state,
    yaw_steering,
)
from sdc_gym.vehicle.dbw_vehicle import VehicleParameters

# --- seed team's PID gains --------------------------------------------------------------------
DEFAULT_KP = 0.8
DEFAULT_KI = 0.25
DEFAULT_KD = 0.1
# --- this stack's choices -------------------------------------------------------------------
DEFAULT_THROTTLE_TAU_S = 0.1  # low-pass time constant: smooths the 50 Hz commands, ~0.1 s lag
YAW_MIN_SPEED_MPS = 0.1  # the original yaw controller's min_speed
STOP_TARGET_MPS = 0.01  # a target speed below this asks for a stop
# Below this speed with a stop target: at least the holding torque. The site car's PID may
# brake at most |decel_limit| = 1 m/s^2 (428 N m), less than its idle creep below ~0.7 m/s:
# without the holding torque above that speed it would creep through a stop line.
STANDSTILL_SPEED_MPS = 1.0
HOLD_TORQUE_MARGIN = 1.25  # x creep_hold_torque: 875 N m site (0 for the sim car: no creep)
WATCHDOG_S = 0.5
# The yaw controller limits the *commanded* yaw rate at the speed it sees; within the next
# step the speed still changes, so the car's lateral acceleration can end a hair above a
# limit commanded exactly (3.0000002 m/s^2 measured). A small margin keeps it below.
LATERAL_LIMIT_FRACTION = 0.95


class PID:
    """A PID controller with output clamping and conditional-integration anti-windup.

    ``step(error, dt)``: ``u = kp e + ki I + kd de/dt`` with ``I`` the running integral of
    ``e dt``. When ``u`` leaves ``[min_output, max_output]`` it is clamped and this step's
    integration is discarded (the integral is kept only while not clamped). The first step
    after a reset has no derivative term. (The arithmetic:
    :func:`~sdc_gym.stack.track.node_kernels.pid_update`.)
    """

    def __init__(self, kp: float, ki: float, kd: float, min_output: float = -math.inf,
                 max_output: float = math.inf) -> None:
        if not min_output < max_output:
            raise ValueError(f"PID: min_output must be < max_output, got {min_output!r} and "
                             f"{max_output!r}")
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.min_output, self.max_output = float(min_output), float(max_output)
        self.reset()

    def reset(self) -> None:
        self.integral = 0.0
        self.last_error: float | None = None

    def step(self, error: float, dt: float) -> float:
        """The output for this sample's ``error`` after ``dt`` seconds (``dt > 0``)."""
        if not dt > 0.0:
            raise ValueError(f"PID.step: dt must be > 0 s, got {dt!r}")
        last = self.last_error
        output, self.integral = pid_update(
            self.kp, self.ki, self.kd, self.min_output, self.max_output, self.integral,
            0.0 if last is None else last, last is not None, float(error), float(dt))
        self.last_error = float(error)
        return output


class LowPassFilter:
    """First-order low-pass ``y = a x + (1 - a) y_prev``, ``a = 1 / (tau / ts + 1)``.

    ``tau`` is the time constant and ``ts`` the sample period, both in s (``tau = 0``:
    no filtering). Starts (and resets) at ``y = 0``.
    """

    def __init__(self, tau_s: float, ts_s: float) -> None:
        if not (tau_s >= 0.0 and ts_s > 0.0):
            raise ValueError(f"LowPassFilter: need tau_s >= 0 and ts_s > 0, got tau_s "
                             f"{tau_s!r}, ts_s {ts_s!r}")
        self.a = 1.0 / (tau_s / ts_s + 1.0)
        self.reset()

    def reset(self) -> None:
        self.value = 0.0

    def filt(self, x: float) -> float:
        """Feed one sample, return the filtered value."""
        self.value = low_pass(self.a, self.value, float(x))
        return self.value


class YawController:
    """Steering-wheel angle from a target twist and the current speed (see the module)."""

    def __init__(self, wheel_base: float, steer_ratio: float, min_speed: float,
                 max_lat_accel: float, max_steer_angle: float) -> None:
        self.wheel_base = float(wheel_base)
        self.steer_ratio = float(steer_ratio)
        self.min_speed = float(min_speed)
        self.max_lat_accel = float(max_lat_accel)
        self.max_steer_angle = float(max_steer_angle)

    def steering(self, target_linear_mps: float, target_angular_radps: float,
                 current_speed_mps: float) -> float:
        """rad, steering-wheel angle (positive: left)."""
        return yaw_steering(self.wheel_base, self.steer_ratio, self.min_speed,
                            self.max_lat_accel, self.max_steer_angle, float(target_linear_mps),
                            float(target_angular_radps), float(current_speed_mps))


@dataclass(frozen=True)
class TwistControllerParameters:
    """Twist controller settings (PID gains: the seed team's).

    Attributes:
        kp, ki, kd: PID gains on the speed error (m/s -> m/s^2).
        throttle_tau_s: low-pass time constant on the acceleration command (0: none).
        steering_tau_s: low-pass time constant on the steering-wheel angle (0: none, the
            seed's).
        yaw_min_speed_mps: the yaw controller's min_speed.
        stop_target_mps: a target speed below this asks for a stop.
        standstill_speed_mps: below this speed with a stop target, hold with the brake.
        hold_torque_margin: holding torque / the vehicle's ``creep_hold_torque`` (> 1).
        lateral_limit_fraction: the yaw controller limits the lateral acceleration to
            this fraction of the vehicle's ``max_lat_accel`` (in (0, 1]).
        watchdog_s: velocity or twist older than this -> target speed 0.
    """

    kp: float = DEFAULT_KP
    ki: float = DEFAULT_KI
    kd: float = DEFAULT_KD
    throttle_tau_s: float = DEFAULT_THROTTLE_TAU_S
    yaw_min_speed_mps: float = YAW_MIN_SPEED_MPS
    stop_target_mps: float = STOP_TARGET_MPS
    standstill_speed_mps: float = STANDSTILL_SPEED_MPS
    hold_torque_margin: float = HOLD_TORQUE_MARGIN
    lateral_limit_fraction: float = LATERAL_LIMIT_FRACTION
    watchdog_s: float = WATCHDOG_S
    steering_tau_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.hold_torque_margin > 1.0:
            raise ValueError(f"TwistControllerParameters: hold_torque_margin must be > 1 (a "
                             f"torque equal to the creep only ties), got "
                             f"{self.hold_torque_margin!r}")
        for key in ("throttle_tau_s", "yaw_min_speed_mps", "stop_target_mps",
                    "standstill_speed_mps", "steering_tau_s"):
            if not (math.isfinite(getattr(self, key)) and getattr(self, key) >= 0.0):
                raise ValueError(f"TwistControllerParameters: {key} must be >= 0, "
                                 f"got {getattr(self, key)!r}")
        if not 0.0 < self.lateral_limit_fraction <= 1.0:
            raise ValueError(f"TwistControllerParameters: lateral_limit_fraction must be in "
                             f"(0, 1], got {self.lateral_limit_fraction!r}")
        if not self.watchdog_s > 0.0:
            raise ValueError(f"TwistControllerParameters: watchdog_s must be > 0 s, "
                             f"got {self.watchdog_s!r}")


@dataclass(frozen=True)
class DBWCommand:
    """The car's commands: throttle [0, 1], brake torque (N m), steering-wheel angle (rad)."""

    throttle: float
    brake_torque: float
    steering: float


NO_COMMAND = DBWCommand(0.0, 0.0, 0.0)


class TwistController:
    """Throttle, brake and steering from a twist command; see the module docstring.

    ``sample_time_s`` is the controller's nominal period (1 / its rate): the filter's
    ``ts`` and the PID's ``dt`` on the first call; later calls use the measured time
    between calls. The node is :func:`~sdc_gym.stack.track.node_kernels.twist_control`
    (the kernel the batched stack runs for every env); this class is its batch of one.

    Attributes after :meth:`control`: ``acceleration_command`` (the filtered ``u``, m/s^2),
    ``holding``, ``stale`` (the watchdog fired), ``pid_integral``, ``filter_value``.
    """

    def __init__(self, vehicle: VehicleParameters, sample_time_s: float,
                 params: TwistControllerParameters | None = None) -> None:
        if not sample_time_s > 0.0:
            raise ValueError(f"TwistController: sample_time_s must be > 0 s, "
                             f"got {sample_time_s!r}")
        self.vehicle = vehicle
        self.params = params or TwistControllerParameters()
        self.sample_time_s = float(sample_time_s)
        p = self.params
        if not vehicle.decel_limit < vehicle.accel_limit:
            raise ValueError(f"PID: min_output must be < max_output, got "
                             f"{vehicle.decel_limit!r} and {vehicle.accel_limit!r}")
        self.filter_gain = LowPassFilter(p.throttle_tau_s, self.sample_time_s).a
        self.brake_torque_per_decel = vehicle.total_mass * vehicle.wheel_radius  # N m / (m/s^2)
        self.hold_torque = p.hold_torque_margin * vehicle.creep_hold_torque
        self.constants = TwistParameters(
            float(p.kp), float(p.ki), float(p.kd), float(vehicle.decel_limit),
            float(vehicle.accel_limit), self.filter_gain, float(vehicle.wheel_base),
            float(vehicle.steer_ratio), float(p.yaw_min_speed_mps),
            float(p.lateral_limit_fraction * vehicle.max_lat_accel),
            float(vehicle.max_steer_angle), self.brake_torque_per_decel, self.hold_torque,
            float(vehicle.brake_deadband), float(p.stop_target_mps),
            float(p.standstill_speed_mps), float(p.watchdog_s), self.sample_time_s,
            LowPassFilter(p.steering_tau_s, self.sample_time_s).a)
        self.state = twist_state(1)
        self._control = TypedCall(twist_control)
        self.reset()

    def reset(self) -> None:
        """Forget the PID state and the filter (manual mode, a new episode)."""
        twist_reset(self.state, 0)

    @property
    def acceleration_command(self) -> float:
        return float(self.state.acceleration_command[0])

    @property
    def holding(self) -> bool:
        return bool(self.state.holding[0])

    @property
    def stale(self) -> bool:
        return bool(self.state.stale[0])

    @property
    def pid_integral(self) -> float:
        """The PID's running integral of the speed error (m)."""
        return float(self.state.integral[0])

    @property
    def filter_value(self) -> float:
        """The low-pass filter's output (m/s^2)."""
        return float(self.state.filtered[0])

    def longitudinal(self, acceleration: float) -> tuple[float, float]:
        """(throttle, brake torque N m) for a filtered acceleration command (m/s^2)."""
        return longitudinal(self.constants, float(acceleration))

    def control(
        self,
        now_s: float,
        target_linear_mps: float,
        target_angular_radps: float,
        twist_time_s: float,
        current_speed_mps: float,
        velocity_time_s: float,
        dbw_enabled: bool,
    ) -> DBWCommand:
        """The commands at ``now_s`` (see the module docstring).

        ``twist_time_s`` and ``velocity_time_s`` are when the twist command and the speed
        were last received (for the watchdog).
        """
        self._control(self.constants, self.state, 0, float(now_s), float(target_linear_mps),
                      float(target_angular_radps), float(twist_time_s),
                      float(current_speed_mps), float(velocity_time_s), bool(dbw_enabled))
        if not dbw_enabled:
            return NO_COMMAND
        throttle, brake, steering = self.state.command[0].tolist()
        return DBWCommand(throttle, brake, steering)
