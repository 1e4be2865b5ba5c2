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

Beyond the seed's first version, its further work as options (each off by default, so the
machine above is unchanged): the modes Alert, Caution, Reverse and Hyper on top of the four
(:mod:`sdc_agents.highway.fsm_modes`; ``mode`` is the one in force, ``base_mode`` the
seed's), straight-line maximum braking, crash rerouting and quintic easing of the steering
target (:mod:`sdc_agents.highway.fsm_options`); all read from a rule file too
(:mod:`sdc_agents.highway.fsm_rules`).

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

import math

from sdc_agents.highway.fsm_modes import OptionalModes, SpeedGoal
from sdc_agents.highway.fsm_options import FSMOptions
from sdc_agents.highway.fsm_parameters import (
    ACTIVE,
    CALM,
    MAX_SPEED_MPS,
    MPH,
    SPEED_LIMIT_MPS,
    DrivingStyle,
    FSMParameters,
    Mode,
    RangeProfile,
)
from sdc_gym.stack.highway.behavior import BehaviorDecision
from sdc_gym.stack.highway.world_model import LaneView, WorldModel

# the parameters stay importable from here, as before the split
__all__ = [
    "ACTIVE", "CALM", "MAX_SPEED_MPS", "MPH", "SPEED_LIMIT_MPS", "DrivingStyle", "FSMBehavior",
    "FSMParameters", "Mode", "RangeProfile"
]


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
        # The optional modes (Alert, Caution, Reverse, Hyper), when any is on.
        self._extra = OptionalModes(self._params) if self._params.extra_modes else None
        # The options (straight-line braking, crash rerouting, easing), when any is on.
        p = self._params
        self._options = FSMOptions(p) if (p.straight_braking.enabled or p.reroute.enabled
                                          or p.easing.enabled) else None
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
        """The mode in force: an optional mode while one holds, else the seed's."""
        extra = self._extra
        if extra is not None and extra.mode is not None:
            return extra.mode
        return self._mode

    @property
    def base_mode(self) -> Mode:
        """The seed's mode (Launch, Adapt, Advance, Cruise), under any optional one."""
        return self._mode

    @property
    def modes_entered(self) -> frozenset[str]:
        """The optional modes entered since the episode began (none without them)."""
        return frozenset(self._extra.entered) if self._extra is not None else frozenset()

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
        if self._extra is not None:
            self._extra.reset()
        if self._options is not None:
            self._options.reset()

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
            if self._options is not None and self._params.easing.enabled:
                self._options.snap(target)

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

        extra = self._extra
        special = None
        brake_range = prof.brake_range_m
        if extra is not None:
            special = extra.update(world, mode, ahead, prof.mid_range_m, p.cruise_speed_mps)
            if special is Mode.ALERT:
                lead_gap, lead_speed = extra.alert_lead(world, lead_gap, lead_speed)
                brake_range = max(brake_range, p.alert.brake_range_m)

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
        if k > 0.0 and brake_range <= lead_gap < math.inf and mode is not Mode.LAUNCH:
            cap = self._range_speed(brake_range, lead_speed) + k * (lead_gap - brake_range)
            if cap < goal:
                goal = cap
                following = True
                if goal < v and accel < p.normal_acceleration_mps2:
                    accel = p.normal_acceleration_mps2
        if lead_gap < brake_range:
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
            if lead_gap < brake_range and push > lead_speed:
                push = lead_speed
            if push > vmax:
                push = vmax
            if push > goal:
                goal = push
                accel = p.push_acceleration_mps2
                replan = True
        if special is not None:
            assert extra is not None
            speed = SpeedGoal(goal, accel, hard, replan)
            extra.adjust_speed(world, speed, p.cruise_speed_mps, self._changing, target)
            goal, accel, hard, replan = speed.goal, speed.accel, speed.hard, speed.replan
            if goal > vmax:
                goal = vmax
        options = self._options
        if options is not None and p.straight_braking.enabled:
            accel = options.braking(accel, hard, world)

        # Lane changes (an optional mode's choice first, where it makes one; then crash
        # rerouting's).
        choice = None
        if special is not None and not self._changing:
            assert extra is not None
            choice = extra.lane_change(world, now - self._last_change_time, hard)
        closed: frozenset[int] = frozenset()
        if options is not None and p.reroute.enabled:
            closed = options.closed_lanes(world)
            if (choice is None and ego in closed and not self._changing and not hard
                    and mode is not Mode.LAUNCH
                    and world.road_radius > p.single_change_radius_m):
                choice = self._reroute(lanes, world.lane_count, ego, v, closed)
                if choice < 0:
                    choice = None  # no way out yet: the seed's rules as usual
        if choice is not None:
            if choice >= 0:
                replan = True
                target = self._begin_change(choice, target, now, mode)
        elif (
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
            if new in closed or (abs(new - ego) == 2 and (ego + new) // 2 in closed):
                new = -1  # never into (or across) a lane a crash closes
            if new >= 0:
                target = self._begin_change(new, target, now, mode)

        target_d = None
        if options is not None and p.easing.enabled:
            target_d = options.target_d(world, target)

        return BehaviorDecision(
            target_lane=target,
            target_speed=goal,
            acceleration=accel,
            replan=replan,
            steering=mode is not Mode.LAUNCH,
            mode=(special or mode).value,
            target_d=target_d,
        )

    def _reroute(self, lanes: tuple[LaneView, ...], n: int, ego: int, v: float,
                 closed: frozenset[int]) -> int:
        """Crash rerouting's lane out of a closed ``ego`` lane: an adjacent open lane with
        more room ahead and a safe gap behind (the most room first), or -1."""
        for t in self._most_room_first(lanes, n, ego - 1, ego + 1):
            if (t not in closed and lanes[t].ahead_gap > lanes[ego].ahead_gap
                    and self._safe_behind(lanes[t], v, self._params.safety_gap_min_m)):
                return t
        return -1

    def _begin_change(self, new: int, target: int, now: float, mode: Mode) -> int:
        """Start a lane change from ``target`` (the lane driven to) to ``new``."""
        self._origin_lane = target
        self._target_lane = new
        self._last_change_time = now
        self._changing = True
        self._aborted = False
        self._change_began_in_advance = mode is Mode.ADVANCE
        return new

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

    def _range_speed(self, brake_range_m: float, lead_speed: float) -> float:
        """The braking curve's speed at the edge of its range, behind ``lead_speed``."""
        return self._params.braking_percent(brake_range_m) * 0.01 * lead_speed

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
