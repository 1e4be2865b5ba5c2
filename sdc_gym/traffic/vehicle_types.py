"""Vehicle types of the traffic: sizes, colours, spawn weights and driving temperament.

The original simulator has one kind of traffic car; its author asked for trucks, SUVs and
motorcycles of different sizes. Each traffic car carries a *type index* into
:data:`VEHICLE_TYPES`; the traffic model reads the size and the acceleration limits from
it, the renderer reads the name and the colour.

Sizes are typical outer dimensions (length along travel, width across, metres). The
acceleration figures feed the Intelligent Driver Model per car (see
:mod:`sdc_gym.traffic.idm`): ``comfort_accel`` is its ``a_max`` and ``comfort_decel`` its
``b``. The car row uses highway-env's IDMVehicle values (3.0 and 5.0 m/s^2) so that the
default mix behaves like highway-env traffic; a loaded truck pulls away and brakes more
gently (a lower ``b`` also makes it keep a longer gap when closing in), a motorcycle
pulls away harder.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class VehicleType:
    """One kind of traffic vehicle.

    Attributes:
        name: short name used in renders and logs.
        length: m, bumper to bumper along the direction of travel.
        width: m, across the direction of travel.
        color: display colour, RGB 0-255.
        spawn_weight: relative frequency at spawn (normalised over all types).
        comfort_accel: m/s^2, IDM ``a_max`` (largest acceleration on a free road).
        comfort_decel: m/s^2, IDM ``b`` (positive; the braking the driver plans with).
    """

    name: str
    length: float
    width: float
    color: tuple[int, int, int]
    spawn_weight: float
    comfort_accel: float
    comfort_decel: float


CAR = 0
SUV = 1
TRUCK = 2
MOTORCYCLE = 3

VEHICLE_TYPES: tuple[VehicleType, ...] = (
    VehicleType("car", 4.7, 1.9, (52, 101, 164), 0.60, 3.0, 5.0),
    VehicleType("suv", 5.1, 2.0, (78, 154, 6), 0.22, 2.6, 4.5),
    VehicleType("truck", 12.0, 2.5, (204, 120, 0), 0.10, 1.2, 3.5),
    VehicleType("motorcycle", 2.2, 0.8, (164, 0, 0), 0.08, 3.5, 5.0),
)
"""All vehicle types, indexed by :data:`CAR`, :data:`SUV`, :data:`TRUCK`, :data:`MOTORCYCLE`."""

# Column views used by the vectorized traffic model (indexed by type index).
TYPE_LENGTHS: NDArray[np.float64] = np.array([t.length for t in VEHICLE_TYPES])
TYPE_WIDTHS: NDArray[np.float64] = np.array([t.width for t in VEHICLE_TYPES])
TYPE_COMFORT_ACCEL: NDArray[np.float64] = np.array([t.comfort_accel for t in VEHICLE_TYPES])
TYPE_COMFORT_DECEL: NDArray[np.float64] = np.array([t.comfort_decel for t in VEHICLE_TYPES])
TYPE_COLORS: NDArray[np.uint8] = np.array([t.color for t in VEHICLE_TYPES], dtype=np.uint8)


def spawn_probabilities(weights: tuple[float, ...] | None = None) -> NDArray[np.float64]:
    """Normalised spawn probabilities per type; ``None`` means the types' own weights.

    Raises ``ValueError`` when the tuple does not have one non-negative weight per type or
    sums to zero.
    """
    if weights is None:
        weights = tuple(t.spawn_weight for t in VEHICLE_TYPES)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(VEHICLE_TYPES),):
        raise ValueError(
            f"vehicle_mix needs one weight per type {[t.name for t in VEHICLE_TYPES]}; "
            f"got {len(w)} value(s)"
        )
    if np.any(~np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError(f"vehicle_mix weights must be finite, >= 0, not all 0; got {weights}")
    return w / w.sum()
