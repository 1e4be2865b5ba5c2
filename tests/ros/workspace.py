"""The tests' ROS 1 set-up from Debian's packages: what must be installed, roscore on a
free port, and the catkin workspace with the message packages (shared by
``tests/test_capstone_ros.py``, ``tests/test_capstone_clock.py`` and
``benchmarks/bench_capstone.py --ros``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import time
import xmlrpc.client
from pathlib import Path

from sdc_gym.bridge.process import PlannerProcess

ROS = Path(__file__).resolve().parent
DEBIAN_TOOLS = ("/usr/bin/roscore", "/usr/bin/catkin_make",
                "/usr/share/std_msgs/msg/Header.msg",
                "/usr/share/geometry_msgs/msg/PoseStamped.msg")
DEBIAN_PACKAGES = ("ros-core python3-rospy catkin ros-message-generation libstd-msgs-dev "
                   "libgeometry-msgs-dev python3-std-msgs python3-geometry-msgs ros-std-msgs "
                   "ros-geometry-msgs")
MISSING_REASON = ("ROS 1 from Debian is not installed (make test installs it as root: "
                  f"{DEBIAN_PACKAGES})")
SYSTEM_PATH = "/usr/bin:/bin"  # ROS's tools on Debian's own Python


def ros_installed() -> bool:
    return all(Path(tool).exists() for tool in DEBIAN_TOOLS)


def build_workspace(root: Path) -> Path:
    """Build the catkin workspace of tests/ros/src in ``root`` with Debian's Python (not
    the tests' one); its ``devel`` Python folder (``styx_msgs``, ``dbw_mkz_msgs``)."""
    shutil.copytree(ROS / "src", root / "src")
    result = subprocess.run(["/usr/bin/catkin_make", "-C", str(root),
                             "-DPYTHON_EXECUTABLE=/usr/bin/python3"],
                            cwd=root, env={**os.environ, "PATH": SYSTEM_PATH,
                                           "PWD": str(root)},
                            capture_output=True, text=True, timeout=600, check=False)
    if result.returncode != 0:
        raise RuntimeError("catkin_make failed:\n" + result.stdout[-3000:]
                           + result.stderr[-3000:])
    return root / "devel" / "lib" / "python3" / "dist-packages"


def ros_env(master_port: int, home: Path) -> dict[str, str]:
    """The environment of a process on the master at ``master_port`` (logs in ``home``)."""
    return {**os.environ, "PATH": SYSTEM_PATH,
            "ROS_MASTER_URI": f"http://127.0.0.1:{master_port}",
            "ROS_HOSTNAME": "127.0.0.1", "ROS_HOME": str(home),
            "ROS_LOG_DIR": str(home / "log")}


def start_roscore(home: Path, timeout: float = 60.0) -> tuple[PlannerProcess, str]:
    """roscore on a free port under the project's process machinery (its whole tree,
    rosmaster and rosout in sessions of their own included, ends with ``stop()``); the
    process and its master URI once the master answers."""
    process = PlannerProcess(["/usr/bin/roscore", "-p", "{port}"], cwd=home,
                             log_path=home / "roscore.log",
                             env={"PATH": SYSTEM_PATH, "ROS_HOME": str(home),
                                  "ROS_LOG_DIR": str(home / "log")})
    process.start()
    uri = f"http://127.0.0.1:{process.port}"
    master = xmlrpc.client.ServerProxy(uri)
    deadline = time.monotonic() + timeout
    while True:
        try:
            master.getSystemState("/tests")
            return process, uri
        except OSError:
            if time.monotonic() > deadline or process.wait_exit(0.0) is not None:
                process.stop()
                log = (home / "roscore.log").read_text()
                raise RuntimeError(f"roscore did not start: {log[-2000:]}") from None
            time.sleep(0.1)


def set_param(uri: str, name: str, value: object) -> None:
    """What a launch file's ``<param>`` does: the master's setParam."""
    code, message, _ = xmlrpc.client.ServerProxy(uri).setParam("/tests", name, value)
    if code != 1:
        raise RuntimeError(f"setParam {name}: {message}")
