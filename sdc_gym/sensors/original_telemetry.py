"""The telemetry's Frenet fields as the original simulator computes them.

``HighwayLoop-v0`` simulates on its exact reference line; the original reports s and d
from its waypoint polyline (:mod:`sdc_gym.geometry.original_frenet`). With the env's
``frenet: original`` (the default), :func:`original_frenet_fields` replaces the exact
values of a telemetry message by the original's, from the same positions:

* ``s``, ``d``: the ego car's position, its own closest waypoint;
* ``end_path_s``, ``end_path_d``: the last unconsumed path point, from the waypoint closest
  to the **ego car** (the original computes them in the ego car's script); 0, 0 when the
  path is empty;
* each sensor fusion row's ``s``, ``d``: the row's (x, y), the car's own closest waypoint.
  A row that reads ``s == d == 0`` (the simulated sensor fault of
  :class:`~sdc_gym.sensors.highway_sensors.SensorConfig`) keeps its zeros; with position
  noise on, s and d follow the noisy x, y.

It runs only when a message is read (the telemetry is built lazily).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.original_frenet import OriginalFrenet

FloatArray = NDArray[np.float64]


def original_frenet_fields(
    frenet: OriginalFrenet, x: float, y: float, previous_path: FloatArray,
    sensor_fusion: FloatArray,
) -> tuple[float, float, float, float, FloatArray]:
    """``(s, d, end_path_s, end_path_d, sensor_fusion)`` by the original's rule.

    ``previous_path`` holds the unconsumed points ``(m, 2)``; ``sensor_fusion`` the present
    rows ``[id, x, y, vx, vy, s, d]`` (a converted copy is returned).
    """
    fusion = np.array(sensor_fusion, dtype=np.float64).reshape(-1, 7)
    has_end = len(previous_path) > 0
    # One conversion for all: the ego, the path's end (both anchored at the ego: the
    # original converts them in the ego car's script), then each car at its own position.
    ego = np.array([[x, y]])
    points = np.concatenate([ego, previous_path[-1:], fusion[:, 1:3]])
    anchors = np.concatenate([ego, ego[:int(has_end)], fusion[:, 1:3]])
    s, d = frenet.convert(points, anchors)
    end_s, end_d = (float(s[1]), float(d[1])) if has_end else (0.0, 0.0)
    if len(fusion):
        first = 1 + int(has_end)
        faulty = (fusion[:, 5] == 0.0) & (fusion[:, 6] == 0.0)
        fusion[:, 5] = np.where(faulty, 0.0, s[first:])
        fusion[:, 6] = np.where(faulty, 0.0, d[first:])
    return float(s[0]), float(d[0]), end_s, end_d, fusion
