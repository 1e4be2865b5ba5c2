"""``benchmarks/bench_learners.py``'s arithmetic: the sequential bound and the port of
PufferLib's advantage kernel, on inputs whose answers are worked out by hand."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_learners
import learners_pufferlib

VALUES = [1.0, 2.0, 3.0, 4.0]
REWARDS = [0.0, 1.0, 1.0, 1.0]
DONES = [0.0, 0.0, 1.0, 0.0]  # the episode ends at t = 2: no bootstrap through it
GAMMA = LAM = 0.5
# Backwards from t = 2, importance w:
#   t=2: delta = w (r3 + g v3 - v2) = w (1 + 2 - 3) = 0;     a2 = 0
#   t=1: delta = w (r2 + g v2 (1 - d2) - v1) = w (1 - 2);    a1 = -w        (d2 cuts a2)
#   t=0: delta = w (r1 + g v1 - v0) = w (1 + 1 - 1) = w;     a0 = w + g lam w a1
# w = 1 (and any w >= 1, clipped to 1): a = [0.75, -1, 0]; w = 0.5: a = [0.4375, -0.5, 0].
EXPECTED = np.array([[0.75, -1.0, 0.0, 9.0], [0.75, -1.0, 0.0, 9.0],
                     [0.4375, -0.5, 0.0, 9.0]], np.float32)


def _rows() -> tuple[np.ndarray, ...]:
    def rows(row: list[float]) -> np.ndarray:
        return np.array([row] * 3, np.float32)

    importance = np.array([[1.0] * 4, [2.0] * 4, [0.5] * 4], np.float32)
    advantages = np.full((3, 4), 9.0, np.float32)  # the last column stays as given
    return rows(VALUES), rows(REWARDS), rows(DONES), importance, advantages


def test_sequential_bound() -> None:
    assert bench_learners.sequential_bound(40_000, 40_000) == pytest.approx(20_000)
    assert bench_learners.sequential_bound(10_000, 30_000) == pytest.approx(7_500)


def test_puff_advantage_known_answer() -> None:
    values, rewards, dones, importance, advantages = _rows()
    learners_pufferlib.puff_advantage(values, rewards, dones, importance, advantages,
                                  GAMMA, LAM, 1.0, 1.0)
    np.testing.assert_array_equal(advantages, EXPECTED)


def test_puff_advantage_as_pufferlibs_op() -> None:
    """Through PuffeRL's own entry (``pufferl.compute_puff_advantage`` calls the torch op
    the benchmark registers), when PufferLib is installed."""
    pytest.importorskip("pufferlib")
    torch = pytest.importorskip("torch")
    pufferl = learners_pufferlib.import_pufferl()
    values, rewards, dones, importance, advantages = (torch.from_numpy(a) for a in _rows())
    out = pufferl.compute_puff_advantage(values, rewards, dones, importance, advantages,
                                         GAMMA, LAM, 1.0, 1.0)
    np.testing.assert_array_equal(out.numpy(), EXPECTED)
