"""The seed FSM's parameters: the driving styles, the range profiles and
:class:`FSMParameters` (every threshold of :mod:`sdc_agents.highway.fsm`, with where it comes
from), apart from the state machine that reads them."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, replace

from sdc_agents.highway.fsm_mode_parameters import (
    AlertRules,
    CautionRules,
    EasingRules,
    HyperRules,
    RerouteRules,
    ReverseRules,
    StraightBrakingRules,
)
from sdc_gym.stack.highway.behavior import (
    BRAKE_CURVE_DECAY_PER_M,
    BRAKE_CURVE_GAIN_PCT_PER_M,
    BRAKE_CURVE_OFFSET_PCT,
    GENTLE_ACCELERATION,
    LAUNCH_ACCELERATION,
    MAX_BRAKING,
    NORMAL_ACCELERATION,
    SAFETY_GAP_MIN_M,
    SAFETY_HORIZON_S,
    STEP,
)
from sdc_gym.stack.highway.behavior import braking_percent as seed_braking_percent
from sdc_gym.stack.highway.behavior import safety_gap_m as seed_safety_gap_m

MPH = 0.44704  # m/s per mph
MAX_SPEED_MPS = 0.4455 / STEP  # 22.275 m/s = 49.83 mph: the seed's largest distance increment
SPEED_LIMIT_MPS = 50.0 * MPH  # 22.352 m/s: the simulator's overspeed limit


class DrivingStyle(enum.Enum):
    CONSERVATIVE = "conservative"
    BOLD = "bold"


class Mode(enum.Enum):
    LAUNCH = "launch"
    ADAPT = "adapt"
    ADVANCE = "advance"
    CRUISE = "cruise"
    # The optional modes (off by default; agents/highway/fsm_mode_parameters.py). They
    # sit on top of the four above, whose timers run on underneath.
    ALERT = "alert"
    CAUTION = "caution"
    REVERSE = "reverse"
    HYPER = "hyper"


@dataclass(frozen=True)
class RangeProfile:
    """The distances and cool-downs that the seed's ``Active`` flag shortens.

    The calm profile is Conservative outside Advance; the active one is Advance (any style)
    and Bold (every mode). Gaps are centre to centre (m); lane changes go to an adjacent
    lane "inward" (nearer the middle lane) or "outward".

    Attributes:
        brake_range_m: the braking curve applies to a lead car closer than this.
        mid_range_m: tactical lane changes start when the lead is closer than this.
        tactical_cooldown_s: least time between lane changes, tactical rules.
        strategic_cooldown_s: least time between lane changes, strategic rules.
        outward_ahead_m: room needed ahead in an outer lane (moving out of the middle).
        inward_ahead_m: room needed ahead in the middle lane (moving into it).
        double_middle_ahead_m: room needed ahead in the lane crossed by a double change
            (and never less than the hard-braking gap, 22.7 m: while changing, that lane's
            car ahead is a lead).
        long_range_clear_m: the ego lane's room ahead needed to return to the middle lane.
        early_change_max_gap_m: early lane changes for a lead between ``mid_range_m`` and
            this.
    """

    brake_range_m: float
    mid_range_m: float
    tactical_cooldown_s: float
    strategic_cooldown_s: float
    outward_ahead_m: float
    inward_ahead_m: float
    double_middle_ahead_m: float
    long_range_clear_m: float
    early_change_max_gap_m: float


CALM = RangeProfile(
    brake_range_m=50.0,
    mid_range_m=76.0,
    tactical_cooldown_s=15.0,
    strategic_cooldown_s=20.0,
    outward_ahead_m=100.0,
    inward_ahead_m=76.0,
    double_middle_ahead_m=45.0,
    long_range_clear_m=100.0,
    early_change_max_gap_m=90.0,
)
ACTIVE = RangeProfile(
    brake_range_m=30.0,
    mid_range_m=35.0,
    tactical_cooldown_s=4.6,
    strategic_cooldown_s=5.0,
    outward_ahead_m=25.0,
    inward_ahead_m=25.0,
    double_middle_ahead_m=20.0,
    long_range_clear_m=35.0,
    early_change_max_gap_m=50.0,
)


@dataclass(frozen=True)
class FSMParameters:
    """Every constant of the planner, with its unit. Defaults: the Conservative style.

    Attributes:
        calm, active: the distance and cool-down profiles (see :class:`RangeProfile`).
        max_speed_mps: no target speed ever exceeds this (49.83 mph).
        cruise_speed_mps: the target speed on an unobstructed road.
        low_cruise_speed_mps: 40 mph: Launch -> Adapt above, Cruise -> Adapt below,
            Adapt -> Cruise above.
        high_cruise_speed_mps: 49 mph: Advance -> Cruise above.
        normal_acceleration_mps2, launch_acceleration_mps2, max_braking_mps2,
        gentle_acceleration_mps2: the seed's speed-change rates.
        push_acceleration_mps2: rate used when pushed from behind (the seed reuses the
            maximum braking figure as an acceleration).
        patience_s: time blocked in Adapt before Advance.
        adapt_clear_ahead_m: room ahead that ends "blocked" and allows Adapt -> Cruise.
        open_lane_m: a lane whose car ahead is at least this far is "open" (inf: nobody).
        centred_tolerance_m: "centred in a lane" for the mode transitions.
        lane_change_done_tolerance_m: a lane change is complete within this of the centre.
        advance_speed_factor: Advance's speed goal, x the lead car's speed.
        adapt_after_advance_lane_change: go back to Adapt after a lane change in Advance.
        brake_curve_gain_pct_per_m, brake_curve_decay_per_m, brake_curve_offset_pct: the
            braking curve p(d) = (gain / decay) (1 - exp(-decay d)) - offset, in %.
        hard_braking_fraction: below this fraction of the lead's speed: replan, brake hard.
        push_from_behind_m: a car closer behind than this makes the ego speed up to the
            mean of the lead's and the follower's speeds (0 disables).
        safety_gap_min_m: the least gap to a car behind in a target lane.
        safety_horizon_s: how far ahead the car behind is projected (constant speeds).
        far_lane_ahead_m: merging into the middle lane, the far lane's car ahead must be
            further than this (it could merge into the middle lane too).
        check_far_lane_behind: merging into the middle lane, the far lane's car behind must
            also be at a safe gap (Conservative).
        double_target_clear_m: a double change needs this much room ahead and behind in the
            target lane.
        return_behind_m: least gap behind in the lane of a strategic change.
        return_far_lane_clear_m: returning to the middle lane, the far lane must be clear by
            this ahead and behind.
        single_change_radius_m: lane changes need a road radius above this.
        double_change_radius_m: double lane changes need a road radius above this.
        approach_gain_per_s: beyond the braking range, the speed goal is capped at
            ``p(range) x lead speed + gain x (gap - range)``, continuous with the braking
            curve at its edge (0 disables the cap: the seed's step from the mode's goal
            to ``p(range)`` at the edge; see "Following" in the module docstring).
        far_lane_merge_watch_m: merging into the middle lane, a far-lane car closer than
            this either way (centre to centre) that may change lanes too makes the ego
            wait: one moving toward the middle lane, or one held up (below).
        far_lane_held_up_s: a far-lane car with a car ahead in its own lane closer than
            this many seconds at its own speed (centre to centre) and no faster than itself
            is held up: it may move over (4 s: 88 m at 49 mph, where car following starts
            to slow a car down).
        abort_gap_m: during a lane change, a car in the target lane closer than this
            either way (or closing on it behind) sends the ego back to its lane, while
            the ego is still within ``abort_window_m`` of the lane it left.
        abort_window_m: how far (m, laterally) from its old lane's centre a lane change
            can still be aborted (2 m: up to the lane line).
        merge_rate_mps: a car in the lane beyond the target one moving toward it faster
            than this (m/s, lateral) counts as entering the target lane.
        alert, caution, reverse, hyper: the optional modes (each off unless ``enabled``;
            see :mod:`sdc_agents.highway.fsm_mode_parameters`).
        straight_braking, reroute, easing: the options straight-line maximum braking,
            crash rerouting and quintic easing of the steering target (the same module).
    """

    calm: RangeProfile = CALM
    active: RangeProfile = ACTIVE
    max_speed_mps: float = MAX_SPEED_MPS
    cruise_speed_mps: float = MAX_SPEED_MPS
    low_cruise_speed_mps: float = 17.8816
    high_cruise_speed_mps: float = 21.905
    normal_acceleration_mps2: float = NORMAL_ACCELERATION
    launch_acceleration_mps2: float = LAUNCH_ACCELERATION
    max_braking_mps2: float = MAX_BRAKING
    gentle_acceleration_mps2: float = GENTLE_ACCELERATION
    push_acceleration_mps2: float = MAX_BRAKING
    patience_s: float = 15.0
    adapt_clear_ahead_m: float = 100.0
    open_lane_m: float = math.inf
    centred_tolerance_m: float = 0.25
    lane_change_done_tolerance_m: float = 0.5
    advance_speed_factor: float = 1.05
    adapt_after_advance_lane_change: bool = True
    brake_curve_gain_pct_per_m: float = BRAKE_CURVE_GAIN_PCT_PER_M
    brake_curve_decay_per_m: float = BRAKE_CURVE_DECAY_PER_M
    brake_curve_offset_pct: float = BRAKE_CURVE_OFFSET_PCT
    hard_braking_fraction: float = 0.8
    push_from_behind_m: float = 10.0
    safety_gap_min_m: float = SAFETY_GAP_MIN_M
    safety_horizon_s: float = SAFETY_HORIZON_S
    far_lane_ahead_m: float = 13.0
    check_far_lane_behind: bool = True
    double_target_clear_m: float = 50.0
    return_behind_m: float = 21.0
    return_far_lane_clear_m: float = 50.0
    single_change_radius_m: float = 500.0
    double_change_radius_m: float = 3000.0
    approach_gain_per_s: float = 1.0
    far_lane_merge_watch_m: float = 20.0
    far_lane_held_up_s: float = 4.0
    abort_gap_m: float = 8.0
    abort_window_m: float = 2.0
    merge_rate_mps: float = 0.3
    alert: AlertRules = field(default_factory=AlertRules)
    caution: CautionRules = field(default_factory=CautionRules)
    reverse: ReverseRules = field(default_factory=ReverseRules)
    hyper: HyperRules = field(default_factory=HyperRules)
    straight_braking: StraightBrakingRules = field(default_factory=StraightBrakingRules)
    reroute: RerouteRules = field(default_factory=RerouteRules)
    easing: EasingRules = field(default_factory=EasingRules)

    def __post_init__(self) -> None:
        if not 0.0 < self.max_speed_mps <= SPEED_LIMIT_MPS:
            raise ValueError(f"max_speed_mps must be in (0, {SPEED_LIMIT_MPS}] m/s")
        if not 0.0 < self.cruise_speed_mps <= self.max_speed_mps:
            raise ValueError("cruise_speed_mps must be in (0, max_speed_mps]")
        if self.brake_curve_decay_per_m <= 0.0:
            raise ValueError("brake_curve_decay_per_m must be > 0")

    @property
    def extra_modes(self) -> bool:
        """Whether any optional mode is on (the seed's machine alone when not)."""
        return (self.alert.enabled or self.caution.enabled or self.reverse.enabled
                or self.hyper.enabled)

    @classmethod
    def for_style(cls, style: DrivingStyle, **overrides: object) -> FSMParameters:
        """The seed's constants for ``style``; keyword arguments replace single fields."""
        base = cls()
        if style is DrivingStyle.BOLD:
            base = replace(
                base,
                calm=ACTIVE,
                advance_speed_factor=1.10,
                adapt_after_advance_lane_change=False,
                check_far_lane_behind=False,
                push_from_behind_m=0.0,
            )
        return replace(base, **overrides) if overrides else base

    def braking_percent(self, gap_m: float) -> float:
        """p(d): % of the lead car's speed to drive at, ``gap_m`` behind it (0 to 100)."""
        return seed_braking_percent(gap_m, self.brake_curve_gain_pct_per_m,
                                    self.brake_curve_decay_per_m, self.brake_curve_offset_pct)

    @property
    def hard_braking_gap_m(self) -> float:
        """The gap below which the braking curve asks for less than
        ``hard_braking_fraction`` of the lead's speed (a replan and the maximum braking):
        22.7 m with the seed's curve. p(d) solved for d."""
        k = self.brake_curve_decay_per_m
        rest = 1.0 - ((100.0 * self.hard_braking_fraction + self.brake_curve_offset_pct) * k
                      / self.brake_curve_gain_pct_per_m)
        return -math.log(rest) / k if rest > 0.0 else math.inf

    def safety_gap_m(self, behind_speed_mps: float, ego_speed_mps: float) -> float:
        """The gap a car behind in a target lane needs: its 3 s projection plus 11 m."""
        return seed_safety_gap_m(behind_speed_mps, ego_speed_mps, self.safety_gap_min_m,
                                 self.safety_horizon_s)
