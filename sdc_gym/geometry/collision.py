"""Contact between oriented rectangles (vehicle footprints), vectorized.

Separating-axis test: two convex boxes are disjoint exactly when their projections onto
one of the four edge normals do not overlap. :func:`first_contact` runs it in three
phases, each skipping the next whenever it can:

1. broad: centre distance against half the sum of the diagonals (circumscribed circles),
   for every (step, car) pair, usually the end of it;
2. a sieve over the few pairs left: the separating-axis test on the ego's two axes only,
   with a margin (:data:`_SIEVE_MARGIN_M`) far above rounding, so it drops only pairs the
   full test would call apart (a car alongside in the next lane is near by the circles
   but 2 m clear across); phases 1 and 2 are one compiled pass over the batch;
3. :func:`boxes_overlap`, the full test, for the pairs that survive (in practice: contacts).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry import exact_math

_FROM_SIZES = np.zeros((0, 0))  # _near_pairs: the reach from the cars' sizes

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
    axes_a = (exact_math.cos(ha), exact_math.sin(ha))
    axes_b = (exact_math.cos(hb), exact_math.sin(hb))
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
    reach_sq: NDArray[np.float64] | None = None,
) -> NDArray[np.int64]:
    """:func:`first_contact` for a batch of envs: ``(envs, k)`` contact ids.

    ``ego_xy`` is (envs, k, 2), ``ego_heading`` (envs, k), the cars' poses (envs, k, n),
    their sizes, ids and ``reach_sq`` (envs, n; ``None``: from the sizes). The broad
    phase and the sieve are one compiled pass (:func:`_near_pairs`); the full test runs on
    the pairs it keeps (in practice: contacts).
    """
    envs, k = ego_heading.shape
    contact = np.full((envs, k), -1, dtype=np.int64)
    if cars_x.shape[-1] == 0:
        return contact
    reach_sq = _FROM_SIZES if reach_sq is None else np.ascontiguousarray(reach_sq,
                                                                         dtype=np.float64)
    pairs = np.empty((max(64, envs * k), 3), dtype=np.int64)
    count = _near_pairs(ego_xy, ego_heading, 0.5 * ego_length, 0.5 * ego_width, cars_x,
                        cars_y, cars_heading, cars_length, cars_width, reach_sq, pairs)
    if not count:
        return contact
    if count > len(pairs):  # more than the buffer held: once more with room for all
        pairs = np.empty((count, 3), dtype=np.int64)
        _near_pairs(ego_xy, ego_heading, 0.5 * ego_length, 0.5 * ego_width, cars_x, cars_y,
                    cars_heading, cars_length, cars_width, reach_sq, pairs)
    env, steps, cars = pairs[:count].T
    hit = boxes_overlap(
        ego_xy[env, steps], ego_heading[env, steps], ego_length, ego_width,
        np.stack([cars_x[env, steps, cars], cars_y[env, steps, cars]], axis=-1),
        cars_heading[env, steps, cars], cars_length[env, cars], cars_width[env, cars],
    )
    if hit.any():
        env, steps, cars = env[hit], steps[hit], cars[hit]
        dx = cars_x[env, steps, cars] - ego_xy[env, steps, 0]
        dy = cars_y[env, steps, cars] - ego_xy[env, steps, 1]
        distance_sq = dx * dx
        distance_sq += dy * dy
        # Nearest first, so that a step touching two cars reports the closer one.
        flat = env * k + steps
        order = np.lexsort((distance_sq, flat))[::-1]
        contact.reshape(-1)[flat[order]] = cars_id[env[order], cars[order]]
    return contact


@njit(cache=True)
def _near_pairs(ego_xy: np.ndarray, ego_heading: np.ndarray, half_length: float,
                half_width: float, cars_x: np.ndarray, cars_y: np.ndarray,
                cars_heading: np.ndarray, cars_length: np.ndarray, cars_width: np.ndarray,
                reach_sq: np.ndarray, pairs: np.ndarray) -> int:
    """The (env, step, car) pairs within the broad phase's reach (centre distance against
    half the sum of the diagonals) that the sieve does not separate along the ego's
    length or width axis (the separating-axis test on those two of the four axes,
    loosened by :data:`_SIEVE_MARGIN_M`: a pair it drops does not overlap). ``reach_sq``:
    :func:`contact_reach_sq`, or an empty array to work it out from the sizes. Returns
    how many; the first ``len(pairs)`` of them are written into ``pairs``."""
    count = 0
    envs, k, cars = cars_x.shape
    own = math.hypot(2.0 * half_length, 2.0 * half_width)
    reach = np.empty(cars)
    for e in range(envs):
        for c in range(cars):
            if reach_sq.size:
                reach[c] = reach_sq[e, c]
            else:
                radius = 0.5 * (own + math.hypot(cars_length[e, c], cars_width[e, c]))
                reach[c] = radius * radius
        for t in range(k):
            ex, ey = ego_xy[e, t, 0], ego_xy[e, t, 1]
            for c in range(cars):
                x = cars_x[e, t, c] - ex
                y = cars_y[e, t, c] - ey
                distance_sq = x * x
                distance_sq += y * y
                if not distance_sq <= reach[c]:
                    continue
                heading = ego_heading[e, t]
                co, si = math.cos(heading), math.sin(heading)
                turn = cars_heading[e, t, c] - heading
                along, across = abs(math.cos(turn)), abs(math.sin(turn))
                length, width = cars_length[e, c], cars_width[e, c]
                # The car's half extents projected on the ego's axes: its radius on each.
                if (abs(x * co + y * si) <= half_length + 0.5 * (length * along + width * across)
                        + _SIEVE_MARGIN_M
                        and abs(y * co - x * si) <= half_width + 0.5 * (
                            length * across + width * along) + _SIEVE_MARGIN_M):
                    if count < pairs.shape[0]:
                        pairs[count, 0], pairs[count, 1], pairs[count, 2] = e, t, c
                    count += 1
    return count
