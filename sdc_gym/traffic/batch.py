"""The traffic of ``envs`` highway envs at once: state as arrays, kernels over them.

:class:`TrafficBatch` owns the constants (config, road tables), the
:class:`~sdc_gym.traffic.state.TrafficState` of every env and each env's generator.
:meth:`TrafficBatch.advance` moves all envs by the same number of physics frames: the
envs whose decision instant falls on a frame decide together
(:func:`~sdc_gym.traffic.decisions.decide`), and the motion between decisions is
evaluated in closed form for all of them (:func:`~sdc_gym.traffic.kinematics.segments`).
Envs reset at different times have different phases of the decision period, so one
advance may hold several decision rounds: round ``j`` takes every env's ``j``-th decision
of the window (each env's segment since its previous one first). Env ``i`` of a batch is
exactly a single env (a batch of one) with the same generator, frame for frame.

Scenarios and road events (:mod:`sdc_gym.traffic.scripted`): ``object_slots`` columns
follow the ``car_count`` cars (parked in random traffic, road objects when an event places
them); an env may start from explicit slots (:meth:`TrafficBatch.reset_slots_at`) and have
a *controller* (a scenario's script, the random road events) called at each of its
decision instants. Until a batch holds such slots (``scripted``), none of this runs.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.generator_kernel import generator_pointers
from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.kernel_threads import SERIAL, KernelThreads
from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.traffic import decisions, placement
from sdc_gym.traffic import scripted as scripting
from sdc_gym.traffic.config import TrafficConfig, TrafficSamples
from sdc_gym.traffic.decisions import decide
from sdc_gym.traffic.kinematics import (
    EGO_D,
    EGO_S,
    EGO_SPEED,
    HEADING,
    SPEED,
    STEP,
    VX,
    VY,
    D,
    S,
    TrafficGeometry,
    X,
    Y,
)
from sdc_gym.traffic.placement import reset_row, reset_row_to
from sdc_gym.traffic.state import TrafficState
from sdc_gym.traffic.vehicle_types import VEHICLE_TYPES, spawn_probabilities

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@njit(cache=True)
def plan_rounds(step: np.ndarray, frames: int, period: int, rows: np.ndarray,
                begin: np.ndarray, end: np.ndarray) -> int:
    """Each env's decisions in a window of ``frames`` frames from its ``step``: on the
    window's frames ``k1, k1 + period, ...`` (``k1`` the first frame at a multiple of the
    period). Round ``j`` holds every env's ``j``-th: ``rows[j]`` which envs have one,
    ``end[j]`` its frame, ``begin[j]`` the previous one's (or 0); row ``rounds`` the last
    segments (``begin`` to ``frames``). Returns the number of rounds."""
    envs = step.shape[0]
    rounds = 0
    for e in range(envs):
        first = (period - step[e] % period) % period
        count = 0 if first >= frames else (frames - 1 - first) // period + 1
        rounds = max(rounds, count)
    for e in range(envs):
        frame = (period - step[e] % period) % period
        start = 0
        for j in range(rounds):
            rows[j, e] = frame < frames
            if rows[j, e]:
                begin[j, e], end[j, e] = start, frame
                start = frame
                frame += period
            else:
                begin[j, e] = end[j, e] = start
        rows[rounds, e] = True
        begin[rounds, e], end[rounds, e] = start, frames
    return rounds


@njit(cache=True)
def close_window(cf: np.ndarray, ei: np.ndarray, ef: np.ndarray, step0: np.ndarray,
                 frames: int, ego_s: np.ndarray, ego_d: np.ndarray, ego_speed: np.ndarray,
                 loop: float,
                 s: np.ndarray, d: np.ndarray, v: np.ndarray, x: np.ndarray, y: np.ndarray,
                 heading: np.ndarray, vx: np.ndarray, vy: np.ndarray) -> None:
    """The window's last frame becomes the state: every car's pose, each env's step and
    the ego's latest s (wrapped), d and speed."""
    last = frames - 1
    for e in range(cf.shape[1]):
        ei[STEP, e] = step0[e] + frames
        ef[EGO_S, e] = py_mod(ego_s[e, last], loop)
        ef[EGO_D, e] = ego_d[e, last]
        ef[EGO_SPEED, e] = ego_speed[e, last]
        for c in range(cf.shape[2]):
            cf[S, e, c], cf[D, e, c], cf[SPEED, e, c] = s[e, last, c], d[e, last, c], \
                v[e, last, c]
            cf[X, e, c], cf[Y, e, c] = x[e, last, c], y[e, last, c]
            cf[HEADING, e, c] = heading[e, last, c]
            cf[VX, e, c], cf[VY, e, c] = vx[e, last, c], vy[e, last, c]


