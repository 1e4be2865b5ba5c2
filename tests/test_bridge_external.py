"""External planners end to end: a planner process speaking the original's protocol drives
the highway through the socket exactly like its in-process twin, and every fault ends the
episode with its reason, in bounded time, leaving no process behind."""

from __future__ import annotations

import json
import os
import shlex
import socket
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import pytest

import evaluate
from sdc_agents.registry import AGENTS, make_agent, parse_agent_spec
from sdc_evaluation.episodes import EpisodeSpec, run_episode
from sdc_gym.bridge import (
    FAULT_REASONS,
    PlannerOptions,
    PlannerSession,
    decode_reply,
    encode_telemetry,
    export_highway_map,
    lockstep_config,
)
from tests.planners.protocol_planner import Planner, TelemetryLaneKeeper
from tests.processes import process_gone

PLANNER = Path(__file__).resolve().parent / "planners" / "protocol_planner.py"
HIGHWAY = "sdc_gym/HighwayLoop-v0"
OVAL = {"map": "oval", "traffic": {"car_count": 8}, "max_duration": 200.0}
# The summary fields a run reproduces exactly (not wall time, not the agent's name).
SUMMARY_KEYS = ("lap_times", "laps", "distance", "time", "incidents", "incident_log",
                "max_acceleration", "max_jerk", "max_raw_acceleration", "max_speed",
                "termination_reason", "distance_without_incident")


def planner_command(*arguments: str) -> str:
    return shlex.join([sys.executable, str(PLANNER), "--port", "{port}", *arguments])


def external(*arguments: str) -> str:
    return "external:" + planner_command(*arguments)


def run(agent: str, config: dict, seed: int = 0, **options) -> dict:
    if "cwd" in options:  # the planner's output beside it, not in the system's temp folder
        options.setdefault("log_path", str(Path(options["cwd"]) / "planner.log"))
    spec = EpisodeSpec(agent, HIGHWAY, seed, config, trace_points=0,
                       agent_options={"external": options})
    return run_episode(spec)


def test_a_lap_through_the_socket_is_the_in_process_planners_lap(tmp_path):
    """The planner at 55 mph on the oval: the same path bit for bit, so the same incidents
    (speed) at the same places, through the socket as when called in-process on the same
    telemetry text."""
    export_highway_map("oval", tmp_path)
    config = dict(OVAL, **lockstep_config(3))
    via_socket = run(external("--target-mph", "55"), config, seed=2, cwd=str(tmp_path),
                     log_path=str(tmp_path / "planner.log"))

    env = gym.make(HIGHWAY, config=config)
    planner = Planner(TelemetryLaneKeeper(str(tmp_path / "highway_map.csv"), 55.0), "none", 0)
    _, info = env.reset(seed=2)
    steps = 0
    while True:
        reply = planner.on_message(encode_telemetry(info["telemetry"]))
        _, _, terminated, truncated, info = env.step(decode_reply(reply))
        steps += 1
        if terminated or truncated:
            break
    in_process = info["summary"]
    assert via_socket["termination_reason"] == "laps_completed"
    assert in_process["incidents"]["speed"] >= 1  # there is something to compare
    assert {key: via_socket[key] for key in SUMMARY_KEYS} == {
        key: in_process[key] for key in SUMMARY_KEYS}
    assert via_socket["planner_exchanges"] == via_socket["env_steps"] == steps
    reports = via_socket["incident_reports"]  # one per incident, with its history
    assert [report["time"] for report in reports] == [
        entry["time"] for entry in in_process["incident_log"]]
    for report in reports:  # the history ends with the step the incident happened in
        # (>= up to the rounding of times summed step by step)
        last = report["history"]["time"][-1]
        assert report["time"] - 0.06 < last and last >= report["time"] - 1e-9
    assert process_gone(via_socket["planner_pid"])
    assert "Listening to port" in (tmp_path / "planner.log").read_text()


