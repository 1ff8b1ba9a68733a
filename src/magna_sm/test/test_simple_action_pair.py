"""MAGNA's SimpleActionClient with MAGNA's SimpleActionServer: the status list and its
keep time, the cancel forms of the protocol, robustness, and shutdown."""
import os
import re
import signal
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.support import WAIT, wait_until

pytestmark = pytest.mark.ros

SERVER_SCRIPT = Path(__file__).resolve().parent / "take_off_server_rostest.py"


@pytest.fixture
def env(rospy_node, ns):
    from magna_msgs.msg import TakeOffAction

    from magna_sm.simple_action import SimpleActionClient, SimpleActionServer

    made = []

    class Env:
        rospy = rospy_node

        @staticmethod
        def server(execute_cb=None, **kwargs):
            server = SimpleActionServer(ns, TakeOffAction, execute_cb=execute_cb, **kwargs)
            made.append(server)
            return server

        @staticmethod
        def client(wait=True):
            client = SimpleActionClient(ns, TakeOffAction)
            made.append(client)
            if wait:
                assert client.wait_for_server(WAIT)
            return client

    yield Env
    for thing in reversed(made):
        if isinstance(thing, SimpleActionServer):
            thing.shutdown()
        else:
            thing.stop()


class StatusRecorder:
    """Every GoalStatusArray published on `<ns>/status`, with the time it arrived."""

    def __init__(self, rospy, ns):
        from actionlib_msgs.msg import GoalStatusArray

        self.messages = []
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(f"{ns}/status", GoalStatusArray, self._on_msg)

    def _on_msg(self, msg):
        with self._lock:
            self.messages.append(msg)

    def snapshot(self):
        with self._lock:
            return list(self.messages)

    def statuses_of(self, goal_id):
        """The status codes of `goal_id` in order, one per message listing it."""
        return [s.status for m in self.snapshot() for s in m.status_list if s.goal_id.id == goal_id]

    def close(self):
        self._sub.unregister()


def take_off(height):
    from magna_msgs.msg import TakeOffGoal

    return TakeOffGoal(height=height)


def hold_until_preempted(server):
    deadline = time.monotonic() + WAIT
    while not server.is_preempt_requested() and time.monotonic() < deadline:
        time.sleep(0.005)
    if server.is_preempt_requested():
        server.set_preempted()
    else:
        server.set_aborted()


def test_status_list_shows_changes_then_drops_finished_goal_after_keep_time(env, ns):
    from actionlib_msgs.msg import GoalStatus

    keep = 0.6
    env.rospy.set_param(f"{ns}/status_list_timeout", keep)   # actionlib's parameter
    server = env.server(lambda goal: server.set_succeeded())
    recorder = StatusRecorder(env.rospy, ns)
    try:
        client = env.client()
        client.send_goal(take_off(1.0))
        assert client.wait_for_result(WAIT)
        assert client.get_state() == GoalStatus.SUCCEEDED
        goal_id = client._goal.id

        wait_until(lambda: GoalStatus.SUCCEEDED in recorder.statuses_of(goal_id), "SUCCEEDED on the status topic")

        def dropped():
            seen = [m for m in recorder.snapshot() if any(s.goal_id.id == goal_id for s in m.status_list)]
            later = [m for m in recorder.snapshot() if seen and m.header.stamp > seen[-1].header.stamp]
            return seen and any(not m.status_list for m in later)

        wait_until(dropped, "the finished goal to leave the status list")
        statuses = recorder.statuses_of(goal_id)
        # Published on every change: the instant ACTIVE phase is on the topic, in order.
        assert statuses[0] in (GoalStatus.PENDING, GoalStatus.ACTIVE)
        assert GoalStatus.ACTIVE in statuses
        assert statuses.index(GoalStatus.ACTIVE) < statuses.index(GoalStatus.SUCCEEDED)
        assert set(statuses[statuses.index(GoalStatus.SUCCEEDED):]) == {GoalStatus.SUCCEEDED}
        # Kept at least `keep` seconds after it finished (never dropped early).
        messages = recorder.snapshot()
        last_listed = max(m.header.stamp for m in messages if any(s.goal_id.id == goal_id for s in m.status_list))
        first_without = min(m.header.stamp for m in messages if m.header.stamp > last_listed)
        assert server.current_goal_status().status == GoalStatus.SUCCEEDED
        assert (first_without - server._current.finished_at).to_sec() >= keep
        # The heartbeat goes on with nothing changing (status is periodic, not only on change).
        count = len(recorder.snapshot())
        wait_until(lambda: len(recorder.snapshot()) >= count + 2, "periodic status messages")
    finally:
        recorder.close()


