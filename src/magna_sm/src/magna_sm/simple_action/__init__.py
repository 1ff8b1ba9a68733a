"""The actionlib protocol in MAGNA's own code: `SimpleActionServer`, `SimpleActionClient`.

Drop-in replacements for actionlib's Python simple server and client (same
constructor arguments, same method names, same wire protocol: the `goal`,
`cancel`, `status`, `feedback` and `result` topics of an action namespace), so
existing code switches with one import, and either side talks to actionlib's
C++ or Python counterpart::

    from magna_sm.simple_action import SimpleActionServer   # was: from actionlib import ...
"""
from actionlib_msgs.msg import GoalStatus

from .client import SimpleActionClient
from .goal_id import GoalIdGenerator
from .server import GoalTable, ServerGoal, SimpleActionServer
from .spec import ActionSpecError
from .status import SimpleGoalState, status_name

__all__ = [
    "ActionSpecError",
    "GoalIdGenerator",
    "GoalStatus",
    "GoalTable",
    "ServerGoal",
    "SimpleActionClient",
    "SimpleActionServer",
    "SimpleGoalState",
    "status_name",
]
