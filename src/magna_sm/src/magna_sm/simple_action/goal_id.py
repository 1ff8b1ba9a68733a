"""Goal ids: unique strings plus the time a goal was created."""
import itertools
import threading

import rospy
from actionlib_msgs.msg import GoalID

# One counter for the whole process: several clients of one node share its name.
_counter = itertools.count(1)
_counter_lock = threading.Lock()


def _next_number() -> int:
    with _counter_lock:
        return next(_counter)


class GoalIdGenerator:
    """Makes `GoalID`s of the form `<node name>-<n>-<seconds>.<nanoseconds>`.

    The name makes ids unique across the ROS graph, the per-process counter
    unique within a process, and the stamp is the creation time (ROS time), which
    the server uses for "cancel everything stamped at or before t".

    Every caller says which name: a server its action namespace (unique in the
    graph even when one process hosts many servers, as the UAV manager host does),
    or NODE_NAME for the node's own name, resolved lazily (objects may be built
    before rospy.init_node()).
    """

    NODE_NAME = None

    def __init__(self, name: str | None):
        self._name = name

    @property
    def name(self) -> str:
        return self._name if self._name is not None else rospy.get_name()

    def generate(self, stamp: rospy.Time | None = None) -> GoalID:
        now = rospy.Time.now() if stamp is None else stamp
        number = _next_number()
        return GoalID(stamp=now, id=f"{self.name}-{number}-{now.secs}.{now.nsecs:09d}")
