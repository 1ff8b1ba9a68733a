#!/usr/bin/env python3
"""The world node through ROS: /tf_static frames, markers, pose-set services, parts, obstacles in magna_sim.

Runs in world_node.test next to magna_sim; expectations come from the library
resolving the same file with the same seed, so the node must publish what the model says.
"""
import json
import os
import sys
import time
import unittest
from pathlib import Path

import numpy as np
import rospy
import rostest
from magna_msgs.srv import AddWorldPart, DeleteModel, DeleteWorldPart, GetFreeSpacePoseSet
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world

WORLD = Path(__file__).resolve().parent / "worlds" / "Test" / "All_Shapes.json"
SEED = 4
INLINE = [{"name": "Extra", "prefix": "X", "origin": [[0, 20, 0], [0, 0, 0]],
           "geometries": [{"name": "Box", "prefix": "box", "shape": "cube", "origin": [[0, 0, 2], [0, 0, 0]],
                           "dimensions": [2, 2, 2], "color": [255, 0, 0], "alpha": 0.5,
                           "poses_sets": [{"type": "matrix", "matrix_type": "dimension", "use": "poses",
                                           "dimensions": [2, 2, 1]},
                                          {"type": "coordinates", "use": "obstacles", "obstacles_shape": ["sphere"],
                                           "obstacles_dimensions": [0.3, 0.3, 0.3],
                                           "coordinates": [[[0, 0, 0], [0, 0, 0]]]}]}]}]


class Latest:
    def __init__(self, topic, kind):
        self.msg = None
        rospy.Subscriber(topic, kind, self._store)

    def _store(self, msg):
        self.msg = msg


def wait(condition, what, seconds=30.0):
    deadline = time.monotonic() + seconds  # wall time: the simulator runs its clock as fast as it can
    while not condition():
        if rospy.is_shutdown() or time.monotonic() > deadline:
            raise AssertionError("timed out waiting for " + what)
        time.sleep(0.01)


def transforms(msg):
    return {t.child_frame_id: t for t in msg.transforms}


class WorldNodeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.expected = resolve_world(load_world(WORLD), SEED)
        cls.tf = Latest("/tf_static", TFMessage)
        cls.markers = Latest("/magna/world/markers", MarkerArray)
        for name in ("/magna/world/add", "/magna/world/get_fspset", "/magna/world/delete"):
            rospy.wait_for_service(name, timeout=60)
        cls.add = rospy.ServiceProxy("/magna/world/add", AddWorldPart)
        cls.get = rospy.ServiceProxy("/magna/world/get_fspset", GetFreeSpacePoseSet)
        cls.delete = rospy.ServiceProxy("/magna/world/delete", DeleteWorldPart)

    def test_1_every_frame_is_on_tf_static_where_the_model_puts_it(self):
        wait(lambda: self.tf.msg is not None and "B_Take_off" in transforms(self.tf.msg), "the world's frames")
        got = transforms(self.tf.msg)
        for parent, child, frame in self.expected.static_transforms():
            self.assertIn(child, got)
            t = got[child]
            self.assertEqual(t.header.frame_id, parent)
            v, q = t.transform.translation, t.transform.rotation
            np.testing.assert_allclose([v.x, v.y, v.z], frame.translation, atol=1e-9)
            np.testing.assert_allclose(np.abs(np.dot([q.x, q.y, q.z, q.w], frame.quaternion())), 1.0, atol=1e-9)
        for name in ("Base", "B_Ring", "B_to_pos_2_0_0", "B_core_obs_0", "F_sw_pos_0", "F_pil_obs_0"):
            self.assertIn(name, got)

    def test_2_markers_show_geometries_poses_and_obstacles(self):
        wait(lambda: self.markers.msg is not None and len(self.markers.msg.markers) > 1, "the markers")
        markers = self.markers.msg.markers
        self.assertEqual(markers[0].action, Marker.DELETEALL)
        geometries = [m for m in markers if m.ns == "geometries"]
        self.assertEqual(len(geometries), len(self.expected.geometries))
        ring = geometries[1]  # file order: Take_off, Ring, Core, Sweep, Pillar
        self.assertEqual(ring.type, Marker.TRIANGLE_LIST)
        self.assertAlmostEqual(ring.color.r, 1.0)
        self.assertAlmostEqual(ring.color.b, 0.0)
        self.assertAlmostEqual(ring.color.a, 0.4, places=6)
        self.assertEqual(geometries[3].type, Marker.TRIANGLE_LIST)  # the prism, as its faces
        self.assertEqual(geometries[0].type, Marker.CUBE)
        self.assertAlmostEqual(geometries[0].scale.x, 6.0)
        obstacles = [m for m in markers if m.ns == "obstacles"]
        self.assertEqual(len(obstacles), len(self.expected.obstacles()))
        points = sum(len(m.points) for m in markers if m.ns == "poses" and m.type == Marker.SPHERE_LIST)
        self.assertEqual(points, self.expected.pose_count())

    def test_3_pose_sets_resolve_the_way_missions_write_them(self):
        answer = self.get(["Base", "Take_off", "matrix", "[2, 0, 0]"])
        self.assertTrue(answer.success, answer.message)
        self.assertEqual(list(answer.frames), ["B_to_pos_2_0_0"])
        p = answer.poses.poses[0].position
        np.testing.assert_allclose([p.x, p.y, p.z], [2.0, -8.0, 0.05], atol=1e-9)
        answer = self.get(["Base", "Ring", "random", "4"])
        self.assertTrue(answer.success, answer.message)
        self.assertEqual(len(answer.poses.poses), 4)
        wait(lambda: all(f in transforms(self.tf.msg) for f in answer.frames), "frames of the random poses")
        answer = self.get(["Field", "Sweep", "path", "Zigzag"])
        self.assertTrue(answer.success, answer.message)
        sweep = next(s for g in self.expected.geometries for s in g.pose_sets if s.path_name)
        got = np.array([[q.position.x, q.position.y, q.position.z] for q in answer.poses.poses])
        np.testing.assert_allclose(got, sweep.positions, atol=1e-9)
        bad = self.get(["Base", "Nowhere", "matrix", "[0, 0, 0]"])
        self.assertFalse(bad.success)
        self.assertIn("definition[1]", bad.message)
        self.assertIn("Take_off", bad.message)

    def test_4_obstacles_are_in_the_simulator(self):
        # Deleting a model the simulator never had fails; these succeed because the node spawned them.
        delete_model = rospy.ServiceProxy("/magna/sim/delete_model", DeleteModel)
        for obstacle in self.expected.obstacles():
            answer = delete_model(obstacle.name)
            self.assertTrue(answer.success, f"{obstacle.name}: {answer.message}")
        self.assertFalse(delete_model("B_core_obs_99").success)

    def test_5_parts_are_added_and_deleted_with_their_frames_and_obstacles(self):
        answer = self.add(id="extra", world="", subworld="", definition_json=json.dumps(INLINE))
        self.assertTrue(answer.success, answer.message)
        self.assertIn("X_box_pos_1_1_0", answer.frames)
        self.assertIn("1 obstacle(s) spawned", answer.message)
        wait(lambda: "X_box_pos_1_1_0" in transforms(self.tf.msg), "the inline part's frames")
        got = self.get(["Extra", "Box", "matrix", "[1, 1, 0]"])
        self.assertTrue(got.success, got.message)
        p = got.poses.poses[0].position
        np.testing.assert_allclose([p.x, p.y, p.z], [0.5, 20.5, 2.0], atol=1e-9)
        again = self.add(id="extra", world="", subworld="", definition_json=json.dumps(INLINE))
        self.assertFalse(again.success)
        self.assertIn("exists already", again.message)
        bad = self.add(id="bad", world="", subworld="", definition_json='[{"name": "V"}]')
        self.assertFalse(bad.success)
        self.assertIn("[0].origin: missing", bad.message)
        gone = self.delete(id="extra")
        self.assertTrue(gone.success, gone.message)
        self.assertIn("1 obstacle(s)", gone.message)
        wait(lambda: "X_box_pos_1_1_0" not in transforms(self.tf.msg), "the deleted part's frames to go")
        self.assertIn("B_Take_off", transforms(self.tf.msg))
        self.assertFalse(self.get(["Extra", "Box", "matrix", "[1, 1, 0]"]).success)
        self.assertFalse(self.delete(id="extra").success)

    def test_6_the_world_boundaries_are_a_parameter(self):
        self.assertEqual(rospy.get_param("/magna/world/boundaries"), [[-30, 30], [-30, 30], [0, 20]])

    def test_7_the_resolved_world_is_recorded(self):
        path = Path(rospy.get_param("/magna_world/record"))
        try:
            wait(path.exists, "the record file")
            record = json.loads(path.read_text())
            main = record["parts"]["main"]
            self.assertEqual(record["seed"], SEED)
            self.assertEqual(len(main["obstacles"]), len(self.expected.obstacles()))
            first = self.expected.obstacles()[0]
            np.testing.assert_allclose(main["obstacles"][0]["position"], first.position, atol=1e-6)
            poses = sum(len(s["frames"]) for g in main["geometries"] for s in g["pose_sets"])
            self.assertEqual(poses, self.expected.pose_count())
            self.assertFalse(main["deleted"])
            self.assertTrue(record["parts"]["extra"]["deleted"], "deleted in test 5, still in the record")
        finally:
            if path.exists() and str(path).startswith("/tmp/"):
                os.unlink(path)


if __name__ == "__main__":
    rospy.init_node("world_node_test")
    rostest.rosrun("magna_worlds", "world_node", WorldNodeTest, sys.argv)
