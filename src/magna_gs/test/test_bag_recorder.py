"""BagRecorder: the ground station's rosbag record, and knowing when it listens (a real master and rosbag)."""
import os
import signal
import threading
import time

import pytest

from magna_gs.bag_recorder import BagRecorder

RATE = 50.0  # Hz of the test publisher


class CountingPublisher:
    """Publishes PoseStamped on `topic` at RATE, the stamp's seconds counting the messages."""

    def __init__(self, rospy, topic):
        from geometry_msgs.msg import PoseStamped

        self.rospy, self.sent, self.stop = rospy, 0, threading.Event()
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


def recorded_counts(path):
    import rosbag

    with rosbag.Bag(str(path)) as bag:
        return [msg.header.stamp.secs for _, msg, _ in bag.read_messages()]


def test_once_it_says_listening_the_bag_gets_the_next_messages(rospy_node, tmp_path):
    topic = f"/uav_{os.getpid() % 1000}/ual/pose"
    publisher = CountingPublisher(rospy_node, topic)
    recorder = BagRecorder(tmp_path / "simulation.bag", r"/uav_[0-9]+/ual/pose", node_name=f"bag_{os.getpid()}")
    try:
        assert recorder.wait_listening([topic], timeout=30.0) == []
        sent_when_listening = publisher.sent
        assert topic in recorder.listening_to()
        time.sleep(0.5)
    finally:
        publisher.close()
        recorder.close()
    assert recorder.process.poll() is not None
    assert (tmp_path / "simulation.bag").is_file() and not (tmp_path / "simulation.bag.active").exists()
    counts = recorded_counts(tmp_path / "simulation.bag")
    # rosbag looks for new topics once a wall second: without the wait, the first ~50 messages would be lost.
    # A few may still pass while the publisher's side of the connection is being set up.
    assert counts and counts[0] <= sent_when_listening + 5, (counts[:3], sent_when_listening)
    assert counts == list(range(counts[0], counts[0] + len(counts)))  # none lost once connected


def test_a_topic_nobody_publishes_is_reported_missing_after_the_timeout(rospy_node, tmp_path):
    recorder = BagRecorder(tmp_path / "simulation.bag", r"/nobody/.*", node_name=f"bag_idle_{os.getpid()}")
    try:
        start = time.monotonic()
        assert recorder.wait_listening(["/nobody/pose"], timeout=1.0) == ["/nobody/pose"]
        assert time.monotonic() - start >= 1.0
        assert recorder.wait_listening([], timeout=5.0) == []
    finally:
        recorder.close()
    assert recorder.process.poll() is not None


def test_a_recorder_that_died_is_not_waited_for(rospy_node, tmp_path):
    recorder = BagRecorder(tmp_path / "simulation.bag", "([", node_name=f"bag_bad_{os.getpid()}")  # a bad regex
    start = time.monotonic()
    missing = recorder.wait_listening(["/uav_1/ual/pose"], timeout=60.0)
    waited = time.monotonic() - start
    with pytest.raises(RuntimeError, match=r"ended by itself \(exit code -?[1-9]"):  # its empty .active stays
        recorder.close()
    assert missing == ["/uav_1/ual/pose"] and waited < 30.0


def test_a_killed_recorders_file_is_kept_and_the_error_says_how_to_mend_it(rospy_node, tmp_path):
    topic = f"/uav_{os.getpid() % 1000 + 1}/ual/pose"
    publisher = CountingPublisher(rospy_node, topic)
    recorder = BagRecorder(tmp_path / "simulation.bag", r"/uav_[0-9]+/ual/pose", node_name=f"bag_kill_{os.getpid()}")
    try:
        assert recorder.wait_listening([topic], timeout=30.0) == []
        time.sleep(0.5)
        os.killpg(recorder.process.pid, signal.SIGKILL)  # as if the machine had to kill it
        recorder.process.wait(10.0)
    finally:
        publisher.close()
    with pytest.raises(RuntimeError, match="rosbag reindex .*simulation.bag.active"):
        recorder.close()
    assert (tmp_path / "simulation.bag.active").stat().st_size > 0 and not (tmp_path / "simulation.bag").exists()


if __name__ == "__main__":
    raise SystemExit(pytest.main([__file__, "-v"]))
