"""A stack speaking the original capstone protocol drives the original track through
sdc-gym's simulator side: the stand-in styx server (tests/stacks/styx_standin.py,
python-socketio's server on eventlet as the original ``server.py``, sdc-gym's own DBW
stack behind it) run as a separate process, found at an OS-given port; every fault ends
the episode with its reason and no process of the stack outlives it (a /proc scan)."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import evaluate
import sdc_gym  # noqa: F401
from sdc_gym.bridge.process import free_port
from sdc_gym.bridge.reaper import descendants
from sdc_gym.capstone import CapstoneOptions, CapstoneSession, run_episode
from sdc_gym.lights.traffic_lights import RED
from tests.conftest import UDACITY
from tests.processes import all_gone, is_alive

STANDIN = Path(__file__).resolve().parent / "stacks" / "styx_standin.py"
CAPSTONE = UDACITY / "capstone"
TRACK = str(CAPSTONE / "wp_yaw_const.csv")
LIGHTS = str(CAPSTONE / "sim_traffic_light_config.yaml")
LAP_FRAMES = 10  # physics frames per telemetry message in the lap test: 5 Hz


def standin(*arguments: str, frames: int = LAP_FRAMES) -> str:
    return shlex.join([sys.executable, str(STANDIN), "--port", "{port}", "--track", TRACK,
                       "--lights", LIGHTS, "--telemetry-frames", str(frames), *arguments])


def track_env(frames: int = LAP_FRAMES, **config) -> gym.Env:
    return gym.make("sdc_gym/TrackLoop-v0", config={
        "track": TRACK, "light_config": LIGHTS, "steps_per_action": frames, **config})


def test_a_full_lap_of_the_original_track_through_the_socket(tmp_path):
    """Lock-step, telemetry at 5 Hz (3,300 exchanges: the suite's longest test, 30-90 s):
    one lap of the 6982 m loop, every red light stopped for before its line; then the
    stand-in's whole tree (it and the child it started in a session of its own, as roscore
    is) is gone."""
    env = track_env(laps=1, max_duration=900.0)
    session = CapstoneSession(env, standin("--spawn"), CapstoneOptions(
        lockstep=True, log_path=str(tmp_path / "stack.log")))
    _, info = env.reset(seed=0)
    session.start()
    tree: list[int] = []
    try:
        for step in range(1_000_000):
            _, _, terminated, truncated, info = env.step(session.action(info))
            if step == 20:
                tree = descendants(session.process.reaper_pid)
            if terminated or truncated:
                break
    finally:
        session.close()
    summary = info["summary"]
    assert summary["termination_reason"] == "laps_completed"
    assert summary["red_light_violations"] == 0
    assert summary["stop_line_crossings"]["red"] == 0
    red_stops = [stop for stop in summary["stops"] if stop["light_state"] == RED]
    assert red_stops and all(-3.0 < stop["offset_m"] < 0.0 for stop in red_stops)
    assert 600.0 < summary["lap_times"][0] < 720.0  # 40 km/h and the waits at red lights
    assert session.client.stats.exchanges == round(info["time"] / (0.02 * LAP_FRAMES))
    assert len(tree) >= 2  # the stand-in and its child
    assert all_gone([*tree, session.process.reaper_pid]) == []
    spawned = int((tmp_path / "stack.log").read_text().split("spawned ")[1].split()[0])
    assert spawned in tree and not is_alive(spawned)
    env.close()


def test_real_time_is_the_default_and_paces_the_env_to_the_wall_clock(tmp_path):
    """Telemetry every physics frame (50 Hz), sent without waiting; the env never runs
    ahead of the wall clock; the stack drives the car off the start."""
    env = track_env(frames=1, max_duration=4.0)
    session = CapstoneSession(env, standin(frames=1), CapstoneOptions(
        log_path=str(tmp_path / "stack.log")))
    result = run_episode(env, session, seed=0)
    assert result["termination_reason"] == "max_duration"
    assert result["stack_exchanges"] == 0  # no acknowledgements asked for
    assert result["stack_commands_received"] > 0
    assert result["distance"] > 1.0
    assert result["real_time_factor"] <= 1.0
    env.close()


@pytest.mark.parametrize(("arguments", "options", "reason", "message"), [
    (("--fault", "never_listen"), {"startup_timeout": 4.0}, "stack_never_connected",
     "no styx server accepted a connection"),
    (("--fault", "die", "--after", "10"), {}, "planner_died", "exit code 3"),
    (("--fault", "garbage", "--after", "10"), {}, "malformed_command",
     "steer.steering_angle is not a number"),
    (("--fault", "stall", "--after", "10"), {"reply_timeout": 2.0}, "stack_stalled",
     "did not handle telemetry message 11"),
    (("--fault", "disconnect", "--after", "10"), {}, "stack_disconnected",
     "closed the connection"),
    # Real time, so that the held commands do not drive the car far in the silent second.
    (("--fault", "mute", "--after", "10"), {"reply_timeout": 1.0, "lockstep": False},
     "stack_stalled", "sent no command for"),
])
def test_a_faulty_stack_ends_its_episode_with_a_named_reason(tmp_path, arguments, options,
                                                             reason, message):
    env = track_env(max_duration=60.0)
    session = CapstoneSession(env, standin(*arguments), CapstoneOptions(
        **{"lockstep": True, "log_path": str(tmp_path / "stack.log"), **options}))
    result = run_episode(env, session, seed=0)
    assert result["termination_reason"] == reason
    assert message in result["abort_message"]
    assert not is_alive(session.process.pid)
    assert all_gone([session.process.reaper_pid]) == []
    env.close()


def test_nothing_listening_without_a_command_is_never_connected():
    env = track_env(max_duration=10.0)
    session = CapstoneSession(env, None, CapstoneOptions(port=free_port(),
                                                         startup_timeout=0.5))
    result = run_episode(env, session, seed=0)
    assert result["termination_reason"] == "stack_never_connected"
    env.close()


def test_evaluate_reports_a_stack_beside_sdc_gyms_own(tmp_path, capsys):
    """evaluate.py with ``capstone:COMMAND`` (lock-step, its working folder) and
    dbw_ground_truth on the original track: one table, the stack's log in the run folder."""
    config = tmp_path / "original_track.yaml"
    config.write_text(json.dumps({"env": "sdc_gym/TrackLoop-v0", "config": {
        "track": TRACK, "light_config": LIGHTS, "steps_per_action": LAP_FRAMES,
        "observe_light_states": True, "max_duration": 40.0}}))
    stack = "capstone:" + standin()
    output = tmp_path / "run"
    result = evaluate.main(["--agents", "dbw_ground_truth", stack, "--config", str(config),
                            "--stack-lockstep", "--stack-cwd", str(tmp_path), "--seeds", "0",
                            "--no-plots", "--no-progress", "--workers", "1",
                            "--output", str(output)])
    rows = {row["agent"]: row for row in result["rows"]}
    assert set(rows) == {"dbw_ground_truth", stack}
    episodes = {episode["agent"]: episode
                for episode in json.loads((output / "summary.json").read_text())["episodes"]}
    ours, theirs = episodes["dbw_ground_truth"], episodes[stack]
    assert theirs["termination_reason"] == ours["termination_reason"] == "max_duration"
    assert theirs["red_light_violations"] == ours["red_light_violations"] == 0
    assert theirs["distance"] > 100.0 and ours["distance"] > 100.0
    assert theirs["stack_exchanges"] == theirs["env_steps"]
    logs = list((output / "stack_logs").iterdir())
    assert len(logs) == 1 and "listening on" in logs[0].read_text()
    assert not is_alive(theirs["stack_pid"])
