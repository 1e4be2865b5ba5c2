"""A cheap ``take_along_axis`` for the small arrays of the traffic kernels.

``np.take_along_axis`` builds its index grids on every call (several microseconds, more
than the gather on a dozen cars); here the flat offsets of each (values shape, index
shape) pair are built once and kept.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

_OFFSETS: dict[tuple[tuple[int, ...], tuple[int, ...]], NDArray[np.intp]] = {}


def gather(values: NDArray, index: NDArray) -> NDArray:
    """``np.take_along_axis(values, index, axis=-1)`` for C-contiguous ``values``; the
    leading dimensions of ``index`` are those of ``values`` or 1 (broadcast)."""
    key = (values.shape, index.shape)
    offsets = _OFFSETS.get(key)
    if offsets is None:
        lead = np.broadcast_shapes(values.shape[:-1], index.shape[:-1])
        offsets = np.zeros(lead, dtype=np.intp)
        for axis, size in enumerate(values.shape[:-1]):
            stride = int(np.prod(values.shape[axis + 1:]))  # elements per step of the axis
            if size > 1:
                shape = [1] * len(lead)
                shape[axis] = size
                offsets = offsets + (np.arange(size) * stride).reshape(shape)
        offsets = np.ascontiguousarray(np.broadcast_to(offsets, lead))[..., None]
        if len(_OFFSETS) > 256:
            _OFFSETS.clear()
        _OFFSETS[key] = offsets
    flat = index + offsets
    return values.take(flat) if values.flags.c_contiguous else np.ravel(values).take(flat)
