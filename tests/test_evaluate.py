"""evaluate.py end to end: the table's numbers come from real episodes, files are written."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

import evaluate

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def test_evaluate_writes_episode_rows_and_summary(tmp_path, capsys):
    output = tmp_path / "run"
    evaluate.main(["--config", str(CONFIGS / "highway_oval.yaml"), "--episodes", "2",
                   "--workers", "2", "--output", str(output)])
    rows = list(csv.DictReader((output / "episodes.csv").open()))
    assert [row["seed"] for row in rows] == ["0", "1"]
    summary = json.loads((output / "summary.json").read_text())
    agent = summary["agents"][0]
    assert agent["agent"] == "lane_keeping" and agent["episodes"] == 2 and agent["laps"] == 2
    # The oval is 1.4 km of centre line; the middle lane (d = 6) is 2 pi 6 m longer.
    for episode in summary["episodes"]:
        assert episode["is_success"]
        assert episode["distance"] == pytest.approx(1402.47 + 2 * 3.14159 * 6.0, rel=0.01)
        assert episode["lap_times"][0] == pytest.approx(episode["time"], abs=0.1)
    assert not list(output.glob(".*.tmp"))  # atomic writes leave no temporary files
    assert "lane_keeping" in capsys.readouterr().out


def test_evaluate_rejects_bad_arguments(tmp_path):
    with pytest.raises(SystemExit):
        evaluate.main(["--agents", "nobody"])
    with pytest.raises(SystemExit):
        evaluate.main(["--episodes", "0"])
    bad = tmp_path / "bad.yaml"
    bad.write_text("environment: x\n")
    with pytest.raises(SystemExit, match="expected a mapping"):
        evaluate.main(["--config", str(bad)])
