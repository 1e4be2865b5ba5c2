"""sdc-gym's ROS clock: a rospy node on a stack's master that publishes ``/clock`` and
tells sdc-gym when the stack has answered each tick.

It runs on the Python that has rospy (Debian's ``/usr/bin/python3``, or a ROS install's
after ``source setup.bash``), not on sdc-gym's: it imports only the standard library,
``rospy`` and ``rosgraph_msgs``. :class:`sdc_gym.capstone.sim_clock.RosClock` starts it
and talks to it through its standard input and output, one line each way per request::

    python3 clock_node.py TOPIC [TOPIC ...]      # the topics that answer a tick

    -> ready use_sim_time=1 pid=PID               (or: error MESSAGE, then exit 2)
    <- tick NANOSECONDS WAIT_SECONDS
    -> done MISSING_COUNT [TOPIC ...] WAITED_SECONDS
    <- quit                                       (or end of input)

``tick`` publishes ``rosgraph_msgs/Clock`` at that time, then waits, at most
``WAIT_SECONDS`` of wall time, until every watched topic has had a message since the
publish (any type: ``rospy.AnyMsg``, so the node needs none of the stack's message
packages), and names those that had none. ``/clock`` is latched (a node that connects
late gets the current time at once) and published synchronously with ``TCP_NODELAY``,
so the tick is on every subscriber's socket when ``publish`` returns; the watched topics
are subscribed with ``tcp_nodelay`` too, so neither direction waits for Nagle's algorithm.
The node's own waits are on the wall clock (it is the clock). Its standard output is the
pipe only: everything else it prints goes to standard error.
"""

from __future__ import annotations

import os
import sys
import threading
import time
import warnings

PROTOCOL_READY = "ready"


def fail(pipe, message: str) -> int:
    pipe.write(f"error {message}\n")
    pipe.flush()
    return 2


def main(argv: list) -> int:
    # The pipe is a private copy of stdout; rospy and anything else print to stderr.
    pipe = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    topics = argv[1:]
    try:
        import rosgraph
        import rospy
        from rosgraph_msgs.msg import Clock
    except ImportError as error:
        return fail(pipe, f"{sys.executable} cannot import rospy/rosgraph_msgs ({error}); "
                          "install python3-rospy and python3-rosgraph-msgs (Debian) or "
                          "source the ROS install's setup.bash")
    master = rosgraph.get_master_uri()
    if not rosgraph.is_master_online(master):
        return fail(pipe, f"no ROS master answers at {master} (ROS_MASTER_URI)")
    rospy.init_node("sdc_gym_clock", anonymous=True, disable_signals=True,
                    disable_rosout=True)
    use_sim_time = bool(rospy.get_param("/use_sim_time", False))
    with warnings.catch_warnings():  # queue_size=None: synchronous, on purpose
        warnings.simplefilter("ignore")
        clock = rospy.Publisher("/clock", Clock, queue_size=None, latch=True,
                                tcp_nodelay=True)
    condition = threading.Condition()
    counts = dict.fromkeys(topics, 0)

    def on_message(_message, topic: str) -> None:
        with condition:
            counts[topic] += 1
            condition.notify_all()

    for topic in topics:
        rospy.Subscriber(topic, rospy.AnyMsg, on_message, callback_args=topic,
                         tcp_nodelay=True)
    pipe.write(f"{PROTOCOL_READY} use_sim_time={int(use_sim_time)} pid={os.getpid()}\n")
    for line in sys.stdin:
        words = line.split()
        if not words or words[0] == "quit":
            break
        if words[0] != "tick" or len(words) != 3:
            return fail(pipe, f"unknown request {line.strip()[:80]!r}")
        nanoseconds, wait = int(words[1]), float(words[2])
        with condition:
            before = dict(counts)
        start = time.monotonic()
        clock.publish(Clock(clock=rospy.Time(nanoseconds // 10**9, nanoseconds % 10**9)))
        deadline = start + wait
        with condition:
            while True:
                missing = [topic for topic in topics if counts[topic] == before[topic]]
                left = deadline - time.monotonic()
                if not missing or left <= 0:
                    break
                condition.wait(left)
        waited = time.monotonic() - start
        pipe.write(" ".join(["done", str(len(missing)), *missing, f"{waited:.6f}"]) + "\n")
    rospy.signal_shutdown("sdc-gym closed the clock")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
