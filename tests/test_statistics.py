"""sdc_evaluation.statistics and sdc_evaluation.verdicts: known answers for every estimate."""

from __future__ import annotations

import numpy as np
import pytest
from rliable import metrics as rliable_metrics

from sdc_evaluation import statistics
from sdc_evaluation.statistics import (
    Settings,
    iqm_interval,
    mean_difference,
    mean_interval,
    poisson_interval,
    poisson_rate,
    probability_of_improvement,
    rate_ratio_test,
)
from sdc_evaluation.summary import AgentSamples
from sdc_evaluation.verdicts import compare

FAST = Settings(resamples=2000)


def test_iqm_of_a_constructed_sample():
    # 8 values: the lowest 2 (-50, 1) and highest 2 (6, 100) are cut: the mean of 2..5.
    assert iqm_interval([1, 2, 3, 4, 5, 6, 100, -50], "x").value == pytest.approx(3.5)
    # An outlier moves the mean, not the IQM.
    values = [10.0, 11.0, 12.0, 13.0, 1000.0]  # int(0.25 * 5) = 1 cut at each end
    assert iqm_interval(values, "x").value == pytest.approx(12.0)
    assert mean_interval(values, "x").value == pytest.approx(209.2)


def test_probability_of_improvement_known_cases():
    assert probability_of_improvement([5, 6, 7], [1, 2, 3], "x").value == 1.0
    assert probability_of_improvement([1, 2, 3], [5, 6, 7], "x").value == 0.0
    assert probability_of_improvement([1, 2, 3], [1, 2, 3], "x").value == 0.5
    # Ties count half: 1 of 4 pairs above, 2 tied, 1 below -> (1 + 2 * 0.5) / 4.
    assert probability_of_improvement([1, 2], [1, 2], "x").value == 0.5
    assert probability_of_improvement([2, 3], [1, 3], "x").value == pytest.approx(0.625)


def test_the_vectorized_improvement_statistic_is_rliables():
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.integers(0, 6, rng.integers(2, 9)).astype(float)  # with ties
        y = rng.integers(0, 6, rng.integers(2, 9)).astype(float)
        ours = statistics._improvement(x[None, :], y[None, :])[0]
        assert ours == pytest.approx(rliable_metrics.probability_of_improvement(
            x[:, None], y[:, None]))


def test_bootstrap_intervals_cover_the_mean_are_seeded_and_narrow_with_more_seeds():
    rng = np.random.default_rng(0)
    few, many = rng.normal(46.0, 1.0, 5), rng.normal(46.0, 1.0, 80)
    a, b = mean_interval(few, "mph", FAST), mean_interval(many, "mph", FAST)
    assert a.low < a.value < a.high and b.low < b.value < b.high
    assert b.high - b.low < a.high - a.low
    # The normal approximation's 95 % half-width is 1.96 sigma / sqrt(n): about 0.22.
    assert (b.high - b.low) / 2 == pytest.approx(1.96 * np.std(many) / np.sqrt(80), rel=0.15)
    assert mean_interval(many, "mph", FAST) == b  # seeded: the same interval again
    assert mean_interval(many, "mph", Settings(resamples=2000, seed=1)) != b
    # A constant sample has an exact interval; one value has none; nothing, no value.
    assert mean_interval([5.0, 5.0, 5.0], "x") == statistics.Interval(5.0, 5.0, 5.0)
    assert mean_interval([5.0], "x") == statistics.Interval(5.0, None, None)
    assert mean_interval([], "x").value is None
    with pytest.raises(ValueError, match="finite"):
        mean_interval([1.0, float("nan")], "x")


def test_pairing_by_seed_removes_the_shared_spread():
    rng = np.random.default_rng(1)
    traffic = rng.normal(0.0, 3.0, 30)  # what a seed's traffic costs both agents
    x = 47.0 + traffic + rng.normal(0.0, 0.2, 30)
    y = 46.0 + traffic + rng.normal(0.0, 0.2, 30)
    paired = mean_difference(x, y, "mph", True, FAST)
    independent = mean_difference(x, y, "mph", False, FAST)
    assert paired.value == pytest.approx(independent.value)
    assert paired.low > 0.8 and paired.high < 1.2  # a clear 1 mph
    assert independent.low < 0.0 < independent.high  # lost in the seeds' spread
    with pytest.raises(ValueError, match="equal lengths"):
        mean_difference([1.0, 2.0], [1.0], "x", True)


