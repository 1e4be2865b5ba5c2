"""End to end through a real ROS 1 graph from Debian's packages (ros-core, python3-rospy,
catkin, the message packages; the Makefile's set-up installs them when it runs as root):
a catkin workspace built here with ``styx_msgs`` and ``dbw_mkz_msgs`` written from their
public definitions (tests/ros/src), roscore, a styx server node and sdc-gym's stack as a
rospy node (tests/ros/), started by one launch command as a team's ``roslaunch`` is. The
simulator side drives the original track through the socket and the graph's topics, in
real time and in sim time (``/use_sim_time`` true, sdc-gym's ``/clock``; the nodes are
the same), and ends the whole graph (roscore, rosmaster, rosout, every node) and its own
clock node with the episode.
"""

from __future__ import annotations

import itertools
import shlex
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.bridge.reaper import descendants
from sdc_gym.capstone import CapstoneOptions, CapstoneSession
from sdc_gym.lights.traffic_lights import RED
from tests.conftest import UDACITY
from tests.processes import all_gone
from tests.ros.workspace import MISSING_REASON, build_workspace, ros_installed

ROS = Path(__file__).resolve().parent / "ros"
CAPSTONE = UDACITY / "capstone"
TRACK = str(CAPSTONE / "wp_yaw_const.csv")
LIGHTS = str(CAPSTONE / "sim_traffic_light_config.yaml")

pytestmark = pytest.mark.skipif(not ros_installed(), reason=MISSING_REASON)


@pytest.fixture(scope="module")
def devel(tmp_path_factory) -> Path:
    """The catkin workspace's Python folder, built with Debian's Python."""
    folder = build_workspace(tmp_path_factory.mktemp("catkin_ws"))
    assert (folder / "styx_msgs" / "msg" / "_Lane.py").is_file()
    assert (folder / "dbw_mkz_msgs" / "msg" / "_BrakeCmd.py").is_file()
    return folder


def graph_command(*extra: str) -> str:
    return shlex.join([sys.executable, str(ROS / "launch_graph.py"), "--port", "{port}",
                       "--track", TRACK, "--lights", LIGHTS, *extra])


def test_a_ros_graph_drives_the_original_track_in_real_time(devel, tmp_path, monkeypatch):
    monkeypatch.setenv("SDC_GYM_ROS_DEVEL", str(devel))
    command = graph_command()
    env = gym.make("sdc_gym/TrackLoop-v0", config={"track": TRACK, "light_config": LIGHTS,
                                                   "max_duration": 25.0})
    session = CapstoneSession(env, command, CapstoneOptions(
        cwd=str(tmp_path), log_path=str(tmp_path / "graph.log"), startup_timeout=120.0))
    _, info = env.reset(seed=0)
    session.start()
    graph: list[int] = []
    try:
        for step in range(1_000_000):
            _, _, terminated, truncated, info = env.step(session.action(info))
            if step == 250:  # 5 s in: every node is up
                graph = descendants(session.process.reaper_pid)
            if terminated or truncated:
                break
    finally:
        session.close()
    summary = info["summary"]
    log = (tmp_path / "graph.log").read_text()
    assert summary["termination_reason"] == "max_duration", log[-2000:]
    assert summary["distance"] > 40.0, log[-2000:]  # away from the start under the stack
    assert summary["red_light_violations"] == 0
    # On the road (a real-time graph on a loaded machine lags: 0.1-2.1 m measured).
    assert summary["max_cross_track_error"] < env.unwrapped.road_half_width
    assert session.client.stats.received["throttle"] > 100
    assert "started core service [/rosout]" in log and "stack running" in log
    # launcher, roscore, rosmaster, rosout, the styx node and the stack node
    assert len(graph) >= 6, graph
    assert all_gone([*graph, session.process.reaper_pid]) == []
    env.close()


SIM_SEED = 3  # light 0 is red when the car comes: it must stop (26.4 s in, ~250 m)


def test_a_ros_graph_on_sim_time_stops_at_the_red_light(devel, tmp_path, monkeypatch):
    """The same graph launched with /use_sim_time true: sdc-gym's /clock drives the nodes'
    rospy.Rate(50) and rospy.get_time(); each step waits for the DBW node's commands. 30 s
    of sim time: the car stops before the first stop line on red."""
    monkeypatch.setenv("SDC_GYM_ROS_DEVEL", str(devel))
    env = gym.make("sdc_gym/TrackLoop-v0", config={"track": TRACK, "light_config": LIGHTS,
                                                   "max_duration": 30.0})
    session = CapstoneSession(
        env, graph_command("--master-port", "{master_port}", "--use-sim-time"),
        CapstoneOptions(cwd=str(tmp_path), log_path=str(tmp_path / "graph.log"),
                        startup_timeout=120.0, sim_time=True))
    _, info = env.reset(seed=SIM_SEED)
    session.start()
    graph: list[int] = []
    try:
        for step in range(1_000_000):
            _, _, terminated, truncated, info = env.step(session.action(info))
            if step == 10:
                graph = descendants(session.process.reaper_pid)
            if terminated or truncated:
                break
    finally:
        session.close()
    summary, extras = info["summary"], session.extras()
    log = (tmp_path / "graph.log").read_text()
    assert summary["termination_reason"] == "max_duration", log[-2000:]
    assert summary["red_light_violations"] == 0
    red_stops = [stop for stop in summary["stops"] if stop["light_state"] == RED]
    assert [stop["line"] for stop in red_stops] == [0], summary["stops"]
    assert -3.0 < red_stops[0]["offset_m"] < 0.0
    assert summary["max_cross_track_error"] < 1.0
    # Lock-step with the clock: one tick and one exchange per step (+ the start-up's).
    steps = round(info["time"] / 0.02)
    offset_ticks = round(extras["stack_clock_offset"] / 0.02)
    assert extras["stack_clock_ticks"] == extras["stack_exchanges"] == steps + offset_ticks
    assert extras["stack_missed_ticks"] < steps // 100, extras
    # The stack node's ROS time: only the clock's values (20 ms steps), never past it,
    # and one loop of its rospy.Rate(50) per tick (100 loops = 2 s of ROS time).
    reports = [line.split() for line in log.splitlines() if line.startswith("stack loop ")]
    now_ns = [int(words[6]) for words in reports]
    assert len(reports) > 10 and all(t % 20_000_000 == 0 for t in now_ns)
    assert all(abs(float(words[4]) - int(words[6]) / 1e9) < 1e-9 for words in reports)
    assert max(now_ns) <= round((info["time"] + extras["stack_clock_offset"]) * 1e9)
    gaps = [b - a for a, b in itertools.pairwise(now_ns)]
    assert sorted(gaps)[len(gaps) // 2] == 2_000_000_000, gaps
    assert "/use_sim_time set" in log
    assert len(graph) >= 6, graph
    assert all_gone([*graph, session.process.reaper_pid, extras["stack_clock_pid"]]) == []
    env.close()
