"""The styx server as a ROS 1 node, written from the original's protocol for the tests.

Like ``ros/src/styx/server.py`` and ``bridge.py``: a python-socketio ``Server`` on
eventlet's WSGI server; ``telemetry`` publishes ``/current_pose`` (PoseStamped, yaw from
degrees), ``/current_velocity`` (TwistStamped, mph * 0.44704) and, when it changes,
``/vehicle/dbw_enabled``, then sends every message queued since the last telemetry;
``trafficlights`` publishes ``/vehicle/traffic_lights`` (TrafficLightArray); the
``/vehicle/{steering,throttle,brake}_cmd`` and ``/final_waypoints`` subscribers queue
``steer``, ``throttle``, ``brake`` (strings, as ``str(msg.pedal_cmd)``) and ``drawline``.
(``image``, ``control``, ``obstacle`` and ``lidar`` are taken and not republished: the
stack of the tests does not use them; the original needs tf and cv_bridge for them.)

    python styx_node.py --port PORT
"""

from __future__ import annotations

import argparse
import math
import warnings

from ros_paths import use_ros

with warnings.catch_warnings():  # before Debian's folder: eventlet would take its OpenSSL
    warnings.simplefilter("ignore")
    import eventlet
    import eventlet.wsgi
    import socketio
use_ros()

import rospy  # noqa: E402
from dbw_mkz_msgs.msg import BrakeCmd, SteeringCmd, ThrottleCmd  # noqa: E402
from geometry_msgs.msg import PoseStamped, TwistStamped  # noqa: E402
from std_msgs.msg import Bool  # noqa: E402
from styx_msgs.msg import Lane, TrafficLight, TrafficLightArray  # noqa: E402


def quaternion_z(yaw: float) -> tuple[float, float, float, float]:
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def pose(x: float, y: float, z: float, yaw_degrees: float) -> PoseStamped:
    message = PoseStamped()
    message.header.stamp = rospy.Time.now()
    message.header.frame_id = "/world"
    message.pose.position.x, message.pose.position.y, message.pose.position.z = x, y, z
    o = message.pose.orientation
    o.x, o.y, o.z, o.w = quaternion_z(math.radians(yaw_degrees))
    return message


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--port", type=int, required=True)
    args = parser.parse_args()
    rospy.init_node("styx_server")
    sio = socketio.Server()
    msgs: dict[str, object] = {}
    state = {"dbw_enable": False}
    publishers = {
        "pose": rospy.Publisher("/current_pose", PoseStamped, queue_size=1),
        "velocity": rospy.Publisher("/current_velocity", TwistStamped, queue_size=1),
        "dbw": rospy.Publisher("/vehicle/dbw_enabled", Bool, queue_size=1, latch=True),
        "lights": rospy.Publisher("/vehicle/traffic_lights", TrafficLightArray, queue_size=1),
    }

    def send(topic: str, data: object) -> None:
        msgs[topic] = data

    rospy.Subscriber("/vehicle/steering_cmd", SteeringCmd, lambda m: send(
        "steer", {"steering_angle": str(m.steering_wheel_angle_cmd)}))
    rospy.Subscriber("/vehicle/throttle_cmd", ThrottleCmd, lambda m: send(
        "throttle", {"throttle": str(m.pedal_cmd)}))
    rospy.Subscriber("/vehicle/brake_cmd", BrakeCmd, lambda m: send(
        "brake", {"brake": str(m.pedal_cmd)}))

    def on_path(lane: Lane) -> None:
        points = [w.pose.pose.position for w in lane.waypoints]
        send("drawline", {"next_x": [p.x for p in points], "next_y": [p.y for p in points],
                          "next_z": [p.z + 0.5 for p in points]})

    rospy.Subscriber("/final_waypoints", Lane, on_path)

    @sio.on("telemetry")
    def telemetry(sid: str, data: dict) -> None:
        if data["dbw_enable"] != state["dbw_enable"]:
            state["dbw_enable"] = data["dbw_enable"]
            publishers["dbw"].publish(Bool(data["dbw_enable"]))
        publishers["pose"].publish(pose(data["x"], data["y"], data["z"], data["yaw"]))
        twist = TwistStamped()
        twist.header.stamp = rospy.Time.now()
        twist.twist.linear.x = data["velocity"] * 0.44704
        publishers["velocity"].publish(twist)
        for _ in range(len(msgs)):
            topic, message = msgs.popitem()
            sio.emit(topic, data=message, skip_sid=True)

    @sio.on("trafficlights")
    def trafficlights(sid: str, data: dict) -> None:
        lights = TrafficLightArray()
        lights.header.stamp = rospy.Time.now()
        for x, y, z, dx, dy, light_state in zip(
                data["light_pos_x"], data["light_pos_y"], data["light_pos_z"],
                data["light_pos_dx"], data["light_pos_dy"], data["light_state"], strict=True):
            light = TrafficLight()
            light.pose = pose(x, y, z, math.degrees(math.atan2(dy, dx)))
            light.state = light_state
            lights.lights.append(light)
        publishers["lights"].publish(lights)

    for event in ("control", "image", "obstacle", "lidar"):
        sio.on(event, lambda sid, data: None)

    listener = eventlet.listen(("127.0.0.1", args.port))
    print(f"styx listening on {args.port}", flush=True)
    eventlet.wsgi.server(listener, socketio.WSGIApp(sio), log_output=False)


if __name__ == "__main__":
    main()
