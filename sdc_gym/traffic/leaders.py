"""The nearest object ahead and behind every car, in every lane: one sort per env.

A car's leader in a lane is the object (a car or the ego) occupying that lane with the
smallest positive gap in s ahead of it; its follower the one with the smallest gap
behind (a gap of 0, the same s, counts as behind; the car itself never counts). Gaps are
modular: ``rel`` holds every object's s minus the ego's, folded to ``[-L/2, L/2)``, and
the difference of two of them is the gap, folded once more to ``[-L/2, L/2)`` in the envs
where objects lie a quarter loop or more from the ego (``fold``). Ties (equal gaps) go to
the lowest object index.

Instead of comparing every car with every object (``O(n^2)`` per lane), the objects are
sorted by ``rel`` once per env, and per lane the next and previous occupant of every
sorted position come from one cumulative minimum and maximum: ``O(n log n)``. Without
folding, the leader of car ``i`` is the first occupant after ``i``'s block of equal
``rel`` values and its follower the last occupant up to that block (the lowest index
among equals, ``i`` left out). With folding, the loop wraps: the first occupant overall
(smallest ``rel``) may lie ahead and the last one behind, and the nearer of the two
candidates per side wins.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


def _gather(values: NDArray, index: NDArray) -> NDArray:
    """``values[..., index]`` along the last axis, ``index`` broadcasting on the others."""
    return np.take_along_axis(values, index, axis=-1)


def nearest_objects(rel: FloatArray, occupies: NDArray[np.bool_], fold: NDArray[np.bool_],
                    loop: float) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """Leaders and followers of the cars in every lane (see the module docstring).

    Args:
        rel: ``(envs, objects)`` s minus the ego's, folded; the cars first, the ego last.
        occupies: ``(envs, objects, lanes)`` which lanes each object occupies.
        fold: ``(envs,)`` whether gaps are folded in that env.
        loop: the loop length (m).

    Returns:
        ``(ahead, ahead_gap, behind, behind_gap)``, each ``(envs, lanes, cars)``: the
        object index (0 where there is none) and the gap in s (``inf`` where none; the
        gap behind is the negated difference, so ``>= 0``).
    """
    envs, objects = rel.shape
    cars = objects - 1
    half = 0.5 * loop
    order = np.argsort(rel, axis=1, kind="stable")  # by rel, then by index
    ranks = np.empty_like(order)
    np.put_along_axis(ranks, order, np.arange(objects)[None, :], axis=1)
    sorted_rel = np.take_along_axis(rel, order, axis=1)
    positions = np.arange(objects)
    # Blocks of equal rel: the first position of each position's block, and the first
    # position after it.
    new_block = np.ones((envs, objects), dtype=bool)
    np.not_equal(sorted_rel[:, 1:], sorted_rel[:, :-1], out=new_block[:, 1:])
    block_start = np.maximum.accumulate(np.where(new_block, positions, 0), axis=1)
    next_start = np.minimum.accumulate(np.where(new_block, positions, objects)[:, ::-1],
                                       axis=1)[:, ::-1]
    block_end = np.empty_like(next_start)
    block_end[:, :-1] = next_start[:, 1:]
    block_end[:, -1] = objects
    # Per lane, in sorted order: the first occupant at or after each position (objects:
    # none) and the last one at or before it (-1: none). Both get one extra column, so
    # that position `objects` (past the end) and -1 (before the start) can be looked up.
    member = np.take_along_axis(occupies, order[:, :, None], axis=1).transpose(0, 2, 1)
    lanes = member.shape[1]
    first_from = np.full((envs, lanes, objects + 1), objects, dtype=np.intp)
    first_from[..., :-1] = np.minimum.accumulate(
        np.where(member, positions, objects)[..., ::-1], axis=2)[..., ::-1]
    last_upto = np.full((envs, lanes, objects + 1), -1, dtype=np.intp)  # [p + 1]: <= p
    last_upto[..., 1:] = np.maximum.accumulate(np.where(member, positions, -1), axis=2)

    car_rank = ranks[:, None, :cars]  # (envs, 1, cars)
    car_end = _gather(block_end[:, None, :], car_rank)  # first position after i's block
    # Ahead: the first occupant past i's block.
    ahead_pos = _gather(first_from, car_end)
    # Behind: the last occupant up to i's block but i, then the first (lowest index)
    # occupant of that one's block, i excluded.
    behind_last = _gather(last_upto, car_end)
    is_self = behind_last == car_rank
    if np.count_nonzero(is_self):
        behind_last = np.where(is_self, _gather(last_upto, car_rank), behind_last)
    behind_pos = _gather(first_from, _gather(np.broadcast_to(
        block_start[:, None, :], (envs, lanes, objects)), np.maximum(behind_last, 0)))
    first_is_self = behind_pos == car_rank
    if np.count_nonzero(first_is_self):
        behind_pos = np.where(first_is_self, _gather(first_from, car_rank + 1), behind_pos)
    behind_pos = np.where(behind_last >= 0, behind_pos, objects)

    car_rel = rel[:, None, :cars]
    ahead, ahead_gap = _resolve(order, rel, car_rel, ahead_pos, objects, np.inf)
    behind, behind_delta = _resolve(order, rel, car_rel, behind_pos, objects, -np.inf)
    folded = np.flatnonzero(fold)
    if len(folded):
        # Gaps fold once more; the loop's other end offers one more candidate per side.
        ahead_gap = _fold(ahead_gap, half, loop)
        behind_delta = _fold(behind_delta, half, loop)
        wrap_ahead_pos = np.broadcast_to(first_from[..., :1], ahead_pos.shape)
        wrap_ahead, wrap_ahead_gap = _resolve(order, rel, car_rel, wrap_ahead_pos, objects,
                                              np.inf)
        wrap_ahead_gap = _fold(wrap_ahead_gap, half, loop)
        last = last_upto[..., -1:]  # the last occupant overall, then its block's first
        wrap_behind_pos = _gather(first_from, _gather(np.broadcast_to(
            block_start[:, None, :], (envs, lanes, objects)), np.maximum(last, 0)))
        wrap_behind_pos = np.where(last >= 0, wrap_behind_pos, objects)
        wrap_behind_pos = np.broadcast_to(wrap_behind_pos, behind_pos.shape)
        wrap_behind, wrap_behind_delta = _resolve(order, rel, car_rel, wrap_behind_pos,
                                                  objects, -np.inf)
        wrap_behind_delta = _fold(wrap_behind_delta, half, loop)
        rows = fold[:, None, None]
        ahead_ok = ahead_gap > 0.0
        wrap_ok = wrap_ahead_gap > 0.0
        take_wrap = wrap_ok & (~ahead_ok | (wrap_ahead_gap < ahead_gap)
                               | ((wrap_ahead_gap == ahead_gap) & (wrap_ahead < ahead)))
        new_ahead = np.where(take_wrap, wrap_ahead, np.where(ahead_ok, ahead, 0))
        new_gap = np.where(take_wrap, wrap_ahead_gap, np.where(ahead_ok, ahead_gap, np.inf))
        ahead = np.where(rows, new_ahead, ahead)
        ahead_gap = np.where(rows, new_gap, ahead_gap)
        self_index = np.arange(cars)[None, None, :]
        behind_ok = behind_delta <= 0.0
        wrap_ok = (wrap_behind_delta <= 0.0) & (wrap_behind != self_index)
        take_wrap = wrap_ok & (~behind_ok | (wrap_behind_delta > behind_delta)
                               | ((wrap_behind_delta == behind_delta)
                                  & (wrap_behind < behind)))
        new_behind = np.where(take_wrap, wrap_behind, np.where(behind_ok, behind, 0))
        new_delta = np.where(take_wrap, wrap_behind_delta,
                             np.where(behind_ok, behind_delta, -np.inf))
        behind = np.where(rows, new_behind, behind)
        behind_delta = np.where(rows, new_delta, behind_delta)
    # The gap behind as the search measured it: the negated difference (+ 0.0 turns the
    # -0.0 of a tie into 0.0, as the sum with a zero penalty did).
    behind_gap = np.negative(behind_delta)
    behind_gap += 0.0
    return ahead, ahead_gap, behind, behind_gap


def _resolve(order: IntArray, rel: FloatArray, car_rel: FloatArray, position: IntArray,
             objects: int, none: float) -> tuple[IntArray, FloatArray]:
    """Object index and raw difference ``rel[object] - rel[car]`` of sorted positions
    (position ``objects``: none, index 0 and difference ``none``)."""
    found = position < objects
    index = _gather(order[:, None, :], np.minimum(position, objects - 1))
    delta = _gather(rel[:, None, :], index) - car_rel
    return np.where(found, index, 0), np.where(found, delta, none)


def _fold(delta: FloatArray, half: float, loop: float) -> FloatArray:
    """Differences folded to ``[-L/2, L/2)`` (inf stays inf)."""
    with np.errstate(invalid="ignore"):
        folded = np.remainder(delta + half, loop) - half
    return np.where(np.isinf(delta), delta, folded)
