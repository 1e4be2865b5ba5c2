"""Geometry helpers shared by the top-down renderers (no pygame here).

* :func:`circular_runs` picks the stretches of a closed road that are in view, as index
  runs over its samples, so a renderer transforms and draws only those;
* :func:`box_corners` gives the corners of oriented boxes (car bodies, windscreens,
  obstacles) in map coordinates.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

CHUNK_SEGMENTS = 48
"""A run of visible samples is drawn in chunks of at most this many segments, so each road
polygon stays simple even when the whole loop is in view."""


def circular_runs(mask: NDArray[np.bool_], closed: bool = True) -> list[NDArray[np.intp]]:
    """Index runs of consecutive True samples on a closed loop, each grown by one sample
    at both ends (so lines reach past the view edge), split into bounded chunks; on an
    open road (``closed`` False) the runs stop at its ends instead of wrapping."""
    n = mask.size
    if not mask.any():
        return []
    if not closed:
        hits = np.flatnonzero(mask)
        breaks = np.flatnonzero(np.diff(hits) > 1) + 1
        runs = [np.arange(max(run[0] - 1, 0), min(run[-1] + 2, n))
                for run in np.split(hits, breaks)]
    elif mask.all():
        runs = [np.arange(n + 1) % n]  # the whole loop, closed
    else:
        first_false = int(np.argmin(mask))
        hits = np.flatnonzero(np.roll(mask, -first_false))
        breaks = np.flatnonzero(np.diff(hits) > 1) + 1
        runs = [
            (np.arange(run[0] - 1, run[-1] + 2) + first_false) % n
            for run in np.split(hits, breaks)
        ]
    chunks = []
    for run in runs:
        # Neighbouring chunks share a whole segment, so their polygons overlap (no seam).
        for start in range(0, len(run) - 1, CHUNK_SEGMENTS):
            chunks.append(run[max(start - 1, 0) : start + CHUNK_SEGMENTS + 1])
    return chunks


def box_corners(
    xy: NDArray[np.float64],
    heading: NDArray[np.float64],
    front: NDArray[np.float64],
    back: NDArray[np.float64],
    half_width: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(n, 4, 2) corners of boxes spanning ``back..front`` metres along the heading from
    ``xy`` and ``±half_width`` across it."""
    fwd = np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    right = np.stack([fwd[:, 1], -fwd[:, 0]], axis=-1)
    along = np.stack([front, front, back, back], axis=-1)[..., None]
    across = np.stack([-half_width, half_width, half_width, -half_width], axis=-1)[..., None]
    return xy[:, None, :] + along * fwd[:, None, :] + across * right[:, None, :]
