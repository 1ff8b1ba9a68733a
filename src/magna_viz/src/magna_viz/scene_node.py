"""The scene node: the UAVs of a mission drawn for rviz, live or from a bag (magna_viz.scene does the drawing).

    rosrun magna_viz scene _mission_file:=/path/mission.json [_topic:=/magna/viz/scene] [_scale:=0]

It subscribes, for every agent of the mission, to /uav_ID/ual/pose (geometry_msgs/PoseStamped),
/magna/uav_ID/path/raw and /path/smoothed (nav_msgs/Path) and /magna/uav_ID/goal (PoseStamped),
and publishes a latched visualization_msgs/MarkerArray on ~topic whenever something changed, at
most ~rate times per wall-clock second (a display paces itself by the wall clock, whatever the
simulated time does).

Replays also pass the world through it: with ~world_in set, MarkerArrays from that topic are
republished (latched) on ~world_out, and with ~keep_world a message that only deletes (the world
node clearing the world when the mission ends) is dropped, so the last frame still shows the world.
"""
from __future__ import annotations

import argparse
import threading
import time

import rospy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from visualization_msgs.msg import MarkerArray

from magna_common.records import Hyperparameters
from magna_common.ros_names import HYPERPARAMETERS, VIZ_SCENE, WORLD_MARKERS, manager, ual
from magna_viz.rviz_config import family_of
from magna_viz.scene import Scene, is_clear_only, styles_from_mission


class SceneNode:
    def __init__(self):
        mission_file = rospy.get_param("~mission_file", "")
        if not mission_file:
            raise SystemExit("scene: set ~mission_file (the mission JSON whose agents to draw)")
        styles = styles_from_mission(mission_file)
        scale = float(rospy.get_param("~scale", 0.0))
        if scale <= 0:
            family = family_of(Hyperparameters.from_param(rospy.get_param(HYPERPARAMETERS, None)).world)
            scale = family.marker_scale if family is not None else 1.0
        self.scene = Scene(styles, scale=scale, max_trail=int(rospy.get_param("~max_trail", 0)))
        self.rate = max(float(rospy.get_param("~rate", 10.0)), 0.5)
        self.lock = threading.Lock()
        self.pub = rospy.Publisher(rospy.get_param("~topic", VIZ_SCENE), MarkerArray, queue_size=2, latch=True)
        self.subscribers = []
        for style in styles:
            i = style.id
            self.subscribers += [
                rospy.Subscriber(ual(i, "pose"), PoseStamped, self._pose, i, queue_size=50),
                rospy.Subscriber(manager(i, "path/raw"), PathMsg, self._path, (i, False), queue_size=2),
                rospy.Subscriber(manager(i, "path/smoothed"), PathMsg, self._path, (i, True), queue_size=2),
                rospy.Subscriber(manager(i, "goal"), PoseStamped, self._goal, i, queue_size=10),
            ]
        world_in = rospy.get_param("~world_in", "")
        if world_in:
            self.keep_world = bool(rospy.get_param("~keep_world", True))
            self.world_pub = rospy.Publisher(rospy.get_param("~world_out", WORLD_MARKERS), MarkerArray,
                                             queue_size=2, latch=True)
            self.subscribers.append(rospy.Subscriber(world_in, MarkerArray, self._world, queue_size=5))
        rospy.loginfo(f"scene: drawing UAVs {', '.join(s.name for s in styles)} of {mission_file} "
                      f"(scale {scale:g})")

    def _pose(self, msg: PoseStamped, uav_id: int) -> None:
        p, q = msg.pose.position, msg.pose.orientation
        with self.lock:
            self.scene.update_pose(uav_id, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), msg.header.stamp.to_sec())

    def _path(self, msg: PathMsg, key) -> None:
        uav_id, smoothed = key
        points = [(s.pose.position.x, s.pose.position.y, s.pose.position.z) for s in msg.poses]
        with self.lock:
            self.scene.update_path(uav_id, points, smoothed)

    def _goal(self, msg: PoseStamped, uav_id: int) -> None:
        p = msg.pose.position
        with self.lock:
            self.scene.update_goal(uav_id, (p.x, p.y, p.z))

    def _world(self, msg: MarkerArray) -> None:
        if self.keep_world and is_clear_only(msg):
            return
        self.world_pub.publish(msg)

    def spin(self) -> None:
        period = 1.0 / self.rate
        while not rospy.is_shutdown():
            with self.lock:
                markers = self.scene.markers() if self.scene.changed else None
            if markers is not None:
                self.pub.publish(markers)
            time.sleep(period)  # wall clock on purpose: see the module's docstring


HELP = """\
The UAVs of a mission drawn for rviz, live or from a bag: for every agent of the mission it
subscribes to /uav_ID/ual/pose, /magna/uav_ID/path/raw and /path/smoothed and
/magna/uav_ID/goal, and publishes a latched visualization_msgs/MarkerArray on ~topic when
something changed, at most ~rate times per wall-clock second.

Private parameters (defaults):
  ~mission_file (required)  the mission JSON (a file path) whose agents to draw
  ~topic (/magna/viz/scene) where the markers go
  ~scale (0)                marker size; 0 takes the world family's (/magna/hyperparameters/world)
  ~max_trail (0)            poses kept in each trail (0: the whole flight)
  ~rate (10)                most marker messages per wall-clock second (at least 0.5)
  ~world_in ("")            also republish the MarkerArrays of this topic (latched) on
  ~world_out (/magna/world/markers), and with ~keep_world (true) drop a message that only
                            clears the world, so the last frame still shows it
"""

EXAMPLES = """\
examples:
  rosrun magna_viz scene _mission_file:=missions/Gym/2UAVs_Crossing_ORCA.json   # the mission's UAVs [background]
"""


def parse_cli(argv) -> None:
    """Only --help: everything else comes from ROS parameters (rospy.myargv has removed them)."""
    parser = argparse.ArgumentParser(prog="rosrun magna_viz scene", description=HELP, epilog=EXAMPLES,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(argv)


def main(argv=None) -> int:
    parse_cli(rospy.myargv()[1:] if argv is None else rospy.myargv(argv)[1:])
    rospy.init_node("magna_scene", argv=argv)
    try:
        node = SceneNode()
    except ValueError as err:  # a bad mission file (magna_uav.config.ConfigError)
        rospy.logfatal(f"scene: {err}")
        return 2
    node.spin()
    return 0
