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

from sdc_gym.config import excerpt

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
