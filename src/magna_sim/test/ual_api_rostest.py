#!/usr/bin/env python3
"""magna_sim through its ROS interface: the UAL API of three UAVs, refusals, spawning, sensing.

Runs in three_uavs.test against `sim.launch uavs:=3`; the UAVs end landed where
they started, so the plain-client test that follows finds them as it expects.

UalBehaviour holds the cases any UAL server must pass (state sequence, take-off, waypoints, the geo
waypoint, set-point streams, the velocity timeout, land, home, refusals, /ual_ids); UalApi adds what
only magna_sim has (clock, battery, spawning, collisions, tf). magna_mavlink's live test runs
UalBehaviour against ual_mavlink in front of magna_sim's MAVLink vehicle (set `ids` in a subclass).
"""
import math
import sys
import time
import unittest

import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseStamped, TwistStamped
from magna_msgs.msg import CollisionEvent
from magna_msgs.srv import DeleteModel, SpawnModel, SpawnModelRequest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, NavSatFix
from std_srvs.srv import Empty
from uav_abstraction_layer.msg import State
from uav_abstraction_layer.srv import GoToWaypoint, GoToWaypointGeo, Land, SetHome, TakeOff

from magna_common.geo import enu_to_geodetic

IDS = (1, 2, 3)
# s of simulated time: a pose stamped this much past this node's clock at a call's return came after it
# (bench/clock_lag.py at rtf 4: poses arrived up to 0.07 s ahead of that clock, 0.13 s with both cores busy)
CAUGHT_UP = 0.25
# A MAVLink autopilot disarms on the ground by itself (PX4's COM_DISARM_*) until it is armed again.
LANDED = (State.LANDED_ARMED, State.LANDED_DISARMED)


def pose_at(x, y, z, yaw=0.0, frame="map"):
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def wait(condition, what, sim_seconds=30.0):
    deadline = rospy.get_rostime() + rospy.Duration(sim_seconds)
    while not condition():
        if rospy.is_shutdown() or rospy.get_rostime() > deadline:
            raise AssertionError("timed out waiting for " + what)
        rospy.sleep(0.02)


def wait_wall(condition, what, wall_seconds=30.0):
    """For conditions on the clock itself, which a simulated-time deadline cannot guard."""
    deadline = time.monotonic() + wall_seconds
    while not condition():
        if rospy.is_shutdown() or time.monotonic() > deadline:
            raise AssertionError("timed out waiting for " + what)
        time.sleep(0.02)


class Latest:
    """The last message of a topic."""

    def __init__(self, topic, kind):
        self.msg, self.all = None, []
        rospy.Subscriber(topic, kind, self._store)

    def _store(self, msg):
        self.msg = msg
        self.all.append(msg)


