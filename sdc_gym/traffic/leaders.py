"""The nearest object ahead and behind every car, in every lane: one sort per env.

A car's leader in a lane is the object (a car or the ego) occupying that lane with the
smallest positive gap ``delta`` in s ahead of it; its follower the one with the smallest
``-delta >= 0`` behind it (a gap of 0, the same s, counts as behind; the car itself never
counts); ties go to the lowest object index. ``rel`` holds every object's s minus the
ego's, folded to ``[-L/2, L/2)``, and ``delta`` is the difference of two of them,
``rel[j] - rel[i]``, folded once more (``((delta + L/2) % L) - L/2``) in the envs where
objects lie a quarter loop or more from the ego (``fold``). That is the definition, the
comparison of every car with every object, as the traffic first computed it.

It is evaluated without the ``n x n`` comparison: the objects are sorted by ``rel`` once
per env, and for a car ``i`` the gap ``delta`` is a non-decreasing function of the sorted
position (subtraction and rounding are monotonic); with folding it is so on each of at
most three runs of positions (where ``delta + L/2`` is below 0, within ``[0, L)``, above),
whose bounds are found by bisection. On each run the first position with ``delta > 0`` is
found by bisection, and per lane the next and previous occupant of any position come
from two tables (first occupant at or after, last at or before) built in one pass: the
leader in a run is the first occupant from there, the follower the last occupant before
it (``i`` skipped), and a following run of equal gaps (ties after rounding) is walked to
its lowest index. ``O(n log n)`` per env instead of ``O(n^2)``, and the same result.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.geometry.exact_math import py_mod


@njit(cache=True, inline="always")
def _gap(rel: np.ndarray, order: np.ndarray, p: int, rel_i: float, fold: bool,
         half: float, loop: float) -> float:
    delta = rel[order[p]] - rel_i
    if fold:
        delta = py_mod(delta + half, loop) - half
    return delta


@njit(cache=True, inline="always")
def _first_above(rel: np.ndarray, order: np.ndarray, low: int, high: int, rel_i: float,
                 fold: bool, half: float, loop: float) -> int:
    """First position in [low, high) whose gap is > 0 (gaps non-decreasing there)."""
    while low < high:
        middle = (low + high) >> 1
        if _gap(rel, order, middle, rel_i, fold, half, loop) > 0.0:
            high = middle
        else:
            low = middle + 1
    return low


@njit(cache=True)
def _stable_order(values: np.ndarray, order: np.ndarray) -> None:
    """``order`` = the stable argsort of ``values`` (``np.argsort(kind="stable")``'s
    permutation: a stable sort's is unique): insertion sort for the usual dozen objects,
    a bottom-up merge sort for many (written out: numba's argsort costs seconds to
    compile)."""
    n = values.shape[0]
    for i in range(n):
        order[i] = i
    if n <= 64:
        for i in range(1, n):
            value = values[i]
            j = i
            while j > 0 and values[order[j - 1]] > value:
                order[j] = order[j - 1]
                j -= 1
            order[j] = i
        return
    source, target = order, np.empty(n, dtype=order.dtype)
    width, passes = 1, 0
    while width < n:
        for low in range(0, n, 2 * width):
            middle, high = min(low + width, n), min(low + 2 * width, n)
            a, b = low, middle
            for k in range(low, high):
                # Ties take the left run's first: stable.
                if a < middle and (b >= high or values[source[b]] >= values[source[a]]):
                    target[k] = source[a]
                    a += 1
                else:
                    target[k] = source[b]
                    b += 1
        source, target = target, source
        width *= 2
        passes += 1
    if passes % 2:  # the result is in the work array
        for i in range(n):
            order[i] = source[i]


@njit(cache=True)
def nearest_objects(rel: np.ndarray, occupies: np.ndarray, fold: bool, loop: float,
                    order: np.ndarray, position: np.ndarray, first_from: np.ndarray,
                    last_upto: np.ndarray, ahead: np.ndarray, ahead_gap: np.ndarray,
                    behind: np.ndarray, behind_gap: np.ndarray) -> None:
    """Leaders and followers of one env's cars in every lane (see the module docstring).

    Args:
        rel: ``(objects,)`` s minus the ego's, folded; the cars first, the ego last.
        occupies: ``(lanes, objects)`` which lanes each object occupies.
        fold: whether gaps are folded once more.
        loop: the loop length (m).
        order: ``(objects,)`` and ``position`` ``(objects + 4,)`` work arrays;
            ``first_from``, ``last_upto``: ``(lanes, objects + 1)`` work arrays.
        ahead, ahead_gap, behind, behind_gap: ``(lanes, cars)`` outputs: the object
            index (0 where there is none) and the gap in s (``inf`` where none; the gap
            behind is the negated difference, ``>= 0``).
    """
    objects = rel.shape[0]
    cars = objects - 1
    lanes = occupies.shape[0]
    half = 0.5 * loop
    _stable_order(rel, order)
    for p in range(objects):
        position[order[p]] = p
    # first_from[lane, p]: first position >= p occupying the lane (objects: none);
    # last_upto[lane, p + 1]: last position <= p occupying it (-1: none).
    for lane in range(lanes):
        first_from[lane, objects] = objects
        for p in range(objects - 1, -1, -1):
            first_from[lane, p] = p if occupies[lane, order[p]] else first_from[lane, p + 1]
        last_upto[lane, 0] = -1
        for p in range(objects):
            last_upto[lane, p + 1] = p if occupies[lane, order[p]] else last_upto[lane, p]
    bounds = position[objects:]  # the runs' bounds (the caller's room after the positions)
    for i in range(cars):
        rel_i = rel[i]
        me = position[i]
        # Runs of positions on which the gap is non-decreasing.
        runs = 1
        bounds[0], bounds[1] = 0, objects
        if fold:
            # delta + L/2 < 0 on a first run, >= L on a last one.
            low, high = 0, objects
            while low < high:
                middle = (low + high) >> 1
                if (rel[order[middle]] - rel_i) + half >= 0.0:
                    high = middle
                else:
                    low = middle + 1
            start = low
            low, high = start, objects
            while low < high:
                middle = (low + high) >> 1
                if (rel[order[middle]] - rel_i) + half >= loop:
                    high = middle
                else:
                    low = middle + 1
            bounds[0], bounds[1], bounds[2], bounds[3] = 0, start, low, objects
            runs = 3
        for lane in range(lanes):
            best_gap, best = math.inf, 0
            best_back, back = math.inf, 0
            for r in range(runs):
                a, b = bounds[r], bounds[r + 1]
                if a >= b:
                    continue
                c = _first_above(rel, order, a, b, rel_i, fold, half, loop)
                # Ahead: the first occupant from c, then its equal-gap successors.
                q = first_from[lane, c]
                if q < b:
                    gap = _gap(rel, order, q, rel_i, fold, half, loop)
                    index = order[q]
                    q = first_from[lane, q + 1]
                    while q < b and _gap(rel, order, q, rel_i, fold, half, loop) == gap:
                        index = min(index, order[q])
                        q = first_from[lane, q + 1]
                    if gap < best_gap or (gap == best_gap and index < best):
                        best_gap, best = gap, index
                # Behind: the last occupant before c (i skipped), then its equal-gap
                # predecessors.
                q = last_upto[lane, c]
                if q == me:
                    q = last_upto[lane, q]
                if q >= a:
                    gap = -_gap(rel, order, q, rel_i, fold, half, loop) + 0.0
                    index = order[q]
                    q = last_upto[lane, q]
                    while q >= a:
                        if q != me:
                            if -_gap(rel, order, q, rel_i, fold, half, loop) + 0.0 != gap:
                                break
                            index = min(index, order[q])
                        q = last_upto[lane, q]
                    if gap < best_back or (gap == best_back and index < back):
                        best_back, back = gap, index
            ahead[lane, i], ahead_gap[lane, i] = best, best_gap
            behind[lane, i], behind_gap[lane, i] = back, best_back


@njit(cache=True)
def nearest_objects_by_comparison(rel: np.ndarray, occupies: np.ndarray, fold: bool,
                                  loop: float, ahead: np.ndarray, ahead_gap: np.ndarray,
                                  behind: np.ndarray, behind_gap: np.ndarray) -> None:
    """The definition itself, every car against every object (``O(n^2)``): the known
    answer :func:`nearest_objects` is tested against."""
    objects = rel.shape[0]
    half = 0.5 * loop
    for lane in range(occupies.shape[0]):
        for i in range(objects - 1):
            best_gap, best = math.inf, 0
            best_back, back = math.inf, 0
            for j in range(objects):
                if not occupies[lane, j]:
                    continue
                delta = rel[j] - rel[i]
                if fold:
                    delta = py_mod(delta + half, loop) - half
                if delta > 0.0 and delta < best_gap:
                    best_gap, best = delta, j
                if j != i and -delta >= 0.0 and -delta + 0.0 < best_back:
                    best_back, back = -delta + 0.0, j
            ahead[lane, i], ahead_gap[lane, i] = best, best_gap
            behind[lane, i], behind_gap[lane, i] = back, best_back
