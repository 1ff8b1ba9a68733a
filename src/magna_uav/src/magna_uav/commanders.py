"""Commanders: the UAV manager's hands on the GRVC UAL API of one UAV.

Thin on purpose: each method is one UAL call. Services are called non-blocking
(`blocking: false`) so the control loop keeps evaluating and recording while a
manoeuvre runs; roles watch the UAL state and the pose to know when it is done.
The original's slips are not repeated: go_to_waypoint is a service, not a topic,
and set_home uses the SetHome type.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import rospy
from geometry_msgs.msg import PoseStamped, TwistStamped
from uav_abstraction_layer.srv import GoToWaypoint, Land, SetHome, TakeOff

from magna_common import ros_names as names
from magna_common import ual_commands
from magna_common.ros_errors import service_error_text

FRAME = "map"


class CommandRefused(ual_commands.CommandRefused):
    """The UAL server refused a command (or is not there); the message carries its reason. The UAV manager
    catches its base class (no ROS there) and ends the role aborted with that reason."""


def pose_stamped(position: Sequence[float], yaw: float = 0.0, frame: str = FRAME) -> PoseStamped:
    """A PoseStamped in `frame` at `position`, level, heading `yaw` (stamped now)."""
    msg = PoseStamped()
    msg.header.stamp = rospy.Time.now()
    msg.header.frame_id = frame
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(p) for p in position)
    orientation = msg.pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)
    return msg


class UalCommander:
    def __init__(self, uav_id: int, wait_for_services: float = 30.0):
        self.uav_id = int(uav_id)
        self._set_velocity = rospy.Publisher(names.ual(self.uav_id, "set_velocity"), TwistStamped, queue_size=1)
        self._set_pose = rospy.Publisher(names.ual(self.uav_id, "set_pose"), PoseStamped, queue_size=1)
        services = {"take_off": TakeOff, "land": Land, "go_to_waypoint": GoToWaypoint, "set_home": SetHome}
        self._services = {}
        for name, kind in services.items():
            full = names.ual(self.uav_id, name)
            try:
                rospy.wait_for_service(full, timeout=wait_for_services)
            except rospy.ROSException:
                raise CommandRefused(f"UAV {self.uav_id}: no UAL service {full} within {wait_for_services:g} s; "
                                     "is magna_sim (or the UAV's UAL server) running?") from None
            self._services[name] = rospy.ServiceProxy(full, kind)

    def close(self) -> None:
        """Unregister the setpoint topics (a manager host goes on after one of its managers ends)."""
        self._set_velocity.unregister()
        self._set_pose.unregister()

    def _call(self, name: str, **request):
        try:
            return self._services[name](**request)
        except rospy.ServiceException as error:  # the server's refusal, or the server gone
            reason, full = service_error_text(error), names.ual(self.uav_id, name)
            raise CommandRefused(reason if reason.startswith(full) else f"{full}: {reason}") from None

    def take_off(self, height: float) -> None:
        self._call("take_off", height=float(height), blocking=False)

    def land(self) -> None:
        self._call("land", blocking=False)

    def go_to_waypoint(self, position: Sequence[float], yaw: float = 0.0) -> None:
        self._call("go_to_waypoint", waypoint=pose_stamped(position, yaw), blocking=False)

    def set_home(self, set_z: bool = True) -> None:
        self._call("set_home", set_z=bool(set_z))

    def set_velocity(self, velocity: Sequence[float], yaw_rate: float = 0.0) -> None:
        msg = TwistStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = FRAME
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z = (float(v) for v in velocity)
        msg.twist.angular.z = float(yaw_rate)
        self._set_velocity.publish(msg)

    def hold_pose(self, position: Sequence[float], yaw: float) -> None:
        """Hover: stream the pose to hold (a zero velocity would drift with the simulator's lag)."""
        self._set_pose.publish(pose_stamped(position, yaw))