class TrafficBatch:
    """Traffic for ``envs`` envs on one :class:`HighwayMap` (see the module docstring).

    Args:
        road: the highway.
        config: traffic settings (``None``: the defaults).
        envs: number of envs.
        dt: s, the physics step.
        object_slots: columns for road objects after the ``car_count`` cars.
        kernel_threads: the threads of the heaviest kernels (segments, poses,
            decisions; :mod:`sdc_gym.kernel_threads`), one by default.
    """

    def __init__(self, road: HighwayMap, config: TrafficConfig | None = None, envs: int = 1,
                 dt: float = 0.02, object_slots: int = 0,
                 kernel_threads: KernelThreads = SERIAL) -> None:
        if envs < 1:
            raise ValueError(f"envs must be >= 1, got {envs}")
        self.road = road
        self.config = config = config if config is not None else TrafficConfig()
        self.dt = float(dt)
        self.envs = envs
        self.reference = road.reference
        self.kernel_threads = kernel_threads
        self.geometry = TrafficGeometry(road, config, self.dt, kernel_threads)
        self.loop = float(road.length)
        # An open road's end: its cars spawn on [0, end] and leave past it (a loop: inf).
        self.road_end = math.inf if road.closed else float(road.end_s)
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
        self.decision_constants = self._decision_constants()
        self.placement_constants = self._placement_constants()
        self.respawn_draws = placement.respawn_draws(self)
        cdf = self.type_p.cumsum()
        self.type_cdf = cdf / cdf[-1]
        self.object_slots = int(object_slots)
        self.slots = config.car_count + self.object_slots
        self.state = TrafficState(envs, self.slots, config.lane_change_duration)
        self.rngs: list[np.random.Generator | None] = [None] * envs
        self.controllers: list[scripting.TrafficController | None] = [None] * envs
        self.scripted = self.object_slots > 0
        # Each env's generator as the kernels draw from it (sdc_gym.generator_kernel).
        self.rng_pointers = np.zeros((envs, 4), dtype=np.uint64)
        self._all = np.ones(envs, dtype=bool)
        self._ready = False
        self._round_plans: dict[int, tuple[NDArray, ...]] = {}
        self._scratch_for(self.slots)
        placement.compile_recycling(self)  # at make, not at the first recycle

    def _decision_constants(self) -> FloatArray:
        cfg, idm = self.config, self.config.idm
        constants = np.zeros(decisions.CONSTANTS)
        for index, value in (
                (decisions.C_LOOP, self.loop), (decisions.C_RANGE, self.range),
                (decisions.C_LANES, self.lanes), (decisions.C_LANE_WIDTH, self.lane_width),
                (decisions.C_EGO_HALF_WIDTH, 0.5 * cfg.ego_width),
                (decisions.C_EGO_HALF_LENGTH, self.ego_half_length),
                (decisions.C_EGO_A_MAX, idm.a_max), (decisions.C_EGO_TSAB, self.ego_tsab),
                (decisions.C_IDM_T, idm.T), (decisions.C_IDM_S0, idm.s0),
                (decisions.C_IDM_MAX_BRAKING, idm.max_braking),
                (decisions.C_IDM_FLOOR, float(idm.floor_desired_gap)),
                (decisions.C_CLEARANCE, cfg.lane_change_clearance),
                (decisions.C_MIN_GAIN, cfg.lane_change_min_gain),
                (decisions.C_MAX_IMPOSED, cfg.lane_change_max_braking_imposed),
                (decisions.C_MIN_SPEED, cfg.lane_change_min_speed),
                (decisions.C_LC_DURATION, cfg.lane_change_duration),
                (decisions.C_LC_STEPS, math.ceil(cfg.lane_change_duration / self.dt - 1e-9)),
                (decisions.C_SUSTAIN, self.sustain_decisions),
                (decisions.C_ROGUE_P, self.rogue_p),
                (decisions.C_ROGUE_DECEL, cfg.rogue_brake_decel),
                (decisions.C_BRAKE_STEPS, self.brake_steps),
                (decisions.C_CUT_IN_WINDOW, self.cut_in_window_steps),
                (decisions.C_CUT_IN_GAP, cfg.rogue_cut_in_gap),
                (decisions.C_CUT_IN_DURATION, cfg.rogue_cut_in_duration),
                (decisions.C_CUT_IN_STEPS,
                 math.ceil(cfg.rogue_cut_in_duration / self.dt - 1e-9)),
                (decisions.C_DECISION_DT, self.decision_dt),
                (decisions.C_ROAD_END, self.road_end)):
            constants[index] = value
        return constants

    def _placement_constants(self) -> FloatArray:
        cfg, idm = self.config, self.config.idm
        constants = np.zeros(placement.PLACEMENT_CONSTANTS)
        for index, value in (
                (placement.K_LOOP, self.loop), (placement.K_LANE_WIDTH, self.lane_width),
                (placement.K_WANDER, cfg.lateral_wander), (placement.K_DT, self.dt),
                (placement.K_MIN_GAP, cfg.spawn_min_gap),
                (placement.K_EGO_HALF_WIDTH, 0.5 * cfg.ego_width),
                (placement.K_EGO_HALF_LENGTH, self.ego_half_length),
                (placement.K_EGO_A_MAX, idm.a_max), (placement.K_EGO_TSAB, self.ego_tsab),
                (placement.K_IDM_T, idm.T), (placement.K_IDM_S0, idm.s0),
                (placement.K_IDM_FLOOR, float(idm.floor_desired_gap)),
                (placement.K_ROAD_END, self.road_end)):
            constants[index] = value
        return constants

    def _scratch_for(self, cars: int) -> None:
        """Work arrays of the decision rounds (per env and object)."""
        self.scratch_ratio = np.zeros((self.envs, cars + 1))
        self.scratch_candidates = np.full((self.envs, self.config.respawn_per_decision), -1,
                                          dtype=np.int64)

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
        self._use_generator(env, rng)
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
        self._use_generator(env, rng)
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
        self._use_generator(env, rng)
        reset_row_to(self, self.state, env, rng, ego_s, ego_d, ego_speed, s, lane, speed,
                     desired, types)
        self._settle_pose(env)

    def _rounds(self, frames: int) -> tuple[int, NDArray[np.bool_], IntArray, IntArray]:
        """The decision rounds of a window of ``frames`` frames: how many, and per round
        which envs decide, at which frame, and where their segment before it begins (row
        ``rounds``: every env's last segment, to the window's end)."""
        plan = self._round_plans.get(frames)
        if plan is None:
            most = frames // self.config.decision_period + 2
            plan = self._round_plans[frames] = (
                np.zeros((most, self.envs), dtype=np.bool_),
                np.zeros((most, self.envs), dtype=np.int64),
                np.zeros((most, self.envs), dtype=np.int64))
        rows, begin, end = plan
        count = plan_rounds(self.state.step, frames, self.config.decision_period, rows, begin,
                            end)
        return count, rows, begin, end

    def __setstate__(self, state: dict[str, Any]) -> None:
        # A copy or an unpickled batch has generators of its own: ``rng_pointers`` are
        # raw addresses into the original's, so a copy would draw from (and advance) the
        # original's, or from freed memory once the original is gone. Point them anew.
        self.__dict__.update(state)
        for env, rng in enumerate(self.rngs):
            if rng is not None:
                self.rng_pointers[env] = generator_pointers(rng)

    def _use_generator(self, env: int, rng: np.random.Generator) -> None:
        if self.rngs[env] is not rng:
            self.rngs[env] = rng
            self.rng_pointers[env] = generator_pointers(rng)

    def _settle_pose(self, env: int) -> None:
        """Env ``env``'s curvature and pose after its placement."""
        st = self.state
        st.kappa[env] = self.geometry.curvature(st.s[env])
        samples = self.geometry.samples_now(st, env)
        if self.scripted:
            scripting.place_objects(self.geometry, st, st.step[env:env + 1] - 1, samples,
                                    np.array([env]))
        self.geometry.update_pose(st, samples, env)

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
        if not self._ready:
            if any(rng is None for rng in self.rngs):
                raise RuntimeError("call reset() before advance()")
            self._ready = True
        if frames < 1:
            raise ValueError(f"frames must be >= 1; got {frames}")
        st = self.state
        envs, cars = st.envs, st.cars
        shape = (envs, frames, cars)
        out = tuple(np.empty(shape) for _ in range(4))
        if self.scratch_ratio.shape != (envs, cars + 1):
            self._scratch_for(cars)
        step0 = st.step.copy()
        if cars:
            # Round j takes every env's j-th decision of the window at once: first the
            # segment since its previous one, then the decisions.
            rounds, rows, begin, end = self._rounds(frames)
            for j in range(rounds):
                self.geometry.segments(st, rows[j], begin[j], end[j], step0, out,
                                       keep_end=True)
                if self.scripted:
                    lc_start = scripting.before_decision_round(
                        self, st, rows[j], end[j], step0, ego_s, ego_d, ego_speed)
                decide(self, rows[j], end[j], step0, ego_s, ego_d, ego_speed)
                if self.scripted:
                    scripting.after_decision(st, lc_start, rows[j])
            # The last segment of every env, from its last decision to the window's end.
            self.geometry.segments(st, self._all, begin[rounds], end[rounds], step0, out,
                                   keep_end=False)
        samples = self.geometry.pose(*out)
        if self.scripted:
            scripting.place_objects(self.geometry, st, step0, samples)
        close_window(st.car_floats, st.env_ints, st.env_floats, step0, frames, ego_s, ego_d,
                     ego_speed, self.loop, samples.s, samples.d, samples.speed, samples.x,
                     samples.y, samples.heading, samples.vx, samples.vy)
        return samples

