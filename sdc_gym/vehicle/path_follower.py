"""The highway ego's "perfect controller", for a batch of envs: paths in, poses out.

Every 0.02 s physics frame the car is placed on the next point of its path, facing the
point after (the original simulator's controller), so the spacing of the points is the
speed; a path that runs out stops the car dead where it stands. A path takes effect
``latency`` frames after it is sent; until then the car keeps consuming the old one.
How a path is taken up and consumed is the original's rule
(:mod:`sdc_gym.vehicle.perfect_controller`). The motion of every env's car over a step is
one compiled pass (:func:`drive_paths`); the heading is numpy's ``arctan2`` of the step
to the next point over the whole batch (its SIMD version, as the env was defined with).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry import exact_math
from sdc_gym.vehicle.perfect_controller import adopted_start, frames_of_motion

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

PHYSICS_DT = 0.02  # s: the original simulator's frame, one path point per frame


@njit(cache=True)
def send_paths(queue: np.ndarray, queue_length: np.ndarray, queue_due: np.ndarray,
               queue_head: np.ndarray, queue_count: np.ndarray, frame: np.ndarray,
               paths: np.ndarray, lengths: np.ndarray, latency: int) -> None:
    """Every env sends a path: it joins the env's queue, due ``latency`` frames on."""
    depth = queue.shape[1]
    for e in range(queue.shape[0]):
        slot = (queue_head[e] + queue_count[e]) % depth
        count = lengths[e]
        for k in range(count):  # element-wise: no array assignment's error path to compile
            queue[e, slot, k, 0], queue[e, slot, k, 1] = paths[e, k, 0], paths[e, k, 1]
        queue_length[e, slot] = count
        queue_due[e, slot] = frame[e] + latency
        queue_count[e] += 1


@njit(cache=True, inline="always")
def _arrive(e: int, xy: np.ndarray, frame: np.ndarray, path: np.ndarray,
            path_length: np.ndarray, path_start: np.ndarray, queue: np.ndarray,
            queue_length: np.ndarray, queue_due: np.ndarray, queue_head: np.ndarray,
            queue_count: np.ndarray) -> None:
    """Adopt env ``e``'s paths due by now: drop the points before the one nearest the car
    (and that one too if the car stands on it)."""
    depth = queue.shape[1]
    while queue_count[e] > 0 and queue_due[e, queue_head[e]] <= frame[e]:
        slot = queue_head[e]
        count = queue_length[e, slot]
        for k in range(count):
            path[e, k, 0], path[e, k, 1] = queue[e, slot, k, 0], queue[e, slot, k, 1]
        path_length[e] = count
        path_start[e] = adopted_start(path[e], count, xy[e, 0], xy[e, 1])
        queue_head[e] = (slot + 1) % depth
        queue_count[e] -= 1


@njit(cache=True)
def drive_paths(frames: int, xy: np.ndarray, frame: np.ndarray, path: np.ndarray,
                path_length: np.ndarray, path_start: np.ndarray, queue: np.ndarray,
                queue_length: np.ndarray, queue_due: np.ndarray, queue_head: np.ndarray,
                queue_count: np.ndarray, track: np.ndarray, step: np.ndarray,
                moving: np.ndarray, speed: np.ndarray) -> None:
    """Move every car ``frames`` frames along its path(s): positions ``track`` ``(envs,
    frames, 2)``; for the frames that move it, the step to the next point (whose angle
    is the heading) in ``step`` and ``moving``; speeds (m/s)."""
    for e in range(xy.shape[0]):
        x0, y0 = xy[e, 0], xy[e, 1]
        done = 0
        while done < frames:
            _arrive(e, xy, frame, path, path_length, path_start, queue, queue_length,
                    queue_due, queue_head, queue_count)
            # Move until the next arrival (splitting a stretch of one path in two moves
            # the car exactly as one stretch would).
            horizon = frames - done
            if queue_count[e] > 0:
                horizon = min(horizon, queue_due[e, queue_head[e]] - frame[e])
            first = path_start[e]
            moves, discard_last = frames_of_motion(path_length[e] - first, horizon)
            for j in range(horizon):
                f = done + j
                if j < moves:
                    here = first + j
                    track[e, f, 0], track[e, f, 1] = path[e, here, 0], path[e, here, 1]
                    step[e, f, 0] = path[e, here + 1, 0] - path[e, here, 0]
                    step[e, f, 1] = path[e, here + 1, 1] - path[e, here, 1]
                    moving[e, f] = True
                    xy[e, 0], xy[e, 1] = track[e, f, 0], track[e, f, 1]
                else:  # the path ran out: the car stands where it is
                    track[e, f, 0], track[e, f, 1] = xy[e, 0], xy[e, 1]
                    step[e, f, 0] = step[e, f, 1] = 0.0
                    moving[e, f] = False
            # One point left: a frame removes it, the car stands still.
            path_start[e] = path_length[e] if discard_last else first + moves
            done += horizon
            frame[e] += horizon
        # A path due now arrives before the observation (the original's lock-step: the
        # reply is applied, then the next telemetry goes out).
        _arrive(e, xy, frame, path, path_length, path_start, queue, queue_length,
                queue_due, queue_head, queue_count)
        for f in range(frames):
            px, py = (x0, y0) if f == 0 else (track[e, f - 1, 0], track[e, f - 1, 1])
            speed[e, f] = math.hypot(track[e, f, 0] - px, track[e, f, 1] - py) / PHYSICS_DT


@njit(cache=True)
def hold_headings(heading: np.ndarray, moving: np.ndarray, yaw: np.ndarray) -> None:
    """A frame that does not move the car keeps the heading before it; ``yaw`` becomes
    each car's heading after the last frame."""
    for e in range(heading.shape[0]):
        for f in range(heading.shape[1]):
            if not moving[e, f]:
                heading[e, f] = heading[e, f - 1] if f else yaw[e]
        yaw[e] = heading[e, heading.shape[1] - 1]


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

    def reset_at(self, env: int, xy: FloatArray, yaw: float) -> None:
        """Env ``env``'s car at ``xy`` facing ``yaw``, without a path."""
        self.xy[env] = xy
        self.yaw[env] = yaw
        self.frame[env] = 0
        self.path_length[env] = self.path_start[env] = 0
        self.queue_head[env] = self.queue_count[env] = 0

    def send(self, paths: FloatArray, lengths: IntArray) -> None:
        """Every env sends a path (``(envs, capacity, 2)``, the first ``lengths`` points)."""
        send_paths(self.queue, self.queue_length, self.queue_due, self.queue_head,
                   self.queue_count, self.frame, paths, lengths, self.latency)

    def remaining(self, env: int) -> FloatArray:
        """Env ``env``'s unconsumed path points."""
        return self.path[env, self.path_start[env]:self.path_length[env]]

    def drive(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Move every car one env step along its path(s): positions ``(envs, frames, 2)``,
        headings and speeds ``(envs, frames)`` after each frame."""
        frames, envs = self.frames_per_step, self.envs
        track = np.empty((envs, frames, 2))
        step = np.empty((envs, frames, 2))
        moving = np.empty((envs, frames), dtype=np.bool_)
        speed = np.empty((envs, frames))
        drive_paths(frames, self.xy, self.frame, self.path, self.path_length,
                    self.path_start, self.queue, self.queue_length, self.queue_due,
                    self.queue_head, self.queue_count, track, step, moving, speed)
        heading = exact_math.atan2(step[..., 1], step[..., 0])
        hold_headings(heading, moving, self.yaw)
        return track, heading, speed
