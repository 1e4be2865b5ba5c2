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

Cost: with a dozen cars a numpy call (about 1 us whatever its size) costs more than the
arithmetic of a car in Python, so the untracked cycle runs per car on Python floats; numpy
only turns the rows into lists and projects the velocities (a full complex product, which
numpy fuses and Python cannot round alike). Every number is the one the array expressions
give (real-by-complex products, sums, ``%``, floor: numpy rounds them as Python does).
Road geometry (point, normal, curvature) comes from a table sampled every 0.25 m along the
exact reference line and interpolated linearly (position error below 0.1 mm), and the
circumradius from a per-lane table sampled every metre, because one call of the exact
spline (about 14 us) costs a quarter of the budget of a cycle. The output dataclasses are
filled through their instance dict (see ``_fast_constructor``). Measured on 12 cars: about
30 us per cycle untracked (was 50 with one array expression per step), about 0.4 ms with
tracking (filterpy, per car).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from filterpy.kalman import KalmanFilter
from numpy.typing import NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.stack.highway.perception_kernel import (
    BOUNDARY,
    FAULTY,
    SOUND,
    measure_batch,
    select_batch,
)
from sdc_gym.stack.highway.world_model import NO_CAR, LaneView, TrackedCar, WorldModel

FloatArray = NDArray[np.float64]

