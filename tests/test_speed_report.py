"""``benchmarks/speed_report.py`` and ``speed_targets.py``: the targets' met / not-met logic
and their reasons on constructed numbers, the report's command-line checks, and one real
smoke run of the track part (never a timed assertion: speed is measured, not tested)."""

from __future__ import annotations

import argparse
import io
import re
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import speed_parts
import speed_report
import speed_targets as targets

ROOT = Path(__file__).resolve().parents[1]


def test_sequential_bound() -> None:
    assert targets.sequential_bound(40_000, 40_000) == pytest.approx(20_000)
    assert targets.sequential_bound(10_000, 30_000) == pytest.approx(7_500)


def test_spread() -> None:
    assert targets.spread([3.0, 1.0, 2.0]) == "1 / 2 / 3"
    assert targets.spread([12_345.6]) == "12,346"
    assert targets.spread([1.25, 1.0], 1) == "1.0 / 1.1 / 1.2"  # the median of two: 1.125


def test_learner_target_not_met_gives_the_sequential_bound() -> None:
    rates = {"env": [20_000, 30_000, 25_000], "sb3": [5_000, 6_000, 7_000],
             "sb3-noop": [10_000], "rllib": [300]}
    row = targets.learner_target(rates)
    assert row.met is False
    assert row.measured == "6,000 (sb3, median)"  # the best learner's median
    # 1 / (1/25,000 + 1/10,000) = 7,143
    assert "1/(1/25,000 + 1/10,000) = 7,143 < 40,000" in row.reason
    assert "min = 10,000" in row.reason


def test_learner_target_met_and_below_a_reachable_bound() -> None:
    assert targets.learner_target({"sb3": [45_000], "env": [1e6]}).met is True
    row = targets.learner_target({"sb3": [30_000], "sb3-noop": [200_000], "env": [200_000]})
    assert row.met is False  # the bound (100,000) is above the goal: the glue loses it
    assert "below its sequential bound 100,000" in row.reason and "0.30 of it" in row.reason
    assert targets.learner_target({"env": [1.0]}).met is None  # no learner measured


def test_learner_target_of_a_split_learner_is_bounded_by_the_split_env() -> None:
    rates = {"env": [20_000], "env-split": [36_000], "sb3": [8_000], "sb3-noop": [18_000],
             "sb3-split": [10_000]}
    row = targets.learner_target(rates)
    assert row.measured == "10,000 (sb3-split, median)"
    # 1 / (1/36,000 + 1/18,000) = 12,000: the split env alone and SB3's own no-op case
    assert row.reason.startswith("sb3-split's sequential bound 1/(1/env + 1/learner) = "
                                 "1/(1/36,000 + 1/18,000) = 12,000 < 40,000")
    # The large settings: their own env case and their own no-op case.
    large = targets.learner_target({**rates, "env-large": [90_000], "sb3-large": [33_000],
                                    "sb3-large-noop": [90_000]})
    assert large.measured == "33,000 (sb3-large, median)"
    assert "below its sequential bound 45,000 (env 90,000, learner 90,000)" in large.reason
    assert "0.73 of it" in large.reason


def test_threads_target() -> None:
    rates = {(64, 1): [90_000], (64, 2): [150_000],  # E < 256 does not count
             (256, 1): [40_000, 41_000, 39_000], (256, 2): [60_000, 62_000, 58_000],
             (1024, 2): [55_000]}
    row = targets.threads_target(rates)
    assert row.met is False and row.measured == "60,000 (E = 256, 2 kernel threads, median)"
    assert "2 kernel threads run 1.50x one thread (40,000)" in row.reason
    assert "2.5x one thread's rate, more than a perfect 2-way split" in row.reason
    # The process split counts too: the best of the two ways at any E >= 256.
    split = targets.threads_target({**rates, (256, targets.SPLIT): [75_000, 76_000, 70_000]})
    assert split.measured == "75,000 (E = 256, 2 processes, median)"
    assert "2 processes run 1.88x one thread (40,000)" in split.reason
    assert targets.threads_target({(1024, targets.SPLIT): [100_000]}).met is True
    assert targets.threads_target({(256, 2): [120_000]}).met is True
    assert targets.threads_target({(64, 2): [1e6]}).met is None
    within = targets.threads_target({(256, 1): [60_000], (256, 2): [70_000]})
    assert "within a perfect 2-way split" in within.reason
    # Measured two-core scaling bounds the split: 1.6 x 60,000 = 96,000 < 100,000.
    bounded = targets.threads_target({(256, 1): [60_000], (256, 2): [70_000]},
                                     scaling=[1.5, 1.6, 1.7])
    assert "more than a perfect split on this machine (1.60x" in bounded.reason


def test_cold_target() -> None:
    row = targets.cold_target({"track": [17.5], "highway": [9.0, 8.0, 30.0]},
                              {"track": [1.2], "highway": [1.7]}, {"track": 15})
    assert row.met is False
    assert row.measured == "17.5 s (track; best 9.0 s)"  # medians: 17.5 and 9.0
    assert row.reason.startswith("1 of 2 envs over") and "(15 functions for track)" in row.reason
    assert "the worst first step is 1.7 s, within the goal" in row.reason
    assert targets.cold_target({"track": [9.9]}).met is True
    assert targets.cold_target({}).met is None


