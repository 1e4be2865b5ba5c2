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

from sdc_gym.traffic.gather import gather

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


def nearest_objects(rel: FloatArray, occupies: NDArray[np.bool_], fold: NDArray[np.bool_],
                    loop: float) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """Leaders and followers of the cars in every lane (see the module docstring).

    Args:
        rel: ``(envs, objects)`` s minus the ego's, folded; the cars first, the ego last.
        occupies: ``(envs, lanes, objects)`` which lanes each object occupies.
        fold: ``(envs,)`` whether gaps are folded in that env.
        loop: the loop length (m).

    Returns:
        ``(ahead, ahead_gap, behind, behind_gap)``, each ``(envs, lanes, cars)``: the
        object index (0 where there is none) and the gap in s (``inf`` where none; the
        gap behind is the negated difference, so ``>= 0``).
    """
    envs, objects = rel.shape
    cars = objects - 1
    lanes = occupies.shape[1]
    positions = _positions(objects)
    order = rel.argsort(axis=1, kind="stable")  # by rel, then by index
    # Sorted rel with a sentinel column (position `objects`: none) of +inf (ahead) and
    # -inf (behind); the object index there is 0.
    sorted_hi = np.empty((envs, objects + 1))
    sorted_rel = sorted_hi[:, :-1]
    sorted_rel[...] = gather(rel, order)
    sorted_hi[:, -1] = np.inf
    sorted_lo = sorted_hi.copy()
    sorted_lo[:, -1] = -np.inf
    order_ext = np.zeros((envs, objects + 1), dtype=np.intp)
    order_ext[:, :-1] = order
    ranks = np.empty((envs, objects), dtype=np.intp)
    ranks[_rows(envs), order] = positions
    car_rank = ranks[:, None, :cars]
    ties = np.count_nonzero(sorted_rel[:, 1:] == sorted_rel[:, :-1])
    block_start = None
    if ties:  # blocks of equal rel: first position of each one's block, first after it
        new_block = np.ones((envs, objects), dtype=bool)
        np.not_equal(sorted_rel[:, 1:], sorted_rel[:, :-1], out=new_block[:, 1:])
        block_start = np.maximum.accumulate(np.where(new_block, positions, 0), axis=1)
        block_end = np.full((envs, objects), objects, dtype=np.intp)
        block_end[:, :-1] = np.minimum.accumulate(
            np.where(new_block, positions, objects)[:, :0:-1], axis=1)[:, ::-1]
        car_end = gather(block_end[:, None, :], car_rank)
    else:
        car_end = car_rank + 1
    # Per lane, in sorted order: the first occupant at or after each position (objects:
    # none) and the last one at or before it (-1: none). Both get one extra column, so
    # that position `objects` (past the end) and -1 (before the start) can be looked up.
    member = gather(occupies, order[:, None, :])
    first_from = np.full((envs, lanes, objects + 1), objects, dtype=np.intp)
    np.minimum.accumulate(np.where(member, positions, objects)[..., ::-1], axis=2,
                          out=first_from[..., -2::-1])
    last_upto = np.full((envs, lanes, objects + 1), -1, dtype=np.intp)  # [p + 1]: <= p
    np.maximum.accumulate(np.where(member, positions, -1), axis=2, out=last_upto[..., 1:])

    ahead_pos = gather(first_from, car_end)  # the first occupant past i's block
    # Behind: the last occupant up to i's block but i, then the first (lowest index)
    # occupant of that one's block, i excluded.
    behind_pos = gather(last_upto, car_end)
    is_self = behind_pos == car_rank
    if np.count_nonzero(is_self):
        behind_pos = np.where(is_self, gather(last_upto, car_rank), behind_pos)
    if block_start is not None:
        first = gather(first_from, gather(block_start[:, None, :], np.maximum(behind_pos, 0)))
        first_is_self = first == car_rank
        if np.count_nonzero(first_is_self):
            first = np.where(first_is_self, gather(first_from, car_rank + 1), first)
        behind_pos = np.where(behind_pos >= 0, first, -1)
    behind_pos %= objects + 1  # -1 (none) -> the sentinel column

    car_rel = rel[:, None, :cars]
    ahead = gather(order_ext[:, None, :], ahead_pos)
    ahead_gap = gather(sorted_hi[:, None, :], ahead_pos)
    ahead_gap -= car_rel
    behind = gather(order_ext[:, None, :], behind_pos)
    behind_delta = gather(sorted_lo[:, None, :], behind_pos)
    behind_delta -= car_rel
    if np.count_nonzero(fold):
        ahead, ahead_gap, behind, behind_delta = _wrap(
            fold, loop, order_ext, sorted_hi, sorted_lo, car_rel, first_from, last_upto,
            block_start, ahead, ahead_gap, behind, behind_delta)
    # The gap behind as the search measured it: the negated difference (+ 0.0 turns the
    # -0.0 of a tie into 0.0, as the sum with a zero penalty did).
    np.negative(behind_delta, out=behind_delta)
    behind_delta += 0.0
    return ahead, ahead_gap, behind, behind_delta


