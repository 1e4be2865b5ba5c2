"""The highway planner's sensor processing: an observation in, a :class:`WorldModel` out.

Layer 1 of the seed's planner. Every planning cycle it

1. reads the sensed rows ``[id, x, y, vx, vy, s, d]`` of ``sensor_fusion`` (rows whose
   ``sensor_fusion_mask`` is 0 are dropouts and are ignored);
2. repairs faulty Frenet coordinates: a row reading ``s == d == 0`` (the original
   simulator's quirk near the end of the loop), or whose (s, d) lie more than
   ``fault_tolerance`` metres from its (x, y), gets s, d recomputed from x, y with the
   map's exact :meth:`~sdc_gym.geometry.reference_line.ReferenceLine.to_frenet` (the seed
   measures those cars by x, y distance instead);
3. projects each car's velocity on the road: ``speed`` along the tangent (m/s of lane),
   ``d_rate`` along the right normal;
4. optionally (``tracking``) runs a constant-velocity Kalman filter per car id in Frenet
   coordinates and uses its estimates instead (see :class:`Perception`);
5. per lane, finds the nearest car ahead and behind by the modular s difference
   (centre to centre, within ``sensing_range``), optionally "ghosts" adjacent cars that
   drift close to the ego into the ego lane's car ahead (the seed's Conservative style),
   picks the preferred lane and the circumradius of the ego lane ahead.

Cost: the per-car steps are compiled kernels over a batch of envs
(:mod:`sdc_gym.stack.highway.perception_kernel`, :func:`sense_batch`); numpy projects the
velocities (a full complex product, which numpy fuses and a per-element product cannot
round alike). Every number is the one the per-car arithmetic on floats gives. Road
geometry (point, normal, curvature) comes from a table sampled every 0.25 m along the
exact reference line and interpolated linearly (position error below 0.1 mm), and the
circumradius from a per-lane table sampled every metre, because one call of the exact
spline (about 14 us) costs more than a cycle. The world model's dataclasses are filled
through their instance dict (see ``_fast_constructor``); the batched behavior env reads
the arrays (:class:`SensedBatch`) and builds none. Tracking (filterpy) runs per car in
Python.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.stack.highway.kalman import FixedOrderKalmanFilter
from sdc_gym.stack.highway.perception_kernel import (
    BOUNDARY,
    FAULTY,
    SOUND,
    ego_frenet,
    measure_batch,
    road_radius,
    select_batch,
    summarize_batch,
)
from sdc_gym.stack.highway.world_model import LaneView, TrackedCar, WorldModel

FloatArray = NDArray[np.float64]

_GEOMETRY_STEP = 0.25  # m between samples of the road geometry table
_RADIUS_STEP = 1.0  # m between samples of the circumradius table

# The world model's classes are plain frozen dataclasses: their __init__ sets each field
# with object.__setattr__, which for 12 cars, 3 lane views and the model costs about a
# fifth of a cycle. _fast_constructor builds an equivalent constructor (positional
# arguments in field order) that fills the instance dict in one go: the same objects
# (equality, hash, repr, pickling and frozenness are unchanged). A class with slots, a
# __post_init__ or non-init fields keeps its own constructor.
def _fast_constructor(cls: type) -> Callable[..., Any]:
    names = [field.name for field in fields(cls)]
    if ("__slots__" in vars(cls) or hasattr(cls, "__post_init__")
            or not all(field.init for field in fields(cls))
            or not all(name.isidentifier() for name in names)):
        return cls
    entries = ", ".join(f"{name!r}: {name}" for name in names)
    source = (f"def make({', '.join(names)}):\n"
              f"    made = new(cls)\n"
              f"    set_dict(made, '__dict__', {{{entries}}})\n"
              f"    return made\n")
    namespace: dict[str, Any] = {"new": object.__new__, "set_dict": object.__setattr__,
                                 "cls": cls}
    exec(source, namespace)
    make = namespace["make"]
    make.__doc__ = f"``{cls.__name__}(*fields)``, about twice as fast."
    return make


_new_car = _fast_constructor(TrackedCar)
_new_lane_view = _fast_constructor(LaneView)
_new_world = _fast_constructor(WorldModel)


@dataclass(frozen=True)
class RoadTables:
    """A road's lookup tables for perception, built once per road and radius spacing and
    shared read-only by every :class:`Perception` of it (a batch of 1,024 envs used to hold
    1,024 copies, about 4.9 MB each on the default loop).

    - ``geometry`` (6, n + 1) complex: point x + iy, right normal and curvature at
      s = k h (k = 0 .. n; row n = row 0 one loop on), then each row's increment to the
      next, for linear interpolation; ``geometry_scale`` = n / length.
    - ``geometry_xy_rows`` (n + 1, 10): the same per sample as real numbers, x and y apart
      (px, py, nx, ny, curvature, then their increments). A cycle interpolates it per car in
      Python floats, which gives the same numbers as the complex expression in
      ``Perception._lookup`` (a real times a complex is the two real products, then a sum).
    - ``circle_curvature`` (lanes, m + 1): 1 / circumradius of each lane's centre line
      through s, s + spacing, s + 2 spacing on a 1 m grid; ``radius_scale`` = m / length.
    """

    geometry: NDArray[np.complex128]
    geometry_scale: float
    geometry_xy_rows: FloatArray
    circle_curvature: FloatArray
    radius_scale: float


_ROAD_TABLES: dict[tuple[int, float], tuple[weakref.ref[HighwayMap], RoadTables]] = {}


def road_tables(road: HighwayMap, radius_spacing: float) -> RoadTables:
    """The :class:`RoadTables` of ``road`` (cached while the road object lives)."""
    key = (id(road), float(radius_spacing))
    cached = _ROAD_TABLES.get(key)
    if cached is not None and cached[0]() is road:
        return cached[1]
    tables = _build_road_tables(road, float(radius_spacing))
    _ROAD_TABLES[key] = (weakref.ref(road, lambda _: _ROAD_TABLES.pop(key, None)), tables)
    return tables


def _build_road_tables(road: HighwayMap, spacing: float) -> RoadTables:
    reference, length = road.reference, float(road.length)
    n = max(math.ceil(length / _GEOMETRY_STEP), 16)
    grid = np.arange(n + 2) * (length / n)
    point, normal = reference.position(grid), reference.normal(grid)
    base = np.column_stack([point[:, 0] + 1j * point[:, 1], normal[:, 0] + 1j * normal[:, 1],
                            reference.curvature(grid)])
    geometry = np.ascontiguousarray(np.hstack([base[:-1], np.diff(base, axis=0)]).T)
    rows = geometry.T
    xy_rows = np.ascontiguousarray(np.column_stack([
        rows[:, 0].real, rows[:, 0].imag, rows[:, 1].real, rows[:, 1].imag, rows[:, 2].real,
        rows[:, 3].real, rows[:, 3].imag, rows[:, 4].real, rows[:, 4].imag, rows[:, 5].real]))
    m = max(math.ceil(length / _RADIUS_STEP), 16)
    radius_grid = np.arange(m + 1) * (length / m)
    circle = np.ascontiguousarray(np.stack([
        _circumcurvature(reference, radius_grid, float(road.lane_center(lane)), spacing)
        for lane in range(int(road.lane_count))]))
    for table in (geometry, xy_rows, circle):
        table.setflags(write=False)  # shared by every Perception of the road
    return RoadTables(geometry, n / length, xy_rows, circle, m / length)


def _circumcurvature(reference: Any, s: FloatArray, d: float, spacing: float) -> FloatArray:
    """1 / circumradius through the points at s, s + spacing, s + 2 spacing, offset d."""
    offset = np.full(len(s), d)
    a = reference.to_xy(s, offset)
    b = reference.to_xy(s + spacing, offset)
    c = reference.to_xy(s + 2.0 * spacing, offset)
    ab, bc, ca = b - a, c - b, a - c
    cross = np.abs(ab[:, 0] * ca[:, 1] - ab[:, 1] * ca[:, 0])
    sides = np.hypot(*ab.T) * np.hypot(*bc.T) * np.hypot(*ca.T)
    return 2.0 * cross / sides


@dataclass(frozen=True)
class PerceptionParameters:
    """Tuning of :class:`Perception` (units in the comments; defaults from the seed/spec)."""

    sensing_range: float = 200.0      # m ahead and behind (s) in which cars fill the lanes
    ghosting: bool = False            # the Conservative style turns it on
    ghost_ahead: float = 20.0         # m: adjacent cars up to this far ahead are ghosted ...
    ghost_behind: float = 10.0        # m: ... or this far behind (centre to centre) ...
    ghost_lateral: float = 3.26       # m: ... when |d - ego d| is below this
    fault_tolerance: float = 5.0      # m: (s, d) this far from (x, y) is recomputed from x, y
    tracking: bool = False            # Kalman-filter every car by id (noisy sensors)
    measurement_noise_position: float = 1.0  # m, std of the sensed s and d
    measurement_noise_velocity: float = 1.0  # m/s, std of the sensed velocity components
    process_noise: float = 3.0        # m/s^2, std of the unmodelled acceleration (s and d)
    track_timeout: float = 0.5        # s without a sighting before a track is dropped
    track_gate: float = 15.0          # m: a sighting this far from its track restarts it
    radius_spacing: float = 60.0      # m: circumradius through s, s + this, s + twice this

    def __post_init__(self) -> None:
        for name in ("sensing_range", "ghost_ahead", "ghost_behind", "ghost_lateral",
                     "fault_tolerance", "measurement_noise_position",
                     "measurement_noise_velocity", "track_timeout", "track_gate",
                     "radius_spacing"):
            if not getattr(self, name) > 0:
                raise ValueError(f"perception {name} must be > 0, got {getattr(self, name)!r}")
        if not self.process_noise >= 0:
            raise ValueError(f"perception process_noise must be >= 0, got {self.process_noise!r}")


class Perception:
    """Turns ``HighwayLoop-v0`` observations into :class:`WorldModel` s.

    Args:
        road: the env's map (``env.unwrapped.road``).
        params: tuning; defaults to :class:`PerceptionParameters`'s.

    Tracking (``params.tracking``): one ``filterpy`` Kalman filter per car id
    (:class:`~sdc_gym.stack.highway.kalman.FixedOrderKalmanFilter`) with
    state ``(s, d, s rate, d rate)`` and a constant-velocity model (white-noise
    acceleration of std ``process_noise`` on both axes). Each sighting measures all four:
    s and d as sensed (or repaired), the s rate as the tangential speed divided by
    ``1 + curvature * d`` (a lane right of a left bend is longer than the centre line) and
    the d rate as the normal speed. The s measurement is unwrapped next to the track's
    estimate (``estimate + modular difference``) and the estimate folded back into
    ``[0, length)`` after every step, so a car crossing the seam keeps its track. A track
    starts on the first sighting of an id, is predicted every cycle by the time elapsed
    since the last one, is updated when its id is sensed (a dropout is predict-only), is
    restarted when a sighting lands more than ``track_gate`` from it (a recycled car keeps
    its slot's id, as in the original, and reappears far from where it left), and is
    dropped when its id has not been sensed for ``track_timeout`` seconds. A ``time``
    earlier than the previous call's starts afresh (a new episode).
    The world model then holds every live track, sensed this cycle or not.

    Lane views use centre-to-centre gaps within ``sensing_range``; ``cars`` lists every
    sensed (or tracked) car whatever its distance. A ghosted car (``ghosting``: adjacent
    lane, ``-ghost_behind <= gap <= ghost_ahead``, ``|d - ego d| < ghost_lateral``) becomes
    the ego lane's car ahead when it is nearer than the real one, with ``ahead_gap`` its
    distance ``|gap|`` (a ghost alongside or slightly behind reads as a car just ahead,
    which makes the seed's braking rule stop hard). It stays in its own lane's view too.
    The ego lane is ``floor(ego d / lane width)`` clipped to the road, so
    ``lanes[ego_lane]`` always exists.
    """

    def __init__(self, road: HighwayMap, params: PerceptionParameters | None = None) -> None:
        self.road = road
        self.params = params or PerceptionParameters()
        p = self.params
        self._length = float(road.length)
        self._half = 0.5 * self._length
        self._lanes = int(road.lane_count)
        self._lane_width = float(road.lane_width)
        self._inverse_width = 1.0 / self._lane_width
        self._middle = self._lanes // 2

        tables = road_tables(road, p.radius_spacing)
        self._geometry = tables.geometry
        self._geometry_scale = tables.geometry_scale
        self._geometry_xy_rows = tables.geometry_xy_rows
        self._radius_scale = tables.radius_scale
        self._circle_curvature = tables.circle_curvature

        self._empty_views = tuple(LaneView(lane) for lane in range(self._lanes))

        # Kalman filter constants (state s, d, s rate, d rate; all four measured).
        position_var = p.measurement_noise_position ** 2
        velocity_var = p.measurement_noise_velocity ** 2
        self._measurement_cov = np.diag([position_var, position_var, velocity_var,
                                         velocity_var])
        self._transition_cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        self._cycle_buffers: dict[tuple[int, int], Any] = {}
        self.reset()

    # ------------------------------------------------------------------ public API
    def reset(self) -> None:
        """Forget every track (start of an episode)."""
        self._filters: dict[int, FixedOrderKalmanFilter] = {}
        self._last_seen: dict[int, float] = {}
        self._last_time: float | None = None

    @property
    def tracked_ids(self) -> tuple[int, ...]:
        """Ids of the live tracks (empty when tracking is off)."""
        return tuple(self._filters)

    def perceive(self, observation: dict[str, Any], time: float) -> WorldModel:
        """One cycle: the world model of ``observation`` at ``time`` (s since the start)."""
        ego = np.asarray(observation["ego"])
        fusion = np.asarray(observation["sensor_fusion"])
        mask = observation.get("sensor_fusion_mask")
        present = (np.ones(len(fusion), dtype=bool) if mask is None
                   else np.asarray(mask).astype(bool))
        return perceive_all([self], ego[None], fusion[None], present[None],
                            np.array([float(time)]))[0]

    def road_radius(self, s: float, lane: int) -> float:
        """Circumradius (m) of ``lane``'s centre line through s, s + spacing, s + 2 spacing.

        ``inf`` where the three points are collinear. Interpolated (linearly in 1 / radius)
        from a 1 m table of the exact values, points from ``reference.to_xy``: within 0.2 %
        of the exact radius where it matters (below 5 km)."""
        return road_radius(self._circle_curvature, self._radius_scale, self._length,
                           float(s), int(lane))

    # ------------------------------------------------------------------ helpers
    def _lookup(self, s: FloatArray) -> NDArray[np.complex128]:
        """Point x + iy, right normal and curvature (3, n) of the road at wrapped ``s``."""
        u = s * self._geometry_scale
        index = u.astype(np.intp)  # s < length: at most n, the table's last row
        rows = np.take(self._geometry, index, axis=1)
        return rows[:3] + (u - index) * rows[3:]

    def _buffers(self, envs: int, cars: int) -> tuple[SensedBatch, tuple[NDArray, ...]]:
        """The arrays a cycle of ``envs`` envs of ``cars`` rows fills (kept: a cycle's
        results are read before the next cycle)."""
        key = (envs, cars)
        buffers = self._cycle_buffers.get(key)
        if buffers is None:
            shape = (envs, cars)
            scratch = (np.zeros(shape), np.zeros(shape), np.zeros(shape),
                       np.zeros(shape, dtype=np.int64), *(np.zeros((envs, cars, 2))
                                                          for _ in range(3)))
            buffers = self._cycle_buffers[key] = (SensedBatch(envs, cars, self._lanes),
                                                  scratch)
        return buffers

    def _transition(self, dt: float) -> tuple[FloatArray, FloatArray]:
        """State transition F and process noise Q of the constant-velocity model."""
        cached = self._transition_cache.get(dt)
        if cached is None:
            transition = np.eye(4)
            transition[0, 2] = transition[1, 3] = dt
            variance = self.params.process_noise ** 2
            noise = np.zeros((4, 4))
            noise[[0, 1], [0, 1]] = 0.25 * dt ** 4 * variance
            noise[[0, 1, 2, 3], [2, 3, 0, 1]] = 0.5 * dt ** 3 * variance
            noise[[2, 3], [2, 3]] = dt ** 2 * variance
            if len(self._transition_cache) > 64:
                self._transition_cache.clear()
            cached = self._transition_cache[dt] = (transition, noise)
        return cached

    def _new_filter(self, z: FloatArray) -> FixedOrderKalmanFilter:
        kf = FixedOrderKalmanFilter(dim_x=4, dim_z=4)
        kf.x = z.reshape(4, 1).copy()
        kf.P = self._measurement_cov.copy()
        kf.R = self._measurement_cov
        kf.H = np.eye(4)
        return kf

    def _track(
        self, time: float, ids: NDArray[np.int64], s: FloatArray, d: FloatArray,
        speed: FloatArray, d_rate: FloatArray, curvature: FloatArray,
    ) -> tuple[NDArray[np.int64], FloatArray, FloatArray, FloatArray, FloatArray]:
        """Update the per-id Kalman filters; the live tracks' ids, s, d, speed, d rate."""
        p = self.params
        length, half = self._length, self._half
        filters, last_seen = self._filters, self._last_seen
        if self._last_time is not None and time < self._last_time:
            self.reset()
            filters, last_seen = self._filters, self._last_seen
        if self._last_time is not None and time > self._last_time:
            transition, noise = self._transition(time - self._last_time)
            for kf in filters.values():
                kf.predict(F=transition, Q=noise)
                kf.x[0, 0] %= length
        self._last_time = time

        measured = np.column_stack([s, d, speed / (1.0 + curvature * d), d_rate])
        gate = p.track_gate ** 2
        for car_id, z in zip(ids.tolist(), measured, strict=True):
            kf = filters.get(car_id)
            if kf is not None:
                state = kf.x
                ds = (z[0] - state[0, 0] + half) % length - half
                if ds * ds + (z[1] - state[1, 0]) ** 2 > gate:
                    kf = None
                else:
                    z[0] = state[0, 0] + ds
                    kf.update(z)
                    kf.x[0, 0] %= length
            if kf is None:
                filters[car_id] = self._new_filter(z)
            last_seen[car_id] = time
        for car_id in [key for key, seen in last_seen.items()
                       if time - seen > p.track_timeout]:
            del filters[car_id], last_seen[car_id]

        if not filters:
            empty = np.zeros(0)
            return np.zeros(0, dtype=np.int64), empty, empty, empty, empty
        states = np.array([kf.x[:, 0] for kf in filters.values()])
        track_s = states[:, 0] % length
        track_d = states[:, 1]
        track_speed = states[:, 2] * (1.0 + self._lookup(track_s)[2].real * track_d)
        return (np.fromiter(filters, dtype=np.int64, count=len(filters)), track_s, track_d,
                track_speed, states[:, 3])


class SensedBatch:
    """One perception cycle of a batch of envs, as arrays (what :func:`sense_batch`
    returns): per env the ego's ``ego_s`` (wrapped), ``ego_d``, ``ego_speed``,
    ``ego_lane``, the lane ``views`` ``(envs, lanes, 6)`` (ahead gap, speed, id, behind
    gap, speed, id), the ``preferred`` lane and the ``road_radius``; the perceived cars
    per env in ``cars(env)``."""

    def __init__(self, envs: int, cars: int, lanes: int) -> None:
        shape = (envs, cars)
        self.ego_s, self.ego_d, self.ego_speed = np.zeros(envs), np.zeros(envs), np.zeros(envs)
        self.ego_lane = np.zeros(envs, dtype=np.int64)
        self.views = np.zeros((envs, lanes, 6))
        self.preferred = np.zeros(envs, dtype=np.int64)
        self.road_radius = np.zeros(envs)
        self.count = np.zeros(envs, dtype=np.int64)
        self.ids = np.zeros(shape, dtype=np.int64)
        self.s, self.d, self.speed, self.d_rate = (np.zeros(shape) for _ in range(4))
        self.car_lane = np.zeros(shape, dtype=np.int64)
        self.car_gap = np.zeros(shape)
        self.tracked: dict[int, tuple[NDArray, ...]] = {}

    ARRAYS = ("ego_s", "ego_d", "ego_speed", "ego_lane", "views", "preferred", "road_radius",
              "count", "ids", "s", "d", "speed", "d_rate", "car_lane", "car_gap")

    def put(self, rows: NDArray[np.intp], part: SensedBatch) -> None:
        """Write ``part`` (a cycle of the envs ``rows``) into these envs' entries."""
        for name in self.ARRAYS:
            getattr(self, name)[rows] = getattr(part, name)
        for env in rows.tolist():
            self.tracked.pop(env, None)
        for index, columns in part.tracked.items():
            self.tracked[int(rows[index])] = columns

    def cars(self, env: int) -> tuple[TrackedCar, ...]:
        """Env ``env``'s perceived cars (its live tracks, with tracking on)."""
        columns = self.tracked.get(env)
        if columns is None:
            n = int(self.count[env])
            columns = (self.ids[env, :n], self.s[env, :n], self.d[env, :n],
                       self.speed[env, :n], self.d_rate[env, :n], self.car_lane[env, :n],
                       self.car_gap[env, :n])
        return tuple(map(_new_car, *(column.tolist() for column in columns)))


def sense_batch(perceptions: list[Perception], ego: NDArray, fusion: NDArray,
                present: NDArray[np.bool_], times: NDArray[np.float64]) -> SensedBatch:
    """One perception cycle of a batch of envs (one :class:`Perception`, with its tracks,
    per env; they share the road and parameters): ``ego`` ``(envs, 6)`` and ``fusion``
    ``(envs, cars, 7)`` as observed, ``present`` the rows sensed. The per-car work runs in
    the compiled kernels of :mod:`sdc_gym.stack.highway.perception_kernel` for every env
    at once."""
    first = perceptions[0]
    p = first.params
    envs, cars = fusion.shape[:2]
    lanes, length = first._lanes, first._length
    out, scratch = first._buffers(envs, cars)
    s, d = out.s, out.d
    nx, ny, bend, fault, xy, velocity, miss = scratch
    # Read-only either way (the sensors' shared all-present mask is): one signature.
    present = np.ascontiguousarray(present).view()
    present.flags.writeable = False
    measure_batch(np.ascontiguousarray(fusion, dtype=np.float64), present,
                  first._geometry_xy_rows, length, first._geometry_scale, p.fault_tolerance,
                  s, d, nx, ny, bend, fault, out.count, xy, velocity, miss, out.ids)
    if (fault != SOUND).any():
        _repair_faults(first, fault, out.count, miss, xy, s, d, nx, ny, bend)
    # (vx + i vy) conj(n) with n = ty - i tx: real = normal speed, imag = tangential.
    projected = (velocity[..., 0] + 1j * velocity[..., 1]) * (nx + 1j * ny).conj()
    out.speed[:], out.d_rate[:] = projected.imag, projected.real
    ego_frenet(np.ascontiguousarray(ego, dtype=np.float64), length, first._inverse_width, lanes,
               out.ego_s, out.ego_d, out.ego_speed, out.ego_lane)
    select_batch(s, d, out.speed, out.ids, out.count, out.ego_s, out.ego_d, out.ego_lane,
                 length, lanes, first._inverse_width, p.ghosting, p.ghost_lateral,
                 p.ghost_ahead, p.ghost_behind, p.sensing_range, out.views, out.car_lane,
                 out.car_gap)
    out.tracked.clear()
    if p.tracking:
        for env, perception in enumerate(perceptions):
            _tracked_views(perception, out, env, float(times[env]), bend)
    summarize_batch(out.views, out.ego_s, out.ego_lane, first._middle,
                    first._circle_curvature, first._radius_scale, length, out.preferred,
                    out.road_radius)
    return out


def _repair_faults(first: Perception, fault: NDArray, count: NDArray, miss: NDArray,
                   xy: NDArray, s: NDArray, d: NDArray, nx: NDArray, ny: NDArray,
                   bend: NDArray) -> None:
    """Rows whose (s, d) are faulty get them from (x, y) (the exact projection)."""
    p = first.params
    length, scale = first._length, first._geometry_scale
    for env in np.flatnonzero((fault != SOUND).any(axis=1)).tolist():
        verdict = fault[env, :count[env]]
        bad = [k for k in range(int(count[env])) if verdict[k] == FAULTY or (
            verdict[k] == BOUNDARY and np.abs(np.array([complex(*miss[env, k])]))[0]
            > p.fault_tolerance)]
        if not bad:
            continue
        s_fixed, d_fixed = first.road.reference.to_frenet(xy[env, bad])
        for k, s_k, d_k in zip(bad, np.mod(s_fixed, length).tolist(), d_fixed.tolist(),
                               strict=True):
            u = s_k * scale
            i = int(u)
            _, _, nxi, nyi, bi, _, _, nx_step, ny_step, b_step = first._geometry_xy_rows[i]
            t = u - i
            s[env, k], d[env, k] = s_k, d_k
            nx[env, k], ny[env, k] = nxi + t * nx_step, nyi + t * ny_step
            bend[env, k] = bi + t * b_step


def _tracked_views(perception: Perception, out: SensedBatch, env: int, time: float,
                   bend: NDArray) -> None:
    """With tracking: env ``env``'s lane views from its live tracks (the same lane
    search, :func:`~sdc_gym.stack.highway.perception_kernel.select_batch`)."""
    p = perception.params
    n = int(out.count[env])
    ids, s, d, speed, d_rate = perception._track(time, out.ids[env, :n], out.s[env, :n],
                                                 out.d[env, :n], out.speed[env, :n],
                                                 out.d_rate[env, :n], bend[env, :n])
    m = len(ids)
    lane, gap = np.zeros((1, m), dtype=np.int64), np.zeros((1, m))
    views = np.zeros((1, perception._lanes, 6))
    select_batch(s[None], d[None], speed[None], ids[None], np.array([m]), out.ego_s[env:env + 1],
                 out.ego_d[env:env + 1], out.ego_lane[env:env + 1], perception._length,
                 perception._lanes, perception._inverse_width, p.ghosting, p.ghost_lateral,
                 p.ghost_ahead, p.ghost_behind, p.sensing_range, views, lane, gap)
    out.views[env] = views[0]
    out.tracked[env] = (ids, s, d, speed, d_rate, lane[0], gap[0])


def perceive_all(perceptions: list[Perception], ego: NDArray, fusion: NDArray,
                 present: NDArray[np.bool_], times: NDArray[np.float64], *,
                 with_cars: bool = True) -> list[WorldModel]:
    """:func:`sense_batch` as world models (``with_cars=False`` leaves
    ``WorldModel.cars`` empty: layers that read only the lane views, the ego and the road
    need no more)."""
    sensed = sense_batch(perceptions, ego, fusion, present, times)
    return [world_model_of(sensed, env, float(times[env]), perception, with_cars)
            for env, perception in enumerate(perceptions)]


def world_model_of(sensed: SensedBatch, env: int, time: float, perception: Perception,
                   with_cars: bool = False) -> WorldModel:
    """Env ``env``'s :class:`WorldModel` of a perception cycle."""
    if env in sensed.tracked or sensed.count[env]:
        lane_views = tuple(_new_lane_view(k, v[0], v[1], int(v[2]), v[3], v[4], int(v[5]))
                           for k, v in enumerate(sensed.views[env].tolist()))
    else:
        lane_views = perception._empty_views
    return _new_world(time, float(sensed.ego_s[env]), float(sensed.ego_d[env]),
                      float(sensed.ego_speed[env]), int(sensed.ego_lane[env]),
                      perception._lanes, perception._lane_width, lane_views,
                      sensed.cars(env) if with_cars else (), int(sensed.preferred[env]),
                      float(sensed.road_radius[env]))
