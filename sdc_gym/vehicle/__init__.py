"""Vehicle models of the track loop: the drive-by-wire car and the human who drives it in
manual-override periods.

See :mod:`sdc_gym.vehicle.dbw_vehicle` for the physics and its conventions (rear-axle
reference point, 50 Hz physics) and :mod:`sdc_gym.vehicle.manual_driver` for the driver.
"""

from sdc_gym.vehicle.dbw_vehicle import (
    FUEL_KG_PER_GALLON,
    GRAVITY,
    PHYSICS_DT,
    SIM_VEHICLE,
    SITE_VEHICLE,
    VEHICLE_PRESETS,
    DBWVehicle,
    VehicleParameters,
    VehicleState,
    vehicle_parameters,
)
from sdc_gym.vehicle.manual_driver import DriverStyle, ManualDriver

__all__ = [
    "FUEL_KG_PER_GALLON",
    "GRAVITY",
    "PHYSICS_DT",
    "SIM_VEHICLE",
    "SITE_VEHICLE",
    "VEHICLE_PRESETS",
    "DBWVehicle",
    "DriverStyle",
    "ManualDriver",
    "VehicleParameters",
    "VehicleState",
    "vehicle_parameters",
]