def _wrap(fold: NDArray[np.bool_], loop: float, order_ext: IntArray, sorted_hi: FloatArray,
          sorted_lo: FloatArray, car_rel: FloatArray, first_from: IntArray,
          last_upto: IntArray, block_start: IntArray | None, ahead: IntArray,
          ahead_gap: FloatArray, behind: IntArray, behind_delta: FloatArray
          ) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """Folded envs: gaps fold once more, and the loop's other end offers one more
    candidate per side (the first occupant overall ahead, the last one behind)."""
    half = 0.5 * loop
    objects = sorted_hi.shape[1] - 1
    cars = car_rel.shape[-1]
    shape = ahead.shape
    folded_ahead = _fold(ahead_gap, half, loop)
    folded_behind = _fold(behind_delta, half, loop)
    wrap_ahead_pos = np.ascontiguousarray(np.broadcast_to(first_from[..., :1], shape))
    wrap_ahead = gather(order_ext[:, None, :], wrap_ahead_pos)
    wrap_ahead_gap = _fold(gather(sorted_hi[:, None, :], wrap_ahead_pos) - car_rel, half, loop)
    last = last_upto[..., -1:]  # the last occupant overall, then its block's first
    if block_start is not None:
        last = np.where(last >= 0, gather(first_from, gather(
            block_start[:, None, :], np.maximum(last, 0))), -1)
    wrap_behind_pos = np.ascontiguousarray(np.broadcast_to(last % (objects + 1), shape))
    wrap_behind = gather(order_ext[:, None, :], wrap_behind_pos)
    wrap_behind_delta = _fold(gather(sorted_lo[:, None, :], wrap_behind_pos) - car_rel,
                              half, loop)
    ahead_ok = folded_ahead > 0.0
    wrap_ok = wrap_ahead_gap > 0.0
    take_wrap = wrap_ok & (~ahead_ok | (wrap_ahead_gap < folded_ahead)
                           | ((wrap_ahead_gap == folded_ahead) & (wrap_ahead < ahead)))
    new_ahead = np.where(take_wrap, wrap_ahead, np.where(ahead_ok, ahead, 0))
    new_gap = np.where(take_wrap, wrap_ahead_gap, np.where(ahead_ok, folded_ahead, np.inf))
    behind_ok = folded_behind <= 0.0
    wrap_ok = (wrap_behind_delta <= 0.0) & (wrap_behind != np.arange(cars))
    take_wrap = wrap_ok & (~behind_ok | (wrap_behind_delta > folded_behind)
                           | ((wrap_behind_delta == folded_behind) & (wrap_behind < behind)))
    new_behind = np.where(take_wrap, wrap_behind, np.where(behind_ok, behind, 0))
    new_delta = np.where(take_wrap, wrap_behind_delta,
                         np.where(behind_ok, folded_behind, -np.inf))
    rows = fold[:, None, None]
    return (np.where(rows, new_ahead, ahead), np.where(rows, new_gap, ahead_gap),
            np.where(rows, new_behind, behind), np.where(rows, new_delta, behind_delta))


def _fold(delta: FloatArray, half: float, loop: float) -> FloatArray:
    """Differences folded to ``[-L/2, L/2)`` (+-inf stay as they are)."""
    with np.errstate(invalid="ignore"):
        folded = np.remainder(delta + half, loop) - half
    return np.where(np.isinf(delta), delta, folded)


_CACHE: dict[tuple[str, int], NDArray[np.intp]] = {}


def _positions(count: int) -> NDArray[np.intp]:
    """``arange(count)`` (kept)."""
    key = ("positions", count)
    if key not in _CACHE:
        _CACHE[key] = np.arange(count)
    return _CACHE[key]


def _rows(envs: int) -> NDArray[np.intp]:
    """``arange(envs)[:, None]`` (kept)."""
    key = ("rows", envs)
    if key not in _CACHE:
        _CACHE[key] = np.arange(envs)[:, None]
    return _CACHE[key]
