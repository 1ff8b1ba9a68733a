"""The world node's reset (/magna/world/reset), live: a node that flew a world, reset with a seed, then given the
world again, records and shows what a node started cold with that seed does; between the two, it latches what a
fresh node latches (no frames, a lone DELETEALL marker) and has left no /magna/world parameters.

No simulator: obstacles are not spawned (~spawn_obstacles false), which leaves world.json unchanged.
"""
import json
import subprocess

import pytest

from magna_common.processes import end_process_group
from tests.support import wait_until

pytestmark = [pytest.mark.ros]

WORLD, SUBWORLD = "Intersection", "Random_Obstacles"  # random obstacles: the seed shows in every pose
FIRST_SEED, SEED = 3, 11
WAIT = 60.0  # a guard against hangs: two world nodes start on a loaded machine


class Latched:
    """Every message of a latched topic, in order."""

    def __init__(self, rospy, topic, kind):
        self.messages = []
        self.subscriber = rospy.Subscriber(topic, kind, self.messages.append)

    @property
    def last(self):
        return self.messages[-1] if self.messages else None

    def close(self):
        self.subscriber.unregister()


def start_node(ros_master, seed, record):
    return ros_master.spawn(["rosrun", "magna_worlds", "world", f"_seed:={seed}", f"_record:={record}",
                             "_spawn_obstacles:=false"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def without_stamps(markers):
    """The marker array as rviz draws it: stamps say when, not what."""
    import rospy

    for marker in markers.markers:
        marker.header.stamp = rospy.Time()
    return markers.markers


def is_fresh(tf, markers):
    from visualization_msgs.msg import Marker

    return (tf.last is not None and tf.last.transforms == [] and markers.last is not None
            and [m.action for m in markers.last.markers] == [Marker.DELETEALL])


def add_world(rospy):
    from magna_msgs.srv import AddWorldPart

    rospy.wait_for_service("/magna/world/add", timeout=WAIT)
    answer = rospy.ServiceProxy("/magna/world/add", AddWorldPart)(id="main", world=WORLD, subworld=SUBWORLD,
                                                                   definition_json="")
    assert answer.success, answer.message
    return answer


def has_world(tf, markers):
    return tf.last is not None and tf.last.transforms and markers.last is not None and len(markers.last.markers) > 1


def test_a_reset_node_flies_the_next_world_as_a_cold_one(rospy_node, ros_master, tmp_path):
    from magna_msgs.srv import ResetWorld
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    rospy = rospy_node
    tf, markers = Latched(rospy, "/tf_static", TFMessage), Latched(rospy, "/magna/world/markers", MarkerArray)
    try:
        node = start_node(ros_master, FIRST_SEED, tmp_path / "first.json")
        try:
            add_world(rospy)
            wait_until(lambda: has_world(tf, markers), "the first world's frames and markers", WAIT)
            assert rospy.has_param("/magna/world/boundaries")
            first = json.loads((tmp_path / "first.json").read_text())

            answer = rospy.ServiceProxy("/magna/world/reset", ResetWorld)(seed=SEED, record=str(tmp_path / "warm.json"))
            assert answer.success, answer.message
            wait_until(lambda: is_fresh(tf, markers), "the reset node to latch no frames and a lone DELETEALL", WAIT)
            assert not rospy.has_param("/magna/world")
            assert not (tmp_path / "warm.json").exists()  # nothing flown yet: a cold node writes no record either

            add_world(rospy)
            wait_until(lambda: has_world(tf, markers), "the warm node's frames and markers", WAIT)
            warm_tf, warm_markers = tf.last, markers.last
            warm_boundaries = rospy.get_param("/magna/world/boundaries")
            warm = json.loads((tmp_path / "warm.json").read_text())
        finally:
            end_process_group(node)
        assert json.loads((tmp_path / "first.json").read_text()) == first  # the reset left the last record alone

        rospy.delete_param("/magna/world")  # as the warm node left it: the cold one must set it again itself
        tf.messages.clear()
        markers.messages.clear()
        node = start_node(ros_master, SEED, tmp_path / "cold.json")
        try:
            # What a fresh node latches first is what the reset latched.
            wait_until(lambda: is_fresh(tf, markers), "the cold node's first latch: no frames, a lone DELETEALL", WAIT)
            add_world(rospy)
            wait_until(lambda: has_world(tf, markers), "the cold node's frames and markers", WAIT)
            cold_tf, cold_markers = tf.last, markers.last
            cold_boundaries = rospy.get_param("/magna/world/boundaries")
        finally:
            end_process_group(node)
    finally:
        tf.close()
        markers.close()

    cold = json.loads((tmp_path / "cold.json").read_text())
    assert warm == cold
    assert first != cold  # the seeds differ, and so do the random obstacles: the comparison can tell
    assert warm_boundaries == cold_boundaries
    assert without_stamps(warm_markers) == without_stamps(cold_markers)
    frames = [(t.header.frame_id, t.child_frame_id, t.transform) for t in warm_tf.transforms]
    assert frames == [(t.header.frame_id, t.child_frame_id, t.transform) for t in cold_tf.transforms]
