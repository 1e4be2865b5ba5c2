"""The thresholds of the FSM's optional modes, the seed's "further research" list
(``seeds/004``: "Additional modes: Alert, Caution, Reverse, Hyper"). Each mode is off by
default, so the seed's four-mode machine is what :class:`FSMParameters` describes unless a
rule file or an agent name (``fsm_alert`` ...) turns one on; :mod:`sdc_agents.highway.fsm_modes`
applies them.

Every distance is a centre-to-centre gap along the road (m), as in the seed's rules.
"""

from __future__ import annotations

from dataclasses import dataclass

from sdc_gym.stack.highway.behavior import MAX_BRAKING


@dataclass(frozen=True)
class AlertRules:
    """Alert: "flag rogue obstacle vehicle behavior (swerving, high acceleration)".

    A car within ``watch_ahead_m`` ahead or ``watch_behind_m`` behind that moves toward
    the ego's lane faster than ``swerve_rate_mps`` (a normal 3 s lane change of the
    traffic peaks near 2 m/s, a rogue 1 s cut-in near 6 m/s) or changes speed faster than
    ``accel_mps2`` is rogue. For ``hold_s`` after the last sighting the ego is in Alert:
    every gap to a lead reads ``margin_m`` shorter (the braking curve keeps that much more
    room), the braking range is at least ``brake_range_m``, a rogue car ahead in the next
    lane counts as a lead, and no lane change starts.
    """

    enabled: bool = False
    watch_ahead_m: float = 40.0
    watch_behind_m: float = 10.0
    swerve_rate_mps: float = 2.5
    accel_mps2: float = 5.5
    hold_s: float = 3.0
    margin_m: float = 10.0
    brake_range_m: float = 50.0


@dataclass(frozen=True)
class CautionRules:
    """Caution: "reduce velocity due to slow-moving traffic in adjacent lane".

    A car in an adjacent lane between ``behind_m`` behind and ``range_m`` ahead that is
    ``slow_by_mps`` or more slower than the ego is slow traffic; while one is there the ego
    passes it at most ``pass_by_mps`` faster than it (such cars are the ones that pull
    out), never below ``min_speed_mps``.
    """

    enabled: bool = False
    range_m: float = 60.0
    behind_m: float = 5.0
    slow_by_mps: float = 6.7
    pass_by_mps: float = 4.5
    min_speed_mps: float = 8.9


@dataclass(frozen=True)
class ReverseRules:
    """Reverse: "back out of a sudden blockage in the road".

    The highway's ego has no reverse gear (a path is points ahead of the car: the env's
    speed is never negative), so backing out is read as its two halves that a forward-only
    car can do: stop short of the blockage, then steer out of the blocked lane from where
    it stands. A car or road object slower than ``standing_mps`` in the ego lane within
    ``detect_m`` ahead is a blockage: the ego brakes on the straight-line stopping profile
    ``v = sqrt(2 a (gap - stop_gap_m))`` at ``a = stop_decel_mps2`` (so it stands
    ``stop_gap_m`` behind it), and changes to an adjacent lane with more than
    ``escape_ahead_m`` of room and a safe gap behind, in bends and during cool-downs
    too, at no more than ``escape_speed_mps`` until it has left the lane (still on a
    stopping profile, to ``escape_stop_gap_m`` behind the blockage, should the way out
    close). The goal runs ``a^2 / (2 motion_jerk_mps3)`` below the profile, where the
    motion layer's jerk-bounded arrival at a goal (4 m/s^3) still brakes at ``a``.
    """

    enabled: bool = False
    standing_mps: float = 1.0
    detect_m: float = 100.0
    stop_gap_m: float = 30.0
    stop_decel_mps2: float = 0.7 * MAX_BRAKING
    escape_ahead_m: float = 30.0
    escape_speed_mps: float = 5.0
    escape_stop_gap_m: float = 8.0
    motion_jerk_mps3: float = 4.0


@dataclass(frozen=True)
class HyperRules:
    """Hyper: "aggressive escape to faster lane, slowing to an open gap, double LC".

    Blocked by a lead within the mid range, a lane (adjacent, or two away for a double
    change) whose car ahead is ``faster_by_mps`` faster than the lead (or that is open)
    is a faster lane; the ego is in Hyper while one exists, for at most ``timeout_s``. It
    changes into it with the cool-down ``cooldown_s`` and double changes where the road's
    radius exceeds ``double_radius_m``; when the car behind in that lane is too close it
    slows to that car's speed less ``slow_by_mps`` so that it passes and opens the gap.

    Hyper is left only once the lead is ``exit_margin_m`` beyond the mid range (hysteresis):
    slowing for the gap lets the lead draw away, and leaving Hyper the moment it crosses the
    mid range would hand the speed back to the approach rule, which plans a second of
    acceleration toward a lead that may be braking (``stress_hard_braking_lead``: a
    collision without the margin).
    """

    enabled: bool = False
    faster_by_mps: float = 2.0
    cooldown_s: float = 2.0
    double_radius_m: float = 1000.0
    slow_by_mps: float = 2.0
    timeout_s: float = 20.0
    exit_margin_m: float = 10.0


# ---------------------------------------------------------------------------- options
# The seed's other further-work items, as options of the FSM (each off by default).


@dataclass(frozen=True)
class StraightBrakingRules:
    """Straight-line maximum braking: under the seed's hard braking (the braking curve
    below 80 %), brake at up to ``decel_limit_mps2`` less what the bend takes: the total
    acceleration stays within the limit, ``sqrt(decel^2 + (v^2 / R)^2) <= limit``
    (``R``: the road's circumradius ahead), never less than the seed's 8.42 m/s^2. The
    seed's step to 8.42 m/s^2 is kept; beyond it the deceleration grows at ``jerk_mps3``
    (the seed's "change in acceleration (+-10 m/s^3)")."""

    enabled: bool = False
    decel_limit_mps2: float = 9.5
    jerk_mps3: float = 10.0


@dataclass(frozen=True)
class RerouteRules:
    """Crash rerouting: a lane with a standing car or object (slower than
    ``standing_mps``) within ``range_m`` ahead is closed by a crash. From a closed lane
    the ego changes early (from any distance in range, the tactical cool-down
    notwithstanding) to an adjacent open lane with more room and a safe gap behind, and
    no lane change goes into a closed lane."""

    enabled: bool = False
    range_m: float = 200.0
    standing_mps: float = 1.0


@dataclass(frozen=True)
class EasingRules:
    """Quintic in-out easing of the steering target between lane splines: during a lane
    change the motion layer aims at ``d(t) = d0 + (d1 - d0) e(u)``, ``u = t / T`` with
    ``T = seconds_per_lane x`` the lanes crossed, ``e(u) = 16 u^5`` for ``u < 1/2`` and
    ``1 - (2 - 2u)^5 / 2`` after, instead of at the target lane's spline at once."""

    enabled: bool = False
    seconds_per_lane: float = 3.0
