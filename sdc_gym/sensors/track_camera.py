"""A pinhole camera on the track car that sees traffic lights.

Frames and conventions
----------------------
World: x, y on the ground plane (m), z up (ground at z = 0); the car's pose is (x, y, yaw)
with yaw counter-clockwise from +x (rad). The camera sits ``mount_forward_m`` ahead of the
car's reference point along its heading, ``mount_height_m`` above the ground, looking
along the heading tilted up by ``pitch_rad`` (positive = nose up, no roll).

Camera frame (OpenCV): X right, Y down, Z forward (depth). With the camera-relative point
split into forward f, left l and up h (car frame, m)::

    X = -l
    Y = f sin(pitch) - h cos(pitch)
    Z = f cos(pitch) + h sin(pitch)

and the pinhole projection ``u = fx X / Z + cx``, ``v = fy Y / Z + cy`` (pixels). Image
coordinates are continuous: pixel column i spans [i, i + 1) (its centre at i + 0.5), so the
default principal point ``cx = width / 2``, ``cy = height / 2`` is the exact image centre.
The horizon (points far ahead at camera height) lies on row ``cy + fy tan(pitch)``.

Defaults match the original: an 800 x 600 image and the seed team's focal lengths
fx = 2574, fy = 2744 px: a narrow view, 17.7 deg wide and 12.5 deg tall. The camera is
pitched up 0.10 rad (5.7 deg) so that a light centred 5.5 m above the ground
(:data:`~sdc_gym.road.track_map.LIGHT_CENTER_HEIGHT_M`, the track's one definition), with
its pole 24 m past the stop line, stays fully in view from 150 m down to about 24 m
(camera to light, along the ground), i.e. while the car waits at the stop line: with the
sim car's front bumper on the line the camera is 26.5 m from the light. The horizon is
then near the bottom of the image (row 575 of 600). The ``training`` preset is the same
camera at a quarter of the resolution (200 x 150, intrinsics x 0.25).

A traffic light is a box :data:`LIGHT_HOUSING_WIDTH_M` x :data:`LIGHT_HOUSING_HEIGHT_M`
(1.0 x 1.95 m, the seed team's assumed size) x :data:`LIGHT_HOUSING_DEPTH_M`, centred at
its 3-D position, whose lamps face ``facing_yaw`` (a light meant for the car faces against
the car's heading). Three lamp discs on the front face: red top, yellow middle, green
bottom; the lamp of the current state is bright, the others dim (UNKNOWN: all dim). From
behind only the housing shows.

Rendering
---------
A background per config is computed once (sky gradient above the horizon, grass with a
straight grey road below it), copied per frame; lights in view are drawn far to near as a
filled housing rectangle (the pixel bounding box of the box's 8 projected corners) and lamp
ellipses (horizontal radius foreshortened by the viewing angle). Lights are skipped when
any housing corner is closer than :data:`NEAR_CLIP_M` in depth (behind or at the camera),
when their ground distance exceeds ``max_range_m``, or when their box is out of the image.

Variation (seeded, on by default): a global brightness gain uniform in
``[1 - brightness_jitter, 1 + brightness_jitter]`` (applied in steps of 1/64) and additive
Gaussian sensor noise of ``noise_sigma`` (0-255 levels, samples clipped at
+-:data:`NOISE_CLIP`). The noise comes from a fixed bank of Gaussian samples built once per
camera (twice the image size, from a constant seed); each frame reads a window of the bank
starting at an offset drawn from the caller's rng. Frames are therefore reproducible from
the rng, and different rng states give differently placed noise, without drawing
H x W x 3 normals per frame. Gain and noise are one fixed-point int16 pass.

Distance varies by itself: every frame sees the lights from where the car is, so a drive
(or a data set of sampled poses) shows each light from ``max_range_m`` down to its stop
line: its housing is about 10 px tall at 150 m and 50 px at the stop line (26.5 m) at the
training size. On top of that, ``distance_jitter`` (opt-in, default 0) draws one factor
``g`` per frame, uniform in ``[1 - j, 1 + j]``, and draws every housing and lamp ``g``
times its size about its centre: the light looks as if it were at ``1 / g`` of its
distance (the pinhole image of an object scaled by ``g`` about its centre is that of the
object moved along the view ray to ``1 / g`` of its depth, up to the perspective of the
0.5 m housing depth). The labels of :meth:`TrackCamera.render_with_labels` give the drawn
boxes; :func:`light_bounding_box` (no rng) gives the un-jittered one, so a crop-based
classifier sees at most ``j / 2`` of the box size of misalignment per side. It is off by
default so that such crops match exactly and default images stay as they were.

Labels: :meth:`TrackCamera.render_with_labels` also returns, per drawn light, its index,
its pixel bounding box (half-open integer bounds ``(u_min, v_min, u_max, v_max)``: crop
with ``image[v_min:v_max, u_min:u_max]``; it covers every pixel the housing touches), its
state, its depth and whether its lamps face the camera.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.config import ConfigError, excerpt, resolve_config
from sdc_gym.geometry import exact_math
from sdc_gym.lights.traffic_lights import GREEN, RED, VALID_STATES, YELLOW

# Re-exported: scenes and benchmarks place lights at the track's one housing height.
from sdc_gym.road.track_map import LIGHT_CENTER_HEIGHT_M as LIGHT_CENTER_HEIGHT_M
from sdc_gym.validation.bounds import MAX_CAMERA_PIXELS, MAX_CAMERA_PX

# --- the seed team's / original's camera ---------------------------------------------------
ORIGINAL_WIDTH_PX = 800
ORIGINAL_HEIGHT_PX = 600
SEED_FX_PX = 2574.0
SEED_FY_PX = 2744.0
TRAINING_SCALE = 0.25  # 800 x 600 -> 200 x 150

DEFAULT_MOUNT_HEIGHT_M = 1.5  # roof-line camera on a sedan
DEFAULT_MOUNT_FORWARD_M = 1.5  # behind the windshield, ahead of the reference point
DEFAULT_PITCH_RAD = 0.10  # up, keeps a 5.5 m high light in view from its stop line
DEFAULT_MAX_RANGE_M = 150.0
DEFAULT_BRIGHTNESS_JITTER = 0.2  # gain in [0.8, 1.2]
DEFAULT_NOISE_SIGMA = 4.0  # 0-255 levels
DEFAULT_DISTANCE_JITTER = 0.0  # opt-in apparent-distance factor spread (see module doc)
MAX_DISTANCE_JITTER = 0.2

# --- the traffic light housing ---------------------------------------------------------------
LIGHT_HOUSING_WIDTH_M = 1.0
LIGHT_HOUSING_HEIGHT_M = 1.95
LIGHT_HOUSING_DEPTH_M = 0.5
LAMP_SPACING_M = LIGHT_HOUSING_HEIGHT_M / 3.0  # centre to centre, red top .. green bottom
LAMP_RADIUS_M = 0.25
MIN_LAMP_RADIUS_PX = 0.75  # a lamp always covers at least the pixel under its centre
NEAR_CLIP_M = 0.5  # housing corners closer than this in depth: not drawn
# Lamp order top to bottom and their offsets from the housing centre (m, up).
LAMP_STATES = (RED, YELLOW, GREEN)
LAMP_OFFSETS_M = (LAMP_SPACING_M, 0.0, -LAMP_SPACING_M)

# --- colours (RGB, uint8) --------------------------------------------------------------------
SKY_TOP_RGB = (70, 120, 200)
SKY_HORIZON_RGB = (195, 215, 235)
SKY_GRADIENT_RAD = math.radians(15.0)  # elevation over which the sky fades to its top colour
GRASS_RGB = (70, 105, 50)
ROAD_RGB = (100, 100, 104)
ROAD_HALF_WIDTH_M = 6.0
HOUSING_RGB = (30, 30, 28)
LAMP_ON_RGB = {RED: (255, 35, 30), YELLOW: (255, 200, 20), GREEN: (40, 255, 90)}
LAMP_OFF_RGB = {RED: (70, 22, 20), YELLOW: (70, 58, 15), GREEN: (18, 62, 30)}

NOISE_BANK_SEED = 0x5DC_CA3  # the bank is a fixed table; the per-frame offset is seeded
MAX_BRIGHTNESS_JITTER = 0.5
# Fixed-point gain: 6 fractional bits. With gain <= 1.5 and |noise| <= NOISE_CLIP levels the
# int16 sum stays below 255 * 96 + 128 * 64 + 32 = 32704 < 32767.
_GAIN_SHIFT = 6
_GAIN_ONE = 1 << _GAIN_SHIFT
NOISE_CLIP = 128  # levels; noise samples beyond this are clipped (irrelevant below sigma 40)
PRESETS = ("full", "training")


# CameraConfig's number fields: a validity test and its wording in errors.
_NUMBER_CHECKS: dict[str, tuple[Callable[[float], bool], str]] = {
    "fx": (lambda value: value > 0, " > 0 px"),
    "fy": (lambda value: value > 0, " > 0 px"),
    "cx": (lambda value: True, " (px)"),
    "cy": (lambda value: True, " (px)"),
    "mount_height_m": (lambda value: value > 0, " > 0 m"),
    "mount_forward_m": (lambda value: True, " (m)"),
    "pitch_rad": (lambda value: abs(value) < math.pi / 2, " within (-pi/2, pi/2)"),
    "max_range_m": (lambda value: value > 0, " > 0 m"),
    "brightness_jitter": (lambda value: 0 <= value <= MAX_BRIGHTNESS_JITTER,
                          f" in [0, {MAX_BRIGHTNESS_JITTER}]"),
    "noise_sigma": (lambda value: value >= 0, " >= 0"),
    "distance_jitter": (lambda value: 0 <= value <= MAX_DISTANCE_JITTER,
                        f" in [0, {MAX_DISTANCE_JITTER}]"),
}


@dataclass(frozen=True)
class CameraConfig:
    """Pinhole intrinsics, mounting and image variation of the track camera.

    Attributes:
        width, height: image size, px.
        fx, fy: focal lengths, px.
        cx, cy: principal point, px (None: the image centre, width / 2 and height / 2).
        mount_height_m: camera height above the ground.
        mount_forward_m: camera ahead of the car's reference point, along the heading.
        pitch_rad: camera tilt, positive up.
        max_range_m: lights farther than this (ground distance) are not drawn.
        variation: apply brightness jitter and noise (needs an rng per frame).
        brightness_jitter: gain drawn uniformly in [1 - j, 1 + j], 0 <= j <= 0.5.
        noise_sigma: standard deviation of additive pixel noise, 0-255 levels.
        distance_jitter: lights are drawn at ``g`` times their size, ``g`` uniform in
            [1 - j, 1 + j] per frame (as if at ``1 / g`` of their distance); 0 <= j <= 0.2.
    """

    width: int = ORIGINAL_WIDTH_PX
    height: int = ORIGINAL_HEIGHT_PX
    fx: float = SEED_FX_PX
    fy: float = SEED_FY_PX
    cx: float | None = None
    cy: float | None = None
    mount_height_m: float = DEFAULT_MOUNT_HEIGHT_M
    mount_forward_m: float = DEFAULT_MOUNT_FORWARD_M
    pitch_rad: float = DEFAULT_PITCH_RAD
    max_range_m: float = DEFAULT_MAX_RANGE_M
    variation: bool = True
    brightness_jitter: float = DEFAULT_BRIGHTNESS_JITTER
    noise_sigma: float = DEFAULT_NOISE_SIGMA
    distance_jitter: float = DEFAULT_DISTANCE_JITTER

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not (
                    1 <= value <= MAX_CAMERA_PX):
                raise ValueError(f"CameraConfig.{name} must be an int in [1, {MAX_CAMERA_PX}] "
                                 f"px, got {excerpt(value)}")
        if self.width * self.height > MAX_CAMERA_PIXELS:
            raise ValueError(f"CameraConfig: width x height must be at most "
                             f"{MAX_CAMERA_PIXELS:,} pixels (4K UHD: each image is a float64 "
                             f"buffer of 24 bytes per pixel), got {self.width} x {self.height}")
        if self.cx is None:
            object.__setattr__(self, "cx", self.width / 2.0)
        if self.cy is None:
            object.__setattr__(self, "cy", self.height / 2.0)
        for name, (valid, expectation) in _NUMBER_CHECKS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or (
                    not math.isfinite(value)) or not valid(value):
                raise ValueError(f"CameraConfig.{name} must be a finite number{expectation}, "
                                 f"got {value!r}")
        if not isinstance(self.variation, bool):
            raise ValueError(f"CameraConfig.variation must be a bool, got {self.variation!r}")

    def scaled(self, factor: float) -> CameraConfig:
        """The same camera at ``factor`` x the resolution (intrinsics scaled alike)."""
        if not factor > 0:
            raise ValueError(f"scale factor must be > 0, got {factor!r}")
        assert self.cx is not None and self.cy is not None
        return dataclasses.replace(
            self, width=round(self.width * factor), height=round(self.height * factor),
            fx=self.fx * factor, fy=self.fy * factor, cx=self.cx * factor, cy=self.cy * factor)

    @classmethod
    def training(cls, **overrides: Any) -> CameraConfig:
        """200 x 150 preset: the original camera with intrinsics x 0.25 (fields overridable)."""
        return dataclasses.replace(cls().scaled(TRAINING_SCALE), **overrides)

    @classmethod
    def from_mapping(
        cls, config: Mapping[str, Any] | None = None, *, owner: str = "camera"
    ) -> CameraConfig:
        """Build from an env config mapping: keys ``preset`` ("full" or "training") and the
        field names; a field not given comes from the preset (cx, cy: the image centre)."""
        resolved = resolve_config(CAMERA_DEFAULTS, config, owner=owner)
        preset = resolved.pop("preset")
        if preset not in PRESETS:
            raise ConfigError(f"{owner}: config key 'preset' must be one of {PRESETS}, "
                              f"got {preset!r}")
        fields = dataclasses.asdict(cls() if preset == "full" else cls.training())
        fields["cx"] = fields["cy"] = None  # recomputed from the (possibly new) size
        given = dict(config or {})
        fields.update({key: value for key, value in resolved.items() if key in given})
        try:
            return cls(**fields)
        except ValueError as error:
            raise ConfigError(f"{owner}: {error}") from error


CAMERA_DEFAULTS: dict[str, Any] = {
    "preset": "full",  # "full" (800 x 600) or "training" (200 x 150)
    **{field.name: field.default for field in dataclasses.fields(CameraConfig)},
}


class LightLabel(NamedTuple):
    """A light drawn in a frame: what a crop-based classifier is trained on."""

    index: int  # which light (row of the positions passed to render)
    bbox: tuple[int, int, int, int]  # (u_min, v_min, u_max, v_max), half-open, px
    state: int  # its state code
    depth_m: float  # camera depth Z of the housing centre
    facing: bool  # True when the lamps face the camera (False: only the back shows)


# --- geometry ------------------------------------------------------------------------------


def camera_position(car_x: float, car_y: float, car_yaw: float,
                    config: CameraConfig) -> NDArray[np.float64]:
    """World position (3,) of the camera for a car pose, m."""
    return np.array([car_x + config.mount_forward_m * math.cos(car_yaw),
                     car_y + config.mount_forward_m * math.sin(car_yaw),
                     config.mount_height_m])


def world_to_camera(points_xyz: ArrayLike, car_x: float, car_y: float, car_yaw: float,
                    config: CameraConfig) -> NDArray[np.float64]:
    """World points (..., 3) -> camera frame (..., 3): X right, Y down, Z forward, m."""
    points = np.asarray(points_xyz, dtype=np.float64)
    if points.shape[-1:] != (3,):
        raise ValueError(f"points_xyz must have shape (..., 3), got {points.shape}")
    relative = points - camera_position(car_x, car_y, car_yaw, config)
    cos_yaw, sin_yaw = math.cos(car_yaw), math.sin(car_yaw)
    dx, dy, up = relative[..., 0], relative[..., 1], relative[..., 2]
    forward = dx * cos_yaw + dy * sin_yaw
    left = dy * cos_yaw - dx * sin_yaw
    cos_pitch, sin_pitch = math.cos(config.pitch_rad), math.sin(config.pitch_rad)
    return np.stack([-left, forward * sin_pitch - up * cos_pitch,
                     forward * cos_pitch + up * sin_pitch], axis=-1)


def project_points(points_xyz: ArrayLike, car_x: float, car_y: float, car_yaw: float,
                   config: CameraConfig
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Pixel coordinates ``(u, v, depth)`` of world points (..., 3); u, v are NaN where
    depth <= 0 (the point is not in front of the camera)."""
    camera = world_to_camera(points_xyz, car_x, car_y, car_yaw, config)
    depth = camera[..., 2]
    in_front = depth > 0
    safe = np.where(in_front, depth, 1.0)
    u = np.where(in_front, config.fx * camera[..., 0] / safe + config.cx, np.nan)
    v = np.where(in_front, config.fy * camera[..., 1] / safe + config.cy, np.nan)
    return u, v, depth


