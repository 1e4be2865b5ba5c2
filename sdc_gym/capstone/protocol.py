"""The capstone simulator's wire protocol: its events, their fields and their units.

The original track simulator (the Unity build of the "System Integration" project) is a
Socket.IO *client* of the stack's styx server (``ros/src/styx/server.py``, port 4567).
What travels, as the original's ``bridge.py`` reads and writes it:

=================  =========  =================================================================
event              direction  fields (units)
=================  =========  =================================================================
``telemetry``      sim->stack ``x``, ``y``, ``z`` (m), ``yaw`` (degrees), ``velocity`` (mph),
                              ``dbw_enable`` (bool): numbers, as the bridge does arithmetic
                              on them (``data['velocity'] * 0.44704``)
``control``        sim->stack ``steering_angle`` (degrees of road wheel: the bridge makes it
                              rad with ``* pi / 180``), ``throttle`` ([0, 1]), ``brake`` (N m)
``trafficlights``  sim->stack ``light_pos_x/y/z`` (m), ``light_pos_dx/dy`` (the pole's facing:
                              the bridge takes ``atan2(dy, dx)``), ``light_state`` (RED 0,
                              YELLOW 1, GREEN 2, UNKNOWN 4): one list entry per light
``obstacle``       sim->stack ``obstacles``: one ``[x, y, z]`` (m) per obstacle (the bridge
                              publishes a pose per entry and a PointCloud2 of the list)
``image``          sim->stack ``image``: base64 of an encoded RGB frame (the bridge decodes it
                              with ``PIL.Image.open``)
``steer``          stack->sim ``steering_angle``: steering-wheel angle, rad, as a *string*
``throttle``       stack->sim ``throttle``: [0, 1], as a string
``brake``          stack->sim ``brake``: torque, N m, as a string
``drawline``       stack->sim ``next_x``, ``next_y``, ``next_z``: the final waypoints (z + 0.5)
=================  =========  =================================================================

The commands are strings because the bridge sends ``str(msg.pedal_cmd)``; the simulator
parses them. A command that is not the string of a finite number (or a number) is a
:class:`~sdc_gym.capstone.errors.MalformedCommand`; an out-of-range one is clamped, as the
original's car controller clamps its inputs.

Pose reference: the original reports the car's transform, near the middle of the body;
sdc-gym's pose is the rear axle, so :func:`telemetry_fields` reports the point
``centre_offset`` m ahead of it (the body's centre: ``TrackSetup.centre_offset``, 2.45 m
for the sim car). ``z`` is 0: the tracks are flat. Obstacles (parked cars) are reported
at their centres, z 0 too. The original's ``lidar`` event (``lidar_x``, ``lidar_y``,
``lidar_z`` lists) is never sent: sdc-gym has no lidar sensor.
"""

from __future__ import annotations

import base64
import io
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from sdc_gym.capstone.errors import MalformedCommand
from sdc_gym.units import MPS_TO_MPH

DEFAULT_HOST: Final = "127.0.0.1"
DEFAULT_PORT: Final = 4567  # the styx server's port in the original's server.py
TELEMETRY: Final = "telemetry"
CONTROL: Final = "control"
TRAFFIC_LIGHTS: Final = "trafficlights"
OBSTACLE: Final = "obstacle"
IMAGE: Final = "image"
STEER: Final = "steer"
THROTTLE: Final = "throttle"
BRAKE: Final = "brake"
DRAWLINE: Final = "drawline"
COMMAND_EVENTS: Final = (STEER, THROTTLE, BRAKE)
STACK_EVENTS: Final = (STEER, THROTTLE, BRAKE, DRAWLINE)
"""Every event a styx server sends to the simulator."""
COMMAND_FIELDS: Final = {STEER: "steering_angle", THROTTLE: "throttle", BRAKE: "brake"}
IMAGE_FORMATS: Final = ("jpeg", "png")
DEFAULT_JPEG_QUALITY: Final = 75  # Pillow's default


@dataclass(frozen=True)
class CarReport:
    """The car as the simulator reports it, SI units (see :func:`car_report`)."""

    x: float  # m, the body's centre
    y: float
    yaw: float  # rad, CCW from +x
    speed: float  # m/s
    dbw_enabled: bool
    throttle: float  # the actuators' actual values
    brake_torque: float  # N m
    road_wheel_angle: float  # rad


def car_report(info: Mapping[str, Any], centre_offset: float,
               road_wheel_ratio: float) -> CarReport:
    """The report of a ``TrackLoop-v0`` step's ``info`` (rear-axle pose, actual actuators)."""
    yaw = float(info["yaw"])
    return CarReport(
        x=float(info["x"]) + centre_offset * math.cos(yaw),
        y=float(info["y"]) + centre_offset * math.sin(yaw),
        yaw=yaw, speed=float(info["speed_mph"]) / MPS_TO_MPH,
        dbw_enabled=bool(info["dbw_enabled"]), throttle=float(info["throttle"]),
        brake_torque=float(info["brake_torque"]),
        road_wheel_angle=float(info["steering_wheel_angle"]) / road_wheel_ratio)


