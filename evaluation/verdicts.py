"""One line per pair of agents: who is faster, by how much, and how sure that is.

A :class:`Comparison` of agents A and B (A the one with the higher mean speed) holds the
difference of their mean speeds with its 95 % t interval (paired by seed when both drove
the same seeds, else Welch's), P(improvement) of A over B with its interval, the spread
of one seed's difference, and their incident rates with the exact test of equal rates.
Its :attr:`~Comparison.verdict` says "faster" only when the interval of the difference
excludes 0, otherwise "no clear difference" and how many seeds that difference would need
to be decided at 80 % power (:func:`sdc_evaluation.statistics.seeds_needed`):

    fsm_bold faster than lane_keeping by 5.34 mph [2.53, 8.15], P(improvement) 1.00
    fsm_bold vs fsm_conservative: no clear difference, +1.36 mph [-2.26, 4.98],
        P(improvement) 0.67, ~16 seeds to decide

and, when either had incidents, :attr:`~Comparison.incident_note` compares their rates.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np

from sdc_evaluation import statistics
from sdc_evaluation.summary import AgentSamples

SIGNIFICANCE = 0.05
"""p-value under which two incident rates are called different."""
RESOLUTION_MPH = 0.01
"""Speed differences whose interval lies within +-this are not called "faster": below
the table's resolution, they are floating-point noise of near-identical drives."""


@dataclass(frozen=True)
class Comparison:
    """Agents ``a`` and ``b`` (labels) compared; see the module docstring."""

    a: str
    b: str
    paired: bool
    speed_difference: statistics.Interval  # mean mph of a minus b
    improvement: statistics.Interval  # P(a's episode faster than b's)
    identical: bool  # the same speed in every paired episode
    incidents: tuple[int, int]
    incident_rates: tuple[float | None, float | None]  # per 100 miles
    incident_p_value: float
    spread: float | None = None  # s.d. of one seed's mph difference (paired) or pooled

    @property
    def seeds_to_decide(self) -> int | None:
        """Seeds per agent at which the observed difference would be told apart at 80 %
        power, from the measured spread (``None``: no spread measured, or noise-level)."""
        if self.spread is None or self.speed_difference.value is None:
            return None
        return statistics.seeds_needed(self.speed_difference.value, self.spread,
                                       self.paired)

    @property
    def clear(self) -> bool:
        """Whether the speed difference's interval excludes 0 (by more than
        :data:`RESOLUTION_MPH`)."""
        d = self.speed_difference
        return d.has_interval and (d.low > RESOLUTION_MPH  # type: ignore[operator]
                                   or d.high < -RESOLUTION_MPH)  # type: ignore[operator]

    @property
    def verdict(self) -> str:
        """The one-line reading of the comparison."""
        d = self.speed_difference
        if self.identical:
            text = f"{self.a} and {self.b}: the same speed in every episode"
        elif not d.has_interval:
            text = (f"{self.a} vs {self.b}: {d.value:+.2f} mph, too few episodes for an "
                    "interval")
        else:
            span = f"[{d.low:.2f}, {d.high:.2f}]"
            if self.clear:
                text = f"{self.a} faster than {self.b} by {d.value:.2f} mph {span}"
            else:
                text = (f"{self.a} vs {self.b}: no clear difference, {d.value:+.2f} mph "
                        f"{span}")
        if self.improvement.value is not None and not self.identical:
            text += f", P(improvement) {self.improvement.value:.2f}"
        if d.has_interval and not self.clear and not self.identical:
            needed = self.seeds_to_decide
            text += (f", ~{needed} seeds to decide" if needed is not None
                     else ", not decidable by seeds")
        return text

    @property
    def incident_note(self) -> str:
        """The incident rates side by side with the exact test ("" without incidents)."""
        if not sum(self.incidents):
            return ""
        rate_a, rate_b = (_rate(rate) for rate in self.incident_rates)
        if self.incidents_differ:
            word = f"{self.a} fewer" if self._a_fewer else f"{self.b} fewer"
            verdict = f"{word}, p {self.incident_p_value:.3f}"
        else:
            verdict = f"no clear difference, p {self.incident_p_value:.2f}"
        return f"incidents per 100 mi {rate_a} vs {rate_b} ({verdict})"

    @property
    def incidents_differ(self) -> bool:
        return self.incident_p_value < SIGNIFICANCE

    @property
    def _a_fewer(self) -> bool:
        rate_a, rate_b = self.incident_rates
        return (rate_a or 0.0) < (rate_b or 0.0)

    def as_dict(self) -> dict[str, Any]:
        return {
            "a": self.a, "b": self.b, "paired_by_seed": self.paired,
            "speed_difference_mph": self.speed_difference.value,
            "speed_difference_mph_ci": self.speed_difference.ci(),
            "probability_of_improvement": self.improvement.value,
            "probability_of_improvement_ci": self.improvement.ci(),
            "clear": self.clear, "identical": self.identical,
            "speed_difference_spread_mph": self.spread,
            "seeds_to_decide": self.seeds_to_decide,
            "incidents": list(self.incidents),
            "incidents_per_100_miles": list(self.incident_rates),
            "incident_rate_p_value": self.incident_p_value,
            "verdict": self.verdict,
            "incident_verdict": self.incident_note,
        }


