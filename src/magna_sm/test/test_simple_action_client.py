"""MAGNA's SimpleActionClient against actionlib's own (Debian) SimpleActionServer."""
import threading
import time

import pytest

from tests.support import WAIT, wait_until

pytestmark = pytest.mark.ros


@pytest.fixture
def env(rospy_node, ns):
    """Builds stock servers and our clients on the test's namespace; tears them down after."""
    import actionlib
    from magna_msgs.msg import TakeOffAction

    from magna_sm.simple_action import SimpleActionClient

    made = {"servers": [], "clients": []}

    class Env:
        rospy = rospy_node

        @staticmethod
        def server(execute_cb=None):
            server = actionlib.SimpleActionServer(ns, TakeOffAction, execute_cb=execute_cb, auto_start=False)
            made["servers"].append(server)
            server.start()
            return server

        @staticmethod
        def client(wait=True):
            client = SimpleActionClient(ns, TakeOffAction)
            made["clients"].append(client)
            if wait:
                assert client.wait_for_server(rospy_node.Duration(WAIT)), "our client never saw the stock server"
            return client

    yield Env
    for client in made["clients"]:
        client.stop()
    for server in made["servers"]:
        with server.terminate_mutex:
            server.need_to_terminate = True
        server.action_server.stop()
        if server.execute_thread is not None:
            server.execute_thread.join(WAIT)


def take_off(height):
    from magna_msgs.msg import TakeOffGoal

    return TakeOffGoal(height=height)


def wait_for_preempt(server):
    deadline = time.monotonic() + WAIT
    while not server.is_preempt_requested() and time.monotonic() < deadline:
        time.sleep(0.005)
    return server.is_preempt_requested()


