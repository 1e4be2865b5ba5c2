"""Interval estimates: what a mean over a few seeds can and cannot say.

Following Agarwal et al., "Deep RL at the edge of the statistical precipice" (NeurIPS
2021), every aggregate comes with a 95 % interval, and agents are compared by the
probability of improvement, not by their means alone. The unit of every sample is one
episode (one seed): episodes are independent, the laps of one episode are not.

* :func:`mean_interval`: the mean with Student's t interval (``mean +- t(n-1) s / sqrt n``,
  :func:`scipy.stats.ttest_1samp`), whose coverage holds at 3 seeds where the percentile
  bootstrap's does not: with n episodes the bootstrap can never reach beyond the sample's
  own range, so at 3 seeds it is about the min-max of three episodes and covers the mean
  only about 70 % of the time (``tests/test_statistics.py`` simulates both on this
  project's own episodes);
* :func:`iqm_interval`: the interquartile mean (the mean of the middle 50 %, robust to an
  odd seed; ``rliable.metrics.aggregate_iqm``) with its bootstrap interval;
* :func:`probability_of_improvement`: P(X > Y), the chance that a random episode of X
  scores above a random episode of Y, ties counting half (the Mann-Whitney U statistic
  over ``nx * ny``; ``rliable.metrics.probability_of_improvement``), with its bootstrap
  interval resampling both agents' episodes independently;
* :func:`mean_difference`: mean(X) - mean(Y) with its t interval: the paired t on the
  per-seed differences when both agents drove the same seeds (their traffic starts alike,
  so the pairing removes much of the seed-to-seed spread), else Welch's;
* :func:`seeds_needed`: how many seeds a difference needs to be told apart at a power
  (80 %) from a measured spread, by the t test's exact power (noncentral t,
  ``statsmodels.stats.power``);
* :func:`poisson_rate`: a count per exposure (incidents per 100 miles) with Garwood's
  exact Poisson interval (1936), from the chi-square quantiles;
* :func:`rate_ratio_test`: whether two such rates differ: the exact conditional test (given
  the total count, one agent's share is binomial in its share of the miles).

The point estimates of IQM and P(improvement) are rliable's own functions; their intervals
(no t interval fits a trimmed mean or a probability) use scipy's vectorized bootstrap,
because rliable's (through ``arch``) calls the statistic once per resample in Python:
1.5 s per agent pair at 2000 resamples, where scipy takes milliseconds for 10,000. Every
bootstrap is seeded from :attr:`Settings.seed` and the statistic's name, so one sample
always gets the same interval, whichever other agents or runs are in the table.
"""

from __future__ import annotations

import warnings
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.stats
from numpy.typing import ArrayLike, NDArray
from rliable import metrics as rliable_metrics
from statsmodels.stats.power import TTestIndPower, TTestPower

CONFIDENCE = 0.95
DEFAULT_RESAMPLES = 10_000
DEFAULT_SEED = 0
POWER = 0.8
"""The power :func:`seeds_needed` plans for: the chance of telling a true difference apart."""
MAX_SEEDS = 100_000
"""Beyond this :func:`seeds_needed` answers ``None`` (the difference is noise-level)."""
_BATCH = 1000  # resamples evaluated at once (bounds the memory of P(improvement))


@dataclass(frozen=True)
class Settings:
    """How intervals are computed: coverage, bootstrap resamples and the seed."""

    confidence: float = CONFIDENCE
    resamples: int = DEFAULT_RESAMPLES
    seed: int = DEFAULT_SEED

    def __post_init__(self) -> None:
        if not 0.0 < self.confidence < 1.0:
            raise ValueError(f"confidence must be in (0, 1), got {self.confidence!r}")
        if self.resamples < 100:
            raise ValueError(f"resamples must be >= 100, got {self.resamples!r}")

    def as_dict(self) -> dict[str, Any]:
        return {"confidence": self.confidence, "mean_interval": "Student t",
                "difference_interval": "paired t (same seeds), else Welch t",
                "bootstrap_resamples": self.resamples, "bootstrap_seed": self.seed,
                "bootstrap_method": "percentile (IQM, P(improvement))",
                "unit": "episode (one seed)", "rate_interval": "Garwood exact Poisson"}


DEFAULT_SETTINGS = Settings()


@dataclass(frozen=True)
class Interval:
    """A point estimate with its confidence interval; ``None`` where a sample cannot give
    one (no value without data, no interval from fewer than two episodes)."""

    value: float | None
    low: float | None = None
    high: float | None = None

    @property
    def has_interval(self) -> bool:
        return self.low is not None and self.high is not None

    def ci(self) -> list[float] | None:
        return [self.low, self.high] if self.has_interval else None  # type: ignore[list-item]


def _rng(settings: Settings, name: str) -> np.random.Generator:
    """The bootstrap's generator: from the settings' seed and the statistic's name."""
    return np.random.default_rng(np.random.SeedSequence([settings.seed,
                                                         zlib.crc32(name.encode())]))