class UalBehaviour(unittest.TestCase):
    ids = IDS  # the UAVs flown: the first blocking, the others not

    @classmethod
    def setUpClass(cls):
        ids = cls.ids
        cls.first, cls.others = ids[0], ids[1:]
        cls.pose = {i: Latest(f"/uav_{i}/ual/pose", PoseStamped) for i in ids}
        cls.velocity = {i: Latest(f"/uav_{i}/ual/velocity", TwistStamped) for i in ids}
        cls.state = {i: Latest(f"/uav_{i}/ual/state", State) for i in ids}
        cls.battery = {i: Latest(f"/uav_{i}/mavros/battery", BatteryState) for i in ids}
        cls.set_pose = {i: rospy.Publisher(f"/uav_{i}/ual/set_pose", PoseStamped, queue_size=1) for i in ids}
        cls.set_velocity = {i: rospy.Publisher(f"/uav_{i}/ual/set_velocity", TwistStamped, queue_size=1)
                            for i in ids}
        cls.services = {}
        for i in ids:
            for name, kind in (("take_off", TakeOff), ("land", Land), ("go_to_waypoint", GoToWaypoint),
                               ("go_to_waypoint_geo", GoToWaypointGeo), ("set_home", SetHome),
                               ("recover_from_manual", Empty)):
                rospy.wait_for_service(f"/uav_{i}/ual/{name}", timeout=30)
                cls.services[i, name] = rospy.ServiceProxy(f"/uav_{i}/ual/{name}", kind)
        wait(lambda: all(cls.state[i].msg and cls.state[i].msg.state == State.LANDED_ARMED for i in ids),
             f"{len(ids)} LANDED_ARMED UAVs")

    def settle(self):
        """Wait until the topics show the UAVs after a call that just returned: for each, a pose stamped a
        little (CAUGHT_UP) past this node's clock at the return, then a state message heard after that pose.
        This node's clock can lag behind the server's, hence the margin."""
        since = rospy.get_rostime() + rospy.Duration(CAUGHT_UP)
        wait(lambda: all(self.pose[i].msg.header.stamp > since for i in self.ids), "poses stamped after the call")
        heard = {i: len(self.state[i].all) for i in self.ids}
        wait(lambda: all(len(self.state[i].all) > heard[i] for i in self.ids), "states heard after those poses")

    def wait_still(self, moved=0.01, window=1.0):
        """Until every UAV's poses of the last `window` s of simulated time lie within `moved` m of each other."""
        def still(i):
            poses = self.pose[i].all
            latest = poses[-1].header.stamp
            recent = [p.pose.position for p in poses if latest - p.header.stamp <= rospy.Duration(window)]
            spans_window = latest - poses[0].header.stamp >= rospy.Duration(window)
            return spans_window and max(math.dist((a.x, a.y, a.z), (recent[-1].x, recent[-1].y, recent[-1].z))
                                        for a in recent) <= moved

        wait(lambda: all(still(i) for i in self.ids), "the UAVs to hold still")

    def position(self, i):
        p = self.pose[i].msg.pose.position
        return (p.x, p.y, p.z)

    def state_of(self, i):
        return self.state[i].msg.state

    def call_fails(self, call, pattern):
        with self.assertRaises(rospy.ServiceException) as caught:
            call()
        self.assertRegex(str(caught.exception), pattern)

    def test_1_landed_side_by_side_with_ids_and_battery(self):
        self.assertEqual(sorted(rospy.get_param("/ual_ids")), list(self.ids))
        ys = [self.position(i)[1] for i in self.ids]
        self.assertEqual(ys, sorted(ys))
        self.assertTrue(all(abs(self.position(i)[2]) < 0.01 for i in self.ids))
        wait(lambda: all(self.battery[i].msg for i in self.ids), "battery messages")
        self.assertGreater(self.battery[self.first].msg.percentage, 0.9)
        self.assertEqual(self.battery[self.first].msg.power_supply_technology,
                         BatteryState.POWER_SUPPLY_TECHNOLOGY_LIPO)

    def test_2_refusals(self):
        first, last = self.first, self.ids[-1]
        self.call_fails(lambda: self.services[first, "land"](blocking=True),
                        f"land refused: UAV {first} is LANDED_(DIS)?ARMED; land needs FLYING_AUTO")
        self.call_fails(lambda: self.services[last, "go_to_waypoint"](waypoint=pose_at(1, 1, 1), blocking=True),
                        "go_to_waypoint refused")
        self.call_fails(lambda: self.services[first, "take_off"](height=float("nan"), blocking=True), "height")

    def test_3_take_off_blocking_and_not(self):
        first, others = self.first, self.others
        starts = {i: self.position(i) for i in self.ids}
        self.services[first, "take_off"](height=2.0, blocking=True)
        self.settle()
        self.assertEqual(self.state_of(first), State.FLYING_AUTO)
        self.assertAlmostEqual(self.position(first)[2], 2.0, delta=0.2)
        for i in others:
            self.services[i, "take_off"](height=2.0, blocking=False)
        self.assertEqual({self.state_of(i) for i in others} - {State.TAKING_OFF, *LANDED}, set())
        wait(lambda: all(self.state_of(i) == State.TAKING_OFF for i in others), "TAKING_OFF after take_off")
        wait(lambda: all(self.state_of(i) == State.FLYING_AUTO for i in others), "FLYING_AUTO")
        self.call_fails(lambda: self.services[first, "take_off"](height=1.0, blocking=True),
                        f"take_off refused: UAV {first} is FLYING_AUTO")
        for i in self.ids:
            self.assertLess(math.dist(self.position(i)[:2], starts[i][:2]), 0.01)

    def test_4_set_pose_set_velocity_and_bad_setpoints(self):
        targets = {i: (1.5, self.position(i)[1], 2.5) for i in self.ids}
        self.stream(lambda i: self.set_pose[i].publish(pose_at(*targets[i], yaw=math.pi / 2)), 6.0)
        for i in self.ids:
            self.assertLess(math.dist(self.position(i), targets[i]), 0.1)
            q = self.pose[i].msg.pose.orientation
            self.assertAlmostEqual(2 * math.atan2(q.z, q.w), math.pi / 2, delta=0.05)
        before = {i: self.position(i) for i in self.ids}
        twist = TwistStamped()
        twist.header.frame_id = "map"
        twist.twist.linear.y = 0.5
        self.stream(lambda i: self.set_velocity[i].publish(twist), 2.0)
        for i in self.ids:
            self.assertAlmostEqual(self.velocity[i].msg.twist.linear.y, 0.5, delta=0.05)
            self.assertAlmostEqual(self.position(i)[1] - before[i][1], 1.0, delta=0.3)
        wait(lambda: all(abs(self.velocity[i].msg.twist.linear.y) < 0.02 for i in self.ids),
             "the hover after set_velocity stops (velocity timeout)")
        self.wait_still()  # the hold position was taken while still moving: it flies back to it
        held = {i: self.position(i) for i in self.ids}
        self.stream(lambda i: self.set_pose[i].publish(pose_at(float("nan"), 0, 2)), 1.0)
        for i in self.ids:
            self.assertLess(math.dist(self.position(i), held[i]), 0.05)

    def test_6_geographic_waypoint_home_frame_and_manual_recovery(self):
        first = self.first
        origin = rospy.get_param("/magna_sim/map_origin_geo")
        lat, lon, alt = enu_to_geodetic([1.0, -2.0, 2.0], origin)
        self.services[first, "go_to_waypoint_geo"](waypoint=NavSatFix(latitude=lat, longitude=lon, altitude=alt),
                                                   blocking=True)
        self.settle()
        self.assertLess(math.dist(self.position(first), (1.0, -2.0, 2.0)), 0.33)
        self.call_fails(lambda: self.services[first, "go_to_waypoint_geo"](
            waypoint=NavSatFix(latitude=float("nan"), longitude=lon, altitude=alt), blocking=True), "finite")
        self.services[first, "set_home"](set_z=False)
        home = self.position(first)
        self.services[first, "go_to_waypoint"](waypoint=pose_at(1.0, 0.0, 1.0, frame=f"uav_{first}_home"),
                                               blocking=True)
        self.settle()
        self.assertLess(math.dist(self.position(first), (home[0] + 1.0, home[1], 1.0)), 0.33)
        self.call_fails(lambda: self.services[first, "go_to_waypoint"](waypoint=pose_at(0, 0, 1, frame="odom"),
                                                                       blocking=True), "frame_id 'odom' is not known")
        self.call_fails(lambda: self.services[first, "recover_from_manual"](), f"UAV {first} is FLYING_AUTO")

    def test_7_go_to_and_land_where_they_started(self):
        for i in self.ids:
            y = (i - 2) * 2.0
            self.services[i, "go_to_waypoint"](waypoint=pose_at(0.0, y, 1.5), blocking=True)
            self.settle()
            self.assertLess(math.dist(self.position(i), (0.0, y, 1.5)), 0.33)
        self.services[self.first, "land"](blocking=True)
        self.settle()
        self.assertIn(self.state_of(self.first), LANDED)
        for i in self.others:
            self.services[i, "land"](blocking=False)
        wait(lambda: all(self.state_of(i) in LANDED for i in self.ids), "all landed")
        for i in self.ids:
            self.assertLess(self.position(i)[2], 0.06)

    def stream(self, publish, sim_seconds):
        deadline = rospy.get_rostime() + rospy.Duration(sim_seconds)
        while rospy.get_rostime() < deadline:
            for i in self.ids:
                publish(i)
            rospy.sleep(0.05)