def test_a_full_lap_of_the_highway_matches_the_in_process_lane_keeping_agent(tmp_path):
    """One lap of the default 6.9 km highway (5 frames per exchange, ~3,500 exchanges):
    the socket planner, reading our exported map and the 7-digit telemetry, has the
    in-process agent's incidents and lap time. The agent works in the env's exact Frenet
    frame, so its telemetry twin asks for it (``frenet: exact``)."""
    config = dict(lockstep_config(5), max_duration=1000.0, frenet="exact")
    in_process = run("lane_keeping", config, seed=0)
    via_socket = run(external("--map", "data/highway_map.csv"), config, seed=0,
                     cwd=str(tmp_path), map_export="data/highway_map.csv")
    # The planner read the map (it drove the lap); the folder is left as found: no file.
    assert not (tmp_path / "data" / "highway_map.csv").exists()
    for result in (in_process, via_socket):
        assert result["termination_reason"] == "laps_completed" and result["laps"] == 1
    assert via_socket["incidents"] == in_process["incidents"]
    assert [entry["kind"] for entry in via_socket["incident_log"]] == [
        entry["kind"] for entry in in_process["incident_log"]]
    assert via_socket["lap_times"][0] == pytest.approx(in_process["lap_times"][0], abs=0.02)
    assert via_socket["distance"] == pytest.approx(in_process["distance"], abs=0.05)
    assert via_socket["planner_exchanges"] == in_process["env_steps"]
    assert process_gone(via_socket["planner_pid"])


STRAIGHT = ("--brain", "straight")


@pytest.mark.parametrize("fault, reason, steps, message", [
    ("die", "planner_died", 4, "exit code 3"),
    ("malformed", "malformed_reply", 4, "not valid JSON"),
    ("empty", "empty_path", 4, "empty path"),
    ("nan", "non_finite_point", 4, "point 3 of the path is not finite"),
    ("null", "non_finite_point", 4, "next_y[2] = null"),
    ("manual", "manual_reply", 4, "manual"),
    ("stall", "reply_timeout", 4, "no reply to telemetry message 5 within 0.5 s"),
])
def test_a_planner_fault_mid_episode_ends_it_with_its_reason(fault, reason, steps, message,
                                                             tmp_path):
    log = tmp_path / "planner.log"
    result = run(external(*STRAIGHT, "--fault", fault, "--after", "4"), OVAL,
                 cwd=str(tmp_path), reply_timeout=0.5, log_path=str(log))
    assert result["termination_reason"] == reason
    assert message in result["abort_message"] and str(log) in result["abort_message"]
    assert result["env_steps"] == steps  # the good replies were driven
    assert result["time"] == pytest.approx(steps * 3 * 0.02)  # the metrics up to the fault
    assert result["is_success"] is False
    assert process_gone(result["planner_pid"])


def test_a_planner_that_never_listens_is_stopped_with_its_children(tmp_path):
    log = tmp_path / "planner.log"
    result = run(external("--fault", "never_listen"), OVAL, cwd=str(tmp_path),
                 startup_timeout=1.0, log_path=str(log))
    assert result["termination_reason"] == "planner_not_listening"
    assert "within 1 s" in result["abort_message"] and result["env_steps"] == 0
    child = int(log.read_text().split("child ")[1].split()[0])
    assert process_gone(result["planner_pid"]) and process_gone(child)


def test_a_planner_that_crashes_at_start_is_reported_with_its_output(tmp_path):
    result = run(external("--fault", "crash_at_start"), OVAL, cwd=str(tmp_path))
    assert result["termination_reason"] == "planner_died"
    assert "exit code 2" in result["abort_message"]
    assert "std::runtime_error" in result["abort_message"]  # the end of its output


