"""Where an episode on an open road ends: its goal along the road and when it was reached.

A loop's episode ends after ``laps`` laps; an open road has no laps. Its episode ends
(terminated) in the first physics frame the ego reaches the *goal*: ``distance_target``
metres driven when the config sets one (the Bosch Challenge's 2.75 miles, on the
odometer as the simulator's "miles driven": the path the car drove, lane changes and all),
else the road's end (its s reaching
:attr:`~sdc_gym.road.highway_map.HighwayMap.end_s`, the last waypoint; the road's end
also ends an episode with a target not yet driven, unsuccessfully). The frame is kept
(:attr:`RoadGoal.time`): a timed run's time is that frame's, not the step's end (a step
is ``steps_per_action`` frames).
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
        self.target = None if distance_target is None else float(distance_target)
        self.end_s = road.end_s
        if self.active and self.target is not None and start_s + self.target > road.end_s:
            raise ConfigError(
                f"{owner}: config key 'distance_target' is {distance_target!r} m, but from the "
                f"start (s = {start_s:.1f} m) the road ends after {road.end_s - start_s:.1f} m; "
                f"valid: (0, {road.end_s - start_s:.1f}] or None (the road's end)")
        self.kind = "road_end" if distance_target is None else "distance_target"
        self.ended = np.zeros(envs, dtype=bool)  # the goal reached, or the road's end
        self.reached = np.zeros(envs, dtype=bool)
        self.time = np.full(envs, np.nan)
        self.odometer = np.zeros(envs)
        self.last_xy = np.zeros((envs, 2))

    def reset_at(self, env: int, xy: FloatArray) -> None:
        """Env ``env`` starts at ``xy``, nothing driven."""
        self.ended[env] = self.reached[env] = False
        self.time[env] = np.nan
        self.odometer[env] = 0.0
        self.last_xy[env] = xy

    def record(self, xy: FloatArray, s: FloatArray, steps: NDArray[np.int64],
               dt: float) -> NDArray[np.bool_]:
        """The envs whose episode ends at the goal or the road's end in this step's frames
        (``xy``: ``(envs, frames, 2)`` the ego's positions, ``s``: ``(envs, frames)``,
        ``steps``: the frames counted after them); keeps the time of the first frame at
        or past the goal."""
        if not self.active:
            return self.ended
        moves = np.diff(np.concatenate([self.last_xy[:, None], xy], axis=1), axis=1)
        driven = self.odometer[:, None] + np.cumsum(np.hypot(moves[..., 0], moves[..., 1]),
                                                    axis=1)
        self.odometer = driven[:, -1].copy()
        self.last_xy = xy[:, -1].copy()
        at_end = s >= self.end_s
        crossed = at_end if self.target is None else driven >= self.target
        for env in np.flatnonzero(~self.ended & (crossed.any(axis=1) | at_end.any(axis=1))
                                  ).tolist():
            self.ended[env] = True
            if crossed[env].any():
                frame = int(np.argmax(crossed[env]))
                self.time[env] = (int(steps[env]) - s.shape[1] + 1 + frame) * dt
                self.reached[env] = True
        return self.ended

    def reason(self, env: int) -> str:
        """The episode's end at the goal: ``distance_target`` or ``road_end``."""
        return self.kind if self.reached[env] else "road_end"

    def summary(self, env: int) -> dict[str, Any]:
        """``summary["goal"]``: the goal, whether and when it was reached, the odometer."""
        reached = bool(self.reached[env])
        return {"kind": self.kind, "distance_target": self.target, "end_s": float(self.end_s),
                "reached": reached, "time": float(self.time[env]) if reached else None,
                "driven": float(self.odometer[env])}
