#!/usr/bin/env python3
"""Python UAL client against a C++ UAL server: every call crosses the wire with checked md5s."""
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseStamped
from uav_abstraction_layer.msg import State
from uav_abstraction_layer.srv import GoToWaypoint, Land, SetHome, TakeOff


class UalInterop(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("ual_interop_client")
        for name in ("take_off", "land", "go_to_waypoint", "set_home"):
            rospy.wait_for_service(f"/uav_1/ual/{name}", timeout=20)

    def wait_for(self, topic, msg_type, predicate, timeout=5.0):
        deadline = rospy.Time.now() + rospy.Duration(timeout)
        while not rospy.is_shutdown() and rospy.Time.now() < deadline:
            msg = rospy.wait_for_message(topic, msg_type, timeout=timeout)
            if predicate(msg):
                return msg
        self.fail(f"{topic} never satisfied the expectation within {timeout} s")

    def test_take_off_go_to_and_land(self):
        self.wait_for("/uav_1/ual/state", State, lambda m: m.state == State.LANDED_ARMED)
        rospy.ServiceProxy("/uav_1/ual/take_off", TakeOff)(height=2.5, blocking=True)
        self.wait_for("/uav_1/ual/state", State, lambda m: m.state == State.FLYING_AUTO)
        pose = self.wait_for("/uav_1/ual/pose", PoseStamped, lambda m: abs(m.pose.position.z - 2.5) < 1e-6)
        self.assertEqual(pose.header.frame_id, "map")

        target = PoseStamped()
        target.header.frame_id = "map"
        target.pose.position.x, target.pose.position.y, target.pose.position.z = 3.0, -1.0, 4.0
        target.pose.orientation.w = 1.0
        rospy.ServiceProxy("/uav_1/ual/go_to_waypoint", GoToWaypoint)(waypoint=target, blocking=True)
        self.wait_for("/uav_1/ual/pose", PoseStamped,
                      lambda m: (m.pose.position.x, m.pose.position.y, m.pose.position.z) == (3.0, -1.0, 4.0))

        rospy.ServiceProxy("/uav_1/ual/set_home", SetHome)(set_z=True)
        rospy.ServiceProxy("/uav_1/ual/land", Land)(blocking=True)
        self.wait_for("/uav_1/ual/state", State, lambda m: m.state == State.LANDED_ARMED)

    def test_server_refuses_land_when_landed(self):
        self.wait_for("/uav_1/ual/state", State, lambda m: m.state == State.LANDED_ARMED)
        with self.assertRaises(rospy.ServiceException):
            rospy.ServiceProxy("/uav_1/ual/land", Land)(blocking=True)


if __name__ == "__main__":
    rostest.rosrun("uav_abstraction_layer", "ual_interop", UalInterop)
