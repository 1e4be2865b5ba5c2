"""sdc-gym's ``/clock`` for sim-time stacks (sdc_gym/capstone/sim_clock.py, clock_node.py)
against a real ROS 1 master from Debian's packages: a rospy node on ``rospy.Rate(50)``
(tests/ros/rate_node.py, Debian's Python, unchanged between wall and sim time) wakes only
at the clock's ticks, once per 20 ms tick, at exactly the ticks' times, and stands still
while the clock does; a tick waits for the watched topics and names those that stayed
silent; a master without ``/use_sim_time`` and a Python without rospy are named faults."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import pytest

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_gym.bridge.reaper import descendants
from sdc_gym.capstone import CapstoneOptions, CapstoneSession
from sdc_gym.capstone.errors import RosClockFailed
from sdc_gym.capstone.sim_clock import RosClock, ros_available
from tests.processes import all_gone
from tests.ros.workspace import MISSING_REASON, ros_env, ros_installed, set_param, start_roscore

RATE_NODE = Path(__file__).resolve().parent / "ros" / "rate_node.py"
TICK_NS = 20_000_000  # 50 Hz


def test_a_python_that_is_not_there_is_named(tmp_path):
    clock = RosClock("http://127.0.0.1:1", python=str(tmp_path / "python3"))
    with pytest.raises(RosClockFailed, match="python3' does not exist"):
        clock.start(5.0)


def test_a_python_without_rospy_is_named(tmp_path):
    if ros_available(sys.executable):
        pytest.skip("this Python has rospy")
    clock = RosClock("http://127.0.0.1:1", python=sys.executable,
                     log_path=str(tmp_path / "clock.log"))
    try:
        with pytest.raises(RosClockFailed, match="cannot import rospy"):
            clock.start(30.0)
    finally:
        clock.close()


def test_topics_must_be_absolute_names():
    with pytest.raises(ValueError, match="absolute ROS names"):
        RosClock(topics=("vehicle/throttle_cmd",))


@pytest.fixture(scope="module")
def master(tmp_path_factory):
    if not ros_installed() or not ros_available():
        pytest.skip(MISSING_REASON)
    home = tmp_path_factory.mktemp("ros_home")
    roscore, uri = start_roscore(home)
    tree = descendants(roscore.reaper_pid)
    try:
        yield uri, home
    finally:
        roscore.stop()
    assert all_gone([*tree, roscore.reaper_pid]) == []


def test_a_master_without_use_sim_time_is_refused(master, tmp_path):
    uri, _ = master
    set_param(uri, "/use_sim_time", False)
    clock = RosClock(uri, topics=("/answer",), log_path=str(tmp_path / "clock.log"))
    try:
        with pytest.raises(RosClockFailed, match="/use_sim_time unset or false"):
            clock.start(30.0)
    finally:
        clock.close()
    assert all_gone([clock.pid]) == []


def test_a_rate_node_wakes_at_the_clocks_ticks_only(master, tmp_path):
    uri, home = master
    set_param(uri, "/use_sim_time", True)  # before the node starts, as a launch file does
    port = int(uri.rpartition(":")[2])
    output = tmp_path / "node.log"
    with output.open("w") as stream:
        node = subprocess.Popen(["/usr/bin/python3", str(RATE_NODE)], stdout=stream,
                                stderr=subprocess.STDOUT, env=ros_env(port, home))
    clock = RosClock(uri, topics=("/answer",), log_path=str(tmp_path / "clock.log"))
    try:
        clock.start(30.0)
        # Start-up: tick until the node answers (it subscribes to /clock and /answer's
        # subscriber connects meanwhile).
        tick = 0
        while clock.tick(tick * TICK_NS, 0.2).missing:
            tick += 1
            assert tick < 300, output.read_text()
        # rospy.Rate catches up after the jumps of the start-up (it may loop twice at one
        # time, or skip one, for a few ticks): 30 ticks to settle, then 50 measured.
        first = tick + 31
        answers = [clock.tick(tick * TICK_NS, 10.0) for tick in range(tick + 1, first + 50)]
        assert all(answer.missing == () for answer in answers)  # the node ran each tick
        # With the clock still, the node stands still too: no loop in 1 s of wall time.
        loops_before = output.read_text().count("\nloop ")
        time.sleep(1.0)
        text = output.read_text()
        assert text.count("\nloop ") == loops_before
    finally:
        clock.close()
    # A watched topic that nobody publishes: the tick waits its whole wait and names it.
    silent = RosClock(uri, topics=("/nobody",), log_path=str(tmp_path / "silent.log"))
    try:
        silent.start(30.0)
        answer = silent.tick((first + 60) * TICK_NS, 0.3)
    finally:
        silent.close()
        node.terminate()
        node.wait(10)
    assert answer.missing == ("/nobody",) and answer.waited >= 0.3
    loops = [line.split() for line in text.splitlines() if line.startswith("loop ")]
    times = [int(words[2]) for words in loops]
    # The last 50 loops woke at exactly the 50 ticks, one loop each: 20 ms of ROS time
    # per loop, whatever the wall clock did.
    assert times[-50:] == [tick * TICK_NS for tick in range(first, first + 50)]
    assert all(abs(float(words[3]) - int(words[2]) / 1e9) < 1e-9 for words in loops)
    assert all(t % TICK_NS == 0 for t in times)  # never a time the clock did not publish
    assert all_gone([clock.pid, silent.pid]) == []


def test_sim_time_options_and_the_master_port_placeholder():
    """No ROS needed: the options' checks, and ``{master_port}`` becoming a free port that
    the stack gets as its ROS_MASTER_URI and the clock node uses."""
    with pytest.raises(ValueError, match="clock_topics must name at least one topic"):
        CapstoneOptions(sim_time=True, clock_topics=())
    with pytest.raises(ValueError, match="tick_timeout must be > 0 s, got 0"):
        CapstoneOptions(tick_timeout=0)
    assert CapstoneOptions(clock_topics=["/a"]).clock_topics == ("/a",)  # a list from JSON
    env = gym.make("sdc_gym/TrackLoop-v0")
    with pytest.raises(ValueError, match=r"has \{master_port\} and ros_master_uri"):
        CapstoneSession(env, "roslaunch -p {master_port} styx.launch",
                        CapstoneOptions(ros_master_uri="http://127.0.0.1:11311"))
    session = CapstoneSession(env, "roslaunch -p {master_port} --port {port} styx.launch",
                              CapstoneOptions(sim_time=True))
    master_port = int(session.process.arguments[2])
    assert session.process.arguments[4] == str(session.port) != str(master_port)
    assert session.ros_master_uri == f"http://127.0.0.1:{master_port}"
    assert session.process.env == {"ROS_MASTER_URI": session.ros_master_uri}
    assert session.clock is not None and session.clock.uri == session.ros_master_uri
    env.close()