def test_a_missing_command_and_a_busy_port_are_named(tmp_path):
    """A missing command is ``planner_not_found`` whatever the port's state: checked before
    the port, so also while another program holds it (the port is held here, never assumed
    free). Only a runnable planner meets a busy port: ``port_in_use``, naming the holder."""
    with socket.socket() as other:  # another program already on the planner's port
        other.bind(("127.0.0.1", 0))
        other.listen()
        port = other.getsockname()[1]
        for options in ({"port": port}, {}):  # the held port, and the default (4567)
            result = run("external:./path_planning", OVAL, cwd=str(tmp_path), **options)
            assert result["termination_reason"] == "planner_not_found"
            assert "./path_planning" in result["abort_message"]
            assert f"no such file: {tmp_path / 'path_planning'}" in result["abort_message"]
        script = tmp_path / "not_executable.sh"
        script.write_text("#!/bin/sh\n")
        result = run("external:./not_executable.sh", OVAL, cwd=str(tmp_path), port=port)
        assert result["termination_reason"] == "planner_not_found"
        assert "is not executable (chmod +x ./not_executable.sh)" in result["abort_message"]
        result = run("external:no-such-planner-xyz --port {port}", OVAL, cwd=str(tmp_path))
        assert result["termination_reason"] == "planner_not_found"
        assert "no program 'no-such-planner-xyz' on PATH" in result["abort_message"]
        result = run(external(*STRAIGHT), OVAL, port=port)
    assert result["termination_reason"] == "port_in_use"
    assert f"port {port} is already in use" in result["abort_message"]
    assert f"by pid {os.getpid()} (" in result["abort_message"]  # this test holds it
    assert {"planner_not_found", "port_in_use", "reply_timeout"} <= set(FAULT_REASONS)


def test_the_manual_mode_probe_checks_the_protocol_before_driving(tmp_path):
    env = gym.make(HIGHWAY, config=OVAL)
    options = PlannerOptions(cwd=str(tmp_path), manual_probe=True,
                             log_path=str(tmp_path / "planner.log"))
    with PlannerSession(planner_command(*STRAIGHT), options) as planner:
        _, info = env.reset(seed=0)
        path = planner.exchange(info["telemetry"])
        assert path.shape == (10, 2) and planner.stats.exchanges == 1
        pid = planner.process.pid
    assert process_gone(pid)


def test_agent_specs_name_the_valid_agents_and_kinds():
    assert parse_agent_spec("lane_keeping") == (None, "lane_keeping")
    assert parse_agent_spec("external:./path_planning --fast") == (
        "external", "./path_planning --fast")
    for bad, message in [("nobody", "valid agents: "), ("ppo2:model.zip", "unknown agent kind"),
                         ("external:", "needs an argument")]:
        with pytest.raises(ValueError, match=message) as error:
            parse_agent_spec(bad)
        assert "external:ARGUMENT" in str(error.value) or "needs" in str(error.value)
        assert "lane_keeping" in str(error.value) or "needs" in str(error.value)
    env = gym.make(HIGHWAY, config=OVAL)
    with pytest.raises(ValueError, match="valid: cwd, port"):
        make_agent("external:./x", env, {"external": {"folder": "."}})
    agent = make_agent("external:./x", env, {"external": {"cwd": "."}})
    assert agent.name == "external:./x" and set(AGENTS) >= {"lane_keeping"}
    track = gym.make("sdc_gym/TrackLoop-v0")
    with pytest.raises(ValueError, match="HighwayLoop-v0"):
        make_agent("external:./x", track)


