"""A simple action client speaking the actionlib wire protocol.

`SimpleActionClient` tracks one goal at a time, with the constructor and methods
of `actionlib.SimpleActionClient`, so code written for actionlib runs unchanged.
"""
from __future__ import annotations

import threading
import time
import traceback
import xmlrpc.client
from typing import Any

import rospy
from actionlib_msgs.msg import GoalID, GoalStatus, GoalStatusArray

from magna_common.processes import TimeoutTransport

from .goal_id import GoalIdGenerator
from .spec import action_topic, action_types, as_duration
from .status import ACTIVE_STATES, CLIENT_NEXT_STATES, SimpleGoalState, is_terminal

__all__ = ["SimpleActionClient"]

# Terminal states a goal only reaches after having been accepted (ACTIVE first).
_ENDS_AFTER_ACTIVE = frozenset({GoalStatus.SUCCEEDED, GoalStatus.ABORTED, GoalStatus.PREEMPTED})
_WAIT_SLICE = 0.1   # s: waits re-check rospy shutdown at least this often
_BUS_INFO_TIMEOUT = 2.0   # s: longest wait for a server node to answer getBusInfo


class _TrackedGoal:
    """What the client knows about the goal it sent last."""

    __slots__ = ("action_goal", "status", "text", "result", "simple_state", "server", "done_cb", "active_cb",
                 "feedback_cb")

    def __init__(self, action_goal, done_cb, active_cb, feedback_cb):
        self.action_goal = action_goal
        self.status = GoalStatus.PENDING
        self.text = ""
        self.result = None
        self.simple_state = SimpleGoalState.PENDING
        self.server: str | None = None   # caller id of the server whose status list showed the goal
        self.done_cb = done_cb
        self.active_cb = active_cb
        self.feedback_cb = feedback_cb

    @property
    def id(self) -> str:
        return self.action_goal.goal_id.id