# Box corners in the light's own frame: (along the facing direction, to its left, up), m.
_CORNER_SIGNS = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)],
                         dtype=np.float64)
_HALF_SIZE = np.array([LIGHT_HOUSING_DEPTH_M, LIGHT_HOUSING_WIDTH_M,
                       LIGHT_HOUSING_HEIGHT_M]) / 2.0
_CORNERS_LOCAL = _CORNER_SIGNS * _HALF_SIZE


def _light_points(centers: NDArray[np.float64], yaws: NDArray[np.float64],
                  local: NDArray[np.float64]) -> NDArray[np.float64]:
    """World positions (..., n, 3) of points given in each light's frame (along its facing
    direction, to its left, up; m) for centres (..., 3) and facing yaws (...)."""
    cos_f, sin_f = exact_math.cos(yaws)[..., None], exact_math.sin(yaws)[..., None]
    points = np.empty((*yaws.shape, len(local), 3))
    points[..., 0] = centers[..., None, 0] + local[:, 0] * cos_f - local[:, 1] * sin_f
    points[..., 1] = centers[..., None, 1] + local[:, 0] * sin_f + local[:, 1] * cos_f
    points[..., 2] = centers[..., None, 2] + local[:, 2]
    return points


def light_box_corners(center_xyz: ArrayLike, facing_yaw: ArrayLike) -> NDArray[np.float64]:
    """The 8 world corners of light housings: centres (k, 3), yaws (k,) -> (k, 8, 3)
    (or (3,), scalar -> (8, 3))."""
    return _light_points(np.asarray(center_xyz, dtype=np.float64),
                         np.asarray(facing_yaw, dtype=np.float64), _CORNERS_LOCAL)