def test_evaluate_reports_external_planners_in_the_same_table(tmp_path, capsys):
    """evaluate.py with a working and a dying external planner beside an in-process agent:
    one table, the planners' output in the run folder, the fault printed."""
    output = tmp_path / "run"
    good = external()
    dying = external(*STRAIGHT, "--fault", "die", "--after", "2")
    result = evaluate.main(["--agents", "lane_keeping", good, dying, "--config",
                            str(Path(evaluate.__file__).parent / "configs/highway_oval.yaml"),
                            "--planner-cwd", str(tmp_path), "--planner-map",
                            "highway_map.csv", "--reply-latency", "5", "--seeds", "2",
                            "--no-plots", "--no-progress", "--workers", "2",
                            "--output", str(output)])
    rows = {row["agent"]: row for row in result["rows"]}
    assert rows[good]["laps"] == rows["lane_keeping"]["laps"] == 1
    assert rows[good]["incidents"] == rows["lane_keeping"]["incidents"]
    assert rows[good]["mean_lap_time"] == pytest.approx(rows["lane_keeping"]["mean_lap_time"],
                                                        abs=0.05)
    assert rows[dying]["laps"] == 0
    episodes = {episode["agent"]: episode
                for episode in json.loads((output / "summary.json").read_text())["episodes"]}
    assert episodes[dying]["termination_reason"] == "planner_died"
    assert episodes["lane_keeping"]["env_steps"] == episodes[good]["planner_exchanges"]
    logs = sorted(path.name for path in (output / "planner_logs").iterdir())
    assert len(logs) == 2 and all(name.endswith("_seed2.log") for name in logs)
    assert "dying after 2 replies" in (output / "planner_logs" / logs[0]).read_text() + (
        output / "planner_logs" / logs[1]).read_text()
    out = capsys.readouterr().out
    assert "ended early, planner_died" in out and "external:" in out


def test_no_planner_outlives_a_parent_killed_without_warning(tmp_path):
    """``kill -9`` on the process that started a planner: nobody calls ``stop()``, and the
    watchdog beside the planner ends its group (the planner and the child it forked)."""
    log = tmp_path / "planner.log"
    parent_code = (
        "import sys, time\n"
        "from sdc_gym.bridge.process import PlannerProcess\n"
        f"planner = PlannerProcess({planner_command('--fault', 'never_listen')!r}, "
        f"log_path={str(log)!r})\n"
        "planner.start()\n"
        "print(planner.pid, flush=True)\n"
        "time.sleep(60)\n")
    parent = subprocess.Popen([sys.executable, "-c", parent_code], stdout=subprocess.PIPE,
                              text=True, cwd=Path(__file__).resolve().parents[1])
    try:
        planner_pid = int(parent.stdout.readline())
        deadline = time.monotonic() + 10.0
        while "child " not in (log.read_text() if log.exists() else ""):
            assert time.monotonic() < deadline, "the planner never started its child"
            time.sleep(0.05)
        child = int(log.read_text().split("child ")[1].split()[0])
        assert not process_gone(planner_pid, wait_s=0.3)  # running while its parent lives
        parent.kill()
        parent.wait()
        assert process_gone(planner_pid) and process_gone(child)
    finally:
        parent.kill()
        parent.stdout.close()


