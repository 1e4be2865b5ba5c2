"""Traffic settings and the shape of what the traffic model hands out per physics frame.

:class:`TrafficConfig` is the one place the traffic's rules are parameterised (see
:mod:`sdc_gym.traffic.highway_traffic` for the model); :class:`TrafficSamples` holds the
traffic state at every physics frame of one advance, for one env (arrays ``(frames, cars)``)
or for a batch of envs (``(envs, frames, cars)``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sdc_gym.traffic.idm import IDMParameters
from sdc_gym.traffic.vehicle_types import mix_weights, spawn_probabilities

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MPH = 0.44704  # m/s per mph


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
        vehicle_mix: spawn weights: one per :data:`VEHICLE_TYPES` entry, or a mapping of
            kind names to weights (the kinds it leaves out weigh 0), e.g.
            ``{"car": 0.6, "bus": 0.1}``; None = the kinds' own weights.
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
    vehicle_mix: tuple[float, ...] | Mapping[str, float] | None = None
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
        # Kept as one weight per kind (hashable, and one form for the kernels).
        object.__setattr__(self, "vehicle_mix", mix_weights(self.vehicle_mix))


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

