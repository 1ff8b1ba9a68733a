"""MAGNA's SimpleActionServer against actionlib's own (Debian) SimpleActionClient.

Every exchange crosses the wire: the stock client only knows the actionlib
protocol, so these tests pin our server to it.
"""
import threading
import time

import pytest

from tests.support import WAIT, wait_until

pytestmark = pytest.mark.ros


def stock_client(ns, spec):
    """actionlib's SimpleActionClient, shielded from a race of its own (ros/actionlib#206, never fixed
    upstream): send_goal publishes the goal before it stores the goal's handle, and a transition
    heard in between is dropped as "not tracking", DONE included, so wait_for_result never ends.
    Our server answers that fast when the test process is busy; here transitions wait for send_goal."""
    import actionlib

    class Client(actionlib.SimpleActionClient):
        def __init__(self, *args):
            self._sending = threading.RLock()   # reentrant: a done callback may send the next goal
            super().__init__(*args)

        def send_goal(self, *args, **kwargs):
            with self._sending:
                super().send_goal(*args, **kwargs)

        def _handle_transition(self, gh):
            with self._sending:
                super()._handle_transition(gh)

        def _handle_feedback(self, gh, feedback):
            with self._sending:
                super()._handle_feedback(gh, feedback)

    return Client(ns, spec)


@pytest.fixture
def env(rospy_node, ns):
    """Builds our servers and stock clients on the test's namespace; tears them down after."""
    from magna_msgs.msg import TakeOffAction

    from magna_sm.simple_action import SimpleActionServer

    made = {"servers": [], "clients": []}

    class Env:
        rospy = rospy_node

        @staticmethod
        def server(execute_cb=None, **kwargs):
            server = SimpleActionServer(ns, TakeOffAction, execute_cb=execute_cb, auto_start=False, **kwargs)
            made["servers"].append(server)
            server.start()
            return server

        @staticmethod
        def client():
            client = stock_client(ns, TakeOffAction)
            made["clients"].append(client)
            assert client.wait_for_server(rospy_node.Duration(WAIT)), "stock client never saw our server"
            return client

    yield Env
    for client in made["clients"]:
        client.stop_tracking_goal()
        client.action_client.stop()
    for server in made["servers"]:
        server.shutdown()


def take_off(height):
    from magna_msgs.msg import TakeOffGoal

    return TakeOffGoal(height=height)