def _bootstrap(samples: Sequence[NDArray[np.float64]], statistic: Callable[..., Any],
               name: str, settings: Settings, paired: bool = False
               ) -> tuple[float | None, float | None]:
    """Percentile bootstrap interval of ``statistic`` (vectorized, ``axis=-1``)."""
    if any(len(sample) < 2 for sample in samples):
        return None, None
    if all(np.ptp(sample) == 0 for sample in samples):  # nothing to resample: exact
        value = float(statistic(*(sample[None, :] for sample in samples), axis=-1)[0])
        return value, value
    result = scipy.stats.bootstrap(
        tuple(samples), statistic, n_resamples=settings.resamples, batch=_BATCH,
        vectorized=True, paired=paired, axis=-1, confidence_level=settings.confidence,
        method="percentile", rng=_rng(settings, name))
    low, high = result.confidence_interval
    return float(low), float(high)


def _array(values: ArrayLike) -> NDArray[np.float64]:
    array = np.asarray(values, dtype=np.float64).ravel()
    if not np.all(np.isfinite(array)):
        raise ValueError(f"samples must be finite numbers, got {array.tolist()}")
    return array


def _t_interval(test: Any, value: float, confidence: float) -> tuple[float, float]:
    """The confidence interval of a scipy t-test result (``[value, value]`` when the
    sample has no spread, where scipy's is NaN)."""
    low, high = test.confidence_interval(confidence_level=confidence)
    if not (np.isfinite(low) and np.isfinite(high)):
        return value, value
    return float(low), float(high)


def _t_test(test: Callable[..., Any], *samples: NDArray[np.float64], **options: Any) -> Any:
    """A scipy t test, quiet about samples that barely differ (near-identical drives):
    their interval is then as narrow as their spread, which is what it should be."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Precision loss", RuntimeWarning)
        return test(*samples, **options)


def t_intervals(samples: ArrayLike, confidence: float = CONFIDENCE
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Student's t intervals of the mean of each row of ``samples`` (``(m, n)``, n >= 2):
    ``mean +- t(n - 1; (1 + confidence) / 2) s / sqrt(n)``, vectorized (the coverage test
    computes thousands at once); a row without spread gets ``[mean, mean]``."""
    array = np.atleast_2d(np.asarray(samples, dtype=np.float64))
    if array.shape[-1] < 2:
        raise ValueError(f"a t interval needs >= 2 values per sample, got {array.shape[-1]}")
    result = _t_test(scipy.stats.ttest_1samp, array, 0.0, axis=-1)
    low, high = result.confidence_interval(confidence_level=confidence)
    mean = array.mean(axis=-1)
    flat = np.ptp(array, axis=-1) == 0
    return np.where(flat, mean, low), np.where(flat, mean, high)


def mean_interval(values: ArrayLike, name: str = "",
                  settings: Settings = DEFAULT_SETTINGS) -> Interval:
    """The mean of ``values`` (one per episode) with Student's t interval (none from fewer
    than two episodes). ``name`` is kept for the bootstrap statistics' signature."""
    sample = _array(values)
    if not len(sample):
        return Interval(None)
    value = float(np.mean(sample))
    if len(sample) < 2:
        return Interval(value)
    low, high = t_intervals(sample, settings.confidence)
    return Interval(value, float(low[0]), float(high[0]))


def bootstrap_mean_interval(values: ArrayLike, name: str,
                            settings: Settings = DEFAULT_SETTINGS) -> Interval:
    """The mean with the percentile bootstrap interval, as the tables had it before the t
    interval: kept to show by simulation why it was replaced (it under-covers at few
    seeds, ``tests/test_statistics.py``)."""
    sample = _array(values)
    if not len(sample):
        return Interval(None)
    low, high = _bootstrap([sample], np.mean, f"mean/{name}", settings)
    return Interval(float(np.mean(sample)), low, high)


def _trim_mean(sample: NDArray[np.float64], axis: int = -1) -> NDArray[np.float64]:
    return np.asarray(scipy.stats.trim_mean(sample, 0.25, axis=axis))


def iqm_interval(values: ArrayLike, name: str, settings: Settings = DEFAULT_SETTINGS) -> Interval:
    """The interquartile mean (25 % trimmed from each end, as rliable defines it: scipy's
    ``trim_mean`` cuts ``int(0.25 n)`` samples at each end) with its bootstrap interval."""
    sample = _array(values)
    if not len(sample):
        return Interval(None)
    value = float(rliable_metrics.aggregate_iqm(sample[:, None]))
    low, high = _bootstrap([sample], _trim_mean, f"iqm/{name}", settings)
    return Interval(value, low, high)


def _improvement(x: NDArray[np.float64], y: NDArray[np.float64],
                 axis: int = -1) -> NDArray[np.float64]:
    """P(X > Y) + P(X = Y) / 2 over every pair of episodes, along the last axis."""
    above = x[..., :, None] > y[..., None, :]
    tied = x[..., :, None] == y[..., None, :]
    return np.mean(above + 0.5 * tied, axis=(-2, -1))