class _LightView(NamedTuple):
    """Vectorized projection of k lights (float pixel coordinates)."""

    visible: NDArray[np.bool_]  # (k,) in front, in range, box overlaps the image
    box: NDArray[np.float64]  # (k, 4) u_min, v_min, u_max, v_max (unclipped)
    depth: NDArray[np.float64]  # (k,) camera depth of the centre
    facing: NDArray[np.bool_]  # (k,) lamps face the camera
    foreshortening: NDArray[np.float64]  # (k,) |cos| of the angle front normal / view ray
    lamp_u: NDArray[np.float64]  # (k, 3) red, yellow, green lamp centres
    lamp_v: NDArray[np.float64]  # (k, 3)
    lamp_depth: NDArray[np.float64]  # (k, 3)
    scale: float  # the housing and lamps are drawn this many times their size


# Lamp centres on the front face in the light's own frame (along facing, left, up), m.
_LAMP_LOCAL = np.array([[LIGHT_HOUSING_DEPTH_M / 2.0, 0.0, offset] for offset in LAMP_OFFSETS_M])
# Points projected per light: 8 housing corners, 3 lamp centres, the housing centre.
_LIGHT_POINTS_LOCAL = np.concatenate([_CORNERS_LOCAL, _LAMP_LOCAL, np.zeros((1, 3))])
_CORNERS = slice(0, 8)
_LAMPS = slice(8, 11)
_CENTRE = 11


