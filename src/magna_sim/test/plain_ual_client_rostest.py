#!/usr/bin/env python3
"""A UAL client that knows only the GRVC UAL API: no MAGNA import anywhere.

It flies every UAV listed in /ual_ids: take off, hold a pose streamed on
set_pose, move at a velocity streamed on set_velocity, go to a waypoint, land;
and checks the published state and pose against each command.
"""
import math
import sys
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseStamped, TwistStamped
from uav_abstraction_layer.msg import State
from uav_abstraction_layer.srv import GoToWaypoint, Land, TakeOff


class Uav:
    def __init__(self, uav_id):
        ns = f"/uav_{uav_id}/ual/"
        self.uav_id, self.pose, self.state = uav_id, None, None
        rospy.Subscriber(ns + "pose", PoseStamped, self._on_pose)
        rospy.Subscriber(ns + "state", State, self._on_state)
        self.set_pose = rospy.Publisher(ns + "set_pose", PoseStamped, queue_size=1)
        self.set_velocity = rospy.Publisher(ns + "set_velocity", TwistStamped, queue_size=1)
        for name in ("take_off", "land", "go_to_waypoint"):
            rospy.wait_for_service(ns + name, timeout=30)
        self.take_off = rospy.ServiceProxy(ns + "take_off", TakeOff)
        self.land = rospy.ServiceProxy(ns + "land", Land)
        self.go_to_waypoint = rospy.ServiceProxy(ns + "go_to_waypoint", GoToWaypoint)

    def _on_pose(self, msg):
        self.pose = msg

    def _on_state(self, msg):
        self.state = msg.state

    def position(self):
        p = self.pose.pose.position
        return (p.x, p.y, p.z)


def pose_at(x, y, z):
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.w = 1.0
    return msg


def wait(condition, what, seconds=30.0):
    deadline = rospy.get_rostime() + rospy.Duration(seconds)  # sim time: the test follows the simulation
    while not condition():
        if rospy.is_shutdown() or rospy.get_rostime() > deadline:
            raise AssertionError("timed out waiting for " + what)
        rospy.sleep(0.05)


class PlainUalClient(unittest.TestCase):
    def test_fly_every_uav_through_the_ual_api(self):
        wait(lambda: len(rospy.get_param("/ual_ids", [])) == 3, "3 ids in /ual_ids")
        uavs = [Uav(i) for i in sorted(rospy.get_param("/ual_ids"))]
        wait(lambda: all(u.pose and u.state == State.LANDED_ARMED for u in uavs), "LANDED_ARMED everywhere")
        starts = [u.position() for u in uavs]

        for uav in uavs:
            uav.take_off(height=2.5, blocking=True)
        for uav, start in zip(uavs, starts, strict=True):
            wait(lambda u=uav: u.state == State.FLYING_AUTO, "FLYING_AUTO")
            self.assertAlmostEqual(uav.position()[2], start[2] + 2.5, delta=0.2)

        # Stream a pose 2 m ahead of each start; every UAV must settle on its own target.
        targets = [(s[0] + 2.0, s[1], 3.0) for s in starts]
        deadline = rospy.get_rostime() + rospy.Duration(8.0)
        while rospy.get_rostime() < deadline:
            for uav, target in zip(uavs, targets, strict=True):
                uav.set_pose.publish(pose_at(*target))
            rospy.sleep(0.05)
        for uav, target in zip(uavs, targets, strict=True):
            self.assertLess(math.dist(uav.position(), target), 0.1, f"uav {uav.uav_id} at {uav.position()}")

        # Stream 0.5 m/s along -x for 2 s of sim time: each UAV moves about 1 m that way.
        before = [u.position() for u in uavs]
        command = TwistStamped()
        command.header.frame_id = "map"
        command.twist.linear.x = -0.5
        deadline = rospy.get_rostime() + rospy.Duration(2.0)
        while rospy.get_rostime() < deadline:
            for uav in uavs:
                uav.set_velocity.publish(command)
            rospy.sleep(0.05)
        for uav, start in zip(uavs, before, strict=True):
            moved = [a - b for a, b in zip(uav.position(), start, strict=True)]
            self.assertAlmostEqual(moved[0], -1.0, delta=0.3)
            self.assertLess(abs(moved[1]) + abs(moved[2]), 0.05)

        for uav, start in zip(uavs, starts, strict=True):
            uav.go_to_waypoint(waypoint=pose_at(start[0], start[1], 1.5), blocking=True)
            rospy.sleep(0.1)  # the 30 Hz pose topic catches up with the call that just returned
            self.assertLess(math.dist(uav.position(), (start[0], start[1], 1.5)), 0.33)

        for uav in uavs:
            uav.land(blocking=False)
        for uav in uavs:
            wait(lambda u=uav: u.state == State.LANDED_ARMED, "LANDED_ARMED after landing")
            self.assertLess(uav.position()[2], 0.06)


if __name__ == "__main__":
    rospy.init_node("plain_ual_client")
    rostest.rosrun("magna_sim", "plain_ual_client", PlainUalClient, sys.argv)
