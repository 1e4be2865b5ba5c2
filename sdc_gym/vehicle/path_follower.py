"""The highway ego's "perfect controller", for a batch of envs: paths in, poses out.

Every 0.02 s physics frame the car is placed on the next point of its path, facing the
point after (the original simulator's controller), so the spacing of the points is the
speed; a path that runs out stops the car dead where it stands. A path takes effect
``latency`` frames after it is sent; until then the car keeps consuming the old one.
How a path is taken up and consumed is the original's rule
(:mod:`sdc_gym.envs.perfect_controller`). All envs of a batch send
their paths at the same frames (steps of ``frames_per_step``), so arrivals fall on the
same frame offsets of a step for all of them; the motion between arrivals is one set of
array expressions for every env.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sdc_gym.envs.perfect_controller import adopted_start, frames_of_motion

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

PHYSICS_DT = 0.02  # s: the original simulator's frame, one path point per frame


class PathFollower:
    """Paths, the paths in flight and the pose of ``envs`` ego cars.

    Args:
        envs: number of envs.
        capacity: most points a path holds.
        frames_per_step: physics frames per env step.
        latency: frames between sending a path and its taking effect.
    """

    def __init__(self, envs: int, capacity: int, frames_per_step: int, latency: int) -> None:
        self.envs = envs
        self.capacity = capacity
        self.frames_per_step = frames_per_step
        self.latency = latency
        depth = latency // frames_per_step + 2  # paths in flight at most
        self.xy = np.zeros((envs, 2))
        self.yaw = np.zeros(envs)
        self.frame = np.zeros(envs, dtype=np.int64)
        self.path = np.zeros((envs, capacity, 2))
        self.path_length = np.zeros(envs, dtype=np.int64)
        self.path_start = np.zeros(envs, dtype=np.int64)
        self.queue = np.zeros((envs, depth, capacity, 2))
        self.queue_length = np.zeros((envs, depth), dtype=np.int64)
        self.queue_due = np.zeros((envs, depth), dtype=np.int64)
        self.queue_head = np.zeros(envs, dtype=np.int64)
        self.queue_count = np.zeros(envs, dtype=np.int64)
        self._rows = np.arange(envs)
        self._steps = np.arange(capacity)

    def reset_at(self, env: int, xy: FloatArray, yaw: float) -> None:
        """Env ``env``'s car at ``xy`` facing ``yaw``, without a path."""
        self.xy[env] = xy
        self.yaw[env] = yaw
        self.frame[env] = 0
        self.path_length[env] = self.path_start[env] = 0
        self.queue_head[env] = self.queue_count[env] = 0

    def send(self, paths: FloatArray, lengths: IntArray) -> None:
        """Every env sends a path (``(envs, capacity, 2)``, the first ``lengths`` points)."""
        slot = (self.queue_head + self.queue_count) % self.queue.shape[1]
        self.queue[self._rows, slot] = paths
        self.queue_length[self._rows, slot] = lengths
        self.queue_due[self._rows, slot] = self.frame + self.latency
        self.queue_count += 1

    def remaining(self, env: int) -> FloatArray:
        """Env ``env``'s unconsumed path points."""
        return self.path[env, self.path_start[env]:self.path_length[env]]

    def _arrive(self) -> None:
        """Adopt the paths due by now: drop the points before the one nearest the car
        (and that one too if the car stands on it)."""
        while True:
            head = self.queue_head
            due = (self.queue_count > 0) & (self.queue_due[self._rows, head] <= self.frame)
            rows = np.flatnonzero(due)
            if not len(rows):
                return
            slot = head[rows]
            path = self.queue[rows, slot]
            length = self.queue_length[rows, slot]
            self.path[rows] = path
            self.path_length[rows] = length
            self.path_start[rows] = adopted_start(path, length, self.xy[rows])
            self.queue_head[rows] = (slot + 1) % self.queue.shape[1]
            self.queue_count[rows] -= 1

    def drive(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Move every car one env step along its path(s): positions ``(envs, frames, 2)``,
        headings and speeds ``(envs, frames)`` after each frame."""
        frames = self.frames_per_step
        envs = self.envs
        track = np.empty((envs, frames + 1, 2))  # row 0: where the cars start
        track[:, 0] = self.xy
        yaw = np.empty((envs, frames))
        done = 0
        while done < frames:
            self._arrive()
            # Every car moves until the next arrival of any (splitting a stretch of one
            # path in two moves the car exactly as one stretch would).
            horizon = frames - done
            waiting = self.queue_count > 0
            if np.count_nonzero(waiting):
                due = self.queue_due[self._rows, self.queue_head] - self.frame
                horizon = int(min(horizon, due[waiting].min()))
            first = self.path_start
            moves, discard_last = frames_of_motion(self.path_length - first, horizon)
            j = np.arange(horizon)[None, :]
            index = np.minimum(first[:, None] + j, self.capacity - 2)
            here = self.path[self._rows[:, None], index]
            ahead = self.path[self._rows[:, None], index + 1]
            heading = np.arctan2(ahead[..., 1] - here[..., 1], ahead[..., 0] - here[..., 0])
            moving = j < moves[:, None]
            last = np.maximum(moves - 1, 0)
            stopped_xy = np.where((moves > 0)[:, None], here[self._rows, last], self.xy)
            stopped_yaw = np.where(moves > 0, heading[self._rows, last], self.yaw)
            track[:, done + 1:done + 1 + horizon] = np.where(moving[..., None], here,
                                                             stopped_xy[:, None, :])
            yaw[:, done:done + horizon] = np.where(moving, heading, stopped_yaw[:, None])
            # One point left: a frame removes it, the car stands still.
            self.path_start = np.where(discard_last, self.path_length, first + moves)
            self.xy = stopped_xy
            self.yaw = stopped_yaw
            done += horizon
            self.frame = self.frame + horizon
        # A path due now arrives before the observation (the original's lock-step: the
        # reply is applied, then the next telemetry goes out).
        self._arrive()
        step = track[:, 1:] - track[:, :-1]
        speed = np.hypot(step[..., 0], step[..., 1])
        speed /= PHYSICS_DT
        return track[:, 1:], yaw, speed