def test_track_target() -> None:
    met = targets.track_target([2_137.0], [2_046.0])
    assert met.met is True and met.measured == "1.04x (2,137 / 2,046 steps/s)"
    noisy = targets.track_target([900.0, 1_000.0, 1_100.0], [1_000.0, 1_050.0, 1_200.0])
    assert noisy.met is False and "the rounds overlap" in noisy.reason
    slower = targets.track_target([500.0, 600.0], [1_000.0])
    assert "slower in every round (best now 600 < worst scalar 1,000" in slower.reason
    assert targets.track_target([], [1.0]).met is None


def test_targets_table_and_parts_not_run() -> None:
    rows = speed_report.judge({"track": speed_parts.TrackResult([2.0], [1.0])})
    assert [row.met for row in rows] == [None, None, None, True]
    assert rows[0].reason == "part 'learners' not run"
    lines = targets.targets_table(rows)
    assert lines[0] == "| target | measured | met | the measured reason |"
    assert lines[2].endswith("| not measured | not measured | part 'learners' not run |")
    assert lines[5] == ("| single TrackLoop-v0 env >= the scalar code | 2.00x (2 / 1 steps/s) "
                        "| met | - |")


def test_parts_argument() -> None:
    assert speed_report.parse_parts("track, cold,track") == ["track", "cold"]
    with pytest.raises(argparse.ArgumentTypeError,
                       match="unknown part 'gpu'; choices: learners, threads, cold, track"):
        speed_report.parse_parts("track,gpu")
    with pytest.raises(argparse.ArgumentTypeError, match="no part in ','"):
        speed_report.parse_parts(",")


def test_bad_command_lines_name_the_argument(tmp_path, capsys) -> None:
    with pytest.raises(SystemExit):
        speed_report.main(["--parts", "gpu"])
    assert "--parts: unknown part 'gpu'; choices:" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        speed_report.main(["--scalar-tree", str(tmp_path)])
    assert f"--scalar-tree: {tmp_path} holds no sdc_gym/" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        speed_report.main(["--race-budget-s", "-1"])
    assert "--race-budget-s must be > 0, got -1.0" in capsys.readouterr().err


def test_quick_settings_shrink_every_part() -> None:
    quick = speed_parts.quick(speed_parts.Settings(target_mph=43.0))
    full = speed_parts.Settings()
    assert quick.target_mph == 43.0
    assert quick.learner_rounds == quick.thread_rounds == quick.track_rounds == 1
    assert quick.track_steps < full.track_steps and quick.race_budget_s < full.race_budget_s
    assert len(quick.cold_cases) < len(full.cold_cases)


def _has_scalar_commit() -> bool:
    done = subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e",
                           f"{speed_parts.SCALAR_COMMIT}^{{commit}}"], capture_output=True,
                          check=False)
    return done.returncode == 0


@pytest.mark.skipif(not _has_scalar_commit(),
                    reason=f"no commit {speed_parts.SCALAR_COMMIT} (a shallow clone)")
def test_quick_track_part_reports_a_ratio() -> None:
    """A real run of ``--quick --parts track``: both trees' single track env, one round."""
    out = io.StringIO()
    results, rows = speed_report.run(["track"], speed_parts.QUICK, out)
    report = out.getvalue()
    assert len(results["track"].now) == len(results["track"].scalar) == 1
    assert re.search(r"^\| now \| [\d,]+ \| \d+\.\d\d \|$", report, re.MULTILINE), report
    assert re.search(r"^\| single TrackLoop-v0 env >= the scalar code \| \d+\.\d\dx \(", report,
                     re.MULTILINE), report
    assert rows[3].met in (True, False)  # either, on a shared machine: measured, not asserted


def test_learner_lines_bound_each_learner_by_its_own_env_and_noop_cases() -> None:
    result = speed_parts.LearnerResult(rates={
        "env": [50_000], "env-split": [40_000], "env-large": [90_000], "sb3": [15_000],
        "sb3-noop": [25_000], "sb3-split": [12_000], "sb3-large": [36_000],
        "sb3-large-noop": [90_000], "rllib": [800]})
    lines = speed_parts.learner_lines(result)
    # 1/(1/50,000 + 1/25,000) = 16,667; 1/(1/40,000 + 1/25,000) = 15,385; 45,000
    assert "| sb3 | env | 50,000 | 25,000 | 16,667 | 15,000 | 0.90 |" in lines
    assert "| sb3-split | env-split | 40,000 | 25,000 | 15,385 | 12,000 | 0.78 |" in lines
    assert "| sb3-large | env-large | 90,000 | 90,000 | 45,000 | 36,000 | 0.80 |" in lines
    assert not any(line.startswith("| rllib | env") for line in lines)  # no no-op case
