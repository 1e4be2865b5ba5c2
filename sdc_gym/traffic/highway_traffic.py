"""Highway traffic: every traffic car at once, in numpy arrays, in the road's Frenet frame.

What the original simulator does (``shared/spec/highway_sim.md``, "Traffic in the
original") and how this model does it:

* **Car following** by the Intelligent Driver Model (:mod:`sdc_gym.traffic.idm`), with
  per-type acceleration limits (:mod:`sdc_gym.traffic.vehicle_types`).
* **Speeds like the original**: a car spawned ahead of the ego car wants 40 to 50 mph, one
  spawned behind it 50 to 60 mph (uniform), so slow cars wait ahead and fast cars come up
  from behind.
* **Recycling like the original**: a car more than ``spawn_range`` (200 m, along s,
  modular) from the ego is respawned near it, a few per decision. As in the original's
  ``CarAIControl.Spawn`` a fair coin picks the side: ahead of the ego (the original: 4 or 5
  map waypoints past the ego's nearest one, about 135-210 m on its map; here
  ``respawn_ahead``, 135-190 m, inside the recycling range) with a desired speed of 40-50
  mph, or behind it (2 or 3 waypoints back: ``respawn_behind``, 60-135 m) with 50-60 mph.
  So cars keep coming up from behind all the time, whichever way the ego left them.
* **Lane changes only into a clear gap**: the target lane must be free within
  ``+-lane_change_clearance`` (20 m) in s for ``lane_change_sustain`` seconds, then the car
  moves over in ``lane_change_duration`` seconds on a minimum-jerk (quintic) profile.
* **Lateral wander**: a slow sine of ``lateral_wander`` metres around the lane centre.
* **Rogue mode** (off by default): hard-braking episodes and cut-ins with small gaps.

The ego car is part of the world: a traffic car follows it when it is ahead in a lane the
car occupies, and it counts for lane-change clearance and spawn gaps. It never yields to
traffic: whatever the ego does, collisions with it are its own (detected elsewhere).

Decision instants and sub-steps
-------------------------------
The expensive work (leader search, IDM, lane-change decisions, recycling, rogue events)
runs only at *decision instants*, every ``decision_period`` physics steps (10 x 0.02 s =
0.2 s by default; highway-v0 decides at 15 Hz, highway-fast-v0 at 5 Hz). In between,
each car's acceleration is held (a braking car stops at zero instead of reversing) and
its lateral position follows its closed-form profile (lane-change quintic plus wander
sine), so the states at all sub-steps of an :meth:`HighwayTraffic.advance` come out of
a handful of vectorized expressions over ``(steps, n)`` arrays. A decision uses the ego's
latest state before it.

Frenet kinematics: a car at speed ``v`` along its lane at offset ``d`` advances
``ds/dt = v / (1 + kappa(s) d)`` (``kappa`` signed, positive turning left, ``d`` to the
right: on a left bend the right lanes are longer). Its world velocity is ``v`` along the
road tangent plus ``d_dot`` along the right normal, its heading the direction of that
velocity (a car slower than 1 m/s keeps pointing along its lane). ``kappa`` is taken at
each decision instant. Road geometry comes from tables of the reference line (point,
tangent, curvature every 0.25 m, linearly interpolated: a handful of numpy calls for a
whole ``(steps, n)`` array; positions within 0.1 mm of ``reference.to_xy``).

Lane occupancy and the leader search
------------------------------------
A car *occupies* its lane, and while changing lanes both its origin and its target lane.
Its leader is the nearest object ahead (smallest modular gap in s) among the objects that
occupy any lane it occupies; clearance checks test every lane the same way. So a changing
car is followed by the cars of both lanes, follows the leaders of both lanes, and is seen
by any car that wants to enter either lane. The ego occupies every lane its footprint
touches. Gaps are bumper to bumper and along the follower's lane: ``delta_s * (1 + kappa
* d) - (L_follower + L_leader) / 2``. The search is an O(n^2) masked argmin over (lane,
car, object) arrays (cheaper than sorting for the n <= 100 this is for).

Lane-change decision (a car not already changing, moving at least
``lane_change_min_speed``): an adjacent lane qualifies if no object occupying it is within
``+-lane_change_clearance`` in s (centre to centre), if the car's IDM acceleration there
(behind that lane's leader) beats its current one by ``lane_change_min_gain`` (MOBIL's
incentive, politeness 0), and if neither the car nor the new follower (a car or the ego)
would have to brake harder than ``lane_change_max_braking_imposed`` (MOBIL's safety
criterion; ``inf`` leaves the bare +-20 m rule). The best such lane must stay the wish at
every decision for ``lane_change_sustain`` seconds. At most one car starts into a given
lane per decision (the lowest slot index): two cars merging into one lane from both sides
at the same instant would not have seen each other in their checks; the other one retries
at the next decision and then does see the first.

Respawn rule: random candidate spots (lane, s) in ``respawn_ahead`` or ``respawn_behind``
from the ego, on the side the coin picked (the other side if no spot fits); a spot is taken only
if the bumper gaps to the nearest objects ahead and behind in that lane are at least
``spawn_min_gap`` and the follower (a car or the ego) would not find the newcomer inside
its IDM desired gap (so it brakes by at most its ``a_max``); the newcomer starts at its
desired speed or, if its own leader is close, at the largest speed whose IDM desired gap
fits (:func:`max_speed_for_gap`). A recycled car gets a new id. When no spot fits (dense
traffic: e.g. 50 cars in +-200 m jam at about 15 m/s), the car drives on where it is and
tries again later. :meth:`HighwayTraffic.reset` lays the cars out uniformly over the free
room (``spawn_min_gap`` from each other and from the ego) within a spread set by
``density``, then slows each car, front to back, to a speed whose IDM desired gap fits
behind its leader (the ego included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.traffic.idm import _NOT_ZERO as _IDM_NOT_ZERO
from sdc_gym.traffic.idm import IDMParameters, desired_gap, max_speed_for_gap
from sdc_gym.traffic.vehicle_types import VEHICLE_TYPES, spawn_probabilities

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MPH = 0.44704  # m/s per mph
_NEVER = -(2**40)  # a step index long past: "no lane change started"
_IDLE = 2**62  # lane-change end step of a car that is not changing lanes
_GEOMETRY_STEP = 0.25  # m, spacing of the geometry look-up tables
_SPAWN_CANDIDATES = 24  # random spots tried per side when placing one car
_RESPAWN_RETRY_STEPS = 100  # a car that found no room to respawn retries after this
_RESPAWN_PAUSE_STEPS = 50  # and after any such failure nobody tries for this long


@dataclass(frozen=True)
class TrafficConfig:
    """Traffic settings; the defaults reproduce the original simulator's traffic.

    Attributes:
        car_count: number of traffic cars (constant: cars are recycled, never removed).
        density: compactness of the initial placement. Cars are spread over
            ``+-0.75 * spawn_range / density`` metres of s around the ego (1.0: +-150 m;
            2.0: +-75 m, a busy start; <= 0.75: the whole +-spawn_range), the spread
            widening by itself if the cars do not fit.
        spawn_range: m along s (modular); a car further from the ego is recycled. Capped at
            0.45 of the loop length on short loops.
        respawn_ahead, respawn_behind: (min, max) m along s from the ego where a recycled
            car reappears ahead of it or behind it (both capped at ``spawn_range - 10``).
        respawn_ahead_probability: chance that a recycled car reappears ahead (the
            original: a fair coin).
        respawn_per_decision: at most this many cars are recycled per decision instant
            (the farthest first): "a few at a time".
        spawn_min_gap: m, smallest bumper gap to the neighbours ahead and behind in the
            lane at (re)spawn.
        lane_change_clearance: m, +- in s (centre to centre) on the target lane that must
            be free of any car (or the ego) occupying it.
        lane_change_sustain: s the clearance (and the wish) must hold before starting.
        lane_change_duration: s for the lateral move (quintic minimum-jerk profile).
        lane_change_min_gain: m/s^2, IDM acceleration the target lane must offer over the
            current one (MOBIL's LANE_CHANGE_MIN_ACC_GAIN).
        lane_change_max_braking_imposed: m/s^2, largest braking the change may require of
            the new follower or of the car itself (MOBIL's safety criterion); ``inf``
            leaves only the clearance rule.
        lane_change_min_speed: m/s, slower cars do not start lane changes.
        lateral_wander: m, amplitude of the lateral sine around the lane centre.
        wander_period: (min, max) s, period of that sine (uniform per car).
        rogue: enable rogue behaviour (stress tests): sudden hard braking for no reason,
            and cut-ins into gaps the normal rule refuses, with a short lateral move.
        rogue_rate: events per car per minute when rogue (half braking, half cut-in).
        rogue_brake_decel: m/s^2, braking of a rogue episode. The default equals
            ``idm.max_braking``, the hardest traffic brakes, so traffic behind (reacting
            one decision later) survives it; above that, followers may run into it.
        rogue_brake_duration: s of one hard-braking episode.
        rogue_cut_in_gap: m, bumper gap a rogue cut-in leaves ahead and behind, on top of
            what braking at ``idm.max_braking`` one decision late needs to match speeds
            (so a cut-in in front of traffic, or of an ego that brakes, is survivable).
        rogue_cut_in_duration: s for a rogue cut-in's lateral move.
        rogue_cut_in_window: s a rogue car keeps looking for a gap to cut into.
        decision_period: physics steps between decision instants (>= 1). Default 10
            (0.2 s, 5 Hz, like highway-fast-v0's simulation and a driver's reaction
            granularity): leaders, IDM accelerations and lane changes are decided then and
            held, while positions are exact at every 0.02 s frame. 5 (10 Hz) is finer and
            costs ~50 us more per 0.1 s with 12 cars.
        speed_ahead_mph: (min, max) desired speed of cars spawned ahead of the ego.
        speed_behind_mph: (min, max) desired speed of cars spawned behind the ego.
        vehicle_mix: spawn weights per :data:`VEHICLE_TYPES` entry; None = their defaults.
        idm: car-following parameters (``a_max`` and ``b`` are overridden per vehicle type).
        ego_length: m, the ego car's length (for gaps to it).
        ego_width: m, the ego car's width (for the lanes it occupies).
    """

    car_count: int = 12
    density: float = 1.0
    spawn_range: float = 200.0
    respawn_ahead: tuple[float, float] = (135.0, 190.0)
    respawn_behind: tuple[float, float] = (60.0, 135.0)
    respawn_ahead_probability: float = 0.5
    respawn_per_decision: int = 2
    spawn_min_gap: float = 8.0
    lane_change_clearance: float = 20.0
    lane_change_sustain: float = 1.0
    lane_change_duration: float = 3.0
    lane_change_min_gain: float = 0.2
    lane_change_max_braking_imposed: float = 2.0
    lane_change_min_speed: float = 5.0
    lateral_wander: float = 0.15
    wander_period: tuple[float, float] = (6.0, 14.0)
    rogue: bool = False
    rogue_rate: float = 1.0
    rogue_brake_decel: float = 6.0
    rogue_brake_duration: float = 1.5
    rogue_cut_in_gap: float = 4.0
    rogue_cut_in_duration: float = 1.0
    rogue_cut_in_window: float = 5.0
    decision_period: int = 10
    speed_ahead_mph: tuple[float, float] = (40.0, 50.0)
    speed_behind_mph: tuple[float, float] = (50.0, 60.0)
    vehicle_mix: tuple[float, ...] | None = None
    idm: IDMParameters = field(default_factory=IDMParameters)
    ego_length: float = 4.7
    ego_width: float = 1.9

    def __post_init__(self) -> None:
        checks = (
            (self.car_count >= 0, "car_count must be >= 0"),
            (self.density > 0, "density must be > 0"),
            (self.spawn_range > 20, "spawn_range must be > 20 m"),
            (0 <= self.respawn_ahead[0] < self.respawn_ahead[1],
             "respawn_ahead must be (min, max) with 0 <= min < max"),
            (0 <= self.respawn_behind[0] < self.respawn_behind[1],
             "respawn_behind must be (min, max) with 0 <= min < max"),
            (0.0 <= self.respawn_ahead_probability <= 1.0,
             "respawn_ahead_probability must be in [0, 1]"),
            (self.respawn_per_decision >= 1, "respawn_per_decision must be >= 1"),
            (self.decision_period >= 1, "decision_period must be >= 1"),
            (self.lane_change_duration > 0, "lane_change_duration must be > 0"),
            (self.rogue_cut_in_duration > 0, "rogue_cut_in_duration must be > 0"),
            (self.lane_change_sustain >= 0, "lane_change_sustain must be >= 0"),
            (0 < self.wander_period[0] <= self.wander_period[1], "wander_period: 0 < min <= max"),
            (self.speed_ahead_mph[0] <= self.speed_ahead_mph[1], "speed_ahead_mph: min <= max"),
            (self.speed_behind_mph[0] <= self.speed_behind_mph[1], "speed_behind_mph: min <= max"),
        )
        for ok, message in checks:
            if not ok:
                raise ValueError(f"TrafficConfig: {message}")
        spawn_probabilities(self.vehicle_mix)  # validates the mix


@dataclass(frozen=True)
class TrafficSamples:
    """Traffic state at each physics sub-step of one :meth:`HighwayTraffic.advance` call.

    Every array is ``(steps, n)``; row ``k`` is the state after sub-step ``k + 1``.
    ``s`` is wrapped to ``[0, road length)``, ``d`` in metres right of the reference line,
    ``speed`` the speed along the lane (m/s), ``x, y`` map metres, ``heading`` radians
    counter-clockwise from +x (the direction of motion), ``vx, vy`` the world velocity
    (m/s, including the lateral motion).
    """

    s: FloatArray
    d: FloatArray
    speed: FloatArray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    vx: FloatArray
    vy: FloatArray

    @classmethod
    def _make(cls, s: FloatArray, d: FloatArray, speed: FloatArray, x: FloatArray,
              y: FloatArray, heading: FloatArray, vx: FloatArray,
              vy: FloatArray) -> TrafficSamples:
        """The constructor without the frozen dataclass's eight ``object.__setattr__``
        calls (a few microseconds, every env step): the same object."""
        made = object.__new__(cls)
        made.__dict__.update(s=s, d=d, speed=speed, x=x, y=y, heading=heading, vx=vx, vy=vy)
        return made


def _any(mask: NDArray[np.bool_]) -> bool:
    """``mask.any()`` at a quarter of its cost on the small arrays of a step (a reduction
    has a large fixed cost in numpy; counting does not)."""
    return np.count_nonzero(mask) > 0


def _smallest(values: FloatArray) -> float:
    """``float(values.min())`` for a few dozen floats, cheaper through a list (no NaN here)."""
    return min(values.ravel().tolist()) if values.size else math.inf


def _per_step(values: ArrayLike, steps: int) -> list[float] | FloatArray:
    """``values`` as ``steps`` floats: a list of that length as it is (the env passes its
    per-frame lists; only a few entries are read), anything else through numpy."""
    if type(values) is list and len(values) == steps:
        return values
    return np.asarray(values, dtype=np.float64).reshape(steps)


def _stopping_gap(v_back: FloatArray, v_front: FloatArray, cfg: TrafficConfig,
                  delay: float) -> FloatArray:
    """Gap (m) a car at ``v_back`` eats up behind one at ``v_front`` (constant speed) before
    it has matched its speed, braking at ``max_braking`` after ``delay`` seconds."""
    closing = np.maximum(v_back - v_front, 0.0)
    return closing * delay + closing * closing / (2.0 * cfg.idm.max_braking)


class HighwayTraffic:
    """Vectorized traffic on a :class:`HighwayMap`; see the module docstring.

    Args:
        road: the highway (its reference line, lane count and width).
        config: traffic settings (``None``: the defaults).
        dt: s, the physics step.

    After :meth:`reset` or :meth:`advance`, these ``(n,)`` arrays hold the current state
    (treat them as read-only; ``advance`` replaces rather than mutates the kinematic ones):
    ``ids`` (fixed slots ``0..n-1``: a respawned car keeps its slot's id, as in the
    original, whose sensor fusion numbers its list of cars), ``spawn_count`` (how often each
    slot has been respawned since the reset), ``s``, ``d``, ``speed``, ``lane`` (the lane
    holding the car's centre), ``target_lane`` (the destination of a lane change, else the
    car's lane), ``length``, ``width``, ``type_index``, ``x``, ``y``, ``heading``, ``vx``,
    ``vy``, and ``desired_speed`` (m/s). ``rogue_brake_count`` and ``rogue_cut_in_count``
    count rogue events since the reset. ``sizes_version`` changes whenever a car's
    ``length`` or ``width`` may have (reset, respawn), so callers can keep values derived
    from the sizes until it does.
    """

    def __init__(self, road: HighwayMap, config: TrafficConfig | None = None,
                 dt: float = 0.02) -> None:
        self.road = road
        self.config = config = config if config is not None else TrafficConfig()
        self.dt = float(dt)
        self._ref = road.reference
        self._loop = float(road.length)
        self._half_loop = 0.5 * self._loop
        self._lanes = int(road.lane_count)
        self._lane_width = float(road.lane_width)
        self._range = min(config.spawn_range, 0.45 * self._loop)
        # Respawn bands (m from the ego), inside the recycling range even on a short loop.
        bands = []
        for lo, hi in (config.respawn_ahead, config.respawn_behind):
            hi = min(hi, self._range - 10.0)
            bands.append((lo if lo < hi else 0.5 * hi, hi))
        self._respawn_bands = tuple(bands)
        self._decision_dt = config.decision_period * self.dt
        self._type_p = spawn_probabilities(config.vehicle_mix)
        self._lane_ids = np.arange(self._lanes)
        self._adjacent = np.abs(self._lane_ids[:, None] - self._lane_ids[None, :]) == 1
        self._rogue_p = config.rogue_rate / 60.0 * self._decision_dt if config.rogue else 0.0
        self._brake_steps = round(config.rogue_brake_duration / self.dt)
        self._cut_in_window_steps = round(config.rogue_cut_in_window / self.dt)
        self._sustain_decisions = math.ceil(config.lane_change_sustain / self._decision_dt - 1e-9)
        # Lane-change profile tables: a change is evaluated at most its duration plus a
        # decision period past its start (its end is processed at the next decision).
        longest = max(config.lane_change_duration, config.rogue_cut_in_duration)
        self._lc_table_len = math.ceil(longest / self.dt) + 2 * config.decision_period + 4
        self._lc_profiles: dict[float, FloatArray] = {}
        self._ego_tsab = 2.0 * math.sqrt(config.idm.a_max * config.idm.b)
        # Geometry tables on a uniform s grid, interpolated linearly: a lookup is a
        # handful of numpy calls, against ~30 for a spline evaluation, and the error is
        # far below anything that matters (point: h^2 * kappa / 8 < 0.1 mm for radii
        # over 50 m; see _GEOMETRY_STEP). Rows: x, y, tangent x, tangent y.
        count = max(math.ceil(self._loop / _GEOMETRY_STEP), 16)
        self._grid_count = count
        self._grid_scale = count / self._loop  # grid cells per metre
        grid = np.arange(count + 1) * (self._loop / count)
        point, tangent = self._ref.frame(grid[:-1])
        table = np.hstack([point, tangent])
        table = np.vstack([table, table[:1]])
        self._geo = table[:-1].copy()
        self._geo_step = np.diff(table, axis=0)
        # The same table component-first, for one gather per lookup: rows x, y, tx, ty,
        # ty, -tx (the right normal's two components follow the tangent), then the steps
        # to the next grid point of each. One extra column, the value at the end of the
        # last cell, lets s == L (after rounding) skip the clamp of the cell index.
        values = np.column_stack([self._geo, self._geo[:, 3], -self._geo[:, 2]]).T
        steps = np.column_stack(
            [self._geo_step, self._geo_step[:, 3], -self._geo_step[:, 2]]).T
        end = values[:, -1] + 1.0 * steps[:, -1]
        self._geo_t = np.ascontiguousarray(np.vstack([
            np.column_stack([values, end]), np.column_stack([steps, np.zeros(6)])]))
        self._clamp_cell = self._loop * self._grid_scale > count
        # Constants of the per-step arithmetic as 0-d arrays: numpy converts a Python float
        # operand on every call, which on a dozen cars costs more than the arithmetic.
        self._loop_0d = np.array(self._loop)
        self._grid_scale_0d = np.array(self._grid_scale)
        self._one_0d = np.array(1.0)
        # A car's d stays within [w/2 - wander, (lanes - 1/2) w + wander]: inside the road
        # (its lane index needs no clamp) while the wander is under half a lane.
        self._clamp_lane = config.lateral_wander >= 0.45 * self._lane_width
        kappa = self._ref.curvature(grid[:-1])
        self._kappa_grid = grid
        self._kappa_table = np.append(kappa, kappa[0])
        self._times: dict[int, tuple[IntArray, FloatArray]] = {}
        self._ego_rows: dict[tuple[int, int], tuple[NDArray[np.bool_], FloatArray]] = {}
        # Gaps at reset are laid out in s; divide by this to hold them in lane metres too.
        self._min_scale = max(1.0 - float(np.abs(kappa).max()) * self.road.road_width, 0.5)
        self._rng: np.random.Generator | None = None
        self.sizes_version = 0
        self._allocate(config.car_count)

    # ------------------------------------------------------------------ state
    def _allocate(self, n: int) -> None:
        cfg = self.config
        zeros = np.zeros(n)
        self.n = n
        self.sizes_version += 1
        self.ids: IntArray = np.arange(n, dtype=np.int64)
        self.spawn_count: IntArray = np.zeros(n, dtype=np.int64)
        self.type_index: IntArray = np.zeros(n, dtype=np.int64)
        self.length: FloatArray = zeros.copy()
        self.width: FloatArray = zeros.copy()
        self.s: FloatArray = zeros.copy()
        self.d: FloatArray = zeros.copy()
        self.speed: FloatArray = zeros.copy()
        self.desired_speed: FloatArray = zeros.copy()
        self.target_lane: IntArray = np.zeros(n, dtype=np.int64)
        self.x: FloatArray = zeros.copy()
        self.y: FloatArray = zeros.copy()
        self.heading: FloatArray = zeros.copy()
        self.vx: FloatArray = zeros.copy()
        self.vy: FloatArray = zeros.copy()
        self.rogue_brake_count = 0
        self.rogue_cut_in_count = 0
        # Per-object quantities, the cars then the ego (index n), stacked so that one
        # gather picks all of a follower's: speed, v * T, a_max * (free-road term), a_max,
        # 2 sqrt(a_max b), desired speed. The first three are refreshed at each decision.
        lanes = self._lanes
        ar = np.arange(n)
        self._obj = np.zeros((6, n + 1))
        self._v_all = self._obj[0]
        self._vt_all = self._obj[1]
        self._afree_all = self._obj[2]
        self._a_all = self._obj[3]
        self._tsab_all = self._obj[4]  # 2 sqrt(a b)
        self._v0_all = self._obj[5]
        self._a_all[n] = cfg.idm.a_max
        self._tsab_all[n] = self._ego_tsab
        self._v0_all[n] = 0.1
        self._half_len_all = np.append(zeros, 0.5 * cfg.ego_length)
        self._s_all = np.zeros(n + 1)  # scratch, filled at each decision
        self._d_all = np.zeros(n + 1)
        self._scale_all = np.zeros(n + 1)
        self._rel = np.zeros(n + 1)  # s minus the ego's, folded (the ego's stays 0)
        self._occ_all = np.zeros((n + 1, lanes), dtype=bool)
        # Per lane, 0 for the objects occupying it and inf for the others; shaped to
        # broadcast against (car, object) matrices.
        self._penalty = np.zeros((lanes, 1, n + 1))
        # The same for the search ahead [0] and behind [1] at once, (2, lanes, car,
        # object); behind, a car is also excluded as its own follower (the diagonal).
        self._penalty2 = np.zeros((2, lanes, n, n + 1))
        self._self_inf = np.zeros((n, n + 1))
        self._self_inf[ar, ar] = np.inf
        self._ego_key: tuple[int, int] | None = None
        # delta to every object [0] and its negative [1]; -1e-300 marks delta > 0 as not
        # behind (nonzero |delta| are >= 2^-52: differences of folded s offsets).
        self._delta2 = np.zeros((2, n, n + 1))
        self._invalid = np.zeros((2, n, n + 1), dtype=bool)
        self._search = np.zeros((2, lanes, n, n + 1))
        self._invalid_cut = np.array([0.0, -1e-300])[:, None, None]
        self._search_base = (np.arange(2 * lanes * n) * (n + 1)).reshape(2, lanes, n)
        # Gap rows: every lane ahead, the own lane(s), every lane behind; the leader
        # speeds in the same layout. [:lanes + 1] are the IDM inputs.
        self._gap_v = np.zeros((2, 2 * lanes + 1, n))
        self._gaps = self._gap_v[0, : lanes + 1]
        self._leader_v = self._gap_v[1, : lanes + 1]
        self._gap_v_flat = self._gap_v.reshape(2, -1)
        row = (lanes + 1) * n * 8
        self._ds_gap = np.lib.stride_tricks.as_strided(  # (2, lanes, n): ahead, behind
            self._gap_v[0], shape=(2, lanes, n), strides=(row, n * 8, 8))
        # Rows: every car, its leader per lane, its follower per lane (leader search
        # indices); [0::2] picks the scale of the follower of each gap.
        self._idx3 = np.zeros((3, lanes, n), dtype=np.intp)
        self._idx3[0] = ar
        self._halves2 = np.zeros((2, lanes, n, n + 1))  # half lengths of car + object
        self._hh_dirty = True
        # IDM follower terms (v, vT, a_max * free, a_max, 2 sqrt(a_max b)) in the gap rows:
        # the car itself in every lane ahead and its own, the new follower behind it.
        self._idm_par = np.zeros((5, 2 * lanes + 1, n))
        self._own_flat = ar.copy()  # own lane * n + car, while not changing
        # IDM results in the gap rows; row `lanes` is each car's acceleration, held
        # between decisions. Rows 2 lanes + 1 and 3 lanes + 2 hold half of it and the
        # wander's angular speed: (acc, acc / 2, omega) is one strided (3, 1, n) array,
        # and the speed, the distance term and the wander angle of every sub-step come
        # out of one multiply-add with (t, t, t_abs) and (v0, v0, phase).
        self._idm_out = np.zeros((3 * lanes + 3, n))
        self._acc = self._idm_out[lanes]
        self._half_acc = self._idm_out[2 * lanes + 1]
        self._wander_omega = self._idm_out[3 * lanes + 2]
        self._rate3 = np.lib.stride_tricks.as_strided(
            self._acc, shape=(3, 1, n), strides=((lanes + 1) * n * 8, 0, 8))
        self._start3 = np.zeros((3, 1, n))
        self._wander_phase = self._start3[2, 0]
        self._speed_low: tuple[FloatArray | None, float] = (None, 0.0)
        self._idm_tmp = np.zeros(n + 1)
        self._occ_dirty = True  # lanes changed since the occupancy was last built
        self._center = np.zeros(n)  # d of the centre of each car's origin lane
        self._respawn_wait = np.zeros(n, dtype=np.int64)  # step before which not to retry
        # Dynamics and decisions.
        self._kappa = zeros.copy()  # curvature at the last decision (for ds/dt)
        self._origin = np.zeros(n, dtype=np.int64)  # lane a change started from
        self._lc_start = np.full(n, _NEVER, dtype=np.int64)  # step it started
        self._lc_end = np.full(n, _IDLE, dtype=np.int64)  # step it ends (_IDLE: none)
        self._lc_duration = np.full(n, cfg.lane_change_duration)
        self._changing_any = False
        self._pending = np.full(n, -1, dtype=np.int64)  # lane wished at the last decision
        self._held = np.zeros(n, dtype=np.int64)  # decisions the wish has held since
        self._wander_speed = zeros.copy()  # amplitude * omega: peak lateral speed
        self._brake_until = np.zeros(n, dtype=np.int64)
        self._cut_in_until = np.zeros(n, dtype=np.int64)
        # Upper bounds of the three arrays above (step numbers), to skip work past them.
        self._brake_max = 0
        self._cut_in_max = 0
        self._lc_next_end = _IDLE  # lower bound of _lc_end
        self._wishes = False  # some _pending / _held may be set
        self._lc_dirty = True  # the per-car lane-change constants need a rebuild
        self._rows = np.arange(n)
        self._tri = np.tri(n, k=-1, dtype=bool)
        self._step = 0
        self._respawn_blocked_until = 0  # after a failed respawn, pause all attempts
        self._ego = (0.0, 0.0, 0.0)  # s, d, speed at the latest sample

    def _ego_occupancy(self, ego_d: float) -> tuple[NDArray[np.bool_], FloatArray]:
        """Lanes touched by the ego's footprint (its width, across d), and their penalty."""
        half = 0.5 * self.config.ego_width
        key = (math.floor((ego_d - half) / self._lane_width),
               math.floor((ego_d + half) / self._lane_width))
        rows = self._ego_rows.get(key)
        if rows is None:
            occ = (self._lane_ids >= key[0]) & (self._lane_ids <= key[1])
            rows = self._ego_rows.setdefault(key, (occ, np.where(occ, 0.0, np.inf)))
        return rows

    def _occupancy(self) -> NDArray[np.bool_]:
        """(n, lanes): the lanes each car occupies (origin and target while changing)."""
        lanes = self._lane_ids[None, :]
        return (lanes == self._origin[:, None]) | (lanes == self.target_lane[:, None])

    def _new_car(self, i: int, type_index: int, s: float, lane: int, speed: float,
                 desired: float, rng: np.random.Generator) -> None:
        """Write a fresh car into slot ``i`` (arrays must be owned, not sample views)."""
        cfg = self.config
        vtype = VEHICLE_TYPES[type_index]
        self.type_index[i] = type_index
        self.length[i] = vtype.length
        self.width[i] = vtype.width
        self.sizes_version += 1
        self._half_len_all[i] = 0.5 * vtype.length
        self._hh_dirty = True
        self._a_all[i] = vtype.comfort_accel
        self._tsab_all[i] = 2.0 * math.sqrt(vtype.comfort_accel * vtype.comfort_decel)
        self.s[i] = s
        self.speed[i] = speed
        self.desired_speed[i] = self._v0_all[i] = desired
        self._origin[i] = self.target_lane[i] = lane
        self._occ_dirty = True
        self._respawn_wait[i] = 0
        self._lc_start[i] = _NEVER
        self._lc_end[i] = _IDLE
        self._pending[i] = -1
        self._held[i] = 0
        self._acc[i] = self._half_acc[i] = 0.0
        self._brake_until[i] = self._cut_in_until[i] = 0
        self._wander_omega[i] = 2.0 * np.pi / rng.uniform(*cfg.wander_period)
        self._wander_phase[i] = rng.uniform(0.0, 2.0 * np.pi)
        self._wander_speed[i] = cfg.lateral_wander * self._wander_omega[i]
        self._lc_dirty = True
        self.d[i] = (lane + 0.5) * self._lane_width + cfg.lateral_wander * math.sin(
            self._wander_omega[i] * self._step * self.dt + self._wander_phase[i]
        )

    def _own_arrays(self) -> None:
        """Copy the per-car arrays a respawn writes into (they may be views of samples)."""
        for name in ("spawn_count", "s", "d", "speed", "type_index", "length", "width",
                     "desired_speed", "target_lane"):
            setattr(self, name, getattr(self, name).copy())

    # ------------------------------------------------------------------ placement
    def _find_spot(self, placed: NDArray[np.bool_], type_index: int, offsets: FloatArray,
                   lanes: IntArray, desired: FloatArray) -> tuple[int, float]:
        """First candidate (ego_s + offset, lane) satisfying the respawn rule, and its speed.

        ``placed`` masks the cars that count; the ego always counts. Returns (-1, 0.0)
        when no candidate fits.
        """
        cfg = self.config
        ego_s, ego_d, ego_speed = self._ego
        vtype = VEHICLE_TYPES[type_index]
        idx = np.append(np.flatnonzero(placed), self.n)  # the ego is object n
        self._fill_objects(ego_s, ego_d, ego_speed)
        s_o = self._s_all[idx]
        len_o = 2.0 * self._half_len_all[idx]
        v_o = self._v_all[idx]
        occ_o = self._occ_all[idx]
        s_c = self._ref.wrap_s(ego_s + offsets)
        scale_c = 1.0 + self._curvature(s_c) * ((lanes + 0.5) * self._lane_width)
        scale_o = 1.0 + self._curvature(s_o) * self._d_all[idx]

        inlane = occ_o[:, lanes].T  # (candidates, objects)
        delta = self._ref.s_difference(s_o[None, :], s_c[:, None])
        ahead = np.where(inlane & (delta >= 0.0), delta, np.inf)
        behind = np.where(inlane & (delta < 0.0), -delta, np.inf)
        rows = np.arange(len(s_c))
        li = ahead.argmin(axis=1)
        fi = behind.argmin(axis=1)
        gap_lead = ahead[rows, li] * scale_c - 0.5 * (vtype.length + len_o[li])
        gap_follow = behind[rows, fi] * scale_o[fi] - 0.5 * (vtype.length + len_o[fi])
        speed = np.minimum(desired, max_speed_for_gap(
            gap_lead, v_o[li], cfg.idm, vtype.comfort_accel, vtype.comfort_decel))
        # The follower (a car or the ego) must not find the newcomer inside its desired
        # gap: it then brakes by at most its a_max, never hard.
        a_f = self._a_all[idx][fi]
        b_f = (0.5 * self._tsab_all[idx][fi]) ** 2 / a_f
        ok = (
            (gap_lead >= cfg.spawn_min_gap)
            & (gap_follow >= cfg.spawn_min_gap)
            & (gap_follow >= desired_gap(v_o[fi], speed, cfg.idm, a_f, b_f))
        )
        if not ok.any():
            return -1, 0.0
        k = int(ok.argmax())
        return k, float(speed[k])

    def _place(self, i: int, placed: NDArray[np.bool_], rng: np.random.Generator,
               offsets: FloatArray) -> bool:
        """Draw a type, lanes and desired speeds for car ``i``; place it if a spot fits."""
        cfg = self.config
        type_index = int(rng.choice(len(VEHICLE_TYPES), p=self._type_p))
        lanes = rng.integers(0, self._lanes, size=len(offsets))
        u = rng.random(len(offsets))
        lo_a, hi_a = cfg.speed_ahead_mph
        lo_b, hi_b = cfg.speed_behind_mph
        desired = MPH * np.where(offsets > 0, lo_a + u * (hi_a - lo_a), lo_b + u * (hi_b - lo_b))
        k, speed = self._find_spot(placed, type_index, offsets, lanes, desired)
        if k < 0:
            return False
        s = float(self._ref.wrap_s(self._ego[0] + offsets[k]))
        self._new_car(i, type_index, s, int(lanes[k]), speed, float(desired[k]), rng)
        return True

    def _free_spot(self, i: int, rel: FloatArray, type_index: int, spread: float,
                   rng: np.random.Generator) -> tuple[float, int] | None:
        """Reset: a centre (s relative to the ego) and lane for car ``i``, drawn uniformly
        over the room that keeps ``spawn_min_gap`` to cars ``0 .. i-1`` and the ego."""
        cfg = self.config
        half = 0.5 * VEHICLE_TYPES[type_index].length
        others = np.append(rel[:i], 0.0)  # placed cars, then the ego
        reach = (np.append(self._half_len_all[:i], 0.5 * cfg.ego_length) + half
                 + cfg.spawn_min_gap) / self._min_scale
        occupied = np.vstack([self._occupancy()[:i], self._ego_occupancy(self._ego[1])[0]])
        pieces: list[tuple[int, float, float]] = []
        for lane in range(self._lanes):
            mask = occupied[:, lane]
            lo, hi = -spread + half, spread - half
            starts, ends = others[mask] - reach[mask], others[mask] + reach[mask]
            order = np.argsort(starts)
            starts, ends = starts[order], np.maximum.accumulate(ends[order])
            # Free room: before the first blocked interval, between them, after the last.
            room_lo = np.concatenate([[lo], ends])
            room_hi = np.concatenate([starts, [hi]])
            room_lo, room_hi = np.maximum(room_lo, lo), np.minimum(room_hi, hi)
            pieces += [(lane, a, b) for a, b in zip(room_lo, room_hi, strict=True) if b > a]
        if not pieces:
            return None
        sizes = np.array([b - a for _, a, b in pieces])
        lane, a, b = pieces[int(rng.choice(len(pieces), p=sizes / sizes.sum()))]
        return float(rng.uniform(a, b)), lane

    def _settle_speeds(self) -> None:
        """Reset: slow each car, front to back, to a speed whose IDM gap fits its leader."""
        cfg = self.config
        n = self.n
        ego_s, ego_d, ego_speed = self._ego
        self._fill_objects(ego_s, ego_d, ego_speed)
        rel = self._ref.s_difference(self._s_all, ego_s)  # the ego has rel 0
        scale = 1.0 + self._curvature(self._s_all[:n]) * self.d
        occ = self._occ_all
        for i in np.argsort(-rel[:n], kind="stable"):
            lane = self._origin[i]
            ahead = occ[:, lane] & (rel > rel[i])
            if not ahead.any():
                continue
            j = int(np.flatnonzero(ahead)[np.argmin(rel[ahead])])
            gap = (rel[j] - rel[i]) * scale[i] - self._half_len_all[i] - self._half_len_all[j]
            a_i = self._a_all[i]
            b_i = (self._tsab_all[i] / 2.0) ** 2 / a_i
            safe = float(max_speed_for_gap(gap, self._v_all[j], cfg.idm, a_i, b_i))
            self.speed[i] = self._v_all[i] = min(self.speed[i], safe)

    # ------------------------------------------------------------------ public API
    def reset(self, rng: np.random.Generator, ego_s: float, ego_d: float,
              ego_speed: float = 0.0) -> None:
        """Place ``car_count`` cars around the ego car (see the module docstring).

        All randomness of the episode comes from ``rng`` (kept for :meth:`advance`).
        ``ego_speed`` defaults to the original's start at rest. Raises ``ValueError`` if
        the cars cannot be placed within ``spawn_range``.
        """
        cfg = self.config
        self._allocate(cfg.car_count)
        self._rng = rng
        self._ego = (float(ego_s) % self._loop, float(ego_d), float(ego_speed))
        spread_max = self._range - 10.0
        spread = min(0.75 * self._range / cfg.density, spread_max)
        rel = np.zeros(self.n)
        for i in range(self.n):
            type_index = int(rng.choice(len(VEHICLE_TYPES), p=self._type_p))
            while (spot := self._free_spot(i, rel, type_index, spread, rng)) is None:
                if spread >= spread_max:
                    raise ValueError(
                        f"cannot place {self.n} traffic cars within +-{spread_max:.0f} m of "
                        f"the ego on {self._lanes} lanes; lower car_count or raise spawn_range"
                    )
                spread = min(1.25 * spread, spread_max)
            rel[i], lane = spot
            lo, hi = cfg.speed_ahead_mph if rel[i] > 0.0 else cfg.speed_behind_mph
            desired = MPH * rng.uniform(lo, hi)
            s = float(self._ref.wrap_s(self._ego[0] + rel[i]))
            self._new_car(i, type_index, s, lane, desired, desired, rng)
        self._settle_speeds()
        self._kappa = self._curvature(self.s)
        self._update_pose(self.samples_now())

    def reset_to(self, rng: np.random.Generator, ego_s: float, ego_d: float, ego_speed: float,
                 *, s: ArrayLike, lane: ArrayLike, speed: ArrayLike,
                 desired_speed: ArrayLike | None = None,
                 type_index: ArrayLike | None = None) -> None:
        """Start from explicit cars instead of a random placement (scenarios, replays, tests).

        Args:
            rng: randomness for the rest of the episode (wander phases, respawns, rogue).
            ego_s, ego_d, ego_speed: the ego car's state.
            s, lane, speed: ``(n,)`` each car's arc length (m), lane index, speed (m/s);
                ``n`` may differ from ``config.car_count``.
            desired_speed: ``(n,)`` m/s; default: ``speed``.
            type_index: ``(n,)`` indices into :data:`VEHICLE_TYPES`; default: all cars.
        """
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        n = len(s)
        lane = np.broadcast_to(np.asarray(lane, dtype=np.int64), (n,))
        speed = np.broadcast_to(np.asarray(speed, dtype=np.float64), (n,))
        desired = speed if desired_speed is None else np.broadcast_to(
            np.asarray(desired_speed, dtype=np.float64), (n,))
        types = np.zeros(n, dtype=np.int64) if type_index is None else np.broadcast_to(
            np.asarray(type_index, dtype=np.int64), (n,))
        if np.any((lane < 0) | (lane >= self._lanes)):
            raise ValueError(f"lane must be in [0, {self._lanes}); got {lane.tolist()}")
        if np.any((types < 0) | (types >= len(VEHICLE_TYPES))):
            raise ValueError(f"type_index must be in [0, {len(VEHICLE_TYPES)})")
        self._allocate(n)
        self._rng = rng
        self._ego = (float(ego_s) % self._loop, float(ego_d), float(ego_speed))
        for i in range(n):
            self._new_car(i, int(types[i]), float(s[i] % self._loop), int(lane[i]),
                          float(speed[i]), float(desired[i]), rng)
        self._kappa = self._curvature(self.s)
        self._update_pose(self.samples_now())

    def samples_now(self) -> TrafficSamples:
        """The current state as a one-step :class:`TrafficSamples`."""
        d, d_dot = self._lateral(1, self._step - 1)
        return self._pose(self.s[None, :], d, self.speed[None, :], d_dot)

    def advance(self, steps: int, ego_s: ArrayLike, ego_d: ArrayLike,
                ego_speed: ArrayLike) -> TrafficSamples:
        """Simulate ``steps`` physics steps; return the state after each one.

        Args:
            steps: number of physics steps (>= 1).
            ego_s, ego_d, ego_speed: ``(steps,)`` the ego's Frenet state and speed (m/s)
                after each sub-step. A decision instant uses the latest ego state before
                it (the previous call's last one for a decision at the start).
        """
        if self._rng is None:
            raise RuntimeError("call reset() before advance()")
        if steps < 1:
            raise ValueError(f"steps must be >= 1; got {steps}")
        ego_s, ego_d, ego_speed = (_per_step(values, steps)
                                   for values in (ego_s, ego_d, ego_speed))
        period = self.config.decision_period
        phase = self._step % period
        if steps <= period - phase:  # the usual call: at most one decision, at the start
            if phase == 0:
                self._decide()
            s, d, v, d_dot, low = self._segment(steps, last=True)
        else:
            low = None
            parts: list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = []
            done = 0
            while done < steps:
                phase = self._step % period
                if phase == 0:
                    if done:
                        self._ego = (float(ego_s[done - 1]) % self._loop,
                                     float(ego_d[done - 1]), float(ego_speed[done - 1]))
                    self._decide()
                m = min(steps - done, period - phase)
                parts.append(self._segment(m)[:4])
                done += m
            s, d, v, d_dot = (np.concatenate(p) for p in zip(*parts, strict=True))
        self._ego = (float(ego_s[-1]) % self._loop, float(ego_d[-1]), float(ego_speed[-1]))
        samples = self._pose(s, d, v, d_dot, low)
        self._update_pose(samples)
        if low is not None and low > -np.inf:  # the new speeds' minimum, for the next call
            self._speed_low = (self.speed, self._end_low)
        return samples

    # ------------------------------------------------------------------ kinematics
    def _curvature(self, s: FloatArray) -> FloatArray:
        """Signed curvature at wrapped ``s`` from the table (linear interpolation)."""
        return np.interp(s, self._kappa_grid, self._kappa_table)

    def _sub_times(self, m: int) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
        """Sub-step numbers ``(m, 1)``, their times, an ``(m + 1, n)`` scratch array whose
        first row stays 0 (the distance at the segment start), and a ``(3, m, 1)`` one
        holding the times twice (then the absolute times, filled by the caller)."""
        cached = self._times.get(m)
        if cached is None or cached[2].shape[1] != self.n:
            k = np.arange(1, m + 1, dtype=np.int64)[:, None]
            t = k * self.dt
            times3 = np.stack([t, t, t])
            cached = self._times[m] = (k, t, np.zeros((m + 1, self.n)), times3)
        return cached

    def _lc_profile(self, duration: float) -> FloatArray:
        """``(2, J + 1)``: the quintic step and its derivative factor ``tau^2 (1 - tau)^2``
        at ``j = 0 .. J`` steps into a lane change of ``duration`` (the same operations
        on the same tau as evaluating them at every sub-step)."""
        profile = self._lc_profiles.get(duration)
        if profile is None:
            j = np.arange(self._lc_table_len, dtype=np.int64)
            tau = np.clip(j * (self.dt / np.array([duration])), 0.0, 1.0)
            tau2 = tau * tau
            step = tau2 * tau * (10.0 + tau * (6.0 * tau - 15.0))
            profile = self._lc_profiles[duration] = np.stack([step, tau2 * (1.0 - tau) ** 2])
        return profile

    def _lc_constants(self) -> None:
        """Per-car lane-change tables (they change only when a change starts or ends)."""
        n, length = self.n, self._lc_table_len
        shift = (self.target_lane - self._origin) * self._lane_width
        self._lc_gain = np.stack([shift, 30.0 * shift / self._lc_duration])[:, None, :]
        table = np.empty((2, n, length))
        for duration in np.unique(self._lc_duration):
            table[:, self._lc_duration == duration] = self._lc_profile(float(duration))[:, None]
        self._lc_table = table.reshape(2, n * length)
        # (step - lc_start) + car * length: the flat index of car's entry (a car not
        # changing lands past the end, clipped to a finite entry that its zero gain
        # cancels; a changing one stays within its row: see _lc_table_len).
        self._lc_base = self._lc_start - self._rows * length
        self._adj_idle = self._adjacent_own & (self._lc_end == _IDLE)
        self._lc_dirty = False

    def _lateral(self, m: int, base: int, angle: FloatArray | None = None
                 ) -> tuple[FloatArray, FloatArray]:
        """d and d_dot ``(m, n)`` after steps ``base + 1 .. base + m`` (closed form);
        ``angle``: the wander's, if the caller has it."""
        cfg = self.config
        k, t, _, _ = self._sub_times(m)
        if self._occ_dirty:
            self._center = (self._origin + 0.5) * self._lane_width
        if cfg.lateral_wander > 0.0:
            if angle is None:
                angle = self._wander_omega * (base * self.dt + t)
                angle += self._wander_phase
            d = np.sin(angle)
            d *= cfg.lateral_wander
            d += self._center
            d_dot = np.cos(angle)
            d_dot *= self._wander_speed
        else:
            d = self._center + np.zeros((m, 1))
            d_dot = np.zeros((m, self.n))
        if self._changing_any:
            if self._lc_dirty:
                self._lc_constants()
            # Quintic minimum-jerk step 10t^3 - 15t^4 + 6t^5 and its time derivative
            # (30 shift / duration) tau^2 (1 - tau)^2, from the per-car tables.
            profile = self._lc_table.take((base + k) - self._lc_base, axis=1, mode="clip")
            profile *= self._lc_gain
            d += profile[0]
            d_dot += profile[1]
        return d, d_dot

    def _segment(self, m: int, last: bool = False
                 ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float]:
        """``m`` sub-steps with the held accelerations: s (unwrapped), d, speed, d_dot, and
        a lower bound of the speeds (or -inf).

        ``last``: the caller takes the new state from the samples (skips updating it)."""
        _, t, dist, times3 = self._sub_times(m)
        v0, acc = self.speed, self._acc
        base = self._step
        # (acc, acc / 2, omega) * (t, t, t_abs) + (v0, v0, phase): the speed, the
        # distance term v0 + acc t / 2 and the wander angle (acc / 2 is kept by _decide).
        start3 = self._start3
        start3[:2, 0] = v0
        np.add(base * self.dt, t, out=times3[2])
        rates = self._rate3 * times3
        rates += start3
        v, inner, angle = rates[0], rates[1], rates[2]
        low = self._end_low = _smallest(v[-1])
        if low > 1e-6:
            # No car reaches v = 0 within the segment: v0 + acc t_max > 1e-6 puts the
            # stop time v0 / -acc beyond t_max by far more than rounding, so te = t.
            te = t
            known, known_low = self._speed_low
            if known is not v0:
                known_low = _smallest(v0)
            low = min(low, known_low)  # v is monotonic in t
        else:
            # Hold the acceleration, but a braking car stops at v = 0 instead of reversing.
            t_stop = np.where(acc < 0.0, v0, np.inf) / np.maximum(-acc, 1e-12)
            te = np.minimum(t, t_stop)
            v = acc * te
            v += v0
            inner = self._half_acc * te
            inner += v0
            low = -np.inf
        # dist[1:] = te * (v0 + 0.5 acc te); dist[0] stays 0, so inc = its differences.
        np.multiply(te, inner, out=dist[1:])
        inc = np.subtract(dist[1:], dist[:-1])
        d, d_dot = self._lateral(m, base, angle)
        # Along-lane distance -> arc length of the reference line: ds = dist / (1 + kappa d).
        scale = self._kappa * d
        scale += self._one_0d
        inc /= scale
        s = np.add.accumulate(inc, axis=0)
        s += self.s
        if not last:
            self.s = s[-1] % self._loop
            self.speed = v[-1]
            self.d = d[-1]
        self._step += m
        return s, d, v, d_dot, low

    def _pose(self, s: FloatArray, d: FloatArray, v: FloatArray, d_dot: FloatArray,
              low: float | None = None) -> TrafficSamples:
        """World pose of ``(steps, n)`` Frenet states: one table lookup for all of them.

        ``low``: a lower bound of ``v``, if known."""
        s = s % self._loop_0d
        u = s * self._grid_scale_0d
        # Cell index and fraction; floor is the cast's truncation for u >= 0, and u - floor
        # is float arithmetic, which numpy runs without the int-to-float buffering of u - i.
        cell = np.floor(u)
        if self._clamp_cell:  # s == L after rounding; else the table's extra column
            np.minimum(cell, self._grid_count - 1, out=cell)
        f = u - cell
        i = cell.astype(np.intp)
        g = self._geo_t.take(i, axis=1)  # (12, steps, n): values, then steps
        geo = g[6:] * f
        geo += g[:6]  # x, y, tx, ty, ty, -tx
        normal = geo[4:]
        # Right normal n = (ty, -tx); velocity = v * tangent + d_dot * n.
        xy = d * normal
        xy += geo[:2]
        vxy = v * geo[2:4]
        vxy += d_dot * normal
        # Heading of the motion; a (near) stopped car keeps pointing along its lane.
        if low is None:
            low = _smallest(v)
        if low >= 1.0:
            direction = vxy
        else:
            direction = np.maximum(v, 1.0) * geo[2:4]
            direction += d_dot * normal
        heading = np.arctan2(direction[1], direction[0])
        return TrafficSamples._make(s, d, v, xy[0], xy[1], heading, vxy[0], vxy[1])

    def _update_pose(self, samples: TrafficSamples) -> None:
        self.s = samples.s[-1]
        self.d = samples.d[-1]
        self.speed = samples.speed[-1]
        self.x = samples.x[-1]
        self.y = samples.y[-1]
        self.heading = samples.heading[-1]
        self.vx = samples.vx[-1]
        self.vy = samples.vy[-1]

    @property
    def lane(self) -> IntArray:
        """``(n,)`` the lane holding each car's centre (worked out when read: the
        simulation itself never needs it)."""
        lane = (self.d * (1.0 / self._lane_width)).astype(np.int64)
        if self._clamp_lane:  # else d always lies within the road (see __init__)
            lane = np.minimum(np.maximum(lane, 0), self._lanes - 1)
        return lane

    # ------------------------------------------------------------------ decisions
    def _fill_objects(self, ego_s: float, ego_d: float, ego_speed: float) -> None:
        """Scratch arrays of all objects: the cars, then the ego at index n."""
        n = self.n
        self._s_all[:n] = self.s
        self._s_all[n] = ego_s
        self._d_all[:n] = self.d
        self._d_all[n] = ego_d
        self._v_all[:n] = self.speed
        self._v_all[n] = ego_speed
        changed = False
        if self._occ_dirty:  # only lane-change starts/ends and respawns move occupancy
            occ = self._occ_all[:n]
            np.equal(self._lane_ids, self._origin[:, None], out=occ)
            occ |= self._lane_ids == self.target_lane[:, None]
            self._penalty[:, 0, :n] = np.where(occ.T, 0.0, np.inf)
            self._center = (self._origin + 0.5) * self._lane_width
            self._own_flat = self._origin * n + self._rows
            self._adjacent_own = self._adjacent[:, self._origin]
            self._occ_dirty = False
            changed = True
        half = 0.5 * self.config.ego_width
        key = (math.floor((ego_d - half) / self._lane_width),
               math.floor((ego_d + half) / self._lane_width))
        if changed or key != self._ego_key:
            self._ego_key = key
            self._occ_all[n], self._penalty[:, 0, n] = self._ego_occupancy(ego_d)
            np.copyto(self._penalty2[0], self._penalty)
            np.add(self._penalty, self._self_inf, out=self._penalty2[1])

    def _recycle(self, rel: FloatArray) -> bool:
        """Respawn (a few of) the cars further than ``spawn_range`` from the ego.

        ``rel`` is each car's s minus the ego's (folded). Returns whether any car moved.
        """
        if self._step < self._respawn_blocked_until:
            return False
        far = (np.abs(rel) > self._range) & (self._respawn_wait <= self._step)
        if not _any(far):
            return False
        rng = self._rng
        assert rng is not None
        self._own_arrays()
        idx = np.flatnonzero(far)
        idx = idx[np.argsort(-np.abs(rel[idx]), kind="stable")][: self.config.respawn_per_decision]
        moved = False
        for i in idx:
            placed = np.ones(self.n, dtype=bool)
            placed[i] = False
            # The original's coin: ahead (slow) or behind (fast), whatever side it left.
            ahead = rng.random() < self.config.respawn_ahead_probability
            (lo_a, hi_a), (lo_b, hi_b) = self._respawn_bands
            spots_ahead = rng.uniform(lo_a, hi_a, size=_SPAWN_CANDIDATES)
            spots_behind = -rng.uniform(lo_b, hi_b, size=_SPAWN_CANDIDATES)
            # The picked side's spots first, then the other side's (no room on the first).
            offsets = np.concatenate((spots_ahead, spots_behind) if ahead
                                     else (spots_behind, spots_ahead))
            if self._place(int(i), placed, rng, offsets):
                self.spawn_count[i] += 1  # the slot keeps its id, as the original's cars
                moved = True
            else:  # no room (dense traffic): the car drives on; retry in a while
                self._respawn_wait[i] = self._step + _RESPAWN_RETRY_STEPS
                self._respawn_blocked_until = self._step + _RESPAWN_PAUSE_STEPS
                break  # the others would not fit either, most likely
        self._changing_any = _any(self._lc_end < _IDLE)
        return moved

    def _decide(self) -> None:
        """One decision instant: recycle, leader search, IDM, lane changes, rogue events.

        Per-lane quantities are ``(lanes, n)`` arrays (lane first: numpy's inner loops then
        run over the cars, which is what makes the masked argmin cheap). The work goes
        into preallocated buffers, in as few numpy calls as the arithmetic allows (with a
        dozen cars each call costs far more than its arithmetic), and through the cheapest
        form of each call: array methods (``.take``) and ``np.putmask`` rather than
        ``np.take`` and ``np.copyto(where=)``, whose Python-level dispatch costs more than
        the gather itself; :func:`_any` rather than ``.any()``.
        """
        n = self.n
        if n == 0:
            return
        cfg = self.config
        idm = cfg.idm
        ego_s, ego_d, ego_speed = self._ego
        step = self._step
        lanes = self._lanes
        rows = self._rows
        if self._changing_any and step >= self._lc_next_end:
            finished = self._lc_end <= step  # finished lane changes free their origin lane
            if _any(finished):
                self._origin = np.where(finished, self.target_lane, self._origin)
                self._lc_start = np.where(finished, _NEVER, self._lc_start)
                self._lc_end = np.where(finished, _IDLE, self._lc_end)
                self._changing_any = _any(self._lc_end < _IDLE)
                self._occ_dirty = True
                self._lc_dirty = True
            self._lc_next_end = int(self._lc_end.min())
        self._fill_objects(ego_s, ego_d, ego_speed)
        rel = self._relative(ego_s)
        tmp = self._idm_tmp
        farthest = max(map(abs, rel.tolist()))
        if farthest > self._range and self._recycle(rel[:n]):  # cars moved: rebuild
            self._fill_objects(ego_s, ego_d, ego_speed)
            rel = self._relative(ego_s)
            farthest = max(map(abs, rel.tolist()))
        # delta[i, j]: s of object j minus s of car i. Unfolded differences of the folded
        # offsets from the ego are exact while every |rel| < L/4 (the usual case).
        delta2 = self._delta2
        delta = delta2[0]
        np.subtract(rel, rel[:n, None], out=delta)
        if farthest >= 0.25 * self._loop:
            delta += self._half_loop
            np.remainder(delta, self._loop, out=delta)
            delta -= self._half_loop
        np.negative(delta, out=delta2[1])
        kappa = np.interp(self._s_all, self._kappa_grid, self._kappa_table)
        self._kappa = kappa[:n]
        scale_all = np.multiply(kappa, self._d_all, out=self._scale_all)
        scale_all += 1.0
        half_len = self._half_len_all

        # Nearest object ahead [0] / behind [1] in every lane: argmin over (side, lane,
        # car, object) of delta [0] and -delta [1], the objects on the wrong side or not
        # occupying a lane pushed to inf. Ties at delta = 0 count as behind; a car is
        # neither ahead of nor behind itself (its own penalty, behind).
        np.less_equal(delta2, self._invalid_cut, out=self._invalid)
        np.putmask(delta2, self._invalid, np.inf)
        search = np.add(delta2[:, None], self._penalty2, out=self._search)
        idx3 = self._idx3
        idx = search.argmin(axis=3, out=idx3[1:])  # (2, lanes, n) object index
        idx_flat = idx + self._search_base
        ds = search.take(idx_flat)  # (2, lanes, n): distance in s ahead, behind
        li, fi = idx[0], idx[1]
        # Bumper gaps along the follower's lane, into the IDM buffers: rows every lane
        # ahead, the own lane(s), every lane behind; leader speeds likewise.
        gap2 = self._ds_gap
        np.multiply(ds, scale_all.take(idx3[::2]), out=gap2)
        if self._hh_dirty:  # half lengths of car i plus object j, in the search layout
            np.copyto(self._halves2, half_len + half_len[:n, None])
            self._hh_dirty = False
        gap2 -= self._halves2.take(idx_flat)
        lead_gap, follow_gap = gap2[0], gap2[1]
        gap_v = self._gap_v
        lead_v = gap_v[1, :lanes]
        self._v_all.take(li, out=lead_v)

        # IDM in every lane (as if there) and with the leader over the occupied lane(s).
        if self._changing_any:  # nearest leader over both lanes of a changing car
            own_gaps = lead_gap + self._penalty[:, 0, :n]  # inf in lanes the car is not in
            own = own_gaps.argmin(axis=0)
            gap_v[0, lanes] = own_gaps[own, rows]
            gap_v[1, lanes] = lead_v[own, rows]
        else:
            gap_v[:, lanes] = self._gap_v_flat.take(self._own_flat, axis=1)
        # Per-object terms (the ego "wants" its current speed), then idm_core's arithmetic
        # for every gap row at once: the car in every lane and in its own, and the new
        # follower behind it in every lane (MOBIL's imposed braking), leader the car.
        self._v0_all[n] = max(ego_speed, 0.1)
        v_all = self._v_all
        np.maximum(v_all, 0.0, out=tmp)
        tmp /= self._v0_all
        free = tmp ** idm.delta
        np.subtract(1.0, free, out=free)
        np.multiply(self._a_all, free, out=self._afree_all)
        np.multiply(v_all, idm.T, out=self._vt_all)
        par = self._idm_par
        obj = self._obj[:5]
        par[:, : lanes + 1] = obj[:, None, :n]
        par[:, lanes + 1:] = obj[:, fi]
        gap_v[1, lanes + 1:] = self.speed
        acc_all = self._idm(par[0], par[1:], gap_v[1], gap_v[0],
                            self._idm_out[: 2 * lanes + 1])
        acc_lane, acc, imposed = acc_all[:lanes], acc_all[lanes], acc_all[lanes + 1:]

        # Lane-change wishes: clear +-clearance, MOBIL incentive and safety; sustained.
        # Eligible: not changing lanes (in _adj_idle), fast enough, not rogue-braking.
        if self._lc_dirty:
            self._lc_constants()
        clear = ds >= cfg.lane_change_clearance  # (2, lanes, n): ahead, behind
        candidate = np.subtract(acc_lane, acc) > cfg.lane_change_min_gain
        candidate &= self._adj_idle
        candidate &= clear[0]
        candidate &= clear[1]
        known, known_low = self._speed_low
        if known is not self.speed or known_low < cfg.lane_change_min_speed:
            candidate &= self.speed >= cfg.lane_change_min_speed
        brake_until = self._brake_until  # as it was before this decision's rogue events
        if step < self._brake_max:
            candidate &= step >= brake_until
        start = None
        if _any(candidate):
            limit = -cfg.lane_change_max_braking_imposed
            candidate &= (acc_lane >= limit) & ((imposed >= limit) | np.isinf(follow_gap))
            best = np.where(candidate, acc_lane, -np.inf).argmax(axis=0)
            want = np.where(candidate[best, rows], best, -1)
            wish = want >= 0
            wish &= want == self._pending
            self._held = held = (self._held + 1) * wish
            self._pending = want
            self._wishes = True
            # held >= sustain >= 1 implies a (sustained) wish.
            start = held >= self._sustain_decisions if self._sustain_decisions else want >= 0
            if _any(start):
                # One start per target lane per decision (the lowest slot): two cars
                # entering a lane at once did not see each other in their checks. The
                # others keep their sustained wish and retry at the next decision.
                conflict = (want[:, None] == want) & start & self._tri
                start &= ~conflict.any(axis=1)
                self._begin_change(start, want, cfg.lane_change_duration)
        elif self._wishes:
            self._pending.fill(-1)
            self._held.fill(0)
            self._wishes = False

        if self._rogue_p > 0.0:
            rogue_acc = self._rogue(acc, brake_until, self._adjacent_own, clear, lead_gap,
                                    follow_gap, lead_v, fi)
            if rogue_acc is not acc:
                np.copyto(acc, rogue_acc)  # acc is self._acc: held until the next decision
        np.multiply(acc, 0.5, out=self._half_acc)  # for _segment's distance term

    def _idm(self, v: FloatArray, terms: FloatArray, leader_v: FloatArray,
             gap: FloatArray, out: FloatArray) -> FloatArray:
        """:func:`idm_core` from the per-object terms ``(vT, a_max * free, a_max,
        2 sqrt(a_max b))`` of the followers ``v``: the same operations on the same values,
        so the same bits, with the free-road term shared by every lane."""
        idm = self.config.idm
        vt, afree, a, tsab = terms
        w = np.subtract(v, leader_v, out=out)
        w *= v
        w /= tsab  # closing term
        if idm.floor_desired_gap:
            w += vt
            np.maximum(w, 0.0, out=w)
            w += idm.s0
        else:
            w += idm.s0 + vt
        w /= np.maximum(gap, _IDM_NOT_ZERO)
        w *= w
        w *= a
        np.subtract(afree, w, out=w)
        return np.maximum(w, -idm.max_braking, out=w)

    def _relative(self, ego_s: float) -> FloatArray:
        """s of every object (cars, then the ego) minus the ego's, folded to [-L/2, L/2)."""
        rel = np.subtract(self._s_all, ego_s, out=self._rel)
        rel += self._half_loop
        np.remainder(rel, self._loop_0d, out=rel)
        rel -= self._half_loop
        return rel

    def _begin_change(self, start: NDArray[np.bool_], lane: IntArray, duration: float) -> None:
        steps = math.ceil(duration / self.dt - 1e-9)
        self.target_lane = np.where(start, lane, self.target_lane)
        self._lc_start = np.where(start, self._step, self._lc_start)
        self._lc_end = np.where(start, self._step + steps, self._lc_end)
        self._lc_duration = np.where(start, duration, self._lc_duration)
        self._pending = np.where(start, -1, self._pending)
        self._held = np.where(start, 0, self._held)
        self._changing_any = True
        self._occ_dirty = True
        self._lc_dirty = True
        self._lc_next_end = min(self._lc_next_end, self._step + steps)

    def _rogue(self, acc: FloatArray, brake_until: IntArray, adjacent: NDArray[np.bool_],
               clear: NDArray[np.bool_], lead_gap: FloatArray, follow_gap: FloatArray,
               lead_v: FloatArray, fi: IntArray) -> FloatArray:
        """Rogue events: hard-braking episodes and cut-ins (see :class:`TrafficConfig`).

        A cut-in takes a gap the normal rule refuses (someone within the clearance) but
        one that braking at ``idm.max_braking`` after a decision period's delay survives,
        for the car cutting in and for its new follower (a car or the ego): a surprise,
        not a certain crash.
        """
        cfg = self.config
        rng = self._rng
        assert rng is not None
        step = self._step
        u = rng.random((2 + self._lanes, self.n))
        event = u[0] < self._rogue_p
        if event.any():
            brake = event & (u[1] < 0.5) & (step >= self._brake_until)
            cut = event & (u[1] >= 0.5)
            self._brake_until = np.where(brake, step + self._brake_steps, self._brake_until)
            self._cut_in_until = np.where(cut, step + self._cut_in_window_steps,
                                          self._cut_in_until)
            self.rogue_brake_count += int(brake.sum())
            self._brake_max = max(self._brake_max, step + self._brake_steps)
            self._cut_in_max = max(self._cut_in_max, step + self._cut_in_window_steps)
        if step < self._cut_in_max:
            # Eligible as for a lane change (those that just started one are not idle).
            trying = (self.speed >= cfg.lane_change_min_speed) & (self._lc_end == _IDLE)
            trying &= step >= brake_until
            trying &= step < self._cut_in_until
            if trying.any():
                v, delay, gap = self.speed, self._decision_dt, cfg.rogue_cut_in_gap
                follow_v = self._v_all[fi]
                room = (lead_gap >= gap + _stopping_gap(v, lead_v, cfg, delay)) & (
                    follow_gap >= gap + _stopping_gap(follow_v, v, cfg, delay))
                blocked = ~(clear[0] & clear[1])
                candidate = trying & adjacent & blocked & room
                pick = np.where(candidate, u[2:], -1.0).argmax(axis=0)
                go = candidate[pick, self._rows]
                if go.any():
                    self._begin_change(go, pick, cfg.rogue_cut_in_duration)
                    self._cut_in_until = np.where(go, 0, self._cut_in_until)
                    self.rogue_cut_in_count += int(go.sum())
        if step < self._brake_max:
            braking = step < self._brake_until
            return np.where(braking, np.minimum(acc, -cfg.rogue_brake_decel), acc)
        return acc
