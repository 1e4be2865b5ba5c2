"""sdc-gym's reference stack as a ROS 1 node, for the tests' graph.

Subscribes to what the styx server publishes (``/current_pose``, ``/current_velocity``,
``/vehicle/dbw_enabled``, ``/vehicle/traffic_lights``), runs the waypoint loader,
updater, detector (the lights' ground truth from ``/vehicle/traffic_lights``, as teams
developed with), pure pursuit and twist controller (:class:`tests.stacks.styx_standin.
StackBridge`) at ``rospy.Rate(50)``, and publishes ``/vehicle/throttle_cmd``,
``/vehicle/brake_cmd`` (torque), ``/vehicle/steering_cmd`` and ``/final_waypoints``.
Every ``REPORT_EVERY`` loops it prints its loop count and ROS time (``rospy.get_time()``
and ``rospy.Time.now()`` in ns): on the wall clock, or on ``/clock`` when the graph runs
with ``/use_sim_time`` true; the node's code is the same in both.

    python stack_node.py --track wp_yaw_const.csv --lights sim_traffic_light_config.yaml
"""

from __future__ import annotations

import argparse
import math

from ros_paths import use_checkout, use_ros

use_checkout()
import tests.stacks.styx_standin  # noqa: E402, F401  (eventlet before Debian's folder)

use_ros()

import rospy  # noqa: E402
from dbw_mkz_msgs.msg import BrakeCmd, SteeringCmd, ThrottleCmd  # noqa: E402
from geometry_msgs.msg import PoseStamped, TwistStamped  # noqa: E402
from std_msgs.msg import Bool  # noqa: E402
from styx_msgs.msg import Lane, TrafficLightArray, Waypoint  # noqa: E402

from tests.stacks.styx_standin import StackBridge  # noqa: E402

RATE_HZ = 50
REPORT_EVERY = 100


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--track", required=True)
    parser.add_argument("--lights", required=True)
    parser.add_argument("--front-offset", type=float, default=2.5)
    args = parser.parse_args()
    args.telemetry_frames = 1  # the stack's loop period: 1 / RATE_HZ
    rospy.init_node("dbw_stack")
    throttle = rospy.Publisher("/vehicle/throttle_cmd", ThrottleCmd, queue_size=1)
    brake = rospy.Publisher("/vehicle/brake_cmd", BrakeCmd, queue_size=1)
    steer = rospy.Publisher("/vehicle/steering_cmd", SteeringCmd, queue_size=1)
    final = rospy.Publisher("/final_waypoints", Lane, queue_size=1)

    def send(topic: str, data: dict) -> None:
        if topic == "throttle":
            throttle.publish(ThrottleCmd(pedal_cmd=float(data["throttle"]), enable=True,
                                         pedal_cmd_type=ThrottleCmd.CMD_PERCENT))
        elif topic == "brake":
            brake.publish(BrakeCmd(pedal_cmd=float(data["brake"]), enable=True,
                                   pedal_cmd_type=BrakeCmd.CMD_TORQUE))
        elif topic == "steer":
            steer.publish(SteeringCmd(steering_wheel_angle_cmd=float(data["steering_angle"]),
                                      enable=True))
        elif topic == "drawline":
            lane = Lane()
            for x, y in zip(data["next_x"], data["next_y"], strict=True):
                waypoint = Waypoint()
                waypoint.pose.pose.position.x, waypoint.pose.pose.position.y = x, y
                lane.waypoints.append(waypoint)
            final.publish(lane)

    bridge = StackBridge(args, send)
    seen = {"pose": False}

    def on_pose(message: PoseStamped) -> None:
        o = message.pose.orientation
        yaw = math.degrees(2 * math.atan2(o.z, o.w))
        bridge.pose = (message.pose.position.x, message.pose.position.y, math.radians(yaw))
        seen["pose"] = True

    def on_velocity(message: TwistStamped) -> None:
        bridge.speed = message.twist.linear.x

    def on_lights(message: TrafficLightArray) -> None:
        bridge.publish_traffic({"light_state": [light.state for light in message.lights]})

    rospy.Subscriber("/current_pose", PoseStamped, on_pose)
    rospy.Subscriber("/current_velocity", TwistStamped, on_velocity)
    rospy.Subscriber("/vehicle/dbw_enabled", Bool, lambda m: bridge.publish_dbw_status(m.data))
    rospy.Subscriber("/vehicle/traffic_lights", TrafficLightArray, on_lights)
    rate = rospy.Rate(RATE_HZ)
    print(f"stack running, ROS time {rospy.get_time()!r}", flush=True)
    loops = 0
    while not rospy.is_shutdown():
        if seen["pose"]:
            bridge.spin()
        loops += 1
        if loops % REPORT_EVERY == 0:
            print(f"stack loop {loops} get_time {rospy.get_time()!r} now_ns "
                  f"{rospy.Time.now().to_nsec()}", flush=True)
        rate.sleep()


if __name__ == "__main__":
    main()
