"""Driving-quality metrics shared by every sdc-gym environment.

The Udacity highway simulator judges a drive by a handful of incidents (exceeding the
acceleration, jerk or speed limit, leaving the road, straddling a lane line too long,
touching another car) and by how far the car gets without one. :class:`DrivingMetrics`
reproduces those rules on the physics samples an environment already has, and adds the
statistics a researcher wants for a report: lap times, distance, speeds, and the raw
per-step acceleration and jerk.

How the simulator measures acceleration (the *block rule*)
----------------------------------------------------------
Physics runs every ``dt`` = 0.02 s. Speeds are grouped into disjoint *blocks* of
``block_steps`` = 10 samples (0.2 s). For each block with mean speed ``v``:

* tangential acceleration ``AccT = (v - v_prev) / 0.2`` where ``v_prev`` is the previous
  block's mean speed;
* normal (centripetal) acceleration ``AccN = v**2 * kappa`` where ``kappa`` is the mean
  curvature of the path over the block;
* total acceleration ``sqrt(AccT**2 + AccN**2)``; an ``"acceleration"`` incident when it
  reaches ``max_acceleration``.

Every ``jerk_blocks`` = 5 block totals (1 s) form a *window*; the jerk is the change of
the window's mean total from the previous window's, divided by the window length (1 s),
and ``|jerk| >= max_jerk`` is a ``"jerk"`` incident. Averaging over blocks and windows is
what makes these numbers robust to the step-to-step noise of a physics engine; the raw
per-step values (see below) are reported alongside for anyone who wants the unfiltered
signal.

Curvature of three points ``p1, p2, p3`` is the Menger curvature
``2 sin(turn angle) / |p3 - p1|``: exactly ``1/R`` for three points on a circle of radius
``R``, 0 on a straight line, and taken as 0 for a degenerate triple (two equal points, e.g.
a stopped car). The magnitude is used, so an S-bend does not cancel out.

Choices this module makes (the simulator leaves them open)
----------------------------------------------------------
* **Curvature triples.** The curvature sample of step ``t`` is that of the three most
  recent positions ``(p[t-2], p[t-1], p[t])``; a block averages the samples of its own
  steps. Its middle points are thus the block's steps shifted back by one. Triples centred
  on the block's steps would need the position *after* the block, delaying every block
  (and the incident it raises) by one step and leaving the last block of an episode
  unmeasured; the shift changes the mean curvature by O(dt) only. The very first step of
  an episode has no ``p[-1]``, so the first block averages the 9 triples it has.
* **First block.** Its ``v_prev`` is the speed given to :meth:`DrivingMetrics.reset`: an
  episode that starts at rest is measured against 0, one that starts at cruise speed is
  not charged for the jump from 0.
* **First jerk window.** It has no previous window, so it produces no jerk value (jerk is
  reported as 0 until the second window closes, at t = 2 s).
* **Raw values.** Velocity ``v_t = (p_t - p_{t-1})/dt``, acceleration
  ``a_t = (v_t - v_{t-1})/dt``, jerk ``j_t = (a_t - a_{t-1})/dt`` (vectors; magnitudes are
  reported). The heading before :meth:`~DrivingMetrics.reset` is unknown, so the raw
  acceleration exists from the 2nd recorded step and the raw jerk from the 3rd (0 before).

Other environments may add incident kinds of their own (the track loop's ``"red_light"``):
pass ``extra_kinds`` to :class:`DrivingMetrics` and the incidents the env detects to
:meth:`~DrivingMetrics.record` (``extra_incidents``). They are counted, logged, ordered
and restart the distance without incident exactly like the built-in kinds; within a step
they come after the built-in kinds, in ``extra_kinds`` order.

Incidents are counted once per *event* (rising edge): consecutive violating steps (or
blocks, or windows) make one incident. A lane-straddle run counts once when it exceeds
``max_straddle_steps``. A collision counts once per contact: a contact with car ``c`` lasts
while consecutive steps report ``c``. Every incident restarts the "distance without
incident". Incidents raised at the same step are ordered as in :data:`INCIDENT_KINDS`.

Chunking invariance
-------------------
:meth:`DrivingMetrics.record` takes the ``k`` physics steps of one environment step at
once. Every quantity is computed per step from the same inputs, and running sums
(distance, progress, block speeds) are accumulated strictly in step order, so feeding a
trajectory one step at a time or in chunks of any size gives bit-identical results.

Cost: ``k`` is small (1-5), where numpy's fixed cost per call (~0.5-1 us) outweighs its
per-element speed, so the arrays are turned into lists once and the per-step work runs on
Python floats; chunk-level ``min``/``max`` tests skip the per-step incident walks in the
common incident-free case, and the block rule runs once per 10 steps.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from itertools import accumulate
from typing import Any

import numpy as np

from sdc_gym.units import MPS_TO_MPH

INCIDENT_KINDS: tuple[str, ...] = ("collision", "acceleration", "jerk", "speed", "lane", "off_road")
"""Every incident kind, in the order incidents of the same step are reported."""

_KIND_ORDER = {kind: i for i, kind in enumerate(INCIDENT_KINDS)}


def _as_list(values: np.ndarray | list[Any]) -> list[Any]:
    """A list as it is, an array as a (nested) list of Python numbers."""
    return values if type(values) is list else np.asarray(values).tolist()


@dataclass(frozen=True)
class IncidentRules:
    """Sampling and thresholds of the incident rules; defaults are the Udacity highway's.

    Other environments pass their own limits, e.g. a track with no lane bands
    (``straddle_bands=()``), other road edges or another speed limit.
    """

    dt: float = 0.02
    """Physics step, s. Every recorded sample is one step apart."""
    block_steps: int = 10
    """Samples per acceleration block (10 x 0.02 s = 0.2 s)."""
    jerk_blocks: int = 5
    """Blocks per jerk window (5 x 0.2 s = 1 s)."""
    max_acceleration: float = 10.0
    """Block total acceleration at or above which an incident is raised, m/s^2."""
    max_jerk: float = 10.0
    """Window jerk magnitude at or above which an incident is raised, m/s^3."""
    speed_limit: float = 22.352
    """Speed strictly above which an incident is raised, m/s (50 mph)."""
    road_d_min: float = 0.8
    """Lateral offset d strictly below which the car is off the road, m."""
    road_d_max: float = 11.2
    """Lateral offset d strictly above which the car is off the road, m."""
    straddle_bands: tuple[tuple[float, float], ...] = ((3.2, 4.8), (7.2, 8.8))
    """Open intervals (lo, hi) of d, m, in which the car straddles a lane line."""
    max_straddle_steps: int = 150
    """Consecutive straddling steps allowed; one more raises an incident (150 = 3 s)."""

    def __post_init__(self) -> None:
        if not self.dt > 0.0:
            raise ValueError(f"dt must be > 0, got {self.dt}")
        if self.block_steps < 1 or self.jerk_blocks < 1 or self.max_straddle_steps < 0:
            raise ValueError("block_steps and jerk_blocks must be >= 1, max_straddle_steps >= 0")
        if not self.road_d_min < self.road_d_max:
            raise ValueError("road_d_min must be < road_d_max")
        # Normalise to a tuple of float pairs so the rules stay hashable and comparable.
        bands = tuple((float(lo), float(hi)) for lo, hi in self.straddle_bands)
        if any(not lo < hi for lo, hi in bands):
            raise ValueError(f"each straddle band needs lo < hi, got {bands}")
        object.__setattr__(self, "straddle_bands", bands)

    @property
    def block_seconds(self) -> float:
        """Duration of one acceleration block, s."""
        return self.block_steps * self.dt

    @property
    def jerk_window_seconds(self) -> float:
        """Duration of one jerk window, s."""
        return self.jerk_blocks * self.block_steps * self.dt


@dataclass(frozen=True)
class Incident:
    """One incident, located at the physics step where it began.

    ``value`` depends on the kind: the car id (collision), the block total acceleration in
    m/s^2 (acceleration), the signed window jerk in m/s^3 (jerk), the speed in m/s
    (speed), the straddle duration in s (lane), ``d`` in m (off_road), or what the env
    documents for its ``extra_kinds`` (the track loop's red_light: the stop line's index).
    Block and window incidents are placed at the last step of their block.
    """

    kind: str
    time: float
    step: int
    x: float
    y: float
    s: float
    d: float
    value: float

    def as_dict(self) -> dict[str, Any]:
        """Plain-Python dict, ready for JSON."""
        return asdict(self)


class DrivingMetrics:
    """Incidents, lap timing and distance statistics of one ego car over an episode.

    Call :meth:`reset` at the start of every episode, then :meth:`record` with the physics
    steps of each environment step. Read the results through the properties,
    :meth:`step_info` (per step, for ``info``) and :meth:`summary` (per episode).

    Args:
        rules: sampling and thresholds (:class:`IncidentRules`).
        loop_length: length of the closed road along ``s``, m; ``s`` wraps at this value.
        extra_kinds: incident kinds an env detects itself and passes to :meth:`record`
            (e.g. ``("red_light",)``); reported after :data:`INCIDENT_KINDS`.
    """

    def __init__(
        self, rules: IncidentRules, loop_length: float, extra_kinds: tuple[str, ...] = ()
    ) -> None:
        if not loop_length > 0.0:
            raise ValueError(f"loop_length must be > 0, got {loop_length}")
        kinds = (*INCIDENT_KINDS, *extra_kinds)
        if len(set(kinds)) != len(kinds):
            raise ValueError(f"extra_kinds must be new, distinct kinds (built-in: "
                             f"{list(INCIDENT_KINDS)}), got {list(extra_kinds)}")
        self.rules = rules
        self.loop_length = float(loop_length)
        self.kinds: tuple[str, ...] = kinds
        """Every incident kind this instance counts, in report order."""
        self._kind_order = {kind: i for i, kind in enumerate(kinds)}
        self._extra_kinds = frozenset(extra_kinds)
        self._info_keys = tuple(f"incidents_{kind}" for kind in kinds)
        # Derived constants, computed once because record() is on the hot path.
        self._inv_dt = 1.0 / rules.dt
        self._inv_dt2 = self._inv_dt**2
        self._inv_dt3 = self._inv_dt**3
        self._ready = False
        self.reset(0.0, 0.0, 0.0, 0.0)
        self._ready = False  # the dummy reset above does not start an episode

    # ------------------------------------------------------------------ episode control
    def reset(self, x: float, y: float, s: float, d: float, speed: float = 0.0) -> None:
        """Start a new episode with the car at ``(x, y)`` / ``(s, d)`` moving at ``speed`` m/s.

        This is step 0 at time 0; it is not checked for incidents.
        """
        x, y = float(x), float(y)
        # p[t-2], p[t-1], velocity * dt, acceleration * dt^2 and |velocity * dt| carried
        # between record() calls. Before the reset they are unknown: p0 copies and zeros
        # stand in, and the samples that use them are masked out (see _mask_warmup).
        self._geo = (x, y, x, y, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._s_last = float(s)
        self._steps = 0
        self._distance = 0.0
        self._progress = 0.0
        self._laps = 0
        self._next_lap_mark = self.loop_length
        self._last_mark_time = 0.0
        self._lap_times: list[float] = []
        self._max_speed = 0.0
        self._last_speed = float(speed)
        self._max_raw_acc = 0.0
        self._max_raw_jerk = 0.0
        self._last_raw_acc = 0.0
        self._last_raw_jerk = 0.0
        # Block rule state.
        self._blk_v: list[float] = []
        self._blk_c: list[float] = []
        self._prev_block_v = float(speed)
        self._window: list[float] = []
        self._prev_window_mean: float | None = None
        self._last_acc = 0.0
        self._last_acc_t = 0.0
        self._last_acc_n = 0.0
        self._last_jerk = 0.0
        self._max_acc = 0.0
        self._max_jerk = 0.0
        # Rising-edge state of each incident kind.
        self._acc_flag = False
        self._jerk_flag = False
        self._speeding = False
        self._off_road = False
        self._straddle_run = 0
        self._contact = -1
        # Incident bookkeeping.
        self._counts = dict.fromkeys(self.kinds, 0)
        self._incidents: list[Incident] = []
        self._dist_at_incident = 0.0
        self._longest_closed = 0.0
        self._ready = True

    def record(
        self,
        xy: np.ndarray | list[list[float]],
        s: np.ndarray | list[float],
        d: np.ndarray | list[float],
        speed: np.ndarray | list[float],
        collision_ids: np.ndarray | None = None,
        extra_incidents: list[tuple[int, str, float]] | None = None,
    ) -> list[Incident]:
        """Add ``k >= 1`` consecutive physics steps and return the incidents they began.

        ``xy``, ``s``, ``d`` and ``speed`` may be arrays or the same as (nested) Python
        lists of floats, which skips their conversion (the highway env passes lists).

        Args:
            xy: positions, shape ``(k, 2)``, m.
            s: arc-length coordinate, shape ``(k,)``, m, wrapping at ``loop_length``.
            d: lateral offset, shape ``(k,)``, m (positive to the right of travel).
            speed: speed, shape ``(k,)``, m/s.
            collision_ids: shape ``(k,)`` ints; -1 for no contact at that step, else the
                id of a car in contact. ``None`` means no contact at all.
            extra_incidents: incidents of the ``extra_kinds`` that the caller detected in
                these steps, as ``(step index in 0..k-1, kind, value)``.

        Returns:
            The incidents that began during these steps, in step order.
        """
        if not self._ready:
            raise RuntimeError("call reset() before record()")
        k = len(speed)
        if k == 0:
            return []
        rules = self.rules
        pts, speed_l, s_l, d_l = (_as_list(values) for values in (xy, speed, s, d))

        # ---- geometry. A scalar loop on Python floats: for the 1-5 samples of an env
        # step it is ~3x faster than the equivalent numpy expressions, whose fixed cost
        # per call dominates at this size. (x1, y1), (x2, y2) are p[t-2], p[t-1];
        # (vx2, vy2), (ax2, ay2) the previous velocity * dt and acceleration * dt^2.
        x1, y1, x2, y2, vx2, vy2, ax2, ay2, l2 = self._geo
        hypot = math.hypot
        curv: list[float] = []
        raw_acc: list[float] = []
        raw_jerk: list[float] = []
        lengths: list[float] = []
        for x, y in pts:
            vx = x - x2
            vy = y - y2
            step_len = hypot(vx, vy)
            ax = vx - vx2
            ay = vy - vy2
            raw_acc.append(hypot(ax, ay))
            raw_jerk.append(hypot(ax - ax2, ay - ay2))
            lengths.append(step_len)
            # Menger curvature 2 |cross| / (|a| |b| |a + b|) of (p[t-2], p[t-1], p[t]);
            # a degenerate triple (any two points equal) has den == 0 and counts as 0.
            den = l2 * step_len * hypot(x - x1, y - y1)
            curv.append(2.0 * abs(vx2 * vy - vy2 * vx) / den if den else 0.0)
            x1, y1, x2, y2, vx2, vy2, ax2, ay2, l2 = x2, y2, x, y, vx, vy, ax, ay, step_len
        self._geo = (x1, y1, x2, y2, vx2, vy2, ax2, ay2, l2)
        t0 = self._steps
        if t0 < 3:
            self._mask_warmup(t0, curv, raw_acc, raw_jerk)

        # ---- running sums, strictly in step order (bit-identical for any chunking).
        cum_dist = list(accumulate(lengths, initial=self._distance))
        length, half = self.loop_length, 0.5 * self.loop_length
        # Signed modular difference: wrapping L -> 0 forward counts forward.
        s_prev = [self._s_last, *s_l]  # one longer than s_l: zip stops at s_l's end
        ds = [(s1 - s0 + half) % length - half for s0, s1 in zip(s_prev, s_l, strict=False)]
        cum_prog = list(accumulate(ds, initial=self._progress))
        self._distance = cum_dist[-1]
        self._progress = cum_prog[-1]
        self._s_last = s_l[-1]
        self._steps = t0 + k
        if self._progress >= self._next_lap_mark:
            self._count_laps(cum_prog, t0)

        # ---- maxima and latest values.
        vmax = max(speed_l)
        if vmax > self._max_speed:
            self._max_speed = vmax
        self._last_speed = speed_l[-1]
        m = max(raw_acc) * self._inv_dt2
        if m > self._max_raw_acc:
            self._max_raw_acc = m
        m = max(raw_jerk) * self._inv_dt3
        if m > self._max_raw_jerk:
            self._max_raw_jerk = m
        self._last_raw_acc = raw_acc[-1] * self._inv_dt2
        self._last_raw_jerk = raw_jerk[-1] * self._inv_dt3

        # ---- per-step incidents. Each check first asks a cheap chunk-level question and
        # only walks the steps when something may have happened (or an event is ongoing).
        pending: list[tuple[int, int, float]] = []  # (chunk index, kind order, value)
        if vmax > rules.speed_limit or self._speeding:
            flag = self._speeding
            for i, v in enumerate(speed_l):
                now = v > rules.speed_limit
                if now and not flag:
                    pending.append((i, _KIND_ORDER["speed"], v))
                flag = now
            self._speeding = flag
        dlo, dhi = min(d_l), max(d_l)
        if dlo < rules.road_d_min or dhi > rules.road_d_max or self._off_road:
            flag = self._off_road
            for i, dd in enumerate(d_l):
                now = dd < rules.road_d_min or dd > rules.road_d_max
                if now and not flag:
                    pending.append((i, _KIND_ORDER["off_road"], dd))
                flag = now
            self._off_road = flag
        bands = rules.straddle_bands
        if self._straddle_run or any(dlo < hi and dhi > lo for lo, hi in bands):
            run = self._straddle_run
            for i, dd in enumerate(d_l):
                if any(lo < dd < hi for lo, hi in bands):
                    run += 1
                    if run == rules.max_straddle_steps + 1:
                        pending.append((i, _KIND_ORDER["lane"], run * rules.dt))
                else:
                    run = 0
            self._straddle_run = run
        if collision_ids is not None:
            ids = collision_ids.tolist()
            if self._contact >= 0 or max(ids) >= 0:
                contact = self._contact
                for i, cid in enumerate(ids):
                    if cid < 0:
                        cid = -1
                    elif cid != contact:
                        pending.append((i, _KIND_ORDER["collision"], float(cid)))
                    contact = cid
                self._contact = contact
        else:
            self._contact = -1

        if extra_incidents:
            for i, kind, value in extra_incidents:
                if kind not in self._extra_kinds or not 0 <= i < k:
                    raise ValueError(f"extra incident ({i}, {kind!r}): the kind must be one "
                                     f"of extra_kinds {sorted(self._extra_kinds)} and the "
                                     f"index within the {k} recorded steps")
                pending.append((i, self._kind_order[kind], float(value)))

        # ---- block rule: small Python work once per completed block (every 10 steps).
        blk_v = self._blk_v
        blk_v.extend(speed_l)
        self._blk_c.extend(curv)
        if len(blk_v) >= rules.block_steps:
            self._close_blocks(k, pending)

        if not pending:
            return []
        return self._log_incidents(pending, t0, pts, s_l, d_l, cum_dist)

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _mask_warmup(t0: int, curv: list[float], acc: list[float], jerk: list[float]) -> None:
        """Blank the samples that would use positions from before the reset.

        Sample ``m`` of the chunk is global step ``t = t0 + 1 + m``; its curvature and raw
        acceleration need ``p[t-2]`` (so ``t >= 2``), its raw jerk ``p[t-3]`` (``t >= 3``).
        Curvature becomes NaN (dropped from the block mean), raw values 0 (neutral for max).
        """
        for m in range(min(len(curv), 3 - t0)):
            t = t0 + 1 + m
            if t < 2:
                curv[m] = math.nan
                acc[m] = 0.0
            if t < 3:
                jerk[m] = 0.0

    def _count_laps(self, cum_prog: list[float], t0: int) -> None:
        """Record every lap mark crossed in this chunk, timed by linear interpolation."""
        dt = self.rules.dt
        for i in range(1, len(cum_prog)):
            p0, p1 = cum_prog[i - 1], cum_prog[i]
            while p1 >= self._next_lap_mark:
                mark = self._next_lap_mark
                # p0 < mark <= p1 here, so p1 > p0 and the fraction lies in (0, 1].
                t_cross = (t0 + i - 1 + (mark - p0) / (p1 - p0)) * dt
                self._lap_times.append(t_cross - self._last_mark_time)
                self._last_mark_time = t_cross
                self._laps += 1
                self._next_lap_mark = (self._laps + 1) * self.loop_length

    def _close_blocks(self, k: int, pending: list[tuple[int, int, float]]) -> None:
        """Evaluate every block completed by this chunk (and the jerk windows they close)."""
        rules = self.rules
        n = rules.block_steps
        block_s = rules.block_seconds
        blk_v, blk_c = self._blk_v, self._blk_c
        # Chunk index of the sample that completes the first block.
        i_end = n - (len(blk_v) - k) - 1
        while len(blk_v) >= n:
            v = sum(blk_v[:n]) / n
            kappa = [c for c in blk_c[:n] if c == c]  # NaN != NaN: drop warm-up samples
            kappa_mean = sum(kappa) / len(kappa) if kappa else 0.0
            del blk_v[:n], blk_c[:n]
            acc_t = (v - self._prev_block_v) / block_s
            acc_n = v * v * kappa_mean
            total = math.hypot(acc_t, acc_n)
            self._prev_block_v = v
            self._last_acc_t = acc_t
            self._last_acc_n = acc_n
            self._last_acc = total
            if total > self._max_acc:
                self._max_acc = total
            violating = total >= rules.max_acceleration
            if violating and not self._acc_flag:
                pending.append((i_end, _KIND_ORDER["acceleration"], total))
            self._acc_flag = violating

            window = self._window
            window.append(total)
            if len(window) == rules.jerk_blocks:
                mean = sum(window) / len(window)
                window.clear()
                if self._prev_window_mean is not None:  # the first window has no jerk
                    jerk = (mean - self._prev_window_mean) / rules.jerk_window_seconds
                    self._last_jerk = jerk
                    if abs(jerk) > self._max_jerk:
                        self._max_jerk = abs(jerk)
                    violating = abs(jerk) >= rules.max_jerk
                    if violating and not self._jerk_flag:
                        pending.append((i_end, _KIND_ORDER["jerk"], jerk))
                    self._jerk_flag = violating
                self._prev_window_mean = mean
            i_end += n

    def _log_incidents(
        self,
        pending: list[tuple[int, int, float]],
        t0: int,
        pts: list[list[float]],
        s_l: list[float],
        d_l: list[float],
        cum_dist: list[float],
    ) -> list[Incident]:
        """Turn pending (index, kind, value) triples into Incidents, in step order."""
        pending.sort(key=lambda p: (p[0], p[1]))
        dt = self.rules.dt
        new: list[Incident] = []
        for i, order, value in pending:
            kind = self.kinds[order]
            step = t0 + 1 + i
            x, y = pts[i]
            new.append(Incident(kind, step * dt, step, x, y, s_l[i], d_l[i], float(value)))
            self._counts[kind] += 1
            # The stretch without incident ends at this step's distance.
            dist = cum_dist[i + 1]
            self._longest_closed = max(self._longest_closed, dist - self._dist_at_incident)
            self._dist_at_incident = dist
        self._incidents.extend(new)
        return new

    # ------------------------------------------------------------------ read-only results
    @property
    def time(self) -> float:
        """Episode time, s."""
        return self._steps * self.rules.dt

    @property
    def steps(self) -> int:
        """Physics steps recorded since reset."""
        return self._steps

    @property
    def distance(self) -> float:
        """Distance travelled, m (sum of straight step lengths)."""
        return self._distance

    @property
    def progress(self) -> float:
        """Unwrapped progress along s since reset, m (negative when driving backwards)."""
        return self._progress

    @property
    def laps_completed(self) -> int:
        """Laps completed: positive multiples of the loop length reached by the progress."""
        return self._laps

    @property
    def lap_times(self) -> list[float]:
        """Duration of each completed lap, s."""
        return list(self._lap_times)

    @property
    def incident_counts(self) -> dict[str, int]:
        """Incidents by kind; every kind of :attr:`kinds` is present."""
        return dict(self._counts)

    @property
    def incidents(self) -> list[Incident]:
        """Every incident of the episode, in step order."""
        return list(self._incidents)

    @property
    def distance_without_incident(self) -> float:
        """Distance since the last incident (or the start), m."""
        return self._distance - self._dist_at_incident

    @property
    def longest_distance_without_incident(self) -> float:
        """Longest stretch without incident so far, including the current one, m."""
        return max(self._longest_closed, self._distance - self._dist_at_incident)

    @property
    def max_speed(self) -> float:
        """Highest recorded speed, m/s."""
        return self._max_speed

    @property
    def max_acceleration(self) -> float:
        """Highest block total acceleration, m/s^2."""
        return self._max_acc

    @property
    def max_jerk(self) -> float:
        """Highest window jerk magnitude, m/s^3."""
        return self._max_jerk

    @property
    def max_raw_acceleration(self) -> float:
        """Highest per-step acceleration magnitude, m/s^2."""
        return self._max_raw_acc

    @property
    def max_raw_jerk(self) -> float:
        """Highest per-step jerk magnitude, m/s^3."""
        return self._max_raw_jerk

    @property
    def last_acceleration(self) -> float:
        """Total acceleration of the latest completed block, m/s^2."""
        return self._last_acc

    @property
    def last_tangential_acceleration(self) -> float:
        """Signed AccT of the latest completed block, m/s^2 (negative when braking)."""
        return self._last_acc_t

    @property
    def last_normal_acceleration(self) -> float:
        """AccN of the latest completed block, m/s^2 (v^2 times mean |curvature|)."""
        return self._last_acc_n

    @property
    def last_jerk(self) -> float:
        """Signed jerk of the latest completed window, m/s^3 (0 before the second window)."""
        return self._last_jerk

    @property
    def last_raw_acceleration(self) -> float:
        """Per-step acceleration magnitude of the latest step, m/s^2."""
        return self._last_raw_acc

    @property
    def last_raw_jerk(self) -> float:
        """Per-step jerk magnitude of the latest step, m/s^3."""
        return self._last_raw_jerk

    @property
    def mean_speed(self) -> float:
        """Distance over time, m/s (0 before the first step)."""
        return self._distance / self.time if self._steps else 0.0

    # ------------------------------------------------------------------ reports
    def step_info(self) -> dict[str, float | int]:
        """Current values for an env's ``info`` dict: the same keys every call, plain numbers.

        ``speed`` is the latest speed sample, ``acceleration``/``jerk`` the latest block
        and window values, ``raw_*`` the latest per-step magnitudes.
        """
        counts = self._counts
        info: dict[str, float | int] = {
            "time": self._steps * self.rules.dt,
            "distance": self._distance,
            "progress": self._progress,
            "laps": self._laps,
            "speed": self._last_speed,
            "acceleration": self._last_acc,
            "jerk": self._last_jerk,
            "raw_acceleration": self._last_raw_acc,
            "raw_jerk": self._last_raw_jerk,
            "distance_without_incident": self._distance - self._dist_at_incident,
            "incidents": len(self._incidents),
        }
        for key, kind in zip(self._info_keys, self.kinds, strict=True):
            info[key] = counts[kind]
        return info

    def summary(self) -> dict[str, Any]:
        """Episode summary of plain Python types (``json.dumps``-able).

        Times in s, distances in m, speeds in m/s (plus ``mean_speed_mph``),
        accelerations in m/s^2, jerks in m/s^3. Lap statistics are ``None`` without laps.
        """
        laps = list(self._lap_times)
        return {
            "lap_times": laps,
            "laps": self._laps,
            "mean_lap_time": sum(laps) / len(laps) if laps else None,
            "best_lap_time": min(laps) if laps else None,
            "distance": self._distance,
            "time": self.time,
            "mean_speed": self.mean_speed,
            "mean_speed_mph": self.mean_speed * MPS_TO_MPH,
            "max_speed": self._max_speed,
            "distance_without_incident": self.distance_without_incident,
            "longest_distance_without_incident": self.longest_distance_without_incident,
            "incidents": dict(self._counts),
            "incident_total": len(self._incidents),
            "max_acceleration": self._max_acc,
            "max_jerk": self._max_jerk,
            "max_raw_acceleration": self._max_raw_acc,
            "max_raw_jerk": self._max_raw_jerk,
        }