def test_succeeds_with_callbacks_in_order_and_state_sequence(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffFeedback, TakeOffResult

    from magna_sm.simple_action import SimpleGoalState

    release = threading.Event()
    feedback_seen = threading.Event()

    def execute(goal):
        feedback = TakeOffFeedback(percent_complete=75.0)
        feedback.current_target.z = goal.height
        while not feedback_seen.wait(0.05):
            server.publish_feedback(feedback)
        release.wait(WAIT)
        server.set_succeeded(TakeOffResult(outcome=f"reached {goal.height:.1f}", message="ok"), "fine")

    server = env.server(execute)
    client = env.client()
    assert client.get_state() == GoalStatus.LOST   # no goal yet, as actionlib reports it
    events, states = [], []

    def on_active():
        events.append("active")

    def on_feedback(fb):
        events.append(("feedback", fb.percent_complete, fb.current_target.z))
        feedback_seen.set()

    def on_done(state, result):
        events.append(("done", state, result.outcome))

    client.send_goal(take_off(3.5), done_cb=on_done, active_cb=on_active, feedback_cb=on_feedback)
    states.append(client.get_state())
    assert feedback_seen.wait(WAIT)
    wait_until(lambda: client.get_state() == GoalStatus.ACTIVE, "ACTIVE at the client")
    states.append(client.get_state())
    assert client.simple_state == SimpleGoalState.ACTIVE
    assert not client.wait_for_result(env.rospy.Duration(0.05))   # held by the server: not done yet
    release.set()
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    states.append(client.get_state())

    assert states == [GoalStatus.PENDING, GoalStatus.ACTIVE, GoalStatus.SUCCEEDED]
    assert client.simple_state == SimpleGoalState.DONE
    assert client.get_result().outcome == "reached 3.5"
    assert client.get_result().message == "ok"
    assert client.get_goal_status_text() == "fine"
    assert events[0] == "active"
    assert events[1][0] == "feedback" and events[1][1:] == (pytest.approx(75.0), pytest.approx(3.5))
    assert events[-1] == ("done", GoalStatus.SUCCEEDED, "reached 3.5")
    assert events.count("active") == 1 and sum(1 for e in events if e[0] == "done") == 1


def test_abort(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    def execute(goal):
        server.set_aborted(TakeOffResult(outcome="failed"), "no GPS")

    server = env.server(execute)
    client = env.client()
    done = []
    client.send_goal(take_off(1.0), done_cb=lambda state, result: done.append((state, result.outcome)))
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.ABORTED
    assert client.get_goal_status_text() == "no GPS"
    assert done == [(GoalStatus.ABORTED, "failed")]


def test_cancel_goal_preempts(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    def execute(goal):
        if wait_for_preempt(server):
            server.set_preempted(TakeOffResult(outcome="stopped"), "as asked")
        else:
            server.set_aborted()

    server = env.server(execute)
    client = env.client()
    active = threading.Event()
    done = []
    client.send_goal(take_off(1.0), active_cb=active.set, done_cb=lambda s, r: done.append((s, r.outcome)))
    assert active.wait(WAIT)
    client.cancel_goal()
    client.cancel_goal()   # twice: harmless
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.PREEMPTED
    assert client.get_goal_status_text() == "as asked"
    assert done == [(GoalStatus.PREEMPTED, "stopped")]
    client.cancel_goal()   # after the end: nothing happens
    assert client.get_state() == GoalStatus.PREEMPTED


def test_cancel_all_goals(env):
    from actionlib_msgs.msg import GoalStatus

    def execute(goal):
        if wait_for_preempt(server):
            server.set_preempted()
        else:
            server.set_succeeded()

    server = env.server(execute)
    client, other = env.client(), env.client()
    active = threading.Event()
    client.send_goal(take_off(1.0), active_cb=active.set)
    assert active.wait(WAIT)
    other.cancel_all_goals()   # from another client, which has no goal of its own
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert client.get_state() == GoalStatus.PREEMPTED


def test_goal_replacement(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    def execute(goal):
        if goal.height == 1.0:
            if wait_for_preempt(server):
                server.set_preempted(TakeOffResult(outcome="replaced"))
                return
        server.set_succeeded(TakeOffResult(outcome=f"reached {goal.height:.1f}"))

    server = env.server(execute)
    first, second = env.client(), env.client()
    active = threading.Event()
    first.send_goal(take_off(1.0), active_cb=active.set)
    assert active.wait(WAIT)
    second.send_goal(take_off(2.0))
    assert first.wait_for_result(env.rospy.Duration(WAIT)) and second.wait_for_result(env.rospy.Duration(WAIT))
    assert (first.get_state(), first.get_result().outcome) == (GoalStatus.PREEMPTED, "replaced")
    assert (second.get_state(), second.get_result().outcome) == (GoalStatus.SUCCEEDED, "reached 2.0")


def test_wait_for_result_times_out_then_succeeds(env):
    from actionlib_msgs.msg import GoalStatus

    release = threading.Event()

    def execute(goal):
        release.wait(WAIT)
        server.set_succeeded()

    server = env.server(execute)
    client = env.client()
    client.send_goal(take_off(1.0))
    assert client.wait_for_result(env.rospy.Duration(0.2)) is False
    assert client.wait_for_result(0.1) is False   # plain seconds work too
    assert client.get_state() in (GoalStatus.PENDING, GoalStatus.ACTIVE)
    assert client.get_result() is None
    release.set()
    assert client.wait_for_result(env.rospy.Duration(WAIT)) is True
    assert client.get_state() == GoalStatus.SUCCEEDED


def test_pending_goal_recalled_by_a_newer_goal_and_cancel_while_pending(env):
    """Stock goal-callback server: goals wait until the test accepts them."""
    from actionlib_msgs.msg import GoalStatus

    server = env.server()
    arrivals = []
    server.register_goal_callback(lambda: arrivals.append(True))
    first, second = env.client(), env.client()
    active_calls = []
    first.send_goal(take_off(1.0), active_cb=lambda: active_calls.append("first"))
    wait_until(lambda: len(arrivals) == 1, "the first goal at the server")
    second.send_goal(take_off(2.0), active_cb=lambda: active_calls.append("second"))
    assert first.wait_for_result(env.rospy.Duration(WAIT))
    assert first.get_state() == GoalStatus.RECALLED
    assert "another goal" in first.get_goal_status_text()   # the stock server's text

    # The second goal, canceled while pending: RECALLING, which a simple client reads PENDING.
    second.cancel_goal()
    wait_until(lambda: second._goal.status == GoalStatus.RECALLING, "RECALLING heard by the client")
    assert second.get_state() == GoalStatus.PENDING
    assert server.accept_new_goal().height == pytest.approx(2.0)
    assert server.is_preempt_requested()
    wait_until(lambda: second.get_state() == GoalStatus.ACTIVE, "PREEMPTING (read ACTIVE)")
    server.set_preempted()
    assert second.wait_for_result(env.rospy.Duration(WAIT))
    assert second.get_state() == GoalStatus.PREEMPTED
    assert active_calls == ["second"]   # the recalled goal never became active


def test_send_goal_and_wait(env):
    from actionlib_msgs.msg import GoalStatus

    def execute(goal):
        if goal.height >= 100:   # a goal that only ends when preempted
            if wait_for_preempt(server):
                server.set_preempted()
                return
        server.set_succeeded()

    server = env.server(execute)
    client = env.client()
    assert client.send_goal_and_wait(take_off(1.0), env.rospy.Duration(WAIT)) == GoalStatus.SUCCEEDED
    state = client.send_goal_and_wait(take_off(100.0), execute_timeout=env.rospy.Duration(0.2),
                                      preempt_timeout=env.rospy.Duration(WAIT))
    assert state == GoalStatus.PREEMPTED


def test_wait_for_server_times_out_without_server(env):
    client = env.client(wait=False)
    assert client.wait_for_server(env.rospy.Duration(0.2)) is False
    assert client.wait_for_result(env.rospy.Duration(0.1)) is False   # no goal: False, no exception
    assert client.get_result() is None


def test_stop_tracking_goal_silences_callbacks(env):
    from actionlib_msgs.msg import GoalStatus

    release = threading.Event()

    def execute(goal):
        release.wait(WAIT)
        server.set_succeeded()

    server = env.server(execute)
    client = env.client()
    done = []
    client.send_goal(take_off(1.0), done_cb=lambda s, r: done.append(s))
    wait_until(lambda: server.is_active(), "the goal to run")
    client.stop_tracking_goal()
    assert client.get_state() == GoalStatus.LOST
    release.set()
    wait_until(lambda: not server.is_active(), "the goal to end at the server")
    # A later goal on the same client is followed normally; the forgotten one never called back.
    client.send_goal(take_off(2.0), done_cb=lambda s, r: done.append(("second", s)))
    release.set()
    assert client.wait_for_result(env.rospy.Duration(WAIT))
    assert done == [("second", GoalStatus.SUCCEEDED)]
