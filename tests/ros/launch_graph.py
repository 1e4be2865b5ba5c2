"""The tests' ROS 1 graph in one command, as ``roslaunch launch/styx.launch`` starts a team's:
roscore (on ``--master-port``, else a free port), then the styx server node and the stack
node.

    python launch_graph.py --port PORT --track wp_yaw_const.csv --lights sim.yaml \
        [--master-port PORT] [--use-sim-time]

``--use-sim-time`` sets the parameter ``/use_sim_time`` to true on the master before the
nodes start, as a launch file's ``<param name="/use_sim_time" value="true"/>`` does: the
nodes (unchanged) then take their time from ``/clock``.

``SDC_GYM_ROS_DEVEL`` must name the catkin workspace's python folder (see
``ros_paths.py``). ROS's logs and home go to ``./ros_home`` (the working directory).
Runs until a process of the graph exits; its owner ends the whole tree.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time
import xmlrpc.client
from pathlib import Path

HERE = Path(__file__).resolve().parent


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--track", required=True)
    parser.add_argument("--lights", required=True)
    parser.add_argument("--master-port", type=int, default=None)
    parser.add_argument("--use-sim-time", action="store_true")
    args = parser.parse_args()
    master = args.master_port or free_port()
    home = Path.cwd() / "ros_home"
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{master}",
           "ROS_HOSTNAME": "127.0.0.1", "ROS_HOME": str(home), "ROS_LOG_DIR": str(home / "log")}
    system = {**env, "PATH": "/usr/bin:/bin"}  # roscore on Debian's own Python
    processes = [subprocess.Popen(["/usr/bin/roscore", "-p", str(master)], env=system)]
    deadline = time.monotonic() + 60
    while True:
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", master)) == 0:
                break
        if time.monotonic() > deadline or processes[0].poll() is not None:
            print("roscore did not start", flush=True)
            return 2
        time.sleep(0.1)
    if args.use_sim_time:  # what roslaunch does for a <param>: the master's setParam
        proxy = xmlrpc.client.ServerProxy(env["ROS_MASTER_URI"])
        for _ in range(100):  # the port opens before the master serves
            try:
                code, message, _ = proxy.setParam("/launch_graph", "/use_sim_time", True)
                break
            except (ConnectionError, xmlrpc.client.Fault, OSError):
                time.sleep(0.1)
        else:
            print("the master did not take /use_sim_time", flush=True)
            return 2
        print(f"/use_sim_time set: {code} {message}", flush=True)
    processes.append(subprocess.Popen([sys.executable, str(HERE / "styx_node.py"), "--port",
                                       str(args.port)], env=env))
    processes.append(subprocess.Popen([sys.executable, str(HERE / "stack_node.py"),
                                       "--track", args.track, "--lights", args.lights],
                                      env=env))
    print(f"graph: roscore {processes[0].pid}, styx {processes[1].pid}, stack "
          f"{processes[2].pid}, master {master}", flush=True)
    while all(process.poll() is None for process in processes):
        time.sleep(0.2)
    return 1


if __name__ == "__main__":
    sys.exit(main())