def _rate(rate: float | None) -> str:
    if rate is None:
        return "-"
    return "0" if rate == 0 else f"{rate:.2f}" if rate < 10 else f"{rate:.1f}"


def compare(first: AgentSamples, second: AgentSamples,
            settings: statistics.Settings = statistics.DEFAULT_SETTINGS) -> Comparison:
    """Compare two agents' samples; the faster (higher mean mph) becomes ``a``."""
    if np.mean(second.speed_mph) > np.mean(first.speed_mph):
        first, second = second, first
    paired = first.seeds == second.seeds
    x, y = first.speed_mph, second.speed_mph
    name = "speed_mph"
    spread = None
    if paired and len(x) >= 2:
        spread = float(np.std(x - y, ddof=1))
    elif len(x) >= 2 and len(y) >= 2:  # pooled: the two-sample test's s.d.
        spread = float(np.sqrt(((len(x) - 1) * np.var(x, ddof=1) + (len(y) - 1)
                                * np.var(y, ddof=1)) / (len(x) + len(y) - 2)))
    return Comparison(
        a=first.label, b=second.label, paired=paired,
        speed_difference=statistics.mean_difference(x, y, name, paired, settings),
        improvement=statistics.probability_of_improvement(x, y, name, settings),
        identical=paired and bool(np.array_equal(x, y)),
        incidents=(first.incident_total, second.incident_total),
        incident_rates=(statistics.poisson_rate(first.incident_total, first.miles).value,
                        statistics.poisson_rate(second.incident_total, second.miles).value),
        incident_p_value=statistics.rate_ratio_test(first.incident_total, first.miles,
                                                    second.incident_total, second.miles),
        spread=spread)


POWER_DIFFERENCE_MPH = 0.5
"""The difference the power note plans for (:func:`power_note`)."""


def power_note(comparisons: Sequence[Comparison],
               difference: float = POWER_DIFFERENCE_MPH) -> str:
    """How many seeds ``difference`` mph needs at 80 % power, from the median spread of
    the comparisons (paired ones when there are any); "" without a spread."""
    paired = [c.spread for c in comparisons if c.paired and c.spread is not None]
    spreads = paired or [c.spread for c in comparisons if c.spread is not None]
    if not spreads:
        return ""
    spread = float(np.median(spreads))
    needed = statistics.seeds_needed(difference, spread, bool(paired))
    seeds = f"~{needed} seeds" if needed is not None else "more seeds than can be run"
    kind = "per-seed differences" if paired else "per-seed speeds"
    return (f"to tell {difference:g} mph apart at 80% power: {seeds} (median s.d. of "
            f"the {kind} here: {spread:.2f} mph)")


def compare_all(samples: Sequence[AgentSamples],
                settings: statistics.Settings = statistics.DEFAULT_SETTINGS,
                pairs: Sequence[tuple[int, int]] | None = None) -> list[Comparison]:
    """Comparisons of ``pairs`` (indices into ``samples``; default every pair, in the
    agents' order)."""
    pairs = pairs if pairs is not None else list(combinations(range(len(samples)), 2))
    return [compare(samples[i], samples[j], settings) for i, j in pairs]