def test_one_table_of_planners_in_their_own_folders_each_map_left_as_found(tmp_path, capsys):
    """The same planner command twice with a folder each (--planner-cwd per external
    agent): both run, named apart by folder (``SPEC@FOLDER``) in the rows and the table;
    each reads the env's map from its own folder; a folder whose file holds the same
    numbers (printed differently) is not touched, one with another map gets the env's for
    the run and its own back after; the two logs do not overwrite each other."""
    from sdc_gym.bridge.map_file import map_text
    from sdc_gym.road.builtin_highways import get_highway_map

    same, other = tmp_path / "same", tmp_path / "other"
    same.mkdir()
    other.mkdir()
    oval = get_highway_map("oval")
    (same / "highway_map.csv").write_text(  # the oval, with more digits and commas
        "\n".join(",".join(f"{value:.10f}" for value in row) for row in oval.waypoints))
    (other / "highway_map.csv").write_text(map_text(get_highway_map("default")))
    before = {folder: (folder / "highway_map.csv").read_bytes() for folder in (same, other)}
    stamp = (same / "highway_map.csv").stat().st_mtime_ns
    planner = external("--map", "highway_map.csv")
    output = tmp_path / "run"
    result = evaluate.main(["--agents", planner, planner, "--config",
                            str(Path(evaluate.__file__).parent / "configs/highway_oval.yaml"),
                            "--planner-cwd", str(same), str(other), "--planner-map",
                            "highway_map.csv", "--reply-latency", "5", "--seeds", "1",
                            "--no-plots", "--no-progress", "--workers", "1",
                            "--output", str(output)])
    rows = {row["agent"]: row for row in result["rows"]}
    in_same, in_other = f"{planner}@{same}", f"{planner}@{other}"
    assert list(rows) == [in_same, in_other]  # each run, none dropped
    assert rows[in_same]["laps"] == rows[in_other]["laps"] == 1  # both drove the oval
    assert rows[in_same]["mean_lap_time"] == pytest.approx(rows[in_other]["mean_lap_time"])
    assert [row["label"] for row in rows.values()] == [
        "external:python@same", "external:python@other"]
    out = capsys.readouterr().out
    assert "external:python@same" in out and "external:python@other" in out
    episodes = json.loads((output / "summary.json").read_text())["episodes"]
    assert [episode["agent"] for episode in episodes] == [in_same, in_other]
    for folder in (same, other):
        assert (folder / "highway_map.csv").read_bytes() == before[folder]
        assert sorted(path.name for path in folder.iterdir()) == ["highway_map.csv"]
    assert (same / "highway_map.csv").stat().st_mtime_ns == stamp  # never rewritten
    logs = sorted(path.name for path in (output / "planner_logs").iterdir())
    assert len(logs) == 2 and logs[0] != logs[1]
    with pytest.raises(SystemExit):  # two folders for one external agent
        evaluate.main(["--agents", planner, "--planner-cwd", str(same), str(other),
                       "--output", str(output)])


def test_repeated_agents_are_named_apart_by_folder_or_refused(tmp_path, capsys):
    """A repeated external spec with a folder each runs once per folder, named
    ``SPEC@FOLDER``; repeats that would be one agent twice are refused, naming it."""
    from sdc_agents.external import AgentRun, agent_runs

    assert agent_runs(["fsm_bold", "external:./p", "external:./p", "external:./q"],
                      ["a", "b", "c"]) == [
        AgentRun("fsm_bold", "fsm_bold"), AgentRun("external:./p@a", "external:./p", "a"),
        AgentRun("external:./p@b", "external:./p", "b"),
        AgentRun("external:./q", "external:./q", "c")]
    assert agent_runs(["external:./p"], ["a"]) == [AgentRun("external:./p", "external:./p", "a")]
    for agents, cwds, message in [
            (["fsm_bold", "fsm_bold"], [], "names 'fsm_bold' 2 times: each agent runs once"),
            (["external:./p", "external:./p"], [], "would run in the current folder"),
            (["external:./p", "external:./p"], ["a"], "would run in the folder a"),
            (["external:./p", "external:./p"], ["a", "./a"], "would run in the folder ./a"),
            (["external:./p", "external:./p"], ["a", "b", "c"], "got 3 folders for 2")]:
        with pytest.raises(ValueError, match=message):
            agent_runs(agents, cwds)
    folder = tmp_path / "a"
    folder.mkdir()
    with pytest.raises(SystemExit):  # evaluate.py says so before running anything
        evaluate.main(["--agents", "external:./p", "external:./p", "--planner-cwd",
                       str(folder), "--output", str(tmp_path / "run")])
    assert "one planner run twice" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_external_planners_drive_on_after_a_collision_unless_configured():
    from sdc_agents.external import EXTERNAL_PATH_POINTS, external_env_config

    assert external_env_config({}) == {"terminate_on_collision": False,
                                       "path_points": EXTERNAL_PATH_POINTS}
    assert external_env_config({"terminate_on_collision": True})["terminate_on_collision"]
