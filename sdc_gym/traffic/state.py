"""The traffic of a batch of envs as arrays: one row per env, one column per car.

:class:`TrafficState` holds every per-car quantity as an ``(envs, cars)`` array and every
per-env one as an ``(envs,)`` array; nothing else of the traffic changes during an
episode. The arrays are views of four packed blocks (car floats, car ints, env ints, env
floats: :attr:`TrafficState.blocks`), which is what the compiled kernels
(:mod:`sdc_gym.traffic.kernels`) take: a handful of arguments per call, whatever the
number of fields. The kernels work on the envs a mask selects; the placement
(:mod:`sdc_gym.traffic.placement`) writes one env's row in place.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from sdc_gym.packed_rows import PackedRows

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

NEVER = -(2**40)  # a step index long past: "no lane change started"
IDLE = 2**62  # lane-change end step of a car that is not changing lanes

# Roles of a slot (``TrafficState.role``): a traffic car (recycled, decides for itself), a
# road object (a static obstacle or a crossing animal: never recycled, never decides, in
# the lanes its footprint touches), or a parked slot (nothing: no lane, no contact, not
# sensed; the free object slots, and car slots a scenario leaves empty).
TRAFFIC = 0
OBJECT = 1
PARKED = 2


class TrafficState(PackedRows):
    """The arrays of a batch's traffic (see the module docstring).

    Per car, ``(envs, cars)``: ``ids`` (the fixed slots ``0..cars-1``: a respawned car
    keeps its slot's id, as in the original), ``spawn_count`` (respawns of the slot since
    the reset), ``type_index``, ``length``, ``width``,
    ``half_length``, ``a_max`` and ``tsab`` (IDM ``a_max`` and ``2 sqrt(a_max b)``), ``s``
    (wrapped), ``d``, ``speed``, ``desired`` (IDM ``v0``), ``origin`` and ``target_lane``
    (equal unless changing lanes), ``x``, ``y``, ``heading``, ``vx``, ``vy`` (the pose of
    the latest frame), ``kappa`` (curvature at the last decision), ``acc`` and
    ``half_acc`` (held between decisions), the lateral wander's ``omega``, ``phase`` and
    ``wander_speed``, the lane change's ``lc_start``, ``lc_end`` and ``lc_duration``, the
    wish being sustained (``pending`` lane, ``held`` decisions), the rogue timers
    ``brake_until`` and ``cut_in_until``, and ``respawn_wait``. Scenarios and road events
    (:mod:`sdc_gym.traffic.roles`): the slot's ``role``, ``hold_lane``, a scripted
    acceleration ``forced_acc`` in force until step ``forced_until``, and a road object's
    lateral position ``base_d`` with its drift ``lateral_rate`` from step ``lateral_from``
    to ``lateral_until``.

    Per env, ``(envs,)``: ``step`` (physics frames since the reset),
    ``respawn_blocked_until``, ``rogue_brake_count``, ``rogue_cut_in_count`` and the ego's
    latest ``ego_s``, ``ego_d``, ``ego_speed``.
    """

    PACKED_ROWS: ClassVar[tuple[tuple[str, str], ...]] = (
        ("car_floats", "CAR_FLOATS"), ("car_ints", "CAR_INTS"), ("env_ints", "ENV_INTS"),
        ("env_floats", "ENV_FLOATS"))
    CAR_FLOATS: ClassVar[tuple[str, ...]] = (
        "length", "width", "half_length", "a_max", "tsab", "s", "d", "speed", "desired",
        "x", "y", "heading", "vx", "vy", "kappa", "acc", "half_acc", "omega", "phase",
        "wander_speed", "lc_duration", "forced_acc", "base_d", "lateral_rate")
    CAR_INTS: ClassVar[tuple[str, ...]] = (
        "ids", "spawn_count", "type_index", "origin", "target_lane", "lc_start", "lc_end",
        "pending", "held", "brake_until", "cut_in_until", "respawn_wait", "role",
        "hold_lane", "forced_until", "lateral_from", "lateral_until")
    ENV_INTS: ClassVar[tuple[str, ...]] = (
        "step", "respawn_blocked_until", "rogue_brake_count", "rogue_cut_in_count")
    ENV_FLOATS: ClassVar[tuple[str, ...]] = ("ego_s", "ego_d", "ego_speed")
    FIELDS: ClassVar[tuple[str, ...]] = CAR_FLOATS + CAR_INTS + ENV_INTS + ENV_FLOATS

    # Declared for type checkers; set by __init__ / take.
    length: FloatArray
    width: FloatArray
    half_length: FloatArray
    a_max: FloatArray
    tsab: FloatArray
    s: FloatArray
    d: FloatArray
    speed: FloatArray
    desired: FloatArray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    vx: FloatArray
    vy: FloatArray
    kappa: FloatArray
    acc: FloatArray
    half_acc: FloatArray
    omega: FloatArray
    phase: FloatArray
    wander_speed: FloatArray
    lc_duration: FloatArray
    forced_acc: FloatArray
    base_d: FloatArray
    lateral_rate: FloatArray
    ids: IntArray
    spawn_count: IntArray
    type_index: IntArray
    origin: IntArray
    target_lane: IntArray
    lc_start: IntArray
    lc_end: IntArray
    pending: IntArray
    held: IntArray
    brake_until: IntArray
    cut_in_until: IntArray
    respawn_wait: IntArray
    role: IntArray
    hold_lane: IntArray
    forced_until: IntArray
    lateral_from: IntArray
    lateral_until: IntArray
    step: IntArray
    respawn_blocked_until: IntArray
    rogue_brake_count: IntArray
    rogue_cut_in_count: IntArray
    ego_s: FloatArray
    ego_d: FloatArray
    ego_speed: FloatArray

    def __init__(self, envs: int, cars: int, lane_change_duration: float = 0.0) -> None:
        self.envs = envs
        self.cars = cars
        self.car_floats = np.zeros((len(self.CAR_FLOATS), envs, cars))
        self.car_ints = np.zeros((len(self.CAR_INTS), envs, cars), dtype=np.int64)
        self.env_ints = np.zeros((len(self.ENV_INTS), envs), dtype=np.int64)
        self.env_floats = np.zeros((len(self.ENV_FLOATS), envs))
        self._bind_rows()
        self.clear_rows(slice(None), lane_change_duration)

    @property
    def blocks(self) -> tuple[FloatArray, IntArray, IntArray, FloatArray]:
        """The packed arrays the kernels take: car floats ``(fields, envs, cars)`` in the
        order of :data:`CAR_FLOATS`, car ints (:data:`CAR_INTS`), env ints ``(fields,
        envs)`` (:data:`ENV_INTS`) and env floats (:data:`ENV_FLOATS`)."""
        return self.car_floats, self.car_ints, self.env_ints, self.env_floats

    def clear_rows(self, rows: slice | IntArray | int, lane_change_duration: float) -> None:
        """Start rows afresh (before a placement writes their cars)."""
        for name in self.FIELDS:
            getattr(self, name)[rows] = 0
        self.ids[rows] = np.arange(self.cars)  # fixed slots, as the original's cars
        self.lc_start[rows] = NEVER
        self.lc_end[rows] = IDLE
        self.pending[rows] = -1
        self.lc_duration[rows] = lane_change_duration