def telemetry_fields(car: CarReport) -> dict[str, Any]:
    """``telemetry``: x, y, z m; yaw degrees; velocity mph; dbw_enable."""
    return {"x": car.x, "y": car.y, "z": 0.0, "yaw": math.degrees(car.yaw),
            "velocity": car.speed * MPS_TO_MPH, "dbw_enable": car.dbw_enabled}


def control_fields(car: CarReport) -> dict[str, Any]:
    """``control``: the road-wheel angle in degrees, throttle, brake torque N m."""
    return {"steering_angle": math.degrees(car.road_wheel_angle), "throttle": car.throttle,
            "brake": car.brake_torque}


def traffic_light_fields(positions: NDArray[np.float64], facing_yaw: NDArray[np.float64],
                         states: NDArray[Any]) -> dict[str, Any]:
    """``trafficlights``: per light its housing's x, y, z (m), facing as dx, dy, state."""
    return {"light_pos_x": [float(v) for v in positions[:, 0]],
            "light_pos_y": [float(v) for v in positions[:, 1]],
            "light_pos_z": [float(v) for v in positions[:, 2]],
            "light_pos_dx": [math.cos(float(v)) for v in facing_yaw],
            "light_pos_dy": [math.sin(float(v)) for v in facing_yaw],
            "light_state": [int(v) for v in states]}


def obstacle_fields(centres: NDArray[np.float64]) -> dict[str, Any]:
    """``obstacle``: per obstacle its centre ``[x, y, z]`` (m, z 0 as in telemetry).

    ``centres`` is (n, 2) x, y, as the env stores them (``TrackWorld.state.obstacles``).
    The original's ``bridge.publish_obstacles`` reads ``obs[0], obs[1], obs[2]`` of each
    entry of ``data['obstacles']``, so each is a list of three numbers.
    """
    if centres.ndim != 2 or centres.shape[1] != 2:
        raise ValueError(f"obstacle centres must be an (n, 2) array of x, y, got shape "
                         f"{centres.shape}")
    return {"obstacles": [[float(x), float(y), 0.0] for x, y in centres.tolist()]}


def encode_image(frame: NDArray[np.uint8], image_format: str = "jpeg",
                 quality: int = DEFAULT_JPEG_QUALITY) -> str:
    """``image``: base64 (ASCII) of the RGB ``frame`` (H, W, 3) encoded with Pillow."""
    from PIL import Image

    if image_format not in IMAGE_FORMATS:
        raise ValueError(f"image format must be one of {IMAGE_FORMATS}, got {image_format!r}")
    buffer = io.BytesIO()
    options = {"quality": quality} if image_format == "jpeg" else {"compress_level": 1}
    Image.fromarray(frame).save(buffer, format=image_format.upper(), **options)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def command_value(event: str, data: Any) -> float:
    """The number of a ``steer``/``throttle``/``brake`` message (a string, as the bridge
    sends it; a JSON number is taken too). Raises :class:`MalformedCommand`."""
    field = COMMAND_FIELDS[event]
    if not isinstance(data, Mapping) or field not in data:
        raise MalformedCommand(f"the stack's {event!r} message must be an object with the "
                               f"field {field!r}, got {_show(data)}")
    raw = data[field]
    if isinstance(raw, bool) or not isinstance(raw, str | int | float):
        raise MalformedCommand(f"{event}.{field} must be the string of a number (the "
                               f"bridge sends str(value)), got {_show(raw)}")
    try:
        value = float(raw)
    except ValueError:
        raise MalformedCommand(f"{event}.{field} is not a number: {_show(raw)}") from None
    if not math.isfinite(value):
        raise MalformedCommand(f"{event}.{field} must be finite, got {_show(raw)}")
    return value


def drawline_points(data: Any) -> NDArray[np.float64]:
    """(m, 2) x, y of a ``drawline`` message. Raises :class:`MalformedCommand`."""
    if not isinstance(data, Mapping) or "next_x" not in data or "next_y" not in data:
        raise MalformedCommand(f"the stack's 'drawline' message must have 'next_x' and "
                               f"'next_y' lists, got {_show(data)}")
    xs, ys = data["next_x"], data["next_y"]
    if not isinstance(xs, list) or not isinstance(ys, list) or len(xs) != len(ys):
        raise MalformedCommand(f"drawline's next_x and next_y must be lists of one length, "
                               f"got {_show(xs)} and {_show(ys)}")
    try:
        points = np.array([xs, ys], dtype=np.float64).T.reshape(-1, 2)
    except (TypeError, ValueError):
        raise MalformedCommand(f"drawline's points must be numbers, got {_show(data)}") \
            from None
    if not np.isfinite(points).all():
        raise MalformedCommand("drawline's points must be finite")
    return points


def _show(value: Any, limit: int = 120) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."