class SimpleActionClient:
    """actionlib's `SimpleActionClient`: send a goal, follow it, get its result.

    `done_cb(state, result)`, `active_cb()` and `feedback_cb(feedback)` are called
    from rospy's subscriber threads, one at a time and in protocol order (active
    before feedback before done), never for a goal the client no longer tracks.
    """

    def __init__(self, ns, ActionSpec):  # noqa: N803 (actionlib's names)
        self.ns = ns
        self.types = action_types(ActionSpec)
        self._lock = threading.RLock()
        self._done = threading.Condition(self._lock)
        self._goal: _TrackedGoal | None = None
        self._ids = GoalIdGenerator(GoalIdGenerator.NODE_NAME)
        self._server_id: str | None = None
        # Our result and feedback connections the server was seen to have added (see _server_connected).
        self._confirmed_links: tuple | None = None
        queue = rospy.get_param("actionlib_client_pub_queue_size", 10)
        queue = queue if queue > 0 else 10
        self._goal_pub = rospy.Publisher(action_topic(ns, "goal"), self.types.action_goal, queue_size=queue)
        self._cancel_pub = rospy.Publisher(action_topic(ns, "cancel"), GoalID, queue_size=queue)
        self._status_sub = rospy.Subscriber(action_topic(ns, "status"), GoalStatusArray, self._on_status,
                                            tcp_nodelay=True)
        self._result_sub = rospy.Subscriber(action_topic(ns, "result"), self.types.action_result,
                                            self._on_result, tcp_nodelay=True)
        self._feedback_sub = rospy.Subscriber(action_topic(ns, "feedback"), self.types.action_feedback,
                                              self._on_feedback, tcp_nodelay=True)

    # -- connecting ---------------------------------------------------------------------------------
    def wait_for_server(self, timeout=rospy.Duration()) -> bool:
        """Block until a server is connected on all five topics, at both ends. A zero timeout waits forever."""
        timeout = as_duration(timeout)
        deadline = rospy.get_rostime() + timeout if timeout > rospy.Duration() else None
        while not rospy.is_shutdown():
            if self._server_connected():
                return True
            if deadline is not None and rospy.get_rostime() >= deadline:
                return False
            time.sleep(0.005)
        return False

    def _server_connected(self) -> bool:
        server = self._server_id   # known from the status messages it sends us
        if server is None:
            return False

        def publishes_to_server(pub):
            return any(c.endpoint_id == server for c in pub.impl.connections)

        def link_from_server(sub):
            return next((c for c in sub.impl.connections if getattr(c, "callerid_pub", None) == server), None)

        if not (publishes_to_server(self._goal_pub) and publishes_to_server(self._cancel_pub)):
            return False
        links = (link_from_server(self._result_sub), link_from_server(self._feedback_sub))
        if None in links:
            return False
        # Our end of a result or feedback connection is there before the server's: a rospy publisher
        # answers the connection header first and adds the connection to its list after, and what it
        # publishes in between reaches nobody (a goal that ends at once loses its result). So the
        # server itself is asked, once per pair of connections.
        if links != self._confirmed_links:
            if not self._server_publishes_to_us(server):
                return False
            self._confirmed_links = links
        return True

    def _server_publishes_to_us(self, server: str) -> bool:
        """Whether the server node's publishers of our result and feedback topics list a connection to us."""
        try:
            code, _, uri = rospy.get_master().lookupNode(server)
            if code != 1:
                return False
            # XML-RPC answers are untyped: the node API answers [code, status message, rows]
            answer: Any = xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(_BUS_INFO_TIMEOUT)).getBusInfo(
                rospy.get_caller_id())
        except (OSError, xmlrpc.client.Error) as error:
            rospy.logdebug("%s: no bus info from %s: %s", self.ns, server, error)
            return False
        code, _, rows = answer
        if code != 1:
            return False
        # a row: connection id, the other end, direction ("o": outbound), transport, topic[, connected]
        me = rospy.get_caller_id()
        ours = {row[4] for row in rows if row[1] == me and row[2] == "o" and (len(row) < 6 or row[5])}
        return self._result_sub.resolved_name in ours and self._feedback_sub.resolved_name in ours

    # -- goals --------------------------------------------------------------------------------------
    def send_goal(self, goal, done_cb=None, active_cb=None, feedback_cb=None) -> None:
        """Send `goal` and track it (a goal tracked before is forgotten, not canceled)."""
        with self._lock:
            goal_id = self._ids.generate()
            action_goal = self.types.action_goal()
            action_goal.header.stamp = goal_id.stamp
            action_goal.goal_id = goal_id
            action_goal.goal = goal
            self._goal = _TrackedGoal(action_goal, done_cb, active_cb, feedback_cb)
            self._goal_pub.publish(action_goal)
            self._done.notify_all()

    def send_goal_and_wait(self, goal, execute_timeout=rospy.Duration(), preempt_timeout=rospy.Duration()) -> int:
        """Send `goal` and wait for it; past `execute_timeout` cancel it and wait up to
        `preempt_timeout` more. Returns the state (`get_state()`) at the end."""
        self.send_goal(goal)
        if not self.wait_for_result(execute_timeout):
            rospy.logdebug("%s: goal not done within the execute timeout, canceling it", self.ns)
            self.cancel_goal()
            if not self.wait_for_result(preempt_timeout):
                rospy.logdebug("%s: goal not done within the preempt timeout either", self.ns)
        return self.get_state()

    def wait_for_result(self, timeout=rospy.Duration()) -> bool:
        """True once the tracked goal is done; False on timeout (a zero timeout waits forever)."""
        with self._done:
            if self._goal is None:
                rospy.logerr("%s: wait_for_result() called with no goal sent", self.ns)
                return False
            timeout = as_duration(timeout)
            deadline = rospy.get_rostime() + timeout if timeout > rospy.Duration() else None
            while not rospy.is_shutdown():
                tracked = self._goal
                if tracked is None:
                    return False
                if tracked.simple_state == SimpleGoalState.DONE:
                    return True
                wait = _WAIT_SLICE
                if deadline is not None:
                    left = (deadline - rospy.get_rostime()).to_sec()
                    if left <= 0:
                        return False
                    wait = min(wait, left)
                self._done.wait(wait)
            return self._goal is not None and self._goal.simple_state == SimpleGoalState.DONE

    def get_result(self):
        """The result of the tracked goal, or None while there is none."""
        tracked = self._goal
        if tracked is None:
            rospy.logerr("%s: get_result() called with no goal sent", self.ns)
            return None
        return tracked.result

    def get_state(self) -> int:
        """The goal's `GoalStatus` state as actionlib's simple client reports it:
        RECALLING reads PENDING, PREEMPTING reads ACTIVE, and LOST when no goal is tracked."""
        tracked = self._goal
        if tracked is None:
            return GoalStatus.LOST
        if tracked.status == GoalStatus.RECALLING:
            return GoalStatus.PENDING
        if tracked.status == GoalStatus.PREEMPTING:
            return GoalStatus.ACTIVE
        return tracked.status

    def get_goal_status_text(self) -> str:
        tracked = self._goal
        if tracked is None:
            rospy.logerr("%s: get_goal_status_text() called with no goal sent", self.ns)
            return "ERROR: no goal is being tracked"
        return tracked.text

    @property
    def simple_state(self) -> int:
        """`SimpleGoalState` of the tracked goal (DONE when there is none)."""
        tracked = self._goal
        return SimpleGoalState.DONE if tracked is None else tracked.simple_state

    # -- canceling ----------------------------------------------------------------------------------
    def cancel_goal(self) -> None:
        """Ask the server to cancel the tracked goal. Nothing to do once it is done."""
        with self._lock:
            tracked = self._goal
            if tracked is None or tracked.simple_state == SimpleGoalState.DONE:
                return
            self._cancel_pub.publish(GoalID(stamp=rospy.Time(), id=tracked.id))

    def cancel_all_goals(self) -> None:
        """Ask the server to cancel every goal it has, from any client."""
        self._cancel_pub.publish(GoalID(stamp=rospy.Time(), id=""))

    def cancel_goals_at_and_before_time(self, time) -> None:
        """Ask the server to cancel every goal stamped at or before `time` (and any arriving later so stamped)."""
        self._cancel_pub.publish(GoalID(stamp=time, id=""))

    def stop_tracking_goal(self) -> None:
        """Forget the tracked goal (no cancel is sent); its callbacks are not called any more."""
        with self._lock:
            self._goal = None
            self._done.notify_all()

    def stop(self) -> None:
        """Unregister from the action's topics (not part of actionlib's simple client)."""
        with self._lock:
            self._goal = None
            self._done.notify_all()
        for handle in (self._goal_pub, self._cancel_pub, self._status_sub, self._result_sub, self._feedback_sub):
            handle.unregister()

    # -- incoming messages (subscriber threads) -----------------------------------------------------
    def _call(self, callback, *args) -> None:
        if callback is None:
            return
        try:
            callback(*args)
        except Exception:
            rospy.logerr("%s: callback %r failed:\n%s", self.ns, callback, traceback.format_exc())

    def _update(self, tracked: _TrackedGoal, status: int, text: str) -> None:
        """Take a status heard from the server; ignore what would move the goal backwards."""
        if status not in CLIENT_NEXT_STATES.get(tracked.status, ()):
            return
        tracked.status = status
        tracked.text = text
        if tracked.simple_state == SimpleGoalState.PENDING and (status in ACTIVE_STATES
                                                                or status in _ENDS_AFTER_ACTIVE):
            tracked.simple_state = SimpleGoalState.ACTIVE
            self._call(tracked.active_cb)

    def _finish(self, tracked: _TrackedGoal) -> None:
        tracked.simple_state = SimpleGoalState.DONE
        self._done.notify_all()
        self._call(tracked.done_cb, tracked.status, tracked.result)

    def _on_status(self, msg: GoalStatusArray) -> None:
        server = msg._connection_header.get("callerid") if hasattr(msg, "_connection_header") else None
        self._server_id = server
        with self._lock:
            tracked = self._goal
            if tracked is None or tracked.simple_state == SimpleGoalState.DONE:
                return
            for status in msg.status_list:
                if status.goal_id.id == tracked.id:
                    tracked.server = server
                    self._update(tracked, status.status, status.text)
                    return
            if tracked.server is None or tracked.server != server:
                return   # not acknowledged yet (or news from another server)
            # The server that had the goal dropped it without our hearing the result.
            if not is_terminal(tracked.status):
                rospy.logwarn("%s: goal %s vanished from the server's status list: LOST", self.ns, tracked.id)
                tracked.status = GoalStatus.LOST
            else:
                rospy.logwarn("%s: goal %s ended %d but its result never arrived", self.ns, tracked.id,
                              tracked.status)
            self._finish(tracked)

    def _on_result(self, msg) -> None:
        with self._lock:
            tracked = self._goal
            if (tracked is None or msg.status.goal_id.id != tracked.id
                    or tracked.simple_state == SimpleGoalState.DONE):
                return
            tracked.result = msg.result
            self._update(tracked, msg.status.status, msg.status.text)
            # The result is the server's last word, whatever we heard before.
            tracked.status = msg.status.status
            tracked.text = msg.status.text
            self._finish(tracked)

    def _on_feedback(self, msg) -> None:
        with self._lock:
            tracked = self._goal
            if (tracked is None or msg.status.goal_id.id != tracked.id
                    or tracked.simple_state == SimpleGoalState.DONE):
                return
            self._update(tracked, msg.status.status, msg.status.text)
            self._call(tracked.feedback_cb, msg.feedback)