def _view_lights(centers: NDArray[np.float64], yaws: NDArray[np.float64], car_x: float,
                 car_y: float, car_yaw: float, config: CameraConfig,
                 scale: float = 1.0) -> _LightView:
    """Project every light's corners, lamps and centre in one pass (the per-frame hot spot);
    ``scale`` sizes the lights about their centres (the distance jitter)."""
    local = _LIGHT_POINTS_LOCAL if scale == 1.0 else _LIGHT_POINTS_LOCAL * scale
    camera = world_to_camera(_light_points(centers, yaws, local),
                             car_x, car_y, car_yaw, config)
    depth = camera[..., 2]
    safe = np.maximum(depth, NEAR_CLIP_M)  # only lights with every corner this far are drawn
    u = config.fx * camera[..., 0] / safe + config.cx
    v = config.fy * camera[..., 1] / safe + config.cy
    corner_u, corner_v = u[:, _CORNERS], v[:, _CORNERS]
    box = np.stack([corner_u.min(-1), corner_v.min(-1), corner_u.max(-1), corner_v.max(-1)],
                   axis=-1)
    overlaps = ((box[:, 0] < config.width) & (box[:, 2] > 0)
                & (box[:, 1] < config.height) & (box[:, 3] > 0))
    cos_yaw, sin_yaw = math.cos(car_yaw), math.sin(car_yaw)
    to_camera_x = car_x + config.mount_forward_m * cos_yaw - centers[:, 0]
    to_camera_y = car_y + config.mount_forward_m * sin_yaw - centers[:, 1]
    ground_distance = np.hypot(to_camera_x, to_camera_y)
    cos_view = (exact_math.cos(yaws) * to_camera_x + exact_math.sin(yaws) * to_camera_y
                ) / np.maximum(ground_distance, 1e-9)
    visible = (depth[:, _CORNERS].min(-1) >= NEAR_CLIP_M) & overlaps & (
        ground_distance <= config.max_range_m)
    return _LightView(visible, box, depth[:, _CENTRE], cos_view > 0, np.abs(cos_view),
                      u[:, _LAMPS], v[:, _LAMPS], depth[:, _LAMPS], scale)


