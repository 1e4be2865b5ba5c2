"""``benchmarks/learner_time_to_mph.py``'s race loop on constructed scores and a fake clock:
where it stops, what it reports, and its command-line checks (no learner trains here)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import learner_time_to_mph as ttm

from sdc_training.validation_laps import LapScore


class Clock:
    """A clock that moves only when the fake learner trains or the scorer scores."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class FakeLearner:
    """Trains ``samples`` in ``seconds_per_chunk`` of the fake clock's time."""

    def __init__(self, clock: Clock, seconds_per_chunk: float = 10.0) -> None:
        self.clock, self.seconds = clock, seconds_per_chunk
        self.samples, self.chunks = 0, 0

    def train(self, samples: int) -> int:
        self.clock.now += self.seconds
        self.samples += samples
        self.chunks += 1
        return self.samples

    def policy(self) -> str:
        return f"policy after {self.chunks} chunks"

    def close(self) -> None:
        pass


def scorer(clock: Clock, mph: list[float], seconds: float = 2.0):
    """Scores ``mph`` in order, each costing ``seconds`` of the clock; records the policies."""
    seen: list[str] = []

    def score(policy: str) -> LapScore:
        clock.now += seconds
        seen.append(policy)
        value = mph[len(seen) - 1]
        return LapScore(value, value - 1, value + 1, True, True, {"incidents": len(seen) - 1})

    score.seen = seen  # type: ignore[attr-defined]
    return score


def test_stops_at_the_first_score_reaching_the_target() -> None:
    clock = Clock()
    learner = FakeLearner(clock)
    score = scorer(clock, [40.0, 41.0, 42.5, 44.0])
    result = ttm.race("fake", learner, score, target_mph=42.0, check_every=1000,
                      budget_s=1e9, clock=clock)
    assert [p.mph for p in result.curve] == [40.0, 41.0, 42.5]  # 44.0 never scored
    assert learner.chunks == 2
    assert [p.samples for p in result.curve] == [0, 1000, 2000]
    assert result.reached_s == pytest.approx(20.0)  # two chunks of training; scoring left out
    assert result.wall_s == pytest.approx(26.0)  # and with the three scores
    assert result.samples_per_s == pytest.approx(100.0)  # 2000 samples in 20 s
    assert [p.incidents for p in result.curve] == [0, 1, 2]
    assert score.seen == ["policy after 0 chunks", "policy after 1 chunks",
                          "policy after 2 chunks"]
    assert result.outcome() == "20 s (0.00 M samples)"


def test_an_untrained_policy_at_the_target_needs_no_training() -> None:
    clock = Clock()
    learner = FakeLearner(clock)
    result = ttm.race("fake", learner, scorer(clock, [45.0]), 42.0, 1000, 1e9, clock=clock)
    assert result.reached_s == 0.0 and learner.chunks == 0 and len(result.curve) == 1


def test_stops_when_the_budget_runs_out() -> None:
    clock = Clock()
    learner = FakeLearner(clock)
    # each chunk + score costs 12 s: the scores end at walls 2, 14, 26, 38 (>= 30: stop)
    result = ttm.race("fake", learner, scorer(clock, [40.0, 41.5, 41.0, 40.5, 50.0]),
                      target_mph=42.0, check_every=500, budget_s=30.0, clock=clock)
    assert result.reached_s is None
    assert len(result.curve) == 4 and learner.chunks == 3
    assert result.best_mph == 41.5
    assert result.outcome() == "not reached in 30 s, best 41.5 mph"


def test_race_table_side_by_side() -> None:
    clock = Clock()
    fast = ttm.race("a", FakeLearner(clock, 5.0), scorer(clock, [40.0, 43.0]), 42.0, 2000,
                    1e9, clock=clock)
    slow = ttm.race("b", FakeLearner(clock, 50.0), scorer(clock, [40.0, 40.5]), 42.0, 2000,
                    50.0, clock=clock)
    lines = ttm.race_table([fast, slow])
    assert lines[0].startswith("| learner | samples/s | training wall to 42.0 mph")
    assert lines[2] == "| a | 400 | 5 s (0.00 M samples) | 2,000 | 9 |"
    assert lines[3] == "| b | 40 | not reached in 50 s, best 40.5 mph | 2,000 | 54 |"
    assert lines[4] == "a mph curve (M samples: mph): 0.00: 40.0, 0.00: 43.0"


def test_command_line_checks() -> None:
    assert ttm.parse_learners("sb3, rllib") == ["sb3", "rllib"]
    with pytest.raises(argparse.ArgumentTypeError, match="unknown learner 'ppo'; choices: sb3"):
        ttm.parse_learners("sb3,ppo")
    with pytest.raises(argparse.ArgumentTypeError, match="must be > 0, got -5"):
        ttm.positive(float)("-5")
    with pytest.raises(argparse.ArgumentTypeError, match="'x' is not a int"):
        ttm.positive(int)("x")
    with pytest.raises(SystemExit):
        ttm.main(["--budget-s", "0"])


def test_optional_learners_are_skipped_with_their_install_line(monkeypatch) -> None:
    monkeypatch.setattr(ttm.importlib.util, "find_spec", lambda name: None)
    assert "pip install --no-deps torchrl" in ttm.skip_reason("torchrl")
    assert "pip install --no-deps pufferlib-core" in ttm.skip_reason("pufferlib")
    assert "Ray is not installed" in ttm.skip_reason("rllib")
    assert ttm.skip_reason("sb3") is None


def test_a_tiny_budget_still_trains_one_chunk() -> None:
    clock = Clock()
    learner = FakeLearner(clock)
    result = ttm.race("fake", learner, scorer(clock, [40.0, 41.0, 50.0]), 42.0, 100,
                      budget_s=0.5, clock=clock)
    assert learner.chunks == 1 and len(result.curve) == 2
    assert result.samples_per_s == pytest.approx(10.0)