def test_cancel_goals_at_and_before_time(env):
    from actionlib_msgs.msg import GoalStatus

    def execute(goal):
        if goal.height >= 100:
            hold_until_preempted(server)
        else:
            server.set_succeeded()

    server = env.server(execute)
    client = env.client()
    active = threading.Event()
    client.send_goal(take_off(100.0), active_cb=active.set)
    assert active.wait(WAIT)
    sent_at = client._goal.action_goal.goal_id.stamp
    client.cancel_goals_at_and_before_time(sent_at)   # the goal's own stamp: "at or before" includes it
    assert client.wait_for_result(WAIT)
    assert client.get_state() == GoalStatus.PREEMPTED

    # A goal stamped later is not touched by that request.
    client.send_goal(take_off(1.0))
    assert client.wait_for_result(WAIT)
    assert client.get_state() == GoalStatus.SUCCEEDED


def test_cancel_by_stamp_recalls_older_goals_arriving_later_and_early_cancel_by_id(env, ns):
    """Raw protocol: a goal whose stamp is at or before the last cancel stamp, or whose id was
    canceled before it arrived, is RECALLED on arrival and never executed."""
    from actionlib_msgs.msg import GoalID, GoalStatus
    from magna_msgs.msg import TakeOffActionGoal, TakeOffActionResult

    rospy = env.rospy
    executed = []

    def execute(goal):
        executed.append(goal.height)
        server.set_succeeded()

    server = env.server(execute)
    results = {}
    goal_pub = rospy.Publisher(f"{ns}/goal", TakeOffActionGoal, queue_size=10)
    cancel_pub = rospy.Publisher(f"{ns}/cancel", GoalID, queue_size=10)
    result_sub = rospy.Subscriber(f"{ns}/result", TakeOffActionResult,
                                  lambda m: results.setdefault(m.status.goal_id.id, m.status))
    try:
        wait_until(lambda: goal_pub.get_num_connections() and cancel_pub.get_num_connections()
                   and result_sub.get_num_connections(), "raw connections")
        now = rospy.Time.now()
        old = rospy.Time(now.secs - 10, now.nsecs)
        cancel_pub.publish(GoalID(stamp=rospy.Time(now.secs - 5, now.nsecs), id=""))
        cancel_pub.publish(GoalID(stamp=rospy.Time(), id="early-cancel"))
        # Both cancels handled first (the two topics are not ordered with each other); they share
        # one connection, so the placeholder of the second implies the first was handled too.
        wait_until(lambda: any(g.id == "early-cancel" for g in server.action_server.goals()), "the cancels")
        stale = TakeOffActionGoal()
        stale.goal_id = GoalID(stamp=old, id="stale")
        stale.goal.height = 1.0
        early = TakeOffActionGoal()
        early.goal_id = GoalID(stamp=now, id="early-cancel")
        early.goal.height = 2.0
        fresh = TakeOffActionGoal()
        fresh.goal_id = GoalID(stamp=rospy.Time.now(), id="fresh")
        fresh.goal.height = 3.0
        for msg in (stale, early, fresh):
            goal_pub.publish(msg)
        wait_until(lambda: len(results) == 3, "three results")
        assert results["stale"].status == GoalStatus.RECALLED
        assert results["early-cancel"].status == GoalStatus.RECALLED
        assert results["fresh"].status == GoalStatus.SUCCEEDED
        assert executed == [3.0]
    finally:
        for handle in (goal_pub, cancel_pub, result_sub):
            handle.unregister()


