"""Traffic for the highway: vectorized IDM car following, gap-checked lane changes,
recycling around the ego car, vehicle types, and an optional rogue mode.

See :mod:`sdc_gym.traffic.highway_traffic` for the model and its rules.
"""

from sdc_gym.traffic.highway_traffic import (
    MPH,
    HighwayTraffic,
    TrafficConfig,
    TrafficSamples,
)
from sdc_gym.traffic.idm import (
    IDMParameters,
    desired_gap,
    idm_acceleration,
    max_speed_for_gap,
)
from sdc_gym.traffic.vehicle_types import (
    CAR,
    MOTORCYCLE,
    SUV,
    TRUCK,
    VEHICLE_TYPES,
    VehicleType,
    spawn_probabilities,
)

__all__ = [
    "CAR",
    "MOTORCYCLE",
    "MPH",
    "SUV",
    "TRUCK",
    "VEHICLE_TYPES",
    "HighwayTraffic",
    "IDMParameters",
    "TrafficConfig",
    "TrafficSamples",
    "VehicleType",
    "desired_gap",
    "idm_acceleration",
    "max_speed_for_gap",
    "spawn_probabilities",
]
