"""The track stack's behavior layer: go or stop at the next stop line, and the target speed.

Between the traffic light detector and the waypoint updater sits one decision: stop at
the next stop line or not, and how fast to drive otherwise. The reference stack hard-wires
"stop for a red light"; here it is a :class:`TrackBehaviorPolicy` so that an RL policy can
take its place. A policy sees a :class:`TrackSituation` (speed, limit, the detector's
debounced light state, the stop line's distance) and returns a
:class:`TrackBehaviorDecision` that the waypoint updater executes (zero speed from its stop
margin before the chosen stop line, a comfortable ramp before it; the target speed caps
the waypoint speeds).

:class:`StopAtRedLights` is the rule-based policy. Besides the original's "stop for the
next red light, else drive at the limit" it handles what a red-only rule gets wrong on a
track whose lights go green -> yellow -> red:

* Yellow (on by default, ``stop_on_yellow``): the original treats yellow as "not red", so
  a light turning red when the car is closer than its braking distance forces a red-light
  violation. The policy stops for a yellow light when it can stop *comfortably*
  (``v^2 <= 2 comfortable_decel * room``), else it drives through while yellow. With the
  ITE yellow time (1 s reaction + ``v / (2 x 3.05 m/s^2)``) every case is covered. A
  light state source that only tells red from not-red (a binary classifier) reports no
  yellow, and the policy then falls back to the original rule.
* Red it cannot stop for (``v^2 > 2 |max_decel| * room``): braking could not keep the car
  behind the line, so it drives through (the stop is "not feasible") rather than stand
  on the brakes into the crossing.
* Once it has decided to stop for a line it keeps stopping for it while the light stays
  yellow or red, feasible or not: the decision to run a light is taken once, at the
  onset, never half-way through a stop (a car creeping the last centimetres to its stop
  would otherwise find the stop "infeasible" and accelerate into the red).
* UNKNOWN (no light in range, nothing recognised) counts as not red, as in the original:
  holding for an unseen light could stand forever.
* Cruise: ``speed_margin_mps`` below the limit, so that the speed controller's small
  overshoot never exceeds it.

``room`` is the distance from the car's reference point to where it should stop: the
stop line's distance minus the updater's stop margin.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from sdc_gym.lights.traffic_lights import UNKNOWN
from sdc_gym.stack.track.node_kernels import FEASIBILITY_SLACK_M, MODE_NAMES, can_stop, stop_at_red

DEFAULT_SPEED_MARGIN_MPS = 0.15
DEFAULT_COMFORTABLE_DECEL_MPS2 = 3.05  # ITE's comfortable deceleration (the env's yellow)
SQUARE = 2.0
"""The exponent of ``v ** 2`` in the stopping test, given to the kernel at run time (a
literal would be compiled to ``v * v``, which the C library's ``pow`` does not always
equal)."""

__all__ = ["DEFAULT_COMFORTABLE_DECEL_MPS2", "DEFAULT_SPEED_MARGIN_MPS", "FEASIBILITY_SLACK_M",
           "StopAtRedLights", "StopAtRedParameters", "TrackBehaviorDecision",
           "TrackBehaviorPolicy", "TrackSituation"]


@dataclass(frozen=True)
class TrackSituation:
    """What the behavior layer knows at a decision.

    Attributes:
        time_s: agent clock.
        speed_mps: current speed.
        speed_limit_mps: the track's limit for the stack.
        stop_line: index of the next stop line ahead (-1: none).
        stop_waypoint: its base waypoint index (-1: none).
        stop_line_distance_m: m from the car's reference point to that line (inf: none).
        light_state: the detector's debounced state of that line's light (RED 0,
            YELLOW 1, GREEN 2, UNKNOWN 4: out of range or not seen).
        stop_margin_m: the updater stops the reference point this far before the line.
    """

    time_s: float
    speed_mps: float
    speed_limit_mps: float
    stop_line: int = -1
    stop_waypoint: int = -1
    stop_line_distance_m: float = float("inf")
    light_state: int = UNKNOWN
    stop_margin_m: float = 0.0

    @property
    def room_m(self) -> float:
        """m left to where the car should stand (negative: already past that point)."""
        return self.stop_line_distance_m - self.stop_margin_m


@dataclass(frozen=True)
class TrackBehaviorDecision:
    """The behavior layer's output, executed by the waypoint updater.

    Attributes:
        target_speed_mps: cruise speed (caps every waypoint speed).
        stop_waypoint: base waypoint index of the stop line to stop at, -1: none.
        mode: a label for logs ("cruise", "stop_red", "stop_yellow", "go_yellow",
            "run_red").
    """

    target_speed_mps: float
    stop_waypoint: int = -1
    mode: str = ""


class TrackBehaviorPolicy(Protocol):
    """Anything that decides go/stop and the target speed from a situation."""

    def reset(self) -> None:
        """Forget all state (start of an episode)."""

    def decide(self, situation: TrackSituation) -> TrackBehaviorDecision:
        """The decision for this updater cycle."""


@dataclass(frozen=True)
class StopAtRedParameters:
    """Settings of :class:`StopAtRedLights`.

    Attributes:
        max_decel_mps2: the hardest deceleration the stack may use (positive; the
            vehicle's ``|decel_limit|``): a red light needing more is run.
        comfortable_decel_mps2: a yellow light is stopped for when this suffices.
        stop_on_yellow: stop for yellow lights that can be stopped for comfortably.
        speed_margin_mps: cruise this much below the limit (the speed controller's
            overshoot must not exceed the limit).
    """

    max_decel_mps2: float = 5.0
    comfortable_decel_mps2: float = DEFAULT_COMFORTABLE_DECEL_MPS2
    stop_on_yellow: bool = True
    speed_margin_mps: float = DEFAULT_SPEED_MARGIN_MPS

    def __post_init__(self) -> None:
        if not self.speed_margin_mps >= 0:
            raise ValueError(f"StopAtRedParameters: speed_margin_mps must be >= 0 m/s, got "
                             f"{self.speed_margin_mps!r}")
        if not (self.max_decel_mps2 > 0 and self.comfortable_decel_mps2 > 0):
            raise ValueError(f"StopAtRedParameters: decelerations must be > 0 m/s^2, got "
                             f"max {self.max_decel_mps2!r}, comfortable "
                             f"{self.comfortable_decel_mps2!r}")


class StopAtRedLights:
    """The rule-based behavior: stop for the next red (and stoppable yellow) light, else
    drive at the limit; see the module docstring. The rule is
    :func:`~sdc_gym.stack.track.node_kernels.stop_at_red`; this class is its batch of one."""

    def __init__(self, params: StopAtRedParameters | None = None) -> None:
        self.params = params or StopAtRedParameters()
        self.reset()

    def reset(self) -> None:
        self._stopping_for = -1  # the stop line the policy committed to stop at

    @staticmethod
    def can_stop(situation: TrackSituation, decel_mps2: float) -> bool:
        """Whether braking at ``decel_mps2`` stops the reference point before the line
        (with :data:`FEASIBILITY_SLACK_M`): ``v^2 <= 2 a (room + slack)``."""
        return bool(can_stop(float(situation.speed_mps), float(situation.room_m),
                             float(decel_mps2), SQUARE))

    def decide(self, situation: TrackSituation) -> TrackBehaviorDecision:
        p = self.params
        speed, waypoint, mode, self._stopping_for = stop_at_red(
            float(p.max_decel_mps2), float(p.comfortable_decel_mps2), bool(p.stop_on_yellow),
            float(p.speed_margin_mps),
            SQUARE, self._stopping_for, float(situation.speed_mps),
            float(situation.speed_limit_mps), int(situation.stop_line),
            int(situation.stop_waypoint), float(situation.room_m), int(situation.light_state))
        return TrackBehaviorDecision(speed, waypoint, MODE_NAMES[mode])