def test_preempt_twice_and_cancel_after_finish_break_nothing(env, ns):
    from actionlib_msgs.msg import GoalID, GoalStatus

    second_preempt = []

    def execute(goal):
        if goal.height >= 100:
            hold_until_preempted(server)
            server.set_preempted()   # a second time: refused (logged), nothing else
            second_preempt.append(server.current_goal_status().status)
        else:
            server.set_succeeded()
            server.set_succeeded()   # twice: refused, the goal stays SUCCEEDED

    server = env.server(execute)
    client = env.client()
    active = threading.Event()
    client.send_goal(take_off(100.0), active_cb=active.set)
    assert active.wait(WAIT)
    client.cancel_goal()
    client.cancel_goal()
    client.cancel_all_goals()
    assert client.wait_for_result(WAIT)
    assert client.get_state() == GoalStatus.PREEMPTED
    wait_until(lambda: second_preempt, "the execute callback to end")
    assert second_preempt == [GoalStatus.PREEMPTED]

    client.send_goal(take_off(1.0))
    assert client.wait_for_result(WAIT)
    assert client.get_state() == GoalStatus.SUCCEEDED
    finished_id = client._goal.id
    # A witness on the cancel topic in this process: rospy hands each message to the server's callback
    # first (subscribed first), so once the witness has the cancel, the server has handled it.
    cancels = []
    witness = env.rospy.Subscriber(f"{ns}/cancel", GoalID, cancels.append)
    try:
        wait_until(lambda: client._cancel_pub.get_num_connections(), "the client's cancel topic to connect")
        client.cancel_goal()          # the goal is done: nothing sent
        client.cancel_all_goals()     # the server has only finished goals: nothing changes
        wait_until(lambda: "" in [c.id for c in cancels], "cancel_all_goals to reach the server")
    finally:
        witness.unregister()
    assert finished_id not in [c.id for c in cancels]  # cancel_goal sent nothing for a finished goal
    statuses = {g.id: g.status.status for g in server.action_server.goals()}
    assert statuses[finished_id] == GoalStatus.SUCCEEDED
    assert client.get_state() == GoalStatus.SUCCEEDED
    # ...and the server still serves.
    assert client.send_goal_and_wait(take_off(2.0), WAIT) == GoalStatus.SUCCEEDED


def test_goal_callback_mode_and_feedback(env):
    """No execute callback: the user accepts goals in the goal callback and ends them later."""
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffFeedback, TakeOffResult

    server = env.server(auto_start=False)
    goals = []
    server.register_goal_callback(lambda: goals.append(server.accept_new_goal()))
    server.start()
    client = env.client()
    feedbacks, order = [], []
    client.send_goal(take_off(7.0), active_cb=lambda: order.append("active"),
                     feedback_cb=lambda fb: (feedbacks.append(fb.percent_complete), order.append("feedback")),
                     done_cb=lambda s, r: order.append(("done", s, r.outcome)))
    wait_until(lambda: goals and client.get_state() == GoalStatus.ACTIVE, "the goal accepted")
    assert goals[0].height == pytest.approx(7.0)
    server.publish_feedback(TakeOffFeedback(percent_complete=10.0))
    wait_until(lambda: feedbacks, "feedback")
    server.set_succeeded(TakeOffResult(outcome="up"))
    assert client.wait_for_result(WAIT)
    assert order == ["active", "feedback", ("done", GoalStatus.SUCCEEDED, "up")]


def test_done_cb_may_send_the_next_goal(env):
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffResult

    server = env.server(lambda goal: server.set_succeeded(TakeOffResult(outcome=str(goal.height))))
    client = env.client()
    outcomes = []

    def done(state, result):
        outcomes.append(result.outcome)
        if len(outcomes) < 3:
            client.send_goal(take_off(float(len(outcomes) + 1)), done_cb=done)

    client.send_goal(take_off(1.0), done_cb=done)
    wait_until(lambda: len(outcomes) == 3, "three chained goals")
    assert client.wait_for_result(WAIT)
    assert outcomes == ["1.0", "2.0", "3.0"]
    assert client.get_state() == GoalStatus.SUCCEEDED


@pytest.mark.parametrize("topic", ["result", "feedback"])
def test_wait_for_server_waits_for_the_servers_end_of_result_and_feedback(env, topic):
    """A rospy publisher adds a subscriber's connection to its list only after the subscriber has it,
    and publishes to nobody in between: a goal ending at once then lost its result. The server's
    end is held back here until the client has been seen to wait for it."""
    from magna_msgs.msg import TakeOffResult

    server = env.server(lambda goal: server.set_succeeded(TakeOffResult(outcome="up")))
    publisher = server.action_server._pubs[topic].impl
    add_connection = publisher.add_connection
    release = threading.Event()

    def added_late(connection):
        # Not in the calling thread: it is the node's one thread taking every incoming connection.
        threading.Thread(target=lambda: (release.wait(WAIT), add_connection(connection)), daemon=True).start()
        return True

    publisher.add_connection = added_late
    client = env.client(wait=False)
    me = env.rospy.get_caller_id()
    try:
        ours = client._result_sub if topic == "result" else client._feedback_sub
        wait_until(lambda: client._server_id == me and any(c.callerid_pub == me for c in ours.impl.connections),
                   "the client's end of the connection")
        assert not client.wait_for_server(0.2)   # the server's end cannot be there yet
    finally:
        release.set()
    assert client.wait_for_server(WAIT)
    assert any(c.endpoint_id == me for c in publisher.connections)
    client.send_goal(take_off(1.0))
    assert client.wait_for_result(WAIT)
    assert client.get_result().outcome == "up"


