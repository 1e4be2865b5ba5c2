"""Incident reports (evaluation/incident_reports.py) and stopping at the first incident."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

import evaluate
from sdc_evaluation.episodes import REPORTS_KEY
from sdc_evaluation.incident_reports import IncidentRecorder


def observation(t: float) -> dict:
    """Ego along x at 10 m/s; car 7 20 m ahead of it, car 9 500 m ahead, car 4 masked."""
    x = 10.0 * t
    fusion = np.array([[7, x + 20.0, 1.0, 10.0, 0.0, x + 20.0, 6.0],
                       [9, x + 500.0, 1.0, 10.0, 0.0, x + 500.0, 6.0],
                       [4, x + 5.0, 1.0, 10.0, 0.0, x + 5.0, 6.0]], dtype=np.float32)
    return {"ego": np.array([x, 1.0, x, 6.0, 0.0, 10.0], dtype=np.float32),
            "sensor_fusion": fusion, "sensor_fusion_mask": np.array([1, 1, 0], dtype=np.int8)}


def test_a_report_holds_the_last_seconds_of_the_ego_and_the_cars_near_it():
    recorder = IncidentRecorder(history_s=3.0, radius_m=60.0)
    for step in range(60):  # 0.0 .. 5.9 s, the incident at 5.0 s
        t = step / 10.0
        recorder.add(observation(t), {"time": t, "new_incidents": ["collision"] if step == 50
                                      else []})
    log = [{"kind": "collision", "time": 5.0, "step": 250, "x": 50.0, "y": 1.0, "s": 50.0,
            "d": 6.0, "value": 7.0}]
    (report,) = recorder.reports(log)
    assert {key: report[key] for key in log[0]} == log[0]
    history = report["history"]
    assert history["time"] == pytest.approx(np.arange(20, 51) / 10.0)  # 2.0 .. 5.0 s
    assert history["ego"]["x"] == pytest.approx(10.0 * np.array(history["time"]), abs=1e-4)
    assert set(history["ego"]) == {"x", "y", "s", "d", "yaw", "speed"}
    (car,) = history["cars"]  # car 9 is never near, car 4 is not sensed
    assert car["id"] == 7 and car["time"] == history["time"]
    assert np.array(car["x"]) - np.array(history["ego"]["x"]) == pytest.approx(20.0, abs=1e-3)
    json.dumps(report)  # plain Python types
    with pytest.raises(ValueError, match="history_s"):
        IncidentRecorder(history_s=0.0)


def test_stop_at_incident_ends_the_episode_and_the_report_shows_how_it_came(tmp_path):
    """Lane keeping under a 10 m/s speed limit: the first incident is the speed crossing
    10 m/s while it accelerates from rest; the episode ends there and the report's
    history is the 3 s before it."""
    config = tmp_path / "slow.yaml"
    config.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoop-v0", "config": {
        "map": "oval", "traffic": {"car_count": 8},
        "incident_rules": {"speed_limit": 10.0}}}))
    output = tmp_path / "run"
    result = evaluate.main(["--agents", "lane_keeping", "--config", str(config), "--seeds", "4",
                            "--stop-at-incident", "--no-plots", "--no-progress",
                            "--output", str(output)])
    (episode,) = result["episodes"]
    assert episode["termination_reason"] == "stop_at_incident"
    assert episode["abort_message"] == "stopped at the first incident: speed"
    assert episode["incident_total"] == 1 and episode["laps"] == 0
    (entry,) = episode["incident_log"]
    assert entry["kind"] == "speed" and entry["value"] > 10.0
    assert episode["time"] - 0.06 < entry["time"] <= episode["time"]  # its step is the last

    (report,) = json.loads((output / "incidents.json").read_text())
    assert report["agent"] == "lane_keeping" and report["seed"] == 4
    assert {key: report[key] for key in entry} == entry
    history = report["history"]
    assert history["time"][-1] == pytest.approx(episode["time"])
    assert history["time"][-1] - history["time"][0] == pytest.approx(3.0, abs=0.07)
    speeds = np.array(history["ego"]["speed"])
    assert speeds[-1] > 10.0 >= speeds[-2] and np.all(np.diff(speeds) > 0)  # accelerating
    ego = np.array([history["ego"]["x"], history["ego"]["y"]]).T
    for car in history["cars"]:  # each came within 60 m of the ego in those 3 s
        at = np.searchsorted(history["time"], car["time"])
        gaps = np.hypot(np.array(car["x"]) - ego[at, 0], np.array(car["y"]) - ego[at, 1])
        assert gaps.min() <= 60.0
    assert REPORTS_KEY not in json.loads((output / "summary.json").read_text())["episodes"][0]
    assert output / "incidents.json" in result["files"]


def test_history_zero_turns_reports_off_and_writes_no_report_file(tmp_path):
    """With reports on, incidents.json is always written (``[]`` without incidents, so a
    ``--scenario results/latest/incidents.json`` chain finds it); ``--incident-history 0``
    turns reports off: no file (an empty one would claim no incidents)."""
    from sdc_evaluation.files import write_incident_reports

    assert write_incident_reports(tmp_path / "none.json", []) == 0
    assert (tmp_path / "none.json").read_text() == "[]\n"
    output = tmp_path / "run"
    result = evaluate.main(["--agents", "lane_keeping", "--env", "sdc_gym/HighwayLoop-v0",
                            "--seeds", "0", "--laps", "1", "--incident-history", "0",
                            "--config", str(evaluate.Path(evaluate.__file__).parent
                                            / "configs" / "highway_oval.yaml"),
                            "--no-plots", "--no-progress", "--output", str(output)])
    assert REPORTS_KEY not in result["episodes"][0]
    assert not (output / "incidents.json").exists()
    with pytest.raises(SystemExit):
        evaluate.parse_args(["--incident-history", "-1"])
