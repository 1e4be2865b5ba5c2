"""Coverage of the evaluation's 95 % intervals on this project's own episodes.

Draws simulated runs of n seeds (with replacement) from the per-episode samples in
``tests/data/episode_samples.json`` and counts how often each interval covers the
population's mean: Student's t (what the tables print, ``sdc_evaluation.statistics``) and the
percentile bootstrap of the mean (what they printed before issue 23; computed here by hand,
vectorized: the same as ``scipy.stats.bootstrap(method="percentile")``) and scipy's BCa
bootstrap (the other candidate). Prints a Markdown table (docs/evaluation.md)::

    .venv/bin/python benchmarks/interval_coverage.py
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import scipy.stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sdc_evaluation.statistics import t_intervals
from tests.test_statistics import SIZES, populations

RUNS = 4000  # the test's
BOOTSTRAP_RUNS = 1000  # (each of 500 resamples: Monte Carlo s.e. of a 0.95 coverage 0.007)
RESAMPLES = 500


def bootstrap_coverage(population: np.ndarray, n: int, rng: np.random.Generator) -> float:
    truth = population.mean()
    hits = 0
    for _ in range(BOOTSTRAP_RUNS // 100):  # 100 runs at a time: 100 x 500 x n draws
        runs = rng.choice(population, size=(100, n))
        picks = rng.integers(0, n, size=(100, RESAMPLES, n))
        means = np.take_along_axis(runs[:, None, :], picks, axis=2).mean(axis=2)
        low, high = np.percentile(means, [2.5, 97.5], axis=1)
        hits += int(np.sum((low <= truth) & (truth <= high)))
    return hits / BOOTSTRAP_RUNS


BCA_RUNS = 300  # scipy's BCa, one call per run (Monte Carlo s.e. of 0.95: 0.013)


def bca_coverage(population: np.ndarray, n: int, rng: np.random.Generator) -> float:
    """scipy's BCa interval of the mean (a sample without spread: no interval, a miss)."""
    truth = population.mean()
    hits = 0
    for _ in range(BCA_RUNS):
        run = rng.choice(population, n)
        if np.ptp(run) == 0:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # degenerate jackknife at tiny n: NaN, a miss
            result = scipy.stats.bootstrap((run,), np.mean, n_resamples=RESAMPLES,
                                           method="BCa", rng=rng)
        low, high = result.confidence_interval
        hits += bool(low <= truth <= high)
    return hits / BCA_RUNS


def main() -> None:
    print("| sample | " + " | ".join(f"t, n = {n}" for n in SIZES) + " | "
          + " | ".join(f"percentile, n = {n}" for n in SIZES) + " | "
          + " | ".join(f"BCa, n = {n}" for n in SIZES) + " |")
    print("|---|" + "---:|" * (3 * len(SIZES)), flush=True)
    for name, population in populations().items():
        truth = population.mean()
        t_cells, boot_cells, bca_cells = [], [], []
        for n in SIZES:
            rng = np.random.default_rng([n, len(name)])  # the test's draws
            low, high = t_intervals(rng.choice(population, size=(RUNS, n)))
            t_cells.append(f"{np.mean((low <= truth) & (truth <= high)):.3f}")
            boot_cells.append(f"{bootstrap_coverage(population, n, rng):.3f}")
            bca_cells.append(f"{bca_coverage(population, n, rng):.3f}")
        print(f"| {name} | " + " | ".join(t_cells + boot_cells + bca_cells) + " |", flush=True)


if __name__ == "__main__":
    main()