def test_garwood_interval_against_tabulated_values():
    # Garwood (1936) / the standard table of exact 95 % Poisson limits.
    assert poisson_interval(0) == pytest.approx((0.0, 3.689), abs=1e-3)
    assert poisson_interval(1) == pytest.approx((0.0253, 5.572), abs=1e-3)
    assert poisson_interval(5) == pytest.approx((1.6235, 11.668), abs=1e-3)
    assert poisson_interval(10) == pytest.approx((4.795, 18.390), abs=1e-3)
    rate = poisson_rate(5, 250.0)  # 5 incidents in 250 miles, per 100 miles
    assert rate.value == pytest.approx(2.0)
    assert (rate.low, rate.high) == pytest.approx((0.6494, 4.6673), abs=1e-3)
    assert poisson_rate(3, 0.0).value is None
    with pytest.raises(ValueError, match="non-negative integer"):
        poisson_interval(-1)


def test_rate_ratio_test_is_the_exact_conditional_binomial():
    assert rate_ratio_test(0, 10.0, 0, 10.0) == 1.0
    # 6 vs 0 in equal miles: P(all 6 on one side) = 2 * 0.5 ** 6.
    assert rate_ratio_test(6, 10.0, 0, 10.0) == pytest.approx(2 * 0.5**6)
    assert rate_ratio_test(3, 10.0, 3, 10.0) == pytest.approx(1.0)


def samples(label: str, speeds, seeds=None, incidents: int = 0, miles: float = 100.0):
    speeds = np.asarray(speeds, dtype=float)
    return AgentSamples(label, label, tuple(seeds if seeds is not None else range(len(speeds))),
                        speeds, 300.0 - speeds, miles, {"collision": incidents})


def test_verdict_names_the_faster_agent_with_the_interval_and_p_improvement():
    slow = samples("dqn", [44.0, 45.0, 46.0, 45.5, 44.5])
    fast = samples("fsm_bold", [45.4, 46.2, 47.5, 46.8, 45.9])
    comparison = compare(slow, fast, FAST)  # the faster becomes the first, either order
    d = comparison.speed_difference
    assert (comparison.a, comparison.b, comparison.paired) == ("fsm_bold", "dqn", True)
    assert d.value == pytest.approx(1.36) and d.low > 0
    # Pairs where fsm_bold's episode is faster: 3 + 4 + 5 + 5 + 5 of 25.
    assert comparison.improvement.value == pytest.approx(0.88)
    assert comparison.verdict == (f"fsm_bold faster than dqn by 1.36 mph [{d.low:.2f}, "
                                  f"{d.high:.2f}], P(improvement) 0.88")
    assert comparison.incident_note == ""


def test_no_clear_difference_when_the_interval_spans_zero():
    a = samples("a", [44.0, 47.0, 45.0, 46.0])
    b = samples("b", [45.0, 45.5, 46.5, 44.5])
    comparison = compare(a, b, FAST)
    assert comparison.speed_difference.low < 0 < comparison.speed_difference.high
    assert "no clear difference" in comparison.verdict and not comparison.clear


def test_identical_drives_and_too_few_episodes_say_so():
    same = compare(samples("a", [44.0, 45.0]), samples("b", [44.0, 45.0]), FAST)
    assert same.verdict == "a and b: the same speed in every episode" and same.identical
    one = compare(samples("a", [45.0]), samples("b", [44.0]), FAST)
    assert "too few episodes for an interval" in one.verdict
    other_seeds = compare(samples("a", [44.0, 45.0], seeds=[0, 1]),
                          samples("b", [44.0, 45.0], seeds=[5, 6]), FAST)
    assert not other_seeds.paired and not other_seeds.identical
    # Differences below the table's resolution are no difference.
    tiny = compare(samples("a", [44.0, 45.0, 46.0]),
                   samples("b", [44.0 - 1e-9, 45.0 - 1e-9, 46.0 - 1e-9]), FAST)
    assert not tiny.clear and "no clear difference" in tiny.verdict


def test_incident_note_compares_the_rates():
    note = compare(samples("a", [45.0, 46.0], incidents=0),
                   samples("b", [44.0, 45.0], incidents=8), FAST).incident_note
    assert note == "incidents per 100 mi 0 vs 8.00 (a fewer, p 0.008)"
    even = compare(samples("a", [45.0, 46.0], incidents=1),
                   samples("b", [44.0, 45.0], incidents=1), FAST).incident_note
    assert even == "incidents per 100 mi 1.00 vs 1.00 (no clear difference, p 1.00)"