class UalApi(UalBehaviour):
    """UalBehaviour, and what only the simulator has: clock, battery drain, spawning, collisions, tf."""

    @classmethod
    def setUpClass(cls):
        cls.collisions = Latest("/magna/sim/collisions", CollisionEvent)
        cls.clock = Latest("/clock", Clock)
        rospy.wait_for_service("/magna/sim/spawn_model", timeout=30)
        cls.spawn = rospy.ServiceProxy("/magna/sim/spawn_model", SpawnModel)
        cls.delete = rospy.ServiceProxy("/magna/sim/delete_model", DeleteModel)
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        super().setUpClass()

    def test_1b_the_clock_runs(self):
        first = self.clock.msg.clock
        wait_wall(lambda: self.clock.msg.clock > first, "the clock to run")

    def test_2b_refused_spawns_leave_the_simulation_running(self):
        answer = self.spawn(SpawnModelRequest(name="uav_2", kind="obstacle", shape="cube", dimensions=[1, 1, 1]))
        self.assertFalse(answer.success)
        self.assertIn("name: 'uav_2' is taken", answer.message)
        answer = self.spawn(SpawnModelRequest(name="uav_9", kind="uav", uav_id=2, airframe="iris"))
        self.assertFalse(answer.success)
        self.assertIn("uav_id: 2", answer.message)
        answer = self.spawn(SpawnModelRequest(name="x", kind="obstacle", shape="cube", dimensions=[1, float("nan"), 1]))
        self.assertFalse(answer.success)
        self.assertIn("dimensions", answer.message)
        self.assertFalse(self.delete(name="nothing_here").success)
        before = self.clock.msg.clock
        wait_wall(lambda: self.clock.msg.clock > before, "the clock to run on")

    def test_3b_tf_follows_the_uav(self):
        transform = self.tf_buffer.lookup_transform("map", "uav_1/base_link", rospy.Time(0), rospy.Duration(5))
        self.assertAlmostEqual(transform.transform.translation.z, self.position(1)[2], delta=0.15)

    def test_5_collision_with_a_spawned_obstacle(self):
        x, y, _ = self.position(3)
        answer = self.spawn(SpawnModelRequest(name="wall", kind="obstacle", shape="cube", dimensions=[0.4, 2, 4],
                                              pose=pose_at(x + 2.0, y, 2.0).pose))
        self.assertTrue(answer.success, answer.message)
        self.services[3, "go_to_waypoint"](waypoint=pose_at(x + 4.0, y, 2.5), blocking=True)
        hits = [c for c in self.collisions.all if c.agent_id == 3 and c.other_kind == "obstacle"]
        self.assertEqual([c.other_name for c in hits][:1], ["wall"])
        self.assertTrue(self.delete(name="wall").success)
        self.services[3, "go_to_waypoint"](waypoint=pose_at(x, y, 2.5), blocking=True)

    def test_8_the_battery_was_used(self):
        self.assertLess(self.battery[1].msg.percentage, 1.0)


if __name__ == "__main__":
    rospy.init_node("ual_api_test")
    rostest.rosrun("magna_sim", "ual_api", UalApi, sys.argv)