def test_succeeds_with_result_and_feedback(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffFeedback, TakeOffResult

    feedback_seen = threading.Event()
    heights = []

    def execute(goal):
        heights.append(goal.height)
        feedback = TakeOffFeedback(percent_complete=42.0)
        feedback.current_target.z = goal.height
        # Keep publishing until the client confirms it heard: no race with the result.
        while not feedback_seen.wait(0.05):
            server.publish_feedback(feedback)
        server.set_succeeded(TakeOffResult(outcome=f"reached {goal.height:.1f}", message="ok"), "all good")

    server = env.server(execute)
    client = env.client()
    feedbacks, events = [], []

    def on_feedback(fb):
        feedbacks.append(fb)
        feedback_seen.set()

    client.send_goal(take_off(2.5), done_cb=lambda state, result: events.append(("done", state, result.outcome)),
                     active_cb=lambda: events.append(("active",)), feedback_cb=on_feedback)
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.SUCCEEDED
    assert client.get_result().outcome == "reached 2.5"
    assert client.get_result().message == "ok"
    assert client.get_goal_status_text() == "all good"
    assert heights == [2.5]
    assert feedbacks and feedbacks[0].percent_complete == pytest.approx(42.0)
    assert feedbacks[0].current_target.z == pytest.approx(2.5)
    assert events == [("active",), ("done", GoalStatus.SUCCEEDED, "reached 2.5")]
    assert not server.is_active()


def test_aborts_with_result_and_text(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    def execute(goal):
        server.set_aborted(TakeOffResult(outcome="failed", message="battery low"), "battery low")

    server = env.server(execute)
    client = env.client()
    client.send_goal(take_off(3.0))
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.ABORTED
    assert client.get_result().outcome == "failed"
    assert client.get_goal_status_text() == "battery low"


def test_execute_cb_without_terminal_state_aborts_and_exception_aborts(env):
    from actionlib_msgs.msg import GoalStatus

    def execute(goal):
        if goal.height > 5:
            raise RuntimeError("motor 3 does not answer")
        # returns without set_succeeded/aborted/preempted: a bug the server absorbs

    env.server(execute)
    client = env.client()
    client.send_goal(take_off(1.0))
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.ABORTED
    assert "terminal state" in client.get_goal_status_text()
    assert client.get_result().outcome == ""   # the default result

    client.send_goal(take_off(9.0))
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.ABORTED
    assert "motor 3 does not answer" in client.get_goal_status_text()


def test_preempt_via_cancel(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    preempt_callbacks = []
    started = threading.Event()

    def execute(goal):
        started.set()
        deadline = time.monotonic() + WAIT
        while not server.is_preempt_requested() and time.monotonic() < deadline:
            time.sleep(0.005)
        if server.is_preempt_requested():
            server.set_preempted(TakeOffResult(outcome="stopped"), "preempted by client")
        else:
            server.set_aborted()

    server = env.server(execute)
    server.register_preempt_callback(lambda: preempt_callbacks.append(True))
    client = env.client()
    client.send_goal(take_off(4.0))
    assert started.wait(WAIT)
    wait_until(lambda: client.get_state() == GoalStatus.ACTIVE, "the goal to be ACTIVE at the client")
    client.cancel_goal()
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.PREEMPTED
    assert client.get_result().outcome == "stopped"
    assert client.get_goal_status_text() == "preempted by client"
    assert preempt_callbacks == [True]


def test_new_goal_replaces_the_current_one(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    executed = []

    def execute(goal):
        executed.append(goal.height)
        if goal.height == 1.0:   # the long one: runs until something preempts it
            deadline = time.monotonic() + WAIT
            while not server.is_preempt_requested() and time.monotonic() < deadline:
                time.sleep(0.005)
            assert server.is_new_goal_available()
            server.set_preempted(TakeOffResult(outcome="replaced"))
            return
        server.set_succeeded(TakeOffResult(outcome=f"reached {goal.height:.1f}"))

    server = env.server(execute)
    first, second = env.client(), env.client()
    first.send_goal(take_off(1.0))
    wait_until(lambda: first.get_state() == GoalStatus.ACTIVE, "the first goal to be ACTIVE")
    second.send_goal(take_off(2.0))
    assert first.wait_for_result(env.rospy.Duration(WAIT))
    assert second.wait_for_result(env.rospy.Duration(WAIT))
    assert first.get_state() == GoalStatus.PREEMPTED
    assert first.get_result().outcome == "replaced"
    assert second.get_state() == GoalStatus.SUCCEEDED
    assert second.get_result().outcome == "reached 2.0"
    assert executed == [1.0, 2.0]


def test_pending_goal_overtaken_by_a_newer_one_is_recalled(env):
    """Goal-callback mode: a goal not accepted yet is recalled when a newer one arrives."""
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    server = env.server()
    goal_callbacks = []
    server.register_goal_callback(lambda: goal_callbacks.append(server.is_new_goal_available()))
    first, second = env.client(), env.client()
    first.send_goal(take_off(1.0))
    wait_until(lambda: len(goal_callbacks) == 1, "the goal callback")
    second.send_goal(take_off(2.0))
    assert first.wait_for_result(env.rospy.Duration(WAIT))
    assert first.get_state() == GoalStatus.RECALLED
    assert second.get_state() == GoalStatus.PENDING
    wait_until(lambda: len(goal_callbacks) == 2, "the goal callback of the second goal")
    assert goal_callbacks == [True, True]

    goal = server.accept_new_goal()
    assert goal.height == pytest.approx(2.0)
    assert not server.is_preempt_requested()
    wait_until(lambda: second.get_state() == GoalStatus.ACTIVE, "the second goal to be ACTIVE")
    server.set_succeeded(TakeOffResult(outcome="done"))
    assert second.wait_for_result(env.rospy.Duration(WAIT))
    assert second.get_state() == GoalStatus.SUCCEEDED


def test_cancel_of_a_pending_goal_reads_pending_then_preempted(env):
    """A cancel while pending puts the goal in RECALLING (PENDING to a simple client);
    accepting it then makes it PREEMPTING with the preempt already requested."""
    from actionlib_msgs.msg import GoalStatus

    server = env.server()
    arrived = threading.Event()
    server.register_goal_callback(arrived.set)
    client = env.client()
    client.send_goal(take_off(1.0))
    assert arrived.wait(WAIT)
    client.cancel_goal()
    wait_until(lambda: client.action_client.last_status_msg is not None and any(
        s.status == GoalStatus.RECALLING for s in client.action_client.last_status_msg.status_list),
        "RECALLING on the status topic")
    assert client.get_state() == GoalStatus.PENDING
    server.accept_new_goal()
    assert server.is_preempt_requested()
    assert server.current_goal_status().status == GoalStatus.PREEMPTING
    wait_until(lambda: client.get_state() == GoalStatus.ACTIVE, "PREEMPTING (read ACTIVE) at the client")
    server.set_preempted()
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.PREEMPTED


def test_reject_new_goal(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    server = env.server()

    def validate():
        server.reject_new_goal(TakeOffResult(outcome="rejected"), "too high")

    server.register_goal_callback(validate)
    client = env.client()
    client.send_goal(take_off(500.0))
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.REJECTED
    assert client.get_goal_status_text() == "too high"
    assert client.get_result().outcome == "rejected"
    assert not server.is_new_goal_available()
    assert server.accept_new_goal() is None   # nothing left to accept, and no exception


def test_register_goal_callback_is_ignored_with_an_execute_callback(env):
    from actionlib_msgs.msg import GoalStatus

    def execute(goal):
        server.set_succeeded()

    server = env.server(execute)
    called = []
    server.register_goal_callback(lambda: called.append(True))
    client = env.client()
    client.send_goal(take_off(1.0))
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.SUCCEEDED
    assert called == []
