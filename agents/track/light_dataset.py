"""Seeded, balanced traffic-light images from the track camera, generated on the fly.

What a sample is
----------------
One frame of the project's :class:`~sdc_gym.sensors.track_camera.TrackCamera` (the camera
the env renders into its ``camera`` observation; by default the 200 x 150 ``training``
preset) seen from a car pose on a track, with every light of the track drawn like the env
draws them. A sample has a *kind*: the state of the one light that faces the camera
(RED 0, YELLOW 1, GREEN 2, UNKNOWN 4 = all lamps dark) or :data:`NO_LIGHT` (-1, no light
faces the camera). The classification target is its *class* (:func:`kind_classes`):
:data:`CLASS_RED` (0), :data:`CLASS_YELLOW` (1) or :data:`CLASS_OTHER` (2: green, dark or no
light). The detector's behavior layer stops for red, and for yellow when it can stop
comfortably; green and "nothing recognised" both mean "drive on", so they share a class.

Poses
-----
Light kinds: pick a light uniformly, put the car's reference point (rear axle) ``distance``
metres before its stop line along the track's reference line, ``distance`` uniform in
[``min_distance_m``, ``max_distance_m``] (default 0..100 m; the light stands 24 m past
the line), ``lateral`` uniform in [-``lateral_offset_m``, +``lateral_offset_m``] (within the
lane, d > 0 to the right) and the heading the road's plus a uniform jitter of
+-``yaw_jitter_rad``. :data:`NO_LIGHT`: the same jitter at an s uniform over the whole loop.

A proposal is kept only when its frame is unambiguous: for a light kind, exactly one light
faces the camera, it is the chosen one, and its lit lamp's centre lies inside the image
(a red light whose red lamp is cut off by the image edge is not a red image); for
:data:`NO_LIGHT`, no light faces the camera (the back of a housing may show). Rejected
samples are proposed again with the same kind, so the mix is exact.

Mix and balance
---------------
A batch of ``n`` has exact class counts: ``n x red_fraction`` red (default 40 %),
``n x yellow_fraction`` yellow (default 20 %) and the rest other, each count rounded down
and the few samples left over given to classes drawn without replacement with
probabilities proportional to the rounded-off fractions (so the expected counts are exact
too). The kinds of the *other* class are drawn from ``other_mix`` (default green 0.4,
unknown 0.2, no light 0.4); then the order is shuffled. The other lights of the track get
uniformly random states (the acceptance rule keeps them out of view or facing away).
Yellow is a fifth of the frames although it is a small part of a light's cycle: a missed
yellow is what makes a red-only stack run lights that turn red inside its braking distance.

Variation and determinism
-------------------------
Brightness and sensor noise are the camera's own (``CameraConfig.variation``). Everything
random comes from one ``numpy.random.Generator`` seeded by the dataset's ``seed``: the same
seed gives the same sequence of batches. Training uses its own seed; held-out evaluation
uses :data:`HELD_OUT_SEEDS`, which training refuses.

Crops
-----
:func:`crop_light` samples a light's pixel bounding box to a fixed :data:`CROP_SIZE_PX`
(rows x columns, 32 x 16: the housing is about twice as tall as wide) by nearest-neighbour
at pixel centres, the input of the crop classifier.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.road.track_map import TrackMap
from sdc_gym.sensors.track_camera import (
    LAMP_OFFSETS_M,
    LAMP_STATES,
    LIGHT_HOUSING_DEPTH_M,
    CameraConfig,
    TrackCamera,
    project_points,
)

NO_LIGHT = -1
"""Sample kind: no light faces the camera (not red)."""
LIGHT_KINDS = (RED, YELLOW, GREEN, UNKNOWN)
SAMPLE_KINDS = (*LIGHT_KINDS, NO_LIGHT)
KIND_NAMES = {RED: "red", YELLOW: "yellow", GREEN: "green", UNKNOWN: "unknown",
              NO_LIGHT: "no_light"}

# Car reference point (rear axle) before the stop line. 0 m: the env keeps a line as the
# next one until the rear axle crosses it (the last wheel_base + 1 m it is under the car),
# and the detector keeps classifying its light until then (a model trained from 2 m on
# called a green light yellow once per lap there).
DEFAULT_MIN_DISTANCE_M = 0.0
DEFAULT_MAX_DISTANCE_M = 100.0
DEFAULT_LATERAL_OFFSET_M = 1.5  # within a ~4 m lane around the path
# Heading jitter. The camera's half field of view is 8.85 deg; +-10 deg puts the light
# anywhere across the frame, edges included, as on curved approaches (the original track's
# first light shows at the image's right edge 60 m before its line; a CNN trained with
# +-3 deg missed it there).
DEFAULT_YAW_JITTER_RAD = math.radians(10.0)

# Classification targets (model output index). CLASS_STATES maps them to the light state
# codes the detector understands; "other" is reported as UNKNOWN (not red, not yellow).
CLASS_RED, CLASS_YELLOW, CLASS_OTHER = 0, 1, 2
CLASS_NAMES = ("red", "yellow", "other")
CLASS_STATES = (RED, YELLOW, UNKNOWN)
OTHER_KINDS = (GREEN, UNKNOWN, NO_LIGHT)

DEFAULT_RED_FRACTION = 0.4
DEFAULT_YELLOW_FRACTION = 0.2
DEFAULT_OTHER_MIX: tuple[tuple[int, float], ...] = ((GREEN, 0.4), (UNKNOWN, 0.2), (NO_LIGHT, 0.4))
# The crop classifier only ever sees a projected light, so its mix has no NO_LIGHT.
CROP_OTHER_MIX: tuple[tuple[int, float], ...] = ((GREEN, 0.7), (UNKNOWN, 0.3))

HELD_OUT_SEEDS = (1001, 1002, 1003, 1004)
"""Evaluation seeds; the training CLI refuses them, so evaluation frames are unseen."""

CROP_SIZE_PX = (32, 16)  # rows, columns

_COUNT_TOLERANCE = 1e-9
# Rejection sampling: a kind that is rarely acceptable (e.g. a track whose lights are all
# out of view from their approach) stops with an error instead of looping forever.
_MAX_PROPOSAL_ROUNDS = 200
# Lamp centre offset (m, up from the housing centre) per state.
_LAMP_OFFSET_BY_STATE = dict(zip(LAMP_STATES, LAMP_OFFSETS_M, strict=True))


@dataclass(frozen=True)
class DatasetConfig:
    """How poses and kinds are drawn (see the module docstring)."""

    min_distance_m: float = DEFAULT_MIN_DISTANCE_M
    max_distance_m: float = DEFAULT_MAX_DISTANCE_M
    lateral_offset_m: float = DEFAULT_LATERAL_OFFSET_M
    yaw_jitter_rad: float = DEFAULT_YAW_JITTER_RAD
    red_fraction: float = DEFAULT_RED_FRACTION
    yellow_fraction: float = DEFAULT_YELLOW_FRACTION
    other_mix: tuple[tuple[int, float], ...] = field(default=DEFAULT_OTHER_MIX)

    def __post_init__(self) -> None:
        if not 0 <= self.min_distance_m <= self.max_distance_m:
            raise ValueError(
                f"DatasetConfig: need 0 <= min_distance_m <= max_distance_m, got "
                f"{self.min_distance_m!r}, {self.max_distance_m!r}")
        for name in ("lateral_offset_m", "yaw_jitter_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"DatasetConfig.{name} must be a finite number >= 0, "
                                 f"got {value!r}")
        red, yellow = self.red_fraction, self.yellow_fraction
        if not (0 <= red <= 1 and 0 <= yellow <= 1 and red + yellow <= 1):
            raise ValueError(f"DatasetConfig: need red_fraction and yellow_fraction in [0, 1] "
                             f"with a sum <= 1, got {red!r}, {yellow!r}")
        kinds = [kind for kind, _ in self.other_mix]
        if not kinds or any(kind not in OTHER_KINDS for kind in kinds) or len(set(kinds)) != len(
                kinds):
            raise ValueError(f"DatasetConfig.other_mix: kinds must be distinct, from "
                             f"{list(OTHER_KINDS)} (GREEN, UNKNOWN, NO_LIGHT), got {kinds}")
        if any(not weight > 0 for _, weight in self.other_mix):
            raise ValueError(f"DatasetConfig.other_mix: weights must be > 0, got "
                             f"{self.other_mix}")

    @property
    def class_fractions(self) -> tuple[float, float, float]:
        """Fractions of red, yellow and other samples in a batch."""
        return (self.red_fraction, self.yellow_fraction,
                1.0 - self.red_fraction - self.yellow_fraction)


class LightBatch(NamedTuple):
    """``n`` samples. Arrays are indexed by sample."""

    images: NDArray[np.uint8]  # (n, H, W, 3) camera frames
    labels: NDArray[np.int64]  # (n,) the target: CLASS_RED, CLASS_YELLOW or CLASS_OTHER
    kinds: NDArray[np.int64]  # (n,) state of the facing light, or NO_LIGHT
    poses: NDArray[np.float64]  # (n, 3) car x, y (m, reference point), yaw (rad)
    light_index: NDArray[np.int64]  # (n,) the facing light, -1 for NO_LIGHT
    bboxes: NDArray[np.int64]  # (n, 4) its pixel bbox u_min, v_min, u_max, v_max; -1s
    distance_m: NDArray[np.float64]  # (n,) car to stop line along the road; NaN: NO_LIGHT

    @property
    def is_red(self) -> NDArray[np.bool_]:
        """(n,) whether the facing light is red (the detector's must-not-miss class)."""
        return self.labels == CLASS_RED


class _Proposals(NamedTuple):
    poses: NDArray[np.float64]  # (m, 3)
    light_index: NDArray[np.int64]  # (m,), -1 for NO_LIGHT
    distance_m: NDArray[np.float64]  # (m,)


class LightDataset:
    """An endless, seeded stream of :class:`LightBatch` from one track and camera.

    Args:
        track: the track whose lights and reference line are used.
        camera_config: the camera (default: ``CameraConfig.training()``, 200 x 150).
        seed: the generator seed; see :data:`HELD_OUT_SEEDS`.
        config: pose and mix parameters.
    """

    def __init__(self, track: TrackMap, camera_config: CameraConfig | None = None, *,
                 seed: int, config: DatasetConfig | None = None) -> None:
        if track.light_count == 0:
            raise ValueError(f"LightDataset: track {track.name!r} has no traffic lights")
        self.track = track
        self.camera = TrackCamera(CameraConfig.training() if camera_config is None
                                  else camera_config)
        self.config = DatasetConfig() if config is None else config
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        kinds, weights = zip(*self.config.other_mix, strict=True)
        self._other_kinds = np.array(kinds, dtype=np.int64)
        self._other_p = np.array(weights) / np.sum(weights)

    def class_counts(self, n: int) -> NDArray[np.int64]:
        """Red, yellow and other counts of a batch of ``n`` (see the module docstring)."""
        if n < 0:
            raise ValueError(f"batch size must be >= 0, got {n}")
        expected = n * np.array(self.config.class_fractions)
        # The tolerance keeps 40 x 0.4 = 16.000000000000004 from rounding as a remainder.
        counts = np.floor(expected + _COUNT_TOLERANCE).astype(np.int64)
        left = n - int(counts.sum())
        if left > 0:
            remainder = np.maximum(expected - counts, 0.0)
            extra = self.rng.choice(len(counts), size=left, replace=False,
                                    p=remainder / remainder.sum())
            counts[extra] += 1
        return counts

    def draw_kinds(self, n: int) -> NDArray[np.int64]:
        """``n`` kinds with exact class counts (:meth:`class_counts`), shuffled."""
        red, yellow, other = self.class_counts(n)
        rest = self.rng.choice(self._other_kinds, size=int(other), p=self._other_p)
        kinds = np.concatenate([np.full(red, RED), np.full(yellow, YELLOW), rest])
        return self.rng.permutation(kinds.astype(np.int64))

    def batch(self, n: int) -> LightBatch:
        """The next ``n`` samples of the stream."""
        kinds = self.draw_kinds(n)
        config = self.camera.config
        images = np.empty((n, config.height, config.width, 3), dtype=np.uint8)
        poses = np.empty((n, 3))
        light_index = np.full(n, -1, dtype=np.int64)
        bboxes = np.full((n, 4), -1, dtype=np.int64)
        distance = np.full(n, np.nan)
        pending = np.arange(n)
        for _ in range(_MAX_PROPOSAL_ROUNDS):
            if not len(pending):
                break
            proposals = self._propose(kinds[pending])
            rejected = []
            for row, sample in enumerate(pending):
                pose = proposals.poses[row]
                target = int(proposals.light_index[row])
                image, bbox = self._render(pose, target, int(kinds[sample]))
                if image is None:
                    rejected.append(sample)
                    continue
                images[sample] = image
                poses[sample] = pose
                if target >= 0:
                    light_index[sample] = target
                    bboxes[sample] = bbox
                    distance[sample] = proposals.distance_m[row]
            pending = np.asarray(rejected, dtype=np.int64)
        else:
            if len(pending):
                raise RuntimeError(
                    f"LightDataset: no acceptable pose for kinds "
                    f"{sorted({KIND_NAMES[int(k)] for k in kinds[pending]})} after "
                    f"{_MAX_PROPOSAL_ROUNDS} rounds on track {self.track.name!r}")
        return LightBatch(images, kind_classes(kinds), kinds, poses, light_index, bboxes,
                          distance)

    def _propose(self, kinds: NDArray[np.int64]) -> _Proposals:
        """Vectorized pose proposals for the given kinds."""
        track, cfg, rng = self.track, self.config, self.rng
        reference = track.reference
        m = len(kinds)
        has_light = kinds != NO_LIGHT
        light = np.where(has_light, rng.integers(0, track.light_count, size=m), -1)
        distance = rng.uniform(cfg.min_distance_m, cfg.max_distance_m, size=m)
        anywhere = rng.uniform(0.0, track.length, size=m)
        s = np.where(has_light, np.asarray(track.stop_line_s)[np.maximum(light, 0)] - distance,
                     anywhere)
        s = reference.wrap_s(s)
        lateral = rng.uniform(-cfg.lateral_offset_m, cfg.lateral_offset_m, size=m)
        jitter = rng.uniform(-cfg.yaw_jitter_rad, cfg.yaw_jitter_rad, size=m)
        xy = np.reshape(reference.to_xy(s, lateral), (m, 2))
        yaw = np.reshape(reference.heading(s), (m,)) + jitter
        poses = np.column_stack([xy, np.angle(np.exp(1j * yaw))])
        return _Proposals(poses, light.astype(np.int64), np.where(has_light, distance, np.nan))

    def _render(self, pose: NDArray[np.float64], target: int, kind: int
                ) -> tuple[NDArray[np.uint8] | None, tuple[int, int, int, int] | None]:
        """The frame and the target's bbox, or (None, None) when the frame is ambiguous."""
        track = self.track
        states = self.rng.choice(LIGHT_KINDS, size=track.light_count)
        if target >= 0:
            states[target] = kind
        x, y, yaw = (float(value) for value in pose)
        image, labels = self.camera.render_with_labels(
            x, y, yaw, track.light_positions, track.light_yaw, states, self.rng)
        facing = [label for label in labels if label.facing]
        if target < 0:
            return (image, None) if not facing else (None, None)
        if len(facing) != 1 or facing[0].index != target:
            return None, None
        if kind != UNKNOWN and not self._lamp_in_image(pose, target, kind):
            return None, None
        return image, facing[0].bbox

    def _lamp_in_image(self, pose: NDArray[np.float64], light: int, state: int) -> bool:
        """Whether the centre of ``light``'s ``state`` lamp projects inside the image."""
        center = self.track.light_positions[light]
        facing = float(self.track.light_yaw[light])
        half_depth = LIGHT_HOUSING_DEPTH_M / 2.0
        lamp = center + np.array([half_depth * math.cos(facing), half_depth * math.sin(facing),
                                  _LAMP_OFFSET_BY_STATE[state]])
        config = self.camera.config
        u, v, _ = project_points(lamp, float(pose[0]), float(pose[1]), float(pose[2]), config)
        return bool(0 <= u < config.width and 0 <= v < config.height)


def kind_classes(kinds: NDArray[np.int64]) -> NDArray[np.int64]:
    """The class (CLASS_RED, CLASS_YELLOW, CLASS_OTHER) of each sample kind."""
    kinds = np.asarray(kinds)
    unknown = sorted(set(np.unique(kinds).tolist()) - set(SAMPLE_KINDS))
    if unknown:
        raise ValueError(f"kind_classes: unknown kinds {unknown}; valid: {list(SAMPLE_KINDS)}")
    return np.where(kinds == RED, CLASS_RED,
                    np.where(kinds == YELLOW, CLASS_YELLOW, CLASS_OTHER)).astype(np.int64)


def crop_light(image: NDArray[np.uint8], bbox: tuple[int, int, int, int] | NDArray[np.int64],
               size: tuple[int, int] = CROP_SIZE_PX) -> NDArray[np.uint8]:
    """The bbox ``(u_min, v_min, u_max, v_max)`` (half-open, px) of ``image`` (H, W, 3)
    resampled to ``size`` (rows, columns) by nearest neighbour at pixel centres."""
    u_min, v_min, u_max, v_max = (int(value) for value in bbox)
    height, width = image.shape[:2]
    if not (0 <= u_min < u_max <= width and 0 <= v_min < v_max <= height):
        raise ValueError(f"crop_light: bbox {tuple(bbox)} must satisfy 0 <= u_min < u_max <= "
                         f"{width} and 0 <= v_min < v_max <= {height}")
    rows_out, cols_out = size
    rows = v_min + ((np.arange(rows_out) + 0.5) * ((v_max - v_min) / rows_out)).astype(np.int64)
    cols = u_min + ((np.arange(cols_out) + 0.5) * ((u_max - u_min) / cols_out)).astype(np.int64)
    return image[rows[:, None], cols[None, :]]

