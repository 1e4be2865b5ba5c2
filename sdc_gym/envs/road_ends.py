"""Where an episode on an open road ends: its goal along the road and when it was reached.

A loop's episode ends after ``laps`` laps; an open road has no laps. Its episode ends
(terminated, a success) in the first physics frame the ego's s reaches the *goal*: the
start plus ``distance_target`` metres when the config sets one (the Bosch Challenge's
2.75 miles), else the road's end (:attr:`~sdc_gym.road.highway_map.HighwayMap.end_s`,
the last waypoint). The frame is kept (:attr:`RoadGoal.time`): a timed run's time is
that frame's, not the step's end (a step is ``steps_per_action`` frames).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.config import ConfigError
from sdc_gym.road.highway_map import HighwayMap

FloatArray = NDArray[np.float64]


class RoadGoal:
    """Per env of a world: whether and when the ego reached the open road's goal.

    Args:
        road: the world's map (a loop has no goal: :attr:`active` is False).
        start_s: the ego's start, m.
        distance_target: m past ``start_s`` (``None``: the road's end).
        envs: the batch size.
        owner: name for error messages.
    """

    def __init__(self, road: HighwayMap, start_s: float, distance_target: Any, envs: int,
                 owner: str) -> None:
        self.active = not road.closed
        if road.closed and distance_target is not None:
            raise ConfigError(f"{owner}: config key 'distance_target' is {distance_target!r}, "
                              "but the map is a loop (it ends after 'laps' laps); "
                              "distance_target is for open roads (None here)")
        if self.active and not 0.0 <= start_s < road.end_s:
            raise ConfigError(f"{owner}: config key 'start_s' is {start_s!r}; on this open "
                              f"road it must lie in [0, {road.end_s:.1f}) m (its end)")
        self.goal_s = road.end_s if distance_target is None else start_s + float(distance_target)
        if self.active and self.goal_s > road.end_s:
            raise ConfigError(
                f"{owner}: config key 'distance_target' is {distance_target!r} m, but from the "
                f"start (s = {start_s:.1f} m) the road ends after {road.end_s - start_s:.1f} m; "
                f"valid: (0, {road.end_s - start_s:.1f}] or None (the road's end)")
        self.kind = "road_end" if distance_target is None else "distance_target"
        self.reached = np.zeros(envs, dtype=bool)
        self.time = np.full(envs, np.nan)

    def reset_at(self, env: int) -> None:
        self.reached[env] = False
        self.time[env] = np.nan

    def record(self, s: FloatArray, steps: NDArray[np.int64], dt: float) -> NDArray[np.bool_]:
        """The envs whose ego reached the goal in this step's frames (``s``: ``(envs,
        frames)``, ``steps``: the frames counted after them); keeps the time of the first
        frame at or past the goal."""
        if not self.active:
            return self.reached
        crossed = s >= self.goal_s
        for env in np.flatnonzero(crossed.any(axis=1) & ~self.reached).tolist():
            frame = int(np.argmax(crossed[env]))
            self.time[env] = (int(steps[env]) - s.shape[1] + 1 + frame) * dt
            self.reached[env] = True
        return self.reached

    def summary(self, env: int) -> dict[str, Any]:
        """``summary["goal"]``: the goal's s, whether and when it was reached."""
        reached = bool(self.reached[env])
        return {"goal_s": float(self.goal_s), "kind": self.kind, "reached": reached,
                "time": float(self.time[env]) if reached else None}
