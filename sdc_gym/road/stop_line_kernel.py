"""The next stop line along a closed track, as a numba kernel (the track world asks it for
every env after every step; :meth:`TrackMap.next_stop_line
<sdc_gym.road.track_map.TrackMap.next_stop_line>` is its batch of one)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import py_mod
from sdc_gym.kernel_compiler import kernel


@kernel
def next_stop_line(sorted_s: NDArray[np.float64], sorted_index: NDArray[np.int64],
                   length: float, s: float) -> tuple[int, float]:
    """(index, m ahead in [0, length)) of the first stop line at or ahead of arc length
    ``s`` (``sorted_s``: the lines' s in increasing order, ``sorted_index``: their indices),
    wrapping at the loop end; ``(-1, inf)`` without lines."""
    count = sorted_s.size
    if count == 0:
        return -1, np.inf
    s = py_mod(s, length)
    for i in range(count):  # bisect_left: the first line at or beyond s
        if sorted_s[i] >= s:
            return sorted_index[i], sorted_s[i] - s
    return sorted_index[0], sorted_s[0] - s + length
