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
* d) - (L_follower + L_leader) / 2``. The search sorts each env's objects by s once and
finds every car's neighbours in every lane from cumulative minima and maxima over the
sorted order (:mod:`sdc_gym.traffic.leaders`): ``O(n log n)``, so 500 cars cost a few
times 100, not 25 times.

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
fits (:func:`max_speed_for_gap`). A recycled car keeps its slot id. When no spot fits (dense
traffic: e.g. 50 cars in +-200 m jam at about 15 m/s), the car drives on where it is and
tries again later. :meth:`HighwayTraffic.reset` lays the cars out uniformly over the free
room (``spawn_min_gap`` from each other and from the ego) within a spread set by
``density``, then slows each car, front to back, to a speed whose IDM desired gap fits
behind its leader (the ego included).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.road.highway_map import HighwayMap
from sdc_gym.traffic.batch import TrafficBatch
from sdc_gym.traffic.config import MPH, TrafficConfig, TrafficSamples

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["MPH", "HighwayTraffic", "TrafficConfig", "TrafficSamples"]


def _as_frames(values: ArrayLike, steps: int) -> FloatArray:
    return np.asarray(values, dtype=np.float64).reshape(1, steps)


class HighwayTraffic:
    """The traffic of one env: a :class:`~sdc_gym.traffic.batch.TrafficBatch` of one, with
    its state as ``(n,)`` arrays; see the module docstring.

    Args:
        road: the highway (its reference line, lane count and width).
        config: traffic settings (``None``: the defaults).
        dt: s, the physics step.

    After :meth:`reset` or :meth:`advance`, these ``(n,)`` arrays hold the current state
    (read-only views of the batch's row): ``ids`` (fixed slots ``0..n-1``: a respawned car
    keeps its slot's id, as in the original, whose sensor fusion numbers its list of
    cars), ``spawn_count`` (how often each slot has been respawned since the reset), ``s``,
    ``d``, ``speed``, ``lane`` (the lane holding the car's centre), ``target_lane`` (the
    destination of a lane change, else the car's lane), ``length``, ``width``,
    ``type_index``, ``x``, ``y``, ``heading``, ``vx``, ``vy``, and ``desired_speed``
    (m/s). ``rogue_brake_count`` and ``rogue_cut_in_count`` count rogue events since the
    reset.
    """

    def __init__(self, road: HighwayMap, config: TrafficConfig | None = None,
                 dt: float = 0.02) -> None:
        self._attach(TrafficBatch(road, config, envs=1, dt=dt), 0)

    @classmethod
    def view(cls, batch: TrafficBatch, env: int) -> HighwayTraffic:
        """Env ``env`` of an existing batch, with this class's ``(n,)`` API."""
        made = object.__new__(cls)
        made._attach(batch, env)
        return made

    def _attach(self, batch: TrafficBatch, env: int) -> None:
        self.batch = batch
        self.env = env
        self.road = batch.road
        self.config = batch.config
        self.dt = batch.dt
        self._clamp_lane = self.config.lateral_wander >= 0.45 * batch.lane_width

    # ------------------------------------------------------------------ public API
    def reset(self, rng: np.random.Generator, ego_s: float, ego_d: float,
              ego_speed: float = 0.0) -> None:
        """Place ``car_count`` cars around the ego car (see the module docstring).

        All randomness of the episode comes from ``rng`` (kept for :meth:`advance`).
        ``ego_speed`` defaults to the original's start at rest. Raises ``ValueError`` if
        the cars cannot be placed within ``spawn_range``.
        """
        self.batch.reset_at(self.env, rng, ego_s, ego_d, ego_speed)

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
        self.batch.reset_to_at(self.env, rng, ego_s, ego_d, ego_speed, s=s, lane=lane, speed=speed,
                               desired_speed=desired_speed, type_index=type_index)

    def samples_now(self) -> TrafficSamples:
        """The current state as a one-step :class:`TrafficSamples`."""
        return _row(self.batch.samples_now(), self.env)

    def advance(self, steps: int, ego_s: ArrayLike, ego_d: ArrayLike,
                ego_speed: ArrayLike) -> TrafficSamples:
        """Simulate ``steps`` physics steps; return the state after each one.

        Args:
            steps: number of physics steps (>= 1).
            ego_s, ego_d, ego_speed: ``(steps,)`` the ego's Frenet state and speed (m/s)
                after each sub-step. A decision instant uses the latest ego state before
                it (the previous call's last one for a decision at the start).
        """
        if steps < 1:
            raise ValueError(f"steps must be >= 1; got {steps}")
        if self.batch.envs != 1:
            raise RuntimeError("advance() of one env of a batch: advance the batch")
        return _row(self.batch.advance(steps, _as_frames(ego_s, steps),
                                         _as_frames(ego_d, steps),
                                         _as_frames(ego_speed, steps)), 0)

    # ------------------------------------------------------------------ state
    @property
    def n(self) -> int:
        return self.batch.state.cars

    def _row(self, name: str) -> Any:
        view = getattr(self.batch.state, name)[self.env]
        view.flags.writeable = False
        return view

    ids = property(lambda self: self._row("ids"))
    spawn_count = property(lambda self: self._row("spawn_count"))
    type_index = property(lambda self: self._row("type_index"))
    length = property(lambda self: self._row("length"))
    width = property(lambda self: self._row("width"))
    s = property(lambda self: self._row("s"))
    d = property(lambda self: self._row("d"))
    speed = property(lambda self: self._row("speed"))
    desired_speed = property(lambda self: self._row("desired"))
    target_lane = property(lambda self: self._row("target_lane"))
    x = property(lambda self: self._row("x"))
    y = property(lambda self: self._row("y"))
    heading = property(lambda self: self._row("heading"))
    vx = property(lambda self: self._row("vx"))
    vy = property(lambda self: self._row("vy"))

    @property
    def rogue_brake_count(self) -> int:
        return int(self.batch.state.rogue_brake_count[self.env])

    @property
    def rogue_cut_in_count(self) -> int:
        return int(self.batch.state.rogue_cut_in_count[self.env])

    @property
    def lane(self) -> IntArray:
        """``(n,)`` the lane holding each car's centre."""
        lane = (self.d * (1.0 / self.batch.lane_width)).astype(np.int64)
        if self._clamp_lane:  # else d always lies within the road
            lane = np.minimum(np.maximum(lane, 0), self.batch.lanes - 1)
        return lane


def _row(samples: TrafficSamples, env: int) -> TrafficSamples:
    """Env ``env`` of a batch's samples: ``(frames, cars)`` arrays."""
    return TrafficSamples._make(samples.s[env], samples.d[env], samples.speed[env],
                                samples.x[env], samples.y[env], samples.heading[env],
                                samples.vx[env], samples.vy[env])
