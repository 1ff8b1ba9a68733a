"""The UTM node: issues the flight plans of a plan file over simulated time and watches them for conflicts.

Thin over magna_gs.utm: it resolves pose definitions through the world node, learns where the
UAVs are and which paths they fly, and publishes what the library decides. The ground
station starts it when a mission needs it (see magna_gs README, "UTM flight plans").
"""
from __future__ import annotations

import argparse
import json
import threading
from pathlib import Path

import numpy as np
import rospy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from std_msgs.msg import String

from magna_common import ros_names as names
from magna_gs.factory import POLL, world_poses
from magna_gs.utm import FlightPlan, Utm, UtmPlanError, choose_plan

HELP = """\
The UTM: issues each UAV's flight plan at the simulated time its plan file says, and checks
the plans (and the paths the UAVs fly of their own) for conflicts.

Topics:  /magna/utm/flight_plans (std_msgs/String, latched): JSON {"plans": {"ID": {"version", "issued_at",
             "waypoints", "times"}}}, every issued plan; published at start and at every change
         /magna/utm/flight_plan/ID (nav_msgs/Path, latched): a UAV's plan, each pose stamped with its planned time
         /magna/utm/conflict_path/N (nav_msgs/Path, latched): conflict N's two closest points (N from 1)
Listens: /uav_ID/ual/pose (where the plan starts from), /magna/uav_ID/path/raw (paths flown, filed)

Private parameters (defaults):
  ~mission_file (required)   the mission JSON: its UAVs, and its top-level "UTM" plan if it has one
  ~plan_file ("")            a plan file (replaces the mission's)
  ~distance, ~time           override the plan's conflict limits (m, s; default 3 and 3)
"""


def _path(plan: FlightPlan) -> PathMsg:
    msg = PathMsg()
    msg.header.frame_id = "map"
    msg.header.stamp = rospy.Time.from_sec(float(plan.issued_at))
    for point, t in zip(plan.points, plan.times, strict=True):
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = rospy.Time.from_sec(max(float(t), 0.0))
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = (float(v) for v in point)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


class UtmNode:
    def __init__(self, utm: Utm, ids: list[int]):
        self.utm, self.ids = utm, ids
        self.lock = threading.Lock()
        self.positions: dict[int, np.ndarray] = {}
        self.dirty = True  # something changed since the last conflict check
        self.reported: set[tuple] = set()
        self.plans_pub = rospy.Publisher(names.UTM_FLIGHT_PLANS, String, queue_size=10, latch=True)
        self.plan_pubs = {i: rospy.Publisher(names.utm_flight_plan(i), PathMsg, queue_size=1, latch=True)
                          for i in ids}
        self.conflict_pubs: dict[int, rospy.Publisher] = {}
        for uav_id in ids:
            rospy.Subscriber(names.ual(uav_id, "pose"), PoseStamped, self._on_pose, uav_id, queue_size=1)
            rospy.Subscriber(names.manager(uav_id, "path/raw"), PathMsg, self._on_path, uav_id, queue_size=5)

    def _on_pose(self, msg, uav_id):
        p = msg.pose.position
        with self.lock:
            self.positions[uav_id] = np.array([p.x, p.y, p.z])

    def _on_path(self, msg, uav_id):
        points = [[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses]
        if not points:
            return
        with self.lock:
            self.utm.file(uav_id, points, rospy.get_time(), self.positions.get(uav_id))
            self.dirty = True

    def step(self) -> None:
        """Issue what is due now, publish it, and report new conflicts."""
        now = rospy.get_time()
        with self.lock:
            positions = dict(self.positions)
        try:
            changed = self.utm.due(now, lambda definition: [p for p, _ in world_poses(definition)], positions)
        except UtmPlanError as error:
            rospy.logerr(f"UTM: {error}; that plan is not issued")
            changed = []
        if changed:
            with self.lock:
                snapshot = self.utm.snapshot()
                self.dirty = True
            for plan in changed:
                rospy.loginfo(f"UTM: flight plan {plan.version} for UAV {plan.uav_id} at t = {now:.1f} s: "
                              f"{len(plan.points)} waypoints")
                if plan.uav_id in self.plan_pubs:
                    self.plan_pubs[plan.uav_id].publish(_path(plan))
            self.plans_pub.publish(String(json.dumps(snapshot)))
        with self.lock:
            if not self.dirty:
                return
            self.dirty = False
            conflicts = self.utm.conflicts()
        for n, conflict in enumerate(conflicts, start=1):
            key = (conflict.uav_ids, conflict.segments, tuple(np.round(np.concatenate(conflict.points), 1)))
            if key not in self.reported:
                self.reported.add(key)
                rospy.logwarn(f"UTM conflict {n}: {conflict.describe()}")
            if n not in self.conflict_pubs:
                self.conflict_pubs[n] = rospy.Publisher(names.utm_conflict_path(n), PathMsg, queue_size=1,
                                                        latch=True)
            msg = PathMsg()
            msg.header.frame_id, msg.header.stamp = "map", rospy.Time.now()
            for point in conflict.points:
                pose = PoseStamped()
                pose.header.frame_id = "map"
                pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = (float(v) for v in point)
                pose.pose.orientation.w = 1.0
                msg.poses.append(pose)
            self.conflict_pubs[n].publish(msg)

    def spin(self) -> None:
        self.plans_pub.publish(String(json.dumps(self.utm.snapshot())))  # the ground station hears we are up
        tick = rospy.rostime.get_rostime_cond()
        while not rospy.is_shutdown():
            self.step()
            with tick:  # wakes at every /clock message, so plans are issued on time at any real-time factor
                tick.wait(POLL)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="rosrun magna_gs utm", description=HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_known_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node("utm")
    mission_file = rospy.get_param("~mission_file", "")
    try:
        data = json.loads(Path(mission_file).expanduser().read_text()) if mission_file else {}
        plan, _ = choose_plan(rospy.get_param("~plan_file", ""), data, mission_file)
    except (OSError, ValueError) as error:  # UtmPlanError is a ValueError; the ground station said it already
        rospy.logfatal(f"utm: {error}")
        return 2
    limits = plan.limits
    distance, time_limit = rospy.get_param("~distance", limits.distance), rospy.get_param("~time", limits.time)
    plan = type(plan)(plan.source, plan.issues, type(limits)(float(distance), float(time_limit)), plan.speed)
    agents = []
    if isinstance(data, dict):
        agents = data["Agents_Config"] if "Agents_Config" in data else data.get("UAVs_Config", [])
    ids = [int(a["ID"]) for a in agents if isinstance(a, dict) and "ID" in a]
    ids = sorted(set(ids) | {i for issue in plan.issues for i in issue.ids})
    rospy.loginfo(f"UTM: {len(plan.issues)} flight plans from {plan.source} for UAVs {ids}; conflicts within "
                  f"{plan.limits.distance:g} m and {plan.limits.time:g} s")
    UtmNode(Utm(plan), ids).spin()
    return 0