def test_server_shutdown_ends_its_thread(env):
    release = threading.Event()
    server = env.server(lambda goal: (release.wait(WAIT), server.set_succeeded()))
    client = env.client()
    client.send_goal(take_off(1.0))
    wait_until(server.is_active, "the goal to run")
    thread = server._thread
    assert thread.is_alive()
    release.set()
    server.shutdown()
    assert not thread.is_alive()
    assert not server.action_server.started


def test_goal_ids_are_unique_and_stamped(rospy_node):
    from magna_sm.simple_action import GoalIdGenerator

    generator = GoalIdGenerator("/some/node")
    ids = [generator.generate() for _ in range(50)]
    assert len({g.id for g in ids}) == 50
    assert all(g.id.startswith("/some/node-") for g in ids)
    assert all(g.stamp.to_sec() > 0 for g in ids)


@pytest.fixture
def subprocess_server(ros_master, rospy_node, request):
    """Our TakeOff server in a process of its own (the rostest's node), ended by the test."""
    action = "/test_sa_pair/sub_" + re.sub(r"[^A-Za-z0-9_]", "_", request.node.name)
    process = ros_master.spawn([sys.executable, str(SERVER_SCRIPT), f"__name:=srv_{os.getpid()}_{id(request)}",
                                f"_action:={action}"])
    yield action, process


def test_client_does_not_hang_when_the_server_dies(subprocess_server):
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffAction

    from magna_sm.simple_action import SimpleActionClient

    action, process = subprocess_server
    client = SimpleActionClient(action, TakeOffAction)
    try:
        assert client.wait_for_server(rospy.Duration(30))
        feedback = threading.Event()
        client.send_goal(take_off(100.0), feedback_cb=lambda fb: feedback.set())   # held until preempted
        assert feedback.wait(WAIT)
        os.killpg(process.pid, signal.SIGKILL)   # the server crashes
        process.wait(WAIT)
        assert client.wait_for_result(rospy.Duration(0.3)) is False
        assert client.get_state() == GoalStatus.ACTIVE
        state = client.send_goal_and_wait(take_off(1.0), execute_timeout=rospy.Duration(0.3),
                                          preempt_timeout=rospy.Duration(0.3))
        assert state == GoalStatus.PENDING   # returned, with nobody to hear the goal
        assert client.wait_for_server(rospy.Duration(0.3)) is False
    finally:
        client.stop()


def test_server_node_shuts_down_cleanly_mid_goal(subprocess_server):
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from magna_msgs.msg import TakeOffAction

    from magna_sm.simple_action import SimpleActionClient

    action, process = subprocess_server
    client = SimpleActionClient(action, TakeOffAction)
    try:
        assert client.wait_for_server(rospy.Duration(30))
        assert client.send_goal_and_wait(take_off(2.0), rospy.Duration(WAIT)) == GoalStatus.SUCCEEDED
        assert client.get_result().outcome == "reached 2.00"
        feedback = threading.Event()
        client.send_goal(take_off(100.0), feedback_cb=lambda fb: feedback.set())
        assert feedback.wait(WAIT)
        os.killpg(process.pid, signal.SIGINT)   # as roslaunch or Ctrl-C would
        # The node exits 0 only if none of the server's threads is left running (see the script).
        assert process.wait(WAIT) == 0
    finally:
        client.stop()


