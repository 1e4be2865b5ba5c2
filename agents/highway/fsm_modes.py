"""The FSM's optional modes (the seed's "Additional modes"): Alert, Caution, Reverse, Hyper.

Each is off unless its rules say ``enabled`` (:mod:`sdc_agents.highway.fsm_mode_parameters`,
a rule file's ``alert:``, ``caution:``, ``reverse:``, ``hyper:``). They sit on top of the
seed's four modes: Launch, Adapt, Advance and Cruise keep their transitions and timers
underneath, and the mode reported (``FSMBehavior.mode``, the decision's ``mode``) is the
optional one while it holds. At most one holds per cycle, by precedence: Reverse (a
blockage ahead), Alert (a rogue car near), Hyper (boxed in beside a faster lane), Caution
(slow traffic beside). None holds during Launch.

* **Alert** watches every sensed car near the ego for swerving toward the ego's lane and
  for speed changes beyond the traffic's own (its acceleration from the speeds of two
  cycles); the ego keeps ``margin_m`` more room, brakes within ``brake_range_m``, treats a
  rogue car ahead in the next lane as a lead, and starts no lane change.
* **Caution** caps the speed at a slow adjacent car's speed plus ``pass_by_mps`` while
  passing it (the speed goal the seed's mode had set is the reference for "slow", so the
  capped ego does not leave Caution by slowing down).
* **Reverse** (no reverse gear on the highway: see ``ReverseRules``) stops on a
  straight-line profile ``stop_gap_m`` behind a standing car or object in the ego lane,
  then leaves the lane at walking pace, cool-downs and bends notwithstanding.
* **Hyper** lane-changes into a faster lane with a short cool-down, double changes where
  the road is straight enough for it, and slows to let a car behind in that lane pass.

:class:`OptionalModes` holds the modes' state (rogue sightings, Hyper's clock) and the
rules; the FSM calls it at three points of its cycle (mode, speed, lane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sdc_agents.highway.fsm_parameters import FSMParameters, Mode
from sdc_gym.stack.highway.world_model import LaneView, WorldModel


@dataclass
class SpeedGoal:
    """The speed part of a decision, as the seed's rules left it, for a mode to change."""

    goal: float
    accel: float
    hard: bool
    replan: bool


