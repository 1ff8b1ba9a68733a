#!/usr/bin/env python3
"""A TakeOff action served by MAGNA's SimpleActionServer, for interop tests.

Goals: height <= 0 is aborted ("refused"); height >= 100 is held, with feedback,
until it is preempted; any other height succeeds at once with the outcome
"reached <height>". The action name is the private parameter `~action`.
On shutdown the node checks that the server left no thread running (exit 3 if so).
"""
import sys
import threading

import rospy
from magna_msgs.msg import TakeOffAction, TakeOffFeedback, TakeOffResult

from magna_sm.simple_action import SimpleActionServer

HOLD_HEIGHT = 100.0


class TakeOffServer:
    def __init__(self, action: str):
        self.server = SimpleActionServer(action, TakeOffAction, execute_cb=self.execute, auto_start=False)
        self.server.start()

    def execute(self, goal):
        if goal.height <= 0:
            self.server.set_aborted(TakeOffResult(outcome="refused", message="height must be positive"),
                                    "height must be positive")
            return
        feedback = TakeOffFeedback()
        feedback.current_target.z = goal.height
        if goal.height >= HOLD_HEIGHT:
            rate = rospy.Rate(20)
            while not rospy.is_shutdown():
                if self.server.is_preempt_requested():
                    self.server.set_preempted(TakeOffResult(outcome="preempted", message="canceled"), "canceled")
                    return
                feedback.percent_complete = 50.0
                self.server.publish_feedback(feedback)
                try:
                    rate.sleep()
                except rospy.ROSInterruptException:
                    return
            return
        feedback.percent_complete = 100.0
        self.server.publish_feedback(feedback)
        self.server.set_succeeded(TakeOffResult(outcome=f"reached {goal.height:.2f}", message="ok"))


def main() -> int:
    rospy.init_node("take_off_server")
    TakeOffServer(rospy.get_param("~action", "take_off"))
    rospy.spin()
    for thread in threading.enumerate():
        if thread.name.startswith(("SimpleActionServer", "action status")):
            thread.join(3.0)
    left = [t.name for t in threading.enumerate() if t.name.startswith(("SimpleActionServer", "action status"))]
    if left:
        print(f"threads still running after shutdown: {left}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
