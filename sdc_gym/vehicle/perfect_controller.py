"""How the original highway simulator's "perfect controller" takes up and consumes a path.

From ``perfect_controller.cs`` (``udacity/self-driving-car-sim``,
``Assets/Standard Assets/Vehicles/Car/Scripts/perfect_controller.cs``), the script that
moves the ego car along the planner's points:

* **A new path** (``setControlPath``): find the point nearest the car (the first of
  equals). Points before it are dropped. The nearest point itself is dropped too
  (``ProgressPath``) when it is not the first point, or when it is the first and lies
  exactly on the car; a first point at any distance from the car is kept (the car is
  "behind the path" and steps onto it). Dropping from a path of one point empties it.
* **Every 0.02 s frame** (``ControllerUpdate``): with at least two points left, the car is
  placed on point 0, turned to face point 1, and point 0 is removed; with one point left,
  that point is removed and the car does not move (it stands where it is, and the
  telemetry's previous path is empty from then on); with none, nothing happens.

The env keeps each path (one per env of a batch) as an array and the index of its first
unconsumed point; :func:`adopted_start` gives that index for new paths,
:func:`frames_of_motion` how many of a span of frames move each car.
"""

from __future__ import annotations

import numpy as np
from numba import njit

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)


@njit(cache=True)
def adopted_start(path: np.ndarray, length: int, car_x: float, car_y: float) -> int:
    """Index of the first point of ``path`` (its first ``length`` points) the car will
    use (0 for an empty path; ``length`` when none is left)."""
    if length <= 0:
        return 0
    nearest, best, first = 0, np.inf, 0.0
    for k in range(length):
        dx = path[k, 0] - car_x
        dy = path[k, 1] - car_y
        distance_sq = dx * dx + dy * dy
        if k == 0:
            first = distance_sq
        if distance_sq < best:
            nearest, best = k, distance_sq
    if nearest > 0 or first == 0.0:
        return nearest + 1  # past the last point: the path is empty
    return 0


@njit(cache=True)
def frames_of_motion(remaining: int, frames: int) -> tuple[int, bool]:
    """Of ``frames`` frames with ``remaining`` unconsumed points: how many move the car,
    and whether the path's last point is discarded (one point left, a frame without
    motion)."""
    moves = min(frames, max(remaining - 1, 0))
    return moves, remaining >= 1 and moves < frames