def _pixel_bbox(box: NDArray[np.float64], config: CameraConfig) -> tuple[int, int, int, int]:
    """Half-open integer bounds of every pixel a float box touches, clipped to the image."""
    return (max(math.floor(box[0]), 0), max(math.floor(box[1]), 0),
            min(math.ceil(box[2]), config.width), min(math.ceil(box[3]), config.height))


def _check_lights(positions: ArrayLike, yaws: ArrayLike
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Light centres as (k, 3) and facing yaws as (k,), or a clear error."""
    centers = np.asarray(positions, dtype=np.float64)
    if centers.size == 0:
        centers = np.zeros((0, 3))
    if centers.ndim != 2 or centers.shape[1] != 3:
        raise ValueError(f"light positions must have shape (k, 3), got {centers.shape}")
    facing = np.asarray(yaws, dtype=np.float64).reshape(-1)
    if facing.shape != (len(centers),):
        raise ValueError(f"light yaws must have shape ({len(centers)},) like the positions, "
                         f"got {np.asarray(yaws).shape}")
    return centers, facing


def light_bounding_box(center_xyz: ArrayLike, facing_yaw: float, car_x: float, car_y: float,
                       car_yaw: float, config: CameraConfig
                       ) -> tuple[int, int, int, int] | None:
    """Pixel bounding box ``(u_min, v_min, u_max, v_max)`` (half-open, clipped to the image)
    of one light housing, or None when it is behind the camera, beyond ``max_range_m`` or
    out of the frame. Crop with ``image[v_min:v_max, u_min:u_max]``."""
    centers, yaws = _check_lights(np.reshape(center_xyz, (1, 3)), [facing_yaw])
    view = _view_lights(centers, yaws, car_x, car_y, car_yaw, config)
    return _pixel_bbox(view.box[0], config) if view.visible[0] else None


# --- rendering -----------------------------------------------------------------------------


def render_background(config: CameraConfig) -> NDArray[np.uint8]:
    """The static scene (H, W, 3): sky gradient above the horizon, grass and a straight
    road of half-width :data:`ROAD_HALF_WIDTH_M` below it."""
    assert config.cx is not None and config.cy is not None
    cos_p, sin_p = math.cos(config.pitch_rad), math.sin(config.pitch_rad)
    # Per row, the ray through the pixel centre (per unit depth): up and forward components.
    y = (np.arange(config.height) + 0.5 - config.cy) / config.fy
    ray_up = sin_p - y * cos_p
    ray_forward = cos_p + y * sin_p
    elevation = exact_math.atan2(ray_up, ray_forward)
    image = np.empty((config.height, config.width, 3), dtype=np.float64)
    blend = np.clip(elevation / SKY_GRADIENT_RAD, 0.0, 1.0)[:, None]
    sky = (1 - blend) * np.array(SKY_HORIZON_RGB) + blend * np.array(SKY_TOP_RGB)
    image[:] = sky[:, None, :]
    ground = ray_up < 0
    # Ground hit at t units of depth; the road edge is where the lateral offset is the
    # half-width: |u - cx| = fx * half_width / t.
    t = np.where(ground, config.mount_height_m / np.where(ground, -ray_up, 1.0), np.inf)
    half_width_px = config.fx * ROAD_HALF_WIDTH_M / t
    u = np.arange(config.width) + 0.5 - config.cx
    on_road = np.abs(u)[None, :] <= half_width_px[:, None]
    image[ground] = GRASS_RGB
    image[ground[:, None] & on_road] = ROAD_RGB
    return np.round(image).astype(np.uint8)


class TrackCamera:
    """Renders the camera image of the track with its traffic lights (see module doc)."""

    def __init__(self, config: CameraConfig | None = None) -> None:
        self.config = CameraConfig() if config is None else config
        config = self.config
        self.background = render_background(config)
        self.background.flags.writeable = False
        self._pixels = config.width * config.height * 3
        self._shape = (config.height, config.width, 3)
        self._noise_bank: NDArray[np.int16] | None = None
        if config.variation and config.noise_sigma > 0:
            # Stored pre-scaled for the fixed-point sum in _vary, rounding bias included.
            bank_rng = np.random.default_rng(NOISE_BANK_SEED)
            noise = np.clip(np.round(bank_rng.normal(0.0, config.noise_sigma,
                                                     2 * self._pixels)), -NOISE_CLIP, NOISE_CLIP)
            self._noise_bank = (noise * _GAIN_ONE + _GAIN_ONE // 2).astype(np.int16)
        self._work = np.empty(self._shape, dtype=np.int16)

    def render(self, car_x: float, car_y: float, car_yaw: float, light_positions: ArrayLike,
               light_yaws: ArrayLike, light_states: ArrayLike,
               rng: np.random.Generator | None = None) -> NDArray[np.uint8]:
        """The camera image (H, W, 3) uint8 for a car pose and k lights: positions (k, 3)
        (housing centres, m), facing yaws (k,) (rad), states (k,) (state codes). ``rng``
        is required when ``config.variation`` is on."""
        return self.render_with_labels(car_x, car_y, car_yaw, light_positions, light_yaws,
                                       light_states, rng)[0]

    def render_with_labels(
        self, car_x: float, car_y: float, car_yaw: float, light_positions: ArrayLike,
        light_yaws: ArrayLike, light_states: ArrayLike,
        rng: np.random.Generator | None = None,
    ) -> tuple[NDArray[np.uint8], list[LightLabel]]:
        """Like :meth:`render`, and the drawn lights' labels, nearest last."""
        config = self.config
        if config.variation and rng is None:
            raise ValueError("TrackCamera: config.variation is on, so render needs an rng "
                             "(or use CameraConfig(variation=False))")
        centers, yaws = _check_lights(light_positions, light_yaws)
        states = np.asarray(light_states).reshape(-1)
        if states.shape != (len(centers),):
            raise ValueError(f"light states must have shape ({len(centers)},), got "
                             f"{np.asarray(light_states).shape}")
        image = self.background.copy()
        labels: list[LightLabel] = []
        scale = 1.0
        if config.variation and config.distance_jitter > 0:
            assert rng is not None
            jitter = config.distance_jitter
            scale = float(rng.uniform(1.0 - jitter, 1.0 + jitter))
        if len(centers):
            view = _view_lights(centers, yaws, car_x, car_y, car_yaw, config, scale)
            drawn = np.flatnonzero(view.visible)
            for light in drawn[np.argsort(-view.depth[drawn], kind="stable")]:
                state = int(states[light])
                if state not in VALID_STATES:
                    raise ValueError(f"light {light}: state must be one of "
                                     f"{sorted(VALID_STATES)}, got {state!r}")
                self._draw_light(image, view, int(light), state)
                labels.append(LightLabel(int(light), _pixel_bbox(view.box[light], config),
                                         state, float(view.depth[light]),
                                         bool(view.facing[light])))
        if config.variation:
            assert rng is not None
            image = self._vary(image, rng)
        return image, labels

    def _draw_light(self, image: NDArray[np.uint8], view: _LightView, light: int,
                    state: int) -> None:
        config = self.config
        u_min, v_min, u_max, v_max = view.box[light]
        # Fill the pixels whose centres lie inside the box (at least one pixel).
        u0, v0 = math.ceil(u_min - 0.5), math.ceil(v_min - 0.5)
        u1, v1 = max(math.ceil(u_max - 0.5), u0 + 1), max(math.ceil(v_max - 0.5), v0 + 1)
        image[max(v0, 0):min(v1, config.height), max(u0, 0):min(u1, config.width)] = HOUSING_RGB
        if not view.facing[light]:
            return
        squeeze = view.foreshortening[light]
        lamp_radius = LAMP_RADIUS_M * view.scale
        for lamp, lamp_state in enumerate(LAMP_STATES):
            colour = LAMP_ON_RGB[lamp_state] if lamp_state == state else LAMP_OFF_RGB[lamp_state]
            depth = view.lamp_depth[light, lamp]
            radius_u = max(config.fx * lamp_radius * squeeze / depth, MIN_LAMP_RADIUS_PX)
            radius_v = max(config.fy * lamp_radius / depth, MIN_LAMP_RADIUS_PX)
            self._fill_ellipse(image, view.lamp_u[light, lamp], view.lamp_v[light, lamp],
                               radius_u, radius_v, colour)

    def _fill_ellipse(self, image: NDArray[np.uint8], u: float, v: float, radius_u: float,
                      radius_v: float, colour: tuple[int, int, int]) -> None:
        """Colour the pixels whose centres lie inside the axis-aligned ellipse."""
        config = self.config
        u0, u1 = max(math.floor(u - radius_u), 0), min(math.ceil(u + radius_u), config.width)
        v0, v1 = max(math.floor(v - radius_v), 0), min(math.ceil(v + radius_v), config.height)
        if u0 >= u1 or v0 >= v1:
            return
        across = ((np.arange(u0, u1) + 0.5 - u) / radius_u) ** 2
        down = ((np.arange(v0, v1) + 0.5 - v) / radius_v) ** 2
        inside = down[:, None] + across[None, :] <= 1.0
        image[v0:v1, u0:u1][inside] = colour

    def _vary(self, image: NDArray[np.uint8], rng: np.random.Generator) -> NDArray[np.uint8]:
        """Brightness gain and additive noise, both from ``rng`` (up to two draws per frame).

        Fixed point in int16: ``(image * round(gain * 64) + noise * 64 + 32) >> 6`` is the
        rounded ``image * gain + noise`` (gain in steps of 1/64), then clipped to 0..255.
        """
        config = self.config
        jitter = config.brightness_jitter
        gain = rng.uniform(1.0 - jitter, 1.0 + jitter) if jitter > 0 else 1.0
        work = self._work
        np.multiply(image, np.int16(round(gain * _GAIN_ONE)), out=work)
        if self._noise_bank is None:
            work += _GAIN_ONE // 2
        else:
            start = int(rng.integers(0, self._noise_bank.size - self._pixels + 1))
            work += self._noise_bank[start:start + self._pixels].reshape(self._shape)
        work >>= _GAIN_SHIFT
        out = np.empty(self._shape, dtype=np.uint8)
        np.clip(work, 0, 255, out=out, casting="unsafe")
        return out
