"""Contact between oriented rectangles (vehicle footprints), vectorized.

Separating-axis test: two convex boxes are disjoint exactly when their projections onto
one of the four edge normals do not overlap. :func:`first_contact` runs it in three
phases, each skipping the next whenever it can:

1. broad: centre distance against half the sum of the diagonals (circumscribed circles),
   a handful of array operations over every (step, car) pair, usually the end of it;
2. a sieve over the few pairs left, in plain Python: the separating-axis test on the ego's
   two axes only, with a margin (:data:`_SIEVE_MARGIN_M`) far above rounding, so it drops
   only pairs the full test would call apart (a car alongside in the next lane is near by
   the circles but 2 m clear across);
3. :func:`boxes_overlap`, the full test, for the pairs that survive (in practice: contacts).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

# m: slack of the sieve's test. Its projections differ from boxes_overlap's by rounding
# (~1e-14 m); a pair it drops is at least this far apart on an axis, so surely apart.
_SIEVE_MARGIN_M = 1e-6


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


def contact_reach_sq(ego_length: float, ego_width: float, cars_length: ArrayLike,
                     cars_width: ArrayLike) -> NDArray[np.float64]:
    """Squared centre distance (per car) within which the ego and a car can touch: half
    the sum of their diagonals, squared. Depends only on the sizes, so callers can keep it
    while the cars stay the same (:func:`first_contact`'s ``reach_sq``)."""
    reach = 0.5 * (np.hypot(ego_length, ego_width) + np.hypot(cars_length, cars_width))
    return reach * reach


def first_contact(
    ego_xy: NDArray[np.float64], ego_heading: NDArray[np.float64], ego_length: float,
    ego_width: float, cars_x: NDArray[np.float64], cars_y: NDArray[np.float64],
    cars_heading: NDArray[np.float64], cars_length: NDArray[np.float64],
    cars_width: NDArray[np.float64], cars_id: NDArray[np.int64],
    reach_sq: NDArray[np.float64] | None = None,
) -> NDArray[np.int64]:
    """Per time step, the id of a car touching the ego, or -1 (the nearest one if several).

    ``ego_xy`` is (k, 2), ``ego_heading`` (k,); the cars' poses are (k, n) and their
    sizes and ids (n,). ``reach_sq``: :func:`contact_reach_sq` of these sizes, if the
    caller keeps it (else it is computed here). One env of :func:`first_contacts`.
    """
    if reach_sq is None:
        reach_sq = contact_reach_sq(ego_length, ego_width, cars_length, cars_width)
    return first_contacts(ego_xy[None], ego_heading[None], ego_length, ego_width,
                          cars_x[None], cars_y[None], cars_heading[None],
                          np.asarray(cars_length)[None], np.asarray(cars_width)[None],
                          np.asarray(cars_id)[None], np.asarray(reach_sq)[None])[0]


def first_contacts(
    ego_xy: NDArray[np.float64], ego_heading: NDArray[np.float64], ego_length: float,
    ego_width: float, cars_x: NDArray[np.float64], cars_y: NDArray[np.float64],
    cars_heading: NDArray[np.float64], cars_length: NDArray[np.float64],
    cars_width: NDArray[np.float64], cars_id: NDArray[np.int64],
    reach_sq: NDArray[np.float64],
) -> NDArray[np.int64]:
    """:func:`first_contact` for a batch of envs: ``(envs, k)`` contact ids.

    ``ego_xy`` is (envs, k, 2), ``ego_heading`` (envs, k), the cars' poses (envs, k, n),
    their sizes, ids and ``reach_sq`` (envs, n).
    """
    envs, k = ego_heading.shape
    dx = cars_x - ego_xy[..., :1]
    dy = cars_y - ego_xy[..., 1:]
    distance_sq = dx * dx
    distance_sq += dy * dy
    near = distance_sq <= reach_sq[:, None, :]
    contact = np.full((envs, k), -1, dtype=np.int64)
    if not np.count_nonzero(near):  # not near.any(), at a quarter of the cost
        return contact
    env, steps, cars = np.nonzero(near)
    length, width = cars_length[env, cars], cars_width[env, cars]
    keep = _ego_axes_sieve(dx[env, steps, cars].tolist(), dy[env, steps, cars].tolist(),
                           ego_heading[env, steps].tolist(),
                           cars_heading[env, steps, cars].tolist(), length.tolist(),
                           width.tolist(), 0.5 * ego_length, 0.5 * ego_width)
    if not keep:
        return contact
    env, steps, cars = env[keep], steps[keep], cars[keep]
    hit = boxes_overlap(
        ego_xy[env, steps], ego_heading[env, steps], ego_length, ego_width,
        np.stack([cars_x[env, steps, cars], cars_y[env, steps, cars]], axis=-1),
        cars_heading[env, steps, cars], cars_length[env, cars], cars_width[env, cars],
    )
    if hit.any():
        env, steps, cars = env[hit], steps[hit], cars[hit]
        # Nearest first, so that a step touching two cars reports the closer one.
        flat = env * k + steps
        order = np.lexsort((distance_sq[env, steps, cars], flat))[::-1]
        contact.reshape(-1)[flat[order]] = cars_id[env[order], cars[order]]
    return contact


def _ego_axes_sieve(dx: list[float], dy: list[float], ego_heading: list[float],
                    car_heading: list[float], car_length: list[float], car_width: list[float],
                    half_length: float, half_width: float) -> list[int]:
    """Indices of the (ego, car) pairs not separated along the ego's length or width axis.

    The separating-axis test on those two of the four axes, per pair on Python floats (a
    few pairs, where numpy's per-call cost would dominate), loosened by
    :data:`_SIEVE_MARGIN_M`: a pair it drops does not overlap. ``dx, dy``: car centre
    minus ego centre.
    """
    cos, sin = math.cos, math.sin
    keep = []
    for index, (x, y, heading, other, length, width) in enumerate(
            zip(dx, dy, ego_heading, car_heading, car_length, car_width, strict=True)):
        c, s = cos(heading), sin(heading)
        turn = other - heading
        along, across = abs(cos(turn)), abs(sin(turn))
        # The car's half extents projected on the ego's axes: its radius on each.
        if (abs(x * c + y * s) <= half_length + 0.5 * (length * along + width * across)
                + _SIEVE_MARGIN_M
                and abs(y * c - x * s) <= half_width + 0.5 * (length * across + width * along)
                + _SIEVE_MARGIN_M):
            keep.append(index)
    return keep
