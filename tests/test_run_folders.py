"""Run folders are never overwritten silently; runs compare side by side."""

from __future__ import annotations

import json
import os

import pytest

import evaluate
from sdc_evaluation import run_folders
from sdc_evaluation.outputs import OWNED_NAMES

OVAL = str(evaluate.Path(evaluate.__file__).resolve().parent / "configs" / "highway_oval.yaml")
QUICK = ["--agents", "lane_keeping", "--config", OVAL, "--no-plots", "--no-progress",
         "--workers", "1", "--bootstrap-resamples", "500"]


def test_new_folders_are_timestamped_and_never_shared(tmp_path):
    root = tmp_path / "results"
    first = run_folders.new_run_folder(root, now=0.0)
    second = run_folders.new_run_folder(root, now=0.0)  # the same second
    assert second.name == f"{first.name}-2" and first.is_dir() and second.is_dir()


def test_latest_is_a_link_replaced_atomically_and_an_old_folder_is_kept(tmp_path):
    root = tmp_path / "results"
    (root / "latest").mkdir(parents=True)  # a results/latest folder of an older version
    (root / "latest" / "summary.json").write_text("{}")
    first = run_folders.new_run_folder(root)
    link = run_folders.point_latest_at(first, root)
    assert link.is_symlink() and os.readlink(link) == first.name  # relative: movable
    kept = [path for path in root.iterdir() if path.name not in (first.name, "latest")]
    assert [path.name for path in kept[0].iterdir()] == ["summary.json"]  # renamed, kept
    second = run_folders.new_run_folder(root)
    run_folders.point_latest_at(second, root)
    assert link.resolve() == second.resolve()
    assert not list(root.glob(".latest*"))


def test_an_explicit_output_is_refused_when_it_holds_files(tmp_path):
    output = tmp_path / "run"
    output.mkdir()
    (output / "summary.json").write_text("{}")
    (output / "incident_gallery").mkdir()
    (output / "notes.txt").write_text("mine")
    with pytest.raises(SystemExit, match="--overwrite"):
        run_folders.prepare_output(output, False, OWNED_NAMES)
    run_folders.prepare_output(output, True, OWNED_NAMES)
    assert sorted(path.name for path in output.iterdir()) == ["notes.txt"]  # only ours go
    empty = tmp_path / "empty"
    empty.mkdir()
    run_folders.prepare_output(empty, False, OWNED_NAMES)  # empty: fine
    run_folders.prepare_output(tmp_path / "new" / "run", False, OWNED_NAMES)
    assert (tmp_path / "new" / "run").is_dir()


def test_evaluate_makes_a_new_folder_per_run_and_compare_reads_them(tmp_path, monkeypatch,
                                                                      capsys):
    monkeypatch.chdir(tmp_path)
    first = evaluate.main([*QUICK, "--seeds", "0", "1"])["output"]
    second = evaluate.main([*QUICK, "--seeds", "2", "3"])["output"]
    assert first != second and first.parent == second.parent == evaluate.Path("results")
    latest = tmp_path / "results" / "latest"
    assert latest.resolve() == second.resolve()
    assert json.loads((first / "summary.json").read_text())["run"]["seeds"] == [0, 1]
    with pytest.raises(SystemExit, match="already holds files"):
        evaluate.main([*QUICK, "--seeds", "0", "--output", str(first)])
    capsys.readouterr()

    out = tmp_path / "compared"
    result = evaluate.main(["compare", str(first), "results/latest", "--output", str(out),
                            "--bootstrap-resamples", "500"])
    labels = [row["label"] for row in result["rows"]]
    assert labels == [f"{first.name}/lane_keeping", f"{second.name}/lane_keeping"]
    (comparison,) = result["comparisons"]  # the same agent across the two runs
    assert not comparison.paired  # other seeds: independent samples
    speeds = {row["label"]: row["mean_speed_mph"] for row in result["rows"]}
    assert comparison.speed_difference.value == pytest.approx(abs(
        speeds[labels[0]] - speeds[labels[1]]))
    # The same statistics as each run's own: one agent's interval is the same in both.
    own = json.loads((first / "summary.json").read_text())["agents"][0]
    assert result["rows"][0]["mean_speed_mph_ci"] == pytest.approx(own["mean_speed_mph_ci"])
    printed = capsys.readouterr().out
    assert " ".join(printed.split()).count(comparison.verdict.split(",")[0]) == 1
    assert {"report.html", "agents.csv", "comparisons.csv", "summary.json"} <= {
        path.name for path in out.iterdir()}
    with pytest.raises(SystemExit, match="not a run folder"):
        evaluate.main(["compare", str(first), str(tmp_path)])
