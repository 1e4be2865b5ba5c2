"""The smallest sim-time stack: a rospy node on ``rospy.Rate(50)`` that, every loop,
prints its loop count and ROS time and publishes that time on ``/answer``.

    /usr/bin/python3 rate_node.py            # ROS_MASTER_URI: the master to join

It runs on Debian's Python as it is (rospy, std_msgs) and knows nothing of sdc-gym: with
``/use_sim_time`` true on the master its time is whatever ``/clock`` says, so the tests see
which times it woke at. Output lines: ``loop N NANOSECONDS GET_TIME``.
"""

import rospy
from std_msgs.msg import Float64


def main() -> None:
    rospy.init_node("rate_node")
    answer = rospy.Publisher("/answer", Float64, queue_size=1)
    rate = rospy.Rate(50)
    print(f"up, ROS time {rospy.get_time()!r}", flush=True)
    loops = 0
    while not rospy.is_shutdown():
        rate.sleep()
        loops += 1
        now = rospy.Time.now()
        print(f"loop {loops} {now.to_nsec()} {rospy.get_time()!r}", flush=True)
        answer.publish(Float64(now.to_sec()))


if __name__ == "__main__":
    try:
        main()
    except rospy.ROSInterruptException:
        pass
