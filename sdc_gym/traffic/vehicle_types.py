"""Kinds of traffic: vehicle sizes, colours, spawn weights and driving temperament, and the
road objects of road events.

The original simulator has one kind of traffic car; its author asked for trucks, buses,
SUVs and motorcycles of different sizes. Each traffic slot carries a *type index* into
:data:`KINDS`: the vehicles (:data:`VEHICLE_TYPES`, which the traffic spawns) first, then
the road objects of road events (:data:`ROAD_OBJECT_TYPES`: construction barriers, fallen
cargo, animals; :mod:`sdc_gym.traffic.road_events`), which are never spawned at random.
The traffic model reads the size and the acceleration limits from the kind, the renderer
its name and colour.

Sizes are typical outer dimensions (length along travel, width across, metres). The
acceleration figures feed the Intelligent Driver Model per car (see
:mod:`sdc_gym.traffic.idm`): ``comfort_accel`` is its ``a_max`` and ``comfort_decel`` its
``b``. The car row uses highway-env's IDMVehicle values (3.0 and 5.0 m/s^2) so that the
default mix behaves like highway-env traffic; a loaded truck, a bus or a semi-trailer pulls
away and brakes more gently (a lower ``b`` also makes it keep a longer gap when closing
in), a motorcycle pulls away harder. ``max_speed_mph`` caps the desired speed a kind is
spawned with (a coach or a semi keeps to 55-60 mph where cars spawned behind the ego want
50-60). Buses, vans and semi-trailers have a spawn weight of 0 by default, so the default
mix, and every default episode, is the one before they existed; ``vehicle_mix`` (a weight
per kind by name, e.g. ``{"bus": 0.05}``) brings them in.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class VehicleType:
    """One kind of traffic vehicle (or road object).

    Attributes:
        name: short name used in renders, logs and scenario files.
        length: m, bumper to bumper along the direction of travel.
        width: m, across the direction of travel.
        color: display colour, RGB 0-255.
        spawn_weight: relative frequency at spawn (normalised over the vehicles).
        comfort_accel: m/s^2, IDM ``a_max`` (largest acceleration on a free road).
        comfort_decel: m/s^2, IDM ``b`` (positive; the braking the driver plans with).
        max_speed_mph: the highest desired speed the kind is spawned with.
    """

    name: str
    length: float
    width: float
    color: tuple[int, int, int]
    spawn_weight: float
    comfort_accel: float
    comfort_decel: float
    max_speed_mph: float = math.inf


CAR = 0
SUV = 1
TRUCK = 2
MOTORCYCLE = 3
BUS = 4
VAN = 5
SEMI = 6

VEHICLE_TYPES: tuple[VehicleType, ...] = (
    VehicleType("car", 4.7, 1.9, (52, 101, 164), 0.60, 3.0, 5.0),
    VehicleType("suv", 5.1, 2.0, (78, 154, 6), 0.22, 2.6, 4.5),
    VehicleType("truck", 12.0, 2.5, (204, 120, 0), 0.10, 1.2, 3.5),
    VehicleType("motorcycle", 2.2, 0.8, (164, 0, 0), 0.08, 3.5, 5.0),
    # A 12 m city bus / coach: slow to pull away, gentle brakes, kept to 55 mph.
    VehicleType("bus", 12.2, 2.55, (237, 212, 0), 0.0, 1.0, 3.0, 55.0),
    # A delivery van: a little longer and less lively than a car.
    VehicleType("van", 5.6, 2.05, (186, 189, 182), 0.0, 2.4, 4.5),
    # A tractor with a 53 ft trailer (16.5 m overall): the slowest to accelerate.
    VehicleType("semi", 16.5, 2.6, (117, 80, 123), 0.0, 0.8, 3.0, 60.0),
)
"""The vehicles, indexed by :data:`CAR`, :data:`SUV`, :data:`TRUCK`, :data:`MOTORCYCLE`,
:data:`BUS`, :data:`VAN`, :data:`SEMI`: the kinds the traffic spawns."""

BARRIER = len(VEHICLE_TYPES)
CARGO = BARRIER + 1
ANIMAL = BARRIER + 2

ROAD_OBJECT_TYPES: tuple[VehicleType, ...] = (
    # One piece of a closed lane: a row of cones and barrels closing 8 m of the lane.
    # (Pieces chain along the lane, so that the closure follows the road's bends.)
    VehicleType("barrier", 8.0, 2.8, (255, 110, 0), 0.0, 1.0, 1.0),
    # A crate or a mattress fallen off a truck.
    VehicleType("cargo", 1.4, 1.2, (139, 87, 42), 0.0, 1.0, 1.0),
    # A deer crossing (it walks across the lanes; see road_events).
    VehicleType("animal", 1.6, 0.6, (201, 160, 110), 0.0, 1.0, 1.0),
)
"""The road objects of road events, indexed by :data:`BARRIER`, :data:`CARGO`,
:data:`ANIMAL` (their IDM figures are placeholders: objects never drive)."""

KINDS: tuple[VehicleType, ...] = VEHICLE_TYPES + ROAD_OBJECT_TYPES
"""Every kind a traffic slot can hold, by type index: the vehicles, then the road objects."""
KIND_INDEX: dict[str, int] = {kind.name: index for index, kind in enumerate(KINDS)}
VEHICLE_NAMES: tuple[str, ...] = tuple(kind.name for kind in VEHICLE_TYPES)

# Column views used by the vectorized traffic model (indexed by type index).
TYPE_LENGTHS: NDArray[np.float64] = np.array([t.length for t in KINDS])
TYPE_WIDTHS: NDArray[np.float64] = np.array([t.width for t in KINDS])
TYPE_COMFORT_ACCEL: NDArray[np.float64] = np.array([t.comfort_accel for t in KINDS])
TYPE_COMFORT_DECEL: NDArray[np.float64] = np.array([t.comfort_decel for t in KINDS])
TYPE_COLORS: NDArray[np.uint8] = np.array([t.color for t in KINDS], dtype=np.uint8)
TYPE_MAX_SPEED_MPH: NDArray[np.float64] = np.array([t.max_speed_mph for t in KINDS])


def mix_weights(mix: tuple[float, ...] | Mapping[str, float] | None
                ) -> tuple[float, ...] | None:
    """A ``vehicle_mix`` as one weight per vehicle kind: a mapping names its kinds (the
    others weigh 0), a sequence has one weight per kind, ``None`` stays ``None`` (the
    kinds' own weights). Raises ``ValueError`` naming the kinds for anything else."""
    if mix is None:
        return None
    if isinstance(mix, Mapping):
        unknown = sorted(set(mix) - set(VEHICLE_NAMES))
        if unknown:
            raise ValueError(f"vehicle_mix names unknown vehicle kinds {unknown}; the kinds "
                             f"are {list(VEHICLE_NAMES)}")
        return tuple(float(mix.get(name, 0.0)) for name in VEHICLE_NAMES)
    return tuple(mix)


def spawn_probabilities(weights: tuple[float, ...] | Mapping[str, float] | None = None
                        ) -> NDArray[np.float64]:
    """Normalised spawn probabilities per vehicle kind; ``None`` means the kinds' own
    weights, a mapping weighs the kinds it names (the others 0).

    Raises ``ValueError`` when a sequence does not have one non-negative weight per kind,
    or the weights sum to zero.
    """
    weights = mix_weights(weights)
    if weights is None:
        weights = tuple(t.spawn_weight for t in VEHICLE_TYPES)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(VEHICLE_TYPES),):
        raise ValueError(
            f"vehicle_mix needs one weight per kind {list(VEHICLE_NAMES)} (or a mapping "
            f"of kind names to weights, e.g. {{'bus': 0.05}}); got {len(w)} value(s)"
        )
    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError(f"vehicle_mix weights must be finite, >= 0, not all 0; got {weights}")
    return w / w.sum()
