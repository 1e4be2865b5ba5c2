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
from numpy.typing import NDArray


def adopted_start(paths: NDArray[np.float64], lengths: NDArray[np.int64],
                  car_xy: NDArray[np.float64]) -> NDArray[np.int64]:
    """Per path (``(paths, points, 2)``, the first ``lengths`` points; ``car_xy``
    ``(paths, 2)``), the index of the first point the car will use (0 for an empty one)."""
    offset = paths - car_xy[:, None, :]  # squared distances: np.sum(offset**2, axis=-1),
    offset *= offset                     # in cheaper calls (the same two-term sums)
    distance_sq = offset[..., 0] + offset[..., 1]
    distance_sq[np.arange(paths.shape[1])[None, :] >= lengths[:, None]] = np.inf
    nearest = distance_sq.argmin(axis=1)
    past = (nearest > 0) | (distance_sq[:, 0] == 0.0)  # past the last point: empty
    return np.where(lengths > 0, nearest + past, 0)


def frames_of_motion(remaining: NDArray[np.int64], frames: int
                     ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Of ``frames`` frames with ``remaining`` unconsumed points (per path): how many move
    the car, and whether the path's last point is discarded (one point left, a frame
    without motion)."""
    moves = np.minimum(frames, np.maximum(remaining - 1, 0))
    return moves, (remaining >= 1) & (moves < frames)