_GEOMETRY_STEP = 0.25  # m between samples of the road geometry table
_RADIUS_STEP = 1.0  # m between samples of the circumradius table
_MIN_CURVATURE = 1e-9  # 1/m: a circumcircle flatter than this counts as a straight (inf)

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
_TABLES: dict[int, Any] = {}
# The lane index of a car whose d is NaN (numpy's cast of NaN to int64 on x86).
_NAN_LANE = -(2**63)


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

    Tracking (``params.tracking``): one ``filterpy`` :class:`KalmanFilter` per car id with
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
        reference = road.reference
        self._length = float(road.length)
        self._half = 0.5 * self._length
        self._lanes = int(road.lane_count)
        self._lane_width = float(road.lane_width)
        self._inverse_width = 1.0 / self._lane_width
        self._middle = self._lanes // 2

        # Geometry table, complex x + iy: point, right normal, curvature at s = k h
        # (k = 0 .. n; row n = row 0 one loop on), then each row's increment to the next,
        # for linear interpolation.
        n = max(math.ceil(self._length / _GEOMETRY_STEP), 16)
        grid = np.arange(n + 2) * (self._length / n)
        point, normal = reference.position(grid), reference.normal(grid)
        base = np.column_stack([point[:, 0] + 1j * point[:, 1], normal[:, 0] + 1j * normal[:, 1],
                                reference.curvature(grid)])
        self._geometry = np.ascontiguousarray(np.hstack([base[:-1], np.diff(base, axis=0)]).T)
        self._geometry_scale = n / self._length

        # The same table as Python tuples of floats per sample, x and y apart (the
        # curvature is real): px, py, nx, ny, curvature, then their increments. A cycle
        # interpolates it per car in Python floats, which gives the same numbers as the
        # array expression in _lookup (a real times a complex is the two real products,
        # then a sum).
        self._geometry_xy_rows: list[tuple[float, ...]] = [
            (point.real, point.imag, normal.real, normal.imag, bend.real,
             point_step.real, point_step.imag, normal_step.real, normal_step.imag,
             bend_step.real)
            for point, normal, bend, point_step, normal_step, bend_step
            in self._geometry.T.tolist()]

        # Circumradius table: the reciprocal (curvature of the circumcircle), per lane.
        m = max(math.ceil(self._length / _RADIUS_STEP), 16)
        grid = np.arange(m + 1) * (self._length / m)
        self._radius_scale = m / self._length
        self._circle_curvature = [
            self._circumcurvature(grid, float(road.lane_center(lane))).tolist()
            for lane in range(self._lanes)
        ]

        # Lane search: a car's key is its lane (floor(d / width)), plus _behind when it is
        # behind the ego; row k of the search holds lane k ahead, row lanes + k lane k
        # behind. _behind > lanes + 1 keeps off-road keys (-1, lanes) out of every row.
        self._behind = 2 * self._lanes + 2
        self._key_rows = {key: row for row, key in enumerate(
            [*range(self._lanes), *(self._behind + lane for lane in range(self._lanes))])}
        self._empty_views = tuple(LaneView(lane) for lane in range(self._lanes))

        # Kalman filter constants (state s, d, s rate, d rate; all four measured).
        position_var = p.measurement_noise_position ** 2
        velocity_var = p.measurement_noise_velocity ** 2
        self._measurement_cov = np.diag([position_var, position_var, velocity_var,
                                         velocity_var])
        self._transition_cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        self.reset()

    # ------------------------------------------------------------------ public API
    def reset(self) -> None:
        """Forget every track (start of an episode)."""
        self._filters: dict[int, KalmanFilter] = {}
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
        table = self._circle_curvature[lane]
        u = (s % self._length) * self._radius_scale
        i = min(int(u), len(table) - 2)
        low = table[i]
        curvature = low + (u - i) * (table[i + 1] - low)
        return 1.0 / curvature if curvature > _MIN_CURVATURE else math.inf

    # ------------------------------------------------------------------ helpers
    def _measure(self, observation: dict[str, Any]) -> tuple[list[Any], ...]:
        """Steps 1 to 3 for the sensed rows: ids, s, d, speed, d rate, reference curvature
        (the last only with tracking on), as Python lists.

        Per car in Python floats (with 12 cars, cheaper than a dozen numpy calls) and
        bit-identical to the array version: the geometry lookup and the fault test use
        only real-by-complex products and sums, which numpy rounds alike (and which are
        computed here on the x and y parts: the same products and sums); the velocity
        projection (a full complex product, which numpy fuses) stays one numpy call.
        """
        p = self.params
        fusion = observation["sensor_fusion"]
        if not (type(fusion) is np.ndarray and fusion.dtype.kind == "f"):
            fusion = np.asarray(fusion, np.float64)
        rows = fusion.tolist()  # id, x, y, vx, vy, s, d
        mask = observation.get("sensor_fusion_mask")
        if mask is not None:
            rows = list(itertools.compress(rows, np.asarray(mask).tolist()))
        length, scale, table = self._length, self._geometry_scale, self._geometry_xy_rows
        tracking = p.tracking
        tolerance = p.fault_tolerance
        # The fault test: Python's |z| against the tolerance, except within rounding of the
        # boundary, where numpy's own modulus decides (as the array version did). A squared
        # miss clearly inside the tolerance skips it (no |z|: the usual, sound car).
        below, above = tolerance * (1.0 - 1e-9), tolerance * (1.0 + 1e-9)
        sound_sq = (tolerance * (1.0 - 1e-6)) ** 2
        ids: list[int] = []
        s_out: list[float] = []
        d_out: list[float] = []
        velocity: list[complex] = []
        normals: list[complex] = []
        curvature: list[float] = []
        faulty: list[int] = []
        for index, (car_id, x, y, vx, vy, s, d) in enumerate(rows):
            s %= length
            u = s * scale
            i = int(u)  # s < length: at most n, the table's last row
            px, py, nx, ny, bend, px_step, py_step, nx_step, ny_step, bend_step = table[i]
            t = u - i
            nx += t * nx_step
            ny += t * ny_step
            # (s, d) as a point, minus the sensed (x, y).
            miss_x = px + t * px_step + d * nx - x
            miss_y = py + t * py_step + d * ny - y
            if miss_x * miss_x + miss_y * miss_y > sound_sq or (s == 0.0 and d == 0.0):
                miss = complex(miss_x, miss_y)
                if (abs(miss) > above or (s == 0.0 and d == 0.0) or (
                        not abs(miss) <= below and np.abs(np.array([miss]))[0] > tolerance)):
                    faulty.append(index)
            ids.append(int(car_id))
            s_out.append(s)
            d_out.append(d)
            velocity.append(complex(vx, vy))
            normals.append(complex(nx, ny))
            if tracking:
                curvature.append(bend + t * bend_step)
        if faulty:
            xy = np.array([rows[index][1:3] for index in faulty], dtype=np.float64)
            s_fixed, d_fixed = self.road.reference.to_frenet(xy)
            for index, s, d in zip(faulty, np.mod(s_fixed, length).tolist(), d_fixed.tolist(),
                                   strict=True):
                u = s * scale
                i = int(u)
                _, _, nx, ny, bend, _, _, nx_step, ny_step, bend_step = table[i]
                t = u - i
                s_out[index] = s
                d_out[index] = d
                normals[index] = complex(nx + t * nx_step, ny + t * ny_step)
                if tracking:
                    curvature[index] = bend + t * bend_step
        # (vx + i vy) conj(n) with n = ty - i tx: real = normal speed, imag = tangential.
        projected = np.array(velocity, np.complex128) * np.array(normals, np.complex128).conj()
        return (ids, s_out, d_out, projected.imag.tolist(), projected.real.tolist(),
                curvature)

    def _select(self, ids: list[int], s: list[float], d: list[float], speed: list[float],
                d_rate: list[float], ego_s: float, ego_d: float,
                ego_lane: int) -> tuple[tuple[LaneView, ...], tuple[TrackedCar, ...]]:
        """Step 5 without the lane preference: the lane views and the perceived cars.

        The nearest car of each search row is the first of the smallest distances (the
        order of the rows given), as numpy's argmin over the rows used to pick it."""
        p = self.params
        length, half, lanes = self._length, self._half, self._lanes
        inverse_width, key_rows, behind = self._inverse_width, self._key_rows, self._behind
        shift = half - ego_s
        best = [math.inf] * (2 * lanes)
        nearest = [0] * (2 * lanes)
        ghosting = p.ghosting
        lateral, ghost_ahead, ghost_behind = p.ghost_lateral, p.ghost_ahead, -p.ghost_behind
        floor = math.floor
        gaps, lane_index = [], []
        for k, (car_s, car_d) in enumerate(zip(s, d, strict=True)):
            gap = (car_s + shift) % length - half
            distance = abs(gap)
            try:
                lane = floor(car_d * inverse_width)
            except (ValueError, OverflowError):  # d not finite
                lane = car_d * inverse_width
            row = key_rows.get(lane + behind if gap < 0 else lane)
            if row is not None and distance < best[row]:
                best[row] = distance
                nearest[row] = k
            # Ghosting: an adjacent car drifting close to the ego also counts as the ego
            # lane's car ahead (it is in no other row of the ego lane).
            if (ghosting and abs(car_d - ego_d) < lateral and lane != ego_lane
                    and abs(lane - ego_lane) == 1 and 0 <= lane < lanes
                    and ghost_behind <= gap <= ghost_ahead and distance < best[ego_lane]):
                best[ego_lane] = distance
                nearest[ego_lane] = k
            if not -1 <= lane <= lanes:
                lane = -1 if lane < 0 else lanes if lane > lanes else _NAN_LANE
            gaps.append(gap)
            lane_index.append(lane)
        cars = tuple(map(_new_car, ids, s, d, speed, d_rate, lane_index, gaps))

        reach = p.sensing_range
        views = []
        for k in range(lanes):
            ahead_gap, behind_gap = best[k], best[k + lanes]
            if ahead_gap <= reach:
                ahead = nearest[k]
                ahead_speed, ahead_id = speed[ahead], ids[ahead]
            else:
                ahead_gap, ahead_speed, ahead_id = math.inf, 0.0, NO_CAR
            if behind_gap <= reach:
                behind_car = nearest[k + lanes]
                behind_speed, behind_id = speed[behind_car], ids[behind_car]
            else:
                behind_gap, behind_speed, behind_id = math.inf, 0.0, NO_CAR
            views.append(_new_lane_view(k, ahead_gap, ahead_speed, ahead_id,
                                        behind_gap, behind_speed, behind_id))
        return tuple(views), cars

    def _lookup(self, s: FloatArray) -> NDArray[np.complex128]:
        """Point x + iy, right normal and curvature (3, n) of the road at wrapped ``s``."""
        u = s * self._geometry_scale
        index = u.astype(np.intp)  # s < length: at most n, the table's last row
        rows = np.take(self._geometry, index, axis=1)
        return rows[:3] + (u - index) * rows[3:]

    def _circumcurvature(self, s: FloatArray, d: float) -> FloatArray:
        """1 / circumradius through the points at s, s + spacing, s + 2 spacing, offset d."""
        reference = self.road.reference
        spacing = self.params.radius_spacing
        offset = np.full(len(s), d)
        a = reference.to_xy(s, offset)
        b = reference.to_xy(s + spacing, offset)
        c = reference.to_xy(s + 2.0 * spacing, offset)
        ab, bc, ca = b - a, c - b, a - c
        cross = np.abs(ab[:, 0] * ca[:, 1] - ab[:, 1] * ca[:, 0])
        sides = np.hypot(*ab.T) * np.hypot(*bc.T) * np.hypot(*ca.T)
        return 2.0 * cross / sides

    def _preferred_lane(self, views: tuple[LaneView, ...], ego_lane: int) -> int:
        """The lane whose car ahead is furthest; ties: the middle lane, then the ego's."""
        gaps = [view.ahead_gap for view in views]
        best = max(gaps)
        if gaps[self._middle] == best:
            return self._middle
        if gaps[ego_lane] == best:
            return ego_lane
        return gaps.index(best)

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

    def _new_filter(self, z: FloatArray) -> KalmanFilter:
        kf = KalmanFilter(dim_x=4, dim_z=4)
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