class RawServer:
    """A hand-driven action server: the test publishes exactly the protocol messages it wants."""

    def __init__(self, rospy, ns):
        from actionlib_msgs.msg import GoalID, GoalStatusArray
        from magna_msgs.msg import TakeOffActionFeedback, TakeOffActionGoal, TakeOffActionResult

        self.rospy = rospy
        self.goals, self.cancels = [], []
        self.status = rospy.Publisher(f"{ns}/status", GoalStatusArray, queue_size=10, latch=True)
        self.result = rospy.Publisher(f"{ns}/result", TakeOffActionResult, queue_size=10)
        self.feedback = rospy.Publisher(f"{ns}/feedback", TakeOffActionFeedback, queue_size=10)
        self.subs = [rospy.Subscriber(f"{ns}/goal", TakeOffActionGoal, self.goals.append),
                     rospy.Subscriber(f"{ns}/cancel", GoalID, self.cancels.append)]
        self.publish_status()

    def publish_status(self, *entries):
        """One status list, each entry (goal_id, status) or (goal_id, status, text)."""
        from actionlib_msgs.msg import GoalStatus, GoalStatusArray

        msg = GoalStatusArray(status_list=[GoalStatus(goal_id=entry[0], status=entry[1],
                                                      text=entry[2] if len(entry) > 2 else "") for entry in entries])
        msg.header.stamp = self.rospy.Time.now()
        self.status.publish(msg)

    def publish_result(self, goal_id, code, outcome=""):
        from actionlib_msgs.msg import GoalStatus
        from magna_msgs.msg import TakeOffActionResult

        msg = TakeOffActionResult()
        msg.header.stamp = self.rospy.Time.now()
        msg.status = GoalStatus(goal_id=goal_id, status=code)
        msg.result.outcome = outcome
        self.result.publish(msg)

    def close(self):
        for handle in (self.status, self.result, self.feedback, *self.subs):
            handle.unregister()


@pytest.fixture
def raw(rospy_node, ns):
    server = RawServer(rospy_node, ns)
    yield server
    server.close()


def test_result_without_any_status_still_calls_active_then_done(env, raw):
    from actionlib_msgs.msg import GoalStatus

    client = env.client()
    order = []
    client.send_goal(take_off(1.0), active_cb=lambda: order.append("active"),
                     done_cb=lambda state, result: order.append(("done", state, result.outcome)))
    wait_until(lambda: raw.goals, "the goal at the raw server")
    raw.publish_result(raw.goals[0].goal_id, GoalStatus.SUCCEEDED, "straight to the end")
    assert client.wait_for_result(WAIT)
    assert order == ["active", ("done", GoalStatus.SUCCEEDED, "straight to the end")]


def test_goal_dropped_from_the_status_list_is_lost_and_stale_status_is_ignored(env, raw, ns):
    from actionlib_msgs.msg import GoalStatus

    client = env.client()
    # Made after the client: rospy runs the callbacks of one topic in order of creation,
    # so once the recorder has a message, the client has handled it.
    recorder = StatusRecorder(env.rospy, ns)
    done = []
    client.send_goal(take_off(1.0), done_cb=lambda state, result: done.append((state, result)))
    wait_until(lambda: raw.goals, "the goal at the raw server")
    goal_id = raw.goals[0].goal_id
    raw.publish_status((goal_id, GoalStatus.ACTIVE))
    wait_until(lambda: client.get_state() == GoalStatus.ACTIVE, "ACTIVE")
    raw.publish_status((goal_id, GoalStatus.PENDING, "stale"))   # out of date: must not move the goal back
    wait_until(lambda: any(s.text == "stale" for m in recorder.snapshot() for s in m.status_list), "the stale status")
    recorder.close()
    assert client.get_state() == GoalStatus.ACTIVE
    assert client.get_goal_status_text() == ""
    raw.publish_status((goal_id, GoalStatus.PREEMPTING))
    wait_until(lambda: client._goal.status == GoalStatus.PREEMPTING, "PREEMPTING")
    assert client.get_state() == GoalStatus.ACTIVE
    assert client.wait_for_result(0.05) is False
    raw.publish_status()   # the server forgot the goal before it ended
    assert client.wait_for_result(WAIT)
    assert client.get_state() == GoalStatus.LOST
    assert done == [(GoalStatus.LOST, None)]


def test_a_terminal_status_waits_for_the_result_that_follows_it(env, raw):
    """Status and result come on different connections: the status list may say SUCCEEDED first."""
    from actionlib_msgs.msg import GoalStatus

    client = env.client()
    client.send_goal(take_off(1.0))
    wait_until(lambda: raw.goals, "the goal at the raw server")
    goal_id = raw.goals[0].goal_id
    raw.publish_status((goal_id, GoalStatus.SUCCEEDED))
    wait_until(lambda: client._goal.status == GoalStatus.SUCCEEDED, "the terminal status")
    assert client.wait_for_result(0.05) is False
    raw.publish_result(goal_id, GoalStatus.SUCCEEDED, "came later")
    assert client.wait_for_result(WAIT)
    assert client.get_state() == GoalStatus.SUCCEEDED
    assert client.get_result().outcome == "came later"
