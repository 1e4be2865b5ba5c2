"""The printed tables read in an 80-column terminal, every figure whole."""

from __future__ import annotations

import pytest
from rich.console import Console

import evaluate
from sdc_evaluation.analysis import analyse, terminal_output
from sdc_evaluation.statistics import Settings
from sdc_evaluation.tables import wide_table, wrap_verdict

CONFIGS = evaluate.Path(evaluate.__file__).resolve().parent / "configs"
KINDS = ("collision", "acceleration", "jerk", "speed", "lane", "off_road", "red_light")


def track_episode(agent: str, seed: int, mph: float, incidents: int) -> dict:
    """A long track episode with every incident kind and stop-line figures: the widest
    cells the tables get (lap times over 1000 s, rates over 100 per 100 miles)."""
    return {
        "agent": agent, "seed": seed, "laps": 2, "lap_times": [1234.5 + seed, 1300.0 - seed],
        "distance": 1200.0, "mean_speed_mph": mph + 0.37 * seed,
        "longest_distance_without_incident": 900.0,
        "incidents": {kind: incidents * (i + 1) for i, kind in enumerate(KINDS)},
        "max_acceleration": 9.84, "max_jerk": 4.31, "is_success": True, "wall_time": 10.0,
        "red_light_violations": incidents, "max_overshoot": 0.41,
        "stops": [{"line": 0, "time": 1.0, "offset_m": -1.09, "light_state": 0,
                   "overshoot_m": 0.0}],
        "rms_cross_track_error": 0.104, "max_cross_track_error": 0.3,
        "max_lateral_acceleration": 2.29,
    }


@pytest.fixture(scope="module")
def analysis():
    episodes = [track_episode(agent, seed, mph, incidents)
                for agent, mph, incidents in (("fsm_conservative", 46.14, 0),
                                              ("dbw_original_follower", 23.5, 3),
                                              ("dqn:agents/highway/policies/dqn_highway.zip",
                                               46.5, 1))
                for seed in range(5)]
    return analyse(episodes, Settings(resamples=500))


def test_the_tables_fit_80_columns_without_cutting_a_figure(analysis):
    console = Console(width=80, record=True, color_system=None)
    terminal_output(console, analysis, "sdc_gym/TrackLoop-v0: seed(s) 0 1 2 3 4 x 2 lap(s)")
    text = console.export_text()
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= 80
    assert "…" not in text
    rows = {row["label"]: row for row in analysis.rows}
    assert list(rows) == ["fsm_conservative", "dbw_original_follower", "dqn:dqn_highway"]
    for row in rows.values():
        low, high = row["mean_speed_mph_ci"]
        whole = f"{row['mean_speed_mph']:.2f} [{low:.2f}, {high:.2f}]"
        assert any(whole in line for line in lines), whole  # an interval is never folded
    # The three tables, and a verdict for each of the three pairs.
    for heading in ("mph [95% CI]", "incidents by kind", "stop lines and tracking"):
        assert heading in text
    assert sum(line.startswith(("fsm_", "dbw_", "dqn:")) and (" faster than " in line
               or " vs " in line) for line in lines) == 3


def test_wide_table_holds_every_column(analysis):
    table = wide_table(analysis.rows, "wide")
    for header in ("IQM mph [95% CI]", "best lap s", "miles no incident", "max jerk",
                   "CTE rms m", *KINDS):
        assert header in table.headers
    console = Console(width=260, record=True, color_system=None)
    console.print(table.rich())
    assert "…" not in console.export_text()


def test_verdicts_wrap_at_spaces_keeping_intervals_whole():
    line = ("fsm_conservative faster than lane_keeping by 2.33 mph [1.21, 3.45], "
            "P(improvement) 0.75; incidents per 100 mi 224.4 vs 0 (no clear difference, "
            "p 0.06)")
    wrapped = wrap_verdict(line, 80).splitlines()
    assert all(len(part) <= 80 for part in wrapped) and len(wrapped) == 3
    assert wrapped[1].startswith("    P(improvement) 0.75;")
    assert wrapped[2] == "    p 0.06)"
    assert " ".join(part.strip() for part in wrapped) == line


def test_a_default_run_reads_whole_in_80_columns():
    """Four highway agents, one lap each, no incidents (the default comparison): every
    name and figure on its row's one line."""
    episodes = []
    for agent, mph in (("fsm_conservative", 45.85), ("fsm_bold", 47.13),
                       ("dqn_swa_highway", 47.70), ("lane_keeping", 41.89)):
        for seed in range(3):
            episode = track_episode(agent, seed, mph, 0)
            episode.update(lap_times=[6900.0 / (mph * 0.44704) + seed], laps=1,
                           distance=6900.0)
            for key in ("stops", "red_light_violations"):
                episode.pop(key)
            episodes.append(episode)
    console = Console(width=80, record=True, color_system=None)
    terminal_output(console, analyse(episodes, Settings(resamples=500)), "highway")
    lines = console.export_text().splitlines()
    assert max(len(line) for line in lines) <= 80
    for label in ("fsm_conservative", "fsm_bold", "dqn_swa_highway", "lane_keeping"):
        (row,) = [line for line in lines if line.startswith(f"{label} ")
                  and "faster" not in line]
        assert "mph" not in row and row.count("[") == 3  # mph, lap, incidents intervals


def test_long_names_are_never_split_keys_stand_in_for_those_that_do_not_fit():
    """Agent names of external planners in their folders, scenario names: at 80 columns
    every name is printed whole, in a row or in the legend under the table with its key;
    the verdicts wrap at spaces, never inside a name."""
    from sdc_evaluation.scenario_runs import verdict_table

    long_a = "external:path_planning_with_a_long_name@build_release_a"
    long_b = "external:path_planning_with_a_long_name@build_release_b"
    episodes = [track_episode(agent, seed, mph, 0)
                for agent, mph in ((long_a, 46.1), (long_b, 44.0), ("lane_keeping", 42.0))
                for seed in range(3)]
    result = analyse(episodes, Settings(resamples=500), labels={
        long_a: long_a, long_b: long_b, "lane_keeping": "lane_keeping"})
    console = Console(width=80, record=True, color_system=None)
    terminal_output(console, result, "sdc_gym/HighwayLoop-v0: seed(s) 0 1 2 x 1 lap(s)")
    text = console.export_text()
    lines = [line.rstrip() for line in text.splitlines()]
    assert max(len(line) for line in lines) <= 80 and "…" not in text
    for name in (long_a, long_b):
        assert sum(name in line for line in lines) >= 3  # legend and verdicts, whole
        key = next(line.split()[0] for line in lines if line.endswith(f" {name}"))
        assert key in ("(1)", "(2)")
        assert any(line.startswith(f"{key} ") and "[" in line for line in lines)  # its row
    assert any(line.startswith("lane_keeping ") for line in lines)  # short: as it is
    # 3 seeds each: the intervals' headers are marked, the caption says why.
    assert "mph [95% CI]*" in text and "* under 5 seeds: too few to decide" in text

    scenario = "stress_cut_in_10m_with_a_really_long_descriptive_name_beyond_the_table"
    rows = [{"scenario": scenario, "agent": agent, "seed": 0, "passed": False,
             "reason": "collision with car at 123.4 s, 5.6 m ahead in the next lane over"}
            for agent in (long_a, "lane_keeping")]
    console = Console(width=80, record=True, color_system=None)
    console.print(verdict_table(rows, "scenarios").rich(console.width))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80
    words = text.split()
    assert scenario in words and long_a in words and "lane_keeping" in words