def perceive_all(perceptions: list[Perception], ego: NDArray, fusion: NDArray,
                 present: NDArray[np.bool_], times: NDArray[np.float64], *,
                 with_cars: bool = True) -> list[WorldModel]:
    """One perception cycle of a batch of envs (one :class:`Perception`, with its tracks,
    per env; they share the road and parameters): ``ego`` ``(envs, 6)`` and ``fusion``
    ``(envs, cars, 7)`` as observed, ``present`` the rows sensed. The per-car work runs in
    the compiled kernels of :mod:`sdc_gym.stack.highway.perception_kernel` for every env
    at once. ``with_cars=False`` leaves ``WorldModel.cars`` empty (layers that read only the
    lane views, the ego and the road: the executor, the shield, the features)."""
    first = perceptions[0]
    p = first.params
    envs, cars = fusion.shape[:2]
    lanes, length = first._lanes, first._length
    table = _TABLES.get(id(first._geometry))
    if table is None or table[0] is not first._geometry:
        table = (first._geometry, np.array(first._geometry_xy_rows))
        _TABLES[id(first._geometry)] = table
    rows = table[1]
    fusion64 = np.ascontiguousarray(fusion, dtype=np.float64)
    shape = (envs, cars)
    s, d, nx, ny, bend = (np.zeros(shape) for _ in range(5))
    fault = np.zeros(shape, dtype=np.int64)
    count = np.zeros(envs, dtype=np.int64)
    xy, velocity, miss = (np.zeros((envs, cars, 2)) for _ in range(3))
    ids = np.zeros(shape, dtype=np.int64)
    measure_batch(fusion64, np.ascontiguousarray(present), rows, length,
                  first._geometry_scale, p.fault_tolerance, s, d, nx, ny, bend, fault, count,
                  xy, velocity, miss, ids)
    scale = first._geometry_scale
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
    # (vx + i vy) conj(n) with n = ty - i tx: real = normal speed, imag = tangential.
    projected = (velocity[..., 0] + 1j * velocity[..., 1]) * (nx + 1j * ny).conj()
    speed, d_rate = projected.imag, projected.real
    ego64 = ego.astype(np.float64)
    ego_s = ego64[:, 2] % length
    ego_d = ego64[:, 3]
    ego_lane = np.minimum(np.maximum(np.floor(ego_d * first._inverse_width), 0),
                          lanes - 1).astype(np.int64)
    views = np.zeros((envs, lanes, 6))
    car_lane = np.zeros(shape, dtype=np.int64)
    car_gap = np.zeros(shape)
    select_batch(s, d, speed, ids, count, ego_s, ego_d, ego_lane, length, lanes,
                 first._inverse_width, p.ghosting, p.ghost_lateral, p.ghost_ahead,
                 p.ghost_behind, p.sensing_range, views, car_lane, car_gap)
    worlds = []
    for env, perception in enumerate(perceptions):
        n = int(count[env])
        e_s, e_d, e_speed = float(ego_s[env]), float(ego_d[env]), float(ego64[env, 5])
        lane = int(ego_lane[env])
        if perception.params.tracking:
            tracked = perception._track(float(times[env]), ids[env, :n], s[env, :n],
                                        d[env, :n], speed[env, :n], d_rate[env, :n],
                                        bend[env, :n])
            columns = [column.tolist() for column in tracked]
            if columns[1]:
                lane_views, cars_seen = perception._select(*columns, e_s, e_d, lane)
            else:
                lane_views, cars_seen = perception._empty_views, ()
        else:
            cars_seen = () if not with_cars else tuple(map(
                _new_car, ids[env, :n].tolist(), s[env, :n].tolist(),
                                  d[env, :n].tolist(), speed[env, :n].tolist(),
                                  d_rate[env, :n].tolist(), car_lane[env, :n].tolist(),
                                  car_gap[env, :n].tolist()))
            lane_views = tuple(
                _new_lane_view(k, v[0], v[1], int(v[2]), v[3], v[4], int(v[5]))
                for k, v in enumerate(views[env].tolist())) if n else perception._empty_views
        worlds.append(_new_world(float(times[env]), e_s, e_d, e_speed, lane, lanes,
                                 perception._lane_width, lane_views, cars_seen,
                                 perception._preferred_lane(lane_views, lane),
                                 perception.road_radius(e_s, lane)))
    return worlds
