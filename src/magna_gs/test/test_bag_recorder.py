"""BagRecorder: the ground station's rosbag record, and knowing when it listens (a real master and rosbag)."""
import itertools
import math
import os
import signal
import sys
import threading
import time
import xmlrpc.client

import pytest

from magna_common.processes import TimeoutTransport, end_process_group
from magna_gs.bag_recorder import BagRecorder, mission_topics
from tests.support import WAIT, wait_until

RATE = 50.0  # Hz of the test publisher
_serial = itertools.count(1)  # topics and node names of their own per test


class CountingPublisher:
    """Publishes PoseStamped on `topic` at RATE, the stamp's seconds counting the messages; `first_connected`
    is the number of the first one sent while this side had a subscriber's connection."""

    def __init__(self, rospy, topic):
        from geometry_msgs.msg import PoseStamped

        self.rospy, self.topic, self.sent, self.stop = rospy, topic, 0, threading.Event()
        self.first_connected = None
        self.publisher = rospy.Publisher(topic, PoseStamped, queue_size=100)
        self.message = PoseStamped()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.wait(1.0 / RATE):
            if self.first_connected is None and self.publisher.get_num_connections():
                self.first_connected = self.sent + 1
            self.sent += 1
            self.message.header.stamp = self.rospy.Time(self.sent)
            self.publisher.publish(self.message)

    def close(self):
        self.stop.set()
        self.thread.join()
        self.publisher.unregister()


@pytest.fixture
def pose_stream(rospy_node):
    publisher = CountingPublisher(rospy_node, f"/uav_{900 + next(_serial)}/ual/pose")
    yield publisher
    publisher.close()


def start_recorder(tmp_path, topics):
    return BagRecorder(tmp_path / "simulation.bag", topics, node_name=f"bag_{os.getpid()}_{next(_serial)}")


def messages_received(recorder, topic):
    """How many messages of `topic` the recorder's node has received (roscpp's getBusStats: per topic, a row
    per connection: id, bytes, messages, ...)."""
    import rosgraph

    uri = rosgraph.Master("/magna_test").lookupNode(recorder.node)
    _published, subscribed = xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(5.0)).getBusStats(
        "/magna_test")[:2]
    return sum(link[2] for name, links in subscribed if name == topic for link in links)


def recorded_counts(path):
    import rosbag

    with rosbag.Bag(str(path)) as bag:
        return [msg.header.stamp.secs for _, msg, _ in bag.read_messages()]


def test_once_it_says_listening_the_bag_gets_the_next_messages(pose_stream, tmp_path):
    recorder = start_recorder(tmp_path, [pose_stream.topic])
    try:
        assert recorder.wait_listening([pose_stream.topic], timeout=30.0) == []
        assert pose_stream.topic in recorder.listening_to()
        wait_until(lambda: messages_received(recorder, pose_stream.topic) >= 25, "25 messages in the recorder")
    finally:
        recorder.close()
    assert recorder.process.poll() is not None
    assert (tmp_path / "simulation.bag").is_file() and not (tmp_path / "simulation.bag.active").exists()
    counts = recorded_counts(tmp_path / "simulation.bag")
    # Messages sent while the publisher's side of the connection is being set up are lost; none after.
    assert pose_stream.first_connected is not None
    assert len(counts) >= 25 and counts[0] <= pose_stream.first_connected, (counts[:3], pose_stream.first_connected)
    assert counts == list(range(counts[0], counts[0] + len(counts)))  # none lost once connected


# Publishes poses on argv[1]; once the file argv[2] exists, it also makes simulated time run.
POSE_SOURCE = """
import os, sys, time
import rospy
from geometry_msgs.msg import PoseStamped
from rosgraph_msgs.msg import Clock
rospy.init_node("pose_source", disable_signals=True)
poses = rospy.Publisher(sys.argv[1], PoseStamped, queue_size=10)
clock = rospy.Publisher("/clock", Clock, queue_size=10)
n = 0
while True:
    n += 1
    poses.publish(PoseStamped())
    if os.path.exists(sys.argv[2]):
        clock.publish(Clock(rospy.Time(n)))
    time.sleep(0.02)
"""


