"""The GRVC UAL v3 API of one UAV as ROS sees it: what a UAL server publishes, subscribes to and serves
under /uav_{id}/ual/, with each name's message or service type.

magna_sim's UAL server and ual_mavlink both advertise through here, so a client cannot tell them apart
by a name, a type or a queue size. What they do on a call stays with each server (its `UalHandlers`).
Imported only by ROS nodes: it needs rospy and the message packages.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

import rospy
from geometry_msgs.msg import PoseStamped, TwistStamped
from nav_msgs.msg import Odometry
from std_srvs.srv import Empty
from uav_abstraction_layer.msg import State
from uav_abstraction_layer.srv import GoToWaypoint, GoToWaypointGeo, Land, SetHome, TakeOff

from . import ros_names as names


class UalPublishers(NamedTuple):
    """The topics of ros_names.UAL_TOPICS, in that order."""

    pose: Any  # geometry_msgs/PoseStamped
    velocity: Any  # geometry_msgs/TwistStamped
    odom: Any  # nav_msgs/Odometry
    state: Any  # uav_abstraction_layer/State


def ual_publishers(uav_id: int, publisher: Callable[[str, type], Any]) -> UalPublishers:
    """One UAV's UAL topics, each made by `publisher(topic, message type)`: the server picks the queue."""
    ual = functools.partial(names.ual, uav_id)
    return UalPublishers(publisher(ual("pose"), PoseStamped), publisher(ual("velocity"), TwistStamped),
                         publisher(ual("odom"), Odometry), publisher(ual("state"), State))


class UalHandlers(Protocol):
    """What a UAL server does with a set-point (ros_names.UAL_SETPOINTS) or a service call (UAL_SERVICES).

    A service handler returns the service's response; one that raises fails the call with its message.
    """

    def on_set_pose(self, msg: Any) -> None: ...

    def on_set_velocity(self, msg: Any) -> None: ...

    def take_off(self, req: Any) -> Any: ...

    def land(self, req: Any) -> Any: ...

    def go_to_waypoint(self, req: Any) -> Any: ...

    def go_to_waypoint_geo(self, req: Any) -> Any: ...

    def set_home(self, req: Any) -> Any: ...

    def recover_from_manual(self, req: Any) -> Any: ...


def serve_ual(uav_id: int, handlers: UalHandlers) -> tuple[list[Any], list[Any]]:
    """Subscribe to one UAV's UAL set-points and serve its UAL services; returns (subscribers, services)."""
    ual = functools.partial(names.ual, uav_id)
    subscribers = [rospy.Subscriber(ual("set_pose"), PoseStamped, handlers.on_set_pose, queue_size=1),
                   rospy.Subscriber(ual("set_velocity"), TwistStamped, handlers.on_set_velocity, queue_size=1)]
    services = [rospy.Service(ual("take_off"), TakeOff, handlers.take_off),
                rospy.Service(ual("land"), Land, handlers.land),
                rospy.Service(ual("go_to_waypoint"), GoToWaypoint, handlers.go_to_waypoint),
                rospy.Service(ual("go_to_waypoint_geo"), GoToWaypointGeo, handlers.go_to_waypoint_geo),
                rospy.Service(ual("set_home"), SetHome, handlers.set_home),
                rospy.Service(ual("recover_from_manual"), Empty, handlers.recover_from_manual)]
    return subscribers, services
