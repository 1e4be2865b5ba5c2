"""Contact between oriented rectangles (vehicle footprints), vectorized.

Separating-axis test: two convex boxes are disjoint exactly when their projections onto
one of the four edge normals do not overlap. A broad phase on centre distance (half the
sum of diagonals) keeps the common case (no car near) to a handful of array operations.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def boxes_overlap(
    center_a: ArrayLike, heading_a: ArrayLike, length_a: ArrayLike, width_a: ArrayLike,
    center_b: ArrayLike, heading_b: ArrayLike, length_b: ArrayLike, width_b: ArrayLike,
) -> NDArray[np.bool_]:
    """Whether box A and box B overlap (touching counts), broadcasting over all arguments.

    Centres have shape ``(..., 2)``; headings (rad, direction of the length axis),
    lengths and widths (m) broadcast against the centres' leading shape.
    """
    ca = np.asarray(center_a, dtype=np.float64)
    cb = np.asarray(center_b, dtype=np.float64)
    delta = cb - ca
    ha = np.asarray(heading_a, dtype=np.float64)
    hb = np.asarray(heading_b, dtype=np.float64)
    axes_a = (np.cos(ha), np.sin(ha))
    axes_b = (np.cos(hb), np.sin(hb))
    half_la, half_wa = 0.5 * np.asarray(length_a), 0.5 * np.asarray(width_a)
    half_lb, half_wb = 0.5 * np.asarray(length_b), 0.5 * np.asarray(width_b)
    overlap = np.ones(np.broadcast_shapes(delta.shape[:-1], ha.shape, hb.shape), dtype=bool)
    for cos_t, sin_t in (axes_a, axes_b):
        for ux, uy in ((cos_t, sin_t), (-sin_t, cos_t)):
            distance = np.abs(delta[..., 0] * ux + delta[..., 1] * uy)
            radius_a = (half_la * np.abs(axes_a[0] * ux + axes_a[1] * uy)
                        + half_wa * np.abs(-axes_a[1] * ux + axes_a[0] * uy))
            radius_b = (half_lb * np.abs(axes_b[0] * ux + axes_b[1] * uy)
                        + half_wb * np.abs(-axes_b[1] * ux + axes_b[0] * uy))
            overlap &= distance <= radius_a + radius_b
    return overlap


def first_contact(
    ego_xy: NDArray[np.float64], ego_heading: NDArray[np.float64], ego_length: float,
    ego_width: float, cars_x: NDArray[np.float64], cars_y: NDArray[np.float64],
    cars_heading: NDArray[np.float64], cars_length: NDArray[np.float64],
    cars_width: NDArray[np.float64], cars_id: NDArray[np.int64],
) -> NDArray[np.int64]:
    """Per time step, the id of a car touching the ego, or -1 (the nearest one if several).

    ``ego_xy`` is (k, 2), ``ego_heading`` (k,); the cars' poses are (k, n) and their
    sizes and ids (n,).
    """
    dx = cars_x - ego_xy[:, :1]
    dy = cars_y - ego_xy[:, 1:]
    distance_sq = dx * dx + dy * dy
    reach = 0.5 * (np.hypot(ego_length, ego_width) + np.hypot(cars_length, cars_width))
    near = distance_sq <= reach * reach
    contact = np.full(len(ego_xy), -1, dtype=np.int64)
    if not near.any():
        return contact
    steps, cars = np.nonzero(near)
    hit = boxes_overlap(
        ego_xy[steps], ego_heading[steps], ego_length, ego_width,
        np.stack([cars_x[steps, cars], cars_y[steps, cars]], axis=-1),
        cars_heading[steps, cars], cars_length[cars], cars_width[cars],
    )
    if hit.any():
        steps, cars = steps[hit], cars[hit]
        # Nearest first, so that a step touching two cars reports the closer one.
        order = np.lexsort((distance_sq[steps, cars], steps))[::-1]
        contact[steps[order]] = cars_id[cars[order]]
    return contact