def test_a_topic_that_appears_while_simulated_time_stands_still_is_connected(fresh_ros_master, tmp_path,
                                                                               monkeypatch):
    # As after spawning: /use_sim_time and no clock, then a UAV's pose topic appears. A --regex recorder
    # looks for new topics on a timer of simulated time and would never find it.
    import rosgraph

    for name, value in fresh_ros_master.env().items():
        monkeypatch.setenv(name, value)
    rosgraph.Master("/magna_test").setParam("/use_sim_time", True)
    topic = "/uav_3/ual/pose"
    recorder = start_recorder(tmp_path, mission_topics([3]))
    source = None
    try:
        def subscribed():  # the recorder has subscribed, and nobody publishes yet
            assert recorder.process.poll() is None, "the recorder ended"
            return topic in {t for t, nodes in rosgraph.Master("/magna_test").getSystemState()[1]
                             if recorder.node in nodes}

        wait_until(subscribed, "the recorder to subscribe to the pose topic", timeout=3 * WAIT)
        assert recorder.listening_to() == set()
        time_runs = tmp_path / "time_runs"
        source = fresh_ros_master.spawn([sys.executable, "-c", POSE_SOURCE, topic, str(time_runs)])
        assert recorder.wait_listening([topic], timeout=20.0) == []
        time_runs.touch()  # rosbag writes nothing before simulated time is valid
        wait_until(lambda: messages_received(recorder, "/clock") > 0, "simulated time in the recorder")
        after_clock = messages_received(recorder, topic)
        wait_until(lambda: messages_received(recorder, topic) >= after_clock + 5, "poses after the clock")
    finally:
        if source is not None:
            end_process_group(source)
        recorder.close()
    assert recorded_counts(tmp_path / "simulation.bag")


def test_a_topic_nobody_publishes_is_reported_missing_after_the_timeout(rospy_node, tmp_path):
    recorder = start_recorder(tmp_path, ["/nobody/pose"])
    try:
        start = time.monotonic()
        assert recorder.wait_listening(["/nobody/pose"], timeout=1.0) == ["/nobody/pose"]
        assert time.monotonic() - start >= 1.0
        assert recorder.wait_listening([], timeout=5.0) == []
    finally:
        recorder.close()
    assert recorder.process.poll() is not None


def test_a_recorder_that_died_is_not_waited_for(rospy_node, tmp_path):
    recorder = start_recorder(tmp_path, ["/uav_1/ual/pose", "not a topic name"])
    answer = {}
    # No time limit: only the recorder's end can end this wait.
    waiter = threading.Thread(target=lambda: answer.setdefault(
        "missing", recorder.wait_listening(["/uav_1/ual/pose"], timeout=math.inf)), daemon=True)
    waiter.start()
    wait_until(lambda: not waiter.is_alive(), "wait_listening to return once the recorder died", timeout=6 * WAIT)
    with pytest.raises(RuntimeError, match=r"no simulation.bag was written: .*ended by itself \(exit code -?[1-9]"):
        recorder.close()
    assert answer["missing"] == ["/uav_1/ual/pose"]


def test_a_killed_recorders_file_is_kept_and_the_error_says_how_to_mend_it(pose_stream, tmp_path):
    recorder = start_recorder(tmp_path, [pose_stream.topic])
    listening = recorder.wait_listening([pose_stream.topic], timeout=30.0)
    wait_until(lambda: messages_received(recorder, pose_stream.topic) >= 10, "messages in the recorder")
    os.killpg(recorder.process.pid, signal.SIGKILL)  # as if the machine had to kill it
    recorder.process.wait(10.0)
    assert listening == []
    with pytest.raises(RuntimeError, match="rosbag reindex .*simulation.bag.active"):
        recorder.close()
    assert (tmp_path / "simulation.bag.active").stat().st_size > 0 and not (tmp_path / "simulation.bag").exists()


def test_the_recorded_missions_bag_heard_each_uav_before_its_first_step(recorded_run):
    import rosbag

    # roslaunch names it ground_station-N.log (a cold start); a batch's warm stack, ground_station.log
    logs = list((recorded_run.sim_dir / "logs").rglob("ground_station*.log"))
    assert logs and not any("the bag is not recording" in log.read_text() for log in logs)
    first = {}
    with rosbag.Bag(str(recorded_run.sim_dir / "simulation.bag")) as bag:
        for uav in recorded_run.uav_ids:
            for topic in (f"/uav_{uav}/ual/pose", f"/uav_{uav}/ual/velocity", f"/magna/uav_{uav}/navigation"):
                first[topic] = next(bag.read_messages(topics=[topic]))[1].header.stamp.to_sec()
    for uav in recorded_run.uav_ids:
        assert first[f"/uav_{uav}/ual/pose"] <= first[f"/magna/uav_{uav}/navigation"]
        assert first[f"/uav_{uav}/ual/velocity"] <= first[f"/magna/uav_{uav}/navigation"]


if __name__ == "__main__":
    raise SystemExit(pytest.main([__file__, "-v"]))