def probability_of_improvement(x: ArrayLike, y: ArrayLike, name: str,
                               settings: Settings = DEFAULT_SETTINGS) -> Interval:
    """P(X > Y) of one score per episode (higher is better), with its bootstrap interval."""
    a, b = _array(x), _array(y)
    if not len(a) or not len(b):
        return Interval(None)
    value = float(rliable_metrics.probability_of_improvement(a[:, None], b[:, None]))
    low, high = _bootstrap([a, b], _improvement, f"p_improvement/{name}", settings)
    return Interval(value, low, high)


def mean_difference(x: ArrayLike, y: ArrayLike, name: str = "", paired: bool = False,
                    settings: Settings = DEFAULT_SETTINGS) -> Interval:
    """mean(X) - mean(Y) with its t interval: ``paired`` (``x[i]`` and ``y[i]`` are the
    same seed's episodes), the one-sample t on the differences; else Welch's t (unequal
    spreads). None from fewer than two episodes on a side."""
    a, b = _array(x), _array(y)
    if not len(a) or not len(b):
        return Interval(None)
    if paired and len(a) != len(b):
        raise ValueError(f"paired samples need equal lengths, got {len(a)} and {len(b)}")
    value = float(np.mean(a) - np.mean(b))
    if len(a) < 2 or len(b) < 2:
        return Interval(value)
    if paired:
        low, high = t_intervals(a - b, settings.confidence)
        return Interval(value, float(low[0]), float(high[0]))
    if np.ptp(a) == 0 and np.ptp(b) == 0:  # no spread on either side: exact
        return Interval(value, value, value)
    test = _t_test(scipy.stats.ttest_ind, a, b, equal_var=False)
    low, high = _t_interval(test, value, settings.confidence)
    return Interval(value, low, high)


def seeds_needed(difference: float, spread: float, paired: bool = True,
                 power: float = POWER, confidence: float = CONFIDENCE) -> int | None:
    """Seeds (per agent) for the two-sided t test at ``1 - confidence`` to tell a true
    mean difference of ``difference`` apart with probability ``power``, when one seed's
    value spreads by ``spread`` (standard deviation: of the per-seed differences when
    ``paired``, else of each agent's values, taken equal). At least 2; ``None`` when
    there is no difference to find or it would take more than :data:`MAX_SEEDS`.

    The paired t test has power 0.8 for a 0.5 s.d. difference at 34 seeds (Cohen's
    tables: 33.4), the two-sample one at 64 per group."""
    difference, spread = abs(float(difference)), float(spread)
    if not difference > 0 or not np.isfinite(difference) or not np.isfinite(spread):
        return None
    if spread <= difference / 100.0:
        return 2  # (almost) no spread: two seeds show it (and the power's numbers overflow)
    effect = difference / spread
    solver = TTestPower() if paired else TTestIndPower()
    alpha = 1.0 - confidence
    # Power grows with the seeds: double, then bisect on whole seeds (statsmodels'
    # solve_power, a root finder on a real n, fails to converge for large effects near
    # n = 2, and its noncentral t gives NaN for small effects at tens of thousands).
    def reached(seeds: int) -> bool:
        value = solver.power(effect, seeds, alpha)
        return bool(np.isfinite(value) and value >= power)

    low, high = 1, 2  # not reached at low (1 seed has no spread), reached at high
    while not reached(high):
        if high >= MAX_SEEDS:
            return None
        low, high = high, min(2 * high, MAX_SEEDS)
    while high - low > 1:
        middle = (low + high) // 2
        if reached(middle):
            high = middle
        else:
            low = middle
    return max(2, high)


def poisson_interval(count: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Garwood's exact interval of a Poisson mean from one observed ``count``:
    ``[chi2(a/2; 2k) / 2, chi2(1 - a/2; 2k + 2) / 2]``, the lower end 0 for ``k = 0``."""
    if count < 0 or int(count) != count:
        raise ValueError(f"count must be a non-negative integer, got {count!r}")
    alpha = 1.0 - confidence
    low = 0.0 if count == 0 else float(scipy.stats.chi2.ppf(alpha / 2, 2 * count) / 2)
    high = float(scipy.stats.chi2.ppf(1 - alpha / 2, 2 * count + 2) / 2)
    return low, high


def poisson_rate(count: int, exposure: float, per: float = 100.0,
                 confidence: float = CONFIDENCE) -> Interval:
    """``count`` events over ``exposure`` (e.g. miles) as a rate per ``per`` with Garwood's
    interval; no value without exposure."""
    if not exposure > 0:
        return Interval(None)
    low, high = poisson_interval(count, confidence)
    scale = per / exposure
    return Interval(count * scale, low * scale, high * scale)


def rate_ratio_test(count_a: int, exposure_a: float, count_b: int, exposure_b: float) -> float:
    """Two-sided p-value that two Poisson rates are equal (exact, conditional on the total
    count: ``count_a ~ Binomial(count_a + count_b, exposure_a / (exposure_a +
    exposure_b))``); 1.0 when neither had an event."""
    total = count_a + count_b
    if total == 0 or not (exposure_a > 0 and exposure_b > 0):
        return 1.0
    share = exposure_a / (exposure_a + exposure_b)
    return float(scipy.stats.binomtest(count_a, total, share).pvalue)