class OptionalModes:
    """The optional modes' state and rules for one FSM (see the module docstring)."""

    def __init__(self, params: FSMParameters) -> None:
        self._p = params
        self.reset()

    def reset(self) -> None:
        self.mode: Mode | None = None
        self._speeds: dict[int, tuple[float, float]] = {}  # car id -> (time, speed)
        self._rogue_until = -math.inf
        self._rogue_ids: set[int] = set()
        self._hyper_since = math.nan
        self._hyper_spent = False
        self._reverse_entered = False
        self.entered: set[str] = set()  # every optional mode entered this episode

    # ------------------------------------------------------------------------ the mode
    def update(self, world: WorldModel, base: Mode, blocked_gap: float, mid_range: float,
               goal_speed: float) -> Mode | None:
        """The optional mode of this cycle (``None``: the seed's own). ``blocked_gap``:
        the ego lane's room ahead; ``goal_speed``: the seed's mode's speed goal."""
        p = self._p
        now = world.time
        rogue = self._watch_rogues(world) if p.alert.enabled else False
        mode: Mode | None = None
        if base is not Mode.LAUNCH:
            own = world.lanes[world.ego_lane]
            if p.reverse.enabled and self._blockage(own):
                mode = Mode.REVERSE
            elif p.alert.enabled and (rogue or now < self._rogue_until):
                mode = Mode.ALERT
            elif p.hyper.enabled and self._hyper_holds(world, blocked_gap, mid_range, now):
                mode = Mode.HYPER
            elif p.caution.enabled and self.slow_beside(world, goal_speed) is not None:
                mode = Mode.CAUTION
        if mode is not Mode.HYPER and not (p.hyper.enabled
                                           and blocked_gap < self._hyper_range(mid_range)):
            self._hyper_since = math.nan
            self._hyper_spent = False
        self._reverse_entered = mode is Mode.REVERSE and self.mode is not Mode.REVERSE
        self.mode = mode
        if mode is not None:
            self.entered.add(mode.value)
        return mode

    def _watch_rogues(self, world: WorldModel) -> bool:
        """Whether a car near the ego swerves toward its lane or changes speed like no
        traffic car does; remembers the speeds for the next cycle's accelerations."""
        a = self._p.alert
        now = world.time
        ego_d = world.ego_d
        seen: dict[int, tuple[float, float]] = {}
        found = False
        for car in world.cars:
            if not -a.watch_behind_m <= car.gap <= a.watch_ahead_m:
                continue
            seen[car.id] = (now, car.speed)
            toward = car.d_rate * (1.0 if ego_d > car.d else -1.0)
            swerving = toward > a.swerve_rate_mps and abs(car.d - ego_d) > 0.5
            jolting = False
            before = self._speeds.get(car.id)
            if before is not None and now > before[0]:
                jolting = abs(car.speed - before[1]) / (now - before[0]) > a.accel_mps2
            if swerving or jolting:
                found = True
                self._rogue_ids.add(car.id)
        self._speeds = seen
        if found:
            self._rogue_until = now + a.hold_s
        elif now >= self._rogue_until:
            self._rogue_ids.clear()
        return found

    def _blockage(self, own: LaneView) -> bool:
        r = self._p.reverse
        return own.has_ahead and own.ahead_gap < r.detect_m and own.ahead_speed < r.standing_mps

    def _faster_lanes(self, world: WorldModel, double: bool) -> list[int]:
        """Lanes (one away, or two with ``double``) whose car ahead is further than the
        ego lane's and faster than it by ``faster_by_mps`` (or that are open), the one with
        the most room first."""
        h = self._p.hyper
        lanes = world.lanes
        ego = world.ego_lane
        own = lanes[ego]
        reach = (2,) if double else (1,)
        found = []
        for step in reach:
            for t in (ego - step, ego + step):
                if not 0 <= t < world.lane_count:
                    continue
                lane = lanes[t]
                if lane.ahead_gap <= own.ahead_gap:
                    continue
                if lane.has_ahead and lane.ahead_speed < own.ahead_speed + h.faster_by_mps:
                    continue
                found.append(t)
        return sorted(found, key=lambda t: -lanes[t].ahead_gap)

    def _hyper_range(self, mid_range: float) -> float:
        """The lead's distance under which Hyper holds: the mid range to enter it, that
        plus the exit margin to stay in it (hysteresis)."""
        if self.mode is Mode.HYPER:
            return mid_range + self._p.hyper.exit_margin_m
        return mid_range

    def _hyper_holds(self, world: WorldModel, blocked_gap: float, mid_range: float,
                     now: float) -> bool:
        h = self._p.hyper
        if blocked_gap >= self._hyper_range(mid_range) or self._hyper_spent:
            return False
        if not (self._faster_lanes(world, False) or self._faster_lanes(world, True)):
            return False
        if math.isnan(self._hyper_since):
            self._hyper_since = now
        elif now - self._hyper_since > h.timeout_s:
            self._hyper_spent = True  # until the ego is no longer blocked
            return False
        return True

    def slow_beside(self, world: WorldModel, goal_speed: float) -> float | None:
        """The speed of the slowest car in an adjacent lane beside or ahead within
        Caution's range that is ``slow_by_mps`` below ``goal_speed`` (``None``: none)."""
        c = self._p.caution
        ego = world.ego_lane
        slowest: float | None = None
        for car in world.cars:
            if abs(car.lane - ego) != 1 or not -c.behind_m <= car.gap <= c.range_m:
                continue
            if goal_speed - car.speed >= c.slow_by_mps and (slowest is None
                                                              or car.speed < slowest):
                slowest = car.speed
        return slowest

    # ----------------------------------------------------------------------- the lead
    def alert_lead(self, world: WorldModel, lead_gap: float, lead_speed: float
                   ) -> tuple[float, float]:
        """Alert's lead: the nearer of the seed's lead and a rogue car ahead in the next
        lane, its gap ``margin_m`` shorter."""
        a = self._p.alert
        for car in world.cars:
            if (car.id in self._rogue_ids and 0.0 < car.gap < lead_gap
                    and abs(car.lane - world.ego_lane) <= 1):
                lead_gap, lead_speed = car.gap, car.speed
        if lead_gap != math.inf:
            lead_gap = max(lead_gap - a.margin_m, 0.0)
        return lead_gap, lead_speed

    # ---------------------------------------------------------------------- the speed
    def adjust_speed(self, world: WorldModel, speed: SpeedGoal, mode_goal: float,
                     changing: bool, target: int) -> None:
        """The optional mode's change to the speed goal (in place)."""
        p = self._p
        v = world.ego_speed
        if self.mode is Mode.CAUTION:
            slow = self.slow_beside(world, mode_goal)
            if slow is not None:
                cap = max(slow + p.caution.pass_by_mps, p.caution.min_speed_mps)
                if cap < speed.goal:
                    speed.goal = cap
        elif self.mode is Mode.REVERSE:
            r = p.reverse
            own = world.lanes[world.ego_lane]
            if changing and target != world.ego_lane:
                # Leaving the lane: the target lane's lead by the braking curve, and
                # still a stop short of the blockage should the way out close.
                lane = world.lanes[target]
                goal = r.escape_speed_mps
                if lane.ahead_gap < p.calm.brake_range_m:
                    goal = min(goal, p.braking_percent(lane.ahead_gap) * 0.01
                               * lane.ahead_speed)
                room = own.ahead_gap - r.escape_stop_gap_m
            else:
                goal = speed.goal
                room = own.ahead_gap - r.stop_gap_m
            # The motion layer eases into a goal at a bounded jerk J (a <= sqrt(2 J dv)):
            # to brake at a the goal runs a^2 / (2 J) below the profile.
            lag = r.stop_decel_mps2 ** 2 / (2.0 * r.motion_jerk_mps3)
            stop = max(math.sqrt(2.0 * r.stop_decel_mps2 * room) - lag, 0.0) if room > 0.0 \
                else 0.0
            speed.goal = min(goal, stop)
            speed.hard = False  # the stop is planned: lane changes stay allowed
            speed.accel = p.max_braking_mps2 if speed.goal < v else p.normal_acceleration_mps2
            # The queued second of path would carry the car on at its speed: replan while
            # the stopping profile binds (as the seed's hard braking does).
            speed.replan = speed.replan or self._reverse_entered or stop < v
        elif self.mode is Mode.HYPER:
            for t in self._faster_lanes(world, False):
                lane = world.lanes[t]
                if not self._safe_behind(lane, v) and lane.has_behind:
                    cap = lane.behind_speed - p.hyper.slow_by_mps
                    if cap < speed.goal:
                        speed.goal = max(cap, 0.0)
                        speed.accel = max(speed.accel, p.normal_acceleration_mps2)
                break

    def _safe_behind(self, lane: LaneView, v: float, least: float | None = None) -> bool:
        p = self._p
        least = p.safety_gap_min_m if least is None else least
        return lane.behind_gap > least and lane.behind_gap > p.safety_gap_m(lane.behind_speed,
                                                                              v)

    # ----------------------------------------------------------------------- the lane
    def lane_change(self, world: WorldModel, since_change: float, hard: bool) -> int | None:
        """The optional mode's lane choice: a lane index, -1 for none (no lane change
        this cycle), or ``None`` to leave it to the seed's rules."""
        p = self._p
        if self.mode is Mode.ALERT:
            return -1
        lanes = world.lanes
        v = world.ego_speed
        own = lanes[world.ego_lane]
        if self.mode is Mode.REVERSE:
            r = p.reverse
            best = -1
            for t in (world.ego_lane - 1, world.ego_lane + 1):
                if not 0 <= t < world.lane_count:
                    continue
                lane = lanes[t]
                if (lane.ahead_gap > max(r.escape_ahead_m, own.ahead_gap)
                        and self._safe_behind(lane, v)
                        and (best < 0 or lane.ahead_gap > lanes[best].ahead_gap)):
                    best = t
            return best
        if self.mode is Mode.HYPER:
            h = p.hyper
            if hard or since_change <= h.cooldown_s:
                return -1
            if world.road_radius > p.single_change_radius_m:
                for t in self._faster_lanes(world, False):
                    if self._safe_behind(lanes[t], v):
                        return t
            if world.road_radius > h.double_radius_m:
                for t in self._faster_lanes(world, True):
                    crossed = lanes[(world.ego_lane + t) // 2]
                    if (crossed.ahead_gap > p.hard_braking_gap_m
                            and self._safe_behind(crossed, v)
                            and self._safe_behind(lanes[t], v, p.double_target_clear_m)):
                        return t
            return None
        return None
