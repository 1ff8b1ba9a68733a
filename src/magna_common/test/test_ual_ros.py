"""ual_ros declares the UAL API under the names ros_names lists, with the GRVC UAL's types."""
from __future__ import annotations

from types import SimpleNamespace

import pytest
from geometry_msgs.msg import PoseStamped, TwistStamped
from nav_msgs.msg import Odometry
from std_srvs.srv import Empty
from uav_abstraction_layer.msg import State
from uav_abstraction_layer.srv import GoToWaypoint, GoToWaypointGeo, Land, SetHome, TakeOff

from magna_common import ros_names, ual_ros


class Handlers:
    def on_set_pose(self, msg): ...
    def on_set_velocity(self, msg): ...
    def take_off(self, req): ...
    def land(self, req): ...
    def go_to_waypoint(self, req): ...
    def go_to_waypoint_geo(self, req): ...
    def set_home(self, req): ...
    def recover_from_manual(self, req): ...


@pytest.fixture
def made(monkeypatch):
    """What serve_ual asks rospy for, without a ROS master."""
    calls = []
    fake = SimpleNamespace(Subscriber=lambda *args, **kwargs: calls.append(("sub", args, kwargs)) or len(calls),
                           Service=lambda *args: calls.append(("srv", args, {})) or len(calls))
    monkeypatch.setattr(ual_ros, "rospy", fake)
    return calls


def test_every_ual_name_is_declared_with_its_type_and_handler(made):
    handlers = Handlers()
    subscribers, services = ual_ros.serve_ual(7, handlers)
    assert (subscribers, services) == ([1, 2], [3, 4, 5, 6, 7, 8])
    setpoints = [(args[0], args[1], args[2], kwargs) for kind, args, kwargs in made if kind == "sub"]
    assert setpoints == [(ros_names.ual(7, "set_pose"), PoseStamped, handlers.on_set_pose, {"queue_size": 1}),
                         (ros_names.ual(7, "set_velocity"), TwistStamped, handlers.on_set_velocity, {"queue_size": 1})]
    assert [name.rsplit("/", 1)[1] for name, *_ in setpoints] == list(ros_names.UAL_SETPOINTS)
    served = [args for kind, args, _ in made if kind == "srv"]
    types = (TakeOff, Land, GoToWaypoint, GoToWaypointGeo, SetHome, Empty)
    assert served == [(ros_names.ual(7, name), kind, getattr(handlers, name))
                      for name, kind in zip(ros_names.UAL_SERVICES, types, strict=True)]


def test_the_topics_are_made_by_the_servers_publisher():
    made = ual_ros.ual_publishers(2, lambda topic, kind: (topic, kind))
    assert made == ((ros_names.ual(2, "pose"), PoseStamped), (ros_names.ual(2, "velocity"), TwistStamped),
                    (ros_names.ual(2, "odom"), Odometry), (ros_names.ual(2, "state"), State))
    assert tuple(made._fields) == ros_names.UAL_TOPICS
