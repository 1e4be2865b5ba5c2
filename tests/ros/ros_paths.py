"""Where the tests' ROS 1 graph finds rospy (Debian's packages) and its catkin messages.

Debian installs rospy and the message packages for its own Python 3.11 into
``/usr/lib/python3/dist-packages``; the nodes run on sdc-gym's Python (also 3.11, with
python-socketio and numpy) and append those folders *after* their own, so the venv's
numpy stays the one imported. ``SDC_GYM_ROS_DEVEL`` names the catkin workspace's
``devel/lib/python3/dist-packages`` (``styx_msgs``, ``dbw_mkz_msgs``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DEBIAN_PYTHON = "/usr/lib/python3/dist-packages"


def use_checkout() -> None:
    """This checkout's ``sdc_gym`` and ``tests`` first on the path."""
    root = str(Path(__file__).resolve().parents[2])
    if root not in sys.path:
        sys.path.insert(0, root)


def use_ros() -> None:
    """Make rospy and the workspace's messages importable (after this Python's packages:
    import eventlet before, or it takes Debian's OpenSSL, built for another cryptography)."""
    use_checkout()
    for folder in (DEBIAN_PYTHON, os.environ.get("SDC_GYM_ROS_DEVEL", "")):
        if folder and folder not in sys.path:
            sys.path.append(folder)
