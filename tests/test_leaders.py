"""The leader search by sorting against its definition (every car against every object).

Known answers: :func:`~sdc_gym.traffic.leaders.nearest_objects_by_comparison` is the
``n x n`` definition the traffic was written with (the nearest occupant ahead and behind
in every lane, the first index of equal gaps, gaps folded around the loop); the sorted
search must pick the same objects and gaps on scenes with ties (positions on a 0.5 m
grid, so equal gaps are exactly equal), folding (objects spread over the whole loop) and
a few hundred objects (the merge sort's range), and its order must be numpy's stable
argsort.
"""

from __future__ import annotations

import numpy as np
import pytest

from sdc_gym.traffic.leaders import (
    _stable_order,
    nearest_objects,
    nearest_objects_by_comparison,
)

LOOP = 6945.554


@pytest.mark.parametrize("n", [1, 2, 7, 64, 65, 200, 513])
def test_stable_order_is_numpys_stable_argsort(n: int) -> None:
    rng = np.random.default_rng(n)
    for values in (rng.random(n), rng.integers(0, max(n // 4, 2), size=n).astype(float),
                   np.zeros(n), np.arange(n, 0, -1, dtype=float)):
        order = np.empty(n, dtype=np.int64)
        _stable_order(values, order)
        np.testing.assert_array_equal(order, np.argsort(values, kind="stable"))


def _scene(rng: np.random.Generator, objects: int, lanes: int, spread: float
           ) -> tuple[np.ndarray, np.ndarray, bool]:
    rel = rng.integers(-int(spread), int(spread), size=objects) * 0.5
    rel = np.mod(rel + 0.5 * LOOP, LOOP) - 0.5 * LOOP
    rel[-1] = 0.0  # the ego, last
    occupies = rng.random((lanes, objects)) < 0.45
    fold = bool(np.abs(rel).max() >= 0.25 * LOOP)
    return rel, occupies, fold


@pytest.mark.parametrize("objects,spread", [(13, 60.0), (13, LOOP), (40, 30.0),
                                            (300, LOOP), (501, 400.0)])
def test_sorted_search_equals_the_definition(objects: int, spread: float) -> None:
    rng = np.random.default_rng(objects)
    lanes, cars = 3, objects - 1
    for _ in range(60):
        rel, occupies, fold = _scene(rng, objects, lanes, spread)
        expected = [np.empty((lanes, cars), dtype=np.int64), np.empty((lanes, cars)),
                    np.empty((lanes, cars), dtype=np.int64), np.empty((lanes, cars))]
        nearest_objects_by_comparison(rel, occupies, fold, LOOP, *expected)
        got = [np.empty_like(a) for a in expected]
        nearest_objects(rel, occupies, fold, LOOP, np.empty(objects, dtype=np.int64),
                        np.empty(objects + 4, dtype=np.int64),
                        np.empty((lanes, objects + 1), dtype=np.int64),
                        np.empty((lanes, objects + 1), dtype=np.int64),
                        got[0], got[1], got[2], got[3])
        for mine, theirs in zip(got, expected, strict=True):
            np.testing.assert_array_equal(mine, theirs)
