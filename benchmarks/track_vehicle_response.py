"""How the track loop's car answers its pedals and wheel, measured by driving it.

    python benchmarks/track_vehicle_response.py            # the sim and site presets
    python benchmarks/track_vehicle_response.py --cars sim creeping

Per car (a preset, or ``creeping``: the sim preset before issue 19, from
``tests/planners/capstone_twist_controllers.py``), each figure comes from stepping
:class:`~sdc_gym.vehicle.dbw_vehicle.DBWVehicle` at 50 Hz:

* creep speed: the speed after 60 s from rest with no throttle and no brake;
* holding brake: the smallest brake torque (bisection to 1 N m) that keeps the car at rest
  for 5 s with no throttle;
* acceleration at throttle 0.17 and 1.0 from 5 m/s (the first step's mean);
* top speed: the speed after 600 s at full throttle from 40 km/h;
* yaw rate at 11 m/s with the steering wheel at 1 rad and at the controllers' limit
  (``max_steer_angle``), and the curvature radius at that limit.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sdc_gym.vehicle.dbw_vehicle import (  # noqa: E402
    PHYSICS_DT,
    DBWVehicle,
    VehicleParameters,
    vehicle_parameters,
)
from tests.planners.capstone_twist_controllers import CARS  # noqa: E402


def car_for(name: str) -> VehicleParameters:
    """A preset by name, or a :data:`CARS` entry applied to the sim preset."""
    if name in CARS:
        return vehicle_parameters("sim").replace(**CARS[name])
    return vehicle_parameters(name)


def drive(params: VehicleParameters, seconds: float, throttle: float, brake: float,
          speed: float = 0.0) -> float:
    """m/s after ``seconds`` of constant pedals from ``speed``."""
    car = DBWVehicle(params)
    car.reset(0.0, 0.0, 0.0, speed, throttle=throttle, brake_torque=brake)
    for _ in range(round(seconds / PHYSICS_DT)):
        car.step(throttle, brake, 0.0)
    return car.state.speed


def holding_brake(params: VehicleParameters) -> float:
    """N m, the least brake torque that keeps the car at rest for 5 s (0 if none needed)."""
    if drive(params, 5.0, 0.0, 0.0) == 0.0:
        return 0.0
    low, high = 0.0, 10_000.0
    while high - low > 1.0:
        middle = 0.5 * (low + high)
        low, high = (low, middle) if drive(params, 5.0, 0.0, middle) == 0.0 else (middle, high)
    return high


def acceleration(params: VehicleParameters, throttle: float, speed: float) -> float:
    car = DBWVehicle(params)
    car.reset(0.0, 0.0, 0.0, speed, throttle=throttle)
    return car.step(throttle, 0.0, 0.0).acceleration


def yaw_rate(params: VehicleParameters, steering: float, speed: float) -> float:
    car = DBWVehicle(params)
    return car.reset(0.0, 0.0, 0.0, speed, steering_wheel_angle=steering).yaw_rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cars", nargs="+", default=["sim", "site", "creeping"])
    args = parser.parse_args()
    print(f"{'car':9s} {'creep m/s':>9s} {'hold N m':>8s} {'a(0.17) m/s2':>12s} "
          f"{'a(1.0) m/s2':>11s} {'top m/s':>7s} {'yaw(1 rad)':>10s} "
          f"{'yaw(max) rad/s':>14s} {'R(max) m':>8s}")
    for name in args.cars:
        params = car_for(name)
        limit = params.max_steer_angle
        at_limit = yaw_rate(params, limit, 11.0)
        print(f"{name:9s} {drive(params, 60.0, 0.0, 0.0):9.3f} {holding_brake(params):8.0f} "
              f"{acceleration(params, 0.17, 5.0):12.3f} {acceleration(params, 1.0, 5.0):11.3f} "
              f"{drive(params, 600.0, 1.0, 0.0, 11.1):7.2f} {yaw_rate(params, 1.0, 11.0):10.4f} "
              f"{at_limit:14.4f} {11.0 / at_limit:8.2f}")


if __name__ == "__main__":
    main()
