"""The manager's /magna/uav_{id}/navigation topic: every recorded control step as a NavigationStep,
with the very numbers of its CSV row."""
from __future__ import annotations

import collections
import threading
from collections.abc import Sequence

import rospy
from geometry_msgs.msg import Point, Vector3
from magna_msgs.msg import NavigationStep

from magna_uav.recorder import HeardStamps


def _time(nanoseconds: int) -> rospy.Time:
    return rospy.Time(nanoseconds // 10**9, nanoseconds % 10**9)


def navigation_msg(index: int, row: dict, role_number: int, heard: Sequence[HeardStamps]) -> NavigationStep:
    """The NavigationStep of the recorder's row `index` (`Recorder.row`): the very numbers its CSV row gets,
    and the stamps of the messages they came from (`heard`, `recorder.heard_stamps`)."""
    msg = NavigationStep(row=index, role_number=role_number, role=row["role"], algorithm=row["algorithm"],
                         goal=Point(*(row[f"goal.{a}"] for a in "xyz")),
                         goal_velocity=Vector3(*(row[f"goal_vel.{a}"] for a in "xyz")),
                         goal_distance=row["goal_dist"],
                         selected_velocity=Vector3(*(row[f"sel_vel.{a}"] for a in "xyz")),
                         feasible=NavigationStep.FEASIBILITY_UNKNOWN if row["feasible"] is None else row["feasible"],
                         teacher_velocity=Vector3(*(row[f"teacher_vel.{a}"] for a in "xyz")),
                         fallback=NavigationStep.FALLBACK_UNKNOWN if row["fallback"] is None else row["fallback"])
    # rounded to the nanosecond, not truncated as Time.from_sec does: a bag reader compares it
    # with the UAL stamps of the same simulated instant
    msg.header.stamp = _time(round(row["time"] * 1e9))
    msg.header.frame_id = "map"
    msg.uav_ids = [h.uav_id for h in heard]
    msg.pose_stamps = [_time(h.pose_ns) for h in heard]
    msg.velocity_stamps = [_time(h.velocity_ns) for h in heard]
    return msg


class NavigationPublisher(rospy.SubscribeListener):
    """Publishes the NavigationSteps, and replays those sent so far to every new subscriber.

    rosbag record finds a topic by polling the master about once a wall second, so at a high
    real-time factor the first steps would be flown before the bag listens. A new subscriber
    first gets the last `backlog` steps, oldest first; a step published while it was joining
    may reach it twice, so readers drop repeats (same `row`: mlr.bags does).
    """

    def __init__(self, topic: str, backlog: int = 10000):
        self._sent: collections.deque[NavigationStep] = collections.deque(maxlen=backlog)
        self._lock = threading.Lock()  # a replay and a new step never interleave on one connection
        # The queue holds a whole replay: a shorter one would drop its oldest steps.
        self.publisher = rospy.Publisher(topic, NavigationStep, queue_size=backlog, subscriber_listener=self)

    def publish(self, msg: NavigationStep) -> None:
        with self._lock:
            self._sent.append(msg)
            self.publisher.publish(msg)

    def peer_subscribe(self, topic_name, topic_publish, peer_publish) -> None:
        with self._lock:
            for msg in self._sent:
                peer_publish(msg)
