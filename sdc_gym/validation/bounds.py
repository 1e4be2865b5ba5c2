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
