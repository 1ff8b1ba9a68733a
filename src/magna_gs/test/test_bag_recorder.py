"""BagRecorder: the ground station's rosbag record, and knowing when it listens (a real master and rosbag)."""
import itertools
import os
import signal
import threading
import time

import pytest

from magna_gs.bag_recorder import BagRecorder

RATE = 50.0  # Hz of the test publisher
POSES = r"/uav_[0-9]+/ual/pose"
_serial = itertools.count(1)  # topics and node names of their own per test


class CountingPublisher:
    """Publishes PoseStamped on `topic` at RATE, the stamp's seconds counting the messages."""

    def __init__(self, rospy, topic):
        from geometry_msgs.msg import PoseStamped

        self.rospy, self.topic, self.sent, self.stop = rospy, topic, 0, threading.Event()
        self.publisher = rospy.Publisher(topic, PoseStamped, queue_size=100)
        self.message = PoseStamped()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.wait(1.0 / RATE):
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


def start_recorder(tmp_path, regex=POSES):
    return BagRecorder(tmp_path / "simulation.bag", regex, node_name=f"bag_{os.getpid()}_{next(_serial)}")


def recorded_counts(path):
    import rosbag

    with rosbag.Bag(str(path)) as bag:
        return [msg.header.stamp.secs for _, msg, _ in bag.read_messages()]


def test_once_it_says_listening_the_bag_gets_the_next_messages(pose_stream, tmp_path):
    recorder = start_recorder(tmp_path)
    try:
        assert recorder.wait_listening([pose_stream.topic], timeout=30.0) == []
        sent_when_listening = pose_stream.sent
        assert pose_stream.topic in recorder.listening_to()
        time.sleep(0.5)
    finally:
        recorder.close()
    assert recorder.process.poll() is not None
    assert (tmp_path / "simulation.bag").is_file() and not (tmp_path / "simulation.bag.active").exists()
    counts = recorded_counts(tmp_path / "simulation.bag")
    # rosbag looks for new topics once a wall second: without the wait, the first ~50 messages would be lost.
    # A few may still pass while the publisher's side of the connection is being set up.
    assert counts and counts[0] <= sent_when_listening + 5, (counts[:3], sent_when_listening)
    assert counts == list(range(counts[0], counts[0] + len(counts)))  # none lost once connected


def test_a_topic_nobody_publishes_is_reported_missing_after_the_timeout(rospy_node, tmp_path):
    recorder = start_recorder(tmp_path, r"/nobody/.*")
    try:
        start = time.monotonic()
        assert recorder.wait_listening(["/nobody/pose"], timeout=1.0) == ["/nobody/pose"]
        assert time.monotonic() - start >= 1.0
        assert recorder.wait_listening([], timeout=5.0) == []
    finally:
        recorder.close()
    assert recorder.process.poll() is not None


def test_a_recorder_that_died_is_not_waited_for(rospy_node, tmp_path):
    recorder = start_recorder(tmp_path, "([")  # a bad regex
    start = time.monotonic()
    missing = recorder.wait_listening(["/uav_1/ual/pose"], timeout=60.0)
    waited = time.monotonic() - start
    with pytest.raises(RuntimeError, match=r"ended by itself \(exit code -?[1-9]"):  # its empty .active stays
        recorder.close()
    assert missing == ["/uav_1/ual/pose"] and waited < 30.0


def test_a_killed_recorders_file_is_kept_and_the_error_says_how_to_mend_it(pose_stream, tmp_path):
    recorder = start_recorder(tmp_path)
    listening = recorder.wait_listening([pose_stream.topic], timeout=30.0)
    time.sleep(0.5)
    os.killpg(recorder.process.pid, signal.SIGKILL)  # as if the machine had to kill it
    recorder.process.wait(10.0)
    assert listening == []
    with pytest.raises(RuntimeError, match="rosbag reindex .*simulation.bag.active"):
        recorder.close()
    assert (tmp_path / "simulation.bag.active").stat().st_size > 0 and not (tmp_path / "simulation.bag").exists()


if __name__ == "__main__":
    raise SystemExit(pytest.main([__file__, "-v"]))
