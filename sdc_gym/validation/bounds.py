"""Sizes bounded by memory and time, each stated in the error that enforces it.

The audit's raw ``MemoryError``\\ s came from sizes nothing bounded: ``path_points: 10**8``
(the action space and its per-step bounds are (path_points, 2) arrays), ``car_count:
10**6`` (traffic arrays and the (C, 7) sensor fusion of every step), ``steps_per_action:
10**9`` (per-frame buffers of a step), a map around 1e12 m (the reference line is
resampled every 2 m). The bounds are far above any real use (the original: 50 points,
12 cars, 3 frames, 7 km) and far below what exhausts a machine.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from sdc_gym.config import ConfigError, excerpt

MAX_PATH_POINTS: Final = 10_000
"""Points of a highway path: 200 s of driving at one point per 0.02 s frame."""
MAX_CAR_COUNT: Final = 1_000
"""Traffic cars of one highway env."""
MAX_STEP_FRAMES: Final = 50_000
"""Physics frames in one env step (1,000 s): a step also never outlasts ``max_duration``."""
MAX_DURATION_S: Final = 10_000_000.0
"""Simulated seconds of one episode (about 116 days; an endurance run of 70 laps: 24,000)."""
MAX_LAPS: Final = 100_000
MAX_OBSTACLES: Final = 1_000
MAX_RENDER_PX: Final = 8_192
"""Width or height of a rendered frame."""
MAX_NUM_ENVS: Final = 4_096
"""Envs of one natively batched vector env (``gym.make_vec(..., num_envs=E)``): its arrays
grow with E times the per-env sizes above (10^7 envs ran 30 s into a MemoryError)."""
MAX_DECISION_PERIOD_S: Final = MAX_STEP_FRAMES * 0.02
"""Seconds between two decisions of a behavior env (1,000 s: the step bound's frames; a
period of 10^6 s allocated 8.94 GiB of per-frame buffers in the first step)."""
MAX_CAMERA_PX: Final = 4_096
"""Width or height of the track camera's image (the original: 800 x 600)."""
MAX_CAMERA_PIXELS: Final = 3_840 * 2_160
"""Pixels of one camera image (4K UHD; its float64 buffer is 200 MB; 10^6 x 600 took
13.4 GiB)."""
MAX_STOP_LINES: Final = 1_000
"""Stop lines of a light config (the original: 8); each is matched to the nearest of the
track's waypoints once at load."""
MAX_STOP_LINE_OFFSET_M: Final = 20.0
"""How far a stop line may lie from the track's path (the original's: at most 0.44 m; the
site's light file on the sim track: 1,314 m)."""
MAX_PATH_CHARS: Final = 4_096
"""Characters of a map, track or light file path (Linux' PATH_MAX)."""


def check_env_count(value: object, key: str = "num_envs") -> int:
    """``value`` as a batch's env count: an int (not a bool) in [1, :data:`MAX_NUM_ENVS`];
    ``ValueError`` naming ``key`` otherwise (``num_envs=True`` was a TypeError naming
    nothing)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer) or not (
            1 <= value <= MAX_NUM_ENVS):
        raise ValueError(f"{key} must be an int in [1, {MAX_NUM_ENVS}] (a batch's arrays "
                         f"grow with it), got {excerpt(value)} ({type(value).__name__})")
    return int(value)


# ---------------------------------------------------------------- batch products
# Each size above bounds one env; a batch multiplies them by num_envs (4,096 envs of
# 10,000 path points are 41 M points, 655 MB per path array), so the products are bounded
# too, before any array of the batch is allocated. A single env is the batch of one: the
# products hold for it as well (and admit every single env within the bounds above, but
# for the step's car updates: 1,000 cars x 50,000 frames is 5e7, past the 1.7e7).
MAX_BATCH_PATH_POINTS: Final = 4_194_304
"""num_envs x path_points (4,096 envs of 1,024 points): the batch's path arrays and its
action space, 16 bytes a point each."""
MAX_BATCH_CARS: Final = 262_144
"""num_envs x cars (traffic cars of the highway, obstacles of the track; 4,096 envs of 64):
the batch's traffic, sensor-fusion and collision arrays."""
MAX_BATCH_FRAMES: Final = 1_048_576
"""num_envs x physics frames per step (a decision of a behavior env): the per-frame buffers
of one step (4,096 envs of 256 frames, 5.12 s each; 4,096 x 1,024 frames measured 6.65 GB and
88 s a step on the highway, benchmarks/hostile_costs.py --batches)."""
MAX_BATCH_CAR_UPDATES: Final = 16_777_216
"""num_envs x cars x frames per step: the car updates one ``step()`` computes (4,096 envs of
16 cars for 256 frames; a single env of 1,000 cars steps at most 16,777 frames at once)."""
MAX_BATCH_CAMERA_PIXELS: Final = 4 * MAX_CAMERA_PIXELS
"""num_envs x camera pixels (four 4K UHD images: 33,177,600 px; 69 envs of the original
800 x 600): the batch's camera observations of every step."""


def check_batch_sizes(owner: str, envs: int, *, frames_per_step: int, path_points: int = 0,
                      cars: int = 0, camera_pixels: int = 0,
                      frames_key: str = "steps_per_action", cars_key: str = "car_count",
                      camera_key: str = "camera pixels") -> None:
    """``ConfigError`` naming the product, its factors and the bound when a batch of
    ``envs`` envs of these per-env sizes would pass one of the batch bounds above (each
    factor is already within its own bound: this is only about their product).

    Called by every batched world (:class:`~sdc_gym.envs.highway_world.HighwayWorld`,
    :class:`~sdc_gym.envs.track_world.TrackWorld`, hence every vector env, SB3 ``VecEnv``
    and single env) before it allocates a per-env array."""
    products = (
        ("path_points", path_points, MAX_BATCH_PATH_POINTS, "points of the batch's paths"),
        (cars_key, cars, MAX_BATCH_CARS, "cars of the batch"),
        (frames_key, frames_per_step, MAX_BATCH_FRAMES,
         "physics frames of one batch step: its per-frame buffers"),
        (camera_key, camera_pixels, MAX_BATCH_CAMERA_PIXELS,
         "camera pixels of one batch observation"),
    )
    for key, size, bound, what in products:
        if envs * size > bound:
            raise ConfigError(
                f"{owner}: num_envs x {key} must be at most {bound:,} ({what}), got {envs:,} x "
                f"{size:,} = {envs * size:,}; lower num_envs to at most {bound // size:,} "
                f"or {key} to at most {bound // envs:,}")
    updates = envs * cars * frames_per_step
    if updates > MAX_BATCH_CAR_UPDATES:
        raise ConfigError(
            f"{owner}: num_envs x {cars_key} x {frames_key} must be at most "
            f"{MAX_BATCH_CAR_UPDATES:,} (car updates of one step: its time), got {envs:,} x "
            f"{cars:,} x {frames_per_step:,} = {updates:,}; lower one of them")
