"""sdc_evaluation.statistics and sdc_evaluation.verdicts: known answers for every estimate."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.stats
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
from sdc_evaluation.tables import FEW_SEEDS
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


def test_mean_intervals_are_students_t_and_narrow_with_more_seeds():
    # [1, 2, 3]: mean 2, s = 1, t(2; 0.975) = 4.302653 (the tables): 2 +- 4.302653 / sqrt 3.
    three = mean_interval([1.0, 2.0, 3.0], "x")
    assert (three.value, three.low, three.high) == pytest.approx((2.0, -0.484138, 4.484138))
    # 90 %: t(2; 0.95) = 2.919986.
    ninety = mean_interval([1.0, 2.0, 3.0], "x", Settings(confidence=0.9))
    assert ninety.high == pytest.approx(2.0 + 2.919986 / np.sqrt(3.0))
    rng = np.random.default_rng(0)
    few, many = rng.normal(46.0, 1.0, 5), rng.normal(46.0, 1.0, 80)
    a, b = mean_interval(few, "mph", FAST), mean_interval(many, "mph", FAST)
    assert a.low < a.value < a.high and b.low < b.value < b.high
    assert b.high - b.low < a.high - a.low
    # t(79; 0.975) = 1.990450: the half-width is t s / sqrt(n).
    assert (b.high - b.low) / 2 == pytest.approx(1.990450 * np.std(many, ddof=1) / np.sqrt(80))
    # The old percentile bootstrap stays within the sample's range: at 3 seeds it is
    # about the min-max, the t interval far wider (the coverage test shows which is honest).
    boot = statistics.bootstrap_mean_interval([1.0, 2.0, 3.0], "x", FAST)
    assert 1.0 <= boot.low < boot.high <= 3.0
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
    # Known answers: paired, the t interval of the differences [0, 0, -0.5];
    d = mean_difference([1.0, 2.0, 3.0], [1.0, 2.0, 3.5], "x", True)
    s = np.std([0.0, 0.0, -0.5], ddof=1)
    assert (d.low, d.high) == pytest.approx((-1 / 6 - 4.302653 * s / np.sqrt(3),
                                             -1 / 6 + 4.302653 * s / np.sqrt(3)))
    # independent, Welch's: variances 1 and 7/3 over 3 each, Welch-Satterthwaite's df.
    w = mean_difference([1.0, 2.0, 3.0], [4.0, 5.0, 7.0], "x", False)
    se2 = 1.0 / 3 + (7.0 / 3) / 3
    df = se2**2 / ((1.0 / 3) ** 2 / 2 + ((7.0 / 3) / 3) ** 2 / 2)
    half = scipy.stats.t.ppf(0.975, df) * np.sqrt(se2)
    assert df == pytest.approx(3.4, abs=0.05)
    assert (w.value, w.low, w.high) == pytest.approx((-10 / 3, -10 / 3 - half, -10 / 3 + half))
    assert mean_difference([5.0, 6.0], [5.0, 6.0], "x", True) == statistics.Interval(0, 0, 0)
    assert mean_difference([5.0], [4.0], "x", False) == statistics.Interval(1.0)
    with pytest.raises(ValueError, match="equal lengths"):
        mean_difference([1.0, 2.0], [1.0], "x", True)


def test_seeds_needed_matches_cohens_power_tables():
    """Cohen (1988), table 2.4.1: the two-sample t test at alpha 0.05 (two-sided) needs 64
    per group for d = 0.5 at power 0.80, 26 for d = 0.8; the paired (one-sample) test
    needs n = 34 for d = 0.5 (33.4 rounded up)."""
    assert statistics.seeds_needed(0.5, 1.0, paired=False) == 64
    assert statistics.seeds_needed(0.8, 1.0, paired=False) == 26
    assert statistics.seeds_needed(0.5, 1.0) == 34
    assert statistics.seeds_needed(1.0, 2.0) == 34  # only the ratio counts
    assert statistics.seeds_needed(-0.5, 1.0) == 34  # either sign
    assert statistics.seeds_needed(0.0, 1.0) is None  # nothing to find
    assert statistics.seeds_needed(1e-6, 1.0) is None  # beyond MAX_SEEDS
    assert statistics.seeds_needed(1.0, 0.0) == 2  # no spread at all
    assert statistics.seeds_needed(10.0, 1.0) == 3  # at n = 2 the t test has 1 df
    # Small effects, where the noncentral t's numbers get large: Guenther's approximation
    # n = ((z(0.975) + z(0.8)) / d)^2 + z(0.975)^2 / 2 gives 284.4 and 78,491.5.
    assert statistics.seeds_needed(0.5, 3.0) == 285
    assert statistics.seeds_needed(0.01, 1.0) in (78491, 78492)


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


# ------------------------------------------------------- coverage on this project's episodes
EPISODE_SAMPLES = Path(__file__).resolve().parent / "data" / "episode_samples.json"
"""Per-episode mph and lap times of the FSM styles and lane keeping, seeds 0-39 (made by
``benchmarks/episode_samples.py``, the command inside)."""
SIZES = (3, 5, 10, 20)
REPETITIONS = 4000  # simulated runs per (population, n): Monte Carlo s.e. of 0.95 is 0.0034
COVERAGE_TOLERANCE = 0.03
"""How far the t interval's simulated coverage may be from the nominal 0.95 from
:data:`sdc_evaluation.tables.FEW_SEEDS` (5) seeds on (measured: 0.923-0.953 at 5 seeds)."""
FEW_SEEDS_COVERAGE = 0.87
"""The least coverage at 3 seeds (measured 0.891-0.957: the t interval is exact for normal
episodes only, and some of these are skewed or heavy-tailed; the percentile bootstrap it
replaced reaches about 0.7). Below 5 seeds the table marks the intervals."""


def populations() -> dict[str, np.ndarray]:
    """Each agent's per-episode mph and lap times, and the per-seed mph differences of the
    two FSM styles (what a paired verdict's interval is about)."""
    data = json.loads(EPISODE_SAMPLES.read_text())["agents"]
    result = {f"{agent} {field}": np.array(values[field], dtype=np.float64)
              for agent, values in data.items() for field in ("mean_speed_mph", "lap_time")}
    bold, conservative = data["fsm_bold"], data["fsm_conservative"]
    assert bold["seed"] == conservative["seed"]
    result["bold - conservative mph"] = (np.array(bold["mean_speed_mph"])
                                         - np.array(conservative["mean_speed_mph"]))
    return result


def test_the_samples_are_this_projects_episodes():
    data = json.loads(EPISODE_SAMPLES.read_text())
    assert data["env_id"] == "sdc_gym/HighwayLoop-v0" and data["laps"] == 1
    assert set(data["agents"]) == {"fsm_conservative", "fsm_bold", "lane_keeping"}
    for values in data["agents"].values():
        assert values["seed"] == list(range(40))
        assert all(30.0 < mph < 50.0 for mph in values["mean_speed_mph"])
        assert all(300.0 < lap < 450.0 for lap in values["lap_time"])


@pytest.mark.parametrize("name", list(populations()))
def test_t_intervals_cover_the_mean_as_claimed_at_every_seed_count(name):
    """Simulated runs of n seeds drawn (with replacement) from the project's own episodes:
    the t interval covers the population's mean 95 % of the time within the tolerance at
    n = 5, 10 and 20, and at least :data:`FEW_SEEDS_COVERAGE` at n = 3 (where the table
    says "too few to decide"); seeded, vectorized (milliseconds)."""
    population = populations()[name]
    truth = float(np.mean(population))
    for n in SIZES:
        rng = np.random.default_rng([n, len(name)])
        runs = rng.choice(population, size=(REPETITIONS, n))
        low, high = statistics.t_intervals(runs)
        coverage = float(np.mean((low <= truth) & (truth <= high)))
        if n < FEW_SEEDS:
            assert FEW_SEEDS_COVERAGE <= coverage <= 0.95 + COVERAGE_TOLERANCE, (name, n)
        else:
            assert abs(coverage - 0.95) <= COVERAGE_TOLERANCE, (name, n, coverage)


def test_the_percentile_bootstrap_it_replaces_under_covers_at_few_seeds():
    """Why the tables no longer use it: at 3 seeds the percentile bootstrap is about the
    sample's min-max, and covers the mean far less often than the 95 % it claims."""
    population = populations()["fsm_conservative mean_speed_mph"]
    truth = float(np.mean(population))
    rng = np.random.default_rng(7)
    settings = Settings(resamples=500)
    hits = []
    for index in range(300):
        interval = statistics.bootstrap_mean_interval(rng.choice(population, 3),
                                                      f"run{index}", settings)
        hits.append(interval.low <= truth <= interval.high)
    assert np.mean(hits) < 0.85
