"""evaluate.py end to end: the table's numbers come from real episodes, files are written."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

import evaluate
from sdc_agents.registry import AGENTS
from sdc_evaluation.episodes import TRACE_KEY
from sdc_evaluation.files import load_traces

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
OVAL = str(CONFIGS / "highway_oval.yaml")
# The oval is 1.4 km of centre line; the middle lane (d = 6) is 2 pi 6 m longer.
OVAL_MIDDLE_LANE_LAP = 1402.47 + 2 * math.pi * 6.0
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_evaluate_writes_episode_rows_summary_traces_and_plots(tmp_path, capsys):
    output = tmp_path / "run"
    result = evaluate.main(["--agents", "lane_keeping", "--config", OVAL, "--episodes", "2",
                            "--workers", "2", "--output", str(output)])
    rows = list(csv.DictReader((output / "episodes.csv").open()))
    assert [row["seed"] for row in rows] == ["0", "1"]
    summary = json.loads((output / "summary.json").read_text())
    agent = summary["agents"][0]
    assert agent["agent"] == "lane_keeping" and agent["episodes"] == 2 and agent["laps"] == 2
    for episode in summary["episodes"]:
        assert TRACE_KEY not in episode  # traces go to traces.npz, not into the JSON
        assert episode["is_success"]
        assert episode["distance"] == pytest.approx(OVAL_MIDDLE_LANE_LAP, rel=0.01)
        assert episode["lap_times"][0] == pytest.approx(episode["time"], abs=0.1)
    # One trace per episode: the reset state plus every step; distance only grows.
    traces = load_traces(output / "traces.npz")
    assert sorted(traces) == [("lane_keeping", 0), ("lane_keeping", 1)]
    for episode in summary["episodes"]:
        trace = traces[("lane_keeping", episode["seed"])]
        assert len(trace) == episode["env_steps"] + 1
        assert all(len(column) == len(trace) for column in trace.columns().values())
        assert np.all(np.diff(trace.distance) >= 0.0) and trace.distance[0] == 0.0
        assert trace.distance[-1] == pytest.approx(episode["distance"])
        assert trace.time[-1] == pytest.approx(episode["time"])
        assert trace.speed.max() * 2.2369362920544 < 50.0  # lane keeping stays legal
    for name in ("means.png", "incidents.png", "profiles.png", "speed_time.png",
                 "incident_map.png"):
        data = (output / name).read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 5000
        assert output / name in result["files"]
    assert (output / "report.html") in result["files"]
    assert not list(output.glob(".*.tmp"))  # atomic writes leave no temporary files
    assert "lane_keeping" in capsys.readouterr().out
    # The agent's row carries its intervals, in the JSON and in agents.csv.
    speeds = [episode["mean_speed_mph"] for episode in summary["episodes"]]
    low, high = agent["mean_speed_mph_ci"]
    assert agent["mean_speed_mph"] == pytest.approx(np.mean(speeds))
    # Student's t with 1 degree of freedom, t(1; 0.975) = 12.7062: s / sqrt(2) = |a - b| / 2.
    half = 12.7062 * abs(speeds[0] - speeds[1]) / 2
    assert (low, high) == pytest.approx((np.mean(speeds) - half, np.mean(speeds) + half))
    assert agent["incidents_per_100_miles"] == 0.0
    miles = sum(episode["distance"] for episode in summary["episodes"]) / 1609.344
    assert agent["incidents_per_100_miles_ci"] == pytest.approx([0.0, 368.888 / miles],
                                                                rel=1e-4)  # Garwood, k = 0
    (csv_row,) = csv.DictReader((output / "agents.csv").open())
    assert float(csv_row["mean_speed_mph_ci_low"]) == pytest.approx(low)
    assert float(csv_row["mean_speed_mph_ci_high"]) == pytest.approx(high)
    assert summary["run"]["statistics"]["bootstrap_resamples"] == 10_000
    assert summary["run"]["seeds"] == [0, 1] and summary["comparisons"] == []


def test_endurance_drives_on_and_reports_miles_without_incident(tmp_path, capsys):
    output = tmp_path / "endurance"
    result = evaluate.main(["--agents", "lane_keeping", "--config", OVAL, "--endurance", "2",
                            "--seeds", "5", "3", "--workers", "2", "--no-plots",
                            "--output", str(output)])
    episodes = json.loads((output / "summary.json").read_text())["episodes"]
    assert [episode["seed"] for episode in episodes] == [5, 3]  # --seeds, in its order
    for episode in episodes:
        assert episode["laps"] == 2 and episode["termination_reason"] == "laps_completed"
        assert episode["incident_total"] == 0
        assert episode["longest_distance_without_incident"] == pytest.approx(
            2 * OVAL_MIDDLE_LANE_LAP, rel=0.01)
        assert episode["distance_without_incident"] == pytest.approx(episode["distance"])
    assert not (output / "profiles.png").exists()
    assert len(load_traces(output / "traces.npz")) == 2
    out = capsys.readouterr().out
    assert "276.53" in out and "endurance" in out
    assert len(result["episodes"]) == 2


def test_endurance_config_counts_collisions_and_allows_the_time():
    assert evaluate.parse_args(["--output", "x"]).output == Path("x")
    args = evaluate.parse_args(["--config", OVAL, "--endurance", "7"])
    env_id, config = evaluate.env_settings(args)
    assert env_id == "sdc_gym/HighwayLoop-v0" and config["map"] == "oval"
    assert config["laps"] == 7 and config["terminate_on_collision"] is False
    assert config["max_duration"] == 7 * 1000.0
    assert args.seeds == [0]  # one episode per agent unless told otherwise
    # Ordinary runs: laps from the command line, time enough for them.
    _, config = evaluate.env_settings(evaluate.parse_args(["--laps", "3"]))
    assert config["laps"] == 3 and config["max_duration"] == 3000.0
    assert "terminate_on_collision" not in config


def test_map_option_overrides_the_config_and_names_bad_maps(tmp_path, monkeypatch):
    from tests.conftest import HIGHWAY_MAP_FILE

    _, config = evaluate.env_settings(evaluate.parse_args(
        ["--config", OVAL, "--map", str(HIGHWAY_MAP_FILE)]))
    assert config["map"] == str(HIGHWAY_MAP_FILE) and config["traffic"] == {"car_count": 8}
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit, match=r"neither a built-in \(default, oval\) nor an existing"):
        evaluate.main(["--map", "no_such_map.csv", "--agents", "lane_keeping"])
    with pytest.raises(SystemExit, match="--map is for the highway envs"):
        evaluate.main(["--config", str(CONFIGS / "track_loop.yaml"), "--map", "oval"])


def test_seed_options():
    assert evaluate.parse_args([]).seeds == [0, 1, 2]
    assert evaluate.parse_args(["--seed", "4", "--episodes", "2"]).seeds == [4, 5]
    assert evaluate.parse_args(["--seeds", "3", "5", "8", "5"]).seeds == [3, 5, 8]


def test_default_comparison_is_the_fsm_the_committed_policy_and_the_baseline():
    from sdc_agents.committed_policies import committed_policies
    from sdc_agents.registry import parse_agent_spec

    assert evaluate.COMMITTED_POLICY == "dqn_swa_highway"  # the one faster than fsm_bold
    assert list(evaluate.DEFAULT_AGENTS) == ["fsm_conservative", "fsm_bold",
                                             evaluate.COMMITTED_POLICY, "lane_keeping"]
    assert parse_agent_spec(evaluate.COMMITTED_POLICY) == (None, "dqn_swa_highway")  # a name
    policy = committed_policies()[evaluate.COMMITTED_POLICY]
    assert policy.algo == "dqn" and policy.model.is_file()
    assert policy.env_id == evaluate.DEFAULT_ENV
    assert "dqn_highway" in committed_policies()  # the first one stays loadable by name
    assert evaluate.parse_args([]).agents is None  # resolved per env in main()
    assert set(evaluate.DEFAULT_TRACK_AGENTS) <= set(AGENTS)


@pytest.mark.parametrize("argv, message", [
    (["--agents", "nobody"], "lane_keeping"),  # the valid agents are listed
    (["--episodes", "0"], "--episodes must be >= 1"),
    (["--endurance", "0"], "--endurance must be >= 1"),
    (["--seeds", "1", "2", "--seed", "3"], "do not combine"),
    (["--seeds", "1", "--episodes", "3"], "do not combine"),
    (["--endurance", "3", "--laps", "2"], "drop --laps"),
    (["--output", ""], "empty string"),
    (["--output", "  "], "empty string"),
    (["--overwrite"], "--overwrite needs --output"),
    (["--seeds", "1", "2", "--plot-seed", "7"], "--plot-seed 7 is not among"),
    (["--bootstrap-resamples", "10"], "--bootstrap-resamples must be >= 100"),
    (["compare", "one_run"], "at least two run folders"),
])
def test_evaluate_rejects_bad_arguments(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # should a check fail, nothing lands in the checkout
    with pytest.raises(SystemExit):
        evaluate.main(argv)
    assert message in capsys.readouterr().err


def test_evaluate_rejects_bad_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    bad = tmp_path / "bad.yaml"
    bad.write_text("environment: x\n")
    with pytest.raises(SystemExit, match="expected a mapping"):
        evaluate.main(["--config", str(bad)])
    broken = tmp_path / "broken.yaml"
    broken.write_text("config: [unclosed\n")
    with pytest.raises(SystemExit, match="not valid YAML"):
        evaluate.main(["--config", str(broken)])
    with pytest.raises(SystemExit, match="config file not found"):
        evaluate.main(["--config", str(tmp_path / "missing.yaml")])
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text("config:\n  no_such_key: 1\n")
    with pytest.raises(SystemExit, match="no_such_key"):
        evaluate.main(["--config", str(unknown), "--output", str(tmp_path / "out")])
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    with pytest.raises(SystemExit):
        evaluate.main(["--output", str(a_file)])


def _track_episode(agent: str, seed: int, stops: list[float], red: int) -> dict:
    """A track-loop episode summary as TrackLoop-v0 writes it (only the fields used)."""
    return {
        "agent": agent, "seed": seed, "laps": 1, "lap_times": [600.0 + seed],
        "distance": 7000.0,
        "mean_speed_mph": 22.0, "longest_distance_without_incident": 7000.0,
        "incidents": {"collision": 0, "acceleration": 0, "jerk": 0, "speed": 0, "lane": 0,
                      "off_road": 0, "red_light": red},
        "max_acceleration": 1.0, "max_jerk": 0.5, "is_success": True, "wall_time": 1.0,
        "red_light_violations": red, "max_overshoot": max([0.0, *stops]),
        "stops": [{"line": i, "time": 10.0 * i, "offset_m": offset, "light_state": 0,
                   "overshoot_m": max(offset, 0.0)} for i, offset in enumerate(stops)],
        "rms_cross_track_error": 0.05 + 0.01 * seed, "max_cross_track_error": 0.3,
        "max_lateral_acceleration": 2.0 + seed,
    }


def test_aggregate_reports_red_lights_and_stop_accuracy_on_a_track():
    from sdc_evaluation.summary import aggregate
    from sdc_evaluation.tables import incidents_table, track_table, wide_table

    episodes = [_track_episode("dbw", 0, [-1.5, -0.4], 0), _track_episode("dbw", 1, [0.3], 1)]
    (row,) = aggregate(episodes)
    assert row["incidents"]["red_light"] == 1 and row["red_light_violations"] == 1
    assert row["stops"] == 3
    assert row["stop_short_max_m"] == pytest.approx(1.5)  # the stop 1.5 m before its line
    assert row["max_overshoot"] == pytest.approx(0.3)
    assert row["rms_cross_track_error"] == pytest.approx(0.06)  # the worse episode
    assert row["max_lateral_acceleration"] == pytest.approx(3.0)
    assert "short m" in track_table([row]).headers
    assert "red light" in incidents_table([row]).headers
    headers = wide_table([row], "track").headers
    assert "red_light" in headers and "short of line m" in headers
    assert row["incidents_per_100_miles"] == pytest.approx(100.0 / (14_000.0 / 1609.344))


def test_highway_rows_have_no_track_columns():
    from sdc_evaluation.summary import aggregate

    episode = _track_episode("lane_keeping", 0, [], 0)
    for key in ("stops", "red_light_violations", "max_overshoot", "rms_cross_track_error",
                "max_cross_track_error", "max_lateral_acceleration"):
        episode.pop(key)
    episode["incidents"].pop("red_light")
    (row,) = aggregate([episode])
    assert "stops" not in row and "red_light" not in row["incidents"]
