"""The seed's rule-based behavior layer: a four-mode finite state machine in two styles.

Modes (:class:`Mode`)
    * Launch: accelerate straight at the launch rate, steering muted; to Adapt above 40 mph
      (or, beyond the seed, as soon as a lead car is inside the braking range). The
      motion layer steers the straight launch states still queued at the hand-over.
    * Adapt: follow the car ahead (the braking curve below); to Advance after ``patience_s``
      blocked; to Cruise above 40 mph, centred (+-0.25 m) in a lane clear for 100 m.
    * Advance: close in on the car ahead (1.05 x its speed, 1.10 Bold, at the gentle rate),
      with the *active* distances and cool-downs (lane changes more often); to Cruise when
      the lane ahead is open, the car centred and above 49 mph; the Conservative style goes
      back to Adapt once a lane change begun in Advance is complete.
    * Cruise: drive at the cruise speed with the long-range (strategic) lane choices; to
      Adapt below 40 mph or when a car is detected ahead (inside the braking range).

Styles (:class:`DrivingStyle`): Conservative uses the *calm* distances and cool-downs outside
Advance, checks the far lane behind before merging into the middle lane and pushes forward
from a tailgater (ghosting is perception's part); Bold ("Active") uses the short distances
and cool-downs in every mode and closes in at 1.10 x in Advance.

Rules, in the order applied each cycle (all modes but Launch, whose lane is fixed):

1. Short range: within ``brake_range_m`` of the lead car, target
   ``p(d) / 100 x lead speed`` with ``p(d) = (a / k) (1 - exp(-k d)) - c`` clipped to
   [0, 100]; below 80 % flag a replan, brake at the maximum rate and allow no lane change.
2. Mid range (tactical, lead within ``mid_range_m``, after ``tactical_cooldown_s``): change
   to an adjacent lane with more room ahead than the ego lane and a safe gap behind; a
   double change when the road is straight enough.
3. Long range (strategic, after ``strategic_cooldown_s``): return to the open middle lane
   when the ego lane is clear; move early to an open adjacent lane when a car shows up
   between ``mid_range_m`` and ``early_change_max_gap_m`` ahead.

Where this implementation goes beyond the seed, and why
    * **Following.** The seed drives at the mode's goal (cruise speed, or 1.05-1.10 x the
      lead in Advance) until the lead enters the braking range, where the goal drops to
      ``p(range)`` x the lead's speed (90 % at Bold's 30 m). The ego then falls back out
      of the range, speeds up again, and hunts: a 35-45 mph sawtooth with hard braking
      and jerk above 5 m/s^3 by the original's measure. Beyond the range the goal is
      therefore capped at ``p(range) x u + approach_gain_per_s x (gap - range)``, which
      meets the braking curve at its edge: the ego settles at
      ``range + u (1 - p(range)) / gain`` (about 32 m for Bold, 50 m Conservative in
      Adapt) at the lead's speed ``u``, and a far lead is approached at a deceleration of
      ``gain x`` the closing speed. A lead held this way counts as blocking for the
      tactical rules even outside ``mid_range_m``.
    * **Far-lane cars beside the ego.** The seed checks the far lane for "potential
      lane-changing vehicles" before merging into the middle lane. Traffic merges into a
      lane that is clear by +-20 m of it, so both could move at once: merging into the
      middle lane waits while a far-lane car within ``far_lane_merge_watch_m`` either way
      may move over (both styles): one already moving toward the middle lane, or one held
      up by a car close ahead in its own lane that is no faster. A far-lane car with open
      road ahead has no reason to change lanes and does not hold the ego back (waiting
      for every far-lane car beside had cost Bold 0.7 mph over seeds 0-19).
    * **Aborting a lane change.** If a car appears in the target lane beside the ego (or
      closes in behind faster than the safety gap allows) while the ego is still on its
      side of the lane line, the ego goes back to its lane (once per lane change), with a
      replan: the queued path would carry it on toward that car for another second.

Gaps
    The world model's gaps are centre-to-centre s distances, which is also how the seed
    measured every distance it quotes (car s minus sensed s), so all thresholds are used as
    given, centre to centre. With cars about 5 m long, ``p(5 m) = 0`` means bumper to
    bumper, and the 11 m minimum safety gap behind leaves about 6 m of clear road.
    A car "behind" is safe when its gap exceeds
    ``max(11, 3 s x (v_behind - v_ego) + 11)`` m: where it will be after 3 s at constant
    speeds, plus the 11 m margin. A lane is "open" ahead when its car ahead is at least
    ``open_lane_m`` away (``inf``: nobody sensed, the seed's empty lane).

Clock: ``world.time``. Lane-change cool-downs count from the last lane change, and from the
first cycle of the episode (the seed's timers start with the program). A lane change is
complete when the ego is within ``lane_change_done_tolerance_m`` of the target lane's centre;
no other lane change starts before that.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, replace

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
    BehaviorDecision,
)
from sdc_gym.stack.highway.behavior import braking_percent as seed_braking_percent
from sdc_gym.stack.highway.behavior import safety_gap_m as seed_safety_gap_m
from sdc_gym.stack.highway.world_model import LaneView, WorldModel

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

    def __post_init__(self) -> None:
        if not 0.0 < self.max_speed_mps <= SPEED_LIMIT_MPS:
            raise ValueError(f"max_speed_mps must be in (0, {SPEED_LIMIT_MPS}] m/s")
        if not 0.0 < self.cruise_speed_mps <= self.max_speed_mps:
            raise ValueError("cruise_speed_mps must be in (0, max_speed_mps]")
        if self.brake_curve_decay_per_m <= 0.0:
            raise ValueError("brake_curve_decay_per_m must be > 0")

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


class FSMBehavior:
    """The seed's finite state machine as a :class:`~sdc_gym.stack.highway.behavior.BehaviorPolicy`.

    Args:
        style: picks the default parameters (``FSMParameters.for_style(style)``).
        params: replace those defaults wholesale (``style`` then only labels the agent).
    """

    def __init__(
        self,
        style: DrivingStyle = DrivingStyle.CONSERVATIVE,
        params: FSMParameters | None = None,
    ) -> None:
        self._style = style
        self._params = params if params is not None else FSMParameters.for_style(style)
        self.reset()

    # ----------------------------------------------------------------- read-only state
    @property
    def style(self) -> DrivingStyle:
        return self._style

    @property
    def params(self) -> FSMParameters:
        return self._params

    @property
    def mode(self) -> Mode:
        return self._mode

    @property
    def target_lane(self) -> int:
        """The lane being driven to (-1 before the first cycle)."""
        return self._target_lane

    @property
    def lane_change_in_progress(self) -> bool:
        return self._changing

    @property
    def time_in_mode(self) -> float:
        """s since the current mode was entered (as of the last cycle)."""
        return self._now - self._mode_since

    @property
    def blocked_time(self) -> float:
        """s blocked in Adapt (the patience timer; 0 in other modes)."""
        return self._now - self._blocked_since if self._mode is Mode.ADAPT else 0.0

    @property
    def time_since_lane_change(self) -> float:
        """s since the last lane change began (or since the first cycle)."""
        return self._now - self._last_change_time

    @property
    def profile(self) -> RangeProfile:
        """The distances and cool-downs in force: the active profile in Advance, else the
        calm one (which is the active one for the Bold style)."""
        return self._params.active if self._mode is Mode.ADVANCE else self._params.calm

    # ----------------------------------------------------------------------- policy
    def reset(self) -> None:
        self._world: WorldModel | None = None  # the cycle's world model, for the lane rules
        self._mode = Mode.LAUNCH
        self._started = False
        self._now = 0.0
        self._mode_since = 0.0
        self._blocked_since = 0.0
        self._last_change_time = 0.0
        self._target_lane = -1
        self._changing = False
        self._change_began_in_advance = False
        self._origin_lane = -1
        self._aborted = False

    def _enter(self, mode: Mode, now: float) -> None:
        self._mode = mode
        self._mode_since = now
        if mode is Mode.ADAPT:
            self._blocked_since = now

    def decide(self, world: WorldModel) -> BehaviorDecision:
        p = self._params
        now = world.time
        self._world = world
        if not self._started:
            self._started = True
            self._target_lane = world.ego_lane
            self._mode_since = self._blocked_since = self._last_change_time = now
        self._now = now
        lanes = world.lanes
        ego = world.ego_lane
        v = world.ego_speed
        width = world.lane_width
        target = self._target_lane

        # Lane change completion (and Conservative's Advance -> Adapt after it).
        if self._changing and (
            abs(world.ego_d - (target + 0.5) * width) <= p.lane_change_done_tolerance_m
        ):
            self._changing = False
            if (
                self._change_began_in_advance
                and self._mode is Mode.ADVANCE
                and p.adapt_after_advance_lane_change
            ):
                self._enter(Mode.ADAPT, now)

        aborting = self._changing and not self._aborted and self._must_abort(world, target)
        if aborting:
            # Someone took the gap: back to the lane being left (once per lane change),
            # now: the queued path would carry the car on toward them for another second.
            self._target_lane = target = self._origin_lane
            self._aborted = True

        own = lanes[ego]
        ahead = own.ahead_gap
        centred = (not self._changing) and abs(
            world.ego_d - (ego + 0.5) * width
        ) <= p.centred_tolerance_m

        # Mode transitions: at most one per cycle.
        mode = self._mode
        if mode is Mode.LAUNCH:
            # A lead inside the braking range ends the launch too: behind a car slower
            # than 40 mph the seed's launch (steering muted) would never end.
            if v > p.low_cruise_speed_mps or ahead < p.calm.brake_range_m:
                self._enter(Mode.ADAPT, now)
        elif mode is Mode.ADAPT:
            if ahead >= p.adapt_clear_ahead_m:
                self._blocked_since = now  # not blocked: patience restarts
                if v > p.low_cruise_speed_mps and centred:
                    self._enter(Mode.CRUISE, now)
            elif now - self._blocked_since > p.patience_s:
                self._enter(Mode.ADVANCE, now)
        elif mode is Mode.ADVANCE:
            if ahead >= p.open_lane_m and centred and v > p.high_cruise_speed_mps:
                self._enter(Mode.CRUISE, now)
        elif v < p.low_cruise_speed_mps or ahead < p.calm.brake_range_m:  # Cruise
            self._enter(Mode.ADAPT, now)
        mode = self._mode
        prof = self.profile

        # The lead: the ego lane's car ahead, and while changing lanes also the cars ahead
        # in the lanes up to the target one (whichever is nearest).
        lead_gap = ahead
        lead_speed = own.ahead_speed
        if self._changing and target != ego:
            step = 1 if target > ego else -1
            for lane_index in range(ego + step, target + step, step):
                lv = lanes[lane_index]
                if lv.ahead_gap < lead_gap:
                    lead_gap = lv.ahead_gap
                    lead_speed = lv.ahead_speed

        # Speed.
        vmax = p.max_speed_mps
        replan = aborting
        if mode is Mode.LAUNCH:
            goal = p.cruise_speed_mps
            accel = p.launch_acceleration_mps2
        elif mode is Mode.ADVANCE:
            goal = (
                p.advance_speed_factor * lead_speed if lead_gap != math.inf else p.cruise_speed_mps
            )
            accel = p.gentle_acceleration_mps2
        else:
            goal = p.cruise_speed_mps
            accel = p.normal_acceleration_mps2
        hard = False
        following = False  # the lead, not the mode, sets the speed goal
        k = p.approach_gain_per_s
        if k > 0.0 and prof.brake_range_m <= lead_gap < math.inf and mode is not Mode.LAUNCH:
            cap = self._range_speed(prof, lead_speed) + k * (lead_gap - prof.brake_range_m)
            if cap < goal:
                goal = cap
                following = True
                if goal < v and accel < p.normal_acceleration_mps2:
                    accel = p.normal_acceleration_mps2
        if lead_gap < prof.brake_range_m:
            fraction = p.braking_percent(lead_gap) * 0.01
            goal = fraction * lead_speed
            if fraction < p.hard_braking_fraction:
                hard = replan = True
                accel = p.max_braking_mps2
        if goal > vmax:
            goal = vmax
        if not hard and own.behind_gap < p.push_from_behind_m and mode is not Mode.LAUNCH:
            lead_v = lead_speed if lead_gap != math.inf else p.cruise_speed_mps
            push = 0.5 * (lead_v + own.behind_speed)
            if lead_gap < prof.brake_range_m and push > lead_speed:
                push = lead_speed
            if push > vmax:
                push = vmax
            if push > goal:
                goal = push
                accel = p.push_acceleration_mps2
                replan = True

        # Lane changes.
        if (
            mode is not Mode.LAUNCH
            and not hard
            and not self._changing
            and world.road_radius > p.single_change_radius_m
        ):
            since = now - self._last_change_time
            new = -1
            blocked = ahead < prof.mid_range_m or (following and lead_gap == ahead)
            if blocked and since > prof.tactical_cooldown_s:
                new = self._tactical(
                    lanes, world.lane_count, ego, ahead, v, prof, world.road_radius
                )
                if new >= 0:
                    replan = True
            if new < 0 and since > prof.strategic_cooldown_s:
                new = self._strategic(lanes, world.lane_count, ego, ahead, v, prof)
            if new >= 0:
                self._origin_lane = target
                self._target_lane = target = new
                self._last_change_time = now
                self._changing = True
                self._aborted = False
                self._change_began_in_advance = mode is Mode.ADVANCE

        return BehaviorDecision(
            target_lane=target,
            target_speed=goal,
            acceleration=accel,
            replan=replan,
            steering=mode is not Mode.LAUNCH,
            mode=mode.value,
        )

    def _must_abort(self, world: WorldModel, target: int) -> bool:
        """A car is in (or entering) the target lane right beside the ego, while the ego
        is still within ``abort_window_m`` of the lane it is leaving."""
        p = self._params
        origin_d = (self._origin_lane + 0.5) * world.lane_width
        if abs(world.ego_d - origin_d) > p.abort_window_m:
            return False
        step = 1 if target > self._origin_lane else -1
        half = 0.5 * world.lane_width
        v = world.ego_speed
        for car in world.cars:
            gap = car.gap
            if gap > p.abort_gap_m:
                continue
            # Inside the target lane, or heading into it from the lane beyond.
            offset = (car.d - (target + 0.5) * world.lane_width) * step
            in_lane = -half < offset < half or (
                half <= offset < 3.0 * half and car.d_rate * step < -p.merge_rate_mps
            )
            if not in_lane:
                continue
            if gap >= -p.abort_gap_m:  # alongside
                return True
            # Behind: closing in faster than the safety gap allows.
            if -gap < p.safety_horizon_s * (car.speed - v) + p.abort_gap_m:
                return True
        return False

    def _range_speed(self, prof: RangeProfile, lead_speed: float) -> float:
        """The braking curve's speed at the edge of its range, behind ``lead_speed``."""
        return self._params.braking_percent(prof.brake_range_m) * 0.01 * lead_speed

    # ------------------------------------------------------------------ lane rules
    def _safe_behind(self, lane: LaneView, v: float, least: float) -> bool:
        """The lane's car behind is further than ``least`` and than its safety gap."""
        p = self._params
        gap = lane.behind_gap
        return gap > least and gap > p.safety_gap_m(lane.behind_speed, v)

    def _merge_ok(self, lanes: tuple[LaneView, ...], n: int, cur: int, t: int, v: float) -> bool:
        """Merging from ``cur`` into ``t`` nearer the middle: the far lane's cars won't."""
        p = self._params
        f = 2 * t - cur
        if f < 0 or f >= n:
            return True
        far = lanes[f]
        if far.ahead_gap <= p.far_lane_ahead_m:
            return False
        if self._far_lane_merger_beside(f, t):
            return False
        return not p.check_far_lane_behind or self._safe_behind(far, v, p.safety_gap_min_m)

    def _far_lane_merger_beside(self, far_lane: int, target: int) -> bool:
        """A "potential lane-changing vehicle" (the seed) in ``far_lane`` within
        ``far_lane_merge_watch_m`` of the ego either way: one already moving toward
        ``target``, or one held up by a car close ahead in its own lane that is no faster
        (it has a reason to move over). Traffic checks only +-20 m of the target lane, so
        such a car and the ego could move into the same gap at once; a car with open road
        ahead has no reason to change lanes and does not hold the ego back."""
        p = self._params
        assert self._world is not None  # set by decide(), the only caller's caller
        cars = self._world.cars
        toward = 1.0 if target > far_lane else -1.0
        for car in cars:
            if car.lane != far_lane or abs(car.gap) >= p.far_lane_merge_watch_m:
                continue
            if car.d_rate * toward > p.merge_rate_mps:
                return True
            reach = p.far_lane_held_up_s * car.speed
            for other in cars:
                ahead = other.gap - car.gap
                if (other.lane == far_lane and 0.0 < ahead < reach
                        and other.speed <= car.speed):
                    return True
        return False

    @staticmethod
    def _most_room_first(lanes: tuple[LaneView, ...], n: int, a: int, b: int) -> tuple[int, ...]:
        """The lanes among ``a`` and ``b`` that exist, the one with more room ahead first
        (``a`` on a tie)."""
        if b < n and (a < 0 or lanes[b].ahead_gap > lanes[a].ahead_gap):
            a, b = b, a
        return tuple(t for t in (a, b) if 0 <= t < n)

    def _tactical(
        self,
        lanes: tuple[LaneView, ...],
        n: int,
        cur: int,
        ahead: float,
        v: float,
        prof: RangeProfile,
        radius: float,
    ) -> int:
        """Mid range: a lane around the slow car ahead, or -1."""
        p = self._params
        centre = (n - 1) * 0.5
        off = abs(cur - centre)
        least = p.safety_gap_min_m
        for t in self._most_room_first(lanes, n, cur - 1, cur + 1):
            lane = lanes[t]
            room = lane.ahead_gap
            if room <= ahead or not self._safe_behind(lane, v, least):
                continue
            if abs(t - centre) < off:  # into the middle lane
                if room > prof.inward_ahead_m and self._merge_ok(lanes, n, cur, t, v):
                    return t
            elif room > prof.outward_ahead_m:
                return t
        if radius > p.double_change_radius_m:
            clear = p.double_target_clear_m
            # The lane crossed is a lead lane during the change: a car in it closer than
            # the hard-braking gap would turn the manoeuvre into an emergency stop.
            crossed_room = max(prof.double_middle_ahead_m, p.hard_braking_gap_m)
            for t in self._most_room_first(lanes, n, cur - 2, cur + 2):
                lane = lanes[t]
                mid = lanes[(cur + t) // 2]
                if (
                    lane.ahead_gap > ahead
                    and lane.ahead_gap > clear
                    and self._safe_behind(lane, v, clear)
                    and mid.ahead_gap > crossed_room
                    and self._safe_behind(mid, v, least)
                ):
                    return t
        return -1

    def _strategic(
        self,
        lanes: tuple[LaneView, ...],
        n: int,
        cur: int,
        ahead: float,
        v: float,
        prof: RangeProfile,
    ) -> int:
        """Long range: back to the open middle lane, or early to an open lane, or -1."""
        p = self._params
        centre = (n - 1) * 0.5
        off = abs(cur - centre)
        inward = cur + 1 if cur < centre else cur - 1
        if off > 0.5 and ahead > prof.long_range_clear_m:  # return to the middle lane
            lane = lanes[inward]
            f = 2 * inward - cur
            far_clear = p.return_far_lane_clear_m
            if (
                lane.ahead_gap >= p.open_lane_m
                and self._safe_behind(lane, v, p.return_behind_m)
                and (
                    f < 0
                    or f >= n
                    or (lanes[f].ahead_gap > far_clear and lanes[f].behind_gap > far_clear)
                )
            ):
                return inward
        if prof.mid_range_m <= ahead < prof.early_change_max_gap_m:  # early change
            if off > 0.5:  # the middle lane first
                candidates = tuple(t for t in (inward, 2 * cur - inward) if 0 <= t < n)
            else:  # from the middle: the lane with the most room first
                candidates = self._most_room_first(lanes, n, cur - 1, cur + 1)
            for t in candidates:
                lane = lanes[t]
                if lane.ahead_gap < p.open_lane_m or not self._safe_behind(
                    lane, v, p.return_behind_m
                ):
                    continue
                if abs(t - centre) < off and not self._merge_ok(lanes, n, cur, t, v):
                    continue
                return t
        return -1
