"""The traffic of ``envs`` highway envs at once: state as arrays, kernels over them.

:class:`TrafficBatch` owns the constants (config, road tables), the
:class:`~sdc_gym.traffic.state.TrafficState` of every env and each env's generator.
:meth:`TrafficBatch.advance` moves all envs by the same number of physics frames: the
envs whose decision instant falls on a frame decide together (their rows taken, decided by
:func:`~sdc_gym.traffic.decisions.decide`, written back), and the motion between
decisions is evaluated in closed form for all of them
(:meth:`~sdc_gym.traffic.kinematics.TrafficGeometry.segment`). Envs reset at different
times have different phases of the decision period, so one advance may hold several
decision rounds, each for the envs of one phase. Env ``i`` of a batch is exactly a
single env (a batch of one) with the same generator, frame for frame.

Scenarios and road events (:mod:`sdc_gym.traffic.scripted`): ``object_slots`` columns
follow the ``car_count`` cars (parked in random traffic, road objects when an event places
them); an env may start from explicit slots (:meth:`TrafficBatch.reset_slots_at`) and have
a *controller* (a scenario's script, the random road events) called at each of its
decision instants. Until a batch holds such slots (``scripted``), none of this runs.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.traffic import scripted as scripting
from sdc_gym.traffic.config import TrafficConfig, TrafficSamples
from sdc_gym.traffic.decisions import decide
from sdc_gym.traffic.kinematics import RowsOf, TrafficGeometry
from sdc_gym.traffic.placement import reset_row, reset_row_to
from sdc_gym.traffic.state import TrafficState
from sdc_gym.traffic.vehicle_types import VEHICLE_TYPES, spawn_probabilities

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class TrafficBatch:
    """Traffic for ``envs`` envs on one :class:`HighwayMap` (see the module docstring).

    Args:
        road: the highway.
        config: traffic settings (``None``: the defaults).
        envs: number of envs.
        dt: s, the physics step.
        object_slots: columns for road objects after the ``car_count`` cars.
    """

    def __init__(self, road: HighwayMap, config: TrafficConfig | None = None, envs: int = 1,
                 dt: float = 0.02, object_slots: int = 0) -> None:
        if envs < 1:
            raise ValueError(f"envs must be >= 1, got {envs}")
        self.road = road
        self.config = config = config if config is not None else TrafficConfig()
        self.dt = float(dt)
        self.envs = envs
        self.reference = road.reference
        self.geometry = TrafficGeometry(road, config, self.dt)
        self.loop = float(road.length)
        self.half_loop = 0.5 * self.loop
        self.loop_0d = np.array(self.loop)
        self.lanes = int(road.lane_count)
        self.lane_width = float(road.lane_width)
        self.lane_ids = np.arange(self.lanes)
        self.adjacent = np.abs(self.lane_ids[:, None] - self.lane_ids[None, :]) == 1
        self.range = min(config.spawn_range, 0.45 * self.loop)
        # Respawn bands (m from the ego), inside the recycling range even on a short loop.
        bands = []
        for lo, hi in (config.respawn_ahead, config.respawn_behind):
            hi = min(hi, self.range - 10.0)
            bands.append((lo if lo < hi else 0.5 * hi, hi))
        self.respawn_bands = tuple(bands)
        self.decision_dt = config.decision_period * self.dt
        self.type_p = spawn_probabilities(config.vehicle_mix)
        self.rogue_p = config.rogue_rate / 60.0 * self.decision_dt if config.rogue else 0.0
        self.brake_steps = round(config.rogue_brake_duration / self.dt)
        self.cut_in_window_steps = round(config.rogue_cut_in_window / self.dt)
        self.sustain_decisions = math.ceil(config.lane_change_sustain / self.decision_dt - 1e-9)
        self.ego_tsab = 2.0 * math.sqrt(config.idm.a_max * config.idm.b)
        self.ego_half_length = 0.5 * config.ego_length
        # Constants of the decision kernel, shaped for its (envs, lanes, cars) arrays.
        self.lane_column = self.lane_ids[None, :, None]
        self.adjacent_of = self.adjacent.copy()  # [origin lane] -> adjacent lanes
        self.penalty = np.array([np.inf, 0.0])  # [occupies]: 0 where the car is
        self.ego_a_max = np.full((envs, 1), config.idm.a_max)
        self.ego_tsab_column = np.full((envs, 1), self.ego_tsab)
        self.ego_half_column = np.full((envs, 1), self.ego_half_length)
        self.object_slots = int(object_slots)
        self.slots = config.car_count + self.object_slots
        self.state = TrafficState(envs, self.slots, config.lane_change_duration)
        self.rngs: list[np.random.Generator | None] = [None] * envs
        self.controllers: list[scripting.TrafficController | None] = [None] * envs
        self.scripted = self.object_slots > 0
        self._all = np.arange(envs)

    # ------------------------------------------------------------------ helpers
    def ego_lanes(self, ego_d: FloatArray) -> NDArray[np.bool_]:
        """``(envs, lanes)``: the lanes the ego's footprint (its width, across d) touches."""
        half = 0.5 * self.config.ego_width
        low = np.floor((ego_d - half) / self.lane_width)[:, None]
        high = np.floor((ego_d + half) / self.lane_width)[:, None]
        return (self.lane_ids >= low) & (self.lane_ids <= high)

    @property
    def cars(self) -> int:
        return self.state.cars

    # ------------------------------------------------------------------ resets
    def reset_at(self, env: int, rng: np.random.Generator, ego_s: float, ego_d: float,
                 ego_speed: float = 0.0) -> None:
        """Lay out env ``env``'s cars around its ego; all its randomness comes from ``rng``
        (kept for :meth:`advance`)."""
        st = self.state
        if st.cars != self.slots:
            self.state = st = TrafficState(self.envs, self.slots,
                                           self.config.lane_change_duration)
        self.rngs[env] = rng
        self.controllers[env] = None
        if self.object_slots:  # the cars as without object slots, then the slots parked
            scripting.reset_random_row(self, st, env, rng, ego_s, ego_d, ego_speed)
        else:
            reset_row(self, st, env, rng, ego_s, ego_d, ego_speed)
        self._settle_pose(env)

    def reset_slots_at(self, env: int, rng: np.random.Generator, ego_s: float, ego_d: float,
                       ego_speed: float, slots: list[scripting.SlotSpec], *, step: int = 0,
                       respawn_blocked_steps: int = 0,
                       controller: scripting.TrafficController | None = None) -> None:
        """Env ``env`` from explicit slots (one :class:`~sdc_gym.traffic.slots.SlotSpec`
        per column: scenarios, replays) with its ``controller``, its traffic clock at
        ``step`` (a replay continues the recorded one)."""
        self.scripted = True
        self.rngs[env] = rng
        self.controllers[env] = controller
        scripting.reset_slots_row(self, self.state, env, rng, ego_s, ego_d, ego_speed, slots,
                                  step, respawn_blocked_steps)
        self._settle_pose(env)

    def reset_to_at(self, env: int, rng: np.random.Generator, ego_s: float, ego_d: float,
                    ego_speed: float, *, s: ArrayLike, lane: ArrayLike, speed: ArrayLike,
                    desired_speed: ArrayLike | None = None,
                    type_index: ArrayLike | None = None) -> None:
        """Env ``env`` from explicit cars (scenarios, replays, tests); with a single env the
        number of cars may differ from ``config.car_count``."""
        s = np.atleast_1d(np.asarray(s, dtype=np.float64))
        n = len(s)
        lane = np.broadcast_to(np.asarray(lane, dtype=np.int64), (n,))
        speed = np.broadcast_to(np.asarray(speed, dtype=np.float64), (n,))
        desired = speed if desired_speed is None else np.broadcast_to(
            np.asarray(desired_speed, dtype=np.float64), (n,))
        types = np.zeros(n, dtype=np.int64) if type_index is None else np.broadcast_to(
            np.asarray(type_index, dtype=np.int64), (n,))
        if np.any((lane < 0) | (lane >= self.lanes)):
            raise ValueError(f"lane must be in [0, {self.lanes}); got {lane.tolist()}")
        if np.any((types < 0) | (types >= len(VEHICLE_TYPES))):
            raise ValueError(f"type_index must be in [0, {len(VEHICLE_TYPES)})")
        if n != self.state.cars:
            if self.envs != 1:
                raise ValueError(f"a batch of {self.envs} envs has {self.state.cars} cars "
                                 f"per env; got {n}")
            self.state = TrafficState(1, n, self.config.lane_change_duration)
        self.rngs[env] = rng
        reset_row_to(self, self.state, env, rng, ego_s, ego_d, ego_speed, s, lane, speed,
                     desired, types)
        self._settle_pose(env)

    def _settle_pose(self, env: int) -> None:
        st = self.state
        rows = np.array([env])
        sub = st.take(rows)
        sub.kappa = self.geometry.curvature(sub.s)
        samples = self.geometry.samples_now(sub)
        if self.scripted:
            scripting.place_objects(self.geometry, sub, sub.step - 1, samples)
        self.geometry.update_pose(sub, samples)
        st.put(rows, sub)

    # ------------------------------------------------------------------ motion
    def samples_now(self) -> TrafficSamples:
        """The current state as a one-frame :class:`TrafficSamples` (``(envs, 1, cars)``)."""
        samples = self.geometry.samples_now(self.state)
        if self.scripted:
            scripting.place_objects(self.geometry, self.state, self.state.step - 1, samples)
        return samples

    def advance(self, frames: int, ego_s: FloatArray, ego_d: FloatArray,
                ego_speed: FloatArray) -> TrafficSamples:
        """Simulate ``frames`` physics frames of every env; the state after each one.

        Args:
            frames: number of physics frames (>= 1).
            ego_s, ego_d, ego_speed: ``(envs, frames)`` the ego's Frenet state and speed
                (m/s) after each frame. A decision instant uses the latest ego state
                before it (the previous call's last one for a decision at the start).

        Returns:
            :class:`TrafficSamples` of ``(envs, frames, cars)`` arrays.
        """
        if any(rng is None for rng in self.rngs):
            raise RuntimeError("call reset() before advance()")
        if frames < 1:
            raise ValueError(f"frames must be >= 1; got {frames}")
        st = self.state
        envs, cars = st.envs, st.cars
        shape = (envs, frames, cars)
        s_out, d_out, v_out, dd_out = (np.empty(shape) for _ in range(4))
        period = self.config.decision_period
        step0 = st.step.copy()
        # Each env's decisions fall on frames k1, k1 + period, ... of the window. Round j
        # takes every env's j-th decision at once: first the segment since the previous
        # one (from each env's own start, padded to the longest), then the decisions.
        decision = (period - step0 % period) % period  # frame of each env's next decision
        segment_start = np.zeros(envs, dtype=np.int64)
        if cars:
            while True:
                rows = np.flatnonzero(decision < frames) if envs > 1 else (
                    self._all if decision[0] < frames else self._all[:0])
                if not len(rows):
                    break
                begin, end = segment_start[rows], decision[rows]
                self._segment_into(st, rows, begin, end - begin, step0,
                                   (s_out, d_out, v_out, dd_out), keep_end=True)
                whole = len(rows) == envs
                sub = st if whole else st.take(rows)
                before = end - 1  # the ego's latest state before the decision
                moved = before >= 0
                if np.count_nonzero(moved):
                    at = rows[moved], before[moved]
                    sub.ego_s[moved] = ego_s[at] % self.loop
                    sub.ego_d[moved] = ego_d[at]
                    sub.ego_speed[moved] = ego_speed[at]
                sub.step = step0[rows] + end
                if self.scripted:
                    lc_start = scripting.before_decision(self, sub, rows)
                decide(self, sub, [self.rngs[e] for e in rows.tolist()])  # type: ignore[misc]
                if self.scripted:
                    scripting.after_decision(sub, lc_start)
                if not whole:
                    st.put(rows, sub)
                segment_start[rows] = end
                decision[rows] = end + period
            # The last segment of every env, from its last decision to the window's end.
            self._segment_into(st, self._all, segment_start, frames - segment_start, step0,
                               (s_out, d_out, v_out, dd_out), keep_end=False)
        st.step = step0 + frames
        st.ego_s = ego_s[:, -1] % self.loop
        st.ego_d = ego_d[:, -1].copy()
        st.ego_speed = ego_speed[:, -1].copy()
        samples = self.geometry.pose(s_out, d_out, v_out, dd_out)
        if self.scripted:
            scripting.place_objects(self.geometry, st, step0, samples)
        self.geometry.update_pose(st, samples)
        return samples

    def _segment_into(self, st: TrafficState, rows: IntArray, begin: IntArray,
                      length: IntArray, step0: IntArray, out: tuple[FloatArray, ...], *,
                      keep_end: bool) -> None:
        """Evaluate the segments of envs ``rows`` (``length`` frames from window frame
        ``begin``) into the window arrays ``out``, one call per (begin, length) pair;
        with ``keep_end``, a segment's end becomes its env's state."""
        keys = begin * (out[0].shape[1] + 1) + length
        groups = [rows] if len(rows) == 1 else [rows[keys == key] for key in np.unique(keys)]
        every = len(rows) == self.envs
        for group in groups:
            first = int(np.flatnonzero(rows == group[0])[0]) if len(groups) > 1 else 0
            b, m = int(begin[first]), int(length[first])
            if m == 0:
                continue
            whole = every and len(group) == self.envs
            source = st if whole else RowsOf(st, group)
            s, d, v, d_dot = self.geometry.segment(source, m, step0[group] + b)
            if whole:
                out[0][:, b:b + m], out[1][:, b:b + m] = s, d
                out[2][:, b:b + m], out[3][:, b:b + m] = v, d_dot
            else:
                out[0][group, b:b + m], out[1][group, b:b + m] = s, d
                out[2][group, b:b + m], out[3][group, b:b + m] = v, d_dot
            if keep_end:
                st.s[group] = s[:, -1] % self.loop
                st.speed[group] = v[:, -1]
                st.d[group] = d[:, -1]
